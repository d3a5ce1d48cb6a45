"""Shared fixtures for the host tests."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path
from urllib.parse import urlencode

import pytest
from cli_runs import LiveRun, run_live
from fake_device import PORT_ENV, FakeData, FakeDevice, device_targets, make_data

EXAMPLE_RIG = """\
name = "bench-L30"
sample_rate_hz = 100

[links.a]
joint = [0.30, 0.0]
[[links.a.sensors]]
model = "adxl345"
position = [0.25, 0.0]
rotation_deg = 0.0
mux_channel = 0
address = 0x53
range_g = 2
noise_density_ug = 400
[[links.a.sensors]]
model = "adxl345"
position = [0.05, 0.0]
mux_channel = 0
address = 0x1D
range_g = 2

[links.b]
joint = [0.0, 0.0]
[[links.b.sensors]]
model = "adxl345"
position = [0.05, 0.0]
mux_channel = 1
address = 0x53
range_g = 2
[[links.b.sensors]]
model = "adxl357"
position = [0.25, 0.01]
rotation_deg = 90.0
mux_channel = 1
address = 0x1D
range_g = 10
"""


@pytest.fixture
def example_rig_text() -> str:
    return EXAMPLE_RIG


@pytest.fixture
def example_rig_path(tmp_path: Path) -> Path:
    p = tmp_path / "rig.toml"
    p.write_text(EXAMPLE_RIG)
    return p


# Device fixtures shared by the tests that talk to a device on a serial port (test_device_io.py,
# test_live.py): the fake device's data, its rig file, and one port per target that exists.


@pytest.fixture(scope="module")
def fake_data() -> tuple[FakeData, str]:
    return make_data(seconds=3.0)


@pytest.fixture
def rig_file(tmp_path: Path, fake_data: tuple[FakeData, str]) -> Path:
    p = tmp_path / "rig.toml"
    p.write_text(fake_data[1])
    return p


@pytest.fixture(params=device_targets())
def port(request: pytest.FixtureRequest, tmp_path: Path,
         fake_data: tuple[FakeData, str]) -> Iterator[str]:
    if request.param == "env":
        yield os.environ[PORT_ENV]
        return
    if request.param.startswith("sim://"):
        yield request.param
        return
    with FakeDevice(fake_data[0], tmp_path) as fake:
        yield str(fake.path)


# The hardware-in-the-loop suite (hil/, issue 5 item 6) runs against the virtual boards:
# every virtual board (sim://native, sim://avr, sim://pico). A
# test body never reaches into a board: it sets the board up through the sim:// URL query
# (boards.options.SIM_QUERY: fast clock, sensor faults, EEPROM file, baud rate, motion, cable pull)
# and talks to it through the protocol and the `jointangle` commands a user types.


HIL_TARGETS_ENV = "JOINTANGLE_HIL_TARGETS"  # e.g. "sim://native,sim://avr": run on these


# Every virtual board (the test command builds them all): one not built fails with the
# launcher's message saying how to build it instead of being skipped.
DEFAULT_HIL_TARGETS = ("sim://native", "sim://avr", "sim://pico")


def hil_targets() -> list[str]:
    """Those named in $JOINTANGLE_HIL_TARGETS, else DEFAULT_HIL_TARGETS."""
    named = [t.strip() for t in os.environ.get(HIL_TARGETS_ENV, "").split(",") if t.strip()]
    return named or list(DEFAULT_HIL_TARGETS)


@pytest.fixture(params=hil_targets())
def hil_port(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture
def sim_url(hil_port: str) -> Callable[..., str]:
    """sim_url(*faults, **options) -> the board's URL with that query, e.g.
    sim_url("a.1:nack@1-2", fast=1) -> "sim://native?fault=a.1:nack@1-2&fast=1"."""

    def make(*faults: str, **options: object) -> str:
        pairs = [("fault", f) for f in faults] + [(k, str(v)) for k, v in options.items()]
        return hil_port + ("?" + urlencode(pairs, safe=":@/.") if pairs else "")

    return make


@pytest.fixture
def live_until() -> Callable[..., LiveRun]:
    return run_live

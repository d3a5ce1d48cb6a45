"""Shared fixtures for the host tests."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
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

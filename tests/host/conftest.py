"""Shared fixtures for the host tests."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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


def simulate_files(tmp_path_factory: pytest.TempPathFactory, name: str,
                   seconds: float) -> tuple[Path, Path]:
    """`seconds` of gravity-ramp as an accelerations CSV and its rig file, in a new folder."""
    from jointangle.cli.main import main

    d = tmp_path_factory.mktemp(name)
    data, rig = d / "data.csv", d / "rig.toml"
    assert main(["simulate", "--scenario", "gravity-ramp", "--seconds", str(seconds), "--out",
                 str(data), "--rig-out", str(rig)]) == 0
    return data, rig


def one_line_error(err: str, *needles: str) -> None:
    """A bad-input error as the CLI must give it: one line, no traceback, naming `needles`."""
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, err


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


# The hardware-in-the-loop suite (test_hil_*.py, issue 5 item 6) runs against the virtual boards:
# every sim:// target of `device_targets` (sim://native; sim://avr once it is listed there). A
# test body never reaches into a board: it sets the board up through the sim:// URL query
# (boards.options.SIM_QUERY: fast clock, sensor faults, EEPROM file, baud rate, motion, cable pull)
# and talks to it through the protocol and the `jointangle` commands a user types.


HIL_TARGETS_ENV = "JOINTANGLE_HIL_TARGETS"  # e.g. "sim://native,sim://avr": run on these


def hil_targets() -> list[str]:
    """The sim:// targets (or those named in $JOINTANGLE_HIL_TARGETS); sim://native when none
    is built, so the suite fails with the launcher's message saying how to build it instead of
    being skipped."""
    named = [t.strip() for t in os.environ.get(HIL_TARGETS_ENV, "").split(",") if t.strip()]
    sims = named or [t for t in device_targets() if t.startswith("sim://")]
    return sims or ["sim://native"]


@pytest.fixture(params=hil_targets())
def hil_port(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture
def sim_url(hil_port: str) -> Callable[..., str]:
    """sim_url(*faults, **options) -> the board's URL with that query, e.g.
    sim_url("a.1:nack@1-2", fast=1) -> "sim://native?fault=a.1:nack@1-2&fast=1"."""
    from urllib.parse import urlencode

    def make(*faults: str, **options: object) -> str:
        pairs = [("fault", f) for f in faults] + [(k, str(v)) for k, v in options.items()]
        return hil_port + ("?" + urlencode(pairs, safe=":@/.") if pairs else "")

    return make


@dataclass
class LiveRun:
    rows: list[dict[str, Any]]  # one per estimate (`live --json-lines`)
    summary: dict[str, Any]  # `live --json`
    returncode: int
    stderr: str


def run_live(url: str, until_device_s: float, *extra: str, timeout_s: float | None = None,
             cwd: Path | None = None) -> LiveRun:
    """`jointangle live --port URL --json-lines --json [extra]` until the device clock passes
    `until_device_s` (whatever the board's speed), then Ctrl-C, as a user would. The time limit
    (default 60 s + 3 s per device second) only catches a board that stopped."""
    import json
    import selectors
    import signal
    import subprocess
    import sys
    import time

    if timeout_s is None:
        timeout_s = 60.0 + 3.0 * until_device_s
    cmd = [sys.executable, "-m", "jointangle", "live", "--port", url, "--json-lines", "--json",
           "--seconds", str(timeout_s), "--timeout", "5", *extra]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=cwd)
    assert proc.stdout is not None
    lines: list[bytes] = []
    buf = b""
    deadline = time.monotonic() + timeout_s + 30
    try:
        with selectors.DefaultSelector() as sel:
            sel.register(proc.stdout, selectors.EVENT_READ)
            done = False
            while not done and time.monotonic() < deadline:
                if not sel.select(timeout=0.2):
                    if proc.poll() is not None:
                        break
                    continue
                chunk = os.read(proc.stdout.fileno(), 1 << 16)
                if not chunk:
                    break
                buf += chunk
                *new, buf = buf.split(b"\n")
                lines += new
                if new and b'"device_t"' in new[-1]:
                    done = json.loads(new[-1])["device_t"] >= until_device_s
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    lines += (buf + out).split(b"\n")
    docs = [json.loads(ln) for ln in lines if ln.strip()]
    rows = [d for d in docs if "device_t" in d]
    summaries = [d for d in docs if "device_t" not in d]
    assert summaries, f"live printed no summary (status {proc.returncode}): {err.decode()[-800:]}"
    return LiveRun(rows, summaries[-1], proc.returncode, err.decode(errors="replace"))


@pytest.fixture
def live_until() -> Callable[..., LiveRun]:
    return run_live

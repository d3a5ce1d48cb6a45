"""HIL: your own Arduino sketch on the virtual rig (issue 22 items 4-6). The example sketch
firmware/sim/avr_board/rig_reader/rig_reader.ino, built with the Debian Arduino core (arduino-mk)
as its README says, runs on `sim://avr?elf=` against rig_reader/rig.toml and a known static pose,
and reads each part through Wire the way common client code does: the ADXL357 through its FIFO,
the ADXL345 through its FIFO and interrupt sources, Wire's status for an absent address. One
board run serves the tests; each checks what the models read as zeros before issue 22."""

from __future__ import annotations

import math
import re
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import urlencode

import pytest

from jointangle.transport import Connection, open_port

SKETCH = Path(__file__).resolve().parents[3] / "firmware/sim/avr_board/rig_reader"
ARDUINO_MK = Path("/usr/share/arduino/Arduino.mk")
G = 9.80665
# The BNO055's pose: roll 10 degrees about its y axis, pitch -20 about x (the datasheet's Euler
# angles, Windows orientation); at rest its specific force is "up" in its own frame.
ROLL, PITCH = math.radians(10.0), math.radians(-20.0)
BNO_UP = (-math.sin(ROLL), math.cos(ROLL) * math.sin(PITCH), math.cos(ROLL) * math.cos(PITCH))
# The pose (m/s^2 in each sensor's frame): a.0 ADXL357, a.1 ADXL345 (channel 0); b.0 BNO055,
# b.1 ADXL345 (channel 1).
POSE = {"a.0": (0.3 * G, -0.5 * G, 0.8 * G), "a.1": (0.1 * G, 0.2 * G, 0.97 * G),
        "b.0": tuple(G * u for u in BNO_UP), "b.1": (0.0, 0.0, G)}
ADXL357_ODR_HZ, ADXL345_ODR_HZ = 125.0, 100.0
LINE = re.compile(rb"^(WIRE|T|A357|A345|B055|PAUSE)\b(.*)$")


def parse(rest: bytes) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for field in rest.decode().split():
        key, _, value = field.partition("=")
        if "," in value:
            out[key] = [int(v) for v in value.split(",")]
        elif key in ("st", "src", "id", "mode", "calib"):
            out[key] = int(value, 16)
        else:
            out[key] = int(value)
    return out


class Sketch:
    """The sketch's report lines, read as they come."""

    def __init__(self, conn: Connection) -> None:
        self.conn = conn
        self.lines: list[tuple[str, dict[str, Any]]] = []
        self.buf = b""

    def read(self, kind: str, after: int = 0, timeout_s: float = 20.0) -> tuple[
            int, dict[str, Any]]:
        """The first line of `kind` at index >= after (reading more as needed)."""
        deadline = time.monotonic() + timeout_s
        while True:
            for i in range(after, len(self.lines)):
                if self.lines[i][0] == kind:
                    return i, self.lines[i][1]
            after = max(after, len(self.lines))
            assert time.monotonic() < deadline, f"no {kind} line: {self.lines[-5:]}"
            self.buf += self.conn.port.read(256)
            *done, self.buf = self.buf.split(b"\n")
            for raw in done:
                m = LINE.match(raw.strip())
                if m:
                    self.lines.append((m.group(1).decode(), parse(m.group(2))))


@pytest.fixture(scope="module")
def sketch_elf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not ARDUINO_MK.is_file() or shutil.which("make") is None:
        pytest.skip("the Debian Arduino core (arduino-mk) is not installed")
    out = tmp_path_factory.mktemp("rig_reader")
    run = subprocess.run(["make", "-C", str(SKETCH), f"OBJDIR={out}"], capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    return next(out.glob("*.elf"))


def run_sketch(elf: Path, motion: Path) -> Iterator[Sketch]:
    query = urlencode({"elf": elf, "rig": SKETCH / "rig.toml", "motion": motion}, safe="/")
    conn = open_port(f"sim://avr?{query}", baud=115200)
    try:
        yield Sketch(conn)
    finally:
        conn.close()


@pytest.fixture(scope="module")
def sketch(sketch_elf: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Sketch]:
    """The static pose."""
    motion = tmp_path_factory.mktemp("rig_reader_run") / "pose.csv"
    ids = list(POSE)
    rows = ["t," + ",".join(f"{i}.{a}" for i in ids for a in "xyz")]
    rows += [f"{t}," + ",".join(repr(v) for i in ids for v in POSE[i]) for t in (0.0, 1.0)]
    motion.write_text("\n".join(rows) + "\n")
    yield from run_sketch(sketch_elf, motion)


TURN_DPS = 20.0  # the BNO055 turns about the vertical, counter-clockwise seen from above
SHAKE_HZ = 0.5  # the ADXL345 on channel 0: x = 2 g sin(2 pi 0.5 t)


@pytest.fixture(scope="module")
def moving(sketch_elf: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Sketch]:
    """A moving scenario: the BNO055 (flat) turns at 20 deg/s from t = 0; the channel-0 ADXL345
    shakes along x beyond its 1.5 g activity threshold; the rest keeps the static pose."""
    motion = tmp_path_factory.mktemp("rig_reader_moving") / "moving.csv"
    ids = list(POSE)
    head = [f"{i}.{a}" for i in ids for a in "xyz"] + ["b.0.gx", "b.0.gy", "b.0.gz"]
    rows = ["t," + ",".join(head)]
    for n in range(3001):  # 30 s at 100 Hz
        t = n / 100.0
        pose = dict(POSE, **{"a.1": (2 * G * math.sin(2 * math.pi * SHAKE_HZ * t), 0.0, G),
                             "b.0": (0.0, 0.0, G)})
        vals = [v for i in ids for v in pose[i]] + [0.0, 0.0, math.radians(TURN_DPS)]
        rows.append(f"{t:.2f}," + ",".join(repr(v) for v in vals))
    motion.write_text("\n".join(rows) + "\n")
    yield from run_sketch(sketch_elf, motion)


def test_wire_reports_an_absent_address_as_address_nack(sketch: Sketch) -> None:
    _, wire = sketch.read("WIRE")
    assert wire["absent"] == 2, wire  # simavr 1.6 alone: 3 (a data NACK)
    assert wire["present"] == 0, wire


def counts357(v: float) -> int:
    return round(v / G * 51200)


def counts345(v: float) -> int:
    return round(v / (0.0039 * G))


def test_adxl357_fifo_equals_xdata_and_its_counters_hold(sketch: Sketch) -> None:
    want = [counts357(v) for v in POSE["a.0"]]
    i, _ = sketch.read("A357")  # the first report: the FIFO since measuring began
    t0 = None
    for _ in range(12):
        i, t = sketch.read("T", i + 1)
        i, r = sketch.read("A357", i + 1)
        assert r["id"] == 0xED and r["xyz"] == want, r
        assert r["fifo"] == want, f"FIFO samples equal XDATA: {r}"
        assert r["marked"] == r["sets"] and r["empty"] == 1, r  # x marker, then the empty flag
        assert r["st"] & 0x02, f"FIFO_FULL: 75 entries >= the watermark 30: {r}"
        assert not r["st"] & 0x04, f"no overrun while drained: {r}"
        if t0 is None:
            t0, total0 = t["ms"], r["total"]
    # Sets drained between two reports = 125 Hz x the time between them (within one set).
    expected = (t["ms"] - t0) / 1000.0 * ADXL357_ODR_HZ
    assert abs(r["total"] - total0 - expected) <= 2, (r, t, t0, total0)


def test_adxl345_fifo_and_interrupt_sources(sketch: Sketch) -> None:
    want = [counts345(v) for v in POSE["a.1"]]
    i, _ = sketch.read("A345")
    i, t = sketch.read("T", i + 1)
    i, r = sketch.read("A345", i + 1)
    t0, total0 = t["ms"], r["total"]
    for _ in range(8):
        i, t = sketch.read("T", i + 1)
        i, r = sketch.read("A345", i + 1)
        assert r["id"] == 0xE5 and r["fifo"] == want, r
        assert 19 <= r["ent"] <= 21, f"stream mode: 20 entries a report at 100 Hz: {r}"
        assert r["src"] & 0x82 == 0x82, f"DATA_READY and watermark (>= 16): {r}"
        assert not r["src"] & 0x11, f"no overrun, no activity at rest: {r}"
    expected = (t["ms"] - t0) / 1000.0 * ADXL345_ODR_HZ
    assert abs(r["total"] - total0 - expected) <= 2, (r, t)


def test_bno055_fusion_outputs_boot_and_calibration(sketch: Sketch) -> None:
    i, _ = sketch.read("B055")
    for _ in range(20):  # > 3 s of reports: the gyroscope calibrates after ~2 s still
        i, r = sketch.read("B055", i + 1)
    assert r["id"] == 0xA0 and r["mode"] == 0x0C, r
    assert r["boot"] >= 650, f"the BNO055 boots with the board (650 ms of NACKs): {r}"
    heading, roll, pitch = (v / 16.0 for v in r["eul"])  # 16 LSB per degree
    assert min(heading, 360.0 - heading) <= 1.0, r  # absolute: the rig's heading, north
    assert abs(roll - 10.0) <= 1.0 and abs(pitch + 20.0) <= 1.0, r
    w, x, y, z = (v / 16384.0 for v in r["qua"])
    assert abs(w * w + x * x + y * y + z * z - 1.0) < 0.01, r
    # The quaternion's tilt matches the Euler angles: roll = asin(-R20), R20 = 2(xz - wy).
    assert abs(math.degrees(math.asin(-2 * (x * z - w * y))) - 10.0) <= 1.0, r
    for k in range(3):  # gravity and linear acceleration within 0.05 m/s^2 (100 LSB each)
        assert abs(r["grv"][k] / 100.0 - POSE["b.0"][k]) <= 0.05, r
        assert abs(r["lia"][k] / 100.0) <= 0.05, r
    assert (r["calib"] >> 4) & 3 == 3, f"gyroscope calibrated after seconds still: {r}"


def test_moving_bno055_follows_the_turn_and_adxl345_sees_activity(moving: Sketch) -> None:
    i, _ = moving.read("B055")
    activity = 0
    for _ in range(15):
        i, t = moving.read("T", i + 1)
        i, r345 = moving.read("A345", i + 1)
        i, r = moving.read("B055", i + 1)
        activity += bool(r345["src"] & 0x10)
        # Heading turns clockwise-negative: 360 - 20 deg/s x t (millis ~ simulated time).
        truth = (-TURN_DPS * t["ms"] / 1000.0) % 360.0
        heading = r["eul"][0] / 16.0
        err = (heading - truth + 180.0) % 360.0 - 180.0
        assert abs(err) <= 1.0 + TURN_DPS * 0.02, (r, t, truth)  # 1 deg + 20 ms of turn
        assert abs(r["eul"][1]) <= 16 and abs(r["eul"][2]) <= 16, r  # flat: within 1 degree
        assert all(abs(v) <= 5 for v in r["lia"]), r  # no linear acceleration
    assert activity >= 3, f"the shake beyond 1.5 g sets activity in INT_SOURCE: {activity}"


def test_fifos_overrun_when_not_read(sketch: Sketch) -> None:
    i, _ = sketch.read("T", len(sketch.lines))
    sketch.conn.port.write(b"p")  # one second without draining
    i, _ = sketch.read("PAUSE", i)
    i, r357 = sketch.read("A357", i + 1)
    i, r345 = sketch.read("A345", i + 1)
    for _ in range(3):  # a report inside the pause: both full
        i, r357 = sketch.read("A357", i + 1)
        i, r345 = sketch.read("A345", i + 1)
    assert r357["ent"] == 96 and r357["st"] & 0x06 == 0x06, r357  # FIFO_FULL, FIFO_OVR
    assert r345["ent"] == 32 and r345["src"] & 0x01, r345  # stream: full, overrun

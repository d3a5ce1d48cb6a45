"""`jointangle configure`: a rig file and a loop rate given to a board and kept in its EEPROM;
a rate the board cannot hold refused naming the one it can, unless --force."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from jointangle.cli.main import main
from jointangle.device.configure import NOT_MULTIPLEXED, rig_commands
from jointangle.io.rig_file import load_rig
from jointangle.protocol import messages as msgs

RIG = """name = "bench-build"
sample_rate_hz = 200

[links.a]
joint = [0.25, 0.001]
[[links.a.sensors]]
model = "adxl345"
position = [0.03, 0.002]
mux_channel = 0
address = 0x53
range_g = 4
rotation_deg = 90.0
[[links.a.sensors]]
model = "adxl345"
position = [0.12, -0.001]
mux_channel = 0
address = 0x1D
range_g = 4
S = [[1.01, 0.0, 0.0], [0.0, 0.99, 0.0], [0.0, 0.0, 1.0]]
offset = [0.05, -0.02, 0.0]

[links.b]
joint = [0.0, 0.0]
[[links.b.sensors]]
model = "adxl345"
position = [0.05, 0.0]
mux_channel = 1
address = 0x53
range_g = 4
[[links.b.sensors]]
model = "adxl345"
position = [0.15, 0.003]
mux_channel = 1
address = 0x1D
range_g = 4
"""


def write_rig_text(tmp_path: Path) -> Path:
    path = tmp_path / "build.toml"
    path.write_text(RIG)
    return path


def test_a_rig_becomes_set_sensor_set_joint_and_set_calibration_in_board_units(
        tmp_path: Path) -> None:
    cmds = rig_commands(load_rig(write_rig_text(tmp_path)))
    sensors = [c for c in cmds if isinstance(c, msgs.SetSensor)]
    joints = [c for c in cmds if isinstance(c, msgs.SetJoint)]
    cals = [c for c in cmds if isinstance(c, msgs.SetCalibration)]
    assert [type(c) for c in cmds] == [msgs.SetSensor] * 4 + [msgs.SetJoint] * 2 + \
        [msgs.SetCalibration]
    first = sensors[0]
    assert (first.slot, first.count, first.link, first.mux_channel, first.address) == \
        (0, 4, msgs.Link.A, 0, 0x53)
    assert (first.x, first.y, first.range_g) == (30_000, 2_000, 4)  # µm
    assert first.rotation == round(math.pi / 2 * 1e6)  # µrad
    assert [s.link for s in sensors] == [msgs.Link.A, msgs.Link.A, msgs.Link.B, msgs.Link.B]
    assert (joints[0].x, joints[0].y) == (250_000, 1_000)
    assert cals[0].slot == 1 and cals[0].s00 == round(1.01 * 2**24) and cals[0].ox == 50_000
    assert NOT_MULTIPLEXED == 255


def run_json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict:
    capsys.readouterr()
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_configure_saves_the_rig_and_rate_and_a_fresh_start_keeps_them(
        hil_port: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rig, eeprom = write_rig_text(tmp_path), tmp_path / "board.eep"
    url = f"{hil_port}?eeprom={eeprom}"
    doc = run_json(capsys, ["configure", "--port", url, "--rig", str(rig), "--rate", "200",
                            "--save", "--json"])
    assert doc["done"] == ["rig bench-build", "rate 200 Hz", "saved in EEPROM"], doc
    assert doc["forced"] is False
    again = run_json(capsys, ["info", "--port", url, "--json"])  # a new board process
    assert again["sample_rate_hz"] == 200
    assert [(s["link"], s["mux_channel"], s["address"]) for s in again["sensors"]] == \
        [("a", 0, "0x53"), ("a", 0, "0x1D"), ("b", 1, "0x53"), ("b", 1, "0x1D")]


def test_a_rate_the_mega_cannot_hold_is_refused_naming_its_rate_unless_forced(
        capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["configure", "--port", "sim://avr", "--rate", "900"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "holds at most" in err and "--force" in err, err
    doc = run_json(capsys, ["configure", "--port", "sim://avr", "--rate", "900", "--force",
                            "--json"])
    assert doc["forced"] is True and doc["sample_rate_hz"] == 900, doc


def test_configure_with_nothing_to_do_or_a_bad_rate_is_one_line_error(
        capsys: pytest.CaptureFixture[str]) -> None:
    for argv in (["configure", "--port", "sim://native"],
                 ["configure", "--port", "sim://native", "--rate", "5000"],
                 ["configure", "--port", "sim://native", "--force"]):
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and err, (argv, err)

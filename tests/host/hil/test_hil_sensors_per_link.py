"""HIL: a rig with three sensors per link (another geometry than the scenarios': sensors off the
link axis, other spans, other joint positions) end to end on every virtual board — the board's
filter takes 2 to 4 sensors per link (issue 15). Recorded with `record`, checked with `replay
--verify` (firmware vs the host `mirror` within the docs/design.md §5 parity budget) and
`--verify-firmware` (bit for bit against the x86 fixed-point core)."""

from __future__ import annotations

import json
from pathlib import Path
from urllib.parse import urlencode

import pytest

from jointangle.cli.main import main

# Link: joint position, then per sensor (x, y, multiplexer channel, address); all ADXL345 ±4 g.
LINKS = {
    "a": ((0.22, 0.0), ((0.02, 0.004, 0, 0x53), (0.09, -0.003, 0, 0x1D), (0.16, 0.0, 1, 0x53))),
    "b": ((0.0, 0.0), ((0.04, 0.0, 2, 0x53), (0.13, 0.005, 2, 0x1D), (0.21, -0.002, 3, 0x53))),
}


def rig_text(rate_hz: int) -> str:
    out = [f'name = "three-per-link"\nsample_rate_hz = {rate_hz}\n']
    for name, (joint, sensors) in LINKS.items():
        out.append(f"[links.{name}]\njoint = [{joint[0]}, {joint[1]}]\n")
        for x, y, channel, address in sensors:
            out.append(f'[[links.{name}.sensors]]\nmodel = "adxl345"\nposition = [{x}, {y}]\n'
                       f"mux_channel = {channel}\naddress = {address:#x}\nrange_g = 4\n")
    return "\n".join(out)


RATE_HZ = 200
SECONDS = 4.0


def run_json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict:
    capsys.readouterr()
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


@pytest.mark.parametrize("board", ["sim://native", "sim://avr"])
def test_three_sensors_per_link_record_and_verify(
        board: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Both virtual boards, whatever $JOINTANGLE_HIL_TARGETS says: the AVR image's own filter
    (4 slots a link on the Mega) is what this checks."""
    rig, sim_rig, motion = tmp_path / "rig3.toml", tmp_path / "sim.toml", tmp_path / "m.csv"
    rec = tmp_path / "run.jrec"
    rig.write_text(rig_text(RATE_HZ))
    assert main(["simulate", "--scenario", "gravity-fast-periodic", "--rig", str(rig),
                 "--rate", str(RATE_HZ), "--seconds", "8", "--seed", "4", "--out", str(motion),
                 "--rig-out", str(sim_rig)]) == 0
    url = f"{board}?{urlencode({'motion': motion, 'rig': sim_rig, 'rate': RATE_HZ}, safe='/')}"
    assert main(["record", "--port", url, "--rig", str(sim_rig), "--seconds", str(SECONDS),
                 "--out", str(rec)]) == 0
    rep = run_json(capsys, ["replay", str(rec), "--verify", "--json"])
    assert rep["frames_lost"] == 0 and rep["crc_errors"] == 0, rep
    assert rep["verified_frames"] >= 0.9 * SECONDS * RATE_HZ, rep
    assert rep["max_abs_dtheta_deg"] <= 1.0, rep  # docs/design.md §5: before 2 s
    assert rep["steady_max_abs_dtheta_deg"] <= 0.05 and rep["steady_rms_dtheta_deg"] <= 0.01, rep
    fw = run_json(capsys, ["replay", str(rec), "--verify-firmware", "--json"])
    assert fw["firmware_frames_compared"] >= 0.9 * SECONDS * RATE_HZ, fw
    assert fw["firmware_mismatches"] == 0, fw

"""`sim://avr`: the launcher of the AVR virtual board (ja_avr_board + an AVR image).

The end-to-end test runs the board's own test image (firmware/sim/avr_board/test_image), which
streams text lines rather than the protocol: it checks the launcher starts the board on a
scenario's rig and motion, connects to the pty it announces and stops it on close.
"""

from __future__ import annotations

import re
import subprocess
import time
from pathlib import Path

import pytest

from jointangle.boards.launchers import AvrBoardLauncher
from jointangle.boards.options import LaunchOptions
from jointangle.errors import InputError
from jointangle.transport import open_port


def test_missing_board_names_the_cmake_target(tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("JOINTANGLE_AVR_BOARD", raising=False)
    with pytest.raises(InputError, match=r"ja_avr_board.*not built"):
        AvrBoardLauncher(root=tmp_path).start(LaunchOptions(build=False))


def test_missing_image_names_its_cmake_target(tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    board = tmp_path / "build" / "x" / "firmware" / "sim" / "ja_avr_board"
    board.parent.mkdir(parents=True)
    board.write_text("")
    monkeypatch.delenv("JOINTANGLE_AVR_BOARD", raising=False)
    monkeypatch.delenv("JOINTANGLE_AVR_IMAGE", raising=False)
    launcher = AvrBoardLauncher(root=tmp_path)
    assert launcher.find_binary() == board
    with pytest.raises(InputError, match=r"jointangle_mega2560\.elf.*`avr_images`.*not built"):
        launcher.start(LaunchOptions(build=False))
    monkeypatch.setenv("JOINTANGLE_AVR_IMAGE", str(tmp_path / "nope.elf"))
    with pytest.raises(InputError, match="JOINTANGLE_AVR_IMAGE"):
        launcher.find_image()


def _test_image(board: Path) -> Path:
    """The test image next to the board (same build tree), built if missing."""
    image = board.parent / "avr_board_test_image.elf"
    if not image.is_file():
        tree = board.parents[2]
        subprocess.run(["cmake", "--build", str(tree), "--target", "ja_avr_board_test_image"],
                       check=True, capture_output=True)
    return image


def test_sim_avr_starts_the_board_on_a_scenario_and_connects(
        monkeypatch: pytest.MonkeyPatch) -> None:
    board = AvrBoardLauncher().find_binary(build=True)
    monkeypatch.setenv("JOINTANGLE_AVR_BOARD", str(board))
    monkeypatch.setenv("JOINTANGLE_AVR_IMAGE", str(_test_image(board)))
    conn = open_port("sim://avr?fast=1&seconds=2",
                     launch=LaunchOptions(scenario="gravity-slow-periodic", seconds=2))
    try:
        data = b""
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and data.count(b"\nD ") < 50:
            data += conn.port.read(4096)
        # (The boot line went before the host opened the pty: opening flushes input.) The
        # image configured the ADXL345 a.0 through the mux and streams its counts: gravity
        # (the gravity rig's hinge axis is horizontal) gives |a| ≈ 1 g = 256 LSB at ±2 g.
        rows = [tuple(int(v, 16) for v in m.groups())
                for m in re.finditer(rb"\nD ([0-9a-f]{4}) ([0-9a-f]{4}) ([0-9a-f]{4})", data)]
        assert len(rows) >= 50
        signed = [[v - 65536 if v >= 32768 else v for v in r] for r in rows]
        norms = [sum(v * v for v in r) ** 0.5 for r in signed]
        assert all(200 < n < 320 for n in norms), norms[:5]
        assert conn.rig_text is not None and "adxl345" in conn.rig_text
        process = conn.board.process  # type: ignore[union-attr]
    finally:
        conn.close()
    assert process.poll() == 0


def test_record_on_the_real_avr_image_loses_nothing_and_verifies(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 6 item 6: `record --port sim://avr --seconds 2` on the real image (simulated motion,
    real time): zero frames lost, and `replay --verify` within the parity bounds of
    docs/design.md §5 (|Δθ| ≤ 1° in the first 2 s of the filter, 0.05° / RMS 0.01° after)."""
    import json

    from jointangle.cli.main import main

    launcher = AvrBoardLauncher()
    monkeypatch.setenv("JOINTANGLE_AVR_BOARD", str(launcher.find_binary(build=True)))
    monkeypatch.setenv("JOINTANGLE_AVR_IMAGE", str(launcher.find_image(build=True)))
    out = tmp_path / "avr.jrec"
    capsys.readouterr()
    assert main(["record", "--port", "sim://avr", "--seconds", "2", "--out", str(out),
                 "--restart-filter", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["complete"] and rec["frames_lost"] == 0 and rec["crc_errors"] == 0, rec
    assert rec["samples"] > 100, rec
    assert main(["replay", str(out), "--verify", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["frames_lost"] == 0 and rep["verified_frames"] >= rec["samples"] - 5, rep
    assert rep["max_abs_dtheta_deg"] <= 1.0, rep
    if rep["steady_max_abs_dtheta_deg"] is not None:
        assert rep["steady_max_abs_dtheta_deg"] <= 0.05 and rep["steady_rms_dtheta_deg"] <= 0.01

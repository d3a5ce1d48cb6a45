"""`jointangle flash`: the avrdude command, board detection by USB VID:PID and refusals."""

from __future__ import annotations

import os
import shlex
import stat
from dataclasses import dataclass
from pathlib import Path

import pytest

from jointangle.cli import flash
from jointangle.cli.main import main


@dataclass
class Info:
    device: str
    vid: int | None
    pid: int | None
    serial_number: str | None = None


MEGA = Info("/dev/ttyACM3", 0x2341, 0x0042, "7573")  # Arduino Mega 2560 R3
MOUSE = Info("/dev/ttyACM0", 0x046D, 0xC52B)  # a USB receiver that is no board
PLAIN = Info("/dev/ttyS0", None, None)


@pytest.fixture
def image(tmp_path: Path) -> Path:
    path = tmp_path / "jointangle_mega2560.hex"
    path.write_text(":00000001FF\n")
    return path


def ports(monkeypatch: pytest.MonkeyPatch, *infos: Info) -> None:
    monkeypatch.setattr(flash, "list_serial_ports", lambda: list(infos))


def test_dry_run_prints_the_exact_avrdude_command_for_the_detected_mega(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], image: Path) -> None:
    ports(monkeypatch, MOUSE, PLAIN, MEGA)
    assert main(["flash", "--dry-run", "--hex", str(image)]) == 0
    out = capsys.readouterr().out.strip()
    assert out == (f"avrdude -p atmega2560 -c wiring -P /dev/ttyACM3 -b 115200 -D "
                   f"-U flash:w:{image}:i")


def test_dry_run_without_a_board_still_prints_the_command(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], image: Path) -> None:
    ports(monkeypatch, MOUSE)
    assert main(["flash", "--dry-run", "--hex", str(image)]) == 0
    cap = capsys.readouterr()
    assert cap.out.strip() == (f"avrdude -p atmega2560 -c wiring -P PORT -b 115200 -D "
                               f"-U flash:w:{image}:i")
    assert "no Arduino Mega found" in cap.err


def test_without_a_board_flash_fails_with_status_2(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], image: Path) -> None:
    ports(monkeypatch, MOUSE, PLAIN)
    assert main(["flash", "--hex", str(image)]) == 2
    err = capsys.readouterr().err
    assert "no Arduino Mega 2560 found" in err and "2341:0042" in err and "--port" in err


def test_a_port_that_is_not_a_mega_is_refused_unless_forced(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], image: Path) -> None:
    ports(monkeypatch, MOUSE, MEGA)
    assert main(["flash", "--port", "/dev/ttyACM0", "--dry-run", "--hex", str(image)]) == 2
    assert "USB 046D:C52B" in capsys.readouterr().err
    assert main(["flash", "--port", "/dev/nonexistent", "--hex", str(image)]) == 2
    assert "not a serial port on this machine" in capsys.readouterr().err
    assert main(["flash", "--port", "/dev/ttyACM0", "--dry-run", "--force",
                 "--hex", str(image)]) == 0
    assert " -P /dev/ttyACM0 " in capsys.readouterr().out


def test_a_missing_hex_file_is_an_input_error(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        tmp_path: Path) -> None:
    ports(monkeypatch, MEGA)
    assert main(["flash", "--hex", str(tmp_path / "nope.hex")]) == 2
    assert "nope.hex" in capsys.readouterr().err


def test_flash_runs_avrdude_with_those_arguments(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], image: Path,
        tmp_path: Path) -> None:
    # A stand-in avrdude on PATH records its arguments; status 0 -> flash succeeds.
    bindir = tmp_path / "bin"
    bindir.mkdir()
    log = tmp_path / "args.txt"
    fake = bindir / "avrdude"
    fake.write_text(f"#!/bin/sh\nprintf '%s\\n' \"$@\" > {log}\nexit ${{FAKE_STATUS:-0}}\n")
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setenv("PATH", f"{bindir}{os.pathsep}{os.environ['PATH']}")
    ports(monkeypatch, MEGA)
    assert main(["flash", "--hex", str(image)]) == 0
    assert log.read_text().split("\n")[:-1] == [
        "-p", "atmega2560", "-c", "wiring", "-P", "/dev/ttyACM3", "-b", "115200", "-D",
        "-U", f"flash:w:{image}:i"]
    assert "Arduino Mega 2560 R3" in capsys.readouterr().err
    monkeypatch.setenv("FAKE_STATUS", "1")
    assert main(["flash", "--hex", str(image)]) == 1
    assert "avrdude failed with status 1" in capsys.readouterr().err


def test_without_a_built_image_or_build_tree_the_target_is_named(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        tmp_path: Path) -> None:
    monkeypatch.setattr(flash, "REPO_ROOT", tmp_path)
    monkeypatch.delenv(flash.HEX_ENV, raising=False)
    ports(monkeypatch, MEGA)
    assert main(["flash"]) == 2
    err = capsys.readouterr().err
    assert "jointangle_mega2560.hex is not built" in err and "avr_images" in err


def test_dry_run_quotes_a_path_with_spaces(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        tmp_path: Path) -> None:
    spaced = tmp_path / "my image.hex"
    spaced.write_text(":00000001FF\n")
    ports(monkeypatch, MEGA)
    assert main(["flash", "--dry-run", "--hex", str(spaced)]) == 0
    out = capsys.readouterr().out.strip()
    assert out.endswith(f"-U 'flash:w:{spaced}:i'")
    assert shlex.split(out)[-1] == f"flash:w:{spaced}:i"  # pastes into a shell as one argument


def test_a_file_that_is_not_intel_hex_is_refused(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        tmp_path: Path) -> None:
    rig = tmp_path / "rig.toml"
    rig.write_text('name = "x"\n')
    ports(monkeypatch, MEGA)
    assert main(["flash", "--dry-run", "--hex", str(rig)]) == 2
    err = capsys.readouterr().err
    assert "rig.toml" in err and "not an Intel HEX image" in err

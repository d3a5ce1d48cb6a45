"""`jointangle flash --board pico`: a UF2 copied to the RPI-RP2 drive, found under mount roots
the tests point at tmp_path; the dry run, the missing drive, the missing image, the refusals."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from jointangle.cli import flash
from jointangle.cli.main import main
from jointangle.flash import rp2_drive, uf2

INFO = "UF2 Bootloader v3.0\nModel: Raspberry Pi RP2\nBoard-ID: RPI-RP2\n"
IMAGE = uf2.encode_uf2({0x10000000: bytes(range(256)), 0x10000100: bytes(256)})


def mount(root: Path, name: str, info: str | None) -> Path:
    drive = root / "user" / name
    drive.mkdir(parents=True)
    if info is not None:
        (drive / "INFO_UF2.TXT").write_text(info)
    return drive


@pytest.fixture
def media(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A /media stand-in holding a USB stick, a SAMD21 UF2 drive and no Pico yet."""
    root = tmp_path / "media"
    mount(root, "STICK", None)
    mount(root, "FEATHERBOOT", "UF2 Bootloader v3.6\nBoard-ID: SAMD21G18A-Feather-v0\n")
    monkeypatch.setattr(rp2_drive, "mount_patterns", lambda: (str(root / "*" / "*"),))
    return root


@pytest.fixture
def image(tmp_path: Path) -> Path:
    path = tmp_path / "firmware.uf2"
    path.write_bytes(IMAGE)
    return path


def files(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir())


def test_dry_run_prints_the_image_and_the_drive_and_copies_nothing(
        media: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    drive = mount(media, "RPI-RP2", INFO)
    assert main(["flash", "--board", "pico", "--dry-run", str(image)]) == 0
    out = capsys.readouterr().out.strip()
    assert out == (f"would copy {image} (UF2, 2 UF2 blocks, flash 0x10000000..0x10000200) "
                   f"to {drive / 'firmware.uf2'}")
    assert files(drive) == ["INFO_UF2.TXT"]


def test_flash_copies_the_uf2_onto_the_drive(
        media: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    drive = mount(media, "RPI-RP2", INFO)
    assert main(["flash", "--board", "pico", str(image)]) == 0
    assert files(drive) == ["INFO_UF2.TXT", "firmware.uf2"]
    assert (drive / "firmware.uf2").read_bytes() == IMAGE
    err = capsys.readouterr().err
    assert f"wrote {drive / 'firmware.uf2'}" in err and "restarts" in err
    assert files(media / "user" / "STICK") == []  # nothing written anywhere else


def test_without_a_drive_flash_fails_in_one_line_saying_what_to_do(
        media: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["flash", "--board", "pico", str(image)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "no RPI-RP2 drive found" in err and str(media / "*" / "*") in err
    assert "hold BOOTSEL while plugging the Pico in" in err


def test_a_dry_run_without_a_drive_still_shows_the_plan(
        media: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["flash", "--board", "pico", "--dry-run", str(image)]) == 0
    cap = capsys.readouterr()
    assert cap.out.strip().endswith("to DRIVE/firmware.uf2")
    assert "hold BOOTSEL" in cap.err


def test_drive_option_must_name_a_pico_drive(
        media: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    feather = media / "user" / "FEATHERBOOT"
    assert main(["flash", "--board", "pico", "--drive", str(feather), str(image)]) == 2
    assert "Board-ID: SAMD21G18A-Feather-v0" in capsys.readouterr().err
    assert files(feather) == ["INFO_UF2.TXT"]
    stick = media / "user" / "STICK"
    assert main(["flash", "--board", "pico", "--drive", str(stick), str(image)]) == 2
    assert "no INFO_UF2.TXT" in capsys.readouterr().err
    pico = mount(media, "elsewhere", INFO.lower().replace("board-id: rpi-rp2", "Board-ID: RPI-RP2"))
    assert main(["flash", "--board", "pico", "--drive", str(pico), str(image)]) == 0
    assert (pico / "firmware.uf2").read_bytes() == IMAGE


def test_two_pico_drives_are_not_guessed_between(
        media: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    mount(media, "RPI-RP2", INFO)
    mount(media, "RPI-RP21", INFO)
    assert main(["flash", "--board", "pico", str(image)]) == 2
    assert "2 RPI-RP2 drives found" in capsys.readouterr().err


def test_a_corrupt_uf2_is_refused_naming_the_block_before_any_copy(
        media: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    drive = mount(media, "RPI-RP2", INFO)
    bad = tmp_path / "bad.uf2"
    damaged = bytearray(IMAGE)
    struct.pack_into("<I", damaged, 512 + 28, 0)  # block 1's familyID
    bad.write_bytes(damaged)
    assert main(["flash", "--board", "pico", str(bad)]) == 2
    assert "bad.uf2: block 1 (bytes 512..1024): family ID 0x00000000" in capsys.readouterr().err
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    assert main(["flash", "--board", "pico", str(text)]) == 2
    assert "neither a UF2 nor an ELF image" in capsys.readouterr().err
    assert files(drive) == ["INFO_UF2.TXT"]


def test_without_an_image_the_pico_build_output_is_used_or_named(
        media: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(flash, "REPO_ROOT", tmp_path)
    monkeypatch.delenv(flash.PICO_ENV, raising=False)
    monkeypatch.delenv("JOINTANGLE_HIDE_BUILT", raising=False)
    assert main(["flash", "--board", "pico", "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "jointangle_pico.uf2 is not built" in err
    assert str(tmp_path / "build/native/pico/jointangle_pico.uf2") in err
    assert "IMAGE.uf2" in err
    built = tmp_path / "build" / "native" / "pico" / "jointangle_pico.uf2"
    built.parent.mkdir(parents=True)
    built.write_bytes(IMAGE)
    drive = mount(media, "RPI-RP2", INFO)
    assert main(["flash", "--board", "pico", "--dry-run"]) == 0
    assert f"would copy {built} " in capsys.readouterr().out
    assert main(["flash", "--board", "pico"]) == 0
    assert (drive / "jointangle_pico.uf2").read_bytes() == IMAGE


def test_options_of_the_other_board_are_refused(
        media: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["flash", "--board", "pico", "--hex", str(image), "--dry-run"]) == 2
    assert "field '--hex'" in capsys.readouterr().err
    assert main(["flash", "--board", "pico", "--port", "/dev/ttyACM0", str(image)]) == 2
    assert "field '--port'" in capsys.readouterr().err
    assert main(["flash", "--dry-run", str(image)]) == 2  # the Mega, the default board
    assert "the Mega takes its image as --hex" in capsys.readouterr().err
    assert main(["flash", "--drive", "/media", "--dry-run"]) == 2
    assert "field '--drive'" in capsys.readouterr().err
    assert main(["flash", "--board", "uno"]) == 2
    err = capsys.readouterr().err
    assert "field '--board'" in err and "'uno'" in err and "mega" in err and "pico" in err


def test_help_names_both_boards(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as done:
        main(["flash", "--help"])
    assert done.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--board {mega,pico}" in text
    assert "Arduino Mega 2560" in text and "avrdude" in text
    assert "Raspberry Pi Pico" in text and "RPI-RP2" in text and "BOOTSEL" in text
    assert "IMAGE" in text and "--drive" in text

"""`sim://pico`: the launcher of the Pico virtual board (node + firmware/sim/pico_board + the
RP2040 image): what it needs is named in one line when missing."""

from __future__ import annotations

from pathlib import Path

import pytest

from jointangle.boards import launchers
from jointangle.boards.launchers import PicoBoardLauncher
from jointangle.boards.options import LaunchOptions
from jointangle.errors import InputError


def test_missing_node_is_one_line_naming_setup(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(launchers.shutil, "which", lambda _: None)
    with pytest.raises(InputError, match=r"needs Node\.js.*scripts/setup\.sh") as e:
        PicoBoardLauncher().start(LaunchOptions(build=False))
    assert "\n" not in str(e.value)


def test_missing_npm_packages_name_setup(tmp_path: Path) -> None:
    harness = tmp_path / "pico_board" / "pico_board.mjs"
    harness.parent.mkdir()
    harness.write_text("")
    with pytest.raises(InputError, match=r"npm packages.*not installed.*scripts/setup\.sh"):
        PicoBoardLauncher(harness=harness).start(LaunchOptions(build=False))


def test_missing_parts_name_their_cmake_targets(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    for env in ("JOINTANGLE_SIM_BOARD_LIB", "JOINTANGLE_PICO_BOOTROM", "JOINTANGLE_PICO_IMAGE"):
        monkeypatch.delenv(env, raising=False)
    launcher = PicoBoardLauncher(root=tmp_path)
    with pytest.raises(InputError, match=r"libja_sim_board\.so.*`ja_sim_board`.*not built"):
        launcher.start(LaunchOptions(build=False))
    lib = tmp_path / "build" / "x" / "firmware" / "sim" / "libja_sim_board.so"
    lib.parent.mkdir(parents=True)
    lib.write_text("")
    with pytest.raises(InputError, match=r"pico_bootrom\.bin.*`ja_pico_bootrom`"):
        launcher.start(LaunchOptions(build=False))
    (lib.parent / "pico_bootrom.bin").write_text("")
    with pytest.raises(InputError, match=r"jointangle_pico\.elf.*`pico_images`"):
        launcher.start(LaunchOptions(build=False))


def test_elf_is_the_avr_boards_option() -> None:
    with pytest.raises(InputError, match="sim://avr"):
        PicoBoardLauncher().start(LaunchOptions(build=False, elf_path=Path("x.elf")))

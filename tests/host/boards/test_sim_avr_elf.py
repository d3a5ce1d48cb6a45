"""`sim://avr?elf=IMAGE.elf` (issue 22 item 5): the query names a user's image; the AVR launcher
passes it as `--elf` (the board's own option), without `--baud` unless one was given; the native
board refuses it. `cold=1` powers the parts up with the board (`--cold-start`, both boards);
`stretch=ADDR=US` is the AVR board's clock stretching. The sketch run itself:
tests/host/hil/test_hil_user_sketch.py."""

from __future__ import annotations

from pathlib import Path

import pytest

from jointangle.boards.launchers import AvrBoardLauncher, NativeBoardLauncher
from jointangle.boards.options import LaunchOptions, apply_sim_query, board_args, split_sim_url
from jointangle.errors import InputError


def test_elf_query_sets_the_image() -> None:
    url = "sim://avr?elf=~/sketch.elf&baud=115200"
    name, pairs = split_sim_url(url)
    opts = apply_sim_query(LaunchOptions(), pairs, url)
    assert name == "avr"
    assert opts.elf_path == Path("~/sketch.elf").expanduser()
    assert opts.baud == 115200
    with pytest.raises(InputError, match="needs a file name"):
        apply_sim_query(LaunchOptions(), [("elf", "")], "sim://avr?elf=")


def test_cold_and_stretch_queries() -> None:
    url = "sim://avr?cold=1&stretch=0x28=400&stretch=41=5"
    opts = apply_sim_query(LaunchOptions(), split_sim_url(url)[1], url)
    assert opts.cold_start and opts.clock_stretch == ((0x28, 400), (41, 5))
    assert "--cold-start" in board_args(opts)
    for bad in ("0x28", "0x80=1", "x=1", "0x28=-1"):
        with pytest.raises(InputError, match="stretch"):
            apply_sim_query(LaunchOptions(), [("stretch", bad)], "sim://avr")


def test_native_board_refuses_an_elf(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="sim://avr"):
        NativeBoardLauncher().start(LaunchOptions(elf_path=tmp_path / "x.elf", build=False))
    with pytest.raises(InputError, match="sim://avr"):
        NativeBoardLauncher().start(LaunchOptions(clock_stretch=((0x28, 1),), build=False))


def test_avr_board_is_started_with_the_users_image(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    elf = tmp_path / "sketch.elf"
    elf.write_bytes(b"\x7fELF")
    seen: list[list[str]] = []

    def fake_start(argv: list[str], options: LaunchOptions, rig_text: str | None = None,
                   workdir: Path | None = None) -> object:
        seen.append(list(argv))
        return object()

    monkeypatch.setattr("jointangle.boards.launchers.start_process_board", fake_start)
    launcher = AvrBoardLauncher()
    monkeypatch.setattr(AvrBoardLauncher, "find_binary", lambda self, build=False: tmp_path / "b")
    launcher.start(LaunchOptions(elf_path=elf, seconds=0.5, build=False))
    assert seen[-1][-2:] == ["--elf", str(elf)] and "--baud" not in seen[-1], seen[-1]
    launcher.start(LaunchOptions(elf_path=elf, seconds=0.5, baud=115200, build=False))
    assert seen[-1][seen[-1].index("--baud") + 1] == "115200", seen[-1]
    launcher.start(LaunchOptions(elf_path=elf, seconds=0.5, build=False,
                                 clock_stretch=((0x28, 400),)))
    assert seen[-1][seen[-1].index("--clock-stretch") + 1] == "0x28=400", seen[-1]
    with pytest.raises(InputError, match="not a file"):
        launcher.start(LaunchOptions(elf_path=tmp_path / "missing.elf", build=False))

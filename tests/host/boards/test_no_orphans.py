"""No orphans (issue 16 item 5): a virtual board started by a host exits within a second when
that host dies by any signal, SIGKILL included, and its work folder goes with it (or at the next
start, when even the board's guard was killed)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from jointangle.boards.launchers import AvrBoardLauncher, NativeBoardLauncher
from jointangle.boards.process import OWNER_FILE, remove_orphaned_workdirs
from jointangle.errors import InputError


def _processes_mentioning(text: str) -> list[int]:
    """Live (not zombie) processes whose command line mentions `text`."""
    out = []
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            cmd = Path(f"/proc/{d}/cmdline").read_bytes()
            state = Path(f"/proc/{d}/stat").read_text().rsplit(")", 1)[-1].split()[0]
        except OSError:
            continue
        if text.encode() in cmd and state != "Z":
            out.append(int(d))
    return out


def _board_urls() -> list[str]:
    urls = ["sim://native"]
    try:
        AvrBoardLauncher().find_binary(build=False)
        AvrBoardLauncher().find_image(build=False)
        urls.append("sim://avr")
    except InputError:  # not built here: the native board is enough
        pass
    return urls


@pytest.mark.parametrize("url", _board_urls())
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGSEGV, signal.SIGTERM],
                         ids=["SIGKILL", "SIGSEGV", "SIGTERM"])
def test_the_board_goes_with_its_host(url: str, sig: signal.Signals, tmp_path: Path) -> None:
    NativeBoardLauncher().find_binary(build=False)  # fails with how to build it
    env = {**os.environ, "TMPDIR": str(tmp_path)}  # the board's work folder lands here
    out = tmp_path / "run.jrec"
    host = subprocess.Popen([sys.executable, "-m", "jointangle", "record", "--port",
                             f"{url}?fast=1&seconds=5", "--seconds", "120", "--out", str(out)],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60
        while not (out.exists() and out.stat().st_size > 4096):  # recording: the board runs
            assert host.poll() is None, host.communicate()[1].decode()[-500:]
            assert time.monotonic() < deadline
            time.sleep(0.05)
        (workdir,) = tmp_path.glob("jointangle-*")
        board = _processes_mentioning(str(workdir))
        assert len(board) == 2  # the guard and the board
        host.send_signal(sig)
        t0 = time.monotonic()
        while (_processes_mentioning(str(workdir)) or workdir.exists()) \
                and time.monotonic() - t0 < 3.0:
            time.sleep(0.01)
        took = time.monotonic() - t0
        assert not _processes_mentioning(str(workdir)), "the board outlived its host"
        assert not workdir.exists(), "its folder was left behind"
        assert took < 1.0, took
    finally:
        if host.poll() is None:
            host.kill()
        host.wait()
        for pid in _processes_mentioning(str(tmp_path)):
            os.kill(pid, signal.SIGKILL)


def test_folders_of_dead_hosts_are_removed_at_the_next_start(tmp_path: Path) -> None:
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    orphan = tmp_path / "jointangle-native-orphan"
    mine = tmp_path / "jointangle-native-mine"
    foreign = tmp_path / "jointangle-native-nofile"
    for d, pid in ((orphan, dead.pid), (mine, os.getppid())):
        d.mkdir()
        (d / OWNER_FILE).write_text(f"{pid}\n")
    foreign.mkdir()
    assert remove_orphaned_workdirs(tmp_path, "jointangle-native-") == [orphan]
    assert not orphan.exists() and mine.exists() and foreign.exists()

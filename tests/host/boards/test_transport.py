"""Transports: USB detection, URL resolution, the table of virtual-board launchers."""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from jointangle.boards.launchers import NativeBoardLauncher
from jointangle.boards.options import LaunchOptions, apply_sim_query, board_args, split_sim_url
from jointangle.boards.process import ProcessBoard, RunningBoard, start_process_board
from jointangle.errors import InputError
from jointangle.transport import DEFAULT_SIM, detect_boards, open_port, resolve_url


@dataclass
class Info:
    device: str
    vid: int | None
    pid: int | None
    serial_number: str | None = None


PORTS = [
    Info("/dev/ttyUSB0", 0x1A86, 0x7523),  # CH340
    Info("/dev/ttyS0", None, None),  # a plain UART: no USB ids
    Info("/dev/ttyACM1", 0x2341, 0x0042, "7573"),  # Mega 2560 R3
    Info("/dev/ttyACM0", 0x046D, 0xC52B),  # a mouse receiver: not ours
]


def test_detect_boards_by_vid_pid_arduino_first() -> None:
    found = detect_boards(lambda: PORTS)
    assert [d.device for d in found] == ["/dev/ttyACM1", "/dev/ttyUSB0"]
    assert "Mega 2560" in found[0].what and found[0].serial_number == "7573"
    assert "CH340" in found[1].what


def test_default_port_is_the_board_else_the_native_virtual_board() -> None:
    assert resolve_url(None, lambda: detect_boards(lambda: PORTS))[0] == "/dev/ttyACM1"
    url, what = resolve_url(None, lambda: [])
    assert url == DEFAULT_SIM == "sim://native" and "virtual" in what
    assert resolve_url("loop://", lambda: [])[0] == "loop://"


def test_sim_native_without_the_board_names_the_missing_target(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("JOINTANGLE_NATIVE_BOARD", raising=False)
    launchers = {"native": NativeBoardLauncher(root=tmp_path)}
    with pytest.raises(InputError, match=r"ja_native_board.*not built"):
        open_port("sim://native", launchers=launchers)
    with pytest.raises(InputError, match=r"unknown virtual board 'sim://nope'.*sim://native"):
        open_port("sim://nope", launchers=launchers)


def test_native_launcher_env_pointing_nowhere(tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("JOINTANGLE_NATIVE_BOARD", str(tmp_path / "missing"))
    with pytest.raises(InputError, match="JOINTANGLE_NATIVE_BOARD"):
        NativeBoardLauncher(root=tmp_path).find_binary()


def test_pyserial_urls_open_as_is() -> None:
    with open_port("loop://", detect=lambda: []) as conn:
        conn.port.write(b"\x01\x02\x00")
        assert conn.port.read(3) == b"\x01\x02\x00"
        assert conn.board is None
    with pytest.raises(InputError, match="cannot open /nonexistent/tty"):
        open_port("/nonexistent/tty")


# A stand-in board process honouring the launcher contract: open a pty, print `PTY <path>`,
# echo bytes back until SIGTERM.
BOARD_SCRIPT = """
import os, sys, tty, signal
m, s = os.openpty(); tty.setraw(s)
signal.signal(signal.SIGTERM, lambda *a: sys.exit(0))
print("starting", flush=True)
print("PTY " + os.ttyname(s), flush=True)
while True:
    os.write(m, os.read(m, 100))
"""


@dataclass(frozen=True)
class ScriptLauncher:
    script: str
    name: str = "script"
    description: str = "a test board"

    def start(self, options: LaunchOptions) -> RunningBoard:
        return start_process_board([sys.executable, "-c", self.script], options, "name = 'x'")


def test_launcher_contract_start_connect_stop() -> None:
    launchers = {"script": ScriptLauncher(BOARD_SCRIPT)}
    conn = open_port("sim://script", launchers=launchers, launch=LaunchOptions(start_timeout_s=10))
    board = conn.board
    assert board is not None and board.port_path.startswith("/dev/pts/")
    assert conn.rig_text == "name = 'x'"
    conn.port.write(b"ping")
    got = b""
    for _ in range(50):
        got += conn.port.read(4)
        if got == b"ping":
            break
    assert got == b"ping"
    conn.close()
    proc = board.process  # type: ignore[attr-defined]
    assert proc.poll() == 0  # stopped cleanly by SIGTERM


def test_launcher_reports_a_board_that_dies() -> None:
    launchers = {"bad": ScriptLauncher("import sys; sys.stderr.write('no sensors'); sys.exit(3)")}
    with pytest.raises(InputError, match=r"exited with status 3.*no sensors"):
        open_port("sim://bad", launchers=launchers, launch=LaunchOptions(start_timeout_s=10))


# A stand-in for the native board binary: checks the arguments of the launcher contract (rig
# file, motion CSV with the accelerations header, baud), then serves an echo pty.
NATIVE_STANDIN = """#!{python}
import os, sys, tty, signal
args = sys.argv[1:]
rig, motion = args[args.index("--rig") + 1], args[args.index("--motion") + 1]
assert open(rig).read().count("[[links.") == 4, "rig"
assert open(motion).readline().startswith("t,a.0.x,a.0.y,a.0.z,"), "motion header"
assert int(args[args.index("--baud") + 1]) == int(os.environ.get("WANT_BAUD", "500000"))
assert args[args.index("--baud") + 2:] == os.environ.get("WANT_ARGS", "--loop-motion").split()
m, s = os.openpty(); tty.setraw(s)
signal.signal(signal.SIGTERM, lambda *a: sys.exit(0))
print("PTY " + os.ttyname(s), flush=True)
while True:
    os.write(m, os.read(m, 100))
"""


def test_native_launcher_contract(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    exe = tmp_path / "ja_native_board"
    exe.write_text(NATIVE_STANDIN.replace("{python}", sys.executable))
    exe.chmod(0o755)
    monkeypatch.setenv("JOINTANGLE_NATIVE_BOARD", str(exe))
    opts = LaunchOptions(seconds=2.0, start_timeout_s=20)
    with open_port("sim://native", launch=opts, detect=lambda: []) as conn:
        board = conn.board
        assert board is not None and conn.url == "sim://native"
        assert conn.rig_text is not None and "gravity" in conn.rig_text
        workdir = board.workdir  # type: ignore[attr-defined]
        assert (workdir / "motion.csv").is_file()
        conn.port.write(b"abc")
        got = b""
        for _ in range(50):
            got += conn.port.read(3)
            if len(got) >= 3:
                break
        assert got == b"abc"
    assert board.process.poll() == 0  # type: ignore[attr-defined]
    assert not workdir.exists()  # the board's files go with it


def test_sim_url_query_sets_the_launch_options(tmp_path: Path) -> None:
    url = ("sim://native?fast=1&fault=a.0:nack@2-4&fault=b.1:frozen=1@0.5&baud=115200"
           f"&eeprom={tmp_path}/e.bin&seconds=8&loop=0&disconnect=1.5&reconnect=0.2&seed=3")
    name, pairs = split_sim_url(url)
    assert name == "native" and pairs[1] == ("fault", "a.0:nack@2-4")
    o = apply_sim_query(LaunchOptions(), pairs, url)
    assert (not o.realtime, o.baud, o.seconds, o.loop, o.seed) == (True, 115200, 8.0, False, 3)
    assert o.faults == ("a.0:nack@2-4", "b.1:frozen=1@0.5") and o.eeprom_path == tmp_path / "e.bin"
    assert board_args(o) == ["--fast", "--eeprom", f"{tmp_path}/e.bin", "--fault",
                             "a.0:nack@2-4", "--fault", "b.1:frozen=1@0.5",
                             "--disconnect-after", "1.5", "--reconnect-after", "0.2"]
    assert board_args(LaunchOptions()) == ["--loop-motion"]


@pytest.mark.parametrize(("url", "message"), [
    ("sim://native?speed=2", "unknown option 'speed'; sim:// options: fast, fault"),
    ("sim://native?fault=a.0:nak@2", "fault='a.0:nak@2': expected SENSOR:KIND"),
    ("sim://native?fault=a.0:nack@4-2", "with END > START"),
    ("sim://native?baud=fast", "baud='fast': not a number"),
    ("sim://native?fast=maybe", "expected 1 or 0"),
    ("sim://native?motion=x.csv", "motion= needs the rig"),
    ("sim://native?reconnect=1", "reconnect= needs disconnect="),
    ("sim://native?fast", "cannot read the query"),
    ("sim://nowhere?fast=1", "unknown virtual board 'sim://nowhere'"),
])
def test_sim_url_query_errors_name_the_option(url: str, message: str) -> None:
    with pytest.raises(InputError, match=re.escape(message)):
        open_port(url, detect=lambda: [])


def test_native_launcher_passes_the_query_to_the_board(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    exe = tmp_path / "ja_native_board"
    exe.write_text(NATIVE_STANDIN.replace("{python}", sys.executable))
    exe.chmod(0o755)
    monkeypatch.setenv("JOINTANGLE_NATIVE_BOARD", str(exe))
    monkeypatch.setenv("WANT_BAUD", "9600")
    monkeypatch.setenv("WANT_ARGS", "--fast --loop-motion --fault a.1:saturate@1")
    url = "sim://native?fast=1&fault=a.1:saturate@1&baud=9600"
    with open_port(url, launch=LaunchOptions(seconds=2.0, start_timeout_s=20)) as conn:
        assert conn.url == url and conn.board is not None
        conn.port.write(b"x")  # the stand-in's assertions passed: it serves its echo pty
        got = b""
        for _ in range(50):
            got += conn.port.read(1)
            if got:
                break
        assert got == b"x"


def test_a_board_that_pulls_its_cable_is_never_reopened_on_its_old_pty() -> None:
    """current_port follows the board's stdout: after DISCONNECTED there is no port (the old
    /dev/pts/N may be another process's by then) until the next PTY line."""
    script = ("import os, sys, time, tty, signal\n"
              "signal.signal(signal.SIGTERM, lambda *a: sys.exit(0))\n"
              "m, s = os.openpty(); tty.setraw(s)\n"
              "print('PTY ' + os.ttyname(s), flush=True)\n"
              "sys.stdin.readline(); print('DISCONNECTED', flush=True); os.close(s)\n"
              "m2, s2 = os.openpty(); tty.setraw(s2)\n"
              "sys.stdin.readline(); print('PTY ' + os.ttyname(s2), flush=True)\n"
              "time.sleep(60)\n")
    import subprocess
    import time

    proc = subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdin is not None and proc.stdout is not None
    first = proc.stdout.readline().decode()[4:].strip()
    board = ProcessBoard(proc, first)
    try:
        assert board.current_port() == first
        proc.stdin.write(b"\n")  # pull the cable
        proc.stdin.flush()
        time.sleep(0.3)
        with pytest.raises(InputError, match="cable is pulled"):
            board.current_port()
        proc.stdin.write(b"\n")  # plug it back in: a new pty
        proc.stdin.flush()
        deadline = time.monotonic() + 5
        second = ""
        while not second and time.monotonic() < deadline:
            try:
                second = board.current_port()
            except InputError:
                time.sleep(0.05)
        assert second.startswith("/dev/") and second != first
    finally:
        board.stop()


def _sim_files(tmp_path: Path) -> tuple[Path, Path]:
    from jointangle.cli.main import main

    motion, rig = tmp_path / "m.csv", tmp_path / "r.toml"
    assert main(["simulate", "--scenario", "gravity-slow-periodic", "--seconds", "1", "--rate",
                 "500", "--out", str(motion), "--rig-out", str(rig)]) == 0
    return motion, rig


def test_a_rig_or_motion_in_the_url_is_checked_as_the_options_are(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # rig= used to skip the geometry check (the board then streamed theta = 0 with exit 0) and
    # motion= was played without a check against the rig (a missing sensor read as 0 m/s^2).
    from jointangle.cli.main import main

    motion, rig = _sim_files(tmp_path)
    text = rig.read_text()
    coincident = tmp_path / "coincident.toml"
    coincident.write_text(text.replace("0.024999999999999967", "0.2525"))
    assert coincident.read_text() != text
    short = tmp_path / "short.csv"
    short.write_text("".join(",".join(line.split(",")[:10]) + "\n"
                             for line in motion.read_text().splitlines()))
    capsys.readouterr()
    for query, needle in ((f"rig={coincident}", "coincident"),
                          (f"rig={rig}&motion={short}", "short.csv"),
                          ("rate=2000", "at most 1000"),
                          ("seconds=1e6", "at most 3600")):
        assert main(["info", "--port", f"sim://native?{query}"]) == 2, query
        err = capsys.readouterr().err
        assert needle in err and err.count("\n") == 1 and "Traceback" not in err, (query, err)


def test_a_given_motion_loops_unless_loop_0(tmp_path: Path) -> None:
    # It used to be played once and then held: a noise-free held sample then read as every
    # sensor frozen, and the filter stopped.
    from jointangle.boards.options import LaunchOptions, apply_sim_query, board_args

    base = LaunchOptions()
    looped = apply_sim_query(base, [("rig", "r.toml"), ("motion", "m.csv")])
    held = apply_sim_query(base, [("rig", "r.toml"), ("motion", "m.csv"), ("loop", "0")])
    assert "--loop-motion" in board_args(looped)
    assert "--loop-motion" not in board_args(held)


@pytest.mark.parametrize(("extra", "field"), [(["--baud", "1"], "--baud"),
                                              (["--sim-seconds", "1e6"], "--sim-seconds")])
def test_virtual_board_options_are_bounded_before_a_board_starts(
        extra: list[str], field: str, capsys: pytest.CaptureFixture[str]) -> None:
    # --baud 1 used to reach the board, which printed its multi-line usage text.
    from jointangle.cli.main import main

    assert main(["info", "--port", "sim://native", *extra]) == 2
    err = capsys.readouterr().err
    assert field in err and err.count("\n") == 1 and "Traceback" not in err

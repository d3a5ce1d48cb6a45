"""`jointangle doctor`: each diagnosis on a fake machine (ports, modes, groups, /proc, PATH,
compiled parts), and its fix."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import pytest

from jointangle import doctor
from jointangle.built import AVR_IMAGE, FILTER_REPLAY, NATIVE_BOARD, PICO_IMAGE, Part
from jointangle.cli.main import main
from jointangle.doctor import Environment, Finding, diagnose
from jointangle.errors import InputError
from jointangle.transport import check_sim_platform, find_port_holders

DIALOUT = 20
ALICE_GID = 1000


@dataclass
class FakePort:
    device: str
    vid: int | None = None
    pid: int | None = None
    serial_number: str | None = None


def fake_stat(gid: int = DIALOUT, mode: int = 0o660) -> os.stat_result:
    return os.stat_result((stat.S_IFCHR | mode, 0, 0, 1, 0, gid, 0, 0, 0, 0))


def machine(tmp_path: Path, **kw: object) -> Environment:
    """A Linux laptop with a Mega on /dev/ttyACM0 the user may use, an empty /proc, avrdude on
    PATH and every compiled part present; `kw` changes what a test needs."""
    proc = tmp_path / "proc"
    proc.mkdir(exist_ok=True)
    base = Environment(
        platform="linux", user=lambda: "alice",
        comports=lambda: [FakePort("/dev/ttyACM0", 0x2341, 0x0042), FakePort("/dev/ttyS0")],
        stat=lambda _p: fake_stat(), access=lambda _p, _m: True,
        session_groups=lambda: [ALICE_GID, DIALOUT],
        group_name=lambda gid: {DIALOUT: "dialout", ALICE_GID: "alice"}[gid],
        group_members=lambda _gid: [], proc=proc, which=lambda name: f"/usr/bin/{name}",
        locate=lambda part: Path("/opt/parts") / part.filename)
    return replace(base, **kw)  # type: ignore[arg-type]


def problems(findings: list[Finding], check: str) -> list[Finding]:
    return [f for f in findings if f.check == check and f.status == "problem"]


def test_a_healthy_machine_has_no_problem(tmp_path: Path) -> None:
    findings = diagnose(machine(tmp_path))
    assert [f for f in findings if f.status != "ok"] == []
    assert any(f.check == "ports" and "/dev/ttyACM0: Arduino Mega 2560 R3 (USB 2341:0042)"
               in f.message for f in findings)


def test_no_board_found_says_so_and_lists_the_usb_ports(tmp_path: Path) -> None:
    env = machine(tmp_path, comports=lambda: [FakePort("/dev/ttyUSB3", 0x1234, 0x5678)])
    (p,) = problems(diagnose(env), "ports")
    assert "no Arduino Mega 2560" in p.message and "/dev/ttyUSB3 (1234:5678)" in p.message
    assert "data cable" in p.fix


def test_user_not_in_the_group_owning_the_port(tmp_path: Path) -> None:
    env = machine(tmp_path, access=lambda _p, _m: False, session_groups=lambda: [ALICE_GID])
    (p,) = problems(diagnose(env), "access")
    assert "/dev/ttyACM0 belongs to group 'dialout'" in p.message and "alice" in p.message
    assert p.fix == "sudo usermod -aG dialout alice, then log out and back in"


def test_user_added_to_the_group_after_logging_in(tmp_path: Path) -> None:
    env = machine(tmp_path, access=lambda _p, _m: False, session_groups=lambda: [ALICE_GID],
                  group_members=lambda gid: ["alice"] if gid == DIALOUT else [])
    (p,) = problems(diagnose(env), "access")
    assert "after this session started" in p.message and "newgrp dialout" in p.fix


def test_group_member_but_the_device_is_not_group_writable(tmp_path: Path) -> None:
    env = machine(tmp_path, access=lambda _p, _m: False, stat=lambda _p: fake_stat(mode=0o600))
    (p,) = problems(diagnose(env), "access")
    assert "mode 600" in p.message and "chmod g+rw /dev/ttyACM0" in p.fix


def test_a_named_port_that_does_not_exist(tmp_path: Path) -> None:
    def missing(path: str) -> os.stat_result:
        raise FileNotFoundError(2, "No such file or directory", path)

    (p,) = problems(diagnose(machine(tmp_path, stat=missing), port="/dev/ttyACM7"), "access")
    assert "/dev/ttyACM7" in p.message and "info --list" in p.fix


def test_urls_are_not_checked_as_devices(tmp_path: Path) -> None:
    findings = diagnose(machine(tmp_path, stat=None), port="socket://localhost:7000")
    assert [f.status for f in findings if f.check == "ports"] == ["note"]
    assert not [f for f in findings if f.check in ("access", "holders")]


def fake_process(proc: Path, pid: int, comm: str, cmdline: list[str],
                 open_files: list[Path] = ()) -> None:  # type: ignore[assignment]
    d = proc / str(pid)
    (d / "fd").mkdir(parents=True)
    (d / "comm").write_text(comm + "\n")
    (d / "cmdline").write_bytes(b"\0".join(a.encode() for a in cmdline) + b"\0")
    for n, f in enumerate(open_files, start=3):
        (d / "fd" / str(n)).symlink_to(f)


def test_a_port_held_by_another_program(tmp_path: Path) -> None:
    device = tmp_path / "ttyACM0"
    device.touch()
    env = machine(tmp_path, comports=lambda: [FakePort(str(device), 0x2341, 0x0042)])
    fake_process(env.proc, 4242, "screen", ["screen", "/dev/ttyACM0", "115200"], [device])
    fake_process(env.proc, 4243, "bash", ["bash"], [tmp_path / "elsewhere"])
    (p,) = problems(diagnose(env), "holders")
    assert "held by another program (pid 4242: screen /dev/ttyACM0 115200)" in p.message
    assert "Serial Monitor" in p.fix and p.fix.endswith("`kill 4242`")


def test_holders_are_found_in_the_real_proc(tmp_path: Path) -> None:
    """The same lookup on this machine's /proc: a child process holding a file open."""
    held = tmp_path / "held"
    held.touch()
    child = subprocess.Popen([sys.executable, "-c", "import sys, time\n"
                              f"f = open({str(held)!r})\nprint('open', flush=True)\n"
                              "time.sleep(30)"], stdout=subprocess.PIPE)
    try:
        assert child.stdout is not None and child.stdout.readline() == b"open\n"
        holders = find_port_holders(str(held))
        assert [pid for pid, _ in holders] == [child.pid]
        assert "time.sleep(30)" in holders[0][1]
    finally:
        child.kill()
        child.wait()
    deadline = time.monotonic() + 5
    while find_port_holders(str(held)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert find_port_holders(str(held)) == []


def test_modem_manager_running(tmp_path: Path) -> None:
    env = machine(tmp_path)
    fake_process(env.proc, 612, "ModemManager", ["/usr/sbin/ModemManager"])
    (p,) = problems(diagnose(env), "modemmanager")
    assert "ModemManager is running (pid 612)" in p.message and "/dev/ttyACM*" in p.message
    assert "systemctl disable --now ModemManager" in p.fix and "ID_MM_DEVICE_IGNORE" in p.fix


def test_modem_manager_is_a_linux_check(tmp_path: Path) -> None:
    env = machine(tmp_path, platform="darwin")
    fake_process(env.proc, 612, "ModemManager", ["/usr/sbin/ModemManager"])
    assert not [f for f in diagnose(env) if f.check in ("modemmanager", "holders")]


@pytest.mark.parametrize(("platform", "fix"), [
    ("linux", "sudo apt install avrdude"), ("darwin", "brew install avrdude"),
    ("win32", "the Arduino IDE ships one")])
def test_avrdude_missing(tmp_path: Path, platform: str, fix: str) -> None:
    env = machine(tmp_path, platform=platform, which=lambda _name: None, stat=fake_stat
                  if platform != "win32" else None)
    (p,) = problems(diagnose(env), "avrdude")
    assert "`flash` needs avrdude" in p.message and fix in p.fix


def test_missing_compiled_parts_are_named_with_how_to_get_them(tmp_path: Path) -> None:
    present = {NATIVE_BOARD}
    env = machine(tmp_path, locate=lambda part: Path("/x") if part in present else None)
    parts = [f for f in diagnose(env) if f.check == "parts"]
    assert [f.status for f in parts] == ["note", "note", "ok", "note", "note", "note", "note",
                                         "note"]
    replay = parts[0]
    assert "libja_filter_replay.so" in replay.message and "--filter firmware" in replay.message
    assert FILTER_REPLAY.target in replay.fix and FILTER_REPLAY.env in replay.fix
    assert AVR_IMAGE.filename in parts[4].message
    assert PICO_IMAGE.filename in parts[7].message and "sim://pico" in parts[7].message
    assert not problems(parts, "parts")  # a pure-Python install is not a problem


def test_a_variable_naming_a_missing_part_is_a_problem(tmp_path: Path) -> None:
    def locate(part: Part) -> Path | None:
        raise InputError(f"{part.env}=/nope does not exist", field=part.env)

    env = machine(tmp_path, parts=[FILTER_REPLAY], locate=locate)
    (p,) = problems(diagnose(env), "parts")
    assert "JOINTANGLE_FIRMWARE_LIB=/nope does not exist" in p.message
    assert p.fix == "unset JOINTANGLE_FIRMWARE_LIB or fix it"


def test_virtual_boards_say_they_need_linux(tmp_path: Path) -> None:
    notes = [f for f in diagnose(machine(tmp_path, platform="darwin")) if f.status == "note"]
    assert any("sim://" in f.message and "need Linux" in f.message for f in notes)
    with pytest.raises(InputError, match=r"sim://native: the virtual boards \(sim://\) need "
                       r"Linux; on win32 name a real board's serial port with --port"):
        check_sim_platform("sim://native", "win32")
    check_sim_platform("sim://native", "linux")


def test_the_command_prints_each_problem_with_its_fix(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    env = machine(tmp_path, which=lambda _name: None)
    monkeypatch.setattr("jointangle.cli.doctor.diagnose",
                        lambda port: doctor.diagnose(env, port))
    assert main(["doctor"]) == 1
    out = capsys.readouterr().out
    assert "PROBLEM  avrdude       `flash` needs avrdude, which is not on PATH\n" in out
    assert "fix: sudo apt install avrdude" in out and out.endswith("1 problem found\n")
    assert main(["doctor", "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["problems"] == 1 and {f["check"] for f in doc["findings"]} >= {
        "ports", "access", "holders", "modemmanager", "avrdude", "parts"}
    env_ok = machine(tmp_path)
    monkeypatch.setattr("jointangle.cli.doctor.diagnose",
                        lambda port: doctor.diagnose(env_ok, port))
    assert main(["doctor"]) == 0

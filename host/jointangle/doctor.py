"""`jointangle doctor`: what commonly stops a board from talking to the host, each with its fix.

The checks (issue 18 item 3), each a function of an `Environment` — the lookups it makes of the
machine (serial ports, file modes, groups, processes, PATH, the compiled parts) — so that the
tests give each one a fake machine:

- `check_ports`: the boards found by USB VID:PID through pyserial's `list_ports`
  (transport.KNOWN_BOARDS), or the port named;
- `check_access`: the user may read and write each port; if not, whether it is the group that
  owns the device (`dialout`, `uucp`) that the user lacks, or has been given only since logging
  in;
- `check_holders`: another program holding a port (the IDE's serial monitor, screen, a second
  jointangle), from /proc;
- `check_modem_manager`: ModemManager running (Linux): it probes every new /dev/ttyACM* with AT
  commands for several seconds, which the board reads as input and which keep the port busy;
- `check_avrdude`: avrdude on PATH for `flash`;
- `check_parts`: which compiled parts (built.PARTS) are present, and what is missing without
  them; the virtual boards' need for Linux.

Importing this module has no side effects.
"""

from __future__ import annotations

import getpass
import os
import shutil
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from jointangle.built import PARTS, Part, env_override, how_to_get, search_build_trees
from jointangle.errors import InputError
from jointangle.transport import (
    KNOWN_BOARDS,
    _PortInfo,
    find_port_holders,
    list_serial_ports,
)

Status = Literal["ok", "problem", "note"]


@dataclass(frozen=True)
class Finding:
    check: str  # "ports", "access", "holders", "modemmanager", "avrdude", "parts"
    status: Status  # problem: stops something working; note: worth knowing, nothing broken
    message: str
    fix: str = ""


def _group_name(gid: int) -> str:
    try:
        import grp  # POSIX only

        return grp.getgrgid(gid).gr_name
    except (ImportError, KeyError):
        return str(gid)


def _group_members(gid: int) -> Sequence[str]:
    """The users /etc/group lists in group `gid` (what `usermod -aG` changed)."""
    try:
        import grp

        return list(grp.getgrgid(gid).gr_mem)
    except (ImportError, KeyError):
        return []


def _session_groups() -> Sequence[int]:
    """The groups this process runs with (the login session's, not /etc/group's)."""
    if not hasattr(os, "getgroups"):
        return []
    return [*os.getgroups(), os.getegid()]


def _locate_part(part: Part) -> Path | None:
    """A compiled part's path, or None; nothing is built."""
    return env_override(part.env) or search_build_trees(part.pattern,
                                                        executable=part.executable)


@dataclass(frozen=True)
class Environment:
    """The machine as doctor sees it; every lookup replaceable (the tests' fake machines)."""

    platform: str = sys.platform
    user: Callable[[], str] = getpass.getuser
    comports: Callable[[], Sequence[_PortInfo]] = list_serial_ports
    stat: Callable[[str], os.stat_result] = os.stat
    access: Callable[[str, int], bool] = os.access
    session_groups: Callable[[], Sequence[int]] = _session_groups
    group_name: Callable[[int], str] = _group_name
    group_members: Callable[[int], Sequence[str]] = _group_members
    proc: Path = Path("/proc")
    which: Callable[[str], str | None] = shutil.which
    locate: Callable[[Part], Path | None] = _locate_part
    parts: Sequence[Part] = field(default=PARTS)

    @property
    def posix(self) -> bool:
        return not self.platform.startswith("win")

    @property
    def linux(self) -> bool:
        return self.platform.startswith("linux")


def is_device_path(port: str) -> bool:
    """A serial device to check (not a pyserial URL such as socket:// or a sim:// board)."""
    return "://" not in port


def ports_to_check(env: Environment, port: str | None) -> tuple[list[str], list[Finding]]:
    """The devices the other checks look at, and what was found: the named port, else every
    known board (USB VID:PID), else every USB serial port."""
    if port is not None:
        if not is_device_path(port):
            return [], [Finding("ports", "note", f"{port} is not a serial device: nothing to "
                                "check on this machine's ports")]
        return [port], [Finding("ports", "ok", f"checking {port} (--port)")]
    ports = list(env.comports())
    known = {(k.vid, k.pid): k.what for k in KNOWN_BOARDS}
    boards = [(p, known[(p.vid, p.pid)]) for p in ports
              if p.vid is not None and p.pid is not None and (p.vid, p.pid) in known]
    if boards:
        return [p.device for p, _ in boards], [
            Finding("ports", "ok", f"{p.device}: {what} (USB {p.vid:04X}:{p.pid:04X})")
            for p, what in boards]
    usb = [p for p in ports if p.vid is not None]
    listed = ", ".join(f"{p.device} ({p.vid:04X}:{p.pid or 0:04X})" for p in usb) or "none"
    return [p.device for p in usb], [Finding(
        "ports", "problem",
        f"no Arduino Mega 2560 or known USB-serial bridge found (USB serial ports: {listed})",
        "plug the board in with a data cable (charge-only cables carry no data) and run "
        "`jointangle doctor` again; a clone with another bridge: name it with --port")]


def check_access(env: Environment, device: str) -> list[Finding]:
    """May the user read and write `device`? If not: which group owns it, and how to join."""
    if not env.posix:
        return []
    try:
        st = env.stat(device)
    except OSError as exc:
        return [Finding("access", "problem", f"{device}: {exc.strerror or exc}",
                        "check the name (`jointangle info --list` lists the ports)")]
    if env.access(device, os.R_OK | os.W_OK):
        return [Finding("access", "ok", f"{device}: you may read and write it")]
    user = env.user()
    group = env.group_name(st.st_gid)
    if st.st_gid in env.session_groups():
        return [Finding("access", "problem",
                        f"{device} is not readable and writable by its group '{group}' "
                        f"(mode {st.st_mode & 0o777:o})",
                        f"sudo chmod g+rw {device} (a udev rule keeps it: "
                        'MODE="0660" for the device)')]
    if user in env.group_members(st.st_gid):
        return [Finding("access", "problem",
                        f"{device} belongs to group '{group}': you ({user}) were added to it "
                        "after this session started",
                        f"log out and back in (or run `newgrp {group}` in this shell)")]
    return [Finding("access", "problem",
                    f"{device} belongs to group '{group}' and you ({user}) are not in it",
                    f"sudo usermod -aG {group} {user}, then log out and back in")]


def check_holders(env: Environment, device: str) -> list[Finding]:
    """Another program holding `device` (Linux: read from /proc)."""
    if not env.linux:
        return []
    holders = find_port_holders(device, env.proc)
    if not holders:
        return [Finding("holders", "ok", f"{device}: no other program has it open")]
    who = "; ".join(f"pid {pid}: {cmd[:80]}" if cmd else f"pid {pid}" for pid, cmd in holders)
    pids = " ".join(str(pid) for pid, _ in holders)
    return [Finding("holders", "problem", f"{device} is held by another program ({who})",
                    "close it (the Arduino IDE's Serial Monitor, screen, minicom, another "
                    f"jointangle), or `kill {pids}`")]


def modem_manager_pids(proc: Path) -> list[int]:
    """Processes named ModemManager in `proc` (/proc/PID/comm)."""
    try:
        pids = [d for d in os.listdir(proc) if d.isdigit()]
    except OSError:
        return []
    found = []
    for pid in pids:
        try:
            if (proc / pid / "comm").read_text(errors="replace").strip() == "ModemManager":
                found.append(int(pid))
        except OSError:
            continue
    return sorted(found)


UDEV_RULE = ('ATTRS{idVendor}=="2341", ENV{ID_MM_DEVICE_IGNORE}="1"' "\n"
             'ATTRS{idVendor}=="2a03", ENV{ID_MM_DEVICE_IGNORE}="1"')


def check_modem_manager(env: Environment) -> list[Finding]:
    """ModemManager probes each new /dev/ttyACM* (the Mega's 16U2 is a CDC ACM modem to it)."""
    if not env.linux:
        return []
    pids = modem_manager_pids(env.proc)
    if not pids:
        return [Finding("modemmanager", "ok", "ModemManager is not running")]
    return [Finding(
        "modemmanager", "problem",
        f"ModemManager is running (pid {', '.join(map(str, pids))}): for several seconds after "
        "a board is plugged in it sends AT commands to /dev/ttyACM*, which the board reads as "
        "input and which keep the port busy",
        "sudo systemctl disable --now ModemManager, or keep it away from Arduino boards: put "
        + " and ".join(repr(r) for r in UDEV_RULE.splitlines())
        + " in /etc/udev/rules.d/99-jointangle.rules, then sudo udevadm control --reload")]


def check_avrdude(env: Environment) -> list[Finding]:
    path = env.which("avrdude")
    if path is not None:
        return [Finding("avrdude", "ok", f"avrdude: {path} (for `flash`)")]
    how = ("brew install avrdude" if env.platform == "darwin"
           else "install avrdude (the Arduino IDE ships one) and put it on PATH"
           if env.platform.startswith("win")
           else "sudo apt install avrdude (Debian, Ubuntu), or your distribution's package")
    return [Finding("avrdude", "problem", "`flash` needs avrdude, which is not on PATH", how)]


def check_parts(env: Environment) -> list[Finding]:
    """Each compiled part present or not, and what is missing without it."""
    out: list[Finding] = []
    for part in env.parts:
        try:
            path = env.locate(part)
        except InputError as exc:  # $ENV names a file that does not exist
            out.append(Finding("parts", "problem", str(exc), f"unset {part.env} or fix it"))
            continue
        if path is not None:
            out.append(Finding("parts", "ok", f"{part.what}: {path}"))
        else:
            out.append(Finding("parts", "note",
                               f"{part.what} ({part.filename}) is not present: without it, no "
                               f"{part.needed_by}", how_to_get(part.target, part.env)))
    if not env.linux:
        out.append(Finding("parts", "note", f"the virtual boards (sim://) need Linux; this is "
                           f"{env.platform}", "use a real board (--port)"))
    return out


def diagnose(env: Environment | None = None, port: str | None = None) -> list[Finding]:
    """Every check, in the order a user meets the problems."""
    env = env or Environment()
    devices, findings = ports_to_check(env, port)
    for device in devices:
        findings += check_access(env, device)
        findings += check_holders(env, device)
    findings += check_modem_manager(env)
    findings += check_avrdude(env)
    findings += check_parts(env)
    return findings

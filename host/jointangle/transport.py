"""Where the bytes come from: real serial ports, any pyserial URL, and the virtual boards.

One entry point, `open_port(url)`, and three kinds of address (docs/design.md §4, issue 5 item 3):

- `None` (no `--port`): the first attached board found by USB VID:PID (`KNOWN_BOARDS`), else
  `sim://native`.
- `sim://NAME[?KEY=VALUE&...]`: a virtual board started by the launcher registered under NAME
  in `jointangle.boards.launchers.SIM_LAUNCHERS` (python-can's table of backends, not
  string-prefix guessing). The launcher starts the board process, waits for the pseudo-terminal
  it announces and returns that path; closing the connection stops the board. The query sets the
  board's launch options (`jointangle.boards.options.SIM_QUERY`, e.g.
  `sim://native?fast=1&fault=a.0:nack@2-4`); it wins over the command line.
- anything else: handed to `serial.serial_for_url` as is (`/dev/ttyACM0`, `/dev/pts/5`,
  `loop://`, `socket://host:port`, `rfc2217://...`, `spy://...`).

Importing this module has no side effects and it keeps no module state.
"""

from __future__ import annotations

import errno
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol

import serial
from serial.tools import list_ports

from jointangle.boards.launchers import SIM_LAUNCHERS
from jointangle.boards.options import (
    DEFAULT_BAUD,
    PORT_FIELD,
    SIM_PREFIX,
    LaunchOptions,
    apply_sim_query,
    split_sim_url,
)
from jointangle.boards.process import BoardLauncher, RunningBoard
from jointangle.errors import InputError

READ_TIMEOUT_S = 0.02  # short reads: the Link polls
DEFAULT_SIM = "sim://native"


@dataclass(frozen=True)
class UsbId:
    vid: int
    pid: int
    what: str


# USB vendor:product ids of the boards and bridges we look for. Sources:
# - Arduino Mega 2560: ArduinoCore-avr boards.txt, `mega.vid.N/mega.pid.N` (0x2341 Arduino LLC,
#   0x2A03 Arduino SRL; 0x0010 Mega 2560, 0x0042 Mega 2560 R3, 0x0210/0x0242 later revisions).
# - CH340/CH341: Linux drivers/usb/serial/ch341.c id_table, USB_DEVICE(0x1a86, 0x7523).
# - CP210x: Linux drivers/usb/serial/cp210x.c, USB_DEVICE(0x10C4, 0xEA60) (CP2102/CP2104).
# - FTDI FT232R/FT232BM: Linux drivers/usb/serial/ftdi_sio_ids.h, FTDI_VID 0x0403,
#   FTDI_8U232AM_PID 0x6001.
KNOWN_BOARDS: tuple[UsbId, ...] = (
    UsbId(0x2341, 0x0010, "Arduino Mega 2560"),
    UsbId(0x2341, 0x0042, "Arduino Mega 2560 R3"),
    UsbId(0x2A03, 0x0010, "Arduino Mega 2560 (arduino.org)"),
    UsbId(0x2A03, 0x0042, "Arduino Mega 2560 R3 (arduino.org)"),
    UsbId(0x2341, 0x0210, "Arduino Mega 2560"),
    UsbId(0x2341, 0x0242, "Arduino Mega 2560"),
    UsbId(0x1A86, 0x7523, "CH340 USB-serial bridge"),
    UsbId(0x10C4, 0xEA60, "CP210x USB-serial bridge"),
    UsbId(0x0403, 0x6001, "FTDI FT232 USB-serial bridge"),
)


@dataclass(frozen=True)
class DetectedPort:
    device: str  # e.g. /dev/ttyACM0
    what: str
    vid: int
    pid: int
    serial_number: str | None = None


class _PortInfo(Protocol):
    """What we read from `serial.tools.list_ports.comports()` entries."""

    device: str
    vid: int | None
    pid: int | None
    serial_number: str | None


def list_serial_ports() -> Sequence[_PortInfo]:
    """`serial.tools.list_ports.comports()`: the serial ports this machine has."""
    return list(list_ports.comports())


def detect_boards(comports: Callable[[], Sequence[_PortInfo]] = list_serial_ports,
                  known: Sequence[UsbId] = KNOWN_BOARDS) -> list[DetectedPort]:
    """Attached ports whose VID:PID is a known board or bridge, Arduino boards first."""
    table = {(k.vid, k.pid): (i, k.what) for i, k in enumerate(known)}
    found: list[tuple[int, DetectedPort]] = []
    for p in comports():
        if p.vid is None or p.pid is None:
            continue
        hit = table.get((p.vid, p.pid))
        if hit is not None:
            found.append((hit[0], DetectedPort(p.device, hit[1], p.vid, p.pid, p.serial_number)))
    return [d for _, d in sorted(found, key=lambda x: (x[0], x[1].device))]


# ---------------------------------------------------------------------------------------------
# Opening


class SerialLike(Protocol):
    """The subset of pyserial's Serial the host uses."""

    def read(self, size: int = 1) -> bytes: ...

    def write(self, data: bytes, /) -> int | None: ...

    @property
    def in_waiting(self) -> int: ...

    def close(self) -> None: ...


@dataclass
class Connection:
    """An open port plus, for a virtual board, the process behind it. Close stops both."""

    url: str
    port: SerialLike
    board: RunningBoard | None = None
    what: str = ""
    baud: int = DEFAULT_BAUD
    timeout_s: float = READ_TIMEOUT_S
    port_open: bool = True

    @property
    def rig_text(self) -> str | None:
        return None if self.board is None else self.board.rig_text

    def close_port(self) -> None:
        """Close the port only (a lost device): a virtual board keeps running."""
        if self.port_open:
            self.port_open = False
            self.port.close()

    def reopen(self) -> None:
        """Open the same device again after it was lost: the same address, or the pty the
        virtual board serves now (it announces a new one when its cable is plugged back in)."""
        self.close_port()
        path = self.url if self.board is None else self.board.current_port()
        self.port = open_serial(path, baud=self.baud, timeout_s=self.timeout_s)
        self.port_open = True

    def close(self) -> None:
        try:
            self.close_port()
        finally:
            if self.board is not None:
                self.board.stop()

    def __enter__(self) -> Connection:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def resolve_url(url: str | None,
                detect: Callable[[], list[DetectedPort]] = detect_boards) -> tuple[str, str]:
    """(url, what) for a --port value: None picks the first known board, else sim://native."""
    if url is not None and url != "":
        return url, ""
    boards = detect()
    if boards:
        return boards[0].device, boards[0].what
    return DEFAULT_SIM, "no board attached: the native virtual board"


def open_serial(url: str, *, baud: int = DEFAULT_BAUD,
                timeout_s: float = READ_TIMEOUT_S) -> SerialLike:
    """`serial.serial_for_url` with our defaults; failures as InputError naming the port.

    The port is opened exclusively (pyserial's `exclusive=True`: flock(LOCK_EX | LOCK_NB) on
    the device, taken before any setting changes): a second jointangle on the same port is
    refused at once instead of stealing the first one's bytes, and the first loses nothing."""
    try:
        port: Any = serial.serial_for_url(url, baudrate=baud, timeout=timeout_s,
                                          write_timeout=1.0, exclusive=True)
    except (serial.SerialException, OSError, ValueError) as exc:
        if getattr(exc, "errno", None) in (errno.EAGAIN, errno.EWOULDBLOCK, errno.EBUSY):
            raise InputError(f"{url} is in use by another program{port_holders(url)}: "
                             "refusing to share it (it would take the other's bytes)",
                             field=PORT_FIELD) from None
        raise InputError(f"cannot open {url}: {exc}", field=PORT_FIELD) from None
    return port


def port_holders(path: str, proc: Path = Path("/proc")) -> str:
    """" (pid N: its command line)" for the other processes that have `path` open (Linux,
    best effort; "" when none is found or /proc is not readable)."""
    found = [f"pid {pid}: {cmd[:80]}" if cmd else f"pid {pid}"
             for pid, cmd in find_port_holders(path, proc)]
    return f" ({'; '.join(found)})" if found else ""


def find_port_holders(path: str, proc: Path = Path("/proc")) -> list[tuple[int, str]]:
    """(pid, command line) of the other processes that have `path` open, read from `proc`
    (Linux, best effort: [] elsewhere or when /proc is not readable)."""
    try:
        target = os.path.realpath(path)
        pids = sorted((d for d in os.listdir(proc) if d.isdigit() and int(d) != os.getpid()),
                      key=int)
    except OSError:
        return []
    found: list[tuple[int, str]] = []
    for pid in pids:
        try:
            fds = os.listdir(proc / pid / "fd")
            if not any(os.readlink(proc / pid / "fd" / fd) == target for fd in fds):
                continue
            cmd = " ".join((proc / pid / "cmdline").read_bytes().replace(b"\0", b" ").decode(
                errors="replace").split())  # one line, whatever the arguments hold
        except OSError:
            continue
        found.append((int(pid), cmd))
    return found


def check_sim_platform(url: str, platform: str = sys.platform) -> None:
    """The virtual boards need Linux (a pseudo-terminal, the firmware built for Linux, simavr):
    said plainly, naming the platform, instead of failing somewhere inside."""
    if not platform.startswith("linux"):
        raise InputError(f"{url}: the virtual boards (sim://) need Linux; on {platform} name a "
                         "real board's serial port with --port (`jointangle info --list`)",
                         field=PORT_FIELD)


def open_port(url: str | None = None, *, baud: int = DEFAULT_BAUD,
              launch: LaunchOptions | None = None,
              launchers: Mapping[str, BoardLauncher] = SIM_LAUNCHERS,
              detect: Callable[[], list[DetectedPort]] = detect_boards,
              timeout_s: float = READ_TIMEOUT_S) -> Connection:
    """Open what --port names (see the module docstring)."""
    resolved, what = resolve_url(url, detect)
    if resolved.startswith(SIM_PREFIX):
        check_sim_platform(resolved)
        name, query = split_sim_url(resolved)
        launcher = launchers.get(name)
        if launcher is None:
            raise InputError(f"unknown virtual board {SIM_PREFIX + name!r}; choose one of "
                             + ", ".join(SIM_PREFIX + n for n in launchers), field=PORT_FIELD)
        options = apply_sim_query(launch or LaunchOptions(baud=baud), query, resolved)
        board = launcher.start(options)
        try:
            port = open_serial(board.port_path, baud=baud, timeout_s=timeout_s)
        except BaseException:
            board.stop()
            raise
        return Connection(resolved, port, board, what or launcher.description, baud, timeout_s)
    return Connection(resolved, open_serial(resolved, baud=baud, timeout_s=timeout_s), None, what,
                      baud, timeout_s)


def list_ports_doc(
        comports: Callable[[], Sequence[_PortInfo]] = list_serial_ports) -> list[dict[str, Any]]:
    """Every serial port with its USB ids and whether it is a known board (for `info --list`)."""
    known = {(k.vid, k.pid): k.what for k in KNOWN_BOARDS}
    out = []
    for p in comports():
        out.append({"device": p.device,
                    "vid": None if p.vid is None else f"{p.vid:04X}",
                    "pid": None if p.pid is None else f"{p.pid:04X}",
                    "known": known.get((p.vid or -1, p.pid or -1))})
    return out

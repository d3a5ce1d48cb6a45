"""Where the bytes come from: real serial ports, any pyserial URL, and the virtual boards.

One entry point, `open_port(url)`, and three kinds of address (docs/design.md §4, issue 5 item 3):

- `None` (no `--port`): the first attached board found by USB VID:PID (`KNOWN_BOARDS`), else
  `sim://native`.
- `sim://NAME[?KEY=VALUE&...]`: a virtual board started by the launcher registered under NAME
  in `SIM_LAUNCHERS` (python-can's table of backends, not string-prefix guessing). The launcher
  starts the board process, waits for the pseudo-terminal it announces and returns that path;
  closing the connection stops the board. The query sets the board's launch options
  (`jointangle.sim_launch.SIM_QUERY`, e.g. `sim://native?fast=1&fault=a.0:nack@2-4`); it wins
  over the command line.
- anything else: handed to `serial.serial_for_url` as is (`/dev/ttyACM0`, `/dev/pts/5`,
  `loop://`, `socket://host:port`, `rfc2217://...`, `spy://...`).

Importing this module has no side effects and it keeps no module state.
"""

from __future__ import annotations

import errno
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType, TracebackType
from typing import Any, Protocol

from jointangle.built import locate_built
from jointangle.errors import InputError
from jointangle.sim_launch import DEFAULT_BAUD as DEFAULT_BAUD
from jointangle.sim_launch import PORT_FIELD as PORT_FIELD
from jointangle.sim_launch import SIM_PREFIX as SIM_PREFIX
from jointangle.sim_launch import SIM_QUERY as SIM_QUERY
from jointangle.sim_launch import LaunchOptions as LaunchOptions
from jointangle.sim_launch import apply_sim_query as apply_sim_query
from jointangle.sim_launch import board_args as board_args
from jointangle.sim_launch import sim_query_help as sim_query_help
from jointangle.sim_launch import split_sim_url as split_sim_url

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
DEFAULT_FACTORY_RATE_HZ = 500  # a launcher that names none (app::kFactoryRateHz)

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
    from serial.tools import list_ports

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
# Virtual boards


class RunningBoard(Protocol):
    """A started virtual board: the pty it serves and how to stop it."""

    @property
    def port_path(self) -> str: ...

    @property
    def rig_text(self) -> str | None:
        """The rig file the board runs (TOML), when known: recordings keep it."""
        ...

    def current_port(self) -> str:
        """The pty the board serves now (it announces a new one after a reconnect); raises
        InputError when the board has exited."""
        ...

    def stop(self) -> None: ...


class BoardLauncher(Protocol):
    """Starts one kind of virtual board (a row of SIM_LAUNCHERS)."""

    @property
    def name(self) -> str: ...

    @property
    def description(self) -> str: ...

    def start(self, options: LaunchOptions) -> RunningBoard: ...


@dataclass
class ProcessBoard:
    """A board process that printed `PTY <path>` on its standard output."""

    process: subprocess.Popen[bytes]
    port_path: str
    rig_text: str | None = None
    stop_timeout_s: float = 3.0
    workdir: Path | None = None  # removed on stop
    _pending: bytes = b""

    def current_port(self) -> str:
        """Reads what the board printed since (`PTY <path>` after a reconnect, `DISCONNECTED`)
        without blocking, and returns the last pty it announced."""
        import selectors

        out = self.process.stdout
        if out is not None and not out.closed:
            with selectors.DefaultSelector() as sel:
                sel.register(out, selectors.EVENT_READ)
                while sel.select(timeout=0):
                    chunk = os.read(out.fileno(), 4096)
                    if not chunk:
                        break
                    self._pending += chunk
            *lines, self._pending = self._pending.split(b"\n")
            for line in lines:
                if line.startswith(b"PTY "):
                    self.port_path = line[4:].decode().strip()
                elif line.strip() == b"DISCONNECTED":
                    self.port_path = ""
        if self.process.poll() is not None:
            raise InputError(f"the virtual board exited with status {self.process.returncode}",
                             field=PORT_FIELD)
        if not self.port_path:
            # Never reopen the old /dev/pts/N: it may belong to another process by now.
            raise InputError("the virtual board's cable is pulled (no pty yet)", field=PORT_FIELD)
        return self.port_path

    def stop(self) -> None:
        p = self.process
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(self.stop_timeout_s)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(self.stop_timeout_s)
        for stream in (p.stdin, p.stdout, p.stderr):
            if stream is not None:
                stream.close()
        if self.workdir is not None:
            shutil.rmtree(self.workdir, ignore_errors=True)


def start_process_board(argv: Sequence[str], options: LaunchOptions,
                        rig_text: str | None = None,
                        workdir: Path | None = None) -> ProcessBoard:
    """Start `argv`, wait for the line `PTY /dev/pts/N` on its stdout, return the board.

    The board contract (issue 5): print `PTY <path>` (one line, flushed) once the pseudo-terminal
    is open and the firmware is running; serve the protocol on it; exit cleanly on SIGTERM. A
    board that pulls its cable prints `DISCONNECTED` (flushed) *before* closing the pty, and
    `PTY <new path>` when it is plugged back in (`ProcessBoard.current_port`).
    Anything else on stdout before that line is ignored; stderr is kept for error messages.
    """
    import selectors

    if not Path(argv[0]).exists() and shutil.which(argv[0]) is None:
        if workdir is not None:
            shutil.rmtree(workdir, ignore_errors=True)
        raise InputError(f"cannot start the virtual board {argv[0]}: No such file or directory",
                         field=PORT_FIELD)
    # Through the guard (board_guard.py): the board and its folder go when this process dies,
    # by any signal. Its stdin is a pipe only this process writes to.
    guard = [sys.executable, "-I", "-S", str(Path(__file__).with_name("board_guard.py")),
             "-" if workdir is None else str(workdir), "--", *argv]
    try:
        proc = subprocess.Popen(guard, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE)
    except OSError as exc:
        raise InputError(f"cannot start the virtual board {argv[0]}: {exc.strerror}",
                         field=PORT_FIELD) from None
    assert proc.stdout is not None
    deadline = time.monotonic() + options.start_timeout_s
    buf = b""
    with selectors.DefaultSelector() as sel:
        sel.register(proc.stdout, selectors.EVENT_READ)
        while time.monotonic() < deadline:
            if sel.select(timeout=0.1):
                chunk = os.read(proc.stdout.fileno(), 4096)
                if not chunk:
                    break
                buf += chunk
                for line in buf.splitlines():
                    if line.startswith(b"PTY "):
                        return ProcessBoard(proc, line[4:].decode().strip(), rig_text,
                                            workdir=workdir)
            elif proc.poll() is not None:
                break
    err = b""
    # Its stdout closed (or the deadline passed): a guard still running past the deadline
    # means the board announced nothing in time; otherwise it is exiting -- wait for its status.
    timed_out = proc.poll() is None and time.monotonic() >= deadline
    if timed_out:
        proc.terminate()  # the guard stops the board and removes its folder
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
    proc.wait(5)
    if proc.stdin is not None:
        proc.stdin.close()
    if proc.stderr is not None:
        err = proc.stderr.read()[-400:]
    if workdir is not None:
        shutil.rmtree(workdir, ignore_errors=True)
    why = (f"it announced no pty within {options.start_timeout_s:.0f} s" if timed_out
           else f"it exited with status {proc.returncode}")
    raise InputError(f"the virtual board {argv[0]} did not start: {why}"
                     + (f" ({err.decode(errors='replace').strip()})" if err else ""),
                     field=PORT_FIELD)


def _repo_root() -> Path:
    return Path(__file__).resolve().parents[2]


def prepare_motion(options: LaunchOptions, workdir: Path) -> tuple[Path, Path, str]:
    """Write the rig file and the accelerations CSV a virtual board plays (docs/design.md §4):
    the scenario's motion at the board's rate, on `options.rig_path` or the scenario's rig.
    With `options.motion_path` the given CSV and rig are used as they are (nothing generated)."""
    from jointangle.io.csv_formats import AccelData, Truth, read_accel_csv, write_accel_csv
    from jointangle.io.rig_file import write_rig
    from jointangle.model import read_checked_rig
    from jointangle.sim.scenarios import get_scenario, simulate

    # The rig is checked as `--rig` is (its geometry too: coincident sensors...) before the board
    # starts, and a given motion against it (columns, numbers) as `estimate` checks its input.
    if options.motion_path is not None:
        if options.rig_path is None:
            raise InputError("a motion CSV needs the rig it was made for", field="rig")
        text, checked = read_checked_rig(options.rig_path)
        if not options.motion_path.is_file():
            raise InputError("motion CSV not found", path=options.motion_path)
        read_accel_csv(options.motion_path, checked)
        return options.rig_path, options.motion_path, text
    rate = float(options.rate_hz or DEFAULT_FACTORY_RATE_HZ)
    rig = (read_checked_rig(options.rig_path)[1].with_sample_rate(rate)
           if options.rig_path is not None else get_scenario(options.scenario).rig(rate))
    sim = simulate(options.scenario, seed=options.seed, rate_hz=rate, seconds=options.seconds,
                   rig=rig)
    rig_path, motion = workdir / "rig.toml", workdir / "motion.csv"
    write_rig(sim.rig, rig_path)
    write_accel_csv(motion, sim.rig, AccelData(t=sim.t, readings=sim.readings,
                                               truth=Truth(sim.theta, sim.omega_a,
                                                           sim.omega_b)))
    return rig_path, motion, rig_path.read_text(encoding="utf-8")


OWNER_FILE = "host.pid"  # in a virtual board's work folder: the pid of the host that made it


def remove_orphaned_workdirs(tmp: Path, prefix: str) -> list[Path]:
    """Remove the work folders (tmp/PREFIX*) of virtual boards whose host is gone: normally the
    board's guard removes its folder when the host dies, this catches a guard killed with it.
    Folders without an owner file, or whose owner still runs, are left alone."""
    removed: list[Path] = []
    try:
        candidates = list(tmp.glob(prefix + "*"))
    except OSError:
        return removed
    for d in candidates:
        try:
            pid = int((d / OWNER_FILE).read_text(encoding="ascii").strip())
        except (OSError, ValueError):
            continue
        if pid == os.getpid() or _alive(pid):
            continue
        shutil.rmtree(d, ignore_errors=True)
        removed.append(d)
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's
    try:  # a zombie is gone too
        stat = Path(f"/proc/{pid}/stat").read_text(encoding="ascii")
    except OSError:
        return True
    return stat.rsplit(")", 1)[-1].split()[0] != "Z"


def _start_virtual_board(binary: Path, options: LaunchOptions, prefix: str,
                         trailing: Sequence[str] = ()) -> RunningBoard:
    """Both virtual boards: the rig and motion in a fresh work directory (removed if writing
    them fails), then `binary --rig R --motion M --baud B <board_args> <extra_args> <trailing>`."""
    import tempfile

    remove_orphaned_workdirs(Path(tempfile.gettempdir()), prefix)
    workdir = Path(tempfile.mkdtemp(prefix=prefix))
    try:
        (workdir / OWNER_FILE).write_text(f"{os.getpid()}\n", encoding="ascii")
        rig_path, motion, rig_text = prepare_motion(options, workdir)
    except BaseException:
        shutil.rmtree(workdir, ignore_errors=True)
        raise
    argv = [str(binary), "--rig", str(rig_path), "--motion", str(motion),
            "--baud", str(options.baud), *board_args(options), *options.extra_args, *trailing]
    return start_process_board(argv, options, rig_text, workdir)


@dataclass(frozen=True)
class NativeBoardLauncher:
    """`sim://native`: the firmware application compiled for x86, serving a pty.

    The board is the CMake target `target`; its binary is found through $JOINTANGLE_NATIVE_BOARD
    or under build/*/firmware/ (built first when a configured build tree exists). It is started
    as

        ja_native_board --rig RIG.toml --motion DATA.csv --baud B [--fast] [extra args]

    with the rig and the motion written by `prepare_motion` plus `board_args` (fast clock,
    motion loop, EEPROM file, faults, cable pull: firmware/platform/posix/README.md), and must
    follow `start_process_board`'s contract (print `PTY <path>`, serve the protocol, exit on
    SIGTERM).
    """

    name: str = "native"
    description: str = "the firmware application compiled for x86 on a pseudo-terminal"
    factory_rate_hz: int = 500  # app::kFactoryRateHz
    target: str = "ja_native_board"
    env: str = "JOINTANGLE_NATIVE_BOARD"
    root: Path = field(default_factory=_repo_root)

    def _missing(self, detail: str = "") -> InputError:
        return InputError(
            f"sim://native needs the native virtual board, CMake target `{self.target}`, "
            f"which is not built{detail}: build it with `cmake -S . -B build/native && cmake "
            f"--build build/native --target {self.target}`, set {self.env}, or name a port "
            "with --port", field=PORT_FIELD)

    def find_binary(self, build: bool = False) -> Path:
        return locate_built(f"firmware/**/{self.target}", env=self.env, target=self.target,
                            missing=self._missing, build=build, root=self.root,
                            executable=True)

    def start(self, options: LaunchOptions) -> RunningBoard:
        options = replace(options, rate_hz=options.rate_hz or self.factory_rate_hz)
        return _start_virtual_board(self.find_binary(build=options.build), options,
                                    "jointangle-native-")


@dataclass(frozen=True)
class AvrBoardLauncher:
    """`sim://avr`: the real AVR image run cycle-exactly in simavr (issue 6), its TWI bridged to
    the virtual devices and its USART0 to a pty (firmware/sim/avr_board/README.md).

    Two CMake artefacts: the board, target `ja_avr_board` (build/*/firmware/sim/), and the
    image `jointangle_mega2560.elf`, target `avr_images` (build/*/avr/); found through
    $JOINTANGLE_AVR_BOARD and $JOINTANGLE_AVR_IMAGE or under build/ (build/native first), built
    first when build/native is configured. Started as

        ja_avr_board --rig RIG.toml --motion DATA.csv --baud B [board_args] [extra] IMAGE.elf

    (the native board's options; --fast runs ahead only while the image streams).
    """

    name: str = "avr"
    description: str = "the AVR firmware image in simavr, UART bridged to a pty"
    factory_rate_hz: int = 250  # the Mega's (firmware/platform/avr/board/board.cpp)
    target: str = "ja_avr_board"
    env: str = "JOINTANGLE_AVR_BOARD"
    image: str = "jointangle_mega2560.elf"
    image_target: str = "avr_images"
    image_env: str = "JOINTANGLE_AVR_IMAGE"
    root: Path = field(default_factory=_repo_root)

    def _missing(self, what: str, target: str, env: str, detail: str) -> InputError:
        return InputError(
            f"sim://avr needs {what}, CMake target `{target}`, which is not built{detail}: "
            f"build it with `cmake -S . -B build/native && cmake --build build/native --target "
            f"{target}`, set {env}, or name a port with --port", field=PORT_FIELD)

    def _locate(self, what: str, pattern: str, target: str, env: str, build: bool) -> Path:
        return locate_built(pattern, env=env, target=target, build=build, root=self.root,
                            missing=lambda detail: self._missing(what, target, env, detail))

    def find_binary(self, build: bool = False) -> Path:
        return self._locate("the AVR virtual board", f"firmware/sim/{self.target}", self.target,
                            self.env, build)

    def find_image(self, build: bool = False) -> Path:
        return self._locate(f"the AVR image {self.image}", f"avr/{self.image}",
                            self.image_target, self.image_env, build)

    def start(self, options: LaunchOptions) -> RunningBoard:
        binary = self.find_binary(build=options.build)
        image = self.find_image(build=options.build)
        options = replace(options, rate_hz=options.rate_hz or self.factory_rate_hz)
        return _start_virtual_board(binary, options, "jointangle-avr-", (str(image),))


SIM_LAUNCHERS: Mapping[str, BoardLauncher] = MappingProxyType({
    "native": NativeBoardLauncher(),
    "avr": AvrBoardLauncher(),
})


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
    import serial

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
    try:
        target = os.path.realpath(path)
        pids = [d for d in os.listdir(proc) if d.isdigit() and int(d) != os.getpid()]
    except OSError:
        return ""
    found: list[str] = []
    for pid in pids:
        try:
            fds = os.listdir(proc / pid / "fd")
            if not any(os.readlink(proc / pid / "fd" / fd) == target for fd in fds):
                continue
            cmd = " ".join((proc / pid / "cmdline").read_bytes().replace(b"\0", b" ").decode(
                errors="replace").split())  # one line, whatever the arguments hold
        except OSError:
            continue
        found.append(f"pid {pid}: {cmd[:80]}" if cmd else f"pid {pid}")
    return f" ({'; '.join(found)})" if found else ""


def open_port(url: str | None = None, *, baud: int = DEFAULT_BAUD,
              launch: LaunchOptions | None = None,
              launchers: Mapping[str, BoardLauncher] = SIM_LAUNCHERS,
              detect: Callable[[], list[DetectedPort]] = detect_boards,
              timeout_s: float = READ_TIMEOUT_S) -> Connection:
    """Open what --port names (see the module docstring)."""
    resolved, what = resolve_url(url, detect)
    if resolved.startswith(SIM_PREFIX):
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

"""A virtual board as a process: what a started board offers (`RunningBoard`), what starts one
(`BoardLauncher`, a row of `launchers.SIM_LAUNCHERS`), and the board contract every virtual board
follows (`start_process_board`): print `PTY <path>` once its pseudo-terminal is open, serve the
protocol there, exit cleanly on SIGTERM. Each board runs behind `guard.py`, so it never outlives
the host that started it.

Importing this module has no side effects and it keeps no module state.
"""

from __future__ import annotations

import os
import selectors
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from jointangle.boards.options import PORT_FIELD, LaunchOptions
from jointangle.errors import InputError


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
    if not Path(argv[0]).exists() and shutil.which(argv[0]) is None:
        if workdir is not None:
            shutil.rmtree(workdir, ignore_errors=True)
        raise InputError(f"cannot start the virtual board {argv[0]}: No such file or directory",
                         field=PORT_FIELD)
    # Through the guard (guard.py): the board and its folder go when this process dies, by any
    # signal. Its stdin is a pipe only this process writes to.
    guard = [sys.executable, "-I", "-S", str(Path(__file__).with_name("guard.py")),
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

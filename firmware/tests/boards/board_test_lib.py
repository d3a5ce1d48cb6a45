"""Helpers shared by the virtual boards' ctest drivers beside this file (test_native_board.py,
test_avr_board.py, test_mega2560_image.py; registered with their targets in
firmware/platform/posix, firmware/sim and firmware/platform/avr).

- the rig and motion files the boards play (four ADXL345 behind the TCA9548A, a slow swing);
- the protocol: message ids, payload layouts and framing are the host's own `jointangle.protocol`
  (messages.py generated from protocol/messages.toml, the hand-written framing.py), which
  tests/protocol checks against the golden vectors in protocol/vectors/, as
  tests/cpp/protocol checks the firmware's; nothing about the wire format is written here;
- a board process: started with its options, its `PTY <path>` (and `DISCONNECTED`) lines read
  from stdout, the pty opened, raw bytes or whole frames read from it, stopped with SIGTERM.

The interpreter is CMake's JA_PYTHON (the project's .venv when scripts/setup.sh made it): the
repository's host/ is put on `sys.path` so jointangle need not be installed, but numpy must be.
"""

from __future__ import annotations

import math
import os
import random
import re
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "host"))
try:
    from jointangle.protocol import messages as msgs
    from jointangle.protocol.codec import decode_message, encode_message
    from jointangle.protocol.framing import Frame, StreamDecoder
except ImportError as e:  # numpy missing: CMake found a Python other than the project's
    sys.exit(f"{sys.executable} cannot import jointangle ({e}): run scripts/setup.sh (it makes "
             "the project's .venv), then configure again with -DJA_PYTHON= (empty: the .venv), "
             "or with -DJA_PYTHON=<a python3 with numpy>")

__all__ = ["BoardProcess", "Frame", "FrameReader", "command", "decode_message",
           "four_adxl345_rig", "kill_started", "msgs", "write_swing_motion"]


def four_adxl345_rig(name: str, rate_hz: int) -> str:
    """Links a and b with two ADXL345 each at 0x53, mux channels 0..3 (a.0, a.1, b.0, b.1)."""
    sensors = {"a": [(0.2525, 0), (0.025, 1)], "b": [(0.0475, 2), (0.275, 3)]}
    joints = {"a": "[0.3, 0.0]", "b": "[0.0, 0.0]"}
    text = f'name = "{name}"\nsample_rate_hz = {rate_hz}\n'
    for link, items in sensors.items():
        text += f"[links.{link}]\njoint = {joints[link]}\n"
        for x, channel in items:
            text += (f'[[links.{link}.sensors]]\nmodel = "adxl345"\nposition = [{x}, 0.0]\n'
                     f"mux_channel = {channel}\naddress = 0x53\nrange_g = 2\n")
    return text


def write_swing_motion(path: Path, seconds: float, rate: float) -> None:
    """a.0, a.1 still, b.0, b.1 swinging 0.3 rad at 0.5 Hz, all with 0.05 m/s² of noise (a
    noise-free input would read as frozen): columns t, a.0.x, ..., b.1.z."""
    rnd = random.Random(1)
    cols = ["t"] + [f"{s}.{ax}" for s in ("a.0", "a.1", "b.0", "b.1") for ax in "xyz"]
    with path.open("w") as f:
        f.write(",".join(cols) + "\n")
        for k in range(int(seconds * rate)):
            t = k / rate
            th = 0.3 * math.sin(2 * math.pi * 0.5 * t)
            row = [t]
            for s in range(4):
                ang = th if s >= 2 else 0.0
                row += [9.81 * math.sin(ang) + rnd.gauss(0, 0.05),
                        9.81 * math.cos(ang) + rnd.gauss(0, 0.05), rnd.gauss(0, 0.05)]
            f.write(",".join(f"{v:.6f}" for v in row) + "\n")


def command(msg: msgs.Message, seq: int) -> bytes:
    """A host command as a frame on the wire (t_us 0, as the host sends it)."""
    return encode_message(msg, seq, 0)


class FrameReader:
    """Frames from a pty, through the host's streaming decoder (strict: a hello built from
    another protocol/messages.toml raises). `bad` counts what a board must never send: damaged
    frames (COBS, length, CRC, version) and frames the sequence accounting drops (duplicate or
    stale)."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.decoder = StreamDecoder(strict=True)

    @property
    def bad(self) -> int:
        s = self.decoder.stats
        return (s.crc_errors + s.malformed + s.oversize + s.version_errors + s.duplicates
                + s.stale)

    def read(self, until: Callable[[list[Frame]], bool], timeout: float) -> list[Frame]:
        """Frames until `until(frames so far)` holds or `timeout` s have passed."""
        got: list[Frame] = []
        deadline = time.monotonic() + timeout
        while not until(got) and time.monotonic() < deadline:
            r, _, _ = select.select([self.fd], [], [], 0.1)
            if r:
                got += self.decoder.feed(os.read(self.fd, 65536))
        return got


class BoardProcess:
    """A virtual board started with `argv`; waits for its `PTY <path>` line and opens the pty."""

    # Killed by kill_started() if a check failed midway.
    started: ClassVar[list[subprocess.Popen[bytes]]] = []

    def __init__(self, argv: list[str], timeout: float = 20.0) -> None:
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        BoardProcess.started.append(self.proc)
        self.fd = -1
        self.buf = b""
        self.open_pty(self.stdout_line(b"PTY ", timeout))

    def stdout_line(self, prefix: bytes, timeout: float = 20.0) -> bytes:
        """The rest of the next stdout line that starts with `prefix` (others are skipped)."""
        assert self.proc.stdout is not None
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            r, _, _ = select.select([self.proc.stdout], [], [], 0.2)
            if r:
                line = self.proc.stdout.readline()
                if line.startswith(prefix):
                    return line[len(prefix):].strip()
                if not line:
                    break
        raise AssertionError(f"no {prefix!r} line from the board (status {self.proc.poll()})")

    def open_pty(self, path: bytes) -> None:
        if self.fd >= 0:
            os.close(self.fd)
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        self.buf = b""

    def read_until(self, pattern: re.Pattern[bytes], timeout: float = 20.0) -> re.Match[bytes]:
        """Raw bytes up to the first match of `pattern` (consumed with it)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            m = pattern.search(self.buf)
            if m:
                self.buf = self.buf[m.end():]
                return m
            r, _, _ = select.select([self.fd], [], [], 0.2)
            if r:
                self.buf += os.read(self.fd, 4096)
        raise AssertionError(f"{pattern.pattern!r} not seen; tail {self.buf[-120:]!r}")

    def read_bytes(self, n: int, timeout: float = 20.0) -> bytes:
        """The next `n` raw bytes (fewer after `timeout` s)."""
        deadline = time.monotonic() + timeout
        while len(self.buf) < n and time.monotonic() < deadline:
            r, _, _ = select.select([self.fd], [], [], 0.2)
            if r:
                self.buf += os.read(self.fd, 4096)
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def send(self, data: bytes) -> None:
        os.write(self.fd, data)

    def stop(self, timeout: float = 20.0) -> tuple[int, bytes]:
        """SIGTERM; (exit status, stderr). A board that does not end in `timeout` s is killed
        and the check fails."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            rc = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            raise AssertionError(f"the board did not end on SIGTERM within {timeout} s") from None
        finally:
            if self.fd >= 0:
                os.close(self.fd)
                self.fd = -1
        assert self.proc.stderr is not None
        return rc, self.proc.stderr.read()


def kill_started() -> None:
    """Kills every board still running (after a failed check)."""
    for proc in BoardProcess.started:
        if proc.poll() is None:
            proc.kill()
            proc.wait()

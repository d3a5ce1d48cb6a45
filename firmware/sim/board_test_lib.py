"""Helpers shared by the virtual boards' ctest drivers (standard library only, so the ctests stay
self-contained): firmware/platform/posix/test_native_board.py, firmware/sim/avr_board/
test_avr_board.py and firmware/platform/avr/test_mega2560_image.py import this file through
`sys.path` from their own location.

- the rig and motion files the boards play (four ADXL345 behind the TCA9548A, a slow swing);
- the frame format (protocol/README.md): COBS, XOR 0x55, CRC-16/CCITT-FALSE, 0x00 delimiter;
- a board process: started with its options, its `PTY <path>` (and `DISCONNECTED`) lines read
  from stdout, the pty opened, raw bytes or whole frames read from it, stopped with SIGTERM.
"""

from __future__ import annotations

import binascii
import math
import os
import random
import re
import select
import signal
import struct
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import ClassVar

Frame = tuple[int, int, int, bytes]  # msg_id, seq, t_us, payload


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


def cobs_decode(data: bytes) -> bytes | None:
    out, i = bytearray(), 0
    while i < len(data):
        code = data[i]
        if code == 0 or i + code > len(data):
            return None
        out += data[i + 1:i + code]
        i += code
        if code < 0xFF and i < len(data):
            out.append(0)
    return bytes(out)


def cobs_encode(data: bytes) -> bytes:
    out, block = bytearray(), bytearray()
    for b in data:
        if b == 0:
            out += bytes([len(block) + 1]) + block
            block = bytearray()
        else:
            block.append(b)
            if len(block) == 254:
                out += bytes([255]) + block
                block = bytearray()
    out += bytes([len(block) + 1]) + block
    return bytes(out)


def encode(msg_id: int, seq: int, payload: bytes = b"") -> bytes:
    """A host frame: version 1, msg_id, seq, t_us 0, payload, CRC; XOR 0x55, COBS, 0x00."""
    body = struct.pack("<BBHI", 1, msg_id, seq, 0) + payload
    body += struct.pack("<H", binascii.crc_hqx(body, 0xFFFF))
    return cobs_encode(bytes(b ^ 0x55 for b in body)) + b"\x00"


def decode(raw: bytes) -> Frame | None:
    """One frame without its delimiter; None when broken (COBS, length or CRC)."""
    dec = cobs_decode(raw)
    if dec is None or len(dec) < 10:
        return None
    body = bytes(b ^ 0x55 for b in dec)
    if binascii.crc_hqx(body[:-2], 0xFFFF) != struct.unpack("<H", body[-2:])[0]:
        return None
    _, msg_id, seq, t_us = struct.unpack("<BBHI", body[:8])
    return msg_id, seq, t_us, body[8:-2]


class FrameReader:
    """Good frames from a pty as (msg_id, seq, t_us, payload); counts the broken ones."""

    def __init__(self, fd: int) -> None:
        self.fd, self.buf, self.bad = fd, b"", 0

    def read(self, until: Callable[[list[Frame]], bool], timeout: float) -> list[Frame]:
        """Frames until `until(frames so far)` holds or `timeout` s have passed."""
        got: list[Frame] = []
        deadline = time.monotonic() + timeout
        while not until(got) and time.monotonic() < deadline:
            r, _, _ = select.select([self.fd], [], [], 0.1)
            if not r:
                continue
            self.buf += os.read(self.fd, 65536)
            *done, self.buf = self.buf.split(b"\x00")
            for raw in done:
                frame = decode(raw)
                if frame is None:
                    self.bad += 1
                else:
                    got.append(frame)
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

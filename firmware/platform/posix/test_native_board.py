"""ctest firmware.native_board_hello: start ja_native_board on a short motion CSV (real time and
--fast), check the hello arrives on the pty it announces, get_info is answered by hello + ack, a
stream has consecutive seq, reset restarts the firmware (hello seq 0), SIGTERM ends it with
status 0, and --fault a.1:nack@0 shows in hello (nack, chip id 0). Standard library only
(framing: protocol/README.md).

usage: test_native_board.py PATH/TO/ja_native_board
"""

from __future__ import annotations

import binascii
import math
import os
import random
import select
import signal
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RIG = """name = "ctest"
sample_rate_hz = 500
[links.a]
joint = [0.3, 0.0]
[[links.a.sensors]]
model = "adxl345"
position = [
    0.25,
    0.0,
]  # multi-line array, as the host writes it
mux_channel = 0
address = 0x53
range_g = 2
[[links.a.sensors]]
model = "adxl345"
position = [0.05, 0.0]
mux_channel = 1
address = 83
range_g = 2
[links.b]
joint = [0.0, 0.0]
[[links.b.sensors]]
model = "adxl345"
position = [0.0475, 0.0]
rotation_deg = 0.0
mux_channel = 2
range_g = 2
[[links.b.sensors]]
model = "adxl345"
position = [0.275, 0.0]
mux_channel = 3
range_g = 2
S = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
offset = [0.0, 0.0, 0.0]
"""

HELLO, SAMPLE_ESTIMATE, ACK, GET_INFO, START_STREAM = 0x01, 0x04, 0x07, 0x40, 0x41
RESET = 0x49


def write_motion(path: Path, seconds: float = 1.0, rate: float = 500.0) -> None:
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
        if code == 0 or i + code > len(data) + 0:
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
    body = struct.pack("<BBHI", 1, msg_id, seq, 0) + payload
    body += struct.pack("<H", binascii.crc_hqx(body, 0xFFFF))
    return cobs_encode(bytes(b ^ 0x55 for b in body)) + b"\x00"


HELLO_SENSORS_AT = 25  # hello payload: 25 bytes of fields, then the sensor count
PAYLOADS: dict[int, bytes] = {}  # the last payload of each message id


def frames(fd: int, want: set[int], timeout: float,
           count: int = 0) -> list[tuple[int, int]]:
    """Reads until every msg id in `want` was seen and `count` good frames arrived; returns
    (msg_id, seq) of the good frames."""
    buf = b""
    seen: set[int] = set()
    got: list[tuple[int, int]] = []
    deadline = time.monotonic() + timeout
    while (not want <= seen or len(got) < count) and time.monotonic() < deadline:
        r, _, _ = select.select([fd], [], [], 0.1)
        if not r:
            continue
        buf += os.read(fd, 4096)
        *done, buf = buf.split(b"\x00")
        for raw in done:
            dec = cobs_decode(raw)
            if dec is None or len(dec) < 10:
                continue
            body = bytes(b ^ 0x55 for b in dec)
            if binascii.crc_hqx(body[:-2], 0xFFFF) != struct.unpack("<H", body[-2:])[0]:
                continue
            _, msg_id, seq, _ = struct.unpack("<BBHI", body[:8])
            PAYLOADS[msg_id] = body[8:-2]
            got.append((msg_id, seq))
            seen.add(msg_id)
    assert want <= seen, f"expected messages {want}, got {got[:20]}"
    return got


def run(board: str, work: Path, fast: bool) -> None:
    argv = [board, "--rig", str(work / "rig.toml"), "--motion", str(work / "motion.csv"),
            "--baud", "500000", "--eeprom", str(work / "eeprom.bin")] + (["--fast"] if fast else [])
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline().decode()
        assert line.startswith("PTY /dev/"), f"no PTY line: {line!r}"
        fd = os.open(line[4:].strip(), os.O_RDWR | os.O_NOCTTY)
        try:
            got = frames(fd, {HELLO}, 10.0)
            assert got[0] == (HELLO, 0), got[:3]
            os.write(fd, encode(GET_INFO, 1))
            got = frames(fd, {HELLO, ACK}, 10.0)
            ids = [m for m, _ in got]
            assert ids.index(HELLO) < ids.index(ACK), ids
            # 200 frames of a sample_estimate stream: consecutive seq, nothing lost.
            os.write(fd, encode(START_STREAM, 2, struct.pack("<BH", SAMPLE_ESTIMATE, 0)))
            got = frames(fd, {SAMPLE_ESTIMATE}, 10.0, count=210)
            seqs = [q for m, q in got if m == SAMPLE_ESTIMATE]
            assert len(seqs) > 150 and seqs == list(range(seqs[0], seqs[0] + len(seqs))), seqs
            # reset: ack, then the firmware restarts (App::Begin again): hello with seq 0.
            os.write(fd, encode(RESET, 3, bytes([0])))
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline:
                got = frames(fd, {HELLO}, 10.0)
                if (HELLO, 0) in got:
                    break
            assert (HELLO, 0) in got, got[-5:]
        finally:
            os.close(fd)
        proc.send_signal(signal.SIGTERM)
        rc = proc.wait(timeout=10)
        err = proc.stderr.read().decode() if proc.stderr else ""
        assert rc == 0, f"exit status {rc}: {err}"
        sys.stdout.write(f"{'fast' if fast else 'real time'}: ok; {err.strip()}\n")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def run_fault(board: str, work: Path) -> None:
    """--fault a.1:nack@0: the sensor refuses its address from power-up; hello says so (status
    nack, chip id 0) and the others are fine."""
    argv = [board, "--rig", str(work / "rig.toml"), "--motion", str(work / "motion.csv"),
            "--fast", "--fault", "a.1:nack@0"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline().decode()
        assert line.startswith("PTY /dev/"), f"no PTY line: {line!r}"
        fd = os.open(line[4:].strip(), os.O_RDWR | os.O_NOCTTY)
        try:
            frames(fd, {HELLO}, 10.0)
        finally:
            os.close(fd)
        p = PAYLOADS[HELLO]
        n = p[HELLO_SENSORS_AT]
        sensors = [p[HELLO_SENSORS_AT + 1 + 7 * i:HELLO_SENSORS_AT + 8 + 7 * i] for i in range(n)]
        chip, status = [s[4] for s in sensors], [s[6] for s in sensors]
        assert n == 4 and status[1] & 0x01 and chip[1] == 0, (chip, status)
        assert all(status[i] & 0x0F == 0 and chip[i] == 0xE5 for i in (0, 2, 3)), (chip, status)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
        sys.stdout.write("fault at power-up: ok\n")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def main() -> int:
    board = sys.argv[1]
    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        (work / "rig.toml").write_text(RIG)
        write_motion(work / "motion.csv")
        run(board, work, fast=False)
        assert (work / "eeprom.bin").stat().st_size == 4096
        run(board, work, fast=True)  # a second start keeps the EEPROM file
        run_fault(board, work)
    return 0


if __name__ == "__main__":
    sys.exit(main())

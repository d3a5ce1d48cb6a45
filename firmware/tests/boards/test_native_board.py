"""ctest firmware.native_board_hello: start ja_native_board on a short motion CSV (real time and
--fast), check the hello arrives on the pty it announces, get_info is answered by hello + ack, a
stream has consecutive seq, reset restarts the firmware (hello seq 0), SIGTERM ends it with
status 0, and --fault a.1:nack@0 shows in hello (nack, chip id 0). Messages, layouts and
framing are the host's generated protocol module (through board_test_lib.py beside this file,
with the board process).

usage: test_native_board.py PATH/TO/ja_native_board
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from board_test_lib import (
    BoardProcess,
    FrameReader,
    command,
    decode_message,
    kill_started,
    msgs,
    write_swing_motion,
)

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

HELLO, SAMPLE_ESTIMATE, ACK = msgs.Hello.MSG_ID, msgs.SampleEstimate.MSG_ID, msgs.Ack.MSG_ID
ADXL345_DEVID = 0xE5  # the part's DEVID register (firmware/drivers)
LAST: dict[int, msgs.Message] = {}  # the last message of each id


def frames(rd: FrameReader, want: set[int], timeout: float,
           count: int = 0) -> list[tuple[int, int]]:
    """Reads until every msg id in `want` was seen and `count` good frames arrived; returns
    (msg_id, seq) of the good frames."""
    got = rd.read(lambda g: want <= {f.msg_id for f in g} and len(g) >= count, timeout)
    for f in got:
        LAST[f.msg_id] = decode_message(f)
    assert want <= {f.msg_id for f in got}, f"expected messages {want}, got {got[:20]}"
    return [(f.msg_id, f.seq) for f in got]


def board_argv(board: str, work: Path, *extra: str) -> list[str]:
    return [board, "--rig", str(work / "rig.toml"), "--motion", str(work / "motion.csv"), *extra]


def run(board: str, work: Path, fast: bool) -> None:
    b = BoardProcess(board_argv(board, work, "--baud", "500000", "--eeprom",
                                str(work / "eeprom.bin"), *(["--fast"] if fast else [])))
    rd = FrameReader(b.fd)
    got = frames(rd, {HELLO}, 10.0)
    assert got[0] == (HELLO, 0), got[:3]
    b.send(command(msgs.GetInfo(), 1))
    got = frames(rd, {HELLO, ACK}, 10.0)
    ids = [m for m, _ in got]
    assert ids.index(HELLO) < ids.index(ACK), ids
    # 200 frames of a sample_estimate stream: consecutive seq, nothing lost.
    b.send(command(msgs.StartStream(mode=msgs.StreamMode.SAMPLE_ESTIMATE, status_interval_ms=0,
                                    every=1), 2))
    got = frames(rd, {SAMPLE_ESTIMATE}, 10.0, count=210)
    seqs = [q for m, q in got if m == SAMPLE_ESTIMATE]
    assert len(seqs) > 150 and seqs == list(range(seqs[0], seqs[0] + len(seqs))), seqs
    # reset: ack, then the firmware restarts (App::Begin again): hello with seq 0.
    b.send(command(msgs.Reset(kind=msgs.ResetKind.REBOOT), 3))
    got4 = rd.read(lambda g: any((f.msg_id, f.seq) == (HELLO, 0) for f in g), 10.0)
    assert any((f.msg_id, f.seq) == (HELLO, 0) for f in got4), \
        [(f.msg_id, f.seq) for f in got4[-5:]]
    rc, err = b.stop(10)
    assert rc == 0, f"exit status {rc}: {err.decode()}"
    sys.stdout.write(f"{'fast' if fast else 'real time'}: ok; {err.decode().strip()}\n")


def run_fault(board: str, work: Path) -> None:
    """--fault a.1:nack@0: the sensor refuses its address from power-up; hello says so (status
    nack, chip id 0) and the others are fine."""
    b = BoardProcess(board_argv(board, work, "--fast", "--fault", "a.1:nack@0"))
    frames(FrameReader(b.fd), {HELLO}, 10.0)
    hello = LAST[HELLO]
    assert isinstance(hello, msgs.Hello)
    chip = [s.chip_id for s in hello.sensors]
    status = [msgs.SensorStatus(s.status) for s in hello.sensors]
    faults = (msgs.SensorStatus.NACK | msgs.SensorStatus.WRONG_ID | msgs.SensorStatus.SATURATED
              | msgs.SensorStatus.FROZEN)
    assert len(hello.sensors) == 4 and status[1] & msgs.SensorStatus.NACK and chip[1] == 0, \
        (chip, status)
    assert all(not status[i] & faults and chip[i] == ADXL345_DEVID for i in (0, 2, 3)), \
        (chip, status)
    assert b.stop(10)[0] == 0
    sys.stdout.write("fault at power-up: ok\n")


def main() -> int:
    board = sys.argv[1]
    try:
        with tempfile.TemporaryDirectory() as d:
            work = Path(d)
            (work / "rig.toml").write_text(RIG)
            write_swing_motion(work / "motion.csv", 1.0, 500.0)
            run(board, work, fast=False)
            assert (work / "eeprom.bin").stat().st_size == 4096
            run(board, work, fast=True)  # a second start keeps the EEPROM file
            run_fault(board, work)
    finally:
        kill_started()
    return 0


if __name__ == "__main__":
    sys.exit(main())

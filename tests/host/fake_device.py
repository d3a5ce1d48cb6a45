"""A protocol-speaking fake device on a pseudo-terminal, for the host-side tests.

It answers get_info with hello (then ack), acks every other command, and while streaming sends
`sample_estimate` frames paced at its rate (plus a `status` frame after start_stream and every
`status_every` samples), built with the protocol codec. Its data is a table of raw counts and
estimates (see `FakeData`); start_stream plays the table from row 0 as a filter that has been
running since boot (no `reset`, like the firmware), set_filter and restart_filter restart it at
row 0 with health `reset`, and so does running off the table's end. Faults it injects, by stream
frame ordinal: lost frames (seq consumed, nothing written), one corrupted byte (a CRC error), and a
disconnect (the pty closes: reads on the host fail). With `reconnect_after_s` it reappears on a
new pty behind the same symlink, keeping its sequence counter (a cable pulled and plugged back
in). `late` holds commands back while it streams (handled, and acknowledged, only after so many
more stream frames): the interleavings a slow host or a busy board gives, made deterministic.

The host opens `fake.path` (a symlink to the current /dev/pts/N) with serial_for_url, exactly as
it opens a real port.
"""

from __future__ import annotations

import fcntl
import os
import select
import struct
import sys
import termios
import threading
import time
import tty
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import decode_message, encode_message
from jointangle.protocol.framing import Frame, StreamDecoder, decode_stream
from jointangle.rig import Rig


@dataclass
class FakeData:
    """What the fake streams: counts (T, n, 3) and θ (Q24), ω (Q16) per row."""

    counts: np.ndarray
    theta_q24: np.ndarray
    omega_a_q16: np.ndarray
    omega_b_q16: np.ndarray
    rate_hz: int
    sensors: tuple[msgs.HelloSensor, ...]
    sensor_status: np.ndarray | None = None  # (T, n) status bits, default 0


@dataclass
class FakeFaults:
    drop: frozenset[int] = frozenset()  # stream frame ordinals never written (seq consumed)
    corrupt: frozenset[int] = frozenset()  # ordinals written with one byte changed
    disconnect_after: int | None = None  # close the pty after this many stream frames
    reconnect_after_s: float | None = None  # then reappear this much later
    protocol_version: int = msgs.PROTOCOL_VERSION
    schema_hash: int = msgs.SCHEMA_HASH
    # Link faults by stream frame ordinal, each on an intact frame: "duplicate" (written twice),
    # "swap" (written after the next one), "stale" (followed by a copy of the frame written
    # STALE_AGE ordinals earlier), "version" (followed by a valid frame of protocol version 2),
    # "unknown" (followed by a frame of an unknown message id, which takes a sequence number).
    inject: dict[int, str] = field(default_factory=dict)
    # Commands (by name) the fake handles only after this many more stream frames when one
    # arrives while it streams, e.g. {"restart_filter": 3}: the frames a board streams between
    # the start_stream ack and a restart_filter that a loaded host sends late (or that the board
    # reads after a few loops). Commands behind a held one wait for it (order is kept).
    late: dict[str, int] = field(default_factory=dict)


STALE_AGE = 300  # ordinals back: older than the host's reorder window
UNKNOWN_ID = 0x3E  # a message id no schema defines


@dataclass
class FakeCounts:
    frames_written: int = 0  # intact frames written (what a receiver must accept)
    stream_frames: int = 0  # sample_estimate ordinals used (written, dropped or corrupted)
    dropped: int = 0
    corrupted: int = 0
    injected: dict[str, int] = field(default_factory=dict)  # link faults injected, by kind
    disconnects: int = 0
    connections: int = 0
    commands: list[str] = field(default_factory=list)


def corrupt_frame(frame: bytes) -> bytes:
    """The frame with one byte changed so that it decodes as exactly one CRC error."""
    for i in range(len(frame) // 2, len(frame) - 1):
        for flip in (0x01, 0x02, 0x04):
            b = frame[i] ^ flip
            if b == 0:
                continue
            bad = frame[:i] + bytes([b]) + frame[i + 1:]
            frames, st = decode_stream(bad)
            if not frames and st.crc_errors == 1 and st.malformed == 0:
                return bad
    raise AssertionError("no single-byte corruption gives a CRC error")


PORT_ENV = "JOINTANGLE_TEST_PORT"


def device_targets() -> list[str]:
    """The targets the device tests run against: those that exist (nothing is skipped).

    "fake" (this module) always; "sim://native" once its binary is built (or named in
    $JOINTANGLE_NATIVE_BOARD); "env" when $JOINTANGLE_TEST_PORT names a port (a real board,
    /dev/ttyACM0, or any pyserial URL) -- pyserial's PORT pattern."""
    from jointangle.boards.launchers import NativeBoardLauncher
    from jointangle.errors import InputError

    out = ["fake"]
    try:
        NativeBoardLauncher().find_binary(build=False)
        out.append("sim://native")
    except InputError:
        pass
    if os.environ.get(PORT_ENV):
        out.append("env")
    return out


def _unread(fd: int) -> int:
    """Bytes written to the pty that the host has not read yet."""
    buf = fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0")
    return int(struct.unpack("i", buf)[0])


def data_from_counts(rig: Rig, counts: np.ndarray, perturb_deg: float = 0.0) -> FakeData:
    """FakeData for raw counts (T, n, 3) on `rig`, θ computed by `mirror` as the host verifies
    it (plus `perturb_deg`)."""
    from jointangle.device.calibration_map import DeviceMaps
    from jointangle.device.rig import device_rig
    from jointangle.device.verify import mirror_theta

    rate_hz = round(rig.sample_rate_hz)
    models = {"adxl345": msgs.SensorModel.ADXL345, "adxl357": msgs.SensorModel.ADXL357,
              "bno055": msgs.SensorModel.BNO055}
    sensors = tuple(msgs.HelloSensor(link=0 if link == "a" else 1, model=models[s.model],
                                     mux_channel=s.mux_channel, address=s.address, chip_id=0xE5,
                                     range_g=s.range_g, status=0)
                    for link, _, s in rig.all_sensors())
    hello = msgs.Hello(msgs.PROTOCOL_VERSION, msgs.SCHEMA_HASH, 0, 9, 1, b"", msgs.Board.NATIVE,
                       rate_hz, 0, 0, sensors)
    drig = device_rig(rig, hello)
    theta = mirror_theta(drig, DeviceMaps.from_rig(drig), counts, (0, 1, 2, 3))
    theta = theta + np.radians(perturb_deg)
    q24 = np.floor(theta * 2**24 + 0.5).astype(np.int64)
    w = np.zeros(len(q24), dtype=np.int64)
    return FakeData(counts, q24, w, w, rate_hz, sensors)


def make_data(seconds: float = 3.0, rate_hz: int = 500, perturb_deg: float = 0.0,
              scenario: str = "gravity-slow-periodic") -> tuple[FakeData, str]:
    """Counts from a simulated gravity rig and estimates computed by `mirror` exactly as the
    host verifies them (plus `perturb_deg` on θ); returns the data and the rig's TOML."""
    from jointangle.device.calibration_map import counts_from_readings
    from jointangle.rig import dump_rig
    from jointangle.sim.scenarios import gravity_rig, simulate

    rig = gravity_rig(rate_hz)
    sim = simulate(scenario, seed=1, rate_hz=rate_hz, seconds=seconds, rig=rig)
    counts = counts_from_readings(rig, sim.readings)
    return data_from_counts(rig, counts, perturb_deg), dump_rig(rig)


class FakeDevice:
    def __init__(self, data: FakeData, directory: Path, faults: FakeFaults | None = None,
                 name: str = "fake-tty") -> None:
        self.data = data
        self.faults = faults or FakeFaults()
        self.path = directory / name
        self.counts = FakeCounts()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="fake-device", daemon=True)
        self._master = -1
        self._slave = -1
        self._out = bytearray()
        self._seq = 0
        self._streaming = False
        self._row = 0
        self._restart = False
        self._t0 = 0.0
        self._sent_since_start = 0
        self._mode = 0
        self._status_every = 250
        self._boot = time.monotonic()
        self._lock = threading.Lock()
        self._history: dict[int, bytes] = {}  # stream frames by ordinal (for "stale")
        self._swapped = b""  # a frame held back by "swap"
        # Commands held back by `late`: (stream frames to go, command frame, command).
        self._held: list[tuple[int, Frame, msgs.Message]] = []

    # lifecycle -------------------------------------------------------------------------
    def __enter__(self) -> FakeDevice:
        self._open_pty()
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self._close_pty()
        self.path.unlink(missing_ok=True)

    def _open_pty(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line discipline: a serial line
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        tmp = self.path.with_suffix(".new")
        tmp.unlink(missing_ok=True)
        tmp.symlink_to(os.ttyname(slave))
        tmp.replace(self.path)
        self._decoder = StreamDecoder()
        self._out.clear()
        self._held.clear()  # (commands sent to the pty before it closed are gone with it)
        self._streaming = False
        self.counts.connections += 1

    def _close_pty(self) -> None:
        for fd in (self._master, self._slave):
            if fd >= 0:
                os.close(fd)
        self._master = self._slave = -1

    # frames ----------------------------------------------------------------------------
    def _next_seq(self) -> int:
        s = self._seq
        self._seq = (self._seq + 1) & 0xFFFF
        return s

    def _t_us(self) -> int:
        return int((time.monotonic() - self._boot) * 1e6) & 0xFFFFFFFF

    def _slot_us(self) -> int:
        start_us = int((self._t0 - self._boot) * 1e6)
        period_us = 1_000_000 // self.data.rate_hz
        return (start_us + (self._sent_since_start - 1) * period_us) & 0xFFFFFFFF

    def _send(self, msg: msgs.Message) -> None:
        self._out += encode_message(msg, self._next_seq(), self._t_us())
        self.counts.frames_written += 1

    def hello(self) -> msgs.Hello:
        f = self.faults
        return msgs.Hello(protocol_version=f.protocol_version, schema_hash=f.schema_hash,
                          firmware_major=0, firmware_minor=9, firmware_patch=1,
                          build=b"fake-1".ljust(12, b"\x00"), board=msgs.Board.NATIVE,
                          sample_rate_hz=self.data.rate_hz, stream_mode=self._mode,
                          eeprom=msgs.EepromState.OK, sensors=self.data.sensors)

    def _status_bits(self, row: int) -> list[int]:
        st = self.data.sensor_status
        n = len(self.data.sensors)
        return [0] * n if st is None else [int(v) for v in st[row]]

    def _send_status(self) -> None:
        bits = self._status_bits(self._row % len(self.data.counts))
        self._send(msgs.Status(
            uptime_ms=int((time.monotonic() - self._boot) * 1000) & 0xFFFFFFFF, loop_overruns=0,
            uart_drops=0, loop_rate_hz=self.data.rate_hz, idle_permille=600,
            eeprom=msgs.EepromState.OK, stream_mode=self._mode, rx_errors=0,
            sensors=tuple(msgs.StatusSensor(0, 0, 0, int(b & msgs.SensorStatus.FROZEN) >> 3, b)
                          for b in bits)))

    def _handle(self, data: bytes) -> None:
        for fr in self._decoder.feed(data):
            try:
                cmd = decode_message(fr)
            except ValueError:
                continue
            late = self.faults.late.get(cmd.NAME, 0) if self._streaming else 0
            if self._held or late:
                self._held.append((late, fr, cmd))
                continue
            self._command(fr, cmd)

    def _release_held(self) -> None:
        """After a stream frame: the held commands whose frames have gone, in order."""
        if self._held:
            left, fr, cmd = self._held[0]
            self._held[0] = (left - 1, fr, cmd)
        while self._held and self._held[0][0] <= 0:
            _, fr, cmd = self._held.pop(0)
            self._command(fr, cmd)

    def _command(self, fr: Frame, cmd: msgs.Message) -> None:
        self.counts.commands.append(cmd.NAME)
        if isinstance(cmd, msgs.GetInfo):
            if self.faults.protocol_version != msgs.PROTOCOL_VERSION:
                from jointangle.protocol.codec import encode_payload
                from jointangle.protocol.framing import encode_frame

                self._out += encode_frame(msgs.Hello.MSG_ID, self._next_seq(), self._t_us(),
                                          encode_payload(self.hello()),
                                          version=self.faults.protocol_version)
                return
            self._send(self.hello())
        ack = msgs.Ack(command_id=fr.msg_id, command_seq=fr.seq, error=msgs.ErrorCode.OK)
        self._send(ack)
        if isinstance(cmd, msgs.StartStream):
            self._mode = cmd.mode
            self._streaming = True
            self._row = 0
            self._t0 = time.monotonic()
            self._sent_since_start = 0
            if cmd.mode & msgs.StreamMode.STATUS:
                self._send_status()
        elif isinstance(cmd, msgs.StopStream):
            self._streaming = False
            self._mode = 0
        elif isinstance(cmd, msgs.SetFilter | msgs.RestartFilter):
            self._restart = True
            self._row = 0

    def _sample(self) -> None:
        d = self.data
        ordinal = self.counts.stream_frames
        self.counts.stream_frames += 1
        if self._row >= len(d.counts):
            self._row = 0
            self._restart = True
        row = self._row
        self._row += 1
        health = msgs.FilterHealth.RUNNING
        if row < 2 * d.rate_hz:
            health |= msgs.FilterHealth.STARTUP
        if self._restart:
            health |= msgs.FilterHealth.RESET
            self._restart = False
        bits = self._status_bits(row)
        msg = msgs.SampleEstimate(
            theta=int(d.theta_q24[row]), omega_a=int(d.omega_a_q16[row]),
            omega_b=int(d.omega_b_q16[row]), health=int(health),
            sensors=tuple(msgs.SampleEstimateSensor(int(c[0]), int(c[1]), int(c[2]), 1, b)
                          for c, b in zip(d.counts[row], bits, strict=True)))
        seq = self._next_seq()
        if ordinal in self.faults.drop:
            self.counts.dropped += 1
        else:
            # t_us = the sample's grid slot, as the firmware stamps it (APP.md "Timing"): the
            # host derives the filter's step periods from it.
            frame = encode_message(msg, seq, self._slot_us())
            if ordinal in self.faults.corrupt:
                self.counts.corrupted += 1
                frame = corrupt_frame(frame)
            else:
                self.counts.frames_written += 1
            self._out += self._inject(ordinal, frame)
        if self._mode & msgs.StreamMode.STATUS and (row + 1) % self._status_every == 0:
            self._send_status()

    def _inject(self, ordinal: int, frame: bytes) -> bytes:
        """The bytes to write for this stream frame, with its injected link fault."""
        from jointangle.protocol.framing import encode_frame

        self._history[ordinal] = frame
        self._history.pop(ordinal - STALE_AGE - 1, None)
        out = frame + self._swapped  # a frame held back by "swap" goes after this one
        self._swapped = b""
        kind = self.faults.inject.get(ordinal)
        if kind is None:
            return out
        self.counts.injected[kind] = self.counts.injected.get(kind, 0) + 1
        if kind == "duplicate":
            return out + frame
        if kind == "swap":
            self._swapped, out = out, b""  # (a swap right after a swap keeps both back)
            return out
        if kind == "stale":
            return out + self._history[ordinal - STALE_AGE]
        if kind == "version":
            return out + encode_frame(msgs.SampleEstimate.MSG_ID, self._seq, self._t_us(),
                                      b"\x01" * 20, version=2)
        if kind == "unknown":
            self.counts.frames_written += 1
            return out + encode_frame(UNKNOWN_ID, self._next_seq(), self._t_us(), b"\x07" * 4)
        raise ValueError(f"unknown fault {kind!r}")

    # thread ----------------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stop.is_set():
            if self._master < 0:
                time.sleep(0.005)
                continue
            r, _, _ = select.select([self._master], [], [], 0.002)
            if r:
                try:
                    data = os.read(self._master, 4096)
                except OSError:
                    data = b""
                if data:
                    self._handle(data)
            if self._streaming:
                due = int((time.monotonic() - self._t0) * self.data.rate_hz)
                while self._sent_since_start < due and self._streaming:
                    self._sent_since_start += 1
                    self._sample()
                    self._release_held()
                    cut = self.faults.disconnect_after
                    if cut is not None and self.counts.stream_frames == cut \
                            and self.counts.disconnects == 0:
                        self._flush()
                        self._disconnect()
                        break
            self._flush()

    def _flush(self) -> None:
        if self._master < 0 or not self._out:
            return
        try:
            n = os.write(self._master, bytes(self._out))
        except BlockingIOError:
            return
        except OSError:
            self._out.clear()
            return
        del self._out[:n]

    def _disconnect(self) -> None:
        self.counts.disconnects += 1
        # Let the host read what was written before the cut, then pull the cable.
        # (The kernel moves written bytes to the reader's queue asynchronously: wait until the
        # queue has stayed empty for a while.)
        deadline = time.monotonic() + 2.0
        quiet_since = time.monotonic()
        while time.monotonic() < deadline:
            self._flush()
            if self._out or _unread(self._slave):
                quiet_since = time.monotonic()
            elif time.monotonic() - quiet_since > 0.1:
                break
            time.sleep(0.002)
        self._close_pty()
        self.path.unlink(missing_ok=True)
        self._streaming = False
        delay = self.faults.reconnect_after_s
        if delay is not None:
            time.sleep(delay)
            self._open_pty()


def serve_board(argv: list[str]) -> int:
    """Run the fake as a stand-in for the native board binary, honouring the launcher contract
    (boards.launchers.NativeBoardLauncher): `--rig RIG --motion CSV --baud B [--fast]`, print
    `PTY <path>`, serve until SIGTERM. Plays the first 3 s of the motion (θ from `mirror`)."""
    import argparse
    import signal
    import tempfile

    from jointangle.device.calibration_map import counts_from_readings
    from jointangle.io.csv_formats import read_accel_csv
    from jointangle.io.rig_file import load_rig

    p = argparse.ArgumentParser()
    p.add_argument("--rig", required=True)
    p.add_argument("--motion", required=True)
    p.add_argument("--baud", type=int, required=True)
    p.add_argument("--fast", action="store_true")
    args = p.parse_args(argv)
    rig = load_rig(args.rig)
    readings = read_accel_csv(args.motion, rig).readings
    counts = counts_from_readings(rig, readings[: round(3 * rig.sample_rate_hz)])
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    with tempfile.TemporaryDirectory() as d, FakeDevice(data_from_counts(rig, counts),
                                                        Path(d)) as fake:
        sys.stdout.write(f"PTY {os.readlink(fake.path)}\n")
        sys.stdout.flush()
        stop.wait()
    return 0


if __name__ == "__main__":
    sys.exit(serve_board(sys.argv[1:]))

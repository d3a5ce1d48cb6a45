"""A protocol link over any byte port (pyserial `Serial`, `serial_for_url("loop://")`, a pty, ...).

Framing only -- no threads, no port discovery (those belong to the commands that use it):

    port = serial.serial_for_url(url, baudrate=500_000, timeout=0.05)
    link = Link(port, recorder=writer)           # writer: an optional JrecWriter
    hello = link.handshake()                     # get_info -> hello; refuses other versions
    link.command(msgs.StartStream(mode=msgs.StreamMode.SAMPLE_ESTIMATE, status_interval_ms=1000))
    for frame in link.poll(): ...                # whatever arrived, decoded and counted

Every byte read is handed to the recorder exactly as received (before decoding), so a recording
holds damage too. Commands carry their own sequence counter and wait for the matching ack;
a NACK raises CommandError with the device's error code.
"""

from __future__ import annotations

import time
from collections import deque
from typing import Protocol

from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import SPECS_BY_ID, decode_message, encode_message
from jointangle.protocol.framing import (
    Frame,
    ProtocolMismatchError,
    StreamDecoder,
    schema_message,
    version_message,
)


class Port(Protocol):
    """What Link needs from a port (pyserial's Serial provides it)."""

    def read(self, size: int = 1) -> bytes: ...

    def write(self, data: bytes, /) -> int | None: ...

    @property
    def in_waiting(self) -> int: ...


class Recorder(Protocol):
    def write(self, data: bytes, host_ns: int | None = None) -> None: ...


class LinkTimeoutError(TimeoutError):
    """No answer from the device in time."""


# How the board bounds a rate by its bus (firmware/app/APP.md "Commands", kSustainableBusNs).
BUS_BOUND = "bus <= 96 % busy"


def refusal_reason(code: int, detail: int = 0) -> str:
    """An ack's error code as the user reads it: its name, and for the codes that name a bound
    the bound (protocol/messages.toml says the same); `detail` is the ack's (a refused
    set_rate: the rate the board holds)."""
    try:
        err = msgs.ErrorCode(code)
    except ValueError:
        return f"error {code}"
    why = {
        msgs.ErrorCode.BAD_CALIBRATION: "S singular or absurd (|det S| < 1/64 or an entry beyond "
                                        "±4) or an offset beyond ±50 m/s²",
        msgs.ErrorCode.BAD_NOISE: "the noise sigma must be 0 (from the datasheet) or "
                                  "100e-6..10 m/s²",
        msgs.ErrorCode.BAD_VALUE: "a value outside what the board takes",
        msgs.ErrorCode.NOT_ALLOWED_WHILE_STREAMING: "stop the stream first",
        msgs.ErrorCode.RATE_NOT_SUSTAINABLE: f"this board holds at most {detail} Hz at >= 20 % "
                                             "asleep with its sensors, filter and stream, its "
                                             f"{BUS_BOUND}; force it to set it anyway",
    }.get(err)
    return err.name.lower() + (f" ({why})" if why else "")


class CommandError(RuntimeError):
    """The device refused a command (its ack carried an error code)."""

    def __init__(self, command: str, code: int, detail: int = 0) -> None:
        super().__init__(f"device refused {command}: {refusal_reason(code, detail)}")
        self.code = code
        self.detail = detail


class Link:
    """Sends commands, receives frames; keeps the decoder's counters in `stats`."""

    def __init__(self, port: Port, *, recorder: Recorder | None = None,
                 timeout_s: float = 1.0) -> None:
        self.port = port
        self.recorder = recorder
        self.timeout_s = timeout_s
        # Frames of another protocol version are counted, never fatal (docs/design.md §6); only a
        # handshake answered in another version or schema is refused (handshake()).
        self.decoder = StreamDecoder()
        self._seq = 0
        self._backlog: deque[Frame] = deque()

    @property
    def stats(self) -> dict[str, int]:
        return self.decoder.stats.as_dict()

    def send(self, msg: msgs.Message) -> int:
        """Send one message; returns the sequence number it carried."""
        seq = self._seq
        self._seq = (self._seq + 1) & 0xFFFF
        self.port.write(encode_message(msg, seq, time.monotonic_ns() // 1000))
        return seq

    def _read(self) -> list[Frame]:
        data = self.port.read(max(1, self.port.in_waiting))
        if not data:
            return []
        if self.recorder is not None:
            self.recorder.write(data)
        return self.decoder.feed(data)

    def poll(self) -> list[Frame]:
        """Frames that arrived (including any held back while waiting for an ack)."""
        out = list(self._backlog)
        self._backlog.clear()
        return out + self._read()

    def wait_for(self, msg_id: int, *, timeout_s: float | None = None,
                 match: int | None = None) -> Frame:
        """The next frame of `msg_id` (for acks: whose command_seq == match); other frames are
        kept for poll()."""
        deadline = time.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)
        while time.monotonic() < deadline:
            frames = self._read()
            for i, fr in enumerate(frames):
                if fr.msg_id == msg_id and (match is None or _acked_seq(fr) == match):
                    # Frames read in the same batch after this one belong to poll() too.
                    self._backlog.extend(frames[i + 1 :])
                    return fr
                self._backlog.append(fr)
        raise LinkTimeoutError(f"no {msgs_name(msg_id)} from the device within "
                               f"{self.timeout_s if timeout_s is None else timeout_s:.1f} s")

    def command(self, msg: msgs.Message, *, timeout_s: float | None = None) -> msgs.Ack:
        """Send a host command and wait for its ack; CommandError if the device refuses it."""
        seq = self.send(msg)
        ack = decode_message(self.wait_for(msgs.Ack.MSG_ID, timeout_s=timeout_s, match=seq))
        assert isinstance(ack, msgs.Ack)
        if ack.error != msgs.ErrorCode.OK:
            raise CommandError(msg.NAME, ack.error, ack.detail)
        return ack

    def handshake(self, *, timeout_s: float | None = None) -> msgs.Hello:
        """get_info -> hello. Raises ProtocolMismatchError (naming both sides) when the answer
        is a hello in another protocol version (or, with no hello of ours in time, when only
        frames of another version came), or a hello announcing another schema hash."""
        dec = self.decoder
        dec.other_hello = None
        others_before = dec.stats.version_errors
        self.send(msgs.GetInfo())
        deadline = time.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)
        while True:
            left = deadline - time.monotonic()
            if dec.other_hello is not None:
                raise ProtocolMismatchError(version_message(dec.other_hello))
            try:
                # Short slices, so that a hello in another version is refused at once.
                frame = self.wait_for(msgs.Hello.MSG_ID, timeout_s=max(0.0, min(left, 0.05)))
                break
            except LinkTimeoutError:
                if dec.other_hello is not None:
                    raise ProtocolMismatchError(version_message(dec.other_hello)) from None
                if left > 0.05:
                    continue
                if dec.stats.version_errors > others_before and dec.mismatch is not None:
                    raise ProtocolMismatchError(dec.mismatch) from None
                raise LinkTimeoutError(
                    f"no hello from the device within "
                    f"{self.timeout_s if timeout_s is None else timeout_s:.1f} s") from None
        hello = decode_message(frame)
        assert isinstance(hello, msgs.Hello)
        if hello.protocol_version != msgs.PROTOCOL_VERSION:
            raise ProtocolMismatchError(version_message(hello.protocol_version))
        if hello.schema_hash != msgs.SCHEMA_HASH:
            raise ProtocolMismatchError(schema_message(hello.schema_hash))
        return hello


def _acked_seq(frame: Frame) -> int | None:
    try:
        msg = decode_message(frame)
    except ValueError:
        return None
    return msg.command_seq if isinstance(msg, msgs.Ack) else None


def msgs_name(msg_id: int) -> str:
    spec = SPECS_BY_ID.get(msg_id)
    return spec.name if spec else f"message 0x{msg_id:02X}"

"""Link over pyserial's loop:// and over a scripted fake device: commands, acks, refusals."""

from __future__ import annotations

import dataclasses

import pytest
import serial

from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import decode_message, encode_message
from jointangle.protocol.framing import ProtocolMismatchError, StreamDecoder
from jointangle.protocol.link import CommandError, Link, LinkTimeoutError


def _hello(**over: object) -> msgs.Hello:
    base = msgs.Hello(protocol_version=msgs.PROTOCOL_VERSION, schema_hash=msgs.SCHEMA_HASH,
                      firmware_major=0, firmware_minor=1, firmware_patch=0,
                      build=b"fake".ljust(12, b"\x00"), board=msgs.Board.NATIVE,
                      sample_rate_hz=500, stream_mode=0, eeprom=msgs.EepromState.OK)
    return dataclasses.replace(base, **over)  # type: ignore[arg-type]


class FakeDevice:
    """Answers every command with an ack (error per `errors`), get_info with a hello first."""

    def __init__(self, hello: msgs.Hello, errors: dict[int, int] | None = None) -> None:
        self.hello = hello
        self.errors = errors or {}
        self.rx = StreamDecoder()
        self.tx = bytearray()
        self.seq = 0
        self.received: list[msgs.Message] = []

    def _send(self, msg: msgs.Message) -> None:
        self.tx += encode_message(msg, self.seq, 1000 * self.seq)
        self.seq += 1

    def write(self, data: bytes) -> int:
        for fr in self.rx.feed(data):
            msg = decode_message(fr)
            self.received.append(msg)
            if isinstance(msg, msgs.GetInfo):
                self._send(self.hello)
            self._send(msgs.Ack(command_id=fr.msg_id, command_seq=fr.seq,
                                error=self.errors.get(fr.msg_id, 0)))
        return len(data)

    @property
    def in_waiting(self) -> int:
        return len(self.tx)

    def read(self, size: int = 1) -> bytes:
        out = bytes(self.tx[:size])
        del self.tx[:size]
        return out


def test_handshake_and_commands() -> None:
    dev = FakeDevice(_hello())
    link = Link(dev, timeout_s=0.2)
    assert link.handshake().sample_rate_hz == 500
    ack = link.command(msgs.SetRate(rate_hz=1000))
    assert ack.command_id == msgs.SetRate.MSG_ID and ack.error == 0
    assert dev.received[-1] == msgs.SetRate(rate_hz=1000)
    assert link.stats["frames"] == 3 and link.stats["frames_lost"] == 0


def test_refused_command_names_the_error() -> None:
    dev = FakeDevice(_hello(), errors={msgs.SaveEeprom.MSG_ID: msgs.ErrorCode.EEPROM_FAILED})
    link = Link(dev, timeout_s=0.2)
    with pytest.raises(CommandError, match="save_eeprom: eeprom_failed"):
        link.command(msgs.SaveEeprom(confirm=0x5AFE))


def test_other_schema_is_refused_naming_both() -> None:
    link = Link(FakeDevice(_hello(schema_hash=0x0BADF00D)), timeout_s=0.2)
    with pytest.raises(ProtocolMismatchError, match="0x0BADF00D"):
        link.handshake()


def test_silence_times_out() -> None:
    port = serial.serial_for_url("loop://", timeout=0.01)
    link = Link(port, timeout_s=0.05)
    with pytest.raises(LinkTimeoutError, match="ack"):
        link.command(msgs.StopStream())


def test_loopback_records_and_decodes_what_arrives() -> None:
    port = serial.serial_for_url("loop://", timeout=0.01)
    got: list[bytes] = []

    class Rec:
        def write(self, data: bytes, host_ns: int | None = None) -> None:
            got.append(data)

    link = Link(port, recorder=Rec())
    link.send(msgs.GetInfo())  # loop:// echoes it back
    frames = link.poll()
    assert [f.msg_id for f in frames] == [msgs.GetInfo.MSG_ID]
    assert b"".join(got) == encode_message(msgs.GetInfo(), 0, frames[0].t_us)


class TrailingDevice(FakeDevice):
    """Sends a log frame right behind every ack, so both arrive in the same read."""

    def write(self, data: bytes) -> int:
        n = super().write(data)
        self._send(msgs.Log(level=1, text="after"))
        return n


def test_frames_behind_an_ack_reach_poll() -> None:
    dev = TrailingDevice(_hello())
    link = Link(dev, timeout_s=0.2)
    link.command(msgs.SetRate(rate_hz=500))
    names = [type(decode_message(fr)).__name__ for fr in link.poll()]
    assert names == ["Log"]

"""Frames of another protocol version and of unknown message ids inside a stream are counted,
never fatal (issue 16 item 1), in the streaming and bulk decoders and on a Link; only a handshake
answered in another version or schema is refused, naming both."""

from __future__ import annotations

import pytest
from test_link import FakeDevice, _hello

from jointangle.protocol import messages as msgs
from jointangle.protocol.bulk import bulk_decode
from jointangle.protocol.codec import encode_message, encode_payload
from jointangle.protocol.framing import (
    ProtocolMismatchError,
    StreamDecoder,
    encode_frame,
    frame_summary,
)
from jointangle.protocol.link import Link

UNKNOWN_ID = 0x3E


def _log(i: int) -> msgs.Log:
    return msgs.Log(level=1, text=f"frame {i}")


def _stream_with_strangers() -> tuple[bytes, int]:
    """100 good frames (seq 0..99); after frame 40 a valid frame of version 2, after frame 60
    one of an unknown message id (which takes seq 61 -- the device sent it), after 80 one of
    version 9 that looks like a hello."""
    out = bytearray()
    seq = 0
    for i in range(100):
        out += encode_message(_log(i), seq, 1000 * i)
        seq += 1
        if i == 40:
            out += encode_frame(msgs.SampleEstimate.MSG_ID, seq, 0, b"\x01" * 20, version=2)
        if i == 60:
            out += encode_frame(UNKNOWN_ID, seq, 0, b"\x07" * 4)
            seq += 1
        if i == 80:
            out += encode_frame(msgs.Hello.MSG_ID, seq, 0, b"\x09" * 30, version=9)
    return bytes(out), seq


def test_stray_frames_are_counted_and_every_good_frame_kept() -> None:
    data, sent = _stream_with_strangers()
    dec = StreamDecoder()
    frames = dec.feed(data)
    st = dec.stats
    assert len(frames) == st.frames == sent == 101  # 100 logs and the unknown one
    assert st.version_errors == 2 and st.unknown_messages == 1
    assert st.versions_seen == {msgs.PROTOCOL_VERSION: 101, 2: 1, 9: 1}
    assert st.frames_lost == 0 and st.crc_errors == 0
    assert dec.mismatch is not None and "version 2" in dec.mismatch
    bulk = bulk_decode(data)
    assert bulk.stats == st  # versions_seen and unknown_messages included
    assert frame_summary(bulk.frames()) == frame_summary(frames)


def test_a_link_keeps_streaming_past_another_version() -> None:
    dev = FakeDevice(_hello())
    link = Link(dev, timeout_s=0.2)
    link.handshake()
    dev.tx += encode_frame(msgs.Log.MSG_ID, 2, 0, b"\x01x", version=2)
    dev.tx += encode_frame(UNKNOWN_ID, 2, 0, b"")
    dev.tx += encode_message(_log(1), 3, 0)
    dev.seq = 4
    got = link.poll()
    assert [f.msg_id for f in got] == [msgs.Ack.MSG_ID, UNKNOWN_ID, msgs.Log.MSG_ID]
    assert link.stats["version_errors"] == 1 and link.stats["unknown_messages"] == 1
    assert link.command(msgs.SetRate(rate_hz=500)).error == 0  # still talking


class OtherVersionDevice(FakeDevice):
    """Answers get_info with a hello framed in protocol version `version`."""

    def __init__(self, version: int, stray_first: bool = False) -> None:
        super().__init__(_hello())
        self.version = version
        self.stray_first = stray_first

    def write(self, data: bytes) -> int:
        if self.stray_first:  # a stray frame of another version before our hello
            self.tx += encode_frame(msgs.Log.MSG_ID, 0, 0, b"\x01x", version=self.version)
            return super().write(data)
        self.tx += encode_frame(msgs.Hello.MSG_ID, 0, 0, encode_payload(self.hello),
                                version=self.version)
        return len(data)


def test_a_handshake_in_another_version_is_refused_naming_both() -> None:
    link = Link(OtherVersionDevice(3), timeout_s=2.0)
    with pytest.raises(ProtocolMismatchError) as err:
        link.handshake()
    msg = str(err.value)
    assert "version 3" in msg and f"version {msgs.PROTOCOL_VERSION}" in msg


def test_a_stray_frame_of_another_version_does_not_refuse_the_handshake() -> None:
    link = Link(OtherVersionDevice(3, stray_first=True), timeout_s=0.5)
    assert link.handshake().protocol_version == msgs.PROTOCOL_VERSION
    assert link.stats["version_errors"] == 1

"""Framing and codec edge cases: refusals that name both versions, bounded buffers, bad values."""

from __future__ import annotations

import dataclasses

import pytest

from jointangle.errors import InputError
from jointangle.protocol import messages as msgs
from jointangle.protocol.bulk import bulk_decode
from jointangle.protocol.codec import PayloadError, decode_payload, encode_message, encode_payload
from jointangle.protocol.framing import (
    MAX_ENCODED,
    ProtocolMismatchError,
    StreamDecoder,
    encode_frame,
)


def _hello(schema: int = msgs.SCHEMA_HASH) -> msgs.Hello:
    return msgs.Hello(protocol_version=msgs.PROTOCOL_VERSION, schema_hash=schema,
                      firmware_major=0, firmware_minor=1, firmware_patch=0, build=b"test".ljust(12,
                      b"\x00"), board=msgs.Board.NATIVE, sample_rate_hz=500, stream_mode=0,
                      eeprom=msgs.EepromState.OK)


def test_other_protocol_version_is_counted_naming_both() -> None:
    frame = encode_frame(msgs.Ack.MSG_ID, 1, 0, b"\x40\x01\x00\x00", version=7)
    for dec in (StreamDecoder(strict=True), StreamDecoder()):  # never fatal in a stream
        assert dec.feed(frame) == []
        assert dec.stats.version_errors == 1 and dec.stats.versions_seen == {7: 1}
        assert dec.mismatch is not None
        assert "version 7" in dec.mismatch and f"version {msgs.PROTOCOL_VERSION}" in dec.mismatch
        assert bulk_decode(frame).mismatch == dec.mismatch
    assert issubclass(ProtocolMismatchError, InputError)


def test_other_schema_hash_is_refused_naming_both() -> None:
    frame = encode_message(_hello(0xDEADBEEF), 0, 0)
    with pytest.raises(ProtocolMismatchError, match="0xDEADBEEF") as err:
        StreamDecoder(strict=True).feed(frame)
    assert f"0x{msgs.SCHEMA_HASH:08X}" in str(err.value)
    assert StreamDecoder(strict=True).feed(encode_message(_hello(), 0, 0))  # ours: accepted
    bulk = bulk_decode(frame)
    assert bulk.stats.schema_errors == 1 and bulk.mismatch == str(err.value)


def test_oversize_runs_keep_the_buffer_bounded() -> None:
    dec = StreamDecoder()
    for _ in range(1000):
        dec.feed(b"\x01" * 997)
        assert len(dec._pending) <= MAX_ENCODED
    good = encode_message(_hello(), 0, 0)
    assert len(dec.feed(b"\x00" + good)) == 1
    assert dec.stats.oversize == 1 and dec.stats.bytes_skipped == 997_000


def test_values_that_do_not_fit_are_rejected_on_encode() -> None:
    msg = msgs.SetRate(rate_hz=70000)
    with pytest.raises(ValueError, match="rate_hz"):
        encode_payload(msg)
    item = msgs.SamplesSensor(x=2**23, y=0, z=0, fresh=0, status=0)
    with pytest.raises(ValueError, match="x"):
        encode_payload(msgs.Samples(sensors=(item,)))
    with pytest.raises(ValueError, match="text"):
        encode_payload(msgs.Log(level=0, text="x" * 201))


def test_payloads_of_the_wrong_length_are_rejected_on_decode() -> None:
    ok = encode_payload(msgs.SetRate(rate_hz=500))
    assert decode_payload(msgs.SetRate.MSG_ID, ok) == msgs.SetRate(rate_hz=500)
    with pytest.raises(PayloadError, match="set_rate"):
        decode_payload(msgs.SetRate.MSG_ID, ok + b"\x00")
    item = msgs.SamplesSensor(x=1, y=2, z=3, fresh=1, status=0)
    raw = encode_payload(msgs.Samples(sensors=(item, item)))
    with pytest.raises(PayloadError, match="group"):
        decode_payload(msgs.Samples.MSG_ID, raw[:-1])
    with pytest.raises(PayloadError, match="unknown message id"):
        decode_payload(0x3F, b"")


def test_enums_and_flags_read_back() -> None:
    hello = _hello()
    assert msgs.Board(hello.board) is msgs.Board.NATIVE
    flags = msgs.SensorStatus(0x05)
    assert msgs.SensorStatus.NACK in flags and msgs.SensorStatus.SATURATED in flags
    assert dataclasses.replace(hello, board=9).board == 9  # unknown values survive as ints

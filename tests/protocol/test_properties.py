"""Property tests (hypothesis): round trips, robustness to arbitrary bytes, damage that loses only
the frames it touches, and the bulk decoder agreeing exactly with the streaming decoder."""

from __future__ import annotations

from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from protocol_strategies import any_message, frame_streams

from jointangle.protocol.bulk import bulk_decode, crc16_rows, crc_tables
from jointangle.protocol.codec import decode_message, encode_message, message_fields
from jointangle.protocol.construct_defs import frame_body
from jointangle.protocol.framing import (
    MAX_ENCODED,
    StreamDecoder,
    cobs_decode,
    cobs_encode,
    crc16,
    decode_stream,
    frame_summary,
    unwhiten,
)

SETTINGS = settings(max_examples=150, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


def crc16_reference(data: bytes) -> int:
    """Bit-by-bit CRC-16/CCITT-FALSE straight from the definition."""
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc


def test_crc_check_value() -> None:
    assert crc16(b"123456789") == 0x29B1 == crc16_reference(b"123456789")


@SETTINGS
@given(st.lists(st.binary(min_size=0, max_size=40), min_size=1, max_size=20),
       st.integers(0, 40))
def test_crc_implementations_agree(rows: list[bytes], width: int) -> None:
    import numpy as np

    mat = np.array([list((r * 41)[:width].ljust(width, b"\x07")) for r in rows], dtype=np.uint8)
    mat = mat.reshape(len(rows), width)
    t8, t16 = crc_tables()
    got = crc16_rows(mat, t8, t16)
    for row, c in zip(mat, got, strict=True):
        assert int(c) == crc16(row.tobytes()) == crc16_reference(row.tobytes())


@SETTINGS
@given(st.binary(max_size=600))
def test_cobs_round_trip(data: bytes) -> None:
    enc = cobs_encode(data)
    assert 0 not in enc
    assert cobs_decode(enc) == data


@SETTINGS
@given(any_message, st.integers(0, 0xFFFF), st.integers(0, 0xFFFFFFFF))
def test_message_round_trip_in_all_decoders(msg: Any, seq: int, t_us: int) -> None:
    frame = encode_message(msg, seq, t_us)
    assert len(frame) <= MAX_ENCODED + 1
    frames, stats = decode_stream(frame)
    assert stats.frames == 1 and (frames[0].seq, frames[0].t_us) == (seq, t_us)
    assert decode_message(frames[0]) == msg
    raw = cobs_decode(frame[:-1])
    assert raw is not None
    raw = unwhiten(raw)
    parsed = frame_body().parse(raw, n=len(raw)).data.value
    assert parsed.header.msg_id == msg.MSG_ID
    for key, value in message_fields(msg).items():
        parts = key.split(".")
        got = parsed.payload[parts[0]] if len(parts) == 1 else \
            parsed.payload[parts[0]][int(parts[1])][parts[2]]
        assert got == value
    assert frame_summary(bulk_decode(frame).frames()) == frame_summary(frames)


def _agree(data: bytes) -> None:
    frames, stats = decode_stream(data)
    bulk = bulk_decode(data)
    assert bulk.stats.as_dict() == stats.as_dict()
    assert frame_summary(bulk.frames()) == frame_summary(frames)
    assert list(bulk.seq) == [f.seq for f in frames]


@SETTINGS
@given(st.binary(max_size=2000), st.lists(st.integers(0, 2000), max_size=8))
def test_arbitrary_bytes_never_crash_and_splitting_does_not_matter(data: bytes,
                                                                    cuts: list[int]) -> None:
    whole = StreamDecoder()
    frames = whole.feed(data)
    split = StreamDecoder()
    pieces: list[Any] = []
    prev = 0
    for c in [*sorted(c % (len(data) + 1) for c in cuts), len(data)]:
        pieces += split.feed(data[prev:c])
        prev = c
    assert frame_summary(pieces) == frame_summary(frames)
    assert split.stats == whole.stats
    assert split.pending_bytes == whole.pending_bytes
    _agree(data)


@SETTINGS
@given(st.lists(st.sampled_from([b"\x00", b"\x01", b"\xff", b"\x02\x00", bytes(range(1, 255))]),
                max_size=40))
def test_structured_garbage(parts: list[bytes]) -> None:
    data = b"".join(parts)
    _agree(data)


def _is_subsequence(needles: list[bytes], hay: list[bytes]) -> bool:
    it = iter(hay)
    return all(any(n == h for h in it) for n in needles)


@SETTINGS
@given(frame_streams(min_frames=2), st.data())
def test_damage_loses_only_the_frames_it_touches(frames: list[bytes], data: st.DataObject) -> None:
    stream = b"".join(frames)
    bounds = []  # (start, end) of each frame, delimiter included
    pos = 0
    for f in frames:
        bounds.append((pos, pos + len(f)))
        pos += len(f)
    kind = data.draw(st.sampled_from(["flip", "delete", "insert"]))
    p = data.draw(st.integers(0, len(stream) - 1))
    if kind == "flip":
        bit = data.draw(st.integers(0, 7))
        damaged = stream[:p] + bytes([stream[p] ^ (1 << bit)]) + stream[p + 1 :]
    elif kind == "delete":
        damaged = stream[:p] + stream[p + 1 :]
    else:
        b = data.draw(st.integers(0, 255))
        damaged = stream[:p] + bytes([b]) + stream[p:]
    # A frame is touched if the damage is inside it or in the delimiter of the frame before it
    # (which merges the two).
    touched = {i for i, (s, e) in enumerate(bounds) if s - 1 <= p < e}
    intact = [f for i, f in enumerate(frames) if i not in touched]
    dec = StreamDecoder()
    got_frames = dec.feed(damaged)
    stats = dec.stats
    got = [encode_message(decode_message(fr), fr.seq, fr.t_us) for fr in got_frames
           if _decodable(fr)]
    assert _is_subsequence(intact, got), (kind, p, touched)
    lost = len(frames) - len(got_frames)
    if lost > 0:  # visible as damage, a sequence gap, or an unfinished (pending) last frame
        assert stats.bytes_skipped > 0 or stats.frames_lost > 0 or dec.pending_bytes > 0
    _agree(damaged)


def _decodable(fr: Any) -> bool:
    try:
        decode_message(fr)
    except ValueError:
        return False
    return True


@SETTINGS
@given(frame_streams(min_frames=1, max_frames=30), st.data())
def test_bulk_matches_stream_on_corrupted_logs(frames: list[bytes], data: st.DataObject) -> None:
    buf = bytearray(b"".join(frames))
    for _ in range(data.draw(st.integers(0, 12))):
        op = data.draw(st.sampled_from(["flip", "delete", "insert", "zero", "junk"]))
        p = data.draw(st.integers(0, max(len(buf) - 1, 0)))
        if not buf:
            break
        if op == "flip":
            buf[p] ^= 1 << data.draw(st.integers(0, 7))
        elif op == "delete":
            del buf[p]
        elif op == "insert":
            buf.insert(p, data.draw(st.integers(0, 255)))
        elif op == "zero":
            buf[p] = 0
        else:
            buf[p:p] = data.draw(st.binary(min_size=1, max_size=300))
    _agree(bytes(buf))
    cut = data.draw(st.integers(0, len(buf)))
    _agree(bytes(buf[:cut]))

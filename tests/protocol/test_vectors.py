"""Golden vectors: every message encodes to its golden frame byte for byte and decodes back, in
every Python decoder; the damaged streams give the listed frames and counts. (The C++ side checks
the same files in tests/cpp/protocol.)"""

from __future__ import annotations

import pytest
from vector_files import VECTORS, StreamVector, Vector, load_golden, load_streams

from jointangle.protocol import messages as msgs
from jointangle.protocol.bulk import bulk_decode
from jointangle.protocol.codec import (
    SPECS_BY_NAME,
    decode_message,
    encode_message,
    message_fields,
)
from jointangle.protocol.construct_defs import frame_body
from jointangle.protocol.framing import (
    COUNT_KEYS,
    StreamDecoder,
    cobs_decode,
    decode_stream,
    unwhiten,
)


def _build(v: Vector) -> msgs.Message:
    spec = SPECS_BY_NAME[v.message]
    values: dict[str, object] = {}
    for f in spec.fields:
        raw = v.fields[f.name]
        values[f.name] = raw.decode() if f.type == "text" else raw  # type: ignore[union-attr]
    if spec.group is not None:
        g = spec.group
        n = len({k.split(".")[1] for k in v.fields if k.startswith(g.name + ".")})
        values[g.name] = tuple(g.cls(**{f.name: v.fields[f"{g.name}.{i}.{f.name}"]
                                        for f in g.fields}) for i in range(n))
    return spec.cls(**values)  # type: ignore[no-any-return]


def test_every_message_has_golden_vectors(golden: list[Vector]) -> None:
    names = {v.message for v in golden}
    assert names == set(SPECS_BY_NAME)
    assert len(golden) == 2 * len(SPECS_BY_NAME)


@pytest.mark.parametrize("v", load_golden(), ids=lambda v: v.name)
def test_encode_equals_golden(v: Vector) -> None:
    assert encode_message(_build(v), v.seq, v.t_us) == v.frame


@pytest.mark.parametrize("v", load_golden(), ids=lambda v: v.name)
def test_decode_golden(v: Vector) -> None:
    frames, stats = decode_stream(v.frame)
    assert stats.frames == 1 and stats.bytes_skipped == 0
    (fr,) = frames
    assert (fr.seq, fr.t_us) == (v.seq, v.t_us)
    msg = decode_message(fr)
    assert v.message == msg.NAME
    got = message_fields(msg)
    spec = SPECS_BY_NAME[v.message]
    if spec.text is not None:
        got[spec.text.name] = got[spec.text.name].encode()
    assert got == v.fields


@pytest.mark.parametrize("v", load_golden(), ids=lambda v: v.name)
def test_construct_and_bulk_agree_with_golden(v: Vector) -> None:
    raw = cobs_decode(v.frame[:-1])
    assert raw is not None
    raw = unwhiten(raw)
    parsed = frame_body().parse(raw, n=len(raw))
    assert parsed.data.value.header.seq == v.seq
    spec = SPECS_BY_NAME[v.message]
    payload = parsed.data.value.payload
    for f in spec.fields:
        value = payload[f.name]
        expect = v.fields[f.name]
        assert (value.encode() if f.type == "text" else value) == expect
    if spec.group is not None:
        for i, item in enumerate(payload[spec.group.name]):
            for f in spec.group.fields:
                assert item[f.name] == v.fields[f"{spec.group.name}.{i}.{f.name}"]
    bulk = bulk_decode(v.frame)
    assert len(bulk) == 1 and bulk.stats.frames == 1
    if spec.text is None:
        cols = bulk.columns(v.message)
        for f in spec.fixed_fields:
            got = cols[f.name][0]
            assert (got.tobytes() if f.type.startswith("char") else int(got)) == v.fields[f.name]
        if spec.group is not None:
            g = spec.group
            for i in range(cols[f"{g.name}.{g.fields[0].name}"].shape[1]):
                for f in g.fields:
                    want = v.fields[f"{g.name}.{i}.{f.name}"]
                    assert int(cols[f"{g.name}.{f.name}"][0, i]) == want


def test_high_rate_frame_fits_the_link() -> None:
    """Four sensors plus the estimate: <= 80 bytes on the wire (500 frames/s at 500 kbaud, 20 %
    headroom). The size is stated in protocol/README.md."""
    sensors = tuple(msgs.SampleEstimateSensor(x=-(2**23), y=2**23 - 1, z=0, fresh=1, status=0)
                    for _ in range(4))
    frame = encode_message(msgs.SampleEstimate(theta=1, omega_a=2, omega_b=3, health=1,
                                               sensors=sensors), 1, 2)
    assert len(frame) == 70 <= 80
    assert 500 * len(frame) * 10 <= 0.8 * 500_000
    readme = (VECTORS.parent / "README.md").read_text()
    assert f"{len(frame)} bytes" in readme


@pytest.mark.parametrize("sv", load_streams() + load_streams("sequence.txt"),
                         ids=lambda s: s.name)
def test_stream_vectors(sv: StreamVector) -> None:
    frames, stats = decode_stream(sv.data)
    assert stats.as_dict() == sv.counts
    assert [(f.msg_id, f.seq) for f in frames] == sv.frames
    # Byte at a time: the same.
    dec = StreamDecoder()
    one = [f for i in range(len(sv.data)) for f in dec.feed(sv.data[i : i + 1])]
    assert [(f.msg_id, f.seq) for f in one] == sv.frames
    assert dec.stats.as_dict() == sv.counts
    bulk = bulk_decode(sv.data)
    assert bulk.stats.as_dict() == sv.counts
    assert [(f.msg_id, f.seq) for f in bulk.frames()] == sv.frames


def test_stream_vectors_cover_every_kind_of_damage(stream_vectors: list[StreamVector]) -> None:
    every = stream_vectors + load_streams("sequence.txt")
    for key in COUNT_KEYS:
        if key != "frames":
            assert any(sv.counts[key] for sv in every), key

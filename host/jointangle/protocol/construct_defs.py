"""The wire format as declarative `construct` definitions, built from the generated SPECS.

This is the readable, declarative description of every frame body (header, per-message payload,
CRC checked by `Checksum`), used for exploration, documentation and as the per-frame baseline of
`jointangle bench protocol`. The fast paths are `framing.StreamDecoder` and `bulk.bulk_decode`;
tests check that all three agree.

    body = frame_body()            # a construct.Struct
    parsed = body.parse(unwhiten(cobs_decode(chunk)), n=len(chunk) - 1)
    parsed.header.msg_id, parsed.payload.theta, parsed.crc
"""

from __future__ import annotations

from typing import Any

import construct as cs

from jointangle.protocol.framing import CRC_SIZE, HEADER_SIZE, cobs_decode, crc16, unwhiten
from jointangle.protocol.messages import SPECS
from jointangle.protocol.spec import FieldSpec, MessageSpec


def _int24() -> Any:
    return cs.BytesInteger(3, signed=True, swapped=True)


def field_construct(f: FieldSpec) -> Any:
    """One field as a named construct."""
    kinds: dict[str, Any] = {
        "u8": cs.Int8ul, "i8": cs.Int8sl, "u16": cs.Int16ul, "i16": cs.Int16sl,
        "i24": _int24(), "u32": cs.Int32ul, "i32": cs.Int32sl, "f32": cs.Float32l,
    }
    if f.type in kinds:
        return f.name / kinds[f.type]
    if f.type == "text":
        return f.name / cs.GreedyString("utf8")
    return f.name / cs.Bytes(f.size)


def payload_construct(spec: MessageSpec) -> Any:
    """The payload of one message: fixed fields, then a u8-prefixed group or trailing text."""
    parts = [field_construct(f) for f in spec.fields]
    if spec.group is not None:
        item = cs.Struct(*[field_construct(f) for f in spec.group.fields])
        parts.append(spec.group.name / cs.PrefixedArray(cs.Int8ul, item))
    return cs.Struct(*parts)


HEADER = cs.Struct(
    "version" / cs.Int8ul,
    "msg_id" / cs.Int8ul,
    "seq" / cs.Int16ul,
    "t_us" / cs.Int32ul,
)


def frame_body() -> Any:
    """A decoded frame body: header, payload (by msg_id), CRC-16 over header + payload.

    Parse with `n=len(body)`: the payload is the n - 10 bytes between header and CRC.
    """
    cases = {s.msg_id: payload_construct(s) for s in SPECS}
    return cs.Struct(
        "data" / cs.RawCopy(cs.Struct(
            "header" / HEADER,
            "payload" / cs.FixedSized(
                lambda ctx: ctx._._params.n - HEADER_SIZE - CRC_SIZE,
                cs.Switch(cs.this.header.msg_id, cases, default=cs.GreedyBytes),
            ),
        )),
        "crc" / cs.Checksum(cs.Int16ul, lambda data: crc16(data), cs.this.data.data),
        cs.Terminated,
    )


def parse_chunks(chunks: list[bytes], body: Any | None = None) -> list[Any]:
    """Per-frame baseline: COBS-decode and unwhiten each chunk, parse it with `frame_body()`.

    Chunks that fail (bad COBS, CRC, layout) are skipped. Returns the parsed containers.
    """
    body = frame_body() if body is None else body
    out = []
    for chunk in chunks:
        raw = cobs_decode(chunk)
        if raw is None:
            continue
        raw = unwhiten(raw)
        try:
            out.append(body.parse(raw, n=len(raw)))
        except cs.ConstructError:
            continue
    return out

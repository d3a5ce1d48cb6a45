"""Payload encoding and decoding of every message, driven by the generated SPECS table.

`encode_message(msg, seq, t_us)` gives the bytes to send; `decode_message(frame)` turns an accepted
frame (see framing.py) into the generated dataclass. Values are raw integers as on the wire;
multiply by the `factor` of the field's FieldSpec for SI units.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from jointangle.protocol.framing import Frame, encode_frame
from jointangle.protocol.messages import SPECS, Message
from jointangle.protocol.spec import FieldSpec, MessageSpec

SPECS_BY_ID: Mapping[int, MessageSpec] = MappingProxyType({s.msg_id: s for s in SPECS})
SPECS_BY_NAME: Mapping[str, MessageSpec] = MappingProxyType({s.name: s for s in SPECS})


class PayloadError(ValueError):
    """A frame whose payload does not match its message definition."""


def spec_of(msg: Message) -> MessageSpec:
    return SPECS_BY_ID[msg.MSG_ID]


def _check(f: FieldSpec, value: Any, where: str) -> Any:
    rng = f.int_range
    if rng is not None:
        if not isinstance(value, int) or not rng[0] <= int(value) <= rng[1]:
            raise ValueError(f"{where}.{f.name}: {value!r} does not fit {f.type}")
        if f.type == "i24":
            return int(value).to_bytes(3, "little", signed=True)
        return int(value)
    if f.type == "f32":
        return float(value)
    if not isinstance(value, bytes | bytearray) or len(value) > f.size:
        raise ValueError(f"{where}.{f.name}: expected up to {f.size} bytes, got {value!r}")
    return bytes(value).ljust(f.size, b"\x00")


def encode_payload(msg: Message) -> bytes:
    """The payload bytes of a message (ValueError if a value does not fit its field)."""
    spec = spec_of(msg)
    values = [_check(f, getattr(msg, f.name), spec.name) for f in spec.fixed_fields]
    out = spec.fixed_struct.pack(*values)
    if spec.group is not None:
        g = spec.group
        items = getattr(msg, g.name)
        if len(items) > g.max:
            raise ValueError(f"{spec.name}.{g.name}: {len(items)} items > {g.max}")
        parts = [out, bytes([len(items)])]
        for item in items:
            vals = [_check(f, getattr(item, f.name), f"{spec.name}.{g.name}") for f in g.fields]
            parts.append(g.item_struct.pack(*vals))
        out = b"".join(parts)
    text = spec.text
    if text is not None:
        raw = str(getattr(msg, text.name)).encode("utf-8")
        if len(raw) > text.max:
            raise ValueError(f"{spec.name}.{text.name}: {len(raw)} bytes > {text.max}")
        out += raw
    return out


def encode_message(msg: Message, seq: int, t_us: int) -> bytes:
    """One complete frame carrying `msg`, delimiter included."""
    return encode_frame(msg.MSG_ID, seq, t_us, encode_payload(msg))


def _i24(values: tuple[Any, ...], positions: tuple[int, ...]) -> tuple[Any, ...] | list[Any]:
    """Convert the 3-byte fields of an unpacked tuple to ints (dataclass fields are positional,
    in wire order, so the tuple feeds the constructor directly)."""
    if not positions:
        return values
    out = list(values)
    for i in positions:
        out[i] = int.from_bytes(out[i], "little", signed=True)
    return out


def decode_payload(msg_id: int, payload: bytes) -> Message:
    """Decode a payload into its dataclass; PayloadError if the id or the length is wrong."""
    spec = SPECS_BY_ID.get(msg_id)
    if spec is None:
        raise PayloadError(f"unknown message id 0x{msg_id:02X}")
    n = len(payload)
    fixed = spec.fixed_size
    if n < fixed:
        raise PayloadError(f"{spec.name}: {n} payload bytes, expected at least {fixed}")
    args = _i24(spec.fixed_struct.unpack_from(payload), spec.i24_positions)
    if spec.group is not None:
        g = spec.group
        count = payload[fixed] if n > fixed else -1
        if count < 0 or count > g.max or n != fixed + 1 + count * g.item_size:
            raise PayloadError(f"{spec.name}: {n} payload bytes do not hold a valid "
                               f"{g.name} group (count byte {count})")
        cls, pos = g.cls, g.i24_positions
        items = tuple(cls(*_i24(vals, pos)) for vals in g.item_struct.iter_unpack(
            payload[fixed + 1 :]))
        return spec.cls(*args, items)
    if spec.text is not None:
        if n - fixed > spec.text.max:
            raise PayloadError(f"{spec.name}: text of {n - fixed} bytes > {spec.text.max}")
        return spec.cls(*args, payload[fixed:].decode("utf-8", errors="replace"))
    if n != fixed:
        raise PayloadError(f"{spec.name}: {n} payload bytes, expected {fixed}")
    return spec.cls(*args)


def decode_message(frame: Frame) -> Message:
    return decode_payload(frame.msg_id, frame.payload)


def message_fields(msg: Message) -> dict[str, Any]:
    """Flat {name: raw value} view: group items as 'sensors.0.x'; char[N] and text as given."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(msg):
        value = getattr(msg, f.name)
        if isinstance(value, tuple):
            for i, item in enumerate(value):
                for g in dataclasses.fields(item):
                    out[f"{f.name}.{i}.{g.name}"] = getattr(item, g.name)
        else:
            out[f.name] = value
    return out


def text_of(raw: bytes) -> str:
    """A NUL-padded char[N] field as text."""
    return raw.split(b"\x00", 1)[0].decode("utf-8", errors="replace")

"""Descriptions of messages, fields and groups, as the generated `messages.py` instantiates them.

These classes are hand-written (the generator only fills them in); the codecs in `codec.py`,
`construct_defs.py` and `bulk.py` are all driven by the same `MessageSpec` table, so the three
decoders cannot disagree about the layout.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from functools import cached_property
from typing import Any

# wire type -> (size in bytes, struct code). i24 travels as 3 raw bytes and is converted by hand.
_SCALARS: dict[str, tuple[int, str]] = {
    "u8": (1, "B"),
    "i8": (1, "b"),
    "u16": (2, "H"),
    "i16": (2, "h"),
    "i24": (3, "3s"),
    "u32": (4, "I"),
    "i32": (4, "i"),
    "f32": (4, "f"),
}
_CHAR_RE = re.compile(r"^char\[(\d+)\]$")
_INT_RANGES: dict[str, tuple[int, int]] = {
    "u8": (0, 0xFF),
    "i8": (-0x80, 0x7F),
    "u16": (0, 0xFFFF),
    "i16": (-0x8000, 0x7FFF),
    "i24": (-0x800000, 0x7FFFFF),
    "u32": (0, 0xFFFFFFFF),
    "i32": (-0x80000000, 0x7FFFFFFF),
}


@dataclass(frozen=True)
class FieldSpec:
    """One field: name, wire type, unit and the fixed-point scale of its raw value."""

    name: str
    type: str  # u8 i8 u16 i16 i24 u32 i32 f32 | char[N] | text
    unit: str = ""
    scale: float | None = None  # SI value = raw * scale
    q: int | None = None  # SI value = raw * 2**-q
    kind: str | None = None  # enum or flag class name in messages.py
    max: int = 0  # text: maximum length in bytes

    @property
    def size(self) -> int:
        """Bytes on the wire (0 for variable-length text)."""
        if self.type in _SCALARS:
            return _SCALARS[self.type][0]
        m = _CHAR_RE.match(self.type)
        return int(m.group(1)) if m else 0

    @property
    def struct_code(self) -> str:
        if self.type in _SCALARS:
            return _SCALARS[self.type][1]
        return f"{self.size}s"

    @property
    def int_range(self) -> tuple[int, int] | None:
        return _INT_RANGES.get(self.type)

    @property
    def factor(self) -> float:
        """Multiply the raw value by this to get SI units (1.0 if the field has no scale)."""
        if self.q is not None:
            return 2.0**-self.q
        if self.scale is not None:
            return self.scale
        return 1.0


@dataclass(frozen=True)
class GroupSpec:
    """A repeated group at the end of a message: u8 count, then `count` items."""

    name: str
    max: int
    cls: type[Any]
    fields: tuple[FieldSpec, ...]

    @property
    def item_size(self) -> int:
        return sum(f.size for f in self.fields)

    @cached_property
    def item_struct(self) -> struct.Struct:
        return struct.Struct("<" + "".join(f.struct_code for f in self.fields))

    @cached_property
    def i24_positions(self) -> tuple[int, ...]:
        """Indices of the i24 fields (unpacked as 3 raw bytes, converted by the codec)."""
        return tuple(i for i, f in enumerate(self.fields) if f.type == "i24")


@dataclass(frozen=True)
class MessageSpec:
    """One message: id, direction, fields in wire order, optional group, dataclass."""

    name: str
    msg_id: int
    direction: str  # "device" (device -> host) or "host" (host -> device)
    cls: type[Any]
    fields: tuple[FieldSpec, ...]
    group: GroupSpec | None = None

    @property
    def text(self) -> FieldSpec | None:
        """The trailing variable-length text field, if any."""
        if self.fields and self.fields[-1].type == "text":
            return self.fields[-1]
        return None

    @property
    def fixed_fields(self) -> tuple[FieldSpec, ...]:
        return tuple(f for f in self.fields if f.type != "text")

    @property
    def fixed_size(self) -> int:
        return sum(f.size for f in self.fixed_fields)

    @cached_property
    def fixed_struct(self) -> struct.Struct:
        return struct.Struct("<" + "".join(f.struct_code for f in self.fixed_fields))

    @cached_property
    def i24_positions(self) -> tuple[int, ...]:
        """Indices (among fixed_fields) of the i24 fields."""
        return tuple(i for i, f in enumerate(self.fixed_fields) if f.type == "i24")

    def payload_size(self, items: int = 0, text_len: int = 0) -> int:
        """Payload bytes for a given group count / text length."""
        n = self.fixed_size
        if self.group is not None:
            n += 1 + items * self.group.item_size
        return n + text_len

    @property
    def max_payload_size(self) -> int:
        text = self.text
        return self.payload_size(self.group.max if self.group else 0, text.max if text else 0)

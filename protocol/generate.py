#!/usr/bin/env python3
"""Generate the C++ header and the Python module of the jointangle wire protocol.

Reads protocol/messages.toml (the single source of truth) and writes
  firmware/protocol/messages.hpp        -- structs, encode/decode, visit, X-macro list
  host/jointangle/protocol/messages.py  -- constants, enums, message specs and dataclasses

Usage:
  python protocol/generate.py           write both files
  python protocol/generate.py --check   exit 1 (naming the stale files) if either differs
  python protocol/generate.py --hash    print the schema hash

Standard library only (it runs before any virtual environment exists). The framing (COBS, CRC,
header) is NOT generated: it is hand-written once per language (firmware/protocol/frame.*,
host/jointangle/protocol/framing.py) like MAVLink's checksum.h / mavcrc.py.

The schema hash (like MAVLink's CRC_EXTRA, but over the whole schema) is the first four bytes of
SHA-256 over a canonical text of everything that affects the bytes on the wire or their meaning:
protocol version, message ids and names, field names, wire types, units, scales, group bounds,
and enum/flag values. Docs and comments do not change it.
"""

from __future__ import annotations

import argparse
import hashlib
import re
import sys
import textwrap
import tomllib
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFINITIONS = ROOT / "protocol" / "messages.toml"
CPP_OUT = ROOT / "firmware" / "protocol" / "messages.hpp"
PY_OUT = ROOT / "host" / "jointangle" / "protocol" / "messages.py"

HEADER_SIZE = 8  # version u8, msg_id u8, seq u16, t_us u32
CRC_SIZE = 2

# wire type -> (size in bytes, C type, Python type)
SCALARS: dict[str, tuple[int, str, str]] = {
    "u8": (1, "uint8_t", "int"),
    "i8": (1, "int8_t", "int"),
    "u16": (2, "uint16_t", "int"),
    "i16": (2, "int16_t", "int"),
    "i24": (3, "int32_t", "int"),
    "u32": (4, "uint32_t", "int"),
    "i32": (4, "int32_t", "int"),
    "f32": (4, "float", "float"),
}
CHAR_RE = re.compile(r"^char\[(\d+)\]$")
NAME_RE = re.compile(r"^[a-z][a-z0-9_]*$")


class DefinitionError(Exception):
    pass


@dataclass(frozen=True)
class Field:
    name: str
    type: str  # wire type: a SCALARS key, "char[N]" or "text"
    unit: str
    scale: float | None  # value = raw * scale
    q: int | None  # value = raw * 2^-q
    enum: str | None
    flags: str | None
    max: int  # text only: maximum length in bytes
    doc: str
    # An appended field's value where older code builds the message without it (Python
    # keyword default; not on the wire, not in the schema hash).
    default: int | None = None

    @property
    def size(self) -> int:
        """Wire size in bytes (0 for text, which is variable)."""
        if self.type in SCALARS:
            return SCALARS[self.type][0]
        m = CHAR_RE.match(self.type)
        if m:
            return int(m.group(1))
        return 0

    @property
    def char_len(self) -> int:
        m = CHAR_RE.match(self.type)
        return int(m.group(1)) if m else 0

    def canonical(self) -> str:
        scale = "" if self.scale is None else repr(self.scale)
        q = "" if self.q is None else str(self.q)
        kind = self.enum or self.flags or ""
        return (f"{self.type} {self.name} unit={self.unit} scale={scale} q={q} kind={kind} "
                f"max={self.max}")


@dataclass(frozen=True)
class Group:
    name: str
    max: int
    fields: tuple[Field, ...]
    doc: str

    @property
    def item_size(self) -> int:
        return sum(f.size for f in self.fields)


@dataclass(frozen=True)
class Message:
    name: str
    id: int
    direction: str
    fields: tuple[Field, ...]
    group: Group | None
    doc: str

    @property
    def fixed_size(self) -> int:
        return sum(f.size for f in self.fields)

    @property
    def text(self) -> Field | None:
        return next((f for f in self.fields if f.type == "text"), None)

    @property
    def max_size(self) -> int:
        n = self.fixed_size
        if self.group is not None:
            n += 1 + self.group.max * self.group.item_size
        if self.text is not None:
            n += self.text.max
        return n

    @property
    def cpp_name(self) -> str:
        return pascal(self.name)

    @property
    def item_cpp_name(self) -> str:
        assert self.group is not None
        return pascal(self.name) + pascal(singular(self.group.name))


@dataclass(frozen=True)
class Kind:
    """An enum (exclusive values) or a flag set (bit values)."""

    name: str
    is_flags: bool
    values: tuple[tuple[str, int], ...]
    doc: str


@dataclass(frozen=True)
class Schema:
    version: int
    max_payload: int
    max_sensors: int
    kinds: tuple[Kind, ...]
    messages: tuple[Message, ...]

    def canonical(self) -> str:
        lines = [f"jointangle-protocol version={self.version} max_payload={self.max_payload}"]
        for k in self.kinds:
            vals = ",".join(f"{n}={v}" for n, v in k.values)
            lines.append(f"{'flags' if k.is_flags else 'enum'} {k.name} {vals}")
        for m in sorted(self.messages, key=lambda m: m.id):
            lines.append(f"message {m.id} {m.name} {m.direction}")
            lines += ["  " + f.canonical() for f in m.fields]
            if m.group is not None:
                lines.append(f"  group {m.group.name} max={m.group.max}")
                lines += ["    " + f.canonical() for f in m.group.fields]
        return "\n".join(lines) + "\n"

    @property
    def hash(self) -> int:
        return int.from_bytes(hashlib.sha256(self.canonical().encode()).digest()[:4], "big")


def pascal(name: str) -> str:
    return "".join(p.capitalize() for p in name.split("_"))


def singular(name: str) -> str:
    return name[:-1] if name.endswith("s") else name


def const_name(name: str) -> str:
    """C++ kConstant spelling of a snake_case value name."""
    return "k" + pascal(name)


# --------------------------------------------------------------------------------------------
# Parsing and validation


def _field(raw: dict[str, object], where: str, in_group: bool) -> Field:
    name = str(raw.get("name", ""))
    if not NAME_RE.match(name):
        raise DefinitionError(f"{where}: bad field name {name!r}")
    ftype = str(raw.get("type", ""))
    if ftype not in SCALARS and not CHAR_RE.match(ftype) and ftype != "text":
        raise DefinitionError(f"{where}.{name}: unknown type {ftype!r}")
    if ftype == "text" and in_group:
        raise DefinitionError(f"{where}.{name}: text is not allowed in a group")
    scale = raw.get("scale")
    q = raw.get("q")
    if scale is not None and q is not None:
        raise DefinitionError(f"{where}.{name}: give scale or q, not both")
    max_len = int(raw.get("max", 0))  # type: ignore[call-overload]
    if ftype == "text" and not 0 < max_len < 255:
        raise DefinitionError(f"{where}.{name}: text needs 0 < max < 255")
    return Field(
        name=name,
        type=ftype,
        unit=str(raw.get("unit", "")),
        scale=None if scale is None else float(scale),  # type: ignore[arg-type]
        q=None if q is None else int(q),  # type: ignore[call-overload]
        enum=None if raw.get("enum") is None else str(raw["enum"]),
        flags=None if raw.get("flags") is None else str(raw["flags"]),
        max=max_len,
        doc=str(raw.get("doc", "")),
        default=None if raw.get("default") is None else int(raw["default"]),  # type: ignore[call-overload]
    )


def load(path: Path = DEFINITIONS) -> Schema:
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    proto = data["protocol"]
    kinds: list[Kind] = []
    for section, is_flags in (("enums", False), ("flags", True)):
        for kname, body in data.get(section, {}).items():
            values = tuple((str(k), int(v)) for k, v in body["values"].items())
            kinds.append(Kind(kname, is_flags, values, str(body.get("doc", ""))))
    kind_names = {k.name for k in kinds}
    messages: list[Message] = []
    for raw in data["messages"]:
        name = str(raw["name"])
        where = f"message {name}"
        fields = tuple(_field(f, where, False) for f in raw.get("fields", []))
        group = None
        if "group" in raw:
            g = raw["group"]
            gfields = tuple(_field(f, f"{where}.{g['name']}", True) for f in g["fields"])
            group = Group(str(g["name"]), int(g.get("max", proto["max_sensors"])), gfields,
                          str(g.get("doc", "")))
        msg = Message(name, int(raw["id"]), str(raw["direction"]), fields, group,
                      str(raw.get("doc", "")))
        if msg.direction not in ("device", "host"):
            raise DefinitionError(f"{where}: direction must be device or host")
        if not 0 < msg.id < 256:
            raise DefinitionError(f"{where}: id must be 1..255")
        texts = [f for f in fields if f.type == "text"]
        if texts and (group is not None or fields[-1].type != "text" or len(texts) > 1):
            raise DefinitionError(f"{where}: text must be the single last field, without a group")
        if msg.max_size > int(proto["max_payload"]):
            raise DefinitionError(f"{where}: up to {msg.max_size} bytes > max_payload")
        for f in fields + (group.fields if group else ()):
            for k in (f.enum, f.flags):
                if k is not None and k not in kind_names:
                    raise DefinitionError(f"{where}.{f.name}: unknown enum/flags {k!r}")
        names = [f.name for f in fields] + ([group.name] if group else [])
        if len(set(names)) != len(names):
            raise DefinitionError(f"{where}: duplicate field names")
        messages.append(msg)
    ids = [m.id for m in messages]
    if len(set(ids)) != len(ids):
        raise DefinitionError("duplicate message ids")
    if len({m.name for m in messages}) != len(messages):
        raise DefinitionError("duplicate message names")
    return Schema(int(proto["version"]), int(proto["max_payload"]), int(proto["max_sensors"]),
                  tuple(kinds), tuple(messages))


# --------------------------------------------------------------------------------------------
# C++ backend


def _cpp_comment(f: Field) -> str:
    parts = []
    if f.q is not None:
        parts.append(f"Q{f.q}" + (f" {f.unit}" if f.unit else ""))
    elif f.scale is not None:
        parts.append(f"x{f.scale:g}" + (f" {f.unit}" if f.unit else ""))
    elif f.unit:
        parts.append(f.unit)
    if f.enum:
        parts.append(f"enum {f.enum}")
    if f.flags:
        parts.append(f"flags {f.flags}")
    if f.doc:
        parts.append(f.doc)
    return ("  // " + "; ".join(parts)) if parts else ""


def _cpp_member(f: Field) -> str:
    if f.type in SCALARS:
        return f"{SCALARS[f.type][1]} {f.name};"
    if f.type == "text":
        return f"Text<{f.max}> {f.name};"
    return f"char {f.name}[{f.char_len}];"


def _cpp_put(f: Field, ptr: str, expr: str) -> str:
    if f.type in SCALARS:
        return f"put_{f.type}({ptr}, {expr});"
    return f"put_chars({ptr}, {expr}, {f.char_len});"


def _cpp_get(f: Field, ptr: str, expr: str) -> str:
    if f.type in SCALARS:
        return f"{expr} = get_{f.type}({ptr});"
    return f"get_chars({ptr}, {expr}, {f.char_len});"


def gen_cpp(s: Schema) -> str:
    out: list[str] = []
    w = out.append
    w("// GENERATED by protocol/generate.py from protocol/messages.toml -- do not edit.")
    w("// Regenerate with `python protocol/generate.py`; ctest and pytest fail when it is stale.")
    w("//")
    w("// One struct per message: plain data (fields in wire order), encode() to payload bytes,")
    w("// decode() from payload bytes (exact length checked), visit() for tests and tools.")
    w("// Enum and flag fields are stored raw (uint8_t) so unknown values survive a round trip.")
    w("// Written for C++11 and later so avr-gcc 5.4 builds it; no allocation, no exceptions.")
    w("// clang-format off")
    w("#ifndef JA_PROTOCOL_MESSAGES_HPP_")
    w("#define JA_PROTOCOL_MESSAGES_HPP_")
    w("")
    w("#include <stddef.h>")
    w("#include <stdint.h>")
    w("")
    w('#include "protocol/wire.hpp"')
    w("")
    w("namespace ja {")
    w("namespace proto {")
    w("")
    w(f"constexpr uint8_t kProtocolVersion = {s.version};")
    w(f"constexpr uint32_t kSchemaHash = 0x{s.hash:08X}u;")
    w(f"constexpr size_t kMaxPayload = {s.max_payload};  // bytes")
    w(f"constexpr size_t kMaxSensors = {s.max_sensors};")
    w("")
    for k in s.kinds:
        w(f"// {k.doc}")
        if k.is_flags:
            w(f"namespace {re.sub(r'(?<!^)(?=[A-Z])', '_', k.name).lower()} {{")
            for n, v in k.values:
                w(f"constexpr uint8_t {const_name(n)} = 0x{v:02X};")
            w("}  // namespace " + re.sub(r"(?<!^)(?=[A-Z])", "_", k.name).lower())
        else:
            w(f"enum class {k.name} : uint8_t {{")
            for n, v in k.values:
                w(f"  {const_name(n)} = {v},")
            w("};")
        w("")
    for m in s.messages:
        if m.group is not None:
            w(f"// One item of {m.cpp_name}::{m.group.name}. {m.group.doc}")
            w(f"struct {m.item_cpp_name} {{")
            for f in m.group.fields:
                w(f"  {_cpp_member(f)}{_cpp_comment(f)}")
            w("};")
            w("")
        arrow = "device -> host" if m.direction == "device" else "host -> device"
        w(f"// {m.name} (0x{m.id:02X}, {arrow}): {m.doc}")
        w(f"struct {m.cpp_name} {{")
        w(f"  static constexpr uint8_t kId = 0x{m.id:02X};")
        w(f"  static constexpr size_t kFixedSize = {m.fixed_size};  // bytes before group/text")
        if m.group is not None:
            w(f"  static constexpr size_t kItemSize = {m.group.item_size};")
            w(f"  static constexpr uint8_t kMaxItems = {m.group.max};")
        w(f"  static constexpr size_t kMaxSize = {m.max_size};")
        w("")
        for f in m.fields:
            w(f"  {_cpp_member(f)}{_cpp_comment(f)}")
        if m.group is not None:
            w(f"  uint8_t {m.group.name}_count;  // items in use (on the wire: one u8 before them)")
            w(f"  {m.item_cpp_name} {m.group.name}[{m.group.max}];")
        w("")
        w("  // Writes the payload; false (nothing meaningful written) if it does not fit `cap`.")
        w("  bool encode(uint8_t* out, size_t cap, size_t* len) const {")
        if m.group is not None:
            g = m.group
            w(f"    if ({g.name}_count > kMaxItems) return false;")
            w(f"    const size_t n = kFixedSize + 1 + "
              f"static_cast<size_t>({g.name}_count) * kItemSize;")
        elif m.text is not None:
            w(f"    if ({m.text.name}.len > {m.text.max}) return false;")
            w(f"    const size_t n = kFixedSize + {m.text.name}.len;")
        else:
            w("    const size_t n = kFixedSize;")
        if m.fixed_size or m.group is not None or m.text is not None:
            w("    if (n > cap) return false;")
        else:
            w("    (void)cap;")
        off = 0
        for f in m.fields:
            if f.type == "text":
                w(f"    put_text(out + {off}, {f.name});")
            else:
                w(f"    {_cpp_put(f, f'out + {off}', f.name)}")
            off += f.size
        if m.group is not None:
            g = m.group
            w(f"    out[{off}] = {g.name}_count;")
            w(f"    for (uint8_t i = 0; i < {g.name}_count; ++i) {{")
            w(f"      uint8_t* p = out + {off + 1} + static_cast<size_t>(i) * kItemSize;")
            ioff = 0
            for f in g.fields:
                w(f"      {_cpp_put(f, f'p + {ioff}', f'{g.name}[i].{f.name}')}")
                ioff += f.size
            w("    }")
        if not m.fields and m.group is None:
            w("    (void)out;")
        w("    *len = n;")
        w("    return true;")
        w("  }")
        w("")
        w("  // Reads a payload; false if its length (or group count) is not exactly right.")
        w("  bool decode(const uint8_t* in, size_t n) {")
        if m.group is not None:
            g = m.group
            w("    if (n < kFixedSize + 1) return false;")
            w(f"    const uint8_t count = in[{m.fixed_size}];")
            w("    if (count > kMaxItems || "
              "n != kFixedSize + 1 + static_cast<size_t>(count) * kItemSize) {")
            w("      return false;")
            w("    }")
        elif m.text is not None:
            w(f"    if (n < kFixedSize || n > kFixedSize + {m.text.max}) return false;")
        else:
            w("    if (n != kFixedSize) return false;")
        off = 0
        for f in m.fields:
            if f.type == "text":
                w(f"    get_text(in + {off}, n - {off}, &{f.name});")
            else:
                w(f"    {_cpp_get(f, f'in + {off}', f.name)}")
            off += f.size
        if m.group is not None:
            g = m.group
            w(f"    {g.name}_count = count;")
            w("    for (uint8_t i = 0; i < count; ++i) {")
            w(f"      const uint8_t* p = in + {off + 1} + static_cast<size_t>(i) * kItemSize;")
            ioff = 0
            for f in g.fields:
                w(f"      {_cpp_get(f, f'p + {ioff}', f'{g.name}[i].{f.name}')}")
                ioff += f.size
            w("    }")
        if not m.fields and m.group is None:
            w("    (void)in;")
        w("    return true;")
        w("  }")
        w("")
        w("  // Calls f(group, index, name, member&) for every field (group nullptr, index -1")
        w("  // for top-level fields); f.group(name, count&, max) comes before a group's items.")
        w("  template <class F>")
        w("  void visit(F& f) {")
        for f in m.fields:
            w(f'    f(nullptr, -1, "{f.name}", {f.name});')
        if m.group is not None:
            g = m.group
            w(f'    f.group("{g.name}", {g.name}_count, kMaxItems);')
            w(f"    for (uint8_t i = 0; i < {g.name}_count && i < kMaxItems; ++i) {{")
            for f in g.fields:
                w(f'      f("{g.name}", i, "{f.name}", {g.name}[i].{f.name});')
            w("    }")
        if not m.fields and m.group is None:
            w("    (void)f;")
        w("  }")
        w("};")
        w("")
    w("// X-macro over every message: X(StructName, id, name)")
    w("#define JA_PROTO_FOR_EACH_MESSAGE(X) \\")
    for i, m in enumerate(s.messages):
        tail = " \\" if i < len(s.messages) - 1 else ""
        w(f'  X({m.cpp_name}, 0x{m.id:02X}, "{m.name}"){tail}')
    w("")
    w("// Name of a message id, or nullptr if the id is unknown.")
    w("inline const char* message_name(uint8_t id) {")
    w("  switch (id) {")
    for m in s.messages:
        w(f"    case 0x{m.id:02X}:")
        w(f'      return "{m.name}";')
    w("    default:")
    w("      return nullptr;")
    w("  }")
    w("}")
    w("")
    w("}  // namespace proto")
    w("}  // namespace ja")
    w("")
    w("#endif  // JA_PROTOCOL_MESSAGES_HPP_")
    w("// clang-format on")
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------------------------
# Python backend


def _py_field(f: Field) -> str:
    args = [repr(f.name), repr(f.type)]
    if f.unit:
        args.append(f"unit={f.unit!r}")
    if f.scale is not None:
        args.append(f"scale={f.scale!r}")
    if f.q is not None:
        args.append(f"q={f.q}")
    if f.enum:
        args.append(f"kind={f.enum!r}")
    if f.flags:
        args.append(f"kind={f.flags!r}")
    if f.max:
        args.append(f"max={f.max}")
    return f"FieldSpec({', '.join(args)})"


def _py_type(f: Field) -> str:
    if f.type in SCALARS:
        return SCALARS[f.type][2]
    if f.type == "text":
        return "str"
    return "bytes"


def gen_py(s: Schema) -> str:
    out: list[str] = []
    w = out.append
    w('"""GENERATED by protocol/generate.py from protocol/messages.toml -- do not edit.')
    w("")
    w("Regenerate with `python protocol/generate.py`; the tests fail when this file is stale.")
    w("Constants, enums, one frozen dataclass per message (fields in wire order; enum and flag")
    w("fields hold plain ints, char[N] fields raw bytes) and SPECS, the table the codecs use.")
    w('"""')
    w("")
    w("from __future__ import annotations")
    w("")
    w("import enum")
    w("from dataclasses import dataclass")
    w("from typing import ClassVar")
    w("")
    w("from jointangle.protocol.spec import FieldSpec, GroupSpec, MessageSpec")
    w("")
    w(f"PROTOCOL_VERSION = {s.version}")
    w(f"SCHEMA_HASH = 0x{s.hash:08X}")
    w(f"MAX_PAYLOAD = {s.max_payload}")
    w(f"MAX_SENSORS = {s.max_sensors}")
    w("")
    for k in s.kinds:
        w("")
        base = "enum.IntFlag" if k.is_flags else "enum.IntEnum"
        w(f"class {k.name}({base}):")
        w(f'    """{k.doc}"""')
        w("")
        for n, v in k.values:
            w(f"    {n.upper()} = {v}")
        w("")
    for m in s.messages:
        if m.group is not None:
            w("")
            w("@dataclass(frozen=True, slots=True)")
            w(f"class {m.item_cpp_name}:")
            w(f'    """One item of {m.cpp_name}.{m.group.name}."""')
            w("")
            for f in m.group.fields:
                w(f"    {f.name}: {_py_type(f)}"
                  + ("" if f.default is None else f" = {f.default}"))
            w("")
        w("")
        w("@dataclass(frozen=True, slots=True)")
        w(f"class {m.cpp_name}:")
        dest = "host" if m.direction == "device" else "device"
        doc = f"{m.name} (0x{m.id:02X}, {m.direction} -> {dest}): {m.doc}"
        lines = textwrap.wrap(doc, 88)
        if len(lines) == 1:
            w(f'    """{lines[0]}"""')
        else:
            w(f'    """{lines[0]}')
            for ln in lines[1:]:
                w(f"    {ln}")
            w('    """')
        w("")
        w(f"    MSG_ID: ClassVar[int] = 0x{m.id:02X}")
        w(f'    NAME: ClassVar[str] = "{m.name}"')
        w("")
        for f in m.fields:
            w(f"    {f.name}: {_py_type(f)}" + ("" if f.default is None else f" = {f.default}"))
        if m.group is not None:
            w(f"    {m.group.name}: tuple[{m.item_cpp_name}, ...] = ()")
        if not m.fields and m.group is None:
            w("    pass")
        w("")
    w("")
    w("# Message classes as a union type, for annotations.")
    w("Message = (")
    names = [m.cpp_name for m in s.messages]
    for i in range(0, len(names), 6):
        lead = "    " if i == 0 else "    | "
        w(lead + " | ".join(names[i : i + 6]))
    w(")")
    w("")
    w("SPECS: tuple[MessageSpec, ...] = (")
    for m in s.messages:
        w("    MessageSpec(")
        w(f"        name={m.name!r},")
        w(f"        msg_id=0x{m.id:02X},")
        w(f"        direction={m.direction!r},")
        w(f"        cls={m.cpp_name},")
        if m.fields:
            w("        fields=(")
            for f in m.fields:
                w(f"            {_py_field(f)},")
            w("        ),")
        else:
            w("        fields=(),")
        if m.group is not None:
            w("        group=GroupSpec(")
            w(f"            name={m.group.name!r},")
            w(f"            max={m.group.max},")
            w(f"            cls={m.item_cpp_name},")
            w("            fields=(")
            for f in m.group.fields:
                w(f"                {_py_field(f)},")
            w("            ),")
            w("        ),")
        w("    ),")
    w(")")
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------------------------


def outputs(schema: Schema) -> dict[Path, str]:
    return {CPP_OUT: gen_cpp(schema), PY_OUT: gen_py(schema)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--check", action="store_true", help="fail if the generated files are stale")
    ap.add_argument("--hash", action="store_true", help="print the schema hash and exit")
    args = ap.parse_args(argv)
    try:
        schema = load()
    except (DefinitionError, KeyError, ValueError, tomllib.TOMLDecodeError) as exc:
        sys.stderr.write(f"generate.py: {DEFINITIONS}: {exc}\n")
        return 2
    if args.hash:
        sys.stdout.write(f"0x{schema.hash:08X}\n")
        return 0
    stale = []
    for path, text in outputs(schema).items():
        current = path.read_text(encoding="utf-8") if path.exists() else None
        if current == text:
            continue
        if args.check:
            stale.append(path)
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
            sys.stdout.write(f"wrote {path.relative_to(ROOT)}\n")
    if stale:
        names = ", ".join(str(p.relative_to(ROOT)) for p in stale)
        sys.stderr.write(f"generate.py: stale generated files: {names}; "
                         "run `python protocol/generate.py`\n")
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

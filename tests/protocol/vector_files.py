"""Readers of the shared vector files (protocol/vectors/), for the protocol tests."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
VECTORS = ROOT / "protocol" / "vectors"


@dataclasses.dataclass
class Vector:
    name: str
    message: str = ""
    seq: int = 0
    t_us: int = 0
    fields: dict[str, Any] = dataclasses.field(default_factory=dict)
    frame: bytes = b""


@dataclasses.dataclass
class StreamVector:
    name: str
    data: bytes = b""
    counts: dict[str, int] = dataclasses.field(default_factory=dict)
    frames: list[tuple[int, int]] = dataclasses.field(default_factory=list)


def load_golden() -> list[Vector]:
    out: list[Vector] = []
    cur: Vector | None = None
    for line in (VECTORS / "golden.txt").read_text().splitlines():
        if not line or line.startswith("#"):
            continue
        key, _, rest = line.partition(" ")
        if key == "vector":
            cur = Vector(rest)
        elif key == "end":
            assert cur is not None
            out.append(cur)
            cur = None
        elif cur is not None and key == "message":
            cur.message = rest
        elif cur is not None and key in ("seq", "t_us"):
            setattr(cur, key, int(rest))
        elif cur is not None and key == "field":
            parts = rest.split(" ", 2)
            name, kind, value = parts if len(parts) == 3 else (*parts, "")
            cur.fields[name] = int(value) if kind == "int" else bytes.fromhex(value)
        elif cur is not None and key == "frame":
            cur.frame = bytes.fromhex(rest)
    return out


def load_streams(name: str = "streams.txt") -> list[StreamVector]:
    """The stream vectors of protocol/vectors/NAME (streams.txt: every decoder; sequence.txt:
    the host's windowed sequence accounting)."""
    out: list[StreamVector] = []
    cur: StreamVector | None = None
    for line in (VECTORS / name).read_text().splitlines():
        if not line or line.startswith("#"):
            continue
        key, _, rest = line.partition(" ")
        if key == "stream":
            cur = StreamVector(rest)
        elif key == "end":
            assert cur is not None
            out.append(cur)
            cur = None
        elif cur is not None and key == "bytes":
            cur.data = bytes.fromhex(rest)
        elif cur is not None and key == "count":
            k, v = rest.split()
            cur.counts[k] = int(v)
        elif cur is not None and key == "frame":
            a, b = rest.split()
            cur.frames.append((int(a), int(b)))
    return out

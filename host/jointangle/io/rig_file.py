"""Rig files (TOML, docs/design.md §4.1) on disk: read with a size cap, validated; written whole
or not at all. The text itself is parsed and written by `jointangle.rig` (`parse_rig`,
`dump_rig`)."""

from __future__ import annotations

from pathlib import Path

from jointangle.io.atomic import atomic_path
from jointangle.io.input_files import RIG_MAX_BYTES, read_input_text
from jointangle.rig import Rig, dump_rig, parse_rig


def load_rig(path: str | Path) -> Rig:
    """Read and validate a rig file."""
    p = Path(path)
    return parse_rig(read_rig_text(p), str(p))


def read_rig_text(path: str | Path) -> str:
    """A rig file's text; unreadable or not UTF-8 -> InputError naming the file."""
    return read_input_text(path, "rig file", RIG_MAX_BYTES, "a rig file is TOML")


def write_rig(rig: Rig, path: str | Path) -> None:
    """Write the rig file whole or not at all (a write error is an InputError naming `path`;
    the file there before is kept)."""
    text = dump_rig(rig)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")

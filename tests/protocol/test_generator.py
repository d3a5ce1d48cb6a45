"""The generator: generated files are current, the schema hash is the same everywhere, and bad
definitions are refused with a message."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

from jointangle.protocol import messages

ROOT = Path(__file__).resolve().parents[2]


def _generator() -> ModuleType:
    spec = importlib.util.spec_from_file_location("ja_generate", ROOT / "protocol" / "generate.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["ja_generate"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_generated_files_are_current() -> None:
    res = subprocess.run([sys.executable, str(ROOT / "protocol" / "generate.py"), "--check"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr


def test_vector_files_are_current() -> None:
    res = subprocess.run([sys.executable, str(ROOT / "protocol" / "make_vectors.py"), "--check"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr


def test_schema_hash_is_the_same_in_both_languages() -> None:
    gen = _generator()
    schema = gen.load()
    assert schema.hash == messages.SCHEMA_HASH
    hpp = (ROOT / "firmware" / "protocol" / "messages.hpp").read_text()
    m = re.search(r"kSchemaHash = 0x([0-9A-F]{8})u;", hpp)
    assert m is not None and int(m.group(1), 16) == messages.SCHEMA_HASH
    assert f"kProtocolVersion = {messages.PROTOCOL_VERSION};" in hpp


def test_schema_hash_ignores_docs_but_not_layout(tmp_path: Path) -> None:
    gen = _generator()
    text = (ROOT / "protocol" / "messages.toml").read_text()
    base = gen.load().hash

    def hash_of(src: str) -> int:
        p = tmp_path / "m.toml"
        p.write_text(src)
        return int(gen.load(p).hash)

    assert hash_of(text.replace('doc = "Filter output and health."', 'doc = "Other."')) == base
    assert hash_of(text.replace('name = "nis", type = "u16"', 'name = "nis", type = "i16"')) != base
    assert hash_of(text.replace("q = 24, unit = \"rad\", doc = \"joint angle",
                                "q = 23, unit = \"rad\", doc = \"joint angle")) != base


@pytest.mark.parametrize(
    ("old", "new", "complaint"),
    [
        ("\nid = 0x02", "\nid = 0x01", "duplicate message ids"),
        ('type = "i24", unit = "count", doc = "raw', 'type = "i99", unit = "count", doc = "raw',
         "unknown type"),
        ('flags = "StreamMode" },\n  { name = "eeprom"', 'flags = "Nope" },\n  { name = "eeprom"',
         "unknown enum/flags"),
        ("max = 200", "max = 240", "max_payload"),
    ],
)
def test_bad_definitions_are_refused(tmp_path: Path, old: str, new: str, complaint: str) -> None:
    gen = _generator()
    text = (ROOT / "protocol" / "messages.toml").read_text()
    assert old in text
    p = tmp_path / "m.toml"
    p.write_text(text.replace(old, new, 1))
    with pytest.raises(gen.DefinitionError, match=complaint):
        gen.load(p)

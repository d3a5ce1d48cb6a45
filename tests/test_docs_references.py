"""Every document and code comment that names a Markdown file names one in the repository, and
every section it names (`docs/design.md §4`, `FILTER.md "Square roots"`) is a heading there.

A fresh clone with nothing beside it must be able to follow every reference (issue 20).
"""

from __future__ import annotations

import re
import subprocess
from functools import cache
from pathlib import Path

import pytest

from jointangle.rig import parse_rig

REPO = Path(__file__).resolve().parents[1]

# Files whose text is read: documents, sources, build and configuration files.
TEXT_SUFFIXES = {".md", ".py", ".hpp", ".cpp", ".h", ".c", ".ino", ".cmake", ".toml", ".sh",
                 ".txt", ".cfg", ".ini", ".yml", ".yaml"}

# A Markdown file name, with an optional path before it; then optionally a section: `§3`,
# `§4.1`, `§A1`, `§D, §D2`, `section 3`, or a quoted heading `"Timing"`.
_REF = re.compile(r"(?<![\w/.-])((?:[\w.-]+/)*[\w-]+\.md)(?![\w])")
_SECTIONS = re.compile(r"\A(?:,? ?(?:§ ?|section )([0-9A-Z](?:[0-9.]*[0-9])?))+")
_SECTION = re.compile(r"(?:§ ?|section )([0-9A-Z](?:[0-9.]*[0-9])?)")
_QUOTED = re.compile(r"\A,? \(?[\"“]([^\"”\n]{3,80})[\"”]")
# Run-in headings count as sections too: a paragraph opening `**Pipelined sampling**` or `Timing:`.
_RUN_IN = re.compile(r"\A(?:\*\*([^*]{3,80})\*\*|([A-Z][\w /-]{2,40}):\s)")


def _tracked_files() -> list[Path]:
    out = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True)
    paths = [REPO / p for p in out.stdout.decode().split("\0") if p]
    return [p for p in paths if p.is_file()
            and (p.suffix in TEXT_SUFFIXES or p.name == "CMakeLists.txt")]


@cache
def _markdown_files() -> dict[str, list[Path]]:
    by_name: dict[str, list[Path]] = {}
    for p in _tracked_files():
        if p.suffix == ".md":
            by_name.setdefault(p.name, []).append(p)
    return by_name


def _resolve(name: str, source: Path) -> Path | None:
    """The document a reference names: a path from the repository root or from the referring
    file's folder, or a file name that is unique in the repository."""
    for base in (source.parent, REPO):
        candidate = (base / name).resolve()
        if candidate.is_file():
            return candidate
    if "/" not in name:
        found = _markdown_files().get(name, [])
        if len(found) == 1:
            return found[0]
    return None


@cache
def _headings(doc: Path) -> list[str]:
    out = []
    for line in doc.read_text(encoding="utf-8").splitlines():
        if line.startswith("#"):
            out.append(line.lstrip("#").strip())
        elif m := _RUN_IN.match(line):
            out.append(m.group(1) or m.group(2))
    return out


def _has_numbered_section(doc: Path, section: str) -> bool:
    # `## 3. The model`, `### 4.1 Rig file`, `## A. Registers`, `### A1 ADXL345`
    pattern = re.compile(rf"\A{re.escape(section)}(?:[.: ]|\Z)")
    return any(pattern.match(h) for h in _headings(doc))


def _has_titled_section(doc: Path, title: str) -> bool:
    t = title.strip().lower()
    return any(t in h.lower() for h in _headings(doc))


def _problems(path: Path) -> list[str]:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        return []
    rel = path.relative_to(REPO)
    out = []
    for n, line in enumerate(text.splitlines(), 1):
        for m in _REF.finditer(line):
            name = m.group(1)
            if "://" in line[max(0, m.start() - 40):m.start()] or name.startswith("http"):
                continue
            doc = _resolve(name, path)
            if doc is None:
                out.append(f"{rel}:{n}: {name} is not in the repository")
                continue
            rest = line[m.end():]
            sections = _SECTIONS.match(rest)
            if sections:
                for s in _SECTION.findall(sections.group(0)):
                    if not _has_numbered_section(doc, s):
                        out.append(f"{rel}:{n}: {name} has no section {s}")
                continue
            quoted = _QUOTED.match(rest)
            if quoted and not _has_titled_section(doc, quoted.group(1)):
                out.append(f"{rel}:{n}: {name} has no section \"{quoted.group(1)}\"")
    return out


def test_every_named_document_and_section_exists() -> None:
    this = Path(__file__).resolve()  # its own examples of broken references below
    problems = [p for f in _tracked_files() if f != this for p in _problems(f)]
    assert not problems, "references that do not resolve:\n" + "\n".join(problems)


@pytest.mark.parametrize(("line", "ok"), [
    ("see docs/design.md §4 for the contract", True),
    ("the rig (docs/design.md §4.1)", True),
    ("(docs/sensors.md §D, §D2)", True),
    ("notation of DESIGN.md §3", False),
    ("docs/design.md §9", False),
    ("docs/sensors.md §A9", False),
    ('FILTER.md "Square roots"', True),
    ('FILTER.md "No such heading"', False),
])
def test_the_checker_tells_resolving_references_from_broken_ones(
        tmp_path: Path, line: str, ok: bool) -> None:
    probe = REPO / "tests" / "_probe_reference.py"
    probe_text = f"# {line}\n"
    try:
        probe.write_text(probe_text, encoding="utf-8")
        assert (_problems(probe) == []) is ok, _problems(probe)
    finally:
        probe.unlink()


_DATE = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b")


@pytest.mark.parametrize("doc", [
    "README.md", "firmware/core/FILTER.md", "firmware/platform/avr/README.md",
    "firmware/platform/posix/README.md", "firmware/sim/avr_board/README.md"])
def test_documents_describe_the_present_and_leave_dated_history_to_docs_history(doc: str) -> None:
    text = (REPO / doc).read_text(encoding="utf-8")
    dated = [line for line in text.splitlines() if _DATE.search(line)]
    assert not dated, f"{doc}: dated history belongs in docs/history.md:\n" + "\n".join(dated)


def test_the_readme_stays_an_overview() -> None:
    lines = (REPO / "README.md").read_text(encoding="utf-8").splitlines()
    # 210 until the user's install section (issue 18) was added.
    assert len(lines) <= 210, f"README.md has {len(lines)} lines; details belong in docs/"


_TOML_BLOCK = re.compile(r"```toml\n(.*?)```", re.S)


@pytest.mark.parametrize("doc", ["docs/pico.md"])
def test_the_rig_files_a_document_shows_are_valid(doc: str) -> None:
    """A rig a user copies out of a document reads as one (jointangle.rig.parse_rig)."""
    rigs = [b for b in _TOML_BLOCK.findall((REPO / doc).read_text(encoding="utf-8"))
            if "[links.a]" in b]
    assert rigs, f"{doc} shows no rig file"
    for text in rigs:
        rig = parse_rig(text, doc)
        assert all(len(link.sensors) >= 2 for link in rig.links.values()), doc

"""What produced a generated benchmark report, so a test can tell when it is stale.

`reports/accuracy.md` is written by `jointangle bench accuracy --markdown` and takes minutes to
produce. Instead of re-running it, the report carries the command that wrote it and a fingerprint
of everything its figures depend on: the estimator sources (host and the firmware core replayed on
x86), the simulator and scenario definitions, the scoring code, and the options of the run. A test
recomputes the fingerprint from the tree and fails, naming the files that changed, when it differs.
Comments and docstrings do not count: a source is hashed as its Python syntax tree without
docstrings, or its C++ text without comments and with runs of white space as one blank.
"""

from __future__ import annotations

import ast
import hashlib
import re
from collections.abc import Sequence
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]

# The sources the accuracy figures depend on, relative to the repository root.
ACCURACY_SOURCES = (
    "host/jointangle/estimators/**/*.py",
    "host/jointangle/sim/**/*.py",
    "host/jointangle/model.py",
    "host/jointangle/rig.py",
    "host/jointangle/sensors.py",
    "host/jointangle/bench/accuracy.py",
    "firmware/core/*.hpp",
    "firmware/platform/posix/filter_replay.cpp",
)

_HEADER = re.compile(
    r"<!-- generated: (?P<command>.+?) -->\n<!-- fingerprint: (?P<fp>[0-9a-f]+) -->")
_FILE = re.compile(r"^<!-- file (?P<hash>[0-9a-f]+) (?P<path>\S+) -->$", re.MULTILINE)


_CPP_COMMENT = re.compile(r"//[^\n]*|/\*.*?\*/", re.DOTALL)


def _code_of(path: Path) -> bytes:
    """What a source file computes with: no comments, no docstrings, no layout."""
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".py":
        tree = ast.parse(text)
        for node in ast.walk(tree):
            body = getattr(node, "body", None)
            if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                    and body and isinstance(body[0], ast.Expr)
                    and isinstance(body[0].value, ast.Constant)
                    and isinstance(body[0].value.value, str)):
                node.body = body[1:] or [ast.Pass()]
        return ast.dump(tree).encode()
    return " ".join(_CPP_COMMENT.sub(" ", text).split()).encode()


def source_hashes(root: Path = REPO, patterns: Sequence[str] = ACCURACY_SOURCES) -> dict[str, str]:
    """SHA-256 (first 16 hex digits) of every source file, by path relative to `root`."""
    out: dict[str, str] = {}
    for pattern in patterns:
        for path in sorted(root.glob(pattern)):
            if path.is_file() and "__pycache__" not in path.parts:
                out[path.relative_to(root).as_posix()] = \
                    hashlib.sha256(_code_of(path)).hexdigest()[:16]
    return dict(sorted(out.items()))


def fingerprint(command: str, hashes: dict[str, str]) -> str:
    """One hash of the command and every source's hash."""
    h = hashlib.sha256(command.encode())
    for path, digest in hashes.items():
        h.update(f"\n{path} {digest}".encode())
    return h.hexdigest()[:16]


def report_header(command: str, root: Path = REPO) -> str:
    """The lines that open a generated report: the command and the fingerprint."""
    hashes = source_hashes(root)
    return (f"<!-- generated: {command} -->\n<!-- fingerprint: {fingerprint(command, hashes)} -->\n"
            "<!-- Do not edit: regenerate with the command above. -->")


def report_footer(root: Path = REPO) -> str:
    """The per-file hashes behind the fingerprint, so a stale report names what changed."""
    return "\n".join(f"<!-- file {d} {p} -->" for p, d in source_hashes(root).items())


def stale_sources(text: str, root: Path = REPO) -> tuple[str, list[str]] | None:
    """None when the report matches the tree; else its command and the paths that changed."""
    m = _HEADER.search(text)
    if m is None:
        return "(no generated header)", ["(report has no fingerprint)"]
    command = m["command"]
    now = source_hashes(root)
    if fingerprint(command, now) == m["fp"]:
        return None
    then = {f["path"]: f["hash"] for f in _FILE.finditer(text)}
    changed = sorted(p for p in now.keys() | then.keys() if now.get(p) != then.get(p))
    return command, changed or ["(the command's options)"]

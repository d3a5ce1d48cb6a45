"""No import cycles in host/jointangle (issue 20): neither between its modules nor between its
parts (a subpackage such as `live` or `recording`, or a top-level module such as `rig`).

Only module-level imports count, as Python runs them at import time; an import inside a
function, or under `if TYPE_CHECKING:`, is left out (function-level imports are kept for a real
cost only: matplotlib, the estimator registry, optional drivers). A cycle between parts means
the two cannot be understood, tested or moved apart, even when no module imports itself back.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[3] / "host" / "jointangle"

Graph = Mapping[str, set[str]]


def module_name(path: Path, root: Path) -> str:
    """`jointangle.live.session` for root/jointangle/live/session.py (a package: its folder)."""
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _top_level_imports(body: Iterable[ast.stmt]) -> Iterable[ast.Import | ast.ImportFrom]:
    """The import statements Python runs when the module is imported: at the top level and in
    top-level if/try blocks, but not under `if TYPE_CHECKING:`."""
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif isinstance(node, ast.If):
            if not (isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"):
                yield from _top_level_imports(node.body)
            yield from _top_level_imports(node.orelse)
        elif isinstance(node, ast.Try):
            for block in (node.body, node.orelse, node.finalbody,
                          *(h.body for h in node.handlers)):
                yield from _top_level_imports(block)


def import_graph(package: Path) -> dict[str, set[str]]:
    """Module -> the package's modules it imports at module level."""
    files = {module_name(p, package): p for p in sorted(package.rglob("*.py"))}

    def resolve(name: str) -> str | None:  # the module an imported name lives in
        while name and name not in files:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {}
    for mod, path in files.items():
        here = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        targets: set[str] = set()
        for node in _top_level_imports(ast.parse(path.read_text(encoding="utf-8")).body):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                base = node.module or ""
                if node.level:
                    pkg = here.rsplit(".", node.level - 1)[0] if node.level > 1 else here
                    base = f"{pkg}.{base}" if base else pkg
                names = [f"{base}.{a.name}" for a in node.names]  # a submodule, or a name in base
            for name in names:
                target = resolve(name)
                if target is not None and target != mod:
                    targets.add(target)
        graph[mod] = targets
    return graph


def part_graph(graph: Graph, package_name: str) -> dict[str, set[str]]:
    """The same imports between the package's parts (`jointangle.live`, `jointangle.rig`)."""
    def part(mod: str) -> str:
        return ".".join(mod.split(".")[:2])

    parts: dict[str, set[str]] = {}
    for mod, targets in graph.items():
        if mod == package_name:
            continue  # the package's own __init__ is no part
        here = parts.setdefault(part(mod), set())
        here.update(part(t) for t in targets if part(t) not in (part(mod), package_name))
    return parts


def cycles(graph: Graph) -> list[list[str]]:
    """The strongly connected components with more than one node (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def _explain(graph: Graph, component: list[str]) -> str:
    inside = set(component)
    edges = [f"{a} -> {b}" for a in component for b in sorted(graph.get(a, ())) if b in inside]
    return f"{' / '.join(component)}: " + "; ".join(edges)


def test_no_module_imports_itself_back_through_others() -> None:
    graph = import_graph(PACKAGE)
    found = cycles(graph)
    assert not found, "import cycles between modules:\n" + "\n".join(
        _explain(graph, c) for c in found)


def test_no_two_parts_of_the_package_import_each_other() -> None:
    parts = part_graph(import_graph(PACKAGE), PACKAGE.name)
    found = cycles(parts)
    assert not found, "import cycles between subpackages and top-level modules:\n" + "\n".join(
        _explain(parts, c) for c in found)


def test_the_check_finds_a_cycle_between_parts_and_ignores_function_level_imports(
        tmp_path: Path) -> None:
    pkg = tmp_path / "demo"
    (pkg / "live").mkdir(parents=True)
    (pkg / "recording").mkdir()
    for d in (pkg, pkg / "live", pkg / "recording"):
        (d / "__init__.py").write_text("")
    (pkg / "live" / "device.py").write_text("from demo.recording.verify import check\n")
    (pkg / "recording" / "verify.py").write_text(
        "from demo.live import device as d\n\ndef check() -> None:\n    import demo.rig\n")
    (pkg / "recording" / "export.py").write_text("import demo.rig\n")
    (pkg / "rig.py").write_text("from typing import TYPE_CHECKING\n"
                                "if TYPE_CHECKING:\n    from demo.recording import export\n")
    graph = import_graph(pkg)
    assert graph["demo.recording.verify"] == {"demo.live.device"}
    assert cycles(graph) == [["demo.live.device", "demo.recording.verify"]]
    assert cycles(part_graph(graph, "demo")) == [["demo.live", "demo.recording"]]

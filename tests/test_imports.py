"""Imports flow one way (issue #19 item 3, issue #40 item 3: lazy imports included).

Builds the import graph of ``src/vpforms`` with :mod:`ast` — every ``import`` / ``from … import``
anywhere in a module (module body, class bodies, ``try``/``if`` blocks AND function bodies),
relative ones resolved; ``from . import x`` where ``x`` is a submodule is an edge to that
submodule; an import of ``vpforms.p.m`` from outside the package ``vpforms.p`` is also an edge to
``vpforms.p`` (its ``__init__`` runs first); ``if TYPE_CHECKING:`` blocks never run and are not
edges — and checks that

* the graph of vpforms modules, imports inside functions INCLUDED, is acyclic: a lazy import is
  still a dependency (a failure prints one cycle as a chain, each edge with its line), and
* an import inside a function is of an optional extra (``OPTIONAL_EXTRAS``, pyproject.toml's
  extras, excluded by name) or is in ``ALLOWED_IN_FUNCTIONS``: deferred for import time only,
  with the cost it saves (it still counts in the graph, so it cannot hide a cycle).

Run as a script to print the counts, the layers (each module's height: 0 for a module that
imports no vpforms module, else 1 + the highest it imports) and any cycle, of any tree::

    python tests/test_imports.py [SRC_DIR]      # default: this checkout's src/

or the tests on another tree: ``VPFORMS_IMPORTS_SRC=/other/src python -m pytest tests/test_imports.py``.

"""

from __future__ import annotations

import ast
import os
import sys
from dataclasses import dataclass
from pathlib import Path

# the tree checked: this checkout's src/, or $VPFORMS_IMPORTS_SRC (to run the test on another tree)
SRC = Path(os.environ.get("VPFORMS_IMPORTS_SRC") or Path(__file__).resolve().parents[1] / "src")
PACKAGE = "vpforms"

# Top-level distributions of the optional extras (pyproject.toml: distributed, diffrax, native,
# docs) and of optional readers: an import of one of these inside a function is how an optional
# dependency stays optional.  (They are outside vpforms, so they can never close a cycle of vpforms
# modules; matplotlib and scipy are NOT here: they are required dependencies, deferred only for
# import time, each in ALLOWED_IN_FUNCTIONS with its cost.)
OPTIONAL_EXTRAS = frozenset(
    {
        "dask",  # distributed
        "distributed",
        "zarr",
        "xarray",
        "h5netcdf",
        "h5py",
        "diffrax",  # diffrax
        "equinox",
        "cffi",  # native
        "platformdirs",
        "setuptools",
        "mkdocs",  # docs
        "mkdocstrings",
        "material",
        "netCDF4",  # grids.mgrid reads NetCDF4 through h5netcdf or netCDF4, whichever is installed
    }
)

# (importing module or package, imported module, package or top-level distribution) -> the
# import-time cost that keeps this import inside a function (a package name covers its
# submodules).  Import time is the ONLY reason: a vpforms module here is still an edge of the
# graph that must stay acyclic, so this list cannot excuse a cycle (issue #40).
ALLOWED_IN_FUNCTIONS: dict[tuple[str, str], str] = {
    ("vpforms.cli", "vpforms.problems"):
        "vpforms.problems imports vpforms.grids (scipy.interpolate, ~0.4 s): only the commands that "
        "build a problem pay it, not `vpforms --help`, `cases`, `classify`, `errata`",
    ("vpforms.cli", "vpforms.grids"):
        "scipy.interpolate (~0.4 s): only `vpforms fieldlines --mgrid` pays it",
    ("vpforms._fieldops", "scipy"):
        "scipy.special costs ~0.15 s at `import vpforms`; only lambdify of a special function needs it",
    ("vpforms.diagnostics.order", "scipy"):
        "scipy.integrate costs ~0.25 s at `import vpforms` (which imports diagnostics); only the "
        "order study's reference solution (solve_ivp, expm) needs it",
    ("vpforms.plots", "matplotlib"):
        "matplotlib costs ~0.35 s, paid only when a figure is drawn (the CLI imports vpforms.plots)",
}


@dataclass(frozen=True)
class Edge:
    src: str  # importing module (dotted)
    dst: str  # imported module (dotted; internal modules resolved to the module/package)
    line: int
    in_function: bool
    internal: bool


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules(root: Path) -> dict[str, Path]:
    return {_module_name(p, root): p for p in sorted((root / PACKAGE).rglob("*.py"))}


def _resolve(module: str, is_package: bool, level: int, name: str | None) -> str:
    base = module.split(".") if is_package else module.split(".")[:-1]
    if level > 1:
        base = base[: len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


class _Visitor(ast.NodeVisitor):
    def __init__(self, module: str, is_package: bool, modules: dict[str, Path]):
        self.module, self.is_package, self.modules = module, is_package, modules
        self.depth = 0  # function nesting
        self.edges: list[Edge] = []

    def _add(self, dst: str, line: int) -> None:
        internal = dst == PACKAGE or dst.startswith(PACKAGE + ".")
        if internal:
            while dst not in self.modules:  # `import vpforms.a.b` of a name: the longest module
                dst = dst.rpartition(".")[0]
        else:
            dst = dst.partition(".")[0]
        targets = [dst]
        if internal:  # importing vpforms.p.m runs vpforms/p/__init__.py first (unless inside p)
            parts = dst.split(".")
            for i in range(2, len(parts)):
                pkg = ".".join(parts[:i])
                if pkg in self.modules and not _within(self.module, pkg):
                    targets.append(pkg)
        for target in targets:
            edge = Edge(self.module, target, line, self.depth > 0, internal)
            if target != self.module and edge not in self.edges:
                self.edges.append(edge)

    def _function(self, node) -> None:
        self.depth += 1
        self.generic_visit(node)
        self.depth -= 1

    visit_FunctionDef = visit_AsyncFunctionDef = visit_Lambda = _function

    def visit_If(self, node: ast.If) -> None:
        test = node.test
        name = test.id if isinstance(test, ast.Name) else getattr(test, "attr", None)
        if name == "TYPE_CHECKING":  # never runs: not an edge
            for child in node.orelse:
                self.visit(child)
            return
        self.generic_visit(node)

    def visit_Import(self, node: ast.Import) -> None:
        for alias in node.names:
            self._add(alias.name, node.lineno)

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        if node.level:
            base = _resolve(self.module, self.is_package, node.level, node.module)
        else:
            base = node.module or ""
        internal = base == PACKAGE or base.startswith(PACKAGE + ".")
        for alias in node.names:
            sub = f"{base}.{alias.name}"
            if internal and sub in self.modules:  # `from . import x`, x a submodule
                self._add(sub, node.lineno)
            else:
                self._add(base, node.lineno)


def import_graph(src: Path | None = None) -> list[Edge]:
    """Every import of every module of ``src/vpforms`` (one edge per statement and target)."""
    src = SRC if src is None else src
    modules = _modules(src)
    edges: list[Edge] = []
    for name, path in modules.items():
        v = _Visitor(name, path.name == "__init__.py", modules)
        v.visit(ast.parse(path.read_text(), filename=str(path)))
        edges.extend(v.edges)
    return edges


def _graph(edges: list[Edge]) -> dict[str, set[str]]:
    """module -> the vpforms modules it imports (anywhere in it: functions included)."""
    graph: dict[str, set[str]] = {}
    for e in edges:
        if e.internal:
            graph.setdefault(e.src, set()).add(e.dst)
            graph.setdefault(e.dst, set())
    return graph


def cycles(edges: list[Edge]) -> list[list[str]]:
    """The strongly connected components (size > 1) of the graph of vpforms modules, imports
    inside functions included."""
    graph = _graph(edges)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def strong(v: str) -> None:  # Tarjan
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(max(10_000, sys.getrecursionlimit()))
    for v in sorted(graph):
        if v not in index:
            strong(v)
    return out


def cycle_chain(edges: list[Edge], component: list[str]) -> list[Edge]:
    """One shortest cycle through the first module of a strongly connected ``component``: the
    edges a → b → … → a (breadth-first within the component)."""
    inside = set(component)
    by_src: dict[str, list[Edge]] = {}
    for e in edges:
        if e.internal and e.src in inside and e.dst in inside:
            by_src.setdefault(e.src, []).append(e)
    start = component[0]
    came: dict[str, Edge] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for e in sorted(by_src.get(v, []), key=lambda e: (e.dst, e.line)):
                if e.dst == start:  # closed: walk back to the start
                    chain = [e]
                    while chain[0].src != start:
                        chain.insert(0, came[chain[0].src])
                    return chain
                if e.dst not in came:
                    came[e.dst] = e
                    nxt.append(e.dst)
        frontier = nxt
    raise AssertionError(f"{component} is not a cycle")  # pragma: no cover — Tarjan's SCCs are


def describe_cycle(chain: list[Edge]) -> str:
    """``a:12 → b:7 (in a function) → a`` — each module with the line of its import."""
    steps = [f"{e.src}:{e.line}" + (" (in a function)" if e.in_function else "") for e in chain]
    return " → ".join(steps + [chain[0].src])


def layers(edges: list[Edge]) -> dict[int, list[str]]:
    """height -> modules: 0 for a module importing no vpforms module, else 1 + the highest
    height it imports (the graph must be acyclic)."""
    graph = _graph(edges)
    height: dict[str, int] = {}

    def h(v: str) -> int:
        if v not in height:
            height[v] = 1 + max((h(w) for w in graph[v]), default=-1)
        return height[v]

    out: dict[int, list[str]] = {}
    for v in sorted(graph):
        out.setdefault(h(v), []).append(v)
    return out


def function_level(edges: list[Edge]) -> list[Edge]:
    return [e for e in edges if e.in_function]


def _within(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def allowed_by(e: Edge) -> tuple[str, str] | None:
    """The allow-list entry that covers an import inside a function, if any."""
    for src, dst in ALLOWED_IN_FUNCTIONS:
        if _within(e.src, src) and _within(e.dst, dst):
            return src, dst
    return None


def violations(edges: list[Edge]) -> list[Edge]:
    """Imports inside functions that are neither of an optional extra nor allow-listed."""
    return [
        e
        for e in function_level(edges)
        if not (not e.internal and e.dst in OPTIONAL_EXTRAS) and allowed_by(e) is None
    ]


def test_no_import_cycles_lazy_imports_included():
    edges = import_graph()
    found = cycles(edges)
    assert not found, "import cycles (imports inside functions count):\n" + "\n".join(
        f"  [{len(c)} modules] {describe_cycle(cycle_chain(edges, c))}" for c in found
    )


def test_imports_inside_functions_are_optional_extras_or_allowed():
    bad = violations(import_graph())
    assert not bad, "imports inside functions (move them to module top, or allow-list them):\n" + (
        "\n".join(f"  {e.src}:{e.line} -> {e.dst}" for e in bad)
    )


def test_allow_list_is_live():
    """Every allow-list entry still names an import inside a function (no stale entries)."""
    used = {allowed_by(e) for e in function_level(import_graph())}
    assert set(ALLOWED_IN_FUNCTIONS) <= used, set(ALLOWED_IN_FUNCTIONS) - used


def test_the_checker_sees_a_lazy_cycle_and_a_function_import(tmp_path):
    """The tool itself: a cycle closed by an import inside a function is a cycle (reported as a
    chain with lines), and so is one through a package's ``__init__``; a deferred import of a
    non-extra is reported, an extra's is not."""
    pkg = tmp_path / PACKAGE
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from . import a\nfrom .sub import c\n")
    (pkg / "a.py").write_text("from .b import thing\n")
    (pkg / "b.py").write_text("import json\n\ndef f():\n    from . import a\n    import numpy\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "c.py").write_text(
        "from .. import a\nimport dask\nfrom typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from .. import b\ndef h():\n    import dask\n")
    edges = import_graph(tmp_path)
    found = cycles(edges)
    assert found == [[f"{PACKAGE}.a", f"{PACKAGE}.b"]]
    assert describe_cycle(cycle_chain(edges, found[0])) == (
        f"{PACKAGE}.a:1 → {PACKAGE}.b:4 (in a function) → {PACKAGE}.a")
    assert [(e.src, e.dst) for e in violations(edges)] == [(f"{PACKAGE}.b", f"{PACKAGE}.a"),
                                                          (f"{PACKAGE}.b", "numpy")]
    pairs = {(e.src, e.dst) for e in edges}
    assert (f"{PACKAGE}", f"{PACKAGE}.sub.c") in pairs
    assert (f"{PACKAGE}.sub.c", f"{PACKAGE}.a") in pairs
    assert (f"{PACKAGE}.sub.c", f"{PACKAGE}.b") not in pairs  # TYPE_CHECKING never runs
    assert (f"{PACKAGE}.b", f"{PACKAGE}.sub") not in pairs
    (pkg / "sub" / "__init__.py").write_text("from .. import b\n")  # runs whenever sub.c is imported
    (pkg / "sub" / "d.py").write_text("")
    (pkg / "b.py").write_text("def f():\n    from .sub.d import h\n")
    found = cycles(import_graph(tmp_path))
    assert found == [[f"{PACKAGE}.b", f"{PACKAGE}.sub"]], found
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "d.py").unlink()
    (pkg / "b.py").write_text("import json\n")  # the cycle broken: layers exist
    assert layers(import_graph(tmp_path)) == {
        0: [f"{PACKAGE}.b", f"{PACKAGE}.sub"], 1: [f"{PACKAGE}.a"], 2: [f"{PACKAGE}.sub.c"],
        3: [PACKAGE]}


def _report(src: Path) -> int:
    edges = import_graph(src)
    fl = function_level(edges)
    found = cycles(edges)
    bad = violations(edges)
    print(f"{src}: {len(edges)} imports, {len(fl)} inside functions "
          f"({sum(e.internal for e in fl)} of vpforms modules), {len(bad)} not allowed")
    print(f"{len(found)} cycle(s) among vpforms modules (imports inside functions count)")
    for c in found:
        print(f"  [{len(c)} modules] {describe_cycle(cycle_chain(edges, c))}")
    for e in bad:
        print(f"  not allowed inside a function: {e.src}:{e.line} -> {e.dst}")
    if not found:
        print("layers (height: 0 imports no vpforms module, else 1 + the highest it imports):")
        for height, mods in sorted(layers(edges).items()):
            print(f"  {height:2d}: " + " ".join(m.removeprefix(PACKAGE + ".") for m in mods))
    return 1 if (found or bad) else 0


if __name__ == "__main__":
    sys.exit(_report(Path(sys.argv[1]) if len(sys.argv) > 1 else SRC))

"""Imports flow one way (issue #19 item 3).

Builds the import graph of ``src/vpforms`` with :mod:`ast` — every ``import`` / ``from … import``,
relative ones resolved, those inside functions included; ``from . import x`` where ``x`` is a
submodule is an edge to that submodule — and checks that

* the graph of module-level imports (everything that runs when a module is imported: module
  body, class bodies, ``try``/``if`` blocks; not function bodies) is acyclic, and
* an import inside a function is of an optional extra (``pyproject.toml``'s extras, below) or
  is in ``ALLOWED_IN_FUNCTIONS`` with the reason it cannot be at module top.

Run as a script to print the counts and cycles of any tree::

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
# dependency stays optional.
OPTIONAL_EXTRAS = frozenset(
    {
        "dask",  # distributed
        "distributed",
        "zarr",
        "xarray",
        "h5netcdf",
        "h5py",
        "diffrax",  # diffrax
        "cffi",  # native
        "platformdirs",
        "setuptools",
        "mkdocs",  # docs
        "mkdocstrings",
        "material",
        "netCDF4",  # grids.mgrid reads NetCDF4 through h5netcdf or netCDF4, whichever is installed
    }
)

# (importing module or package, imported module, package or top-level distribution) -> why this
# import cannot be at module top (a package name covers its submodules).  Keep it short: every entry is a cycle a function-level import is the honest answer
# to (a class whose method wraps a function of a higher layer) or an import-time cost.
ALLOWED_IN_FUNCTIONS: dict[tuple[str, str], str] = {
    ("vpforms._methods._base", "vpforms._recovery"):
        "Method.step_with_recovery's host path calls recover_points, which dispatches on the Method "
        "subclasses (Recovering, Composition, …) of the modules above _base",
    ("vpforms._methods._base", "vpforms._spec"):
        "Method.spec() wraps _spec.method_spec, which sits above the methods (it tests Adjoint and "
        "rebuilds through scheme/compose)",
    ("vpforms._methods.rk4", "vpforms._spec"):
        "RK4.spec() wraps _spec.method_spec (above the methods, it tests RK4)",
    ("vpforms._solution", "vpforms.diagnostics.failures"):
        "Solution.explain() wraps explain_failures; the diagnostics package runs integrate (order, "
        "poincare, volume), which returns Solutions",
    ("vpforms._solution", "vpforms.io"):
        "Solution.to_xarray/to_netcdf wrap vpforms.io, which stores runs (saved_steps of _solution)",
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
        edge = Edge(self.module, dst, line, self.depth > 0, internal)
        if dst != self.module and edge not in self.edges:
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


def cycles(edges: list[Edge], *, with_functions: bool = False) -> list[list[str]]:
    """The strongly connected components (size > 1) of the internal module-level graph (with
    ``with_functions``: of the graph that also counts the imports inside functions)."""
    graph: dict[str, set[str]] = {}
    for e in edges:
        if e.internal and (with_functions or not e.in_function):
            graph.setdefault(e.src, set()).add(e.dst)
            graph.setdefault(e.dst, set())
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


def test_module_level_imports_are_acyclic():
    found = cycles(import_graph())
    assert not found, "import cycles among module-level imports:\n" + "\n".join(
        " <-> ".join(c) for c in found
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


def test_the_checker_sees_a_cycle_and_a_function_import(tmp_path):
    """The tool itself: a two-module cycle and a deferred internal import are reported."""
    pkg = tmp_path / PACKAGE
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from . import a\nfrom .sub import c\n")
    (pkg / "a.py").write_text("from .b import thing\n")
    (pkg / "b.py").write_text("from . import a\n\ndef f():\n    from .sub.c import g\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "c.py").write_text("from .. import a\nimport dask\ndef h():\n    import dask\n")
    edges = import_graph(tmp_path)
    assert cycles(edges) == [[f"{PACKAGE}.a", f"{PACKAGE}.b"]]
    assert [(e.src, e.dst) for e in violations(edges)] == [(f"{PACKAGE}.b", f"{PACKAGE}.sub.c")]
    assert (f"{PACKAGE}", f"{PACKAGE}.sub.c") in {(e.src, e.dst) for e in edges}
    assert (f"{PACKAGE}.sub.c", f"{PACKAGE}.a") in {(e.src, e.dst) for e in edges}


def _report(src: Path) -> int:
    edges = import_graph(src)
    fl = function_level(edges)
    found = cycles(edges)
    bad = violations(edges)
    print(f"{src}: {len(edges)} imports, {len(fl)} inside functions "
          f"({sum(e.internal for e in fl)} of vpforms modules), {len(bad)} not allowed")
    print(f"{len(found)} cycle(s) among module-level imports")
    for c in found:
        print(f"  [{len(c)} modules] " + " ".join(c))
    held = cycles(edges, with_functions=True)
    print(f"{len(held)} cycle(s) once the imports inside functions count too")
    for c in held:
        print(f"  [{len(c)} modules] " + " ".join(c))
    for e in bad:
        print(f"  {e.src}:{e.line} -> {e.dst}")
    return 1 if (found or bad) else 0


if __name__ == "__main__":
    sys.exit(_report(Path(sys.argv[1]) if len(sys.argv) > 1 else SRC))

"""MkDocs build hooks (``hooks:`` in mkdocs.yml; no plugin): generated content of the site.

At every build (``mkdocs build``/``serve``) this

* runs the gallery scripts ``docs/gallery/*.py`` (each in its own Python process, MPLBACKEND=Agg,
  in parallel with the jobs below) and puts their code, printed output and figures into the pages
  that ask for them with ``<!-- vpforms:gallery NAME -->``; a script that fails fails the build;
* renders the tables that the library computes with SymPy: ``<!-- vpforms:table36 -->`` (the 36
  cases, with the proof column dλ = f*ν̃ − ν) and ``<!-- vpforms:errata -->`` (the errata report,
  measured live, as ``vpforms errata`` prints it);
* generates the CLI reference from the argparse parser (``<!-- vpforms:cli-reference -->``: one
  section per subcommand with its ``--help``);
* quotes benchmark result files verbatim (``<!-- vpforms:include benchmarks/methods/results.md -->``, or a
  part of one: ``…/results_orders.md#section:pick-per-accuracy-target/table:2``, the selectors of
  ``benchmarks/quote.py``);
* checks the ``<!-- quote: … -->`` blocks of every page against their results files
  (``benchmarks/quote.py``, which writes them): a stale block is a warning, so an error under
  ``mkdocs build --strict``.

The generated figures are added to the site as files ``gallery/NAME-K.png``.
"""

from __future__ import annotations

import base64
import importlib.util
import json
import logging
import os
import re
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

log = logging.getLogger("mkdocs.hooks.vpforms")

ROOT = Path(__file__).resolve().parent.parent
GALLERY = ROOT / "docs" / "gallery"
MARKER = re.compile(r"<!--\s*vpforms:([a-z0-9-]+)(?:\s+([^\s>]+))?\s*-->")

# every job runs under this wrapper (argv: "script" PATH | "code" SOURCE): a script's figures are
# written as PNG; its output is captured; it reports its CPU time (it and its children, e.g. gcc)
_RUNNER = textwrap.dedent(
    """
    import base64, io, json, resource, runpy, sys
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plt.show = lambda *a, **k: None
    from matplotlib.figure import Figure
    if sys.argv[1] == "script":
        names = runpy.run_path(sys.argv[2], run_name="__main__")
    else:
        names = {"__name__": "__main__"}
        exec(sys.argv[2], names)
    # pyplot's figures, then Figure objects the script holds (vpforms.plots makes those)
    found = [plt.figure(num) for num in plt.get_fignums()]
    found += [v for v in names.values() if isinstance(v, Figure) and v not in found]
    figs = []
    for fig in found:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
        figs.append(base64.b64encode(buf.getvalue()).decode())
    cpu = sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                  resource.getrusage(resource.RUSAGE_CHILDREN)))
    sys.stdout.flush()
    sys.stderr.write("\\n@@VPFORMS-RESULT@@" + json.dumps({"figures": figs, "cpu": cpu}))
    """
)



def _quote_module():
    """``benchmarks/quote.py`` (standard library only), loaded by path: the benchmarks are no package."""
    spec = importlib.util.spec_from_file_location("vpforms_bench_quote", ROOT / "benchmarks" / "quote.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


quote = _quote_module()

_TABLES = {
    "table36": "from vpforms.symbolic.tables import table36_markdown; print(table36_markdown(prove=True))",
    "errata": "from vpforms.symbolic.errata import errata_report; print(errata_report('markdown'))",
}

#: results of the jobs of one build: key -> dict(stdout, figures, seconds)
_RESULTS: dict[str, dict] = {}


def _run(key: str, argv: list[str]) -> tuple[str, dict]:
    env = dict(os.environ, MPLBACKEND="Agg", COLUMNS="100", NO_COLOR="1")
    t = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", _RUNNER, *argv], cwd=ROOT, env=env,
                       capture_output=True, text=True)
    dt = time.perf_counter() - t
    err, _, res = p.stderr.partition("@@VPFORMS-RESULT@@")
    if p.returncode != 0 or not res:
        raise RuntimeError(f"docs job {key!r} failed (exit {p.returncode}):\n{err[-4000:]}")
    res = json.loads(res)
    return key, {"stdout": p.stdout, "figures": res["figures"], "seconds": dt, "cpu": res["cpu"]}


def _jobs() -> list[tuple[str, list[str]]]:
    jobs = [(f"gallery:{s.stem}", ["script", str(s)]) for s in sorted(GALLERY.glob("*.py"))]
    jobs += [(k, ["code", code]) for k, code in _TABLES.items()]
    return jobs


def on_pre_build(config, **kwargs):
    """Run every job (gallery scripts, SymPy tables) in parallel processes, once per build.

    ``VPFORMS_DOCS_NO_RUN=1`` skips them (a quick look at the pages while editing: the generated
    parts then say that they were not run); the tests and CI never set it.
    """
    _RESULTS.clear()
    if os.environ.get("VPFORMS_DOCS_NO_RUN"):
        log.warning("vpforms docs: VPFORMS_DOCS_NO_RUN is set: gallery and tables NOT run")
        return
    jobs = _jobs()
    workers = max(1, min(len(jobs), os.cpu_count() or 1))
    t = time.perf_counter()
    with ThreadPoolExecutor(workers) as pool:
        for key, res in pool.map(lambda j: _run(*j), jobs):
            _RESULTS[key] = res
            log.info(f"vpforms docs: {key} ran in {res['seconds']:.1f} s (CPU {res['cpu']:.1f} s)")
    log.info(f"vpforms docs: {len(jobs)} generation jobs in {time.perf_counter() - t:.1f} s")


_NOT_RUN = {"stdout": "(not run: VPFORMS_DOCS_NO_RUN is set)", "figures": [], "seconds": 0.0, "cpu": 0.0}


def on_files(files, config, **kwargs):
    """Add the gallery figures to the site as gallery/NAME-K.png."""
    from mkdocs.structure.files import File

    for key, res in _RESULTS.items():
        if key.startswith("gallery:"):
            name = key.split(":", 1)[1]
            for k, b64 in enumerate(res["figures"], 1):
                files.append(File.generated(config, f"gallery/{name}-{k}.png",
                                            content=base64.b64decode(b64)))
    return files


def cli_reference() -> str:
    """Markdown: ``vpforms --help`` and every subcommand's ``--help``, from the argparse parser."""
    import argparse

    from vpforms.cli import build_parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal width: fix it
    try:
        parser = build_parser()
        parts = ["## vpforms\n", "```text\n" + parser.format_help().rstrip() + "\n```\n"]
        for action in parser._subparsers._group_actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    parts.append(f"## vpforms {name}\n")
                    parts.append("```text\n" + sub.format_help().rstrip() + "\n```\n")
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old
    return "\n".join(parts)


def _gallery(name: str, page) -> str:
    if not (GALLERY / f"{name}.py").is_file():
        raise RuntimeError(f"{page.file.src_uri}: no gallery script docs/gallery/{name}.py")
    res = _RESULTS.get(f"gallery:{name}", _NOT_RUN)
    code = (GALLERY / f"{name}.py").read_text()
    out = [f'```python title="{name}.py"\n{code.rstrip()}\n```\n',
           f"Output (printed when this site was built; {res['cpu']:.0f} s of CPU time including "
           f"JAX compilation):\n", "```text\n" + res["stdout"].rstrip() + "\n```\n"]
    # relative to the page (gallery/NAME.md -> NAME-K.png next to it)
    page_dir = Path(page.file.src_uri).parent
    for k in range(1, len(res["figures"]) + 1):
        rel = os.path.relpath(f"gallery/{name}-{k}.png", page_dir.as_posix() or ".")
        out.append(f"![{name} figure {k}]({rel})\n")
    return "\n".join(out)


def on_page_markdown(markdown, page, config, files, **kwargs):
    def replace(m):
        what, arg = m.group(1), m.group(2)
        if what == "cli-reference":
            return cli_reference()
        if what in _TABLES:
            text = _RESULTS.get(what, _NOT_RUN)["stdout"]
            return re.sub(r"^#", "###", text, flags=re.M)  # its headings below the page's
        if what == "gallery":
            return _gallery(arg, page)
        if what == "include":
            if "#" in arg:  # a part of the file, quote.py's selectors
                text = quote.source(arg, ROOT)
            else:
                text = (ROOT / arg).read_text()
            return re.sub(r"^#", "###", text, flags=re.M)  # its headings below the page's
        raise RuntimeError(f"{page.file.src_uri}: unknown marker vpforms:{what}")

    where = f"docs/{page.file.src_uri}"
    for msg in quote.stale(markdown, ROOT, where):
        log.warning(f"vpforms docs: {msg.splitlines()[0]}")
    return MARKER.sub(replace, markdown)


_ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|data|attr|exc|obj|const):<code>(~?)([^<]*)</code>")


def on_page_content(html, page, config, files, **kwargs):
    """Sphinx roles in docstrings (:func:`x`, :class:`~a.b.C`) as plain code (``x``, ``C``)."""
    return _ROLE.sub(lambda m: f"<code>{m.group(2).rsplit('.', 1)[-1] if m.group(1) else m.group(2)}</code>",
                     html)

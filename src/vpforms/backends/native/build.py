"""Compile generated C once and cache the shared object (cffi + the system C compiler).

The cache lives in ``native/`` of vpforms' cache folder (:func:`vpforms._cache.cache_root`:
``VPFORMS_CACHE_DIR`` or ``platformdirs.user_cache_dir("vpforms")``; the environment variable
``VPFORMS_NATIVE_CACHE`` names another folder), keyed by a hash of source + declarations + flags +
compiler version + the CPU that ``-march=native`` resolves to (a folder shared by machines with
other CPUs never hands one a kernel built for another); a build writes into a private temporary
directory and is published by ``os.replace`` (atomic on POSIX), so concurrent processes never see
a half-written object.
``VPFORMS_NATIVE_DISABLE=1`` makes :func:`available` report no compiler (tests, debugging).
A compilation is a phase of :mod:`vpforms._phases` ("compiling the native kernel (… KB of C)"),
announced on stderr for sources of :data:`ANNOUNCE_BYTES` or more (issue #41 item 2).

What the compiler prints (with these flags gcc's ``cc1: note: disable pass …`` for each
``-fdisable-tree-…``) is captured, not shown: it goes to the logger ``vpforms.native`` at level
INFO (``vpforms -v`` shows it); a failed compilation raises an error quoting its first error line.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import logging
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import threading
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path

from ..._cache import cache_root
from ..._phases import phase

__all__ = ["FLAGS", "available", "build", "cache_dir", "compiler", "COUNTERS"]

#: -ffast-math lets gcc call libmvec's vector sin/cos; -fno-finite-math-only keeps NaN/inf tests
#: working; -fdisable-tree-sincos stops the sin+cos → sincos fusion that has no vector variant.
#: That pass also expands __builtin_powi, which -ffast-math's reassociation makes of x*x: without
#: it every square becomes a scalar __powidf2 call (unvectorisable), so reassociation is off too.
#: -g0 drops the debug information Python's own CFLAGS ask for (-g): nobody steps through a
#: generated kernel, and gcc's variable tracking for it cost a quarter of a spline kernel's compile.
FLAGS = ("-O3", "-march=native", "-ffast-math", "-fno-finite-math-only",
         "-fdisable-tree-sincos", "-fdisable-tree-reassoc1", "-fdisable-tree-reassoc2", "-fopenmp", "-g0")
#: How many compilations / cache hits this process did (tests read it).
COUNTERS = {"compiled": 0, "cache_hits": 0}
#: a compilation of at least this much C is announced on stderr (vpforms._phases): smaller ones take
#: about a second and stay silent (an order-4 spline kernel, 67 KB with every entry, takes ~5 s of gcc:
#: benchmarks/native/results_compile.md)
ANNOUNCE_BYTES = 8192

_loaded: dict[str, object] = {}
_log = logging.getLogger("vpforms.native")
_CAPTURE = threading.Lock()  # one redirection of the process's stdout/stderr at a time


def cache_dir() -> Path:
    """The folder of compiled kernels: ``VPFORMS_NATIVE_CACHE``, else ``native/`` of
    :func:`vpforms._cache.cache_root`."""
    env = os.environ.get("VPFORMS_NATIVE_CACHE")
    if env:
        return Path(env)
    return cache_root() / "native"


def compiler() -> str | None:
    """The C compiler's path (``$CC`` or sysconfig's CC, else gcc/cc), or None."""
    if os.environ.get("VPFORMS_NATIVE_DISABLE", "") not in ("", "0"):
        return None
    for cand in (os.environ.get("CC"), (sysconfig.get_config_var("CC") or "").split(" ")[0], "gcc", "cc"):
        if cand and shutil.which(cand):
            return shutil.which(cand)
    return None


@lru_cache(maxsize=8)
def _version(cc: str) -> str:
    try:
        return subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30).stdout
    except (OSError, subprocess.SubprocessError):
        return ""


@lru_cache(maxsize=8)
def _target(cc: str) -> str:
    """What ``-march=native`` means here: the compiler's own expansion of it (gcc's ``cc1`` line
    with ``-march=znver3 -mavx512f …``; clang's ``-target-cpu``/``-target-feature`` s), for the
    cache key."""
    try:
        out = subprocess.run([cc, "-march=native", "-E", "-v", "-x", "c", os.devnull, "-o", os.devnull],
                             capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return ""
    return "\n".join(ln for ln in (out.stderr + out.stdout).splitlines() if "cc1" in ln)


def available() -> tuple[bool, str]:
    """(True, compiler description) if native kernels can be built here, else (False, why)."""
    cc = compiler()
    if cc is None:
        return False, "no C compiler found: install gcc"
    try:
        import cffi  # noqa: F401
    except ImportError:
        return False, "the native backend needs cffi: pip install cffi"
    v = _version(cc).splitlines()
    return True, v[0] if v else cc


def build(source: str, cdef: str):
    """The cffi ``lib`` of ``source`` (declarations ``cdef``), compiled once and cached."""
    cc = compiler()
    if cc is None:
        raise OSError("no C compiler found: install gcc")
    key = hashlib.sha256("\0".join([source, cdef, " ".join(FLAGS), _version(cc), _target(cc)]).encode()).hexdigest()[:20]
    if key in _loaded:
        return _loaded[key]
    name = f"_vpk_{key}"
    suffix = importlib.machinery.EXTENSION_SUFFIXES[0]
    d = cache_dir()
    d.mkdir(parents=True, exist_ok=True)
    so = d / (name + suffix)
    if so.exists():
        COUNTERS["cache_hits"] += 1
    else:
        import cffi

        ffi = cffi.FFI()
        ffi.cdef(cdef)
        ffi.set_source(name, source, extra_compile_args=[*FLAGS, "-w"], extra_link_args=["-fopenmp"],
                       libraries=["m"])
        tmp = tempfile.mkdtemp(prefix=name + ".", dir=d)
        kb = len(source.encode()) / 1024
        try:
            env_cc = os.environ.get("CC")
            os.environ["CC"] = cc
            failure = None
            try:  # a phase (vpforms._phases) said before the output is redirected: no thread writes into it
                with phase(f"compiling the native kernel ({kb:.0f} KB of C)", delay=0, live=False,
                           announce=kb * 1024 >= ANNOUNCE_BYTES), _compiler_output() as printed:
                    try:
                        out = ffi.compile(tmpdir=tmp, verbose=False)
                    except Exception as exc:  # noqa: BLE001  (cffi's VerificationError, distutils' CompileError …)
                        failure = exc
            finally:
                if env_cc is None:
                    os.environ.pop("CC", None)
                else:
                    os.environ["CC"] = env_cc
            text = "".join(printed).strip()
            if text:
                _log.info("the C compiler's output for native kernel %s:\n%s", name, text)
            if failure is not None:  # one line: the compiler's first error (all of it: vpforms -v)
                first = next((ln for ln in text.splitlines() if "error" in ln), text.partition("\n")[0])
                raise OSError(f"the C compiler ({cc}) failed on native kernel {name}: "
                              f"{type(failure).__name__}: {failure}" + (f"; {first.strip()}" if first else "")
                              + " (its whole output: vpforms -v, or the logger 'vpforms.native' at INFO)") from None
            os.replace(out, so)  # atomic publish: readers see the old state or the whole file
            COUNTERS["compiled"] += 1
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    spec = importlib.util.spec_from_file_location(name, so)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    _loaded[key] = mod
    return mod


@contextmanager
def _compiler_output():
    """Collect what is written to file descriptors 1 and 2 (the compiler is a child process that
    inherits them) into the list this yields, filled on exit; nothing is redirected where the
    descriptors cannot be duplicated."""
    printed: list[str] = []
    with _CAPTURE, tempfile.TemporaryFile() as sink:
        for stream in (sys.stdout, sys.stderr):
            _flush(stream)
        try:
            saved = [os.dup(1), os.dup(2)]
        except OSError:
            yield printed
            return
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            yield printed
        finally:
            for stream in (sys.stdout, sys.stderr):
                _flush(stream)
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            printed.append(sink.read().decode(errors="replace"))


def _flush(stream) -> None:
    try:
        stream.flush()
    except (AttributeError, OSError, ValueError):
        pass

"""vpforms' on-disk caches: one directory, every entry keyed by the content that determines it.

A new process pays again for what an earlier one compiled: the native kernels (gcc, seconds to
minutes) and, on spline and coil fields, the JAX computations of a method's construction (the
potentials' check compiles for tens of seconds in every process; issue #41 item 3). Both are
kept, under :func:`cache_root` — ``VPFORMS_CACHE_DIR``, else ``platformdirs.user_cache_dir
("vpforms")`` (``$XDG_CACHE_HOME/vpforms`` or ``~/.cache/vpforms`` without platformdirs):

* ``native/`` — compiled kernels (:mod:`vpforms.backends.native.build`; ``VPFORMS_NATIVE_CACHE``
  overrides the folder), named by a hash of the C source, the compiler flags, the compiler's
  version and the CPU that ``-march=native`` resolves to;
* ``jax/`` — JAX's persistent compilation cache (:func:`enable_jax_cache`; the command line turns
  it on), whose key is XLA's own fingerprint of the computation (its constants — a spline's
  coefficients — included), the compile options and the JAX/XLA versions; XLA refuses an entry
  compiled for other CPU features and compiles again.

Nothing cached is a number: an entry is compiled code, found only by the hash of everything its
result depends on, so a cache can make a run faster, never different or stale. Delete the folder
any time; ``VPFORMS_JAX_CACHE=0`` keeps JAX's cache off.
"""

from __future__ import annotations

import os
from pathlib import Path

import jax

__all__ = ["cache_root", "enable_jax_cache", "jax_cache_dir"]

#: JAX computations that compile faster than this are not written to the cache. JAX's default
#: (1 s) leaves out most of a spline method's compilations (0.2–1 s each), and 0.2 s the ~300
#: element-wise ones of a study's host-side sums (0.04 s each): `vpforms fieldlines --problem
#: coil_stellarator` with a warm cache took 36 s at 0.2 s and 28 s at 0 (370 entries, 27 MB; load 1.6)
JAX_MIN_COMPILE_SECONDS = 0.0


def cache_root() -> Path:
    """The folder of vpforms' caches (module docstring)."""
    env = os.environ.get("VPFORMS_CACHE_DIR")
    if env:
        return Path(env)
    try:
        import platformdirs
    except ImportError:  # the native extra is not installed: the XDG default
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        return Path(base) / "vpforms"
    return Path(platformdirs.user_cache_dir("vpforms"))


def jax_cache_dir() -> Path:
    """The folder of JAX's persistent compilation cache for vpforms (``jax/`` of :func:`cache_root`)."""
    return cache_root() / "jax"


def enable_jax_cache() -> Path | None:
    """Turn on JAX's persistent compilation cache in :func:`jax_cache_dir`, before anything is
    compiled; returns the folder in use, or None where it stays off: ``VPFORMS_JAX_CACHE=0``, or
    the folder cannot be created. A cache the user configured (``JAX_COMPILATION_CACHE_DIR``, or
    ``jax_compilation_cache_dir`` already set) is kept and returned as it is."""
    if os.environ.get("VPFORMS_JAX_CACHE", "1") == "0":
        return None
    mine = os.environ.get("JAX_COMPILATION_CACHE_DIR") or jax.config.jax_compilation_cache_dir
    if mine:
        return Path(mine)
    folder = jax_cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", JAX_MIN_COMPILE_SECONDS)
    return folder

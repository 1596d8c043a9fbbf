"""vpforms' on-disk caches across processes (issue #41 item 3, :mod:`vpforms._cache`): a second
process finds what the first compiled — JAX's compilation of a computation on data, and a native
kernel — and a changed input is never served from the cache (a new compilation, or the same code
fed the new data: the answer is the new input's)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import vpforms as vp
from vpforms import _cache
from vpforms.backends.native import build as nbuild

NATIVE_OK, NATIVE_WHY = vp.native.available()

CHILD = textwrap.dedent("""
    import json, sys
    import numpy as np
    import jax, jax.numpy as jnp
    import vpforms
    from vpforms import problems
    from vpforms._cache import enable_jax_cache
    from vpforms.backends.native import build
    from vpforms.backends.native.codegen import kernel_source
    from vpforms.backends.native.codegen.entries import entries_cdef

    folder = enable_jax_cache()
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)  # this one compiles fast
    events = []
    shift, order = float(sys.argv[1]), int(sys.argv[2])
    # a computation on data, as a spline's potentials check closes over its coefficients; the
    # cache's events of its compilation alone
    c = np.linspace(0.0, 1.0, 2000)
    c[7] += shift
    listen = lambda e, **k: events.append(e)
    jax.monitoring.register_event_listener(listen)
    value = float(jax.jit(lambda x: jnp.sum(jnp.sin(x * jnp.asarray(c))))(0.5))
    jax.monitoring.unregister_event_listener(listen)
    native = None
    if sys.argv[3] == "1":
        field = problems.get("abc").field
        m = vpforms.scheme(field, "SE+SE", recover=False)
        src = kernel_source(m if order == 1 else vpforms.compose(m, order=order))
        lib = build.build(src, entries_cdef(src))
        native = dict(build.COUNTERS, has_run=hasattr(lib.lib, "vp_run"))
    print(json.dumps({"folder": str(folder), "hits": events.count("/jax/compilation_cache/cache_hits"),
                      "value": value, "native": native}))
""")


def _child(tmp_path, shift: float, order: int) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("JAX_COMPILATION_CACHE_DIR", "VPFORMS_NATIVE_CACHE",
                                                           "VPFORMS_JAX_CACHE")}
    env.update(VPFORMS_CACHE_DIR=str(tmp_path / "cache"), JAX_PLATFORMS="cpu", OMP_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", CHILD, repr(shift), str(order), "1" if NATIVE_OK else "0"],
                         capture_output=True, text=True, env=env, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_second_process_hits_the_caches_and_a_changed_input_does_not(tmp_path):
    c = np.linspace(0.0, 1.0, 2000)
    first = _child(tmp_path, 0.0, 1)
    assert first["folder"] == str(tmp_path / "cache" / "jax")
    assert first["hits"] == 0 and any((tmp_path / "cache" / "jax").iterdir())
    assert first["value"] == pytest.approx(float(np.sum(np.sin(0.5 * c))), rel=1e-13)
    second = _child(tmp_path, 0.0, 1)
    assert second["hits"] >= 1 and second["value"] == first["value"]
    # the data changed: the answer is the new data's, never the cached one's — today because the
    # closed-over data are constants of the computation, part of XLA's key (a miss); were JAX to pass
    # them as arguments instead, a hit would be right too, and only the first assertion would stay
    c[7] += 0.25
    changed = _child(tmp_path, 0.25, 2)
    assert changed["value"] == pytest.approx(float(np.sum(np.sin(0.5 * c))), rel=1e-13)
    assert changed["value"] != first["value"] and changed["hits"] == 0
    if NATIVE_OK:
        assert first["native"] == {"compiled": 1, "cache_hits": 0, "has_run": True}
        assert second["native"] == {"compiled": 0, "cache_hits": 1, "has_run": True}
        assert changed["native"] == {"compiled": 1, "cache_hits": 0, "has_run": True}  # another method


def test_the_native_key_holds_what_native_means_on_this_machine(tmp_path, monkeypatch):
    """A kernel built for one CPU is never loaded on another that shares the folder: the key
    holds the compiler's expansion of -march=native."""
    if not NATIVE_OK:
        pytest.skip(NATIVE_WHY)
    cc = nbuild.compiler()
    assert "-march=native" in nbuild.FLAGS and nbuild._target(cc)  # the expansion is in the key
    monkeypatch.setenv("VPFORMS_NATIVE_CACHE", str(tmp_path))
    src = "double vp_twice(double x) { return 2.0 * x; }"
    lib = nbuild.build(src, "double vp_twice(double x);")
    assert lib.lib.vp_twice(1.5) == 3.0
    monkeypatch.setattr(nbuild, "_target", lambda cc: "cc1 -march=some-other-cpu")
    before = dict(nbuild.COUNTERS)
    nbuild.build(src, "double vp_twice(double x);")
    assert nbuild.COUNTERS["compiled"] == before["compiled"] + 1
    assert len([p for p in tmp_path.iterdir() if p.name.startswith("_vpk_")]) == 2


def test_the_cache_folder_and_its_switches(tmp_path, monkeypatch):
    monkeypatch.setenv("VPFORMS_CACHE_DIR", str(tmp_path / "c"))
    monkeypatch.delenv("VPFORMS_NATIVE_CACHE", raising=False)
    assert _cache.cache_root() == tmp_path / "c"
    assert _cache.jax_cache_dir() == tmp_path / "c" / "jax"
    assert nbuild.cache_dir() == tmp_path / "c" / "native"
    monkeypatch.setenv("VPFORMS_JAX_CACHE", "0")
    assert _cache.enable_jax_cache() is None
    monkeypatch.setenv("VPFORMS_JAX_CACHE", "1")
    monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", str(tmp_path / "users"))
    assert _cache.enable_jax_cache() == tmp_path / "users"  # the user's own cache is kept
    assert not (tmp_path / "c").exists()

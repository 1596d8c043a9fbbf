"""The native backend (issue 9): generated C kernels agree with the JAX methods they are built from.

One tmp cache directory per test session (env ``VPFORMS_NATIVE_CACHE``); each kernel compiles once.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp

import vpforms as vp
from vpforms._quadrature import DEFAULT_N
import vpforms.problems as P
from vpforms import RESULTS
from vpforms.backends import NativeUnavailableError, select_backend
from vpforms.backends.native import build as nbuild
from vpforms.backends.native.runner import run_points
from vpforms.backends.native.codegen import kernel_source

_OK, _WHY = vp.native.available()
# skipped only without a compiler, with the reason shown (CI has gcc)
pytestmark = pytest.mark.skipif(not _OK, reason=f"native backend unavailable: {_WHY}")


@pytest.fixture(scope="module", autouse=True)
def _cache(isolated_native_cache):
    return isolated_native_cache


@pytest.fixture(scope="module")
def methods():
    out = {}
    for pn in ("abc", "rigid_body"):
        prob = P.get(pn)
        b = vp.scheme(prob.field, "SE+SE")
        out[pn] = (prob, {"RK4": vp.RK4(prob.field), "SE+SE": b, "adjoint": b.adjoint(),
                          "order 2": vp.compose(b, 2), "order 4": vp.compose(b, 4),
                          "order 4 BM": vp.compose(b, 4, "blanes_moan")})
    return out


@pytest.mark.parametrize("pn", ["abc", "rigid_body"])
@pytest.mark.parametrize("which", ["RK4", "SE+SE", "adjoint", "order 2", "order 4", "order 4 BM"])
def test_native_equals_jax_after_100_steps(methods, pn, which):
    prob, ms = methods[pn]
    m = ms[which]
    assert select_backend(m, "auto")[0] == "native"
    x0 = prob.x0
    a = vp.integrate(m, x0, 0.1, 100, save_every=10, backend="native")
    b = vp.integrate(m, x0, 0.1, 100, save_every=10, backend="jax")
    assert a.stats["backend"] == "native" and b.stats["backend"] == "jax"
    assert a.xs.shape == b.xs.shape and np.array_equal(a.steps, b.steps)
    assert np.all(a.status == 0) and np.all(b.status == 0)
    assert np.max(np.abs(a.xs - b.xs)) <= 1e-11
    assert np.all(a.recovered == 0)


def _native_step(m, x, h):
    xs, st, _, _ = run_points(m, np.atleast_2d(x), h, [0, 1])
    assert np.all(st == 0)
    return xs[:, 1]


@pytest.mark.parametrize("which", ["SE+SE", "order 4", "order 4 BM"])
def test_native_step_preserves_volume(methods, which):
    """det of the central-difference Jacobian of the native step: 1 up to the FD error O(ε²)."""
    _, ms = methods["abc"]
    m, h, eps = ms[which], 0.3, 1e-5
    x = np.array([[0.3, 1.1, 2.2], [4.0, 0.5, 5.5]])
    cols = []
    for k in range(3):
        e = np.zeros(3)
        e[k] = eps
        cols.append((_native_step(m, x + e, h) - _native_step(m, x - e, h)) / (2 * eps))
    J = np.stack(cols, axis=-1)  # (N, 3, 3)
    det = np.linalg.det(J)
    assert np.max(np.abs(det - 1.0)) < 1e-8
    # and it is the JAX Jacobian of the same map (the bare method: the kernel is built from it)
    mb = m.without_recovery()
    Jj = np.stack([np.asarray(jax.jacfwd(lambda p: mb.step(p, h))(jnp.asarray(p))) for p in x])
    assert np.max(np.abs(J - Jj)) < 1e-8


def test_nan_initial_condition_gives_nonfinite_status(methods):
    _, ms = methods["abc"]
    m = ms["SE+SE"]
    x0 = np.array([[0.1, 0.2, 0.3], [np.nan, 0.0, 0.0], [1.0, 2.0, 3.0]])
    xs, st, failed, rec = run_points(m, x0, 0.1, [0, 5, 10])
    assert list(st) == [RESULTS.successful, RESULTS.nonfinite, RESULTS.successful]
    assert list(failed) == [-1, 0, -1]
    good = vp.integrate(m.without_recovery(), x0[[0, 2]], 0.1, 10, save_every=5, backend="jax")
    assert np.max(np.abs(xs[[0, 2]] - good.xs)) <= 1e-12
    with pytest.raises(ValueError, match="NaN"):  # the front door still rejects it
        vp.integrate(m, x0, 0.1, 10)


# ---- failure, freezing and recovery: a field that overflows at a known step -------------------
def _overflow_field():
    x1, x2, x3 = vp.fields.SYMBOLS
    # a = (1, 0, e^{x1}): x1 = x1(0) + t, and RK4's x3 update overflows once x1 ≈ log(DBL_MAX) − h
    return vp.Field.from_sympy((sp.Integer(1), sp.Integer(0), sp.exp(x1)), name="overflow")


class _Fake:
    """A method whose bare (native) step overflows near x1 ≈ 709 and whose recovering step succeeds."""

    def __init__(self):
        self.bare = vp.RK4(_overflow_field())
        self.name = "fake-recovering"

    def without_recovery(self):
        return self.bare

    def step_with_status(self, x, h):
        return self.bare.step_with_status(x, h)

    def step_with_recovery(self, x, h):  # finite: only moves x1 (its exact flow), per point
        n = jnp.shape(x)[:-1]
        return x + jnp.array([h, 0.0, 0.0]), jnp.zeros(n, jnp.int32), jnp.ones(n, jnp.int32)


def test_failed_native_step_is_recovered_through_jax():
    m = _Fake()
    x0 = np.array([[700.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    sol = vp.integrate(m, x0, 1.0, 15, save_every=1, backend="native")
    # the bare step first fails at step n_fail (JAX says where); from there on every step of
    # particle 0 is recovered, each one through the JAX recovering step
    n_fail = int(vp.integrate(m.bare, x0, 1.0, 15, backend="jax").failed_step[0])
    assert 0 < n_fail < 15
    assert list(sol.status) == [0, 0]
    assert list(sol.recovered) == [15 - n_fail, 0]
    assert sol.xs[0, -1, 0] == 715.0 and np.all(np.isfinite(sol.xs))
    # the fake reports RECOVERY code 1 for each of them
    assert sol.stats["recovered_how"] == {vp.RECOVERY.messages[1]: 15 - n_fail}


def test_failed_native_step_without_recovery_is_frozen():
    m = vp.RK4(_overflow_field())  # a bare method: its failing particle is frozen
    x0 = np.array([[700.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    sol = vp.integrate(m, x0, 1.0, 15, save_every=1, backend="native")
    ref = vp.integrate(m, x0, 1.0, 15, save_every=1, backend="jax")
    assert list(sol.status) == [RESULTS.nonfinite, 0] == list(ref.status)
    n_fail = int(ref.failed_step[0])
    assert list(sol.failed_step) == [n_fail, -1] and 0 < n_fail < 15
    assert np.all(np.isfinite(sol.xs))  # frozen, never NaN
    assert np.all(sol.xs[0, n_fail + 1 :] == sol.xs[0, n_fail])
    assert np.max(np.abs(sol.xs - ref.xs) / (1 + np.abs(ref.xs))) < 1e-12


# ---- selection, no compiler, unsupported methods ----------------------------------------------
def test_no_compiler_gives_clear_error_or_jax_fallback(methods, monkeypatch):
    prob, ms = methods["abc"]
    monkeypatch.setenv("VPFORMS_NATIVE_DISABLE", "1")
    ok, why = vp.native.available()
    assert not ok and "no C compiler found" in why
    with pytest.raises(NativeUnavailableError, match="install gcc"):
        vp.integrate(ms["SE+SE"], prob.x0, 0.1, 3, backend="native")
    sol = vp.integrate(ms["SE+SE"], prob.x0, 0.1, 3, backend="auto")
    assert sol.stats["backend"] == "jax" and "no C compiler" in sol.stats["backend_reason"]


def test_unsupported_methods_fall_back_or_raise():
    f = P.get("abc").field
    g = vp.Field.from_callable(f, name="abc-callable") if hasattr(vp.Field, "from_callable") else None
    if g is not None:
        name, why = select_backend(vp.RK4(g), "auto")
        assert name == "jax" and "Field.from_sympy" in why
    m = vp.scheme(f, "DL+DL", fast=False)  # the engine form (the default is the θ-stages)
    assert select_backend(m, "auto")[0] == "jax"
    with pytest.raises(NativeUnavailableError, match="engine form"):
        select_backend(m, "native")
    with pytest.raises(ValueError, match="backend must be"):
        select_backend(m, "cuda")


# ---- the cache ---------------------------------------------------------------------------------
def test_second_build_is_a_cache_hit(methods):
    from vpforms.backends.native.codegen import CDEF, kernel_source

    src = kernel_source(methods["abc"][1]["SE+SE"])
    # this process may hold the module already, loaded from another test file's cache directory:
    # forget it, so that the first build puts the .so in this module's cache (compiles or hits)
    nbuild._loaded.clear()
    nbuild.build(src, CDEF)
    nbuild._loaded.clear()  # forget the loaded module: a new process would start like this
    before = dict(nbuild.COUNTERS)
    lib = nbuild.build(src, CDEF)
    assert nbuild.COUNTERS["compiled"] == before["compiled"]
    assert nbuild.COUNTERS["cache_hits"] == before["cache_hits"] + 1
    assert hasattr(lib.lib, "vp_run")


def test_concurrent_builds_do_not_corrupt_the_cache(tmp_path):
    code = textwrap.dedent(f"""
        import os, sys
        sys.path.insert(0, {os.path.dirname(os.path.dirname(vp.__file__))!r})
        from vpforms.backends.native import build
        lib = build.build("int vp_twice(int a) {{ return 2 * a; }} /* concurrency */", "int vp_twice(int a);")
        assert lib.lib.vp_twice(21) == 42
        print("ok")
    """)
    env = {**os.environ, "VPFORMS_NATIVE_CACHE": str(tmp_path)}
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(3)]
    outs = [p.communicate(timeout=120) for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    files = sorted(os.listdir(tmp_path))
    assert len(files) == 1 and files[0].endswith(".so"), files  # one object, no temporary left


# ---- CLI ----------------------------------------------------------------------------------------
def test_cli_run_says_which_backend_ran(tmp_path, capsys):
    from vpforms.cli import main

    out = tmp_path / "r.npz"
    assert main(["run", "--steps", "5", "--particles", "3", "--backend", "native", "--out", str(out)]) == 0
    assert "native" in capsys.readouterr().out
    assert main(["run", "--steps", "5", "--method", "DL+DL", "--engine", "--backend", "native",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("vpforms: error:") and "engine form" in err[0]
    assert "--engine" in err[0]  # what to do instead (leave it out); the default runs natively:
    assert main(["run", "--steps", "5", "--particles", "3", "--method", "DL+DL",
                 "--backend", "native", "--out", str(out)]) == 0
    assert "native" in capsys.readouterr().out


# ---- the generic engine (Newton) ----------------------------------------------------------------
@pytest.mark.parametrize("pn", ["linear", "lotka_volterra"])
def test_native_newton_engine_equals_jax(pn):
    prob = P.get(pn)
    m = vp.scheme(prob.field, "SE+SE")
    assert select_backend(m, "native")[0] == "native"
    a = vp.integrate(m, prob.x0, 0.05, 100, save_every=25, backend="native")
    b = vp.integrate(m, prob.x0, 0.05, 100, save_every=25, backend="jax")
    assert np.all(a.status == 0) and np.all(b.status == 0)
    assert np.max(np.abs(a.xs - b.xs)) <= 1e-11


def test_newton_failure_is_frozen_with_its_status():
    prob = P.get("lotka_volterra")
    # one iteration cannot converge (bare: recovery is tested below)
    m = vp.scheme(prob.field, "SE+SE", newton={"max_iter": 1}, recover=False)
    a = vp.integrate(m, prob.x0, 0.05, 10, save_every=1, backend="native")
    b = vp.integrate(m, prob.x0, 0.05, 10, save_every=1, backend="jax")
    assert np.all(b.status == RESULTS.not_converged)  # the JAX engine fails too (no recovery)
    assert np.array_equal(a.status, b.status) and np.array_equal(a.failed_step, b.failed_step)
    assert np.all(np.isfinite(a.xs)) and np.array_equal(a.xs, np.repeat(a.xs[:, :1], 11, axis=1))


def test_forced_newton_engine_equals_closed_form_on_abc(methods):
    prob, ms = methods["abc"]
    a = run_points(ms["SE+SE"], prob.x0, 0.1, [0, 100], engine="newton")
    b = run_points(ms["SE+SE"], prob.x0, 0.1, [0, 100])
    assert np.all(a[1] == 0) and np.max(np.abs(a[0] - b[0])) <= 1e-11


# ---- every generated case of every class (issue 9, second pass) --------------------------------
def _rotation():
    """A skew (hence traceless) linear field with every off-diagonal entry nonzero: bounded orbits,
    and every S1/S2 case's recipe defined (the relabelled a₁₃, a₁₂ are never 0)."""
    A = np.array([[0.0, 0.7, -1.1], [-0.7, 0.0, 0.4], [1.1, -0.4, 0.0]])
    return vp.Field.linear(A, name="rotation")


_PROBLEMS = {  # class → the problems its cases are checked on (S1/S2: the linear recipe on a
    # linear field, Quispel's correction map (closed-form f_c) on a nonlinear one; the DL classes
    # as their nested θ-stages, fast=True)
    "SE+SE": ("abc", "lotka_volterra"),
    "S1": ("rotation", "lotka_volterra"),
    "S2": ("rotation", "lotka_volterra"),
    "DL+DL": ("abc", "lotka_volterra"),
    "SE+DL": ("abc", "tokamak"),
}

_DL = ("DL+DL", "SE+DL")


def _scheme(f, case, **kw):
    """The bare method of ``case``; the DL classes in their natively generated form (fast=True)."""
    cls = case if isinstance(case, str) else case.cls
    return vp.scheme(f, case, recover=False, **({"fast": True} if cls in _DL else {}), **kw)


def _problem(pn):
    if pn == "rotation":
        return _rotation(), np.array([[1.0, 0.0, 0.0], [0.3, -0.5, 0.7]])
    prob = P.get(pn)
    return prob.field, prob.x0


@pytest.fixture(scope="module")
def fields():
    return {pn: _problem(pn) for pn in ("abc", "lotka_volterra", "rotation", "linear", "tokamak")}


def _agree(a, b, tol=1e-11):
    """native == JAX to tol, relative to 1 + |x| (the linear problem grows to |x| ~ 4e2)."""
    assert a.stats["backend"] == "native" and b.stats["backend"] == "jax"
    assert np.array_equal(a.status, b.status) and np.array_equal(a.failed_step, b.failed_step)
    err = np.max(np.abs(a.xs - b.xs) / (1.0 + np.abs(b.xs)))
    assert err <= tol, err


_GENERATED = [pytest.param(cls, pn, c, id=f"{cls}-{pn}-{c}")
              for cls, pns in _PROBLEMS.items() for pn in pns for c in vp.cases() if c.cls == cls]


@pytest.mark.parametrize("cls, pn, case", _GENERATED)
def test_every_generated_case_equals_jax(fields, cls, pn, case):
    """All 36 cases: the 6 of each class (relabelled representatives, and the adjoints of the SE+DL
    3-cycles), 100 steps, on two problems each (one kernel per case and problem: the relabelled
    field's potentials differ)."""
    f, x0 = fields[pn]
    m = _scheme(f, case)
    assert m.case == case and select_backend(m, "native")[0] == "native"
    a = vp.integrate(m, x0, 0.05, 100, save_every=50, backend="native")
    b = vp.integrate(m, x0, 0.05, 100, save_every=50, backend="jax")
    assert np.all(b.status == 0)
    _agree(a, b)


_COMPOSED = [("lotka_volterra", "SE+SE"), ("abc", "SE+SE"), ("rotation", "S1"), ("linear", "S2"),
             ("abc", "S1"), ("lotka_volterra", "S2"), ("tokamak", "DL+DL"), ("abc", "SE+DL")]


@pytest.mark.parametrize("case", [c for c in vp.cases() if c.cls == "DL+DL"], ids=str)
def test_every_dldl_case_with_midpoint_stages_equals_jax(fields, case):
    """θ = ½ (implicit-midpoint-type stages: p̄ depends on q₁, so the inner solve sits inside the
    outer Newton) for the 6 DL+DL cases on ABC."""
    f, x0 = fields["abc"]
    m = _scheme(f, case, theta=0.5)
    a = vp.integrate(m, x0, 0.1, 100, save_every=50, backend="native")
    b = vp.integrate(m, x0, 0.1, 100, save_every=50, backend="jax")
    assert np.all(b.status == 0)
    _agree(a, b)


@pytest.mark.parametrize("order", [2, 4])
@pytest.mark.parametrize("pn, cls", _COMPOSED)
def test_compositions_of_relabelled_cases_equal_jax(fields, pn, cls, order):
    """Compositions need the adjoint Ψ*_h = (Ψ_{−h})⁻¹: through the inverse map, implicit on
    Lotka–Volterra and for the linear recipes (the inverse Newton engine), on a relabelled case."""
    f, x0 = fields[pn]
    case = next(c for c in vp.cases() if c.cls == cls and c.sigma != (3, 2, 1))
    m = vp.compose(_scheme(f, case), order)
    assert select_backend(m, "native")[0] == "native"
    a = vp.integrate(m, x0, 0.05, 100, save_every=50, backend="native")
    b = vp.integrate(m, x0, 0.05, 100, save_every=50, backend="jax")
    assert np.all(b.status == 0)
    _agree(a, b)


def test_closed_form_and_newton_solves_give_the_same_relabelled_map(fields):
    """engine="newton" iterates where the emitter uses the closed form (ABC's shears, adjoint too)."""
    f, x0 = fields["abc"]
    case = next(c for c in vp.cases() if c.cls == "SE+SE" and c.sigma == (1, 3, 2))
    m = vp.compose(vp.scheme(f, case, recover=False), 2)
    a = run_points(m, x0, 0.1, [0, 100], engine="newton")
    b = run_points(m, x0, 0.1, [0, 100])
    assert np.all(a[1] == 0) and np.max(np.abs(a[0] - b[0])) <= 1e-11


@pytest.mark.parametrize("which", ["case", "order 2"])
def test_newton_failure_of_a_relabelled_case_is_frozen_like_jax(fields, which):
    f, x0 = fields["lotka_volterra"]
    case = next(c for c in vp.cases() if c.cls == "SE+SE" and c.sigma == (2, 3, 1))
    m = vp.scheme(f, case, recover=False, newton={"max_iter": 2})
    m = m if which == "case" else vp.compose(m, 2)
    a = vp.integrate(m, x0, 0.2, 30, save_every=1, backend="native")
    b = vp.integrate(m, x0, 0.2, 30, save_every=1, backend="jax")
    assert np.any(b.status == RESULTS.not_converged)  # the JAX engine fails too
    _agree(a, b)
    assert np.all(np.isfinite(a.xs))


@pytest.mark.slow  # ~30 s: the JAX recovering method compiles its alternatives
def test_recovery_of_a_relabelled_case_agrees_with_jax(fields):
    """recover=True (the default): where the bare native step fails (Newton capped at 3
    iterations), the runner takes that step through the JAX recovering method; the result, the
    status and Solution.recovered are those of the JAX backend."""
    f, x0 = fields["lotka_volterra"]
    case = next(c for c in vp.cases() if c.cls == "SE+SE" and c.sigma == (1, 3, 2))
    m = vp.scheme(f, case, newton={"max_iter": 3}, recover_classes=False, recover_substeps=2)
    a = vp.integrate(m, x0, 0.12, 40, save_every=10, backend="native")
    b = vp.integrate(m, x0, 0.12, 40, save_every=10, backend="jax")
    assert np.sum(b.recovered) > 0 and np.all(b.status == 0), (b.recovered, b.status)
    assert np.array_equal(a.recovered, b.recovered)
    _agree(a, b)


@pytest.mark.parametrize("cls", ["DL+DL", "SE+DL"])
def test_dl_engine_form_is_left_on_jax_and_says_why(cls):
    """fast=False solves the generating map of L_d (an inner Newton for p̄ inside a potential):
    "auto" runs it on JAX and "native" says why, pointing at the default stage form."""
    m = vp.scheme(P.get("lotka_volterra").field, cls, recover=False, fast=False)
    name, why = select_backend(m, "auto")
    assert name == "jax" and "discrete Lagrangians" in why and "stage form" in why
    assert select_backend(vp.scheme(P.get("lotka_volterra").field, cls, recover=False), "auto")[0] == "native"
    with pytest.raises(NativeUnavailableError, match="inner Newton"):
        select_backend(m, "native")
    assert select_backend(_scheme(P.get("lotka_volterra").field, cls), "auto")[0] == "native"


@pytest.mark.parametrize("theta", [0.0, 0.5])
def test_native_dl_step_preserves_volume(fields, theta):
    """det of the central-difference Jacobian of the native DL+DL step (a relabelled case) = 1 up
    to the FD error, and = the JAX jacfwd of the same step."""
    f, _ = fields["abc"]
    case = next(c for c in vp.cases() if c.cls == "DL+DL" and c.sigma == (2, 1, 3))
    m, h, eps = _scheme(f, case, theta=theta), 0.3, 1e-5
    x = np.array([[0.3, 1.1, 2.2], [4.0, 0.5, 5.5]])
    J = np.stack([(_native_step(m, x + e, h) - _native_step(m, x - e, h)) / (2 * eps)
                  for e in np.eye(3) * eps], axis=-1)
    assert np.max(np.abs(np.linalg.det(J) - 1.0)) < 1e-8
    Jj = np.stack([np.asarray(jax.jacfwd(lambda p: m.step(p, h))(jnp.asarray(p))) for p in x])
    assert np.max(np.abs(J - Jj)) < 1e-8


@pytest.mark.parametrize("max_iter", [1, 2])
def test_dl_newton_failure_is_frozen_like_jax(fields, max_iter):
    """θ = ½ on Lotka–Volterra needs more than 1–2 Newton iterations (outer or inner): the native
    lanes fail at the step JAX fails, with its status, and stay finite."""
    f, x0 = fields["lotka_volterra"]
    m = _scheme(f, "DL+DL", theta=0.5, newton={"max_iter": max_iter})
    a = vp.integrate(m, x0, 0.1, 20, save_every=1, backend="native")
    b = vp.integrate(m, x0, 0.1, 20, save_every=1, backend="jax")
    assert np.any(b.status == RESULTS.not_converged)
    _agree(a, b)
    assert np.all(np.isfinite(a.xs))


@pytest.mark.parametrize("cls", ["S1", "S2"])
def test_quadrature_correction_runs_natively_and_equals_jax(fields, cls):
    """The correction integral f_c by the JAX method's own Gauss–Legendre rule (issue #20: S1/S2
    on fields without a closed form, e.g. coils): C loops over the same nodes, with the
    derivatives of the rule itself in the Newton solve for X_j. ``auto`` picks native; the run,
    its inverse (the adjoint) and a relabelled case equal JAX to rounding, statuses included."""
    f, x0 = fields["lotka_volterra"]
    m = vp.scheme(f, cls, recover=False, integral="quadrature")
    assert m.integral == f"quadrature(n={DEFAULT_N})"
    assert select_backend(m, "auto")[0] == "native"
    src = kernel_source(m)
    assert f"VP_GL_T{DEFAULT_N}[" in src  # a loop over the nodes, not a closed form
    for meth in (m, m.adjoint(), m.relabel((2, 3, 1))):
        _agree(vp.integrate(meth, x0, 0.05, 40, save_every=10, backend="native"),
               vp.integrate(meth, x0, 0.05, 40, save_every=10, backend="jax"))


def test_lanes_the_vectorised_pass_leaves_undecided_are_redone_exactly(fields, monkeypatch):
    """With one vectorised Newton iteration no implicit solve converges in the fast pass, so every
    step of every lane goes through the exact early-exit redo: still the JAX result and status."""
    from vpforms.backends.native.codegen import emit

    monkeypatch.setattr(emit, "FIXED_ITERS", 1)
    f, x0 = fields["lotka_volterra"]
    m = vp.compose(vp.scheme(f, "SE+SE", recover=False), 2)  # a fresh method: a fresh kernel
    assert "n2_run = n2_run * (1.0 - fail)" in emit.kernel_source(m)  # an implicit solve, 1 pass
    a = vp.integrate(m, x0, 0.05, 100, save_every=50, backend="native")
    b = vp.integrate(m, x0, 0.05, 100, save_every=50, backend="jax")
    assert np.all(b.status == 0)
    _agree(a, b)


def test_dl_lanes_the_vectorised_pass_leaves_undecided_are_redone_exactly(fields, monkeypatch):
    """The same with the nested solves of a DL+DL θ = ½ step (outer q₁, inner p̄)."""
    from vpforms.backends.native.codegen import emit

    monkeypatch.setattr(emit, "FIXED_ITERS", 1)
    f, x0 = fields["tokamak"]
    m = _scheme(f, "DL+DL", theta=0.5)
    assert "t0i_run = t0i_run * (1.0 - fail)" in emit.kernel_source(m)  # nested, 1 pass
    a = vp.integrate(m, x0, 0.05, 100, save_every=50, backend="native")
    b = vp.integrate(m, x0, 0.05, 100, save_every=50, backend="jax")
    assert np.all(b.status == 0)
    _agree(a, b)


# ---- the front door's caches (issue #19) --------------------------------------------------------
def test_backend_choice_is_remembered_per_method_object_and_dropped_with_it():
    """select_backend plans a method once: the entry answers only for that very object (an id
    reused by a later method is planned afresh) and goes when the method is collected."""
    import gc

    from vpforms.backends import _reasons

    f = P.get("abc").field
    m = vp.scheme(f, "DL+DL", fast=False)
    key = id(m)
    assert select_backend(m, "auto")[0] == "jax" and key in _reasons
    assert select_backend(m, "auto")[0] == "jax"  # from the cache: the same answer
    with pytest.raises(NativeUnavailableError, match="engine form"):
        select_backend(m, "native")
    del m
    gc.collect()
    assert key not in _reasons
    _reasons[key] = (lambda: None, "stale")  # an id reused: the stale entry is not this method's
    try:
        m2 = vp.scheme(f, "SE+SE")
        if id(m2) == key:
            assert select_backend(m2, "auto")[0] == "native"
        assert select_backend(m2, "auto")[0] == "native"
    finally:
        _reasons.pop(key, None)


def test_saved_rows_are_copied_bit_for_bit():
    from vpforms.backends.native.runner import _put

    x = np.random.default_rng(3).normal(size=(7, 3))
    x[2, 1], x[4, 0] = np.nan, -np.inf
    xs = np.zeros((7, 3, 3))
    _put(xs, 1, x)
    assert xs[:, 1].tobytes() == x.tobytes() and not xs[:, 0].any() and not xs[:, 2].any()
    _put(np.empty((0, 2, 3)), 0, np.empty((0, 3)))


def test_potential_checks_are_lambdified_once():
    from vpforms import _potentials as pot

    f = P.get("abc").field
    m = vp.scheme(f, "SE+SE")
    x0 = np.random.default_rng(0).uniform(0, 6, size=(64, 3))
    m.check_domain(x0)
    before = pot._numpy_fn_cached.cache_info()
    m.check_domain(x0)
    after = pot._numpy_fn_cached.cache_info()
    assert after.misses == before.misses and after.hits > before.hits

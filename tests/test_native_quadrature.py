"""Native C for quadrature potentials, and special functions (erf, …) in fields and potentials.

A field whose potentials SymPy cannot integrate gets Gauss–Legendre potentials (MATH.md §3,
:mod:`vpforms._quadrature`); the native backend generates them as loops over the same nodes, with
the derivatives the methods need as quadratures of the differentiated integrand — the derivatives
``jax.grad`` takes of the JAX quadrature. So native and JAX run the same map, to rounding.

One tmp cache directory per module (env ``VPFORMS_NATIVE_CACHE``); each kernel compiles once.
"""

from __future__ import annotations

import re

import jax
import numpy as np
import pytest
import sympy as sp

import vpforms as vp
import vpforms.problems as P
from vpforms._case import CLASSES
from vpforms._potentials import potential_exprs
from vpforms._quadrature import DEFAULT_N, GL_T, GLSum, _nodes_weights
from vpforms.backends import select_backend
from vpforms.backends.native.codegen import kernel_source
from vpforms.backends.native.codegen.potentials import potential_pair
from vpforms.fields import SYMBOLS

_OK, _WHY = vp.native.available()
# the native tests are skipped only without a compiler, with the reason shown (CI has gcc)
native = pytest.mark.skipif(not _OK, reason=f"native backend unavailable: {_WHY}")

x1, x2, x3 = SYMBOLS


@pytest.fixture(scope="module", autouse=True)
def _cache(isolated_native_cache):
    return isolated_native_cache


def _curl(A):
    return (sp.diff(A[2], x2) - sp.diff(A[1], x3), sp.diff(A[0], x3) - sp.diff(A[2], x1),
            sp.diff(A[1], x1) - sp.diff(A[0], x2))


@pytest.fixture(scope="module")
def quad_field():
    """a = ∇×(sin x₂x₃, cos x₁x₃, sin x₁x₂): ∫x₁cos(x₁s) ds is Piecewise in x₁ (x₁ = 0), so both
    pairs are quadratures."""
    f = vp.Field.from_sympy(_curl((sp.sin(x2 * x3), sp.cos(x1 * x3), sp.sin(x1 * x2))), name="curl")
    assert f.potential_methods == {"se": "quadrature(n=32)", "dl": "quadrature(n=32)"}
    return f


@pytest.fixture(scope="module")
def erf_field():
    """div a = 0 (a₁ free of x₁, a₂ of x₂, a₃ of x₃); G² = ∫a₃(s, x₂, 0) ds has erf(x₁)."""
    f = vp.Field.from_sympy((sp.sin(x2) * x3 + x2**2, sp.cos(x3) * x1 - x3 * x1**2,
                             sp.exp(-x1**2) * sp.sin(x2)), name="erf")
    assert f.potential_methods == {"se": "closed form", "dl": "closed form"}
    assert f.dl_potential_exprs[1].has(sp.erf)
    return f


def _bare(f, case, **kw):
    cls = case if isinstance(case, str) else case.cls
    return vp.scheme(f, case, recover=False, **({"fast": True} if "DL" in cls else {}), **kw)


def _agree(m, x0, h, steps=100, tol=1e-10):
    """native and JAX: the same statuses and failed steps, states equal to tol relative to 1 + |x|."""
    assert select_backend(m, "auto")[0] == "native"
    a = vp.integrate(m, x0, h, steps, save_every=steps // 2, backend="native")
    b = vp.integrate(m, x0, h, steps, save_every=steps // 2, backend="jax")
    assert a.stats["backend"] == "native" and b.stats["backend"] == "jax"
    assert np.array_equal(a.status, b.status) and np.array_equal(a.failed_step, b.failed_step)
    err = np.max(np.abs(a.xs - b.xs) / (1.0 + np.abs(b.xs)))
    assert err <= tol, err
    return a, b


def _eval_gl(expr, point):
    """A SymPy expression with GLSums at a point: each Σᵢ wᵢ f(tᵢ) summed numerically."""
    t, w = _nodes_weights(32)
    sub = dict(zip(SYMBOLS, point))
    vals = {}
    for q in expr.atoms(GLSum):
        f = sp.lambdify(GL_T, q.integrand.xreplace(sub), "numpy")
        vals[q] = sp.Float(float(np.dot(w, np.broadcast_to(f(t), t.shape))), 17)
    return float(expr.xreplace(vals).xreplace(sub))


# ------------------------------------------------------------------------------- no compiler needed
def test_symbolic_quadrature_is_the_jax_quadrature_with_its_derivatives(quad_field):
    """The GLSum potentials C is generated from, and the derivatives the methods take of them
    (SE+SE: ∂₂F¹, ∂₃F¹, ∂₂∂₃F¹, ∂₁F³, ∂₂F³, ∂₁∂₂F³), equal the JAX quadrature and its jax.grad."""
    F1, F3 = quad_field.se_potentials
    P1, P3 = potential_pair(quad_field, "se")
    g = jax.grad
    pairs = [(F1, P1, ()), (F3, P3, ()), (g(F1, 1), P1, (x2,)), (g(F1, 2), P1, (x3,)),
             (g(g(F1, 1), 2), P1, (x2, x3)), (g(F3, 0), P3, (x1,)), (g(F3, 1), P3, (x2,)),
             (g(g(F3, 0), 1), P3, (x1, x2))]
    for p in ([0.3, -0.7, 0.9], [-0.95, 0.4, -0.2]):
        for jf, expr, wrt in pairs:
            ref = float(jax.jit(jf)(*p))
            got = _eval_gl(sp.diff(expr, *wrt) if wrt else expr, p)
            assert abs(got - ref) <= 1e-14 * (1 + abs(ref)), (wrt, got, ref)


def test_kernel_loops_over_the_jax_nodes(quad_field):
    """The C tables are the nodes and weights of vpforms._quadrature bit for bit (n = 32, and the
    field's own quadrature_n = 12), and the potentials are loops, not an expanded sum."""
    f12 = vp.Field.from_sympy(quad_field.exprs, name="curl-12", quadrature_n=12)
    for f, n in ((quad_field, 32), (f12, 12)):
        src = kernel_source(_bare(f, "SE+SE"))
        assert set(re.findall(r"VP_GL_[TW](\d+)\[\d+\] =", src)) == {str(n)}
        for name, ref in zip("TW", _nodes_weights(n)):
            body = re.search(rf"VP_GL_{name}{n}\[{n}\] = {{([^}}]*)}}", src).group(1)
            assert np.array_equal(np.array([float(v) for v in body.split(",")]), ref)
        assert f"< {n}; " in src and src.count("sin(") < 100


def test_erf_field_runs_under_jit_on_jax(erf_field):
    """The erf of G² goes to jax.scipy.special.erf (it was math.erf: ConcretizationTypeError
    under jit): the DL pair rebuilds the field by autodiff, and a jitted DL step runs."""
    pts = erf_field.sample_points(64)
    assert erf_field.reconstruction_error("dl") <= 1e-13  # jit(autodiff of G¹, G²)
    m = _bare(erf_field, "DL+DL")
    X, st = jax.jit(m.step_with_status)(pts[:8], 0.05)
    assert np.all(np.asarray(st) == 0)
    # consistent: X = x + h a(x) + O(h²)
    assert np.max(np.abs(np.asarray(X) - pts[:8] - 0.05 * np.asarray(erf_field(pts[:8])))) <= 0.05


def test_function_without_jax_implementation_is_named():
    """A component with Airy's Ai (no JAX implementation): a ValueError naming it."""
    with pytest.raises(ValueError, match="airyai"):
        vp.Field.from_sympy((sp.airyai(x2), x3, x1))


def test_closed_form_without_jax_implementation_falls_back_to_quadrature():
    """∫cos(s³) ds is a hypergeometric function (no JAX implementation): the SE pair is the
    quadrature of the field's own components instead, and rebuilds the field."""
    a = (sp.cos(x2**3), x3, x1)
    assert potential_exprs(a, SYMBOLS, "se")[1].has(sp.hyper)
    f = vp.Field.from_sympy(a, name="cos-cube")
    assert f.potential_methods == {"se": "quadrature(n=32)", "dl": "closed form"}
    assert f.reconstruction_error("se") <= 1e-13


# ------------------------------------------------------------------------------------------ native
@native
@pytest.mark.parametrize("kw", [
    {}, pytest.param({"origin": (0.1, 0.2, -0.3), "quadrature_n": 7}, marks=pytest.mark.slow)],
    ids=["default", "origin-n7"])
def test_quadrature_field_runs_natively_and_equals_jax(quad_field, kw):
    """SE+SE on quadrature potentials: native == JAX after 100 steps (h = 0.02: at h = 0.05
    trajectories leave the box and fail near thresholds, where rounding decides the status); also
    from another base point c with a 7-node rule (s = c + (x − c)t)."""
    f = vp.Field.from_sympy(quad_field.exprs, name="curl", **kw) if kw else quad_field
    _agree(_bare(f, "SE+SE"), f.sample_points(16), 0.02)


@native
@pytest.mark.slow  # 3 kernels and 3 JAX methods, ~12 s
def test_erf_fields_run_natively_and_equal_jax(erf_field):
    """The erf field (its DL pair has erf(x₁); the θ-stages need only its derivative), and a field
    with erf, erfc in its components — C's erf/erfc in the Euler guess, the guard and the
    quadrature loops of its SE pair (∫erf(s x₃) ds is Piecewise in x₃)."""
    x0 = erf_field.sample_points(8)
    for cls in ("SE+SE", "DL+DL"):
        _agree(_bare(erf_field, cls), x0, 0.05)
    f = vp.Field.from_sympy((sp.erf(x2 * x3), sp.cos(x1) * x3, sp.erfc(x1) * sp.sin(x2)), name="erfc")
    assert f.potential_methods["se"] == "quadrature(n=32)"
    m = _bare(f, "SE+SE")
    src = kernel_source(m)
    assert "erf(" in src and "erfc(" in src
    _agree(m, f.sample_points(8), 0.05)


@native
def test_c_unprintable_function_runs_on_jax_and_says_why():
    """Si has a JAX implementation (sici) but no C one: auto keeps the method on JAX, saying so."""
    f = vp.Field.from_sympy((sp.Si(x2), x3, x1), name="si")
    name, why = select_backend(_bare(f, "SE+SE"), "auto")
    assert name == "jax" and "Si" in why


@native
def test_native_quadrature_step_preserves_volume(quad_field):
    """det of the central-difference Jacobian of the native SE+SE step on quadrature potentials is
    1 up to the finite-difference error O(ε²): the quadrature's exact derivatives keep the map
    volume preserving (MATH.md §3)."""
    from vpforms.backends.native.runner import run_points

    m, h, eps = _bare(quad_field, "SE+SE"), 0.1, 1e-5
    for x in quad_field.sample_points(4, seed=3):
        cols = []
        for e in np.eye(3) * eps:
            pts = np.stack([x + e, x - e])
            xs = run_points(m, pts, h, np.array([0, 1]))[0][:, -1]
            cols.append((xs[0] - xs[1]) / (2 * eps))
        assert abs(np.linalg.det(np.stack(cols, axis=1)) - 1.0) <= 1e-8


@native
@pytest.mark.parametrize("pn", P.names())
def test_every_problem_and_class_is_generated_natively(pn):
    """No field of the library falls back to JAX for want of generated code, in any of the five
    classes: S1/S2 on the nonlinear fields are Quispel's correction maps, whose f_c runs natively
    in closed form or by quadrature (issue #20)."""
    f = P.get(pn).field
    for cls in CLASSES:
        name, why = select_backend(vp.scheme(f, cls, recover=False), "auto")
        assert name == "native", (cls, why)
    quad = vp.scheme(f, "S1", recover=False, integral="quadrature") if f.linear_matrix is None else None
    assert quad is None or select_backend(quad, "auto")[0] == "native"


# ------------------------------------------------------------------------ slow: the wider matrix
@native
@pytest.mark.slow  # 14 kernels and 14 JAX methods, 2–14 s each, ~90 s in all
@pytest.mark.parametrize("closed_form", [True, False], ids=["closed", "quadrature"])
@pytest.mark.parametrize("pn", P.names())
def test_every_problem_runs_natively_both_ways(pn, closed_form):
    """Every field of the problem library, with its closed-form potentials and rebuilt with
    ``closed_form=False`` (the quadrature of its components): SE+SE native == JAX, 100 steps."""
    prob = P.get(pn)
    f = prob.field if closed_form else vp.Field.from_sympy(
        prob.field.exprs, prob.field.symbols, name=f"{pn}-quadrature", box=prob.field.box,
        closed_form=False)
    assert f.potential_methods["se"] == ("closed form" if closed_form else "quadrature(n=32)")
    _agree(_bare(f, "SE+SE"), prob.x0, 0.05)


@native
@pytest.mark.slow  # one kernel and one JAX method per case, 7–17 s each (JAX compiles DL slowly)
@pytest.mark.parametrize("case", ["SE+SE-relabelled", "DL+DL", "SE+DL", "DL+DL-relabelled", "order 2",
                                  "S1", "S2"])
def test_quadrature_field_every_kind_of_stage(quad_field, case):
    """A relabelled SE+SE case (its own relabelled field's quadrature), the DL classes as θ-stages
    (fast=True) on the quadrature DL pair, relabelled too, a symmetric composition (the adjoint:
    the inverse map), and S1/S2 (the correction integral a quadrature of the field's derivatives)."""
    pick = {"SE+SE-relabelled": ("SE+SE", (2, 3, 1)), "DL+DL-relabelled": ("DL+DL", (2, 3, 1))}
    if case in pick:
        cls, sigma = pick[case]
        c = next(c for c in vp.cases() if c.cls == cls and c.sigma == sigma)
        m = _bare(quad_field, c)
        assert m.case == c
    elif case == "order 2":
        m = vp.compose(_bare(quad_field, "SE+SE"), 2)
    elif case in ("S1", "S2"):
        m = _bare(quad_field, case)
        assert m.integral == f"quadrature(n={DEFAULT_N})"
    else:
        m = _bare(quad_field, case)
    _agree(m, quad_field.sample_points(8), 0.02)


@native
@pytest.mark.slow  # two kernels and two JAX methods, ~10 s
def test_closed_form_without_jax_implementation_runs_natively():
    """The cos(x₂³) field (SE pair by quadrature, DL pair closed form) on native == JAX."""
    f = vp.Field.from_sympy((sp.cos(x2**3), x3, x1), name="cos-cube")
    x0 = f.sample_points(8)
    for cls in ("SE+SE", "SE+DL"):
        _agree(_bare(f, cls), x0, 0.05)

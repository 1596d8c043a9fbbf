"""The closing table of issue #5: class × field → max |det − 1|, observed order, error constant
at h = 0.05, mean Newton iterations per step.  Run ``python -m vpforms._methods.report``.

* max |det − 1|: 64 seeded points of the field's box, step sizes uniform in [0.01, 0.1], J by
  forward-mode AD through the step;
* observed order: least-squares slope of log(global error at T) against log h, n = 4, 8, 16, 32
  steps (T = 0.4; ABC: T = 0.1, which keeps the DL classes inside (0, π/2)³, away from their folds);
  reference: scipy DOP853, rtol = atol = 1e-13;
* error constant: (global error at T with h = 0.05) / h^p, p the nominal order (1);
* Newton iterations: the engine's (or the correction map's) scalar Newton iterations per step,
  averaged over the points and the steps of the h = 0.05 run.
"""

from __future__ import annotations

import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from scipy.integrate import solve_ivp

from ..problems import get
from ._scheme import scheme

FIELDS = {  # problem, box of random points, T
    "linear": ("linear", (-1.0, 1.0), 0.4),
    "abc": ("abc", (0.45, 1.1), 0.1),
    "lotka_volterra": ("lotka_volterra", (0.5, 2.0), 0.4),
}
ROWS = [
    ("SE+SE", {}),
    ("SE+DL", {}),
    ("DL+DL", {}),
    ("DL+DL", {"theta": 0.5}),
    ("S1", {}),
    ("S1", {"variant": "az"}),
    ("S2", {}),
]


def _reference(field, x0, T):
    def f(t, y):
        return np.asarray(field(jnp.asarray(y.reshape(-1, 3)))).ravel()

    sol = solve_ivp(f, (0.0, T), x0.ravel(), method="DOP853", rtol=1e-13, atol=1e-13)
    return sol.y[:, -1].reshape(x0.shape)


def row(field, box, T, cls, opts, n_pts=64, seed=0):
    m = scheme(field, cls, **opts)
    rng = np.random.default_rng(seed)
    x = rng.uniform(box[0], box[1], (n_pts, 3))
    hs = rng.uniform(0.01, 0.1, n_pts)

    def one(p, h):
        def fwd(z):
            X, st, it = m._forward(z, h)
            return X, (X, st, it)

        J, (X, st, it) = jax.jacfwd(fwd, has_aux=True)(p)
        return X, jnp.linalg.det(J), st, it

    F = jax.jit(jax.vmap(one))
    t0 = time.perf_counter()
    X, det, st, _ = F(jnp.asarray(x), jnp.asarray(hs))
    assert np.all(np.asarray(st) == 0), (cls, opts)
    det_err = float(np.max(np.abs(np.asarray(det) - 1)))

    def run(x0, h, n):
        def body(i, c):
            x, its = c
            X, _, _, it = F(x, jnp.full(x.shape[0], h))
            return X, its + jnp.sum(it)

        return lax.fori_loop(0, n, body, (x0, 0))

    run = jax.jit(run)
    x0 = x[:8]
    ref = _reference(field, x0, T)
    ns = (4, 8, 16, 32)
    errs = []
    for n in ns:
        xn, _ = run(jnp.asarray(x0), T / n, n)
        errs.append(float(np.max(np.abs(np.asarray(xn) - ref))))
    p = float(np.polyfit(np.log([T / n for n in ns]), np.log(errs), 1)[0])
    n05 = int(round(T / 0.05))
    xn, its = run(jnp.asarray(x0), T / n05, n05)
    err05 = float(np.max(np.abs(np.asarray(xn) - _reference(field, x0, T))))
    return dict(
        method=m.name,
        det=det_err,
        order=p,
        const=err05 / (T / n05) ** m.order,
        newton=float(its) / (n05 * len(x0)),
        seconds=time.perf_counter() - t0,
    )


def main(argv=None) -> int:
    names = list(argv if argv else sys.argv[1:]) or list(FIELDS)
    print("| class | options | field | method | max abs(det−1) | observed order | "
          "error const. (h=0.05) | Newton it./step | s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in names:
        prob, box, T = FIELDS[name]
        field = get(prob).field
        for cls, opts in ROWS:
            if opts.get("variant") == "az" and field.linear_matrix is None:
                continue
            r = row(field, box, T, cls, dict(opts))
            o = ", ".join(f"{k}={v}" for k, v in opts.items()) or "—"
            print(f"| {cls} | {o} | {name} | {r['method']} | {r['det']:.1e} | {r['order']:.3f} | "
                  f"{r['const']:.3g} | {r['newton']:.2f} | {r['seconds']:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Streamlines of a Stokes flow confined in the unit sphere (Bajer–Moffatt type)."""
import matplotlib.pyplot as plt
import numpy as np

import vpforms
from vpforms import problems

flow = problems.get("stokes_sphere", eps=0)  # ε = 0: axisymmetric, ψ = R²(1 − r²) is invariant
chaotic = problems.get("stokes_sphere")      # ε = 1/10 breaks the symmetry
x0 = np.array([[0.3, 0.0, 0.0], [0.5, 0.0, 0.2], [0.7, 0.0, -0.1]])
h, n = 0.05, 2000

fig, axes = plt.subplots(1, 2, figsize=(10, 4.6))
for ax, prob in zip(axes, (flow, chaotic)):
    method = vpforms.compose(vpforms.scheme(prob.field, "SE+SE", recover=False), order=2)
    sol = vpforms.integrate(method, x0, h, n, save_every=1, progress=False)
    r = np.linalg.norm(sol.xs, axis=-1)
    print(f"eps = {prob.params['eps']:g}: max radius {r.max():.6f} (the ball r ≤ 1 is invariant), "
          f"failed: {sol.n_failed}")
    if "psi" in prob.invariants:
        psi = np.asarray(prob.invariant_values(sol.xs.reshape(-1, 3))["psi"]).reshape(r.shape)
        print(f"  invariant psi: max drift over t ≤ {h * n:g} = {np.max(np.abs(psi - psi[:, :1])):.1e}")
    for k in range(len(x0)):
        R = np.hypot(sol.xs[k, :, 0], sol.xs[k, :, 1])
        ax.plot(R, sol.xs[k, :, 2], lw=0.4)
    t = np.linspace(0, np.pi, 200)
    ax.plot(np.sin(t), np.cos(t), "k", lw=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("R = √(x₁² + x₂²)")
    ax.set_ylabel("x₃")
    ax.set_title(f"ε = {prob.params['eps']:g}")
fig.suptitle("Stokes flow in the unit sphere: streamlines in the meridian plane")
plt.show()

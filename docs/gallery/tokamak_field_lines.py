"""Magnetic field lines of a tokamak model: flux surfaces and the (2, 1) island chain."""
import matplotlib.pyplot as plt
import numpy as np

import vpforms
from vpforms import problems
from vpforms.diagnostics import poincare_section

tok = problems.get("tokamak")  # R0 = 1, B0 = 1.8, (m, n) = (2, 1), ε = 0.01
method = vpforms.compose(vpforms.scheme(tok.field, "SE+SE", recover=False), order=2)

# start points on the outer midplane x2 = 0, x3 = 0, from the magnetic axis outwards
R = np.linspace(1.04, 1.32, 12)
x0 = np.stack([R, np.zeros_like(R), np.zeros_like(R)], axis=1)

# puncture plot: crossings of the half-plane x2 = 0 (x1 > 0) going around the torus
sec = poincare_section(method, x0, h=0.1, n_steps=6000, axis=1, value=0.0, direction=1,
                       progress=False)
keep = sec.points[:, 0] > 0
print(f"{np.count_nonzero(keep)} punctures of the plane φ = 0 by {len(x0)} field lines to t = 600")
print(f"punctures per field line: {np.bincount(sec.particle[keep], minlength=len(x0)).tolist()}")

fig, ax = plt.subplots(figsize=(5.5, 5.5))
ax.scatter(sec.points[keep, 0], sec.points[keep, 2], s=0.8, c=sec.particle[keep] % 10, cmap="tab10")
ax.set_xlabel("R = x₁ (on φ = 0)")
ax.set_ylabel("x₃")
ax.set_aspect("equal")
ax.set_title("Tokamak field lines: Poincaré section at φ = 0\n(2,1) islands between flux surfaces")
plt.show()

"""Field lines of a coil stellarator, traced exactly volume preserving: φ = 0 Poincaré section."""
import math

import matplotlib.pyplot as plt
import numpy as np

import vpforms
from vpforms import problems
from vpforms.diagnostics import log_det, poincare_section
from vpforms.toroidal import to_toroidal

# l = 2, m = 5 stellarator coils → cubic spline of A on a 40×32×40 (R, φ, Z) grid → B = ∇×A,
# traced in the coordinates (u = R²/2, φ, Z) of unit Jacobian
prob = problems.get("coil_stellarator")
print(f"field: {prob.field.potential_methods['se']}")
print(f"spline error max|B_spline − B_coils| / max|B_coils| = {prob.params['spline_error']:.1e}")

method = vpforms.compose(vpforms.scheme(prob.field, "SE+SE", recover=False), order=2)
R_axis = 0.983112  # the magnetic axis at φ = 0 (vpforms.coils.l2_stellarator)
r = np.array([0.01, 0.03, 0.05, 0.07, 0.09, 0.11, 0.13])
x0 = np.asarray(to_toroidal(np.c_[R_axis + r, 0 * r, 0 * r]))

period = 2 * math.pi / 5  # one field period in φ = x₂
sec = poincare_section(method, x0, h=0.05, n_steps=3000, axis=1, value=0.0, period=period,
                       progress=False)
turns = (3000 * 0.05) / (2 * math.pi)
print(f"lines that stopped (left the grid or failed): {int(np.count_nonzero(sec.status))}")
print(f"{sec.points.shape[0]} crossings of φ = 0 (mod 2π/5) by {len(x0)} lines, ≈ {turns:.0f} toroidal turns each")
ld = log_det(method, x0[:4], 0.05, 100)
print(f"max |log det DΨ| over 100 steps of 4 lines: {ld.max_abs:.1e}")

R, Z = np.sqrt(2 * sec.points[:, 0]), sec.points[:, 2]
fig, ax = plt.subplots(figsize=(5.5, 5))
ax.scatter(R, Z, c=sec.particle, s=1.5, cmap="viridis")
ax.plot([R_axis], [0.0], "r+", ms=10, label="magnetic axis")
ax.set_xlabel("R (m)")
ax.set_ylabel("Z (m)")
ax.set_aspect("equal")
ax.set_title("l = 2 stellarator coils, SE+SE order 2, h = 0.05")
ax.legend(loc="upper right")

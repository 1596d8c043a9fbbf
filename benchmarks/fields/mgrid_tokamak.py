"""Write an mgrid netCDF file of the axisymmetric tokamak of the problem library (ε = 0), for
`vpforms fieldlines --mgrid` by hand (no test runs it: the axis's compile on a spline field takes
minutes, see notes/closing-note-22-24.md).

Covariant A = (0, u²/2 − R₀²u/2 + uZ², −B₀u/R₀) in (u = R²/2, φ, Z), whose curl is the problem's
(−2uZ, B₀/R₀, u − R₀²/2 + Z²): the axis is (R₀, 0) and its ι is R₀²/B₀.

    python benchmarks/fields/mgrid_tokamak.py /tmp/mg17.nc 17
    vpforms fieldlines --mgrid /tmp/mg17.nc --axis-guess 1.03,0.02 --transits 4 --radii 0.05,0.1 --no-recover
"""
import numpy as np, sys
from vpforms.grids import MGrid, write_mgrid
n=int(sys.argv[2])
R0, B0 = 1.0, 1.8
R, Z = np.linspace(0.6, 1.4, n), np.linspace(-0.4, 0.4, n)
phi = np.linspace(0, 2 * np.pi, 4, endpoint=False)
P, ZZ, RR = np.meshgrid(phi, Z, R, indexing="ij")
u = RR * RR / 2
a_phi = u * u / 2 - R0 * R0 * u / 2 + u * ZZ * ZZ
A = np.stack([0 * u, a_phi / RR, -B0 * u / R0])
B = np.stack([-2 * u * ZZ / RR, RR * B0 / R0, u - R0 * R0 / 2 + ZZ * ZZ])
write_mgrid(MGrid(rmin=R[0], rmax=R[-1], zmin=Z[0], zmax=Z[-1], nfp=1, B=B, A=A), sys.argv[1])

"""Method → C source for the native backend, in three steps (one module each), and the spline data:

* :mod:`.potentials` — what a class supplies: its generating map at step h as SymPy expressions
  (φ, Φ in the generic order of eq:volpot, the case, the sign, the Newton controls), or the reason
  it has none;
* :mod:`.plan` — one step of a method as a list of stages ``(stage, coefficient of h)``:
  relabelling (prop:trivperm) relabels a stage's case, adjunction (prop:switchperm) inverts the
  stages at −h in reverse order, compositions concatenate them;
* :mod:`.vecpot` — fields of a vector potential of data: :mod:`.splines` (splines of A,
  :mod:`vpforms.grids`) and :mod:`.coils` (filament coils, :mod:`vpforms.coils`) as SymPy atoms of
  their evaluations, and their C; the run-time data array they read (:mod:`.data`: a new grid or
  coil set of the same structure reuses the compiled kernel);
* :mod:`.emit` — C from the stages: the generic map's two scalar Newton solves per lane (closed
  form where the equation is affine in its unknown), RK4, and the block/SIMD/OpenMP kernel.
"""

from .emit import BLOCK, CDEF, kernel_parts, kernel_source
from .plan import unsupported_reason

__all__ = ["BLOCK", "CDEF", "kernel_parts", "kernel_source", "unsupported_reason"]

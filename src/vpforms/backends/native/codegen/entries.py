"""The entries of a kernel — ``vp_run``, ``vp_sections`` with ``vp_locate`` (:mod:`.sections`),
``vp_wall`` (:mod:`.walls`) — and which of them one compiled object holds.

Every entry runs the same step (``vp_step_fast``, ``vp_step_exact``) in the lane code of
:mod:`.lanes`. A kernel with a vectorised pass inlines its stages into each entry's lane loop, so
it holds only the entry asked for (the others would multiply the compiler's work on a closed
form). A kernel without one (splines, coils, quadratures) calls its stages, compiled once: there
the stages are nearly all of the compiler's work, and one object holds every entry the method
allows, so that a study's axis, section, ι and wall trace compile once, not once each (issue #41:
8.6 s of gcc for all three entries of an order-2 spline kernel against 7–8 s for each alone).
:func:`entries_cdef` gives the declarations of the entries a source defines.
"""

from __future__ import annotations

from .sections import SECTIONS_CDEF
from .walls import WALL_CDEF

__all__ = ["ENTRIES", "ONE_OBJECT", "RUN_CDEF", "entries_cdef", "run_entry"]

#: whether a kernel without a vectorised pass holds every entry (False: only the one asked for, as
#: before issue #41; benchmarks/native/bench_compile.py compares the two)
ONE_OBJECT = True

RUN_CDEF = ("void vp_run(int64_t N, double *x, int32_t *status, int64_t *n, int64_t n_target, double h, "
            "int64_t save_every, int64_t n_total, double *xs, int64_t n_saves, const double *fd);")

#: entry → (the C name that marks its definition in a source, its cffi declarations)
ENTRIES = {
    "run": ("\nvoid vp_run(", RUN_CDEF),
    "sections": ("\nint64_t vp_sections(", SECTIONS_CDEF),
    "wall": ("\nvoid vp_wall(", WALL_CDEF),
}


def entries_cdef(source: str) -> str:
    """The cffi declarations of the entries ``source`` defines (in the order of :data:`ENTRIES`)."""
    out = [cdef for mark, cdef in ENTRIES.values() if mark in source]
    if not out:
        raise ValueError("the source defines no kernel entry (vp_run, vp_sections, vp_wall)")
    return "\n".join(out)


def run_entry(lanes: dict[str, str]) -> str:
    """The C of ``vp_run`` around the shared lane code ``lanes`` (load, step, store): steps to
    ``n_target`` and, with ``save_every`` > 0, the saved states (the comment in the C)."""
    return f"""/* Saves (save_every > 0): xs has shape (N, n_saves + 1, 3), slot 0 the initial state (not
   written here), slot j the state after step j·save_every and slot n_saves after n_total (the last
   step, saved even off the stride). A live lane at a saved step writes its slot; a lane that stops
   (its status set, now or before this call) fills its later slots with its frozen state, as the
   JAX loop saves a frozen particle. So one call runs a whole segment, however many saves it holds. */
static inline int64_t vp_slot(int64_t c, int64_t se, int64_t n_total, int64_t n_saves) {{
    if (c % se == 0) return c / se;
    return c == n_total ? n_saves : -1;
}}
void vp_run(int64_t N, double *x, int32_t *status, int64_t *n, int64_t n_target, double h,
            int64_t save_every, int64_t n_total, double *xs, int64_t n_saves, const double *fd) {{
    int64_t Bn = vp_block(N), nb = (N + Bn - 1) / Bn;
    #pragma omp parallel for schedule(dynamic, 1) if (nb > 1)  /* one block: no thread team to wake and wait for */
    for (int64_t b = 0; b < nb; b++) {{
{lanes['load']}        for (int64_t k = nmin; k < n_target; k++) {{
{lanes['step']}            if (save_every > 0) for (int i = 0; i < m; i++) {{
                /* a live lane at a saved step writes its state (again, harmlessly, while it waits) */
                if (st[i] != 0) continue;
                int64_t j = vp_slot(nn[i], save_every, n_total, n_saves);
                if (j > 0) {{
                    double *o = xs + 3 * ((lo + i) * (n_saves + 1) + j);
                    o[0] = a1[i]; o[1] = a2[i]; o[2] = a3[i];
                }}
            }}
        }}
        if (save_every > 0) for (int i = 0; i < m; i++) {{  /* frozen lanes: their later slots */
            if (st[i] == 0) continue;
            for (int64_t j = nn[i] / save_every + 1; j <= n_saves; j++) {{
                double *o = xs + 3 * ((lo + i) * (n_saves + 1) + j);
                o[0] = a1[i]; o[1] = a2[i]; o[2] = a3[i];
            }}
        }}
{lanes['store']}    }}
}}
"""

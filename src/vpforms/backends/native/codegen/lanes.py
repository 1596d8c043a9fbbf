"""The lane code every kernel entry shares: ``vp_run`` (:mod:`.emit`) and ``vp_sections``
(:mod:`.sections`) load a block of ``B`` particles into L1 as structure-of-arrays, step all its
live lanes — the vectorised pass ``vp_step_fast``, then ``vp_step_exact`` for the lanes it did not
decide — and store them back. ``fd`` is the field's run-time data (:mod:`.splines`; NULL without)."""

from __future__ import annotations

from ...._errors import RESULTS

__all__ = ["lane_code"]


def lane_code() -> dict[str, str]:
    """The lane code every kernel entry shares (``vp_run``, and ``vp_sections`` of :mod:`.sections`):
    a block's lanes loaded into L1 (``load``), one step of all its live lanes (``step``: a lane is
    live while its status is 0 and n < n_target), stored back (``store``)."""
    nf = RESULTS.nonfinite
    return {
        "load": """        int64_t lo = b * Bn;
        int m = (int)(N - lo < Bn ? N - lo : Bn);
        double a1[B], a2[B], a3[B];
        int32_t st[B];
        int64_t nn[B];
        int redo[B];
        int64_t nmin = n_target;
        /* the lanes stepped: m rounded up to 8 (a multiple of every SIMD width), so a short block
           (a few field lines) costs its own lanes, not B; the padding lanes are inactive */
        int mv = (m + 7) & ~7;
        for (int i = 0; i < B; i++) {
            if (i < m) {
                a1[i] = x[3 * (lo + i)]; a2[i] = x[3 * (lo + i) + 1]; a3[i] = x[3 * (lo + i) + 2];
                st[i] = status[lo + i]; nn[i] = n[lo + i];
                if (st[i] == 0 && nn[i] < nmin) nmin = nn[i];
            } else {
                a1[i] = a2[i] = a3[i] = 0.0; st[i] = 1; nn[i] = n_target;  /* padding lane: inactive */
            }
        }
""",
        "step": f"""            #pragma omp simd
            for (int i = 0; i < mv; i++) {{  /* vectorised: the lanes the fast pass decides */
                double X1, X2, X3;
                double good = vp_step_fast(a1[i], a2[i], a3[i], h, &X1, &X2, &X3, fd);
                int act = (st[i] == 0) & (nn[i] < n_target);
                int ok = act & (good > 0.5);
                a1[i] = ok ? X1 : a1[i]; a2[i] = ok ? X2 : a2[i]; a3[i] = ok ? X3 : a3[i];
                nn[i] += ok;
                redo[i] = act & !(good > 0.5);
            }}
            int any = 0;
            for (int i = 0; i < mv; i++) any |= redo[i];
            /* the others, exactly (status, frozen on failure); the guard matters: gcc vectorises
               this loop with masks, i.e. it costs a full step of the block when entered */
            if (any) for (int i = 0; i < mv; i++) {{
                if (!redo[i]) continue;
                double X1, X2, X3;
                int code = vp_step_exact(a1[i], a2[i], a3[i], h, &X1, &X2, &X3, fd);
                int inok = _VP_FINITE(a1[i], a2[i], a3[i]), fin = _VP_FINITE(X1, X2, X3);
                code = !inok ? {nf} : code ? code : fin ? 0 : {nf};
                if (code == 0) {{ a1[i] = X1; a2[i] = X2; a3[i] = X3; nn[i] += 1; }}
                else st[i] = code;
            }}
""",
        "store": """        for (int i = 0; i < m; i++) {
            x[3 * (lo + i)] = a1[i]; x[3 * (lo + i) + 1] = a2[i]; x[3 * (lo + i) + 2] = a3[i];
            status[lo + i] = st[i]; n[lo + i] = nn[i];
        }
""",
    }

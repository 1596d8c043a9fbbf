"""Shared test helpers, and the two test tiers (docs/testing.md).

* Fast tier: ``python -m pytest`` (the README's command; pyproject's addopts select
  ``-m "not (slow or fuzz or verification)"``): ≤ 5 minutes on 2 cores, exercises every module
  (but the script ``vpforms._methods.report``, which no test runs).
* Verification tier: ``python -m pytest -m "slow or fuzz or verification"`` (a later ``-m``
  replaces the one in addopts): long runs, the full case matrices, fuzzing, the docs site build.

A test goes to the verification tier when it is marked ``slow`` or ``fuzz`` in its file, or when
its node id matches a pattern of ``VERIFICATION`` below (this hook adds the ``verification``
marker) and none of ``KEEP_FAST``.  Everything else is in the fast tier: a new test is fast
unless it is marked, or listed here.
"""

import codecs
import os
import re
from pathlib import Path

import platformdirs
import pytest

import vpforms  # noqa: F401  (float64 on)

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"

# ------------------------------------------------------------- one compilation per computation
# XLA compilation is about half of the suite's time, and the same computations are compiled by
# both xdist workers, again after a cache clear (below), again by the verification tier after
# the fast tier, and again by every clone of the repository.  JAX's persistent compilation cache
# shares them on disk (same executables, so the same numbers; its key is the computation and the
# JAX/XLA versions, not the source path), in the user's cache directory beside the native
# backend's (platformdirs.user_cache_dir("vpforms")/jax-tests; delete it any time).  Unbounded on
# purpose: JAX's size bound (jax_compilation_cache_max_size) keeps an access-time file per entry,
# and one entry left without it (a process killed while writing: the Dask tests kill workers)
# makes every later write fail, so the cache silently stops growing.  Subprocesses (the CLI tests)
# inherit it through the environment.  A user's own JAX_COMPILATION_CACHE_DIR wins;
# VPFORMS_TEST_JAX_CACHE=0 turns it off (a cold run), also the `vpforms` command's own cache
# (vpforms._cache.enable_jax_cache) in the CLI tests' subprocesses.
if os.environ.get("VPFORMS_TEST_JAX_CACHE", "1") == "0":
    os.environ["VPFORMS_JAX_CACHE"] = "0"
else:
    os.environ.setdefault("JAX_COMPILATION_CACHE_DIR",
                          str(Path(platformdirs.user_cache_dir("vpforms")) / "jax-tests"))
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.5")
    import jax

    jax.config.update("jax_compilation_cache_dir", os.environ["JAX_COMPILATION_CACHE_DIR"])
    jax.config.update("jax_persistent_cache_min_compile_time_secs",
                      float(os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"]))

# --------------------------------------------------------------------------------- the two tiers
# Patterns match the whole node id as pytest prints it, with σ/Σ written as such; "*" is the only
# wildcard ("[" and "]" are literal).  Times: one run of the whole suite on 2 shared cores.
VERIFICATION = [
    # -- the 36-case matrices (one test per case; KEEP_FAST keeps the σ = (2,3,1) row fast)
    "tests/test_native.py::test_every_generated_case_equals_jax[*",  # 36 cases × 2 problems, ~350 s
    "tests/test_native.py::test_every_dldl_case_with_midpoint_stages_equals_jax[*",  # 6, ~20 s
    "tests/test_sese_fast_adjoint.py::test_fast_adjoint_is_generic_adjoint[*",  # 12, ~60 s
    "tests/test_map.py::test_all_36_cases_volume_inverse_residual",  # hypothesis over 36 cases, ~12 s
    "tests/test_spec.py::test_all_36_cases_roundtrip",  # ~20 s
    # -- compositions of order 4 and 6 (compile-heavy), the DL classes composed
    "tests/test_native.py::test_native_equals_jax_after_100_steps[order 4*",  # Suzuki, Blanes–Moan: ~30 s
    "tests/test_native.py::test_native_equals_jax_after_100_steps[adjoint-*",
    "tests/test_native.py::test_native_step_preserves_volume[order 4 BM]",  # ~18 s
    "tests/test_native.py::test_compositions_of_relabelled_cases_equal_jax[*",  # 16, ~60 s
    "tests/test_native.py::test_dl_lanes_the_vectorised_pass_leaves_undecided_are_redone_exactly",  # tokamak, ~9 s
    "tests/test_methods_compose.py::test_adjoint_is_the_inverse_at_minus_h",  # ~160 s
    "tests/test_methods_compose.py::test_compositions_are_symmetric_and_checked",  # ~60 s
    "tests/test_methods_compose.py::test_higher_order_compositions[*-blanes_moan-*",
    "tests/test_methods_compose.py::test_higher_order_compositions[*-kahan_li-*",
    "tests/test_methods_compose.py::test_higher_order_compositions[*-yoshida-*",
    "tests/test_methods_compose.py::test_adjoint_composition_has_order_two[SE+DL-*",
    "tests/test_methods_compose.py::test_adjoint_composition_has_order_two[DL+DL-*",
    "tests/test_spec.py::test_compositions_adjoint_rk4",  # ~40 s
    "tests/test_spec.py::test_every_class[SE+DL]",
    "tests/test_spec.py::test_every_class[DL+DL]",
    "tests/test_spec.py::test_every_problem[tokamak]",  # ~10 s
    "tests/test_spec.py::test_hypothesis_abc_parameters_and_cases",  # hypothesis over cases, ~15 s
    "tests/test_cli.py::test_composition_chooses_the_order_4_coefficients",  # two order-4 runs, ~15 s
    # -- recipes re-checked at many step sizes / against SymPy (each 15–35 s)
    "tests/test_methods_recipes.py::test_s1_s2_linear_step_is_a_unimodular_matrix",
    "tests/test_methods_recipes.py::test_dl_potentials_are_the_symbolic_recipes[0.0]",
    "tests/test_methods_recipes.py::test_dl_theta0_same_map_theta_half_differs",
    "tests/test_methods_recipes.py::test_printed_variants_volume_preserving_but_inconsistent",
    "tests/test_methods_recipes.py::test_correction_map_closed_form_equals_quadrature",
    "tests/test_symbolic_consistency.py::test_random_integer_matrices",  # ~9 s
    # -- API and diagnostics paths that compile the recovering alternatives (~60 s)
    "tests/test_methods_api.py::test_shapes_jit_vmap_status_iterations",
    "tests/test_methods_longrun.py::test_dl_engine_reports_the_fold_the_stage_form_crosses",  # ~17 s
    "tests/test_diffrax.py::test_failure_maps_to_results_like_integrate[twist]",  # ~15 s
    "tests/test_diffrax.py::test_recovering_method_same_numbers_as_integrate",
    "tests/test_diffrax.py::test_generic_engine_methods_vmapped[*",  # DL engines under vmap, ~15 s each
    # -- Dask clusters, benchmark scripts
    "tests/test_distributed.py::test_dask_cluster_bit_identical",  # a LocalCluster, ~26 s
    "tests/test_distributed.py::test_checkpoint_resume_bit_identical",  # DL+DL on 10⁴ particles, ~30 s
    "tests/test_benchmarks_smoke.py::*",  # the benchmark scripts in --smoke mode, ~75 s
    "tests/test_fields.py::test_from_callable_divergence_at_random_points",  # hypothesis, ~10 s
    # -- trimmed from the fast tier (it had reached 296 s of its 300 s in CI twice): what stays fast is named
    "tests/test_native_splines.py::test_a_line_leaving_the_grid_is_stopped_not_recovered[*",  # ~15–19 s each;
    #   test_a_line_leaving_the_grid_stops_with_left_domain_natively stays fast
    "tests/test_native_walls.py::test_native_jax_and_chunks_stop_the_same_lines",  # ~10 s; the walls' other tests kept
    "tests/test_native.py::test_quadrature_correction_runs_natively_and_equals_jax[S1]",  # ~9 s;
    #   test_native_quadrature.py::test_quadrature_field_runs_natively_and_equals_jax stays fast
    "tests/test_deterministic_preparation.py::test_corpus_preparation_does_not_depend_on_the_clock[12]",  # ~11 s;
    #   the module's other clock tests stay fast
    "tests/test_recover.py::test_a_recovering_method_pickles_before_and_after_its_alternatives_are_built",  # ~8 s
    "tests/test_right_steps.py::test_recovery_never_takes_a_refused_case",  # ~7 s
    "tests/test_stages.py::test_relabelling_relabels_each_stage[pi0]",  # ~6 s; [pi1] kept
    "tests/test_stages.py::test_relabelling_relabels_each_stage[pi2]",  # ~5 s
    "tests/test_native.py::test_quadrature_correction_runs_natively_and_equals_jax[S2]",  # ~6 s
    # -- φ-time on a domain (issue #38): the steps on the K spline and on the exact field, ~25 s; the
    #   module's construction, round-trip, convergence and bad-input tests stay fast
    "tests/test_phitime_domain.py::test_phi_exact_steps_preserve_volume_and_follow_the_exact_field",
    "tests/test_phitime_domain.py::test_w7x_with_phi_as_the_time_crosses_where_time_stepping_does",  # W7-X grids
    "tests/test_quasi_interpolation.py::test_w7x_quintic_of_a_on_the_whole_box_is_accurate_inside_the_plasma",
    "tests/test_quasi_interpolation.py::test_w7x_quintic_of_a_on_a_domain_is_the_whole_boxs_there_and_nan_far_from_it",  # ~12 s
]

# Representatives of the matrices above that stay in the fast tier: the σ = (2,3,1) row of the
# 36-case table (one relabelled case of every class; SE+DL has two, one is kept).
KEEP_FAST = [
    "tests/test_native.py::test_every_generated_case_equals_jax[SE+SE-abc-(σ=(2,3,1), *",
    "tests/test_native.py::test_every_generated_case_equals_jax[S1-rotation-(σ=(2,3,1), *",
    "tests/test_native.py::test_every_generated_case_equals_jax[S2-lotka_volterra-(σ=(2,3,1), *",
    "tests/test_native.py::test_every_generated_case_equals_jax[DL+DL-abc-(σ=(2,3,1), *",
    "tests/test_native.py::test_every_generated_case_equals_jax[SE+DL-abc-(σ=(2,3,1), Σ=(3,1,2))]",
    "tests/test_native.py::test_every_dldl_case_with_midpoint_stages_equals_jax[(σ=(2,3,1), *",
    "tests/test_sese_fast_adjoint.py::test_fast_adjoint_is_generic_adjoint[abc-(σ=(2,3,1), *",
    # one composition of each kind of stage, natively: closed form, linear recipes, DL stages
    "tests/test_native.py::test_compositions_of_relabelled_cases_equal_jax[abc-SE+SE-4]",
    "tests/test_native.py::test_compositions_of_relabelled_cases_equal_jax[abc-S1-2]",
    "tests/test_native.py::test_compositions_of_relabelled_cases_equal_jax[lotka_volterra-S2-2]",
    "tests/test_native.py::test_compositions_of_relabelled_cases_equal_jax[abc-SE+DL-2]",
]

# Tests of the documentation site (mkdocs build --strict): verification tier, and marked `docs`
# so that CI, which runs `mkdocs build --strict` itself, can leave them out (.ci/run).
DOCS = ["tests/test_docs.py::*"]


def _regex(patterns):
    return re.compile("|".join("(?:" + ".*".join(map(re.escape, p.split("*"))) + ")" for p in patterns))


_VERIFICATION, _KEEP_FAST, _DOCS = _regex(VERIFICATION), _regex(KEEP_FAST), _regex(DOCS)


def _readable(nodeid: str) -> str:
    """The node id with pytest's escapes of non-ASCII ids undone (\\u03c3 → σ)."""
    try:
        return codecs.decode(nodeid, "unicode_escape") if "\\" in nodeid else nodeid
    except UnicodeDecodeError:
        return nodeid


@pytest.hookimpl(tryfirst=True)  # before -m deselects (and before xdist reads the marks)
def pytest_collection_modifyitems(config, items):
    for item in items:
        nodeid = _readable(item.nodeid)
        if _DOCS.fullmatch(nodeid):
            item.add_marker(pytest.mark.docs)
            item.add_marker(pytest.mark.verification)
        elif _VERIFICATION.fullmatch(nodeid) and not _KEEP_FAST.fullmatch(nodeid):
            item.add_marker(pytest.mark.verification)


@pytest.fixture(scope="module")
def isolated_native_cache(tmp_path_factory):
    """A fresh native kernel cache (VPFORMS_NATIVE_CACHE) for one test module, restored after."""

    d = tmp_path_factory.mktemp("native_cache")
    old = os.environ.get("VPFORMS_NATIVE_CACHE")
    os.environ["VPFORMS_NATIVE_CACHE"] = str(d)
    yield d
    if old is None:
        os.environ.pop("VPFORMS_NATIVE_CACHE", None)
    else:
        os.environ["VPFORMS_NATIVE_CACHE"] = old


# ------------------------------------------------------------------------- compiled-code budget
# An xdist worker runs hundreds of tests in one process and every jit compile stays cached: each
# XLA executable maps ~3 memory regions, and the verification tier compiled enough to approach
# Linux's vm.max_map_count (65530) and several GB per worker; a worker then died inside an XLA
# compile (abort/segfault, CI of stop 27). Past either budget the caches are dropped between tests
# (the next use recompiles): numbers are unchanged, only compile time is paid again.
MAX_MAPS = 24_000
MAX_RSS_BYTES = 5 * 2**30


def _maps_and_rss() -> tuple[int, int]:
    """(memory mappings, resident bytes) of this process; (0, 0) where /proc is absent."""
    try:
        with open("/proc/self/maps", "rb") as fh:
            maps = fh.read().count(b"\n")
        with open("/proc/self/statm", "rb") as fh:
            rss = int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except OSError:
        return 0, 0
    return maps, rss


_FLOOR = {"maps": MAX_MAPS, "rss": MAX_RSS_BYTES}  # raised to what a clear leaves, plus a margin


@pytest.fixture(autouse=True)
def _bounded_compiled_code():
    yield
    maps, rss = _maps_and_rss()
    if maps > _FLOOR["maps"] or rss > _FLOOR["rss"]:
        import gc

        import jax

        jax.clear_caches()
        gc.collect()
        maps, rss = _maps_and_rss()  # what is left (malloc may keep freed pages): clear again only
        _FLOOR["maps"] = max(MAX_MAPS, maps + MAX_MAPS // 2)  # after as much new growth
        _FLOOR["rss"] = max(MAX_RSS_BYTES, rss + MAX_RSS_BYTES // 2)

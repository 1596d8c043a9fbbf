"""Store-backed, resumable, Dask-distributed runs (issue #10): bit-identical to one integrate;
verified stores that redo what is damaged and run the chosen backend (issue #22)."""

import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import vpforms as V
from vpforms import distributed as D
from vpforms import io as VIO
from vpforms import problems as P

pytest.importorskip("dask.distributed")
xr = pytest.importorskip("xarray")

H, N_STEPS, SAVE = 0.05, 6, 2
_NATIVE, _WHY = V.native.available()
needs_native = pytest.mark.skipif(not _NATIVE, reason=f"native backend unavailable: {_WHY}")


@pytest.fixture(scope="module")
def prob():
    return P.get("abc")


@pytest.fixture(scope="module")
def dldl(prob):
    # the engine form: a recovering method on the JAX backend (the default stage form runs natively)
    return V.scheme(prob.field, "DL+DL", fast=False)


@pytest.fixture(scope="module")
def order4(prob):
    return V.compose(V.scheme(prob.field, "SE+SE"), 4)


@pytest.fixture(scope="module")
def x0(prob):
    return prob.initial_conditions(10_000, seed=3)


@pytest.fixture(scope="module")
def ref_dldl(dldl, x0):
    return V.integrate(dldl, x0, H, N_STEPS, save_every=SAVE, progress=False)


@pytest.fixture(scope="module")
def ref_order4(order4, x0):
    return V.integrate(order4, x0, H, N_STEPS, save_every=SAVE, progress=False)


@pytest.fixture(scope="module")
def cluster_client():
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    yield client
    client.close()
    cluster.close()


@pytest.fixture(scope="module")
def sese(prob):
    return V.scheme(prob.field, "SE+SE")  # generated natively: a chunk takes milliseconds


def _files(store):
    """Every file of a store (data, metadata, done markers) by relative path: the bytes."""
    out = {}
    for root, _dirs, files in os.walk(store):
        for f in files:
            path = os.path.join(root, f)
            with open(path, "rb") as fh:
                out[os.path.relpath(path, store)] = fh.read()
    return out


def _same_store(store, ref_store):
    """The store is bitwise the uninterrupted run's: the same files with the same bytes."""
    got, want = _files(store), _files(ref_store)
    assert sorted(got) == sorted(want)
    assert [k for k in want if got[k] != want[k]] == []


def _same(ds, ref):
    assert np.array_equal(ds.x.values, ref.xs)
    assert np.array_equal(ds.status.values, ref.status)
    assert np.array_equal(ds.failed_step.values, ref.failed_step)
    assert np.array_equal(ds.time.values, ref.ts)
    assert np.array_equal(ds.recovered.values, ref.recovered)  # issue #12: the same recovered steps


@pytest.mark.slow
def test_recovered_steps_survive_chunks_checkpoints_and_workers(cluster_client, dldl, x0, tmp_path):
    """At h = 0.5 bare DL+DL steps fail on ABC and are recovered (issue #12): a chunked,
    checkpointed store run, in process and on the cluster, has the same states, statuses,
    per-particle recovered counts and recovered steps by alternative as one integrate."""
    pts, h = x0[:400], 0.5
    ref = V.integrate(dldl, pts, h, 6, save_every=2, progress=False, backend="jax")
    assert ref.recovered.sum() > 0, "no step was recovered: the test would prove nothing"
    for store, kw in ((tmp_path / "r1.zarr", {"checkpoint_every": 2}),
                      (tmp_path / "r2.zarr", {"checkpoint_every": 4, "client": cluster_client})):
        ds = D.run(dldl, pts, h, 6, store=store, save_every=2, chunk_particles=150, progress=False,
                   backend="jax", **kw)
        _same(ds, ref)
        # … and how they were recovered (issue #22), as Solution.stats["recovered_how"], in the store
        assert json.loads(VIO.store_attrs(store)["recovered_how"]) == ref.stats["recovered_how"]


def test_in_process_with_checkpoints_is_bit_identical(order4, x0, ref_order4, tmp_path):
    ds = D.run(order4, x0, H, N_STEPS, store=tmp_path / "a.zarr", save_every=SAVE,
               chunk_particles=4000, checkpoint_every=3, progress=False)
    _same(ds, ref_order4)
    assert json.loads(ds.attrs["spec"]) == order4.spec() and ds.attrs["version"] == V.__version__
    ds2 = xr.open_zarr(tmp_path / "a.zarr")  # a plain xarray reader (consolidated metadata: no warning)
    assert np.array_equal(ds2.x.values, ref_order4.xs)


def test_dask_cluster_bit_identical(cluster_client, dldl, order4, x0, ref_dldl, ref_order4, tmp_path):
    """On the cluster each chunk runs the backend chosen for the run (issue #22: native for the
    order-4 SE+SE composition, every worker its own compiled kernel; JAX for DL+DL), and the store
    is bitwise the single-process store."""
    ds = D.run(dldl, x0, H, N_STEPS, store=tmp_path / "d.zarr", save_every=SAVE,
               chunk_particles=2500, client=cluster_client, progress=False)
    _same(ds, ref_dldl)
    assert ds.attrs["backend"] == "jax"
    ds = D.run(order4, x0, H, N_STEPS, store=tmp_path / "o.zarr", save_every=SAVE,
               chunk_particles=5000, client=cluster_client, progress=False)
    _same(ds, ref_order4)
    assert ds.attrs["backend"] == ("native" if _NATIVE else "jax")
    D.run(order4, x0, H, N_STEPS, store=tmp_path / "o1.zarr", save_every=SAVE, chunk_particles=5000,
          progress=False)
    _same_store(tmp_path / "o.zarr", tmp_path / "o1.zarr")


@pytest.mark.slow
def test_killed_worker_loses_nothing(cluster_client, dldl, x0, ref_dldl, tmp_path):
    store = tmp_path / "k.zarr"
    out = {}

    def go():
        out["ds"] = D.run(dldl, x0, H, N_STEPS, store=store, save_every=SAVE, chunk_particles=1000,
                          client=cluster_client, progress=False)

    th = threading.Thread(target=go)
    th.start()
    pids = cluster_client.run(os.getpid)
    done = os.path.join(store, ".vpforms", "done")
    t_end = time.time() + 120
    while time.time() < t_end and not (os.path.isdir(done) and len(os.listdir(done)) >= 2):
        time.sleep(0.05)
    victim = sorted(pids.values())[0]
    os.kill(victim, signal.SIGKILL)  # one worker process dies mid-run
    th.join(timeout=300)
    assert not th.is_alive()
    assert len(os.listdir(done)) == 10  # every chunk done exactly once (a marker per chunk)
    _same(out["ds"], ref_dldl)
    # the chunk the dead worker was running is redone from the start, and the run says so; a chunk
    # it had finished (marker written) but not yet reported is found done by the retry, and said so
    report = out["ds"].attrs["chunks_report"]
    m = re.fullmatch(r"(\d+) run(?:; (\d+) redone: an earlier attempt did not finish \(chunk \d from the start\))?"
                     r"(?:; (\d+) finished by an earlier attempt that did not report \(chunk \d; kept after "
                     r"verification\))?", report)
    assert m, report
    ran, restarted, finished = (int(g or 0) for g in m.groups())
    assert ran + restarted + finished == 10 and restarted + finished >= 1, report
    D.run(dldl, x0, H, N_STEPS, store=tmp_path / "one.zarr", save_every=SAVE, chunk_particles=1000,
          progress=False)
    _same_store(store, tmp_path / "one.zarr")  # bitwise the uninterrupted single-process run
    cluster_client.wait_for_workers(2, timeout=120)  # the nanny restarts it for later tests


def test_the_report_accounts_for_every_chunk():
    """A chunk whose worker died after its done marker but before its result came back is found
    done by the retry (``skipped``): the report counts it, so the parts always add up to the run."""
    results = [{"chunk": c, "skipped": False, "restarted": c == 2, "from_step": 0} for c in range(10) if c != 7]
    results.append({"chunk": 7, "skipped": True, "wall_s": 0.0})
    assert D._report(0, {}, results) == (
        "8 run; 1 redone: an earlier attempt did not finish (chunk 2 from the start); "
        "1 finished by an earlier attempt that did not report (chunk 7; kept after verification)")
    assert D._report(0, {}, results[:9]) == "8 run; 1 redone: an earlier attempt did not finish (chunk 2 from the start)"


def test_checkpoint_resume_bit_identical(dldl, x0, ref_dldl, tmp_path, monkeypatch):
    store = tmp_path / "c.zarr"
    from vpforms import _integrate

    real, calls = _integrate.integrate, []

    def flaky(*a, **k):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt("simulated crash after a checkpoint")
        return real(*a, **k)

    monkeypatch.setattr(_integrate, "integrate", flaky)
    with pytest.raises(KeyboardInterrupt):
        D.run(dldl, x0, H, N_STEPS, store=store, save_every=SAVE, chunk_particles=5000,
              checkpoint_every=2, progress=False)
    assert os.path.exists(VIO.ckpt_path(store, 0)) and not VIO.is_done(store, 0)
    monkeypatch.setattr(_integrate, "integrate", real)
    ds = D.run(dldl, x0, H, N_STEPS, store=store, save_every=SAVE, chunk_particles=5000,
               checkpoint_every=2, progress=False)
    _same(ds, ref_dldl)


_CHILD = """
import sys, numpy as np, vpforms as V
from vpforms import problems as P, distributed as D
prob = P.get("abc")
x0 = prob.initial_conditions(10_000, seed=3)
D.run(V.scheme(prob.field, "DL+DL", fast=False), x0, {H}, {N}, store=sys.argv[1], save_every={S},
      chunk_particles=1000, checkpoint_every=2, progress=False)
"""


@pytest.mark.slow
def test_killed_client_then_resume(dldl, x0, ref_dldl, tmp_path):
    store = str(tmp_path / "r.zarr")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    child = subprocess.Popen([sys.executable, "-c", _CHILD.format(H=H, N=N_STEPS, S=SAVE), store], env=env)
    done = os.path.join(store, ".vpforms", "done")

    def n_marked():  # done markers only: a kill inside mark_done leaves its temporary file (".c.pid.tmp")
        return sum(VIO.is_done(store, c) for c in range(10))

    def running():  # ≥ 3 chunks done and one begun: killed between two chunks, nothing would be redone
        return (os.path.isdir(done) and n_marked() >= 3
                and any(os.path.exists(VIO.started_path(store, c)) and not VIO.is_done(store, c) for c in range(10)))

    t_end = time.time() + 180
    while time.time() < t_end and not running():
        time.sleep(0.01)
    child.kill()  # the client dies mid-run
    child.wait()
    n_done = n_marked()
    assert 3 <= n_done < 10
    ds = D.run(dldl, x0, H, N_STEPS, store=store, save_every=SAVE, chunk_particles=1000,
               checkpoint_every=2, progress=False)
    _same(ds, ref_dldl)
    # the chunk the dead client was running is redone (from its checkpoint, if it had one)
    assert re.fullmatch(rf"{n_done} kept \(verified\); {9 - n_done} run; 1 redone: an earlier attempt did not "
                        r"finish \(chunk \d from (the start|step [24])\)", ds.attrs["chunks_report"]), ds.attrs["chunks_report"]
    D.run(dldl, x0, H, N_STEPS, store=tmp_path / "one.zarr", save_every=SAVE, chunk_particles=1000,
          progress=False)
    _same_store(store, tmp_path / "one.zarr")  # bitwise the uninterrupted single-process run


def test_mismatching_store_refused(sese, order4, x0, tmp_path):
    store = tmp_path / "m.zarr"
    D.run(sese, x0[:50], H, 2, store=store, progress=False)  # native: no compile wait
    def spec_sha(m):
        return hashlib.sha256(json.dumps(m.spec(), sort_keys=True).encode()).hexdigest()[:12]

    def x0_sha(x):
        return hashlib.sha256(x.tobytes()).hexdigest()[:12]

    both = {  # a refusal prints both values of what differs (issue #22)
        "method": f"spec: store SE+SE (spec sha256 {spec_sha(sese)}), this run {order4.name} (spec sha256 {spec_sha(order4)})",
        "h": f"h: store {H}, this run {2 * H}",
        "x0": f"x0_sha256: store sha256 {x0_sha(x0[:50])}, this run sha256 {x0_sha(x0[1:51])}",
        "n_steps": "n_steps: store 2, this run 3",
    }
    for kw in ({"method": order4}, {"h": 2 * H}, {"x0": x0[1:51]}, {"n_steps": 3}):
        a = {"method": sese, "x0": x0[:50], "h": H, "n_steps": 2, **kw}
        with pytest.raises(VIO.StoreMismatchError, match=re.escape(f"different run ({both[next(iter(kw))]})")) as err:
            D.run(a["method"], a["x0"], a["h"], a["n_steps"], store=store, progress=False)
        assert "\n" not in str(err.value)
    D.run(order4, x0[:50], H, 2, store=store, resume=False, progress=False)  # explicit overwrite


def test_callable_field_method_is_refused(tmp_path):
    import jax.numpy as jnp

    f = V.Field.from_callable(lambda x: jnp.stack([x[1], -x[0], 0.0 * x[2]]), name="rot")
    with pytest.raises(V.SpecError, match="cannot be shipped"):
        D.run(V.RK4(f), np.zeros((4, 3)), H, 2, store=tmp_path / "f.zarr")


def test_to_netcdf_round_trip(dldl, x0, tmp_path):
    sol = V.integrate(dldl, x0[:20], H, 4, save_every=2, progress=False)
    path = tmp_path / "s.nc"
    sol.to_netcdf(path, method=dldl)
    ds = xr.load_dataset(path)
    assert np.array_equal(ds.x.values, sol.xs) and np.array_equal(ds.time.values, sol.ts)
    assert np.array_equal(ds.status.values, sol.status)
    assert V.method_from_spec(ds.attrs["spec"]).spec() == dldl.spec()
    one = V.integrate(dldl, x0[0], H, 4, progress=False).to_xarray()
    assert one.x.shape == (1, 2, 3) and one.attrs["single"] == 1


@needs_native
def test_cli_zarr_run_resume_and_refusal(tmp_path, capsys, monkeypatch):
    from vpforms.cli import main

    monkeypatch.setenv("COLUMNS", "250")  # the summary's rows unwrapped (xdist workers may set 80)

    out = str(tmp_path / "cli.zarr")
    base = ["run", "--problem", "abc", "--particles", "30", "--steps", "4", "--save-every", "2",
            "--chunk-particles", "10", "--out", out]
    assert main(base) == 0
    ds = xr.open_zarr(out)
    sol = V.integrate(V.scheme(P.get("abc").field, "SE+SE"), P.get("abc").initial_conditions(30, seed=0),
                      0.1, 4, save_every=2, progress=False)
    assert np.array_equal(ds.x.values, sol.xs)
    assert "native (auto: native available)" in capsys.readouterr().out
    assert main(base) == 0  # resume: every chunk already done, and verified
    assert "3 kept (verified)" in capsys.readouterr().out
    os.remove(os.path.join(out, "x", "c", "1", "0", "0"))  # issue #22: a chunk's states deleted
    assert main(base) == 0
    assert "3 kept (verified)" not in (o := capsys.readouterr().out)
    assert "2 kept (verified); 1 redone: failed verification (chunk 1: x missing)" in o, o
    assert np.array_equal(xr.open_zarr(out).x.values, sol.xs)
    assert main(base[:-1] + [out, "--h", "0.2"]) == 2  # a different run into the same store
    err = capsys.readouterr().err.strip()
    assert err.startswith("vpforms: error:") and "different run (h: store 0.1, this run 0.2)" in err
    assert "\n" not in err
    assert main(base[:-1] + [out, "--backend", "jax"]) == 2  # the store was written natively
    assert "(backend: store 'native', this run 'jax')" in capsys.readouterr().err
    assert main(base[:-1] + [str(tmp_path / "dl.zarr"), "--method", "DL+DL", "--engine",
                                 "--backend", "native"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("vpforms: error: native backend cannot run") and "\n" not in err


# -- issue #22: verified stores, the chosen backend -----------------------------------------------
SESE_RUN = {"save_every": SAVE, "chunk_particles": 500, "progress": False}


@pytest.fixture(scope="module")
def sese_store(sese, x0, tmp_path_factory):
    """An uninterrupted single-process store run: 2000 particles in 4 chunks."""
    store = tmp_path_factory.mktemp("sese") / "ref.zarr"
    D.run(sese, x0[:2000], H, N_STEPS, store=store, **SESE_RUN)
    return store


def _chunk_file(store, array, c):
    return os.path.join(store, array, "c", str(c), *(["0", "0"] if array == "x" else []))


@pytest.mark.parametrize("array", list(VIO.CHUNK_ARRAYS))
def test_damaged_chunks_are_found_and_redone(sese, x0, sese_store, array, tmp_path):
    """A random chunk of each array deleted, truncated or overwritten with garbage: the done marker
    is not trusted, the resumed run redoes exactly that chunk, says so, and the store is bitwise
    the uninterrupted run's."""
    rng = np.random.default_rng(len(array))
    for fault in ("delete", "truncate", "corrupt"):
        store = tmp_path / f"{fault}.zarr"
        shutil.copytree(sese_store, store)
        c = int(rng.integers(4))
        path = _chunk_file(store, array, c)
        with open(path, "rb") as fh:
            data = bytearray(fh.read())
        if fault == "delete":
            os.remove(path)
        else:
            if fault == "truncate":
                data = data[: int(rng.integers(1, len(data)))]
            else:
                at = int(rng.integers(len(data) - 16))
                data[at:at + 16] = rng.integers(0, 256, 16, dtype=np.uint8).tobytes()
            with open(path, "wb") as fh:
                fh.write(bytes(data))
        bad = VIO.verify_store(store)["bad"]
        assert list(bad) == [c], (fault, bad)
        assert {"delete": "missing", "truncate": "unreadable"}.get(fault, "") in bad[c]
        assert bad[c].startswith(array)
        ds = D.run(sese, x0[:2000], H, N_STEPS, store=store, **SESE_RUN)
        assert ds.attrs["redone"] == bad
        assert ds.attrs["chunks_report"] == f"3 kept (verified); 1 redone: failed verification (chunk {c}: {bad[c]})"
        _same_store(store, sese_store)


def test_verify_finds_a_non_finite_particle_without_a_failure_status(sese_store, tmp_path, capsys):
    """A store whose checksums agree with its data (markers rewritten to match: a consistent lie)
    still fails when a particle is NaN with status 'succeeded' or was never written."""
    from vpforms.cli import main

    assert main(["verify", str(sese_store)]) == 0
    assert "4 (data equal to the checksums" in capsys.readouterr().out
    for c, array, i, value, why in [(0, "x", 7, np.nan, "particle 7: a non-finite state with status 'succeeded'"),
                                    (1, "status", 600, -1, "particle 600: status -1 is no result code (never written)")]:
        store = tmp_path / f"{array}.zarr"
        shutil.copytree(sese_store, store)
        g = VIO._group(store, "r+")
        if array == "x":
            g["x"][i, -1, 0] = value
        else:
            g[array][i] = value
        lo, hi = 500 * c, 500 * (c + 1)
        rec = VIO.read_marker(store, c)
        VIO.mark_done(store, c, {**rec, "arrays": VIO.chunk_digest(store, lo, hi)})
        assert VIO.verify_store(store)["bad"] == {c: why + " (1 particle(s))"}
        assert main(["verify", str(store)]) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith("vpforms: error: StoreVerificationError:") and "\n" not in err and why in err
    assert main(["verify", str(tmp_path / "none.zarr")]) == 2
    assert "no store at" in capsys.readouterr().err


@needs_native
def test_store_opens_in_xarray_without_warnings(sese_store):
    """Consolidated metadata: xarray and zarr open the store without listing it (no warning about
    the bookkeeping folder, none about missing consolidated metadata)."""
    import warnings

    import zarr

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ds = xr.open_zarr(sese_store)
        g = zarr.open_group(sese_store, mode="r")
    assert sorted(g.array_keys()) == ["coord", "failed_step", "recovered", "status", "step", "time", "x"]
    assert ds.attrs["backend"] == "native" and json.loads(ds.attrs["recovered_how"]) == {}
    assert ds.attrs["store_format"] == VIO.STORE_FORMAT


def test_checkpoint_over_damaged_states_is_not_continued(sese, x0, sese_store, tmp_path, monkeypatch):
    """A chunk interrupted after a checkpoint continues from it; when the states already written
    were damaged meanwhile, it starts over instead (and says why): either way bitwise the
    uninterrupted run."""
    from vpforms import _integrate

    real = _integrate.integrate
    for damage in (False, True):
        store, calls = tmp_path / f"d{damage}.zarr", []

        def flaky(*a, calls=calls, **k):
            calls.append(1)
            if len(calls) == 2:
                raise KeyboardInterrupt("simulated crash after the first checkpoint")
            return real(*a, **k)

        monkeypatch.setattr(_integrate, "integrate", flaky)
        with pytest.raises(KeyboardInterrupt):
            D.run(sese, x0[:2000], H, N_STEPS, store=store, checkpoint_every=2, **SESE_RUN)
        monkeypatch.setattr(_integrate, "integrate", real)
        assert os.path.exists(VIO.ckpt_path(store, 0))
        if damage:
            with open(_chunk_file(store, "x", 0), "r+b") as fh:
                fh.write(b"\x00" * 8)  # particle 0's x₁ at t = 0
        ds = D.run(sese, x0[:2000], H, N_STEPS, store=store, checkpoint_every=2, **SESE_RUN)
        report = ds.attrs["chunks_report"]
        if damage:
            assert report == ("3 run; 1 redone: an earlier attempt did not finish (chunk 0 from the start); "
                              "1 checkpoint(s) not continued (chunk 0: the states the checkpoint continues "
                              "differ from those it was taken after)")
        else:
            assert report == "3 run; 1 redone: an earlier attempt did not finish (chunk 0 from step 2)"
        _same_store(store, sese_store)


@pytest.mark.slow  # a JAX compile, ~3 s
@needs_native
def test_store_runs_the_chosen_backend(sese, dldl, x0, tmp_path):
    """backend="jax" is honoured and recorded (bitwise integrate(backend="jax")); a resume with
    another backend is refused with both values; "auto" resumes with the store's backend; a method
    the native backend cannot run is refused before any chunk runs."""
    from vpforms.backends import NativeUnavailableError

    pts, store = x0[:60], tmp_path / "j.zarr"
    ds = D.run(sese, pts, H, N_STEPS, store=store, save_every=SAVE, chunk_particles=20, backend="jax",
               progress=False)
    # chunk_size as the store's: XLA's last bits depend on the batch shape (not the native kernel's)
    _same(ds, V.integrate(sese, pts, H, N_STEPS, save_every=SAVE, progress=False, backend="jax", chunk_size=20))
    assert ds.attrs["backend"] == "jax" and ds.attrs["backend_reason"] == "requested"
    assert {VIO.read_marker(store, c)["backend"] for c in range(3)} == {"jax"}
    with pytest.raises(VIO.StoreMismatchError, match=r"\(backend: store 'jax', this run 'native'\)"):
        D.run(sese, pts, H, N_STEPS, store=store, save_every=SAVE, chunk_particles=20, backend="native",
              progress=False)
    ds = D.run(sese, pts, H, N_STEPS, store=store, save_every=SAVE, chunk_particles=20, progress=False)
    assert ds.attrs["backend"] == "jax" and ds.attrs["backend_reason"].startswith("auto: the backend that wrote")
    assert ds.attrs["chunks_report"] == "3 kept (verified)"
    with pytest.raises(NativeUnavailableError, match="native backend cannot run"):
        D.run(dldl, pts, H, N_STEPS, store=tmp_path / "n.zarr", backend="native", progress=False)
    assert not os.path.exists(tmp_path / "n.zarr")

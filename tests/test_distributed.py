"""Store-backed, resumable, Dask-distributed runs (issue #10): bit-identical to one integrate."""

import json
import os
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


@pytest.fixture(scope="module")
def prob():
    return P.get("abc")


@pytest.fixture(scope="module")
def dldl(prob):
    return V.scheme(prob.field, "DL+DL")


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


def _same(ds, ref):
    assert np.array_equal(ds.x.values, ref.xs)
    assert np.array_equal(ds.status.values, ref.status)
    assert np.array_equal(ds.failed_step.values, ref.failed_step)
    assert np.array_equal(ds.time.values, ref.ts)
    assert np.array_equal(ds.recovered.values, ref.recovered)  # issue #12: the same recovered steps


@pytest.mark.slow
def test_recovered_steps_survive_chunks_checkpoints_and_workers(cluster_client, dldl, x0, tmp_path):
    """At h = 0.5 bare DL+DL steps fail on ABC and are recovered (issue #12): a chunked,
    checkpointed store run, in process and on the cluster, has the same states, statuses and
    per-particle recovered counts as one integrate."""
    pts, h = x0[:400], 0.5
    ref = V.integrate(dldl, pts, h, 6, save_every=2, progress=False, backend="jax")
    assert ref.recovered.sum() > 0, "no step was recovered: the test would prove nothing"
    _same(D.run(dldl, pts, h, 6, store=tmp_path / "r1.zarr", save_every=2, chunk_particles=150,
                checkpoint_every=2, progress=False, backend="jax"), ref)
    _same(D.run(dldl, pts, h, 6, store=tmp_path / "r2.zarr", save_every=2, chunk_particles=150,
                checkpoint_every=4, client=cluster_client, progress=False, backend="jax"), ref)


def test_in_process_with_checkpoints_is_bit_identical(order4, x0, ref_order4, tmp_path):
    ds = D.run(order4, x0, H, N_STEPS, store=tmp_path / "a.zarr", save_every=SAVE,
               chunk_particles=4000, checkpoint_every=3, progress=False)
    _same(ds, ref_order4)
    assert json.loads(ds.attrs["spec"]) == order4.spec() and ds.attrs["version"] == V.__version__
    ds2 = xr.open_zarr(tmp_path / "a.zarr", consolidated=False)  # a plain xarray reader
    assert np.array_equal(ds2.x.values, ref_order4.xs)


def test_dask_cluster_bit_identical(cluster_client, dldl, order4, x0, ref_dldl, ref_order4, tmp_path):
    _same(D.run(dldl, x0, H, N_STEPS, store=tmp_path / "d.zarr", save_every=SAVE,
                chunk_particles=2500, client=cluster_client, progress=False), ref_dldl)
    _same(D.run(order4, x0, H, N_STEPS, store=tmp_path / "o.zarr", save_every=SAVE,
                chunk_particles=5000, client=cluster_client, progress=False), ref_order4)


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
    cluster_client.wait_for_workers(2, timeout=120)  # the nanny restarts it for later tests


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
D.run(V.scheme(prob.field, "DL+DL"), x0, {H}, {N}, store=sys.argv[1], save_every={S},
      chunk_particles=1000, checkpoint_every=2, progress=False)
"""


@pytest.mark.slow
def test_killed_client_then_resume(dldl, x0, ref_dldl, tmp_path):
    store = str(tmp_path / "r.zarr")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    child = subprocess.Popen([sys.executable, "-c", _CHILD.format(H=H, N=N_STEPS, S=SAVE), store], env=env)
    done = os.path.join(store, ".vpforms", "done")
    t_end = time.time() + 180
    while time.time() < t_end and not (os.path.isdir(done) and len(os.listdir(done)) >= 3):
        time.sleep(0.05)
    child.kill()  # the client dies mid-run
    child.wait()
    n_done = len(os.listdir(done))
    assert 3 <= n_done < 10
    ds = D.run(dldl, x0, H, N_STEPS, store=store, save_every=SAVE, chunk_particles=1000,
               checkpoint_every=2, progress=False)
    _same(ds, ref_dldl)


def test_mismatching_store_refused(dldl, order4, x0, tmp_path):
    store = tmp_path / "m.zarr"
    D.run(dldl, x0[:50], H, 2, store=store, progress=False)
    for kw in ({"method": order4}, {"h": 2 * H}, {"x0": x0[1:51]}, {"n_steps": 3}):
        a = {"method": dldl, "x0": x0[:50], "h": H, "n_steps": 2, **kw}
        with pytest.raises(VIO.StoreMismatchError, match="different run"):
            D.run(a["method"], a["x0"], a["h"], a["n_steps"], store=store, progress=False)
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


def test_cli_zarr_run_resume_and_refusal(tmp_path, capsys):
    from vpforms.cli import main

    out = str(tmp_path / "cli.zarr")
    base = ["run", "--problem", "abc", "--particles", "30", "--steps", "4", "--save-every", "2",
            "--chunk-particles", "10", "--out", out]
    assert main(base) == 0
    ds = xr.open_zarr(out, consolidated=False)
    sol = V.integrate(V.scheme(P.get("abc").field, "SE+SE"), P.get("abc").initial_conditions(30, seed=0),
                      0.1, 4, save_every=2, progress=False)
    assert np.array_equal(ds.x.values, sol.xs)
    assert main(base) == 0  # resume: every chunk already done
    capsys.readouterr()
    assert main(base[:-1] + [out, "--h", "0.2"]) == 2  # a different run into the same store
    err = capsys.readouterr().err.strip()
    assert err.startswith("vpforms: error:") and "different run" in err and "\n" not in err

"""appell.sweep: grid specs, a tiny sweep on a local Dask cluster (2 threaded workers),
the HDF5 dataset and summary, and a failing run recorded without stopping the sweep."""

import json
import os
import time

import numpy as np
import pytest

from appell import numeric_model

pytest.importorskip("dask.distributed")
pytest.importorskip("appell.simulation.simulate")

import appell  # noqa: E402
from appell.examples.catalog import CATALOG  # noqa: E402
from appell.io.results import write_netcdf
from appell.simulation.sweep import parameter_grid, parse_spec, sweep  # noqa: E402


def test_specs():
    name, values = parse_spec("m=0.5:2:4")  # values of np.linspace: exact to an ulp
    assert name == "m" and np.allclose(values, [0.5, 1.0, 1.5, 2.0])
    assert np.allclose(parse_spec("L=1,2.5")[1], [1.0, 2.5])
    assert np.allclose(parse_spec("g=9.81")[1], [9.81])
    grid = parameter_grid(["m=1:2:2", "L=1,2,3"])
    assert len(grid) == 6 and grid[1] == {"m": 1.0, "L": 2.0}
    for bad in ("m", "m=", "m=1:2", "m=a:b:3", "m=1:2:0", "1x=3"):
        with pytest.raises(appell.ModelError):
            parse_spec(bad)


def test_tiny_sweep(tmp_path):
    """Pendulum rod tension over m and g: released at rest at 60 deg the tension is
    m g (3 cos th - 2 cos 60 deg) (catalog.pendulum), 2 m g at the bottom, so the largest is
    at the largest m and g; runs with m = 0 (singular mass matrix) fail and are recorded."""
    out = tmp_path / "sweep.h5"
    res = sweep(
        CATALOG["pendulum"](),
        ["m=0:2:3", "g=5,9.81"],
        1.2,
        output=out,
        samples=61,
        n_workers=2,
        processes=False,
        backend="numpy",
        progress=False,
    )
    assert out.exists() and (tmp_path / "sweep.h5.summary.json").exists()
    assert len(res.runs) == 6
    statuses = {tuple(r.parameters.values()): r.status for r in res.runs}
    assert all(s == 0 for k, s in statuses.items() if k[0] > 0)
    assert all(s < 0 for k, s in statuses.items() if k[0] == 0)
    assert all(r.message for r in res.failed)
    import h5py

    with h5py.File(out) as f:
        lam = f["multipliers/rod"][()]
        assert lam.shape == (6, 61)
        assert np.allclose(f["parameters/m"][()], [0, 0, 1, 1, 2, 2])
        assert np.all(np.isnan(lam[:2]))
        assert np.all(f["status"][()][2:] == 0)
        assert json.loads(f.attrs["summary"])["multipliers"]["rod"]["argmax_parameters"]["m"] == 2.0
    top = res.summary["multipliers"]["rod"]
    # the bottom is passed within 1.2 s (L = 1 m; quarter period about 0.55 s at g = 9.81);
    # the largest sample, 1.8 ms from the bottom at t = K(1/4)/sqrt(g/L) = 0.538 s, is
    # 0.75 g/L dt^2 = 2.3e-5 below 2 m g (a fixed grid: rounding does not move it); the run's error is 1e-9
    assert top["max"] == pytest.approx(2 * 2.0 * 9.81, rel=1e-3)
    assert "rod" in res.summary_text()


def test_a_sweep_leaves_no_default_dask_client_behind(tmp_path):
    """After a sweep in the same process, a netCDF export (xarray, which uses dask's default
    scheduler when one is configured) still works: the sweep's client is not made the
    default ('Requested dask.distributed scheduler but no Client active' before)."""
    import dask

    sweep(
        CATALOG["pendulum"](),
        ["m=1,2"],
        0.2,
        output=tmp_path / "s.h5",
        samples=11,
        n_workers=1,
        processes=False,
        backend="numpy",
        progress=False,
    )
    assert dask.config.get("scheduler", None) != "dask.distributed"
    sol = appell.simulate(appell.derive(CATALOG["pendulum"]()), 0.1, t_eval=[0.0, 0.1], progress=False)
    write_netcdf(sol, tmp_path / "after.nc")
    import xarray as xr

    with xr.open_dataset(tmp_path / "after.nc", engine="h5netcdf") as ds:
        # m g cos 60 deg at rest: one split solve, rounding only
        assert ds["lambda_rod"].values[0] == pytest.approx(9.81 * 0.5, rel=1e-9)


# ------------------------------------------------------------- tasks, shipping, real processes
from appell.simulation.sweep import chunks, sweep_cluster  # noqa: E402


def test_chunks_hold_every_run_once_in_order_and_end_with_single_runs():
    """Guided self-scheduling: the tasks, concatenated, are the runs in order (nothing lost
    or doubled); sizes never grow; the last task is one run; at least one task per slot."""
    for runs in (0, 1, 2, 7, 64, 101, 1000):
        todo = [(i, {"m": float(i)}) for i in range(runs)]
        for slots in (1, 2, 3, 16):
            tasks = chunks(todo, slots)
            assert [r for t in tasks for r in t] == todo
            sizes = [len(t) for t in tasks]
            assert all(a >= b for a, b in zip(sizes, sizes[1:])) and all(sizes)
            if runs:
                assert sizes[-1] == 1 and len(tasks) >= min(runs, slots)
    assert [len(t) for t in chunks(list(range(64)), 2)][:4] == [
        8,
        7,
        7,
        6,
    ]  # ceil(64/8), ceil(56/8), ceil(49/8), ceil(42/8)


def _car():
    from appell.examples import example_path
    from appell.io.cli import command_options

    system = appell.load_model(example_path("car"))
    opts = command_options(system, 2.0)
    return system, {"t_end": opts.t_end, "t_eval": opts.t_eval, **opts.changes(but=("t_end", "t_eval"))}


def _loop_run(model, t_end, params, opts):
    """The reference: one run of the plain loop, in this process."""
    return appell.simulate(model, t_end, params=params, progress=False, **opts)


def test_real_dask_processes_lose_a_busy_worker_and_every_run_is_recorded_once(dask_processes, tmp_path):
    """A 'dask scheduler' and two 'dask worker' processes (tests/processes.py); the worker
    with tasks assigned is killed (SIGKILL) once the first runs are in. Every run index is
    recorded exactly once, all reach t_end, and each run's states and reactions equal those
    of a plain loop of simulate with the same compiled model and parameters (the independent
    route: no Dask, no shipping)."""
    import threading

    from dask.distributed import Client

    system, opts = _car()
    t_end, t_eval = opts.pop("t_end"), opts.pop("t_eval")
    derivation = appell.derive(system)
    procs = dask_processes.workers(2)
    specs = ["F=600:1000:4", "M=1000:1400:4"]
    out = tmp_path / "car.h5"
    box = {}

    def run():
        try:
            box["result"] = sweep(
                derivation,
                specs,
                t_end,
                t_eval=t_eval,
                output=out,
                backend="c",
                scheduler=dask_processes.address,
                progress=False,
                **opts,
            )
        except BaseException as exc:  # noqa: BLE001 (reported by the main thread)
            box["error"] = exc

    thread = threading.Thread(target=run)
    thread.start()
    partial = out.with_name("car.h5.partial")
    with Client(dask_processes.address, timeout=60) as watcher:
        deadline = time.monotonic() + 180
        while not (partial.exists() and len(partial.read_text().splitlines()) > 1):
            assert time.monotonic() < deadline and thread.is_alive(), box
            time.sleep(0.02)
        busy = [addr for addr, tasks in watcher.processing().items() if tasks]
        assert busy, "no worker had a task when the first runs were in"
        pid = watcher.run(os.getpid, workers=busy[:1])[busy[0]]
        victim = next(p for p in procs if p.pid == pid)
        victim.kill()
        in_at_kill = len(partial.read_text().splitlines()) - 1
    thread.join(timeout=300)
    assert not thread.is_alive() and "error" not in box, box
    res = box["result"]
    grid = appell.parameter_grid(specs)
    assert in_at_kill < len(grid)  # killed mid-sweep
    assert sorted(r.index for r in res.runs) == list(range(len(grid)))
    assert all(r.status == 0 for r in res.runs), res.summary_text()
    assert not partial.exists()
    import h5py

    model = numeric_model(derivation, "c")
    with h5py.File(out) as f:
        for i, params in enumerate(grid):
            assert {k: f[f"parameters/{k}"][i] for k in params} == params
            ref = _loop_run(model, t_end, params, {**opts, "t_eval": t_eval})
            # the same model and options in another process: rounding only (uses 2e-4 of these)
            for name, values in ref.multipliers.items():
                np.testing.assert_allclose(f[f"multipliers/{name}"][i], values, rtol=1e-10, atol=1e-9)
            for name, values in ref.states.items():
                np.testing.assert_allclose(f[f"states/{name}"][i], values, rtol=1e-10, atol=1e-12)


def _built_models(client):
    from appell.simulation import sweep as sweep_module

    def keys():
        return sorted(sweep_module._MODELS)

    return client.run(keys)


def test_a_kept_cluster_builds_each_model_once_per_worker_and_ships_numpy_models(dask_processes, tmp_path):
    """sweep_cluster connected to a real scheduler with one 'dask worker': three sweeps on
    the same client. The worker keeps its process (same pid) and builds the C model of the
    derivation once (one key after two sweeps of it); the NumPy model (lambdified functions,
    which do not pickle) is shipped by its derivation. Every run equals the plain loop's. The
    derivation, its numeric model used, and a controlled one pickle and run on the worker
    (:func:`_derivations_pickle_after_numeric_use_and_run_on_the_worker`)."""
    system, opts = _car()
    t_end, t_eval = opts.pop("t_end"), opts.pop("t_eval")
    opts["t_eval"] = t_eval[::4]
    derivation = appell.derive(system)
    dask_processes.workers(1)
    grid_specs = ["F=700,900", "M=1100,1300"]
    with sweep_cluster(scheduler=dask_processes.address) as client:
        pids = client.run(os.getpid)
        first = sweep(
            derivation, grid_specs, t_end, output=tmp_path / "a.h5", backend="c", client=client, progress=False, **opts
        )
        after_first = _built_models(client)
        sweep(
            derivation, grid_specs, t_end, output=tmp_path / "b.h5", backend="c", client=client, progress=False, **opts
        )
        assert _built_models(client) == after_first and len(next(iter(after_first.values()))) == 1
        numpy_model = numeric_model(derivation)
        third = sweep(numpy_model, grid_specs, t_end, output=tmp_path / "c.h5", client=client, progress=False, **opts)
        assert len(next(iter(_built_models(client).values()))) == 2
        assert client.run(os.getpid) == pids
        _derivations_pickle_after_numeric_use_and_run_on_the_worker(client, derivation)
    assert not client.status == "running"
    for res, model in ((first, numeric_model(derivation, "c")), (third, numpy_model)):
        import h5py

        assert [r.status for r in res.runs] == [0] * 4
        with h5py.File(res.path) as f:
            for r in res.runs:
                ref = _loop_run(model, t_end, r.parameters, opts)
                # the same model and options in another process: rounding only (uses 1e-4 of these)
                for name, values in ref.multipliers.items():
                    np.testing.assert_allclose(f[f"multipliers/{name}"][r.index], values, rtol=1e-10, atol=1e-9)


def test_sweep_refuses_a_client_together_with_a_scheduler(tmp_path):
    with pytest.raises(appell.ModelError, match="not both"):
        sweep(
            CATALOG["pendulum"](),
            ["m=1"],
            0.1,
            client=object(),
            scheduler="tcp://127.0.0.1:8786",
            output=tmp_path / "s.h5",
            progress=False,
        )
    with pytest.raises(appell.ModelError, match="Client"):
        sweep(CATALOG["pendulum"](), ["m=1"], 0.1, client=object(), output=tmp_path / "s.h5", progress=False)


def test_appell_cluster_serves_sweeps_until_ctrl_c(tmp_path):
    """'appell cluster --port 0' prints its scheduler's address; 'appell sweep --scheduler'
    runs on it (the pendulum released at rest from 60 deg: largest rod tension 2 m g at the
    bottom, closed form); Ctrl-C (SIGINT) stops it with exit code 0."""
    import re
    import signal
    import subprocess
    import sys

    from click.testing import CliRunner

    from appell.io.cli import cli
    from processes import dask_cli, env_with_src

    dask_cli()  # skipped without distributed
    log = open(tmp_path / "cluster.log", "w")  # Dask's log: a pipe left unread could fill and stall it
    proc = subprocess.Popen(
        [sys.executable, "-m", "appell.io.cli", "cluster", "--workers", "1", "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=log,
        text=True,
        env=env_with_src(),
    )
    try:
        line = proc.stdout.readline()
        found = re.search(r"Dask scheduler at (\S+) with 1 worker", line)
        assert found, (line, proc.poll())
        out = tmp_path / "s.h5"
        result = CliRunner().invoke(
            cli,
            [
                "sweep",
                "pendulum",
                "--param",
                "m=1,2",
                "--t-end",
                "1.2",
                "--samples",
                "61",
                "--backend",
                "numpy",
                "--scheduler",
                found.group(1),
                "--out",
                str(out),
            ],
        )
        assert result.exit_code == 0, result.output
        summary = json.loads(out.with_name("s.h5.summary.json").read_text())
        # the largest sample, 1.8 ms from the bottom at t = K(1/4)/sqrt(g/L) = 0.538 s, is
        # 0.75 g/L dt^2 = 2.3e-5 below 2 m g (a fixed grid: rounding does not move it); the run's error is 1e-9
        assert summary["multipliers"]["rod"]["max"] == pytest.approx(2 * 2.0 * 9.81, rel=1e-3)
        proc.send_signal(signal.SIGINT)
        stdout, _ = proc.communicate(timeout=60)
        assert proc.returncode == 0, (stdout, (tmp_path / "cluster.log").read_text()[-2000:])
        assert "stopping the cluster" in stdout
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        log.close()


def _derivations_pickle_after_numeric_use_and_run_on_the_worker(client, car):
    """A Derivation keeps only its symbolic data in a pickle (issue 21: after its first
    numeric use it no longer pickled, and the sweep deleted instance entries to ship it):
    the car, whose NumPy model was used here, is sent to the 'dask worker' process, which
    builds its model again and returns the reactions at a state, equal to the ones here; a
    controlled derivation (the cart-pole) likewise with its controls."""
    import dataclasses
    import pickle

    from appell.io.cli import derive_model, load_system

    cart_pole = derive_model(load_system("cart_pole"))
    q, w = [0.0, 0.0, 0.3], [1.2, 0.5, 0.1]
    here = numeric_model(car).solve(0.0, q, w).multipliers
    y = np.zeros(len(numeric_model(cart_pole).state_names))
    y[:2] = [0.1, 0.2]
    here_controlled = numeric_model(cart_pole).evaluate(0.0, y, numeric_model(cart_pole).params()).controls
    for d in (car, cart_pole):  # numeric use leaves the derivation as it was (issue 21: no attached state)
        assert set(vars(d)) <= {f.name for f in dataclasses.fields(d)} | {"reduced", "reactions"}
        copy = pickle.loads(pickle.dumps(d))
        assert copy.system == d.system and set(vars(copy)) <= set(vars(d))

    def reactions(derivation):
        return numeric_model(derivation).solve(0.0, q, w).multipliers

    def controls(derivation):
        return numeric_model(derivation).evaluate(0.0, y, numeric_model(derivation).params()).controls

    there = client.submit(reactions, car).result(timeout=120)
    there_controlled = client.submit(controls, cart_pole).result(timeout=120)
    np.testing.assert_allclose(there, here, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(there_controlled, here_controlled, rtol=1e-13, atol=1e-13)

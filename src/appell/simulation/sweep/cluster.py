"""The Dask side of a sweep (:mod:`appell.simulation.sweep`): the optional package
(``pip install 'appell[sweep]'``, :func:`_distributed`), scheduler addresses, starting or
reaching a cluster, a cluster kept for several sweeps (:func:`sweep_cluster`), the submission
of the runs and their gathering with lost workers and timeouts, and Ctrl-C (the workers of a
local cluster ignore it; the command that started them stops them)."""

from __future__ import annotations

import contextlib
import logging
import os
import re
import time
import uuid

from appell.arguments import count, number
from appell.errors import ModelError, ResourceError
from appell.simulation.sweep.runs import RAISED, _prepare_worker, _run_chunk, chunks

#: Dask scheduler addresses: ``protocol://host:port`` or ``host:port``
_ADDRESS = re.compile(r"^(?:(?:tcp|tls|ws|wss|ucx)://)?(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+):(\d{1,5})$")


def _distributed():
    """``dask.distributed``, or :class:`~appell.errors.MissingDependencyError` with the install
    command (``pip install 'appell[sweep]'``)."""
    from appell.errors import import_optional

    return import_optional("dask.distributed", extra="sweep", feature="a parameter sweep")


def check_scheduler_address(scheduler: str) -> str:
    """``scheduler`` if it looks like a Dask scheduler address (``tcp://host:port``, also
    ``tls://``, ``ws://``, ``ucx://`` or a bare ``host:port``), else a ModelError."""
    if (
        not isinstance(scheduler, str)
        or not (m := _ADDRESS.match(scheduler.strip()))
        or not 0 < int(m.group(1)) < 65536
    ):
        raise ModelError(
            f"bad Dask scheduler address {scheduler!r}",
            hint="give the address 'dask scheduler' prints, e.g. tcp://192.168.1.10:8786",
        )
    return scheduler.strip()


def _connect(scheduler: str, timeout: float):
    Client = _distributed().Client

    try:
        return Client(scheduler, timeout=timeout, set_as_default=False)
    except Exception as exc:  # noqa: BLE001 (refused, timed out, or not a Dask scheduler at all)
        raise ResourceError(
            f"cannot connect to the Dask scheduler at {scheduler}: {type(exc).__name__}: {exc}",
            hint="start one with 'dask scheduler' and give the address it prints, or leave out "
            "the scheduler to run on a local cluster",
        ) from None


def _cancelled(exc: BaseException) -> bool:
    """Whether ``exc`` says a future was cancelled (asyncio's or concurrent.futures' error)."""
    import asyncio
    import concurrent.futures

    return isinstance(exc, (asyncio.CancelledError, concurrent.futures.CancelledError))


def _failed(index: int, message: str) -> dict:
    return {"index": index, "status": RAISED, "message": message, "wall_time": float("nan")}


def _worker_count(client) -> tuple[int, int]:
    """The scheduler's workers and their threads."""
    try:
        workers = client.scheduler_info(n_workers=-1).get("workers", {})
    except TypeError:  # older distributed: no n_workers argument
        workers = client.scheduler_info().get("workers", {})
    return len(workers), sum(int(w.get("nthreads", 1)) for w in workers.values())


def _gather(client, futures, tasks, on_result, worker_timeout: float, bar=None):
    """Collect the tasks' runs as they finish (``on_result(dict)`` per run). ``tasks[k]``
    lists the run indices of ``futures[k]``. A task whose worker was lost is computed again
    by Dask; one lost for good (KilledWorker) or cancelled gives failed runs. A finished
    task's result is released at once, so that losing its worker later computes nothing
    again (each task is taken once, when it finishes); a task whose worker dies while its
    result is fetched is fetched again once Dask has computed it again (it never blocks the
    sweep: the checks below still run). When the cluster has had no
    worker for ``worker_timeout`` seconds (or the scheduler is lost), the pending tasks are
    cancelled and their runs recorded as failed."""
    as_completed = _distributed().as_completed

    pending = dict(zip(futures, tasks))
    finished = as_completed(futures, loop=client.loop)  # the sweep's client is not the default one

    def record(r):
        on_result(r)
        if bar is not None:
            bar.update(1)

    no_worker_since, last_check, regather = None, 0.0, []
    while pending:
        done = finished.next_batch(block=False) if finished.has_ready() else []
        done += [f for f in regather if f.done()]
        regather = [f for f in regather if f not in done]
        for fut in done:
            try:
                results = fut.result(timeout=10.0)
            except TimeoutError:
                # its worker died while its result was fetched: Dask computes it again
                regather.append(fut)
                continue
            except BaseException as exc:  # noqa: BLE001 (a lost worker, a cancelled run: record it)
                if not isinstance(exc, Exception) and not _cancelled(exc):
                    raise
                lost = (
                    "lost with the Dask workers (killed, or their machine gone): "
                    if _cancelled(exc) or type(exc).__name__ == "KilledWorker"
                    else ""
                )
                results = [_failed(i, f"{lost}{type(exc).__name__}: {exc}") for i in pending[fut]]
            pending.pop(fut)
            fut.release()
            for r in results:
                record(r)
        if done or not pending:
            continue
        time.sleep(0.05)
        now = time.monotonic()
        if now - last_check < 0.5:
            continue
        last_check = now
        reason = None
        try:
            workers, _ = _worker_count(client)
        except Exception as exc:  # noqa: BLE001 (the scheduler is gone)
            workers, reason = 0, f"lost the Dask scheduler ({type(exc).__name__}: {exc})"
        if workers:
            no_worker_since = None
            continue
        no_worker_since = no_worker_since or now
        if reason is None and now - no_worker_since < worker_timeout:
            continue
        reason = reason or f"no Dask worker for {worker_timeout:g} s (all workers lost?)"
        try:
            client.cancel(list(pending))
        except Exception:  # noqa: BLE001 (the scheduler may be gone too)
            pass
        for i in sorted(i for indices in pending.values() for i in indices):
            record(_failed(i, f"not run: {reason}"))
        pending.clear()


def _start_cluster(n_workers, processes, scheduler, connect_timeout, host=None, port=0):
    """``(client, cluster)``: a new local cluster of single-threaded workers whose scheduler
    listens on ``host:port`` (default 127.0.0.1, a free port; ``cluster`` to be closed after
    the client), or a client of the scheduler at ``scheduler``."""
    if scheduler is not None:
        return _connect(scheduler, connect_timeout), None
    distributed = _distributed()
    cluster = client = None
    try:
        with _interrupt_after():  # a cluster half started cannot be closed cleanly
            # Dask's warnings (a worker restarted, a task cancelled) stay off the terminal: the
            # sweep records every run's fate itself
            cluster = distributed.LocalCluster(
                n_workers=n_workers,
                threads_per_worker=1,
                processes=processes,
                dashboard_address=None,
                host=host,
                scheduler_port=port,
                silence_logs=logging.ERROR,
            )
            client = distributed.Client(cluster, set_as_default=False)
        return client, cluster
    except BaseException as exc:
        if isinstance(exc, KeyboardInterrupt) and client is not None:
            _silence(client)
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
        if isinstance(exc, OSError):  # the port is taken, the host is not this machine's
            raise ResourceError(
                f"cannot start a Dask scheduler on {host or '127.0.0.1'}:{port}: {exc.strerror or exc}",
                hint="choose another port (0: a free one) or host",
            ) from None
        raise


@contextlib.contextmanager
def _interrupt_after():
    """Hold a Ctrl-C (SIGINT) until the block has run, then raise it (KeyboardInterrupt); a
    second one meanwhile goes to the previous handler at once. Only in the main thread."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = []

    def hold(signum, frame):
        if held and callable(previous):
            previous(signum, frame)
        held.append(signum)

    previous = signal.signal(signal.SIGINT, hold)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if held:
        raise KeyboardInterrupt


def _silence(client) -> None:
    """Nothing more on the terminal from an interrupted sweep's cluster while it closes: Dask's
    loggers here, and the workers' stderr (:func:`_mute_worker`)."""
    _quiet_dask()
    try:
        client.run(_mute_worker, on_error="ignore")
    except Exception:  # noqa: BLE001 (a worker gone: its messages may stay)
        pass


@contextlib.contextmanager
def _workers_without_interrupts(local: bool):
    """Worker processes of a local cluster started in the block ignore SIGINT, so that Ctrl-C in
    the terminal (sent to the whole process group) stops this process only, which then closes
    the cluster, instead of a traceback from every worker (``local``: a local cluster of
    processes; else nothing is done).

    A disposition ``SIG_IGN`` survives ``fork`` and ``exec`` (a handler or a blocked mask does
    not reach a spawned worker): the workers are forked from multiprocessing's fork server
    (Dask's ``multiprocessing-method = "forkserver"``), started here with SIGINT ignored for
    the instant of its own start, so that every process it forks ignores SIGINT too."""
    import multiprocessing
    import signal
    import threading

    _distributed()  # a missing dask: the extra to install, before anything starts
    if (
        not local
        or "forkserver" not in multiprocessing.get_all_start_methods()
        or threading.current_thread() is not threading.main_thread()
    ):
        yield
        return
    from multiprocessing import forkserver

    import dask
    from distributed.utils import get_mp_context

    with dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"}):
        get_mp_context()  # Dask's preload of the fork server (its imports, done once there)
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            forkserver.ensure_running()
        finally:
            signal.signal(signal.SIGINT, previous)
        yield


def _mute_worker() -> None:
    """In a worker process of an interrupted sweep (``client.run``): nothing more on the
    terminal's stderr while the cluster closes (Dask's warnings, a traceback of a connection
    closed under the worker's feet)."""
    import sys

    _quiet_dask()
    sys.stderr = open(os.devnull, "w", encoding="utf-8")  # noqa: SIM115 (kept until the process ends)


def _quiet_dask() -> None:
    """Silence Dask's loggers while an interrupted sweep closes its cluster (its warnings, such
    as a worker killed after its grace period, are expected then)."""
    for name in list(logging.root.manager.loggerDict):
        if name.split(".")[0] in ("distributed", "tornado", "asyncio"):
            logging.getLogger(name).disabled = True


@contextlib.contextmanager
def sweep_cluster(
    n_workers: int | None = None,
    *,
    scheduler: str | None = None,
    processes: bool = True,
    host: str | None = None,
    port: int = 0,
    connect_timeout: float = 30.0,
):
    """A Dask client kept for several sweeps: ``with sweep_cluster(2) as client:
    sweep(..., client=client)``.

    Starts a local cluster of ``n_workers`` single-threaded workers (default one per core;
    ``processes=False``: threads of this process) whose scheduler listens on ``host:port``
    (default 127.0.0.1 and a free port; more workers may join it with ``dask worker
    ADDRESS``), or connects to the running scheduler at ``scheduler`` (``dask scheduler``,
    ``appell cluster``). The scheduler's address is ``client.scheduler.address``.
    The workers import appell's simulation layer at once, and keep the numeric model of
    each sweep (by the content of its derivation), so that a later sweep of the same model
    starts its runs without a cluster start, an import or a compilation. The cluster (not a
    scheduler given by address) is closed when the block ends.
    """
    if n_workers is not None:
        n_workers = count(n_workers, "n_workers", maximum=4096)
    if scheduler is not None:
        scheduler = check_scheduler_address(scheduler)
    connect_timeout = number(connect_timeout, "connect_timeout", positive=True)
    port = count(port, "port", minimum=0, maximum=65535)
    with _workers_without_interrupts(processes and scheduler is None):
        client, cluster = _start_cluster(n_workers, processes, scheduler, connect_timeout, host, port)
        try:
            client.run(_prepare_worker)
            yield client
        finally:
            client.close()
            if cluster is not None:
                cluster.close()


def _compute_on(
    shipment,
    todo,
    t_end,
    t_eval,
    simulate_options,
    on_result,
    *,
    client,
    scheduler,
    n_workers,
    processes,
    progress,
    worker_timeout,
    connect_timeout,
):
    """:func:`_compute` (its docstring), inside its handling of Ctrl-C for the workers."""
    own = client is None
    cluster = None
    if own:
        client, cluster = _start_cluster(n_workers, processes, scheduler, connect_timeout)
    token = uuid.uuid4().hex
    bar = None
    try:
        _, threads = _worker_count(client)
        tasks = chunks(todo, threads or os.cpu_count() or 1)
        futures = [
            client.submit(
                _run_chunk,
                shipment,
                chunk,
                t_end,
                t_eval,
                simulate_options,
                key=f"appell-runs-{chunk[0][0]}-{chunk[-1][0]}-{token}",
                pure=False,
            )
            for chunk in tasks
        ]
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=len(todo), desc="sweep", unit="run")
        _gather(client, futures, [[i for i, _ in chunk] for chunk in tasks], on_result, worker_timeout, bar)
    except KeyboardInterrupt:
        if own:  # the workers ignore Ctrl-C and run on until the cluster closes below
            _silence(client)
        raise
    finally:
        if bar is not None:
            bar.close()
        if own:
            client.close()
            if cluster is not None:
                cluster.close()

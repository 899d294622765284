"""Child processes of the tests: the environment that imports this checkout's appell, and a
real Dask cluster of separate processes ('dask scheduler', 'dask worker')."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

import appell

SRC = str(Path(appell.__file__).resolve().parents[1])


def env_with_src(**extra) -> dict:
    """The environment of a child process that imports this checkout's appell."""
    env = dict(os.environ)
    env["PYTHONPATH"] = SRC + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("APPELL_DEBUG", None)
    env.update(extra)
    return env


def dask_cli() -> str:
    """The 'dask' command of this Python (the test is skipped without it)."""
    pytest.importorskip("dask.distributed", reason="distributed is not installed (pip install 'appell[sweep]')")
    exe = shutil.which("dask") or str(Path(sys.executable).with_name("dask"))
    if not os.path.exists(exe):
        pytest.skip("the dask command line is not installed")
    return exe


class DaskProcesses:
    """A real 'dask scheduler' on a free port of 127.0.0.1 and 'dask worker' processes
    (no nanny: a killed worker stays dead); :meth:`close` kills them all."""

    def __init__(self, directory: Path):
        self.exe, self.directory = dask_cli(), directory
        self.file = directory / "scheduler.json"
        self.procs = []
        self.scheduler = self._start(
            ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(self.file)],
            "scheduler",
        )
        deadline = time.monotonic() + 90
        while not self.file.exists() and time.monotonic() < deadline:
            if self.scheduler.poll() is not None:
                self.close()
                raise RuntimeError(f"dask scheduler exited: {(directory / 'scheduler.log').read_text()[-2000:]}")
            time.sleep(0.2)
        time.sleep(0.3)
        self.address = json.loads(self.file.read_text())["address"]

    def _start(self, args, name):
        with open(self.directory / f"{name}.log", "w") as log:
            proc = subprocess.Popen([self.exe, *args], stdout=log, stderr=subprocess.STDOUT, env=env_with_src())
        self.procs.append(proc)
        return proc

    def workers(self, count: int) -> list[subprocess.Popen]:
        """Start ``count`` single-threaded workers and wait until the scheduler has them all."""
        from dask.distributed import Client

        started = [
            self._start(
                ["worker", "--scheduler-file", str(self.file), "--nthreads", "1", "--no-nanny", "--no-dashboard"],
                f"worker{len(self.procs)}",
            )
            for _ in range(count)
        ]
        with Client(self.address, timeout=60) as client:
            client.wait_for_workers(len(self.procs) - 1, timeout=120)
        return started

    def close(self):
        for proc in reversed(self.procs):
            proc.kill()
            proc.wait(timeout=30)

"""Fault injection: full and read-only disks, what sits at an output path, hostile model
names, a corrupt compiled-code cache, signals during a write, lost Dask workers and bad
scheduler addresses (issue 11, section 7).

The independent value each test checks is the state of the file system (the previous
file's bytes, the file type and mode seen by ``os.stat``, the files in the directory),
the exit status of the process, or a closed form: the rod tension of the pendulum
released at rest from theta0 = 60 degrees, m g (3 cos(theta) - 2 cos(theta0)), largest
(2 m g) at the bottom (energy conservation; examples/pendulum.toml).
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import socket
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import appell
from appell import files
from appell.examples import example_path
from appell.examples.catalog import CATALOG
from appell.io.cli import cli
from appell.io.results import write_netcdf
from processes import env_with_src

SRC = str(Path(appell.__file__).resolve().parents[1])
G = 9.81


def run(*args):
    """The command line in-process: click's Result (exit_code, stdout, stderr)."""
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def run_process(args, timeout=180, **kw):
    return subprocess.run(
        [sys.executable, *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=kw.pop("env", env_with_src()),
        **kw,
    )


def enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def leftovers(directory: Path) -> list[str]:
    """Hidden temporary files of appell's writer left in ``directory``."""
    return sorted(p.name for p in directory.iterdir() if ".appell-" in p.name)


def pendulum_model(tmp_path: Path, name: str = "pendulum", **replace) -> Path:
    text = example_path("pendulum").read_text()
    text = text.replace('name = "pendulum"', f"name = {json.dumps(name)}")
    for old, new in replace.items():
        text = text.replace(old, new)
    path = tmp_path / "model.toml"
    path.write_text(text, encoding="utf-8")
    return path


# ---------------------------------------------------------------------- a full disk
@pytest.mark.parametrize("suffix", [".h5", ".csv", ".nc"])
def test_full_disk_fails_cleanly_and_keeps_the_old_file(tmp_path, monkeypatch, suffix):
    """A writer failing with ENOSPC: exit 1, 'No space left on device' with the path, the
    previous file byte for byte, no temporary file left (h5py crashed with exit 139 here)."""
    target = tmp_path / f"out{suffix}"
    target.write_bytes(b"previous result\n")
    # HDF5 and netCDF-4: the bytes of the file built in memory
    monkeypatch.setattr(files, "write_bytes", enospc)
    from appell.io import results

    monkeypatch.setattr(results, "write_bytes", enospc)

    if suffix == ".csv":

        def rows(self):
            yield ["t"]
            enospc()

        monkeypatch.setattr("appell.io.results.csv_rows", rows)
    result = run("simulate", "pendulum", "--t-end", "0.2", "--backend", "numpy", "--out", target)
    assert result.exit_code == 1, result.output
    assert "no space left on device" in result.stderr.lower() and str(target) in result.stderr
    assert "internal error" not in result.stderr and "Traceback" not in result.stderr
    assert target.read_bytes() == b"previous result\n"
    assert leftovers(tmp_path) == []


def test_read_only_file_system_is_an_environment_error(tmp_path, monkeypatch):
    """EROFS while creating the temporary file: exit 1 naming the cause, not 'internal error'."""
    import tempfile

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(tmp_path))

    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    result = run("simulate", "pendulum", "--t-end", "0.1", "--backend", "numpy", "--out", tmp_path / "a.csv")
    assert result.exit_code == 1, result.output
    assert "Read-only file system" in result.stderr and "internal error" not in result.stderr


def _tmpfs_command(size_kb: int, directory: Path, inner: str) -> list[str] | None:
    """A command running ``inner`` (sh) with a tmpfs of ``size_kb`` KiB mounted on
    ``directory``: in a private mount namespace (unshare) where possible, so that nothing
    leaks to the machine's mounts, else directly when we may mount; None if neither."""
    probe = directory / "probe"
    probe.mkdir()
    for prefix in (["unshare", "-rm"], []):
        if prefix and shutil.which("unshare") is None:
            continue
        check = subprocess.run(
            prefix + ["sh", "-c", f"mount -t tmpfs -o size=16k tmpfs {probe} && umount {probe}"],
            capture_output=True,
            timeout=30,
        )
        if check.returncode == 0:
            mount = f"mount -t tmpfs -o size={size_kb}k tmpfs {directory}"
            umount = f"; rc=$?; cd /; umount {directory}; exit $rc" if not prefix else ""
            return prefix + ["sh", "-c", f"{mount} && cd {directory} && {{ {inner} ; }}{umount}"]
    return None


def test_full_disk_on_a_real_tmpfs(tmp_path):
    """A 12 KiB tmpfs that the car's HDF5 file (about 26 KiB) cannot fill: the real
    ENOSPC from the kernel gives exit 1 and the message, never a crash (exit 139), and the
    previous file survives. Skipped where no tmpfs can be mounted (no root, no user namespaces)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    python = sys.executable
    inner = (
        f"echo previous > car.h5 && PYTHONPATH={SRC} {python} -m appell.io.cli simulate car --t-end 2 "
        f'--backend numpy --out car.h5; echo "rc=$?"; cat car.h5; ls -a'
    )
    command = _tmpfs_command(12, disk, inner)
    if command is None:
        pytest.skip("cannot mount a tmpfs here (needs root or unprivileged user namespaces)")
    proc = subprocess.run(command, capture_output=True, text=True, timeout=180, env=env_with_src())
    assert "rc=1" in proc.stdout, (proc.stdout, proc.stderr)
    assert "No space left on device" in proc.stderr and "internal error" not in proc.stderr
    listing = proc.stdout.split("rc=1", 1)[1]
    assert "previous" in listing and ".appell-" not in listing


def test_sweep_on_a_full_disk_keeps_the_finished_runs_and_resumes(tmp_path, monkeypatch):
    """The dataset cannot be written (ENOSPC): ResourceError naming the partial file, which
    holds every finished run; resume=True then computes none again and writes the dataset,
    whose largest tension is 2 m g at m = 2 (closed form)."""
    pytest.importorskip("dask.distributed")
    from appell.simulation import sweep as sweep_module

    out = tmp_path / "s.h5"
    args = (CATALOG["pendulum"](), ["m=1:2:3"], 1.2)
    kw = dict(output=out, samples=61, n_workers=1, processes=False, backend="numpy", progress=False)
    with monkeypatch.context() as patch:
        patch.setattr(files, "write_bytes", enospc)
        with pytest.raises(appell.ResourceError, match="No space left on device") as info:
            sweep_module.sweep(*args, **kw)
    assert "3 finished run(s) are kept in" in str(info.value) and "--resume" in str(info.value)
    assert not out.exists() and len(info.value.result.runs) == 3
    header, kept = sweep_module.read_partial(out.with_name("s.h5.partial"))
    assert header["model"] == "pendulum" and sorted(r["index"] for r in kept) == [0, 1, 2]

    def nothing_to_compute(model, todo, *a, **k):
        raise AssertionError(f"computed again: {todo}")

    monkeypatch.setattr(sweep_module, "_compute", nothing_to_compute)
    res = sweep_module.sweep(*args, **kw, resume=True)
    assert out.exists() and not out.with_name("s.h5.partial").exists()
    # the largest sample, 1.8 ms from the bottom at t = K(1/4)/sqrt(g/L) = 0.538 s, is
    # 0.75 g/L dt^2 = 2.3e-5 below 2 m g (a fixed grid: rounding does not move it); the run's error is 1e-9
    assert res.summary["multipliers"]["rod"]["max"] == pytest.approx(2 * 2.0 * G, rel=1e-3)


def test_sweep_partial_file_stops_growing_on_a_full_disk_but_keeps_complete_lines(tmp_path):
    """Appending to the partial file fails midway: the line is cut back, later runs are no
    longer appended, and the file reads back with the runs written before."""
    from appell.simulation.sweep import _PartialFile, read_partial

    path = tmp_path / "x.partial"
    partial = _PartialFile(path, {"appell_sweep_partial": 1, "t": np.arange(3.0)})
    partial.add({"index": 0, "status": 0, "t": np.arange(3.0)})
    real = partial.fh

    class Full:
        def __init__(self):
            self.written = 0

        def tell(self):
            return real.tell()

        def write(self, text):
            real.write(text[: len(text) // 2])
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def flush(self):
            real.flush()

        def seek(self, pos):
            real.seek(pos)

        def truncate(self):
            real.truncate()

        def close(self):
            real.close()

    partial.fh = Full()
    partial.add({"index": 1, "status": 0, "t": np.arange(3.0)})
    partial.add({"index": 2, "status": 0, "t": np.arange(3.0)})
    partial.close()
    header, runs = read_partial(path)
    assert [r["index"] for r in runs] == [0] and partial.kept == 1
    assert partial.error is not None and partial.error.errno == errno.ENOSPC


# ------------------------------------------------------- what sits at the output path
def test_output_through_a_symlink_writes_its_target_and_keeps_the_link(tmp_path):
    real = tmp_path / "real.csv"
    real.write_text("old\n")
    link = tmp_path / "link.csv"
    link.symlink_to(real.name)
    assert run("simulate", "pendulum", "--t-end", "0.1", "--backend", "numpy", "--out", link).exit_code == 0
    assert link.is_symlink() and os.readlink(link) == "real.csv"
    assert real.read_text().startswith("t,x,y,x_dot,y_dot,x_ddot,y_ddot,lambda_rod")


def test_replaced_file_keeps_its_mode(tmp_path):
    """A 0600 file stays 0600 (it used to become 0644); a new file gets 0666 & ~umask."""
    private = tmp_path / "private.csv"
    private.write_text("old\n")
    private.chmod(0o600)
    assert run("simulate", "pendulum", "--t-end", "0.1", "--backend", "numpy", "--out", private).exit_code == 0
    assert stat.S_IMODE(private.stat().st_mode) == 0o600 and private.read_text().startswith("t,")
    fresh = tmp_path / "fresh.csv"
    umask = os.umask(0o022)
    try:
        assert run("simulate", "pendulum", "--t-end", "0.1", "--backend", "numpy", "--out", fresh).exit_code == 0
    finally:
        os.umask(umask)
    assert stat.S_IMODE(fresh.stat().st_mode) == 0o644


def test_fifo_device_and_directory_are_refused_with_exit_2(tmp_path):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    result = run("simulate", "pendulum", "--t-end", "0.1", "--backend", "numpy", "--out", fifo)
    assert result.exit_code == 2 and str(fifo) in result.stderr and "FIFO" in result.stderr
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    if os.path.exists("/dev/null"):
        result = run("simulate", "pendulum", "--t-end", "0.1", "--backend", "numpy", "--plot", "/dev/null")
        assert result.exit_code == 2 and "/dev/null is a character device" in result.stderr
        assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    with pytest.raises(appell.ModelError, match="is a directory"):
        with files.atomic_path(tmp_path):
            pass
    assert leftovers(tmp_path) == []


def test_stale_temporary_of_a_dead_process_is_removed_on_the_next_write(tmp_path):
    """A write killed with SIGKILL leaves .<name>.appell-<pid>-*; the next write to the same
    file removes it, and keeps the temporary of a process that still runs."""
    dead = subprocess.Popen(["true"])
    dead.wait()
    stale = tmp_path / f".out.csv.appell-{dead.pid}-abc.csv"
    stale.write_text("half")
    alive = tmp_path / f".out.csv.appell-{os.getppid()}-xyz.csv"
    alive.write_text("busy")
    with files.atomic_path(tmp_path / "out.csv") as tmp:
        tmp.write_text("new\n")
    assert not stale.exists() and alive.exists()
    assert (tmp_path / "out.csv").read_text() == "new\n"


SLOW_WRITE = """
import sys, time
import appell.io.results
from appell.io.cli import main

def rows(self):
    yield ["t"]
    print("writing", flush=True)
    time.sleep(60)
    yield ["1"]

appell.io.results.csv_rows = rows
main(sys.argv[1:])
"""


@pytest.mark.parametrize("sig, code, word", [(signal.SIGTERM, 143, "terminated"), (signal.SIGINT, 130, "interrupted")])
def test_signal_during_a_write_removes_the_temporary_and_keeps_the_old_file(tmp_path, sig, code, word):
    """SIGTERM (exit 143) and Ctrl-C (SIGINT, exit 130; it used to be 1) while the CSV is
    being written: no hidden temporary file is left beside the target, the old file stays."""
    script = tmp_path / "slow.py"
    script.write_text(SLOW_WRITE)
    target = tmp_path / "out.csv"
    target.write_text("previous\n")
    # the script calls appell.io.cli.main, which keeps Python's SIGINT handling; Python installs
    # its handler only where SIGINT is not ignored at start, and a suite started in the
    # background by a shell without job control inherits SIGINT ignored: give the child the
    # default disposition (the appell command installs its own handler, appell_entry)
    proc = subprocess.Popen(
        [
            sys.executable,
            str(script),
            "simulate",
            "pendulum",
            "--t-end",
            "0.1",
            "--backend",
            "numpy",
            "--out",
            str(target),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env_with_src(),
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        assert proc.stdout.readline().strip() == "writing"
        assert leftovers(tmp_path)  # the temporary file exists while writing
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == code, err
    assert err.lstrip().startswith(f"error: {word}") and "Traceback" not in err
    assert target.read_text() == "previous\n" and leftovers(tmp_path) == []


# ------------------------------------------------------------- names used as paths
def test_hostile_model_name_stays_in_the_working_directory(tmp_path, monkeypatch):
    """name = "../x/evil": the default outputs of report and sweep are x_evil-report.html and
    x_evil-sweep.h5 in the working directory; nothing is written outside it."""
    work = tmp_path / "work"
    work.mkdir()
    model = pendulum_model(tmp_path, "../x/evil")
    monkeypatch.chdir(work)
    result = run("report", model, "--no-simulation")
    assert result.exit_code == 0, result.output
    assert (work / "x_evil-report.html").exists()
    pytest.importorskip("dask.distributed")
    result = run(
        "sweep", model, "--param", "m=1", "--t-end", "0.2", "--samples", "5", "--workers", "1", "--backend", "numpy"
    )
    assert result.exit_code == 0, result.output
    assert (work / "x_evil-sweep.h5").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.toml", "work"]


@pytest.mark.parametrize(
    "name, expected",
    [
        ("../x/evil", "x_evil"),
        ("/etc/passwd", "etc_passwd"),
        ("..", "model"),
        (".hidden", "hidden"),
        ("a b\nc", "a_b_c"),
        ("Pendel_ä", "Pendel"),
    ],
)
def test_default_file_name_is_one_safe_component(name, expected):
    path = files.default_file_name(name, "-report.html")
    assert path == Path(expected + "-report.html") and len(path.parts) == 1


def test_non_ascii_model_name_and_symbols_in_netcdf(tmp_path):
    """A model named 'Pendel_ä' and a coordinate named θ: the netCDF file is written (it raised
    UnicodeEncodeError, reported as a bug) with UTF-8 attributes and names."""
    model = pendulum_model(tmp_path, "Pendel_ä")
    out = tmp_path / "p.nc"
    result = run("simulate", model, "--t-end", "0.1", "--backend", "numpy", "--out", out)
    assert result.exit_code == 0, result.output
    import xarray as xr

    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert ds.attrs["model"] == "Pendel_ä"
    import sympy as sp

    th, thd = sp.symbols("θ θ_dot")
    system = appell.System(
        coordinates=[th],
        parameters={sp.Symbol("k"): 1.0},
        kinetic_energy=thd**2 / 2,
        potential_energy=sp.Symbol("k") * th**2 / 2,
        initial={"θ": 1.0, "θ_dot": 0.0},
    )
    from appell.simulation.simulate import simulate

    sol = simulate(appell.derive(system), 1.0, t_eval=[0.0, 1.0], progress=False)
    write_netcdf(sol, tmp_path / "theta.nc")
    with xr.open_dataset(tmp_path / "theta.nc", engine="h5netcdf") as ds:  # netCDF-4 names are UTF-8
        # theta'' = -theta; the default rtol 1e-9 over 1 s: 7e-11 (measured)
        assert ds["θ"].values == pytest.approx([1.0, np.cos(1.0)], abs=1e-7)


# ----------------------------------------------------------- the compiled-code cache
needs_cc = pytest.mark.skipif(shutil.which("cc") is None and not os.environ.get("APPELL_CC"), reason="no C compiler")

CACHE_PROBE = """
import sys, warnings
warnings.simplefilter("ignore")
import appell
from appell.examples.catalog import CATALOG
from appell.numerics.codegen import compile_c
m = compile_c(appell.derive(CATALOG["pendulum"]()), "c")
print(m.freshly_compiled, float(m.solve(0.0, [0.6, -0.8], [0.0, 0.0]).multipliers[0]))
"""


CORRUPTIONS = """
import hashlib, os, shutil, sys, warnings
from pathlib import Path
warnings.simplefilter("ignore")
import appell
from appell.examples.catalog import CATALOG
from appell.numerics.codegen import compile_c

foreign = sys.argv[1]
d = appell.derive(CATALOG["pendulum"]())
first = Path(os.environ["APPELL_CACHE_DIR"])


def tension(cache):
    os.environ["APPELL_CACHE_DIR"] = str(cache)
    m = compile_c(d, "c")
    return m.freshly_compiled, float(m.solve(0.0, [0.6, -0.8], [0.0, 0.0]).multipliers[0])


print("first", *tension(first))
lib = compile_c(d, "c").library_path  # the model's (the cache also holds the loop's and the fast-call extension)
cases = {
    "truncated": lambda so: so.write_bytes(so.read_bytes()[:100]),
    "empty": lambda so: so.write_bytes(b""),
    "foreign": lambda so: shutil.copyfile(foreign, so),
    "forged": lambda so: (shutil.copyfile(foreign, so),
                          so.with_name(so.name + ".sha256").write_text(hashlib.sha256(so.read_bytes()).hexdigest())),
}
for name, corrupt in cases.items():
    # one cache directory per case: the dynamic loader caches libraries by path
    cache = first.with_name(name)
    shutil.copytree(first, cache)
    corrupt(cache / lib.name)
    print(name, *tension(cache))
    print(name + "-again", *tension(cache))
"""


@needs_cc
def test_corrupt_cache_is_detected_and_rebuilt(tmp_path):
    """Truncated, empty and foreign libraries (a system library, also with a forged checksum)
    in $APPELL_CACHE_DIR are compiled again, never run: each gives the tension of the
    pendulum at rest at theta = acos(0.8), m g cos(theta) = 7.848 N, and then is trusted
    again; the process never aborts (it did with 'free(): invalid pointer', exit 134)."""
    proc = run_process(["-c", CORRUPTIONS, ctypes_library()], env=env_with_src(APPELL_CACHE_DIR=str(tmp_path / "c")))
    assert proc.returncode == 0, (proc.returncode, proc.stdout, proc.stderr)
    rows = {line.split()[0]: line.split()[1:] for line in proc.stdout.splitlines()}
    assert list(rows) == [
        "first",
        "truncated",
        "truncated-again",
        "empty",
        "empty-again",
        "foreign",
        "foreign-again",
        "forged",
        "forged-again",
    ]
    for case, (fresh, tension) in rows.items():
        assert fresh == ("False" if case.endswith("-again") else "True"), case
        assert float(tension) == pytest.approx(G * 0.8, rel=1e-12), case  # one split solve: rounding only


@needs_cc
def test_a_library_not_matching_its_checksum_is_compiled_again_with_a_warning(tmp_path, monkeypatch):
    monkeypatch.setenv("APPELL_CACHE_DIR", str(tmp_path))
    from appell.numerics.codegen import build_library, c_source

    source = c_source(appell.derive(CATALOG["knife_edge"]()))
    lib, fresh = build_library(source)
    assert fresh and build_library(source) == (lib, False)
    lib.write_bytes(lib.read_bytes()[:-1])
    with pytest.warns(RuntimeWarning, match="does not match its checksum"):
        assert build_library(source) == (lib, True)
    assert lib.with_name(lib.name + ".sha256").read_text().strip() == files_sha256(lib)


def ctypes_library() -> str:
    """A shared library of the system that is not appell's (libm, else libc)."""
    import ctypes.util

    for name in ("m", "c"):
        found = ctypes.util.find_library(name)
        if found:
            for directory in (
                "/lib/x86_64-linux-gnu",
                "/usr/lib/x86_64-linux-gnu",
                "/lib64",
                "/usr/lib64",
                "/lib",
                "/usr/lib",
                "/lib/aarch64-linux-gnu",
                "/usr/lib/aarch64-linux-gnu",
            ):
                if os.path.exists(os.path.join(directory, found)):
                    return os.path.join(directory, found)
    pytest.skip("no system shared library found to play a foreign one")


def files_sha256(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


@needs_cc
def test_concurrent_cold_cache_compiles_are_safe(tmp_path):
    """Three processes compile the same model into an empty cache at once: all succeed with
    the same tension, and one verified library per source is left."""
    cache = tmp_path / "cache"
    env = env_with_src(APPELL_CACHE_DIR=str(cache))
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", CACHE_PROBE], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
        )
        for _ in range(3)
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0, 0], outs
    assert all(float(o.split()[1]) == pytest.approx(G * 0.8, rel=1e-12) for o, _ in outs)  # rounding only
    libs = sorted(cache.glob("*.so"))
    assert len(libs) == 2  # the model's library and the fast-call extension (numerics/fastcall.c), once each
    for lib in libs:
        assert lib.with_name(lib.name + ".sha256").read_text().strip() == files_sha256(lib)
    assert not [p for p in cache.iterdir() if p.suffix == ".tmp" or "_load_" in p.name]


def test_backend_c_without_a_compiler_is_refused_and_auto_falls_back(monkeypatch, tmp_path):
    monkeypatch.setenv("APPELL_CC", "/nonexistent/cc")
    result = run("simulate", "pendulum", "--t-end", "0.1", "--backend", "c")
    assert result.exit_code == 2 and "needs a C compiler" in result.stderr
    out = tmp_path / "auto.csv"
    with pytest.warns(RuntimeWarning, match="no C compiler"):
        result = run("simulate", "pendulum", "--t-end", "0.1", "--backend", "auto", "--out", out)
    assert result.exit_code == 0 and out.exists()


def test_unwritable_cache_directory_falls_back_for_auto(monkeypatch, tmp_path):
    """$APPELL_CACHE_DIR on a file (not a directory): 'c' is an environment error naming the
    cache, 'auto' falls back to NumPy with a warning."""
    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("APPELL_CACHE_DIR", str(blocker / "cache"))
    d = appell.derive(CATALOG["pendulum"]())
    from appell.numerics.codegen import CompiledNumericModel, compile_c

    with pytest.raises(appell.ResourceError, match="compiled-code cache"):
        compile_c(d, "c")
    with pytest.warns(RuntimeWarning):
        model = compile_c(d, "auto")
    assert not isinstance(model, CompiledNumericModel)


# -------------------------------------------------------------------------- Dask
def _sweep_process(model, address, out, runs, timeout_s):
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "appell.io.cli",
            "sweep",
            str(model),
            "--param",
            f"m=1:2:{runs}",
            "--t-end",
            "2",
            "--samples",
            "201",
            "--backend",
            "numpy",
            "--scheduler",
            address,
            "--worker-timeout",
            str(timeout_s),
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env_with_src(),
    )


def _wait_for_runs(partial: Path, count: int, proc, timeout=180):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if partial.exists() and len(partial.read_text().splitlines()) > count:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.1)
    raise AssertionError("the sweep produced no run in time")


def test_dask_sweep_survives_losing_one_worker(dask_processes, tmp_path):
    """Two workers, one killed (SIGKILL) after the first run is in: every run is computed
    (Dask moves the lost runs to the other worker), exit 0, largest tension 2 m g at m = 2."""
    w1, _ = dask_processes.workers(2)
    out = tmp_path / "one.h5"
    proc = _sweep_process(example_path("pendulum"), dask_processes.address, out, 8, 30)
    try:
        _wait_for_runs(out.with_name("one.h5.partial"), 1, proc)
        w1.kill()
        stdout, stderr = proc.communicate(timeout=240)
    finally:
        proc.kill()
    assert proc.returncode == 0, (stdout, stderr)
    summary = json.loads(out.with_name("one.h5.summary.json").read_text())
    assert summary["status_counts"] == {"0": 8} and summary["failed_runs"] == []
    # the largest sample, 1.8 ms from the bottom at t = K(1/4)/sqrt(g/L) = 0.538 s, is
    # 0.75 g/L dt^2 = 2.3e-5 below 2 m g (a fixed grid: rounding does not move it); the run's error is 1e-9
    assert summary["multipliers"]["rod"]["max"] == pytest.approx(2 * 2.0 * G, rel=1e-3)


def test_dask_sweep_whose_workers_all_die_fails_and_lists_the_lost_runs(dask_processes, tmp_path):
    """Every worker killed mid-sweep: after --worker-timeout the runs not done are recorded as
    failed, the exit code is 1 (it was 0 with 8 of 12 runs cancelled), and the summary's
    extremes come from the successful runs only: the largest tension equals 2 m g for the
    largest mass among them (closed form)."""
    workers = dask_processes.workers(2)
    out = tmp_path / "all.h5"
    proc = _sweep_process(example_path("pendulum"), dask_processes.address, out, 12, 3)
    try:
        _wait_for_runs(out.with_name("all.h5.partial"), 1, proc)
        for w in workers:
            w.kill()
        stdout, stderr = proc.communicate(timeout=240)
    finally:
        proc.kill()
    assert proc.returncode == 1, (stdout, stderr)
    assert "runs of the sweep failed" in stderr and "internal error" not in stderr
    summary = json.loads(out.with_name("all.h5.summary.json").read_text())
    ok = [r for r in summary["runs"] if r["status"] >= 0]
    failed = summary["failed_runs"]
    assert ok and failed and len(ok) + len(failed) == 12
    assert all("worker" in f["message"] or "Killed" in f["message"] for f in failed), failed
    largest = max(r["parameters"]["m"] for r in ok)
    top = summary["multipliers"]["rod"]
    assert top["argmax_parameters"]["m"] == largest
    # the largest sample, 1.8 ms from the bottom at t = K(1/4)/sqrt(g/L) = 0.538 s, is
    # 0.75 g/L dt^2 = 2.3e-5 below 2 m g (a fixed grid: rounding does not move it); the run's error is 1e-9
    assert top["max"] == pytest.approx(2 * largest * G, rel=1e-3)
    assert f"{len(failed)} failed run(s)" in stdout


def test_summary_ignores_values_of_failed_runs():
    """A failed run whose last values blew up (3.15e6) is not the sweep's extreme."""
    from appell.simulation.sweep import RunRecord, _summary

    runs = (
        RunRecord(0, {"m": 1.0}, 0, "reached the final time", 0.1),
        RunRecord(1, {"m": 2.0}, -1, "the integrator failed", 0.1),
    )
    groups = {"multipliers": {"rod": np.array([[1.0, 2.0], [3.15e6, np.nan]])}}
    summary = _summary(groups, runs)
    assert summary["multipliers"]["rod"]["max"] == 2.0 and summary["multipliers"]["rod"]["argmax_run"] == 0
    assert summary["failed_runs"] == [
        {"run": 1, "parameters": {"m": 2.0}, "status": -1, "message": "the integrator failed"}
    ]
    assert summary["successful_runs"] == 1


@pytest.fixture
def junk_server():
    """A TCP server that answers every connection with bytes that are not Dask's protocol."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    stop = threading.Event()

    def serve():
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            with conn:
                conn.sendall(b"\xff" * 64 + b"HTTP/1.1 400 Bad Request\r\n\r\n")

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    stop.set()
    thread.join(timeout=5)
    server.close()


def test_bad_scheduler_addresses(junk_server, tmp_path):
    """Malformed: exit 2; a server that is not a Dask scheduler: exit 1 'cannot connect'
    (it gave 'internal error ... MemoryError 3.07 EiB'); a closed port: ResourceError."""
    pytest.importorskip("dask.distributed")
    for bad in ("tcp://host", "http://x:1", "tcp://a:99999", "a b:1"):
        result = run(
            "sweep", "pendulum", "--param", "m=1", "--t-end", "0.1", "--scheduler", bad, "--out", tmp_path / "s.h5"
        )
        assert result.exit_code == 2 and "bad Dask scheduler address" in result.stderr, (bad, result.output)
    result = run(
        "sweep", "pendulum", "--param", "m=1", "--t-end", "0.1", "--scheduler", junk_server, "--out", tmp_path / "s.h5"
    )
    assert result.exit_code == 1, result.output
    assert "cannot connect to the Dask scheduler" in result.stderr and "internal error" not in result.stderr
    from appell.simulation.sweep import sweep

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # closed once the block ends
    with pytest.raises(appell.ResourceError, match="cannot connect"):
        sweep(
            CATALOG["pendulum"](),
            ["m=1"],
            0.1,
            scheduler=f"tcp://127.0.0.1:{port}",
            connect_timeout=2,
            progress=False,
            output=tmp_path / "s.h5",
        )
    assert list(tmp_path.iterdir()) == []  # no partial file without runs


# --------------------------------------------------------------------- model files
def test_bom_at_the_start_of_a_model_file_is_accepted(tmp_path):
    """A UTF-8 byte-order mark (Windows editors): the same System as without it, and errors
    keep their line numbers."""
    text = example_path("pendulum").read_text(encoding="utf-8")
    assert appell.loads_model("\ufeff" + text, source="p.toml") == appell.loads_model(text, source="p.toml")
    with_bom = tmp_path / "bom.toml"
    with_bom.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    assert appell.load_model(with_bom).name == "pendulum"
    broken = tmp_path / "broken.toml"
    broken.write_bytes(b'\xef\xbb\xbf[model]\ncoordinates = ["x"]\n[mechanics]\nkinetic_energy = "x\'^"\n')
    with pytest.raises(appell.ModelError, match=r"broken.toml:4"):
        appell.load_model(broken)


def _kept_partial(tmp_path, monkeypatch, system, **kw):
    """A sweep of ``system`` whose dataset cannot be written (ENOSPC): its partial file keeps
    every finished run; returns the arguments to resume it."""
    from appell.simulation import sweep as sweep_module

    out = tmp_path / "s.h5"
    base = dict(output=out, samples=41, n_workers=1, processes=False, backend="numpy", progress=False, **kw)
    with monkeypatch.context() as patch:
        patch.setattr(files, "write_bytes", enospc)
        with pytest.raises(appell.ResourceError, match="No space left on device"):
            sweep_module.sweep(system, ["m=1:2:2"], 0.8, **base)
    assert out.with_name("s.h5.partial").exists()
    return sweep_module, base


@pytest.mark.parametrize(
    "change, named",
    [
        ("parameter", "the model's content"),  # --set L=1.5: another parameter value
        ("model", "the model's content"),  # the model file edited: another potential
        ("options", "the solver options"),  # another rtol
        ("backend", "the numeric backend"),
    ],
)
def test_resume_refuses_runs_computed_from_anything_else_and_names_it(tmp_path, monkeypatch, change, named):
    """Issue 20: a resumed sweep took the kept runs whenever the model name, grid and output
    times matched, mixing runs of another --set value or of an edited model file silently
    into the dataset. Every input of a run is now in the partial file's header, and a
    mismatch is refused by name; the kept file is left as it was."""
    import sympy as sp

    pendulum = CATALOG["pendulum"]()
    sweep_module, base = _kept_partial(tmp_path, monkeypatch, pendulum, rtol=1e-9)
    partial = (tmp_path / "s.h5.partial").read_bytes()
    system, kw = pendulum, dict(base)
    if change == "parameter":
        L = next(p for p in pendulum.parameter_values if p.name == "L")
        system = pendulum.replace(
            parameters=tuple(appell.Parameter(p.symbol, 1.5 if p.symbol == L else p.value) for p in pendulum.parameters)
        )
    elif change == "model":
        system = pendulum.replace(potential_energy=pendulum.potential_energy * sp.Rational(101, 100))
    elif change == "options":
        kw["rtol"] = 1e-10
    else:
        kw["backend"] = "c"
    with pytest.raises(appell.ModelError, match="holds the runs of another sweep") as info:
        sweep_module.sweep(system, ["m=1:2:2"], 0.8, **kw, resume=True)
    assert named in str(info.value) and str(info.value).count("differ") == 1
    assert (tmp_path / "s.h5.partial").read_bytes() == partial


def test_resume_of_the_same_sweep_in_a_new_process_takes_every_kept_run(tmp_path, monkeypatch):
    """The fingerprint is the same in other processes (canonical text of the expression graph, not a pickle that
    depends on hash randomisation: two fresh interpreters with different PYTHONHASHSEED read
    the same model file to the header's fingerprint), and resuming the same sweep computes
    nothing again."""
    from appell.simulation import sweep as sweep_module

    system = appell.load_model(example_path("pendulum"))
    _, base = _kept_partial(tmp_path, monkeypatch, system)
    header, kept = sweep_module.read_partial(tmp_path / "s.h5.partial")
    code = (
        "import sys; from appell.simulation.sweep import model_fingerprint; import appell; "
        f"print(model_fingerprint(appell.load_model({str(example_path('pendulum'))!r})))"
    )
    for seed in ("1", "2"):
        proc = subprocess.run(
            [sys.executable, "-c", code],
            capture_output=True,
            text=True,
            timeout=120,
            env={**env_with_src(), "PYTHONHASHSEED": seed},
        )
        assert proc.stdout.strip() == header["content"], proc.stderr

    def nothing_to_compute(model, todo, *a, **k):
        raise AssertionError(f"computed again: {todo}")

    monkeypatch.setattr(sweep_module, "_compute", nothing_to_compute)
    res = sweep_module.sweep(system, ["m=1:2:2"], 0.8, **base, resume=True)
    assert len(res.runs) == 2 and (tmp_path / "s.h5").exists()


def test_a_binary_or_foreign_partial_file_is_refused_by_name(tmp_path):
    """Issue 20: a binary FILE.h5.partial gave a UnicodeDecodeError; it is 'not the partial
    file of an appell sweep', like any JSON that is not one."""
    from appell.simulation.sweep import read_partial

    for content in (bytes(range(256)) * 4, b"\x89HDF\r\n\x1a\n" + b"\x00" * 64, b"[1, 2, 3]\n", b""):
        path = tmp_path / "s.h5.partial"
        path.write_bytes(content)
        with pytest.raises(appell.ModelError, match="is not the partial file of an appell sweep"):
            read_partial(path)

"""How appell's cost grows with the number of speeds n and of constraints s, on the n-link
pendulum with s = 1 (tip on a vertical line) and s = 2 (tip held at a point).

    .venv/bin/python benchmarks/scaling.py [--sizes 2,5,10,20]
        derivation (derive + NumPy functions), C generation + compilation, one evaluation
        (NumPy and C, called from Python)
    .venv/bin/python benchmarks/scaling.py --c-loop --sizes 10,20,40
        one evaluation (accelerations + the reaction) of appell's generated C from a C loop
        against the hand-written O(n) recursion (reference/nlink_aba.c), interleaved, and the
        arithmetic in appell's generated straight-line code
    .venv/bin/python benchmarks/scaling.py --compile [--dense] --sizes 10,20,40,50
        generated C of the catalog's chain (--dense: its expanded blocks, the route of systems
        without a tree, split into translation units): arithmetic, size, translation units, generation and
        compile time, peak memory of the compilers (a fresh process and empty cache per n)
    .venv/bin/python benchmarks/scaling.py --pipeline 50 [--pipeline 100]
        model file -> first compiled step with an empty cache, in a fresh process: time of each
        stage and peak memory of the process and of the compiler it ran
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

from appell import numeric_model

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import appell  # noqa: E402
from models import nlink_appell, nlink_parameters, nlink_state  # noqa: E402


def per_call(fn) -> float:
    timer = timeit.Timer(fn)
    number, _ = timer.autorange()
    return min(timer.repeat(5, number)) / number


def generated_operations(source: str) -> int:
    """Arithmetic operators (+ - * /) and calls in the generated straight-line code (the lines
    ``const double xN = ...``, ``x[N] = ...`` and ``oK[i] = ...``), not in the fixed solver loops."""
    ops = 0
    for line in source.splitlines():
        if re.match(r"\s+(const double x\d+|x\[\d+\]|o\d+\[\d+\]) = ", line):
            rhs = line.split("=", 1)[1]
            ops += len(re.findall(r"[-+*/]|\b(sin|cos|tan|exp|log|sqrt|pow)\(", rhs))
    return ops


def model_file(n: int) -> str:
    """The n-link pendulum with its tip on the line x = d as a model file (docs/model-format.md),
    with lengths l_i = 1 - i/(2n) m (the catalog's 1 - 0.02 i vanish at n = 50) and a start on
    the constraint (as :func:`models.nlink_state`)."""
    p = nlink_parameters(n)
    p.update({f"l{i}": 1.0 - i / (2 * n) for i in range(1, n + 1)})
    lengths = np.array([p[f"l{i}"] for i in range(1, n + 1)])
    rng = np.random.default_rng(1)
    th = rng.uniform(-0.3, 0.3, n)
    th[-1] = np.arcsin(np.clip((p["d"] - lengths[:-1] @ np.sin(th[:-1])) / lengths[-1], -1, 1))
    w = rng.uniform(-0.5, 0.5, n)
    w[-1] = -(lengths[:-1] * np.cos(th[:-1])) @ w[:-1] / (lengths[-1] * np.cos(th[-1]))
    lines = [
        "[model]",
        f'name = "pendulum{n}"',
        f"coordinates = [{', '.join(f'{chr(34)}theta{i}{chr(34)}' for i in range(1, n + 1))}]",
        "",
        "[parameters]",
    ]
    lines += [f"{k} = {v!r}" for k, v in p.items()]
    x, y = [], []
    for i in range(1, n + 1):
        x.append(f"l{i}*sin(theta{i})")
        y.append(f"- l{i}*cos(theta{i})")
        position = f'position = ["{" + ".join(x)}", "{" ".join(y)}", 0]'
        lines += ["", "[[bodies]]", f'name = "bob{i}"', f'mass = "m{i}"', position]
        # gravity as a force on each bob (the potential would exceed the format's 10000 characters)
        lines += ["", "[[forces]]", f'name = "weight{i}"', f'vector = [0, "-m{i}*g", 0]', position]
    lines += ["", "[constraints.tip]", 'kind = "holonomic"', f'expr = "{" + ".join(x)} - d"', "", "[initial]"]
    lines += [f"theta{i + 1} = {float(th[i])!r}" for i in range(n)]
    lines += [f'"theta{i + 1}\'" = {float(w[i])!r}' for i in range(n)]
    return "\n".join(lines) + "\n"


_PIPELINE = r"""
import json, resource, sys, time
t0 = time.perf_counter()
import appell
from appell.io.modelfile import load_model
from appell.core.derive import derive  # the derivation itself, not appell.derive's cache
from appell.numerics.codegen import c_source
t1 = time.perf_counter()
system = load_model(sys.argv[1])
t2 = time.perf_counter()
d = derive(system)
t3 = time.perf_counter()
cm = appell.numeric_model(d, "c")
t4 = time.perf_counter()
sol = appell.simulate(cm, 1e-3, t_eval=[0.0, 1e-3])
t5 = time.perf_counter()
src = cm.library_path.with_suffix(".c").read_text()
me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({"import": t1 - t0, "load": t2 - t1, "derive": t3 - t2, "generate+compile": t4 - t3,
                  "first step": t5 - t4, "total": t5 - t0, "source_kB": len(src) / 1024, "tree": float("tree_solve" in src),
                  "compiler_cpu_s": kids.ru_utime + kids.ru_stime,
                  "peak_process_MB": me.ru_maxrss / 1024}))
"""


_COMPILE = r"""
import json, resource, sys, time
sys.path.insert(0, sys.argv[2])
import appell
from appell.numerics import codegen as codegen_c
from models import nlink_appell
from scaling import generated_operations
d = appell.derive(nlink_appell(int(sys.argv[1])))
if sys.argv[3] == "dense" and hasattr(codegen_c, "particle_tree"):   # the route of systems without a tree
    import appell.numerics.codegen.source as codegen_source
    codegen_source.particle_tree = lambda inertia, n: None
t0 = time.perf_counter()
src = codegen_c.c_source(d)
t1 = time.perf_counter()
codegen_c.build_library(src)
t2 = time.perf_counter()
units = len(codegen_c.source_units(src)) if hasattr(codegen_c, "source_units") else 1
kids = resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({"ops": generated_operations(src), "kB": len(src) / 1024, "units": units, "generate_s": t1 - t0,
                  "compile_s": t2 - t1, "compiler_cpu_s": kids.ru_utime + kids.ru_stime}))
"""


def measuring_compiler(work: Path) -> tuple[str, Path]:
    """A compiler command that records each compiler run's peak resident memory (kB) in a log
    (``/usr/bin/time -f %M``; the compiler's own child processes, cc1 and as, included)."""
    log = work / "compiler-peaks.log"
    script = work / "cc-measured"
    script.write_text(f'#!/bin/sh\nexec /usr/bin/time -a -o "{log}" -f %M {shutil.which("cc")} "$@"\n')
    script.chmod(0o755)
    return str(script), log


def compiler_peaks(log: Path) -> list[float]:
    """Peak memory of each compiler run [MB]."""
    return [int(x) / 1024 for x in log.read_text().split()] if log.exists() else []


def compile_cost(n: int, dense: bool = False) -> dict:
    """C generation and compilation of the chain in a fresh process with an empty cache
    (``dense``: the expanded blocks, as for a system without a tree)."""
    work = Path(tempfile.mkdtemp(prefix="appell_compile_"))
    try:
        cc, log = measuring_compiler(work)
        env = {**os.environ, "APPELL_CACHE_DIR": str(work / "cache"), "APPELL_CC": cc}
        out = subprocess.run(
            [sys.executable, "-c", _COMPILE, str(n), str(HERE), "dense" if dense else "tree"],
            env=env,
            capture_output=True,
            text=True,
        )
        if out.returncode != 0:
            raise RuntimeError(out.stderr[-2000:])
        r = json.loads(out.stdout.strip().splitlines()[-1])
        r["compiler_peak_MB"] = max(compiler_peaks(log), default=0.0)
        return r
    finally:
        shutil.rmtree(work, ignore_errors=True)


def pipeline(n: int) -> dict:
    """Model file -> derive -> C (empty cache) -> one step of simulate, in a fresh process."""
    work = Path(tempfile.mkdtemp(prefix="appell_pipeline_"))
    try:
        (work / "chain.toml").write_text(model_file(n))
        cc, log = measuring_compiler(work)
        env = {**os.environ, "APPELL_CACHE_DIR": str(work / "cache"), "APPELL_CC": cc}
        out = subprocess.run(
            [sys.executable, "-c", _PIPELINE, str(work / "chain.toml")], env=env, capture_output=True, text=True
        )
        if out.returncode != 0:
            raise RuntimeError(out.stderr[-2000:])
        r = json.loads(out.stdout.strip().splitlines()[-1])
        peaks = compiler_peaks(log)
        r["peak_compiler_MB"] = max(peaks, default=0.0)
        # the process waits while its compilers run: at most min(units, cores) of them at once
        r["peak_with_compilers_MB"] = (
            r["peak_process_MB"] + sorted(peaks)[-1] * min(len(peaks), os.cpu_count() or 1)
            if peaks
            else r["peak_process_MB"]
        )
        return r
    finally:
        shutil.rmtree(work, ignore_errors=True)


def c_loop(sizes) -> None:
    """appell_evaluate from a C loop against reference/nlink_aba.c: 41 interleaved rounds, the
    best time of each and the median of the paired ratios."""
    cc = shutil.which("cc")
    work = Path(tempfile.mkdtemp(prefix="appell_cloop_"))
    exe = work / "bench_aba"
    subprocess.run(
        [
            cc,
            "-O2",
            "-o",
            str(exe),
            str(HERE / "reference" / "bench_aba.c"),
            str(HERE / "reference" / "nlink_aba.c"),
            "-lm",
            "-ldl",
        ],
        check=True,
    )
    print(
        f"{'n':>3} {'gen. ops':>9} {'appell C [us]':>14} {'O(n) recursion [us]':>20} {'ratio of best':>14} "
        f"{'median ratio':>13} {'rel. diff':>10}"
    )
    for n in sizes:
        d = appell.derive(nlink_appell(n))
        cm = numeric_model(d, "c")
        pv = np.array([p.value for p in d.system.parameters])
        y = np.concatenate(nlink_state(n))
        ops = generated_operations(cm.library_path.with_suffix(".c").read_text())
        iters = max(2000, 4_000_000 // (n * n))
        out = subprocess.run(
            [
                str(exe),
                str(cm.library_path),
                str(n),
                str(iters),
                str(d.partition.dependent[0]),
                *map(repr, y.tolist()),
                *map(repr, pv.tolist()),
            ],
            capture_output=True,
            text=True,
            check=True,
        )
        r = json.loads(out.stdout)
        print(
            f"{n:>3} {ops:>9} {r['appell_c_ns'] / 1e3:14.3f} {r['recursion_ns'] / 1e3:20.3f} "
            f"{r['appell_c_ns'] / r['recursion_ns']:14.2f} {r['median_ratio']:13.2f} {r['max_rel_diff']:10.1e}",
            flush=True,
        )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="2,5,10,20")
    ap.add_argument("--c-loop", action="store_true", help="C loop against the O(n) recursion")
    ap.add_argument("--pipeline", type=int, action="append", help="model file -> first compiled step at this n")
    ap.add_argument("--compile", action="store_true", help="generated C and its compilation")
    ap.add_argument("--dense", action="store_true", help="with --compile: the expanded blocks (no tree)")
    args = ap.parse_args()
    os.environ["APPELL_CACHE_DIR"] = tempfile.mkdtemp(prefix="appell_scaling_")
    if args.pipeline:
        for n in args.pipeline:
            r = pipeline(n)
            print(f"n = {n}: " + ", ".join(f"{k} {v:.1f}" for k, v in r.items()), flush=True)
        return
    if args.compile:
        print(
            f"{'n':>3} {'gen. ops':>9} {'source [kB]':>12} {'units':>6} {'generate [s]':>13} {'compile [s]':>12} "
            f"{'compiler CPU [s]':>17} {'compiler peak [MB]':>19}"
        )
        for n in map(int, args.sizes.split(",")):
            r = compile_cost(n, args.dense)
            print(
                f"{n:>3} {r['ops']:>9} {r['kB']:>12.0f} {r['units']:>6} {r['generate_s']:>13.1f} "
                f"{r['compile_s']:>12.1f} {r['compiler_cpu_s']:>17.1f} {r['compiler_peak_MB']:>19.0f}",
                flush=True,
            )
        return
    if args.c_loop:
        c_loop(list(map(int, args.sizes.split(","))))
        return
    print(
        f"{'n':>3} {'s':>2} {'derive [s]':>11} {'numpy fns [s]':>14} {'C gen+cc [s]':>13} {'C source [kB]':>14} "
        f"{'eval numpy [us]':>16} {'eval C [us]':>12}"
    )
    for n in map(int, args.sizes.split(",")):
        for s in (1, 2):
            if s > n - 1:
                continue
            t0 = time.perf_counter()
            d = appell.derive(nlink_appell(n, s))
            t1 = time.perf_counter()
            nm = numeric_model(d)
            t2 = time.perf_counter()
            cm = numeric_model(d, "c")
            t3 = time.perf_counter()
            th, w = nlink_state(n)
            y = np.concatenate([th, w])
            e_np, e_c = per_call(lambda: nm.evaluate(0.0, y)), per_call(lambda: cm.evaluate(0.0, y))  # noqa: B023
            src = cm.library_path.with_suffix(".c").stat().st_size / 1024
            print(
                f"{n:>3} {s:>2} {t1 - t0:11.2f} {t2 - t1:14.2f} {t3 - t2:13.2f} {src:14.0f} "
                f"{e_np * 1e6:16.1f} {e_c * 1e6:12.2f}",
                flush=True,
            )


if __name__ == "__main__":
    main()

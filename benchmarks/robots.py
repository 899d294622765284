"""Real robots from URDF files as shipped (``example-robot-data``) on appell's recursive route
for rigid-body trees, against Pinocchio (issue 22 §1 targets).

    python benchmarks/robots.py                       # the default robots, a table
    python benchmarks/robots.py --robot panda --runs 3
    python benchmarks/robots.py --c-loop              # from C: appell_forward against Pinocchio's C++

Columns:

* **first number** — a fresh Python process with an empty compiled-code cache: import appell,
  read the URDF (every joint's force and moment as outputs), derive, generate and compile the
  C, solve the accelerations at a state and evaluate every joint wrench; wall time, the
  median of ``--runs`` processes; **peak memory**: the largest resident set of that process
  plus that of its largest child (the C compiler);
* **Pinocchio load** — ``pin.buildModelFromUrdf`` in the same kind of fresh process (after
  its import);
* **eval from Python** — one state: appell's ``compiled.forward`` (the accelerations by the
  tree's factors of M, the multipliers and every joint's reaction, one C call) against Pinocchio's
  ``aba`` plus ``rnea`` (whose ``data.f`` are the joint wrenches), interleaved
  (benchmarks/harness.py), CPU time per call (pair of calls), and their ratio.

Targets (issue 22): first number 7-DOF arm ≤ 10 s, 18-DOF quadruped ≤ 15 s, Baxter or a
30-DOF humanoid ≤ 30 s, peak memory ≤ 500 MB; eval ≤ 1.0× Pinocchio.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from appell import numeric_model

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import harness  # noqa: E402

#: name -> (path under example-robot-data's robots folder, floating base)
ROBOTS = {
    "ur5": ("ur_description/urdf/ur5_robot.urdf", False),
    "panda": ("panda_description/urdf/panda.urdf", False),
    "solo12": ("solo_description/robots/solo12.urdf", True),
    "baxter": ("baxter_description/urdf/baxter.urdf", False),
    "talos": ("talos_data/robots/talos_reduced.urdf", True),
}
TARGETS = {"panda": 10.0, "solo12": 15.0, "baxter": 30.0, "talos": 30.0}


def robots_folder() -> Path:
    """:func:`harness.robots_folder`, or the script's end where it is not installed."""
    folder = harness.robots_folder()
    if folder is None:
        sys.exit("example-robot-data is not installed (pip install example-robot-data)")
    return folder


FIRST = """
import json, resource, sys, time, warnings
t0 = time.perf_counter()
import numpy as np
import appell
from appell.core.derive import derive  # the derivation itself, not appell.derive's cache
from appell.mechanism.urdf import urdf_system
warnings.simplefilter("ignore")
system = urdf_system(sys.argv[1], floating_base=sys.argv[2] == "1")
derivation = derive(system)
model = appell.numeric_model(derivation, "c")
q = np.full(len(system.coordinates), 0.3)
w = np.full(len(system.speeds), 0.2)
sol = model.solve(0.0, q, w)
out = model.outputs(0.0, q, w, solution=sol)
elapsed = time.perf_counter() - t0
own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
print(json.dumps({"seconds": elapsed, "peak_mb": max(own, child) / 1024, "own_mb": own / 1024,
                  "child_mb": child / 1024, "n": len(system.speeds), "bodies": len(derivation.inertia.tree.nodes),
                  "outputs": len(out), "route": type(derivation.inertia).__name__}))
"""

PIN_LOAD = """
import json, sys, time
import pinocchio as pin
t0 = time.perf_counter()
model = pin.buildModelFromUrdf(sys.argv[1], pin.JointModelFreeFlyer()) if sys.argv[2] == "1" else \\
    pin.buildModelFromUrdf(sys.argv[1])
print(json.dumps({"seconds": time.perf_counter() - t0}))
"""


def fresh(script: str, path: Path, floating: bool) -> dict:
    with tempfile.TemporaryDirectory() as cache:
        env = {**__import__("os").environ, "APPELL_CACHE_DIR": cache}
        out = subprocess.run(
            [sys.executable, "-c", script, str(path), "1" if floating else "0"],
            capture_output=True,
            text=True,
            env=env,
            check=True,
        )
    return json.loads(out.stdout.strip().splitlines()[-1])


def evaluation(path: Path, floating: bool, rounds: int) -> tuple[float, float, float]:
    """CPU time per (solve + joint_wrenches) and per (aba + rnea), and their ratio."""
    import warnings

    import pinocchio as pin

    import appell
    from appell.mechanism.urdf import urdf_system

    warnings.simplefilter("ignore")
    system = urdf_system(path, floating_base=floating, reactions=None)
    model = numeric_model(appell.derive(system), "c")
    pmodel = (
        pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer()) if floating else pin.buildModelFromUrdf(str(path))
    )
    data = pmodel.createData()
    rng = np.random.default_rng(0)
    q = rng.uniform(-0.5, 0.5, len(system.coordinates))
    w = rng.uniform(-0.5, 0.5, len(system.speeds))
    qp = pin.randomConfiguration(pmodel) if np.all(np.isfinite(pmodel.upperPositionLimit)) else pin.neutral(pmodel)
    vp = rng.uniform(-0.5, 0.5, pmodel.nv)
    zero = np.zeros(pmodel.nv)

    def ours():
        model.forward(0.0, q, w)

    def theirs():
        a = pin.aba(pmodel, data, qp, vp, zero)
        pin.rnea(pmodel, data, qp, vp, a)

    times = harness.interleaved({"appell": ours, "pinocchio": theirs}, rounds=rounds)
    return (
        harness.median(times["appell"]),
        harness.median(times["pinocchio"]),
        harness.ratio(times, "appell", "pinocchio"),
    )


#: what the C++ driver needs beside Pinocchio's headers (in the pin wheel): Eigen and urdfdom's
#: headers (Debian: libeigen3-dev, liburdfdom-headers-dev), and the configuration Pinocchio's
#: own build passes to its users
CXX_FLAGS = [
    "-O3",
    "-DNDEBUG",
    "-std=c++17",
    "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
    "-DBOOST_MPL_LIMIT_LIST_SIZE=30",
    "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
    "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
    "-DBOOST_FUSION_INVOKE_FUNCTION_OBJECT_MAX_ARITY=12",
    "-DBOOST_FUSION_INVOKE_PROCEDURE_MAX_ARITY=12",
    "-DPINOCCHIO_WITH_URDFDOM",
]


def c_loop_driver() -> Path:
    """reference/bench_robot.cpp compiled against the installed Pinocchio (about 2.5 minutes the
    first time; kept in ~/.cache/appell-bench by the source's hash)."""
    import hashlib
    import shutil

    source = HERE / "reference" / "bench_robot.cpp"
    prefix = robots_folder().parents[2]  # cmeel.prefix
    eigen = Path("/usr/include/eigen3")
    if not (eigen / "Eigen").is_dir() or not Path("/usr/include/urdf_model/model.h").exists():
        sys.exit(
            "the C loop needs Eigen's and urdfdom's headers (apt-get install libeigen3-dev liburdfdom-headers-dev)"
        )
    key = hashlib.sha256(source.read_bytes() + " ".join(CXX_FLAGS).encode()).hexdigest()[:16]
    exe = Path.home() / ".cache" / "appell-bench" / f"bench_robot-{key}"
    if not exe.exists():
        exe.parent.mkdir(parents=True, exist_ok=True)
        print("compiling the Pinocchio driver (a few minutes) ...", flush=True)
        tmp = exe.with_suffix(".tmp")
        subprocess.run(
            [
                shutil.which("c++") or "g++",
                *CXX_FLAGS,
                f"-I{prefix / 'include'}",
                f"-I{eigen}",
                str(source),
                "-o",
                str(tmp),
                f"-L{prefix / 'lib'}",
                "-lpinocchio_default",
                "-lpinocchio_parsers",
                "-ldl",
                f"-Wl,-rpath,{prefix / 'lib'}",
            ],
            check=True,
        )
        tmp.replace(exe)
    return exe


def c_loop(names) -> None:
    """appell_forward from a C++ loop against Pinocchio's C++ aba + rnea, interleaved (41
    rounds; best time of each and the median of the paired ratios)."""
    import warnings

    import appell
    from appell.mechanism.urdf import urdf_system

    warnings.simplefilter("ignore")
    exe, folder, rows = c_loop_driver(), robots_folder(), []
    for name in names:
        rel, floating = ROBOTS[name]
        system = urdf_system(folder / rel, floating_base=floating, reactions=None)
        derivation = appell.derive(system)
        model = appell.numeric_model(derivation, "c")
        rng = np.random.default_rng(0)
        q = rng.uniform(-0.5, 0.5, len(system.coordinates))
        w = rng.uniform(-0.5, 0.5, len(system.speeds))
        p = model.default_parameters
        sizes = [len(q), len(w), len(p), len(derivation.inertia.tree.nodes), derivation.constraints.count]
        out = subprocess.run(
            [
                str(exe),
                str(model.library_path),
                str(folder / rel),
                "1" if floating else "0",
                "20000",
                *map(str, sizes),
                *(repr(float(x)) for x in [*q, *w, *p]),
            ],
            capture_output=True,
            text=True,
            check=True,
        )
        r = json.loads(out.stdout)
        rows.append(
            [
                name + (" (floating)" if floating else ""),
                str(r["nv"]),
                f"{r['appell_ns'] / 1e3:.2f} µs",
                f"{r['pinocchio_ns'] / 1e3:.2f} µs",
                f"{r['median_ratio']:.2f}×",
            ]
        )
        print(" | ".join(rows[-1]), flush=True)
    print()
    print(
        f"machine: {harness.machine()}; {harness.today()}; commit {harness.git_commit()}; "
        f"both at {' '.join(CXX_FLAGS[:2])} (appell's library at its own -O3)"
    )
    print(
        harness.markdown_table(
            ["robot", "speeds", "appell_forward (C)", "Pinocchio aba + rnea (C++)", "median ratio"], rows
        )
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", action="append", choices=sorted(ROBOTS), help="robots (default: all)")
    parser.add_argument("--runs", type=int, default=1, help="fresh processes per robot for the first number")
    parser.add_argument("--rounds", type=int, default=15, help="interleaved rounds of the evaluation timing")
    parser.add_argument(
        "--c-loop", action="store_true", help="appell_forward from a C++ loop against Pinocchio's own C++ aba + rnea"
    )
    args = parser.parse_args()
    if args.c_loop:
        c_loop(args.robot or list(ROBOTS))
        return
    folder = robots_folder()
    rows = []
    for name in args.robot or list(ROBOTS):
        rel, floating = ROBOTS[name]
        path = folder / rel
        first = [fresh(FIRST, path, floating) for _ in range(args.runs)]
        seconds = statistics.median(r["seconds"] for r in first)
        peak = max(r["peak_mb"] for r in first)
        load = fresh(PIN_LOAD, path, floating)["seconds"]
        ours, theirs, ratio = evaluation(path, floating, args.rounds)
        limit = TARGETS.get(name)
        rows.append(
            [
                name + (" (floating)" if floating else ""),
                str(first[0]["n"]),
                str(first[0]["bodies"]),
                str(first[0]["outputs"]),
                f"{seconds:.1f} s" + (f" (≤ {limit:.0f})" if limit else ""),
                f"{peak:.0f} MB",
                f"{load * 1e3:.1f} ms",
                harness.us(ours),
                harness.us(theirs),
                f"{ratio:.2f}×",
            ]
        )
        print(" | ".join(rows[-1]), flush=True)
    print()
    print(f"machine: {harness.machine()}; {harness.today()}; commit {harness.git_commit()}")
    print(
        harness.markdown_table(
            [
                "robot",
                "speeds",
                "bodies",
                "outputs",
                "first number",
                "peak memory",
                "Pinocchio load",
                "appell forward",
                "Pinocchio aba + rnea",
                "ratio",
            ],
            rows,
        )
    )


if __name__ == "__main__":
    main()

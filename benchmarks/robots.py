"""Real robots from URDF files as shipped (``example-robot-data``) on appell's recursive route
for rigid-body trees, against Pinocchio (issue 22 §1 targets).

    python benchmarks/robots.py                       # the default robots, a table
    python benchmarks/robots.py --robot panda --runs 3

Columns:

* **first number** — a fresh Python process with an empty compiled-code cache: import appell,
  read the URDF (every joint's force and moment as outputs), derive, generate and compile the
  C, solve the accelerations at a state and evaluate every joint wrench; wall time, the
  median of ``--runs`` processes; **peak memory**: the largest resident set of that process
  plus that of its largest child (the C compiler);
* **Pinocchio load** — ``pin.buildModelFromUrdf`` in the same kind of fresh process (after
  its import);
* **eval from Python** — one state: appell's ``compiled.forward`` (the accelerations by the
  split solve, the multipliers and every joint's reaction, one C call) against Pinocchio's
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
    for base in map(Path, sys.path):
        folder = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if folder.is_dir():
            return folder
    sys.exit("example-robot-data is not installed (pip install example-robot-data)")


FIRST = """
import json, resource, sys, time, warnings
t0 = time.perf_counter()
import numpy as np
import appell
from appell.mechanism.urdf import urdf_system
warnings.simplefilter("ignore")
system = urdf_system(sys.argv[1], floating_base=sys.argv[2] == "1")
derivation = appell.derive(system)
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
        out = subprocess.run([sys.executable, "-c", script, str(path), "1" if floating else "0"],
                             capture_output=True, text=True, env=env, check=True)
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
    pmodel = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer()) if floating else pin.buildModelFromUrdf(str(path))
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
    return harness.median(times["appell"]), harness.median(times["pinocchio"]), harness.ratio(times, "appell", "pinocchio")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", action="append", choices=sorted(ROBOTS), help="robots (default: all)")
    parser.add_argument("--runs", type=int, default=1, help="fresh processes per robot for the first number")
    parser.add_argument("--rounds", type=int, default=15, help="interleaved rounds of the evaluation timing")
    args = parser.parse_args()
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
        rows.append([name + (" (floating)" if floating else ""), str(first[0]["n"]), str(first[0]["bodies"]),
                     str(first[0]["outputs"]),
                     f"{seconds:.1f} s" + (f" (≤ {limit:.0f})" if limit else ""), f"{peak:.0f} MB",
                     f"{load * 1e3:.1f} ms", harness.us(ours), harness.us(theirs), f"{ratio:.2f}×"])
        print(" | ".join(rows[-1]), flush=True)
    print()
    print(f"machine: {harness.machine()}; {harness.today()}; commit {harness.git_commit()}")
    print(harness.markdown_table(["robot", "speeds", "bodies", "outputs", "first number", "peak memory",
                                  "Pinocchio load", "appell forward", "Pinocchio aba + rnea", "ratio"], rows))


if __name__ == "__main__":
    main()

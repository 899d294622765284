"""Instant and fast by default (issue 46): what a new user gets without asking.

    python benchmarks/instant.py              # every table
    python benchmarks/instant.py --quick      # fewer rounds, no second robot

Tables (machine, load and date printed first; ratios within one run):

1. ``simulate(derive(load_model("car")))`` with the defaults (backend 'auto', the model
   file's method) against ``simulate(numeric_model(d, "c"))`` and against the NumPy model
   by name, interleaved (CPU time). Target: the default within 2x of the compiled model.
2. A robot's first run and second run in fresh processes sharing one cache folder (empty
   before the first): ``derive_file`` (load + derive, or the derivation cache) + the
   compiled model + one solve and every joint wrench; wall time. Target: second <= 0.35x
   first and <= 3 s (the Panda).
3. ``import appell`` against ``import sympy`` in fresh processes, median of ``--runs``
   (wall time). Target: <= 1.2x.
4. A URDF's first accelerations and joint wrenches through the numeric tree route
   (:mod:`appell.numerics.tree_route`) in a fresh process, import included, no compiler used;
   wall time, median of ``--runs``. Targets: <= 1 s the Panda, <= 3 s a 30-DOF humanoid.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import harness  # noqa: E402

ROBOTS = {"panda": ("panda_description/urdf/panda.urdf", False),
          "talos": ("talos_data/robots/talos_reduced.urdf", True)}


def robots_folder() -> Path | None:
    for base in map(Path, sys.path):
        folder = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if folder.is_dir():
            return folder
    return None


def _fresh(code: str, *args, env=None) -> dict:
    import os

    out = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True,
                         env={**os.environ, **(env or {})}, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def car(rounds: int) -> None:
    import warnings

    import appell

    warnings.simplefilter("ignore", RuntimeWarning)
    d = appell.derive(appell.load_model("car"))
    compiled, numpy = appell.numeric_model(d, "c"), appell.numeric_model(d, "numpy")
    appell.simulate(d)  # built once (kept), as a user's second call finds it
    times = harness.interleaved({
        "simulate(d) (defaults)": lambda: appell.simulate(d),
        "simulate(numeric_model(d, 'c'))": lambda: appell.simulate(compiled),
        "simulate(numeric_model(d, 'numpy'))": lambda: appell.simulate(numpy),
    }, rounds=rounds, batch=False)
    reference = "simulate(numeric_model(d, 'c'))"
    rows = [[name, f"{harness.median(v) * 1e3:.1f} ms", f"{harness.ratio(times, name, reference):.2f}x"]
            for name, v in times.items()]
    print("\n## 1. the car, 10 s, the model file's [simulation] (method "
          f"{dict(d.system.settings).get('method')}), CPU time\n")
    print(harness.markdown_table(["call", "median", "ratio to compiled"], rows))


RUN = """
import json, sys, time, warnings
t0 = time.perf_counter()
import numpy as np
import appell
warnings.simplefilter("ignore")
d = appell.derive_file(sys.argv[1], floating_base=sys.argv[2] == "1")
t1 = time.perf_counter()
m = appell.numeric_model(d)
q = np.full(len(m.coordinate_names), 0.3); w = np.full(len(m.speed_names), 0.2)
sol = m.solve(0.0, q, w); out = m.outputs(0.0, q, w, solution=sol)
print(json.dumps({"seconds": time.perf_counter() - t0, "derive": t1 - t0}))
"""


def second_run(name: str, path: Path, floating: bool) -> None:
    with tempfile.TemporaryDirectory() as cache:
        env = {"APPELL_CACHE_DIR": cache}
        first = _fresh(RUN, path, "1" if floating else "0", env=env)
        second = _fresh(RUN, path, "1" if floating else "0", env=env)
    print(f"\n## 2. {name}: first and second run, fresh processes, one cache folder (wall time)\n")
    print(harness.markdown_table(
        ["run", "to derivation", "to first joint wrenches"],
        [["first (empty cache)", f"{first['derive']:.2f} s", f"{first['seconds']:.2f} s"],
         ["second (warm cache)", f"{second['derive']:.2f} s", f"{second['seconds']:.2f} s"],
         ["ratio", f"{second['derive'] / first['derive']:.2f}x", f"{second['seconds'] / first['seconds']:.2f}x"]]))


IMPORT = """
import json, sys, time
t0 = time.perf_counter()
__import__(sys.argv[1])
print(json.dumps({"seconds": time.perf_counter() - t0}))
"""


def imports(runs: int) -> None:
    times = {"appell": [], "sympy": []}
    for _ in range(runs):  # interleaved
        for module in times:
            times[module].append(_fresh(IMPORT, module)["seconds"])
    a, s = statistics.median(times["appell"]), statistics.median(times["sympy"])
    print("\n## 3. import, fresh processes (wall time, median)\n")
    print(harness.markdown_table(["import", "median", "ratio to sympy"],
                                 [["appell", f"{a * 1e3:.0f} ms", f"{a / s:.3f}x"],
                                  ["sympy", f"{s * 1e3:.0f} ms", "1x"]]))


ROUTE = """
import json, sys, time, warnings
t0 = time.perf_counter()
import numpy as np
from appell.numerics.tree_route import tree_route
warnings.simplefilter("ignore")
route = tree_route(sys.argv[1], floating_base=sys.argv[2] == "1")
q = np.full(route.n, 0.3); w = np.full(route.n, 0.2)
if sys.argv[2] == "1":  # the free joint's quaternion at the identity
    names = route.coordinate_names
    q[[k for k, n in enumerate(names) if n.endswith(("_q1", "_q2", "_q3"))]] = 0.0
    q[[k for k, n in enumerate(names) if n.endswith("_q0")]] = 1.0
a, out = route.forward(0.0, q, w)
print(json.dumps({"seconds": time.perf_counter() - t0, "n": route.n, "outputs": len(out)}))
"""


def numeric_route(name: str, path: Path, floating: bool, runs: int) -> None:
    results = [_fresh(ROUTE, path, "1" if floating else "0") for _ in range(runs)]
    seconds = statistics.median(r["seconds"] for r in results)
    print(f"\n## 4. {name} ({results[0]['n']} speeds): first accelerations and {results[0]['outputs']} joint "
          "wrench components by the numeric tree route, fresh process with its imports (wall time, median)\n")
    print(harness.markdown_table(["robot", "first numbers"], [[name, f"{seconds:.2f} s"]]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    runs = 3 if args.quick else args.runs
    print("# instant and fast by default\n")
    print(f"{harness.today()}; {harness.machine()}; {harness.load()}; {harness.versions()}")
    car(5 if args.quick else 15)
    imports(runs)
    folder = robots_folder()
    if folder is None:
        print("\n(example-robot-data is not installed: no robot tables)")
        return
    for name, (rel, floating) in ROBOTS.items():
        if args.quick and name != "panda":
            continue
        numeric_route(name, folder / rel, floating, runs)
    second_run("panda", folder / ROBOTS["panda"][0], False)


if __name__ == "__main__":
    main()

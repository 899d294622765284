"""Gear and rack couplings at scale: a train of 11 spur gears on parallel shafts (10 gear
meshes) with a rack under each of the first 10 gears (10 rack-and-pinion meshes): 21
coordinates, 20 couplings, one degree of freedom, every bearing and guide load an output.

    .venv/bin/python benchmarks/gear_train.py [--couplings 20]

Prints the time to build the System, derive it (appell.derive) and compile it
(numeric_model(d, 'c'); into an empty compile cache, a cold build, unless --warm), and one evaluation of the accelerations, multipliers and outputs
(target of issue 43: derive and compile in at most 10 s).
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time

import numpy as np

import appell
from appell import numeric_model
from appell.core.derive import derive  # the derivation itself, not appell.derive's cache
from appell.mechanism import Mechanism


def gear_train(couplings: int = 20) -> appell.System:
    """``couplings // 2`` gear meshes along x (radius 0.05 m, ratio 1) and as many racks,
    each under one gear of the train; a motor torque on the first gear, gravity along -y."""
    meshes = couplings // 2
    racks = couplings - meshes
    mech = Mechanism("gear_train", gravity=(0, -9.81, 0))
    for i in range(meshes + 1):
        gear = mech.body(f"gear{i}", 0.5, inertia=(1e-4, 1e-4, 6e-4))
        mech.revolute(f"shaft{i}", "ground", gear, origin=(0.1 * i, 0, 0))
        if i:
            mech.gear(f"mesh{i}", f"shaft{i - 1}", f"shaft{i}", 1.0, pressure_angle=math.radians(20))
    for i in range(racks):
        rack = mech.body(f"rack{i}", 1.0, inertia=(1e-3, 1e-3, 1e-3))
        mech.prismatic(f"guide{i}", "ground", rack, axis=(1, 0, 0), origin=(0.1 * i, -0.06, 0.01 * (i % 2)))
        mech.rack_pinion(f"teeth{i}", f"shaft{i}", f"guide{i}", 0.05, pressure_angle=math.radians(20))
    mech.actuator("motor", "shaft0", 2.0)
    return mech.system()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--couplings", type=int, default=20)
    ap.add_argument("--warm", action="store_true", help="keep the compile cache (default: an empty one)")
    args = ap.parse_args()
    if args.warm:
        run(args.couplings)
        return
    with tempfile.TemporaryDirectory(prefix="appell-gear-train-") as cache:
        os.environ["APPELL_CACHE_DIR"] = cache
        run(args.couplings)


def run(couplings: int):
    """Build, derive, compile and evaluate the train; print the table."""
    times = {}
    t0 = time.perf_counter()
    system = gear_train(couplings)
    times["build System"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    d = derive(system)
    times["derive"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    model = numeric_model(d, "c")
    times["compile (C)"] = time.perf_counter() - t0
    n = len(system.coordinates)
    q, w = np.zeros(n), np.zeros(n)
    t0 = time.perf_counter()
    sol = model.solve(0.0, q, w)
    out = model.outputs(0.0, q, w, solution=sol)
    times["one solve + outputs"] = time.perf_counter() - t0
    print(f"gear train: {n} coordinates, {len(system.constraints)} couplings, {len(out)} outputs")
    print(f"{'stage':<22}{'seconds':>10}")
    for stage, seconds in times.items():
        print(f"{stage:<22}{seconds:>10.3f}")
    total = times["build System"] + times["derive"] + times["compile (C)"]
    print(f"{'derive + compile':<22}{total:>10.3f}   (target <= 10 s)")


if __name__ == "__main__":
    main()

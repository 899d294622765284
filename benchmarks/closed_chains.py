"""A loop-closed biped of Cassie's size on appell's closed-chain route (issue 41 part 2-3
targets), against Pinocchio's constraint dynamics on the same MJCF file.

    python benchmarks/closed_chains.py            # the table, machine and date
    python benchmarks/closed_chains.py --rounds 5

The model is ``src/appell/examples/loop_biped.xml`` (22 degrees of freedom, a floating
pelvis, four leg loops closed by ``connect``; written for appell, not Agility's Cassie).

* **file to first evaluation** — a fresh Python process: import appell, read the MJCF file
  (MuJoCo's compiler, :func:`appell.mechanism.mjcf.mjcf_mechanism`), build the closed-chain
  model (:func:`appell.loop_model`: the joints' small terms compiled) and evaluate the
  accelerations, every loop force and every joint wrench at a state; wall time and the
  process's peak resident memory. Nothing is cached between runs;
* **one evaluation** — appell's ``LoopModel.evaluate`` (accelerations, 13 multipliers, 17
  joint wrenches; NumPy recursions) against Pinocchio's ``constraintDynamics`` with the four
  ``RigidConstraintModel`` s its MJCF reader builds (accelerations and contact forces), and
  its ``lcaba`` where it runs; interleaved (benchmarks/harness.py), CPU time per call;
* **inverse dynamics** — the legs on a fixed pelvis along 1,000 samples: the four motors per
  leg given, the ankles, toes and rods from the loops, torques, loop forces and joint wrenches.

Targets (issue 41): file to first evaluation ≤ 30 s; one evaluation ≤ 1.0× Pinocchio from C,
≤ 1.5× from Python; inverse dynamics along 1,000 samples ≤ 1 s. appell's route is NumPy here
(no C for the loop rows yet): the table says so.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from harness import interleaved, machine, median, optional, ratio, target, today, versions  # noqa: E402

MODEL = HERE.parent / "src" / "appell" / "examples" / "loop_biped.xml"

FIRST = r"""
import time, resource, json, sys, warnings
t0 = time.perf_counter()
import numpy as np
import appell
from appell.mechanism.mjcf import load_mjcf, mjcf_mechanism
warnings.simplefilter("ignore")
mech, _ = mjcf_mechanism(load_mjcf(sys.argv[1]), sys.argv[1])
model = appell.loop_model(mech)
q = np.array([model.start.get(n, 0.0) for n in model.coordinate_names])
state = model.evaluate(q, np.zeros(model.n))
assert np.isfinite(state.a).all() and len(state.wrenches) == 17
print(json.dumps({"seconds": time.perf_counter() - t0,
                  "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def first_evaluation() -> dict:
    out = subprocess.run([sys.executable, "-c", FIRST, str(MODEL)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _appell_model():
    import warnings

    import appell
    from appell.mechanism.mjcf import load_mjcf, mjcf_mechanism

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech, _ = mjcf_mechanism(load_mjcf(MODEL), str(MODEL))
    return appell.loop_model(mech)


def evaluation(rounds: int) -> dict:
    """Per-call CPU times of appell's evaluation and Pinocchio's constrained dynamics at one
    state (the base at rest in the identity pose, the joints' angles and rates random), and the
    largest difference of their joint accelerations."""
    model = _appell_model()
    rng = np.random.default_rng(0)
    q = np.zeros(model.n)
    q[3] = 1.0
    q[7:] = rng.uniform(-0.3, 0.3, model.n - 7)
    w = np.zeros(model.n)
    w[7:] = rng.normal(size=model.n - 7)
    candidates = {"appell": lambda: model.evaluate(q, w)}
    pin = optional("pinocchio")
    agree = None
    if pin is not None:
        pmodel, cmodels = pin.buildModelAndLegacyConstraintsFromMJCF(str(MODEL))
        pdata = pmodel.createData()
        cdatas = [c.createData() for c in cmodels]
        pin.initConstraintDynamics(pmodel, pdata, cmodels, cdatas)
        prox = pin.ProximalSettings(1e-12, 1e-12, 3)
        pq = np.concatenate([q[:3] + pin.neutral(pmodel)[:3], [0, 0, 0, 1], q[7:]])  # pin: x y z qx qy qz qw
        pv = np.concatenate([np.zeros(6), w[7:]])
        tau = np.zeros(pmodel.nv)
        candidates["pinocchio constraintDynamics"] = lambda: pin.constraintDynamics(pmodel, pdata, pq, pv, tau, cmodels,
                                                                                     cdatas, prox)
        a_pin = np.array(pin.constraintDynamics(pmodel, pdata, pq, pv, tau, cmodels, cdatas, prox))
        agree = float(np.abs(a_pin[6:] - model.evaluate(q, w).a[7:]).max())
        try:
            pin.computeJointMinimalOrdering(pmodel, pdata, cmodels)
            pin.lcaba(pmodel, pdata, pq, pv, tau, cmodels, cdatas, prox)
            candidates["pinocchio lcaba"] = lambda: pin.lcaba(pmodel, pdata, pq, pv, tau, cmodels, cdatas, prox)
        except Exception as exc:  # noqa: BLE001 - a peer's API that may be absent
            print(f"(lcaba not run: {exc})")
    times = interleaved(candidates, rounds=rounds)
    return {"times": times, "agree": agree}


def inverse(samples: int = 1000) -> float:
    """Wall time of the legs' inverse dynamics on a fixed pelvis along ``samples`` samples."""
    import warnings

    import appell
    from appell.mechanism.mjcf import load_mjcf, mjcf_mechanism

    xml = MODEL.read_text().replace('<freejoint name="floating_base"/>', "")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech, _ = mjcf_mechanism(load_mjcf(xml))
    model = appell.loop_model(mech)
    from appell.examples.parallel_examples import biped_gait

    t = np.linspace(0.0, 1.0, samples)
    given = biped_gait(t)
    t0 = time.perf_counter()
    appell.inverse_dynamics(model, t, given)
    return time.perf_counter() - t0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--samples", type=int, default=1000)
    args = parser.parse_args(argv)
    print(f"# closed chains: {MODEL.name} (22 DOF, 4 loops, floating base)\n")
    print(f"{today()}; {machine()}\n{versions()}\n")
    first = first_evaluation()
    ev = evaluation(args.rounds)
    inv = inverse(args.samples)
    times = ev["times"]
    print("| measure | appell | peer | ratio appell / peer |")
    print("|---|---|---|---|")
    print(f"| file to first evaluation (fresh process) | {first['seconds']:.1f} s, {first['peak_mb']:.0f} MB peak | — | — |")
    best_peer = None
    for peer in [k for k in times if k != "appell"]:
        r = ratio(times, "appell", peer)
        best_peer = r if best_peer is None else max(best_peer, r)
        print(f"| one evaluation from Python (every loop force and joint wrench) | {median(times['appell']) * 1e6:.0f} µs "
              f"| {peer} {median(times[peer]) * 1e6:.1f} µs | {r:.1f}× |")
    print(f"| inverse dynamics, legs, {args.samples} samples | {inv:.2f} s | — | — |")
    if ev["agree"] is not None:
        print(f"\njoint accelerations, appell against Pinocchio at the state: largest difference {ev['agree']:.2e}")
    print("\n" + "\n".join([
        target("file to first evaluation", first["seconds"], 30, " s"),
        target("one evaluation from Python against Pinocchio's fastest", best_peer, 1.5),
        "- one evaluation from C (target ≤ 1×): not measured — the loop rows have no C code yet",
        target(f"inverse dynamics along 1000 samples (from {args.samples} measured)", inv * 1000 / args.samples, 1.0,
               " s"),
    ]))


if __name__ == "__main__":
    main()

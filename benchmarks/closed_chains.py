"""A loop-closed biped of Cassie's size and a parallel gripper on appell's closed-chain route
(issue 41 part 2-3 targets), against Pinocchio's constraint dynamics on the same MJCF file.

    python benchmarks/closed_chains.py            # the table, machine and date
    python benchmarks/closed_chains.py --rounds 5

The models are ``src/appell/examples/loop_biped.xml`` (22 degrees of freedom, a floating
pelvis, four leg loops closed by ``connect``; written for appell, not Agility's Cassie) and
``src/appell/examples/parallel_gripper.xml`` (the 2F-85's structure: two planar four-bar
fingers closed by ``connect``, a joint equality, an actuator on a tendon, armature rotors).

* **file to first evaluation** — a fresh Python process with an empty cache (its own empty
  ``$APPELL_CACHE_DIR``): import appell, read the MJCF file (MuJoCo's compiler,
  :func:`appell.mechanism.mjcf.mjcf_mechanism`; the gripper by
  :func:`~appell.mechanism.mjcf.mjcf_system` for its equality and actuator), build the
  closed-chain model (:func:`appell.loop_model`: the joints' small terms compiled) and evaluate
  the accelerations, every loop force and every joint wrench at a state; wall time, CPU time
  (the process's and the C compiler's it started: the fair measure on a loaded machine) and
  the peak resident memory of the process and of its largest child (the C compiler, or a
  forked copy of the process);
* **one evaluation** — appell's ``LoopModel.evaluate`` (accelerations, 13 multipliers, 17
  joint wrenches; one call of the compiled ``appell_loop_evaluate``, and the NumPy route for
  comparison) against Pinocchio's ``constraintDynamics`` with the four
  ``RigidConstraintModel`` s its MJCF reader builds (accelerations and contact forces), and
  its ``lcaba`` where it runs; interleaved (benchmarks/harness.py), CPU time per call;
* **one evaluation from C** — like with like, no Python in the loop on either side:
  ``appell_loop_evaluate`` (appell's generated C as ``loop_model`` compiles it; accelerations,
  every multiplier, every joint wrench) called in a C loop (``reference/bench_loops.c``), and
  Pinocchio 4's ``constraintDynamics`` (``initConstraintDynamics`` once before the loop) and
  ``lcaba`` (``computeJointMinimalOrdering`` once) called in a C++ loop
  (``pinocchio_loop.cpp``: the model and its four ``RigidConstraintModel`` s that Python's
  ``buildModelAndLegacyConstraintsFromMJCF`` reads, written joint by joint to a text file and
  rebuilt there; header only, Pinocchio's templates compiled in that unit with
  ``g++ -O3 -march=native -DNDEBUG``; the headers of the pip package ``pin`` and Eigen's of
  ``cmeel-eigen``, extra ``[bench]``; skipped with a note where g++ or the headers are
  missing). Each: per-call CPU time of the best and the median of 41 rounds at the same state,
  its accelerations checked against appell's;
* **inverse dynamics** — the legs on a fixed pelvis along 1,000 samples: the four motors per
  leg given, the ankles, toes and rods from the loops, torques, loop forces and joint wrenches.

Targets (issue 41): file to first evaluation ≤ 30 s (biped), ≤ 15 s (gripper), peak memory
≤ 500 MB; one evaluation ≤ 1.0× Pinocchio from C, ≤ 1.5× from Python; inverse dynamics along
1,000 samples ≤ 1 s.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from harness import interleaved, machine, median, optional, ratio, target, today, versions  # noqa: E402

MODEL = HERE.parent / "src" / "appell" / "examples" / "loop_biped.xml"
GRIPPER = MODEL.parent / "parallel_gripper.xml"

FIRST = r"""
import time, resource, json, sys, warnings
t0 = time.perf_counter()
import numpy as np
import appell
from appell.mechanism.mjcf import load_mjcf, mjcf_mechanism, mjcf_system
warnings.simplefilter("ignore")
if sys.argv[2] == "system":
    model = appell.loop_model(mjcf_system(sys.argv[1], actuators="controls"))
else:
    mech, _ = mjcf_mechanism(load_mjcf(sys.argv[1]), sys.argv[1])
    model = appell.loop_model(mech)
q = np.array([model.start.get(n, 0.0) for n in model.coordinate_names])
state = model.evaluate(q, np.zeros(model.n), np.ones(len(model.control_names)))
assert model.backend == "c" and np.isfinite(state.a).all() and len(state.wrenches) == int(sys.argv[3])
own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({"seconds": time.perf_counter() - t0, "peak_mb": own.ru_maxrss / 1024,
                  "cpu": own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime,
                  "compiler_peak_mb": kids.ru_maxrss / 1024}))
"""


def first_evaluation(path=MODEL, route="mechanism", joints=17) -> dict:
    """Wall time and peak memory of a fresh process from the file to the first compiled
    evaluation, with an empty cache of derivations and compiled code."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "APPELL_CACHE_DIR": cache}
        env.pop("APPELL_NO_CACHE", None)
        out = subprocess.run(
            [sys.executable, "-c", FIRST, str(path), route, str(joints)],
            capture_output=True,
            text=True,
            check=True,
            env=env,
        )
    return json.loads(out.stdout.strip().splitlines()[-1])


def _appell_model(backend="auto"):
    import warnings

    import appell
    from appell.mechanism.mjcf import load_mjcf, mjcf_mechanism

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech, _ = mjcf_mechanism(load_mjcf(MODEL), str(MODEL))
    return appell.loop_model(mech, backend)


def from_c(model, q, w, iterations=5000) -> tuple[float, float] | None:
    """CPU seconds per call (best and median round) of the compiled ``appell_loop_evaluate`` at
    ``(q, w)`` in a C loop (``reference/bench_loops.c``), or None without a compiled model or a
    C compiler."""
    cc = shutil.which("cc")
    if model.compiled is None or cc is None:
        return None
    with tempfile.TemporaryDirectory() as tmp:
        exe = Path(tmp) / "bench_loops"
        subprocess.run([cc, "-O2", str(HERE / "reference" / "bench_loops.c"), "-o", str(exe), "-ldl"], check=True)
        p = model.parameter_values
        sizes = [len(q), len(w), len(model.control_names), len(p), len(model.constraint_names), len(model.joints)]
        out = subprocess.run(
            [
                str(exe),
                str(model.compiled.library_path),
                str(iterations),
                *map(str, sizes),
                *(repr(float(x)) for x in [*q, *w, *p]),
            ],
            capture_output=True,
            text=True,
            check=True,
        )
    r = json.loads(out.stdout)
    assert r["status"] == 0 and abs(r["a0"] - model.evaluate(q, w).a[0]) <= 1e-9 * max(1.0, abs(r["a0"]))
    return r["appell_ns"] * 1e-9, r["appell_median_ns"] * 1e-9


#: g++ flags of pinocchio_loop.cpp: Pinocchio's own compile definitions (its CMake targets)
CXXFLAGS = (
    "-O3",
    "-march=native",
    "-DNDEBUG",
    "-std=c++17",
    "-DBOOST_MPL_LIMIT_LIST_SIZE=30",
    "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
    "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
    "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
)


def pinocchio_executable() -> tuple[Path | None, str]:
    """``pinocchio_loop.cpp`` built (kept in the temporary folder under a hash of its source and
    flags: the build takes minutes), or None and the reason it is not."""
    gxx = shutil.which("g++")
    inc = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix" / "include"
    needs = {
        "g++": gxx,
        "Pinocchio's headers (pip package pin)": (inc / "pinocchio").is_dir(),
        "Eigen's headers (pip package cmeel-eigen)": (inc / "eigen3" / "Eigen").is_dir(),
        "Boost's headers (pip package cmeel-boost)": (inc / "boost").is_dir(),
    }
    missing = [k for k, ok in needs.items() if not ok]
    if missing:
        return None, f"not built: no {', '.join(missing)} (pip install appell[bench])"
    source = HERE / "pinocchio_loop.cpp"
    key = hashlib.sha256(source.read_bytes() + " ".join(CXXFLAGS).encode() + str(inc).encode()).hexdigest()[:16]
    exe = Path(tempfile.gettempdir()) / f"appell-bench-pinocchio-{key}"
    if not exe.exists():
        cmd = [gxx, *CXXFLAGS, f"-I{inc}", f"-I{inc / 'eigen3'}", str(source), "-o", str(exe) + ".tmp"]
        out = subprocess.run(cmd, capture_output=True, text=True)
        if out.returncode != 0:
            return None, "not built: g++ failed: " + out.stderr.strip().splitlines()[-1][:200]
        os.replace(str(exe) + ".tmp", exe)
    return exe, "built"


#: Pinocchio's ProximalSettings (accuracy, mu, iterations): constraintDynamics as the Python benchmark
#: has always called it (it agrees with appell to 1e-13); lcaba with mu = 1e-4 and up to 100
#: iterations: with mu = 1e-12 it returns accelerations 3.6 off constraintDynamics' on this model (its
#: proximal step breaks down), with mu = 1e-4 it converges in 4 iterations to 1e-8 of them
PROX_CD, PROX_LCABA = (1e-12, 1e-12, 3), (1e-12, 1e-4, 100)


def pinocchio_spec(pin, pmodel, cmodels) -> str:
    """The text that ``pinocchio_loop.cpp`` rebuilds Pinocchio's model and closures from (its
    comment): the settings, the joints, inertias and gravity of ``pmodel``, the
    ``RigidConstraintModel`` s."""

    def numbers(*arrays):
        return " ".join(repr(float(x)) for a in arrays for x in np.ravel(a))

    def placement(M):
        return numbers(M.rotation, M.translation)

    lines = [f"settings {numbers(PROX_CD, PROX_LCABA)}", f"gravity {numbers(pmodel.gravity.linear)}"]
    for i in range(1, pmodel.njoints):
        joint, inertia = pmodel.joints[i], pmodel.inertias[i]
        kind = joint.shortname().removeprefix("JointModel")
        axis = getattr(joint, "axis", np.zeros(3)) if kind == "RevoluteUnaligned" else np.zeros(3)
        lines.append(
            f"joint {pmodel.parents[i]} {kind} {numbers(axis)} {placement(pmodel.jointPlacements[i])} "
            f"{numbers([inertia.mass], inertia.lever, inertia.inertia)}"
        )
    frames = {pin.ReferenceFrame.WORLD: 0, pin.ReferenceFrame.LOCAL: 1, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED: 2}
    for c in cmodels:
        size = 6 if c.type == pin.ContactType.CONTACT_6D else 3
        lines.append(
            f"contact {size} {c.joint1_id} {placement(c.joint1_placement)} {c.joint2_id} "
            f"{placement(c.joint2_placement)} {frames[c.reference_frame]}"
        )
    return "\n".join(lines) + "\n"


def pinocchio_cpp(spec, pq, pv, iterations=2000) -> dict:
    """Pinocchio's constraintDynamics and lcaba timed in C++ (``pinocchio_loop.cpp``) on the
    model of ``spec`` (:func:`pinocchio_spec`) at Pinocchio's state ``(pq, pv)``:
    ``{"constraintDynamics": (best, median) s, "lcaba": ..., "a": accelerations, "a_lcaba": ...}``,
    or ``{"note": why not}``."""
    exe, note = pinocchio_executable()
    if exe is None:
        return {"note": note}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.txt"
        path.write_text(spec)
        out = subprocess.run(
            [str(exe), str(path), str(iterations), *(repr(float(x)) for x in [*pq, *pv])],
            capture_output=True,
            text=True,
        )
    if out.returncode != 0:
        return {"note": "failed: " + (out.stderr.strip() or f"status {out.returncode}")[:200]}
    r = json.loads(out.stdout)
    return {
        "constraintDynamics": tuple(x * 1e-9 for x in r["constraintDynamics_ns"]),
        "lcaba": tuple(x * 1e-9 for x in r["lcaba_ns"]),
        "a": np.array(r["a_constraintDynamics"]),
        "a_lcaba": np.array(r["a_lcaba"]),
    }


def evaluation(rounds: int) -> dict:
    """Per-call CPU times of appell's evaluation and Pinocchio's constrained dynamics at one
    state (the base at rest in the identity pose, the joints' angles and rates random, then the
    loops closed), and the
    largest difference of their joint accelerations."""
    from appell.simulation.inverse import _newton

    model = _appell_model()
    rng = np.random.default_rng(0)
    q = np.zeros(model.n)
    q[3] = 1.0
    q[7:] = rng.uniform(-0.3, 0.3, model.n - 7)
    w = np.zeros(model.n)
    w[7:] = rng.normal(size=model.n - 7)
    # the loops closed (Newton's method on the legs) and the rates tangent to them: appell's planar
    # loops hold along body1's axes, Pinocchio's contacts along the world's, one constraint only there
    legs = list(range(7, model.n))
    q, _, J = _newton(model, q, legs, model.parameter_values, 1e-13, 50)
    w[7:] -= np.linalg.lstsq(J[:, 7:], J @ w, rcond=None)[0]
    plain = _appell_model("numpy")
    candidates = {"appell": lambda: model.evaluate(q, w), "appell NumPy route": lambda: plain.evaluate(q, w)}
    pin = optional("pinocchio")
    agree, agree_lcaba, cpp = None, None, {"note": "Pinocchio is not installed"}
    if pin is not None:
        pmodel, cmodels = pin.buildModelAndLegacyConstraintsFromMJCF(str(MODEL))
        pdata = pmodel.createData()
        cdatas = [c.createData() for c in cmodels]
        pin.initConstraintDynamics(pmodel, pdata, cmodels, cdatas)
        prox = pin.ProximalSettings(*PROX_CD)
        lprox = pin.ProximalSettings(*PROX_LCABA)
        pq = np.concatenate([q[:3] + pin.neutral(pmodel)[:3], [0, 0, 0, 1], q[7:]])  # pin: x y z qx qy qz qw
        pv = np.concatenate([np.zeros(6), w[7:]])
        tau = np.zeros(pmodel.nv)
        candidates["pinocchio constraintDynamics"] = lambda: pin.constraintDynamics(
            pmodel, pdata, pq, pv, tau, cmodels, cdatas, prox
        )
        a_pin = np.array(pin.constraintDynamics(pmodel, pdata, pq, pv, tau, cmodels, cdatas, prox))
        agree = float(np.abs(a_pin[6:] - model.evaluate(q, w).a[7:]).max())
        cpp = pinocchio_cpp(pinocchio_spec(pin, pmodel, cmodels), pq, pv)
        if "a" in cpp:  # the C++ run at the same state: the same accelerations as from Python
            cpp["agree"] = max(float(np.abs(cpp["a"] - a_pin).max()), float(np.abs(cpp["a_lcaba"] - a_pin).max()))
        try:
            pin.computeJointMinimalOrdering(pmodel, pdata, cmodels)
            a_lcaba = np.array(pin.lcaba(pmodel, pdata, pq, pv, tau, cmodels, cdatas, lprox))
            agree_lcaba = float(np.abs(a_lcaba - a_pin).max())
            candidates["pinocchio lcaba"] = lambda: pin.lcaba(pmodel, pdata, pq, pv, tau, cmodels, cdatas, lprox)
        except Exception as exc:  # noqa: BLE001 - a peer's API that may be absent
            print(f"(lcaba not run: {exc})")
    times = interleaved(candidates, rounds=rounds)
    return {
        "times": times,
        "agree": agree,
        "agree_lcaba": agree_lcaba,
        "from_c": from_c(model, q, w),
        "backend": model.backend,
        "cpp": cpp,
    }


def inverse(samples: int = 1000) -> tuple[float, float]:
    """Wall and CPU time of the legs' inverse dynamics on a fixed pelvis along ``samples``
    samples (on a loaded machine the CPU time is the fair one)."""
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
    t0, c0 = time.perf_counter(), time.process_time()
    appell.inverse_dynamics(model, t, given)
    return time.perf_counter() - t0, time.process_time() - c0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--samples", type=int, default=1000)
    args = parser.parse_args(argv)
    print(f"# closed chains: {MODEL.name} (22 DOF, 4 loops, floating base), {GRIPPER.name}\n")
    print(f"{today()}; {machine()}\n{versions()}\n")
    first = first_evaluation()
    grip = first_evaluation(GRIPPER, "system", 11)
    ev = evaluation(args.rounds)
    inv = inverse(args.samples)
    times, cpp = ev["times"], ev["cpp"]
    print("| measure | appell | peer | ratio appell / peer |")
    print("|---|---|---|---|")
    for label, r in (("biped", first), ("gripper", grip)):
        print(
            f"| {label}: file to first compiled evaluation (fresh process, empty cache; wall, CPU) | "
            f"{r['seconds']:.1f} s, {r['cpu']:.1f} s CPU; {r['peak_mb']:.0f} MB peak (largest child "
            f"{r['compiler_peak_mb']:.0f} MB) | — | — |"
        )
    best_peer = best_c = None
    peers = [k for k in times if k.startswith("pinocchio")]
    for name in ("appell", "appell NumPy route"):
        for peer in peers:
            r = ratio(times, name, peer)
            if name == "appell":
                best_peer = r if best_peer is None else max(best_peer, r)
            route = f"{ev['backend']}" if name == "appell" else "numpy"
            print(
                f"| one evaluation from Python ({route}; every loop force and joint wrench) | "
                f"{median(times[name]) * 1e6:.1f} µs | {peer} from Python {median(times[peer]) * 1e6:.1f} µs | "
                f"{r:.2f}× |"
            )
    if ev["from_c"] is not None:
        best, mid = ev["from_c"]
        for peer in ("constraintDynamics", "lcaba"):
            if peer not in cpp:
                continue
            pbest, pmid = cpp[peer]
            r = mid / pmid
            best_c = r if best_c is None else max(best_c, r)
            print(
                f"| one evaluation from C: appell_loop_evaluate in a C loop (best; median) | {best * 1e6:.1f}; "
                f"{mid * 1e6:.1f} µs | pinocchio {peer} in a C++ loop {pbest * 1e6:.1f}; {pmid * 1e6:.1f} µs | "
                f"{r:.2f}× (medians), {best / pbest:.2f}× (best) |"
            )
        if "note" in cpp:
            print(
                f"| one evaluation from C: appell_loop_evaluate in a C loop (best; median) | {best * 1e6:.1f}; "
                f"{mid * 1e6:.1f} µs | Pinocchio's C++ loop {cpp['note']} | — |"
            )
    print(
        f"| inverse dynamics, legs, {args.samples} samples (wall; CPU) | {inv[0]:.2f} s; {inv[1]:.2f} s CPU | — | — |"
    )
    print(
        "\nColumns: appell's evaluation gives the accelerations, every multiplier (each loop force) and every "
        "joint's wrench; Pinocchio's the accelerations and the constraint forces (lambda_c). From Python: "
        "per-call CPU time, the median of the interleaved rounds, binding costs included on both sides. From C: "
        "no Python in the loop on either side, the per-call CPU time of the best and the median of 41 rounds "
        "at the same state; the ratio is appell's over the peer's."
    )
    if ev["agree"] is not None:
        print(f"\njoint accelerations, appell against Pinocchio at the state: largest difference {ev['agree']:.2e}")
    if ev["agree_lcaba"] is not None:
        print(
            f"Pinocchio's lcaba (mu {PROX_LCABA[1]:g}) against its constraintDynamics at the state: largest "
            f"difference {ev['agree_lcaba']:.2e}"
        )
    if "agree" in cpp:
        print(
            f"Pinocchio's C++ runs (both) against its Python constraintDynamics at the state: largest difference "
            f"{cpp['agree']:.2e}"
        )
    print(
        "\n"
        + "\n".join(
            [
                target("biped: file to first evaluation, wall", first["seconds"], 30, " s"),
                target("biped: file to first evaluation, CPU", first["cpu"], 30, " s"),
                target("gripper: file to first evaluation, wall", grip["seconds"], 15, " s"),
                target("gripper: file to first evaluation, CPU", grip["cpu"], 15, " s"),
                target(
                    "peak memory, the largest process",
                    max(first["peak_mb"], grip["peak_mb"], first["compiler_peak_mb"], grip["compiler_peak_mb"]),
                    500,
                    " MB",
                ),
                target("one evaluation from Python against Pinocchio's fastest from Python", best_peer, 1.5),
                target("one evaluation from C against Pinocchio's fastest from C++ (medians)", best_c, 1.0)
                if best_c is not None
                else f"- one evaluation from C (target ≤ 1×): not measured ({cpp.get('note', 'no compiled model')})",
                target(
                    f"inverse dynamics along 1000 samples, CPU time (from {args.samples} measured)",
                    inv[1] * 1000 / args.samples,
                    1.0,
                    " s",
                ),
            ]
        )
    )


if __name__ == "__main__":
    main()

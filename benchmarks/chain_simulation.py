"""A whole simulation of the n-link pendulum with its tip on a vertical line: 10 s with the
state and the tip reaction recorded at 1 kHz (10 001 samples), appell against PyDy.

    python benchmarks/chain_simulation.py [--sizes 4,10] [--rounds 3] [--json F] [--markdown F]

Candidates, interleaved in every round, all DOP853 at rtol 1e-9, atol 1e-12, from the same
start on the constraint (``models.nlink_state``), compilation done before timing:

  appell simulate      ``appell.simulate`` of the compiled (C) model with its defaults
                       otherwise (drift control by projection); records states,
                       accelerations, the reaction and the constraint residuals
  PyDy + solve_ivp     PyDy's Cython ODE function of Kane's augmented system
                       [M -J^T; J 0] [u'; lam] = [f; -c] under plain ``scipy.integrate.solve_ivp``
                       with ``t_eval`` (states only, no drift control)
  ... + reactions      the same, plus one call of the ODE function per sample for lam
  appell C + solve_ivp ``CompiledNumericModel.evaluate`` under the same plain ``solve_ivp``

Times are CPU time of the process (harness.CLOCK; all candidates are single-threaded).
The ratio column is appell simulate / PyDy (median of the per-round ratios). The table also
gives how far the runs are apart (the chain is chaotic: differences of the order of the
tolerance grow along the run) and each run's largest constraint residual |x_tip - d|.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import appell  # noqa: E402
from appell.numerics.codegen import compile_c  # noqa: E402
from harness import CLOCK, markdown_table, median, optional, target  # noqa: E402
from models import nlink_appell, nlink_kane, nlink_parameters, nlink_state  # noqa: E402

RTOL, ATOL = 1e-9, 1e-12


def pydy_rhs(n: int):
    import sympy as sp
    from pydy.codegen.ode_function_generators import generate_ode_function
    from sympy.physics.mechanics import dynamicsymbols

    KM, A, b, params, q, u = nlink_kane(n)
    lam_state = dynamicsymbols("lam_state")  # stands for lam so that A [u'; lam] = b fits PyDy
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rhs = generate_ode_function(
            b, q, list(u) + [lam_state], params, mass_matrix=A, coordinate_derivatives=sp.Matrix(u), generator="cython"
        )
    values = nlink_parameters(n)
    return rhs, np.array([values[s.name] for s in params])


def run_pydy(rhs, pk, n, y0, t_end, t_eval):
    buf = np.zeros(2 * n + 1)

    def fun(t, x):
        buf[: 2 * n] = x
        # PyDy's Cython function returns the same output array at every call: a view would be
        # overwritten by the next call (DOP853's dense output then corrupts its stages)
        return rhs(buf, t, pk)[: 2 * n].copy()

    t0 = CLOCK()
    sol = solve_ivp(fun, (0.0, t_end), y0, method="DOP853", t_eval=t_eval, rtol=RTOL, atol=ATOL)
    t1 = CLOCK()
    lam = np.empty(len(sol.t))
    for k, (t, x) in enumerate(zip(sol.t, sol.y.T)):
        buf[: 2 * n] = x
        lam[k] = rhs(buf, t, pk)[2 * n]
    t2 = CLOCK()
    return sol, lam, t1 - t0, t2 - t1


def run_appell_ivp(cm, y0, t_end, t_eval):
    t0 = CLOCK()
    sol = solve_ivp(
        lambda t, x: cm.evaluate(t, x).derivative,
        (0.0, t_end),
        y0,
        method="DOP853",
        t_eval=t_eval,
        rtol=RTOL,
        atol=ATOL,
    )
    lam = np.array([cm.evaluate(t, x).multipliers[0] for t, x in zip(sol.t, sol.y.T)])
    return sol, lam, CLOCK() - t0


def run_simulate(cm, y0, t_end, t_eval):
    t0 = CLOCK()
    sol = appell.simulate(cm, t_end, t_eval=t_eval, rtol=RTOL, atol=ATOL, initial=y0, progress=False)
    wall = CLOCK() - t0
    return sol, wall


def tip_residual(theta: np.ndarray, n: int) -> float:
    p = nlink_parameters(n)
    lengths = np.array([p[f"l{i}"] for i in range(1, n + 1)])
    return float(np.max(np.abs(lengths @ np.sin(theta) - p["d"])))


def measure(n: int, args) -> dict:
    th, w = nlink_state(n)
    y0 = np.concatenate([th, w])
    t_eval = np.linspace(0.0, args.t_end, int(round(args.t_end * args.rate)) + 1)
    cm = compile_c(appell.derive(nlink_appell(n)), "c")
    have_pydy = optional("pydy") is not None and optional("Cython") is not None
    rhs = pk = None
    if have_pydy:
        rhs, pk = pydy_rhs(n)
    # warm-up (caches, first calls), not timed
    run_simulate(cm, y0, 0.05, t_eval[:51])
    rows = {"simulate": [], "ivp": []}
    if have_pydy:
        run_pydy(rhs, pk, n, y0, 0.05, t_eval[:51])
        rows |= {"pydy": [], "pydy_rec": []}
    sim = ps = plam = None
    for _ in range(args.rounds):
        sim, wall = run_simulate(cm, y0, args.t_end, t_eval)
        rows["simulate"].append(wall)
        if have_pydy:
            ps, plam, t_int, t_rec = run_pydy(rhs, pk, n, y0, args.t_end, t_eval)
            rows["pydy"].append(t_int)
            rows["pydy_rec"].append(t_int + t_rec)
        ivp, ivp_lam, wall = run_appell_ivp(cm, y0, args.t_end, t_eval)
        rows["ivp"].append(wall)
    names = list(cm.state_names)
    sim_y = np.column_stack([np.asarray(sim.states[k]) for k in names]) if hasattr(sim, "states") else None
    sim_lam = np.asarray(sim.multipliers["tip"])
    out = {
        "n": n,
        "samples": len(t_eval),
        "status": int(sim.status),
        "median_s": {k: median(v) for k, v in rows.items()},
        "rounds": rows,
    }
    out["residual"] = {
        "simulate": tip_residual(sim_y[:, :n].T, n) if sim_y is not None else None,
        "ivp": tip_residual(ivp.y[:n], n),
    }
    if have_pydy:
        out["ratio_states"] = median(a / b for a, b in zip(rows["simulate"], rows["pydy"]))
        out["ratio_reactions"] = median(a / b for a, b in zip(rows["simulate"], rows["pydy_rec"]))
        out["ratio_ivp"] = median(a / b for a, b in zip(rows["ivp"], rows["pydy_rec"]))
        out["residual"]["pydy"] = tip_residual(ps.y[:n], n)
        if sim_y is not None and ps.y.shape[1] == sim_y.shape[0]:
            out["max_theta_diff"] = float(np.max(np.abs(ps.y[:n].T - sim_y[:, :n])))
            out["max_lam_diff"] = float(np.max(np.abs(plam - sim_lam)))
            out["lam_scale"] = float(np.max(np.abs(sim_lam)))
    return out


def markdown(results: list[dict]) -> str:
    rows = []
    for r in results:
        m = r["median_s"]
        pyd = "pydy" in m
        rows.append(
            [
                str(r["n"]),
                f"{m['simulate']:.3f} s",
                f"{m['pydy']:.3f} s" if pyd else "not installed",
                f"{m['pydy_rec']:.3f} s" if pyd else "—",
                f"{m['ivp']:.3f} s",
                f"**{r['ratio_states']:.2f}×** / {r['ratio_reactions']:.2f}×" if pyd else "—",
                (f"{r['max_theta_diff']:.0e} rad / {r['max_lam_diff']:.0e} N" if "max_theta_diff" in r else "—"),
                " / ".join(
                    f"{r['residual'][k]:.0e}" for k in ("simulate", "pydy", "ivp") if r["residual"].get(k) is not None
                ),
            ]
        )
    goals = [
        target(f"n = {r['n']}: simulate / PyDy + solve_ivp (states only)", r["ratio_states"], 0.5)
        for r in results
        if "ratio_states" in r
    ]
    return (
        "CPU time of the process, median of the rounds:\n\n"
        + markdown_table(
            [
                "n",
                "appell simulate",
                "PyDy + solve_ivp",
                "PyDy + solve_ivp + reactions",
                "appell C + solve_ivp (+ reactions)",
                "simulate / PyDy (states / + reactions)",
                "largest difference simulate vs PyDy (θ / λ)",
                "largest constraint residual, m (simulate / PyDy / appell C + solve_ivp)",
            ],
            rows,
        )
        + ("\n\nTargets (issue 13):\n\n" + "\n".join(goals) if goals else "")
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="4,10")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--t-end", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=1000.0, help="samples per second")
    ap.add_argument("--json")
    ap.add_argument("--markdown")
    args = ap.parse_args()
    results = []
    for n in map(int, args.sizes.split(",")):
        r = measure(n, args)
        results.append(r)
        m = r["median_s"]
        print(
            f"n = {n}: {r['samples']} samples; median CPU time [s]: " + ", ".join(f"{k} {v:.3f}" for k, v in m.items())
        )
        if "ratio_states" in r:
            print(
                f"  simulate / PyDy: {r['ratio_states']:.2f} (states), {r['ratio_reactions']:.2f} (+ reactions); "
                f"appell C + solve_ivp / PyDy + reactions: {r['ratio_ivp']:.2f}"
            )
        print(
            f"  differences: { ({k: r[k] for k in ('max_theta_diff', 'max_lam_diff') if k in r}) }, "
            f"residuals {r['residual']}",
            flush=True,
        )
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    if args.markdown:
        Path(args.markdown).write_text(markdown(results) + "\n")


if __name__ == "__main__":
    main()

"""The Whipple-Carvallo benchmark bicycle (Meijaard, Papadopoulos, Ruina, Schwab, "Linearized
dynamics equations for the balance and steer of a bicycle: a benchmark and review",
Proc. R. Soc. A 463 (2007) 1955-1982), built from its Table 1 through the public API
(appell.examples.mechanism_examples.benchmark_bicycle: a free rear frame, two revolute
wheels, a tilted steer revolute, two rolling-disc contacts; 9 coordinates, 6 constraints),
linearised about upright straight running (issue 23).

Published values (the paper's eq. 5.4 matrices, to 14 digits, and its Table 2 speeds):
M, C1, K0, K2 of M q'' + v C1 q' + (g K0 + v^2 K2) q = 0 for q = (roll, steer); the weave
speed 4.29238253634111 m/s and the capsize speed 6.02426201538837 m/s, between which the
bicycle is self-stable.
"""

from __future__ import annotations

import numpy as np
import pytest

from appell import derive, linearise, stability_sweep, steady_motion
from appell.examples.mechanism_examples import benchmark_bicycle
from bundled import bundled_derivation

M_PUB = np.array([[80.81722, 2.31941332208709], [2.31941332208709, 0.29784188199686]])
C1_PUB = np.array([[0.0, 33.86641391492494], [-0.85035641456978, 1.68540397397560]])
K0_PUB = np.array([[-80.95, -2.59951685249872], [-2.59951685249872, -0.80329488458618]])
K2_PUB = np.array([[0.0, 76.59734589573222], [0.0, 2.65431523794604]])
WEAVE, CAPSIZE = 4.29238253634111, 6.02426201538837
G = 9.81
R_REAR, R_FRONT = 0.3, 0.35

#: speeds left free when the steady motion is found at each forward speed, and the
#: coordinates and the speed (the rear wheel's rate, the forward speed) left out
FREE = [
    "rear_x_dot",
    "rear_y_dot",
    "rear_z_dot",
    "rear_rz_dot",
    "rear_rx_dot",
    "rear_ry_dot",
    "front_spin_dot",
    "steer_dot",
    "rear_z",
    "rear_ry",
]
IGNORE = ["rear_x", "rear_y", "rear_rz", "rear_spin", "front_spin", "rear_spin_dot"]


@pytest.fixture(scope="module")
def bicycle():
    return derive(benchmark_bicycle())


def upright(d, v):
    """The linear model about upright straight running at forward speed v."""
    point = steady_motion(
        d,
        {"rear_z": -R_REAR, "rear_x_dot": v, "rear_spin_dot": -v / R_REAR, "front_spin_dot": -v / R_FRONT},
        free=FREE,
        ignore=IGNORE[:5],
    )
    assert point["rear_x_dot"] == pytest.approx(v, abs=1e-12)
    return linearise(d, point, ignore=IGNORE, coordinates=["rear_rx", "steer"])


@pytest.fixture(scope="module")
def bicycle_file():
    """The bundled model file, its geometry given by parameters (the steer axis by the
    parameter lam) and its initial values other than the speeds computed from the contacts."""
    return bundled_derivation("benchmark_bicycle")  # through the run's cache (tests/bundled.py)


@pytest.mark.parametrize("source", ["builder", "model file"])
def test_the_benchmark_matrices(request, source):
    """M, C1, K0, K2 from the second-order forms at v = 0 and v = 5 against the published
    values: 1e-12 relative to each matrix's largest entry (they are printed to 14 digits)."""
    bicycle = request.getfixturevalue("bicycle" if source == "builder" else "bicycle_file")
    lm0, lm5 = upright(bicycle, 0.0), upright(bicycle, 5.0)
    assert lm5.states == ("rear_rx", "steer", "rear_rx_dot", "steer_dot")
    M, C0, K0g, _ = lm0.second_order()
    M5, C5, K5, _ = lm5.second_order()
    for got, published in ((M, M_PUB), (M5, M_PUB), (C5 / 5.0, C1_PUB), (K0g / G, K0_PUB), ((K5 - K0g) / 25.0, K2_PUB)):
        assert np.abs(got - published).max() <= 1e-12 * np.abs(published).max(), (got, published)
    assert np.abs(C0).max() <= 1e-12


def published_eigenvalues(v):
    """Eigenvalues of the published matrices' first-order form at speed v."""
    K = G * K0_PUB + v**2 * K2_PUB
    Minv = np.linalg.inv(M_PUB)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Minv @ K, -v * Minv @ C1_PUB]])
    return np.sort_complex(np.linalg.eigvals(A))


@pytest.mark.parametrize("v", [0.0, 2.0, 4.0, 4.5, 6.0, 10.0])
def test_eigenvalues_against_the_published_matrices(bicycle, v):
    """The eigenvalues of appell's linear model against those of the published matrices
    (eigenvalues of a 4 x 4 with entries near 100: 1e-10 absolute)."""
    got = np.sort_complex(upright(bicycle, v).eigenvalues())
    assert np.abs(got - published_eigenvalues(v)).max() <= 1e-10


def test_weave_and_capsize_speeds(bicycle):
    """The sweep over the rear wheel's rate (the forward speed v = -0.3 rate) locates the
    weave speed (an oscillatory pair turns stable) and the capsize speed (a real mode turns
    unstable) to 1e-10 m/s."""
    rates = -np.linspace(3.0, 7.0, 9)[::-1] / R_REAR  # increasing rates: decreasing speeds
    sweep = stability_sweep(
        bicycle,
        "rear_spin_dot",
        rates,
        at={"rear_z": -R_REAR, "rear_x_dot": 7.0, "front_spin_dot": -7.0 / R_FRONT},
        free=FREE,
        ignore=IGNORE,
        coordinates=["rear_rx", "steer"],
        xtol=1e-13,
    )
    speeds = sorted(-R_REAR * c.value for c in sweep.crossings)
    kinds = {round(-R_REAR * c.value, 6): c.kind for c in sweep.crossings}
    assert len(speeds) == 2
    assert speeds[0] == pytest.approx(WEAVE, abs=1e-10)
    assert speeds[1] == pytest.approx(CAPSIZE, abs=1e-10)
    assert kinds[round(speeds[0], 6)] == "oscillatory" and kinds[round(speeds[1], 6)] == "real"


def test_the_json_document_reads_back_exactly(bicycle_file):
    """Issue 23 §6: the symbolic stages finish on this model. Its reactions have about 1.5
    million tree nodes over 2,000 distinct subexpressions; the JSON document writes each
    shared subexpression once (``exact_shared``) and reads back structurally equal."""
    import json

    from appell.core.simplification import tree_size
    from appell.io.printing import JSON_TREE_LIMIT, derivation_json, read_json

    reactions = bicycle_file.reactions.as_dict()
    assert max(tree_size(e, JSON_TREE_LIMIT) for e in reactions.values()) > JSON_TREE_LIMIT
    text = json.dumps(derivation_json(bicycle_file))
    assert len(text) < 2_000_000
    doc = json.loads(text)
    assert len(doc["shared"]) == len(doc["exact_shared"]) > 0
    back = read_json(doc)
    for name, expr in reactions.items():
        assert back["multipliers"][name] == expr, name
    for got, expr in zip(back["reduced_equations"], bicycle_file.reduced.equations):
        assert got == expr


@pytest.mark.parametrize("grid", ["21 values, chart named", "the file's [stability] table"])
def test_a_sweep_over_the_files_speed_parameter_keeps_the_conserved_speed(bicycle_file, grid):
    """The model file writes its initial speeds in the parameter v (rear_x' = v,
    rear_spin' = -v/rR, ...): sweeping v moves the point with it, and with the forward speed
    left in the linear model (its eigenvalue is exactly zero at every speed) the capsize
    mode, a real eigenvalue crossing zero, is not confused with it: the published weave and
    capsize speeds to 1e-10. (Picking the trial eigenvalue nearest the interpolated one
    alone put the capsize speed 1.3e-5 off on 1001 values and 4.2e-6 off on the table's
    201: at equal distance it took the conserved speed's exact zero as the root.)"""
    from appell.io.cli import stability_analysis

    if grid.startswith("21"):
        sweep = stability_sweep(
            bicycle_file, "v", np.linspace(0.0, 10.0, 21), ignore=IGNORE[:5], coordinates=["rear_rx", "steer"]
        )
    else:  # as 'appell stability benchmark_bicycle' runs it: v = 0:10:201, the chart chosen by QR
        sweep = stability_analysis(bicycle_file)
        assert sweep.values.size == 201
    assert "rear_spin_dot" in sweep.states
    assert np.abs(sweep.eigenvalues.real).min(axis=1).max() <= 1e-9  # the conserved speed's zero
    speeds = sorted(c.value for c in sweep.crossings)
    assert len(speeds) == 2
    assert abs(speeds[0] - WEAVE) <= 1e-10 and abs(speeds[1] - CAPSIZE) <= 1e-10


def test_cyclic_finds_the_wheel_angles_and_the_heading(bicycle):
    """``ignore='cyclic'`` finds the five coordinates the published model leaves out: x, y
    (nothing contains them), the wheels' angles (their sines and cosines cancel in the
    contacts without the expressions showing it) and the heading (it drives only the rates
    of x and y); the steady motion at 5 m/s is found with the same 'cyclic', and the
    eigenvalues are the published ones (1e-10)."""
    v = 5.0
    point = steady_motion(
        bicycle,
        {"rear_z": -R_REAR, "rear_x_dot": v, "rear_spin_dot": -v / R_REAR, "front_spin_dot": -v / R_FRONT},
        free=FREE,
        ignore="cyclic",
    )
    lm = linearise(bicycle, point, ignore="cyclic")
    assert set(lm.ignored) == set(IGNORE[:5])
    # the forward speed stays a state here (its zero eigenvalue is the sixth)
    got = np.sort_complex(lm.eigenvalues())
    zero = np.argmin(np.abs(got))
    assert abs(got[zero]) < 1e-9
    assert np.abs(np.delete(got, zero) - published_eigenvalues(v)).max() <= 1e-10


def test_a_coordinate_that_matters_cannot_be_left_out(bicycle):
    """Leaving out the roll angle, which the other states depend on (gravity's moment), is
    refused with the coupling named, instead of a silently wrong linear model."""
    from appell.errors import ModelError

    point = steady_motion(
        bicycle,
        {"rear_z": -R_REAR, "rear_x_dot": 5.0, "rear_spin_dot": -5.0 / R_REAR, "front_spin_dot": -5.0 / R_FRONT},
        free=FREE,
        ignore=IGNORE[:5],
    )
    with pytest.raises(ModelError, match="rear_rx cannot be left out"):
        linearise(bicycle, point, ignore=IGNORE[:5] + ["rear_rx"])

"""Bushings and general force elements between two markers (Mechanism.bushing,
Mechanism.force_pair) against closed forms: Newton's and Euler's laws of the body they
act on, and the moment balance of each body carried by its joint (named in each test)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from appell import derive, numeric_model
from appell.mechanism import Mechanism

G = 9.81


def _outputs(d, q, w, t=0.0):
    model = numeric_model(d)
    sol = model.solve(t, q, w)
    return sol, model.outputs(t, q, w, solution=sol)


def test_bushing_holds_a_puck_in_its_own_axes():
    """Closed form (Newton and Euler of a body on a planar joint held at its mass centre
    by a bushing whose frame is turned 90 degrees about z, so its x axis is the world y):
    m x'' = -K_y x - C_y x', m y'' = -K_x y - C_x y' - m g, I phi'' = -K_rz sin(phi) - C_rz phi'
    (the bushing's angle is vex(R - R^T)/2 = sin(phi) about z); the plane carries nothing
    in the plane and the out-of-plane gains do nothing."""
    m, I = 2.0, 0.05
    K, C, Kr, Cr = (100.0, 300.0, 50.0), (2.0, 5.0, 1.0), (7.0, 8.0, 9.0), (0.1, 0.2, 0.3)
    mech = Mechanism("bushing", gravity=(0, -G, 0))
    puck = mech.body("puck", m, inertia=(0.1, 0.1, I))
    mech.planar("plane", "ground", puck)
    mech.bushing("mount", ("ground", (0, 0, 0)), (puck, (0, 0, 0)), K, C, Kr, Cr, rotation=(0, 0, math.pi / 2))
    q, w = [0.03, -0.02, 0.4], [0.5, -0.3, 1.2]
    sol, out = _outputs(derive(mech.system()), q, w)
    acc = [
        (-K[1] * q[0] - C[1] * w[0]) / m,
        (-K[0] * q[1] - C[0] * w[1]) / m - G,
        (-Kr[2] * math.sin(q[2]) - Cr[2] * w[2]) / I,
    ]
    # rounding only (a 3x3 solve of well-scaled terms)
    assert sol.accelerations == pytest.approx(acc, rel=1e-12)
    assert [out[f"F_plane_{a}"] for a in "xy"] == pytest.approx([0, 0], abs=1e-12)
    assert out["M_plane_z"] == pytest.approx(0.0, abs=1e-12)


def test_force_pair_between_two_sliders_and_the_couple_of_their_offset():
    """Closed form (two blocks on parallel slides along x pulled together by a force element
    F = -k (x_b - x_a) e_x at markers at heights h_a, h_b): m_a x_a'' = -F, m_b x_b'' = F; the
    slides carry the moments of the element about their origins, on b -(p_b - O_b) x F and on
    a (p_a - O_a) x F + (p_b - p_a) x F (the element's couple, so that it has no net moment)."""
    k, ma, mb, ha, hb = 40.0, 1.0, 3.0, 0.1, 0.3
    mech = Mechanism("pair", gravity=None)
    a = mech.body("a", ma, inertia=(1, 1, 1))
    b = mech.body("b", mb, inertia=(1, 1, 1))
    mech.prismatic("sa", "ground", a, axis=(1, 0, 0))
    mech.prismatic("sb", "ground", b, axis=(1, 0, 0), origin=(0, 0, 1))
    mech.force_pair("link", (a, (0, ha, 0)), (b, (0, hb, 0)), force=(f"-{k}*(sb - sa)", 0, 0))
    xa, xb = 0.1, 0.35
    sol, out = _outputs(derive(mech.system()), [xa, xb], [0.0, 0.0])
    F = np.array([-k * (xb - xa), 0, 0])
    # rounding only
    assert sol.accelerations == pytest.approx([-F[0] / ma, F[0] / mb], rel=1e-12)
    pa, pb = np.array([xa, ha, 0]), np.array([xb, hb, 1.0])
    Oa, Ob = np.array([xa, 0, 0]), np.array([xb, 0, 1.0])
    assert [out[f"M_sb_{c}"] for c in "xyz"] == pytest.approx(-np.cross(pb - Ob, F), abs=1e-12)
    assert [out[f"M_sa_{c}"] for c in "xyz"] == pytest.approx(np.cross(pa - Oa, F) + np.cross(pb - pa, F), abs=1e-12)


MODEL = """
[mechanism]
gravity = [0, -9.81, 0]
[[bodies]]
name = "puck"
mass = 2.0
inertia = [0.1, 0.1, 0.05]
[[joints]]
name = "plane"
type = "planar"
parent = "ground"
child = "puck"
[[loads]]
name = "mount"
type = "bushing"
body_a = "ground"
point_a = [0, 0, 0]
body_b = "puck"
point_b = [0, 0, 0]
stiffness = [100, 300, 50]
rotational_stiffness = [7, 8, 9]
[[loads]]
name = "push"
type = "force_pair"
body_a = "ground"
point_a = [0, 0, 0]
body_b = "puck"
point_b = [0, 0, 0]
force = ["2*t", 0, 0]
"""


def test_bushing_and_force_pair_in_a_model_file(tmp_path):
    """The same bushing from a model file, with a force element 2 t along x: closed form
    m x'' = -K_x x + 2 t, m y'' = -K_y y - m g, I phi'' = -K_rz sin(phi)."""
    from appell import load_model

    path = tmp_path / "mount.toml"
    path.write_text(MODEL)
    q = [0.03, -0.02, 0.4]
    sol, _ = _outputs(derive(load_model(path)), q, [0.0, 0.0, 0.0], t=0.5)
    acc = [(-100 * q[0] + 1.0) / 2.0, -300 * q[1] / 2.0 - G, -9 * math.sin(q[2]) / 0.05]
    # rounding only
    assert sol.accelerations == pytest.approx(acc, rel=1e-12)

"""Spring-dampers of appell.mechanism with a rest length of zero whose ends coincide at
the start: the force -k d - c v is defined there (no division by the spring's length).
Source: the closed form of a damped harmonic oscillator under a constant force."""

from __future__ import annotations

import math

import numpy as np
import pytest

from appell import derive, simulate
from appell.mechanism import Mechanism

G = 9.81


@pytest.mark.parametrize("c", [0.0, 0.8])
def test_zero_length_spring_pendulum_is_a_harmonic_oscillator(c):
    """Closed form: a body held by a zero-length spring-damper (k, c) at its mass centre to
    the origin, under gravity, starting at rest at the origin (the spring's ends coincide):
    m y'' + c y' + k y = -m g, so y(t) = -y_s (1 - e^{-z w t} (cos w_d t + z w / w_d sin w_d t)),
    y_s = m g / k, w = sqrt(k/m), z = c / (2 m w), w_d = w sqrt(1 - z^2); x stays 0 and
    the spring's force on the ground is the reaction F = -k (x, y) - c (x', y')."""
    m, k = 2.0, 50.0
    mech = Mechanism("zero_spring", gravity=(0, -G, 0))
    bob = mech.body("bob", m, inertia=(0.1, 0.1, 0.1))
    mech.planar("plane", "ground", bob)
    mech.spring("spring", ("ground", (0, 0, 0)), (bob, (0, 0, 0)), k, 0, damping=c)
    t = np.linspace(0.0, 3.0, 31)
    sol = simulate(derive(mech.system(initial={"plane_x": 0.0, "plane_y": 0.0})), 3.0, t_eval=t)
    w = math.sqrt(k / m)
    z = c / (2 * m * w)
    wd = w * math.sqrt(1 - z**2)
    ys = m * G / k
    y = -ys * (1 - np.exp(-z * w * t) * (np.cos(wd * t) + z * w / wd * np.sin(wd * t)))
    # DOP853 at the default rtol 1e-9 over 3 s (about 5 periods): ~1e-9 of ys = 0.39 m; 1e-7 is 100x
    assert np.abs(sol["plane_y"] - y).max() < 1e-7
    assert np.abs(sol["plane_x"]).max() < 1e-12
    # the plane's reaction balances nothing in the plane: the spring and gravity move the bob
    assert np.abs(sol["F_plane_y"]).max() < 1e-9

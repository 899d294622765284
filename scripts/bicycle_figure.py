"""Draw docs/_static/bicycle_eigenvalues.png: the benchmark bicycle's eigenvalues against
its forward speed (the figure of docs/stability.md; Meijaard et al. 2007, Fig. 3).

    python scripts/bicycle_figure.py
"""

from pathlib import Path

import numpy as np

from appell import derive, stability_sweep
from appell.examples.mechanism_examples import benchmark_bicycle

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

d = derive(benchmark_bicycle())
rates = -np.linspace(0.0, 10.0, 201)[::-1] / 0.3
sweep = stability_sweep(
    d,
    "rear_spin_dot",
    rates,
    at={"rear_z": -0.3, "rear_x_dot": 10.0, "front_spin_dot": -10.0 / 0.35},
    free=FREE,
    ignore=IGNORE,
    coordinates=["rear_rx", "steer"],
)
from matplotlib.figure import Figure

fig = Figure(figsize=(7, 4.2), constrained_layout=True)
ax = fig.subplots()
v = -0.3 * sweep.values
for j in range(sweep.eigenvalues.shape[1]):
    ax.plot(v, sweep.eigenvalues[:, j].real, "k-", lw=1.2)
    ax.plot(v, np.abs(sweep.eigenvalues[:, j].imag), "k:", lw=1.0)
for c in sweep.crossings:
    ax.axvline(-0.3 * c.value, color="tab:red", lw=0.8)
    ax.annotate(f"{-0.3 * c.value:.4f} m/s", (-0.3 * c.value, 8), rotation=90, va="top", ha="right", fontsize=8)
ax.set_ylim(-10, 10)
ax.set_xlabel("forward speed v [m/s]")
ax.set_ylabel("real part (solid), |imaginary part| (dotted) [1/s]")
ax.set_title("benchmark bicycle: eigenvalues of appell's linear model")
out = Path(__file__).resolve().parent.parent / "docs" / "_static" / "bicycle_eigenvalues.png"
fig.savefig(out, dpi=90, metadata={"Software": None})
print("wrote", out, [(-0.3 * c.value, c.kind) for c in sweep.crossings])

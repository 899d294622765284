"""The picture of a motion in headless Chromium (issue 24 §1): Debian's chromium draws the
page with SwiftShader's WebGL. For the car, the four-bar, the URDF arm and the bicycle,
screenshots at two times whose coloured pixels (the bodies, the arrows; the grid and page
are grey and white) are many and differ; the page reports the viewer ready at the right
frame; the status line says when the block on the incline sticks. (tests/test_viewer.py
checks the frames themselves.)"""

from __future__ import annotations

import re

import numpy as np
import pytest

import appell
from appell.examples import example_path
from appell.io.modelfile import load_model
from appell.io.viewer import view_motion
from browser import CHROMIUM, SKIP_REASON, chromium
from bundled import bundled_derivation

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason=SKIP_REASON)


@pytest.fixture(scope="module")
def four_bar():
    system = load_model(example_path("four_bar"))
    return system, appell.simulate(bundled_derivation("four_bar"), t_end=1.5)  # tests/bundled.py


@pytest.fixture(scope="module")
def car():
    system = load_model(example_path("car"))
    return system, appell.simulate(bundled_derivation("car"))  # tests/bundled.py


# ------------------------------------------------------------------ Chromium
def _mechanism_pixels(png) -> np.ndarray:
    """Pixels of the canvas that are coloured (bodies, arrows): the page, the grid, the
    ground and the pins are white or grey."""
    import matplotlib.image

    rgb = matplotlib.image.imread(str(png))[..., :3]
    return (rgb.max(axis=-1) - rgb.min(axis=-1)) > 0.15


def _two_screenshots(motion, times, tmp_path):
    page = tmp_path / "view.html"
    page.write_text(motion.page())
    shots = []
    for k, t in enumerate(times):
        shot = tmp_path / f"shot{k}.png"
        done = chromium(
            ["--window-size=1000,760", "--virtual-time-budget=2000", f"--screenshot={shot}", f"{page.as_uri()}#t={t}"],
            tmp_path,
        )
        assert done.returncode == 0 and shot.exists(), done.stderr[-2000:]
        shots.append(_mechanism_pixels(shot)[60:620])  # the canvas, below the title
    return shots


def _bicycle():
    system = load_model(example_path("benchmark_bicycle"))
    given = {k: v for k, v in system.initial if k not in system.initial_guesses}
    solution = appell.simulate(
        bundled_derivation("benchmark_bicycle"), t_end=2.0, initial={**given, "rear_rx_dot": 0.5}, complete=True
    )  # a roll rate: the bicycle weaves
    return system, solution


def _arm():
    path = example_path("four_bar").parent / "arm.urdf"
    return load_model(path), appell.simulate(bundled_derivation(path), t_end=0.5)  # tests/bundled.py


@pytest.mark.parametrize("model", ["car", "four_bar", "arm", "bicycle"])
def test_the_mechanism_moves_on_screen(model, four_bar, car, tmp_path):
    system, solution = {"car": lambda: car, "four_bar": lambda: four_bar, "arm": _arm, "bicycle": _bicycle}[model]()
    motion = view_motion(system, solution)
    t_end = float(solution.t[-1])
    first, second = _two_screenshots(motion, (0.1 * t_end, 0.9 * t_end), tmp_path)
    for shot in (first, second):
        assert shot.sum() > 800, f"{model}: only {shot.sum()} coloured pixels: is the mechanism drawn?"
    moved = np.logical_xor(first, second).sum() / np.logical_or(first, second).sum()
    assert moved > 0.1, f"{model}: the mechanism's pixels barely change between two times ({moved:.1%})"


def test_the_status_line_says_when_the_block_sticks(tmp_path):
    system = load_model(example_path("block_on_incline"))
    page = tmp_path / "block.html"
    view_motion(system, appell.simulate(appell.derive(system))).save(page)
    said = {}
    for t in (0.05, 0.9):
        done = chromium(["--virtual-time-budget=2000", "--dump-dom", f"{page.as_uri()}#t={t}"], tmp_path)
        said[t] = re.search(r'data-viewer-states="([^"]*)"', done.stdout).group(1)
    assert said == {0.05: "slide: slips", 0.9: "slide: sticks"}


def test_the_page_reports_the_viewer_ready(four_bar, tmp_path):
    page = tmp_path / "view.html"
    page.write_text(view_motion(*four_bar).page())
    done = chromium(["--virtual-time-budget=2000", "--dump-dom", page.as_uri() + "#t=0.5"], tmp_path)
    root = re.search(r"<div class=\"appell-viewer\"[^>]*>", done.stdout).group(0)
    attrs = dict(re.findall(r'(data-viewer[a-z-]*)="([^"]*)"', root))
    assert attrs["data-viewer"] == "ready", attrs
    assert int(attrs["data-viewer-meshes"]) >= 10 and int(attrs["data-viewer-frames"]) == four_bar[1].t.size
    assert int(attrs["data-viewer-frame"]) == int(np.searchsorted(four_bar[1].t, 0.5 + 1e-9)) - 1

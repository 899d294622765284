"""The HTML report in a real browser: headless Chromium, offline.

The report carries a small inline script that, after the page has loaded, counts the
``<math>`` elements with a nonzero box, the fractions laid out as fractions (numerator
above denominator: a browser that does not render MathML shows them inline) and the
images that decoded, and writes the counts into attributes of ``<body>``. Chromium's
``--dump-dom`` prints the DOM after that; a screenshot must not be blank.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from appell.io.cli import cli
from browser import CHROMIUM, SKIP_REASON, body_attributes, chromium, references, without_namespaces

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason=SKIP_REASON)


@pytest.fixture(scope="module")
def car_report(tmp_path_factory) -> Path:
    """The README's quick-start report (Dobronravov's car), made through the command line."""
    out = tmp_path_factory.mktemp("report") / "car-report.html"
    result = CliRunner().invoke(cli, ["report", "car", "-o", str(out)], catch_exceptions=False)
    assert result.exit_code == 0, result.output + result.stderr
    return out


def test_report_references_nothing_outside_the_page(car_report):
    """Nothing is fetched: no address, no stylesheet link; the one link is the motion's
    data file, written beside the page."""
    page = without_namespaces(car_report.read_text(encoding="utf-8"))
    assert "http://" not in page and "https://" not in page
    assert not re.search(r"<link\b", page, re.IGNORECASE)
    styles = " ".join(re.findall(r"<style>(.*?)</style>", page, re.S)) + " ".join(re.findall(r'style="([^"]*)"', page))
    assert not re.search(r"@import|url\(", styles, re.IGNORECASE)  # CSS fetches nothing
    found = references(page)
    for tag, attr, value in found:
        if (tag, attr, value) == ("a", "href", "car-report.csv"):
            assert (car_report.parent / value).is_file()
            continue
        assert value.startswith(("#", "data:image/png;base64,")), (tag, attr, value[:60])
    assert ("a", "href", "car-report.csv") in found
    assert any(attr == "src" for _, attr, _ in found), "the plots are embedded images"


def test_mathematics_and_plots_render_in_chromium(car_report, tmp_path):
    done = chromium(["--virtual-time-budget=10000", "--dump-dom", car_report.as_uri()], tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    attrs = body_attributes(done.stdout)
    assert attrs.get("data-render-check") == "done", "the report's load-time check did not run"
    assert attrs.get("data-viewers") == "ready", "the 3-D view of the motion did not start"
    counts = {k: int(v) for k, v in attrs.items() if k not in ("data-render-check", "data-viewers")}
    # the car: 3 reduced/dependent equations, 2 reactions, constraints, parameters, ...
    assert counts["data-math-total"] >= 10
    assert counts["data-math-rendered"] == counts["data-math-total"]
    # 1/sin(theta) is now a shared subexpression defined once; the reduced equation is a quotient
    assert counts["data-frac-total"] >= 2, "the car's formulas have 1/sin(theta) and a quotient"
    assert counts["data-frac-stacked"] == counts["data-frac-total"], "fractions are not laid out as MathML"
    # coordinates, speeds, reactions, residuals
    assert counts["data-img-total"] >= 4
    assert counts["data-img-loaded"] == counts["data-img-total"]


def test_screenshot_is_not_blank(car_report, tmp_path):
    shot = tmp_path / "report.png"
    done = chromium(
        ["--window-size=1200,2400", "--virtual-time-budget=10000", f"--screenshot={shot}", car_report.as_uri()],
        tmp_path,
    )
    assert done.returncode == 0 and shot.exists(), done.stderr[-2000:]
    import matplotlib.image

    pixels = matplotlib.image.imread(str(shot))[..., :3]
    assert pixels.shape[0] >= 2000 and pixels.shape[1] >= 1000
    ink = np.any(pixels < 0.9, axis=-1)  # anything clearly darker than the white page
    assert ink.mean() > 0.02, f"only {ink.mean():.2%} of the screenshot is not white"
    # text and plot lines in many places: ink spread over most bands of rows
    bands = ink.reshape(24, -1, ink.shape[1]).any(axis=(1, 2))
    assert bands.mean() > 0.75
    # colour from the plots (matplotlib's default blue and orange lines)
    r, b = pixels[..., 0], pixels[..., 2]
    assert np.count_nonzero((b - r > 0.3) & (b > 0.5)) > 200

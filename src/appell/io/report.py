"""The report: one self-contained HTML page about a model (the last stage of the pipeline).

:func:`render_report` turns a derivation, optionally a simulated :class:`~appell.simulation.solution.Solution`
and a :class:`~appell.numerics.crosscheck.CrossCheckReport`, into a page with

* the model: parameters with units, coordinates and speeds, programs, constraints,
  controls, initial values;
* the equations as mathematics: the reduced equations of motion (1.4) (or (2.4)), the
  dependent accelerations from ``f = 0``, one reaction formula per constraint (1.5)
  (or (2.5)), and for a controlled system the dynamic conditions (2.3) and the control laws;
* plots of the coordinates, reactions, controls and constraint residuals;
* the cross-check against the independent routes (augmented multiplier system, the
  printed reaction formulas, Lagrange's equations) and the energy balance.

The page needs no network: formulas are converted from LaTeX to MathML (rendered natively
by browsers) with the pure-Python ``latex2mathml``; each formula keeps a plain-text form
(``alttext`` and a collapsed text block) for readers without MathML; plots are PNG images
embedded as base64 ``data:`` URIs; styles and the one small script are inline. The script
measures, after the page has loaded, that every ``<math>`` element has a nonzero box,
that fractions are laid out as fractions (numerator above denominator, which a browser
without MathML would not do) and that every image decoded (``naturalWidth > 0``), and
writes the counts into the ``data-math-*``, ``data-frac-*`` and ``data-img-*`` attributes
of ``<body>`` (the test suite reads them from headless Chromium).

:func:`write_report` writes the page atomically (temporary file, then :func:`os.replace`).
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import io
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sympy as sp

from appell.core.equations import is_controlled
from appell.files import atomic_path
from appell.io.printing import ITEMS, REDUNDANT_FORMULAS, latex, printed_equations

__all__ = [
    "EquationRow",
    "equation_groups",
    "mathml",
    "render_report",
    "write_report",
    "solution_figures",
    "solution_plots",
]


@dataclass(frozen=True)
class EquationRow:
    """One displayed equation ``lhs = rhs`` with its equation label, e.g. ``(1.5)``."""

    label: str
    lhs: sp.Expr
    rhs: sp.Expr

    @property
    def text(self) -> str:
        """Plain text, SymPy's ``str`` of both sides."""
        return f"{self.lhs} = {self.rhs}"

    @property
    def latex(self) -> str:
        """LaTeX with dotted time derivatives (:func:`appell.io.printing.latex`)."""
        return f"{latex(self.lhs)} = {latex(self.rhs)}"


def equation_groups(derivation, expand: bool = False) -> list[tuple[str, list[EquationRow]]]:
    """The equations shown in the report, grouped under titles, as ``appell derive`` prints
    them (:func:`appell.io.printing.printed_equations`): short formulas in closed form, then
    the subexpressions the longer ones share, each defined once (last, after the formulas
    that use them). ``expand``: each reaction also in the state, the accelerations of (1.4)
    substituted (by default its (1.5) names them).

    For a :class:`~appell.core.equations.Derivation`: the accelerations of (1.4) and the
    dependent ones from ``f = 0`` (or the equations themselves when they are not solved),
    the multipliers (1.5) ``lambda = J_h^{-T} E_h``, and each multiplier in terms of the
    state. For a controlled derivation (:mod:`appell.control.servo`): the dynamic
    conditions (2.3), the reduced equations (2.4), the reactions (2.5), the control laws
    and the internal dynamics.
    """
    printed = printed_equations(derivation, expand=expand)
    rows = {item: [f for f in printed.formulas if f.item == item] for item in ITEMS}
    groups = []
    shared = [EquationRow("", sym, e) for sym, e in printed.blocks + printed.definitions]
    if is_controlled(derivation):
        controls = rows["controls"]
        groups.append(
            (
                "Dynamic conditions (2.3) — the equations of the controls",
                [EquationRow(f.label, f.lhs, f.rhs) for f in controls if f.label.startswith("(2.3)")],
            )
        )
        groups.append(
            ("Reduced equations of motion (2.4)", [EquationRow(f.label, f.lhs, f.rhs) for f in rows["motion"]])
        )
        reactions = [EquationRow(f.label, f.lhs, f.rhs) for f in rows["reactions"]]
        if reactions:
            groups.append(("Reactions of the real constraints (2.5)", reactions))
        groups.append(
            ("Control laws", [EquationRow("control", f.lhs, f.rhs) for f in controls if f.label == "(control)"])
        )
        internal = [
            EquationRow("internal", sp.sympify(e), sp.S.Zero)
            for e in getattr(derivation, "internal_dynamics", {}).values()
        ]
        if internal:
            groups.append(("Internal dynamics left by the servo constraints", internal))
        return groups + _shared_group(shared)
    groups.append(
        (
            "Motion: the accelerations of (1.4) — free of multipliers — and f = 0",
            [EquationRow(f.label, f.lhs, f.rhs) for f in rows["motion"]],
        )
    )
    by_formula = [EquationRow(f.label, f.lhs, f.rhs) for f in rows["reactions"] if f.label == "(1.5)"]
    by_state = [EquationRow(f.label, f.lhs, f.rhs) for f in rows["reactions"] if f.label != "(1.5)"]
    if by_formula:
        groups.append(("Reactions (1.5) — one formula per constraint multiplier", by_formula))
    if by_state:
        groups.append(("Each reaction in terms of the state (t, q, w), the accelerations of (1.4) put in", by_state))
    elif printed.notes:
        groups.append(
            (
                "Each reaction in terms of the state (t, q, w): its (1.5) with the accelerations of (1.4) "
                "and f = 0 above (shown substituted with expand=True)",
                [],
            )
        )
    if rows["outputs"]:
        groups.append(
            (
                "Outputs (e.g. joint forces and moments) from t, q, w, the accelerations and the multipliers",
                [EquationRow(f.label, f.lhs, f.rhs) for f in rows["outputs"]],
            )
        )
    return groups + _shared_group(shared)


def _shared_group(shared: list[EquationRow]) -> list[tuple[str, list[EquationRow]]]:
    return (
        [
            (
                "Named blocks (the reduced mass matrix M_r, forcing f_r) and shared subexpressions of the longer "
                "formulas above, each defined once",
                shared,
            )
        ]
        if shared
        else []
    )


# ------------------------------------------------------------------ mathematics
_XMLNS = re.compile(r'\s+xmlns="[^"]*"')


def mathml(latex_source: str, display: bool = True, alttext: str | None = None) -> str | None:
    """MathML for a LaTeX formula (``latex2mathml``), or None if it cannot be converted.

    The namespace attribute is dropped (HTML5 knows ``<math>``), so the page holds no
    URL at all; ``alttext`` carries the plain-text form.
    """
    try:
        from latex2mathml.converter import convert
    except ImportError:  # the plain-text fallback is shown instead
        return None
    try:
        markup = convert(latex_source, display="block" if display else "inline")
    except Exception:  # latex2mathml raises its own exception types for unsupported input
        return None
    markup = _XMLNS.sub("", markup, count=1)
    if alttext:
        markup = markup.replace("<math", f'<math alttext="{html.escape(alttext, quote=True)}"', 1)
    return markup


def _formula(latex_source: str, text: str, display: bool = True) -> str:
    """A formula as MathML with its plain text (or the plain text alone)."""
    markup = mathml(latex_source, display, alttext=text)
    plain = html.escape(text)
    if markup is None:
        return f'<code class="plain-only">{plain}</code>'
    if not display:
        return markup
    return f'{markup}<details class="plain"><summary>plain text</summary><code>{plain}</code></details>'


def _inline(expr) -> str:
    expr = sp.sympify(expr)
    return _formula(latex(expr), str(expr), display=False)


# ------------------------------------------------------------------ plots
def _png_data_uri(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80, metadata={"Software": None})
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def solution_figures(solution, panels=None) -> list[tuple[str, str]]:
    """``(caption, data URI)`` of :func:`solution_plots`."""
    return [(key, uri) for key, uri, _ in solution_plots(solution, panels)]


def solution_plots(solution, panels=None) -> list[tuple[str, str, tuple[float, float, float, float]]]:
    """``(caption, data URI)`` of PNG plots of a :class:`~appell.simulation.solution.Solution`,
    one per panel of :meth:`~appell.simulation.solution.Solution.panels` (coordinates,
    speeds, reactions, controls, constraint residuals; panels with nothing to show are
    left out; ``panels`` keeps only the named ones, ``('reactions', 'controls')`` say), drawn
    as :meth:`~appell.simulation.solution.Solution.plot` draws them. The
    figures are made without :mod:`matplotlib.pyplot`: the user's backend is left alone.
    With each, the time axis ``(t0, t1, x0, x1)``: the times at its ends and their places
    as fractions of the image's width (the page's time cursor)."""
    from matplotlib.figure import Figure

    from appell.simulation.solution import draw_panel

    out = []
    for key, label, series, log in solution.panels():
        if not series or (panels is not None and key not in panels):
            continue
        fig = Figure(figsize=(7.5, 3.0), constrained_layout=True)
        ax = fig.subplots()
        draw_panel(ax, solution.t, label, series, log, getattr(solution, "events", ()))
        ax.set_xlabel("t [s]")
        uri = _png_data_uri(fig)  # drawn: the layout is final
        box = ax.get_position()
        t0, t1 = ax.get_xlim()
        out.append((key, uri, (t0, t1, box.x0, box.x1)))
    return out


# ------------------------------------------------------------------ page
_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 64rem; margin: 2rem auto;
       padding: 0 1rem; color: #1b1b1b; line-height: 1.45; }
h1 { font-size: 1.6rem; margin-bottom: .2rem; } h2 { border-bottom: 1px solid #ccc; margin-top: 2rem; }
h3 { font-size: 1.05rem; margin-top: 1.4rem; }
table { border-collapse: collapse; margin: .5rem 0; } th, td { border: 1px solid #ddd; padding: .25rem .6rem;
       text-align: left; vertical-align: top; } th { background: #f4f4f4; }
.eq { display: flex; align-items: flex-start; gap: 1rem; margin: .5rem 0; }
.eq .label { min-width: 6rem; color: #555; font-size: .9rem; padding-top: .4rem; }
.eq .body { overflow-x: auto; flex: 1; }
math[display="block"] { margin: .2rem 0; }
details.plain summary { font-size: .75rem; color: #777; cursor: pointer; }
details.plain code, code.plain-only { font-size: .8rem; white-space: pre-wrap; word-break: break-all; }
.pass { color: #1a7f37; font-weight: bold; } .fail { color: #c62828; font-weight: bold; }
figure { margin: 1rem 0; } figure img { max-width: 100%; border: 1px solid #eee; }
.muted { color: #666; font-size: .9rem; } pre { background: #f7f7f7; padding: .6rem; overflow-x: auto; }
"""

# Runs after load; no network. Writes what rendered into attributes of <body>.
_RENDER_CHECK = """
window.addEventListener("load", function () {
  var maths = document.querySelectorAll("math"), rendered = 0;
  for (var i = 0; i < maths.length; i++) {
    var r = maths[i].getBoundingClientRect();
    if (r.width > 0 && r.height > 0) rendered++;
  }
  var imgs = document.querySelectorAll("img"), loaded = 0;
  for (var j = 0; j < imgs.length; j++) {
    if (imgs[j].complete && imgs[j].naturalWidth > 0) loaded++;
  }
  // laid out as mathematics, not as inline text: numerators sit above denominators
  var fracs = document.querySelectorAll("mfrac"), stacked = 0;
  for (var k = 0; k < fracs.length; k++) {
    var parts = fracs[k].children;
    if (parts.length === 2) {
      var num = parts[0].getBoundingClientRect(), den = parts[1].getBoundingClientRect();
      if (num.height > 0 && den.height > 0 && num.bottom <= den.top + 1) stacked++;
    }
  }
  var b = document.body;
  b.setAttribute("data-math-total", maths.length);
  b.setAttribute("data-math-rendered", rendered);
  b.setAttribute("data-frac-total", fracs.length);
  b.setAttribute("data-frac-stacked", stacked);
  b.setAttribute("data-img-total", imgs.length);
  b.setAttribute("data-img-loaded", loaded);
  b.setAttribute("data-render-check", "done");
});
"""


def _e(value) -> str:
    return html.escape(str(value))


def _table(header: Sequence[str] | None, rows: Sequence[Sequence[str]]) -> str:
    """A table; cells are HTML already; no header row when ``header`` is None."""
    head = "" if header is None else "<thead><tr>" + "".join(f"<th>{h}</th>" for h in header) + "</tr></thead>"
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table>{head}<tbody>{body}</tbody></table>"


_COMPONENT = re.compile(r"^(F|M)_(.+)_x$")
_READ = re.compile(r"^(?P<what>.*), x \((?P<axes>[^()]*)\)$")


def _reaction_rows(outputs) -> list[tuple[str, str, str, str]]:
    """One row per vector output ``F_<name>_x, _y, _z`` (``M_...``) of a mechanism: the joint,
    coupling or closure it belongs to, on which body, about which point (the joint origin, a
    marker, the pitch point) and along which axes, as its description says
    (:meth:`appell.mechanism.Mechanism.reaction_output`, ``reactions_in``)."""
    names = {o.name for o in outputs}
    rows = []
    for o in outputs:
        m, read = _COMPONENT.match(o.name), _READ.match(o.description or "")
        if m is None or read is None or not {f"{m[1]}_{m[2]}_y", f"{m[1]}_{m[2]}_z"} <= names:
            continue
        rows.append((_e(f"{m[1]}_{m[2]}_x, _y, _z"), _e(read["what"]), _e(read["axes"]), _e(o.unit or "—")))
    return rows


def _model_section(system, kinematics) -> str:
    parts = ["<h2 id='model'>Model</h2>"]
    if system.description:
        parts.append(f"<p>{_e(system.description)}</p>")
    if system.parameters:
        rows = [
            (_inline(p.symbol), _e(f"{p.value:g}"), _e(p.unit or "—"), _e(p.description or ""))
            for p in system.parameters
        ]
        parts.append("<h3>Parameters</h3>" + _table(("parameter", "value", "unit", "description"), rows))
    view = getattr(system, "view", None)
    if view is not None and any(b.mass is not None for b in view.bodies):
        rows = [
            (
                _e(b.name),
                _e("particle" if b.particle else "rigid body"),
                _e(b.mass or "—"),
                _e(f"[{', '.join(f'{x:g}' for x in b.com)}]"),
                _e(b.inertia or "—"),
            )
            for b in view.bodies
        ]
        parts.append(
            "<h3>Bodies</h3>"
            + _table(
                ("body", "kind", "mass", "mass centre (body frame)", "inertia about the mass centre (body axes)"), rows
            )
        )
    if view is not None and view.joints:
        rows = [
            (
                _e(j.name),
                _e(j.kind),
                _e(f"{j.parent} → {j.child}"),
                _e(j.origin),
                _e(j.axis or "—"),
                _e(j.coordinates or "—"),
            )
            for j in view.joints
        ]
        parts.append(
            "<h3>Joints</h3>"
            + _table(
                ("joint", "type", "parent → child", "origin (parent frame)", "axis (joint frame)", "coordinates"), rows
            )
        )
    reactions = _reaction_rows(system.outputs)
    if reactions:
        parts.append(
            "<h3>Reactions: where each is read</h3>"
            + _table(("outputs", "force and moment of … on … about …", "axes", "unit"), reactions)
        )
    q = list(kinematics.coordinates)
    w = list(kinematics.speeds)
    rows = [("coordinates q", ", ".join(_inline(s) for s in q)), ("speeds w", ", ".join(_inline(s) for s in w))]
    relations = [
        (sp.Symbol(f"{s.name}_dot"), r)
        for s, r in zip(q, kinematics.coordinate_rates)
        if r != sp.Symbol(f"{s.name}_dot")
    ]
    if relations:
        rows.append(("kinematic relations", "<br>".join(_inline(sp.Eq(d, r, evaluate=False)) for d, r in relations)))
    for prog in system.programs:
        rows.append((f"program {_e(prog.symbol)}(t)", _inline(sp.Eq(prog.symbol, prog.expr, evaluate=False))))
    units = system.unit_of
    if system.initial:
        rows.append(
            (
                "initial values",
                _e(", ".join(f"{k} = {v:g}" + (f" {units[k]}" if k in units else "") for k, v in system.initial)),
            )
        )
    parts.append("<h3>Coordinates and speeds</h3>" + _table(None, rows))
    if system.constraints:
        rows = [
            (
                _e(c.name),
                _e(c.kind),
                _inline(sp.Eq(c.expr, 0, evaluate=False)),
                _inline(sp.Symbol(f"lambda_{c.name}"))
                + _e(f" [{units[f'lambda_{c.name}']}]" if f"lambda_{c.name}" in units else ""),
            )
            for c in system.constraints
        ]
        parts.append("<h3>Constraints (ideal)</h3>" + _table(("name", "kind", "constraint", "multiplier"), rows))
    if system.controls:
        rows = [(_e(c.name), _e(c.kind), _inline(c.unknown)) for c in system.controls]
        parts.append("<h3>Controls</h3>" + _table(("control", "kind", "unknown"), rows))
    if system.servo_constraints:
        rows = [(_e(c.name), _e(c.kind), _inline(sp.Eq(c.expr, 0, evaluate=False))) for c in system.servo_constraints]
        parts.append(
            "<h3>Servo constraints (realised by the controls)</h3>" + _table(("name", "kind", "constraint"), rows)
        )
    if system.first_integrals:
        rows = [
            (_e(f.name), _inline(f.expr), _e("—" if f.value is None else f"{f.value:g}"))
            for f in system.first_integrals
        ]
        parts.append("<h3>First integrals</h3>" + _table(("name", "expression", "value"), rows))
    return "\n".join(parts)


def _equation_section(derivation, expand: bool = False) -> str:
    ind, dep = derivation.partition.names(derivation.accelerations)
    parts = [
        "<h2 id='equations'>Equations</h2>",
        f"<p>Independent accelerations: {', '.join(_inline(sp.Symbol(n)) for n in ind) or '—'}; "
        f"dependent accelerations: {', '.join(_inline(sp.Symbol(n)) for n in dep) or '—'} "
        "(condition (1.2): the block of the constraint Jacobian on the dependent accelerations is "
        "nonsingular).</p>",
    ]
    red = getattr(derivation, "redundancy", None)
    if red is not None:  # statically indeterminate supports
        lines = red.summary()
        parts.append(
            "<h3>Redundant constraints (statically indeterminate)</h3><p>"
            + _e(lines[0])
            + "</p><ul>"
            + "".join(f"<li>{_e(line.strip())}</li>" for line in lines[1:])
            + "</ul>"
            "<p>" + _e(REDUNDANT_FORMULAS) + ".</p>"
        )
    if not ind:
        parts.append(
            "<p>No acceleration is free (p = 0): the constraints"
            + (" and the servo constraints" if is_controlled(derivation) else "")
            + " prescribe the motion; the formulas below give "
            + ("the controls and " if is_controlled(derivation) else "")
            + "every reaction along it.</p>"
        )
    for title, rows in equation_groups(derivation, expand):
        parts.append(f"<h3>{_e(title)}</h3>")
        if not rows and not title.startswith("Each reaction"):
            parts.append("<p class='muted'>none</p>")
        for row in rows:
            parts.append(
                f"<div class='eq'><div class='label'>{_e(row.label)}</div>"
                f"<div class='body'>{_formula(row.latex, row.text)}</div></div>"
            )
    return "\n".join(parts)


def _simulation_section(solution, system=None, data_file: str | None = None) -> str:
    parts = ["<h2 id='simulation'>Simulation</h2>", f"<pre>{_e(solution.summary())}</pre>"]
    if data_file:
        parts.append(
            f"<p>Every column of the motion (states, accelerations, reactions, controls, residuals): "
            f'<a href="{_e(data_file)}" download>{_e(data_file)}</a></p>'
        )
    if solution.log:
        parts.append("<details><summary>log</summary><pre>" + _e("\n".join(solution.log)) + "</pre></details>")
    parts.append(_motion_view(system, solution))
    for key, uri, (t0, t1, x0, x1) in solution_plots(solution):
        parts.append(
            f"<figure><div class='appell-plot' data-t0='{t0:.9g}' data-t1='{t1:.9g}' data-x0='{x0:.6f}' "
            f'data-x1=\'{x1:.6f}\'><img src="{uri}" alt="plot of the {_e(key)} over time">'
            f"<div class='appell-cursor'></div></div><figcaption>{_e(key)}</figcaption></figure>"
        )
    return "\n".join(parts)


def _motion_view(system, solution) -> str:
    """The 3-D view of the motion (:mod:`appell.io.viewer`), or a note saying why not."""
    if system is None or solution.t.size == 0:
        return ""
    from appell.errors import AppellError
    from appell.io.viewer import scene_data, viewer_fragment

    try:
        scene = scene_data(system, solution)
    except (AppellError, ValueError, TypeError, ZeroDivisionError) as exc:
        return f"<p class='muted'>The motion cannot be drawn: {_e(exc)}</p>"
    return (
        "<h3 id='motion'>The motion</h3><p class='muted'>Drag to turn, scroll to zoom; the cursor on every "
        "plot follows the time, and a click on a plot shows that time.</p>" + viewer_fragment(scene)
    )


def _check_section(check, tolerance: float, energy=None, energy_tolerance: float | None = None) -> str:
    """The cross-check: a :class:`~appell.numerics.crosscheck.CrossCheckReport` (one table
    row per route and line, with the normalisation stated) or the controlled systems'
    check of :mod:`appell.control.servo_numeric`; then the energy balance
    (:class:`~appell.simulation.energy_balance.EnergyBalance`) when given. The verdict
    fails when any line exceeds its tolerance."""
    from appell.simulation.energy_balance import ENERGY_TOLERANCE

    energy_tolerance = ENERGY_TOLERANCE if energy_tolerance is None else energy_tolerance
    ok = check.passed(tolerance) and (energy is None or energy.passed(energy_tolerance))
    verdict = "<span class='pass'>passed</span>" if ok else "<span class='fail'>failed</span>"
    parts = ["<h2 id='check'>Cross-check</h2>"]
    if hasattr(check, "comparisons"):
        from appell.numerics.crosscheck import NORMALISATION

        rows = []
        for c in check.comparisons:
            note = f" ({c.skipped} state(s) skipped: {c.note})" if c.skipped else ""
            for key, value in c.lines.items():
                flag = "" if value <= tolerance else " <span class='fail'>exceeds</span>"
                rows.append((_e(c.route), _e(c.description + note), _e(key), f"{value:.3e}{flag}"))
        text = (
            "nothing was cross-checked"
            if not check.checked
            else f"the split route against independent routes at {check.states} states"
        )
        parts.append(
            f"<p>{_e(text)}: {verdict} (tolerance {tolerance:g} on every line"
            + (f", {energy_tolerance:g} on the energy balance" if energy is not None and energy.formed else "")
            + f"). Normalisation: {_e(NORMALISATION)}.</p>"
        )
        if rows:
            parts.append(_table(("route", "against", "quantity", "largest normalised difference"), rows))
        for route, reason in check.unavailable.items():
            parts.append(f"<p class='muted'>{_e(route)}: not available — {_e(reason)}</p>")
    else:
        rows = [
            ("controls", f"{check.controls:.3e}"),
            ("accelerations", f"{check.accelerations:.3e}"),
            ("multipliers", f"{check.multipliers:.3e}"),
        ]
        if np.isfinite(check.servo_multipliers):
            rows.append(("servo multipliers (2.3) at the solution (absolute)", f"{check.servo_multipliers:.3e}"))
        route = getattr(check, "route", "augmented")
        what = (
            "the independent augmented multiplier system with the controls as unknowns"
            if route == "augmented"
            else f"the {_e(route)} route"
        )
        parts.append(
            f"<p>The split route against {what} at {check.states} states: {verdict} "
            f"(tolerance {tolerance:g} on the largest relative difference).</p>"
        )
        parts.append(_table(("quantity", "largest relative difference"), rows))
    parts.append(f"<pre class='muted'>{_e(str(check))}</pre>")
    if energy is not None:
        parts.append("<h3>Energy balance</h3>")
        if energy.formed:
            state = (
                "<span class='pass'>holds</span>"
                if energy.passed(energy_tolerance)
                else "<span class='fail'>fails</span>"
            )
            parts.append(
                f"<p>E(t) − E(0) against the work of the applied forces and of the reactions along the "
                f"motion from the initial values: {state} (relative residual {energy.relative:.3e}, "
                f"tolerance {energy_tolerance:g}).</p>"
            )
        parts.append(f"<pre class='muted'>{_e(str(energy))}</pre>")
    return "\n".join(parts)


def _integrals_section(report) -> str:
    """The verdict on each candidate first integral (:mod:`appell.reduction.first_integrals`)."""
    rows = [(_e(c.name), _e(c.verdict), _e(c.route), _e(c.message)) for c in report.checks]
    verdict = (
        f"Reducible by {len(report.integrals)} first integral(s): {', '.join(report.integrals)}."
        if report.reducible
        else "Not reducible: no candidate is a first integral."
    )
    return (
        "<h2 id='integrals'>First integrals (method.md §5)</h2>"
        "<p>Each candidate is added as a constraint; its multiplier (1.5) vanishes on the motion "
        "exactly when it is a first integral.</p>"
        + _table(("candidate", "verdict", "shown", "detail"), rows)
        + f"<p>{_e(verdict)}</p>"
    )


def _internal_section(linearisation) -> str:
    """The internal dynamics linearised at the initial state
    (:class:`~appell.control.internal_dynamics.InternalLinearisation`), with a warning when unstable."""
    values = ", ".join(
        f"{z.real:.6g}" + (f" {'+' if z.imag >= 0 else '−'} {abs(z.imag):.6g}i" if z.imag else "")
        for z in linearisation.eigenvalues
    )
    warning = linearisation.warning()
    verdict = (
        f"<p class='fail'>Unstable: {_e(warning)}.</p>"
        if warning
        else "<p class='pass'>Not unstable to first order.</p>"
    )
    return (
        "<h2 id='internal'>Internal dynamics</h2>"
        f"<p>What is left of the motion once the controls realise the servo constraints, linearised at "
        f"t = {linearisation.time:g} in {_e(', '.join(linearisation.coordinates))} "
        f"(Jacobian of the closed-loop motion on the servo manifold): eigenvalues {_e(values)}.</p>" + verdict
    )


def _stability_section(sweep) -> str:
    """The eigenvalues of a :class:`~appell.numerics.stability.StabilitySweep` against its
    parameter (plot), the crossings where a mode turns unstable or stable (table) and the
    stable range."""
    rows = [
        [
            _e(f"{c.value:.12g}"),
            _e(f"{c.mode}: {sweep.names[c.mode]}"),
            "unstable" if c.direction > 0 else "stable",
            _e(c.kind),
            _e(f"{abs(c.imag):.6g}") if c.kind == "oscillatory" else "",
        ]
        for c in sweep.crossings
    ]
    stable = sweep.stable()
    inside = sweep.values[stable]
    verdict = (
        (
            f"Stable at {int(stable.sum())} of {stable.size} values"
            + (f" (from {inside.min():g} to {inside.max():g})." if inside.size else ".")
        )
        if stable.any()
        else "Unstable at every value."
    )
    figure = _png_data_uri(sweep.plot())
    return (
        "<h2 id='stability'>Stability</h2>"
        f"<p>Eigenvalues of the linear model (<code>appell.linearise</code>, states "
        f"{_e(', '.join(sweep.states))}) at {sweep.values.size} values of {_e(sweep.name)} from "
        f"{sweep.values[0]:g} to {sweep.values[-1]:g} (the model's [stability] table), modes tracked "
        "across the values; each crossing of a real part through zero located by root finding.</p>"
        f"<figure><img alt='eigenvalues against {_e(sweep.name)}' src='{figure}'></figure>"
        + (
            _table([f"{sweep.name}", "mode", "becomes", "kind", "frequency [rad/s]"], rows)
            if rows
            else "<p>No mode changes stability over the range.</p>"
        )
        + f"<p>{_e(verdict)}</p>"
    )


def render_report(
    derivation,
    solution=None,
    check=None,
    *,
    title: str | None = None,
    tolerance: float = 1e-9,
    simulation_note: str | None = None,
    integrals=None,
    internal=None,
    energy=None,
    energy_tolerance: float | None = None,
    stability=None,
    data_file: str | None = None,
    expand: bool = False,
) -> str:
    """The HTML page (a string) for ``derivation`` (a :class:`~appell.core.equations.Derivation`
    or a controlled derivation of :mod:`appell.control.servo`), with the plots of ``solution``
    (:class:`~appell.simulation.solution.Solution`) and the table of ``check``
    (:class:`~appell.numerics.crosscheck.CrossCheckReport`, judged at ``tolerance``) when given.
    ``simulation_note`` says why there is no simulation (shown in its place); ``integrals``
    a :class:`~appell.reduction.first_integrals.FirstIntegralReport` to show; ``internal`` the
    linearised internal dynamics of a controlled system
    (:func:`appell.control.internal_dynamics.internal_linearisation`), flagged when unstable;
    ``energy`` an :class:`~appell.simulation.energy_balance.EnergyBalance` shown with the
    cross-check and judged at ``energy_tolerance`` (the verdict fails when any line exceeds
    its tolerance); ``stability`` a :class:`~appell.numerics.stability.StabilitySweep`
    (the eigenvalues against a parameter, with the critical values); ``data_file`` the
    motion's data file, linked by its name relative to the page; ``expand`` shows each
    reaction also in the state, the accelerations of (1.4) substituted.
    The simulation section shows the motion in 3-D (:mod:`appell.io.viewer`) beside its plots,
    which share a time cursor with it."""
    from appell import __version__

    system = derivation.system
    title = title or f"appell report: {system.name}"
    sections = [_model_section(system, derivation.kinematics), _equation_section(derivation, expand)]
    nav = ["<a href='#model'>model</a>", "<a href='#equations'>equations</a>"]
    if internal is not None:
        sections.append(_internal_section(internal))
        nav.append("<a href='#internal'>internal dynamics</a>")
    if stability is not None:
        sections.append(_stability_section(stability))
        nav.append("<a href='#stability'>stability</a>")
    if solution is not None:
        sections.append(_simulation_section(solution, system, data_file))
        nav.append("<a href='#simulation'>simulation</a>")
    elif simulation_note:
        sections.append(f"<h2 id='simulation'>Simulation</h2><p class='muted'>{_e(simulation_note)}</p>")
    if check is not None:
        sections.append(_check_section(check, tolerance, energy, energy_tolerance))
        nav.append("<a href='#check'>cross-check</a>")
    if integrals is not None:
        sections.append(_integrals_section(integrals))
        nav.append("<a href='#integrals'>first integrals</a>")
    stamp = _dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    return (
        "\n".join(
            [
                "<!DOCTYPE html>",
                "<html lang='en'><head><meta charset='utf-8'>",
                "<meta name='viewport' content='width=device-width, initial-scale=1'>",
                f"<title>{_e(title)}</title>",
                f"<style>{_STYLE}</style>",
                f"<script>{_RENDER_CHECK}</script>",
                "</head><body>",
                f"<h1>{_e(title)}</h1>",
                f"<p class='muted'>Do Shan's method (Gibbs–Appell equations split into motion and reactions). "
                f"Generated by appell {_e(__version__)} on {_e(stamp)}. " + " · ".join(nav) + "</p>",
                *sections,
                "</body></html>",
            ]
        )
        + "\n"
    )


def write_report(path, derivation, solution=None, check=None, **options) -> Path:
    """Render the report (:func:`render_report`) and write it to ``path`` atomically:
    the page is built first, written to a temporary file beside ``path`` and moved over
    it, so that a failure leaves no partial file. Returns the path."""
    page = render_report(derivation, solution, check, **options)
    path = Path(path)
    with atomic_path(path, suffix=".tmp") as tmp:
        tmp.write_text(page, encoding="utf-8")
    return path

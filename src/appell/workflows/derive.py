"""``appell derive``: the printed equations (:func:`show_derivation`) and their JSON document
(:func:`derivation_json`).
"""

from __future__ import annotations

import json

from appell.workflows.load import _print, _warn_internal, internal_stability


def derivation_json(derivation, reduction=None) -> dict:
    """The JSON document of ``appell derive --format json``.

    Keys (at least): ``coordinates``, ``speeds``, ``independent``, ``dependent``,
    ``reduced_equations`` (1.4)/(2.4), ``multipliers`` (constraint name -> formula
    (1.5)/(2.5)), ``controls`` (control name -> control law from the dynamic conditions
    (2.3); empty without servo constraints), ``first_integrals`` (name -> expression) and,
    with ``reduction`` (a :class:`~appell.reduction.cyclic.RouthReduction`), ``routh``.
    Every expression is a string for reading; ``symbols`` and ``exact`` give them exactly
    (:func:`appell.io.printing.read_json`). ``outputs``: output name -> ``expression``,
    ``unit``, ``description``.
    """
    from appell.io.printing import document_expressions, json_document

    system = derivation.system
    out = document_expressions(derivation)
    out.setdefault(
        "outputs",
        {o.name: {"expression": o.expr, "unit": o.unit, "description": o.description} for o in system.outputs},
    )
    linearisation, _ = internal_stability(derivation)
    if linearisation is not None:
        out["internal_linearisation"] = linearisation.to_json()
    out.setdefault("controls", {})
    if not out.get("first_integrals"):
        out["first_integrals"] = {f.name: f.expr for f in system.first_integrals}
    if reduction is not None:
        out["routh"] = {
            "cyclic": [q.name for q in reduction.cyclic],
            "momenta": {h.name: v for h, v in zip(reduction.momenta, reduction.momentum_values)},
            **dict(reduction.equations()),
        }
    return json_document(out, derivation)


def show_derivation(derivation, fmt: str = "text", reduction=None, only=None, echo=None, expand: bool = False) -> None:
    """``appell derive``: the reduced equations (1.4) and the reaction formulas (1.5) of
    ``derivation`` as ``fmt`` ('text', 'latex' or 'json', :func:`derivation_json`), after the
    Routh ``reduction`` when given; ``only`` the items of :func:`appell.io.printing.to_text`;
    ``expand``: each reaction also in the state (t, q, w), the accelerations substituted
    (JSON always holds it).
    A friction note and a warning on unstable internal dynamics go to stderr."""
    echo = echo or _print
    linearisation, note = internal_stability(derivation)
    if fmt == "json":
        echo(json.dumps(derivation_json(derivation, reduction), indent=2))
    elif fmt == "latex":
        from appell.io.printing import to_latex

        body = to_latex(derivation, only or None, expand=expand)
        echo((reduction.to_latex() + "\n\n" if reduction is not None else "") + body)
    else:
        from appell.io.printing import to_text

        body = to_text(derivation, only or None, expand=expand)
        echo((reduction.to_text() + "\n\n" if reduction is not None else "") + body)
        if linearisation is not None and (not only or "controls" in only):
            echo(linearisation.to_text())
    frictions = derivation.system.frictions
    if frictions:
        echo(
            "note: the equations above are those of the ideal constraints; the friction of "
            + ", ".join(f.name for f in frictions)
            + " adds Q_f = (dv_t/dw)^T F_t to Q (sliding: "
            "F_t = -mu_k |N| v_t/|v_t| - c v_t, N by its formula (1.5); sticking: v_t = 0), applied by "
            "simulate and check (docs/friction.md)",
            err=True,
        )
    _warn_internal(linearisation, note, echo)

"""The JSON document of ``appell derive --format json`` gives back exactly the derived
expressions (issue 11 §6): a symbol table and exact trees, read by
:func:`appell.io.printing.read_json`.

The reference in every test is the SymPy expression object appell derived, compared with
the one read back by structural equality (``==`` and :func:`sympy.srepr`), not by
simplification.
"""

import json

import pytest
import sympy as sp
from click.testing import CliRunner

import appell
from appell import Parameter, System, derive, holonomic
from appell.errors import ModelError
from appell.examples import list_examples
from appell.io.cli import cli, derivation_json, load_system
from appell.io.printing import document_expressions, read_json
from bundled import bundled_derivation


def _expressions(node, path=()):
    """(path, expression) of every SymPy leaf of a document (matrices entry by entry)."""
    if isinstance(node, sp.MatrixBase):
        for i, row in enumerate(node.tolist()):
            for j, e in enumerate(row):
                yield path + (i, j), e
    elif isinstance(node, sp.Basic):
        yield path, node
    elif isinstance(node, dict):
        for k, v in node.items():
            yield from _expressions(v, path + (k,))
    elif isinstance(node, (list, tuple)):
        for i, v in enumerate(node):
            yield from _expressions(v, path + (i,))


def _at(node, path):
    for key in path:
        node = node[key]
    return node


def _raw_document(derivation):
    out = document_expressions(derivation)
    out.setdefault("first_integrals", {})
    if not out["first_integrals"]:
        out["first_integrals"] = {f.name: f.expr for f in derivation.system.first_integrals}
    return out


def _assert_round_trip(derivation):
    written = json.loads(json.dumps(derivation_json(derivation)))  # through JSON text
    back = read_json(written)
    shared = "exact_shared" in written  # a large document: shared subexpressions written once
    count = 0
    for path, expr in _expressions(_raw_document(derivation)):
        got = _at(back, path)
        assert got == expr, path
        if not shared:  # srepr and str walk the whole tree: millions of nodes for a shared document
            assert sp.srepr(got) == sp.srepr(expr), path
            assert _at(written, path) == str(expr)  # the readable string stays at the same key
        count += 1
    return count


#: bundled examples whose round trip is tested in their own module (tests/test_bicycle.py,
#: on the derivation it builds anyway) and here only in a slow run
HEAVY = {"benchmark_bicycle"}


@pytest.mark.parametrize(
    "name", [pytest.param(n, marks=pytest.mark.slow) if n in HEAVY else n for n in list_examples()]
)
def test_every_bundled_example_reads_back_structurally_equal(name):
    """Every expression of every bundled example's JSON document == the derived object."""
    derivation = bundled_derivation(name)  # tests/bundled.py
    assert _assert_round_trip(derivation) > 0


def _system_with_sympy_names():
    """Parameters named like SymPy's objects: I (imaginary unit), E (Euler's number), S, N,
    O, Q (SymPy's singleton registry, evalf, Order, assumptions), one of them positive."""
    x, y, xd, yd = sp.symbols("x y x_dot y_dot")
    I, E, S, N, O = sp.symbols("I E S N O")
    Q = sp.Symbol("Q", positive=True)
    return System(
        name="sympy_names",
        coordinates=(x, y),
        parameters=(
            Parameter(I, 2.0),
            Parameter(E, 3.0),
            Parameter(S, 0.5),
            Parameter(N, 1.5),
            Parameter(O, 0.7),
            Parameter(Q, 1.1),
        ),
        kinetic_energy=I / 2 * xd**2 + S / 2 * yd**2,
        potential_energy=E * x**2 / 2 + N * sp.sin(y),
        constraints=(holonomic("link", O * x - Q * y),),
    )


def test_parameters_named_I_E_S_N_O_Q_read_back_as_symbols():
    """The defect: sympify of the printed string reads I as the imaginary unit; read_json
    gives the derived expression itself (structural equality), with Q's assumption."""
    derivation = derive(_system_with_sympy_names())
    doc = json.loads(json.dumps(appell.to_json(derivation)))
    lam = derivation.reactions.as_dict()["link"]
    for text, expr in ((doc["multipliers"]["link"], lam), (doc["blocks"]["mass_matrix"][0][0], sp.Symbol("I"))):
        assert _sympify_or_none(text) != expr  # sympify misreads the string (or fails)
    back = read_json(doc)
    assert back["multipliers"]["link"] == lam
    assert sp.srepr(back["blocks"]["mass_matrix"][0][0]) == sp.srepr(sp.Symbol("I"))
    assert doc["symbols"]["Q"] == {"role": "parameter", "assumptions": {"positive": True}}
    assert doc["symbols"]["I"] == {"role": "parameter", "assumptions": {}}
    assert doc["symbols"]["x_ddot"]["role"] == "acceleration"
    assert _assert_round_trip(derivation) > 10


def _sympify_or_none(text):
    try:
        return sp.sympify(text)
    except (TypeError, ValueError, SyntaxError, AttributeError):
        return None


def test_cli_json_and_routh_section_read_back(tmp_path):
    """``appell derive --routh --format json``: the Routh formulas (T*, V, L*) read back
    equal to :meth:`RouthReduction.equations` of the same model."""
    from appell.reduction.cyclic import routh_reduction

    result = CliRunner().invoke(cli, ["derive", "symmetric_top", "--routh", "--format", "json"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.output)
    path = tmp_path / "top.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    back = read_json(path)
    reduction = routh_reduction(load_system("symmetric_top"))
    for name, expr in reduction.equations():
        assert back["routh"][name] == expr
        assert sp.srepr(back["routh"][name]) == sp.srepr(expr)


def test_factored_expressions_keep_their_structure():
    """A factored product 2*(x + I) (SymPy keeps it unevaluated) is not re-expanded, which
    re-parsing a string would do."""
    from appell.io.expression_tree import expression_from_tree, expression_tree

    x, I = sp.symbols("x I")
    e = sp.factor(2 * x + 2 * I) / (x - sp.Float(0.1))
    back = expression_from_tree(json.loads(json.dumps(expression_tree(e))), {"x": x, "I": I})
    assert sp.srepr(back) == sp.srepr(e)
    assert sp.srepr(sp.sympify(str(e)).subs(sp.I, I)) != sp.srepr(e)


@pytest.mark.parametrize(
    "tree, why",
    [
        (["Symbol", "__import__"], "not in the symbol table"),
        (["eval", ["Integer", "1"]], "unknown head"),
        (["Integer", "1e5"], "not an integer literal"),
        (["Integer", "9" * 5000], "not an integer literal"),
        (["Rational", "2", "4"], "lowest terms"),
        (["Float", 0, "zz", 0, 1, 53], "hexadecimal"),
        (["Constant", "os"], "unknown constant"),
        ("x", "must be a list"),
    ],
)
def test_read_json_refuses_malformed_trees(tree, why):
    """Hostile or broken documents raise ModelError naming the node; nothing is evaluated."""
    doc = {"symbols": {"x": {"role": "coordinate", "assumptions": {}}}, "exact": {"e": tree}}
    with pytest.raises(ModelError, match=why):
        read_json(doc)


def test_read_json_refuses_deep_nesting_and_missing_table():
    """A tree nested beyond MAX_DEPTH, and a document without the exact part."""
    from appell.io.expression_tree import MAX_DEPTH

    tree = ["Symbol", "x"]
    for _ in range(MAX_DEPTH + 5):
        tree = ["sin", tree]
    with pytest.raises(ModelError, match="nested deeper"):
        read_json({"symbols": {"x": {"assumptions": {}}}, "exact": {"e": tree}})
    with pytest.raises(ModelError, match="'symbols' or 'exact' is missing"):
        read_json({"multipliers": {"rod": "x"}})
    with pytest.raises(ModelError, match="assumptions"):
        read_json({"symbols": {"x": {"assumptions": {"positive": "yes"}}}, "exact": {}})

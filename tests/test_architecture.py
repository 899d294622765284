"""Imports flow one way: model -> core (symbolic) -> numerics -> simulation -> control and
reduction (the methods built on the simulation) -> io/cli, with errors, symbols and
files underneath all and the package's ``__init__`` on top (issue 14, "Architecture").

Every import in the package, at module level or inside a function, is read with ``ast``;
a module may import its own layer or lower ones only.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import appell
from appell import numeric_model

PACKAGE = Path(appell.__file__).parent

#: layer of each top-level module or subpackage of appell (higher imports lower)
LAYERS = {
    "errors": 0,
    "names": 0,
    "symbols": 0,
    "files": 0,
    "arguments": 0,
    "_cache": 0,
    "model": 1,
    "rigid_tree": 1,
    "mechanism": 1.5,
    "examples": 2,
    "core": 3,
    "numerics": 4,
    "simulation": 5,
    "control": 6,
    "reduction": 6,
    "io": 7,
    "workflows": 7,
    "view": 1,
}


def _unit(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "appell" else None


def _imports(path: Path, module: str):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against the module's package
                base = (
                    module.split(".")[: -node.level]
                    if not path.name == "__init__.py"
                    else module.split(".")[: len(module.split(".")) - node.level + 1]
                )
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            yield node.lineno, target


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).with_suffix("")
        parts = ("appell",) + rel.parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        yield path, ".".join(parts)


def test_every_module_has_a_layer():
    units = {_unit(m) for _, m in _modules()} - {None, "__main__"}
    assert units <= set(LAYERS), f"give these a layer: {sorted(units - set(LAYERS))}"


def test_no_layer_imports_a_higher_one():
    """Fails listing ``file:line imports module`` for each import against the flow."""
    bad = []
    for path, module in _modules():
        unit = _unit(module)
        if unit is None or unit == "__main__":  # the package's __init__ (and __main__) sit on top
            continue
        for line, target in _imports(path, module):
            other = _unit(target)
            if other is None or other == unit:
                continue
            if LAYERS.get(other, 99) > LAYERS[unit]:
                bad.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {target}")
    assert not bad, "imports against the layers:\n" + "\n".join(bad)


def test_no_import_circle_inside_a_layer():
    """Modules of one layer may import each other, but never in a circle."""
    circles = _circles(_import_graph(list(_modules())))
    assert not circles, "import circles:\n" + "\n".join(" -> ".join(c) for c in circles)


def test_controlled_derivations_are_told_apart_by_their_type():
    """Plain and controlled derivations share the base appell.core.equations.Derived, whose
    ``controlled`` every layer reads (issue 21: 'is it controlled?' was a hasattr test in five
    places): no module probes for the attributes of a controlled derivation."""
    import appell
    from appell.core.equations import Derived, is_controlled
    from appell.io.cli import derive_model, load_system

    plain, controlled = appell.derive(appell.load_model("pendulum")), derive_model(load_system("cart_pole"))
    assert isinstance(plain, Derived) and isinstance(controlled, Derived)
    assert (is_controlled(plain), is_controlled(controlled), is_controlled(numeric_model(plain))) == (
        False,
        True,
        False,
    )
    probes = [
        f"{path.relative_to(PACKAGE)}:{node.lineno}"
        for path in PACKAGE.rglob("*.py")
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.Call)
        and getattr(node.func, "id", None) == "hasattr"
        and len(node.args) == 2
        and isinstance(node.args[1], ast.Constant)
        and node.args[1].value in ("control_laws", "dynamic_conditions")
    ]
    assert not probes, probes


def _layer_of(module: str) -> float:
    unit = _unit(module)
    return LAYERS.get(unit, 99) if unit is not None else 99


def test_no_class_carries_code_of_a_higher_layer():
    """After ``import appell`` (which imports every layer), each class of the package holds only
    functions written in its own layer or below (issue 21: the package's ``__init__`` patched
    ``numeric``, ``compiled`` and the printed forms onto the frozen ``Derivation``, a dependency
    on the layers above that the import test could not see). The numeric model comes from
    :func:`appell.numerics.boundary.numeric_model`, the printed forms from
    :mod:`appell.io.printing`."""
    import importlib
    import inspect
    from functools import cached_property

    bad = []
    for _, module in _modules():
        if _unit(module) in (None, "__main__"):
            continue
        mod = importlib.import_module(module)
        for name, cls in vars(mod).items():
            if not inspect.isclass(cls) or cls.__module__ != module:
                continue
            for attr, value in vars(cls).items():
                fn = value.func if isinstance(value, cached_property) else getattr(value, "fget", value)
                fn = getattr(fn, "__func__", fn)
                where = getattr(fn, "__module__", None)
                if callable(fn) and where and where.startswith("appell.") and _layer_of(where) > _layer_of(module):
                    bad.append(f"{module}.{name}.{attr} comes from {where}")
    assert not bad, "attributes from higher layers:\n" + "\n".join(bad)


def test_the_numeric_model_is_kept_outside_the_derivation():
    """``numeric_model`` builds a derivation's numeric functions once and keeps them in
    :mod:`appell.numerics.boundary`, not on the derivation: the same object on the second call,
    the derivation's instance dictionary unchanged, a pickled copy equal in its numbers."""
    import pickle

    import numpy as np

    import appell
    from appell.numerics import boundary

    d = appell.derive(appell.load_model("pendulum"))
    before = set(vars(d))
    model = numeric_model(d)
    assert numeric_model(d) is model and numeric_model(d, "numpy") is model
    assert set(vars(d)) == before
    copy = pickle.loads(pickle.dumps(d))
    q, w = [0.6, -0.8], [0.3, 0.4]
    assert np.allclose(
        numeric_model(copy).solve(0.0, q, w).multipliers, model.solve(0.0, q, w).multipliers, rtol=1e-14, atol=0
    )
    boundary.forget(d)
    assert numeric_model(d) is not model
    with pytest.raises(appell.ModelError, match="unknown numeric backend"):
        numeric_model(d, "fortran")
    with pytest.raises(appell.ModelError, match="needs a derivation"):
        numeric_model(d.system)


def test_the_driver_reads_like_the_method():
    """``simulate`` is a table of contents of a run (issue 21 item 5: it was one function of 364
    lines beside a 221-line bookkeeping class): its code (signature and docstring aside) stays under 90 lines;
    the integrator, the event location, the projection and the record of the run are modules
    of their own; each kind of event that changes a run has one handler; the mode of a run is
    one frozen record, and no module updates a friction model's signs in place."""
    import dataclasses
    import inspect

    from appell.simulation import simulate as driver
    from appell.simulation.events import locate  # noqa: F401 (event location in one place)
    from appell.simulation.integration import Integration  # noqa: F401
    from appell.simulation.projection import project  # noqa: F401
    from appell.simulation.recording import Mode

    # the lines of its body after the docstring: the signature, one parameter a line as the
    # formatter writes it, is not code of the run
    function = ast.parse(inspect.getsource(driver.simulate)).body[0]
    body = function.body[1:] if isinstance(function.body[0], ast.Expr) else function.body
    code = function.end_lineno - body[0].lineno + 1
    assert code <= 90, f"simulate has {code} lines of code"
    handlers = {"stop": "_stop", "impact": "_impact", "mode": "_mode_change", "release": "_release"}
    assert all(callable(getattr(driver._Motion, h)) for h in handlers.values())
    assert hasattr(driver._Motion, "on_singular") and dataclasses.is_dataclass(Mode)
    with pytest.raises(dataclasses.FrozenInstanceError):
        Mode().released = ("x",)
    mutations = [
        f"{path.relative_to(PACKAGE)}:{node.lineno}"
        for path in PACKAGE.rglob("*.py")
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.Call)
        and isinstance(node.func, ast.Attribute)
        and node.func.attr == "update"
        and isinstance(node.func.value, ast.Attribute)
        and node.func.value.attr == "signs"
    ]
    assert not mutations, mutations


SOURCE = PACKAGE.parent
#: the modules beside the package (pyproject.toml ``py-modules``): the entry point and its interrupt state
TOP_LEVEL = ("appell_entry", "appell_interrupts")


def _all_modules():
    """The package's modules and the top-level modules beside it, with their files."""
    yield from _modules()
    for name in TOP_LEVEL:
        yield SOURCE / f"{name}.py", name


def _import_graph(modules) -> dict[str, set[str]]:
    """module -> the modules among ``modules`` (``(path, name)`` pairs) that it imports, at module
    level or inside a function; an import of ``appell`` itself (the package's ``__init__``, which
    imports every layer) is left out."""
    names = {m for _, m in modules}
    graph: dict[str, set[str]] = {}
    for path, module in modules:
        deps = set()
        for _, target in _imports(path, module):
            while target and target not in names:
                target = target.rpartition(".")[0]
            if target and target != module and target != "appell" and not module.startswith(target + "."):
                deps.add(target)
        graph[module] = deps
    return graph


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    seen, stack, circles = set(), [], []

    def visit(node):
        if node in stack:
            circles.append(stack[stack.index(node) :] + [node])
            return
        if node in seen:
            return
        seen.add(node)
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            visit(nxt)
        stack.pop()

    for node in sorted(graph):
        visit(node)
    return circles


def test_no_import_circle_through_the_entry_point():
    """No import circle anywhere, the entry point included (issue 45: ``appell_entry`` imported
    ``appell.io.cli``, which imported ``appell_entry`` back for the interrupt state, a circle the
    layer test could not see). The detector itself is checked on a graph with a known circle."""
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c", "a"]]
    graph = _import_graph(list(_all_modules()))
    assert "appell.io.cli" in graph["appell_entry"]  # the entry point's import is seen
    circles = _circles(graph)
    assert not circles, "import circles:\n" + "\n".join(" -> ".join(c) for c in circles)


def test_the_interrupt_state_needs_the_standard_library_only():
    """``appell_interrupts`` is imported before appell (a Ctrl-C during the import of SymPy is
    handled): it imports nothing but the standard library, and the entry point nothing else
    at module level."""
    import sys

    for name in TOP_LEVEL:
        tree = ast.parse((SOURCE / f"{name}.py").read_text(encoding="utf-8"))
        top = {alias.name.split(".")[0] for node in tree.body if isinstance(node, ast.Import) for alias in node.names}
        top |= {node.module.split(".")[0] for node in tree.body if isinstance(node, ast.ImportFrom)}
        assert top <= set(sys.stdlib_module_names) | {"appell_interrupts"}, (name, top)
    every = {
        alias.name.split(".")[0]
        for node in ast.walk(ast.parse((SOURCE / "appell_interrupts.py").read_text()))
        if isinstance(node, ast.Import)
        for alias in node.names
    }
    assert every <= set(sys.stdlib_module_names), every

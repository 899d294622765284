"""Imports flow one way: model -> core (symbolic) -> numerics -> simulation -> control and
reduction (the methods built on the simulation) -> io/cli, with errors, symbols and
files underneath all and the package's ``__init__`` on top (issue 14, "Architecture").

Every import in the package, at module level or inside a function, is read with ``ast``;
a module may import its own layer or lower ones only.
"""

from __future__ import annotations

import ast
from pathlib import Path

import appell

PACKAGE = Path(appell.__file__).parent

#: layer of each top-level module or subpackage of appell (higher imports lower)
LAYERS = {
    "errors": 0, "symbols": 0, "files": 0, "arguments": 0,
    "model": 1, "rigid_tree": 1,
    "mechanism": 1.5,
    "examples": 2,
    "core": 3,
    "numerics": 4,
    "simulation": 5,
    "control": 6, "reduction": 6,
    "io": 7,
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
                base = module.split(".")[: -node.level] if not path.name == "__init__.py" else module.split(".")[: len(module.split(".")) - node.level + 1]
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
    graph: dict[str, set[str]] = {}
    names = {m for _, m in _modules()}
    for path, module in _modules():
        deps = set()
        for _, target in _imports(path, module):
            while target and target not in names:
                target = target.rpartition(".")[0]
            if target and target != module and target != "appell" and not module.startswith(target + "."):
                deps.add(target)
        graph[module] = deps
    seen, stack, circles = set(), [], []

    def visit(node):
        if node in stack:
            circles.append(stack[stack.index(node):] + [node])
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
    assert (is_controlled(plain), is_controlled(controlled), is_controlled(plain.numeric)) == (False, True, False)
    probes = [f"{path.relative_to(PACKAGE)}:{node.lineno}" for path in PACKAGE.rglob("*.py")
              for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
              if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "hasattr" and len(node.args) == 2
              and isinstance(node.args[1], ast.Constant) and node.args[1].value in ("control_laws", "dynamic_conditions")]
    assert not probes, probes

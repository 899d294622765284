"""``appell --help`` and ``appell examples`` answer without importing SymPy (issue 45): the
command line imports click and the standard library; the workflows, the simulation layer
(whose integrators' names and defaults the help of ``--method`` and ``--rtol`` shows) and
the examples' builders are imported by the command that needs them.

Checked in a child process by ``sys.modules`` after the command. The package's own
``__init__`` is a separate matter (it imports the whole API): the first test runs the
command line with the package registered but its ``__init__`` not run, so that it sees what
the command line itself imports; the second runs it as the ``appell`` script does, and is
skipped while ``import appell`` itself loads SymPy."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from processes import SRC, env_with_src

PROBE = """
import json, sys, types
if {bare!r}:  # the package registered without running its __init__ (the API's eager imports)
    package = types.ModuleType("appell")
    package.__path__ = [{package!r}]
    sys.modules["appell"] = package
import io, contextlib
from appell_entry import main
out = io.StringIO()
with contextlib.redirect_stdout(out):
    code = main({args!r})
heavy = sorted(m for m in ("sympy", "scipy", "numpy", "matplotlib") if m in sys.modules)
print(json.dumps({{"code": code, "out": out.getvalue(), "heavy": heavy}}))
"""


def _probe(args, bare):
    code = PROBE.format(bare=bare, package=f"{SRC}/appell", args=args)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env_with_src())
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


@pytest.mark.parametrize(
    "args",
    [["--help"], ["examples"], ["examples", "pendulum"], ["simulate", "--help"]],
    ids=["help", "examples", "example", "simulate-help"],
)
def test_the_command_line_itself_imports_no_sympy(args):
    result = _probe(args, bare=True)
    assert result["code"] == 0
    if args == ["simulate", "--help"]:  # the integrators' names and defaults, read for this help
        assert "[DOP853|" in result["out"] and "else 1e-9)" in result["out"]
        return
    assert "sympy" not in result["heavy"], result["heavy"]
    if args == ["examples"]:
        assert "pendulum" in result["out"] and "benchmarks (published benchmark problems" in result["out"]
    elif args == ["--help"]:
        assert "Commands:" in result["out"] and "simulate" in result["out"]
    else:
        assert "[model]" in result["out"]


def test_appell_help_and_examples_import_no_sympy():
    done = subprocess.run(
        [sys.executable, "-c", "import sys, appell; print('sympy' in sys.modules)"],
        capture_output=True,
        text=True,
        timeout=300,
        env=env_with_src(),
    )
    if done.stdout.strip() == "True":
        pytest.skip("the package's __init__ imports SymPy at once (its lazy imports are another change)")
    for args in (["--help"], ["examples"]):
        result = _probe(args, bare=False)
        assert result["code"] == 0 and "sympy" not in result["heavy"], (args, result["heavy"])

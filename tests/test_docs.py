"""The documentation is executed: every code example on every page, and the Sphinx build.

For each page of ``docs/``, in document order and in a fresh temporary directory (with
``examples/`` pointing at the bundled model files, as at the repository root):

* fenced ``python`` blocks run in one namespace per page;
* lines of ``console`` / ``bash`` blocks that start with ``appell `` (or ``$ appell ``)
  run through the command line (click's CliRunner) and must exit with 0;
* ``toml`` blocks that hold a complete model (a ``[model]`` table and mechanics, or a
  ``[mechanism]``) must load as model files.

The gallery and the API page are checked to cover every bundled example and public module;
the site's build (``sphinx-build -W``) is checked in tests/test_docs_offline.py, so that the
pytest-xdist worker that runs these pages does not wait for it.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
from click.testing import CliRunner

import appell
from appell.examples import example_path, list_examples
from appell.io.cli import cli

DOCS = Path(__file__).resolve().parent.parent / "docs"
EXAMPLES = example_path(list_examples()[0]).parent
PAGES = sorted(p.name for p in DOCS.glob("*.md"))

FENCE = re.compile(r"^(?P<fence>`{3,}|~{3,})(?P<info>[^\n`]*)$")


def code_blocks(text: str):
    """``(language, first line number, code)`` of every fenced block, in order."""
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i].strip()) if not lines[i].startswith((" ", "\t")) else None
        if m is None:
            i += 1
            continue
        fence, info = m.group("fence"), m.group("info").strip()
        start = i + 1
        j = start
        while j < len(lines) and not lines[j].startswith(fence):
            j += 1
        language = info.split()[0] if info else ""
        yield language, start + 1, "\n".join(lines[start:j])
        i = j + 1


def cli_commands(code: str):
    """The ``appell ...`` command lines of a console or bash block, as argument lists."""
    for line in code.splitlines():
        line = line.strip()
        if line.startswith("$ "):
            line = line[2:]
        if line.startswith("appell "):
            yield shlex.split(line, comments=True)[1:]


def is_complete_model(code: str) -> bool:
    """A TOML block with a ``[model]`` table and mechanics (not a fragment of one)."""
    return bool(re.search(r"^\[model\]", code, re.MULTILINE)) and bool(
        re.search(r"^(kinetic_energy|acceleration_energy)\s*=|^\[\[bodies\]\]|^\[mechanism\]", code, re.MULTILINE)
    )


@pytest.fixture()
def workdir(tmp_path, monkeypatch):
    """An empty working directory with ``examples/`` -> the bundled model files."""
    (tmp_path / "examples").symlink_to(EXAMPLES, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    return tmp_path


def test_pages_are_found():
    assert {"index.md", "tutorial.md", "method.md", "gallery.md", "api.md"} <= set(PAGES)


@pytest.mark.parametrize("page", PAGES)
def test_code_examples_run(page, workdir):
    text = (DOCS / page).read_text(encoding="utf-8")
    namespace: dict = {"__name__": f"docs.{page[:-3]}"}
    runner = CliRunner()
    ran = 0
    for language, line, code in code_blocks(text):
        where = f"docs/{page}:{line}"
        if language in ("python", "py", "python3"):
            exec(compile(code, where, "exec"), namespace)  # noqa: S102 - our own documentation
            ran += 1
        elif language in ("console", "bash", "shell", "sh"):
            for args in cli_commands(code):
                result = runner.invoke(cli, args, catch_exceptions=False)
                assert result.exit_code == 0, f"{where}: appell {shlex.join(args)}\n{result.output}{result.stderr}"
                ran += 1
        elif language == "toml" and is_complete_model(code):
            appell.loads_model(code, source=where)
            ran += 1
    if page in ("tutorial.md", "method.md", "gallery.md"):
        assert ran >= 3, f"{page}: expected runnable examples"


def test_tutorial_model_is_the_bundled_one():
    """The tutorial prints the knife edge's model file; it must not drift from the file."""
    text = (DOCS / "tutorial.md").read_text(encoding="utf-8")
    shown = next(code for lang, _, code in code_blocks(text) if lang == "toml" and "knife_edge" in code)
    a, b = appell.loads_model(shown), appell.load_model(example_path("knife_edge"))
    assert [(c.name, c.expr) for c in a.constraints] == [(c.name, c.expr) for c in b.constraints]
    assert a.parameters == b.parameters and a.initial == b.initial
    assert a.kinetic_energy == b.kinetic_energy and a.potential_energy == b.potential_energy


def test_gallery_covers_every_bundled_example():
    text = (DOCS / "gallery.md").read_text(encoding="utf-8")
    headings = " ".join(line for line in text.splitlines() if line.startswith("#"))
    missing = [name for name in list_examples() if f"`{name}`" not in headings]
    assert not missing, f"docs/gallery.md has no section for {missing}"


def test_api_page_covers_every_public_module():
    text = (DOCS / "api.md").read_text(encoding="utf-8")
    documented = set(re.findall(r"automodule:: (appell[\w.]*)", text))
    package = Path(appell.__file__).parent
    modules = set()
    for path in package.rglob("*.py"):
        parts = path.relative_to(package).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if parts and not any(p.startswith("_") for p in parts):
            modules.add(".".join(("appell",) + parts))
    missing = sorted(modules - documented)
    assert not missing, f"docs/api.md does not document {missing}"


def test_readme_python_example_runs(workdir, capsys):
    """The README's Python example runs as printed and gives the rod tension it states
    (m g cos(theta) = 9.81 * 0.8 = 7.848 N at rest at x = 0.6, y = -0.8)."""
    readme = (DOCS.parent / "README.md").read_text(encoding="utf-8")
    blocks = [(line, code) for language, line, code in code_blocks(readme) if language == "python"]
    assert blocks, "README.md has no python block"
    for line, code in blocks:
        namespace: dict = {"__name__": "readme"}
        exec(compile(code, f"README.md:{line}", "exec"), namespace)  # noqa: S102 - our own README
    assert namespace["sol"].multipliers[0] == pytest.approx(9.81 * 0.8, rel=1e-12)
    assert "lambda_rod" in capsys.readouterr().out

"""Packaging: the licence and its metadata in the built wheel, the README's links, and the
environment script that installs the runtime for the main command and the test tools only
for the test command."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_license_is_mit_and_declared_in_pyproject():
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert text.startswith("MIT License")
    assert "Permission is hereby granted, free of charge" in text and 'THE SOFTWARE IS PROVIDED "AS IS"' in text
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert project["license"] == "MIT" and project["license-files"] == ["LICENSE"]


def test_the_wheel_carries_the_licence_and_its_metadata(tmp_path):
    """Build the wheel from a copy of the sources (setuptools' PEP 517 backend, offline) and
    read its METADATA: License-Expression MIT, License-File LICENSE, the file itself."""
    setuptools = pytest.importorskip("setuptools")
    if int(setuptools.__version__.split(".")[0]) < 77:
        pytest.skip("license-files needs setuptools >= 77 (the extra [test] installs it)")
    tree = tmp_path / "tree"
    tree.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, tree / name)
    shutil.copytree(ROOT / "src", tree / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    dist = tmp_path / "dist"
    dist.mkdir()
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from setuptools import build_meta as b; print(b.build_wheel(sys.argv[1]))",
            str(dist),
        ],
        cwd=tree,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    wheel = dist / done.stdout.strip().splitlines()[-1]
    with zipfile.ZipFile(wheel) as zf:
        names = zf.namelist()
        metadata = zf.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
        licence = next(n for n in names if n.endswith(".dist-info/licenses/LICENSE"))
        assert zf.read(licence).decode().startswith("MIT License")
    assert "License-Expression: MIT" in metadata.splitlines()
    assert "License-File: LICENSE" in metadata.splitlines()
    assert "appell/__main__.py" in names  # python -m appell
    assert any(n.startswith("appell/examples/") and n.endswith(".toml") for n in names)


def test_readme_links_nothing_outside_the_repository():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "../" not in text
    targets = re.findall(r"\]\(([^)\s]+)\)", text) + re.findall(r"""(?:href|src)=["']([^"']+)""", text)
    assert targets, "the README links the method page"
    for target in targets:
        assert not re.match(r"[a-z]+:", target), f"external link {target}"
        path = (ROOT / target.split("#")[0]).resolve()
        assert path.is_relative_to(ROOT) and path.exists(), target
    assert "docs/method.md" in targets


# ------------------------------------------------------------------ scripts/env.sh
STUB_PYTHON = """#!/usr/bin/env bash
echo "$*" >> "$(dirname "$0")/../calls.log"
"""


def _env(tree: Path, mode: str) -> list[str]:
    """Source env.sh in ``mode`` with a stub interpreter; the pip installs it asked for."""
    log = tree / ".venv" / "calls.log"
    log.unlink(missing_ok=True)
    done = subprocess.run(
        ["bash", "-c", f"source scripts/env.sh {mode} && command -v python"],
        cwd=tree,
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "PATH": os.environ["PATH"]},
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == str(tree / ".venv" / "bin" / "python")  # the environment comes first on PATH
    return [line for line in log.read_text().splitlines() if "install" in line and "-e" in line] if log.exists() else []


def test_env_script_installs_the_runtime_for_the_main_command_and_test_tools_for_tests(tmp_path):
    tree = tmp_path / "repo"
    (tree / "scripts").mkdir(parents=True)
    shutil.copy(ROOT / "scripts" / "env.sh", tree / "scripts" / "env.sh")
    shutil.copy(ROOT / "pyproject.toml", tree / "pyproject.toml")
    python = tree / ".venv" / "bin" / "python"
    python.parent.mkdir(parents=True)
    python.write_text(STUB_PYTHON)
    python.chmod(0o755)
    assert _env(tree, "runtime") == [f"-m pip install --quiet -e {tree}"]  # no [test]
    assert _env(tree, "runtime") == []  # up to date
    assert _env(tree, "test") == [f"-m pip install --quiet -e {tree}[test]"]
    assert _env(tree, "runtime") == []  # the test environment serves the main command
    assert _env(tree, "test") == []
    with open(tree / "pyproject.toml", "a") as fh:
        fh.write("\n# changed\n")
    assert _env(tree, "runtime") == [f"-m pip install --quiet -e {tree}"]
    for script, mode in (("appell.sh", "runtime"), ("test.sh", "test")):
        text = (ROOT / "scripts" / script).read_text()
        assert re.search(rf'^source .*/env\.sh" {mode}$', text, re.MULTILINE), script

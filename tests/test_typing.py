"""What a type checker sees of ``import appell`` is what the package gives at run time: the
names of appell/__init__.py's ``_LAZY`` table (imported on first use, PEP 562) are imported
again under ``if TYPE_CHECKING:``, each from the same module, so that mypy types
``appell.derive(...)`` instead of taking it as ``Any`` (tests/typing_api.py holds the checks
of the signatures, which scripts/test.sh runs mypy on).

Source of truth: the ``_LAZY`` table itself, read at run time, against the block read with ``ast``."""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import appell

ROOT = Path(__file__).resolve().parents[1]


def _type_checking_imports() -> dict[str, str]:
    tree = ast.parse(Path(appell.__file__).read_text(encoding="utf-8"))
    blocks = [n for n in tree.body if isinstance(n, ast.If) and ast.unparse(n.test) == "TYPE_CHECKING"]
    assert len(blocks) == 1, "one `if TYPE_CHECKING:` block in appell/__init__.py"
    return {
        alias.name: node.module for node in blocks[0].body if isinstance(node, ast.ImportFrom) for alias in node.names
    }


def test_the_type_checking_block_names_every_lazy_name_from_its_module():
    assert _type_checking_imports() == appell._LAZY


def test_mypy_checks_the_package_root_and_the_signature_checks():
    files = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["mypy"]["files"]
    assert "src/appell/__init__.py" in files and "tests/typing_api.py" in files
    assert all((ROOT / f).is_file() for f in files)

"""``appell examples``: the bundled examples listed (:func:`example_listing`) and copied
(:func:`copy_example`).
"""

from __future__ import annotations

import shutil
from pathlib import Path

from appell.files import atomic_path


def _first_line(path: Path) -> str:
    """The model's description (``[model] description``), else its first comment line."""
    import tomllib

    text = path.read_text(encoding="utf-8")
    try:
        description = tomllib.loads(text).get("model", {}).get("description")
    except tomllib.TOMLDecodeError:
        description = None
    if description:
        return str(description)
    for line in text.splitlines():
        if line.startswith("#"):
            return line.lstrip("# ").strip()
    return ""


def example_listing() -> str:
    """``appell examples``: each bundled example and benchmark with its description."""
    from appell.examples import example_path, list_benchmarks, list_examples

    lines = [f"{item:<20s} {_first_line(example_path(item))}" for item in list_examples()]
    lines.append("\nbenchmarks (published benchmark problems, larger):")
    lines += [f"{item:<20s} {_first_line(example_path(item))}" for item in list_benchmarks()]
    return "\n".join(lines)


def copy_example(name: str, to) -> Path:
    """``appell examples NAME --to DIR``: the example's model file copied into ``to`` (created)."""
    from appell.examples import example_path

    source = example_path(name)
    target_dir = Path(to)
    target_dir.mkdir(parents=True, exist_ok=True)
    target = target_dir / source.name
    with atomic_path(target) as tmp:
        shutil.copyfile(source, tmp)
    return target

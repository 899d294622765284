"""Where the package ``example-robot-data`` (in ``appell[test]``) put its robot descriptions:
``ROBOTS``, the folder of its ``robots`` (URDF files of real robots: the UR5, the Panda,
Talos ...), or None where it is not installed (the tests that read them are then skipped)."""

from __future__ import annotations

import sys
from pathlib import Path


def _robots_folder() -> Path | None:
    for base in map(Path, sys.path):
        folder = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if folder.is_dir():
            return folder
    return None


ROBOTS = _robots_folder()

"""Headless Chromium for the tests that look at pages the way a reader does (the HTML
report, the documentation): offline, without the user's profile."""

from __future__ import annotations

import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None)
SKIP_REASON = "headless Chromium is not installed (Debian: apt-get install chromium; .ci/run does it)"

# flags keep the browser off the network and away from the user's profile
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-extensions",
    "--disable-default-apps",
    "--mute-audio",
    "--hide-scrollbars",
]


#: XML namespace names (``document.createElementNS``) in three.js: identifiers, never fetched
_NAMESPACES = re.compile(r"http://www\.w3\.org/(1999/xhtml|2000/svg|1998/Math/MathML)")


def without_namespaces(page: str) -> str:
    """``page`` without the XML namespace names, which look like addresses but are never
    fetched; what remains must name no address."""
    return _NAMESPACES.sub("", page)


def chromium(args, tmp_path, timeout=90) -> subprocess.CompletedProcess:
    profile = tmp_path / "profile"
    cmd = [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


def body_attributes(dom: str) -> dict[str, str]:
    """The ``data-*`` attributes of ``<body>`` in a dumped DOM (written by a render check)."""
    body = re.search(r"<body([^>]*)>", dom)
    assert body, dom[:500]
    return dict(re.findall(r'(data-[a-z-]+)="([^"]*)"', body.group(1)))


class _Resources(HTMLParser):
    """Every attribute value that could make the browser fetch something."""

    def __init__(self):
        super().__init__()
        self.references: list[tuple[str, str, str]] = []

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if name in ("src", "href", "srcset", "data", "poster", "action", "background") and value:
                self.references.append((tag, name, value))


def references(page: str) -> list[tuple[str, str, str]]:
    """``(tag, attribute, value)`` of every attribute of ``page`` that names a resource or link."""
    parser = _Resources()
    parser.feed(page)
    return parser.references

"""MkDocs hook: the site's quick start is the README's, taken at build time.

A page that holds the line ``<!-- quick start: README.md -->`` gets, in its place, the
README's "Quick start" section without its heading, so the two never differ and the tests
run the quick start once (from the README, in an empty folder). Links in it that point into
``docs/`` are made relative to the site.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

PLACEHOLDER = "<!-- quick start: README.md -->"
README = Path(__file__).resolve().parents[2] / "README.md"


def on_page_markdown(markdown: str, **_: Any) -> str:
    if PLACEHOLDER not in markdown:
        return markdown
    return markdown.replace(PLACEHOLDER, quick_start())


def quick_start() -> str:
    text = README.read_text()
    found = re.search(r"^## Quick start\n(.*?)(?=^## )", text, flags=re.S | re.M)
    if found is None:
        raise ValueError("README.md has no '## Quick start' section")
    section = found.group(1).strip()
    return re.sub(r"\]\(docs/", "](", section)

"""The documents stay true and short: the README a user's page (at most 15 KB), DEVELOPERS.md a map
(at most 12 KB), every file they name exists, and they give the quick tests the figure dev.py gives."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DOCS = ("README.md", "DEVELOPERS.md", "docs/method.md", "docs/headless.md")
SEARCHED = ("", "grass_addon", "grass_addon/bridge", "headless", "tests/core", "tests/blender", "tests/window",
            "operators", "panels", "docs", "scenes")


def test_the_readme_and_the_map_stay_short():
    assert (REPO / "README.md").stat().st_size <= 15 * 1024
    assert (REPO / "DEVELOPERS.md").stat().st_size <= 12 * 1024


def test_every_file_the_documents_name_exists():
    missing = []
    for doc in DOCS:
        for name in set(re.findall(r"`([\w./-]+\.(?:py|toml|md))`", (REPO / doc).read_text())):
            if name.startswith("../shared/"):
                continue
            if not any((REPO / folder / name).exists() for folder in SEARCHED):
                missing.append(f"{doc}: {name}")
    assert not missing, missing


def test_the_quick_tests_have_one_figure():
    """README.md, DEVELOPERS.md and dev.py say the same time for ``dev.py test --quick``."""
    figure = re.compile(r"under (\d+) s|< (\d+) s")

    def said(text: str) -> set[str]:
        lines = [line for line in text.splitlines() if "quick" in line]
        following = [text.splitlines()[i + 1] for i, line in enumerate(text.splitlines()) if "--quick" in line
                     and i + 1 < len(text.splitlines())]
        return {a or b for line in lines + following for a, b in figure.findall(line)}

    figures = [said((REPO / name).read_text()) for name in ("README.md", "DEVELOPERS.md", "dev.py")]
    assert all(figures) and figures[0] == figures[1] == figures[2], figures

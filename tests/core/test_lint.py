"""The repository stays ruff-clean (rules and their justified exceptions: ruff.toml), and the engine and
the bridge type-check (mypy.ini)."""

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def test_ruff_reports_nothing():
    result = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "."], cwd=REPO,
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.slow  # (13 s: the quick loop leaves it to dev.py test; mypy on its own: .venv/bin/mypy)
def test_the_engine_and_the_bridge_type_check():
    """mypy on grass_addon/ (the engine and the bridge), operators, panels and headless: what may be
    None is checked before use, a function's arguments and results are what it says (issue #38: 46
    errors in the engine alone before; issue #58: 33 in operators, panels and headless)."""
    result = subprocess.run([sys.executable, "-m", "mypy", "--config-file", "mypy.ini", "--cache-dir", "/dev/null"],
                            cwd=REPO, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Success: no issues found" in result.stdout

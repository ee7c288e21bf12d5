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
    errors in the engine alone before; issue #58: 33 in operators, panels and headless, then 38 more
    once mypy followed their imports of the package, ``windgrass``)."""
    result = subprocess.run([sys.executable, "-m", "mypy", "--config-file", "mypy.ini", "--cache-dir", "/dev/null"],
                            cwd=REPO, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Success: no issues found" in result.stdout


@pytest.mark.slow  # (a mypy run of its own, about 10 s)
def test_a_misread_parameter_is_a_type_error(tmp_path):
    """Every read of a parameter is checked (issue #58: the sections are typed, params_typed.py): a
    misspelt setting and a setting read as what it is not are mypy errors; the right reads pass. The
    probe imports the engine as the headless scripts and the tests do, ``windgrass.grass_addon``
    (mypy.ini's ``.tools/windgrass``: before, that name was unknown to mypy and every read Any)."""
    code = ("from windgrass.grass_addon.schema import Params\n"
            "def speed(params: Params) -> float:\n    return params.wind.speed\n"
            "def typo(params: Params) -> float:\n    return params.wind.sped\n"
            "def kind(params: Params) -> int:\n    return params.wind.type\n"
            "def row(params: Params) -> str:\n    return params.species()[0]['plant']\n")
    probe = tmp_path / "probe.py"
    probe.write_text(code)
    result = subprocess.run([sys.executable, "-m", "mypy", "--config-file", "mypy.ini", "--cache-dir", "/dev/null",
                             str(probe)], cwd=REPO, capture_output=True, text=True)
    errors = [line for line in result.stdout.splitlines() if ": error:" in line]
    assert len(errors) == 2, result.stdout
    assert '"WindSection" has no attribute "sped"' in errors[0]
    assert 'got "str", expected "int"' in errors[1]

"""The test suite cleans up after itself."""

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_a_test_run_leaves_no_temporary_folder(tmp_path):
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    env = dict(os.environ, TMPDIR=str(tmpdir))
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "--basetemp", str(tmp_path / "basetemp"), "tests/core/test_presets.py"],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "passed" in proc.stdout
    assert list(tmpdir.iterdir()) == []


def test_the_engine_has_one_import_name():
    """Scripts, core tests and Blender tests all import the engine as windgrass.grass_addon: one
    copy of every module, one ParameterError class."""
    import sys

    from windgrass.grass_addon import errors, schema

    assert not [name for name in sys.modules if name == "grass_addon" or name.startswith("grass_addon.")]
    assert schema.ParameterError is errors.ParameterError


def test_a_deprecation_warning_from_the_add_ons_code_fails_the_test():
    """Issue #35: numpy 2.5 deprecated assigning ``ndarray.shape`` on the per-frame path, and the
    suite only printed it. A DeprecationWarning raised from Windgrass's code is an error."""
    import pytest
    from windgrass.grass_addon import kinematics

    with pytest.raises(DeprecationWarning):
        exec(compile("import warnings\nwarnings.warn('old', DeprecationWarning)", kinematics.__file__, "exec"),
             {"__name__": kinematics.__name__})


def test_every_test_left_to_one_blender_line_exists():
    """dev.py's whole-suite run on 4.5 LTS leaves some tests to 5.2 LTS by file or node id: a name
    that no longer exists (a renamed test) would run them on both lines, or stop the run."""
    import importlib.util
    import re

    spec = importlib.util.spec_from_file_location("windgrass_dev", REPO / "dev.py")
    dev = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(dev)
    for entry in dev.SAME_ON_EVERY_LINE:
        path, _, name = entry.partition("::")
        assert (REPO / path).is_file(), entry
        if name:  # (a parametrized test's one case by its id: test_name[id])
            function, _, case = name.partition("[")
            assert re.search(rf"^def {function}\(", (REPO / path).read_text(), re.M), entry
            assert not case or f"{case.rstrip(']')}" in (REPO / path).read_text(), entry

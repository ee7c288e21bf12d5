"""Test-wide setup: Blender must write its user files to a temp dir, set before ``import bpy``.

The temp dir is removed when the session ends (``pytest_unconfigure``), so runs leave nothing.
"""

import os
import shutil
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
_tmp = Path(tempfile.mkdtemp(prefix="windgrass-tests-"))
if "bpy" not in sys.modules:
    os.environ["BLENDER_USER_RESOURCES"] = str(_tmp / "blender-user")
    os.environ["HOME"] = str(_tmp / "home")
    (_tmp / "home").mkdir()
if str(REPO / "headless") not in sys.path:
    sys.path.insert(0, str(REPO / "headless"))
import addon_loader  # noqa: E402

# The one name of the package (never `grass_addon` from the repository root: a second copy).
addon_loader.load_package()


def pytest_unconfigure(config):
    shutil.rmtree(_tmp, ignore_errors=True)

"""A process that uses Windgrass on the bpy module exits cleanly with its own status, on every
supported Blender line (4.2 and 4.5 used to segfault or hang at exit once the add-on registered)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

SCRIPT = """
import sys
sys.path.insert(0, {headless!r})
import bpy
import addon_loader
addon = addon_loader.load_addon()
from importlib import import_module
props = import_module(addon.__name__ + ".grass_addon.bridge.properties")
runtime = import_module(addon.__name__ + ".grass_addon.bridge.runtime")
schema = import_module(addon.__name__ + ".grass_addon.schema")
params = schema.defaults().replace({{"field.blocks_x": 1, "field.blocks_y": 1, "field.cells_per_block": 4}})
scene = bpy.context.scene
item = props.add_field(scene, params)
runtime.build_field(scene, item)
scene.frame_set(3)
print("windgrass ready", flush=True)
raise SystemExit({status})
"""


@pytest.mark.parametrize("status", [0, 3])
def test_exit_status_is_the_scripts_own(tmp_path, status):
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"), HOME=str(tmp_path))
    script = SCRIPT.format(headless=str(REPO / "headless"), status=status)
    proc = subprocess.run([sys.executable, "-c", script], env=env, cwd=REPO, capture_output=True,
                          text=True, timeout=120)
    assert "windgrass ready" in proc.stdout, proc.stderr[-2000:]
    assert proc.returncode == status, f"exit status {proc.returncode}\n{proc.stderr[-2000:]}"

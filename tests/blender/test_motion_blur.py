"""Motion blur: every written frame carries a per-vertex velocity (m/s) from the deterministic
simulation, and sub-frames (Blender's motion-blur steps) get the pose of that instant."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
W, H = 128, 72


@pytest.fixture
def bridge(with_bridge):
    import stage
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import owned, properties, runtime

    return schema, properties, runtime, stage, owned


def _attribute(obj, name) -> np.ndarray:
    data = obj.data.attributes[name].data
    out = np.empty(len(data) * 3, np.float32)
    data.foreach_get("vector", out)
    return out.reshape(-1, 3)


def test_velocity_is_the_motion_between_neighbouring_frames(bridge):
    schema, properties, runtime, _, owned = bridge
    scene = bpy.context.scene
    scene.camera = None  # every block is geometry and keeps its slot
    scene.render.use_motion_blur = True
    params = schema.defaults().replace({"field.blocks_x": 2, "field.blocks_y": 2, "field.cells_per_block": 8,
                                        "wind.type": "moderate_breeze", "wind.speed": 12.0})
    item = properties.add_field(scene, params)
    runtime.build_field(scene, item)
    blades = owned.slot_objects(item, owned.ROLE_BLADES)[0]
    positions = {}
    for frame in (29, 31, 30):
        scene.frame_set(frame)
        positions[frame] = _attribute(blades, "position")
    velocity = _attribute(blades, "velocity")
    fps = scene.render.fps
    np.testing.assert_allclose(velocity, (positions[31] - positions[29]) * fps / 2, atol=1e-5)
    assert np.linalg.norm(velocity, axis=1).max() > 0.2  # tips move by decimetres a second
    # A motion-blur step at frame 30.5: the pose halfway, moving at that frame's pace.
    scene.frame_set(30, subframe=0.5)
    np.testing.assert_allclose(_attribute(blades, "position"), 0.5 * (positions[30] + positions[31]), atol=1e-6)
    np.testing.assert_allclose(_attribute(blades, "velocity"), (positions[31] - positions[30]) * fps, atol=1e-4)


def _render(rendered, wind: dict, blur: bool, path: Path, engine: str = "cycles") -> np.ndarray:
    from windgrass.grass_addon import schema

    params = schema.defaults().replace({
        "field.blocks_x": 2, "field.blocks_y": 2, "field.cells_per_block": 8, "field.blades_per_cell": 4, **wind,
        "camera.mode": "fixed", "camera.position": (0.0, -1.0, 0.3), "camera.target": (0.0, 0.0, 0.12),
        "render.engine": engine, "render.samples": 16 if engine == "cycles" else 4,
        "render.resolution_x": W, "render.resolution_y": H,
        "render.motion_blur": blur, "render.shutter": 2.0})
    return rendered(params, 40, path)


def _detail(image: np.ndarray) -> float:
    return float(np.abs(np.diff(image, axis=1)).mean() + np.abs(np.diff(image, axis=0)).mean())


STRONG = {"wind.type": "whirlwind", "wind.speed": 6.0, "wind.vortex_speed": 20.0, "wind.vortex_radius": 0.5,
          "wind.turbulence": 2.0}
CALM = {"wind.type": "calm", "wind.speed": 0.0, "wind.turbulence": 0.0}


def test_eevee_blurs_by_the_sub_frame_poses(rendered, tmp_path, addon):
    """EEVEE renders motion blur from the scene evaluated at sub-frames: the handler's poses of
    those instants. A strong vortex loses fine detail; calm grass does not change."""
    images = {(name, blur): _render(rendered, wind, blur, tmp_path / f"{name}_{blur}.png", "eevee")
              for name, wind in (("calm", CALM), ("strong", STRONG)) for blur in (False, True)}
    assert np.abs(images["calm", True] - images["calm", False]).mean() < 0.001
    assert np.abs(images["strong", True] - images["strong", False]).mean() > 0.01
    assert _detail(images["strong", True]) < 0.85 * _detail(images["strong", False])


def test_blur_smears_moving_grass_and_leaves_still_grass_alone(rendered, tmp_path, addon):
    """Cycles, a close-up: in a strong vortex, blur on changes the image and takes away fine detail
    along the motion; in calm air it changes nothing beyond sampling noise."""
    strong, calm = STRONG, CALM
    images = {(name, blur): _render(rendered, wind, blur, tmp_path / f"{name}_{blur}.png")
              for name, wind in (("calm", calm), ("strong", strong)) for blur in (False, True)}
    calm_change = np.abs(images["calm", True] - images["calm", False]).mean()
    strong_change = np.abs(images["strong", True] - images["strong", False]).mean()
    assert calm_change < 0.004 and strong_change > 5 * calm_change
    assert _detail(images["strong", True]) < 0.7 * _detail(images["strong", False])
    assert abs(_detail(images["calm", True]) - _detail(images["calm", False])) < 0.05 * _detail(images["calm", False])


def test_render_farm_splits_are_pixel_identical_with_blur(tmp_path):
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"), HOME=str(tmp_path))
    config = tmp_path / "blur.toml"
    config.write_text("[field]\nblocks_x = 2\nblocks_y = 2\ncells_per_block = 8\nblades_per_cell = 3\n"
                      "[wind]\ntype = \"moderate_breeze\"\nspeed = 10.0\n"
                      "[camera]\nmode = \"flythrough\"\nheight = 0.4\n"
                      "[render]\nsamples = 2\nresolution_x = 48\nresolution_y = 27\nframe_end = 4\n"
                      "motion_blur = true\nshutter = 1.0\n")
    outs = []
    for frames in ("1-3", "3"):
        out = tmp_path / frames
        proc = subprocess.run([sys.executable, str(REPO / "headless" / "render_field.py"), "--config", str(config),
                               "--frames", frames, "--out", str(out)], env=env, cwd=REPO, capture_output=True,
                              text=True, timeout=300)
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
        outs.append(out)
    full, alone = (np.array(bpy.data.images.load(str(out / "frame_0003.png")).pixels[:]) for out in outs)
    assert np.abs(full - alone).max() == 0.0

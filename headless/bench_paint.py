#!/usr/bin/env python3
"""Benchmark of painting: what a stroke costs in Blender, and what painting grass out saves.

    python3.11 dev.py bench --paint [--json]      (or headless/bench_paint.py in the project's .venv)

Prints one JSON object:

* ``stroke``: for a 100 m and a 1 km field on a terrain mesh painted with a vertex group
  (``paint.density = "vertex_group:meadow"``), the seconds from a stroke's end (a 3 m dab of
  weight, the depsgraph update Blender sends) to the frame showing it: ``stroke_s`` (reading the
  weights, draping them, making again the blocks the dab touched, the frame's writes) against
  ``frame_s``, the same frame written without a stroke (the floor), and their ratio. Goal: under
  0.5 s on the 100 m field.
* ``half_painted``: the engine's frame update (wind, solver, cell data, LOD, the blade vertices of
  every block that needs them) of a 1 km field with its west half painted out, against the same
  field unpainted, the camera on the border looking along it: ``ratio`` (goal: about 0.5).
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # (Blender's -P does not put the script's folder on the path)

import common  # noqa: E402

common.load()  # the engine as windgrass.grass_addon (numpy only, no Blender)
import numpy as np  # noqa: E402
from windgrass.grass_addon import schema  # noqa: E402
from windgrass.grass_addon.field import GrassField  # noqa: E402
from windgrass.grass_addon.lod import Camera  # noqa: E402
from windgrass.grass_addon.paint import Paint, Raster  # noqa: E402


def half_painted(frames: int = 12) -> dict:
    """Frame update of a 1 km field with its west half painted out, against unpainted."""
    params = schema.defaults().replace({"field.blocks_x": 625, "field.blocks_y": 625})
    west = np.ones((4, 1024), np.float32)  # a sharp border (a pixel is 1 m)
    west[:, :512] = 0.0
    paint = Paint(density=Raster(west, (-500.0, -500.0, 500.0, 500.0)))
    cam = Camera.look_at((0.0, -20.0, 1.7), (0.0, 20.0, 0.0), math.radians(70.0))
    out: dict[str, dict] = {}
    for name, field in (("plain", GrassField(params)), ("half_painted", GrassField(params, paint=paint))):
        times = []
        for frame in range(1, frames + 4):
            t0 = time.perf_counter()
            field.frame(frame, 0.0, cam)  # the frame Blender draws
            if frame > 3:
                times.append(time.perf_counter() - t0)
        out[name] = {"frame_ms": round(1000 * statistics.median(times), 2), "window_blocks": int(field.layout.n_blocks)}
    return {**out, "ratio": round(out["half_painted"]["frame_ms"] / out["plain"]["frame_ms"], 3)}


PROFILE = bool(os.environ.get("WINDGRASS_PROFILE"))


def stroke(size_m: float, quads: int) -> dict:
    """A dab on a painted field of ``size_m`` on a terrain grid of ``quads`` x ``quads`` quads."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    common.load(addon=True)
    from windgrass.grass_addon.bridge import runtime

    bpy.ops.mesh.primitive_grid_add(x_subdivisions=quads, y_subdivisions=quads, size=size_m)
    terrain = bpy.context.active_object
    group = terrain.vertex_groups.new(name="meadow")
    group.add(list(range(len(terrain.data.vertices))), 0.5, "REPLACE")
    blocks = max(1, round(size_m / 1.6))
    assert bpy.ops.windgrass.field_add(blocks_x=blocks, blocks_y=blocks, use_selected_mesh=True) == {"FINISHED"}
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    item.paint.density = "vertex_group:meadow"
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.0, -8.0, 1.7)
    cam.rotation_euler = (math.radians(80.0), 0.0, 0.0)
    scene.frame_set(2)
    assert runtime.field_error(scene, item) is None, runtime.field_error(scene, item)
    co: np.ndarray = np.empty(len(terrain.data.vertices) * 3, np.float32)
    terrain.data.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    floors, strokes, made = [], [], []
    for i in range(5):
        t0 = time.perf_counter()
        scene.frame_set(3 + 2 * i)  # the floor: a frame without a stroke
        floors.append(time.perf_counter() - t0)
        centre = np.array([-4.0 + 2.0 * i, 0.0])
        dab = np.flatnonzero(np.hypot(co[:, 0] - centre[0], co[:, 1] - centre[1]) < 1.5)
        group.add(dab.tolist(), 1.0, "REPLACE")
        terrain.data.update()
        t0 = time.perf_counter()
        if PROFILE and i == 4:
            import cProfile
            profile = cProfile.Profile()
            profile.enable()
        bpy.context.view_layer.update()  # the stroke's end: Blender's depsgraph update
        scene.frame_set(4 + 2 * i)
        strokes.append(time.perf_counter() - t0)
        if PROFILE and i == 4:
            import pstats
            profile.disable()
            pstats.Stats(profile, stream=sys.stderr).sort_stats("cumulative").print_stats(25)
        live = runtime.get_runtime(scene, item)
        assert live is not None, "the field has no runtime after a frame change"
        made.append(live.last_repaint[1])
    frame_s, stroke_s = statistics.median(floors), statistics.median(strokes)
    return {"field_m": size_m, "terrain_vertices": len(terrain.data.vertices), "frame_s": round(frame_s, 3),
            "stroke_s": round(stroke_s, 3), "ratio": round(stroke_s / frame_s, 2),
            "blocks_made_again": int(statistics.median(made))}


def main(argv) -> int:
    args = common.parser(__doc__).parse_args(argv)
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp())
    result: dict[str, object] = {"half_painted": half_painted()}
    result["stroke"] = [stroke(100.0, 200), stroke(1000.0, 500)]
    common.emit(result, args)
    return 0


if __name__ == "__main__":
    common.finish(main(sys.argv[1:]))

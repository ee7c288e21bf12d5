#!/usr/bin/env python3
"""Benchmark of a rendered frame of the default scene: where the seconds go.

    python3.11 dev.py bench --render [--json] [--frames N] [--sizes 400x225,1280x720]

For each size, the default scene (scenes/default.toml, Cycles) renders ``--frames`` frames of its
fly-through; each frame is timed as

* ``grass_s``: the frame change (the camera posed, the grass simulated and written);
* ``sync_s``: from the render's start to Cycles' first sample (scene synchronisation, BVH, lights);
* ``render_s``: the whole ``render.render`` call (sync and sampling);
* ``floor_s``: the same frame rendered again with nothing changed (what sampling alone costs, plus
  whatever Cycles redoes without a change);

and ``ratio`` = (grass_s + render_s) / floor_s (goal at 1280x720: under 1.15). Medians over the
frames after the first (the first builds everything).
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # (Blender's -P does not put the script's folder on the path)
import common  # noqa: E402
import render_field  # noqa: E402


def _size(text: str) -> tuple[int, int]:
    w, h = text.lower().split("x")
    return int(w), int(h)


def run(sizes, frames: int) -> dict:
    import bpy

    schema = render_field.addon_module("grass_addon.schema")
    import stage
    out: dict = {}
    for w, h in sizes:
        params = schema.load_toml(render_field.DEFAULT_CONFIG).replace(
            {"render.resolution_x": w, "render.resolution_y": h})
        scene = render_field.build_scene(params)
        marks: dict = {}

        def stats(*args, marks=marks):
            text = " ".join(str(a) for a in args)
            if "Sample" in text and "sample" not in marks:
                marks["sample"] = time.perf_counter()

        handlers = bpy.app.handlers.render_stats if hasattr(bpy.app.handlers, "render_stats") else None
        if handlers is not None:
            handlers.append(stats)
        rows = []
        try:
            folder = Path(tempfile.mkdtemp())
            for i, frame in enumerate(range(params.render.frame_start, params.render.frame_start + frames + 1)):
                t0 = time.perf_counter()
                stage.pose_camera(scene, params, frame)
                scene.frame_set(frame)
                t1 = time.perf_counter()
                scene.render.filepath = str(folder / f"{frame}.png")
                marks.clear()
                bpy.ops.render.render(write_still=False)
                t2 = time.perf_counter()
                sync = marks.get("sample", t2) - t1
                bpy.ops.render.render(write_still=False)
                t3 = time.perf_counter()
                if i:
                    rows.append({"grass_s": t1 - t0, "sync_s": sync, "render_s": t2 - t1, "floor_s": t3 - t2})
        finally:
            if handlers is not None:
                handlers.remove(stats)
        med = {k: round(statistics.median(r[k] for r in rows), 3) for k in rows[0]}
        med["ratio"] = round((med["grass_s"] + med["render_s"]) / med["floor_s"], 3)
        med["persistent_data"] = bool(scene.render.use_persistent_data)
        out[f"{w}x{h}"] = med
    return out


def main(argv) -> int:
    parser = common.parser(__doc__)
    parser.add_argument("--sizes", default="400x225,1280x720", help="image sizes WxH, comma-separated")
    parser.add_argument("--frames", type=int, default=2, help="frames rendered per size (default 2)")
    args = parser.parse_args(argv)
    common.emit(run([_size(s) for s in args.sizes.split(",")], args.frames), args)
    return 0


if __name__ == "__main__":
    common.finish(main(sys.argv[1:]))

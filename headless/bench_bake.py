#!/usr/bin/env python3
"""Size and time of a bake, Alembic against USD, of the same frames of the default scene.

    python3.11 dev.py bench --bake [--json]   (or headless/bench_bake.py in the project's .venv)

Prints one JSON object. The default scene (``scenes/default.toml``: 524,288 blades, the camera
flying over them) is baked over its first 24 frames, once to Alembic and once to USD, each from
a fresh scene and a saved .blend (what the Grass tab's Bake does). For each format: the files'
bytes, bytes per frame, per drawn blade per frame (the blades of the blade pool's slots, which
the files hold whether drawn or collapsed) and the bake's seconds; ``usd_to_alembic``: the ratio
of their sizes in the same run.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # (Blender's -P does not put the script's folder on the path)
import common  # noqa: E402
import render_field  # noqa: E402

FRAMES = 24


def bake(fmt: str, folder: Path) -> dict:
    import bpy

    schema = render_field.addon_module("grass_addon.schema")
    runtime = render_field.addon_module("grass_addon.bridge.runtime")
    owned = render_field.addon_module("grass_addon.bridge.owned")
    bake_module = render_field.addon_module("grass_addon.bridge.bake")
    params = schema.load_toml(render_field.DEFAULT_CONFIG)
    scene = render_field.build_scene(params)
    item = scene.windgrass.fields[0]
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / f"{fmt}.blend"))
    first = params.render.frame_start
    started = time.perf_counter()
    cache = runtime.bake_field(scene, item, first, first + FRAMES - 1, fmt=fmt)
    seconds = time.perf_counter() - started
    size = bake_module.cache_size(cache)
    points = sum(len(o.data.vertices) for o in owned.slot_objects(item, owned.ROLE_BLADES).values())
    blades = points // (2 * (params.blade.segments + 1))
    return {"bytes": size, "bytes_per_frame": size // FRAMES, "blade_slots": blades,
            "bytes_per_blade_per_frame": round(size / (blades * FRAMES), 2), "seconds": round(seconds, 2)}


def main(argv) -> int:
    args = common.parser(__doc__).parse_args(argv)
    common.load(addon=True)
    folder = Path(tempfile.mkdtemp())
    alembic, usd = bake("alembic", folder), bake("usd", folder)
    result = {"frames": FRAMES, "alembic": alembic, "usd": usd,
              "usd_to_alembic": round(usd["bytes"] / alembic["bytes"], 2)}
    common.emit(result, args)
    return 0


if __name__ == "__main__":
    common.finish(main(sys.argv[1:]))

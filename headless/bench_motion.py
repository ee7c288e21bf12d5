#!/usr/bin/env python3
"""Benchmark of Update Motion: sampling a 1M-vertex collider's motion over 100 frames (Blender).

    python3.11 dev.py bench --motion [--json]   (or headless/bench_motion.py in the project's .venv)

Prints one JSON object. A field of 3.2 m and, in turn, a 1,000,000-vertex mesh moved by keys
(``keyed``) and one parented to a keyed bone of an armature (``bone``); each is sampled over 100
frames by ``tracks.sample`` (what Update Motion does). ``floor_s`` is the same 100 frames stepped
by ``scene.frame_set`` alone, in the same run: what Blender needs to evaluate the scene.
``seconds_per_100_frames`` (goal: at most 1 s) and ``ratio`` (against the floor).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # (Blender's -P does not put the script's folder on the path)
import common  # noqa: E402

FRAMES = 100
VERTICES = 1_000_000


def _big_mesh(name: str):
    """A grid of about VERTICES vertices, 1.2 m square, 0.3 m above the ground."""
    import bpy

    side = int(VERTICES ** 0.5)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=side - 1, y_subdivisions=side - 1, size=1.2,
                                    location=(-1.0, 0.0, 0.3))
    obj = bpy.context.active_object
    obj.name = name
    return obj


def _case(kind: str) -> dict:
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    common.load(addon=True)
    from windgrass.grass_addon.bridge import properties, tracks

    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, FRAMES
    assert bpy.ops.windgrass.field_add(blocks_x=2, blocks_y=2, cells_per_block=16) == {"FINISHED"}
    item = scene.windgrass.fields[-1]
    item.interaction.recovery = 0.1  # (the range sampled: the scene's frames and a few before)
    obj = _big_mesh("Collider")
    mover = obj
    if kind == "bone":
        arm = bpy.data.objects.new("Rig", bpy.data.armatures.new("Rig"))
        scene.collection.objects.link(arm)
        bpy.context.view_layer.objects.active = arm
        bpy.ops.object.mode_set(mode="EDIT")
        bone = arm.data.edit_bones.new("carry")
        bone.head, bone.tail = (0.0, 0.0, 0.0), (0.0, 0.0, 0.5)
        bpy.ops.object.mode_set(mode="OBJECT")
        obj.parent, obj.parent_type, obj.parent_bone = arm, "BONE", "carry"
        mover = arm.pose.bones["carry"]
    for frame, x in ((1, -1.0), (FRAMES, 1.0)):
        mover.location = (x, 0.0, 0.0) if kind == "keyed" else (0.0, x + 1.0, 0.0)
        mover.keyframe_insert("location", frame=frame)
    coll = bpy.data.collections.new("Colliders")
    scene.collection.children.link(coll)
    for c in list(obj.users_collection):
        c.objects.unlink(obj)
    coll.objects.link(obj)
    params = properties.params_from_settings(item, scene)
    frames = tracks.frame_range(scene, params)
    item.collider_collection = None
    started = time.perf_counter()
    for f in frames:
        scene.frame_set(f)
    floor = time.perf_counter() - started
    item.collider_collection = coll
    started = time.perf_counter()
    track = tracks.sample(scene, item, params)
    seconds = time.perf_counter() - started
    per_100 = seconds * 100.0 / len(frames)
    return {"vertices": len(obj.data.vertices), "frames": len(frames), "seconds": round(seconds, 3),
            "seconds_per_100_frames": round(per_100, 3), "floor_s": round(floor, 3),
            "ratio": round(seconds / max(floor, 1e-9), 2), "spheres_per_frame": round(len(track["radii"]) /
                                                                                     len(frames), 1)}


def main(argv) -> int:
    args = common.parser(__doc__).parse_args(argv)
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp())
    result: dict[str, object] = {kind: _case(kind) for kind in ("keyed", "bone")}
    result["goal"] = "seconds_per_100_frames <= 1"
    common.emit(result, args)
    return 0


if __name__ == "__main__":
    common.finish(main(sys.argv[1:]))

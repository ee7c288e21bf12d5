"""Cost against field size: ``python headless/bench.py --scale [--json]``; prints ONE JSON object.

For fields of 25.6 m, 100 m, 1 km and 10 km (default layout, default LOD distances), each in a
process of its own so that its peak memory is its own:

* build_s: ``GrassField(params)`` and the first window for the fixed camera (blocks made);
* frame_ms: median engine frame at the fixed camera: seek (wind, solver on the window), LOD,
  blade and card vertices of the blocks the pools would show, into preallocated arrays;
* flythrough_ms: mean engine frame of a camera flying at 1.5 m/s (new blocks join the window and
  are caught up: the mean includes those frames);
* seek_1_s, seek_10000_s, seek_worst_s: from a built field, straight to frame 1, to frame 10,000 and
  to the last frame of an epoch (the longest seek there is);
* frame_set_ms: median ``scene.frame_set`` in Blender with the add-on (when ``bpy`` imports), and
  frame_set_cpu_ms, the process's CPU time in it (all its threads: the work, whatever else the
  machine runs; on a shared machine the steadier of the two); frame_set_epoch_ms: the mean over
  a whole epoch played from its start (in its second half the next trajectory warms up beside the
  shown one: those frames cost more);
* peak_rss_mb: the process's peak resident memory.

Ratios against the 25.6 m field of the same run (and against the 100.8 m field, the smallest that
fills the card range of the fixed camera: a 25.6 m field shows a third of that grass), and the
goals, are printed with them. Wall-clock numbers on a shared machine: compare ratios taken in one run.
"""

from __future__ import annotations

import math
import resource
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))  # (Blender's -P does not put the script's folder on the path)
import common  # noqa: E402

SIZES_M = (25.6, 100.8, 1000.0, 10000.0)
BLOCK_M = 1.6  # default blocks: 16 cells of 0.1 m
FRAMES = 24
FLY_FRAMES = 48
FLY_SPEED = 1.5  # m/s
GOALS = {"frame_ratio_max": 1.3, "build_s_max": 3.0, "peak_rss_mb_max": 3072, "seek_ratio_max": 1.5,
         "flythrough_ratio_max": 2.0}


def _params(size_m: float):
    from windgrass.grass_addon import schema

    blocks = max(1, round(size_m / BLOCK_M))
    return schema.defaults().replace({"field.blocks_x": blocks, "field.blocks_y": blocks})


def _camera(params, t: float = 0.0, speed: float = 0.0):
    from windgrass.grass_addon.lod import Camera

    c = params.camera
    position = np.array(c.position, dtype=np.float64)
    target = np.array(c.target, dtype=np.float64)
    heading = (target - position)[:2] / np.linalg.norm((target - position)[:2])
    shift = np.append(heading * speed * t, 0.0)
    aspect = params.render.resolution_x / params.render.resolution_y
    return Camera.look_at(position + shift, target + shift, math.radians(c.fov), aspect)


def _frame(field, frame: int, camera) -> None:
    """One frame as the add-on computes it (``GrassField.frame``), without writing it to Blender."""
    field.frame(frame, 0.0, camera)


def engine_run(size_m: float) -> dict:
    from windgrass.grass_addon.field import GrassField

    params = _params(size_m)
    camera = _camera(params)
    clock = time.perf_counter
    t0 = clock()
    field = GrassField(params)
    field.view(camera, 1)
    build_s = clock() - t0
    t0 = clock()
    field.seek(1, camera)
    seek_1 = clock() - t0
    times = []
    for frame in range(2, 2 + FRAMES):
        t0 = clock()
        _frame(field, frame, camera)
        times.append(clock() - t0)
    window_blocks = int(field.layout.n_blocks)
    fly = []
    for i in range(FLY_FRAMES):
        frame = 2 + FRAMES + i
        cam = _camera(params, (frame - 1) / params.render.fps, FLY_SPEED)
        t0 = clock()
        _frame(field, frame, cam)
        fly.append(clock() - t0)
    far = GrassField(params)
    far.view(camera, 10_000)
    t0 = clock()
    far.seek(10_000, camera)
    seek_far = clock() - t0
    worst = GrassField(params)  # the last frame of an epoch: one whole trajectory and the warm-up of the next
    last = params.render.frame_start + 70 * worst.sim.epoch - 1
    worst.view(camera, last)
    t0 = clock()
    worst.seek(last, camera)
    seek_worst = clock() - t0
    return {
        "size_m": round(field.grid.size[0], 1), "blocks": field.grid.n_blocks,
        "blades": field.grid.n_blades,
        "build_s": round(build_s, 3), "frame_ms": round(1e3 * statistics.median(times), 2),
        "flythrough_ms": round(1e3 * statistics.mean(fly), 2),
        "flythrough_max_ms": round(1e3 * max(fly), 2),
        "seek_1_s": round(seek_1, 3), "seek_10000_s": round(seek_far, 3), "seek_worst_s": round(seek_worst, 3),
        "window_blocks": window_blocks, "blocks_made": field.cache.made,
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
    }


def blender_run(size_m: float) -> dict:
    """Median ``scene.frame_set`` of the field in Blender, the scene camera at the fixed view."""
    import bench_peers
    import bpy
    from windgrass.grass_addon.simulation import epoch_frames

    params = _params(size_m)
    scene = bench_peers._fresh_scene()
    common.load(addon=True)
    result = bpy.ops.windgrass.field_add(blocks_x=params.field.blocks_x, blocks_y=params.field.blocks_y)
    if "FINISHED" not in result:
        raise RuntimeError(f"windgrass.field_add returned {result}")
    common.scene_camera(scene, params)
    scene.render.resolution_x, scene.render.resolution_y = params.render.resolution_x, params.render.resolution_y
    clock = time.perf_counter
    t0 = clock()
    scene.frame_set(1)
    first = clock() - t0
    times, cpu = [], []
    for frame in range(2, 2 + FRAMES):
        t0, c0 = clock(), time.process_time()
        scene.frame_set(frame)
        times.append(clock() - t0)
        cpu.append(time.process_time() - c0)
    epoch = epoch_frames(params)[0]  # (frames the next trajectory warms up in cost more: a whole epoch's mean)
    played = list(times)
    for frame in range(2 + FRAMES, 2 + epoch):
        t0 = clock()
        scene.frame_set(frame)
        played.append(clock() - t0)
    return {"frame_set_ms": round(1e3 * statistics.median(times), 2), "first_frame_set_s": round(first, 3),
            "frame_set_cpu_ms": round(1e3 * statistics.median(cpu), 2),
            "frame_set_epoch_ms": round(1e3 * statistics.mean(played), 2),
            "peak_rss_mb_blender": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}


def _child(kind: str, size_m: float) -> dict:
    """Run one measurement in a fresh process (its own memory peak): ``bench_scale.py KIND SIZE``."""
    return common.child(__file__, kind, repr(size_m))


def run_scale(blender: bool = True) -> dict:
    try:
        import bpy  # noqa: F401
    except ImportError:
        blender = False
    rows = []
    for size in SIZES_M:
        row = _child("engine", size)
        if blender:
            row.update(_child("blender", size))
        rows.append(row)
    base, full = rows[0], rows[1]  # 25.6 m; 100.8 m: the smallest field that fills the card range
    for row in rows:
        if "error" in row or "error" in base or "error" in full:
            continue
        row["frame_ratio"] = round(row["frame_ms"] / base["frame_ms"], 2)
        row["frame_ratio_to_100m"] = round(row["frame_ms"] / full["frame_ms"], 2)
        row["flythrough_ratio"] = round(row["flythrough_ms"] / row["frame_ms"], 2)
        row["seek_ratio"] = round(row["seek_10000_s"] / row["seek_1_s"], 2)
        row["seek_worst_ratio"] = round(row["seek_worst_s"] / row["seek_1_s"], 2)
        if "frame_set_ms" in row and "frame_set_ms" in base:
            row["frame_set_ratio"] = round(row["frame_set_ms"] / base["frame_set_ms"], 2)
    return {"fields": rows, "goals": GOALS, "frames": FRAMES, "flythrough_frames": FLY_FRAMES,
            "flythrough_speed_m_s": FLY_SPEED}


if __name__ == "__main__":  # one measurement of run_scale: bench_scale.py engine|blender SIZE_M
    parser = common.parser(__doc__, json_flag=False)
    parser.add_argument("kind", choices=("engine", "blender"))
    parser.add_argument("size", type=float, help="the field's side in metres")
    args = parser.parse_args()
    if args.kind == "blender":
        import bench_peers

        bench_peers._prepare_blender_env()
    common.load()
    measure = {"engine": engine_run, "blender": blender_run}[args.kind]
    common.emit(measure(args.size), compact=True, prefix="RESULT ")

"""Benchmark of one frame update of the engine (numpy only); prints ONE JSON object.

    python headless/bench.py [--blades N] [--segments S] [--frames F] [--json] [--peers]
    python headless/bench.py --scale [--json]     (cost against field size: bench_scale.py)
    python headless/bench.py --bake [--json]      (bake size, Alembic against USD: bench_bake.py)
    python headless/bench.py --edits [--json]     (an edit of a setting against a frame change: bench_edits.py)
    python headless/bench.py --handover [--json]  (strips written whole against Geometry Nodes: bench_handover.py)
    python headless/bench.py --realism [--image PNG] [--json]   (a meadow in wind, in numbers: bench_realism.py,
                                                                 and from every camera: bench_cameras.py)
    python headless/bench.py --farm [--blender PATH] [--json]   (farm chunks against one process: bench_farm.py)

Field: blocks of 16 x 16 cells x 2 blades (the paper's layout), as many blocks as give about
N blades, laid out near-square (default 524,288 blades = 32 x 32 blocks). Each timed frame runs
the phases of a frame update separately:

* wind: WindField.sample_layout(t, layout) of every cell (eqs 12-13);
* solver: the frame's solver sub-steps (eqs 14-32), as Simulation does them;
* lod: eqs 7-11 for every cell + block frustum culling, from the scene's fixed camera;
* kinematics: the shared cell data (celldata.cell_data, eq 34) and the blade strip vertices of
  every blade (LOD off: every blade is geometry) into a preallocated array (what the add-on
  hands to foreach_set).

phases_ms holds the median of each phase over the timed frames (after warm-up frames);
drawn_frame_ms the median of the next frames through ``GrassField.frame`` from the fixed camera,
the path the add-on takes (the window of blocks the camera needs, LOD, the blocks each pool
shows and their vertices);
frame_update_ms is their sum. floor_copy_ms is one np.copyto of the whole solver state (every
SolverState array), timed in the same run: the least any frame update that touches the state once
could cost; ratio_to_floor = frame_update_ms / floor_copy_ms. --peers adds the peer comparison of
headless/bench_peers.py (Blender) under "peers". Wall-clock numbers on a shared machine: compare
ratios taken in one run.
"""

from __future__ import annotations

import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # (Blender's -P does not put the script's folder on the path)

import common  # noqa: E402

common.load()  # the engine as windgrass.grass_addon (numpy only, no Blender)
from windgrass.grass_addon import kinematics, schema  # noqa: E402
from windgrass.grass_addon.errors import ParameterError  # noqa: E402
from windgrass.grass_addon.lod import Camera, lod_weights  # noqa: E402

CELLS_PER_BLOCK = 16
BLADES_PER_CELL = 2
WARMUP_FRAMES = 2
# flag -> the script that measures it, run in a process of its own
CHILD_SCRIPTS = {"edits": "bench_edits.py", "handover": "bench_handover.py", "render": "bench_render.py",
                 "bake": "bench_bake.py", "motion": "bench_motion.py", "interaction": "bench_interaction.py",
                 "paint": "bench_paint.py"}


def field_params(blades: int, segments: int) -> schema.Params:
    """Default params with a near-square grid of blocks holding about `blades` blades."""
    if blades < 1:
        raise ParameterError("blades", f"{blades} is out of range (valid: >= 1; flag --blades)")
    cpb = CELLS_PER_BLOCK
    per_block = cpb * cpb * BLADES_PER_CELL
    if blades < per_block:  # tiny benchmark: one smaller block
        cpb = max(1, int(math.sqrt(blades / BLADES_PER_CELL)))
        bx = by = 1
    else:
        n_blocks = max(1, round(blades / per_block))
        bx = max(1, round(math.sqrt(n_blocks)))
        by = max(1, round(n_blocks / bx))
    return schema.defaults().replace({
        "field.blocks_x": bx, "field.blocks_y": by, "field.cells_per_block": cpb,
        "field.blades_per_cell": BLADES_PER_CELL, "blade.segments": segments})


def fixed_camera(params: schema.Params) -> Camera:
    c = params.camera
    aspect = params.render.resolution_x / params.render.resolution_y
    return Camera.look_at(c.position, c.target, math.radians(c.fov), aspect)


def _state_arrays(state) -> list[np.ndarray]:
    """Every numpy array of a SolverState (bend, bend_vel, twist, twist_vel, ...)."""
    fields = vars(state) if hasattr(state, "__dict__") else {k: getattr(state, k) for k in state.__slots__}
    return [v for v in fields.values() if isinstance(v, np.ndarray)]


def machine_info() -> dict:
    info: dict[str, Any] = {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
            "cpu_count": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
            "kinematics_threads": kinematics.THREADS}
    try:
        info["affinity_cpus"] = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        pass
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    info["cpu_model"] = line.split(":", 1)[1].strip()
                    break
        info["load_average"] = [round(x, 2) for x in os.getloadavg()]
    except OSError:
        pass
    return info


def run_bench(blades: int, segments: int, frames: int) -> dict:
    from windgrass.grass_addon.celldata import cell_data
    from windgrass.grass_addon.field import GrassField

    params = field_params(blades, segments)
    t0 = time.perf_counter()
    field = GrassField(params)
    build_ms = (time.perf_counter() - t0) * 1e3
    layout, sim, solver = field.layout, field.sim, field.sim.solver
    camera = fixed_camera(params)
    frame_dt = 1.0 / params.render.fps
    substeps = solver.stable_substeps(frame_dt)
    blocks = field.all_blocks()
    out = np.empty((kinematics.blade_vertex_count(layout, len(blocks)), 3), np.float32)
    state = _state_arrays(solver.state)
    floor_dst = [np.empty_like(a) for a in state]
    field.seek(params.render.frame_start)  # preroll from rest, as the add-on does

    names = ("wind", "solver", "lod", "kinematics", "floor_copy")
    times: dict[str, list[float]] = {k: [] for k in names}
    cpu: dict[str, list[float]] = {k: [] for k in names}
    frame = params.render.frame_start
    clock = time.perf_counter
    for i in range(WARMUP_FRAMES + frames):
        # One frame forward, phase by phase, as Simulation.seek(frame + 1) + the add-on do it.
        frame += 1
        t = sim.time(frame)
        stamps = [(clock(), time.process_time())]
        wind = field.wind.sample_layout(t, layout)  # eqs 12-13, as Simulation samples them
        stamps.append((clock(), time.process_time()))
        solver.step(wind, frame_dt, substeps)  # eqs 14-32
        stamps.append((clock(), time.process_time()))
        weights = lod_weights(layout, camera, params)  # eqs 7-11 + culling
        stamps.append((clock(), time.process_time()))
        cells = cell_data(layout, sim)  # shared cell data, eq 34
        kinematics.blade_vertices(layout, cells, blocks, None, out)  # every blade as geometry
        stamps.append((clock(), time.process_time()))
        for src, dst in zip(state, floor_dst):
            np.copyto(dst, src)
        stamps.append((clock(), time.process_time()))
        if i >= WARMUP_FRAMES:
            for k, key in enumerate(names):
                times[key].append((stamps[k + 1][0] - stamps[k][0]) * 1e3)
                cpu[key].append((stamps[k + 1][1] - stamps[k][1]) * 1e3)
    # The same field's next frames through the path Blender takes (GrassField.frame: the window
    # the camera needs, seek, LOD, the blocks each role shows and their vertices, as drawn).
    drawn = []
    for i in range(WARMUP_FRAMES + frames):
        frame += 1
        t0 = clock()
        field.frame(frame, 0.0, camera)
        if i >= WARMUP_FRAMES:
            drawn.append((clock() - t0) * 1e3)
    med = {k: statistics.median(v) for k, v in times.items()}
    phases = {k: round(med[k], 3) for k in ("wind", "solver", "lod", "kinematics")}
    update = sum(med[k] for k in phases)
    state_bytes = sum(a.nbytes for a in state)
    return {
        "blades": layout.n_blades,
        "segments": layout.segments,
        "cells": layout.n_cells,
        "blocks": [layout.blocks_x, layout.blocks_y],
        "frames": frames,
        "warmup_frames": WARMUP_FRAMES,
        "substeps_per_frame": substeps,
        "phases_ms": phases,
        "frame_update_ms": round(update, 3),
        "floor_copy_ms": round(med["floor_copy"], 3),
        "floor_copy_bytes": state_bytes,
        "ratio_to_floor": round(update / med["floor_copy"], 2) if med["floor_copy"] > 0 else None,
        "vertices_mb": round(out.nbytes / 2**20, 1),
        "drawn_frame_ms": round(statistics.median(drawn), 3),
        "build_ms": round(build_ms, 1),
        "target": {"frame_update_ms": 60, "ratio_to_floor": 25},
        "lod_visible_blocks": int(weights.block_visible.sum()),
        "machine": machine_info(),
        # CPU time of all the process's threads per phase (median): on a busy machine wall-clock
        # phases stretch while these stay put; about wall x 2 where a phase runs on 2 threads.
        "phases_cpu_ms": {k: round(statistics.median(v), 3) for k, v in cpu.items()},
        "detail_ms": {k: [round(x, 3) for x in v] for k, v in times.items()},
    }


def run_peers_json() -> dict:
    """headless/bench_peers.run_peers(), with Blender's C-level stdout sent to stderr."""
    try:
        import bench_peers
    except ImportError as exc:
        return {"error": f"headless/bench_peers.py could not be imported: {exc}"}
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        return bench_peers.run_peers((10_000, 100_000), frames=3, ours=True)
    except Exception as exc:  # the peer run reports, the engine numbers stand
        return {"error": f"{type(exc).__name__}: {exc}"}
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def realism(args) -> int:
    """bench_realism.py's figures and bench_cameras.py's (every camera; with Blender), as one JSON
    object: the cameras' under "cameras"."""
    import json
    import subprocess

    here = Path(__file__).resolve().parent
    parts = []
    for script, extra in (("bench_realism.py", ["--image", args.image] if args.image else []),
                          ("bench_cameras.py", [])):
        done = subprocess.run([sys.executable, str(here / script), "--json", *extra], capture_output=True, text=True)
        if done.returncode != 0:
            print(done.stdout[-2000:] + done.stderr[-4000:], file=sys.stderr)
            return done.returncode
        parts.append(json.loads(done.stdout.strip().splitlines()[-1]))
    result = {**parts[0], "cameras": parts[1]}
    print(json.dumps(result, separators=(",", ":")) if args.json else json.dumps(result, indent=2), flush=True)
    return 0


def main(argv=None) -> int:
    parser = common.parser(__doc__)
    parser.add_argument("--blades", type=int, default=524_288, help="about this many blades (default 524288)")
    parser.add_argument("--segments", type=int, default=5, help="segments per blade (default 5)")
    parser.add_argument("--frames", type=int, default=10, help="timed frames after warm-up (default 10)")
    parser.add_argument("--peers", action="store_true", help="also time the Blender peers (bench_peers.py)")
    parser.add_argument("--scale", action="store_true",
                        help="cost against field size: 25.6 m to 10 km (bench_scale.py); other flags ignored")
    parser.add_argument("--paint", action="store_true",
                        help="a paint stroke's cost at 100 m and 1 km, a half-painted field's frame against a "
                             "plain one (bench_paint.py); other flags ignored")
    parser.add_argument("--interaction", action="store_true",
                        help="what 10 colliders and a vortex add to a 1 km field's frame (bench_interaction.py); "
                             "other flags ignored")
    parser.add_argument("--motion", action="store_true",
                        help="Update Motion of a 1M-vertex collider moved by keys and by a bone, against the "
                             "scene's own frame steps (bench_motion.py); other flags ignored")
    parser.add_argument("--bake", action="store_true",
                        help="the size and time of a bake of the default scene, Alembic against USD "
                             "(bench_bake.py); other flags ignored")
    parser.add_argument("--edits", action="store_true",
                        help="what an edit of a setting costs on the Add-menu field and a 100 m field, against a "
                             "frame change (bench_edits.py; Blender); other flags ignored")
    parser.add_argument("--handover", action="store_true",
                        help="blade strips handed to Blender whole against strips Geometry Nodes build from the "
                             "joints, at 10k and 100k blades (bench_handover.py; Blender); other flags ignored")
    parser.add_argument("--render", action="store_true",
                        help="where a rendered frame of the default scene spends its time, against the same "
                             "frame rendered again (bench_render.py); other flags ignored")
    parser.add_argument("--realism", action="store_true",
                        help="how much the default scene reads as a meadow: clumps, each species' sway peak, the "
                             "gust waves' speed; with --image PNG, a rendered frame's colours (bench_realism.py); "
                             "and from every camera (close-up, eye level, straight down, a drone: bench_cameras.py)")
    parser.add_argument("--image", help="with --realism: a rendered frame of scenes/default.toml")
    parser.add_argument("--farm", action="store_true",
                        help="a farm job in chunks of 4 and 1 under openjd against one process (bench_farm.py; "
                             "--blender PATH: the workers' Blender); other flags ignored")
    parser.add_argument("--blender", default="blender", help="with --farm: the workers' Blender")
    args = parser.parse_args(argv)
    if args.farm:
        import subprocess

        return subprocess.call([sys.executable, str(Path(__file__).with_name("bench_farm.py")), "--blender",
                                args.blender] + (["--json"] if args.json else []))
    if args.realism:
        return realism(args)
    script = next((name for flag, name in CHILD_SCRIPTS.items() if getattr(args, flag)), None)
    if script:  # (each in a process of its own)
        import subprocess

        return subprocess.call([sys.executable, str(Path(__file__).with_name(script))]
                               + (["--json"] if args.json else []))
    if args.scale:
        import bench_scale

        common.emit(bench_scale.run_scale(), args)
        return 0
    try:
        if args.frames < 1:
            raise ParameterError("frames", f"{args.frames} is out of range (valid: >= 1; flag --frames)")
        result = run_bench(args.blades, args.segments, args.frames)
    except ParameterError as exc:
        print(f"bench.py: error: {exc}", file=sys.stderr)
        return 2
    if args.peers:
        result["peers"] = run_peers_json()
    load = result["machine"].get("load_average")
    if load and load[0] > 0.5 * (os.cpu_count() or 1):
        result["note"] = (f"busy machine (load average {load[0]:g} on {os.cpu_count()} CPUs): wall-clock "
                          "phases include waiting for the CPU; phases_cpu_ms shows the work itself")
    common.emit(result, args)
    return 0


if __name__ == "__main__":
    sys.exit(main())

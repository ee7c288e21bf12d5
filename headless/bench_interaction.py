#!/usr/bin/env python3
"""Benchmark of colliders and force fields: what they add to a frame of a 1 km field.

    python3.11 dev.py bench --interaction [--json]   (or headless/bench_interaction.py in the project's .venv)

Prints one JSON object: the engine's frame update (wind, solver, cell data, LOD, the blade and
card vertices of every block that needs them) of a 1 km field seen from near its centre,

* ``plain``: no collider, no force field (the floor);
* ``colliders``: 10 balls (0.3-0.6 m) rolling across the view at 1-3 m/s, with their trails
  (interaction.recovery 4 s), ``ratio`` against the floor (goal: under 1.2);
* ``vortex``: a Vortex force field over the view, ``ratio`` against the floor;
* ``turbulence``: a Turbulence over the whole window (eddies of 1 m), the engine's own noise;
  ``turbulence_blender``: the same with Blender's noise, as the add-on reads it (only where the
  ``bpy`` module is there); either is read once while the field stands still;
* ``far_colliders``: the same 10 balls 400 m away (outside the simulated window): ``ratio``
  (about 1.0: a collider that reaches no simulated cell costs nothing).
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # (Blender's -P does not put the script's folder on the path)

import common  # noqa: E402

common.load()  # the engine as windgrass.grass_addon (numpy only, no Blender)
from windgrass.grass_addon import forces, schema  # noqa: E402
from windgrass.grass_addon.field import GrassField  # noqa: E402
from windgrass.grass_addon.lod import Camera  # noqa: E402


def balls(offset: float = 0.0) -> list[dict]:
    """10 balls crossing the view (x from -15 to 15 m, y from 2 to 20 m ahead of the camera)."""
    rows = []
    for i in range(10):
        r = 0.3 + 0.03 * i
        y = offset + 2.0 + 2.0 * i
        speed = 1.0 + 0.2 * i
        rows.append({"radius": r, "path": [{"time": 0.0, "position": [offset - 15.0, y, r]},
                                           {"time": 30.0 / speed, "position": [offset + 15.0, y, r]}]})
    return rows


def _frame(field, cam, frame: int) -> float:
    t0 = time.perf_counter()
    field.frame(frame, 0.0, cam)  # the frame Blender draws (vertices, trails), without writing it
    return time.perf_counter() - t0


def run(frames: int = 36) -> dict:
    """Every case steps the same frames in turn (a frame of each, then the next frame), so a
    machine that slows down for a while slows every case alike; ratios are medians of per-frame
    ratios against the plain field."""
    base = schema.defaults().replace({"field.blocks_x": 625, "field.blocks_y": 625})
    cam = Camera.look_at((0.0, -1.0, 1.7), (0.0, 20.0, 0.0), math.radians(70.0))
    vortex = [{"type": "vortex", "position": [0.0, 8.0, 0.0], "strength": 6.0, "max_distance": 12.0}]
    turbulence = [{"type": "turbulence", "position": [0.0, 8.0, 0.0], "strength": 3.0, "size": 1.0}]
    cases = {"plain": {}, "colliders": {"interaction.colliders": balls()},
             "vortex": {"interaction.effectors": vortex}, "turbulence": {"interaction.effectors": turbulence},
             "far_colliders": {"interaction.colliders": balls(400.0)}}
    fields = {name: GrassField(base.replace(change)) for name, change in cases.items()}
    blender = _blender_turbulence()
    if blender is not None:
        row = base.replace({"interaction.effectors": turbulence}).interaction.effectors[0]
        still = forces.SampledEffectors([0.0], [[forces.from_row(row)]], turbulence=blender)
        cases["turbulence_blender"] = {}
        fields["turbulence_blender"] = GrassField(base, effectors=still)
    times: dict[str, list[float]] = {name: [] for name in cases}
    for frame in range(1, frames + 4):
        for name, field in fields.items():
            seconds = _frame(field, cam, frame)
            if frame > 3:
                times[name].append(seconds)
    out: dict[str, object] = {"plain": {"frame_ms": round(1000 * statistics.median(times["plain"]), 2)}}
    for name in list(cases)[1:]:
        ratios = [a / b for a, b in zip(times[name], times["plain"])]
        out[name] = {"frame_ms": round(1000 * statistics.median(times[name]), 2),
                     "ratio": round(statistics.median(ratios), 3)}
    out["goal"] = "colliders ratio < 1.2"
    return out


def _blender_turbulence():
    """Blender's noise as the add-on hands it to the engine, or None without the ``bpy`` module."""
    try:
        common.load(addon=True, register=False)
        from windgrass.grass_addon.bridge.tracks import blender_turbulence
    except ImportError:
        return None
    return blender_turbulence


def main(argv) -> int:
    args = common.parser(__doc__).parse_args(argv)
    common.emit(run(), args)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

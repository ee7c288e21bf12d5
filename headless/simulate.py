"""Simulate a grass field without Blender and write a trace (numpy only).

    python headless/simulate.py [--config FILE.toml] [--frames N] [--fps 24] [--trace OUT.npz]
                                [--wind-speed 6 ... any parameter flag, see --help]

Simulates frames render.frame_start .. render.frame_start + N - 1 (N defaults to the scene's frame
range), prints a one-screen summary and, with --trace, writes an .npz whose keys are documented in
README.md. Bad input exits with status 2 and a message naming the parameter.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

HEADLESS = Path(__file__).resolve().parent
sys.path.insert(0, str(HEADLESS))  # (Blender's -P does not put the script's folder on the path)
import common  # noqa: E402

common.load()  # the engine as windgrass.grass_addon (numpy only, no Blender)
from windgrass.grass_addon import kinematics, schema  # noqa: E402
from windgrass.grass_addon.errors import ParameterError  # noqa: E402
from windgrass.grass_addon.field import WHOLE_FIELD_CELLS, GrassField  # noqa: E402
from windgrass.grass_addon.folders import ensure_writable  # noqa: E402
from windgrass.grass_addon.grid import FieldGrid  # noqa: E402

MAX_TRACE_BLADES = 100_000  # blade_tip is stored for fields up to this many blades
SUMMARY_BLADES = 100_000  # tip statistics of larger fields use evenly spread blocks up to this many


def parse_args(argv):
    parser = common.parser(
        "Simulate a Windgrass field (no Blender) and write a trace.", json_flag=False,
        epilog="Every parameter flag overrides the --config file, which overrides the defaults. Numbers are "
               "written as 5, -2.5, +7, 3. or 1e-3 (ASCII digits; no underscores).")
    parser.add_argument("--config", metavar="FILE.toml", help="scene file (TOML); default: built-in defaults")
    parser.add_argument("--frames", metavar="N", type=int, default=None,
                        help="frames to simulate from render.frame_start (default: the scene's frame range)")
    parser.add_argument("--fps", metavar="N", type=int, default=None, help="frames per second (same as --render-fps)")
    parser.add_argument("--trace", metavar="OUT.npz", help="write the trace here (keys: README.md)")
    schema.add_cli_arguments(parser)
    return parser.parse_args(argv)


def load_params(args) -> schema.Params:
    overrides = schema.cli_overrides(args)
    if args.fps is not None:
        overrides["render.fps"] = args.fps
    if not args.config:
        return schema.defaults().replace(overrides)
    schema.check_flags(overrides)
    return schema.load_toml(args.config, flags=overrides)  # (a file's sizes keep their meaning)


def _sample_blocks(layout) -> tuple[np.ndarray, bool]:
    """Blocks whose blades enter the tip statistics: all, or evenly spread ones up to SUMMARY_BLADES."""
    if layout.n_blades <= SUMMARY_BLADES or layout.blades_per_block == 0:
        return np.arange(layout.n_blocks), True
    count = max(1, SUMMARY_BLADES // layout.blades_per_block)
    return np.unique(np.linspace(0, layout.n_blocks - 1, count).round().astype(np.int64)), False


def _tips(layout, v) -> np.ndarray:
    return v.reshape(-1, layout.segments + 1, 2, 3)[:, -1].mean(axis=1)


def run(params: schema.Params, frames: int, trace_path: str | None) -> dict:
    t0 = time.perf_counter()
    field = GrassField.of_scene(params)
    if not field.whole:
        count = field.grid.n_blocks * field.grid.cells_per_block ** 2
        raise ParameterError("field.blocks_x", f"simulate.py traces every cell of the field, which has {count:,}; "
                             f"valid: at most {WHOLE_FIELD_CELLS:,} cells (fewer blocks or cells per block)")
    build_s = time.perf_counter() - t0
    layout, n = field.layout, field.layout.segments
    ny, nx = layout.cells_y, layout.cells_x
    f0 = params.render.frame_start
    store_tips = layout.n_blades <= MAX_TRACE_BLADES
    blocks, all_blades = _sample_blocks(layout)
    tip_buf = np.empty((kinematics.blade_vertex_count(layout, len(blocks)), 3), np.float32)

    # Rest tips: the same kinematics with zero bend and twist.
    rest = SimpleNamespace(bend=np.zeros((layout.n_cells, n, 2), np.float32),
                           twist=np.zeros((layout.n_cells, n), np.float32))
    rest_tip = (_tips(layout, kinematics.blade_vertices(layout, rest, blocks, out=tip_buf)).copy()
                if layout.blades_per_block else np.zeros((0, 3)))

    tr: dict[str, np.ndarray] = {
        "frame": np.arange(f0, f0 + frames, dtype=np.int32),
        "time": np.empty(frames, np.float64),
        "wind_speed": np.empty(frames, np.float32),
        "wind_direction": np.empty(frames, np.float32),
        "cell_wind": np.empty((frames, ny, nx, 2), np.float32),
        "cell_bend": np.empty((frames, ny, nx, n), np.float32),
        "cell_bend_vector": np.empty((frames, ny, nx, n, 2), np.float32),
        "cell_twist": np.empty((frames, ny, nx, n), np.float32),
        "card_offset": np.empty((frames, ny, nx, 3), np.float32),
    }
    if store_tips:
        tr["blade_tip"] = np.empty((frames, layout.n_blades, 3), np.float32)
    tip_disp_mean = np.empty(frames)
    tip_disp_max = np.empty(frames)

    t1 = time.perf_counter()
    field.seek(f0 - 1)  # the preroll, from rest (timed apart from the frames)
    preroll_s = time.perf_counter() - t1
    sim_s = 0.0
    for i in range(frames):
        t1 = time.perf_counter()
        cells = field.seek(f0 + i)
        sim_s += time.perf_counter() - t1
        speed, direction = field.wind.mean(field.sim.time(f0 + i))
        tr["time"][i] = field.sim.time(f0 + i)
        tr["wind_speed"][i], tr["wind_direction"][i] = speed, direction
        tr["cell_wind"][i] = np.asarray(cells.wind).reshape(ny, nx, 2)
        bend = np.asarray(cells.bend).reshape(ny, nx, n, 2)
        tr["cell_bend_vector"][i] = bend
        # signed bend component along the mean wind direction of this frame (rad)
        tr["cell_bend"][i] = bend[..., 0] * math.cos(direction) + bend[..., 1] * math.sin(direction)
        tr["cell_twist"][i] = np.asarray(cells.twist).reshape(ny, nx, n)
        tr["card_offset"][i] = np.asarray(cells.card_offset).reshape(ny, nx, 3)
        if layout.blades_per_block:
            tips = _tips(layout, field.blade_vertices(blocks, out=tip_buf))  # as drawn: colliders cleared
            disp = np.linalg.norm(tips - rest_tip, axis=1)
            tip_disp_mean[i], tip_disp_max[i] = disp.mean(), disp.max()
            if store_tips:
                tr["blade_tip"][i] = tips
        else:
            tip_disp_mean[i] = tip_disp_max[i] = 0.0

    total_bend = np.linalg.norm(tr["cell_bend_vector"].sum(axis=3), axis=-1)  # (F, ny, nx) rad
    summary = {
        "build_s": build_s,
        "preroll_s": preroll_s,
        "seconds_per_frame": sim_s / max(frames, 1),
        "bend_mean_deg": float(np.degrees(total_bend.mean())),
        "bend_max_deg": float(np.degrees(total_bend.max())),
        "tip_mean_m": float(tip_disp_mean.mean()),
        "tip_max_m": float(tip_disp_max.max()),
        "tips_all_blades": all_blades,
        "tips_stored": store_tips,
    }
    if trace_path:
        tr["cell_x"] = layout.cell_center[:nx, 0].copy()
        tr["cell_y"] = layout.cell_center[::nx, 1].copy()
        tr["tip_displacement_mean"] = tip_disp_mean.astype(np.float32)
        tr["tip_displacement_max"] = tip_disp_max.astype(np.float32)
        if store_tips:
            tr["blade_root"] = layout.blade_root
            tr["blade_rest_tip"] = rest_tip.astype(np.float32)
        tr["params_toml"] = np.array(schema.dumps_toml(params))
        write_trace(Path(trace_path), tr)
    return summary


def check_trace_path(path: Path) -> Path:
    """The trace's path, once its folder is known to take a new file (before simulating)."""
    path = path.expanduser()
    if path.is_dir():
        raise ParameterError("trace", f"{path} is a folder; give a file name such as {path / 'trace.npz'}")
    folder = path.resolve().parent
    if not folder.is_dir():
        raise ParameterError("trace", f"folder {folder} of {path} does not exist")
    try:
        ensure_writable(folder, create=False)
    except OSError as exc:
        raise ParameterError("trace", f"cannot write into {folder}: {exc.strerror or exc}") from None
    return path


def write_trace(path: Path, arrays: dict) -> None:
    """Write the .npz beside ``path`` under a temporary name, then rename it into place: a failed
    write (disk full) leaves any earlier trace at ``path`` untouched and no partial file."""
    fd, partial = tempfile.mkstemp(dir=path.resolve().parent, prefix=f".{path.name}.", suffix=".partial")
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(partial, path)
    except BaseException:
        Path(partial).unlink(missing_ok=True)
        raise


def print_summary(params, frames: int, summary: dict, trace_path: str | None, layout_info: dict) -> None:
    w, f = params.wind, params.field
    lines = [
        "Windgrass simulate",
        f"  field      {f.blocks_x} x {f.blocks_y} blocks of {f.cells_per_block} x {f.cells_per_block} cells "
        f"({layout_info['cells']:,} cells of {f.cell_size:g} m, "
        f"{layout_info['size_x']:g} x {layout_info['size_y']:g} m)",
        f"  blades     {layout_info['blades']:,} ({f.blades_per_cell} per cell, {params.blade.segments} segments)",
        f"  wind       {w.type}, {w.speed:g} m/s towards {w.direction:g} deg, turbulence {w.turbulence:g} m/s",
        f"  frames     {frames} from frame {params.render.frame_start} at {params.render.fps} fps "
        f"(preroll {params.simulation.preroll:g} s)",
        f"  time       build {summary['build_s']:.2f} s, preroll {summary['preroll_s']:.2f} s, "
        f"{summary['seconds_per_frame'] * 1000:.1f} ms per frame (simulation)",
        f"  bend       total bend angle mean {summary['bend_mean_deg']:.2f} deg, max {summary['bend_max_deg']:.2f} deg",
        f"  tips       displacement from rest mean {summary['tip_mean_m'] * 100:.2f} cm, "
        f"max {summary['tip_max_m'] * 100:.2f} cm"
        + ("" if summary["tips_all_blades"] else f" (blades of evenly spread blocks, ~{SUMMARY_BLADES:,})"),
    ]
    if not summary["tips_stored"]:
        lines.append(f"  note       blade_tip not stored: the field has more than {MAX_TRACE_BLADES:,} blades")
    lines.append(f"  trace      {trace_path}" if trace_path else "  trace      (none; use --trace OUT.npz)")
    print("\n".join(lines))


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        params = load_params(args)
        frames = args.frames
        if frames is None:
            frames = params.render.frame_end - params.render.frame_start + 1
        if frames < 1 or frames > 1_000_000:
            raise ParameterError("frames", f"{frames} is out of range (valid: 1 to 1000000; flag --frames)")
        if args.trace:
            check_trace_path(Path(args.trace))
        summary = run(params, frames, args.trace)
    except ParameterError as exc:
        print(f"simulate.py: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # the trace could not be written after all (disk full)
        print(f"simulate.py: failed: cannot write the trace {args.trace}: {exc.strerror or exc}; "
              "an earlier file there is unchanged", file=sys.stderr)
        return 1
    grid = FieldGrid.of(params)
    info = {"cells": grid.n_cells, "blades": grid.n_blades, "size_x": grid.size[0], "size_y": grid.size[1]}
    print_summary(params, frames, summary, args.trace, info)
    return 0


if __name__ == "__main__":
    sys.exit(main())

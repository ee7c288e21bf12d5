#!/usr/bin/env python3
"""Benchmark of a farm job against one process: what splitting the frames into tasks costs.

    python3.11 dev.py bench --farm [--json] [--blender PATH] [--work DIR]

12 frames of ``scenes/trample.toml`` at 320x180, 2 samples, rendered by the same Blender
(``--blender``: a binary, default ``blender`` on the PATH) in one process (``blender -b -P
render_field.py``), and as job bundles (``farm.py``) under the real Open Job Description runtime
(``openjd run``, what Deadline Cloud's workers run) in chunks of 4 and of 1. The job's worker
session keeps one Blender (``grass_addon/bridge/farm_session.py``); each task is handed to it by a
small Blender (``--hand-over blender``) or by python3 (``--hand-over python3``). Prints the seconds
of each and the ratios against one process (goals: 1.10 for chunks of 4, 1.3 for chunks of 1),
and whether all give the same pixels. ``--work``: the folder for the job's files (a Blender reached through
chroot needs them inside its root).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import common  # noqa: E402

common.load()
from windgrass.grass_addon import images, schema  # noqa: E402

OPENJD = Path(sys.executable).with_name("openjd")
FRAMES = "1-12"
HAND_OVERS = ("blender", "python3")


def _timed(command: list[str], env: dict) -> float:
    t0 = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, env=env)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command[:3])} ... failed ({done.returncode}):\n{done.stdout[-2000:]}"
                           f"{done.stderr[-2000:]}")
    return time.perf_counter() - t0


def _pixels(folder: Path) -> list:
    return [images.decode_png(p.read_bytes()) for p in sorted(folder.glob("frame_*.png"))]


def run(blender: str, work: Path) -> dict:
    work.mkdir(parents=True, exist_ok=True)
    for name in ("tmp", "home"):
        (work / name).mkdir(exist_ok=True)
    env = dict(os.environ, TMPDIR=str(work / "tmp"), HOME=str(work / "home"), PYTHONUNBUFFERED="1")
    env.pop("BLENDER_USER_RESOURCES", None)
    params = schema.load_toml(HERE.parent / "scenes" / "trample.toml").replace(
        {"render.resolution_x": 320, "render.resolution_y": 180, "render.samples": 2})
    scene = work / "trample-320.toml"
    scene.write_text(schema.dumps_toml(params))
    seconds: dict[str, float] = {}
    runs: list[str] = []
    for hand_over in HAND_OVERS:
        bundle = work / f"bundle-{hand_over}"
        _timed([sys.executable, str(HERE / "farm.py"), "--config", str(scene), "--frames", FRAMES, "--chunk", "4",
                "--hand-over", hand_over, "--out", str(work / "out"), str(bundle)], env)
        if not seconds:
            script = bundle / "windgrass" / "headless" / "render_field.py"
            seconds["one_process_s"] = _timed([blender, "-b", "-P", str(script), "--", "--config", str(scene),
                                               "--frames", FRAMES, "--out", str(work / "one")], env)
        for chunk in (4, 1):
            runs.append(f"{hand_over}_chunks_of_{chunk}")
            seconds[f"{runs[-1]}_s"] = _timed([
                str(OPENJD), "run", str(bundle / "template.yaml"), "--job-param",
                f"file://{bundle / 'job_params.yaml'}", "--job-param", f"BlenderExecutable={blender}",
                "--job-param", f"ChunkSize={chunk}", "--job-param", f"OutputDir={work / runs[-1]}", "--step",
                "Render"], env)
    one = _pixels(work / "one")
    same = all(len(_pixels(work / r)) == len(one) == 12 and all(
        (a == b).all() for a, b in zip(_pixels(work / r), one)) for r in runs)
    out: dict[str, object] = {k: round(v, 1) for k, v in seconds.items()}
    for run in runs:
        out[f"{run}_ratio"] = round(seconds[f"{run}_s"] / seconds["one_process_s"], 3)
    out.update(goals={"chunks_of_4": 1.10, "chunks_of_1": 1.3}, frames=12, resolution="320x180", samples=2,
               same_pixels=bool(same))
    return out


def main(argv=None) -> int:
    parser = common.parser(__doc__, prog="bench_farm.py")
    parser.add_argument("--blender", default="blender", help="the workers' Blender (default: blender on the PATH)")
    parser.add_argument("--work", type=Path, help="the folder for the job's files (default: a temporary one)")
    args = parser.parse_args(argv)
    work = args.work if args.work is not None else Path(tempfile.mkdtemp(prefix="windgrass-bench-farm-"))
    try:
        result = run(args.blender, work)
    except (RuntimeError, OSError) as exc:
        print(f"bench_farm.py: failed: {exc}", file=sys.stderr)
        return 1
    common.emit(result, args)
    return 0


if __name__ == "__main__":
    sys.exit(main())

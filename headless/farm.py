#!/usr/bin/env python3
"""Write a render-farm job bundle for a Windgrass scene file (Open Job Description; Flamenco).

    python headless/farm.py --config scenes/trample.toml --frames 1-96 --chunk 8 --out /farm/renders/trample BUNDLE

BUNDLE gets ``template.yaml`` and ``parameter_values.yaml`` (run it with ``openjd run
BUNDLE/template.yaml --job-param file://BUNDLE/job_params.yaml --step Render``, or submit it
unchanged to AWS Deadline Cloud: ``deadline bundle submit BUNDLE``), the Windgrass scripts and
add-on its tasks run (``windgrass/``), and Flamenco's job type (``flamenco/windgrass.js``). Each
task renders a chunk of frames with ``render_field.py --resume``: frames already complete on disk
are skipped, so a rerun renders only what is missing. The workers' Blender is a job parameter
(``BlenderExecutable``, default ``blender`` on PATH). A saved .blend with live grass: Grass tab >
Farm Job in Blender. Bad input: a sentence and exit status 2.
"""

from __future__ import annotations

import re
import shutil
import sys
from pathlib import Path

HEADLESS = Path(__file__).resolve().parent
sys.path.insert(0, str(HEADLESS))  # (Blender's -P does not put the script's folder on the path)
import common  # noqa: E402

common.load()
from windgrass.grass_addon import farm, schema  # noqa: E402
from windgrass.grass_addon.errors import ParameterError  # noqa: E402
from windgrass.grass_addon.folders import ensure_writable  # noqa: E402

SCRIPTS = ("render_field.py", "stage.py", "addon_loader.py", "common.py")
OWNED = ".written-by-windgrass-farm"  # in the bundle's windgrass/: farm.py may replace that folder


def write(config: Path, frames: str, chunk: int, out: Path, bundle: Path, blender: str = "",
          hand_over: str = "blender") -> Path:
    """The bundle for ``config``'s frames ``frames`` in chunks of ``chunk`` into ``out``; ``blender``:
    the Blender line (X.Y) its frames are made with ('' any); ``hand_over``: what hands the worker
    session's Blender each task (farm.HAND_OVERS)."""
    if not config.is_file():
        raise ParameterError("config", f"{config} is not a scene file")
    params = schema.load_toml(config)
    farm.check_chunk(chunk)
    farm.check_hand_over(hand_over)
    chosen = farm.parse_frames(frames, params.render.frame_start, params.render.frame_end)
    for folder, name in ((out, "out"), (bundle, "bundle")):
        try:
            ensure_writable(folder, create=True)
        except OSError as exc:
            raise ParameterError(name, f"cannot write into {folder}: {exc.strerror or exc}") from None
    runtime = bundle / "windgrass"
    mark = runtime / OWNED
    if runtime.is_symlink() or (runtime.exists() and not mark.is_file()):
        # (it deleted such a folder with whatever a user kept there: a clone lost its .git)
        raise ParameterError("bundle", f"{runtime} exists and was not written by farm.py: move it away or give "
                             "another bundle folder (farm.py replaces only the windgrass/ it wrote)")
    if runtime.exists():
        shutil.rmtree(runtime)
    root = HEADLESS.parent
    for path, name in farm.extension_files(root):
        (runtime / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(path, runtime / name)
    (runtime / "headless").mkdir(parents=True, exist_ok=True)
    for name in SCRIPTS:
        shutil.copy2(HEADLESS / name, runtime / "headless" / name)
    mark.write_text("Written by Windgrass's farm.py, which replaces this folder when it writes the bundle again.\n")
    (bundle / "flamenco").mkdir(exist_ok=True)
    (bundle / "flamenco" / "windgrass.js").write_text(farm.flamenco_job_type())
    scene = carry_scene(params, config, runtime / "scene")
    span = farm.frames_text(chosen)
    template = farm.scene_template(span, chunk, f"Windgrass {config.stem} {span}", blender, hand_over)
    return farm.write_bundle(bundle, template, {
        "Frames": span, "ChunkSize": chunk, "OutputDir": str(out.resolve()),
        "WindgrassDir": str(runtime.resolve()), "SceneFile": str(scene.resolve()), "BlenderVersion": blender})


def carry_scene(params, config: Path, folder: Path) -> Path:
    """The scene file written into ``folder`` with copies of the files it names (paint maps, the
    terrain's heightmap) in ``folder/maps/``, its paths pointing at them: the bundle carries every
    input (Deadline Cloud attaches what lies inside it without asking)."""
    maps = folder / "maps"
    maps.mkdir(parents=True)
    copied: dict[str, str] = {}

    def carry(path: str, setting: str) -> str:
        if path not in copied:
            source = Path(path)
            if not source.is_file():
                raise ParameterError(setting, f"{source} is not a file: the bundle carries the files the scene names")
            name = f"{len(copied)}_{source.name}"
            shutil.copy2(source, maps / name)
            copied[path] = f"maps/{name}"
        return copied[path]

    scene = folder / config.name
    scene.write_text(schema.dumps_toml(schema.with_files(params, carry)))
    return scene


def main(argv=None) -> int:
    parser = common.parser(__doc__, prog="farm.py", json_flag=False)
    parser.add_argument("--config", type=Path, required=True, help="the scene file (TOML)")
    parser.add_argument("--frames", help="A-B within the scene's frames (default: all of them)")
    parser.add_argument("--chunk", type=int, default=4, help="frames a task renders (default 4)")
    parser.add_argument("--out", type=Path, required=True, help="the folder the frames are written to")
    parser.add_argument("--blender-version", metavar="X.Y", default="",
                        help="the Blender line the frames are made with: a worker on another refuses (default: any; "
                             "two lines render a frame a little differently)")
    parser.add_argument("--hand-over", choices=farm.HAND_OVERS, default="blender",
                        help="what hands each task to the worker session's Blender: a small Blender (any worker, "
                             "about a second a task) or python3 (Linux and macOS workers with Python 3.8+: "
                             "milliseconds)")
    parser.add_argument("bundle", type=Path, help="the job bundle's folder (made)")
    args = parser.parse_args(argv)
    try:
        frames = args.frames
        if frames is None:
            params = schema.load_toml(args.config) if args.config.is_file() else None
            frames = f"{params.render.frame_start}-{params.render.frame_end}" if params else "1"
        if args.blender_version and not re.fullmatch(r"\d+\.\d+", args.blender_version):
            raise ParameterError("blender-version", f"{args.blender_version!r} is not a Blender line such as 5.2")
        bundle = write(args.config, frames, args.chunk, args.out, args.bundle, args.blender_version, args.hand_over)
    except ParameterError as exc:
        print(f"farm.py: error: {exc}", file=sys.stderr)
        return 2
    print(f"job bundle: {bundle} (openjd run {bundle / 'template.yaml'} --job-param "
          f"file://{bundle / 'job_params.yaml'} --step Render; or deadline bundle submit {bundle} --yes, "
          f"the frames coming back into {bundle / 'output'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())

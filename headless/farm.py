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
from windgrass.grass_addon import farm, schema, simulation  # noqa: E402
from windgrass.grass_addon.errors import ParameterError  # noqa: E402
from windgrass.grass_addon.folders import ensure_writable, user_folder  # noqa: E402

SCRIPTS = ("render_field.py", "stage.py", "addon_loader.py", "common.py")


def write(config: Path, frames: str, chunk: int, out: Path, bundle: Path, blender: str = "",
          hand_over: str = "blender", allow_outside: bool = False) -> Path:
    """The bundle for ``config``'s frames ``frames`` in chunks of ``chunk`` into ``out``; ``blender``:
    the Blender line (X.Y) its frames are made with ('' any); ``hand_over``: what hands the worker
    session's Blender each task (farm.HAND_OVERS); ``allow_outside``: carry files the scene names
    from outside its folder too. Nothing is written until all of it is checked (``farm.Bundle``)."""
    if not config.is_file():
        raise ParameterError("config", f"{config} is not a scene file")
    params = schema.load_toml(config)
    farm.check_chunk(chunk)
    farm.check_hand_over(hand_over)
    chosen = farm.parse_frames(frames, params.render.frame_start, params.render.frame_end)
    simulation.check_seek(params, chosen)
    out = user_folder(out, "out")
    with farm.Bundle(bundle, "bundle") as job:
        try:
            ensure_writable(out, create=True)
        except OSError as exc:
            raise ParameterError("out", f"cannot write into {out}: {exc.strerror or exc}") from None
        root = HEADLESS.parent
        for path, name in farm.extension_files(root):
            shutil.copy2(path, job.path(f"windgrass/{name}"))
        for name in SCRIPTS:
            shutil.copy2(HEADLESS / name, job.path(f"windgrass/headless/{name}"))
        job.path("flamenco/windgrass.js").write_text(farm.flamenco_job_type())
        scene = carry_scene(params, config, job, "windgrass/scene", allow_outside)
        span = farm.frames_text(chosen)
        template = farm.scene_template(span, chunk, f"Windgrass {config.stem} {span}", blender, hand_over)
        return farm.write_bundle(job, template, {
            "Frames": span, "ChunkSize": chunk, "OutputDir": str(out.resolve()),
            "WindgrassDir": str(job.final("windgrass").resolve()), "SceneFile": str(scene.resolve()),
            "BlenderVersion": blender})


def carry_scene(params, config: Path, job, folder: str, allow_outside: bool = False) -> Path:
    """The scene file written into the bundle's ``folder`` with copies of the files it names (paint
    maps, the terrain's heightmap) in ``folder/maps/``, its paths pointing at them: the bundle
    carries every input (Deadline Cloud attaches what lies inside it without asking). Files from
    outside the scene file's folder (a link to one counts where it points) are refused, each named,
    unless ``allow_outside`` (issue #57: ``~/.aws/credentials`` as a paint map was uploaded)."""
    home = config.resolve().parent
    copied: dict[str, str] = {}
    outside: list[str] = []

    def carry(path: str, setting: str) -> str:
        if path not in copied:
            source = Path(path)
            if not source.is_file():
                raise ParameterError(setting, f"{source} is not a file: the bundle carries the files the scene names")
            name = f"{len(copied)}_{source.name}"
            if not source.resolve().is_relative_to(home):
                outside.append(f"{setting} = {source.resolve()}")
            if allow_outside or not outside:  # (a file refused is never copied, not even while staged)
                shutil.copy2(source, job.path(f"{folder}/maps/{name}"))
            copied[path] = f"maps/{name}"
        return copied[path]

    text = schema.dumps_toml(schema.with_files(params, carry))
    if outside and not allow_outside:
        raise ParameterError(outside[0].split(" = ")[0], f"the scene names files outside its folder {home}, which "
                             f"the bundle would carry to the farm: {'; '.join(outside)} (valid: files inside the "
                             "scene file's folder; --allow-outside carries these too)")
    job.path(f"{folder}/{config.name}").write_text(text)
    return job.final(f"{folder}/{config.name}")


def main(argv=None) -> int:
    parser = common.parser(__doc__, prog="farm.py", json_flag=False)
    parser.add_argument("--config", type=Path, required=True, help="the scene file (TOML)")
    parser.add_argument("--frames", help="A-B within the scene's frames (default: all of them)")
    parser.add_argument("--chunk", type=int, default=4, help="frames a task renders (default 4)")
    parser.add_argument("--out", required=True, help="the folder the frames are written to")
    parser.add_argument("--blender-version", metavar="X.Y", default="",
                        help="the Blender line the frames are made with: a worker on another refuses (default: any; "
                             "two lines render a frame a little differently)")
    parser.add_argument("--hand-over", choices=farm.HAND_OVERS, default="blender",
                        help="what hands each task to the worker session's Blender: a small Blender (any worker, "
                             "about a second a task) or python3 (Linux and macOS workers with Python 3.8+: "
                             "milliseconds)")
    parser.add_argument("--allow-outside", action="store_true",
                        help="carry files the scene names from outside its folder too (default: refused, each named: "
                             "the bundle uploads what it carries)")
    parser.add_argument("bundle", help="the job bundle's folder: a new or empty one, or one farm.py wrote")
    args = parser.parse_args(argv)
    try:
        args.config = args.config.expanduser()
        frames = args.frames
        if frames is None:
            params = schema.load_toml(args.config) if args.config.is_file() else None
            frames = f"{params.render.frame_start}-{params.render.frame_end}" if params else "1"
        if args.blender_version and not re.fullmatch(r"\d+\.\d+", args.blender_version):
            raise ParameterError("blender-version", f"{args.blender_version!r} is not a Blender line such as 5.2")
        bundle = write(args.config, frames, args.chunk, args.out, args.bundle, args.blender_version,
                       args.hand_over, args.allow_outside)
    except ParameterError as exc:
        print(f"farm.py: error: {exc}", file=sys.stderr)
        return 2
    print(f"job bundle: {bundle} (openjd run {bundle / 'template.yaml'} --job-param "
          f"file://{bundle / 'job_params.yaml'} --step Render; or deadline bundle submit {bundle} --yes, "
          f"the frames coming back into {bundle / 'output'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())

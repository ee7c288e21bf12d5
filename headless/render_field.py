#!/usr/bin/env python3
"""Render a grass field swaying in the wind to numbered PNGs (paper VI: a fly-through).

    python headless/render_field.py [options]                 # bpy module (the .venv)
    blender -b -P headless/render_field.py -- [options]       # a Blender 4.5+ install

With no --config the scene is scenes/default.toml. Every schema parameter has a flag
(--wind-speed 6 ...); precedence: schema defaults < --config file < flags. Frames go to
OUT/frame_NNNN.png (each written under a temporary name and renamed when complete).

The state of frame N is a function of (parameters, seed, N) and the camera path is a pure
function of N, so any sub-range (--frames 10-20) renders exactly the images of the full run:
split a long animation across machines freely.

Exit codes: 0 done, 2 bad input (the message names the option), 1 a failure inside Blender (or a
frame or scene.blend that could not be written whole: nothing incomplete is left under its name), 130 stopped by
Ctrl-C after the frame in progress (the finished frames are kept).
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import time
import tomllib
from pathlib import Path

HEADLESS = Path(__file__).resolve().parent
REPO = HEADLESS.parent
DEFAULT_CONFIG = REPO / "scenes" / "default.toml"
DEFAULT_OUT = REPO / "renders"
sys.path.insert(0, str(HEADLESS))  # (Blender's -P does not put the script's folder on the path)

# the manifest's blender_version_min (Blender's own check for the extension; 4.5.0)
OLDEST_BLENDER = tuple(int(v) for v in tomllib.loads((REPO / "blender_manifest.toml").read_text())[
    "blender_version_min"].split("."))


def blender_version_error(version: tuple[int, ...]) -> str | None:
    """The message for a Blender older than Windgrass supports, else None."""
    if tuple(version[:3]) >= OLDEST_BLENDER:
        return None
    oldest = ".".join(str(v) for v in OLDEST_BLENDER[:2])
    return f"Windgrass needs Blender {oldest} or newer (this is {'.'.join(str(v) for v in version[:3])})"


if "bpy" in sys.modules:  # run by a Blender executable: refuse an old one before loading anything
    _too_old = blender_version_error(tuple(sys.modules["bpy"].app.version))
    if _too_old:
        print(f"render_field.py: error: {_too_old}", file=sys.stderr, flush=True)
        os._exit(1)  # `blender -b -P` would ignore sys.exit and go on

import common  # noqa: E402

# The add-on package without registering it (no bpy yet): one copy of the schema, so the
# ParameterError raised inside the add-on is the one caught here.
_PACKAGE = common.load(addon=True, register=False)


def addon_module(name: str):
    """A module of the loaded add-on package: ``addon_module("grass_addon.bridge.materials")``."""
    return importlib.import_module(f"{_PACKAGE.__name__}.{name}")


schema = addon_module("grass_addon.schema")
ParameterError = schema.ParameterError
WindgrassError = addon_module("grass_addon.errors").WindgrassError
ensure_writable = addon_module("grass_addon.folders").ensure_writable
ensure_user_folder = addon_module("grass_addon.folders").user_folder
FieldGrid = addon_module("grass_addon.grid").FieldGrid
farm = addon_module("grass_addon.farm")
farm_frames = addon_module("grass_addon.farm_frames")

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130
FRAME_NAME = "frame_{:04d}.png"
PARTIAL_SUFFIX = ".partial.png"  # temporary name of a frame being written
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_END = b"IEND\xaeB`\x82"  # the last chunk of a complete PNG: type and CRC


class BadInputError(Exception):
    """Bad command-line input; the message names the option."""


# --------------------------------------------------------------------------------------------
# Arguments (no bpy here: bad input is reported at once)


def script_argv(argv: list[str]) -> list[str]:
    """Our arguments: after '--' when run by a Blender binary (``blender -b -P script -- ...``),
    else everything after the script name (``python render_field.py ...``)."""
    if argv and Path(argv[0]).resolve() == Path(__file__).resolve():
        return argv[1:]
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    return []


def build_parser() -> argparse.ArgumentParser:
    parser = common.parser(
        "Render a grass field swaying in the wind (Windgrass) to numbered PNGs. "
        "Precedence: schema defaults < --config < flags.", prog="render_field.py", json_flag=False,
        epilog="Run inside Blender: blender -b -P headless/render_field.py -- [options]. "
               "Numbers are written as 5, -2.5, +7, 3. or 1e-3 (ASCII digits; no underscores). "
               "Exit codes: 0 done, 2 bad input, 1 failure inside Blender, 130 stopped by Ctrl-C "
               "after the frame in progress.")
    job = parser.add_argument_group("render job")
    job.add_argument("--config", metavar="SCENE.toml", type=Path,
                     help=f"scene file (TOML, see scenes/); default {DEFAULT_CONFIG.relative_to(REPO)}")
    job.add_argument("--frames", metavar="A-B",
                     help="frames to render, 'A-B', one frame 'N' or a list of them ('9,10,20-21', as Flamenco "
                          "gives a task), within render.frame_start.."
                          "render.frame_end (default: all of them); any sub-range renders the same "
                          "images as the full run")
    job.add_argument("--out", metavar="DIR",
                     help=f"output folder (created); default {DEFAULT_OUT.relative_to(REPO)}/")
    job.add_argument("--engine", metavar="{cycles,eevee}",
                     help="render engine (render.engine); EEVEE wants a GPU: with software OpenGL "
                          "a field frame takes minutes, Cycles on the CPU seconds")
    job.add_argument("--samples", metavar="N", help="samples per pixel (render.samples)")
    job.add_argument("--resolution", metavar="WxH",
                     help="image size in pixels, e.g. 640x360 (render.resolution_x/_y)")
    job.add_argument("--seed", metavar="N", help="random seed of layout and turbulence (field.seed)")
    job.add_argument("--variants", metavar="K", type=int, default=1,
                     help="render K scenes with seeds seed+i and wind types cycling through "
                          f"{', '.join(schema.WIND_TYPES)}, each in OUT/variant_XX/")
    job.add_argument("--save-blend", action="store_true", help="also save the scene as OUT/scene.blend")
    job.add_argument("--bake", action="store_true",
                     help="bake the grass of the frames into OUT/scene_windgrass/ (Alembic, or USD: "
                          "--bake-format) and save OUT/scene.blend playing it: that file renders the grass in a "
                          "Blender without Windgrass; the frames are then rendered from the bake")
    job.add_argument("--bake-format", choices=("alembic", "usd"), default="alembic",
                     help="what --bake writes: Alembic (.abc, the default) or USD (.usdc: time-sampled points, "
                          "velocities and extents for renderers outside Blender); scene.blend plays either")
    job.add_argument("--resume", action="store_true",
                     help="skip the frames already complete in --out (a farm task run again renders only what "
                          "is missing)")
    job.add_argument("--video", action="store_true",
                     help="also encode the frames as OUT/animation.mp4 (Blender's FFmpeg)")
    job.add_argument("--blender-version", metavar="X.Y", default="",
                     help="the Blender line the job's frames are made with (a farm job's): another refuses, since "
                          "two lines render the same frame a little differently (default: any)")
    schema.add_cli_arguments(parser)
    return parser


# Dedicated options that map onto a schema parameter (they win over its --section-key flag).
_ALIASES = {"engine": "render.engine", "samples": "render.samples", "seed": "field.seed"}


def parse_resolution(text: str) -> tuple[int, int]:
    parts = text.lower().replace("×", "x").split("x")
    try:
        w, h = (int(p) for p in parts)
    except ValueError:
        raise BadInputError(f"--resolution: {text!r} is not WIDTHxHEIGHT in pixels, e.g. 640x360") from None
    for p, value in (("render.resolution_x", w), ("render.resolution_y", h)):
        param = schema.BY_NAME[p]
        if not param.minimum <= value <= param.maximum:
            raise BadInputError(f"--resolution: {value} px is out of range ({p}: valid {param.range_text()})")
    return w, h


def parse_frames(text: str, params) -> tuple[int, ...]:
    """``'A-B'``, ``'N'`` or Flamenco's lists (``'5,6'``, ``'9,10,20,21'``) -> the frames, inside the
    scene's render.frame_start..frame_end."""
    start, end = params.render.frame_start, params.render.frame_end
    try:
        return farm.parse_frames(text, start, end)
    except ParameterError as exc:
        raise BadInputError(f"--frames: {exc.message} (render.frame_start/frame_end: set them with "
                            "--render-frame-start/-end)" if "outside" in exc.message else f"--frames: {exc.message}"
                            ) from None


def resolve(args: argparse.Namespace):
    """Params (defaults < config < flags) and the frame range; BadInputError/ParameterError on bad input."""
    config = args.config if args.config is not None else DEFAULT_CONFIG
    if args.config is not None and not config.is_file():
        raise BadInputError(f"--config: {config} does not exist or is not a file")
    overrides = schema.cli_overrides(args)
    flags = {name: schema.named(name).cli_flag for name in overrides}
    for option, name in _ALIASES.items():
        value = getattr(args, option)
        if value is not None:
            flag = "--" + option
            try:
                overrides[name] = schema.cli_overrides(argparse.Namespace(**{name: value}))[name]
            except ParameterError as exc:
                raise BadInputError(f"{flag}: {exc}") from None
            flags[name] = flag
    if args.resolution is not None:
        overrides["render.resolution_x"], overrides["render.resolution_y"] = parse_resolution(args.resolution)
    try:
        schema.check_flags(overrides)  # (each flag's own range, named by its flag)
        # the flags go into the file's text, so that its sizes and densities keep their meaning
        params = schema.load_toml(config, flags=overrides)
    except ParameterError as exc:
        given = flags.get(exc.key)
        raise BadInputError(f"{given}: {exc}" if given else f"--config: {exc}") from None
    addon_module("grass_addon.interaction").check_scene(params)  # (refused before a scene is built)
    if args.variants < 1:
        raise BadInputError(f"--variants: {args.variants} must be >= 1")
    last_seed = params.field.seed + args.variants - 1
    if last_seed > schema.BY_NAME["field.seed"].maximum:
        raise BadInputError(f"--variants: seeds up to {last_seed} exceed field.seed's range "
                       f"({schema.BY_NAME['field.seed'].range_text()})")
    if params.camera.mode == "fixed" and params.camera.position == params.camera.target:
        raise ParameterError("camera.target", "equals camera.position; the camera needs a point to look at")
    if args.frames is None:
        frames = tuple(range(params.render.frame_start, params.render.frame_end + 1))
    else:
        frames = parse_frames(args.frames, params)
    addon_module("grass_addon.simulation").check_seek(params, frames)
    return params, frames, config


def prepare_out(out) -> Path:
    """The output folder (``~`` expanded, an empty name refused), created and proven writable
    before anything is built or rendered."""
    try:
        out = ensure_user_folder(out, "out").resolve()
    except ParameterError as exc:
        raise BadInputError(f"--out: {exc.message}") from None
    if out.exists() and not out.is_dir():
        raise BadInputError(f"--out: {out} is a file; give a folder (it is created if missing)")
    try:
        ensure_writable(out)
    except OSError as exc:
        raise BadInputError(f"--out: cannot write into {out}: {exc.strerror or exc}") from None
    return out


def check_png(path: Path) -> None:
    """Raise OSError unless ``path`` holds a whole PNG (a full disk leaves empty or cut files)."""
    try:
        size = path.stat().st_size
        with path.open("rb") as fh:
            head = fh.read(len(PNG_SIGNATURE))
            fh.seek(max(0, size - len(PNG_END)))
            tail = fh.read()
    except OSError as exc:
        raise OSError(f"cannot read back {path.name}: {exc.strerror or exc}") from None
    if size == 0:
        raise OSError(f"{path.name} is empty (disk full?)")
    if head != PNG_SIGNATURE or tail != PNG_END:
        raise OSError(f"{path.name} is not a complete PNG ({size} bytes; disk full?)")


def variant_params(params, index: int, keep_speed: bool):
    """Variant ``index``: seed + index, wind type cycling through schema.WIND_TYPES (each with its
    preset speed and turbulence, schema.wind_preset, unless the user set --wind-speed)."""
    wind_type = schema.WIND_TYPES[index % len(schema.WIND_TYPES)]
    changes = {"field.seed": params.field.seed + index, "wind.type": wind_type}
    if keep_speed:
        changes["wind.speed"] = params.wind.speed
    return params.replace(changes)


# --------------------------------------------------------------------------------------------
# Blender


def fresh_scene():
    """An empty factory scene with the add-on loaded from this repository (an installed copy of
    the extension is switched off by the factory settings, so the two never run together)."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    common.load(addon=True)
    return bpy.context.scene


def build_scene(params):
    """Stage (render settings, sun, sky, camera) and the grass field of ``params``."""
    properties = addon_module("grass_addon.bridge.properties")
    import stage
    runtime = addon_module("grass_addon.bridge.runtime")
    scene = fresh_scene()
    stage.setup_stage(scene, params)
    item = properties.add_field(scene, params, name="Grass")
    collection = runtime.build_field(scene, item)
    if collection is not None and item.collection is None:
        item.collection = collection
    return scene


def _fmt_seconds(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    return f"{seconds // 60}:{seconds % 60:02d}"


class FrameWriteError(RuntimeError):
    """A frame could not be written completely (disk full, folder gone)."""


ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"  # a compressed .blend's first bytes
ZSTD_SEEKABLE_FOOTER = b"\xb1\xea\x92\x8f"  # ... and its last: Blender writes the seek table last


def blend_is_whole(path: Path) -> bool:
    """Whether the .blend at ``path`` was written to its end (a full disk leaves it cut short
    and Blender says nothing): a compressed one ends with zstd's seekable-format footer, a plain
    one with its ENDB block."""
    try:
        with open(path, "rb") as f:
            head = f.read(7)
            f.seek(0, os.SEEK_END)
            size = f.tell()
            f.seek(max(0, size - 32))
            tail = f.read()
    except OSError:
        return False
    if head[:4] == ZSTD_MAGIC:
        return tail.endswith(ZSTD_SEEKABLE_FOOTER)
    return head == b"BLENDER" and b"ENDB" in tail


def save_blend(blend: Path, copy: bool) -> None:
    """Save the open scene as ``blend`` (compressed), whole or not at all: a copy goes through a
    hidden partial name and takes ``blend``'s name once whole; the file itself (``copy`` False: a
    bake's cache is found beside it) is removed when cut short. FrameWriteError says which."""
    import bpy

    target = blend.with_name(f".{blend.stem}.partial.blend") if copy else blend
    _clear_the_way(blend, target)
    try:
        bpy.ops.wm.save_as_mainfile(filepath=str(target), copy=copy, compress=True)
        if not blend_is_whole(target):
            raise FrameWriteError(f"{blend} could not be written whole (disk full?): nothing is left under its name")
        if copy:
            os.replace(target, blend)
    except RuntimeError as exc:
        if not isinstance(exc, FrameWriteError):
            exc = FrameWriteError(f"{blend} could not be written: {exc}")
        for path in {target, blend}:
            if path.is_file() or path.is_symlink():
                path.unlink()
        raise exc from None


class FieldError(RuntimeError):
    """A grass field could not be simulated: its frame would be rendered without it."""


class StopAfterFrame:
    """Ctrl-C (SIGINT) while frames render: finish the frame in progress, then stop.

    A second Ctrl-C stops at once (the frame in progress is discarded)."""

    def __init__(self):
        self.requested = False
        self._previous = None

    def __enter__(self):
        try:
            self._previous = signal.signal(signal.SIGINT, self._handle)
        except ValueError:  # not the main thread: Ctrl-C keeps its default
            self._previous = None
        return self

    def __exit__(self, *exc):
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)

    def _handle(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        print("\ninterrupt: stopping after the frame in progress (Ctrl-C again to stop now)", flush=True)


def check_fields(scene) -> None:
    """Raise FieldError when a field of ``scene`` could not be simulated for this frame (its grass
    would be missing from the image)."""
    runtime = addon_module("grass_addon.bridge.runtime")
    for item in scene.windgrass.fields:
        error = runtime.field_error(scene, item)
        if error:
            raise FieldError(f"grass field '{item.name}' cannot be simulated: {error}")


def _whole(path: Path, size: tuple[int, int], fingerprint: str) -> bool:
    """The frame at ``path`` is whole, ``size`` (width, height) pixels and this job's on these
    pixels (``farm_frames.kept``): a frame ``--resume`` may keep (a PNG zeroed in its middle, one of
    another size, an edited submission's and another job's pixels under this job's text are
    rendered again; issues #36, #57). A link, a pipe or a device under its name is a sentence."""
    try:
        return farm_frames.kept(path, fingerprint, size)
    except farm_frames.FrameError as exc:
        raise FrameWriteError(str(exc)) from None


def fingerprints(params):
    """frame -> the fingerprint of that frame of this job (``farm.frame_fingerprint``: the
    settings, the files they name, Blender's and Windgrass's versions)."""
    import bpy

    named: list[str] = []

    def note(path, name):
        named.append(path)
        return path

    schema.with_files(params, note)
    inputs = [Path(p).read_bytes() for p in named if Path(p).is_file()]
    settings, blender = schema.dumps_toml(params), bpy.app.version_string
    windgrass = farm.extension_version(Path(__file__).resolve().parents[1])
    return lambda frame: farm.frame_fingerprint(frame, settings, inputs, blender, windgrass)


def _clear_the_way(final: Path, partial: Path) -> None:
    """Before a frame is written: a leftover partial file (or a link planted under its name, which
    Blender would write through, outside the folder) is removed; a folder under either name is a
    sentence (issue #36: it was a traceback)."""
    for path in (final, partial):
        if path.is_dir() and not path.is_symlink():
            raise FrameWriteError(f"{path} is a folder where frame {final.name} goes: move it away")
    if partial.is_symlink() or partial.exists():
        partial.unlink()


def render_frames(scene, params, frames: tuple[int, ...], out: Path, fingerprint, stop: StopAfterFrame | None = None,
                  resume: bool = False) -> list[Path]:
    """Render ``frames`` to ``out/frame_NNNN.png``; one progress line per frame and Blender's
    ``Saved: '<path>'`` line (what farm managers read). Each frame is written under a temporary name,
    checked to be a whole PNG, then renamed into place; with ``stop`` requested the loop ends after
    the frame in progress; with ``resume`` a frame already whole on disk is kept (and listed).
    Each frame carries its ``fingerprint`` (``fingerprints``) in a PNG text chunk."""
    import bpy
    import stage
    total = len(frames)
    r = scene.render
    size = (r.resolution_x * r.resolution_percentage // 100, r.resolution_y * r.resolution_percentage // 100)
    written: list[Path] = []
    scene.render.use_file_extension = False
    began = time.perf_counter()
    for i, frame in enumerate(frames, start=1):
        if stop is not None and stop.requested:
            break
        if resume and _whole(out / FRAME_NAME.format(frame), size, fingerprint(frame)):
            written.append(out / FRAME_NAME.format(frame))
            print(f"frame {i}/{total} (#{frame}) already rendered: kept", flush=True)
            continue
        t0 = time.perf_counter()
        # The camera first: the frame handler (grass LOD, eqs 7-11) reads it in frame_change_pre.
        stage.pose_camera(scene, params, frame)
        scene.frame_set(frame)
        check_fields(scene)
        t_update = time.perf_counter() - t0
        final = out / FRAME_NAME.format(frame)
        partial = final.with_name("." + final.stem + PARTIAL_SUFFIX)
        _clear_the_way(final, partial)
        scene.render.filepath = str(partial)
        try:
            # (written by save_render, not write_still: Blender's own "Saved:" line named the hidden
            # partial file, and farm managers read every Saved: line as an output; issue #62)
            result = bpy.ops.render.render(write_still=False, scene=scene.name)
            if "FINISHED" in result:
                try:
                    bpy.data.images["Render Result"].save_render(filepath=str(partial), scene=scene)
                except (RuntimeError, KeyError) as exc:
                    raise FrameWriteError(f"frame {frame} could not be written to {out}: {exc}") from None
            if "FINISHED" not in result or not partial.is_file():
                raise FrameWriteError(f"Blender did not write frame {frame} to {out} (disk full or folder removed?)")
            try:
                check_png(partial)
                partial.write_bytes(farm_frames.stamped(partial.read_bytes(), fingerprint(frame)))
            except (OSError, ValueError) as exc:
                raise FrameWriteError(f"frame {frame} could not be written to {out}: {exc}") from None
            os.replace(partial, final)
        finally:
            if partial.exists() or partial.is_symlink():
                partial.unlink()
        print(f"Saved: '{final}'", flush=True)
        written.append(final)
        spent = time.perf_counter() - t0
        eta = (time.perf_counter() - began) / i * (total - i)
        print(f"frame {i}/{total} (#{frame}) {spent:.2f} s (grass {t_update:.2f} s), ETA {_fmt_seconds(eta)} "
              f"-> {final.name}",
              flush=True)
    return written


def encode_video(frames: list[Path], fps: int, target: Path) -> Path | None:
    """Encode the PNGs as an H.264 mp4 with Blender's FFmpeg (an image strip in the sequencer);
    None with a note when this Blender has no FFmpeg."""
    import bpy

    if not getattr(bpy.app.build_options, "codec_ffmpeg", False):
        print("note: this Blender is built without FFmpeg; --video skipped (the PNGs are complete)",
              flush=True)
        return None
    first = bpy.data.images.load(str(frames[0]), check_existing=False)
    width, height = first.size
    bpy.data.images.remove(first)
    scene = bpy.data.scenes.new("Windgrass Video")
    render = scene.render
    render.resolution_x, render.resolution_y = width - width % 2, height - height % 2  # yuv420p
    render.resolution_percentage = 100
    render.fps, render.fps_base = fps, 1.0
    scene.frame_start, scene.frame_end = 1, len(frames)
    scene.view_settings.view_transform = "Standard"  # the PNGs are display-referred already
    editor = scene.sequence_editor_create()
    strips = editor.strips if hasattr(editor, "strips") else editor.sequences  # 5.0 renamed it
    strip = strips.new_image("frames", str(frames[0]), 1, 1)
    for path in frames[1:]:
        strip.elements.append(path.name)
    settings = render.image_settings
    if hasattr(settings, "media_type"):
        settings.media_type = "VIDEO"
    settings.file_format = "FFMPEG"
    render.ffmpeg.format = "MPEG4"
    render.ffmpeg.codec = "H264"
    render.ffmpeg.constant_rate_factor = "HIGH"
    render.ffmpeg.audio_codec = "NONE"
    render.use_file_extension = False
    partial = target.with_name("." + target.stem + ".partial.mp4")
    render.filepath = str(partial)
    try:
        bpy.ops.render.render(animation=True, scene=scene.name)
        if not partial.is_file():
            raise RuntimeError(f"FFmpeg wrote no video at {partial}")
        os.replace(partial, target)
    finally:
        if partial.exists():
            partial.unlink()
        bpy.data.scenes.remove(scene)
    return target


# In a farm worker's session Blender (farm_session.py) the scene built for one task renders the
# next task's frames too: {"key": the scene file's settings, "scene": the scene} of the last build.
_SESSION: dict = {}


def session_task(argv: list[str]) -> int:
    """One farm task in the session's Blender (``grass_addon/bridge/farm_session.py``): ``main``,
    keeping the scene that an earlier task of the session built from the same settings (a frame is
    a function of its number alone: the frames equal those of a Blender of their own)."""
    _SESSION.setdefault("key", None)
    return main([__file__, *argv])


def _scene_for(params):
    """The scene of ``params``: built, or in a session the one built for the same settings."""
    if not _SESSION:
        return build_scene(params)
    key = schema.dumps_toml(params)
    scene = _SESSION.get("scene")
    try:
        if _SESSION["key"] == key and scene is not None and scene.name:
            print("scene kept from the session's earlier task", flush=True)
            return scene
    except ReferenceError:  # (removed since)
        pass
    _SESSION.update(key=None, scene=None)
    scene = build_scene(params)
    _SESSION.update(key=key, scene=scene)
    return scene


def _all_kept(params, frames, out: Path, args, fingerprint) -> bool:
    """With ``--resume`` every frame already whole on disk (and this job's: ``fingerprint``):
    listed as kept, nothing built (a requeued job's finished chunks cost no build)."""
    if not getattr(args, "resume", False) or args.bake or args.save_blend or args.video:
        return False
    size = (params.render.resolution_x, params.render.resolution_y)
    if not all(_whole(out / FRAME_NAME.format(f), size, fingerprint(f)) for f in frames):
        return False
    for i, frame in enumerate(frames, start=1):
        print(f"frame {i}/{len(frames)} (#{frame}) already rendered: kept", flush=True)
    return True


def run_variant(params, frames, out: Path, args, stop: StopAfterFrame | None = None) -> dict:
    """Build one scene, render its frames (and optional .blend and video) into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    fingerprint = fingerprints(params)  # (reads the files the settings name: once a variant)
    if _all_kept(params, frames, out, args, fingerprint):
        return {"out": out, "frames": [out / FRAME_NAME.format(f) for f in frames], "seconds": 0.0, "video": None,
                "interrupted": False}
    t0 = time.perf_counter()
    scene = _scene_for(params)
    f = params.field
    blades = FieldGrid.of(params).n_blades
    print(f"scene ready in {time.perf_counter() - t0:.1f} s: {blades:,} blades, wind {params.wind.type} "
          f"{params.wind.speed:g} m/s, seed {f.seed}, {params.render.engine} {params.render.samples} spp "
          f"{params.render.resolution_x}x{params.render.resolution_y}, camera {params.camera.mode}",
          flush=True)
    if args.bake:
        runtime = addon_module("grass_addon.bridge.runtime")
        blend = out / "scene.blend"
        save_blend(blend, copy=False)  # the cache goes beside it
        t_bake = time.perf_counter()
        # (the bake holds every frame from the first to the last asked: a list's gaps too)
        cache = runtime.bake_field(scene, scene.windgrass.fields[0], frames[0], frames[-1], fmt=args.bake_format)
        save_blend(blend, copy=False)
        blend.with_suffix(".blend1").unlink(missing_ok=True)  # Blender's backup of the first save
        per_frame = addon_module("grass_addon.bridge.bake").cache_size(cache) / (frames[-1] - frames[0] + 1)
        print(f"baked {cache}/ in {time.perf_counter() - t_bake:.1f} s ({per_frame / 1e6:.2f} MB per frame); "
              f"saved {blend}", flush=True)
    elif args.save_blend:
        blend = out / "scene.blend"
        save_blend(blend, copy=True)
        print(f"saved {blend}", flush=True)
    t1 = time.perf_counter()
    written = render_frames(scene, params, frames, out, fingerprint, stop, resume=getattr(args, "resume", False))
    seconds = time.perf_counter() - t1
    interrupted = stop is not None and stop.requested
    video = (encode_video(written, params.render.fps, out / "animation.mp4")
             if args.video and written and not interrupted else None)
    if video is not None:
        print(f"video {video}", flush=True)
    return {"out": out, "frames": written, "seconds": seconds, "video": video, "interrupted": interrupted}


def main(argv: list[str]) -> int:
    parser = build_parser()
    args = parser.parse_args(script_argv(argv))  # argparse exits with 2 on unknown options
    try:
        params, frames, config = resolve(args)
        keep_speed = "wind.speed" in schema.cli_overrides(args)
        # made one at a time as they render: --variants 1000000000 starts at once, in constant memory
        variants = (variant_params(params, i, keep_speed) for i in range(args.variants)) if args.variants > 1 \
            else iter([params])
        out = prepare_out(args.out if args.out is not None else DEFAULT_OUT)
    except (BadInputError, ParameterError) as exc:
        print(f"render_field.py: error: {exc}\n(render_field.py --help lists the options)", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        import bpy  # the module, or the running Blender
    except ImportError:
        print("render_field.py: error: Blender's Python module 'bpy' is not importable here; run this "
              "inside .venv (python3.11 dev.py render) or as blender -b -P headless/render_field.py -- ...",
              file=sys.stderr)
        return EXIT_FAILED
    too_old = blender_version_error(bpy.app.version) or farm.other_blender(args.blender_version, bpy.app.version)
    if too_old:
        print(f"render_field.py: error: {too_old}", file=sys.stderr)
        return EXIT_FAILED
    if args.bake:
        missing = addon_module("grass_addon.bridge.bake").missing_build_feature(args.bake_format)
        if missing:
            print(f"render_field.py: failed: --bake: {missing}", file=sys.stderr)
            return EXIT_FAILED
    print(f"config {config}; frames {farm.frames_text(frames)}; output {out}", flush=True)
    note = addon_module("grass_addon.simulation").seek_note(params)
    if note:
        print(f"note: {note}", flush=True)
    results = []
    try:
        with StopAfterFrame() as stop:
            for index, variant in enumerate(variants):
                target = out / f"variant_{index:02d}" if args.variants > 1 else out
                results.append(run_variant(variant, frames, target, args, stop))
                if stop.requested:
                    break
    except (BadInputError, ParameterError) as exc:
        print(f"render_field.py: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (FrameWriteError, FieldError, WindgrassError) as exc:
        print(f"render_field.py: failed: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        done = sum(len(r["frames"]) for r in results)
        print(f"render_field.py: interrupted: stopped at once; the frame in progress was discarded "
              f"(finished frames of completed variants: {done})", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:  # a failure inside Blender
        import traceback

        traceback.print_exc()
        print(f"render_field.py: failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return EXIT_FAILED
    count = sum(len(r["frames"]) for r in results)
    seconds = sum(r["seconds"] for r in results)
    per = seconds / max(count, 1)
    interrupted = any(r["interrupted"] for r in results)
    print(f"{'interrupted' if interrupted else 'done'}: {count} frame(s) in {seconds:.1f} s "
          f"({per:.2f} s per frame)", flush=True)
    for r in results:
        names = r["frames"]
        if not names:
            continue
        span = f"{names[0].name} .. {names[-1].name}" if len(names) > 1 else names[0].name
        print(f"  {r['out']}/  {span}" + (f"  + {r['video'].name}" if r["video"] else ""), flush=True)
    if interrupted:
        print("render_field.py: interrupted by Ctrl-C: the finished frames above are complete and kept; "
              "render the rest with --frames", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_OK


if __name__ == "__main__":
    inside_blender = Path(sys.argv[0]).resolve() != Path(__file__).resolve()
    try:
        code = main(sys.argv)
    except SystemExit as exc:  # argparse: --help (0), bad options (2)
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else EXIT_BAD_INPUT)
    sys.stdout.flush()
    sys.stderr.flush()
    if inside_blender:
        # `blender -b -P` ignores a script's exit status and would go on: leave with ours.
        os._exit(code)
    sys.exit(code)

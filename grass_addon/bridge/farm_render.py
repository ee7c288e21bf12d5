"""A farm task: render frames A-B (or a list: 9,10,20-21) of the open .blend (copied into job bundles by ``farm.py``).

    blender -b FILE.blend -P farm_render.py -- --frames A-B --out DIR [--version V] [--extension ZIP]
        [--blender-version X.Y]
    blender -b -P farm_render.py -- --blend FILE.blend --frames A-B ...   (opened only when a frame is missing)

Runs in any Blender 4.5+. A live grass field needs the Windgrass extension: the job's environment
installs it (OpenJD), or ``--extension`` installs the zip here (Flamenco); ``--version`` refuses an
extension other than the one the job was made with. Each frame is written under a temporary name
and renamed into place when whole, then Blender's ``Saved: '<path>'`` line is printed; a frame
already complete on disk is skipped (a rerun of a failed job renders only what is missing). Exit
status: 0 done, 1 failed (with the reason on stderr), 2 bad arguments.
"""

import argparse
import hashlib
import importlib.util
import os
import sys
from pathlib import Path

import bpy

FRAME_NAME = "frame_{:04d}.png"
MAX_FRAMES = 100_000  # frames of one task (as grass_addon.farm.MAX_JOB_FRAMES)


def _args(argv):
    parser = argparse.ArgumentParser(prog="farm_render.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", required=True, help="A-B, N or a list of them (9,10,20-21)")
    parser.add_argument("--blend", default="", help="the .blend to render, opened only when a frame is missing "
                        "(default: the open one)")
    parser.add_argument("--out", required=True, help="folder of frame_NNNN.png")
    parser.add_argument("--version", default="", help="the Windgrass version the job was made with")
    parser.add_argument("--extension", default="", help="a Windgrass extension zip to install first")
    parser.add_argument("--blender-version", default="", help="the Blender line (X.Y) the job's frames are made "
                        "with; another refuses (default: any)")
    return parser.parse_args(argv)


def _load_frames_module():
    """``farm_frames`` (standard library only): beside this script in a job bundle, or in the
    package (``grass_addon/farm_frames.py``) where it runs from the extension's own folder."""
    here = Path(__file__).resolve()
    for path in (here.with_name("farm_frames.py"), here.parents[1] / "farm_frames.py"):
        if path.is_file():
            spec = importlib.util.spec_from_file_location("windgrass_farm_frames", path)
            if spec is None or spec.loader is None:
                break
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            return module
    raise ImportError(f"farm_frames.py is missing beside {here.name}: write the job's bundle again")


farm_frames = _load_frames_module()


def fingerprint(blend: Path, version: str):
    """frame -> what makes a frame this job's: a hash of its number, the .blend's bytes, Blender's
    version and the job's Windgrass version (``grass_addon.farm.frame_fingerprint``'s reading, its
    own copy: this script runs where the extension may be missing). A rerun keeps only frames
    that carry it, bound to their pixels (``farm_frames``; issue #36: the frames of an earlier,
    edited submission were kept)."""
    blend_hash = hashlib.sha256(blend.read_bytes()).hexdigest() if blend.is_file() else ""

    def of(frame: int) -> str:
        digest = hashlib.sha256()
        for part in (str(int(frame)), "", bpy.app.version_string, version, blend_hash):
            digest.update(part.encode("utf-8") + b"\0")
        return digest.hexdigest()[:32]

    return of


def kept(path: Path, stamp, size=None) -> bool:
    """The frame is whole and this job's (``farm_frames.kept``); RuntimeError with a sentence when
    its name holds a link, a pipe or a device (reading one would hang the task)."""
    try:
        return farm_frames.kept(path, stamp, size)
    except farm_frames.FrameError as exc:
        raise RuntimeError(str(exc)) from None


def windgrass():
    """The enabled Windgrass add-on module, or None."""
    for name, module in list(sys.modules.items()):
        if (name == "windgrass" or name.endswith(".windgrass")) and getattr(module, "_registered", False):
            return module
    return None


def _version(module) -> str:
    manifest = Path(module.__file__).with_name("blender_manifest.toml")
    for line in manifest.read_text().splitlines():
        if line.strip().startswith("version"):
            return line.split("=", 1)[1].strip().strip('"')
    return ""


def live_fields() -> set:
    """The tags of the .blend's live grass fields, read without the add-on: a field's collection
    carries ``wg_uid``, a baked field's cache files the same tag (Blender 5.0 no longer answers
    ``scene.get("windgrass")`` for the add-on's settings: frames rendered without grass passed)."""
    fields = {c.get("wg_uid") for c in bpy.data.collections if c.get("wg_uid")}
    return fields - {c.get("wg_uid") for c in bpy.data.cache_files}


def prepare(args) -> None:
    """Install the extension when asked, check its version, and make sure every live field can be
    simulated; RuntimeError with a sentence otherwise."""
    here = f"{bpy.app.version[0]}.{bpy.app.version[1]}"
    if args.blender_version and args.blender_version != here:  # (as grass_addon.farm.other_blender says it)
        raise RuntimeError(f"this worker runs Blender {here}, the job's frames are made with Blender "
                           f"{args.blender_version}: give the job that Blender (BlenderExecutable), or set "
                           "BlenderVersion to '' to let any Blender render them")
    live = bool(live_fields())
    module = windgrass()
    if module is None and args.extension:
        blend = bpy.data.filepath
        bpy.ops.extensions.package_install_files(filepath=args.extension, repo="user_default", enable_on_install=True)
        bpy.ops.wm.open_mainfile(filepath=blend)  # (its fields are made again with the add-on on)
        module = windgrass()
    if module is None:
        if live:
            raise RuntimeError("this .blend has live grass fields but Blender has no Windgrass extension enabled "
                               "(install the job's extension zip, or bake the fields)")
        return
    if args.version and _version(module) != args.version:
        raise RuntimeError(f"the Windgrass extension here is {_version(module)}, the job was made with "
                           f"{args.version}: submit the job again from this version")
    fields = sum(len(getattr(getattr(s, "windgrass", None), "fields", ())) for s in bpy.data.scenes)
    print(f"Windgrass extension {_version(module)} ({module.__name__}): {fields} live grass field(s)", flush=True)


def frames(text: str) -> list[int]:
    """The frames of 'A-B', 'N' or a list of them ('9,10,20-21', as Flamenco's chunker gives a
    task), in order, each once, at most MAX_FRAMES of them (counted before any is listed). (This
    script runs where the extension may be missing: it keeps its own copy of
    ``grass_addon.farm.parse_frames``'s reading; the scene's range is checked once it is open.)"""
    spans = []
    for part in text.split(",") if len(text) <= 65536 else ["(too long)"]:
        a, sep, b = part.strip().partition("-") if not part.strip().startswith("-") else ("", "", "")
        if not a.strip().isdigit() or (sep and not b.strip().isdigit()) or len(a.strip()) > 9 or len(b.strip()) > 9:
            raise ValueError(f"--frames {text[:40]}: not 'A-B', a frame number or a list of them (e.g. 1-4 or "
                             "9,10,20-21)")
        first, last = int(a), int(b or a)
        if last < first:
            raise ValueError(f"--frames {text[:40]}: {part.strip()} ends before it starts")
        spans.append((first, last))
    count = sum(last - first + 1 for first, last in spans)
    if count > MAX_FRAMES:
        raise ValueError(f"--frames {text[:40]}: {count:,} frames (valid: at most {MAX_FRAMES:,} in one task)")
    return sorted({f for first, last in spans for f in range(first, last + 1)})


def check_range(chosen: list[int], scene) -> None:
    """The frames lie within the scene's Frame Start..End (ValueError naming them otherwise: frame 0
    or one past the end renders a frame the artist never made)."""
    outside = [f for f in chosen if not scene.frame_start <= f <= scene.frame_end]
    if outside:
        raise ValueError(f"--frames: frame {outside[0]} is outside the scene's frames {scene.frame_start}-"
                         f"{scene.frame_end} (valid: frames within them)")


def render(args, chosen: list[int], stamp) -> int:
    scene = bpy.context.scene
    out = Path(args.out).expanduser()
    out.mkdir(parents=True, exist_ok=True)
    r = scene.render
    size = (r.resolution_x * r.resolution_percentage // 100, r.resolution_y * r.resolution_percentage // 100)
    module = windgrass()
    runtime = None if module is None else sys.modules[f"{module.__name__}.grass_addon.bridge.runtime"]
    scene.render.use_file_extension = False
    scene.render.image_settings.file_format = "PNG"
    for frame in chosen:
        final = out / FRAME_NAME.format(frame)
        if kept(final, stamp(frame), size):
            print(f"Skipped: '{final}' (already rendered)", flush=True)
            continue
        scene.frame_set(frame)
        for item in getattr(getattr(scene, "windgrass", None), "fields", ()) if runtime is not None else ():
            error = runtime.field_error(scene, item) if runtime is not None else None
            if error:
                raise RuntimeError(f"grass field '{item.name}' cannot be simulated: {error}")
        partial = out / ("." + final.stem + ".partial.png")
        for path in (final, partial):
            if path.is_dir() and not path.is_symlink():
                raise RuntimeError(f"{path} is a folder where frame {final.name} goes: move it away")
        if partial.is_symlink() or partial.exists():
            partial.unlink()  # (a leftover, or a link Blender would write through, outside the folder)
        scene.render.filepath = str(partial)
        try:
            bpy.ops.render.render(write_still=False)  # (saved below: Blender's own Saved: line named the partial)
            try:
                bpy.data.images["Render Result"].save_render(filepath=str(partial), scene=scene)
                partial.write_bytes(farm_frames.stamped(partial.read_bytes(), stamp(frame)))
            except (OSError, ValueError, RuntimeError, KeyError) as exc:
                raise RuntimeError(f"Blender did not write frame {frame} whole to {out} ({exc})") from None
            os.replace(partial, final)
        finally:
            if partial.exists() or partial.is_symlink():
                partial.unlink()
        print(f"Saved: '{final}'", flush=True)
    return 0


def opened(args, chosen: list[int], stamp) -> bool:
    """``--blend`` open, unless every frame is already whole and this job's (``stamp``; listed as
    skipped: a requeued job's finished chunks load nothing); False when there is nothing left to
    render."""
    if not args.blend or Path(bpy.data.filepath or ".").resolve() == Path(args.blend).resolve():
        return True
    out = Path(args.out).expanduser()
    if all(kept(out / FRAME_NAME.format(f), stamp(f)) for f in chosen):
        for f in chosen:
            print(f"Skipped: '{out / FRAME_NAME.format(f)}' (already rendered)", flush=True)
        return False
    bpy.ops.wm.open_mainfile(filepath=str(args.blend))
    print(f"farm_render.py: opened {args.blend}", flush=True)
    return True


def main(argv: list[str]) -> int:
    """The task of ``argv`` (after '--' when run by a Blender binary, else after the script)."""
    argv = argv[argv.index("--") + 1:] if "--" in argv else argv[1:]
    try:
        args = _args(argv)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 2
    try:
        # (the .blend's bytes hashed once a task: --blend, or the one Blender opened)
        stamp = fingerprint(Path(args.blend or bpy.data.filepath), args.version)
        chosen = frames(args.frames)  # (read once: the frames checked, kept and rendered)
        if not opened(args, chosen, stamp):
            return 0
        check_range(chosen, bpy.context.scene)
        prepare(args)
        return render(args, chosen, stamp)
    except (RuntimeError, ValueError, OSError) as exc:
        print(f"farm_render.py: failed: {exc}", file=sys.stderr, flush=True)
        return 1


def session_task(argv: list[str]) -> int:
    """One task in a farm worker's session Blender (``farm_session.py``): the .blend opened by the
    session's first task that renders stays open for the next."""
    return main(["farm_render.py", *argv])


if __name__ == "__main__":
    code = main(sys.argv)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)  # (blender -b -P would go on after the script: leave with its status)

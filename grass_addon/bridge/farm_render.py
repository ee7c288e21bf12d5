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
import os
import struct
import sys
import zlib
from pathlib import Path

import bpy

FRAME_NAME = "frame_{:04d}.png"
FRAME_KEY = "WindgrassFrame"  # (as grass_addon.farm.FRAME_KEY: the PNG text chunk naming the frame's job)


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


def whole_png(path: Path) -> bool:
    """The file is a PNG whose chunks are all there, ending with IEND (not cut off by a kill)."""
    try:
        data = path.read_bytes()
    except OSError:
        return False
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        return False
    pos = 8
    while pos + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        end = pos + 12 + length
        if end > len(data) or struct.unpack(">I", data[end - 4:end])[0] != zlib.crc32(data[pos + 4:end - 4]):
            return False
        if kind == b"IEND":
            return True
        pos = end
    return False


def fingerprint(blend: Path, version: str):
    """frame -> what makes a frame this job's: a hash of its number, the .blend's bytes, Blender's
    version and the job's Windgrass version (``grass_addon.farm.frame_fingerprint``'s reading, its
    own copy: this script runs where the extension may be missing). A rerun keeps only frames
    that carry it (issue #36: the frames of an earlier, edited submission were kept)."""
    blend_hash = hashlib.sha256(blend.read_bytes()).hexdigest() if blend.is_file() else ""

    def of(frame: int) -> str:
        digest = hashlib.sha256()
        for part in (str(int(frame)), "", bpy.app.version_string, version, blend_hash):
            digest.update(part.encode("utf-8") + b"\0")
        return digest.hexdigest()[:32]

    return of


def kept(path: Path, stamp: str) -> bool:
    """The frame is whole and carries this job's fingerprint ``stamp``."""
    if not whole_png(path):
        return False
    data = path.read_bytes()
    return (b"tEXt" + FRAME_KEY.encode() + b"\0" + stamp.encode()) in data


def stamped(data: bytes, stamp: str) -> bytes:
    """The PNG with a tEXt chunk FRAME_KEY: ``stamp`` before its IEND (``grass_addon.images.
    with_png_text``'s, its own copy: this script runs where the extension may be missing)."""
    end = data.rindex(b"IEND") - 4
    body = b"tEXt" + FRAME_KEY.encode() + b"\0" + stamp.encode()
    return data[:end] + struct.pack(">I", len(body) - 4) + body + struct.pack(">I", zlib.crc32(body)) + data[end:]


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
    task), in order, each once. (This script runs where the extension may be missing: it keeps
    its own copy of ``grass_addon.farm.parse_frames``'s reading, without the scene's range.)"""
    out: set[int] = set()
    for part in text.split(","):
        a, sep, b = part.strip().partition("-") if not part.strip().startswith("-") else ("", "", "")
        if not a.strip().isdigit() or (sep and not b.strip().isdigit()):
            raise ValueError(f"--frames {text}: not 'A-B', a frame number or a list of them (e.g. 1-4 or 9,10,20-21)")
        first, last = int(a), int(b or a)
        if last < first:
            raise ValueError(f"--frames {text}: {part.strip()} ends before it starts")
        out.update(range(first, last + 1))
    return sorted(out)


def render(args, stamp) -> int:
    scene = bpy.context.scene
    chosen = frames(args.frames)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    module = windgrass()
    runtime = None if module is None else sys.modules[f"{module.__name__}.grass_addon.bridge.runtime"]
    scene.render.use_file_extension = False
    scene.render.image_settings.file_format = "PNG"
    for frame in chosen:
        final = out / FRAME_NAME.format(frame)
        if kept(final, stamp(frame)):
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
            bpy.ops.render.render(write_still=True)
            if not whole_png(partial):
                raise RuntimeError(f"Blender did not write frame {frame} whole to {out}")
            partial.write_bytes(stamped(partial.read_bytes(), stamp(frame)))
            os.replace(partial, final)
        finally:
            if partial.exists() or partial.is_symlink():
                partial.unlink()
        print(f"Saved: '{final}'", flush=True)
    return 0


def opened(args, stamp) -> bool:
    """``--blend`` open, unless every frame is already whole and this job's (``stamp``; listed as
    skipped: a requeued job's finished chunks load nothing); False when there is nothing left to
    render."""
    if not args.blend or Path(bpy.data.filepath or ".").resolve() == Path(args.blend).resolve():
        return True
    out = Path(args.out)
    if all(kept(out / FRAME_NAME.format(f), stamp(f)) for f in frames(args.frames)):
        for f in frames(args.frames):
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
        if not opened(args, stamp):
            return 0
        prepare(args)
        return render(args, stamp)
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

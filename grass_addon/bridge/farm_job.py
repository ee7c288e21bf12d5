"""A render-farm job bundle for the saved .blend (``farm.py`` writes the templates; bpy here).

The bundle carries what a worker whose Blender has never seen Windgrass needs: the extension zip
(made from the running add-on, so its version is this one's), ``farm_render.py`` and the job's
template and parameter values (frames, chunk size and output folder from the scene), and
Flamenco's job type, and a copy of the .blend with the files it uses from its own folder (images,
paint maps, baked caches: at the same places beside it, so its relative paths find them). Deadline
Cloud's client attaches what lies in the bundle without asking (``deadline bundle submit --yes``);
files the .blend uses from elsewhere are named in ``asset_references.yaml`` and said to the artist.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import bpy

from .. import farm
from ..errors import ParameterError
from ..folders import ensure_writable
from .registry import REGISTRY

ADDON_ROOT = Path(__file__).resolve().parents[2]


def output_folder(scene) -> Path:
    """The folder of the scene's render output (Output Properties > Output)."""
    path = bpy.path.abspath(scene.render.filepath or "//")
    return Path(path) if path.endswith(("/", "\\")) else Path(path).parent


def check_saved() -> Path:
    """The saved .blend, or ParameterError when there is none or it has unsaved changes."""
    if not bpy.data.filepath:
        raise ParameterError("file", "the file is not saved: save it first (a farm renders the .blend on disk)")
    try:
        bpy.context.view_layer.update()  # (pending edits reach the handlers, which tell the grass's own apart)
    except (RuntimeError, AttributeError):  # no depsgraph here (mid-render, a restricted context)
        pass
    # REGISTRY.unchanged: no edit of the artist's since the file was loaded or saved (the grass's own
    # mesh writes make Blender call the file modified). Without a window Blender does not keep
    # that flag (5.2: never modified; 4.5: always, even after a save): the add-on's record decides.
    if not REGISTRY.unchanged and (bpy.data.is_dirty or bpy.app.background):
        raise ParameterError("file", "the file has unsaved changes: save it first (a farm renders the .blend on "
                             "disk, not what is open here)")
    return Path(bpy.data.filepath)


def carry_blend(blend: Path, job: farm.Bundle, allow_outside: bool = False) -> tuple[Path, list[str]]:
    """Copy the saved ``blend`` into the bundle's ``scene/`` with the files it uses beneath its own
    folder (the same layout beside the copy); return the copy and the files it uses from elsewhere
    (a link counts where it points). Those are refused, each named, unless ``allow_outside``: the
    bundle would name them for the farm to upload (issue #57)."""
    shutil.copy2(blend, job.path(f"scene/{blend.name}"))
    home, elsewhere = blend.resolve().parent, []
    blenders = Path(bpy.utils.system_resource("DATAFILES")).resolve()  # (its brushes: every Blender has them)
    for name in sorted(set(bpy.utils.blend_paths(absolute=True, packed=False, local=True))):
        path = Path(name).resolve()
        if not path.is_file() or path == blend.resolve() or {job.folder.resolve(), blenders} & set(path.parents):
            continue  # (a missing file or a numbered sequence: Blender's own report names it)
        if home not in path.parents:
            elsewhere.append(str(path))
            continue
        shutil.copy2(path, job.path(f"scene/{path.relative_to(home).as_posix()}"))
    if elsewhere and not allow_outside:
        more = " ..." if len(elsewhere) > 3 else ""
        raise ParameterError("file", f"the file uses {len(elsewhere)} file(s) from outside its folder {home}, which "
                             f"the farm would upload: {', '.join(elsewhere[:3])}{more} (valid: files beside the "
                             ".blend; Allow Outside Files names them for the farm too)")
    return job.final(f"scene/{blend.name}"), elsewhere


def write_blend_bundle(scene, folder: Path, chunk: int, out: Path | None = None, hand_over: str = "blender",
                       allow_outside: bool = False) -> tuple[Path, list[str]]:
    """The job bundle of the saved .blend's scene frames in chunks of ``chunk`` into ``folder``, and
    the files the .blend uses that the bundle does not carry (they lie outside its folder: refused
    unless ``allow_outside``). Only a new or empty folder, or one a bundle writer wrote, is written
    (``farm.Bundle``); nothing is, until all of it is checked."""
    blend = check_saved()
    farm.check_chunk(chunk)
    farm.check_hand_over(hand_over)
    out = output_folder(scene) if out is None else out
    with farm.Bundle(folder, "bundle") as job:
        try:
            ensure_writable(out, create=True)
        except OSError as exc:
            raise ParameterError("output", f"cannot write into {out}: {exc.strerror or exc}") from None
        version = farm.extension_version(ADDON_ROOT)
        farm.zip_extension(ADDON_ROOT, job.path(f"windgrass-{version}.zip"))
        here = Path(__file__)
        for name in ("farm_render.py", "farm_session.py"):
            shutil.copy2(here.with_name(name), job.path(name))
        shutil.copy2(here.parents[1] / "farm_frames.py", job.path("farm_frames.py"))
        copy, elsewhere = carry_blend(blend, job, allow_outside)
        job.path("flamenco/windgrass.js").write_text(farm.flamenco_job_type())
        span = f"{scene.frame_start}-{scene.frame_end}"
        blender = f"{bpy.app.version[0]}.{bpy.app.version[1]}"  # (the line this file's frames are made with)
        template = farm.blend_template(span, chunk, f"Windgrass {blend.stem} {span}", version, blender, hand_over)
        farm.write_bundle(job, template, {
            "Frames": span, "ChunkSize": chunk, "OutputDir": str(out.resolve()), "BlendFile": str(copy),
            "ExtensionZip": str(job.final(f"windgrass-{version}.zip").resolve()),
            "FarmScript": str(job.final("farm_render.py").resolve()),
            "SessionScript": str(job.final("farm_session.py").resolve()),
            "WindgrassVersion": version, "BlenderVersion": blender}, elsewhere, [copy.parent])
    return job.folder, elsewhere

"""What the headless scripts share: the engine loaded as ``windgrass``, their command lines, their JSON.

Every script starts the same way (Blender's ``-P`` does not put the script's folder on the path)::

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common  # noqa: E402

    common.load()  # the engine as windgrass.grass_addon (numpy only); common.load(addon=True) registers it

then builds its flags with ``common.parser(__doc__)`` (argparse; ``--json`` is always there) and
prints its result with ``common.emit(result, args)``: one JSON object, on one line with ``--json``,
indented without.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import addon_loader


def load(addon: bool = False, register: bool = True):
    """The repository as the package ``windgrass``; ``addon``: as the add-on (``register``: also
    registered in Blender)."""
    return addon_loader.load_addon(register=register) if addon else addon_loader.load_package()


def parser(doc: str, prog: str | None = None, json_flag: bool = True, epilog: str | None = None
           ) -> argparse.ArgumentParser:
    """An argument parser described by the first paragraph of ``doc``, with ``--json`` unless
    the script prints no JSON (``json_flag``)."""
    out = argparse.ArgumentParser(prog=prog, description=(doc or "").strip().split("\n\n")[0], epilog=epilog)
    if json_flag:
        out.add_argument("--json", action="store_true", help="one line of JSON (default: indented)")
    return out


def emit(result, args=None, compact: bool | None = None, prefix: str = "") -> None:
    """Print ``result`` as one JSON object on stdout: on one line with ``--json`` (``args.json``) or
    ``compact``, else indented; ``prefix`` marks it among other output (``RESULT ``)."""
    one_line = compact if compact is not None else bool(getattr(args, "json", False))
    text = json.dumps(result, separators=(",", ":")) if one_line else json.dumps(result, indent=2)
    print(prefix + text, flush=True)
    sys.stdout.flush()


def finish(code: int) -> None:
    """Leave with ``code`` at once, output flushed: the scripts that load Blender's ``bpy`` module
    skip its teardown at exit (and ``blender -b -P`` would ignore a plain exit status)."""
    import os

    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def scene_camera(scene, params):
    """A camera object (made here) as the scene's camera, at the settings' ``[camera]`` position,
    looking at its target with its field of view: the benchmarks' fixed view in Blender."""
    import math

    import bpy
    from mathutils import Vector

    data = bpy.data.cameras.new("bench camera")
    cam = bpy.data.objects.new("bench camera", data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    c = params.camera
    cam.location = Vector(c.position)
    cam.rotation_euler = (Vector(c.target) - Vector(c.position)).to_track_quat("-Z", "Y").to_euler()
    data.angle = math.radians(c.fov)
    return cam


def child(script: str, *args: str) -> dict:
    """Run one measurement of ``script`` in a fresh process (its own memory, its own Blender):
    ``python script ARGS``, which prints its result as ``emit(..., prefix="RESULT ")``; the result,
    or {"error": the last line it wrote}."""
    here = Path(script).resolve()
    proc = subprocess.run([sys.executable, str(here), *args], capture_output=True, text=True,
                          cwd=str(here.parent.parent))
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    return {"error": (proc.stderr or proc.stdout).strip().splitlines()[-1:] or [f"exit {proc.returncode}"]}

#!/usr/bin/env python3
"""Measure how well the levels of detail stand for the grass they replace (paper VI: "little
perceivable loss in image quality"): the LOD render against the all-geometry render of the same
frame, in calm air, and the frame-to-frame change of a slow fly-through with and without LOD.

    python headless/lod_compare.py [--config scenes/default.toml] [--resolution 320x180]
                                   [--samples 16] [--engine cycles|eevee]
                                   [--lights sun overcast] [--presets default meadow]
                                   [--views square strip] [--heights 1.1 2.5 6]
                                   [--out renders/lod_compare] [--json]
    python3.11 dev.py lod ...      # the same, inside the project's .venv

Two views: ``square``, the scene's eye over a square field looking across it to its far edge;
``strip``, a narrow camera (20 degrees) at each of --heights looking along a field 16 m wide
and 102 m long, so every band (blades, cards, the far canopy) is seen from low grazing to steep
slopes with an all-geometry reference (each row's pixels on the field are compared: all of
them to about 40 m, only the middle sixth nearer the far edge, ``field_pixels``).

Prints one JSON object: for every view, light and species preset (and height, strip),
``row_diff_max`` (the largest difference of an image row's mean colour, linear RGB 0-1, LOD
against all geometry), ``row_ratio_max`` (the largest relative difference of a grass row's mean
green: a seam shows here) and ``mean_abs_diff`` (of the whole image, its sky too), and for the
fly-through ``flicker_lod`` and ``flicker_geometry`` (mean absolute change between consecutive
frames) and their ratio. The strip's rows at its far edge (102 m away, against the sky or the
world's floor beyond) are left out: the square view holds the far edge. The images (PNG, display
colours) and each case's row means, images and compared pixels (``<case>_rows.npz``: lod,
geometry, lod_image, geometry_image, field; linear RGB) are written to --out for a look. Exit
status 2 on bad input.

The strip's rows were once compared over its middle sixth alone: from 1.1 m at 12 m that is 0.7 m
of field, a few cards, and a cluster of the cards' daisies there moved a row by 0.05-0.08 from one
build to the next; over the whole row (4 m) the same renders differ by 0.032 at most.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

HEADLESS = Path(__file__).resolve().parent
REPO = HEADLESS.parent
sys.path.insert(0, str(HEADLESS))  # (Blender's -P does not put the script's folder on the path)
import common  # noqa: E402

common.load()  # the engine as windgrass.grass_addon
from windgrass.grass_addon import presets, schema  # noqa: E402
from windgrass.grass_addon.errors import ParameterError  # noqa: E402
from windgrass.grass_addon.grid import FieldGrid  # noqa: E402

OVERCAST = (0.55, 0.58, 0.62)  # uniform grey sky (linear RGB)
STRIP_BLOCKS = (10, 64)  # the strip view's field in blocks (16 x 102 m with the default's blocks)
STRIP_FOV = 20.0  # degrees: the strip's middle sixth stays on the field to its far edge


def parse_args(argv):
    parser = common.parser(__doc__, prog="lod_compare.py")
    parser.add_argument("--config", type=Path, default=REPO / "scenes" / "default.toml")
    parser.add_argument("--resolution", default="320x180", help="WIDTHxHEIGHT in pixels")
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--engine", default="cycles", choices=["cycles", "eevee"])
    parser.add_argument("--lights", nargs="+", default=["sun", "overcast"], choices=["sun", "overcast"])
    parser.add_argument("--presets", nargs="+", default=["default", "even", "meadow", "painted"],
                        help=f"species presets: default (the scene's), even (the paper's even field), one of "
                             f"{', '.join(presets.PRESET_NAMES)}, or "
                             "painted (the even field, with a path and a density gradient painted)")
    parser.add_argument("--views", nargs="+", default=["square", "strip"], choices=["square", "strip"])
    parser.add_argument("--heights", nargs="+", type=float, default=[1.1, 2.5, 6.0],
                        help="camera heights (m) of the strip view")
    parser.add_argument("--flythrough-frames", type=int, default=3, help="frames of the slow fly-through (0: none)")
    parser.add_argument("--blocks", type=int, default=24,
                        help="blocks per side of the compared field (all geometry must fit: default 24, 38.4 m)")
    parser.add_argument("--out", type=Path, default=REPO / "renders" / "lod_compare")
    return parser.parse_args(argv)


def scene_params(args, preset: str, fixed: bool, strip_height: float | None = None, check: bool = False):
    params = schema.load_toml(args.config)
    try:
        w, h = (int(v) for v in args.resolution.lower().split("x"))
    except ValueError:
        raise ParameterError("resolution", f"{args.resolution!r} is not WIDTHxHEIGHT, e.g. 320x180") from None
    if args.samples < 1:
        raise ParameterError("samples", f"{args.samples} must be >= 1")
    params = params.replace({"field.blocks_x": args.blocks, "field.blocks_y": args.blocks})
    size_y = FieldGrid.of(params).size[1]
    changes = {"wind.type": "calm", "wind.speed": 0.0, "wind.turbulence": 0.0, "render.engine": args.engine,
               "render.samples": args.samples, "render.resolution_x": w, "render.resolution_y": h,
               "render.motion_blur": False}
    if fixed:
        changes.update({"camera.mode": "fixed", "camera.position": (0.0, -0.4 * size_y, params.camera.height),
                        "camera.target": (0.0, 0.5 * size_y, 0.0)})
    else:
        changes.update({"camera.mode": "flythrough", "camera.speed": 0.5})
    params = params.replace(changes)
    if strip_height is not None:
        if not 0.05 <= strip_height <= 50.0:
            raise ParameterError("heights", f"{strip_height} m is out of range (valid: 0.05-50)")
        params = params.replace({"field.blocks_x": STRIP_BLOCKS[0], "field.blocks_y": STRIP_BLOCKS[1]})
        size_y = FieldGrid.of(params).size[1]
        params = params.replace({"camera.fov": STRIP_FOV, "camera.height": strip_height,
                                 "camera.position": (0.0, -0.5 * size_y + 0.3, strip_height),
                                 "camera.target": (0.0, 0.5 * size_y, 0.0)})
    if preset in ("even", "painted"):
        params = even(params)
    if preset == "painted":
        # the LOD bands brought close, so the path crosses blades, cards and the far canopy in the field
        size = FieldGrid.of(params).size[1]
        # (``check``: settings checked before anything runs, nothing written: a refused run leaves no map)
        path = args.out / PAINTED_MAP if check else painted_map(args.out, params)
        params = params.replace({"paint.density": str(path), "lod.blade_near": 0.1 * size,
                                 "lod.blade_far": 0.2 * size, "lod.card_near": 0.35 * size,
                                 "lod.card_far": 0.9 * size})  # (the far edge stays in the card band)
    elif preset not in ("default", "even"):
        if preset not in presets.PRESET_NAMES:
            valid = ", ".join(("default", "even", "painted", *presets.PRESET_NAMES))
            raise ParameterError("presets", f"unknown preset {preset!r} (valid: {valid})")
        # the preset's species without its look (tussocks, patches, heads: meadow.py), which the cards
        # and the far canopy do not carry yet (issue #34): the levels of detail are compared without it
        params = params.replace({"blade.species": [dict(r, heads=0.0) for r in presets.species_rows(preset)]})
    return params


def even(params):
    """``params`` as the paper's even field: the schema's species, no tussocks, patches, heads or
    dry tips (meadow.py)."""
    return params.replace({"blade.species": schema.defaults().species(), "field.clumping": 0.0,
                           "field.patchiness": 0.0, "blade.dry_tips": 0.0})


PAINTED_MAP = "painted_density.png"


def painted_map(out: Path, params) -> Path:
    """A density map over the compared field: a path 2 m wide from the camera to the far edge
    (x = 2 m, density 0) and a gradient across the field (1 on the west edge, 0.3 on the east)."""
    import numpy as np
    from windgrass.grass_addon import images

    size_x = FieldGrid.of(params).size[0]
    xs = ((np.arange(512) + 0.5) / 512 - 0.5) * size_x
    row = 1.0 - 0.7 * (xs - xs[0]) / (xs[-1] - xs[0])
    row[np.abs(xs - 2.0) < 1.0] = 0.0
    out.mkdir(parents=True, exist_ok=True)
    path = out / PAINTED_MAP
    path.write_bytes(images.encode_png(np.tile(row, (64, 1))))
    return path


def render(params, lod: bool, light: str, frames, out: Path, tag: str):
    """Linear RGB images (H, W, 3) of ``frames`` with the LOD on or off."""
    import bpy
    import numpy as np

    bpy.ops.wm.read_factory_settings(use_empty=True)
    common.load(addon=True)
    import stage
    from windgrass.grass_addon.bridge import properties, runtime

    params = params.replace({"lod.enabled": lod})
    scene = bpy.context.scene
    stage.setup_stage(scene, params, surroundings=False)  # the grass against the grass, as measured before
    if light == "overcast":
        for obj in scene.objects:
            if obj.type == "LIGHT":
                obj.hide_render = True
        background = next(n for n in scene.world.node_tree.nodes if n.bl_idname == "ShaderNodeBackground")
        for link in list(background.inputs["Color"].links):
            scene.world.node_tree.links.remove(link)
        background.inputs["Color"].default_value = (*OVERCAST, 1.0)
        background.inputs["Strength"].default_value = 1.0
    item = properties.add_field(scene, params)
    runtime.build_field(scene, item)
    images = []
    for frame in frames:
        stage.pose_camera(scene, params, frame)
        scene.frame_set(frame)
        scene.render.image_settings.file_format = "OPEN_EXR"
        exr = out / f"{tag}_{'lod' if lod else 'geometry'}_{frame:04d}.exr"
        scene.render.filepath = str(exr)
        bpy.ops.render.render(write_still=True)
        image = bpy.data.images.load(str(exr))
        w, h = image.size
        images.append(np.array(image.pixels[:], dtype=np.float32).reshape(h, w, 4)[::-1, :, :3])
        scene.render.image_settings.file_format = "PNG"
        image.save_render(str(exr.with_suffix(".png")), scene=scene)
        bpy.data.images.remove(image)
        exr.unlink()
    return images


def field_pixels(params, shape, margin: float = 1.0):
    """(H, W) bool: the strip view's pixels whose rays cross the grass layer (from the ground to
    ``margin`` m up) inside the field, ``margin`` m within its sides (blades lean that far at
    most): a row's pixels there show the field and nothing beside it."""
    import math

    import numpy as np
    from windgrass.grass_addon.lod import Camera

    h, w = shape
    size_x, size_y = FieldGrid.of(params).size
    camera = Camera.look_at(params.camera.position, params.camera.target, math.radians(params.camera.fov), w / h)
    f, r, u = camera.basis()
    tx = math.tan(0.5 * camera.fov_x)
    x = ((np.arange(w) + 0.5) / w - 0.5) * 2.0 * tx
    y = (0.5 - (np.arange(h) + 0.5) / h) * 2.0 * tx * h / w
    rays = f[None, None, :] + x[None, :, None] * r[None, None, :] + y[:, None, None] * u[None, None, :]
    eye = np.asarray(params.camera.position, dtype=np.float64)
    inside = np.ones(shape, dtype=bool)
    for z in (0.0, margin):  # where the ray enters the grass layer and where it meets the ground
        down = eye[2] - z
        t = np.where(rays[..., 2] < 0.0, down / np.maximum(-rays[..., 2], 1e-12), np.inf)
        px, py = eye[0] + t * rays[..., 0], eye[1] + t * rays[..., 1]
        inside &= np.isfinite(t) & (np.abs(px) <= 0.5 * size_x - margin) & (np.abs(py) <= 0.5 * size_y)
    return inside


def field_rows(image, mask=None):
    """(H, 3) each row's mean over its pixels in ``mask`` (``field_pixels``), or over the middle
    sixth (``middle_columns``, on the field to its far edge) where the mask holds fewer; over
    the whole row without a mask (the square view)."""
    import numpy as np

    if mask is None:
        return image.mean(axis=1)
    middle = np.zeros(mask.shape[1], dtype=bool)
    middle[middle_columns(image)] = True
    use = np.where(mask.sum(axis=1, keepdims=True) >= middle.sum(), mask, middle[None, :])
    return (image * use[..., None]).sum(axis=1) / use.sum(axis=1)[:, None]


def middle_columns(image) -> slice:
    """The strip view's middle sixth of an image (H, W, ...): on the field from the camera to its
    far edge (STRIP_FOV)."""
    w = image.shape[1]
    return slice(w // 2 - w // 12, w // 2 + w // 12)


def grass_rows(geometry_rows):
    """Rows of grass (green over red and blue, not the sky) in an image's row means (rows, 3),
    leaving out the rows next to the horizon (where sky, the world's floor beyond the field and
    the field's edge share pixels: 3 rows, or 1/40 of the height)."""
    import numpy as np

    green = (geometry_rows[:, 1] > geometry_rows[:, 0]) & (geometry_rows[:, 1] > geometry_rows[:, 2])
    green &= geometry_rows.mean(axis=1) < 0.3
    sky = np.flatnonzero(~green)
    margin = max(3, int(np.ceil(len(green) / 40)))
    top = int(sky[sky < len(green) // 2].max()) + margin if np.any(sky < len(green) // 2) else 0
    green[:top] = False
    return green


def compare_images(lod, geo, edge: bool = True, mask=None) -> dict:
    """The figures of one case (module doc) from linear RGB images (H, W, 3); ``edge``: the rows
    where the field's far edge meets the sky count (the strip view leaves them to the square's);
    ``mask``: the pixels on the field (``field_pixels``, the strip view), else whole rows."""
    import numpy as np

    rows_lod, rows_geo = field_rows(lod, mask), field_rows(geo, mask)
    grass = grass_rows(rows_geo)
    diff = np.abs(rows_lod - rows_geo).max(axis=1)
    if not edge:
        # the strip's camera aims at the foot of the field's far edge, so the rows below the
        # middle are the field before it; the edge's fringe stands above the middle, against the
        # sky or (from higher eyes) the world's floor beyond the field, which grass_rows takes
        # for grass
        below = np.arange(len(grass)) > len(grass) // 2
        grass &= below
        diff = np.where(below, diff, 0.0)
    ratio = np.abs(rows_lod[grass, 1] / np.maximum(rows_geo[grass, 1], 1e-6) - 1.0)
    return {"row_diff_max": round(float(diff.max()), 4),
            "row_ratio_max": round(float(ratio.max()), 3) if ratio.size else None,
            "mean_abs_diff": round(float(np.abs(lod - geo).mean()), 4),
            "worst_row_from_top": int(diff.argmax())}


def compare(args) -> dict:
    import numpy as np

    args.out.mkdir(parents=True, exist_ok=True)
    result = {"engine": args.engine, "resolution": args.resolution, "samples": args.samples, "cases": {}}
    runs = [(view, height) for view in args.views
            for height in ([None] if view == "square" else args.heights)]
    for view, height in runs:
        for preset in args.presets:
            for light in args.lights:
                tag = f"{preset}_{light}" if view == "square" else f"strip{height:g}m_{preset}_{light}"
                t0 = time.perf_counter()
                params = scene_params(args, preset, fixed=True, strip_height=height)
                lod, = render(params, True, light, [1], args.out, tag)
                geo, = render(params, False, light, [1], args.out, tag)
                mask = field_pixels(params, lod.shape[:2]) if view == "strip" else None
                result["cases"][tag] = case = compare_images(lod, geo, edge=view == "square", mask=mask)
                case["seconds"] = round(time.perf_counter() - t0, 1)
                np.savez(args.out / f"{tag}_rows.npz", lod=field_rows(lod, mask), geometry=field_rows(geo, mask),
                         lod_image=lod, geometry_image=geo,
                         field=np.ones(lod.shape[:2], bool) if mask is None else mask)
                print(f"{tag}: {case}", file=sys.stderr, flush=True)
    if args.flythrough_frames > 1:
        params = scene_params(args, args.presets[0], fixed=False)
        frames = list(range(1, args.flythrough_frames + 1))
        flicker = {}
        for lod in (True, False):
            images = render(params, lod, args.lights[0], frames, args.out, "flythrough")
            flicker[lod] = float(np.mean([np.abs(a - b).mean() for a, b in zip(images, images[1:])]))
        result["flythrough"] = {"frames": len(frames), "flicker_lod": round(flicker[True], 4),
                                "flicker_geometry": round(flicker[False], 4),
                                "ratio": round(flicker[True] / max(flicker[False], 1e-9), 3)}
    return result


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        for preset in args.presets:  # bad input before anything renders (or is written)
            scene_params(args, preset, fixed=True, check=True)
        for height in args.heights if "strip" in args.views else ():
            scene_params(args, args.presets[0], fixed=True, strip_height=height, check=True)
        result = compare(args)
    except ParameterError as exc:
        print(f"lod_compare.py: error: {exc}", file=sys.stderr)
        return 2
    common.emit(result, args)
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""The default scene from every camera an artist uses, in the numbers a person would check; prints
ONE JSON object (``dev.py bench --realism`` runs it after bench_realism.py's figures).

    python headless/bench_cameras.py [--resolution 640x360] [--out renders/cameras] [--json]

Frame 12 of ``scenes/default.toml`` (Cycles, its samples) from each of ``CAMERAS`` (issue #59's
shots), rendered by this process as ``render_field.py`` renders it, and the PNGs written to --out:

* ``close-up`` (0.35 m up, looking across the grass): the share of the ground's pixels (below the
  horizon) that are flowers (yellow: buttercups' petals and daisies' discs; white: daisies' rays)
  and how many yellow blobs have white about them on three sides or more (daisies seen with their
  centres);
* ``eye level`` (1.1 m up, the default camera's fly-through pose): bench_realism.py's image figures
  (the near grass's hue spread and share not green; the far band's contrast and hue across its
  rows of 8 x 8-pixel tiles: the meadow's patches at distance);
* ``top-down`` (1.3 m straight down): the share of the frame where the floor shows (the ground
  rendered as a holdout: transparent where a ray meets it) and the flowers' share;
* ``drone`` (20 m up over a 100 m field, looking at its middle): the flowers' share (yellow or
  white pixels, and the share of the field's pixels tinted towards yellow by flowers too small for
  a pixel), and the wind seen from above: the mean change of the field's pixels from frame 12 to
  frame 24 (half a second) and the contrast of its 8 x 8-pixel tiles (the waves' bands).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HEADLESS = Path(__file__).resolve().parent
REPO = HEADLESS.parent
sys.path.insert(0, str(HEADLESS))  # (Blender's -P does not put the script's folder on the path)
import common  # noqa: E402
import render_field  # noqa: E402

# (name, render_field.py options) of each camera; docs_media.py renders the same shots for the README
CAMERAS = (
    ("close-up", ["--camera-position", "0", "0", "0.35", "--camera-target", "2", "1", "0.25"]),
    ("eye level", ["--camera-position", "0", "0", "1.1", "--camera-target", "10", "3", "0.3"]),
    ("top-down", ["--camera-position", "0", "0", "1.3", "--camera-target", "0.01", "0", "0"]),
    ("drone", ["--field-blocks-x", "64", "--field-blocks-y", "64", "--camera-position", "-40", "-40", "20",
               "--camera-target", "0", "0", "0"]),
)
FRAME, LATER = 12, 24
LUMA = np.array([0.2126, 0.7152, 0.0722])


def camera_params(options: list[str], resolution: str):
    """The default scene's settings with a camera's options, as render_field.py reads them."""
    args = render_field.build_parser().parse_args(["--config", str(render_field.DEFAULT_CONFIG), "--camera-mode",
                                                  "fixed", "--resolution", resolution, *options])
    return render_field.resolve(args)[0]


def render(scene, path: Path, sky: bool = False) -> np.ndarray:
    """(H, W, 4) display RGBA 0..1 of the scene's frame, written to ``path`` and read back; the sky
    transparent (alpha 0 where a ray meets nothing, lit as it lights the scene) unless ``sky``."""
    import bpy

    scene.render.filepath = str(path)
    scene.render.film_transparent = not sky
    scene.render.image_settings.color_mode = "RGB" if sky else "RGBA"
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(path))
    w, h = image.size
    pixels = np.array(image.pixels[:], dtype=np.float32).reshape(h, w, 4)[::-1]
    bpy.data.images.remove(image)
    return pixels


def floor_share(scene, path: Path) -> float:
    """The share of the frame where the floor shows: the ground material a holdout (film
    transparent), the frame rendered again; its transparent pixels."""
    owned = render_field.addon_module("grass_addon.bridge.owned")
    item = scene.windgrass.fields[0]
    tree = owned.registered(item)[owned.ROLE_GROUND_MATERIAL].node_tree
    out = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    was = out.inputs["Surface"].links[0].from_socket
    hold = tree.nodes.new("ShaderNodeHoldout")
    tree.links.new(hold.outputs[0], out.inputs["Surface"])
    try:
        alpha = render(scene, path)[..., 3]
    finally:
        tree.links.new(was, out.inputs["Surface"])
        tree.nodes.remove(hold)
    return float((alpha < 0.5).mean())


def yellow(rgb: np.ndarray) -> np.ndarray:
    return (rgb[..., 0] > 0.45) & (rgb[..., 1] > 0.35) & (rgb[..., 2] < 0.5 * rgb[..., 1])


def white(rgb: np.ndarray) -> np.ndarray:
    return (rgb.min(axis=-1) > 0.6) & (rgb.max(axis=-1) - rgb.min(axis=-1) < 0.15)


def components(mask: np.ndarray, least: int = 4) -> list[np.ndarray]:
    """(k, 2) pixel rows and columns of each 8-connected cluster of ``mask`` of ``least`` or more."""
    todo = {(int(y), int(x)) for y, x in np.argwhere(mask)}
    out = []
    while todo:
        stack, found = [todo.pop()], []
        while stack:
            y, x = stack.pop()
            found.append((y, x))
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    if (y + dy, x + dx) in todo:
                        todo.remove((y + dy, x + dx))
                        stack.append((y + dy, x + dx))
        if len(found) >= least:
            out.append(np.array(found))
    return out


def ringed_centres(rgb: np.ndarray) -> int:
    """Yellow blobs with white about them on three sides or more (a daisy's disc in its rays)."""
    rays = white(rgb)
    h, w = rays.shape
    found = 0
    for blob in components(yellow(rgb)):
        (cy, cx), r = blob.mean(axis=0), max(1.0, float(np.ptp(blob, axis=0).max()))
        sides = 0
        for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            ys = np.clip(np.round(cy + dy * np.linspace(0.6, 2.0, 8) * r).astype(int), 0, h - 1)
            xs = np.clip(np.round(cx + dx * np.linspace(0.6, 2.0, 8) * r).astype(int), 0, w - 1)
            sides += bool(rays[ys, xs].any())
        found += sides >= 3
    return found


def flower_figures(rgba: np.ndarray) -> dict:
    """The flowers' shares of the meadow's pixels (those not showing the sky: ``render`` keeps the
    sky transparent; near the horizon it is as pale as a daisy's rays)."""
    meadow = rgba[..., 3] > 0.5
    rgb = rgba[..., :3]
    return {"yellow_share": round(float(yellow(rgb)[meadow].mean()), 4),
            "white_share": round(float(white(rgb)[meadow].mean()), 4)}


def drone_figures(first: np.ndarray, later: np.ndarray) -> dict:
    """The flowers and the waves from the drone: the field's pixels (the lower half: it fills them)."""
    h = first.shape[0]
    field, after = first[h // 2:, :, :3], later[h // 2:, :, :3]
    hue = _hue(field.reshape(-1, 3))
    grass = np.median(hue[(hue > 40) & (hue < 170)])
    lum = field @ LUMA
    tiles = lum[: lum.shape[0] // 8 * 8, : lum.shape[1] // 8 * 8]
    tiles = tiles.reshape(tiles.shape[0] // 8, 8, tiles.shape[1] // 8, 8).mean(axis=(1, 3))
    yellower = (hue > 0) & (hue < grass - 12.0)
    return {**flower_figures(first[h // 2:]), "yellower_share": round(float(yellower.mean()), 4),
            "change_12_to_24": round(float(np.abs(after - field).mean()), 4),
            "tile_contrast": round(float(tiles.std() / tiles.mean()), 4)}


def _hue(rgb: np.ndarray) -> np.ndarray:
    import bench_realism

    return bench_realism._hue(rgb)


def run(resolution: str, out: Path) -> dict:
    import bench_realism

    out.mkdir(parents=True, exist_ok=True)
    result: dict = {"frame": FRAME, "resolution": resolution}
    for name, options in CAMERAS:
        t0 = time.perf_counter()
        params = camera_params(options, resolution)
        scene = render_field.build_scene(params)
        scene.frame_set(FRAME)
        path = out / f"{name.replace(' ', '_')}_{FRAME:04d}.png"
        rgba = render(scene, path)
        figures: dict = {}
        if name == "close-up":
            figures = {**flower_figures(rgba), "daisies_with_centres": ringed_centres(rgba[..., :3])}
        elif name == "eye level":
            render(scene, path, sky=True)  # (the far band is measured against its sky)
            figures = bench_realism.image_figures(path)
        elif name == "top-down":
            figures = {"floor_share": round(floor_share(scene, Path(tempfile.mkdtemp()) / "floor.png"), 4),
                       **flower_figures(rgba)}
        elif name == "drone":
            scene.frame_set(LATER)
            figures = drone_figures(rgba, render(scene, out / f"drone_{LATER:04d}.png"))
        figures["seconds"] = round(time.perf_counter() - t0, 1)
        result[name] = figures
    return result


def main(argv=None) -> int:
    parser = common.parser(__doc__)
    parser.add_argument("--resolution", default="640x360", help="WIDTHxHEIGHT (default 640x360)")
    parser.add_argument("--out", type=Path, default=REPO / "renders" / "cameras", help="where the frames go")
    args = parser.parse_args(argv)
    try:
        render_field.parse_resolution(args.resolution)
    except Exception as exc:  # (argparse's own message names the option)
        print(f"bench_cameras.py: error: --resolution: {exc}", file=sys.stderr)
        return 2
    common.emit(run(args.resolution, args.out), args)
    return 0


if __name__ == "__main__":
    common.finish(main())

#!/usr/bin/env python3
"""The README's pictures: a still and a short animation of the default scene, the default scene from
every camera an artist uses, and the LOD comparison.

    python headless/docs_media.py [--frames 1-30] [--resolution 960x540] [--out docs]
    python3.11 dev.py docs ...    # the same inside the project's .venv (installs Pillow there)

Renders ``scenes/default.toml`` with ``render_field.py`` into ``renders/docs/``, then writes
``<out>/default_scene.png`` (the middle frame) and ``<out>/default_scene.webp`` (every frame, an
animated WebP of a few hundred kB), and ``<out>/cameras.png``: frame 12 from eye level (the still),
a close-up, straight down from 1.3 m and a drone 20 m up over a 100 m field (``CAMERAS``), two by
two. When ``renders/lod_compare/`` holds the images of ``dev.py lod``,
``<out>/lod_compare.png`` puts the LOD render beside the all-geometry render (sun and overcast).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # (Blender's -P does not put the script's folder on the path)
import bench_cameras  # noqa: E402
import common  # noqa: E402

HEADLESS = Path(__file__).resolve().parent
ANIMATION_WIDTH = 640
REPO = HEADLESS.parent


# (name, render_field.py options) of the cameras beside the eye-level still (issue #59's shots, as
# bench_cameras.py measures them)
CAMERAS = tuple(c for c in bench_cameras.CAMERAS if c[0] != "eye level")


def render_cameras(resolution: str) -> list[Path] | None:
    """Frame 12 of the default scene from each of ``CAMERAS`` (None: a render failed)."""
    out = []
    for name, options in CAMERAS:
        folder = REPO / "renders" / "docs_cameras" / name
        status = subprocess.call([sys.executable, str(HEADLESS / "render_field.py"), "--frames", "12",
                                  "--resolution", resolution, "--camera-mode", "fixed", *options,
                                  "--out", str(folder)], cwd=REPO)
        if status:
            return None
        out.append(folder / "frame_0012.png")
    return out


def parse_args(argv):
    parser = common.parser(__doc__, prog="docs_media.py", json_flag=False)
    parser.add_argument("--frames", default="1-30", help="frame range of the animation (default 1-30)")
    parser.add_argument("--resolution", default="960x540", help="WIDTHxHEIGHT (default 960x540)")
    parser.add_argument("--out", type=Path, default=REPO / "docs", help="folder of the README's pictures")
    parser.add_argument("--skip-render", action="store_true", help="use the frames already in renders/docs")
    return parser.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        from PIL import Image
    except ImportError:
        print("docs_media.py: error: needs Pillow (python3.11 dev.py docs installs it)", file=sys.stderr)
        return 2
    frames_dir = REPO / "renders" / "docs"
    if not args.skip_render:
        status = subprocess.call([sys.executable, str(HEADLESS / "render_field.py"), "--frames", args.frames,
                                  "--resolution", args.resolution, "--out", str(frames_dir)], cwd=REPO)
        if status:
            return status
    frames = sorted(frames_dir.glob("frame_*.png"))
    if not frames:
        print(f"docs_media.py: error: no frames in {frames_dir}", file=sys.stderr)
        return 1
    args.out.mkdir(parents=True, exist_ok=True)
    images = [Image.open(p).convert("RGB") for p in frames]
    images[len(images) // 2].save(args.out / "default_scene.png", optimize=True)
    # the animation at most ANIMATION_WIDTH wide (the still keeps the full size): a README loads it
    if images[0].width > ANIMATION_WIDTH:
        size = (ANIMATION_WIDTH, round(images[0].height * ANIMATION_WIDTH / images[0].width))
        images = [im.resize(size, Image.Resampling.LANCZOS) for im in images]
    images[0].save(args.out / "default_scene.webp", save_all=True, append_images=images[1:], duration=1000 // 24,
                   loop=0, quality=70, method=6)
    print(f"wrote {args.out / 'default_scene.png'} and {args.out / 'default_scene.webp'} ({len(images)} frames)")
    width, height = images[0].size
    shots = None if args.skip_render else render_cameras(f"{width}x{height}")
    if shots is not None:
        sheet = Image.new("RGB", (2 * width, 2 * height))
        eye = Image.open(frames[len(frames) // 2]).convert("RGB").resize((width, height), Image.Resampling.LANCZOS)
        for k, image in enumerate([eye] + [Image.open(p).convert("RGB") for p in shots]):
            sheet.paste(image.resize((width, height), Image.Resampling.LANCZOS), ((k % 2) * width, (k // 2) * height))
        sheet.save(args.out / "cameras.png", optimize=True)
        print(f"wrote {args.out / 'cameras.png'} (eye level, close-up; straight down from 1.3 m, drone)")
    lod = REPO / "renders" / "lod_compare"
    pairs = [(lod / f"default_{light}_lod_0001.png", lod / f"default_{light}_geometry_0001.png")
             for light in ("sun", "overcast")]
    if all(p.exists() for pair in pairs for p in pair):
        rows = [[Image.open(p).convert("RGB") for p in pair] for pair in pairs]
        w, h = rows[0][0].size
        sheet = Image.new("RGB", (2 * w, 2 * h))
        for y, row in enumerate(rows):
            for x, image in enumerate(row):
                sheet.paste(image, (x * w, y * h))
        sheet.save(args.out / "lod_compare.png", optimize=True)
        print(f"wrote {args.out / 'lod_compare.png'} (left: levels of detail, right: every blade as geometry)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Batch renders: headless/render_field.py as a subprocess, and the stage's camera path.

Renders are tiny (64x36 px, 2 samples, a 3.2 m field) so the whole file stays within a few
minutes on two cores. PNGs are decoded with a small zlib-based reader below and compared
pixel for pixel.
"""

from __future__ import annotations

import json
import math
import os
import signal
import struct
import subprocess
import sys
import textwrap
import zlib
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "headless" / "render_field.py"

# A small field the camera flies over at knee height: every frame shows grass below the horizon.
TINY_SCENE = """
[field]
blocks_x = 4
blocks_y = 4
cells_per_block = 8
cell_size = 0.1
blades_per_cell = 4
seed = 3

[wind]
type = "gentle_breeze"
speed = 5.0

[lod]
blade_near = 1.5
blade_far = 2.5
card_near = 3.0
card_far = 4.0

[camera]
mode = "flythrough"
height = 0.5
speed = 1.5

[render]
samples = 2
resolution_x = 64
resolution_y = 36
frame_start = 1
frame_end = 6

[simulation]
preroll = 0.5
"""


# --------------------------------------------------------------------------------------------
# Helpers


def read_png(path: Path) -> tuple[int, int, int, list[bytes]]:
    """Decode an 8-bit RGB/RGBA PNG: (width, height, channels, rows of raw bytes)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            break
    width, height, depth, colour, _, _, interlace = header
    assert depth == 8 and colour in (2, 6) and interlace == 0, f"unsupported PNG {header}"
    channels = 3 if colour == 2 else 4
    raw = zlib.decompress(idat)
    stride = width * channels
    rows, prev = [], bytearray(stride)
    for y in range(height):
        kind = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b = prev[i]
            c = prev[i - channels] if i >= channels else 0
            if kind == 1:
                line[i] = (line[i] + a) & 255
            elif kind == 2:
                line[i] = (line[i] + b) & 255
            elif kind == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line))
        prev = line
    return width, height, channels, rows


def pixels(path: Path) -> list[tuple[int, int, int]]:
    """Row-major RGB pixels, top row first."""
    width, height, channels, rows = read_png(path)
    return [tuple(row[x * channels:x * channels + 3]) for row in rows for x in range(width)]


def lower_green_share(path: Path) -> float:
    """Share of the pixels of the lower third that are green-dominant (G above R and B)."""
    width, height, _, _ = read_png(path)
    px = pixels(path)[(2 * height // 3) * width:]
    return sum(1 for r, g, b in px if g > r and g > b) / len(px)


def mean_abs_difference(a: Path, b: Path) -> float:
    pa, pb = pixels(a), pixels(b)
    return sum(abs(x - y) for p, q in zip(pa, pb) for x, y in zip(p, q)) / (3 * len(pa))


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    """Blender's user files in a temp dir for the subprocesses."""
    base = tmp_path_factory.mktemp("render-env")
    (base / "home").mkdir()
    return dict(os.environ, BLENDER_USER_RESOURCES=str(base / "user"), HOME=str(base / "home"),
                PYTHONUNBUFFERED="1")


@pytest.fixture(scope="module")
def tiny_config(tmp_path_factory):
    path = tmp_path_factory.mktemp("config") / "tiny.toml"
    path.write_text(TINY_SCENE)
    return path


def render(env, *args, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], env=env, cwd=REPO,
                          capture_output=True, text=True, timeout=timeout)


def split_renders(env, flags, tmp_path: Path, last: int) -> list[Path]:
    """Frames 1..last and frame ``last`` alone with ``flags``: both folders, after checking that
    frame ``last`` came out pixel for pixel the same (the render-farm contract)."""
    runs = []
    for frames in (f"1-{last}", str(last)):
        out = tmp_path / frames
        proc = render(env, *flags, "--frames", frames, "--out", out)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        runs.append(out)
    name = f"frame_{last:04d}.png"
    assert pixels(runs[1] / name) == pixels(runs[0] / name)
    return runs


def frames_in(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.glob("*.png"))


# --------------------------------------------------------------------------------------------
# Renders


@pytest.fixture(scope="module")
def cycles_run(env, tiny_config, tmp_path_factory):
    """Frames 1-4 with Cycles, with the .blend and the video."""
    out = tmp_path_factory.mktemp("cycles")
    proc = render(env, "--config", tiny_config, "--engine", "cycles", "--frames", "1-4", "--out", out,
                  "--save-blend", "--video")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return out, proc


def test_cycles_frames_show_grass_in_wind(cycles_run):
    out, proc = cycles_run
    names = frames_in(out)
    assert names == [f"frame_{i:04d}.png" for i in range(1, 5)]
    for name in names:
        width, height, _, _ = read_png(out / name)
        assert (width, height) == (64, 36)
        # Grass fills the lower image: the camera is 0.5 m above a field 2.7 m deep ahead of it.
        assert lower_green_share(out / name) > 0.6, name
    # Camera and blades move between frames: consecutive images are not the same.
    for a, b in zip(names, names[1:]):
        assert mean_abs_difference(out / a, out / b) > 0.2, (a, b)
    # One progress line per frame and a summary naming the output folder.
    progress = [line for line in proc.stdout.splitlines() if line.startswith("frame ")]
    assert len(progress) == 4 and progress[0].startswith("frame 1/4") and "ETA" in progress[0]
    assert "done: 4 frame(s)" in proc.stdout and str(out) in proc.stdout
    # One Saved: line a frame, naming the frame (farm managers read each as an output; issue #62:
    # Blender's own named the hidden .frame_NNNN.partial.png first)
    saved = [line.split("Saved: ")[1] for line in proc.stdout.splitlines() if "Saved: " in line]
    assert [s for s in saved if "frame_" in s] == [f"'{out / n}'" for n in names], saved
    assert not list(out.glob(".*")), "temporary files left behind"
    # Cycles loads every image the materials read (5.2 called an Image Texture without an image
    # "Image file  does not exist" and "Failed to load 1 image files")
    assert "Failed to load" not in proc.stdout + proc.stderr and "does not exist" not in proc.stdout + proc.stderr


def test_save_blend_and_video(cycles_run):
    out, proc = cycles_run
    blend = out / "scene.blend"
    assert blend.is_file() and blend.stat().st_size > 10_000
    video = out / "animation.mp4"
    assert video.is_file(), proc.stdout[-2000:]
    head = video.read_bytes()[:64]
    assert b"ftyp" in head  # an ISO media (mp4) container


def test_sub_range_renders_the_same_pixels(cycles_run, env, tiny_config, tmp_path):
    """Render-farm contract: a task's frames alone equal those frames of the 1-4 run, pixel for pixel
    and byte for byte (no render-time text in the PNGs). The task's frames are written as Flamenco's
    chunker hands them out (issue #36: '5,6' for a chunk of two frames, '9,10,20,21' across a gap;
    'A-B' was all render_field.py took, so each such task failed): here '1,3,4'."""
    full, _ = cycles_run
    proc = render(env, "--config", tiny_config, "--engine", "cycles", "--frames", "1,3,4", "--out", tmp_path)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert frames_in(tmp_path) == ["frame_0001.png", "frame_0003.png", "frame_0004.png"]
    assert "frames 1,3-4;" in proc.stdout
    for name in frames_in(tmp_path):
        assert pixels(tmp_path / name) == pixels(full / name), name
        assert (tmp_path / name).read_bytes() == (full / name).read_bytes(), name


def test_a_split_far_into_a_long_range_renders_the_same_pixels(env, tiny_config, tmp_path):
    """A 10,000-frame scene with a moving camera: frame 10,000 rendered alone equals frame 10,000
    of the run 9,999-10,000 (each reaches it through a bounded number of steps, not 10,000)."""
    runs = []
    for frames in ("9999-10000", "10000"):
        out = tmp_path / frames
        proc = render(env, "--config", tiny_config, "--engine", "cycles", "--render-frame-end", "10000",
                      "--frames", frames, "--out", out)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        runs.append(out)
    assert frames_in(runs[1]) == ["frame_10000.png"]
    assert pixels(runs[1] / "frame_10000.png") == pixels(runs[0] / "frame_10000.png")
    assert lower_green_share(runs[1] / "frame_10000.png") > 0.6


def test_a_painted_path_on_a_heightmap_renders_bare_and_splits_the_same(addon, env, tiny_config, tmp_path):
    """A batch render painted from the command line: a density map with a bare stripe down the
    middle (x in -0.4..0.4 m, the camera looking along it) and hills from a heightmap. The stripe is
    bare ground in the image's lower middle while the sides are grass, and frame 4 rendered alone
    equals frame 4 of 1-4 with the maps (they are part of what each frame is a function of)."""
    from windgrass.grass_addon import images

    density = np.ones((64, 64), np.float32)
    density[:, 22:42] = 0.0  # 0.8 m of the 3.2 m field
    (tmp_path / "path.png").write_bytes(images.encode_png(density))
    hills = np.fromfunction(lambda y, x: 0.5 + 0.5 * np.sin(x / 10.0) * np.cos(y / 13.0), (64, 64))
    (tmp_path / "hills.png").write_bytes(images.encode_png(hills.astype(np.float32)))
    flags = ["--config", tiny_config, "--engine", "cycles", "--paint-density", tmp_path / "path.png",
             "--terrain-heightmap", tmp_path / "hills.png", "--terrain-height", "0.3", "--camera-mode", "fixed",
             "--camera-position", "0", "-2.2", "1.3", "--camera-target", "0", "0.6", "0",
             "--render-resolution-x", "128", "--render-resolution-y", "72"]
    runs = split_renders(env, flags, tmp_path, 4)
    width, height, _, _ = read_png(runs[0] / "frame_0004.png")
    image = np.array(pixels(runs[0] / "frame_0004.png"), np.float32).reshape(height, width, 3) / 255.0
    lower = image[int(0.8 * height):]
    excess = lower[..., 1] - np.maximum(lower[..., 0], lower[..., 2])  # grass is green, the floor olive-brown
    middle = excess[:, int(0.42 * width):int(0.58 * width)]
    sides = excess[:, list(range(8)) + list(range(width - 8, width))]
    assert float(middle.mean()) < 0.5 * float(sides.mean()), (float(middle.mean()), float(sides.mean()))


def test_a_scene_files_colliders_render_split_the_same_and_show_their_balls(env, tmp_path):
    """A ball ([[colliders]]) rolls through the tiny field while a vortex ([[effectors]]) turns
    the grass: the batch render shows the ball (its red) and frame 5 rendered alone equals frame 5
    of 1-5, pixel for pixel (the colliders' trail and the vortex are functions of the frame)."""
    config = tmp_path / "ball.toml"
    config.write_text(TINY_SCENE + """
[[colliders]]
radius = 0.25
path = [{time = 0.0, position = [-1.0, 0.6, 0.25]}, {time = 0.3, position = [1.0, 0.6, 0.25]}]

[[effectors]]
type = "vortex"
strength = 4.0
""")
    flags = ["--config", config, "--engine", "cycles", "--camera-mode", "fixed", "--camera-position", "0", "-1.5",
             "1.0", "--camera-target", "0", "0.8", "0.1"]
    runs = split_renders(env, flags, tmp_path, 5)
    red = [p for p in pixels(runs[0] / "frame_0005.png") if p[0] > p[1] + 30 and p[0] > p[2] + 30]
    assert len(red) > 20, len(red)


def test_eevee_frames_show_grass(env, tiny_config, tmp_path):
    proc = render(env, "--config", tiny_config, "--engine", "eevee", "--samples", "1", "--frames", "1-3",
                  "--out", tmp_path)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    names = frames_in(tmp_path)
    assert names == ["frame_0001.png", "frame_0002.png", "frame_0003.png"]
    for name in names:
        assert lower_green_share(tmp_path / name) > 0.6, name
    for a, b in zip(names, names[1:]):
        assert mean_abs_difference(tmp_path / a, tmp_path / b) > 0.2, (a, b)


def test_variants_get_own_folders_seeds_and_wind(env, tiny_config, tmp_path):
    proc = render(env, "--config", tiny_config, "--frames", "2", "--variants", "2", "--out", tmp_path)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    a, b = tmp_path / "variant_00" / "frame_0002.png", tmp_path / "variant_01" / "frame_0002.png"
    assert a.is_file() and b.is_file()
    assert "seed 3" in proc.stdout and "seed 4" in proc.stdout
    assert "wind calm" in proc.stdout and "wind gentle_breeze" in proc.stdout
    # Another seed grows other blades: the images differ.
    assert mean_abs_difference(a, b) > 0.2


# --------------------------------------------------------------------------------------------
# Bad input: exit code 2, a message naming the option, no PNG written


def _bad_toml(tmp_path: Path) -> Path:
    path = tmp_path / "broken.toml"
    path.write_text("[field\nblocks_x = 4\n")
    return path


def _config_bytes(name: str, data: bytes):
    def make(tmp_path: Path) -> list:
        path = tmp_path / name
        path.write_bytes(data)
        return ["--config", path]
    return make


def _out_at_file(tmp_path: Path) -> list:
    path = tmp_path / "a-file.png"
    path.write_text("not a folder")
    return ["--out", path]


BAD_INPUTS = [
    (["--wind-type", "tornado"], "wind.type"),
    (["--field-blades-per-cell", "-1"], "field.blades_per_cell"),
    (["--wind-speed", "nan"], "wind.speed"),
    (["--samples", "0"], "--samples"),
    (["--seed", "-5"], "--seed"),
    ([lambda tmp: ["--config", _bad_toml(tmp)]], "--config"),
    (["--config", "no/such/scene.toml"], "--config"),
    (["--frames", "4-2"], "--frames"),
    (["--frames", "one-two"], "--frames"),
    (["--frames", "1,,2"], "--frames"),
    (["--frames", "3,1-999"], "--frames"),
    (["--frames", "1-999"], "--frames"),
    (["--resolution", "64by36"], "--resolution"),
    (["--resolution", "8x8"], "--resolution"),
    (["--variants", "0"], "--variants"),
    (["--no-such-option", "3"], "--no-such-option"),
    (["--frames", ""], "--frames"),
    (["--lod-enabled", "maybe"], "--lod-enabled"),
    ([_out_at_file], "--out"),
    (["--out", "/proc/windgrass-cannot-be-made"], "--out"),
    ([_config_bytes("utf16.toml", "[field]\nblocks_x = 4\n".encode("utf-16"))], "--config"),
    ([_config_bytes("binary.toml", bytes(range(256)) * 8)], "--config"),
    # (issue #37 item 11: 10,000 colliders were built for 172 s, 1.3 GB, before the engine refused them)
    ([_config_bytes("crowd.toml", "".join(
        f"[[colliders]]\nradius = 0.2\npath = [{{time = 0.0, position = [{i * 0.01:.2f}, 0.0, 0.2]}}, "
        f"{{time = 1.0, position = [{i * 0.01:.2f}, 1.0, 0.2]}}]\n" for i in range(10000)).encode())],
     "interaction.recovery"),
    ([_config_bytes("deep.toml", b"a = " + b"[" * 50000 + b"]" * 50000)], "--config"),
]


BAD_IDS = [f"{n}:{a[-1] if isinstance(a[-1], str) else getattr(a[-1], '__name__', 'file')}:{i}"
           for i, (a, n) in enumerate(BAD_INPUTS)]


@pytest.mark.parametrize("args, named", BAD_INPUTS, ids=BAD_IDS)
def test_bad_input_exits_2_naming_the_option(env, tiny_config, tmp_path, args, named):
    out = tmp_path / "out"
    expanded = []
    for a in args:
        expanded.extend(a(tmp_path) if callable(a) else [a])
    if "--config" not in expanded:
        expanded = ["--config", tiny_config, *expanded]
    if "--out" not in expanded:
        expanded += ["--out", out]
    proc = render(env, *expanded, timeout=60)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert named in proc.stderr, proc.stderr
    # Before anything is built: no scene, no frame, no traceback, no internal helper names.
    assert "scene ready" not in proc.stdout and "Traceback" not in proc.stderr
    assert "_parse" not in proc.stderr and "e+09" not in proc.stderr
    assert not (out.exists() and list(out.rglob("*.png")))


def _files_of_at_most(size: int):
    """For a child process: no file it writes grows past ``size`` bytes (writes past it fail with
    EFBIG, as on a full disk, instead of the signal that would end it)."""
    import resource
    import signal

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))
    return limit


@pytest.mark.parametrize("flag", ["--field-blades-per-cell", "--field-density"])
def test_a_field_of_no_blades_renders_bare_ground(env, tiny_config, tmp_path, flag):
    """Issue #57: the panel's Blades 0 /m² (or no blades a cell) failed the build with a
    ValueError from the cards' atlas. The frame renders: where the grass stood, the ground alone
    (a flat colour, where blades shade the same rows from dark to light)."""
    out = {}
    for name, value in (("bare", "0"), ("grass", "4" if "cell" in flag else "400")):
        out[name] = tmp_path / name
        proc = render(env, "--config", tiny_config, "--frames", "1", "--out", out[name], flag, value)
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    spread = {}
    for name, folder in out.items():
        width, height, _, _ = read_png(folder / "frame_0001.png")
        lower = np.array(pixels(folder / "frame_0001.png")[(2 * height // 3) * width:], float)
        spread[name] = lower.std(axis=0).max()
    assert spread["bare"] < 3.0 < 6.0 < spread["grass"], spread


def test_a_frame_that_cannot_be_written_fails_and_leaves_nothing(env, tiny_config, tmp_path):
    """A full disk (writes past 1 KB fail): the job fails with status 1 and no file looks like a
    finished frame."""
    proc = subprocess.run([sys.executable, str(SCRIPT), "--config", str(tiny_config), "--frames", "1", "--out",
                           str(tmp_path)], env=env, cwd=REPO, capture_output=True, text=True, timeout=120,
                          preexec_fn=_files_of_at_most(1024))
    assert proc.returncode == 1, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "frame 1" in proc.stderr and "done:" not in proc.stdout
    assert frames_in(tmp_path) == [] and not list(tmp_path.iterdir())


@pytest.mark.parametrize("flag", ["--save-blend", "--bake"])
def test_a_blend_file_that_cannot_be_written_whole_fails_and_is_not_left(env, tiny_config, tmp_path, flag):
    """Issue #37 item 10: on a full disk (writes past 100 KB fail; the tiny scene's .blend is about
    240 KB) scene.blend was left cut short ("Missing DNA block" on open) and the job said "saved"
    and exited 0. Now it fails with status 1 naming scene.blend, and no scene.blend (nor a partial
    one) is left; with room to write, the file is whole: it opens in Blender."""
    proc = subprocess.run([sys.executable, str(SCRIPT), "--config", str(tiny_config), "--frames", "1", "--out",
                           str(tmp_path / "full"), flag], env=env, cwd=REPO, capture_output=True, text=True,
                          timeout=300, preexec_fn=_files_of_at_most(100_000))
    assert proc.returncode == 1, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "scene.blend" in proc.stderr and "saved" not in proc.stdout
    assert not [p.name for p in (tmp_path / "full").iterdir() if p.suffix == ".blend"]
    whole = render(env, "--config", tiny_config, "--frames", "1", "--out", tmp_path / "room", "--save-blend")
    assert whole.returncode == 0, whole.stdout[-2000:] + whole.stderr[-2000:]
    check = subprocess.run([sys.executable, "-c", "import bpy, sys; bpy.ops.wm.open_mainfile(filepath=sys.argv[1]); "
                            "print('SCENES', len(bpy.data.scenes))", str(tmp_path / "room" / "scene.blend")],
                           env=env, capture_output=True, text=True, timeout=120)
    assert "SCENES 1" in check.stdout, check.stdout[-1000:] + check.stderr[-1000:]


def _chunks_of(data: bytes) -> list[tuple[bytes, bytes]]:
    out, pos = [], 8
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        out.append((kind, data[pos + 8:pos + 8 + length]))
        pos += 12 + length
    return out


def _png_of(chunks) -> bytes:
    return b"\x89PNG\r\n\x1a\n" + b"".join(struct.pack(">I", len(body)) + kind + body
                                          + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)
                                          for kind, body in chunks)


@pytest.fixture(scope="module")
def one_frame(env, tiny_config, tmp_path_factory):
    out = tmp_path_factory.mktemp("one-frame")
    proc = render(env, "--config", tiny_config, "--frames", "1", "--out", out)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return out / "frame_0001.png"


@pytest.mark.parametrize("case", ["another job's pixels", "a sparse file of 3 GB"])
def test_resume_renders_again_a_frame_whose_stamp_is_not_on_its_pixels(env, tiny_config, tmp_path, one_frame, case):
    """Issue #57: --resume kept a frame that carried this job's fingerprint chunk over another
    job's pixels (the fingerprint did not cover the pixels), and read a 3 GB sparse file with a
    PNG's header and end whole. Each is rendered again (the frame the job makes, pixel for pixel),
    the sparse file without being read (the task stays well under its size in memory)."""
    out = tmp_path / "out"
    out.mkdir()
    target = out / "frame_0001.png"
    chunks = _chunks_of(one_frame.read_bytes())
    if case == "another job's pixels":
        header = next(body for kind, body in chunks if kind == b"IHDR")
        width, height = struct.unpack(">II", header[:8])
        black = zlib.compress(bytes(height * (width * (3 if header[9] == 2 else 4) + 1)))
        image = [kind for kind, _ in chunks].index(b"IDAT")  # (one IDAT of black, the rest as it was)
        target.write_bytes(_png_of([c for c in chunks[:image] if c[0] != b"IDAT"] + [(b"IDAT", black)]
                                   + [c for c in chunks[image:] if c[0] != b"IDAT"]))
    else:
        with target.open("wb") as fh:
            fh.write(_png_of([c for c in chunks if c[0] in (b"IHDR", b"tEXt")]))
            fh.seek(3 << 30)
            fh.write(_png_of([(b"IEND", b"")])[8:])
    # (a parent of its own tells the task's peak memory: its only child's)
    measure = ("import resource, subprocess, sys; code = subprocess.run(sys.argv[1:]).returncode; "
               "print('MAXRSS', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
               "sys.exit(code)")
    proc = subprocess.run([sys.executable, "-c", measure, sys.executable, str(SCRIPT), "--config", str(tiny_config),
                           "--frames", "1", "--out", str(out), "--resume"], env=env, cwd=REPO, capture_output=True,
                          text=True, timeout=300)
    stdout, stderr = proc.stdout, proc.stderr
    assert proc.returncode == 0, stdout[-2000:] + stderr[-2000:]
    assert "already rendered: kept" not in stdout
    assert pixels(target) == pixels(one_frame)
    peak_kb = int(stderr.split("MAXRSS ")[1].split()[0])
    assert peak_kb < 2 << 20, peak_kb  # (under 2 GB)


@pytest.mark.parametrize("planted", ["a pipe", "a link to a pipe", "a link to /dev/zero"])
def test_resume_over_a_frame_name_that_is_no_file_is_a_sentence_not_a_hang(env, tiny_config, tmp_path, planted):
    """Issue #57: a FIFO, a link to one or to /dev/zero named like a frame hung the task until it
    was killed. The task says what lies there and fails at once (status 1), writing through none."""
    out = tmp_path / "out"
    out.mkdir()
    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    name = out / "frame_0001.png"
    if planted == "a pipe":
        os.mkfifo(name)
    else:
        name.symlink_to(pipe if "pipe" in planted else Path("/dev/zero"))
    try:
        proc = render(env, "--config", tiny_config, "--frames", "1", "--out", out, "--resume", timeout=120)
    except subprocess.TimeoutExpired:
        pytest.fail(f"--resume over {planted} hung")
    assert proc.returncode == 1, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "frame_0001.png" in proc.stderr and ("link" in proc.stderr or "not a regular file" in proc.stderr)
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("planted", ["link", "folder"])
def test_what_lies_under_a_frames_names_is_never_written_through(env, tiny_config, tmp_path, planted):
    """Issue #36: a link planted under a frame's temporary name made the render write through it,
    outside the output folder; a folder named like a frame gave a traceback. The link is removed
    and the frame written in the folder; a folder in the way is a sentence, and left alone."""
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere.png"
    out.mkdir()
    if planted == "link":
        (out / ".frame_0001.partial.png").symlink_to(elsewhere)
    else:
        (out / "frame_0001.png").mkdir()
    proc = render(env, "--config", tiny_config, "--frames", "1", "--out", out, timeout=120)
    assert not elsewhere.exists()
    if planted == "link":
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert frames_in(out) == ["frame_0001.png"] and not (out / ".frame_0001.partial.png").is_symlink()
    else:
        assert proc.returncode == 1 and "is a folder where frame frame_0001.png goes" in proc.stderr, proc.stderr
        assert "Traceback" not in proc.stderr and (out / "frame_0001.png").is_dir()


def test_incomplete_pngs_are_refused(addon, tmp_path):
    import render_field

    empty = tmp_path / "empty.png"
    empty.write_bytes(b"")
    cut = tmp_path / "cut.png"
    whole = tmp_path / "whole.png"
    whole.write_bytes(render_field.PNG_SIGNATURE + b"\0" * 40 + render_field.PNG_END)
    cut.write_bytes(whole.read_bytes()[:30])
    render_field.check_png(whole)
    for bad, why in ((empty, "empty"), (cut, "not a complete PNG")):
        with pytest.raises(OSError, match=why):
            render_field.check_png(bad)


def test_older_blender_is_named_with_the_version_needed(addon):
    import render_field

    assert render_field.blender_version_error((3, 4, 1)) == \
        "Windgrass needs Blender 4.5 or newer (this is 3.4.1)"  # (the manifest's floor: 4.5 LTS)
    assert render_field.blender_version_error((4, 2, 0)) == "Windgrass needs Blender 4.5 or newer (this is 4.2.0)"
    assert render_field.blender_version_error((4, 5, 0)) is None
    assert render_field.blender_version_error((5, 0, 1)) is None


def test_ctrl_c_stops_after_the_frame_in_progress(env, tiny_config, tmp_path):
    """SIGINT during a batch render: the frame in progress finishes, the job stops, the finished
    frames stay whole, status 130 and a message saying so."""
    proc = subprocess.Popen([sys.executable, str(SCRIPT), "--config", tiny_config, "--render-frame-end", "40",
                             "--frames", "1-40", "--out", str(tmp_path)], env=env, cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        for line in proc.stdout:
            if line.startswith("frame 1/40"):
                proc.send_signal(signal.SIGINT)
                break
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, out[-2000:] + err[-2000:]
    names = frames_in(tmp_path)
    assert 1 <= len(names) < 40 and names[0] == "frame_0001.png"
    for name in names:
        width, height, _, _ = read_png(tmp_path / name)
        assert (width, height) == (64, 36)
    assert "interrupted" in err and "kept" in err
    assert not list(tmp_path.glob(".*")), "temporary files left behind"


def test_help_documents_every_option(env):
    proc = render(env, "--help", timeout=60)
    assert proc.returncode == 0
    for option in ("--config", "--frames", "--out", "--engine", "--samples", "--resolution", "--seed",
                   "--variants", "--save-blend", "--video", "--wind-speed", "--camera-mode",
                   "--field-blades-per-cell"):
        assert option in proc.stdout, option


# --------------------------------------------------------------------------------------------
# The flythrough path (in process): a pure, smooth function of the frame inside the field


@pytest.fixture
def stage(addon):
    import stage

    return stage


@pytest.fixture
def tiny_params(addon, tiny_config):
    from importlib import import_module

    return import_module(f"{addon.__name__}.grass_addon.schema").load_toml(tiny_config)


def test_flythrough_stays_over_the_field_and_looks_where_it_goes(stage, tiny_params):
    p = tiny_params.replace({"render.frame_end": 2000})
    ex, ey = stage.field_extent(p)
    step = p.camera.speed / p.render.fps  # metres per frame
    turn_radius = 0.5 * stage.FLY_WIDTH_SHARE * ex
    previous = None
    for frame in range(1, 2001):  # several laps of the racetrack
        (x, y, z), yaw, pitch = stage.flythrough_pose(p, frame)
        assert abs(x) < ex / 2 and abs(y) < ey / 2 and z == p.camera.height
        assert pitch < 0  # looks slightly down at the grass ahead
        if previous is not None:
            (px, py, _), pyaw = previous
            moved = math.hypot(x - px, y - py)
            # camera.speed along the path: chords of the turns are a little shorter than arcs;
            # the sway of the straights (amplitude <= 0.1 of their length, slope <= 0.1 pi)
            # lengthens them by at most sqrt(1 + (0.1 pi)^2) = 1.048.
            assert 0.9 * step < moved <= 1.048 * step
            # The camera looks where it goes: heading of the chord within a few degrees of yaw.
            chord = math.atan2(y - py, x - px)
            assert abs(math.remainder(chord - 0.5 * (yaw + pyaw), 2 * math.pi)) < math.radians(3)
            # The heading turns smoothly (unwrapped: no 2 pi jumps), no faster than along the
            # tightest curve: the half circles of radius w (the sway's curvature is smaller).
            assert abs(yaw - pyaw) <= 1.05 * step / turn_radius
        previous = ((x, y, z), yaw)


def test_camera_pose_is_a_pure_function_of_the_frame(stage, tiny_params, scene):
    camera = stage.setup_stage(scene, tiny_params)
    assert scene.camera == camera and scene.render.fps == tiny_params.render.fps
    forward = []
    for frame in (5, 2, 5):
        stage.pose_camera(scene, tiny_params, frame)
        scene.frame_set(frame)
        # The keyframes agree with the pose function: the evaluated camera is where it should be.
        location, rotation = stage.camera_pose(tiny_params, frame)
        assert tuple(camera.matrix_world.translation) == pytest.approx(location, abs=1e-5)
        forward.append(tuple(-camera.matrix_world.col[2].to_3d()))
    assert forward[0] == pytest.approx(forward[2], abs=1e-6)
    # Fixed mode looks from camera.position at camera.target.
    fixed = tiny_params.replace({"camera.mode": "fixed", "camera.position": [0, -3, 1],
                                 "camera.target": [0, 1, 1]})
    (pos, rot) = stage.camera_pose(fixed, 1)
    from mathutils import Euler, Vector

    direction = Euler(rot, "XYZ").to_matrix() @ Vector((0, 0, -1))
    assert tuple(direction) == pytest.approx((0, 1, 0), abs=1e-6) and pos == (0, -3, 1)


def test_sun_and_sky_follow_the_render_parameters(stage, tiny_params, scene):
    p = tiny_params.replace({"render.sun_elevation": 30.0, "render.sun_azimuth": 90.0})
    stage.setup_stage(scene, p)
    suns = [o for o in scene.objects if o.type == "LIGHT" and o.data.type == "SUN"]
    assert len(suns) == 1
    # A sun light shines down its local -Z: from elevation 30 deg, azimuth 90 deg (+Y) the light
    # travels towards -Y and down.
    travel = suns[0].matrix_world.to_3x3().col[2] * -1
    assert tuple(travel) == pytest.approx((0.0, -math.cos(math.radians(30)), -0.5), abs=1e-5)
    assert scene.world is not None and scene.world.node_tree is not None
    assert scene.view_settings.view_transform in ("AgX", "Filmic")
    assert scene.cycles.device == "CPU" and not scene.cycles.use_animated_seed


def test_past_a_small_field_lies_meadow_to_hills_not_a_ruler_line(env, tiny_config, tmp_path):
    """A 3.2 m field seen from 1.5 m up, looking 30 m out over its edge: below the horizon the
    land beyond it is grass-coloured (green well above red and blue, where the old world's land
    was olive-grey: G/R 1.16, G/B 1.33), and the skyline above it rises and falls over the
    bearing by some pixels as hills do (a bare world's horizon is one row)."""
    proc = render(env, "--config", tiny_config, "--frames", "1", "--out", tmp_path, "--resolution", "480x270",
                  "--samples", "4", "--camera-mode", "fixed", "--camera-position", "0", "-1.4", "1.5",
                  "--camera-target", "0", "30", "0")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    image = np.array(pixels(tmp_path / "frame_0001.png"), np.float64).reshape(270, 480, 3)
    degree = 270 / (2 * math.degrees(math.atan(math.tan(math.radians(27.5)) * 9 / 16)))  # rows per degree
    horizon = int(round(135 - math.degrees(math.atan2(1.5, 31.4)) * degree))
    land = image[horizon + int(3 * degree):horizon + int(8 * degree)].reshape(-1, 3).mean(axis=0)
    assert land[1] > 1.3 * land[0] and land[1] > 1.5 * land[2], f"the land past the field is {land.round()}"
    light = image.mean(axis=2)
    drops = light[1:horizon + 4] < 0.96 * light[:horizon + 3]  # a row darker than the one above it
    skyline = np.array([np.flatnonzero(column).min() if column.any() else horizon for column in drops.T])
    assert skyline.max() - skyline.min() >= 4, f"the skyline spans rows {skyline.min()}-{skyline.max()}"
    assert np.all(skyline <= horizon + 2), "the sky reaches below the horizon"


def test_example_scenes_are_valid_and_the_default_is_small(addon):
    """Every scenes/*.toml loads; the default (README's first command) stays a short, light job."""
    from importlib import import_module

    schema = import_module(f"{addon.__name__}.grass_addon.schema")
    scenes = sorted((REPO / "scenes").glob("*.toml"))
    assert any(p.name == "default.toml" for p in scenes)
    for path in scenes:
        schema.load_toml(path)  # raises ParameterError naming the key and the file
    p = schema.load_toml(REPO / "scenes" / "default.toml")
    frames = p.render.frame_end - p.render.frame_start + 1
    # A few minutes on two CPU cores: at most ~2 s of animation at modest size and samples.
    assert frames <= 48 and p.render.resolution_x * p.render.resolution_y <= 480 * 270
    assert p.render.samples <= 16 and p.render.engine == "cycles" and p.camera.mode == "flythrough"


def test_a_field_that_cannot_be_simulated_fails_the_batch_render(addon):
    """Grass that could not be simulated for a frame is an error for a batch render, not a frame
    rendered without it (or with the grass of another frame)."""
    from importlib import import_module

    import render_field

    properties = import_module(f"{addon.__name__}.grass_addon.bridge.properties")
    runtime = import_module(f"{addon.__name__}.grass_addon.bridge.runtime")
    schema = import_module(f"{addon.__name__}.grass_addon.schema")
    import bpy

    scene = bpy.context.scene
    params = schema.defaults().replace({"field.blocks_x": 1, "field.blocks_y": 1, "field.cells_per_block": 4})
    item = properties.add_field(scene, params, name="Meadow")
    runtime.build_field(scene, item)
    scene.frame_set(2)
    render_field.check_fields(scene)  # fine
    item.lod.blade_far = 1.0  # nearer than blade_near: cannot be simulated
    scene.frame_set(3)
    with pytest.raises(render_field.FieldError, match="Meadow.*lod.blade_far"):
        render_field.check_fields(scene)


def test_bake_flag_writes_a_cache_and_a_blend_that_plays_it(env, tiny_config, tmp_path):
    proc = render(env, "--config", tiny_config, "--frames", "1-2", "--bake", "--out", tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    caches = list((tmp_path / "scene_windgrass").rglob("*.abc"))
    assert len(caches) == 1 and caches[0].stat().st_size > 1000
    assert (tmp_path / "scene.blend").is_file() and not (tmp_path / "scene.blend1").exists()
    assert "baked" in proc.stdout and "MB per frame" in proc.stdout
    assert frames_in(tmp_path) == ["frame_0001.png", "frame_0002.png"]


def test_bake_format_usd_writes_a_usd_cache_the_saved_blend_plays(env, tiny_config, tmp_path):
    import bpy

    if bpy.app.version < (5, 0, 0):
        proc = render(env, "--config", tiny_config, "--frames", "1-2", "--bake", "--bake-format", "usd",
                      "--out", tmp_path)
        assert proc.returncode == 1 and "USD needs Blender 5.0 or later" in proc.stderr
        assert not list(tmp_path.rglob("*.usdc"))
        return
    proc = render(env, "--config", tiny_config, "--frames", "1-2", "--bake", "--bake-format", "usd", "--out",
                  tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    caches = list((tmp_path / "scene_windgrass").rglob("*.usdc"))
    assert len(caches) == 1 and caches[0].stat().st_size > 1000 and not list(tmp_path.rglob("*.abc"))
    assert frames_in(tmp_path) == ["frame_0001.png", "frame_0002.png"]
    bad = render(env, "--config", tiny_config, "--bake", "--bake-format", "obj", "--out", tmp_path / "bad")
    assert bad.returncode == 2 and "--bake-format" in bad.stderr and "usd" in bad.stderr


def test_lod_comparison_script_measures_rows_images_and_flicker(env, tiny_config, tmp_path):
    import json

    proc = subprocess.run([sys.executable, str(REPO / "headless" / "lod_compare.py"), "--config", str(tiny_config),
                           "--resolution", "48x27", "--samples", "1", "--lights", "sun", "overcast",
                           "--presets", "default", "--views", "square", "--flythrough-frames", "2",
                           "--out", str(tmp_path), "--json"],
                          env=env, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    for case in ("default_sun", "default_overcast"):
        figures = result["cases"][case]
        assert 0.0 <= figures["mean_abs_diff"] <= 1.0 and 0.0 <= figures["row_diff_max"] <= 1.0
    assert result["flythrough"]["flicker_geometry"] > 0.0 and result["flythrough"]["ratio"] > 0.0
    assert sorted(p.name for p in tmp_path.glob("default_sun_*.png")) == [
        "default_sun_geometry_0001.png", "default_sun_lod_0001.png"]
    bad = subprocess.run([sys.executable, str(REPO / "headless" / "lod_compare.py"), "--presets", "prairie"],
                         env=env, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "presets" in bad.stderr and "meadow" in bad.stderr
    bad = subprocess.run([sys.executable, str(REPO / "headless" / "lod_compare.py"), "--views", "strip",
                          "--heights", "1.1", "200"], env=env, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "heights" in bad.stderr and "0.05-50" in bad.stderr


def test_a_long_range_keys_the_camera_on_every_frame(stage, tiny_params, scene):
    """10,000 frames of camera path are keyed in bulk; the evaluated camera follows the pose
    function on any of them."""
    params = tiny_params.replace({"render.frame_end": 10_000})
    stage.setup_render(scene, params)
    camera = stage.setup_camera(scene, params)
    from windgrass.grass_addon.bridge import animation

    curves = animation.action_fcurves(camera.animation_data)
    assert len(curves) == 6 and all(len(fc.keyframe_points) == 10_000 for fc in curves)
    for frame in (1, 4321, 10_000):
        scene.frame_set(frame)
        location, _ = stage.camera_pose(params, frame)
        assert tuple(camera.matrix_world.translation) == pytest.approx(location, abs=1e-4)


MEMORY_PROBE = textwrap.dedent("""
    import json, os, sys
    sys.path.insert(0, sys.argv[-2])

    def high_water():  # this process's peak resident memory (getrusage's would keep its parent's)
        with open("/proc/self/status") as status:
            return next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmHWM"))

    import bpy, addon_loader
    addon_loader.load_addon()
    from windgrass.grass_addon import memory, schema
    import stage
    from windgrass.grass_addon.bridge import properties, runtime
    params = schema.load_toml(sys.argv[-1]).replace({"lod.card_far": 40.0, "render.resolution_x": 160,
        "render.resolution_y": 90, "render.samples": 1})
    scene = bpy.context.scene
    stage.setup_stage(scene, params)
    stage.pose_camera(scene, params, 1)
    before = high_water()
    item = properties.add_field(scene, params)
    runtime.build_field(scene, item)
    scene.frame_set(2)
    bpy.ops.render.render()
    peak = high_water()
    print("MEMORY", json.dumps({"peak": peak, "before": before, "estimate": memory.estimate(params).total}))
    sys.stdout.flush()
    os._exit(0)
""")


def test_memory_estimate_bounds_what_a_render_takes(tmp_path):
    """Issue: memory followed lod.card_far, not the budget. The estimate that Windgrass checks
    before building is an upper bound of what Blender really takes to build and render the
    default 2 km scene (peak resident memory of a fresh process)."""
    script = tmp_path / "probe.py"
    script.write_text(MEMORY_PROBE)
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"), HOME=str(tmp_path))
    args = [sys.executable, str(script), str(REPO / "headless"), str(REPO / "scenes" / "default.toml")]
    result = subprocess.run(args, capture_output=True, text=True, env=env, timeout=600)
    line = next(line for line in result.stdout.splitlines() if line.startswith("MEMORY"))
    measured = json.loads(line.split(" ", 1)[1])
    assert measured["peak"] < measured["estimate"], measured
    assert measured["estimate"] < 2.5 * measured["peak"], measured  # an estimate, not a wild guess


def test_a_card_range_that_would_run_out_of_memory_is_refused_before_anything_is_built(with_bridge):
    """Issue: --lod-card-far 300 passed 12 GB. Refused up front, naming lod.card_far and the
    longest card range that fits, which does fit."""
    import bpy
    from windgrass.grass_addon import memory, schema
    from windgrass.grass_addon.bridge import properties, runtime

    params = schema.load_toml(REPO / "scenes" / "default.toml").replace({"lod.card_far": 300.0})
    scene = bpy.context.scene
    item = properties.add_field(scene, params)
    with pytest.raises(schema.ParameterError) as info:
        runtime.build_field(scene, item)
    assert info.value.key == "lod.card_far"
    assert item.collection is None and not [o for o in bpy.data.objects if o.get("wg_uid")]  # nothing built
    suggested = float(str(info.value).split("lod.card_far up to ")[1].split(" m")[0])
    assert params.lod.card_near <= suggested < 300.0
    fits = params.replace({"lod.card_far": suggested})
    assert memory.estimate(fits).total <= fits.simulation.memory_mb << 20

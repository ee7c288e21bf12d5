"""Render farms (issue #29): the job bundles run on the real Open Job Description runtime (``openjd
run``, what AWS Deadline Cloud's workers run), with the ``bpy`` module standing in for the
workers' ``blender`` (a small executable that runs ``-b [FILE] -P SCRIPT -- ARGS`` and
``--command extension install-file`` with the module). Frames rendered in chunks equal the frames
one process renders, pixel for pixel; a job run again after a chunk was killed renders only what
is missing; a saved .blend with live grass renders on a Blender that has never seen Windgrass.
The last tests run the jobs with the real Blender 5.2 LTS binary as the workers' Blender (where
this machine has the window tests' Debian root)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from pathlib import Path

import bpy
import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
OPENJD = Path(sys.executable).with_name("openjd")

TINY = """
[field]
blocks_x = 2
blocks_y = 2
cells_per_block = 8
cell_size = 0.1
blades_per_cell = 3
seed = 5
[wind]
speed = 5.0
[lod]
blade_near = 1.5
blade_far = 2.5
card_near = 3.0
card_far = 4.0
[camera]
mode = "fixed"
position = [0.0, -1.6, 0.5]
target = [0.0, 0.5, 0.0]
[render]
samples = 1
resolution_x = 48
resolution_y = 27
frame_start = 1
frame_end = 6
[simulation]
preroll = 0.5
"""

STAND_IN = '''#!{python}
"""A stand-in for a worker's Blender: the bpy module runs what the job's command lines ask."""
import os, runpy, sys
args = sys.argv[1:]
os.environ.setdefault("HOME", os.environ.get("BLENDER_USER_RESOURCES", "/tmp"))
import bpy
if args[:3] == ["--command", "extension", "install-file"]:
    bpy.ops.extensions.package_install_files(filepath=args[-1], repo="user_default", enable_on_install=True)
    bpy.ops.wm.save_userpref()
    os._exit(0)
blend = args[args.index("-b") + 1] if "-b" in args and not args[args.index("-b") + 1].startswith("-") else None
script = args[args.index("-P") + 1] if "-P" in args else args[args.index("--python") + 1]
user = os.environ.get("BLENDER_USER_RESOURCES")
if user and "--factory-startup" not in args:  # (the module does not read the user's preferences: enable
    import addon_utils                        # what is installed there)
    folder = os.path.join(user, "extensions", "user_default")
    for name in [n for n in os.listdir(folder) if not n.startswith(".")] if os.path.isdir(folder) else ():
        addon_utils.enable("bl_ext.user_default." + name, default_set=True)
if blend:
    bpy.ops.wm.open_mainfile(filepath=blend)
sys.argv = [script] + (args[args.index("--") + 1:] if "--" in args else [])
runpy.run_path(script, run_name="__main__")
'''


@pytest.fixture
def stand_in(tmp_path) -> Path:
    path = tmp_path / "blender"
    path.write_text(STAND_IN.format(python=sys.executable))
    path.chmod(0o755)
    return path


def _env(tmp_path, user: Path | None = None) -> dict:
    env = dict(os.environ, HOME=str(tmp_path / "home"), PYTHONUNBUFFERED="1")
    (tmp_path / "home").mkdir(exist_ok=True)
    env.pop("BLENDER_USER_RESOURCES", None)
    if user is not None:
        env["BLENDER_USER_RESOURCES"] = str(user)
    return env


def _openjd(bundle: Path, stand_in: Path, env: dict, *more: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(OPENJD), "run", str(bundle / "template.yaml"), "--job-param",
                           f"file://{bundle / 'job_params.yaml'}", "--job-param", f"BlenderExecutable={stand_in}",
                           "--step", "Render", *more], capture_output=True, text=True, env=env, timeout=900)


def _pixels(folder: Path) -> dict[str, np.ndarray]:
    from windgrass.grass_addon import images

    return {p.name: images.decode_png(p.read_bytes()) for p in sorted(folder.glob("frame_*.png"))}


def test_a_scene_file_job_renders_in_chunks_what_one_process_renders(tmp_path, stand_in):
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY)
    bundle, out = tmp_path / "bundle", tmp_path / "farm"
    env = _env(tmp_path)
    made = subprocess.run([sys.executable, str(REPO / "headless" / "farm.py"), "--config", str(scene), "--frames",
                           "1-6", "--chunk", "2", "--out", str(out), str(bundle)], capture_output=True, text=True,
                          env=env, timeout=300)
    assert made.returncode == 0, made.stderr
    check = subprocess.run([str(OPENJD), "check", str(bundle / "template.yaml")], capture_output=True, text=True)
    assert check.returncode == 0 and "passes validation" in check.stdout, check.stdout + check.stderr
    run = _openjd(bundle, stand_in, env)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    saved = [line for line in run.stdout.splitlines() if "Saved: '" in line and ".partial" not in line]
    assert len(saved) == 6 and "Chunks run: 3" in run.stdout
    # one Blender for the session's three chunks: the scene built once (issue #36: 11-12 s a task)
    assert run.stdout.count("Windgrass session: one Blender") == 1
    assert run.stdout.count("scene ready in") == 3 and run.stdout.count("scene kept from the session's") == 2
    _ended(run.stdout)
    one = tmp_path / "one"
    single = subprocess.run([sys.executable, str(REPO / "headless" / "render_field.py"), "--config", str(scene),
                             "--frames", "1-6", "--out", str(one)], capture_output=True, text=True, env=env,
                            timeout=900)
    assert single.returncode == 0, single.stderr
    farm_frames, one_frames = _pixels(out), _pixels(one)
    assert list(farm_frames) == [f"frame_{i:04d}.png" for i in range(1, 7)] == list(one_frames)
    for name in farm_frames:
        assert np.array_equal(farm_frames[name], one_frames[name]), name
    # a chunk killed mid-way: frame 3 gone, frame 4 cut off; frame 5 zeroed in its middle (its
    # signature and end intact), frame 6 a whole PNG of another size: the job run again renders
    # those four (issue #36: the last two were kept)
    (out / "frame_0003.png").unlink()
    data = (out / "frame_0004.png").read_bytes()
    (out / "frame_0004.png").write_bytes(data[: len(data) // 2])
    data = bytearray((out / "frame_0005.png").read_bytes())
    data[len(data) // 3: 2 * len(data) // 3] = bytes(len(data) // 3)
    (out / "frame_0005.png").write_bytes(bytes(data))
    from windgrass.grass_addon import images

    (out / "frame_0006.png").write_bytes(images.encode_png(np.full((8, 8), 0.5)))
    redo = ("frame_0003.png", "frame_0004.png", "frame_0005.png", "frame_0006.png")
    kept = {n: (out / n).stat().st_mtime_ns for n in farm_frames if n not in redo}
    again = _openjd(bundle, stand_in, env)
    assert again.returncode == 0, again.stderr[-3000:]
    assert again.stdout.count("already rendered: kept") == 2
    # the finished chunk 1-2 built nothing; 3-4 built the scene, 5-6 kept it
    assert again.stdout.count("scene ready in") == 2 and again.stdout.count("scene kept from the session's") == 1
    assert sorted(line.split("Saved: ")[1] for line in again.stdout.splitlines()
                  if "Saved: '" in line and ".partial" not in line) == [f"'{out / n}'" for n in redo]
    assert all((out / n).stat().st_mtime_ns == t for n, t in kept.items())
    rerun = _pixels(out)
    assert all(np.array_equal(rerun[n], one_frames[n]) for n in one_frames)
    # the scene edited (another wind) and submitted again into the same folder: every frame is
    # rendered again (issue #36: --resume kept the earlier submission's frames)
    scene.write_text(TINY.replace("speed = 5.0", "speed = 7.0"))
    made = subprocess.run([sys.executable, str(REPO / "headless" / "farm.py"), "--config", str(scene), "--frames",
                           "1-6", "--chunk", "2", "--out", str(out), str(bundle)], capture_output=True, text=True,
                          env=env, timeout=300)
    assert made.returncode == 0, made.stderr
    edited = _openjd(bundle, stand_in, env)
    assert edited.returncode == 0, edited.stderr[-3000:]
    assert "already rendered" not in edited.stdout
    assert len([line for line in edited.stdout.splitlines() if "Saved: '" in line and ".partial" not in line]) == 6
    assert not np.array_equal(_pixels(out)["frame_0006.png"], one_frames["frame_0006.png"])


def _ended(log: str) -> None:
    """The session's Blender (its pid as the session's start printed it) has ended with the session."""
    import re
    import time

    pid = int(re.search(r"Windgrass session: one Blender \(pid (\d+)\)", log).group(1))
    for _ in range(100):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.1)
    raise AssertionError(f"the session's Blender (pid {pid}) outlived its session")


def test_a_task_whose_session_blender_is_gone_renders_in_a_blender_of_its_own(tmp_path, stand_in):
    """The session's Blender may die (killed, out of memory): its address is still in the session
    folder, nothing answers there. The task renders its frames in a Blender of its own."""
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY)
    session = tmp_path / "session"
    (session / ".windgrass-session").mkdir(parents=True, mode=0o700)
    gone = Path(tempfile.mkdtemp(prefix="wg-", dir="/tmp")) / "server.sock"  # (short: a socket's path)
    with socket.socket(socket.AF_UNIX) as closed:  # (a socket nothing listens on any more)
        closed.bind(str(gone))
    address = session / ".windgrass-session" / "session.json"
    address.write_text(json.dumps({"socket": str(gone), "token": "0" * 64, "pid": 999_999, "stamp": ""}))
    address.chmod(0o600)
    out = tmp_path / "frames"
    proc = subprocess.run([str(stand_in), "-b", "--factory-startup", "-P",
                           str(REPO / "grass_addon" / "bridge" / "farm_session.py"), "--", "run", "--dir", str(session),
                           "--blender", str(stand_in), "--script", str(REPO / "headless" / "render_field.py"), "--",
                           "--config", str(scene), "--frames", "2-3", "--out", str(out), "--resume"],
                          capture_output=True, text=True, env=_env(tmp_path), timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "the session's Blender is gone; this task starts its own" in proc.stdout
    assert sorted(p.name for p in out.glob("frame_*.png")) == ["frame_0002.png", "frame_0003.png"]
    assert not address.exists()


@pytest.mark.parametrize("args, words", [
    (["--chunk", "0"], "at least 1"),
    (["--frames", "5-9"], "outside the scene's frames 1-6"),
    (["--out", "/proc/windgrass-farm"], "cannot write into"),
])
def test_bad_farm_input_is_a_sentence(tmp_path, args, words):
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY)
    base = {"--chunk": "2", "--frames": "1-6", "--out": str(tmp_path / "out")}
    base.update(dict(zip(args[::2], args[1::2])))
    flags = [x for pair in base.items() for x in pair]
    proc = subprocess.run([sys.executable, str(REPO / "headless" / "farm.py"), "--config", str(scene), *flags,
                           str(tmp_path / "bundle")], capture_output=True, text=True, env=_env(tmp_path), timeout=120)
    assert proc.returncode == 2 and words in proc.stderr and "Traceback" not in proc.stderr, proc.stderr


def _farm_py(tmp_path, config, bundle, *more, out=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(REPO / "headless" / "farm.py"), "--config", str(config),
                           "--out", str(out or tmp_path / "out"), *more, str(bundle)], capture_output=True, text=True,
                          env=_env(tmp_path), timeout=120, cwd=tmp_path)


def _tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_bundle_is_written_only_into_a_folder_of_its_own_and_deletes_nothing_else(tmp_path):
    """Issue #57 (and #36): farm.py replaced the user's files that share its names (template.yaml,
    job_params.yaml) without a word and deleted a windgrass/ it had not written; writing a bundle
    again from the scene file it carries destroyed that scene and its map; a scene whose map was
    missing exited 2 after the old bundle's windgrass/ was gone. Now a folder it did not write is
    a sentence and stays byte for byte; its own is written again whole or not at all, keeping what
    the user put beside it (an output/ the farm brought back)."""
    from PIL import Image

    (tmp_path / "maps").mkdir()
    Image.fromarray(np.full((8, 8), 200, np.uint8)).save(tmp_path / "maps" / "paths.png")
    config = tmp_path / "tiny.toml"
    config.write_text(TINY + '[paint]\ndensity = "maps/paths.png"\n')
    for name, files in (("project", {"notes.txt": b"my notes", "template.yaml": b"mine", "tex/wood.png": b"png"}),
                        ("clone", {"windgrass/.git/HEAD": b"ref: refs/heads/main\n"})):
        folder = tmp_path / name
        for rel, data in files.items():
            (folder / rel).parent.mkdir(parents=True, exist_ok=True)
            (folder / rel).write_bytes(data)
        refused = _farm_py(tmp_path, config, folder)
        assert refused.returncode == 2 and "not written by farm.py" in refused.stderr, refused.stderr
        assert "Traceback" not in refused.stderr and _tree(folder) == files
    bundle = tmp_path / "bundle"
    assert _farm_py(tmp_path, config, bundle).returncode == 0
    (bundle / "output").mkdir()
    (bundle / "output" / "frame_0001.png").write_bytes(b"the farm's frame")
    (bundle / "notes.txt").write_text("the user's")
    carried = bundle / "windgrass" / "scene" / "tiny.toml"
    again = _farm_py(tmp_path, carried, bundle)  # from the scene file the bundle carries
    assert again.returncode == 0, again.stderr
    assert carried.is_file() and "density" in carried.read_text()
    density = carried.read_text().split('density = "')[1].split('"')[0]
    assert (carried.parent / density).read_bytes() == (tmp_path / "maps" / "paths.png").read_bytes()
    assert (bundle / "output" / "frame_0001.png").read_bytes() == b"the farm's frame"
    assert (bundle / "notes.txt").read_text() == "the user's"
    before = _tree(bundle)
    broken = tmp_path / "broken.toml"
    broken.write_text(TINY + '[paint]\ndensity = "maps/missing.png"\n')
    failed = _farm_py(tmp_path, broken, bundle)
    assert failed.returncode == 2 and "missing.png" in failed.stderr, failed.stderr
    assert _tree(bundle) == before  # (the bundle before, whole)
    hidden = [p for p in bundle.rglob("*") if any(part.startswith(".") for part in p.relative_to(bundle).parts)]
    assert [p.name for p in hidden] == [".windgrass-bundle.json"] and not any(p.is_symlink() for p in bundle.rglob("*"))


def test_a_bundle_carries_only_the_scenes_own_files(tmp_path):
    """Issue #57: a scene file naming ~/.aws/credentials as paint.density had the credentials copied
    into the bundle that deadline bundle submit uploads (exit 0), and so did a link beside the
    scene pointing there. A file from outside the scene's folder is refused, named, and nothing is
    written; --allow-outside carries it."""
    secret = tmp_path / "home" / ".aws" / "credentials"
    secret.parent.mkdir(parents=True)
    secret.write_bytes(b"[default]\naws_secret_access_key = hunter2\n")
    scene_dir = tmp_path / "scene"
    (scene_dir / "maps").mkdir(parents=True)
    (scene_dir / "maps" / "link.png").symlink_to(secret)
    for value in ("~/.aws/credentials", "maps/link.png"):
        config = scene_dir / "tiny.toml"
        config.write_text(TINY + f'[paint]\ndensity = "{value}"\n')
        bundle = tmp_path / "bundle"
        refused = _farm_py(tmp_path, config, bundle)
        assert refused.returncode == 2, refused.stderr
        assert "paint.density" in refused.stderr and "outside its folder" in refused.stderr, refused.stderr
        assert str(secret) in refused.stderr and "--allow-outside" in refused.stderr
        assert not bundle.exists() or not any(p.is_file() for p in bundle.rglob("*"))
    allowed = _farm_py(tmp_path, config, bundle, "--allow-outside")
    assert allowed.returncode == 0, allowed.stderr
    assert any(p.read_bytes() == secret.read_bytes() for p in (bundle / "windgrass" / "scene" / "maps").iterdir())


@pytest.mark.parametrize("case", ["a frame list too long for OpenJD", "100 million frames", "a long epoch", "~",
                                  "an empty bundle path"])
def test_farm_py_bounds_what_it_is_given(tmp_path, case):
    """Issue #57: a frame list over 1,024 characters wrote a bundle openjd check refuses;
    1-100000000 grew to 3 GB before it was killed; frame 1,000,000 with a long epoch simulated
    for minutes; ~ in --out or the bundle made a folder named ~; an empty bundle path wrote into
    the current folder."""
    config = tmp_path / "long.toml"
    config.write_text(TINY.replace("frame_end = 6", "frame_end = 1000000")
                      + ("epoch = 1000000.0\n" if case == "a long epoch" else ""))
    frames = {"a frame list too long for OpenJD": ",".join(str(f) for f in range(1, 1200, 2)),
              "100 million frames": "1-1000000", "a long epoch": "1000000"}.get(case, "1-4")
    bundle = {"~": "~/bundle", "an empty bundle path": ""}.get(case, str(tmp_path / "bundle"))
    out = "~/frames" if case == "~" else None
    proc = _farm_py(tmp_path, config, bundle, "--frames", frames, out=out)
    words = {"a frame list too long for OpenJD": "at most 1,024", "100 million frames": "at most 100,000",
             "a long epoch": "simulation.epoch", "an empty bundle path": "bundle: no folder given"}.get(case)
    if words is None:
        assert proc.returncode == 0, proc.stderr
        assert (tmp_path / "home" / "bundle" / "template.yaml").is_file() and (tmp_path / "home" / "frames").is_dir()
        assert not (tmp_path / "~").exists()
    else:
        assert proc.returncode == 2 and words in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
        assert not any(p.is_file() for p in tmp_path.rglob("template.yaml"))


def test_a_worker_on_another_blender_line_refuses_the_jobs_frames(tmp_path, stand_in):
    """Issue #36 item 4: the same frame from two Blender lines differs (18/255 on average), and a
    job took any Blender on the workers' PATH. A job says the line its frames are made with; a
    worker on another fails with a sentence and writes nothing."""
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY)
    bundle, out = tmp_path / "bundle", tmp_path / "out"
    made = subprocess.run([sys.executable, str(REPO / "headless" / "farm.py"), "--config", str(scene), "--frames",
                           "1-2", "--chunk", "2", "--blender-version", "4.0", "--out", str(out), str(bundle)],
                          capture_output=True, text=True, env=_env(tmp_path), timeout=120)
    assert made.returncode == 0, made.stderr
    run = _openjd(bundle, stand_in, _env(tmp_path))
    here = ".".join(str(v) for v in bpy.app.version[:2])
    assert run.returncode != 0
    assert f"this worker runs Blender {here}, the job's frames are made with Blender 4.0" in run.stdout + run.stderr
    assert not list(out.glob("*.png"))


def _live_blend(tmp_path, with_bridge) -> Path:
    """A saved .blend with a live field, a keyed ball rolling through it and a camera."""
    from windgrass.grass_addon.bridge import properties

    assert bpy.ops.windgrass.field_add(blocks_x=2, blocks_y=2, cells_per_block=8, blades_per_cell=3) == {"FINISHED"}
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 4
    item = scene.windgrass.fields[-1]
    with properties.batch(item):
        item.simulation.preroll = 0.5
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.25, location=(-0.8, 0.0, 0.25))
    ball = bpy.context.active_object
    ball.keyframe_insert("location", frame=1)
    ball.location.x = 0.8
    ball.keyframe_insert("location", frame=4)
    coll = bpy.data.collections.new("Colliders")
    scene.collection.children.link(coll)
    for c in list(ball.users_collection):
        c.objects.unlink(ball)
    coll.objects.link(ball)
    item.collider_collection = coll
    bpy.ops.object.camera_add(location=(0.0, -1.8, 0.6), rotation=(1.35, 0.0, 0.0))
    scene.camera = bpy.context.active_object
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.render.resolution_x, scene.render.resolution_y = 48, 27
    scene.render.filepath = str(tmp_path / "farm") + "/"
    path = tmp_path / "live.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def test_a_saved_blend_with_live_grass_renders_on_a_blender_without_windgrass(tmp_path, stand_in, with_bridge):
    """Farm Job on a saved .blend: the worker's Blender (a fresh user folder: no Windgrass) installs
    the bundle's extension in the session's own user folder and renders the four frames in two
    chunks; they equal the frames one process renders, the keyed ball's trail included."""
    blend = _live_blend(tmp_path, with_bridge)
    bundle = tmp_path / "bundle"
    assert bpy.ops.windgrass.farm_job(directory=str(bundle) + "/", chunk_size=2) == {"FINISHED"}
    check = subprocess.run([str(OPENJD), "check", str(bundle / "template.yaml")], capture_output=True, text=True)
    assert check.returncode == 0, check.stdout + check.stderr
    run = _openjd(bundle, stand_in, _env(tmp_path))
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-3000:]
    assert "Entering Environment: Windgrass extension" in run.stdout and "Preferences saved" in run.stdout
    assert run.stdout.count("Windgrass extension 0.") == 2  # each chunk's task has it (none before)
    assert run.stdout.count("farm_render.py: opened") == 1  # the session's one Blender opened the .blend once
    farm_frames = _pixels(tmp_path / "farm")
    assert len(farm_frames) == 4
    # (one process, its frames written as Flamenco's chunker writes a list: issue #36)
    _one_process_renders(stand_in, bundle, blend, "1,2,3-4", tmp_path / "one", _env(tmp_path, tmp_path / "user-one"),
                         farm_frames)
    # run again: every frame kept; the .blend edited (the ball rolls the other way) and submitted
    # again: every frame rendered again (issue #36: the earlier submission's frames were kept)
    again = _openjd(bundle, stand_in, _env(tmp_path))
    assert again.returncode == 0 and again.stdout.count("(already rendered)") == 4, again.stdout[-3000:]
    ball = bpy.data.objects["Sphere"]
    ball.animation_data.action = None
    ball.location.x = 0.5
    bpy.ops.wm.save_mainfile()
    assert bpy.ops.windgrass.farm_job(directory=str(bundle) + "/", chunk_size=2) == {"FINISHED"}
    edited = _openjd(bundle, stand_in, _env(tmp_path))
    assert edited.returncode == 0 and "already rendered" not in edited.stdout, edited.stdout[-3000:]
    assert edited.stdout.count("Saved: '") - edited.stdout.count(".partial") == 4


def _one_process_renders(blender: Path, bundle: Path, blend: Path, frames: str, one: Path, env: dict,
                         farm_frames: dict) -> None:
    """``blender`` with the bundle's extension installed (in ``env``'s user folder) renders the
    .blend's ``frames`` in one process: the same pixels as ``farm_frames``."""
    for command in (["--command", "extension", "install-file", "--repo", "user_default", "--enable",
                     str(next(bundle.glob("windgrass-*.zip")))],
                    ["-b", str(blend), "-P", str(bundle / "farm_render.py"), "--", "--frames", frames, "--out",
                     str(one)]):
        proc = subprocess.run([str(blender), *command], capture_output=True, text=True, env=env, timeout=900)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    one_frames = _pixels(one)
    assert list(one_frames) == list(farm_frames)
    for name in one_frames:
        assert np.array_equal(one_frames[name], farm_frames[name]), name


def test_farm_job_into_the_blends_own_folder_writes_a_folder_of_its_own(tmp_path, with_bridge):
    """Issue #37 item 5: the file browser falls back to the .blend's folder when the suggested
    bundle folder does not exist yet, and the bundle's files were strewn beside the .blend; they
    go into <name>_farm_job/ there, and the report names it."""
    blend = _live_blend(tmp_path, with_bridge)
    before = {p.name for p in tmp_path.iterdir()}
    bpy.ops.windgrass.farm_job(directory=str(tmp_path) + "/", chunk_size=2)
    # (and the frames' folder, the scene's output path: made ready for the workers)
    assert {p.name for p in tmp_path.iterdir()} - before == {"live_farm_job", "farm"}
    assert (tmp_path / "live_farm_job" / "template.yaml").is_file() and blend.is_file()


def test_farm_job_into_the_artists_project_folder_is_refused_and_deletes_nothing(tmp_path, with_bridge):
    """Issue #57: with the bundle folder set to a folder holding the .blend's project (notes,
    textures), Farm Job... failed with a traceback and the artist's files and the saved .blend were
    gone; into a folder holding other files it succeeded and deleted them. Both are refused with a
    sentence, every file as it was; a file the .blend uses from outside its folder is refused, named,
    unless Allow Outside Files is on."""
    blend = _live_blend(tmp_path, with_bridge)
    project = tmp_path / "project"
    (project / "textures").mkdir(parents=True)
    (project / "notes.txt").write_text("shot 12: wind from the west")
    (project / "textures" / "bark.png").write_bytes(b"\x89PNG bark")
    (project / "scene").mkdir()
    shutil.copy2(blend, project / "scene" / blend.name)
    before = _tree(project)
    for folder in (project, project / "scene"):
        with pytest.raises(RuntimeError, match="not written by farm.py"):
            bpy.ops.windgrass.farm_job(directory=str(folder) + "/", chunk_size=2)
    assert _tree(project) == before and blend.is_file()
    from PIL import Image

    Image.fromarray(np.zeros((4, 4), np.uint8)).save(tmp_path.parent / f"{tmp_path.name}-outside.png")
    image = bpy.data.images.load(str(tmp_path.parent / f"{tmp_path.name}-outside.png"))
    image.use_fake_user = True
    bpy.ops.wm.save_mainfile()
    with pytest.raises(RuntimeError, match="from outside its folder"):
        bpy.ops.windgrass.farm_job(directory=str(tmp_path / "bundle") + "/", chunk_size=2)
    assert not (tmp_path / "bundle" / "template.yaml").exists()
    assert bpy.ops.windgrass.farm_job(directory=str(tmp_path / "bundle") + "/", chunk_size=2,
                                      allow_outside=True) == {"FINISHED"}
    references = json.loads((tmp_path / "bundle" / "asset_references.yaml").read_text())
    outside = str((tmp_path.parent / f"{tmp_path.name}-outside.png").resolve())
    assert references["assetReferences"]["inputs"]["filenames"] == [outside]


def test_farm_job_refuses_an_unsaved_or_modified_file(tmp_path, with_bridge):
    with pytest.raises(RuntimeError, match="not saved"):
        bpy.ops.windgrass.farm_job(directory=str(tmp_path / "b") + "/")
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "x.blend"))
    bpy.ops.mesh.primitive_cube_add()
    with pytest.raises(RuntimeError, match="unsaved changes"):
        bpy.ops.windgrass.farm_job(directory=str(tmp_path / "b") + "/")


def test_a_task_on_a_blender_without_windgrass_fails_with_a_sentence_and_writes_nothing(tmp_path, stand_in,
                                                                                         with_bridge):
    """Issue #36 item 5: a .blend task on a worker without the extension (its zip missing or not
    installed) rendered frames without grass and exited 0 on Blender 5.x (the live-grass check
    read ``scene.get("windgrass")``, which 5.0 no longer answers)."""
    blend = _live_blend(tmp_path, with_bridge)
    out = tmp_path / "frames"
    proc = subprocess.run([str(stand_in), "-b", str(blend), "-P", str(REPO / "grass_addon" / "bridge" /
                                                                       "farm_render.py"),
                           "--", "--frames", "1-2", "--out", str(out)], capture_output=True, text=True,
                          env=_env(tmp_path, tmp_path / "user-without-windgrass"), timeout=300)
    assert proc.returncode == 1 and "has live grass fields but Blender has no Windgrass" in proc.stderr, \
        proc.stdout[-2000:] + proc.stderr[-2000:]
    assert not out.exists() or not list(out.glob("*.png"))


def test_a_blends_task_refuses_frames_outside_the_scene_and_lists_too_long(tmp_path, stand_in, with_bridge):
    """Issue #57: farm_render.py --frames rendered frame 0 and frames past the scene's end, and
    1-100000000 grew to 3 GB before it was killed. Each is a sentence naming the range or the
    limit, at once, and no frame is written."""
    blend = _live_blend(tmp_path, with_bridge)  # (frames 1-4)
    out = tmp_path / "frames"
    for frames, words in (("0", "outside the scene's frames 1-4"), ("3-5", "frame 5 is outside the scene's frames"),
                          ("1-100000000", "at most 100,000")):
        proc = subprocess.run([str(stand_in), "-b", str(blend), "-P", str(REPO / "grass_addon" / "bridge" /
                                                                           "farm_render.py"),
                               "--", "--frames", frames, "--out", str(out)], capture_output=True, text=True,
                              env=_env(tmp_path, tmp_path / "user"), timeout=120)
        assert proc.returncode == 1 and words in proc.stderr, proc.stdout[-2000:] + proc.stderr[-2000:]
        assert "Traceback" not in proc.stderr and not list(out.glob("*.png"))


def test_the_wrong_extension_version_is_a_sentence(tmp_path, stand_in, with_bridge):
    """A worker whose Windgrass is another version than the job's: the task fails with a sentence."""
    blend = _live_blend(tmp_path, with_bridge)
    script = REPO / "grass_addon" / "bridge" / "farm_render.py"
    code = textwrap.dedent(f"""
        import sys, runpy, bpy
        sys.path.insert(0, {str(REPO / 'headless')!r})
        import addon_loader
        addon_loader.load_addon()
        bpy.ops.wm.open_mainfile(filepath={str(blend)!r})
        sys.argv = ["farm_render.py", "--frames", "1-1", "--out", {str(tmp_path / 'x')!r}, "--version", "9.9.9"]
        runpy.run_path({str(script)!r}, run_name="__main__")
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_env(tmp_path),
                          timeout=300)
    assert proc.returncode == 1 and "the job was made with 9.9.9" in proc.stderr, proc.stderr[-2000:]


DEADLINE_OFFLINE = Path(__file__).with_name("deadline_offline.py")
FARM_ID, QUEUE_ID = "farm-" + "0" * 32, "queue-" + "1" * 32


def _deadline_submit(bundle: Path, tmp_path: Path) -> tuple[subprocess.CompletedProcess, dict, list[str]]:
    """``deadline bundle submit BUNDLE --yes`` by Deadline Cloud's own client (its AWS calls
    answered offline, ``deadline_offline.py``), saved as a debug snapshot: the run, the parameters
    it would create the job with and the files its job attachments would upload (bundle-relative)."""
    import json

    snapshot = tmp_path / f"snapshot-{bundle.name}"
    env = dict(_env(tmp_path), DEADLINE_CLOUD_TELEMETRY_OPT_OUT="true")
    run = subprocess.run([sys.executable, str(DEADLINE_OFFLINE), "bundle", "submit", str(bundle), "--yes",
                          "--farm-id", FARM_ID, "--queue-id", QUEUE_ID, "--save-debug-snapshot", str(snapshot)],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    if run.returncode != 0:
        return run, {}, []
    parameters = json.loads((snapshot / "parameters_param.json").read_text())
    files = [p["path"] for manifest in (snapshot / "Manifests").rglob("*_input")
             for p in json.loads(manifest.read_text())["paths"]]
    return run, parameters, files


def test_deadline_clouds_client_submits_both_bundles_with_yes_and_attaches_their_inputs(tmp_path, with_bridge):
    """Issue #36 item 3: ``deadline bundle submit BUNDLE --yes`` was cancelled ("there were unknown
    paths": the scene file, the .blend and the output folder lay outside the bundle) and a paint map
    beside the scene file was not attached. Both bundles now carry their inputs: the client accepts
    them without asking, and its attachments hold the scene with its paint map (the same bytes), and
    the .blend with the image it paints with, at the place the .blend's relative path names."""
    from PIL import Image

    maps = tmp_path / "maps"
    maps.mkdir()
    Image.fromarray(np.tile(np.linspace(0, 255, 32, dtype=np.uint8), (32, 1))).save(maps / "paths.png")
    config = tmp_path / "tiny.toml"
    config.write_text(TINY + '[paint]\ndensity = "maps/paths.png"\n')
    scene_bundle = tmp_path / "scene-bundle"
    made = subprocess.run([sys.executable, str(REPO / "headless" / "farm.py"), "--config", str(config), "--out",
                           str(tmp_path / "frames"), "--chunk", "2", str(scene_bundle)],
                          capture_output=True, text=True, env=_env(tmp_path), timeout=300)
    assert made.returncode == 0, made.stderr
    run, parameters, files = _deadline_submit(scene_bundle, tmp_path)
    assert run.returncode == 0 and "canceled" not in run.stdout.lower(), run.stdout[-3000:] + run.stderr[-2000:]
    scene = Path(parameters["SceneFile"]["path"])
    assert scene.parent.parent == scene_bundle / "windgrass" and scene.is_file()
    carried = [f for f in files if f.startswith("windgrass/scene/maps/")]
    assert len(carried) == 1 and f"windgrass/scene/{scene.name}" in files
    assert (scene_bundle / carried[0]).read_bytes() == (maps / "paths.png").read_bytes()
    assert f'density = "{carried[0].removeprefix("windgrass/scene/")}"' in scene.read_text()
    assert parameters["OutputDir"]["path"] == str(scene_bundle / "output")

    _live_blend(tmp_path, with_bridge)
    image = bpy.data.images.load(str(maps / "paths.png"))
    image.filepath, image.use_fake_user = "//maps/paths.png", True
    from windgrass.grass_addon.bridge import properties

    item = bpy.context.scene.windgrass.fields[-1]
    with properties.batch(item):  # (applied at once, as the Farm Job's saved-file check wants)
        item.paint.density = f"image:{image.name}"
    bpy.ops.wm.save_mainfile()  # (the ground's material takes the image as the save's refill writes it: no edit)
    blend_bundle = tmp_path / "blend-bundle"
    assert bpy.ops.windgrass.farm_job(directory=str(blend_bundle) + "/", chunk_size=2) == {"FINISHED"}
    run, parameters, files = _deadline_submit(blend_bundle, tmp_path)
    assert run.returncode == 0 and "canceled" not in run.stdout.lower(), run.stdout[-3000:] + run.stderr[-2000:]
    assert Path(parameters["BlendFile"]["path"]) == blend_bundle / "scene" / "live.blend"
    assert {"scene/live.blend", "scene/maps/paths.png", "farm_render.py"} <= set(files)
    assert any(f.startswith("windgrass-") and f.endswith(".zip") for f in files)


# -- the real Blender 5.2 LTS binary as the workers' Blender (issue #35 item 4) ------------------------
# Debian's Blender 5.2.2 in the root the window tests use (tests/window/conftest.py; made by dev.py),
# reached through chroot: the job's folders lie inside the root, and the worker's command passes their
# paths as Blender there sees them. The runs beside compare it with are the same binary's.

WORKER = '''#!{python}
"""The workers' {program}: Debian's, in {root} (Blender 5.2 LTS), through chroot."""
import os, subprocess, sys
ROOT, BLENDER = {root!r}, {blender!r}
def inside(s):
    return "blender" if s == BLENDER else s.replace(ROOT + "/", "/")  # (the session starts the Blender)
env = {{"PATH": "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin", "LANG": "C.UTF-8"}}
env.update({{k: inside(os.environ[k]) for k in ("HOME", "BLENDER_USER_RESOURCES", "TMPDIR", "PYTHONUNBUFFERED")
            if k in os.environ}})
sys.exit(subprocess.run(["chroot", ROOT, {program!r}, *map(inside, sys.argv[1:])], env=env).returncode)
'''


@pytest.fixture
def real_worker(tmp_path):
    """(the worker's command, a folder inside the root for the job's files); skipped, saying why,
    where this machine has no root with Blender (or is not root: chroot needs it)."""
    import pwd
    import shutil
    import tempfile

    default = Path(pwd.getpwuid(os.getuid()).pw_dir) / ".cache" / "windgrass" / "sid"
    root = Path(os.environ.get("WINDGRASS_WINDOW_ROOT", default))
    if os.geteuid() != 0 or not (root / "usr" / "bin" / "blender").exists():
        pytest.skip(f"no Debian root with Blender 5.2 at {root} (python3.11 dev.py test makes one; chroot needs root)")
    work = Path(tempfile.mkdtemp(prefix="windgrass-farm-", dir=root / "tmp"))
    for name in ("home", "tmp", "bin"):
        (work / name).mkdir()
    worker = tmp_path / "blender-5.2"
    for path, program in ((worker, "blender"), (work / "bin" / "python3", "python3")):  # (python3: a hand-over)
        path.write_text(WORKER.format(python=sys.executable, root=str(root), blender=str(worker), program=program))
        path.chmod(0o755)
    try:
        version = subprocess.run([str(worker), "--version"], capture_output=True, text=True, timeout=120).stdout
        assert version.startswith("Blender 5.2."), version
        yield worker, work
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _worker_env(work: Path, user: Path | None = None) -> dict:
    """The environment of ``openjd run`` and the worker: home, temp (openjd's session folders) and
    Blender's user folder inside the root; the root's python3 first on the PATH."""
    env = dict(_env(work, user), TMPDIR=str(work / "tmp"))
    return dict(env, PATH=os.pathsep.join([str(work / "bin"), env.get("PATH", "")]))


def test_workers_on_real_blender_5_2_render_a_scene_file_job_as_one_process_does(real_worker):
    """A scene file's job in chunks of 2 under ``openjd run`` with Blender 5.2.2 as the workers'
    Blender, the tasks handed to the session's Blender by the worker's python3: its frames equal,
    pixel for pixel, the frames that Blender renders in one process."""
    worker, work = real_worker
    scene = work / "tiny.toml"
    scene.write_text(TINY)
    bundle, out, one = work / "bundle", work / "farm", work / "one"
    env = _worker_env(work)
    made = subprocess.run([sys.executable, str(REPO / "headless" / "farm.py"), "--config", str(scene), "--frames",
                           "1-6", "--chunk", "2", "--blender-version", "5.2", "--hand-over", "python3", "--out",
                           str(out), str(bundle)], capture_output=True, text=True, env=env, timeout=300)
    assert made.returncode == 0, made.stderr
    run = _openjd(bundle, worker, env)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert "Chunks run: 3" in run.stdout and run.stdout.count("scene kept from the session's") == 2
    assert '"command": "python3"' in (bundle / "template.yaml").read_text()
    _ended(run.stdout)
    single = subprocess.run([str(worker), "-b", "-P", str(bundle / "windgrass" / "headless" / "render_field.py"),
                             "--", "--config", str(scene), "--frames", "1-6", "--out", str(one)],
                            capture_output=True, text=True, env=env, timeout=600)
    assert single.returncode == 0, single.stdout[-3000:] + single.stderr[-3000:]
    farm_frames, one_frames = _pixels(out), _pixels(one)
    assert list(farm_frames) == [f"frame_{i:04d}.png" for i in range(1, 7)] == list(one_frames)
    for name in farm_frames:
        assert np.array_equal(farm_frames[name], one_frames[name]), name
    # grass in them: below the horizon the frames are green (their mean green a fifth over their red)
    lower = np.stack(list(farm_frames.values()))[:, 14:, :, :3].reshape(-1, 3).mean(axis=0)
    assert lower[1] > 1.2 * lower[0] and lower[1] > 1.2 * lower[2], lower


def test_workers_on_real_blender_5_2_without_windgrass_render_a_saved_blends_job(real_worker, with_bridge):
    """The .blend (saved by this Blender) on workers whose Blender has never seen Windgrass: the
    session installs the bundle's extension, the chunks' frames equal one process's (the same
    binary with the extension installed); without it the task refuses with a sentence."""
    worker, work = real_worker
    blend = _live_blend(work, with_bridge)
    bundle = work / "bundle"
    assert bpy.ops.windgrass.farm_job(directory=str(bundle) + "/", chunk_size=2) == {"FINISHED"}
    run = _openjd(bundle, worker, _worker_env(work))
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-3000:]
    assert "Entering Environment: Windgrass extension" in run.stdout
    assert run.stdout.count("farm_render.py: opened") == 1  # one Blender for the session
    farm_frames = _pixels(work / "farm")
    assert len(farm_frames) == 4
    script, one = bundle / "farm_render.py", work / "one"
    bare = subprocess.run([str(worker), "-b", str(blend), "-P", str(script), "--", "--frames", "1-2", "--out",
                           str(one)], capture_output=True, text=True, env=_worker_env(work, work / "bare"), timeout=300)
    assert bare.returncode == 1 and "has live grass fields but Blender has no Windgrass" in bare.stderr, \
        bare.stdout[-2000:] + bare.stderr[-2000:]
    assert not one.exists() or not list(one.glob("*.png"))
    _one_process_renders(worker, bundle, blend, "1-4", one, _worker_env(work, work / "user-one"), farm_frames)


# --------------------------------------------------------------------------------------------
# The worker session's Blender on a shared render node (issue #57): another account can neither
# read its token nor reach it, no message kills it or holds its tasks up, a task trusts only the
# server that proves it is its session's, and ``stop`` ends only the process the session started.
# The session's Blender is the bpy module behind the stand-in; the attacks run as the account
# ``nobody`` (the machine's Python, outside this one's home) where the tests run as root, and are
# skipped, saying so, elsewhere.

SESSION = REPO / "grass_addon" / "bridge" / "farm_session.py"
AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
OTHER = "nobody"

TASK = '''
import sys
from pathlib import Path

def session_task(argv):
    Path(argv[0]).write_text("by the session")
    print("task ran in the session", argv[1:])
    return 0

if __name__ == "__main__":  # (a Blender of the task's own)
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    Path(argv[0]).write_text("by its own Blender")
    print("task ran in its own Blender")
'''


@pytest.fixture
def node():
    """A session folder as a render node may have one: under /tmp, open for others to look into
    (mode 0755, as the session folders of some runtimes are), with a stand-in Blender and a task."""
    top = Path(tempfile.mkdtemp(prefix="wg-node-", dir="/tmp"))
    top.chmod(0o755)
    (top / "blender").write_text(STAND_IN.format(python=sys.executable))
    (top / "blender").chmod(0o755)
    (top / "task.py").write_text(TASK)
    session = top / "session"
    session.mkdir()
    session.chmod(0o755)
    yield top
    subprocess.run([sys.executable, str(SESSION), "stop", "--dir", str(session)], capture_output=True, timeout=60)
    shutil.rmtree(top, ignore_errors=True)


def _session(node: Path, action: str, *task: str, timeout=300) -> subprocess.CompletedProcess:
    extra = ["--script", str(node / "task.py"), "--", *task] if action == "run" else []
    return subprocess.run([sys.executable, str(SESSION), action, "--dir", str(node / "session"),
                           "--blender", str(node / "blender"), *extra], capture_output=True, text=True,
                          env=_env(node), timeout=timeout)


def _started(node: Path) -> dict:
    proc = _session(node, "start")
    assert proc.returncode == 0 and "one Blender (pid" in proc.stdout, proc.stdout + proc.stderr
    return json.loads((node / "session" / ".windgrass-session" / "session.json").read_text())


def _as_other(code: str) -> dict:
    """Run ``code`` (it prints one JSON line) as the account ``nobody``; its result."""
    proc = subprocess.run(["/usr/bin/python3", "-c", textwrap.dedent(code)], user=OTHER, capture_output=True,
                          text=True, timeout=60, cwd="/")
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}/stat").is_file() and " Z " not in Path(f"/proc/{pid}/stat").read_text()


def _tcp_listeners(pid: int) -> list[str]:
    """The TCP sockets process ``pid`` listens on (state 0A in /proc/net/tcp and tcp6)."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    rows = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            cols = line.split()
            if cols[3] == "0A" and cols[9] in inodes:
                rows.append(cols[1])
    return rows


needs_root = pytest.mark.skipif(not AS_ROOT, reason="the attacks run as another account: the tests need root")


@needs_root
def test_another_account_can_neither_read_the_token_nor_reach_the_server(node):
    """Issue #57: the address file with the token was 0644 in a 0755 folder, the server a TCP port
    any account could see (ss -ltn) and connect to; nobody read the token and had the session's
    Blender run its own script, as root."""
    session = _started(node)
    private = node / "session" / ".windgrass-session"
    assert stat.S_IMODE(private.stat().st_mode) == 0o700
    assert stat.S_IMODE((private / "session.json").stat().st_mode) == 0o600
    assert stat.S_IMODE(os.stat(session["socket"]).st_mode) & 0o077 == 0
    assert _tcp_listeners(session["pid"]) == []  # (no port at all: a Unix socket)
    planted = node / "planted"
    attack = f"""
        import json, socket
        out = {{}}
        try:
            open({str(private / "session.json")!r}).read(); out["read"] = "read"
        except OSError as exc:
            out["read"] = type(exc).__name__
        try:
            s = socket.socket(socket.AF_UNIX); s.connect({session["socket"]!r}); out["connect"] = "connected"
        except OSError as exc:
            out["connect"] = type(exc).__name__
        print(json.dumps(out))
    """
    assert _as_other(attack) == {"read": "PermissionError", "connect": "PermissionError"}
    # Even with the folder, the file and the socket opened to all (a careless chmod -R): the token
    # read, a proof made with it, the server still closes another account's connection unanswered.
    private.chmod(0o755)
    (private / "session.json").chmod(0o644)
    os.chmod(session["socket"], 0o666)
    attack = f"""
        import hashlib, hmac, json, socket
        token = json.load(open({str(private / "session.json")!r}))["token"]
        s = socket.socket(socket.AF_UNIX); s.settimeout(20); s.connect({session["socket"]!r})
        first = s.recv(4096)
        try:
            nonce = json.loads(first)["nonce"]
            proof = hmac.new(token.encode(), ("client:" + nonce).encode(), hashlib.sha256).hexdigest()
            s.sendall((json.dumps({{"action": "run", "script": {str(node / "task.py")!r},
                                   "argv": [{str(planted)!r}], "proof": proof, "nonce": "n"}}) + "\\n").encode())
            answer = s.recv(4096)
        except (ValueError, OSError) as exc:
            answer = b""
        print(json.dumps({{"first": first.decode(), "answer": answer.decode()}}))
    """
    assert _as_other(attack) == {"first": "", "answer": ""}
    time.sleep(1.0)
    assert not planted.exists()
    # ... and the job's own tasks no longer trust a folder others can write into: each runs alone
    ran = _session(node, "run", str(node / "own"))
    assert ran.returncode == 0 and (node / "own").read_text() == "by its own Blender", ran.stdout + ran.stderr
    assert _alive(session["pid"])


def _hello(path: str) -> socket.socket:
    conn = socket.socket(socket.AF_UNIX)
    conn.settimeout(30)
    conn.connect(path)
    assert "nonce" in json.loads(conn.recv(4096))
    return conn


def _rss_kb(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError("no VmRSS")


HOSTILE = {
    "a number": b"5\n", "null": b"null\n", "a string": b'"run"\n', "a list": b"[]\n",
    "not JSON": b"{run\n", "not UTF-8": b"\xff\xfe\n", "no proof": b'{"action": "run", "script": "x", "argv": []}\n',
    "a wrong proof": b'{"action": "run", "script": "x", "argv": [], "proof": "00", "nonce": "n"}\n',
    "nested a million deep": b"[" * 500_000 + b"]" * 500_000 + b"\n",
}


def test_no_message_kills_the_server_or_holds_its_tasks_up(node):
    """Issue #57: one idle connection (or half a line) held the server, so every later task hung
    until its timeout killed it; a JSON number, null, a string or a list killed it; 1.5 GB without
    a newline took it from 376 MB to 1.9 GB. Now each is answered or dropped, and a task runs at
    once beside them; the server's memory grows by less than 64 MB."""
    session = _started(node)
    idle = [_hello(session["socket"]) for _ in range(3)]
    idle[1].sendall(b'{"action": "ru')  # (half a line, then silence)
    ran = _session(node, "run", str(node / "first"), "beside", "idle")
    assert ran.returncode == 0 and "task ran in the session ['beside', 'idle']" in ran.stdout, ran.stdout + ran.stderr
    for conn in idle:  # (the task did not wait for them: they are still open, unanswered)
        conn.settimeout(0.05)
        with pytest.raises(socket.timeout):
            conn.recv(1)
    answers = {}
    for name, payload in HOSTILE.items():
        with _hello(session["socket"]) as conn:
            conn.sendall(payload)
            answers[name] = json.loads(conn.recv(65536).decode().splitlines()[0]).get("error", "")
    assert all(answers.values()), answers
    assert "not this session's task" in answers["no proof"] and "not an object" in answers["a list"]
    before = _rss_kb(session["pid"])
    with _hello(session["socket"]) as conn:
        try:
            for _ in range(64):  # 64 MB without a newline: refused after the first megabyte
                conn.sendall(b"x" * (1 << 20))
        except OSError:
            pass  # (the server closed it)
    assert _rss_kb(session["pid"]) - before < 64 * 1024
    for conn in idle:
        conn.close()
    again = _session(node, "run", str(node / "second"), "after", "all")
    assert again.returncode == 0 and (node / "second").read_text() == "by the session", again.stdout + again.stderr
    assert _alive(session["pid"])


@needs_root
def test_a_task_trusts_only_its_own_sessions_server(node):
    """Issue #57: after crashing the server, nobody took its port; the next task connected, its
    script never ran, and it printed the frames' Saved: lines and exited 0. Now nobody cannot
    listen where the session's Blender did, and a server without the token (the job's own user's,
    at the session's address) is not believed: the task renders in a Blender of its own."""
    session = _started(node)
    os.kill(session["pid"], signal.SIGKILL)
    bind = f"""
        import json, os, socket
        path = {session["socket"]!r}
        try:
            os.unlink(path)
        except OSError:
            pass
        try:
            s = socket.socket(socket.AF_UNIX); s.bind(path); out = "bound"
        except OSError as exc:
            out = type(exc).__name__
        print(json.dumps({{"bind": out}}))
    """
    assert _as_other(bind) == {"bind": "PermissionError"}
    gone = _session(node, "run", str(node / "after-kill"))
    assert gone.returncode == 0 and (node / "after-kill").read_text() == "by its own Blender", gone.stdout + gone.stderr
    assert "this task starts its own" in gone.stdout
    # a forger at the address, with the session file put back: it greets, claims success, no proof
    _forged_session(node, session)
    forged = _session(node, "run", str(node / "forged"))
    assert forged.returncode == 0 and (node / "forged").read_text() == "by its own Blender", forged.stdout
    assert "did not prove it is the session's Blender" in forged.stdout and "Saved" not in forged.stdout


def _forged_session(node: Path, session: dict) -> None:
    path = session["socket"]
    if os.path.exists(path):
        os.unlink(path)
    listener = socket.socket(socket.AF_UNIX)
    listener.bind(path)
    listener.listen(1)

    def answer():
        conn, _ = listener.accept()
        conn.sendall(b'{"nonce": "abc"}\n')
        conn.recv(65536)
        conn.sendall(b'{"proof": "forged"}\n{"out": "Saved: \'frame_0001.png\'\\n"}\n{"exit": 0}\n')
        conn.close()
        listener.close()

    threading.Thread(target=answer, daemon=True).start()
    private = node / "session" / ".windgrass-session"
    (private / "session.json").write_text(json.dumps(session))
    (private / "session.json").chmod(0o600)


@pytest.mark.parametrize("case", ["a live stranger's pid", "no socket", "a number", "not JSON", "a file for a socket",
                                  "a silent socket"])
def test_a_stale_or_broken_session_file_is_no_traceback_and_kills_no_stranger(node, case):
    """Issue #57: ``stop`` with a stale address file killed an unrelated live process whose pid it
    named; an address file without its port, or naming another program's port, was a traceback
    with no fallback. Now ``run`` renders in its own Blender and ``stop`` ends nobody else."""
    stranger = subprocess.Popen(["sleep", "120"])
    private = node / "session" / ".windgrass-session"
    private.mkdir(mode=0o700)
    listener = socket.socket(socket.AF_UNIX)
    silent = str(node / "silent.sock")
    listener.bind(silent)
    listener.listen(1)
    (node / "plain").write_text("")
    base = {"socket": str(private / "server.sock"), "token": "0" * 64, "pid": stranger.pid, "stamp": "0:1"}
    text = {"a live stranger's pid": json.dumps(base), "no socket": json.dumps({**base, "socket": None}),
            "a number": "7", "not JSON": "{",
            "a file for a socket": json.dumps({**base, "socket": str(node / "plain")}),
            "a silent socket": json.dumps({**base, "socket": silent})}[case]
    with socket.socket() as closed:  # and the address file an earlier version left: a closed port
        closed.bind(("127.0.0.1", 0))
        legacy = {"port": closed.getsockname()[1], "token": "x", "pid": stranger.pid}
    if case == "no socket":
        del legacy["port"]

    def leave():
        (private / "session.json").write_text(text)
        (private / "session.json").chmod(0o600)
        (node / "session" / "windgrass-session.json").write_text(json.dumps(legacy))

    leave()
    try:
        ran = _session(node, "run", str(node / "own"))
        assert ran.returncode == 0 and (node / "own").read_text() == "by its own Blender", ran.stdout + ran.stderr
        assert "Traceback" not in ran.stdout + ran.stderr
        leave()
        stopped = _session(node, "stop")
        assert stopped.returncode == 0 and "Traceback" not in stopped.stderr, stopped.stderr
        assert stranger.poll() is None, "stop killed a process the session did not start"
    finally:
        stranger.kill()
        stranger.wait()
        listener.close()

"""The Flamenco job type (grass_addon/windgrass_flamenco.js) compiled under Node against Flamenco's
documented job-compiler API: ``author.Task(name, type)``, ``author.Command(type, parameters)``,
``task.addCommand``, ``job.addTask``, ``frameChunker(frames, chunkSize)`` (ranges 'A-B' of at most
chunkSize frames, in order) and ``path``. No Flamenco Manager runs here (none can be installed
from the package registries): this checks what the compiler hands to one."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest
from windgrass.grass_addon import farm

REPO = Path(__file__).resolve().parents[2]
NODE = shutil.which("node") or shutil.which("nodejs")

HARNESS = r"""
const fs = require("fs");
const path = require("path");
const tasks = [];
const author = {
  Task: (name, type) => { const t = {name, type, commands: [], addCommand(c) { this.commands.push(c); }}; return t; },
  Command: (type, parameters) => ({type, parameters}),
};
function print() {}
function frameChunker(frames, chunkSize) {
  // What Flamenco's chunker hands tasks (seen from its own job compiler, issue #36): the frames of
  // "1-10,20-25" in order, chunkSize at a time, each chunk written as its runs: "1-4" for a run of
  // three or more, "5,6" for a run of two, "9,10,20,21" across a gap
  const all = [];
  for (const part of String(frames).split(",")) {
    const [a, b] = part.trim().split("-").map(Number);
    for (let f = a; f <= (b === undefined ? a : b); f++) all.push(f);
  }
  const out = [];
  for (let i = 0; i < all.length; i += chunkSize) {
    const chunk = all.slice(i, i + chunkSize), runs = [];
    for (const f of chunk) {
      const run = runs[runs.length - 1];
      if (run && f === run[1] + 1) run[1] = f; else runs.push([f, f]);
    }
    out.push(runs.map(([s, e]) => e - s >= 2 ? `${s}-${e}` : e > s ? `${s},${e}` : `${s}`).join(","));
  }
  return out;
}
const load = new Function("author", "frameChunker", "path", "print",
                          fs.readFileSync(process.argv[2], "utf8") + "\nreturn {JOB_TYPE, compileJob};");
const {JOB_TYPE, compileJob} = load(author, frameChunker, path, print);
const job = {settings: JSON.parse(process.argv[3]), addTask(t) { tasks.push(t); }};
try {
  compileJob(job);
  console.log(JSON.stringify({types: JOB_TYPE.settings.map(s => s.key), tasks}));
} catch (e) {
  console.log(JSON.stringify({error: String(e)}));
}
"""


def _compile(tmp_path, **settings) -> dict:
    harness = tmp_path / "harness.js"
    harness.write_text(HARNESS)
    base = {"kind": "blend", "blendfile": "/shots/meadow.blend", "windgrass_dir": "/farm/windgrass",
            "extension_zip": "/farm/windgrass/windgrass-0.2.0.zip", "version": "0.2.0", "frames": "1-30",
            "chunk_size": 4, "render_output_root": "/renders/meadow"}
    base.update(settings)
    proc = subprocess.run([NODE, str(harness), str(REPO / "grass_addon" / "windgrass_flamenco.js"),
                           json.dumps(base)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def _frames(chunk: str) -> list[int]:
    """A task's frames as render_field.py and farm_render.py read them."""
    return list(farm.parse_frames(chunk, -10**6, 10**6))


pytestmark = [pytest.mark.skipif(NODE is None, reason="Node is not installed (Debian: apt-get install nodejs)"),
              pytest.mark.slow]  # (each test starts Node: dev.py test --quick leaves them out)


@pytest.mark.parametrize("frames", ["1-30", "7-7", "10-17", "9-10,20-21", "1-3,7,9-12"])
@pytest.mark.parametrize("chunk", [1, 2, 3, 4, 7, 100])
@pytest.mark.parametrize("kind", ["blend", "scene_file"])
def test_tasks_cover_the_frame_range_exactly_once(tmp_path, frames, chunk, kind):
    result = _compile(tmp_path, kind=kind, frames=frames, chunk_size=chunk, scene_file="/shots/meadow.toml")
    covered = []
    for task in result["tasks"]:
        (command,) = task["commands"]
        args = command["parameters"]["args"]
        chunk_text = args[args.index("--frames") + 1]
        assert task["name"] == f"render-{chunk_text}" and len(_frames(chunk_text)) <= chunk
        covered += _frames(chunk_text)
        assert args[args.index("--out") + 1] == "/renders/meadow"
        if kind == "scene_file":
            assert command["type"] == "exec" and command["parameters"]["exe"] == "{blender}"
            assert args[:3] == ["-b", "-P", "/farm/windgrass/headless/render_field.py"] and "--resume" in args
            assert args[args.index("--config") + 1] == "/shots/meadow.toml"
        else:
            assert command["type"] == "blender-render" and command["parameters"]["blendfile"] == "/shots/meadow.blend"
            assert args[:2] == ["--python", "/farm/windgrass/farm_render.py"]
            assert args[args.index("--version") + 1] == "0.2.0"
    assert covered == _frames(frames)  # each frame once, in order


@pytest.mark.parametrize("settings, words", [
    ({"chunk_size": 0}, "at least 1"),
    ({"kind": "scene_file"}, "needs the scene file"),
    ({"blendfile": ""}, "needs the saved .blend"),
    ({"kind": "movie"}, 'valid: "blend" or "scene_file"'),
])
def test_bad_settings_are_a_sentence(tmp_path, settings, words):
    assert words in _compile(tmp_path, **settings)["error"]


def test_the_job_type_offers_what_the_compiler_reads(tmp_path):
    keys = set(_compile(tmp_path)["types"])
    assert {"kind", "blendfile", "scene_file", "windgrass_dir", "extension_zip", "version", "frames", "chunk_size",
            "render_output_root"} <= keys


def test_the_extension_a_bundle_carries_is_its_tracked_files_without_hidden_files_or_links(tmp_path):
    """Issue #57: farm.py ignored the manifest's exclude list, so a checkout's .env, swap files,
    .blend1 and a link to a credentials file (copied as its content) went into the bundle that
    deadline bundle submit uploads. Only files git tracks, none hidden, none a link, none the
    manifest leaves out."""
    root = tmp_path / "checkout"
    manifest = (REPO / "blender_manifest.toml").read_text()
    files = {"blender_manifest.toml": manifest, "__init__.py": "", "grass_addon/engine.py": "",
             "grass_addon/.env": "AWS_SECRET=1", "grass_addon/.engine.py.swp": "swap", "grass_addon/old.blend1": "b",
             "grass_addon/untracked.py": "", "operators/op.py": "", "panels/__pycache__/p.cpython-313.pyc": "",
             "panels/p.py": ""}
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    secret = tmp_path / "credentials"
    secret.write_text("[default]\n")
    (root / "grass_addon" / "keys.py").symlink_to(secret)
    subprocess.run(["git", "init", "-q", str(root)], check=True)
    tracked = [n for n in files if n != "grass_addon/untracked.py"] + ["grass_addon/keys.py"]
    subprocess.run(["git", "-C", str(root), "add", "-f", *tracked], check=True)
    names = sorted(name for _, name in farm.extension_files(root))
    assert names == ["__init__.py", "blender_manifest.toml", "grass_addon/engine.py", "operators/op.py", "panels/p.py"]
    shutil.rmtree(root / ".git")  # (an installed extension: no checkout, the same rules without git's list)
    names = sorted(name for _, name in farm.extension_files(root))
    assert names == ["__init__.py", "blender_manifest.toml", "grass_addon/engine.py", "grass_addon/untracked.py",
                     "operators/op.py", "panels/p.py"]


def test_a_bundle_written_again_never_writes_through_a_link_planted_in_it(tmp_path):
    """Issue #57: a bundle deletes and replaces only its own files. A link planted where one of its
    folders was (windgrass/ pointing elsewhere) is a sentence, and nothing is written through it."""
    from windgrass.grass_addon.errors import ParameterError

    with farm.Bundle(tmp_path / "bundle", "bundle") as job:
        job.path("windgrass/headless/render_field.py").write_text("# the bundle's")
        job.path("template.yaml").write_text("{}")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    shutil.rmtree(tmp_path / "bundle" / "windgrass")
    (tmp_path / "bundle" / "windgrass").symlink_to(elsewhere)
    with pytest.raises(ParameterError, match="is not a folder the bundle wrote"):
        with farm.Bundle(tmp_path / "bundle", "bundle") as job:
            job.path("windgrass/headless/render_field.py").write_text("# again")
            job.path("template.yaml").write_text("{}")
    assert not any(elsewhere.iterdir()) and (tmp_path / "bundle" / "template.yaml").read_text() == "{}"
    assert [p.name for p in (tmp_path / "bundle").iterdir() if p.name.startswith(".windgrass-staging")] == []

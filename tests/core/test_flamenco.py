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
function frameChunker(frames, chunkSize) {  // Flamenco's: "A-B" (or "A") chunks of at most chunkSize frames
  const out = [];
  for (const part of String(frames).split(",")) {
    const [a, b] = part.trim().split("-").map(Number);
    const last = Number.isNaN(b) ? a : b;
    for (let s = a; s <= last; s += chunkSize) {
      const e = Math.min(s + chunkSize - 1, last);
      out.push(s === e ? `${s}` : `${s}-${e}`);
    }
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
    a, _, b = chunk.partition("-")
    return list(range(int(a), int(b or a) + 1))


pytestmark = [pytest.mark.skipif(NODE is None, reason="Node is not installed (Debian: apt-get install nodejs)"),
              pytest.mark.slow]  # (each test starts Node: dev.py test --quick leaves them out)


@pytest.mark.parametrize("frames", ["1-30", "7-7", "10-17"])
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
    a, _, b = frames.partition("-")
    assert covered == list(range(int(a), int(b) + 1))


@pytest.mark.parametrize("settings, words", [
    ({"chunk_size": 0}, "at least 1"),
    ({"kind": "scene_file"}, "needs the scene file"),
    ({"blendfile": ""}, "needs the saved .blend"),
])
def test_bad_settings_are_a_sentence(tmp_path, settings, words):
    assert words in _compile(tmp_path, **settings)["error"]


def test_the_job_type_offers_what_the_compiler_reads(tmp_path):
    keys = set(_compile(tmp_path)["types"])
    assert {"kind", "blendfile", "scene_file", "windgrass_dir", "extension_zip", "version", "frames", "chunk_size",
            "render_output_root"} <= keys

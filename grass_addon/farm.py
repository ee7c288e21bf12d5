"""Render-farm jobs (no bpy): Open Job Description bundles and a Flamenco job type.

A Windgrass frame is a function of the frame number, so frames can be split between machines in
any chunks and come out pixel for pixel as one process renders them. Two kinds of job:

* **a scene file** (``scene_bundle``): each task runs ``render_field.py --config SCENE --frames A-B
  --out DIR --resume`` with the Windgrass scripts carried in the bundle (``windgrass/``);
* **a saved .blend with live grass** (``blend_bundle``): the worker's Blender has never seen
  Windgrass, so a step environment installs the extension zip carried in the bundle into a
  user folder inside the session's working directory (``BLENDER_USER_RESOURCES``; Blender's
  ``--command extension install-file``), and each task renders its frames with
  ``farm_render.py`` (carried too). A baked .blend needs no extension.

A worker's session keeps one Blender (``bridge/farm_session.py``, started and ended by the step's
"Windgrass session" environment): each task hands it its script and arguments, so the scene is
built (or the .blend opened) once a session, not once a task; a task without it starts its own.

Chunks use OpenJD's ``TASK_CHUNKING`` extension: a ``CHUNK[INT]`` task parameter over the frame
range with contiguous chunks gives ``1-4``, ``5-8``: exactly ``--frames A-B``. The template and its
parameter values are written as JSON, which is YAML too (``template.yaml``,
``parameter_values.yaml``), so the same folder runs under ``openjd run`` and submits unchanged to
AWS Deadline Cloud (``deadline bundle submit DIR``). Every task prints Blender's
``Saved: '<path>'`` line for each frame, skips frames already complete on disk (a rerun redoes only
what is missing) and exits non-zero with its message when it fails.
"""

from __future__ import annotations

import fnmatch
import hashlib
import json
import os
import re
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

from .errors import ParameterError

SPECIFICATION = "jobtemplate-2023-09"
FLAMENCO_JOB_TYPE = Path(__file__).with_name("windgrass_flamenco.js")  # (shipped with the add-on)


MAX_FRAMES_TEXT = 65536  # characters of a frame list (Flamenco's and OpenJD's chunks are short)
MAX_JOB_FRAMES = 100_000  # frames of one job: over an hour at 24 fps (1-100000000 grew to 3 GB)
_FRAMES = re.compile(r"\s*(-?\d{1,9})\s*(?:-\s*(-?\d{1,9})\s*)?")  # (frames have at most 7 digits)


def parse_frames(text: str, first: int, last: int) -> tuple[int, ...]:
    """The frames of 'A-B', 'N' or a list of them ('5,6', '9,10,20,21', '1-4,8': what Flamenco's
    chunker and OpenJD's range expressions give a task), in order, each once, within the scene's
    ``first``..``last``; ParameterError otherwise."""
    valid = "'A-B', one frame number or a list of them (e.g. 1-48, 12 or 9,10,20-21)"
    text = str(text)
    if len(text) > MAX_FRAMES_TEXT:
        raise ParameterError("frames", f"a list of {len(text):,} characters (valid: at most {MAX_FRAMES_TEXT:,}: "
                             f"{valid})")
    spans = []
    for part in text.split(","):
        match = _FRAMES.fullmatch(part)
        if not match:
            raise ParameterError("frames", f"{text!r} is not {valid}")
        a = int(match.group(1))
        b = int(match.group(2)) if match.group(2) is not None else a
        if b < a:
            raise ParameterError("frames", f"{text!r}: {part.strip()} ends before it starts (valid: A-B with A <= B)")
        if a < first or b > last:
            raise ParameterError("frames", f"{text!r} is outside the scene's frames {first}-{last} (valid: frames "
                                 "within them)")
        spans.append((a, b))
    count = sum(b - a + 1 for a, b in spans)  # (an upper bound, counted before any frame is listed)
    if count > MAX_JOB_FRAMES:
        raise ParameterError("frames", f"{text[:40]!r} names {count:,} frames (valid: at most {MAX_JOB_FRAMES:,} "
                             "in one job or task)")
    return tuple(sorted({f for a, b in spans for f in range(a, b + 1)}))


def frames_text(frames) -> str:
    """'1-4,8' for frames (1, 2, 3, 4, 8): runs of consecutive frames as A-B."""
    runs: list[list[int]] = []
    for f in frames:
        if runs and f == runs[-1][1] + 1:
            runs[-1][1] = f
        else:
            runs.append([f, f])
    return ",".join(f"{a}-{b}" if b > a else f"{a}" for a, b in runs)


def other_blender(wanted: str, version) -> str | None:
    """The sentence for a worker whose Blender is not the job's line ``wanted`` ('5.2'; '' takes
    any), else None: two lines render the same frame a little differently (18/255 on average between
    4.3 and 5.0), so a job's frames come from one."""
    here = f"{version[0]}.{version[1]}"
    if not wanted or wanted == here:
        return None
    return (f"this worker runs Blender {here}, the job's frames are made with Blender {wanted}: give the job that "
            f"Blender (BlenderExecutable), or set BlenderVersion to '' to let any Blender render them")




def frame_fingerprint(frame: int, settings: str, inputs: Sequence[bytes], blender: str, windgrass: str) -> str:
    """What makes a frame this job's (issue #36: ``--resume`` kept the frames of an earlier, edited
    submission): a hash of the frame's number, the scene's settings (TOML), the bytes of the files
    it reads (maps, heightmap, the .blend), the Blender (its version) and Windgrass's version.
    Written into each frame (``farm_frames.FRAME_KEY``); a rerun keeps only frames that carry its own."""
    digest = hashlib.sha256()
    for part in (str(int(frame)), settings, blender, windgrass, *[hashlib.sha256(b).hexdigest() for b in inputs]):
        digest.update(part.encode("utf-8") + b"\0")
    return digest.hexdigest()[:32]


def check_chunk(chunk) -> int:
    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise ParameterError("chunk", f"{chunk!r} frames a task (valid: a whole number, at least 1)")
    return chunk


def _param(name: str, kind: str, default, description: str, **more) -> dict:
    out = {"name": name, "type": kind, "description": description}
    if default is not None:
        out["default"] = default
    out.update(more)
    return out


def _common_params(frames: str, chunk: int, out_dir: str, name: str, blender: str = "") -> list[dict]:
    return [
        _param("BlenderVersion", "STRING", blender, "The Blender line (X.Y) the frames are made with: a worker on "
               "another refuses; empty: any Blender renders them", minLength=0),
        _param("JobName", "STRING", name, "What the farm shows for the job"),
        _param("BlenderExecutable", "STRING", "blender", "The Blender the workers run (4.5 or newer): a name on "
               "their PATH or a full path"),
        _param("Frames", "STRING", frames, "The frames to render, A-B"),
        _param("ChunkSize", "INT", chunk, "Frames a task renders in one Blender", minValue=1),
        _param("OutputDir", "PATH", out_dir, "Where the frames are written (frame_NNNN.png)",
               objectType="DIRECTORY", dataFlow="OUT"),
    ]


# What runs the session's actions (start, each task's hand-over, stop): a factory-startup Blender
# (any worker; about a second a task) or the worker's python3 (Linux, macOS: a few milliseconds).
HAND_OVERS = ("blender", "python3")


def check_hand_over(hand_over: str) -> str:
    if hand_over not in HAND_OVERS:
        raise ParameterError("hand_over", f"{hand_over!r} (valid: {', '.join(HAND_OVERS)})")
    return hand_over


def _session_action(session: str, hand_over: str, *args: str) -> dict:
    tail = [*args, "--dir", "{{Session.WorkingDirectory}}", "--blender", "{{Param.BlenderExecutable}}"]
    if check_hand_over(hand_over) == "python3":
        return {"command": "python3", "args": [session, *tail]}
    return {"command": "{{Param.BlenderExecutable}}", "args": ["-b", "--factory-startup", "-P", session, "--", *tail]}


def _chunked_step(name: str, session: str, script: str, args: list[str], environments: tuple = (),
                  hand_over: str = "blender") -> dict:
    """The step whose tasks run ``script`` with ``args`` in the worker session's one Blender
    (``bridge/farm_session.py``, started by the step's last environment and ended by it), handed
    over by ``hand_over`` (HAND_OVERS)."""
    one_blender = {
        "name": "Windgrass session",
        "description": "One Blender renders this session's tasks: the scene is built once, not per task",
        "script": {"actions": {"onEnter": _session_action(session, hand_over, "start"),
                               "onExit": _session_action(session, hand_over, "stop")}},
    }
    run = _session_action(session, hand_over, "run")
    run["args"] += ["--script", script, "--", *args]
    return {
        "name": name,
        "parameterSpace": {"taskParameterDefinitions": [{
            "name": "Frame", "type": "CHUNK[INT]", "range": "{{Param.Frames}}",
            "chunks": {"defaultTaskCount": "{{Param.ChunkSize}}", "rangeConstraint": "CONTIGUOUS"}}]},
        "script": {"actions": {"onRun": run}},
        "stepEnvironments": [*environments, one_blender],
    }


def scene_template(frames: str, chunk: int, name: str, blender: str = "", hand_over: str = "blender") -> dict:
    """The OpenJD template of a scene-file job (paths as the bundle's parameter values give them)."""
    params = _common_params(frames, chunk, "output", name, blender) + [
        _param("WindgrassDir", "PATH", "windgrass", "The Windgrass scripts and add-on carried in the bundle",
               objectType="DIRECTORY", dataFlow="IN"),
        _param("SceneFile", "PATH", "scene/scene.toml", "The scene file (TOML) with its maps beside it",
               objectType="FILE", dataFlow="IN"),
    ]
    args = ["--config", "{{Param.SceneFile}}", "--frames", "{{Task.Param.Frame}}", "--out", "{{Param.OutputDir}}",
            "--resume", "--blender-version={{Param.BlenderVersion}}"]
    step = _chunked_step("Render", "{{Param.WindgrassDir}}/grass_addon/bridge/farm_session.py",
                         "{{Param.WindgrassDir}}/headless/render_field.py", args, hand_over=hand_over)
    return {"specificationVersion": SPECIFICATION, "extensions": ["TASK_CHUNKING"], "name": "{{Param.JobName}}",
            "parameterDefinitions": params, "steps": [step]}


def blend_template(frames: str, chunk: int, name: str, version: str, blender: str = "",
                   hand_over: str = "blender") -> dict:
    """The OpenJD template of a saved .blend with live grass: the extension installed per session."""
    params = _common_params(frames, chunk, "output", name, blender) + [
        _param("BlendFile", "PATH", "scene/scene.blend", "The saved .blend", objectType="FILE", dataFlow="IN"),
        _param("ExtensionZip", "PATH", f"windgrass-{version}.zip", "The Windgrass extension the .blend was made "
               "with", objectType="FILE", dataFlow="IN"),
        _param("FarmScript", "PATH", "farm_render.py", "Renders a chunk of frames of the .blend",
               objectType="FILE", dataFlow="IN"),
        _param("SessionScript", "PATH", "farm_session.py", "Keeps one Blender per worker session",
               objectType="FILE", dataFlow="IN"),
        _param("WindgrassVersion", "STRING", version, "The version the extension zip must have"),
    ]
    install = {
        "name": "Windgrass extension",
        "description": "Installs the Windgrass extension into a Blender user folder of this session only",
        "variables": {"BLENDER_USER_RESOURCES": "{{Session.WorkingDirectory}}/blender-user"},
        "script": {"actions": {"onEnter": {
            "command": "{{Param.BlenderExecutable}}",
            "args": ["--command", "extension", "install-file", "--repo", "user_default", "--enable",
                     "{{Param.ExtensionZip}}"]}}},
    }
    args = ["--blend", "{{Param.BlendFile}}", "--frames", "{{Task.Param.Frame}}", "--out", "{{Param.OutputDir}}",
            "--version", "{{Param.WindgrassVersion}}", "--blender-version={{Param.BlenderVersion}}"]
    step = _chunked_step("Render", "{{Param.SessionScript}}", "{{Param.FarmScript}}", args, (install,), hand_over)
    return {"specificationVersion": SPECIFICATION, "extensions": ["TASK_CHUNKING"], "name": "{{Param.JobName}}",
            "parameterDefinitions": params, "steps": [step]}


BUNDLE_MARK = ".windgrass-bundle.json"  # the files a bundle's writer wrote (relative paths)
STAGING = ".windgrass-staging-"  # a bundle being written, beside what it replaces


class Bundle:
    """A job bundle's folder, owned by what writes it (issue #57: Farm Job... into the folder of
    the artist's project deleted their notes, textures and the saved .blend).

    A bundle is written only into a folder that is empty, new, or that a bundle writer wrote
    (``BUNDLE_MARK`` lists its files); any other is refused with a sentence before anything is
    written. Everything goes to a staging folder inside it first (``path``), so a bundle that
    fails (a missing map) leaves the one before whole; ``commit`` then moves each file into place,
    refusing first when a name is taken by a file the writer did not write, and deletes only files
    of the earlier bundle that the new one no longer has. The artist's files, a ``output/`` the
    farm brought back, are never touched. Use as ``with Bundle(folder, "bundle") as bundle:``."""

    def __init__(self, folder, name: str):
        from .folders import user_folder

        self.folder, self.name = user_folder(folder, name), name
        self.owned = self._owned()
        self.written: set[str] = set()
        self.staging: Path | None = None

    def _owned(self) -> set[str]:
        """The files of the earlier bundle in the folder (none when it is new or empty)."""
        folder = self.folder
        if folder.is_symlink() or (folder.exists() and not folder.is_dir()):
            raise ParameterError(self.name, f"{folder} is not a folder (valid: an empty folder, or a new one)")
        if not folder.exists():
            return set()
        mark = folder / BUNDLE_MARK
        if mark.is_file() and not mark.is_symlink():
            try:
                listed = json.loads(mark.read_text())
            except (OSError, ValueError):
                listed = None
            if isinstance(listed, list) and all(isinstance(n, str) for n in listed):
                return {n for n in listed if _safe_name(n)}
        others = sorted(p.name for p in folder.iterdir() if not p.name.startswith(STAGING))
        if others:
            shown = ", ".join(others[:3]) + (" ..." if len(others) > 3 else "")
            raise ParameterError(self.name, f"{folder} holds files that were not written by farm.py ({shown}): give "
                                 "an empty folder or a new one (a bundle is written only into a folder of its own)")
        return set()

    def __enter__(self) -> Bundle:
        self.folder.mkdir(parents=True, exist_ok=True)
        for old in self.folder.glob(STAGING + "*"):  # (a writer killed before it finished)
            shutil.rmtree(old, ignore_errors=True)
        self.staging = Path(tempfile.mkdtemp(prefix=STAGING, dir=self.folder))
        return self

    def __exit__(self, kind, value, trace) -> None:
        try:
            if kind is None:
                self.commit()
        finally:
            if self.staging is not None:
                shutil.rmtree(self.staging, ignore_errors=True)

    def final(self, name: str) -> Path:
        """Where the bundle's file ``name`` (a path inside it) lies once written."""
        return self.folder / name

    def path(self, name: str) -> Path:
        """Where to write the bundle's file ``name`` now (its folder made)."""
        if self.staging is None or not _safe_name(name):
            raise ValueError(f"not a bundle's file name: {name!r}")
        self.written.add(name)
        target = self.staging / name
        target.parent.mkdir(parents=True, exist_ok=True)
        return target

    def commit(self) -> None:
        assert self.staging is not None
        taken = sorted(n for n in self.written - self.owned if os.path.lexists(self.final(n)))
        if taken:
            raise ParameterError(self.name, f"{self.final(taken[0])} was not written by farm.py: move it away, or "
                                 "give an empty folder or a new one")
        for name in self.written:  # (a link anywhere below the bundle's folder would be written through)
            for folder in self.final(name).parents:
                if folder == self.folder:
                    break
                if folder.is_symlink() or (folder.exists() and not folder.is_dir()):
                    raise ParameterError(self.name, f"{folder} is not a folder the bundle wrote: move it away")
        _write_list(self.folder / BUNDLE_MARK, self.owned | self.written)  # (a kill mid-way loses no record)
        for name in sorted(self.written):
            self.final(name).parent.mkdir(parents=True, exist_ok=True)
            os.replace(self.staging / name, self.final(name))
        for name in sorted(self.owned - self.written, reverse=True):
            gone = self.final(name)
            if gone.is_symlink() or gone.is_file():
                gone.unlink()
            for parent in gone.parents:  # (the folders it leaves empty, up to the bundle's)
                if parent == self.folder or not parent.is_dir() or any(parent.iterdir()):
                    break
                parent.rmdir()
        _write_list(self.folder / BUNDLE_MARK, self.written)


def _safe_name(name: str) -> bool:
    """A relative path inside a bundle (no ``..``, not absolute)."""
    parts = Path(name).parts
    return bool(parts) and not Path(name).is_absolute() and ".." not in parts and name != BUNDLE_MARK


def _write_list(path: Path, names) -> None:
    temp = path.with_name(path.name + ".new")
    temp.write_text(json.dumps(sorted(names), indent=0) + "\n")
    os.replace(temp, path)


MAX_PARAMETER_TEXT = 1024  # OpenJD's longest STRING parameter value (openjd check refuses more)


def write_bundle(bundle: Bundle, template: dict, values: dict, elsewhere: Sequence[str] = (),
                 carried: Sequence[Path] = ()) -> Path:
    """``template.yaml`` and ``parameter_values.yaml`` (Deadline Cloud's job bundle layout; JSON is
    YAML) in ``bundle``, and the same values as ``openjd run`` reads them (``job_params.yaml``);
    ``values``: {parameter: value}, paths as absolute strings where the bundle puts them.

    Deadline Cloud's client submits with ``--yes`` only paths it knows: those inside the bundle.
    So its parameter values leave the paths out: the template's defaults name every input by its
    path inside the bundle (the writer put them there; the client joins a default with the bundle's
    folder) and the output as the bundle's ``output/`` (``deadline job download-output`` brings the
    frames there); ``openjd run`` reads the absolute paths, the output folder given included.
    ``asset_references.yaml`` names the rest of the inputs: ``carried``, folders inside the bundle
    that no parameter names (a .blend's images beside its copy), and ``elsewhere``, input files
    outside the bundle (Deadline Cloud attaches them after asking, or without where a storage
    profile knows their folder)."""
    folder = bundle.folder
    for param in template["parameterDefinitions"]:
        if param["type"] == "PATH" and param.get("dataFlow") == "IN":
            param["default"] = _inside(folder, values[param["name"]], param["name"])
        if param["type"] == "STRING" and len(str(values.get(param["name"], ""))) > MAX_PARAMETER_TEXT:
            raise ParameterError(param["name"].lower(), f"{len(str(values[param['name']])):,} characters (valid: at "
                                 f"most {MAX_PARAMETER_TEXT:,}, Open Job Description's limit for a job parameter; "
                                 "give fewer runs of frames, e.g. one range A-B)")
    paths = {p["name"] for p in template["parameterDefinitions"] if p["type"] == "PATH"}
    bundle.path("template.yaml").write_text(json.dumps(template, indent=2) + "\n")
    rows = [{"name": k, "value": v} for k, v in values.items() if k not in paths]
    bundle.path("parameter_values.yaml").write_text(json.dumps({"parameterValues": rows}, indent=2) + "\n")
    bundle.path("job_params.yaml").write_text(json.dumps({k: str(v) for k, v in values.items()}, indent=2) + "\n")
    inputs = {"filenames": sorted(elsewhere), "directories": [str(Path(d).resolve()) for d in carried]}
    bundle.path("asset_references.yaml").write_text(json.dumps({"assetReferences": {"inputs": inputs}}, indent=2)
                                                    + "\n")
    return folder


def _inside(folder: Path, value, name: str) -> str:
    """``value``'s path inside ``folder``, relative to it (ParameterError when it lies outside)."""
    path, top = Path(value).resolve(), folder.resolve()
    if not path.is_relative_to(top):
        raise ParameterError(name, f"{path} lies outside the bundle {folder}: the bundle carries its inputs")
    return path.relative_to(top).as_posix()


def flamenco_job_type() -> str:
    """The Flamenco job type (JavaScript: ``JOB_TYPE`` and ``compileJob(job)``) for both kinds of
    job: put it in a ``scripts/`` folder beside the Flamenco Manager."""
    return FLAMENCO_JOB_TYPE.read_text()


EXTENSION_PARTS = ("__init__.py", "blender_manifest.toml", "grass_addon", "operators", "panels")


def extension_files(root: Path):
    """(path, name in the extension) of every file of the extension at ``root``: what Blender's
    build puts in the zip (the manifest's ``paths_exclude_pattern``: no caches, hidden files,
    scripts or tests), never a link (its target's content would travel), and in a git checkout only
    the files git tracks (issue #57: a checkout's ``.env``, swap files, ``.blend1`` and a link to a
    credentials file went into the bundle that ``deadline bundle submit`` uploads)."""
    patterns = _exclude_patterns(root)
    tracked = _tracked(root)
    for part in EXTENSION_PARTS:
        top = root / part
        paths = [top] if top.is_file() else sorted(p for p in top.rglob("*") if p.is_file())
        for path in paths:
            name = path.relative_to(root).as_posix()
            if tracked is not None and name not in tracked:
                continue
            if _linked(root, path) or any(p.startswith(".") for p in name.split("/")) or _excluded(name, patterns):
                continue
            yield path, name


def _exclude_patterns(root: Path) -> list[str]:
    try:
        import tomllib

        build = tomllib.loads((root / "blender_manifest.toml").read_text()).get("build", {})
    except (OSError, ValueError):
        return []
    patterns = build.get("paths_exclude_pattern", []) if isinstance(build, dict) else []
    return [p for p in patterns if isinstance(p, str) and p.strip("/")]


def _excluded(name: str, patterns: list[str]) -> bool:
    """Whether the manifest's patterns (gitignore's way, as Blender's build reads them: '/' in
    front anchors at the top, '/' at the end means a folder) leave ``name`` out."""
    parts = name.split("/")
    for pattern in patterns:
        body, folder = pattern.strip("/"), pattern.endswith("/")
        depth = body.count("/") + 1
        if pattern.startswith("/"):
            candidates = ["/".join(parts[:depth])] if len(parts) > depth or not folder else []
        else:
            candidates = parts[:-1] if folder else parts
        if any(fnmatch.fnmatchcase(c, body) for c in candidates):
            return True
    return False


def _linked(root: Path, path: Path) -> bool:
    """``path`` or a folder above it (below ``root``) is a symbolic link."""
    while path != root and root in path.parents:
        if path.is_symlink():
            return True
        path = path.parent
    return False


def _tracked(root: Path) -> set[str] | None:
    """The files git tracks in a checkout at ``root`` (None: no checkout, or no git here)."""
    if not (root / ".git").exists():
        return None
    try:
        out = subprocess.run(["git", "-C", str(root), "ls-files", "-z", "--cached"], capture_output=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return None
    return set(out.stdout.decode("utf-8", "replace").split("\0")) - {""} if out.returncode == 0 else None


def extension_version(root: Path) -> str:
    for line in (root / "blender_manifest.toml").read_text().splitlines():
        if line.strip().startswith("version"):
            return line.split("=", 1)[1].strip().strip('"')
    raise ParameterError("extension", f"{root / 'blender_manifest.toml'} has no version")


def zip_extension(root: Path, target: Path) -> Path:
    """The extension at ``root`` as an installable zip (``blender --command extension install-file``)."""
    import zipfile

    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as zf:
        for path, name in extension_files(root):
            zf.write(path, name)
    return target

#!/usr/bin/env python3
"""Windgrass developer entry point: sets up .venv with pinned packages, then runs a job.

    python3.11 dev.py render [render_field.py options]   # render the default grass animation
    python3.11 dev.py test [pytest options]              # the test suite on Blender 5.0, then the
                                                         # Blender tests on 4.2 LTS (.venv-4.2)
    python3.11 dev.py simulate [simulate.py options]     # numpy-only simulation summary
    python3.11 dev.py bench [bench.py options]           # benchmark JSON
    python3.11 dev.py lod [lod_compare.py options]       # LOD against all-geometry renders (JSON)
    python3.11 dev.py docs [docs_media.py options]       # the README's still, animation, LOD pictures
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
# (virtual environment, its requirements): the current Blender line, and the oldest supported one
LATEST = (ROOT / ".venv", ROOT / "requirements.txt")
OLDEST = (ROOT / ".venv-4.2", ROOT / "requirements-blender-4.2.txt")
DOCS_REQUIREMENT = "pillow==11.0.0"  # dev.py docs only (animated WebP)


def ensure_venv(env_dir: Path = LATEST[0], requirements: Path = LATEST[1]) -> Path:
    """Create ``env_dir`` and install ``requirements`` once (again only when the file changes)."""
    if sys.version_info[:2] != (3, 11):
        sys.exit(f"dev.py needs Python 3.11 (the bpy module is built for it); this is {sys.version.split()[0]}")
    python = env_dir / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    stamp = env_dir / ".requirements.sha1"
    digest = hashlib.sha1(requirements.read_bytes()).hexdigest()
    if python.exists() and stamp.exists() and stamp.read_text() == digest:
        return python
    if not python.exists():
        print(f"dev.py: creating {env_dir.name}", flush=True)
        venv.create(env_dir, with_pip=True)
    print(f"dev.py: installing {requirements.name} into {env_dir.name} (bpy is ~400 MB, first time only)",
          flush=True)
    subprocess.check_call([str(python), "-m", "pip", "install", "-q", "-r", str(requirements)])
    stamp.write_text(digest)
    return python


def main(argv: list[str]) -> int:
    jobs = {
        "render": ["headless/render_field.py"],
        "simulate": ["headless/simulate.py"],
        "bench": ["headless/bench.py"],
        "lod": ["headless/lod_compare.py"],
        "docs": ["headless/docs_media.py"],
        "test": ["-m", "pytest", "tests"],
    }
    if not argv or argv[0] not in jobs:
        print(__doc__)
        return 2
    python = ensure_venv()
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    if argv[0] == "test":
        return run_tests(python, argv[1:], env)
    if argv[0] == "docs":  # Pillow writes the animation; only this job needs it
        subprocess.check_call([str(python), "-m", "pip", "install", "-q", DOCS_REQUIREMENT])
    cmd = [str(python), *jobs[argv[0]], *argv[1:]]
    return subprocess.call(cmd, cwd=ROOT, env=env)


def run_tests(python: Path, args: list[str], env: dict) -> int:
    """Every test on the current Blender, then the Blender tests on the oldest supported line
    (4.2 LTS): both must pass. Options go to both runs; test paths given replace the defaults
    (``tests``, and ``tests/blender`` on 4.2)."""
    paths = [a for a in args if not a.startswith("-")]
    latest = subprocess.call([str(python), "-m", "pytest", *args, *([] if paths else ["tests"])],
                             cwd=ROOT, env=env)
    oldest_python = ensure_venv(*OLDEST)
    print("dev.py: the Blender tests again on Blender 4.2 LTS (.venv-4.2)", flush=True)
    oldest = subprocess.call([str(oldest_python), "-m", "pytest", "-p", "no:cacheprovider", *args,
                              *([] if paths else ["tests/blender"])], cwd=ROOT, env=env)
    # pytest's 5 (no test collected) on 4.2: the paths given hold no Blender test
    return latest or (0 if oldest == 5 and paths else oldest)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

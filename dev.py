#!/usr/bin/env python3
"""Windgrass developer entry point: sets up .venv with pinned packages, then runs a job.

    python3.11 dev.py render [render_field.py options]   # render the default grass animation
    python3.11 dev.py test [pytest options]              # run the test suite
    python3.11 dev.py simulate [simulate.py options]     # numpy-only simulation summary
    python3.11 dev.py bench [bench.py options]           # benchmark JSON
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
PYTHON = VENV / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
REQUIREMENTS = ROOT / "requirements.txt"
STAMP = VENV / ".requirements.sha1"


def ensure_venv() -> Path:
    """Create .venv and install requirements.txt once (again only when it changes)."""
    if sys.version_info[:2] != (3, 11):
        sys.exit(f"dev.py needs Python 3.11 (the bpy module is built for it); this is {sys.version.split()[0]}")
    digest = hashlib.sha1(REQUIREMENTS.read_bytes()).hexdigest()
    if PYTHON.exists() and STAMP.exists() and STAMP.read_text() == digest:
        return PYTHON
    if not PYTHON.exists():
        print("dev.py: creating .venv", flush=True)
        venv.create(VENV, with_pip=True)
    print("dev.py: installing requirements.txt into .venv (bpy is ~400 MB, first time only)", flush=True)
    subprocess.check_call([str(PYTHON), "-m", "pip", "install", "-q", "-r", str(REQUIREMENTS)])
    STAMP.write_text(digest)
    return PYTHON


def main(argv: list[str]) -> int:
    jobs = {
        "render": ["headless/render_field.py"],
        "simulate": ["headless/simulate.py"],
        "bench": ["headless/bench.py"],
        "test": ["-m", "pytest", "tests"],
    }
    if not argv or argv[0] not in jobs:
        print(__doc__)
        return 2
    python = ensure_venv()
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    cmd = [str(python), *jobs[argv[0]], *argv[1:]]
    return subprocess.call(cmd, cwd=ROOT, env=env)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

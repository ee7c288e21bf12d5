#!/usr/bin/env python3
"""Windgrass developer entry point: sets up .venv with pinned packages, then runs a job.

    python3.11 dev.py render [render_field.py options]   # render the default grass animation
    python3.11 dev.py test [pytest options]              # the test suite on Blender 5.0 (and a real
                                                         # Blender 4.3 window, tests/window), then the
                                                         # Blender tests on 4.2 LTS (.venv-4.2)
    python3.11 dev.py test --quick                       # tests/core without the slow ones (< 30 s)
    python3.11 dev.py simulate [simulate.py options]     # numpy-only simulation summary
    python3.11 dev.py bench [bench.py options]           # benchmark JSON
    python3.11 dev.py lod [lod_compare.py options]       # LOD against all-geometry renders (JSON)
    python3.11 dev.py docs [docs_media.py options]       # the README's still, animation, LOD pictures
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
# (virtual environment, its requirements): the current Blender line, and the oldest supported one
LATEST = (ROOT / ".venv", ROOT / "requirements.txt")
OLDEST = (ROOT / ".venv-4.2", ROOT / "requirements-blender-4.2.txt")
# A real Blender with its window for tests/window: Debian 13's Blender 4.3 in a Debian 13 root made
# with debootstrap (Debian 12 ships Blender 3.4), on a virtual screen (Xvfb, Mesa's software GL).
TRIXIE = Path(os.environ.get("WINDGRASS_TRIXIE", Path.home() / ".cache" / "windgrass" / "trixie"))
TRIXIE_PACKAGES = ("blender", "python3-numpy", "xvfb", "xauth", "xdotool", "x11-apps", "netpbm")


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
    cmd = [str(python), *jobs[argv[0]], *argv[1:]]
    return subprocess.call(cmd, cwd=ROOT, env=env)


def ensure_real_blender() -> Path | None:
    """The Debian 13 root with Blender for tests/window, made once (about a minute to five, as the
    mirror allows); None (the window tests then skip, saying why) when this machine cannot make
    one: not root, or WINDGRASS_TRIXIE=off."""
    if os.environ.get("WINDGRASS_TRIXIE") == "off":
        print("dev.py: WINDGRASS_TRIXIE=off: the real-Blender window tests are skipped", flush=True)
        return None
    stamp = TRIXIE / ".windgrass-packages"
    wanted = " ".join(TRIXIE_PACKAGES)
    if stamp.exists() and stamp.read_text() == wanted:
        return TRIXIE
    if os.geteuid() != 0:
        print("dev.py: the real-Blender window tests need a Debian 13 root (debootstrap, chroot: run as root); "
              "they are skipped", flush=True)
        return None
    print(f"dev.py: making a Debian 13 root with Blender in {TRIXIE} (first time only)", flush=True)
    if shutil.which("debootstrap") is None:
        subprocess.check_call(["apt-get", "install", "-y", "-q", "debootstrap"])
    if not (TRIXIE / "usr" / "bin" / "apt-get").exists():
        shutil.rmtree(TRIXIE, ignore_errors=True)
        TRIXIE.parent.mkdir(parents=True, exist_ok=True)
        subprocess.check_call(["debootstrap", "--variant=minbase", "trixie", str(TRIXIE)],
                              stdout=subprocess.DEVNULL)
    shutil.copy2("/etc/resolv.conf", TRIXIE / "etc" / "resolv.conf")
    env = {"PATH": "/usr/sbin:/usr/bin:/sbin:/bin", "DEBIAN_FRONTEND": "noninteractive", "LANG": "C.UTF-8"}
    subprocess.check_call(["chroot", str(TRIXIE), "apt-get", "update", "-q"], env=env, stdout=subprocess.DEVNULL)
    subprocess.check_call(["chroot", str(TRIXIE), "apt-get", "install", "-y", "-q", "--no-install-recommends",
                           *TRIXIE_PACKAGES], env=env, stdout=subprocess.DEVNULL)
    stamp.write_text(wanted)
    return TRIXIE


QUICK = ["tests/core", "-m", "not slow"]


def run_tests(python: Path, args: list[str], env: dict) -> int:
    """Every test on the current Blender (with the real-Blender window tests), then the Blender
    tests on the oldest supported line (4.2 LTS): both must pass. Options go to both runs; test
    paths given replace the defaults (``tests``, and ``tests/blender`` on 4.2). ``--quick``: the
    numpy tests without those marked slow, nothing else."""
    if "--quick" in args:
        rest = [a for a in args if a != "--quick"]
        return subprocess.call([str(python), "-m", "pytest", *QUICK, *rest], cwd=ROOT, env=env)
    paths = [a for a in args if (ROOT / a.split("::")[0]).exists()]
    options = [a for a in args if a not in paths]
    under = {p: Path(p.split("::")[0]).parts[:2] for p in paths}
    if not paths or any(parts in (("tests", "window"), ("tests",)) for parts in under.values()):
        root = ensure_real_blender()
        if root is not None:
            env = dict(env, WINDGRASS_TRIXIE=str(root))
    latest = subprocess.call([str(python), "-m", "pytest", *args, *([] if paths else ["tests"])],
                             cwd=ROOT, env=env)
    # the bpy-module Blender tests among the paths (all of them for "tests" or none given)
    blender = [p for p, parts in under.items() if parts == ("tests", "blender")]
    if not paths or ("tests",) in under.values():
        blender = ["tests/blender"]
    if not blender:
        return latest
    oldest_python = ensure_venv(*OLDEST)
    print("dev.py: the Blender tests again on Blender 4.2 LTS (.venv-4.2)", flush=True)
    oldest = subprocess.call([str(oldest_python), "-m", "pytest", "-p", "no:cacheprovider", *options, *blender],
                             cwd=ROOT, env=env)
    # pytest's 5 (no test collected) on 4.2: the tests selected hold no Blender test
    return latest or (0 if oldest == 5 else oldest)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

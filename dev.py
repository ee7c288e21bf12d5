#!/usr/bin/env python3
"""Windgrass developer entry point: sets up .venv with pinned packages, then runs a job.

    python3.11 dev.py render [render_field.py options]   # render the default grass animation
    python3.11 dev.py test [pytest options]              # the test suite on Blender 5.2 LTS (and a real
                                                         # Blender 5.2 window, tests/window), the
                                                         # Blender tests on 4.5 LTS (.venv-4.5) and
                                                         # those of the APIs that move on 5.3 (.venv-5.3)
    python3.11 dev.py test --quick                       # tests/core without the slow ones (< 30 s)
    python3.11 dev.py simulate [simulate.py options]     # numpy-only simulation summary
    python3.11 dev.py bench [bench.py options]           # benchmark JSON
    python3.11 dev.py lod [lod_compare.py options]       # LOD against all-geometry renders (JSON)
    python3.11 dev.py docs [docs_media.py options]       # the README's still, animation, LOD pictures
    python3.11 dev.py params                             # grass_addon/params_typed.py from the schema
"""

from __future__ import annotations

import concurrent.futures
import hashlib
import os
import shutil
import subprocess
import sys
import time
import typing
from pathlib import Path

ROOT = Path(__file__).resolve().parent
# (virtual environment, its requirements, its Python): the supported Blender lines. 5.2 LTS, the
# bpy module for CPython 3.13, runs everything; 4.5 LTS (CPython 3.11), the oldest line the manifest
# claims, runs the Blender tests again.
LATEST = (ROOT / ".venv", ROOT / "requirements.txt", (3, 13))
OLDEST = (ROOT / ".venv-4.5", ROOT / "requirements-blender-4.5.txt", (3, 11))
# 5.3, the current line (CPython 3.13 too), runs the Blender tests of the APIs that move between
# lines (CURRENT_LINE_TESTS): the rest is the same code on the same numpy as 5.2's.
CURRENT = (ROOT / ".venv-5.3", ROOT / "requirements-blender-5.3.txt", (3, 13))
CURRENT_LINE_TESTS = ("tests/blender/test_extension.py", "tests/blender/test_saved_files.py",
                      "tests/blender/test_live_edits.py", "tests/blender/test_loop.py", "tests/blender/test_undo.py",
                      "tests/blender/test_bake.py", "tests/blender/test_heads.py",
                      "tests/blender/test_wind_force.py", "tests/blender/test_field_map.py",
                      "tests/blender/test_handover.py")
# A real Blender with its window for tests/window: Debian's unstable suite ships Blender 5.2 LTS
# (Debian 13 has 4.3), in a root made with debootstrap, on a virtual screen (Xvfb, Mesa's software GL).
WINDOW_ROOT = Path(os.environ.get("WINDGRASS_WINDOW_ROOT", Path.home() / ".cache" / "windgrass" / "sid"))
WINDOW_PACKAGES = ("blender", "python3-numpy", "python3-cattr", "python3-requests", "xvfb", "xauth", "xdotool",
                   "x11-apps", "netpbm")


def find_python(version: tuple[int, int]) -> str | None:
    """A CPython of ``version``: this one, pyenv's build of it, or ``python3.X`` on PATH; None when
    the machine has none."""
    if sys.version_info[:2] == version:
        return sys.executable
    name = "python{}.{}".format(*version)
    pyenv = Path(os.environ.get("PYENV_ROOT", Path.home() / ".pyenv")) / "versions"
    builds = sorted(pyenv.glob("{}.{}.*/bin/{}".format(*version, name)), reverse=True)  # (not pyenv's shims)
    for candidate in [*map(str, builds), shutil.which(name)]:
        if candidate and subprocess.run([candidate, "-c", f"import sys; sys.exit(sys.version_info[:2] != {version})"],
                                        capture_output=True).returncode == 0:
            return candidate
    return None


def ensure_venv(env_dir: Path, requirements: Path, version: tuple[int, int]) -> Path:
    """Create ``env_dir`` with a CPython of ``version`` and install ``requirements`` once (again
    only when the file changes; made anew when it holds another Python)."""
    python = env_dir / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    stamp = env_dir / ".requirements.sha1"
    digest = hashlib.sha1(requirements.read_bytes()).hexdigest()
    config = env_dir / "pyvenv.cfg"
    wanted = "version = {}.{}.".format(*version)
    if config.exists() and wanted not in config.read_text().replace("version_info", "version"):
        print(f"dev.py: {env_dir.name} holds another Python; making it anew for Python {version[0]}.{version[1]}",
              flush=True)
        shutil.rmtree(env_dir)
    if python.exists() and stamp.exists() and stamp.read_text() == digest:
        return python
    if not python.exists():
        base = find_python(version)
        if base is None:
            sys.exit(f"dev.py: {env_dir.name} needs CPython {version[0]}.{version[1]} and this machine has none")
        print(f"dev.py: creating {env_dir.name} (Python {version[0]}.{version[1]})", flush=True)
        subprocess.check_call([base, "-m", "venv", str(env_dir)])
    log = env_dir / "pip-install.log"
    print(f"dev.py: installing {requirements.name} into {env_dir.name} (1.4 GB with bpy, first time only; pip's "
          f"lines go to {log})", flush=True)
    with open(log, "w") as out:
        run_logged([str(python), "-m", "pip", "install", "-q", "-r", str(requirements)], out, log)
    stamp.write_text(digest)
    return python


def run_logged(cmd: list[str], out, log: Path, env: dict | None = None) -> None:
    """``cmd`` with its output in the open log file ``out`` (at ``log``): a newcomer's terminal shows
    one line a step, not apt's or pip's; when it fails, the log's last lines and the error."""
    out.write(f"$ {' '.join(cmd)}\n")
    out.flush()
    try:
        subprocess.check_call(cmd, stdout=out, stderr=subprocess.STDOUT, env=env)
    except subprocess.CalledProcessError:
        out.flush()
        print(f"dev.py: {Path(cmd[0]).name} failed; the end of {log}:\n"
              + "".join(log.read_text().splitlines(True)[-20:]), flush=True)
        raise


def latest_or_oldest() -> tuple[Path, bool]:
    """The 5.2 LTS environment, or 4.5 LTS's where no CPython 3.13 can be found (said once):
    (its python, whether it is 5.2's)."""
    if find_python(LATEST[2]) is not None or (LATEST[0] / ".requirements.sha1").exists():
        return ensure_venv(*LATEST), True
    print("dev.py: no CPython 3.13 here (Blender 5.2's bpy module needs it: pyenv install 3.13, or your "
          "system's python3.13); using Blender 4.5 LTS (CPython 3.11) instead", flush=True)
    return ensure_venv(*OLDEST), False


def main(argv: list[str]) -> int:
    jobs = {
        "render": ["headless/render_field.py"],
        "simulate": ["headless/simulate.py"],
        "bench": ["headless/bench.py"],
        "lod": ["headless/lod_compare.py"],
        "docs": ["headless/docs_media.py"],
        "params": ["headless/typed_params.py"],
        "test": ["-m", "pytest", "tests"],
    }
    if argv[:1] in (["-h"], ["--help"]):
        print(__doc__)
        return 0
    if not argv or argv[0] not in jobs:
        print(__doc__)
        return 2
    if sys.version_info[:2] != (3, 11):
        sys.exit(f"dev.py runs on Python 3.11 (the 4.5 LTS bpy module is built for it); this is "
                 f"{sys.version.split()[0]}")
    if argv[0] == "test" and needs_window(argv[1:]):
        start_real_blender()  # (downloads beside the virtual environments' installs)
    python, is_latest = latest_or_oldest()
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    if argv[0] == "test":
        return run_tests(python, argv[1:], env, also_oldest=is_latest)
    cmd = [str(python), *jobs[argv[0]], *argv[1:]]
    return subprocess.call(cmd, cwd=ROOT, env=env)


_REAL_BLENDER: concurrent.futures.Future | None = None


def needs_window(args: list[str]) -> bool:
    """Whether ``dev.py test args`` runs the window tests: no test path given (and no ``--quick``),
    or tests/ or tests/window."""
    paths = [Path(a.split("::")[0]).parts[:2] for a in args if (ROOT / a.split("::")[0]).exists()]
    if not paths:
        return "--quick" not in args
    return any(p in (("tests", "window"), ("tests",)) for p in paths)


def start_real_blender() -> None:
    """``ensure_real_blender`` started in a thread now (its result: ``with_window_root``)."""
    global _REAL_BLENDER
    _REAL_BLENDER = concurrent.futures.ThreadPoolExecutor(1).submit(ensure_real_blender)


def ensure_real_blender() -> Path | None:
    """The root of Debian's unstable suite with Blender 5.2 for tests/window, made once (a few
    minutes, as the mirror allows); None (the window tests then skip, saying why) when this machine
    cannot make one: not root, or WINDGRASS_WINDOW_ROOT=off."""
    if os.environ.get("WINDGRASS_WINDOW_ROOT") == "off":
        print("dev.py: WINDGRASS_WINDOW_ROOT=off: the real-Blender window tests are skipped", flush=True)
        return None
    stamp = WINDOW_ROOT / ".windgrass-packages"
    wanted = " ".join(WINDOW_PACKAGES)
    if stamp.exists() and stamp.read_text() == wanted:
        return WINDOW_ROOT
    if os.geteuid() != 0:
        print("dev.py: the real-Blender window tests need a Debian root (debootstrap, chroot: run as root); "
              "they are skipped", flush=True)
        return None
    log = WINDOW_ROOT.parent / "sid-setup.log"
    WINDOW_ROOT.parent.mkdir(parents=True, exist_ok=True)
    print(f"dev.py: making a root of Debian's unstable suite with Blender 5.2 in {WINDOW_ROOT} (first time only: "
          f"about 1.8 GB; apt's and debootstrap's lines go to {log})", flush=True)
    env = {"PATH": "/usr/sbin:/usr/bin:/sbin:/bin", "DEBIAN_FRONTEND": "noninteractive", "LANG": "C.UTF-8"}
    with open(log, "w") as out:
        def step(*cmd: str) -> None:  # (in the root: a clean environment)
            run_logged(list(cmd), out, log, env if cmd[0] == "chroot" else None)

        if shutil.which("debootstrap") is None:
            step("apt-get", "update", "-q")
            step("apt-get", "install", "-y", "-q", "debootstrap")
        if not (WINDOW_ROOT / "usr" / "bin" / "apt-get").exists():
            shutil.rmtree(WINDOW_ROOT, ignore_errors=True)
            step("debootstrap", "--variant=minbase", "sid", str(WINDOW_ROOT))
        shutil.copy2("/etc/resolv.conf", WINDOW_ROOT / "etc" / "resolv.conf")
        # (the unstable suite's release file carries a date after which apt calls it stale)
        step("chroot", str(WINDOW_ROOT), "apt-get", "-o", "Acquire::Check-Valid-Until=false", "update", "-q")
        step("chroot", str(WINDOW_ROOT), "apt-get", "install", "-y", "-q", "--no-install-recommends", *WINDOW_PACKAGES)
    stamp.write_text(wanted)
    return WINDOW_ROOT


QUICK = ["tests/core", "-m", "not slow", "-n", "2"]  # (two processes: 41 s in one on 2 cores, idle)
# Two test processes (pytest-xdist): the tests share out test by test, the ones that share a
# module's renders of minutes (xdist_group marks) in one process
PARALLEL = ["-n", "2", "--dist", "loadgroup"]


def run_tests(python: Path, args: list[str], env: dict, also_oldest: bool = True) -> int:
    """Every test on the current Blender (with the real-Blender window tests), then the Blender
    tests on the oldest supported line (4.5 LTS): both must pass. Options go to every run; test
    paths given replace the defaults (``tests``, and ``tests/blender`` on 4.5). ``--quick``: the
    numpy tests without those marked slow, nothing else.

    The whole suite (no paths) fits two cores: the window tests (one Blender with its window, about
    one core) run beside the 4.5 LTS Blender tests, then tests/core and tests/blender on 5.2 LTS
    in two processes (the window tests' last minutes beside them)."""
    if "--quick" in args:
        rest = [a for a in args if a != "--quick"]
        return subprocess.call([str(python), "-m", "pytest", *QUICK, *rest], cwd=ROOT, env=env)
    paths = [a for a in args if (ROOT / a.split("::")[0]).exists()]
    options = [a for a in args if a not in paths]
    under = {p: Path(p.split("::")[0]).parts[:2] for p in paths}
    if paths:
        if needs_window(args):
            env = with_window_root(env)
        latest = subprocess.call([str(python), "-m", "pytest", *args], cwd=ROOT, env=env)
        blender = [p for p, parts in under.items() if parts == ("tests", "blender")]
        if ("tests",) in under.values():
            blender = ["tests/blender"]
        if not blender or not also_oldest:
            return latest
        oldest = subprocess.call(oldest_command(blender, options), cwd=ROOT, env=env)
        return latest or (0 if oldest == 5 else oldest)  # (5: no test collected: none of them a Blender test)
    # The 4.5 LTS run starts first; the window's root is made (first time: minutes of downloads)
    # and its tests start beside it; the 5.3 run starts when either of them ends (the two cores
    # kept busy), and the 5.2 LTS run, in two processes, when all three have ended.
    oldest_run = subprocess.Popen(oldest_command(["tests/blender"], options), cwd=ROOT, env=env) \
        if also_oldest else None
    window: Beside | None = None
    window_failed = False
    try:
        env = with_window_root(env)
        if "WINDGRASS_WINDOW_ROOT" in env:
            window = run_beside([str(python), "-m", "pytest", "-p", "no:cacheprovider", "tests/window", *options],
                                env, "window", "the real-Blender window tests (tests/window)")
    except subprocess.CalledProcessError as exc:  # (the root could not be made: the suite has not passed)
        print(f"dev.py: the window tests' root could not be made ({exc}); they did not run", flush=True)
        window_failed = True
    current: Beside | None = None
    if also_oldest and find_python(CURRENT[2]) is not None:  # (without CPython 3.13 there is no 5.3 line here)
        command = current_command(options)  # (its venv made now, beside the runs)
        while all(p is not None and p.poll() is None for p in (oldest_run, window.proc if window else None)):
            time.sleep(2.0)
        current = run_beside(command, env, "current",
                             "the Blender tests of the APIs that move, on Blender 5.3 (.venv-5.3)")
    oldest_status = oldest_run.wait() if oldest_run is not None else 0
    window_status = 1 if window_failed else (0 if window is None else window.wait())
    current_status = 0 if current is None else current.wait()
    print("dev.py: tests/core and tests/blender on Blender 5.2 LTS, in two processes", flush=True)
    # (the LOD comparisons first: their renders of minutes start at once, the rest fills in beside them)
    latest = subprocess.call([str(python), "-m", "pytest", *PARALLEL, *options, "tests/blender/test_lod_fidelity.py",
                              "tests/blender", "tests/core"], cwd=ROOT, env=env)
    return latest or window_status or oldest_status or current_status


def with_window_root(env: dict) -> dict:
    """``env`` naming the real Blender's root for tests/window (made if needed, or waited for when
    ``start_real_blender`` began it), when there is one."""
    root = _REAL_BLENDER.result() if _REAL_BLENDER is not None else ensure_real_blender()
    return env if root is None else dict(env, WINDGRASS_WINDOW_ROOT=str(root))


# The level-of-detail comparisons render each frame twice in the same Blender (the LOD against every
# blade as geometry) and measure the engine's LOD, which is the same on every line; they take a
# quarter of the Blender tests' time, so the whole suite's run on the oldest line leaves them to the
# current one (a single test named on the command line still runs there). So do the far canopy's
# trail against the blades' (a comparison of the same kind), the LOD comparison script's own test
# (its figures, not Blender's: a minute of renders), the splits rendered again to compare pixels
# with the whole run (the engine's determinism: frame N from the settings and N alone; the 4.5
# run still renders motion blur, paint, colliders and farm chunks), and the farm tests whose
# workers are the real Blender 5.2 binary (the bpy module only saves their .blend).
SAME_ON_EVERY_LINE = ("tests/blender/test_lod_fidelity.py",
                      "tests/blender/test_interaction.py::test_the_far_canopy_shows_a_trail_as_the_grass_does",
                      "tests/blender/test_render_field.py::test_lod_comparison_script_measures_rows_images_and_flicker",
                      "tests/blender/test_render_field.py::test_a_split_far_into_a_long_range_renders_the_same_pixels",
                      "tests/blender/test_motion_blur.py::test_render_farm_splits_are_pixel_identical_with_blur",
                      *(f"tests/blender/test_farm.py::test_workers_on_real_blender_5_2_{name}" for name in (
                          "render_a_scene_file_job_as_one_process_does",
                          "without_windgrass_render_a_saved_blends_job")),
                      # The engine's look and its determinism in renders of a few seconds each, the same
                      # numpy on every line (7 min of the 4.5 run; the Blender API they use, materials,
                      # Geometry Nodes, renders, the CLI, is tested on 4.5 by the rest): pressed grass,
                      # the screen size's LOD, meadows' and lawns' far looks, splits, farm chunks, memory.
                      *(f"tests/blender/{name}" for name in (
                          "test_farm.py::test_a_scene_file_job_renders_in_chunks_what_one_process_renders",
                          "test_meadow.py::test_pressed_grass_lies_along_the_track_and_stays_green",
                          "test_meadow.py::test_the_far_canopy_seen_from_above_shows_the_flowers_at_their_share",
                          "test_meadow.py::test_the_far_canopy_is_yellower_where_more_buttercups_grow",
                          "test_meadow.py::test_a_lawn_reads_as_green_turf_not_bare_ground",
                          "test_meadow.py::test_the_cards_carry_each_of_the_fields_flowers",
                          "test_cameras.py::test_a_larger_frame_draws_blades_further_out_and_the_canopy_further_back",
                          "test_render_field.py::test_memory_estimate_bounds_what_a_render_takes",
                          "test_render_field.py::test_a_field_of_no_blades_renders_bare_ground",
                          "test_render_field.py::test_a_scene_files_colliders_render_split_the_same_and_show_their_balls",
                          "test_render_field.py::test_a_painted_path_on_a_heightmap_renders_bare_and_splits_the_same",
                          "test_render_field.py::test_past_a_small_field_lies_meadow_to_hills_not_a_ruler_line",
                          "test_render_field.py::test_variants_get_own_folders_seeds_and_wind",
                          "test_scene.py::test_gust_waves_run_across_the_far_field",
                          "test_terrain.py::test_grass_field_on_selected_mesh_covers_the_mesh_or_says_how_much[300.0]")))


def oldest_command(blender: list[str], options: list[str]) -> list[str]:
    """The Blender tests ``blender`` on Blender 4.5 LTS (.venv-4.5, made if needed)."""
    oldest_python = ensure_venv(*OLDEST)
    print("dev.py: the Blender tests on Blender 4.5 LTS (.venv-4.5)", flush=True)
    skip = [f"--deselect={p}" if "::" in p else f"--ignore={p}" for p in SAME_ON_EVERY_LINE] \
        if blender == ["tests/blender"] else []
    return [str(oldest_python), "-m", "pytest", "-p", "no:cacheprovider", *options, *skip, *blender]


def current_command(options: list[str]) -> list[str]:
    """The Blender tests of the APIs that move (CURRENT_LINE_TESTS) on Blender 5.3 (.venv-5.3, made
    if needed)."""
    current_python = ensure_venv(*CURRENT)
    return [str(current_python), "-m", "pytest", "-p", "no:cacheprovider", *options, *CURRENT_LINE_TESTS]


class Beside:
    """A test run started in the background, its output kept in a file (``run_beside``)."""

    def __init__(self, proc: subprocess.Popen, log: typing.TextIO, label: str) -> None:
        self.proc, self.log, self.label = proc, log, label

    def wait(self) -> int:
        """Wait for it, print its output and give its exit status."""
        status = self.proc.wait()
        self.log.seek(0)
        print(f"dev.py: {self.label} ended ({status}):\n{self.log.read()}", flush=True)
        self.log.close()
        return status


def run_beside(command: list[str], env: dict, name: str, label: str) -> Beside:
    """``command`` started now in the background, its output kept in ``.<name>-tests.log``
    (gitignored) and printed when it is waited for."""
    log = open(ROOT / f".{name}-tests.log", "w+")
    print(f"dev.py: {label} run beside, their output follows when they end", flush=True)
    proc = subprocess.Popen(command, cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT)
    return Beside(proc, log, label)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

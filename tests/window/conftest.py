"""A real Blender binary with its window, for what only the artist's Blender shows.

The bpy module runs in background mode: no window, no event loop, no keymap, no viewport, no real
undo stack as the window pushes it. These tests run Debian's Blender 5.2 LTS in a root of Debian's
unstable suite made by ``dev.py`` (``debootstrap``; see README "Get going"), with its window on a
virtual screen (Xvfb, Mesa's software OpenGL), the extension built and installed by Blender's own
tool, and drive it as an artist would through ``driver.py``: operators as the UI calls them, property edits
followed by the undo step the window pushes, keys typed with ``xdotool``, screenshots.

``WINDGRASS_WINDOW_ROOT`` names the root (default ``~/.cache/windgrass/sid``). Without one (or not
as root: ``chroot`` needs it) the tests are skipped with that reason; ``dev.py test`` makes the
root first, so CI runs them.
"""

from __future__ import annotations

import json
import os
import pwd
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))  # scenarios.py


def window_root() -> Path:
    default = Path(pwd.getpwuid(os.getuid()).pw_dir) / ".cache" / "windgrass" / "sid"
    return Path(os.environ.get("WINDGRASS_WINDOW_ROOT", default))


@dataclass
class Run:
    """One Blender session: its exit status, output, report (driver.py) and screenshots."""

    returncode: int
    output: str
    report: dict
    shots: Path
    crash: str

    @property
    def steps(self) -> list[dict]:
        return self.report.get("steps", [])

    def results(self, kind: str) -> list:
        return [s.get("result") for s in self.steps if kind in s["step"]]

    def problems(self) -> list[str]:
        """Every check's problems and every step that raised, with the step."""
        out = []
        for s in self.steps:
            if "exception" in s:
                out.append(f"{s['step']}: {s['exception']}")
            result = s.get("result")
            if isinstance(result, dict) and result.get("problems"):
                out.append(f"{s['step']}: {result['problems']}")
        return out

    def last_steps(self, count: int = 4) -> str:
        """The last steps begun, with when (s into the session): where a session that timed out
        was."""
        return "\n".join(f"{s.get('at', '?')} s: {json.dumps(s['step'])[:200]}" for s in self.steps[-count:])

    def assert_clean(self) -> None:
        assert self.returncode == 0, (f"Blender exited with {self.returncode}\n{self.crash}\n{self.output[-3000:]}\n"
                                      f"the last steps begun:\n{self.last_steps()}")
        assert self.report.get("finished"), f"the scenario did not finish\n{self.output[-3000:]}"
        problems = self.problems()
        assert not problems, "\n".join(problems)
        traceback_lines = [line for line in self.output.splitlines() if line.startswith("Traceback")]
        assert not traceback_lines, self.output[-3000:]


class RealBlender:
    """Debian's Blender 5.2 in its root, with Windgrass installed as an extension."""

    def __init__(self, root: Path, work: Path):
        self.root, self.work = root, work  # work: a folder inside root
        self.inside = Path("/") / work.relative_to(root)
        self.user = work / "user"
        self.counter = 0

    def _chroot(self, script: str, timeout: float) -> subprocess.CompletedProcess:
        env = {"PATH": "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin", "LANG": "C.UTF-8",
               "HOME": str(self.inside / "home"), "BLENDER_USER_RESOURCES": str(self.inside / "user")}
        return subprocess.run(["chroot", str(self.root), "/bin/sh", "-c", script], capture_output=True, text=True,
                              env=env, timeout=timeout)

    def install(self) -> str:
        """Build the extension with Blender's tool from a copy of the working tree and install it."""
        repo = self.work / "repo"
        files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=REPO, capture_output=True,
                               text=True, check=True).stdout.split("\n")
        for name in filter(None, files):
            src = REPO / name
            if src.is_file():
                (repo / name).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(src, repo / name)
        (self.work / "home").mkdir(exist_ok=True)
        (self.work / "dist").mkdir(exist_ok=True)
        inside = self.inside
        result = self._chroot(
            f"blender --factory-startup --command extension build --source-dir {inside}/repo "
            f"--output-dir {inside}/dist && blender --factory-startup --command extension install-file "
            f"-r user_default -e {inside}/dist/windgrass-*.zip && blender --background --python-expr "
            "'import bpy; bpy.context.preferences.view.show_splash = False; bpy.ops.wm.save_userpref()'",
            timeout=300)
        assert result.returncode == 0, result.stdout + result.stderr
        return result.stdout

    def run(self, steps: list[dict], timeout: float = 300, width: int = 1280, height: int = 800,
            name: str | None = None) -> Run:
        """One fresh Blender session (the default startup file, the installed extension) running
        ``steps`` (driver.py) in its window. ``{case}`` in a step's strings is this session's own
        folder (as Blender sees it): files written there go away with the session."""
        self.counter += 1
        tag = name or f"run{self.counter}"
        case = self.work / tag
        shutil.rmtree(case, ignore_errors=True)
        (case / "shots").mkdir(parents=True)
        shutil.copy2(HERE / "driver.py", case / "driver.py")
        inside = self.inside / tag
        (case / "scenario.json").write_text(json.dumps({"steps": steps}).replace("{case}", str(inside)))
        crash = self.root / "tmp" / "blender.crash.txt"
        crash.unlink(missing_ok=True)
        try:
            result = self._chroot(
                f"cd {inside} && export TMPDIR={inside} && xvfb-run -a -s '-screen 0 {width}x{height}x24' "
                f"blender --python {inside}/driver.py "
                f"-- {inside}/scenario.json {inside}/report.json {inside}/shots", timeout=timeout)
            returncode, output = result.returncode, result.stdout + result.stderr
        except subprocess.TimeoutExpired as exc:
            returncode, output = -1, f"timed out after {timeout} s\n{exc.stdout or ''}{exc.stderr or ''}"
            subprocess.run(["pkill", "-f", f"{inside}/driver.py"], check=False)
        report_path = case / "report.json"
        report = json.loads(report_path.read_text()) if report_path.exists() else {}
        return Run(returncode, output, report, case / "shots", crash.read_text() if crash.exists() else "")


@pytest.fixture(scope="session")
def real_blender():
    root = window_root()
    if os.geteuid() != 0:
        pytest.skip("the real-Blender tests run Debian's Blender through chroot, which needs root")
    if not (root / "usr" / "bin" / "blender").exists():
        pytest.skip(f"no Debian root with Blender at {root} (python3.11 dev.py test makes one)")
    work = Path(tempfile.mkdtemp(prefix="windgrass-window-", dir=root / "tmp"))
    try:
        blender = RealBlender(root, work)
        blender.install()
        yield blender
    finally:
        if not os.environ.get("WINDGRASS_KEEP_WINDOW_RUNS"):
            shutil.rmtree(work, ignore_errors=True)

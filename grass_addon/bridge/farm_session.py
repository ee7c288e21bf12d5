"""One Blender per farm worker session: the scene is built once, every task hands it its frames.

    blender -b --factory-startup -P farm_session.py -- start --dir SESSION_DIR
    blender -b --factory-startup -P farm_session.py -- run --dir SESSION_DIR --script TASK.py -- TASK_ARGS
    blender -b --factory-startup -P farm_session.py -- stop --dir SESSION_DIR
    python3 farm_session.py run --dir SESSION_DIR --blender BLENDER --script TASK.py -- TASK_ARGS

A task that starts its own Blender pays for the start, the scene's build and a slow first frame
every time (11-12 s a task; chunks of 1 cost 3.5 times one process). An OpenJD step environment
runs ``start`` when a worker's session begins: it starts one Blender (the server, ``serve``) and
returns when that listens on a local socket, its address in ``SESSION_DIR/windgrass-session.json``
(with a token: only this session's tasks talk to it). Each task's ``run`` (a factory-startup
Blender: about a second) sends its script and arguments; the server runs the script's
``session_task(argv)`` in its own process, where the scene built for an earlier task is still
there, and streams the task's printed lines back; ``run`` prints them and exits with the task's
status. ``stop`` (the environment's onExit) ends the server; so does its session folder going away.

Nothing is lost when the server is missing: ``run`` then renders the task in a Blender of its own,
as before (``blender -b -P TASK.py -- TASK_ARGS``). A task cancelled mid-frame ends the server (its
frame in progress is never renamed into place) and the next task starts without it. The frames
are the same either way: a Windgrass frame is a function of its number alone.

Runs in any Blender 4.5+ without the extension (standard library and ``bpy.app`` only); ``start``,
``run`` and ``stop`` with ``--blender`` also in a plain Python 3.8+ (``python3 farm_session.py run
...``: a bundle made with ``--hand-over python3``), which costs a task milliseconds, not a second.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import secrets
import signal
import socket
import subprocess
import sys
import time
import traceback
from pathlib import Path

SESSION_FILE = "windgrass-session.json"
LOG_FILE = "windgrass-session.log"
START_TIMEOUT = 120.0  # seconds the server may take to listen (one Blender start)


def _args(argv):
    parser = argparse.ArgumentParser(prog="farm_session.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("action", choices=("start", "run", "stop", "serve"))
    parser.add_argument("--dir", required=True, help="the session's working folder")
    parser.add_argument("--script", default="", help="run: the task's script (render_field.py, farm_render.py)")
    parser.add_argument("--blender", default="", help="the Blender to start (the job's BlenderExecutable; default: "
                        "this one)")
    return parser.parse_args(argv)


def _blender(args) -> str:
    if args.blender:
        return args.blender
    import bpy  # (run by a Blender)

    return bpy.app.binary_path


def _session(folder: Path) -> dict | None:
    try:
        return json.loads((folder / SESSION_FILE).read_text())
    except (OSError, ValueError):
        return None


def start(folder: Path, blender: str) -> int:
    """Start the server and wait until it listens (or has died: then the tasks run alone)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / SESSION_FILE).unlink(missing_ok=True)
    log = open(folder / LOG_FILE, "ab")
    # (its own process group, so that a signal to the starting task's group leaves it running)
    detach = ({"creationflags": getattr(subprocess, "CREATE_NEW_PROCESS_GROUP", 0) | getattr(
        subprocess, "DETACHED_PROCESS", 0)} if os.name == "nt" else {"start_new_session": True})
    server = subprocess.Popen([blender, "-b", "-P", os.path.abspath(__file__), "--", "serve", "--dir", str(folder)],
                              stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, **detach)
    began = time.monotonic()
    while time.monotonic() - began < START_TIMEOUT:
        if _session(folder) is not None:
            print(f"Windgrass session: one Blender (pid {server.pid}) renders this session's tasks "
                  f"(its log: {folder / LOG_FILE})", flush=True)
            return 0
        if server.poll() is not None:
            break
        time.sleep(0.1)
    print(f"Windgrass session: the session's Blender did not start ({folder / LOG_FILE}); each task starts "
          "its own", flush=True)
    return 0


def stop(folder: Path) -> int:
    session = _session(folder)
    if session is not None:
        try:
            with socket.create_connection(("127.0.0.1", session["port"]), timeout=10) as conn:
                conn.sendall((json.dumps({"token": session["token"], "stop": True}) + "\n").encode())
                conn.recv(16)
        except OSError:
            _kill(session)
        (folder / SESSION_FILE).unlink(missing_ok=True)
    print("Windgrass session: ended", flush=True)
    return 0


def _kill(session: dict) -> None:
    try:
        os.kill(int(session["pid"]), signal.SIGTERM)  # (on Windows: TerminateProcess)
    except (OSError, ValueError, KeyError):
        pass


def run(folder: Path, blender: str, script: str, argv: list[str]) -> int:
    """The task, by the session's Blender when it is there, else by a Blender of its own."""
    session = _session(folder)
    if session is not None:
        code = _ask(folder, session, script, argv)
        if code is not None:
            return code
        print("Windgrass session: the session's Blender is gone; this task starts its own", flush=True)
    return subprocess.call([blender, "-b", "-P", script, "--", *argv])


def _ask(folder: Path, session: dict, script: str, argv: list[str]) -> int | None:
    """The task's exit status from the server (its lines printed as they come), or None when no
    server answers. A signal that ends this task ends the server too: the frame it was rendering
    is never renamed into place."""
    try:
        conn = socket.create_connection(("127.0.0.1", session["port"]), timeout=10)
    except OSError:
        (folder / SESSION_FILE).unlink(missing_ok=True)
        return None

    def cancelled(signum, frame):
        _kill(session)
        (folder / SESSION_FILE).unlink(missing_ok=True)
        os._exit(128 + signum)

    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, cancelled)
    with conn:
        conn.settimeout(None)
        conn.sendall((json.dumps({"token": session["token"], "script": script, "argv": argv}) + "\n").encode())
        for line in conn.makefile("r", encoding="utf-8"):
            message = json.loads(line)
            if "exit" in message:
                return int(message["exit"])
            print(message.get("out", ""), end="", file=sys.stderr if message.get("err") else sys.stdout, flush=True)
    return None  # (the server died mid-task)


class _Lines:
    """A text stream whose writes go to the task's client as JSON lines."""

    def __init__(self, conn, err: bool):
        self.conn, self.err = conn, err

    def write(self, text: str) -> int:
        if text:
            message = {"out": text, "err": True} if self.err else {"out": text}
            try:
                self.conn.sendall((json.dumps(message) + "\n").encode())
            except OSError:
                pass  # (the client is gone: the task still finishes its frame)
        return len(text)

    def flush(self) -> None:
        pass


def serve(folder: Path) -> int:
    """Answer this session's tasks one at a time until told to stop or the session folder goes."""
    token = secrets.token_hex(16)
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.bind(("127.0.0.1", 0))
    listener.listen(4)
    listener.settimeout(1.0)
    address = folder / (SESSION_FILE + ".new")
    address.write_text(json.dumps({"port": listener.getsockname()[1], "token": token, "pid": os.getpid()}))
    os.replace(address, folder / SESSION_FILE)
    modules: dict[str, object] = {}
    while folder.is_dir():
        try:
            conn, _ = listener.accept()
        except TimeoutError:
            continue
        with conn:
            conn.settimeout(None)
            try:
                request = json.loads(conn.makefile("r", encoding="utf-8").readline())
            except (OSError, ValueError):
                continue
            if request.get("token") != token:
                continue
            if request.get("stop"):
                conn.sendall(b"{}\n")
                return 0
            code = _task(modules, request["script"], [str(a) for a in request["argv"]], conn)
            try:
                conn.sendall((json.dumps({"exit": code}) + "\n").encode())
            except OSError:
                pass
    return 0


def _task(modules: dict, script: str, argv: list[str], conn) -> int:
    """Run ``session_task(argv)`` of the task's script (imported once: what it built stays)."""
    out, err = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = _Lines(conn, False), _Lines(conn, True)
    try:
        module = modules.get(script)
        if module is None:
            spec = importlib.util.spec_from_file_location(f"windgrass_task_{len(modules)}", script)
            if spec is None or spec.loader is None:
                print(f"farm_session.py: {script} is not a Python script", file=sys.stderr)
                return 2
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            modules[script] = module
        return int(module.session_task(argv))
    except SystemExit as exc:  # (argparse)
        return exc.code if isinstance(exc.code, int) else 2
    except Exception:
        traceback.print_exc()
        return 1
    finally:
        sys.stdout.flush()
        sys.stdout, sys.stderr = out, err


def main(argv: list[str]) -> int:
    # (python farm_session.py ARGS, or blender ... -P farm_session.py -- ARGS)
    here = bool(argv) and os.path.abspath(argv[0]) == os.path.abspath(__file__)
    ours = argv[1:] if here or "--" not in argv else argv[argv.index("--") + 1:]
    task = []
    if "--" in ours:
        ours, task = ours[: ours.index("--")], ours[ours.index("--") + 1:]
    args = _args(ours)
    folder = Path(args.dir)
    if args.action == "start":
        return start(folder, _blender(args))
    if args.action == "stop":
        return stop(folder)
    if args.action == "serve":
        return serve(folder)
    return run(folder, _blender(args), args.script, task)


if __name__ == "__main__":
    code = main(sys.argv)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)  # (blender -b -P would go on after the script: leave with its status)

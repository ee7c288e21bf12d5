"""One Blender per farm worker session: the scene is built once, every task hands it its frames.

    blender -b --factory-startup -P farm_session.py -- start --dir SESSION_DIR
    blender -b --factory-startup -P farm_session.py -- run --dir SESSION_DIR --script TASK.py -- TASK_ARGS
    blender -b --factory-startup -P farm_session.py -- stop --dir SESSION_DIR
    python3 farm_session.py run --dir SESSION_DIR --blender BLENDER --script TASK.py -- TASK_ARGS

A task that starts its own Blender pays for the start, the scene's build and a slow first frame
every time (11-12 s a task; chunks of 1 cost 3.5 times one process). An OpenJD step environment
runs ``start`` when a worker's session begins: it starts one Blender (the server, ``serve``) and
returns when that listens. Each task's ``run`` (a factory-startup Blender: about a second) sends
its script and arguments; the server runs the script's ``session_task(argv)`` in its own process,
where the scene built for an earlier task is still there, and streams the task's printed lines
back; ``run`` prints them and exits with the task's status. ``stop`` (the environment's onExit)
ends the server; so does its session folder going away.

A render node is shared (issue #57), so only the job's own user can reach the server:

* it listens on a Unix socket in ``SESSION_DIR/.windgrass-session/``, a folder of mode 0700 owned
  by that user (a short folder of the system's temporary ones where that path is too long for a
  socket); the session file beside it (mode 0600) holds the socket's path, a token and the
  server's pid with its start stamp;
* the server closes any connection from another user at once (the peer's uid, where the system
  says it); each side proves it knows the token (an HMAC of the other's nonce), so neither a
  client nor a server that merely sits at the address is trusted, and the token never travels;
* each message is one JSON line of at most MAX_MESSAGE bytes read within READ_TIMEOUT seconds, in
  a thread of its own, so an idle or endless client holds no task up; a malformed message is
  answered with an error and the server carries on;
* ``stop`` and a cancelled task end only the process the session started (its pid and its start
  stamp both match).

Nothing is lost when the server is missing or cannot be trusted: ``run`` then renders the task in
a Blender of its own, as before (``blender -b -P TASK.py -- TASK_ARGS``), saying why. A task
cancelled mid-frame ends the server (its frame in progress is never renamed into place) and the
next task starts without it. The frames are the same either way: a Windgrass frame is a function
of its number alone.

Runs in any Blender 4.5+ without the extension (standard library and ``bpy.app`` only); ``start``,
``run`` and ``stop`` with ``--blender`` also in a plain Python 3.8+ (``python3 farm_session.py run
...``: a bundle made with ``--hand-over python3``), which costs a task milliseconds, not a second.
On a system without Unix sockets (Windows) every task starts its own Blender.
"""

from __future__ import annotations

import argparse
import hashlib
import hmac
import importlib.util
import json
import os
import queue
import secrets
import shutil
import signal
import socket
import stat
import struct
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from pathlib import Path

PRIVATE = ".windgrass-session"  # the session's own folder inside SESSION_DIR (mode 0700)
SESSION_FILE = "session.json"  # in it: the socket, the token, the server's pid and start stamp
SOCKET_FILE = "server.sock"
LOG_FILE = "windgrass-session.log"
START_TIMEOUT = 120.0  # seconds the server may take to listen (one Blender start)
READ_TIMEOUT = 10.0  # seconds a peer may take to send one whole message
MAX_MESSAGE = 1 << 20  # bytes of one message (a task's arguments are a few hundred)
MAX_SESSION_FILE = 1 << 16
SOCKET_PATH_MAX = 100  # bytes of a Unix socket's path (Linux allows 107, macOS 103)


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


class RefusedError(Exception):
    """The session cannot be used safely (its sentence says why): the task starts its own Blender."""


# --------------------------------------------------------------------------------------------
# The session's private folder and its file


def _private(folder: Path, make: bool) -> Path:
    """``folder``/PRIVATE: a real folder owned by this user that no one else may enter (made so
    when ``make``); RefusedError otherwise (a link, another user's, open to others)."""
    if not hasattr(socket, "AF_UNIX") or not hasattr(os, "getuid"):
        raise RefusedError("this system has no Unix sockets")
    path = folder / PRIVATE
    if make:
        folder.mkdir(parents=True, exist_ok=True)
        try:
            os.mkdir(path, 0o700)
        except FileExistsError:
            pass
    try:
        info = os.lstat(path)
    except OSError as exc:
        raise RefusedError(f"no session folder ({exc.strerror or exc})") from None
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid():
        raise RefusedError(f"{path} is not a folder of this user's")
    if info.st_mode & 0o077:
        if not make:
            raise RefusedError(f"{path} is open to other users (mode {stat.S_IMODE(info.st_mode):o})")
        os.chmod(path, 0o700)  # (ours: closed before anything is put in it)
    return path


def _write_private(path: Path, text: str) -> None:
    """``text`` into ``path`` (mode 0600), whole or not at all."""
    fd, temp = tempfile.mkstemp(dir=str(path.parent), prefix=".new-")  # (mkstemp's files are 0600)
    with os.fdopen(fd, "w") as fh:
        fh.write(text)
    os.replace(temp, path)


def _session(folder: Path) -> dict | None:
    """The session file's values when the folder and the file are this user's alone and the file
    says what ``serve`` writes; None otherwise (the task then starts its own Blender)."""
    try:
        private = _private(folder, make=False)
        path = private / SESSION_FILE
        fd = os.open(str(path), os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except (RefusedError, OSError):
        return None
    with os.fdopen(fd, "rb") as fh:
        info = os.fstat(fh.fileno())
        if not stat.S_ISREG(info.st_mode) or info.st_uid != os.getuid() or info.st_mode & 0o077:
            return None
        raw = fh.read(MAX_SESSION_FILE + 1)
    try:
        session = json.loads(raw.decode("utf-8")) if len(raw) <= MAX_SESSION_FILE else None
    except (UnicodeDecodeError, ValueError):
        return None
    fields = {"socket": str, "token": str, "pid": int, "stamp": str}
    if not isinstance(session, dict) or any(not isinstance(session.get(k), t) for k, t in fields.items()):
        return None
    if isinstance(session["pid"], bool) or session["pid"] <= 0 or len(session["token"]) < 32:
        return None
    return session


def _clear(folder: Path) -> None:
    try:
        (_private(folder, make=False) / SESSION_FILE).unlink()
    except (RefusedError, OSError):
        pass


# --------------------------------------------------------------------------------------------
# The server's process: known by its pid and its start stamp


def _stamp(pid: int) -> str:
    """When process ``pid`` started, as the system tells it ('' when it cannot): a pid the system
    gave to another process since has another stamp."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:  # Linux: field 22, clock ticks since boot
            fields = fh.read().rsplit(b")", 1)[1].split()
        owner = os.stat(f"/proc/{pid}").st_uid
        return f"{owner}:{fields[19].decode()}" if owner == os.getuid() else ""
    except (OSError, IndexError):
        pass
    try:  # (macOS, the BSDs)
        out = subprocess.run(["ps", "-o", "uid=,lstart=", "-p", str(pid)], capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return ""
    uid, _, started = out.stdout.strip().partition(" ")
    return f"{uid}:{started.strip()}" if out.returncode == 0 and uid == str(os.getuid()) else ""


def _end_server(session: dict) -> None:
    """End the session's server: the process the session file names, if it is still that one."""
    pid = session["pid"]
    if session["stamp"] and _stamp(pid) == session["stamp"]:
        try:
            os.kill(pid, signal.SIGTERM)
        except OSError:
            pass


# --------------------------------------------------------------------------------------------
# Messages: one JSON line each, bounded in size and time


def _proof(token: str, role: str, nonce: str) -> str:
    return hmac.new(token.encode(), f"{role}:{nonce}".encode(), hashlib.sha256).hexdigest()


class _Peer:
    """One end of a connection: JSON lines in, at most MAX_MESSAGE bytes each, within a deadline."""

    def __init__(self, conn: socket.socket):
        self.conn, self.buffer = conn, b""

    def send(self, message: dict) -> None:
        self.conn.sendall((json.dumps(message) + "\n").encode())

    def receive(self, timeout: float | None = READ_TIMEOUT) -> dict:
        """The next message (a JSON object); ValueError when it is too long, late, cut or not one."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while b"\n" not in self.buffer:
            if len(self.buffer) > MAX_MESSAGE:
                raise ValueError(f"a message of more than {MAX_MESSAGE:,} bytes")
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                raise ValueError(f"no whole message within {timeout:g} s")
            self.conn.settimeout(left)
            try:
                more = self.conn.recv(65536)
            except socket.timeout:  # noqa: UP041 (Python 3.8, the hand-over's oldest: not yet TimeoutError)
                raise ValueError(f"no whole message within {timeout:g} s") from None
            if not more:
                raise ValueError("the connection closed mid-message" if self.buffer else "the connection closed")
            self.buffer += more
        line, self.buffer = self.buffer.split(b"\n", 1)
        if len(line) > MAX_MESSAGE:
            raise ValueError(f"a message of more than {MAX_MESSAGE:,} bytes")
        try:
            message = json.loads(line.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError):  # (a megabyte of [[[[...)
            raise ValueError("a message that is not JSON (or nested too deeply)") from None
        if not isinstance(message, dict):
            raise ValueError(f"a message that is a JSON {type(message).__name__}, not an object")
        return message


def _peer_uid(conn: socket.socket) -> int | None:
    """The uid of the process at the other end (Linux), else None."""
    option = getattr(socket, "SO_PEERCRED", None)
    if option is None:
        return None
    try:
        _, uid, _ = struct.unpack("3i", conn.getsockopt(socket.SOL_SOCKET, option, struct.calcsize("3i")))
    except OSError:
        return None
    return uid


def _request(message: dict) -> dict:
    """A task's or a stop's request, checked; ValueError says what is wrong with it."""
    action = message.get("action")
    if action == "stop":
        return {"action": "stop"}
    if action != "run":
        raise ValueError("a request that is neither 'run' nor 'stop'")
    script, argv = message.get("script"), message.get("argv")
    if not isinstance(script, str) or not script:
        raise ValueError("a task without its script (a text)")
    if not isinstance(argv, list) or not all(isinstance(a, str) for a in argv):
        raise ValueError("a task whose 'argv' is not a list of texts")
    return {"action": "run", "script": script, "argv": argv}


# --------------------------------------------------------------------------------------------
# start, stop, run: the worker's side


def start(folder: Path, blender: str) -> int:
    """Start the server and wait until it listens (or has died: then the tasks run alone)."""
    try:
        private = _private(folder, make=True)
    except (RefusedError, OSError) as exc:
        print(f"Windgrass session: no session's Blender ({exc}); each task starts its own", flush=True)
        return 0
    (private / SESSION_FILE).unlink(missing_ok=True)
    fd = os.open(str(private / LOG_FILE), os.O_WRONLY | os.O_CREAT | os.O_APPEND | getattr(os, "O_NOFOLLOW", 0), 0o600)
    log = os.fdopen(fd, "ab")
    # (its own process group, so that a signal to the starting task's group leaves it running)
    server = subprocess.Popen([blender, "-b", "-P", os.path.abspath(__file__), "--", "serve", "--dir", str(folder)],
                              stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    began = time.monotonic()
    while time.monotonic() - began < START_TIMEOUT:
        if _session(folder) is not None:
            print(f"Windgrass session: one Blender (pid {server.pid}) renders this session's tasks "
                  f"(its log: {private / LOG_FILE})", flush=True)
            return 0
        if server.poll() is not None:
            break
        time.sleep(0.1)
    print(f"Windgrass session: the session's Blender did not start ({private / LOG_FILE}); each task starts "
          "its own", flush=True)
    return 0


def _connect(session: dict) -> tuple[_Peer, str]:
    """A connection to the session's server that proved it holds the token, and our nonce's proof
    of the same; RefusedError (with why) otherwise."""
    conn = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        conn.settimeout(READ_TIMEOUT)
        conn.connect(session["socket"])
        peer = _Peer(conn)
        owner = _peer_uid(conn)
        if owner is not None and owner != os.getuid():
            raise RefusedError("another user's process listens at the session's address")
        hello = peer.receive()
        if not isinstance(hello.get("nonce"), str):
            raise RefusedError("what listens at the session's address is not the session's Blender")
        return peer, _proof(session["token"], "client", hello["nonce"])
    except (OSError, ValueError) as exc:
        conn.close()
        raise RefusedError(f"the session's Blender does not answer ({exc})") from None
    except RefusedError:
        conn.close()
        raise


def _ask(session: dict, request: dict, lines: bool = True) -> int | None:
    """Send ``request`` to the session's server; the task's exit status (its lines printed as they
    come), or None when the server is gone or cannot prove it is the session's."""
    try:
        peer, proof = _connect(session)
    except RefusedError as exc:
        print(f"Windgrass session: {exc}", flush=True)
        return None
    nonce = secrets.token_hex(16)
    with peer.conn:
        try:
            peer.send({**request, "proof": proof, "nonce": nonce})
            answer = peer.receive()
        except (OSError, ValueError) as exc:
            print(f"Windgrass session: the session's Blender does not answer ({exc})", flush=True)
            return None
        if not hmac.compare_digest(str(answer.get("proof", "")), _proof(session["token"], "server", nonce)):
            print(f"Windgrass session: what listens at the session's address did not prove it is the session's "
                  f"Blender ({answer.get('error', 'no proof')})", flush=True)
            return None
        while True:
            try:
                message = peer.receive(timeout=None)  # (a proven server: a frame may take minutes)
            except (OSError, ValueError):
                return None  # (the server died mid-task)
            if "exit" in message:
                return int(message["exit"]) if isinstance(message["exit"], int) else 1
            if lines:
                print(message.get("out", ""), end="", file=sys.stderr if message.get("err") else sys.stdout,
                      flush=True)


def stop(folder: Path) -> int:
    session = _session(folder)
    if session is not None:
        if _ask(session, {"action": "stop"}, lines=False) is None:
            _end_server(session)
        _clear(folder)
    print("Windgrass session: ended", flush=True)
    return 0


def run(folder: Path, blender: str, script: str, argv: list[str]) -> int:
    """The task, by the session's Blender when it is there, else by a Blender of its own."""
    session = _session(folder)
    if session is not None:

        def cancelled(signum, frame):  # (the frame it was rendering is never renamed into place)
            _end_server(session)
            _clear(folder)
            os._exit(128 + signum)

        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, cancelled)
        code = _ask(session, {"action": "run", "script": script, "argv": argv})
        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, signal.SIG_DFL)
        if code is not None:
            return code
        _clear(folder)
        print("Windgrass session: the session's Blender is gone; this task starts its own", flush=True)
    return subprocess.call([blender, "-b", "-P", script, "--", *argv])


# --------------------------------------------------------------------------------------------
# serve: the session's Blender


class _Lines:
    """A text stream whose writes go to the task's client as JSON lines."""

    def __init__(self, peer: _Peer, err: bool):
        self.peer, self.err = peer, err

    def write(self, text: str) -> int:
        for begin in range(0, len(text), 65536):  # (each message well within MAX_MESSAGE)
            piece = text[begin:begin + 65536]
            try:
                self.peer.send({"out": piece, "err": True} if self.err else {"out": piece})
            except OSError:
                pass  # (the client is gone: the task still finishes its frame)
        return len(text)

    def flush(self) -> None:
        pass


def _socket_path(private: Path) -> tuple[Path, Path | None]:
    """Where the server listens, and a folder made for it (None: the private folder itself)."""
    path = private / SOCKET_FILE
    if len(os.fsencode(str(path))) <= SOCKET_PATH_MAX:
        return path, None
    short = Path(tempfile.mkdtemp(prefix="windgrass-"))  # (mode 0700, this user's)
    return short / SOCKET_FILE, short


def _greet(conn: socket.socket, token: str, tasks: queue.Queue) -> None:
    """One connection: the peer's uid, the nonces' proofs, the request checked; a good request
    goes to the task queue (the main thread runs tasks), anything else gets its error."""
    peer = _Peer(conn)
    try:
        uid = _peer_uid(conn)
        if uid is not None and uid != os.getuid():
            conn.close()  # (another user's: not a word)
            return
        nonce = secrets.token_hex(16)
        peer.send({"nonce": nonce})
        message = peer.receive()
        if not hmac.compare_digest(str(message.get("proof", "")), _proof(token, "client", nonce)):
            raise ValueError("not this session's task (no proof of its token)")
        request = _request(message)
        if not isinstance(message.get("nonce"), str) or not message["nonce"]:
            raise ValueError("a request without its nonce")
        peer.send({"proof": _proof(token, "server", message["nonce"])})
    except (OSError, ValueError) as exc:
        try:
            peer.send({"error": str(exc)})
        except OSError:
            pass
        conn.close()
        return
    except Exception:  # (nothing a peer sends may end this thread with its connection open)
        conn.close()
        raise
    tasks.put((peer, request))


def _accept(listener: socket.socket, token: str, tasks: queue.Queue, done: threading.Event) -> None:
    while not done.is_set():
        try:
            conn, _ = listener.accept()
        except socket.timeout:  # noqa: UP041 (Python 3.8: not yet TimeoutError)
            continue
        except OSError:
            return
        threading.Thread(target=_greet, args=(conn, token, tasks), daemon=True).start()


def serve(folder: Path) -> int:
    """Answer this session's tasks one at a time until told to stop or the session folder goes."""
    private = _private(folder, make=True)
    path, short = _socket_path(private)
    token = secrets.token_hex(32)
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old = os.umask(0o177)
    try:
        path.unlink(missing_ok=True)
        listener.bind(str(path))
    finally:
        os.umask(old)
    listener.listen(16)
    listener.settimeout(1.0)
    _write_private(private / SESSION_FILE, json.dumps({"socket": str(path), "token": token, "pid": os.getpid(),
                                                        "stamp": _stamp(os.getpid())}))
    tasks: queue.Queue = queue.Queue()
    done = threading.Event()
    threading.Thread(target=_accept, args=(listener, token, tasks, done), daemon=True).start()
    modules: dict[str, object] = {}
    try:
        while folder.is_dir():
            try:
                peer, request = tasks.get(timeout=1.0)
            except queue.Empty:
                continue
            with peer.conn:
                if request["action"] == "stop":
                    peer.send({"exit": 0})
                    return 0
                code = _task(modules, request["script"], request["argv"], peer)
                try:
                    peer.send({"exit": code})
                except OSError:
                    pass
        return 0
    finally:
        done.set()
        listener.close()
        path.unlink(missing_ok=True)
        if short is not None:
            shutil.rmtree(short, ignore_errors=True)


def _task(modules: dict, script: str, argv: list[str], peer: _Peer) -> int:
    """Run ``session_task(argv)`` of the task's script (imported once: what it built stays)."""
    out, err = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = _Lines(peer, False), _Lines(peer, True)
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
    folder = Path(args.dir).expanduser()
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

"""Drives Windgrass in Blender as an artist would, step by step, and checks the field after each.

Runs inside Blender: in a real Blender window (``tests/window``: ``blender --python driver.py --
SCENARIO REPORT``, each step on a timer so that Blender draws and handles events between steps,
keys typed by ``xdotool``) or in the ``bpy`` module (``tests/blender``: ``run_steps`` in a loop).
No pytest here: the report (JSON) says what happened and the tests assert on it.

A step is a dict; its one action key says what it does:
  ``{"op": "windgrass.field_add", "args": {...}}``  an operator, called as the UI calls it (an undo
                                                   step is pushed after it, as the window does);
  ``{"set": "windgrass.fields[0].field.seed", "value": 3}``  a property of the scene edited as in
                                                   the panel (its update runs, then an undo step);
  ``{"key": "ctrl+z"}``                            a key typed over the 3D view (window only; the
                                                   bpy module runs the operator it is bound to);
  ``{"undo": 1}`` / ``{"redo": 1}``                 ``ed.undo`` / ``ed.redo`` as operators;
  ``{"frame": 1}``                                 a frame change by that many frames;
  ``{"wait": 0.5}``                                seconds for timers and events (window only);
  ``{"settle": "shaders", "max": 900}``            until EEVEE's shaders are compiled (``"view"``:
                                                   until the screen stays the same for a second; or
                                                   until a few lines of Python set ``result`` true), as
                                                   long as it takes (at most ``max`` s): progress, not
                                                   a guess;
  ``{"check": "fields"}``                          every field matches its settings and shows grass;
  ``{"view": {...}}``, ``{"shading": "SOLID"}``, ``{"shot": "name"}``, ``{"save": path}``,
  ``{"open": path}``, ``{"probe": "name"}``, ``{"sidebar": "Grass"}``, ``{"quit": true}``: see
  ``Driver``'s methods of those names.
``"optional": true`` on a step: an operator whose poll fails, or an edit of a field that is not
there (random sequences), is recorded as skipped instead of failing.
Every step's outcome (and any Python error) goes to the report; a crash of Blender shows as the
process's exit status and ``blender.crash.txt``.
"""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import time
import traceback

import bpy
import numpy as np

UI_EDIT_SETTLE_S = 0.4  # longer than runtime.EDIT_SETTLE_S: the deferred engine update has run


def addon():
    """The loaded Windgrass package, whatever name it was loaded by (``windgrass`` in the tests,
    ``bl_ext.user_default.windgrass`` when installed as an extension)."""
    for name, module in sys.modules.items():
        if (name == "windgrass" or name.endswith(".windgrass")) and hasattr(module, "register"):
            if f"{name}.grass_addon" in sys.modules:
                return module
    raise RuntimeError("the Windgrass add-on is not loaded")


def bridge(name: str):
    return sys.modules[f"{addon().__name__}.grass_addon.bridge.{name}"]


def view3d():
    """(window, area, region) of the largest 3D view, or Nones in background mode."""
    wm = bpy.context.window_manager
    best = (None, None, None)
    size = -1
    for win in wm.windows:
        for area in win.screen.areas:
            if area.type == "VIEW_3D" and area.width * area.height > size:
                region = next(r for r in area.regions if r.type == "WINDOW")
                best, size = (win, area, region), area.width * area.height
    return best


def _resolve_path(path: str):
    """(owner, attribute) of a data path relative to the scene: ``windgrass.fields[0].field.seed``."""
    owner_path, attr = path.rsplit(".", 1)
    owner = eval("bpy.context.scene." + owner_path, {"bpy": bpy})  # test scenarios only
    return owner, attr


def field_state(scene, item) -> dict:
    """What a person sees of a field, and whether it matches its settings."""
    runtime, properties, owned = bridge("runtime"), bridge("properties"), bridge("owned")
    out = {"name": item.name, "error": runtime.field_error(scene, item), "baked": item.get("wg_bake") is not None}
    if item.collection is None:
        out["objects"] = False
        return out
    out["objects"] = True
    try:
        params = properties.params_from_settings(item, scene)
    except Exception as exc:  # a setting out of range: reported as such
        out["settings_error"] = str(exc)
        return out
    heightfield = runtime.terrain_of(scene, item, params)[0]
    wanted = runtime.topology_of(params, heightfield, item)
    out["topology_matches"] = item.collection.get(owned.TOPOLOGY) == wanted
    rt = runtime.get_runtime(scene, item)
    out["runtime_matches"] = rt is not None and not rt.stale and rt.params.digest() == params.digest()
    out["frame_written"] = None if rt is None else rt.frame
    shown, saved = 0, 0
    for role in (owned.ROLE_BLADES, owned.ROLE_CARDS):
        for obj in owned.slot_objects(item, role).values():
            saved += int(not obj.is_runtime_data) + int(not obj.data.is_runtime_data)  # what a file would hold
            n = len(obj.data.vertices)
            if n:
                co = np.empty(n * 3, np.float32)
                obj.data.attributes["position"].data.foreach_get("vector", co)
                shown += int(np.count_nonzero(np.abs(co.reshape(-1, 3)).max(axis=1) > 0))
    out["vertices_shown"] = shown
    out["slots_saved"] = saved
    out["blade_objects"] = len(owned.slot_objects(item, owned.ROLE_BLADES))
    return out


def fields_ok(states: list[dict]) -> list[str]:
    """What is wrong with the fields (empty: each matches its settings and shows grass)."""
    problems = []
    for s in states:
        if s.get("baked") or not s.get("objects"):
            continue
        if s.get("settings_error"):
            continue  # a bad setting is reported in the panel; not what undo is about
        if s.get("error") and re.match(r"^[a-z_]+(\.[a-z_0-9\[\]]+)+: ", s["error"]):
            # settings that cannot be simulated (a paint source that needs a terrain): the grass
            # is hidden and the panel says why; it must not show another state's grass
            if s.get("vertices_shown"):
                problems.append(f"{s['name']}: grass shown although it cannot be simulated ({s['error']})")
            continue
        for key, text in (("topology_matches", "objects do not match the settings"),
                          ("runtime_matches", "the engine does not match the settings")):
            if not s.get(key):
                problems.append(f"{s['name']}: {text}")
        if s.get("error"):
            problems.append(f"{s['name']}: error {s['error']}")
        if not s.get("vertices_shown"):
            problems.append(f"{s['name']}: no grass shown")
        if s.get("slots_saved"):
            problems.append(f"{s['name']}: {s['slots_saved']} slot objects or meshes would be written into files "
                            "(saves, autosaves, quit.blend)")
    return problems


class Driver:
    def __init__(self, steps: list[dict], report_path: str | None = None, shots: str | None = None):
        self.steps = list(steps)
        self.report_path = report_path
        self.shots = shots
        self.report = {"blender": bpy.app.version_string, "background": bpy.app.background,
                       "alembic": bool(getattr(bpy.app.build_options, "alembic", False)), "steps": []}
        self.index = 0
        self.messages: list[str] = []
        self.settling: tuple | None = None  # (started, quiet since) while a settle step waits
        self.last_screen: np.ndarray | None = None  # the screen a second ago (settle "view")
        self.started = time.monotonic()

    # ---------------------------------------------------------------- running

    def run_background(self) -> dict:
        """Every step at once (the bpy module: no event loop)."""
        while self.index < len(self.steps):
            self._do(self.steps[self.index])
            self.index += 1
        return self.report

    def start_window(self) -> None:
        bpy.app.timers.register(self._tick, first_interval=1.0, persistent=True)  # (survives file loads)

    def _tick(self):
        if self.index >= len(self.steps):
            self._finish()
            return None
        step = self.steps[self.index]
        self.index += 1
        delay = self._do(step)
        return delay if delay is not None else 0.2

    def _finish(self) -> None:
        self.report["finished"] = True
        self._write_report()
        os._exit(0)  # quit at once, with status 0 (the report says how the steps went)

    def _write_report(self) -> None:
        if self.report_path:
            with open(self.report_path, "w") as f:
                json.dump(self.report, f, indent=1, default=str)

    def _do(self, step: dict):
        record = {"step": step, "at": round(time.monotonic() - self.started, 1)}  # (s since the driver began)
        self.report["steps"].append(record)
        delay = None
        try:
            kind = next(k for k in step if k not in ("args", "value", "note", "optional"))
            began = time.monotonic()
            result = getattr(self, f"do_{kind}")(step[kind], step)
            record["took"] = round(time.monotonic() - began, 3)  # (s the step itself held the window)
            if isinstance(result, tuple):
                result, delay = result
            record["result"] = result
        except Exception as exc:
            if step.get("optional") and isinstance(exc, (IndexError, RuntimeError)):
                record["skipped"] = str(exc)  # (fuzzing: an edit when undo removed every field)
            else:
                record["exception"] = "".join(traceback.format_exception(exc))
        self._write_report()  # a crash later still leaves what happened so far
        return delay

    # ---------------------------------------------------------------- actions

    def _context(self):
        win, area, region = view3d()
        if win is None:
            return {}
        return {"window": win, "area": area, "region": region, "screen": win.screen}

    def do_op(self, name: str, step: dict):
        module, op = name.split(".")
        func = getattr(getattr(bpy.ops, module), op)
        args = step.get("args", {})
        if step.get("invoke"):  # as a button or menu entry runs it (dialogs, modal operators)
            try:
                with bpy.context.temp_override(**self._context()):
                    return sorted(func("INVOKE_DEFAULT", True, **args)), UI_EDIT_SETTLE_S
            except RuntimeError as exc:  # the operator reported an error
                return {"error": str(exc)}, UI_EDIT_SETTLE_S
        with bpy.context.temp_override(**self._context()):
            if bpy.app.background:  # (the module segfaults on an operator's own undo push)
                result = func("EXEC_DEFAULT", **args)
                if "FINISHED" in result:
                    bpy.ops.ed.undo_push(message=name)
            else:  # as the UI calls it: with the undo push Blender makes after a UI operator
                result = func("EXEC_DEFAULT", True, **args)
        return sorted(result), (None if bpy.app.background else UI_EDIT_SETTLE_S)

    def do_set(self, path: str, step: dict):
        owner, attr = _resolve_path(path)
        value = step["value"]
        setattr(owner, attr, value)  # the property's update runs, as when typed in the panel
        with bpy.context.temp_override(**self._context()):
            bpy.ops.ed.undo_push(message=f"{attr} = {value}")  # as the window does after an edit
        return getattr(owner, attr), (None if bpy.app.background else UI_EDIT_SETTLE_S)

    def do_drag(self, path: str, step: dict):
        """One step of a slider dragged with the mouse: the value set as the slider sets it while
        the mouse moves (its update runs; no undo step: the window pushes one when the drag
        ends, a ``set``), then ``wait`` s (default 0.1) before the next step, as a hand moves on."""
        owner, attr = _resolve_path(path)
        setattr(owner, attr, step["value"])
        return getattr(owner, attr), float(step.get("wait", 0.1))

    def do_key(self, keys: str, step: dict):
        if bpy.app.background:  # the operator the key is bound to
            return self.do_undo(1, step) if keys == "ctrl+z" else self.do_redo(1, step)
        win, area, region = view3d()
        x = win.x + region.x + region.width // 2
        y = win.height - (region.y + region.height // 2)
        subprocess.run(["xdotool", "mousemove", str(x), str(y)], check=True, timeout=10)
        subprocess.run(["xdotool", "key", "--clearmodifiers", keys], check=True, timeout=10)
        return keys, 1.0  # Blender handles the key after this timer returns

    def do_undo(self, times: int, step: dict):
        with bpy.context.temp_override(**self._context()):
            results = [sorted(bpy.ops.ed.undo()) for _ in range(int(times))]
        return results, (None if bpy.app.background else UI_EDIT_SETTLE_S)

    def do_redo(self, times: int, step: dict):
        with bpy.context.temp_override(**self._context()):
            results = [sorted(bpy.ops.ed.redo()) for _ in range(int(times))]
        return results, (None if bpy.app.background else UI_EDIT_SETTLE_S)

    def do_frame(self, delta: int, step: dict):
        scene = bpy.context.scene
        scene.frame_set(scene.frame_current + int(delta))
        return scene.frame_current

    def do_wait(self, seconds: float, step: dict):
        return seconds, float(seconds)

    def do_settle(self, what: str, step: dict):
        """Polled each second (the step repeats itself) until ``what`` holds: ``"shaders"``, no
        shader compilation has run for three seconds in a row; else a few lines of Python setting
        ``result`` (as ``python`` steps), true once done. At most ``max`` seconds: on a loaded
        machine it waits longer instead of failing. The result: seconds waited and whether it
        still had not settled."""
        if bpy.app.background:
            return {"waited": 0.0, "settled": True}, None
        now = time.monotonic()
        start, quiet = self.settling or (now, None)
        if what == "shaders":
            busy = bpy.app.is_job_running("SHADER_COMPILATION")
            quiet = None if busy else (quiet or now)
            done = quiet is not None and now - quiet >= 3.0
        elif what == "view":
            done = self._screen_still()
        else:
            done = bool(self.do_python(what, step))
        if not done and now - start < float(step.get("max", 900)):
            self.settling = (start, quiet)
            self.index -= 1  # (this step again in a second, recorded once)
            self.report["steps"].pop()
            return None, 1.0
        self.settling = self.last_screen = None
        return {"waited": round(now - start, 1), "settled": done}, 0.2

    def _screen_still(self) -> bool:
        """The screen is the same as a second ago (the viewport has gathered its samples: its
        first ones are noisy; mean difference under 0.1 %)."""
        ppm = subprocess.run("xwd -root -silent | xwdtopnm 2>/dev/null", shell=True, capture_output=True,
                             check=True, timeout=60).stdout
        magic, width, height, top, pixels = ppm.split(maxsplit=4)
        image = np.frombuffer(pixels[:int(width) * int(height) * 3], np.uint8).astype(np.float32) / float(top)
        last, self.last_screen = self.last_screen, image
        return last is not None and last.shape == image.shape and float(np.abs(image - last).mean()) < 1e-3

    def do_check(self, what: str, step: dict):
        states = [field_state(s, item) for s in bpy.data.scenes if hasattr(s, "windgrass")
                  for item in s.windgrass.fields]
        return {"fields": states, "problems": fields_ok(states)}

    def do_probe(self, what: str, step: dict):
        """Values a test asserts on: ``selected``, ``materials``, ``lod`` (blocks per pool)."""
        scene = bpy.context.scene
        if what == "lod":
            runtime = bridge("runtime")
            out = {}
            for item in scene.windgrass.fields:
                rt = runtime.get_runtime(scene, item)
                out[item.name] = None if rt is None else {"blade_blocks": [int(b) for b in rt.blades.blocks],
                                                          "card_blocks": [int(b) for b in rt.cards.blocks],
                                                          "blades_drawn": rt.blades_drawn}
            return out
        if what == "engine":  # what each field's engine runs now: its wind speed and stiffness
            runtime = bridge("runtime")
            out = {}
            for item in scene.windgrass.fields:
                rt = runtime.get_runtime(scene, item)
                out[item.name] = None if rt is None or not rt.built else {
                    "wind_speed": rt.params.wind.speed, "root_stiffness": rt.params.blade.root_stiffness}
            return out
        if what == "objects":
            return sorted(o.name for o in scene.objects)
        if what == "materials":
            return {m.name: list(m.diffuse_color) for m in bpy.data.materials}
        raise ValueError(f"unknown probe {what!r}")

    def do_view(self, view: dict, step: dict):
        """Place the largest 3D view (``"area": i``: the i-th from the left): ``{"location": [x, y,
        z], "distance": d, "rotation": [w, x, y, z]}``, ``{"look": [eye, target]}`` or
        ``{"perspective": "CAMERA"}``; then let the viewport follow."""
        win, area, region = view3d()
        if "area" in view:
            areas = sorted((a for a in win.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.x)
            area = areas[view["area"]]
        r3d = area.spaces.active.region_3d
        if "perspective" in view:
            r3d.view_perspective = view["perspective"]
        if "location" in view:
            r3d.view_location = view["location"]
        if "distance" in view:
            r3d.view_distance = view["distance"]
        if "rotation" in view:
            r3d.view_rotation = view["rotation"]
        if "look" in view:  # eye and target: the rotation that looks from one at the other
            from mathutils import Vector
            eye, target = Vector(view["look"][0]), Vector(view["look"][1])
            direction = target - eye
            r3d.view_rotation = direction.to_track_quat("-Z", "Y")
            r3d.view_location = target
            r3d.view_distance = direction.length
            r3d.view_perspective = "PERSP"
        area.tag_redraw()
        return [list(r3d.view_location), r3d.view_distance, r3d.view_perspective], 1.0

    def do_sidebar(self, category: str, step: dict):
        """Show the largest 3D view's sidebar and turn to its ``category`` tab: each step clicks
        the next place down the tab strip (its right edge) until the tab is ``category``; repeat
        the step until the result names it."""
        win, area, region = view3d()
        area.spaces.active.show_region_ui = True
        ui = next(r for r in area.regions if r.type == "UI")
        tries = self.__dict__.setdefault("_tab_tries", [0])
        if ui.width > 1 and ui.active_panel_category != category and not bpy.app.background:
            scale = bpy.context.preferences.system.ui_scale
            x = win.x + ui.x + ui.width - int(10 * scale)
            y = win.height - (ui.y + ui.height) + int((20 + 24 * tries[0]) * scale)
            tries[0] += 1
            subprocess.run(["xdotool", "mousemove", str(x), str(y), "click", "1"], check=True, timeout=10)
        area.tag_redraw()
        return {"category": ui.active_panel_category, "width": ui.width}, 0.5

    def do_split(self, direction: str, step: dict):
        """Split the largest 3D view in two (``VERTICAL``: side by side)."""
        win, area, region = view3d()
        with bpy.context.temp_override(window=win, screen=win.screen, area=area, region=region):
            result = bpy.ops.screen.area_split(direction=direction, factor=0.5)
        return sorted(result), 1.0

    def do_shading(self, kind: str, step: dict):
        win, area, region = view3d()
        area.spaces.active.shading.type = kind
        area.tag_redraw()
        return kind, 1.5

    def do_shot(self, name: str, step: dict):
        """A screenshot of the whole virtual screen (X's own image of it)."""
        if bpy.app.background or not self.shots:
            return None
        path = os.path.join(self.shots, f"{name}.png")
        subprocess.run(f"xwd -root -silent | xwdtopnm 2>/dev/null | pnmtopng > '{path}'", shell=True, check=True,
                       timeout=60)
        return path

    def do_save(self, path: str, step: dict):
        """File > Save As (``args``: the operator's options, e.g. ``{"compress": true}``); the
        result: the operator's and the file's size."""
        with bpy.context.temp_override(**self._context()):
            result = bpy.ops.wm.save_as_mainfile(filepath=path, **step.get("args", {}))
        return [sorted(result), os.path.getsize(path)]

    def do_quit(self, _value, step: dict):
        """File > Quit (no save prompt): the report is finished now, Blender then exits its own way,
        writing quit.blend into its temporary folder (window only; the last step)."""
        bpy.context.preferences.view.use_save_prompt = False
        self.report["finished"] = True
        self.index = len(self.steps) + 1  # (no _finish: Blender's exit ends the session)
        with bpy.context.temp_override(**self._context()):
            bpy.ops.wm.quit_blender()
        return "quitting", 60.0

    def do_open(self, path: str, step: dict):
        with bpy.context.temp_override(**self._context()):
            result = bpy.ops.wm.open_mainfile(filepath=path)
        return sorted(result), 1.0

    def do_select(self, name: str | None, step: dict):
        """Select (and make active) one object by name, or nothing (None)."""
        for obj in bpy.context.view_layer.objects:
            obj.select_set(False)
        if name is not None:
            obj = bpy.data.objects[name]
            obj.select_set(True)
            bpy.context.view_layer.objects.active = obj
        return name

    def do_python(self, code: str, step: dict):
        """A few lines of Python (the result of the last expression ``result = ...``)."""
        scope = {"bpy": bpy, "np": np, "math": math, "bridge": bridge, "result": None}
        exec(code, scope)
        return scope["result"]


def main() -> None:
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    with open(argv[0]) as f:
        scenario = json.load(f)
    driver = Driver(scenario["steps"], report_path=argv[1], shots=argv[2] if len(argv) > 2 else None)
    driver.start_window()


if __name__ == "__main__":
    main()

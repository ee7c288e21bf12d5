"""What an edit of a setting changes: each parameter belongs to one part of a field.

A slider edit updates only its part (``GrassField.retune``), so an edit of the wind does not make
the field's blocks again, and an edit of a colour does not simulate again. Every part keeps the
frame bit-identical to a fresh build of the same settings (``tests/blender/test_live_edits.py``
checks each setting):

========== ============================================== ==========================================
part       settings                                       what an edit does
========== ============================================== ==========================================
layout     the grid, seed, blade shapes (eqs 1-6),        the blocks are made again (a new engine);
           species' shapes and shares, terrain, paint     of the stiffness (blocks.reshapes), from
                                                          the blades they grew: rest shapes anew
wind       wind.*, the clock (fps, first frame)           a new wind and solver run; blocks kept
physics    the solver's constants (eqs 14-32), sub-steps  a new solver run; blocks and wind kept
lod        LOD distances and card width (eqs 7-11)        the next frame's LOD; the run kept
look       colours (species', heads', floor, haze, sun)   the layout's colours; the run kept
render     resolution, samples, camera, frame end, ...    nothing in the engine
========== ============================================== ==========================================

A parameter not named below is ``layout``: the safe part (everything is made again).
"""

from __future__ import annotations

import functools
import hashlib
import json
import threading
from collections import OrderedDict
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import numpy as np

from . import schema

LAYOUT, WIND, PHYSICS, LOD, LOOK, RENDER = "layout", "wind", "physics", "lod", "look", "render"
PARTS = (LAYOUT, WIND, PHYSICS, LOD, LOOK, RENDER)

# Parts that run the solver again (the frame's state depends on them).
SIMULATED = frozenset({LAYOUT, WIND, PHYSICS})

_PART_OF: dict[str, str] = {
    **{f"wind.{p.key}": WIND for p in schema.section_params("wind")},
    **{f"render.{k}": WIND for k in ("fps", "fps_base", "frame_start")},
    "simulation.loop": WIND,
    **{f"blade.{k}": PHYSICS for k in ("nonlinear_stiffness", "response_torque", "twist_stiffness", "damping_mass",
                                      "air_damping", "damping_stiffness", "boundary_k", "boundary_lambda")},
    **{f"simulation.{k}": PHYSICS for k in ("sub_steps", "preroll", "epoch")},
    **{f"interaction.{k}": PHYSICS for k in ("recovery", "tolerance")},
    **{f"lod.{k}": LOD for k in ("blade_near", "blade_far", "card_near", "card_far", "card_width",
                                  "viewport_amount", "screen_size")},
    "field.floor": LOOK,
    **{f"render.{k}": LOOK for k in ("sun_elevation", "sun_azimuth", "haze_distance", "haze_color")},
    **{f"render.{k}": RENDER for k in ("engine", "samples", "resolution_x", "resolution_y", "frame_end",
                                       "motion_blur", "shutter")},
    **{f"camera.{p.key}": RENDER for p in schema.section_params("camera")},
    "simulation.memory_mb": RENDER,  # (a check before anything is built)
}

# Columns of a species row whose edit changes only its look (any other column changes its blades).
SPECIES_LOOK = frozenset({"name", "color", "head_color"})


def part_of(name: str) -> str:
    """The part the parameter ``name`` ("wind.speed") belongs to."""
    return _PART_OF.get(name, LAYOUT)


def species_columns(old: tuple[Mapping[str, Any], ...], new: tuple[Mapping[str, Any], ...]) -> set[str] | None:
    """The columns that differ between two species tables, None when their rows differ in number."""
    if len(old) != len(new):
        return None
    return {k for a, b in zip(old, new) for k in set(a) | set(b) if a.get(k) != b.get(k)}


def _species_part(old: tuple[Mapping[str, Any], ...], new: tuple[Mapping[str, Any], ...]) -> str | None:
    if old == new:
        return None
    columns = species_columns(old, new)
    return LOOK if columns is not None and columns <= SPECIES_LOOK else LAYOUT


def changed_settings(old: schema.Params, new: schema.Params) -> list[tuple[str, Any, Any]]:
    """(name, value in ``old``, value in ``new``) of each setting that differs."""
    a, b = old.to_dict(), new.to_dict()
    return [(f"{section}.{key}", a[section][key], value) for section, values in b.items()
            for key, value in values.items() if a[section][key] != value]


def changed_parts(old: schema.Params, new: schema.Params) -> frozenset[str]:
    """The parts of a field that differ between the settings ``old`` and ``new``."""
    parts = (_species_part(a, b) if name == "blade.species" else part_of(name)
             for name, a, b in changed_settings(old, new))
    return frozenset(part for part in parts if part is not None)


def digest_of(params: schema.Params, parts: Iterable[str]) -> str:
    """A digest of the settings of ``parts`` alone (of the species table, its look columns for
    ``look``, the others for ``layout``): what is computed from those settings alone (the blocks,
    the sward's look, the card atlas) is kept by it through edits of other parts."""
    wanted = set(parts)
    values: dict[str, Any] = {}
    for section, entries in params.to_dict().items():
        for key, value in entries.items():
            name = f"{section}.{key}"
            if name == "blade.species":
                looks, shapes = LOOK in wanted, LAYOUT in wanted
                if looks or shapes:
                    values[name] = [{k: v for k, v in row.items() if (k in SPECIES_LOOK and looks)
                                     or (k not in SPECIES_LOOK and shapes)} for row in value]
            elif part_of(name) in wanted:
                values[name] = value
    return hashlib.sha1(json.dumps(values, sort_keys=True, default=str).encode()).hexdigest()


def remembered(parts: Iterable[str], keep: int = 8) -> Callable:
    """Decorate ``f(params, *args, **kwargs)``, a function of the settings of ``parts`` alone (and
    small arguments: numbers, arrays): its answers are kept for the ``keep`` settings last asked, so
    an edit of another part costs nothing, and work done ahead (``look.prepare``, on a thread)
    is not done again. Each call gets its own copy of the answer's arrays (callers may write to
    them); thread-safe."""
    wanted = tuple(parts)

    def wrap(compute: Callable) -> Callable:
        answers: OrderedDict[tuple, Any] = OrderedDict()
        lock = threading.Lock()

        def key_of(params, args, kwargs) -> tuple:
            return (digest_of(params, wanted), tuple(_argument_key(a) for a in args),
                    tuple((k, _argument_key(v)) for k, v in sorted(kwargs.items())))

        @functools.wraps(compute)
        def call(params, *args, **kwargs):
            key = key_of(params, args, kwargs)
            with lock:
                found = answers.get(key)
            if found is None:
                found = compute(params, *args, **kwargs)
                with lock:
                    answers[key] = found
                    while len(answers) > keep:
                        answers.popitem(last=False)
            return _fresh(found)

        def known(params, *args, **kwargs) -> bool:
            """The answer for these settings and arguments is kept (no work to ask for it)."""
            with lock:
                return key_of(params, args, kwargs) in answers

        call.known = known  # type: ignore[attr-defined]
        return call

    return wrap


def _argument_key(value) -> Any:
    if isinstance(value, (list, tuple, np.ndarray)):
        array = np.asarray(value, dtype=np.float64)
        return array.shape, array.tobytes()
    return repr(value)


def _fresh(value):
    """``value`` with its arrays copied (tuples and lists of them too)."""
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, tuple):
        return tuple(_fresh(v) for v in value)
    if isinstance(value, list):
        return [_fresh(v) for v in value]
    return value

"""Edits in place (``GrassField.retune``): every setting's edit gives the frame a fresh build of the
same settings gives, bit for bit, and an edit of a colour or a LOD distance simulates nothing again."""

import dataclasses

import numpy as np
import pytest
from windgrass.grass_addon import blocks, edit_parts, kinematics, schema
from windgrass.grass_addon import frame as frames
from windgrass.grass_addon.errors import ParameterError
from windgrass.grass_addon.field import GrassField
from windgrass.grass_addon.lod import Camera

BASE = {"field.blocks_x": 3, "field.blocks_y": 2, "field.cells_per_block": 4, "field.blades_per_cell": 2,
        "blade.segments": 4, "simulation.preroll": 0.5, "simulation.epoch": 1.0, "wind.speed": 6.0,
        "wind.gust_waves": 0.5, "wind.turbulence": 0.6, "lod.blade_near": 1.0, "lod.blade_far": 2.0,
        "lod.card_near": 2.5, "lod.card_far": 6.0,
        "blade.species": ({"name": "a", "weight": 2.0, "color": (0.1, 0.3, 0.05), "heads": 0.3},
                          {"name": "b", "weight": 1.0, "color": (0.3, 0.3, 0.1), "head_shape": "flower",
                           "heads": 0.5})}
CAMERA = Camera.look_at((-2.0, -1.5, 1.2), (1.0, 0.5, 0.2), fov_x=1.0)


def base_params() -> schema.Params:
    return schema.defaults().replace(BASE)


def edited(p: schema.Param, value):
    """Values to try for ``p`` other than ``value`` (the first the schema accepts is used)."""
    if p.kind == "bool":
        return [not value]
    if p.kind == "enum":
        return [c for c in p.choices if c != value]
    if p.kind == "vec":
        return [tuple(min(p.maximum, v * 0.8 + 0.05) for v in value), tuple(max(p.minimum, v * 0.7) for v in value)]
    if p.kind in ("int", "float"):
        lo, hi = p.minimum, p.soft_max if p.soft_max is not None else p.maximum
        out = [value * 1.25, value * 0.8, value + 1, value - 1, (lo + hi) / 2 if hi is not None else value + 1]
        out = [int(round(v)) if p.kind == "int" else float(v) for v in out]
        return [v for v in out if v != value and (lo is None or v >= lo) and (hi is None or v <= hi)]
    return []


def edits():
    """(name, params after the edit) for every setting outside the layout part, and the species'
    look columns."""
    base = base_params()
    out = []
    for p in schema.PARAMS:
        if edit_parts.part_of(p.name) == edit_parts.LAYOUT:
            continue
        for value in edited(p, base.get(p.name)):
            try:
                out.append((p.name, base.replace({p.name: value})))
                break
            except ParameterError:
                continue
        else:
            if p.kind not in ("str", "keys", "table_list"):
                raise AssertionError(f"no edit of {p.name} found")
    rows = [dict(r) for r in base.blade.species]
    rows[1]["color"], rows[0]["head_color"] = (0.5, 0.1, 0.4), (0.9, 0.9, 0.2)
    out.append(("blade.species (colours)", base.replace({"blade.species": tuple(rows)})))
    return out


EDITS = edits()


def drawn(field: GrassField, frame: int, views):
    shown = field.frame(frame, 0.0, views)
    out = [a.vertices[: a.count * a.shape.verts_per_block].copy() for a in (shown.blades, shown.cards)]
    out += [np.asarray(shown.blades.shown).copy(), np.asarray(shown.cards.shown).copy()]
    out += list(frames.blade_tints(shown.blades.layout, shown.blades.local).values())  # (colours)
    return out + list(frames.card_fade(shown.cards.layout, shown.cards.local, shown.lod).values())


@pytest.mark.parametrize("views", [None, CAMERA], ids=["whole", "camera"])
@pytest.mark.parametrize("name,params", EDITS, ids=[e[0] for e in EDITS])
def test_an_edit_in_place_draws_what_a_fresh_build_draws(name, params, views):
    field = GrassField(base_params())
    drawn(field, 30, views)  # a frame shown before the edit (its state, its window)
    assert field.can_retune(params), name
    field.retune(params)
    got = drawn(field, 31, views)
    want = drawn(GrassField(params), 31, views)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b, err_msg=name)


@pytest.mark.parametrize("name", ["lod.card_near", "render.sun_elevation", "blade.species (colours)",
                                  "render.samples"])
def test_a_look_or_lod_edit_simulates_nothing_again(name):
    """Nothing of the run is made again: no step, the same solver (its constants from the blades'
    physics), the same blocks' arrays and per-blade constants of the strips (stop 72: a colour
    edit of a 100 m field spent 0.13-0.15 s remaking them)."""
    params = dict(EDITS)[name]
    field = GrassField(base_params())
    drawn(field, 30, CAMERA)
    steps, solver, layout = field.sim.steps, field.sim.solver, field.layout
    constants = kinematics._constants(layout)
    field.retune(params)
    drawn(field, 30, CAMERA)
    assert field.sim.steps == steps
    assert field.sim.solver is solver and field.layout.blade_root is layout.blade_root
    assert kinematics._constants(field.layout) is constants


def test_a_wind_edit_keeps_the_blocks_and_a_shape_edit_needs_a_new_field():
    field = GrassField(base_params())
    drawn(field, 10, None)
    made = field.cache.made
    field.retune(base_params().replace({"wind.speed": 9.0}))
    drawn(field, 10, None)
    assert field.cache.made == made  # no block made again
    assert not field.can_retune(base_params().replace({"field.seed": 3}))
    assert edit_parts.changed_parts(base_params(), base_params().replace({"blade.root_stiffness": 0.004})) \
        == {edit_parts.LAYOUT}


def _stiffer_species(params: schema.Params) -> schema.Params:
    rows = [dict(r) for r in params.blade.species]
    rows[1]["stiffness"] = 2.5
    return params.replace({"blade.species": tuple(rows)})


@pytest.mark.parametrize("edit", [{"blade.root_stiffness": 0.004}, {"blade.stiffness_offset": 0.12},
                                  {"blade.density": 0.006}, "species"], ids=["root", "offset", "weight", "species"])
def test_a_rest_shape_edit_makes_the_blocks_from_the_blades_they_grew(edit):
    """A stiffness edit changes only the blades' rest shapes (eqs 1-6): the new field makes its
    blocks from the blades the field before grew (``blocks.reshapes``; nothing drawn again), and
    every array of every block, and the frame, is what a fresh build of the new settings has."""
    base = base_params()
    params = _stiffer_species(base) if edit == "species" else base.replace(edit)
    field = GrassField(base)
    drawn(field, 10, CAMERA)
    assert blocks.reshapes(base, params)
    made = GrassField(params, before=field.cache.fork())
    got = drawn(made, 10, CAMERA)
    fresh = GrassField(params)
    want = drawn(fresh, 10, CAMERA)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)
    assert set(made.cache._blocks) == set(fresh.cache._blocks) == set(field.cache._blocks)
    for b, block in fresh.cache._blocks.items():
        again = made.cache._blocks[b]
        assert again.grown_length is field.cache._blocks[b].grown_length  # (the blades it grew, not drawn again)
        for entry in dataclasses.fields(block):
            x, y = getattr(block, entry.name), getattr(again, entry.name)
            assert (x is None and y is None) or np.array_equal(x, y), (b, entry.name)
    assert not np.array_equal(made.layout.blade_rest_tilt, field.layout.blade_rest_tilt)


def test_only_rest_shape_settings_keep_the_grown_blades():
    base = base_params()
    assert not blocks.reshapes(base, base)
    for other in ({"field.blades_per_cell": 3}, {"field.seed": 9}, {"blade.inclination": 20.0},
                  {"blade.root_stiffness": 0.004, "field.seed": 9}):
        assert not blocks.reshapes(base, base.replace(other)), other
        assert GrassField(base.replace(other), before=GrassField(base).cache).cache._before is None
    rows = [dict(r) for r in base.blade.species]
    rows[0]["length"] = 0.5
    assert not blocks.reshapes(base, base.replace({"blade.species": tuple(rows)}))
    assert blocks.reshapes(base, _stiffer_species(base))


RERUNS = [(name, params) for name, params in EDITS if GrassField(base_params()).reruns(params)]
assert {"wind.speed", "blade.air_damping"} <= {name for name, _ in RERUNS}


@pytest.mark.parametrize("views", [None, CAMERA], ids=["whole", "camera"])
@pytest.mark.parametrize("name,params", RERUNS, ids=[e[0] for e in RERUNS])
def test_a_twin_retuned_on_a_thread_draws_a_fresh_build_and_leaves_its_original(name, params, views):
    """A wind or solver edit in the UI runs on a thread (``GrassField.twin``): the twin retuned
    there draws what a fresh build draws, while the field it came from goes on drawing its own
    frames, its window moving meanwhile, untouched by the twin."""
    import threading

    field = GrassField(base_params())
    before = drawn(field, 30, views)
    twin = field.twin()
    worker = threading.Thread(target=lambda: (twin.retune(params), twin.seek(31)))
    worker.start()
    again = drawn(field, 30, views)  # (the original, stepped meanwhile)
    worker.join()
    for a, b in zip(again, before):
        np.testing.assert_array_equal(a, b)
    want = drawn(GrassField(params), 31, views)
    for a, b in zip(drawn(twin, 31, views), want):
        np.testing.assert_array_equal(a, b, err_msg=name)


def test_an_edit_of_another_part_keeps_a_remembered_look():
    """The sward's look and the card atlas are kept by the settings they read (``remembered``): a
    wind edit asks for nothing new, an edit of the look does; each call gets its own copy."""
    from windgrass.grass_addon import atlas, look, sward

    params = base_params().replace({"field.seed": 9071})
    look.prepare(params)
    assert look.ready(params) and look.ready(params.replace({"wind.speed": 2.0, "blade.air_damping": 0.7}))
    assert not look.ready(params.replace({"render.sun_elevation": 20.0}))
    first = atlas.card_atlas(params)
    first[...] = 0.0  # (a caller writes into its copy)
    assert np.any(atlas.card_atlas(params)) and sward.canopy_height.known(params)


def test_a_look_held_for_a_new_fields_blocks_is_worked_out_once_they_are_made():
    """Add Grass Field from the menu makes the field's blocks and its far grass's look on two
    threads; the look waits for the blocks (``look.hold``): asked for while they are made it is not
    worked out, and once they are (the event set) it is, without being asked again."""
    import threading
    import time

    from windgrass.grass_addon import atlas, look

    params = base_params().replace({"field.seed": 9083, "render.sun_elevation": 33.0})  # (a look never made)
    made = threading.Event()
    look.hold(made)
    try:
        assert not look.ask(params) and look.working()
        time.sleep(1.0)  # (the whole look, unheld, takes well under a second: its atlas a quarter)
        assert not atlas.card_atlas.known(params) and not look.ready(params)
        made.set()
        deadline = time.monotonic() + 60.0
        while look.working() and time.monotonic() < deadline:
            time.sleep(0.02)
        assert look.ready(params) and look.ask(params)
    finally:
        made.set()

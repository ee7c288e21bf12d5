"""The engine facade GrassField: wiring, determinism of seek, LOD-driven geometry."""

import math

import numpy as np
import pytest
from windgrass.grass_addon import kinematics, schema
from windgrass.grass_addon.field import GrassField
from windgrass.grass_addon.frame import BLADES, CARDS, needs
from windgrass.grass_addon.lod import Camera


def small_params(**values):
    base = {"field.blocks_x": 3, "field.blocks_y": 2, "field.cells_per_block": 4, "field.blades_per_cell": 2,
            "blade.segments": 4, "simulation.preroll": 0.5}
    base.update(values)
    return schema.defaults().replace(base)


@pytest.fixture(scope="module")
def field():
    return GrassField(small_params(**{"wind.speed": 7.0}))


def test_shapes_and_dtypes(field):
    lay = field.layout
    cells = field.seek(5)
    assert cells.bend.shape == (lay.n_cells, lay.segments, 2) and cells.twist.shape == (lay.n_cells, lay.segments)
    blocks = field.all_blocks()
    np.testing.assert_array_equal(blocks, np.arange(lay.n_blocks))
    v = field.blade_vertices(blocks)
    assert v.shape == (lay.n_blades * (lay.segments + 1) * 2, 3) and v.dtype == np.float32 and v.flags.c_contiguous
    c = field.card_vertices(blocks[:2])
    assert c.shape == (2 * lay.cells_per_block_total * 4, 3) and c.dtype == np.float32
    assert kinematics.blade_faces(lay).max() < lay.blades_per_block * (lay.segments + 1) * 2


def test_seek_is_deterministic(field):
    """The state at frame N is a function of (params, seed, N): seeking N twice, or after other
    frames (forwards and backwards), or in a fresh field gives bit-identical vertices."""
    blocks = field.all_blocks()
    field.seek(9)
    first = field.blade_vertices(blocks).copy()
    cards = field.card_vertices(blocks).copy()
    field.seek(9)
    np.testing.assert_array_equal(field.blade_vertices(blocks), first)
    field.seek(2)
    field.seek(14)
    field.seek(9)
    np.testing.assert_array_equal(field.blade_vertices(blocks), first)
    np.testing.assert_array_equal(field.card_vertices(blocks), cards)
    fresh = GrassField(small_params(**{"wind.speed": 7.0}))
    fresh.seek(9)
    np.testing.assert_array_equal(fresh.blade_vertices(blocks), first)


def test_a_frame_asked_again_is_the_frame_a_fresh_field_draws():
    """``frame`` asked again for the same frame and views keeps its vertices (a build's frame,
    worked out on its thread, then written), and asked with fewer blades, or after another
    frame, draws what a fresh field draws then."""
    camera = Camera.look_at((-1.5, -1.2, 0.8), (0.5, 0.3, 0.1), fov_x=1.0)
    params = small_params(**{"wind.speed": 7.0})
    field = GrassField(params)

    def drawn(f, frame, amount=1.0):
        shown = f.frame(frame, 0.0, camera, amount=amount)
        return [part.vertices.copy() for part in shown.roles()]

    first = drawn(field, 9)
    for again, fresh in ((drawn(field, 9), drawn(GrassField(params), 9)),
                         (drawn(field, 9, amount=0.4), drawn(GrassField(params), 9, amount=0.4)),
                         (drawn(field, 12), drawn(GrassField(params), 12)), (drawn(field, 9), first)):
        for a, b in zip(again, fresh):
            np.testing.assert_array_equal(a, b)
    assert not np.array_equal(drawn(field, 9, amount=0.4)[0], first[0])


def test_wind_moves_the_blades(field):
    """A 7 m/s wind bends blades away from their rest shape; the frames differ as it sways."""
    lay = field.layout
    field.seek(12)
    v12 = field.blade_vertices(field.all_blocks()).reshape(lay.n_blades, lay.segments + 1, 2, 3).copy()
    calm = GrassField(small_params(**{"wind.speed": 0.0, "wind.turbulence": 0.0, "wind.type": "calm"}),
                      wind_keys=[(0.0, 0.0, 0.0)])
    calm.seek(12)
    rest = calm.blade_vertices(calm.all_blocks()).reshape(v12.shape)
    tip_move = np.linalg.norm(v12[:, -1].mean(axis=1) - rest[:, -1].mean(axis=1), axis=1)
    assert tip_move.mean() > 0.005  # more than 5 mm on average
    # the downwind component (wind towards 30 degrees) of the tip motion is positive on average
    d = np.array([math.cos(math.radians(30.0)), math.sin(math.radians(30.0))])
    assert ((v12[:, -1].mean(axis=1) - rest[:, -1].mean(axis=1))[:, :2] @ d).mean() > 0.0


def test_no_wind_keeps_the_rest_shape():
    """No wind at all: every blade keeps the gravity rest shape of eqs 1-6 (tip height
    sum l/n cos(rest tilt))."""
    calm = GrassField(small_params(**{"wind.speed": 0.0, "wind.turbulence": 0.0, "wind.type": "calm"}),
                      wind_keys=[(0.0, 0.0, 0.0)])
    lay = calm.layout
    calm.seek(6)
    v = calm.blade_vertices(calm.all_blocks()).reshape(lay.n_blades, lay.segments + 1, 2, 3)
    height = (lay.blade_length[:, None] / lay.segments * np.cos(lay.blade_rest_tilt)).sum(axis=1)
    np.testing.assert_allclose(v[:, -1, :, 2].mean(axis=1), height, rtol=1e-4, atol=1e-6)


def test_lod_drives_blade_count_and_blocks(field):
    lay = field.layout
    field.seek(3)
    # a camera 100 m up looks down at the field: every cell is past the cards (K_t = 1)
    far = Camera(np.array([0.0, 0.0, 100.0]), np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0]),
                 math.radians(60.0), 1.0)
    w = field.lod(far)
    assert np.all(w.blade_count == 0) and np.all(w.k_texture == 1.0)
    assert not needs(BLADES, field.layout, w).any() and not needs(CARDS, field.layout, w).any()
    v = field.blade_vertices(field.all_blocks(), lod=w).reshape(lay.n_blades, -1, 3)
    np.testing.assert_array_equal(v, np.broadcast_to(lay.blade_root[:, None, :], v.shape))
    # no camera: all geometry, every block
    w = field.lod(None)
    assert np.all(w.blade_count == lay.blades_per_cell)
    np.testing.assert_array_equal(np.flatnonzero(needs(BLADES, field.layout, w)), field.all_blocks())
    # preallocated out is filled in place
    out = np.empty((kinematics.blade_vertex_count(lay, 2), 3), np.float32)
    res = field.blade_vertices([0, 1], lod=w, out=out)
    assert np.shares_memory(res, out)

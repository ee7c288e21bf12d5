"""Slot pools (grass_addon/slots.py): sizes from the LOD distances, k blocks per object, the
canonical assignment of blocks to positions and which objects a frame writes. No Blender."""

import numpy as np
import pytest
from windgrass.grass_addon import schema, slots
from windgrass.grass_addon.layout import build_layout


@pytest.mark.slow
def test_pool_size_bounds_every_camera_position():
    """The blade pool holds every block whose nearest point is within blade_far of the camera,
    wherever the camera stands: checked against brute force over many camera positions."""
    params = schema.defaults().replace({"field.blocks_x": 40, "field.blocks_y": 40, "field.cells_per_block": 4,
                                        "field.blades_per_cell": 1, "lod.blade_near": 2.0, "lod.blade_far": 3.0})
    layout = build_layout(params)
    pool = slots.blocks_within(layout, params.lod.blade_far)
    assert pool < layout.n_blocks  # the pool follows the LOD distance, not the field size
    b = layout.block_bounds
    rng = np.random.default_rng([0, 99])
    worst = 0
    for x, y in rng.uniform(-8.0, 8.0, (200, 2)):
        dx = np.maximum(np.maximum(b[:, 0] - x, x - b[:, 2]), 0.0)
        dy = np.maximum(np.maximum(b[:, 1] - y, y - b[:, 3]), 0.0)
        worst = max(worst, int((np.hypot(dx, dy) <= params.lod.blade_far).sum()))
    assert worst <= pool
    assert slots.pool_blocks(layout, params.replace({"lod.enabled": False})) == {"blades": layout.n_blocks, "cards": 0}


def test_objects_hold_k_blocks_and_cover_the_pool():
    """An object holds k blocks (k from the vertices per block: fewer objects, less per-object
    cost in Blender); objects * k positions still hold every block the pool needs."""
    params = schema.defaults().replace({"field.blocks_x": 14, "field.blocks_y": 14})
    layout = build_layout(params)
    verts = {"blades": layout.blades_per_block * (layout.segments + 1) * 2, "cards": layout.cells_per_block_total * 4}
    for p in (params, params.replace({"lod.enabled": False})):
        blocks, shapes = slots.pool_blocks(layout, p), slots.pool_shapes(layout, p)
        for role, v in verts.items():
            shape, need = shapes[role], blocks[role]
            if need == 0:
                assert shape.objects == 0
                continue
            assert shape.k == max(1, min(slots.SLOT_VERTEX_BUDGET // v, need))
            assert shape.positions == shape.objects * shape.k
            assert shape.positions - shape.k < need <= shape.positions  # no object more than needed
    # Defaults: 512 blades of 12 vertices (6144) per block: 4 blocks per object; LOD off, the
    # 196 blocks of the field take 49 objects instead of 196.
    shapes = slots.pool_shapes(layout, params.replace({"lod.enabled": False}))
    blades, cards = shapes["blades"], shapes["cards"]
    assert (blades.k, blades.objects, cards.objects) == (4, 49, 0)
    faces, uvs = slots.tiled_topology(np.array([[0, 1, 3, 2]]), np.zeros((4, 2), np.float32), 6, 3)
    assert faces.tolist() == [[0, 1, 3, 2], [6, 7, 9, 8], [12, 13, 15, 14]] and uvs.shape == (12, 2)


def test_assignment_is_a_function_of_the_chosen_blocks():
    """Which position shows which block must not depend on earlier frames (frames rendered apart
    must equal frames rendered in one run)."""
    out = slots.assign_positions(5, np.array([9, 3, 5], dtype=np.int32))
    assert out.tolist() == [3, 5, 9, slots.FREE, slots.FREE]
    assert slots.assign_positions(5, np.array([5, 9, 3], dtype=np.int32)).tolist() == out.tolist()


def test_pool_state_writes_what_changed_and_is_canonical():
    """Nearest needed blocks fill the first positions in block order; an object is written unless
    it was and stays all FREE, and marked changed where a position shows another block. Two pools
    reaching the same frame by different paths show the same blocks."""
    shape = slots.PoolShape.of(verts_per_block=100, blocks=6)
    assert (shape.k, shape.objects) == (6, 1)
    shape = slots.PoolShape(verts_per_block=100, k=2, objects=3)
    distance = np.array([5.0, 1.0, 2.0, 9.0, 3.0, 4.0, 0.5])
    needs = np.array([True, True, True, False, True, False, False])
    a, b = slots.PoolState(shape), slots.PoolState(shape)
    first = a.assign(needs, distance)
    assert first.shown.tolist() == [0, 1, 2, 4, slots.FREE, slots.FREE]
    assert first.count == 4 and first.write.tolist() == [True, True, True] and first.changed.all()
    again = a.assign(needs, distance)
    assert again.write.tolist() == [True, True, False] and not again.changed.any()
    b.assign(np.ones(7, bool), distance)  # another history
    assert b.assign(needs, distance).shown.tolist() == again.shown.tolist()
    a.forget()
    assert a.assign(needs, distance).write.all()

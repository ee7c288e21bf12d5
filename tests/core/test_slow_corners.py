"""Corners of the valid ranges that used to take minutes (issue #27 item 6), on a 6.4 m field:
each is made proportional to what it touches, or refused up front naming the setting and what
would fit. Work is counted (cells looked at, spheres kept), never timed."""

from __future__ import annotations

import numpy as np
import pytest
from windgrass.grass_addon import interaction, schema
from windgrass.grass_addon.errors import ParameterError
from windgrass.grass_addon.field import GrassField

FIELD = {"field.blocks_x": 4, "field.blocks_y": 4, "field.cells_per_block": 16, "field.cell_size": 0.1,
         "field.blades_per_cell": 2, "wind.speed": 0.0}


def _params(**more):
    return schema.defaults().replace({**FIELD, **more})


def _ball(radius, x0=-3.0, x1=3.0, z=None, length=0.0):
    z = radius if z is None else z
    row = {"radius": radius, "path": [{"time": 0.0, "position": [x0, 0.0, z]}, {"time": 2.0, "position": [x1, 0.0, z]}]}
    if length:
        row.update(shape="capsule", length=length)
    return row


def test_a_collider_wider_than_the_field_looks_only_at_the_field():
    """A sphere of 100 m radius over the 6.4 m field: the cells it presses are the field's (4,096),
    found without enumerating the 4 million cells of its disc."""
    field = GrassField(_params(**{"interaction.colliders": [_ball(100.0, z=99.9)]}))
    n_cells = field.grid.n_blocks * field.grid.cells_per_block ** 2
    spheres = field.interaction.spheres(field.interaction.time(10))
    s, ids, xy = interaction._cells_around(field.grid, spheres, spheres.radii)
    assert len(ids) == n_cells and len(np.unique(ids)) == n_cells
    field.seek(10)
    assert len(field.interaction.contacts(10)) <= n_cells


def test_a_capsule_taller_than_anything_keeps_only_the_spheres_that_reach_the_grass():
    """A standing capsule 100 m long (radius 0.1 m: 2,000 spheres along its axis) walking through
    the field: only the spheres near the grass are weighed, each frame and in the refusal's count."""
    row = _ball(0.1, z=50.0, length=100.0)
    field = GrassField(_params(**{"interaction.colliders": [row]}))
    along = interaction.PathCollider("capsule", 0.1, 100.0, [0.0, 2.0], [[-3, 0, 50.0], [3, 0, 50.0]])
    assert len(along.offsets) > 1000
    kept = field.interaction.spheres(field.interaction.time(10))
    assert 0 < len(kept) < 100


def test_many_colliders_remembered_for_long_are_refused_naming_the_recovery():
    """500 balls remembered for 600 s (a frame alone weighed 7 million contacts: 125 s) are refused
    before anything is computed; the recovery the message names as valid is accepted."""
    rows = [_ball(0.2, -3.0 + 0.01 * i, 3.0) for i in range(500)]
    with pytest.raises(ParameterError) as info:
        GrassField(_params(**{"interaction.colliders": rows, "interaction.recovery": 600.0}))
    assert info.value.key == "interaction.recovery" and "valid: interaction.recovery up to" in str(info.value)
    longest = float(str(info.value).split("up to ")[1].split(" s")[0])
    GrassField(_params(**{"interaction.colliders": rows, "interaction.recovery": longest}))  # accepted


def test_too_many_force_fields_or_keep_out_shapes_are_refused():
    vortex = {"type": "vortex", "position": [0.0, 0.0, 0.0], "strength": 1.0}
    with pytest.raises(ParameterError) as info:
        schema.defaults().replace({"interaction.effectors": [vortex] * 33})
    assert info.value.key == "interaction.effectors" and "at most 32" in str(info.value)
    disc = {"shape": "disc", "center": [0.0, 0.0], "radius": 0.1}
    with pytest.raises(ParameterError) as info:
        schema.defaults().replace({"keep_out.shapes": [disc] * 257})
    assert info.value.key == "keep_out.shapes" and "at most 256" in str(info.value)
    schema.defaults().replace({"keep_out.shapes": [disc] * 256, "interaction.effectors": [vortex] * 32})

"""Field layout (paper III, III.A-B): blocks of cells, blades in cells, species, cards."""

import numpy as np
from windgrass.grass_addon import schema
from windgrass.grass_addon.layout import build_layout


def make(**values):
    base = {"field.blocks_x": 3, "field.blocks_y": 2, "field.cells_per_block": 4, "field.blades_per_cell": 5,
            "field.cell_size": 0.25}
    base.update(values)
    return build_layout(schema.defaults().replace(base))


def test_counts_and_shapes():
    lay = make()
    assert (lay.cells_x, lay.cells_y) == (12, 8)
    assert lay.n_cells == 96 and lay.n_blocks == 6
    assert lay.blades_per_block == 16 * 5 and lay.n_blades == 96 * 5
    assert lay.blade_root.shape == (lay.n_blades, 3) and lay.blade_root.dtype == np.float32
    assert lay.blade_rest_tilt.shape == (lay.n_blades, lay.segments)
    # every cell holds exactly blades_per_cell blades with slots 0..num-1
    np.testing.assert_array_equal(np.bincount(lay.blade_cell, minlength=lay.n_cells), 5)
    for slot in range(5):
        np.testing.assert_array_equal(np.sort(lay.blade_cell[lay.blade_slot == slot]), np.arange(lay.n_cells))


def test_blades_stand_inside_their_cell_on_the_ground():
    lay = make()
    half = 0.5 * lay.cell_size + 1e-6
    offset = lay.blade_root[:, :2] - lay.cell_center[lay.blade_cell]
    assert np.all(np.abs(offset) <= half)
    assert np.all(lay.blade_root[:, 2] == 0.0)
    # the field is centred on the origin
    np.testing.assert_allclose(lay.cell_center.mean(axis=0), 0.0, atol=1e-6)


def test_block_slices_are_contiguous_and_inside_their_block():
    lay = make()
    for b in range(lay.n_blocks):
        sl = lay.block_blades(b)
        cells = lay.blade_cell[sl]
        assert set(cells.tolist()) == set(lay.block_cells[b].tolist())
        xmin, ymin, xmax, ymax = lay.block_bounds[b]
        root = lay.blade_root[sl]
        assert np.all((root[:, 0] >= xmin - 1e-6) & (root[:, 0] <= xmax + 1e-6))
        assert np.all((root[:, 1] >= ymin - 1e-6) & (root[:, 1] <= ymax + 1e-6))
    # flat cell ids are row-major over the field: c = cy * cells_x + cx
    c = lay.block_cells[1, 0]  # block (bx=1, by=0) starts at cell column 4, row 0
    assert c == 4


def test_species_mixed_by_weight():
    """Two species with weights 3:1 over 9600 blades: the share of the first is 0.75 within 4
    standard errors (sqrt(0.75 * 0.25 / 9600) = 0.0044)."""
    rows = [{"name": "a", "weight": 3.0, "length": 0.2, "length_variation": 0.0},
            {"name": "b", "weight": 1.0, "length": 0.6, "length_variation": 0.0}]
    lay = build_layout(schema.defaults().replace({
        "field.blocks_x": 4, "field.blocks_y": 4, "field.cells_per_block": 6, "field.blades_per_cell": 17,
        "blade.species": rows}))
    assert lay.n_blades > 9000
    share = np.mean(lay.blade_species == 0)
    assert abs(share - 0.75) < 4 * np.sqrt(0.75 * 0.25 / lay.n_blades)
    # without variation each blade has exactly its species' length
    np.testing.assert_allclose(lay.blade_length[lay.blade_species == 0], 0.2, rtol=1e-6)
    np.testing.assert_allclose(lay.blade_length[lay.blade_species == 1], 0.6, rtol=1e-6)


def test_lengths_positive_and_mean_near_reference():
    """l = l_base + lambda N(0, 1) (paper III.A): mean close to l_base = 0.32 m (lambda = 0.07 m, the
    floor at 15 % of l_base is 3.6 sigma away, so it barely shifts the mean)."""
    lay = make(**{"field.blocks_x": 6, "field.blocks_y": 6})
    assert np.all(lay.blade_length > 0.0)
    se = 0.07 / np.sqrt(lay.n_blades)
    assert abs(lay.blade_length.mean() - 0.32) < 5 * se + 1e-3
    assert abs(lay.blade_length.std() - 0.07) < 0.01
    assert np.all(lay.card_height > 0.0)
    assert np.all((lay.blade_facing >= 0) & (lay.blade_facing < 2 * np.pi))


def test_same_seed_same_field_other_seed_other_field():
    a, b, c = make(), make(), make(**{"field.seed": 5})
    np.testing.assert_array_equal(a.blade_root, b.blade_root)
    np.testing.assert_array_equal(a.blade_rest_tilt, b.blade_rest_tilt)
    assert not np.array_equal(a.blade_root, c.blade_root)

"""A meadow's variety (meadow.py): tussocks, patches, heads, dry tips; a pure function of the
seed and the place."""

import dataclasses

import numpy as np
from windgrass.grass_addon import meadow, presets, schema
from windgrass.grass_addon.blocks import BlockCache, Species, make_block
from windgrass.grass_addon.grid import FieldGrid


def _meadow(**overrides):
    values = {"field.blocks_x": 6, "field.blocks_y": 6, "field.blades_per_cell": 3}
    values.update(overrides)
    return presets.apply_preset(schema.defaults(), "meadow").replace(values)


def test_tussocks_pull_each_root_towards_its_nearest_clump_centre():
    """Brute force over the lattice: every point's nearest jittered centre, and the pulled root on
    the segment to it at (1 - clumping) of the distance."""
    rng = np.random.default_rng(3)
    points = rng.uniform(-3.0, 3.0, (400, 2))
    size, seed = 0.45, 5
    i, j = np.meshgrid(np.arange(-10, 10), np.arange(-10, 10), indexing="ij")
    i, j = i.ravel().astype(float), j.ravel().astype(float)
    centres = np.stack([(i + meadow._hash01(seed, 11, i, j)) * size, (j + meadow._hash01(seed, 12, i, j)) * size], 1)
    nearest = centres[((points[:, None] - centres[None]) ** 2).sum(axis=2).argmin(axis=1)]
    np.testing.assert_allclose(meadow.clump_centres(points, seed, size), nearest, atol=1e-12)
    pulled = meadow.clumped(points, seed, 0.35, size)
    np.testing.assert_allclose(pulled, nearest + 0.65 * (points - nearest), atol=1e-12)
    assert np.array_equal(meadow.clumped(points, seed, 0.0, size), points)


def test_a_meadows_roots_are_clumped_and_a_lawns_are_even():
    """Counts of roots in 0.25 m squares: variance over mean at least 1.5 for the meadow preset
    (tussocks), below 1 for the lawn's even spread (the paper's random place in each cell)."""
    def ratio(params):
        grid = FieldGrid.of(params)
        roots = np.concatenate([make_block(params, grid, Species(params), b).blade_root[:, :2]
                                for b in range(grid.n_blocks)])
        edges = np.arange(-4.5, 4.5001, 0.25)
        counts, _, _ = np.histogram2d(roots[:, 0], roots[:, 1], bins=[edges, edges])
        return counts.var() / counts.mean()

    assert ratio(_meadow()) >= 1.5
    assert ratio(presets.apply_preset(_meadow(), "lawn")) < 1.0


def test_patches_change_height_and_mix_over_metres_and_are_the_same_anywhere():
    """Patch noise spans -1..1 over a field, varies little over a blade's reach and much over
    tens of metres; blocks made alone or in a window are the same bits (seed and place alone)."""
    xy = np.random.default_rng(1).uniform(-200.0, 200.0, (20000, 2))
    p = meadow.patches(xy, 7, 0, 8.0)
    assert p.min() < -0.9 and p.max() > 0.9
    near = meadow.patches(xy + 0.05, 7, 0, 8.0)
    far = meadow.patches(xy + 20.0, 7, 0, 8.0)
    assert np.abs(near - p).mean() < 0.05 < 0.3 < np.abs(far - p).mean()
    # (a cache grows blocks together: the meadow's noise over all their blades in one pass, on
    # the edge's ragged line too; blocks far apart in the field)
    params = _meadow(**{"field.edge": 1.0, "field.blocks_x": 12, "field.blocks_y": 12})
    alone = make_block(params, FieldGrid.of(params), Species(params), 7)
    cached = BlockCache(params).get([3, 140, 7, 11, 80])[2]
    for entry in dataclasses.fields(alone):
        a, b = getattr(alone, entry.name), getattr(cached, entry.name)
        assert (a is None and b is None) or np.array_equal(a, b), entry.name


def test_each_species_has_its_share_of_heads_and_the_blades_their_dry_tips():
    params = _meadow(**{"field.blocks_x": 12, "field.blocks_y": 12, "field.patchiness": 0.0})
    grid, species = FieldGrid.of(params), Species(params)
    blocks = [make_block(params, grid, species, b) for b in range(grid.n_blocks)]
    kind = np.concatenate([b.blade_species for b in blocks])
    headed = np.concatenate([(b.blade_head > 0) | (b.blade_flower > 0) for b in blocks])
    dry = np.concatenate([b.blade_dry for b in blocks])
    for k, row in enumerate(params.species()):
        assert abs(headed[kind == k].mean() - row["heads"]) < 0.05, row["name"]
    assert abs((dry > 0).mean() - params.blade.dry_tips) < 0.02 and dry[dry > 0].min() >= 0.5


def test_tussocks_keep_every_root_on_the_field():
    """A clump centre beyond the field's edge pulls its roots no further than the edge (the drawn
    ground ends there)."""
    params = _meadow(**{"field.clumping": 0.9, "field.clump_size": 2.0, "field.blocks_x": 2, "field.blocks_y": 2})
    grid = FieldGrid.of(params)
    roots = np.concatenate([make_block(params, grid, Species(params), b).blade_root[:, :2] for b in range(4)])
    half = 0.5 * np.asarray(grid.size)
    assert np.all(np.abs(roots) <= half + 1e-6) and np.any(np.abs(roots) >= half - 1e-6)


def test_the_fields_edge_thins_out_along_a_ragged_line():
    """Issue #59 item 5: a field seen from outside stood as a wall at its edge. With field.edge
    (m) its blades shorten towards the edge: on the edge itself to at most a quarter of the
    interior's height, deeper than the edge's width (and its wander) exactly as without it; the
    line where they reach full height wanders along the edge, as a meadow's edge does."""
    from windgrass.grass_addon.layout import build_layout

    base = schema.defaults().replace({"field.blocks_x": 4, "field.blocks_y": 4, "field.edge": 0.0})
    hard, soft = build_layout(base), build_layout(base.replace({"field.edge": 0.8}))
    xy = hard.blade_root[:, :2].astype(np.float64)
    half = 0.5 * 4 * 16 * 0.1
    inside = np.minimum(half - np.abs(xy[:, 0]), half - np.abs(xy[:, 1]))
    ratio = soft.blade_length / hard.blade_length
    assert np.mean(ratio[inside < 0.05]) <= 0.25
    deep = inside > 0.8 * (1.0 + meadow.EDGE_RAGGED) + 0.01
    np.testing.assert_array_equal(soft.blade_length[deep], hard.blade_length[deep])
    # along the south edge: how far in the blades first reach 90 % of their height, per 0.5 m
    south = (xy[:, 1] < 0.0) & (np.abs(xy[:, 1]) > np.abs(xy[:, 0]))
    reach = [inside[south & (np.abs(xy[:, 0] - x) < 0.25) & (ratio > 0.9)].min() for x in np.arange(-2.5, 2.6, 0.5)]
    assert np.std(reach) > 0.05, reach


def test_noise_hashed_once_a_lattice_point_is_the_noise_hashed_once_a_point():
    """``value_noise`` and ``clump_centres`` hash each lattice point once for a block's points
    (``meadow._lattice``); they give the bits of the plain formula, one hash per point (its twin),
    for a block's few lattice points and for points spread too wide for a table; so do the
    patches of several species worked out together (``patch_channels``)."""
    rng = np.random.default_rng(3)

    def plain_noise(xy, seed, channel, size):
        p = xy / size
        i, j = np.floor(p[:, 0]), np.floor(p[:, 1])
        w = (p - np.floor(p)) ** 2 * (3.0 - 2.0 * (p - np.floor(p)))
        v = {(a, b): meadow._hash01(seed, channel, i + a, j + b) for a in (0, 1) for b in (0, 1)}
        bottom = v[0, 0] + (v[1, 0] - v[0, 0]) * w[:, 0]
        top = v[0, 1] + (v[1, 1] - v[0, 1]) * w[:, 0]
        return bottom + (top - bottom) * w[:, 1]

    def plain_centres(xy, seed, size):
        home = np.floor(xy / size)
        found = [np.stack([(home[:, 0] + a + meadow._hash01(seed, 11, home[:, 0] + a, home[:, 1] + b)) * size,
                           (home[:, 1] + b + meadow._hash01(seed, 12, home[:, 0] + a, home[:, 1] + b)) * size], 1)
                 for a in (-1.0, 0.0, 1.0) for b in (-1.0, 0.0, 1.0)]
        d = np.stack([((c - xy) ** 2).sum(axis=1) for c in found])
        return np.stack(found)[np.argmin(d, axis=0), np.arange(len(xy))]

    for xy in (rng.uniform(-31.0, -29.4, (512, 2)), rng.uniform(-300.0, 300.0, (300, 2))):
        for size in (0.3, 2.7, 9.0):
            assert np.array_equal(meadow.value_noise(xy, 7, 5, size), plain_noise(xy, 7, 5, size))
            assert np.array_equal(meadow.clump_centres(xy, 7, size), plain_centres(xy, 7, size))
            # every species' patches at once (a block's shares): each row the bits of its own channel
            rows = meadow.patch_channels(xy, 7, [1, 2, 6], size)
            for row, channel in zip(rows, (1, 2, 6)):
                octaves = [plain_noise(xy, 7, 2 * channel + c, s) for c, s in ((101, size), (102, size / 3.0),
                                                                                (301, size * 3.0))]
                want = np.clip(3.2 * ((0.5 * octaves[0] + 0.2 * octaves[1] + 0.3 * octaves[2]) - 0.5), -1.0, 1.0)
                assert np.array_equal(row, want)

"""Flower heads as meshes (``heads.py``): shapes as a botanist would draw them, placed on a stem's
tip as Blender places them, and the marks the engine hands Blender."""

import numpy as np
from windgrass.grass_addon import heads, presets, schema
from windgrass.grass_addon.layout import build_layout


def test_a_daisy_is_white_rays_round_a_yellow_disc_a_third_of_its_width():
    """The ox-eye daisy's disc florets (the centre) lie within a fifth of the head's width of its
    axis, domed above the rays' bases; its rays reach out to half its width on every side (the
    head is one wide), and under it a green cup hangs below the rays."""
    m = heads.head_mesh("daisy")
    r = np.hypot(m.vertices[:, 0], m.vertices[:, 1])
    disc, rays, cup = (m.part == heads.CENTRE), (m.part == heads.PETALS), (m.part == heads.GREEN)
    assert r[disc].max() <= 0.2 and 0.45 <= r[rays].max() <= 0.51
    angles = np.arctan2(m.vertices[rays, 1], m.vertices[rays, 0])[r[rays] > 0.4]
    assert np.histogram(angles, bins=8, range=(-np.pi, np.pi))[0].min() > 0  # all round
    assert m.vertices[disc, 2].max() > 0.05 and m.vertices[cup, 2].min() < -0.1
    colours = heads.colours(m, "daisy", (0.75, 0.75, 0.7))
    assert np.allclose(colours[rays], (0.75, 0.75, 0.7)) and np.all(colours[disc][:, 2] < 0.1)  # a yellow disc


def test_a_buttercup_is_a_cup_of_five_glossy_petals():
    """Meadow buttercup: five petals whose tips stand higher than their bases (a cup), glossier
    (rougher at most 0.2) than the boss in their middle; sepals below them."""
    m = heads.head_mesh("buttercup")
    petals = m.part == heads.PETALS
    r = np.hypot(m.vertices[:, 0], m.vertices[:, 1])
    outer, inner = petals & (r > 0.4), petals & (r < 0.15)
    assert m.vertices[outer, 2].mean() > m.vertices[inner, 2].mean() + 0.1
    assert m.roughness[petals].max() <= 0.2 < m.roughness[m.part == heads.CENTRE].min()
    tips = np.arctan2(m.vertices[outer, 1], m.vertices[outer, 0])
    assert len(np.unique(np.round(tips / (2 * np.pi / 5)).astype(int) % 5)) == 5
    assert m.vertices[m.part == heads.GREEN, 2].max() < 0.0


def test_a_timothy_spike_is_a_lumpy_cylinder_over_the_stems_top_and_a_panicle_a_pyramid_of_spikelets():
    """Seed heads as meshes over the stem's top (z 0 at its joint n - 1 or n - 2, 1 at its tip):
    timothy's spike is a dense cylinder over the top segment, the seed head 1 wide (its middle 0.35-0.65
    from the axis, lumpy with spikelets, rounded at both ends); a meadow grass's panicle, in units
    of the span, is an open pyramid: a thin axis to the tip, whorls of branches whose spikelets
    (the head's colour, 5 % of the span long) reach further out the lower they are."""
    m = heads.head_mesh("spike")
    z, r = m.vertices[:, 2], np.hypot(m.vertices[:, 0], m.vertices[:, 1])
    assert z.min() == 0.0 and z.max() == 1.0
    middle = (z > 0.2) & (z < 0.8)
    assert 0.35 < r[middle].min() and r[middle].max() < 0.65 and np.ptp(r[middle]) > 0.1  # lumpy
    assert r[(z < 0.01) | (z > 0.99)].max() < 0.1  # rounded ends
    p = heads.head_mesh("panicle")
    z, r = p.vertices[:, 2], np.hypot(p.vertices[:, 0], p.vertices[:, 1])
    spikelets = p.part == heads.PETALS
    assert spikelets.sum() == 5 * 4 * 5 * 4  # 5 whorls of 4 branches of 5 spikelets (lozenges)
    assert z.max() <= 1.0 and z[p.part == heads.CENTRE].max() >= 0.99  # the axis to the tip
    low, high = spikelets & (z < 0.4), spikelets & (z > 0.8)
    assert 0.2 < r[low].max() < 0.4 and r[low].max() > 2.0 * r[high].max()  # a pyramid
    assert np.allclose(heads.colours(p, "panicle", (0.3, 0.25, 0.1))[spikelets], (0.3, 0.25, 0.1))


def test_a_head_is_placed_on_the_tip_along_the_stem_and_as_wide_as_its_flower():
    """``placed``: the head's axis (+Z) onto the stem's last segment, its centre on the tip, its
    width scaled to the flower's; the turn about the axis keeps its width."""
    m = heads.head_mesh("daisy")
    tips = np.array([[1.0, 2.0, 0.4], [0.0, 0.0, 0.3]])
    directions = np.array([[0.0, 1.0, 1.0], [0.0, 0.0, 2.0]])
    v = heads.placed(m, tips, directions, np.array([0.03, 0.02]), np.array([0.7, 0.0]))
    top = np.argmax(m.vertices[:, 2])  # the disc's crown, on the axis
    axis = (v[:, top] - tips) / np.linalg.norm(v[:, top] - tips, axis=1, keepdims=True)
    assert np.allclose(axis, directions / np.linalg.norm(directions, axis=1, keepdims=True), atol=1e-6)
    spread = np.linalg.norm(v - tips[:, None], axis=2).max(axis=1)
    assert np.allclose(spread, [0.03 * 0.5, 0.02 * 0.5], rtol=0.03)


def test_the_marks_sit_on_the_first_vertex_of_each_stem_that_carries_a_flower_mesh_or_leaves():
    """Blender reads each stem's mark on its first vertex: the meadow's flowering daisies and
    buttercups carry their flowers' widths in metres (1-5 cm), its grasses' seed heads (panicles,
    timothy's spikes) their spindles' widths (0.5-4 cm), every stem of a species with leaves its
    longest leaf (the species' leaf size times the stem's length), a stem of a species with none
    of these nothing; each mark names that vertex."""
    params = presets.apply_preset(schema.defaults(), "meadow").replace(
        {"field.blocks_x": 2, "field.blocks_y": 2, "field.blades_per_cell": 3})
    rows = [dict(r) for r in params.species()]
    rows[1].update(leaves="none")  # timothy: neither a mesh head (a spindle of its strip) nor leaves
    rows[0]["head_shape"], rows[2]["head_shape"] = "panicle", "spike"  # seed heads as meshes
    params = params.replace({"blade.species": rows})
    layout = build_layout(params)
    marks = heads.tip_marks(layout, np.arange(layout.n_blocks)).reshape(-1, 2 * (layout.segments + 1), 5)
    kind = layout.blade_species
    flowering = np.array([rows[k]["head_shape"] in ("daisy", "buttercup") for k in kind]) & (layout.blade_flower > 0)
    seeding = np.array([rows[k]["head_shape"] in heads.SEED_SHAPES for k in kind]) & (layout.blade_head > 0)
    leafy = kind != 1
    assert flowering.sum() > 10 and seeding.sum() > 10 and (~leafy).sum() > 10
    assert np.array_equal(marks[:, 0, 0] > 0, flowering | leafy) and not marks[:, 1:].any()
    assert np.array_equal(marks[leafy, 0, 0] - 1, kind[leafy])
    assert 0.01 < marks[flowering, 0, 1].min() and marks[flowering, 0, 1].max() < 0.05
    assert np.allclose(marks[seeding, 0, 1], layout.blade_head[seeding] * layout.blade_width[seeding])
    assert 0.005 < marks[seeding, 0, 1].min() and marks[seeding, 0, 1].max() < 0.04
    assert not marks[~(flowering | seeding), 0, 1].any()
    size = np.array([rows[k]["leaf_size"] for k in kind])
    assert np.allclose(marks[leafy, 0, 4], size[leafy] * layout.blade_length[leafy], rtol=1e-6)
    assert 0.03 < marks[leafy, 0, 4].min() and marks[leafy, 0, 4].max() < 0.6  # (basal leaves, 3-60 cm)
    first = np.flatnonzero(flowering | leafy) * 2 * (layout.segments + 1)
    assert np.array_equal(marks[flowering | leafy, 0, 3], first)



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
    buttercups carry their flowers' widths in metres (1-5 cm), every stem of a species with
    leaves its longest leaf (the species' leaf size times the stem's length), a stem of a species
    with neither nothing; each mark names that vertex."""
    params = presets.apply_preset(schema.defaults(), "meadow").replace(
        {"field.blocks_x": 2, "field.blocks_y": 2, "field.blades_per_cell": 3})
    rows = [dict(r) for r in params.species()]
    rows[1]["leaves"] = "none"  # timothy: neither a flower mesh nor leaves
    params = params.replace({"blade.species": rows})
    layout = build_layout(params)
    marks = heads.tip_marks(layout, np.arange(layout.n_blocks)).reshape(-1, 2 * (layout.segments + 1), 5)
    kind = layout.blade_species
    flowering = np.array([rows[k]["head_shape"] in ("daisy", "buttercup") for k in kind]) & (layout.blade_flower > 0)
    leafy = kind != 1
    assert flowering.sum() > 10 and (~leafy).sum() > 10
    assert np.array_equal(marks[:, 0, 0] > 0, flowering | leafy) and not marks[:, 1:].any()
    assert np.array_equal(marks[leafy, 0, 0] - 1, kind[leafy])
    assert 0.01 < marks[flowering, 0, 1].min() and marks[flowering, 0, 1].max() < 0.05
    assert not marks[~flowering, 0, 1].any()
    size = np.array([rows[k]["leaf_size"] for k in kind])
    assert np.allclose(marks[leafy, 0, 4], size[leafy] * layout.blade_length[leafy], rtol=1e-6)
    assert 0.03 < marks[leafy, 0, 4].min() and marks[leafy, 0, 4].max() < 0.6  # (basal leaves, 3-60 cm)
    first = np.flatnonzero(flowering | leafy) * 2 * (layout.segments + 1)
    assert np.array_equal(marks[flowering | leafy, 0, 3], first)



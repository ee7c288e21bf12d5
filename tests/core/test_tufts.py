"""The leaves at a stem's foot (tufts.py), checked as a botanist draws them: grass leaves narrow,
pointed and arching, a rosette's broad and lying out, clover's three leaflets held flat; and which
stems carry how long a tuft."""

import numpy as np
from windgrass.grass_addon import presets, schema, tufts
from windgrass.grass_addon.layout import build_layout


def _face_normals(mesh) -> tuple[np.ndarray, np.ndarray]:
    """(unit normals, areas) of the mesh's triangles."""
    tri = mesh.vertices[tufts.triangles(mesh)].astype(np.float64)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    return cross / np.maximum(2.0 * area, 1e-12)[:, None], area


def _leaves_of(mesh) -> list[np.ndarray]:
    """Vertex ids of each leaf."""
    return [np.flatnonzero(mesh.leaf == k) for k in range(int(mesh.leaf.max()) + 1)]


def _centre_line(mesh, ids) -> tuple[np.ndarray, np.ndarray]:
    """(joints (m + 1, 3), widths (m + 1,)) of a leaf strip: its vertices by their place along it."""
    along = np.unique(mesh.v[ids])
    joints = np.array([mesh.vertices[ids[mesh.v[ids] == v]].mean(axis=0) for v in along])
    widths = np.array([np.ptp(mesh.vertices[ids[mesh.v[ids] == v]], axis=0).max() if (mesh.v[ids] == v).sum() > 1
                       else 0.0 for v in along])
    return joints, widths


def test_a_grass_tuft_is_ten_narrow_pointed_leaves_arching_out_all_round_its_root():
    m = tufts.leaf_mesh("tuft")
    leaves = _leaves_of(m)
    assert len(leaves) == 10
    assert m.vertices[:, 2].min() >= 0.0  # nothing below the ground
    lines = [_centre_line(m, ids) for ids in leaves]
    feet = np.array([joints[0] for joints, _ in lines])
    assert np.hypot(feet[:, 0], feet[:, 1]).max() <= 0.061  # a tussock's tillers, close round the root
    out = np.array([joints[-1, :2] - joints[0, :2] for joints, _ in lines])
    assert np.linalg.norm(out, axis=1).min() > 0.3  # every leaf reaches out
    angle = np.sort(np.arctan2(out[:, 1], out[:, 0]))
    assert np.diff(np.concatenate([angle, angle[:1] + 2 * np.pi])).max() < np.radians(80)  # all round
    lengths = []
    for joints, widths in lines:
        steps = np.diff(joints, axis=0)
        lengths.append(np.linalg.norm(steps, axis=1).sum())
        assert widths.max() <= 0.06 * max(lengths[-1], 1.0) and widths[-1] == 0.0  # narrow, pointed
        tilt = np.degrees(np.arccos(steps[:, 2] / np.linalg.norm(steps, axis=1)))
        assert tilt[0] < 45.0 and tilt[-1] > tilt[0] + 20.0  # rising, then arching over
    assert np.isclose(max(lengths), 1.0, atol=0.05)  # the unit frame: the longest leaf 1 long


def test_a_rosette_lies_out_and_clover_holds_three_leaflets_flat():
    """Seen from above, most of a rosette's leaf area and of clover's leaflets faces the sky (a
    grass tuft's much less); a rosette's leaves are broad (a quarter of their length); clover has
    three leaflets to a stalk."""
    share = {}
    for shape in tufts.LEAF_SHAPES:
        m = tufts.leaf_mesh(shape)
        normal, area = _face_normals(m)
        share[shape] = float((np.abs(normal[:, 2]) * area).sum() / area.sum())
    assert share["rosette"] > 0.75 and share["clover"] > 0.8 and share["tuft"] < share["rosette"]
    rosette = tufts.leaf_mesh("rosette")
    widths = [_centre_line(rosette, ids)[1].max() for ids in _leaves_of(rosette)]
    assert 0.2 < min(widths) and max(widths) < 0.35
    clover = tufts.leaf_mesh("clover")
    fans = sum(1 for f in clover.faces if len(f) == 3 and clover.v[f[0]] == 1.0 and clover.v[f[1]] == 1.0)
    assert fans == 4 * 3 * 9  # 4 leaves of 3 leaflets of 9 triangles


def test_each_stem_of_a_leafy_species_carries_its_leaf_size_times_its_length():
    """The meadow's species all have leaves: a stem's longest leaf is its species' Leaf Size times
    its length; a species set to none has none, and a stem painted out none."""
    params = presets.apply_preset(schema.defaults(), "meadow").replace({"field.blocks_x": 2, "field.blocks_y": 2})
    rows = [dict(r) for r in params.species()]
    rows[0]["leaves"] = "none"
    params = params.replace({"blade.species": rows})
    layout = build_layout(params)
    lengths = tufts.leaf_lengths(rows, layout.blade_species, layout.blade_length, layout.blade_alive)
    size = np.array([r["leaf_size"] if r["leaves"] != "none" else 0.0 for r in rows])[layout.blade_species]
    assert np.allclose(lengths, size * layout.blade_length, rtol=1e-6)
    assert not lengths[layout.blade_species == 0].any() and lengths[layout.blade_species != 0].min() > 0.03
    assert tufts.leafy(rows).tolist() == [False, True, True, True, True, True]


def test_dead_leaves_are_straw_where_the_meadow_is_dry():
    m = tufts.leaf_mesh("tuft")
    green = np.array([0.1, 0.3, 0.05])
    assert np.allclose(m.tints(green, 0.0), green)
    dry = m.tints(green, 0.3)
    assert m.dead.any() and np.allclose(dry[m.dead], tufts.STRAW, atol=1e-6)
    assert np.allclose(dry[~m.dead], green)

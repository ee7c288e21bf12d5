"""A collider's shape as spheres (collider_shapes.py): every point of the object the grass can reach
is inside a sphere, a ball is one sphere, and a rigid object's pieces cut once follow its matrix."""

from __future__ import annotations

import math

import numpy as np
from windgrass.grass_addon import collider_shapes


def _ball(radius=0.3, n=4000, seed=1):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    return radius * v / np.linalg.norm(v, axis=1, keepdims=True)


def _covered(points, centres, radii, slack=1e-9):
    d = np.linalg.norm(points[:, None, :] - centres[None], axis=2) - radii[None]
    return (d <= slack).any(axis=1)


def test_a_ball_is_one_sphere_and_a_wall_several():
    ball = _ball() + [1.0, 2.0, 0.3]
    centres, radii = collider_shapes.spheres_of(ball, 0.8, 10.0)
    assert len(radii) == 1 and abs(radii[0] - 0.3) < 0.01 and np.allclose(centres[0], [1.0, 2.0, 0.3], atol=0.01)
    rng = np.random.default_rng(2)
    wall = np.column_stack([rng.uniform(0, 4, 20000), rng.uniform(0, 0.2, 20000), rng.uniform(0, 2, 20000)])
    centres, radii = collider_shapes.spheres_of(wall, 0.8, 0.5)  # the grass reaches 0.5 m up
    assert len(radii) == 5 and _covered(wall[wall[:, 2] < 0.5], centres, radii).all()


def _turn(angle, shift, scale=1.0):
    c, s = math.cos(angle), math.sin(angle)
    m = np.eye(4)
    m[:3, :3] = scale * np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    m[:3, 3] = shift
    return m


def test_rigid_pieces_cover_the_moved_object_below_the_grass_top():
    """A 3 m x 1 m x 1.5 m block of 50,000 points cut once in its own frame: turned, moved and
    scaled by its matrix, every moved point below the grass's top lies inside a moved sphere, and
    the spheres are small (radius at most the piece's half diagonal times the scale)."""
    rng = np.random.default_rng(3)
    local = rng.uniform([-1.5, -0.5, 0.0], [1.5, 0.5, 1.5], (50000, 3))
    pieces = collider_shapes.RigidPieces(local, np.zeros(len(local), np.int64))
    for angle, shift, scale in ((0.0, (0, 0, 0), 1.0), (0.7, (3.0, -2.0, 0.1), 1.0), (2.0, (0, 0, 0.2), 1.5)):
        m = _turn(angle, shift, scale)
        centres, radii, mid = pieces.at(m, 0.6)
        moved = local @ m[:3, :3].T + m[:3, 3]
        assert _covered(moved[moved[:, 2] < 0.6], centres, radii, slack=1e-6).all()
        assert radii.max() <= collider_shapes.PIECE * math.sqrt(3) / 2 * scale + 1e-9
        np.testing.assert_allclose(mid, m[:3, :3] @ local.mean(axis=0) + m[:3, 3])
        assert (centres[:, 2] - radii < 0.6).all()  # only pieces the grass can reach
    ball = collider_shapes.RigidPieces(_ball(), np.zeros(4000, np.int64))  # compact: one sphere, itself
    centres, radii, _ = ball.at(_turn(1.0, (2.0, 0.0, 0.3)), 1.0)
    assert len(radii) == 1 and abs(radii[0] - 0.3) < 0.01 and np.allclose(centres[0], [2.0, 0.0, 0.3], atol=0.01)


def test_two_islands_are_two_parts():
    edges = np.array([[0, 1], [1, 2], [3, 4]])
    labels = collider_shapes.mesh_islands(5, edges)
    assert labels.tolist() == [0, 0, 0, 3, 3]

"""A collider's shape as spheres (numpy only): what the grass feels of an object at one frame.

* ``spheres_of``: the part of an object's points the grass can reach (below ``top_z``), per island
  of its mesh (two feet are two), cut into pieces at most ``cluster`` metres across, each piece in
  its bounding sphere (a ball is one sphere, exactly; a foot one, a car or a wall several).
* ``RigidPieces``: an object whose shape never changes in its own frame (moved by keys,
  constraints or a parent, a bone included) is cut into pieces once, in its own frame, and each
  frame only its matrix moves them: the cost of a frame no longer grows with its vertices.
* ``mesh_islands``: the connected parts of a mesh.

Reductions per piece sort the points once (``_bounds``), which is several times faster than
``ufunc.at`` on millions of points.
"""

from __future__ import annotations

import numpy as np

PIECE = 0.4  # m: the edge of the cells a rigid collider is cut into, in its own frame (radius <= 0.35 m)


def _bounds(keys: np.ndarray, points: np.ndarray):
    """(inverse (k,), bmin (m, 3), bmax (m, 3), order, starts) of the points grouped by ``keys``
    (the sort ``order`` and each group's first index ``starts`` in it, for further reductions)."""
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    starts = np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]])
    group = np.cumsum(np.r_[False, sorted_keys[1:] != sorted_keys[:-1]])
    inverse = np.empty(len(keys), np.int64)
    inverse[order] = group
    ordered = points[order]
    return inverse, np.minimum.reduceat(ordered, starts, axis=0), np.maximum.reduceat(ordered, starts, axis=0), \
        order, starts


def _spheres(keys: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(centres, radii): each group's bounding box centre and the sphere around it holding all
    of the group's points."""
    inverse, bmin, bmax, order, starts = _bounds(keys, points)
    centres = 0.5 * (bmin + bmax)
    reach = np.linalg.norm(points[order] - centres[inverse[order]], axis=1)
    return centres, np.maximum.reduceat(reach, starts)


def spheres_of(points: np.ndarray, cluster: float, top_z: float, islands: np.ndarray | None = None):
    """(centres (m, 3), radii (m,)) covering the points (k, 3) below ``top_z``, per island
    (``islands`` (k,)), in pieces at most ``cluster`` metres across in the ground plane."""
    below = points[:, 2] < top_z
    low = points[below]
    if not len(low):
        return np.zeros((0, 3)), np.zeros(0)
    island = islands[below] if islands is not None else np.zeros(len(low), np.int64)
    _, island = np.unique(island, return_inverse=True)
    island = island.reshape(-1)
    _, lo, hi, _, _ = _bounds(island, low)
    lo, hi = lo[:, :2], hi[:, :2]
    counts = np.maximum(1, np.ceil((hi - lo) / cluster - 1e-9)).astype(np.int64)
    size = (hi - lo) / counts + 1e-12
    ij = np.minimum(((low[:, :2] - lo[island]) / size[island]).astype(np.int64), counts[island] - 1)
    piece = (island * 1_000_003 + ij[:, 0]) * 1_000_003 + ij[:, 1]
    return _spheres(piece, low)


def mesh_islands(n: int, edges: np.ndarray) -> np.ndarray:
    """(n,) the connected part of the mesh each vertex belongs to (the smallest vertex index of
    it), by spreading the smallest label along the edges (e, 2) until nothing changes."""
    labels = np.arange(n)
    if not len(edges):
        return labels
    a, b = edges[:, 0], edges[:, 1]
    while True:
        low = np.minimum(labels[a], labels[b])
        before = labels.copy()
        np.minimum.at(labels, a, low)
        np.minimum.at(labels, b, low)
        labels = labels[labels]  # (jump along: converges in a few rounds)
        if np.array_equal(labels, before):
            return labels


class RigidPieces:
    """A rigid object's points (k, 3) in its own frame, cut once into pieces per island (an island
    at most ``cluster`` across whole, a larger one in cells of at most ``PIECE`` a side), each in its
    bounding sphere; ``at(matrix, top_z)`` gives them where ``matrix`` (4, 4: its own frame to the
    field's) puts the object."""

    def __init__(self, local: np.ndarray, islands: np.ndarray, cluster: float = 0.8):
        self.mid = local.mean(axis=0) if len(local) else np.zeros(3)
        if not len(local):
            self.centres, self.radii = np.zeros((0, 3)), np.zeros(0)
            return
        _, island = np.unique(islands, return_inverse=True)
        island = island.reshape(-1)
        _, lo, hi, _, _ = _bounds(island, local)
        # an island at most ``cluster`` across is one piece (a ball is itself), a larger one is cut
        # into equal cells of at most PIECE a side
        compact = ((hi - lo) <= cluster).all(axis=1, keepdims=True)
        counts = np.where(compact, 1, np.maximum(1, np.ceil((hi - lo) / PIECE - 1e-9))).astype(np.int64)
        size = (hi - lo) / counts + 1e-12
        cell = np.minimum(((local - lo[island]) / size[island]).astype(np.int64), counts[island] - 1)
        key = ((island * 1_000_003 + cell[:, 0]) * 1_000_003 + cell[:, 1]) * 1_000_003 + cell[:, 2]
        self.centres, self.radii = _spheres(key, local)

    def at(self, matrix: np.ndarray, top_z: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(centres, radii, the object's middle) in the field's frame: the pieces that reach below
        ``top_z`` (a scaled object scales its spheres by its largest scale)."""
        m = np.asarray(matrix, np.float64)
        centres = self.centres @ m[:3, :3].T + m[:3, 3]
        radii = self.radii * float(np.linalg.norm(m[:3, :3], axis=0).max())
        keep = centres[:, 2] - radii < top_z
        return centres[keep], radii[keep], m[:3, :3] @ self.mid + m[:3, 3]

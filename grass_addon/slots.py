"""Slot pools: which block each mesh object of a field shows this frame (numpy only).

Blender holds a field as two pools of mesh objects, one for blade strips and one for cards. Every
block has the same topology, so one object ("slot") is k copies of one block's topology and shows
k blocks at its k "positions": object s holds positions s*k .. s*k + k - 1. A pool is sized from the
LOD distances (blades need d < d_g2 of eq 7, cards d < d_s2 of eq 10), not from the field's size,
so memory and per-frame cost follow what is near the camera.

Each frame the nearest visible blocks that need the pool's level of detail go to the first
positions in block order (canonical: a frame's assignment depends on the frame and the camera
alone, never on the frames visited before); the other positions are FREE (collapsed to a point).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from . import atlas
from .roles import ROLES
from .schema import Params

FREE = -1  # a position that shows nothing
UNKNOWN = -2  # what a position shows is not known (new pool, undo, reopened file): write it
# Vertices a slot object aims at: k = SLOT_VERTEX_BUDGET // vertices per block blocks share one
# object (default blades 6144 vertices per block: k = 4; cards 1024: k = 24). Fewer, larger
# objects cut Blender's per-object cost (one write, one update, one evaluation per object).
SLOT_VERTEX_BUDGET = 24576


def blocks_within(layout, distance: float) -> int:
    """Blocks whose nearest point can lie within ``distance`` of a camera, at most the field's.

    A block (edge s) with a point within d of the camera has its centre within d + s/sqrt(2);
    every such block lies inside the disc of radius d + s*sqrt(2) (d + block diagonal), so their
    number is at most that disc's area over the block's area.
    """
    edge = layout.cells_per_block * layout.cell_size
    radius = distance + edge * math.sqrt(2.0)
    return int(min(layout.blocks_x * layout.blocks_y, math.ceil(math.pi * radius * radius / (edge * edge))))


def pool_blocks(layout, params: Params) -> dict[str, int]:
    """{role: blocks} each role's pool must show at once (``roles.ROLES``): those within its
    ``Role.far``; LOD off: every block for the roles drawn then (blades), none for the others. A
    field without blades has nothing in its blade pool."""
    lod, out = params.lod, {}
    for role in ROLES:
        if not role.vertices_per_block(layout):
            out[role.name] = 0
        elif not lod.enabled:
            out[role.name] = layout.blocks_x * layout.blocks_y if role.without_lod else 0
        else:
            out[role.name] = blocks_within(layout, float(getattr(lod, role.far)))
    return out


@dataclass(frozen=True)
class PoolShape:
    """The objects of one pool: ``objects`` objects of ``k`` block positions of ``verts_per_block``."""

    verts_per_block: int
    k: int
    objects: int

    @classmethod
    def of(cls, verts_per_block: int, blocks: int) -> PoolShape:
        if blocks <= 0:
            return cls(verts_per_block, 1, 0)
        k = max(1, min(SLOT_VERTEX_BUDGET // max(1, verts_per_block), blocks))  # never more than needed
        return cls(verts_per_block, k, -(-blocks // k))

    @property
    def positions(self) -> int:
        return self.objects * self.k

    @property
    def verts_per_object(self) -> int:
        return self.k * self.verts_per_block


def pool_shapes(layout, params: Params) -> dict[str, PoolShape]:
    """{role: its pool's shape} of a field (``roles.ROLES``)."""
    blocks = pool_blocks(layout, params)
    return {role.name: PoolShape.of(role.vertices_per_block(layout), blocks[role.name]) for role in ROLES}


def topology_key(grid, params: Params, terrain=None) -> str:
    """What a field's slot objects are built for (``grid``: the field's ``FieldGrid`` or a layout;
    ``terrain``: its heightfield or None); they are rebuilt when it changes."""
    shapes = pool_shapes(grid, params)
    return json.dumps([grid.blades_per_block, grid.segments, grid.cells_per_block, atlas.UV_LAYOUT,
                       *([shapes[role.name].objects, shapes[role.name].k] for role in ROLES),
                       [round(float(v), 6) for v in grid.size],
                       terrain.fingerprint() if terrain is not None else "flat"])


def tiled_topology(faces: np.ndarray, uvs: np.ndarray, verts_per_block: int, k: int):
    """(faces, uvs) of k copies of one block's topology: copy i uses vertices from
    i * verts_per_block on; UVs repeat per copy."""
    offsets = (np.arange(k, dtype=np.int32) * verts_per_block)[:, None, None]
    tiled = (faces.astype(np.int32)[None] + offsets).reshape(-1, 4)
    return np.ascontiguousarray(tiled), np.ascontiguousarray(np.tile(uvs, (k, 1)), dtype=np.float32)


def nearest_blocks(candidates: np.ndarray, distance: np.ndarray, count: int) -> np.ndarray:
    """Up to ``count`` candidate blocks, nearest first (stable for equal distances)."""
    idx = np.flatnonzero(candidates)
    order = np.argsort(distance[idx], kind="stable")
    return idx[order[:count]].astype(np.int64)


def assign_positions(n_positions: int, chosen: np.ndarray) -> np.ndarray:
    """Block shown at every position: the chosen blocks in block order, then FREE."""
    out = np.full(n_positions, FREE, dtype=np.int64)
    blocks = np.sort(np.asarray(chosen, dtype=np.int64))[:n_positions]
    out[: len(blocks)] = blocks
    return out


@dataclass
class Assignment:
    """One frame of a pool: ``shown`` block per position (FREE after the first ``count``),
    ``write`` and ``changed`` per object (``changed``: some position shows another block);
    ``relit``: the LOD weights differ from those of the last write (data that read them, the
    cards' opacity, are written again)."""

    shown: np.ndarray
    count: int
    write: np.ndarray
    changed: np.ndarray
    relit: bool = True


class PoolState:
    """What each position of a pool shows, frame to frame (the writes skip what did not change)."""

    def __init__(self, shape: PoolShape):
        self.shape = shape
        self.shown = np.full(shape.positions, UNKNOWN, dtype=np.int64)
        self.lod: object = None  # the LOD weights (``lod.LodWeights``) of the last write

    def forget(self) -> None:
        """The objects' data may be anything now (undo, a reopened file): write everything next."""
        self.shown.fill(UNKNOWN)
        self.lod = None

    def assign(self, needs: np.ndarray, block_distance: np.ndarray, block_ids: np.ndarray | None = None) -> Assignment:
        """This frame's assignment: the nearest blocks that ``need`` the pool (bool per block).
        ``block_ids``: the field-wide id of each block (ascending; a window of the field), which
        the positions then hold; None: the blocks are the field's own."""
        chosen = nearest_blocks(needs, block_distance, self.shape.positions)
        if block_ids is not None:
            chosen = np.asarray(block_ids, dtype=np.int64)[chosen]
        return self.record(assign_positions(self.shape.positions, chosen))

    def record(self, shown: np.ndarray, lod: object = None) -> Assignment:
        """Take ``shown`` (the block at each position, FREE after the shown ones; the engine's
        ``frame.RoleFrame.shown``) and ``lod`` (its LOD weights: the same object while they hold,
        ``GrassField.lod``) as this frame's, and say which objects must be written."""
        k = self.shape.k
        cur, prev = shown.reshape(-1, k), self.shown.reshape(-1, k)
        # an object whose positions are all FREE now and were FREE before stays collapsed
        write = ~((cur == FREE).all(axis=1) & (prev == FREE).all(axis=1))
        changed = (cur != prev).any(axis=1)
        self.shown = shown.copy()
        relit = lod is None or lod is not self.lod
        self.lod = lod
        return Assignment(shown, int(np.count_nonzero(shown != FREE)), write, changed, relit)

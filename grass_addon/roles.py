"""The levels of detail drawn as geometry, described once (paper III): blade strips near the
camera, billboard cards beyond them. (The far canopy beyond the cards is the ground's material:
no slot objects.) Each ``Role`` is an entry of ``ROLES``: which cells need it (eqs 7-11), how far
its pool reaches, one block's quads and UVs, how its vertices are made from the cell data, which
per-corner data its slots carry, and what rides on it. The engine (``field.py``, ``frame.py``,
``slots.py``) and the bridge (``bridge/scene.py``, ``pools.py``) loop over ``ROLES``; a third level
of detail is one entry here with its kinematics. Numpy only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from . import atlas, heads, kinematics, meadow

BLADES, CARDS = "blades", "cards"
# per-corner data (the bridge writes each into the UV map of that name: ``bridge/pools.py``)
TINT_RG, TINT_BS, FADE = "tint_rg", "tint_bs", "fade"
HEAD = "head"  # per vertex, not per corner: where a flower mesh rides a tip (heads.tip_marks)


def blade_tints(layout, local: np.ndarray, lod=None) -> dict:
    """Per corner of every blade quad of the positions ``local`` (FREE: zero): the colour at the
    corner's end of its segment (``meadow.segment_colours``: a joint's, a flower's head wholly in its
    colour) as (r, g), (b, shade); quad j's corners are (left_j, right_j, right_j+1, left_j+1); and
    the flower heads' marks per vertex (``HEAD``, (vertices, 5)) where a species carries a head,
    leaves or a plant (nothing else draws them)."""
    n = layout.segments
    bpb = layout.blades_per_block
    shown = local >= 0
    rg = np.zeros((len(local), bpb, n, 4, 2), dtype=np.float32)
    bs = np.zeros((len(local), bpb, n, 4, 2), dtype=np.float32)
    blades = local[shown, None].astype(np.int64) * bpb + np.arange(bpb)[None, :]
    kind = layout.blade_species[blades]
    flower = heads.strip_flowers(layout, blades)  # (a flower that is a mesh: its stem green to the tip)
    joints = meadow.joint_colours(n, layout.species_color[kind], layout.species_head_color[kind],
                                  layout.blade_dry[blades], layout.blade_head[blades], flower)  # (shown, bpb, n + 1, 3)
    ends = meadow.segment_colours(joints, flower)  # (shown, bpb, n, bottom/top, 3)
    colour = ends[:, :, :, [0, 0, 1, 1]]  # (shown, bpb, n, 4, 3)
    rg[shown] = colour[..., :2]
    bs[shown, ..., 0] = colour[..., 2]
    bs[shown, ..., 1] = layout.blade_shade[blades][..., None, None]
    out = {TINT_RG: rg.reshape(-1, 2), TINT_BS: bs.reshape(-1, 2)}
    if heads.carries_any(layout):
        out[HEAD] = heads.tip_marks(layout, local)
    return out


def card_fade(layout, local: np.ndarray, lod) -> dict:
    """Per corner of every card of the positions ``local``: (K_b, K_b), times the cell's painted
    density (a card shows only its cell's blades that grow); FREE positions: zero."""
    opacity = np.zeros((len(local), layout.cells_per_block_total), dtype=np.float32)
    shown = local >= 0
    if lod is not None:
        opacity[shown] = lod.k_billboard[layout.block_cells[local[shown]]]
    if layout.cell_density is not None:
        opacity[shown] *= layout.cell_density[layout.block_cells[local[shown]]]
    return {FADE: np.ascontiguousarray(np.repeat(opacity.reshape(-1, 1), 8, axis=1).reshape(-1, 2))}


def _blade_vertices(layout, cells, blocks, lod, out):
    return kinematics.blade_vertices(layout, cells, blocks, None if lod is None else lod.blade_count, out)


def _card_vertices(layout, cells, blocks, lod, out):
    return kinematics.card_vertices(layout, cells, blocks, out)


@dataclass(frozen=True)
class Role:
    """One level of detail drawn in slot objects (``slots.py``)."""

    name: str  # its slot objects' role (``bridge/owned.py`` tags, mesh names)
    level: str  # the ``lod.LodWeights`` array of the cells that need it (> 0): eq 9's N, eq 11's K_b
    far: str  # the ``params.lod`` distance its pool reaches (how many blocks it shows at once)
    without_lod: bool  # drawn with the LOD off (every blade as geometry)
    vertices_per_block: Callable  # (layout) -> vertices of one block
    faces: Callable  # (layout) -> (quads, 4) of one block
    uvs: Callable  # (layout) -> per-corner UVs of one block
    vertices: Callable  # (layout, cells, blocks, lod, out) -> the blocks' vertices (``kinematics.py``)
    corner_data: tuple[str, ...]  # the per-corner data its slots carry
    data: Callable  # (layout, local positions, lod) -> {name: per-corner (or HEAD: per-vertex) data}
    data_by_blocks: bool  # its data depend on a slot's blocks alone: kept by them, written when they change
    cleared: bool  # its vertices are bent out of colliders (``clearance.py``)
    bare_collapsed: bool  # a cell where nothing grows collapses (many see-through cards would use up a
    # renderer's transparent layers along a path)
    heads: bool  # the flowers', leaves' and plants' node tree rides its objects (``bridge/heads.py``)


ROLES: tuple[Role, ...] = (
    Role(BLADES, "blade_count", "blade_far", True,
         lambda lay: kinematics.blade_vertex_count(lay, 1),
         kinematics.blade_faces, kinematics.blade_uvs, _blade_vertices, (TINT_RG, TINT_BS), blade_tints,
         data_by_blocks=True, cleared=True, bare_collapsed=False, heads=True),
    Role(CARDS, "k_billboard", "card_far", False,
         lambda lay: kinematics.card_vertex_count(lay, 1),
         kinematics.card_faces, atlas.card_uvs, _card_vertices, (FADE,), card_fade,
         data_by_blocks=False, cleared=False, bare_collapsed=True, heads=False),
)
NAMES: tuple[str, ...] = tuple(role.name for role in ROLES)
BY_NAME: dict[str, Role] = {role.name: role for role in ROLES}

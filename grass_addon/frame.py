"""One frame of a field as Blender draws it, computed once by the engine (``GrassField.frame``).

A ``Frame`` holds, for each of the field's two roles (blade strips, cards), which block every slot
position shows (``slots.py``), the float32 vertices of those positions (colliders cleared, bare
cells collapsed), their velocities when motion blur asks, and the per-vertex attributes of any
slot object (blade colours, card opacity); plus what the materials need: the gust waves' offset
and the colliders' trail map for the far canopy. The bridge only writes it (``bridge/pools.py``);
the headless scripts and the tests read the same arrays.

Which blocks a role shows: the visible blocks that need its level of detail (blades: some cell
with N > 0, eq 9; cards: some card opacity K_b > 0, eqs 7 and 11) and where something grows
(paint), the nearest first, up to the pool's positions, then in block order (canonical: a frame
never depends on the frames shown before).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from . import heads, meadow, slots

BLADES, CARDS = "blades", "cards"
# per-vertex attributes (the bridge writes each into the UV map of that role's name)
TINT_RG, TINT_BS, FADE = "tint_rg", "tint_bs", "fade"
HEAD = "head"  # per vertex, not per corner: where a flower mesh rides a tip (heads.tip_marks)


def grows(layout) -> np.ndarray | bool:
    """(n_blocks,) bool: some blade of the block grows (paint.py); True without paint."""
    if layout.cell_density is None:
        return True
    return (layout.cell_density[layout.block_cells] > 0).any(axis=1)


def needs(role: str, layout, lod) -> np.ndarray:
    """(n_blocks,) bool: the window's blocks that ``role`` shows at these LOD weights."""
    if lod is None:  # every blade as geometry, no card
        return np.full(layout.n_blocks, role == BLADES)
    level = lod.blade_count if role == BLADES else lod.k_billboard
    return (level[layout.block_cells] > 0).any(axis=1) & lod.block_visible & grows(layout)


def block_distance(layout, lod, views) -> np.ndarray:
    """(n_blocks,) float32: how near each block is, for choosing the nearest: from the views'
    eyes (``lod.block_distance``), or without views from the field's centre."""
    if views:
        return np.asarray(lod.block_distance, dtype=np.float32)
    bounds = layout.block_bounds
    centre = 0.5 * (bounds[:, :2] + bounds[:, 2:])
    return np.hypot(centre[:, 0], centre[:, 1]).astype(np.float32)


def blade_tints(layout, local: np.ndarray) -> dict:
    """Per corner of every blade quad of the positions ``local`` (FREE: zero): the colour at the
    corner's end of its segment (``meadow.segment_colours``: a joint's, a flower's head wholly in its
    colour) as (r, g), (b, shade); quad j's corners are (left_j, right_j, right_j+1, left_j+1)."""
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
    return {TINT_RG: rg.reshape(-1, 2), TINT_BS: bs.reshape(-1, 2)}


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


@dataclass(eq=False)
class RoleFrame:
    """What one role's slot objects show at a frame.

    ``shown`` (positions,): the field-wide block id at each position (``slots.FREE`` after the
    first ``count``); ``local``: the same as the window's local ids; ``vertices`` (positions x
    verts_per_block, 3) float32, FREE positions zero; ``velocity``: the same shape in m/s with
    motion blur, else None."""

    role: str
    shape: slots.PoolShape
    layout: object
    lod: object
    shown: np.ndarray
    local: np.ndarray
    count: int
    vertices: np.ndarray
    velocity: np.ndarray | None
    colours: dict | None = None  # the blades' colours and marks of a slot's blocks, kept by them (``attributes``)

    def object_rows(self, index: int) -> slice:
        """The rows of ``vertices`` that slot object ``index`` holds."""
        rows = self.shape.verts_per_object
        return slice(index * rows, (index + 1) * rows)

    def attributes(self, index: int, changed: bool) -> dict:
        """{name: per-corner float32 (corners, 2)} of slot object ``index``: blade colours when a
        position of it shows another block than before (``changed``), and then the flower heads'
        marks per vertex (``HEAD``, (vertices, 5); none where no species carries a head or
        leaves or is a plant: nothing draws them); card opacity always."""
        k = self.shape.k
        local = self.local[index * k:(index + 1) * k]
        if self.role == BLADES:
            if not changed:
                return {}
            key = local.tobytes()
            out = self.colours.get(key) if self.colours is not None else None
            if out is None:
                out = blade_tints(self.layout, local)
                if heads.carries_any(self.layout):
                    out[HEAD] = heads.tip_marks(self.layout, local)
                if self.colours is not None:
                    self.colours[key] = out
            return out
        return card_fade(self.layout, local, self.lod)


@dataclass(eq=False)
class Frame:
    """Everything Blender draws of a field at ``frame + subframe`` (``seconds`` on its clock)."""

    frame: int
    subframe: float
    seconds: float
    lod: object  # lod.LodWeights of the views (all geometry without views)
    blades: RoleFrame
    cards: RoleFrame
    gust: tuple | None  # with gust waves (``GrassField._gust``): (displacement (2,) m, mean speed m/s,
    # the loop's other displacement, (weight, other weight)); else None
    trail: object  # interaction.TrailMap the far canopy shows, or None

    def roles(self) -> tuple[RoleFrame, RoleFrame]:
        return self.blades, self.cards

    def blades_drawn(self) -> int:
        """How many blades the blade strips draw (the slots below each cell's N, eq 9, that grow)."""
        part = self.blades
        layout: Any = part.layout
        lod: Any = self.lod
        local = part.local[:part.count]
        num = layout.blades_per_cell
        cells = layout.block_cells[local].ravel()
        limit = np.full(len(cells), num) if lod is None else lod.blade_count[cells]
        drawn = np.arange(num)[None, :] < limit[:, None]  # (cells, slots)
        if layout.blade_alive is not None:
            blades = (local[:, None] * layout.blades_per_block + np.arange(layout.blades_per_block)).ravel()
            drawn &= layout.blade_alive[blades].reshape(len(cells), num)
        return int(drawn.sum())

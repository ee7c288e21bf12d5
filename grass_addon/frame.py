"""One frame of a field as Blender draws it, computed once by the engine (``GrassField.frame``).

A ``Frame`` holds, for each of the field's roles (``roles.ROLES``: blade strips, cards), which block every slot
position shows (``slots.py``), the float32 vertices of those positions (colliders cleared, bare
cells collapsed), their velocities when motion blur asks, and the per-vertex attributes of any
slot object (blade colours, card opacity); plus what the materials need: the gust waves' offset
and the colliders' trail map for the far canopy. The bridge only writes it (``bridge/pools.py``);
the headless scripts and the tests read the same arrays.

Which blocks a role shows: the visible blocks that need its level of detail (``Role.level``;
blades: some cell with N > 0, eq 9; cards: some card opacity K_b > 0, eqs 7 and 11) and where something grows
(paint), the nearest first, up to the pool's positions, then in block order (canonical: a frame
never depends on the frames shown before).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from . import slots
from .roles import BLADES, BY_NAME, CARDS, FADE, HEAD, NAMES, TINT_BS, TINT_RG, blade_tints, card_fade

# (the roles and their per-corner data are described once, in roles.py)
__all__ = ["BLADES", "CARDS", "FADE", "HEAD", "TINT_BS", "TINT_RG", "Frame", "RoleFrame", "block_distance",
           "blade_tints", "card_fade", "grows", "needs"]


def grows(layout) -> np.ndarray | bool:
    """(n_blocks,) bool: some blade of the block grows (paint.py); True without paint."""
    if layout.cell_density is None:
        return True
    return (layout.cell_density[layout.block_cells] > 0).any(axis=1)


def needs(role: str, layout, lod) -> np.ndarray:
    """(n_blocks,) bool: the window's blocks that ``role`` shows at these LOD weights."""
    entry = BY_NAME[role]
    if lod is None:  # every blade as geometry, no card
        return np.full(layout.n_blocks, entry.without_lod)
    level = getattr(lod, entry.level)
    return (level[layout.block_cells] > 0).any(axis=1) & lod.block_visible & grows(layout)


def block_distance(layout, lod, views) -> np.ndarray:
    """(n_blocks,) float32: how near each block is, for choosing the nearest: from the views'
    eyes (``lod.block_distance``), or without views from the field's centre."""
    if views:
        return np.asarray(lod.block_distance, dtype=np.float32)
    bounds = layout.block_bounds
    centre = 0.5 * (bounds[:, :2] + bounds[:, 2:])
    return np.hypot(centre[:, 0], centre[:, 1]).astype(np.float32)


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

    def attributes(self, index: int, changed: bool, relit: bool = True) -> dict:
        """{name: per-corner float32 (corners, 2)} of slot object ``index`` (``roles.Role.data``:
        blade colours and the flower heads' marks, card opacity). Data that depend on a slot's
        blocks alone come only when a position of it shows another block than before
        (``changed``), kept by those blocks in ``colours``; data that read the LOD weights too
        only then or when the weights are others than at the last write (``relit``)."""
        k = self.shape.k
        local = self.local[index * k:(index + 1) * k]
        entry = BY_NAME[self.role]
        if not entry.data_by_blocks:
            return entry.data(self.layout, local, self.lod) if changed or relit else {}
        if not changed:
            return {}
        key = local.tobytes()
        out = self.colours.get(key) if self.colours is not None else None
        if out is None:
            out = entry.data(self.layout, local, self.lod)
            if self.colours is not None:
                self.colours[key] = out
        return out


@dataclass(eq=False)
class Frame:
    """Everything Blender draws of a field at ``frame + subframe`` (``seconds`` on its clock)."""

    frame: int
    subframe: float
    seconds: float
    lod: object  # lod.LodWeights of the views (all geometry without views)
    parts: dict  # {role name: RoleFrame} of every role of ``roles.ROLES``
    gust: tuple | None  # with gust waves (``GrassField._gust``): (displacement (2,) m, mean speed m/s,
    # the loop's other displacement, (weight, other weight)); else None
    trail: object  # interaction.TrailMap the far canopy shows, or None

    def roles(self) -> tuple[RoleFrame, ...]:
        return tuple(self.parts[name] for name in NAMES)

    @property
    def blades(self) -> RoleFrame:
        return self.parts[BLADES]

    @property
    def cards(self) -> RoleFrame:
        return self.parts[CARDS]

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

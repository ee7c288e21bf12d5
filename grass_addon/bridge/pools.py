"""A field's two slot pools in Blender: blade strips and cards, one class used twice.

``slots.py`` decides (numpy only) which block each position shows; a ``SlotPool`` fills one float32
buffer with the vertices of the shown blocks, writes each object's rows with one bulk
``foreach_set`` and its per-vertex attributes (blade colours when a position changed block, card
opacity K_b every frame). FREE positions are collapsed to a point (zero area, nothing drawn).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .. import slots
from . import materials
from . import scene as field_scene
from .registry import warn_once


def write_positions(mesh, verts: np.ndarray) -> None:
    """Write float32 positions in bulk and tell Blender they changed.

    The bulk write goes to the ``position`` attribute (about 10x faster than
    ``vertices.foreach_set("co")``), but that path does not tag the positions as changed, so
    Blender would keep the bounds of an earlier frame and a render would depend on the frames
    rendered before it. Assigning one vertex through ``MeshVertex.co`` runs Blender's
    positions-changed update (bounds and normals recomputed) for the whole mesh.
    """
    mesh.attributes["position"].data.foreach_set("vector", verts.ravel())
    if len(mesh.vertices):
        first = mesh.vertices[0]
        first.co = first.co


class SlotPool:
    """The objects of one role (``blades`` or ``cards``) of a field and what they show.

    needs(lod) -> (n_blocks,) bool: blocks that need this level of detail (visible ones);
    fill(blocks, lod, out): their vertices into ``out``;
    attributes(mesh, blocks, lod, changed): per-vertex attributes of one object showing ``blocks``
    (FREE where nothing); ``changed``: some position of it shows another block than before.
    """

    def __init__(self, role: str, shape: slots.PoolShape, needs: Callable, fill: Callable, attributes: Callable):
        self.role = role
        self.shape = shape
        self.state = slots.PoolState(shape)
        self._needs, self._fill, self._attributes = needs, fill, attributes
        self.buffer = np.zeros((shape.positions * shape.verts_per_block, 3), dtype=np.float32)
        self.blocks = np.zeros(0, np.int32)  # the blocks shown at the last write, sorted

    def write(self, item, lod, block_distance: np.ndarray) -> None:
        """Assign this frame's blocks to positions and write every object that needs it."""
        assignment = self.state.assign(self._needs(lod), block_distance)
        shown, count = assignment.shown, assignment.count
        self.blocks = shown[:count].copy()
        rows_per_block = self.shape.verts_per_block
        if count:
            self._fill(shown[:count], lod, self.buffer[: count * rows_per_block])
        self.buffer[count * rows_per_block:] = 0.0
        objects = field_scene.slot_objects(item, self.role)
        k, rows = self.shape.k, self.shape.verts_per_object
        for index in np.flatnonzero(assignment.write).tolist():
            obj = objects.get(index)
            if obj is None:
                warn_once(f"{self.role} slot {index} of field '{item.name}' was deleted; its blocks are not "
                          "drawn (rebuild the field to restore it)")
                continue
            mesh = obj.data
            write_positions(mesh, self.buffer[index * rows:(index + 1) * rows])
            self._attributes(mesh, shown[index * k:(index + 1) * k], lod, bool(assignment.changed[index]))
            mesh.update()

    def collapse(self, item) -> None:
        """Every object to a point (nothing drawn); the next write rewrites everything."""
        for obj in field_scene.slot_objects(item, self.role).values():
            if len(obj.data.vertices):
                write_positions(obj.data, np.zeros((len(obj.data.vertices), 3), np.float32))
                obj.data.update()
        self.state.forget()
        self.blocks = np.zeros(0, np.int32)


def blade_pool(field, shape: slots.PoolShape) -> SlotPool:
    """Blade strips: blocks where some cell has N > 0 (eq 9); colours rewritten where a position
    changed block (FREE positions cleared, so an object's data is a function of the frame alone)."""
    layout = field.layout
    per_blade = (layout.segments + 1) * 2
    bpb = layout.blades_per_block

    def needs(lod):
        return (lod.blade_count[layout.block_cells] > 0).any(axis=1) & lod.block_visible

    def fill(blocks, lod, out):
        field.blade_vertices(blocks, lod=lod, out=out)

    def attributes(mesh, blocks, lod, changed):
        if not changed:
            return
        shown = blocks >= 0
        rgba = np.zeros((len(blocks), bpb, 4), dtype=np.float32)
        shade = np.zeros((len(blocks), bpb), dtype=np.float32)
        blades = blocks[shown, None].astype(np.int64) * bpb + np.arange(bpb)[None, :]
        rgba[shown, :, :3] = layout.species_color[layout.blade_species[blades]]
        rgba[shown, :, 3] = 1.0
        shade[shown] = layout.blade_shade[blades]
        mesh.attributes[materials.ATTR_COLOR].data.foreach_set(
            "color", np.repeat(rgba.reshape(-1, 4), per_blade, axis=0).ravel())
        mesh.attributes[materials.ATTR_SHADE].data.foreach_set("value", np.repeat(shade.ravel(), per_blade))

    return SlotPool(field_scene.ROLE_BLADES, shape, needs, fill, attributes)


def card_pool(field, shape: slots.PoolShape) -> SlotPool:
    """Cards: blocks where some card has opacity K_b > 0 (eqs 7, 11); the opacity follows the
    camera every frame, not only when a position changes block."""
    layout = field.layout

    def needs(lod):
        return (lod.k_billboard[layout.block_cells] > 0).any(axis=1) & lod.block_visible

    def fill(blocks, lod, out):
        field.card_vertices(blocks, out=out)

    def attributes(mesh, blocks, lod, changed):
        opacity = np.zeros((len(blocks), layout.cells_per_block_total), dtype=np.float32)
        shown = blocks >= 0
        opacity[shown] = lod.k_billboard[layout.block_cells[blocks[shown]]]
        mesh.attributes[materials.ATTR_OPACITY].data.foreach_set("value", np.repeat(opacity.ravel(), 4))

    return SlotPool(field_scene.ROLE_CARDS, shape, needs, fill, attributes)

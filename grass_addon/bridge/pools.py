"""A field's two slot pools in Blender: blade strips and cards, one class used twice.

``slots.py`` decides (numpy only) which block each position shows; a ``SlotPool`` fills one float32
buffer with the vertices of the shown blocks, writes each object's rows with one bulk
``foreach_set`` and its per-vertex attributes (blade colours when a position changed block, card
opacity K_b every frame). FREE positions are collapsed to a point (zero area, nothing drawn).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .. import kinematics, slots
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


def write_velocity(mesh, velocity: np.ndarray) -> None:
    """The per-point ``velocity`` attribute (m/s) Cycles and EEVEE blur a rewritten mesh by."""
    attribute = mesh.attributes.get(materials.ATTR_VELOCITY)
    if attribute is None:
        attribute = mesh.attributes.new(materials.ATTR_VELOCITY, "FLOAT_VECTOR", "POINT")
    attribute.data.foreach_set("vector", velocity.ravel())


class SlotPool:
    """The objects of one role (``blades`` or ``cards``) of a field and what they show.

    needs(layout, lod) -> (n_blocks,) bool: blocks of the field's window that need this level of
    detail (visible ones); fill(layout, cells, blocks, lod, out): their vertices for cell data
    ``cells`` into ``out``; attributes(layout, mesh, blocks, lod, changed): per-vertex attributes
    of one object showing ``blocks`` (FREE where nothing); ``changed``: some position of it shows
    another block than before. ``blocks`` are the window's local ids; positions record
    field-wide ids (``self.blocks``, ``state.shown``), so what an object shows never depends
    on the window.
    """

    def __init__(self, role: str, shape: slots.PoolShape, needs: Callable, fill: Callable, attributes: Callable):
        self.role = role
        self.shape = shape
        self.state = slots.PoolState(shape)
        self._needs, self._fill, self._attributes = needs, fill, attributes
        self.buffer = np.zeros((shape.positions * shape.verts_per_block, 3), dtype=np.float32)
        self.velocity: np.ndarray | None = None  # m/s per vertex, made when motion blur asks for it
        self.ahead: np.ndarray | None = None  # the later pose, scratch space of GrassField.motion
        self.blocks = np.zeros(0, np.int64)  # the blocks (field-wide ids) shown at the last write, sorted

    def write(self, item, field, lod, block_distance: np.ndarray, motion=None) -> None:
        """Assign this frame's blocks to positions and write every object that needs it.

        ``motion``: None, or (frame, subframe, fps) for motion blur: the vertices at that instant
        and a ``velocity`` attribute (m/s) from the same blocks' poses at the neighbouring frames
        (``GrassField.motion``), so a position that shows another block than on the neighbouring
        frame never smears across the image."""
        layout = field.layout
        assignment = self.state.assign(self._needs(layout, lod), block_distance, layout.block_ids)
        shown, count = assignment.shown, assignment.count
        self.blocks = shown[:count].copy()
        local = np.full(shown.shape, slots.FREE, dtype=np.int64)
        local[:count] = np.searchsorted(layout.block_ids, shown[:count])
        rows = count * self.shape.verts_per_block
        if motion is None:
            if count:
                self._fill(layout, field.cells, local[:count], lod, self.buffer[:rows])
        else:
            if self.velocity is None:
                self.velocity = np.zeros_like(self.buffer)
                self.ahead = np.empty_like(self.buffer)
            frame, subframe, fps = motion
            if count:
                def vertices(cells, out):
                    self._fill(layout, cells, local[:count], lod, out)

                field.motion(frame, subframe, fps, vertices, self.buffer[:rows], self.velocity[:rows],
                             self.ahead[:rows])
            self.velocity[rows:] = 0.0
        self.buffer[rows:] = 0.0
        objects = field_scene.slot_objects(item, self.role)
        k, rows = self.shape.k, self.shape.verts_per_object
        if motion is not None:  # every object carries this frame's velocities (FREE: zero)
            assignment.write[:] = True
        for index in np.flatnonzero(assignment.write).tolist():
            obj = objects.get(index)
            if obj is None:
                warn_once(f"{self.role} slot {index} of field '{item.name}' was deleted; its blocks are not "
                          "drawn (rebuild the field to restore it)")
                continue
            mesh = obj.data
            write_positions(mesh, self.buffer[index * rows:(index + 1) * rows])
            if motion is not None:
                write_velocity(mesh, self.velocity[index * rows:(index + 1) * rows])
            self._attributes(layout, mesh, local[index * k:(index + 1) * k], lod, bool(assignment.changed[index]))
            mesh.update()

    def collapse(self, item) -> None:
        """Every object to a point (nothing drawn); the next write rewrites everything."""
        collapse_objects(field_scene.slot_objects(item, self.role).values())
        self.state.forget()
        self.blocks = np.zeros(0, np.int64)


def collapse_objects(objects) -> None:
    """Every vertex of each object's mesh to the origin (nothing drawn)."""
    for obj in objects:
        if len(obj.data.vertices):
            write_positions(obj.data, np.zeros((len(obj.data.vertices), 3), np.float32))
            obj.data.update()


def _write_uv(mesh, name: str, uv: np.ndarray) -> None:
    mesh.uv_layers[name].data.foreach_set("uv", np.ascontiguousarray(uv, dtype=np.float32).ravel())


def _grows(layout) -> np.ndarray | bool:
    """(n_blocks,) bool: some blade of the block grows (paint.py); True without paint."""
    if layout.cell_density is None:
        return True
    return (layout.cell_density[layout.block_cells] > 0).any(axis=1)


def blade_pool(field, shape: slots.PoolShape) -> SlotPool:
    """Blade strips: blocks where some cell has N > 0 (eq 9); colours rewritten where a position
    changed block (FREE positions cleared, so an object's data is a function of the frame alone)."""

    def needs(layout, lod):
        return (lod.blade_count[layout.block_cells] > 0).any(axis=1) & lod.block_visible & _grows(layout)

    def fill(layout, cells, blocks, lod, out):
        kinematics.blade_vertices(layout, cells, blocks, lod.blade_count, out)

    def attributes(layout, mesh, blocks, lod, changed):
        if not changed:
            return
        corners = layout.segments * 4  # per blade: n quads
        bpb = layout.blades_per_block
        shown = blocks >= 0
        rg = np.zeros((len(blocks), bpb, 2), dtype=np.float32)
        bs = np.zeros((len(blocks), bpb, 2), dtype=np.float32)
        blades = blocks[shown, None].astype(np.int64) * bpb + np.arange(bpb)[None, :]
        colour = layout.species_color[layout.blade_species[blades]]
        rg[shown] = colour[..., :2]
        bs[shown, :, 0] = colour[..., 2]
        bs[shown, :, 1] = layout.blade_shade[blades]
        _write_uv(mesh, materials.UV_TINT_RG, np.repeat(rg.reshape(-1, 2), corners, axis=0))
        _write_uv(mesh, materials.UV_TINT_BS, np.repeat(bs.reshape(-1, 2), corners, axis=0))

    return SlotPool(field_scene.ROLE_BLADES, shape, needs, fill, attributes)


def card_pool(field, shape: slots.PoolShape) -> SlotPool:
    """Cards: blocks where some card has opacity K_b > 0 (eqs 7, 11); the opacity follows the
    camera every frame, not only when a position changes block."""

    def needs(layout, lod):
        return (lod.k_billboard[layout.block_cells] > 0).any(axis=1) & lod.block_visible & _grows(layout)

    def fill(layout, cells, blocks, lod, out):
        kinematics.card_vertices(layout, cells, blocks, out)
        if layout.cell_density is not None:
            # a cell where nothing grows has no card at all: collapsed, so rays do not cross it
            # (many see-through cards along a path would use up a renderer's transparent layers)
            bare = layout.cell_density[layout.block_cells[blocks]] <= 0.0
            quads = out.reshape(len(blocks), layout.cells_per_block_total, 4, 3)
            quads[bare] = quads[bare][:, :1]

    def attributes(layout, mesh, blocks, lod, changed):
        opacity = np.zeros((len(blocks), layout.cells_per_block_total), dtype=np.float32)
        shown = blocks >= 0
        opacity[shown] = lod.k_billboard[layout.block_cells[blocks[shown]]]
        if layout.cell_density is not None:  # a card shows only its cell's blades that grow (paint)
            opacity[shown] *= layout.cell_density[layout.block_cells[blocks[shown]]]
        _write_uv(mesh, materials.UV_FADE, np.repeat(opacity.ravel(), 8))  # (K_b, K_b) at 4 corners

    return SlotPool(field_scene.ROLE_CARDS, shape, needs, fill, attributes)

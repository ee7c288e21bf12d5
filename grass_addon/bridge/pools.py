"""A field's two slot pools in Blender: blade strips and cards, one class used twice.

The engine computes the frame (``GrassField.frame``: which block each position shows, the
vertices, velocities and attributes); a ``SlotPool`` writes one role of it: each object's rows
with one bulk ``foreach_set``, its velocities with motion blur, and its per-vertex attributes
(blade colours when a position changed block, card opacity when it or the LOD weights did). ``slots.PoolState``
remembers what each position showed, so objects that did not change are not written.
"""

from __future__ import annotations

import numpy as np

from .. import frame as frames
from .. import slots
from . import heads, materials, meshes, owned
from .registry import warn_once

# the UV map each engine attribute is written to
UV_OF = materials.UV_OF


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
    write_point_vectors(mesh, materials.ATTR_VELOCITY, velocity)


def write_point_vectors(mesh, name: str, values: np.ndarray) -> None:
    """The per-point 3-vector attribute ``name`` (made if missing)."""
    attribute = mesh.attributes.get(name)
    if attribute is None:
        attribute = mesh.attributes.new(name, "FLOAT_VECTOR", "POINT")
    attribute.data.foreach_set("vector", np.ascontiguousarray(values, dtype=np.float32).ravel())


def write_point_values(mesh, name: str, values: np.ndarray, kind: str = "FLOAT") -> None:
    """The per-point number attribute ``name`` (``kind`` FLOAT or INT; made if missing)."""
    attribute = mesh.attributes.get(name)
    if attribute is None:
        attribute = mesh.attributes.new(name, kind, "POINT")
    attribute.data.foreach_set("value", np.ascontiguousarray(values, np.float32 if kind == "FLOAT" else np.int32))


class SlotPool:
    """The objects of one role (``blades`` or ``cards``) of a field and what they showed."""

    def __init__(self, role: str, shape: slots.PoolShape):
        self.role = role
        self.shape = shape
        self.state = slots.PoolState(shape)
        self.blocks = np.zeros(0, np.int64)  # the blocks (field-wide ids) shown at the last write, sorted

    def write(self, item, part) -> None:
        """Write ``part`` (this role's ``frame.RoleFrame``) into every object that needs it: one
        whose positions changed, or all of them when the frame carries velocities."""
        assignment = self.state.record(part.shown, part.lod)
        self.blocks = part.shown[:part.count].copy()
        if part.velocity is not None:  # every object carries this frame's velocities (FREE: zero)
            assignment.write[:] = True
        for index in np.flatnonzero(assignment.write).tolist():
            obj = owned.slot_object(item, self.role, index)
            if obj is None:
                warn_once(f"{self.role} slot {index} of field '{item.name}' was deleted; its blocks are not "
                          "drawn (rebuild the field to restore it)")
                continue
            mesh = obj.data
            if not obj.is_runtime_data:  # a copy of a slot (a Full Copy of the scene): kept out of files too
                obj.is_runtime_data = mesh.is_runtime_data = True
            rows = part.object_rows(index)
            write_positions(mesh, part.vertices[rows])
            if part.velocity is not None:
                write_velocity(mesh, part.velocity[rows])
            for name, values in part.attributes(index, bool(assignment.changed[index]), assignment.relit).items():
                if name == frames.HEAD:
                    heads.write_marks(mesh, values)
                else:
                    meshes.write_uv(mesh, UV_OF[name], values)
            mesh.update()

    def collapse(self, item) -> None:
        """Every object to a point (nothing drawn); the next write rewrites everything."""
        collapse_objects(owned.slot_objects(item, self.role).values())
        self.state.forget()
        self.blocks = np.zeros(0, np.int64)


def collapse_objects(objects) -> None:
    """Every vertex of each object's mesh to the origin (nothing drawn)."""
    for obj in objects:
        if len(obj.data.vertices):
            write_positions(obj.data, np.zeros((len(obj.data.vertices), 3), np.float32))
            obj.data.update()


"""What the far grass and the ground show of a field's paint: the ground grid a painted field
needs, the paint map image the canopy reads, the canopy and fringe heights scaled by the length map."""

from __future__ import annotations

import bpy
import numpy as np

from .. import paint as paint_core
from .. import terrain as terrain_core
from ..grid import FieldGrid
from ..schema import Params
from . import materials
from .meshes import edge_ring, read_uv, thinning_edge, write_uv
from .owned import MADE_KEY, ROLE_CANOPY_MATERIAL, ROLE_PAINT_MAP, ground_object, record, registered, tag

# The ground of a painted field on flat ground is a grid of this many cells along its longer side,
# so the canopy can follow a length map (a mown patch stands lower).
PAINT_GROUND_CELLS = 256

PAINT_MAP_PIXELS = 1024  # the paint map image's longer side (the canopy's share of growing blades)


def painted_settings(params: Params, item) -> bool:
    """Whether the field's settings paint it (maps, keep-out shapes or a keep-out collection):
    its ground is then a grid and its canopy reads a paint map (part of the slot topology)."""
    return bool(paint_core.map_settings(params) or params.keep_out.shapes or item.keep_out_collection)


def paint_ground(params: Params, heightfield):
    """The heightfield the ground mesh of a painted field follows (a flat grid on flat ground)."""
    if heightfield is not None:
        return heightfield
    grid = FieldGrid.of(params)
    spacing = max(grid.size) / PAINT_GROUND_CELLS
    nx, ny = (max(1, int(np.ceil(s / spacing - 1e-9))) for s in grid.size)
    return terrain_core.Heightfield.flat(grid.origin, spacing, nx, ny)


def paint_map_extent(paint, field) -> tuple[float, float, float, float]:
    """What the paint map covers: the painted density map's rectangle and the keep-out footprints'
    reach, within the field (outside it the map's edge values go on, as a raster's do)."""
    boxes = []
    if paint is not None and paint.density is not None:
        boxes.append(paint.density.extent)
    if paint is not None and paint.keep_out is not None and len(paint.keep_out.triangles):
        boxes.append(paint.keep_out.bounds())
    if not boxes:
        return field
    x0, y0 = max(field[0], min(b[0] for b in boxes)), max(field[1], min(b[1] for b in boxes))
    x1, y1 = min(field[2], max(b[2] for b in boxes)), min(field[3], max(b[3] for b in boxes))
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else field


def update_paint_look(item, params: Params, paint) -> None:
    """What the far grass shows of the paint: the paint map image (R: the share of blades that
    grow, G: their length / 2 over the field's extent) and the canopy and fringe heights of the
    ground (scaled by the length map). Data writes only (no datablock is added or removed)."""
    image = registered(item).get(ROLE_PAINT_MAP)
    ground = ground_object(item)
    field = paint_core.field_extent(params)
    if isinstance(image, bpy.types.Image):
        x0, y0, x1, y1 = extent = paint_map_extent(paint, field)
        w, h = x1 - x0, y1 - y0
        longest = PAINT_MAP_PIXELS
        if paint is not None and paint.density is not None and paint.keep_out is None:
            raster = paint.density  # no finer than the density map's own pixels
            pixel = min((raster.extent[2] - raster.extent[0]) / raster.values.shape[1],
                        (raster.extent[3] - raster.extent[1]) / raster.values.shape[0])
            longest = int(min(PAINT_MAP_PIXELS, max(16, np.ceil(max(w, h) / pixel))))
        size = (longest, max(1, round(longest * h / w))) if w >= h else (max(1, round(longest * w / h)), longest)
        if tuple(image.size) != size:
            image.scale(*size)
        iw, ih = size
        px = x0 + (np.arange(iw) + 0.5) / iw * w
        py = y0 + (np.arange(ih) + 0.5) / ih * h
        xy = np.stack(np.meshgrid(px, py), axis=-1).reshape(-1, 2)
        rgba = np.ones((len(xy), 4), np.float32)
        if paint is not None:
            rgba[:, 0] = paint.density_at(xy)
            rgba[:, 1] = 0.5 * paint.length_at(xy)
        else:
            rgba[:, 1] = 0.5
        rgba[:, 2] = 0.0
        image.pixels.foreach_set(rgba.ravel())
        image.update()
        materials.set_paint_map(registered(item).get(ROLE_CANOPY_MATERIAL), image, field, extent)
    if ground is None or ground.data.get("wg_layers") is None:
        return
    mesh = ground.data
    n, canopy, top, nx, ny = (float(v) for v in list(mesh["wg_layers"])[:5])
    n, nx, ny = int(n), int(nx), int(ny)
    co: np.ndarray = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.attributes["position"].data.foreach_get("vector", co)
    co = co.reshape(-1, 3)
    floor_z = co[:n, 2]
    scale = np.ones(len(co)) if paint is None else paint.length_at(co[:, :2])
    edge = thinning_edge(params)
    if edge is not None:  # (the field's thinning edge brings the canopy down as it does the blades)
        scale = scale * edge[1](co[:, :2])
    lift = np.zeros(len(co))
    lift[n:2 * n] = canopy * scale[n:2 * n]
    # the fringe's top vertices stand over the edge's floor vertices (the ring, in order)
    ring_floor = edge_ring(nx, ny) if nx else np.array([0, 1, 2, 3])
    lift[2 * n:] = max(top, canopy) * scale[2 * n:]
    z = np.concatenate([floor_z, floor_z + lift[n:2 * n], floor_z[ring_floor] + lift[2 * n:]])
    co[:, 2] = z
    mesh.attributes["position"].data.foreach_set("vector", co.ravel())
    first = mesh.vertices[0]
    first.co = first.co  # (positions changed: bounds)
    corners = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", corners)
    uv = read_uv(mesh, materials.UV_SWARD_Z)
    uv[:, 1] = lift[corners]
    write_uv(mesh, materials.UV_SWARD_Z, uv)
    mesh.update()


def paint_map(item, uid: str, base: str, grid, canopy) -> None:
    """The field's paint map image (``grid``: the field's, when it is painted; None: none), packed
    and read by the canopy; written by ``update_paint_look``."""
    image = registered(item).get(ROLE_PAINT_MAP)
    if grid is None:
        if isinstance(image, bpy.types.Image):
            del item[MADE_KEY][ROLE_PAINT_MAP]
            if image.users == 0:
                bpy.data.images.remove(image)
        materials.set_paint_map(canopy, None)
        return
    if not isinstance(image, bpy.types.Image):
        image = bpy.data.images.new(f"{base} paint map", width=PAINT_MAP_PIXELS, height=PAINT_MAP_PIXELS,
                                    alpha=False)
        image.colorspace_settings.name = "Non-Color"
        image.pack()
        tag(image, uid, ROLE_PAINT_MAP)
        record(item, ROLE_PAINT_MAP, image)
    materials.set_paint_map(canopy, image)

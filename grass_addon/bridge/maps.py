"""The field's paint in Blender: maps and keep-out footprints from the scene (paint.py is the engine).

A map setting (``paint.density``, ``paint.length``, a species row's ``density_map``) names:
  * a PNG file (read by ``images.read_map``, as batch renders read it);
  * ``vertex_group:NAME`` or ``attribute:NAME`` of the terrain mesh (a float or colour attribute on
    its points or face corners): painted in Weight or Vertex Paint mode, draped over the field
    like the terrain itself (the top surface's values at a grid of the field's cells);
  * ``image:NAME``, an image of the file: over the terrain's UV map, or over ``paint.extent`` (the
    field's extent) on flat ground; painted in Texture Paint mode.
The field's keep-out collection: the ground outline (the triangles of the evaluated mesh, seen from
above) of every object in it, a curve with a bevel included.

Everything is read in the field's frame (the ground object's inverse world matrix), so moving the
field moves what it grows around. Numbers that make a map: ``fingerprint`` goes into the field's
digest (renders stay a function of the scene), the rasters into ``GrassField(paint=...)``.
"""

from __future__ import annotations

import json
import os

import bpy
import numpy as np
from mathutils import Vector

from .. import images
from .. import paint as paint_core
from .. import terrain as terrain_core
from ..errors import ParameterError
from ..grid import FieldGrid
from ..schema import Params
from .meshes import read_uv
from .owned import ground_object
from .registry import warn_once

MAX_MAP_SAMPLES = 1024  # samples along a side of a map draped from the terrain (one per cell, or coarser)


def _to_field(item):
    """4x4 numpy matrix from world to the field's frame (the ground's inverse), or None."""
    ground = ground_object(item)
    if ground is None:
        return None
    return np.array(ground.matrix_world.inverted_safe(), dtype=np.float64)


def map_grid(params: Params, detail: float = 0.0) -> tuple[np.ndarray, float, int, int]:
    """(origin, spacing, nx, ny): the grid maps are draped onto, a sample per cell corner, or per
    ``detail`` metres where the mesh holds no finer detail (half its mean edge), or coarser for
    large fields (at most MAX_MAP_SAMPLES along a side)."""
    grid = FieldGrid.of(params)
    step = max(1, int(detail // grid.cell_size))
    cells = max(grid.cells_x, grid.cells_y)
    return terrain_core.grid_for(params, max_cells=max(1, min(MAX_MAP_SAMPLES, cells // step)))


def _detail(triangles: np.ndarray) -> float:
    """Half the mean edge length of a mesh's triangles (seen from above): the finest detail that
    values on its vertices can hold."""
    if not len(triangles):
        return 0.0
    edges = np.linalg.norm(triangles[:, [1, 2, 0], :2] - triangles[:, :, :2], axis=-1)
    return 0.5 * float(edges.mean())


def _grid_raster(values: np.ndarray, params: Params, name: str, detail: float = 0.0) -> paint_core.Raster:
    """A raster whose pixel centres are the map grid's samples."""
    origin, spacing, nx, ny = map_grid(params, detail)
    h = 0.5 * spacing
    extent = (origin[0] - h, origin[1] - h, origin[0] + nx * spacing + h, origin[1] + ny * spacing + h)
    return paint_core.Raster(values.reshape(ny + 1, nx + 1), extent, name)


def _mesh_corners(obj, to_field: np.ndarray):
    """(triangles (T, 3, 3) in the field's frame, loop triangles' loop ids (T, 3), their vertex
    ids (T, 3), the mesh) of the object's evaluated mesh (free it with ``_done``)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    mesh.calc_loop_triangles()
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    loops = np.empty(len(mesh.loop_triangles) * 3, np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    verts = np.empty(len(mesh.loop_triangles) * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", verts)
    m = to_field @ np.array(evaluated.matrix_world, dtype=np.float64)
    world = co.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]
    return world[verts].reshape(-1, 3, 3), loops.reshape(-1, 3), verts.reshape(-1, 3), evaluated, mesh


def _vertex_group_weights(obj, mesh, name: str, setting: str) -> np.ndarray:
    group = obj.vertex_groups.get(name)
    if group is None:
        have = ", ".join(repr(g.name) for g in obj.vertex_groups) or "none"
        raise ParameterError(setting, f"the terrain '{obj.name}' has no vertex group {name!r} (it has: {have})")
    index, weights = group.index, np.zeros(len(mesh.vertices))
    for v in mesh.vertices:  # (no bulk access to vertex group weights)
        for g in v.groups:
            if g.group == index:
                weights[v.index] = g.weight
    return weights


def _attribute_values(obj, mesh, name: str, setting: str) -> tuple[np.ndarray, str]:
    """(values, domain) of a float or colour attribute (colours: the mean of R, G and B)."""
    attribute = mesh.attributes.get(name) if name not in ("position",) else None
    usable = [a.name for a in mesh.attributes if a.data_type in ("FLOAT", "FLOAT_COLOR", "BYTE_COLOR")
              and a.domain in ("POINT", "CORNER") and not a.name.startswith(".")]
    if attribute is None or attribute.name not in usable:
        raise ParameterError(setting, f"the terrain '{obj.name}' has no float or colour attribute {name!r} on its "
                             f"points or face corners (it has: {', '.join(map(repr, usable)) or 'none'})")
    n = len(attribute.data)
    if attribute.data_type == "FLOAT":
        values = np.empty(n, np.float32)
        attribute.data.foreach_get("value", values)
    else:
        rgba = np.empty(n * 4, np.float32)
        attribute.data.foreach_get("color", rgba)
        values = rgba.reshape(n, 4)[:, :3].mean(axis=1)
    return values.astype(np.float64), attribute.domain


IMAGES_KEY = "wg_maps"  # the field item's custom property: {setting: the image it paints with}


def hold_images(item, params: Params) -> None:
    """Record on the field's item the image each ``image:NAME`` map setting names: an ID pointer
    counts as a user, so Blender keeps the image when the file is saved, and it follows a rename
    (``map_image``). Called where datablocks may change (``lifecycle.apply_settings``)."""
    held = dict(item.get(IMAGES_KEY) or {})
    wanted = {}
    for setting, value in paint_core.map_settings(params):
        kind, _, name = value.partition(":")
        if kind == "image":
            image = bpy.data.images.get(name) or held.get(setting)
            if isinstance(image, bpy.types.Image):
                wanted[setting] = image
    if {k: getattr(v, "name", None) for k, v in held.items()} != {k: v.name for k, v in wanted.items()}:
        item[IMAGES_KEY] = wanted


def map_image(item, setting: str, name: str):
    """The image ``image:NAME`` of ``setting`` names: the image of that name, else the one the item
    holds for the setting (renamed since); None when neither exists."""
    image = bpy.data.images.get(name)
    if image is None:
        held = (item.get(IMAGES_KEY) or {}).get(setting) if item is not None else None
        image = held if isinstance(held, bpy.types.Image) else None
    return image


def _image_pixels(name: str, setting: str, item=None) -> np.ndarray:
    """(h, w) grey levels 0..1 of an image datablock (row 0 at the bottom, as Blender stores it)."""
    image = map_image(item, setting, name)
    if image is None:
        have = ", ".join(repr(i.name) for i in bpy.data.images if i.type in ("IMAGE", "UV_TEST")) or "none"
        raise ParameterError(setting, f"there is no image {name!r} in this file (images: {have}); pick the map "
                             "with the button beside the setting, or clear it to grow the grass everywhere")
    w, h = image.size
    if w * h == 0:
        raise ParameterError(setting, f"the image {name!r} has no pixels (is its file missing?)")
    pixels = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(pixels)
    pixels = pixels.reshape(h, w, image.channels)
    return pixels[..., :3].mean(axis=-1) if image.channels >= 3 else pixels[..., 0]


def _sample_image(pixels: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear values of an image (row 0 at the bottom) at UVs (n, 2), its edge pixels beyond it
    (as an image texture set to Extend shows it: a map's edge is not its opposite edge)."""
    h, w = pixels.shape
    u = np.clip(uv[:, 0] * w - 0.5, 0.0, w - 1)
    v = np.clip(uv[:, 1] * h - 0.5, 0.0, h - 1)
    i0, j0 = np.floor(u).astype(np.intp), np.floor(v).astype(np.intp)
    fu, fv = u - i0, v - j0
    i1, j1 = np.minimum(i0 + 1, w - 1), np.minimum(j0 + 1, h - 1)
    low = pixels[j0, i0] + (pixels[j0, i1] - pixels[j0, i0]) * fu
    high = pixels[j1, i0] + (pixels[j1, i1] - pixels[j1, i0]) * fu
    return low + (high - low) * fv


def _blender_map(scene, item, params: Params, setting: str, value: str, to_field) -> paint_core.Raster:
    """The raster of a ``vertex_group:``, ``attribute:`` or ``image:`` map setting."""
    kind, _, name = value.partition(":")
    terrain = terrain_object(scene, item)
    if kind == "image" and terrain is None:  # flat ground: the image over the extent
        extent = paint_core.map_extent(params, params.paint.extent, "paint.extent")
        return paint_core.Raster(_image_pixels(name, setting, item), extent, setting)
    if terrain is None:
        raise ParameterError(setting, f"{value!r} is read from the terrain mesh, and field '{item.name}' has none "
                             "(set its Terrain; on flat ground use image:NAME or a PNG file)")
    if to_field is None:
        raise ParameterError(setting, f"field '{item.name}' has no ground object yet (Rebuild it)")
    triangles, loops, verts, evaluated, mesh = _mesh_corners(terrain, to_field)
    try:
        if kind == "vertex_group":
            corner = _vertex_group_weights(terrain, mesh, name, setting)[verts]
        elif kind == "attribute":
            values, domain = _attribute_values(terrain, mesh, name, setting)
            corner = values[verts] if domain == "POINT" else values[loops]
        else:
            uv_layer = mesh.uv_layers.active
            if uv_layer is None:
                raise ParameterError(setting, f"the terrain '{terrain.name}' has no UV map to lay {value!r} on "
                                     "(add one, or paint a vertex group)")
            corner_uv = read_uv(mesh, uv_layer.name)[loops]
            pixels = _image_pixels(name, setting, item)
            corner = None
    finally:
        evaluated.to_mesh_clear()
    detail = _detail(triangles) if corner is not None else 0.0  # (an image holds its own detail)
    origin, spacing, nx, ny = map_grid(params, detail)
    if corner is not None:
        _, hit, draped = terrain_core.drape(triangles, origin, spacing, nx, ny, corner_values=corner[..., None])
        values = np.where(hit, draped[..., 0], 1.0)
    else:
        _, hit, draped = terrain_core.drape(triangles, origin, spacing, nx, ny, corner_values=corner_uv)
        values = np.where(hit, _sample_image(pixels, draped.reshape(-1, 2)).reshape(hit.shape), 1.0)
    return _grid_raster(values, params, setting, detail)


SURFACE_TYPES = ("MESH", "CURVE", "SURFACE", "META", "FONT")


def keep_out_triangles(item, to_field, notes: list | None = None) -> np.ndarray:
    """(T, 3, 2) ground outlines of the objects of the field's keep-out collection. An object with
    no surface (an empty, a light) or no faces (a curve without a bevel) keeps nothing out; it is
    left out, and ``notes`` (a list) gets a sentence saying so."""
    coll = item.keep_out_collection
    if coll is None:
        return np.zeros((0, 3, 2))
    parts = []
    for obj in coll.all_objects:
        if obj.type not in SURFACE_TYPES:
            if notes is not None:
                notes.append(f"'{obj.name}' in the keep-out collection is a {obj.type.lower()} with no surface: it "
                             "keeps no grass out (meshes, curves with a bevel and text do)")
            continue
        if to_field is None:
            continue
        triangles, _, _, evaluated, _ = _mesh_corners(obj, to_field)
        evaluated.to_mesh_clear()
        if not len(triangles):
            if notes is not None:
                notes.append(f"'{obj.name}' in the keep-out collection has no faces: it keeps no grass out (a curve "
                             "needs a bevel or an extrusion to have a footprint)")
            continue
        parts.append(triangles[..., :2])
    return np.concatenate(parts) if parts else np.zeros((0, 3, 2))


def keep_out_notes(item) -> list[str]:
    """What the panel says of the objects of the keep-out collection that keep nothing out (from
    their types and data alone: cheap enough for every redraw)."""
    coll = item.keep_out_collection
    notes: list[str] = []
    for obj in coll.all_objects if coll is not None else ():
        if obj.type not in SURFACE_TYPES:
            notes.append(f"'{obj.name}' in the keep-out collection is a {obj.type.lower()} with no surface: it "
                         "keeps no grass out (meshes, curves with a bevel and text do)")
        elif (obj.type == "MESH" and not obj.modifiers and not len(obj.data.polygons)) or (
                obj.type == "CURVE" and not obj.data.bevel_depth and not obj.data.extrude
                and obj.data.bevel_object is None):
            notes.append(f"'{obj.name}' in the keep-out collection has no faces: it keeps no grass out (a curve "
                         "needs a bevel or an extrusion to have a footprint)")
    return notes


def paint_of(scene, item, params: Params) -> paint_core.Paint | None:
    """The field's paint now (None: nothing painted); ParameterError naming the setting for a
    source that is not there (with what is)."""
    to_field = _to_field(item)
    extra = {}
    for setting, value in paint_core.map_settings(params):
        if value.startswith(paint_core.BLENDER_SOURCES):
            extra[setting] = _blender_map(scene, item, params, setting, value, to_field)
    rows = len(params.species())
    footprint = keep_out_triangles(item, to_field)
    blender = paint_core.Paint(
        density=extra.get("paint.density"), length=extra.get("paint.length"),
        species=tuple(extra.get(f"blade.species[{i}].density_map") for i in range(rows)),
        keep_out=paint_core.KeepOut(footprint) if len(footprint) else None)
    return paint_core.from_params(params, read_file, extra=blender, blender=True)


def read_file(path: str, name: str):
    """A map file's values; Blender's relative paths (``//map.png``) are from the .blend's folder."""
    return images.read_map(bpy.path.abspath(path), name)


def _setting_of(params: Params, value: str) -> str:
    return next((setting for setting, v in paint_core.map_settings(params) if v == value), "")


def depends_on(scene, item, params: Params) -> set:
    """Names of the datablocks the field's paint reads (its terrain, images, keep-out objects):
    an update to one of them is a stroke or an edit to apply."""
    names = set()
    terrain = terrain_object(scene, item)
    for _, value in paint_core.map_settings(params):
        kind, _, name = value.partition(":")
        if kind in ("vertex_group", "attribute") and terrain is not None:
            names.add(("OBJECT", terrain.name))
            names.add(("MESH", terrain.data.name))
        elif kind == "image":
            image = map_image(item, _setting_of(params, value), name)
            names.add(("IMAGE", image.name if image is not None else name))
            if terrain is not None:
                names.add(("OBJECT", terrain.name))
    coll = item.keep_out_collection
    if coll is not None:
        names |= {("OBJECT", o.name) for o in coll.all_objects}
        names.add(("COLLECTION", coll.name))
    return names


def extent_xy(obj) -> tuple[float, float]:
    """The x and y extent (metres) of ``obj``'s world bounding box."""
    corners = np.array([tuple(obj.matrix_world @ Vector(c)) for c in obj.bound_box])
    size = corners.max(axis=0) - corners.min(axis=0)
    return float(size[0]), float(size[1])


def terrain_object(scene, item):
    """``item.terrain`` when it is a mesh object of ``scene``, else None."""
    obj = item.terrain
    if obj is None or obj.type != "MESH" or scene.objects.get(obj.name) is not obj:
        return None
    return obj


def terrain_key(scene, item, params: Params) -> str:
    """Cheap key of what the terrain samples depend on besides the mesh data (the object and the
    grid): the runtime keeps its samples while it holds; Rebuild re-samples anyway."""
    obj = terrain_object(scene, item)
    _, spacing, nx, ny = terrain_core.grid_for(params)
    if obj is None:
        t = params.terrain
        if not t.heightmap:
            return ""
        try:
            stat = os.stat(bpy.path.abspath(t.heightmap))
            mark = [stat.st_mtime_ns, stat.st_size]
        except OSError:
            mark = None  # read (and reported) by sample_terrain
        return json.dumps(["heightmap", t.heightmap, mark, t.height, list(t.extent), round(spacing, 9), nx, ny])
    return json.dumps([obj.name, round(spacing, 9), nx, ny])


def _world_triangles(obj) -> np.ndarray:
    """(T, 3, 3) float64 world-space triangles of the mesh as evaluated (modifiers, shape keys)."""
    def extract(mesh, matrix) -> np.ndarray:
        mesh.calc_loop_triangles()
        co = np.empty(len(mesh.vertices) * 3, np.float32)
        mesh.vertices.foreach_get("co", co)
        tri = np.empty(len(mesh.loop_triangles) * 3, np.int32)
        mesh.loop_triangles.foreach_get("vertices", tri)
        m = np.array(matrix, dtype=np.float64)
        world = co.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]
        return world[tri].reshape(-1, 3, 3)

    if len(obj.modifiers) or obj.data.shape_keys is not None:
        try:
            evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
            mesh = evaluated.to_mesh()
            try:
                return extract(mesh, evaluated.matrix_world)
            finally:
                evaluated.to_mesh_clear()
        except Exception as exc:  # no depsgraph here (e.g. mid-render): the mesh without modifiers
            warn_once(f"terrain '{obj.name}': modifiers not applied ({type(exc).__name__}: {exc})")
    return extract(obj.data, obj.matrix_world)


def sample_terrain(scene, item, params: Params):
    """(heightfield, centre_xy) of ``item.terrain``, or (None, None) for flat ground.

    The field is centred on the terrain's XY bounding-box centre (world space); the heightfield
    holds the world Z of the mesh's top surface at the grid's samples (``terrain.grid_for``), a
    downward ray cast per sample done as one vectorised pass (``terrain.drape``); samples off the
    mesh take the nearest hit's height. Deterministic: a function of the mesh and the params.
    """
    obj = terrain_object(scene, item)
    coll = item.collection
    if obj is None and params.terrain.heightmap and item.terrain is None:
        return terrain_core.from_params(params, read_file), None  # a scene file's heightmap
    if obj is None:
        lost = item.terrain is not None or (coll is not None and coll.get("wg_terrain"))
        if lost:
            name = coll.get("wg_terrain") if coll is not None and coll.get("wg_terrain") else item.terrain.name
            warn_once(f"terrain '{name}' of field '{item.name}' is gone or not a mesh in this scene; "
                               "the grass grows on flat ground")
        return None, None
    tris = _world_triangles(obj)
    if len(tris) == 0:
        warn_once(f"terrain '{obj.name}' of field '{item.name}' has no faces; the grass grows on flat ground")
        return None, None
    lo, hi = tris.reshape(-1, 3).min(axis=0), tris.reshape(-1, 3).max(axis=0)
    centre = 0.5 * (lo[:2] + hi[:2])
    tris = tris - np.array([centre[0], centre[1], 0.0])  # into the field's frame (z stays world z)
    origin, spacing, nx, ny = terrain_core.grid_for(params)
    heights, hit = terrain_core.drape(tris, origin, spacing, nx, ny)
    if not hit.all():
        heights = terrain_core.fill_missing(heights, hit, fallback=float(lo[2]))
    surface = terrain_core.Heightfield(origin, spacing, heights)
    rise = terrain_core.surface_rise(tris, surface)  # (the ground drawn over the mesh hides its ridges)
    return terrain_core.Heightfield(origin, spacing, heights, rise), (float(centre[0]), float(centre[1]))

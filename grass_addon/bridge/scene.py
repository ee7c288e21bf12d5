"""The Blender datablocks of a grass field: collection, ground, slot objects, materials, terrain.

One collection per field holds:
  * a ground plane the size of the field (far LOD, paper III.C); every other object of the
    field is parented to it, so moving the ground moves the field;
  * the blade slot objects: meshes of k copies of one block's topology (``slots.py`` sizes the
    pools from the LOD distances and assigns blocks to positions; ``pools.py`` writes them);
  * the card slot objects (paper III.B), likewise.

Terrain: when ``item.terrain`` is a mesh of the scene, ``sample_terrain`` drapes a heightfield grid
(``grass_addon/terrain.py``) over its evaluated surface in world space, the field is centred on the
mesh's XY bounding-box centre, the blades are rooted on the surface and the ground becomes a grid
mesh following it. The user's mesh is never changed or removed.

What belongs to a field is recorded on its settings item: the custom property ``wg_objects`` holds
ID pointers to its ground, slot objects, materials and card image (Blender keeps them valid through
renames, save and reopen, and points a Full Copy of the scene at the copies; on the collection
itself such pointers crash Blender 4.2's Full Copy). Rebuild and Remove touch only those, so a
user's Shift+D copy of a grass object (tags and all) is never taken for a slot, never taken over and
never deleted, and a copied scene's field never touches the original's. Every datablock also carries
``wg_uid`` and ``wg_role`` custom properties (files of 0.1 are found through them, inside the
field's collection only).

This module builds and removes datablocks; when to build is ``runtime.py``'s business.
"""

from __future__ import annotations

import json
import os

import bpy
import numpy as np

from .. import atlas, slots, sward
from .. import kinematics as kin
from .. import paint as paint_core
from .. import terrain as terrain_core
from ..grid import FieldGrid
from . import materials, textures
from .registry import warn_once

# The ground grid over a terrain sits this far above the heightfield, so it does not z-fight with
# the user's terrain mesh where both coincide; blade roots stay on the surface (hidden by 2 mm).
GROUND_LIFT = 0.002

# Roles stored in ``wg_role`` of the datablocks of a field.
ROLE_COLLECTION = "collection"
ROLE_GROUND = "ground"
ROLE_BLADES = "blades"
ROLE_CARDS = "cards"
ROLE_BLADE_MATERIAL = "blade_material"
ROLE_CARD_MATERIAL = "card_material"
ROLE_GROUND_MATERIAL = "ground_material"
ROLE_CANOPY_MATERIAL = "canopy_material"
ROLE_CARD_IMAGE = "card_image"
ROLE_GUST_IMAGE = "gust_image"
ROLE_TRAIL_IMAGE = "trail_image"



def owner_tag(scene, item) -> str:
    """The ``wg_uid`` value on the field's datablocks.

    Field uids are unique per scene only, so the tag is ``"<scene name>/<uid>"`` at creation and
    is read back from the field's collection afterwards (a renamed scene keeps its fields).
    """
    coll = item.collection
    if coll is not None and coll.get("wg_uid"):
        return coll["wg_uid"]
    return f"{scene.name}/{item.uid}"


def _unused_tag(base: str) -> str:
    taken = {d.get("wg_uid") for coll in (bpy.data.collections, bpy.data.objects, bpy.data.materials)
             for d in coll}
    tag, n = base, 0
    while tag in taken:
        n += 1
        tag = f"{base}#{n}"
    return tag


def _tag(idblock, uid: str, role: str, index: int | None = None) -> None:
    idblock["wg_uid"] = uid
    idblock["wg_role"] = role
    if index is not None:
        idblock["wg_slot"] = index


def _owned(collection, uid: str, role: str | None = None) -> list:
    """Datablocks of ``collection`` (a bpy.data collection) made by the field ``uid``."""
    return [d for d in collection if d.get("wg_uid") == uid and (role is None or d.get("wg_role") == role)]


TOPOLOGY = "wg_topology"  # the collection's custom property: slots.topology_key it was built for
REGISTRY = "wg_objects"  # the field item's custom property: {key: ID pointer} of what it made


def registered(item) -> dict:
    """{key: datablock} recorded on the field's settings item (keys ``ground``, ``blades 003``,
    ``cards 000``, ``blade_material``, ...); datablocks deleted since are left out."""
    group = item.get(REGISTRY)
    if group is None or not hasattr(group, "items"):
        return _tagged(item)
    return {key: value for key, value in group.items() if isinstance(value, bpy.types.ID)}


def _tagged(item) -> dict:
    """What a 0.1 file's field made, found by its tag: objects inside its collection only."""
    coll = item.collection
    uid = coll.get("wg_uid") if coll is not None else None
    if not uid:
        return {}
    found = {}
    for obj in coll.objects:
        if obj.get("wg_uid") == uid and obj.get("wg_role"):
            role = obj["wg_role"]
            found.setdefault(role if role == ROLE_GROUND else _slot_key(role, int(obj.get("wg_slot", -1))), obj)
    for data in _owned(bpy.data.materials, uid) + _owned(bpy.data.images, uid):
        found.setdefault(data.get("wg_role"), data)
    return found


def _register(item, key: str, idblock) -> None:
    if item.get(REGISTRY) is None or not hasattr(item[REGISTRY], "items"):
        item[REGISTRY] = _tagged(item)
    item[REGISTRY][key] = idblock


def _slot_key(role: str, index: int) -> str:
    return f"{role} {index:03d}"


def field_objects(item) -> list:
    """The field's own objects (never a user's tagged copies elsewhere)."""
    return [d for d in registered(item).values() if isinstance(d, bpy.types.Object)]


# --------------------------------------------------------------------------------------------
# Meshes


def quad_mesh(name: str, n_verts: int, faces: np.ndarray, uvs: np.ndarray, material,
              attributes: dict[str, str], data_uvs: tuple[str, ...] = ()) -> bpy.types.Mesh:
    """A mesh of quads from topology arrays: faces (F, 4) local vertex ids, uvs (F*4, 2) per
    corner, every vertex at the origin (collapsed) until the runtime writes positions. ``data_uvs``:
    more UV maps, after the texture's "UVMap", that carry per-frame data (materials.py)."""
    mesh = bpy.data.meshes.new(name)
    fill_quads(mesh, n_verts, faces, uvs, attributes, data_uvs)
    if material is not None:
        mesh.materials.append(material)
    return mesh


def fill_quads(mesh, n_verts: int, faces: np.ndarray, uvs: np.ndarray, attributes: dict[str, str],
               data_uvs: tuple[str, ...] = ()) -> None:
    """Give an empty mesh its quads (see ``quad_mesh``); its materials are kept."""
    faces = np.ascontiguousarray(faces, dtype=np.int32).reshape(-1, 4)
    n_faces = len(faces)
    mesh.vertices.add(n_verts)
    mesh.loops.add(n_faces * 4)
    mesh.polygons.add(n_faces)
    mesh.loops.foreach_set("vertex_index", faces.ravel())
    mesh.polygons.foreach_set("loop_start", np.arange(0, n_faces * 4, 4, dtype=np.int32))
    mesh.polygons.foreach_set("use_smooth", np.ones(n_faces, dtype=bool))
    uv = mesh.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", np.ascontiguousarray(uvs, dtype=np.float32).ravel())
    for data_uv in data_uvs:
        mesh.uv_layers.new(name=data_uv, do_init=False)
    for attr_name, attr_type in attributes.items():
        mesh.attributes.new(attr_name, attr_type, "POINT")
    mesh.update(calc_edges=True)


def ground_mesh(name: str, size: tuple[float, float], heightfield=None, canopy: float = 0.0,
                top: float = 0.0) -> bpy.types.Mesh:
    """Two layers covering the field, centred on the origin: the ground (material 0) and, ``canopy``
    metres above it, the plane of the far grass (material 1, ``materials.canopy_material``), with
    a fringe rising to ``top`` metres above the ground along the field's edge (material 1 too,
    where the tallest tips stand against the sky). The UV map ``wg_sward_z`` gives the canopy's
    height above the ground at each corner and marks the fringe (1, on the plane 0). Flat
    ground: one quad per layer; over a terrain (``heightfield``, in the field's frame) a grid of one
    quad per heightfield cell following its heights."""
    if heightfield is not None:
        nx, ny = heightfield.nx, heightfield.ny
        u, v = np.meshgrid(np.linspace(0.0, 1.0, nx + 1), np.linspace(0.0, 1.0, ny + 1))
        xy = np.stack([(u - 0.5) * size[0], (v - 0.5) * size[1]], axis=-1)  # exactly the field's extent
        floor = np.empty((ny + 1, nx + 1, 3), np.float32)
        floor[..., :2] = xy
        floor[..., 2] = heightfield.sample(xy) + np.float32(GROUND_LIFT)
        floor = floor.reshape(-1, 3)
        corner = (np.arange(ny)[:, None] * (nx + 1) + np.arange(nx)[None, :]).ravel()
        faces = np.stack([corner, corner + 1, corner + nx + 2, corner + nx + 1], axis=1)
        uv_of_vertex = np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float32)
        smooth = True
    else:
        hx, hy = 0.5 * size[0], 0.5 * size[1]
        floor = np.array([(-hx, -hy, 0), (hx, -hy, 0), (hx, hy, 0), (-hx, hy, 0)], dtype=np.float32)
        faces = np.array([[0, 1, 2, 3]])
        uv_of_vertex = np.array([(0, 0), (1, 0), (1, 1), (0, 1)], dtype=np.float32)
        nx = ny = 1
        smooth = False
    ring = edge_ring(nx, ny) if heightfield is not None else np.array([0, 1, 2, 3])
    top = max(top, canopy)
    plane = floor + np.array([0.0, 0.0, canopy], dtype=np.float32)
    rim = floor[ring] + np.array([0.0, 0.0, top], dtype=np.float32)
    n = len(floor)
    verts = np.concatenate([floor, plane, rim])
    following = np.roll(np.arange(len(ring)), -1)
    skirt = np.stack([n + ring, n + ring[following], 2 * n + following, 2 * n + np.arange(len(ring))], axis=1)
    layer_faces = np.concatenate([faces, faces + n, skirt])
    # the fringe's UVs: where it stands on the field's edge (the canopy reads its paint map there)
    skirt_uv = uv_of_vertex[np.stack([ring, ring[following], ring[following], ring], axis=1).ravel()]
    uvs = np.concatenate([uv_of_vertex[faces.ravel()]] * 2 + [skirt_uv])
    mesh = quad_mesh(name, len(verts), layer_faces, uvs, None, {}, (materials.UV_SWARD_Z,))
    height = np.zeros((len(layer_faces), 4, 2), np.float32)
    height[len(faces):, :, 1] = canopy
    height[2 * len(faces):, :, 0] = 1.0  # the fringe
    height[2 * len(faces):, 2:, 1] = top  # its top corners
    mesh.uv_layers[materials.UV_SWARD_Z].data.foreach_set("uv", height.ravel())
    mesh.materials.clear()
    mesh.polygons.foreach_set("use_smooth", np.full(len(layer_faces), smooth))
    index = np.concatenate([np.zeros(len(faces), np.int32), np.ones(len(faces) + len(skirt), np.int32)])
    mesh.polygons.foreach_set("material_index", index)
    mesh.attributes["position"].data.foreach_set("vector", verts.ravel())
    # floor vertices, heights, grid (0, 0: one quad) for update_paint_look
    mesh["wg_layers"] = [n, canopy, top, nx, ny] if heightfield is not None else [n, canopy, top, 0, 0]
    mesh.update()
    return mesh


# The ground of a painted field on flat ground is a grid of this many cells along its longer side,
# so the canopy can follow a length map (a mown patch stands lower).
PAINT_GROUND_CELLS = 256
PAINT_MAP_PIXELS = 1024  # the paint map image's longer side (the canopy's share of growing blades)
ROLE_PAINT_MAP = "paint_map"


def painted_settings(params, item) -> bool:
    """Whether the field's settings paint it (maps, keep-out shapes or a keep-out collection):
    its ground is then a grid and its canopy reads a paint map (part of the slot topology)."""
    from . import maps

    return bool(maps.sources(params) or params.keep_out.shapes or getattr(item, "keep_out_collection", None))


def paint_ground(params, heightfield):
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


def update_paint_look(item, params, paint) -> None:
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
    n, canopy, top, nx, ny = (float(v) for v in mesh["wg_layers"])
    n, nx, ny = int(n), int(nx), int(ny)
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.attributes["position"].data.foreach_get("vector", co)
    co = co.reshape(-1, 3)
    floor_z = co[:n, 2]
    scale = np.ones(len(co)) if paint is None else paint.length_at(co[:, :2])
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
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    layer = mesh.uv_layers[materials.UV_SWARD_Z]
    layer.data.foreach_get("uv", uv)
    uv = uv.reshape(-1, 2)
    uv[:, 1] = lift[corners]
    layer.data.foreach_set("uv", uv.ravel())
    mesh.update()


def edge_ring(nx: int, ny: int) -> np.ndarray:
    """Floor vertex ids along the field's edge, counter-clockwise seen from above (the fringe
    faces outwards), of a grid of (nx + 1) x (ny + 1) vertices."""
    grid = np.arange((ny + 1) * (nx + 1)).reshape(ny + 1, nx + 1)
    return np.concatenate([grid[0, :-1], grid[:-1, -1], grid[-1, ::-1][:-1], grid[::-1, 0][:-1]])


# --------------------------------------------------------------------------------------------
# Terrain


def terrain_object(scene, item):
    """``item.terrain`` when it is a mesh object of ``scene``, else None."""
    obj = getattr(item, "terrain", None)
    if obj is None or obj.type != "MESH" or scene.objects.get(obj.name) is not obj:
        return None
    return obj


def terrain_key(scene, item, params) -> str:
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


def sample_terrain(scene, item, params):
    """(heightfield, centre_xy) of ``item.terrain``, or (None, None) for flat ground.

    The field is centred on the terrain's XY bounding-box centre (world space); the heightfield
    holds the world Z of the mesh's top surface at the grid's samples (``terrain.grid_for``), a
    downward ray cast per sample done as one vectorised pass (``terrain.drape``); samples off the
    mesh take the nearest hit's height. Deterministic: a function of the mesh and the params.
    """
    obj = terrain_object(scene, item)
    coll = item.collection
    if obj is None and params.terrain.heightmap and getattr(item, "terrain", None) is None:
        from .maps import read_file

        return terrain_core.from_params(params, read_file), None  # a scene file's heightmap
    if obj is None:
        lost = getattr(item, "terrain", None) is not None or (coll is not None and coll.get("wg_terrain"))
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
    return terrain_core.Heightfield(origin, spacing, heights), (float(centre[0]), float(centre[1]))


# --------------------------------------------------------------------------------------------
# Building


def ensure_collection(scene, item) -> bpy.types.Collection:
    """The field's collection, linked under the scene collection (created if needed)."""
    coll = item.collection
    if coll is None or not coll.get("wg_uid"):
        coll = bpy.data.collections.new(item.name or "Grass field")
        _tag(coll, _unused_tag(f"{scene.name}/{item.uid}"), ROLE_COLLECTION)
        item.collection = coll
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)
    return coll


def _material(item, role: str, make):
    """The field's material of ``role``; made anew when missing or built by an older version."""
    found = registered(item).get(role)
    if isinstance(found, bpy.types.Material) and materials.is_current(found):
        return found
    mat = make()
    mat["wg_role"] = role
    _register(item, role, mat)
    return mat


def field_materials(item):
    """(blade, card, ground, canopy) materials of the field, created once and recorded on ``item``."""
    uid, base_name = item.collection["wg_uid"], item.collection.name
    image = registered(item).get(ROLE_CARD_IMAGE)
    if not isinstance(image, bpy.types.Image):
        image = textures.ensure_card_image(f"{base_name} card texture")
        _tag(image, uid, ROLE_CARD_IMAGE)
        _register(item, ROLE_CARD_IMAGE, image)
    gusts = registered(item).get(ROLE_GUST_IMAGE)
    if not isinstance(gusts, bpy.types.Image):
        gusts = textures.ensure_gust_image(f"{base_name} gust waves")
        _tag(gusts, uid, ROLE_GUST_IMAGE)
        _register(item, ROLE_GUST_IMAGE, gusts)
    trails = registered(item).get(ROLE_TRAIL_IMAGE)
    if not isinstance(trails, bpy.types.Image):
        trails = textures.ensure_trail_image(f"{base_name} trails")
        _tag(trails, uid, ROLE_TRAIL_IMAGE)
        _register(item, ROLE_TRAIL_IMAGE, trails)
    blade = _material(item, ROLE_BLADE_MATERIAL, lambda: materials.blade_material(f"{base_name} blades", uid))
    card = _material(item, ROLE_CARD_MATERIAL,
                     lambda: materials.card_material(f"{base_name} cards", uid, image, gusts))
    ground = _material(item, ROLE_GROUND_MATERIAL, lambda: materials.ground_material(f"{base_name} ground", uid))
    canopy = _material(item, ROLE_CANOPY_MATERIAL,
                       lambda: materials.canopy_material(f"{base_name} canopy", uid, gusts, trails))
    return blade, card, ground, canopy


MATERIALS_DIGEST = "wg_materials"  # the collection's custom property: what its materials show


def update_field_materials(item, params, scene=None) -> None:
    """Refresh the parameter-dependent values (eq 10 distances, colours, the card atlas) of the
    materials, and the cards' layer limit from ``scene``'s transparent bounces (Cycles); nothing
    when they already show these."""
    cycles = getattr(scene, "cycles", None)
    bounces = cycles.transparent_max_bounces if cycles is not None else -1
    reg = registered(item)
    digest = f"{params.digest()}|{bounces}|" + ",".join(sorted(d.name for d in reg.values()
                                                               if isinstance(d, (bpy.types.Material, bpy.types.Image))))
    coll = item.collection
    if coll is not None and coll.get(MATERIALS_DIGEST) == digest:
        return
    materials.update_materials(params, reg.get(ROLE_CANOPY_MATERIAL))
    mats = [reg.get(role) for role in (ROLE_BLADE_MATERIAL, ROLE_CARD_MATERIAL, ROLE_GROUND_MATERIAL,
                                       ROLE_CANOPY_MATERIAL)]
    materials.update_haze(params, *mats)
    materials.update_viewport_colours(params, *mats)
    if cycles is not None:
        materials.set_card_depth(reg.get(ROLE_CARD_MATERIAL), cycles.transparent_max_bounces)
    image = reg.get(ROLE_CARD_IMAGE)
    if isinstance(image, bpy.types.Image):
        textures.paint_card_image(image, params)
    gust_image = reg.get(ROLE_GUST_IMAGE)
    if isinstance(gust_image, bpy.types.Image):
        textures.paint_gust_image(gust_image, params)
    materials.update_gusts(params, reg.get(ROLE_CARD_MATERIAL), reg.get(ROLE_CANOPY_MATERIAL))
    if coll is not None:
        coll[MATERIALS_DIGEST] = digest


def _link(coll, obj, parent) -> None:
    coll.objects.link(obj)
    if parent is not None:
        obj.parent = parent


def _purge_orphan_meshes(uid: str) -> None:
    """Delete the field's meshes that no object uses any more (objects deleted by hand)."""
    for mesh in [m for m in bpy.data.meshes if m.get("wg_uid") == uid and m.users == 0]:
        bpy.data.meshes.remove(mesh)


def _remove_objects(objects) -> None:
    meshes = [o.data for o in objects if o.type == "MESH"]
    for obj in objects:
        bpy.data.objects.remove(obj, do_unlink=True)
    for mesh in meshes:
        if mesh.users == 0:
            bpy.data.meshes.remove(mesh)


def build_slots(scene, item, params, heightfield=None, terrain_centre=None) -> bpy.types.Collection:
    """(Re)create the ground and the blade/card slot objects of the field of ``params``
    (``slots.pool_shapes``); idempotent. ``heightfield``: its terrain in the field's frame (None:
    flat), ``terrain_centre``: the world XY the field is centred on over it. The collection records
    ``slots.topology_key``. Called by ``runtime.apply_settings`` only (datablocks change inside the
    operator or edit that asked for them, never between undo steps)."""
    grid = FieldGrid.of(params)
    coll = ensure_collection(scene, item)
    uid = coll["wg_uid"]
    base = coll.name
    blade_mat, card_mat, ground_mat, canopy_mat = field_materials(item)
    # Where the user placed the field (the ground carries it) survives the rebuild.
    old_ground = ground_object(item)
    placement = (old_ground.matrix_basis.copy(), old_ground.parent) if old_ground is not None else None
    _remove_objects(field_objects(item))
    _purge_orphan_meshes(uid)  # (slots deleted by hand): their names are free for the new ones
    for key in [k for k, v in registered(item).items() if not isinstance(v, (bpy.types.Material, bpy.types.Image))]:
        del item[REGISTRY][key]

    painted = painted_settings(params, item)
    mesh = ground_mesh(f"{base} ground", grid.size, paint_ground(params, heightfield) if painted else heightfield,
                       sward.canopy_height(params), sward.sward_top(params))
    _paint_map(item, uid, base, grid if painted else None, canopy_mat)
    ground = bpy.data.objects.new(f"{base} ground", mesh)
    mesh.materials.append(ground_mat)
    mesh.materials.append(canopy_mat)
    _tag(ground, uid, ROLE_GROUND)
    _tag(ground.data, uid, ROLE_GROUND)
    _link(coll, ground, None)
    _register(item, ROLE_GROUND, ground)
    centre = terrain_centre if heightfield is not None else None
    if centre is not None:
        # On a terrain the mesh places the field: centred on it, heights in world Z.
        from mathutils import Matrix

        ground.matrix_basis = Matrix.Translation((centre[0], centre[1], 0.0))
        coll["wg_terrain"] = item.terrain.name if item.terrain is not None else ""
    else:
        if placement is not None:
            ground.matrix_basis, ground.parent = placement
        if "wg_terrain" in coll and heightfield is None and terrain_object(scene, item) is None:
            del coll["wg_terrain"]

    for role, material in ((ROLE_BLADES, blade_mat), (ROLE_CARDS, card_mat)):
        spec = _SlotTopology(grid, params, role)
        for i in range(spec.shape.objects):  # once per build, not per frame
            mesh = quad_mesh(f"{base} {role} {i:03d}", spec.shape.verts_per_object, spec.faces, spec.uvs, material,
                             spec.attributes, spec.data_uvs)
            obj = bpy.data.objects.new(mesh.name, mesh)
            obj.visible_shadow = True
            _tag(obj, uid, role, i)
            _tag(mesh, uid, role, i)
            _link(coll, obj, ground)
            _register(item, _slot_key(role, i), obj)
    coll[TOPOLOGY] = topology(params, heightfield, painted)
    update_field_materials(item, params, scene)
    return coll


def topology(params, heightfield, painted: bool) -> str:
    """What the field's objects are built for: ``slots.topology_key`` and whether it is painted
    (its ground a grid, its canopy reading a paint map)."""
    key = slots.topology_key(FieldGrid.of(params), params, heightfield)
    return key + (" painted" if painted else "")


def _paint_map(item, uid: str, base: str, grid, canopy) -> None:
    """The field's paint map image (``grid``: the field's, when it is painted; None: none), packed
    and read by the canopy; written by ``update_paint_look``."""
    image = registered(item).get(ROLE_PAINT_MAP)
    if grid is None:
        if isinstance(image, bpy.types.Image):
            del item[REGISTRY][ROLE_PAINT_MAP]
            if image.users == 0:
                bpy.data.images.remove(image)
        materials.set_paint_map(canopy, None)
        return
    if not isinstance(image, bpy.types.Image):
        image = bpy.data.images.new(f"{base} paint map", width=PAINT_MAP_PIXELS, height=PAINT_MAP_PIXELS,
                                    alpha=False)
        image.colorspace_settings.name = "Non-Color"
        image.pack()
        _tag(image, uid, ROLE_PAINT_MAP)
        _register(item, ROLE_PAINT_MAP, image)
    materials.set_paint_map(canopy, image)


class _SlotTopology:
    """What every slot object of a role holds: k copies of one block's quads (``slots.py``)."""

    def __init__(self, grid, params, role: str):
        blade_shape, card_shape = slots.pool_shapes(grid, params)
        if role == ROLE_BLADES:
            self.shape, faces, uvs = blade_shape, kin.blade_faces(grid), kin.blade_uvs(grid)
            self.data_uvs = (materials.UV_TINT_RG, materials.UV_TINT_BS)
        else:
            self.shape, faces, uvs = card_shape, kin.card_faces(grid), atlas.card_uvs(grid)
            self.data_uvs = (materials.UV_FADE,)
        self.faces, self.uvs = slots.tiled_topology(faces, uvs, self.shape.verts_per_block, self.shape.k)
        self.attributes = {materials.ATTR_VELOCITY: "FLOAT_VECTOR"}


def clear_slots(item) -> None:
    """Empty the slot meshes of a live field (before a save: the file keeps its settings, ground
    and materials, not megabytes of slot geometry that ``fill_slots`` makes again)."""
    for role in (ROLE_BLADES, ROLE_CARDS):
        for obj in slot_objects(item, role).values():
            if len(obj.data.vertices):
                obj.data.clear_geometry()


def fill_slots(item, params) -> bool:
    """Give every empty slot mesh of the field its quads again (after a save, in a reopened file);
    returns whether any was filled (its positions are then to be written)."""
    grid, filled = FieldGrid.of(params), False
    for role in (ROLE_BLADES, ROLE_CARDS):
        objects = slot_objects(item, role)
        empty = [obj for obj in objects.values() if not len(obj.data.vertices)]
        if not empty:
            continue
        spec = _SlotTopology(grid, params, role)
        for obj in empty:
            fill_quads(obj.data, spec.shape.verts_per_object, spec.faces, spec.uvs, spec.attributes, spec.data_uvs)
            filled = True
    return filled


def slot_objects(item, role: str) -> dict[int, bpy.types.Object]:
    """{slot index: object} of the field's slots that still exist in its collection (the user may
    delete some; copies of them are not slots)."""
    coll = item.collection
    out = {}
    if coll is None:
        return out
    for obj in field_objects(item):
        if obj.get("wg_role") == role and obj.type == "MESH" and coll.objects.get(obj.name) is obj:
            out[int(obj.get("wg_slot", -1))] = obj
    return out


def ground_object(item):
    for obj in field_objects(item):
        if obj.get("wg_role") == ROLE_GROUND:
            return obj
    return None


def separate_copy(item) -> bool:
    """A Full Copy of the scene (or a copied collection) shares the original's tag and, unless
    the user's preferences duplicate them, its materials: give this field's collection a tag of
    its own and its own copies of the materials and card image. Returns whether it was a copy.
    Called by ``build_field`` (Rebuild); until then the copy draws with the shared materials."""
    coll = item.collection
    if coll is None or not coll.get("wg_uid"):
        return False
    tag = coll["wg_uid"]
    if not any(c is not coll and c.get("wg_uid") == tag for c in bpy.data.collections):
        return False
    new_tag = _unused_tag(tag.split("#")[0])
    coll["wg_uid"] = new_tag
    reg = registered(item)
    copies = {}
    for key, data in reg.items():
        if isinstance(data, (bpy.types.Material, bpy.types.Image)):
            copies[data] = data.copy()
            copies[data]["wg_uid"] = new_tag
            _register(item, key, copies[data])
    card_mat, image = copies.get(reg.get(ROLE_CARD_MATERIAL)), copies.get(reg.get(ROLE_CARD_IMAGE))
    if card_mat is not None and image is not None:
        materials.set_card_image(card_mat, image)
    for obj in field_objects(item):
        obj["wg_uid"] = new_tag
        if obj.data is not None:
            obj.data["wg_uid"] = new_tag
            mats = obj.data.materials
            for i, mat in enumerate(mats):
                if mat in copies:
                    mats[i] = copies[mat]
    return True


def remove_datablocks(item) -> None:
    """Delete the field's objects, their meshes, its materials, image and collection (what its
    settings item records, nothing else); no orphan data is left behind, also when the artist
    deleted the collection or some objects by hand first (their meshes are then orphans)."""
    coll = item.collection
    reg = registered(item)
    tags = {d.get("wg_uid") for d in reg.values()} | ({coll.get("wg_uid")} if coll is not None else set())
    _remove_objects(field_objects(item))
    for tag in tags - {None}:
        _purge_orphan_meshes(tag)  # (they use the materials)
    if item.get(REGISTRY) is not None:
        del item[REGISTRY]  # its pointers count as users of the materials and the image
    data = [d for d in reg.values() if isinstance(d, (bpy.types.Material, bpy.types.Image))]
    data.sort(key=lambda d: isinstance(d, bpy.types.Image))  # the materials use the image
    for block in data:  # shared with a copied scene's field: kept while that one uses it
        if block.users == 0:
            (bpy.data.materials if isinstance(block, bpy.types.Material) else bpy.data.images).remove(block)
    if coll is not None:
        bpy.data.collections.remove(coll)
    try:
        item.collection = None
    except (AttributeError, TypeError):  # the item may already be gone
        pass

"""Meshes of a grass field written in bulk: quad meshes of slot topology, the ground and its layers."""

from __future__ import annotations

import bpy
import numpy as np

from .. import meadow
from ..grid import FieldGrid
from ..schema import Params
from . import materials

# The ground grid over a terrain sits this far above the heightfield, so it does not z-fight with
# the user's terrain mesh where both coincide, and more where the terrain's ridges rise above the
# heightfield's smooth sampling of it (``Heightfield.rise``); blade roots stay on the sampled surface
# (hidden by the lift).
GROUND_LIFT = 0.002


def write_uv(mesh, name: str, values: np.ndarray) -> None:
    """Write the UV map ``name`` (float32 (corners, 2)) through its attribute: a UV map is a 2-D
    corner attribute, and ``uv_layers[name].data`` writes it item by item (50x slower: 30-55 ms
    against 0.6-0.7 ms for 400,000 corners on 4.5, 5.2 and 5.3)."""
    mesh.attributes[name].data.foreach_set("vector", np.ascontiguousarray(values, dtype=np.float32).ravel())


def read_uv(mesh, name: str) -> np.ndarray:
    """The UV map ``name`` as float32 (corners, 2), read through its attribute (``write_uv``)."""
    out = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.attributes[name].data.foreach_get("vector", out)
    return out.reshape(-1, 2)


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
    mesh.uv_layers.new(name="UVMap")
    write_uv(mesh, "UVMap", uvs)
    for data_uv in data_uvs:
        mesh.uv_layers.new(name=data_uv, do_init=False)
    for attr_name, attr_type in attributes.items():
        mesh.attributes.new(attr_name, attr_type, "POINT")
    mesh.update(calc_edges=True)


def thinning_edge(params: Params):
    """(width m, scale) of the field's thinning edge for the ground mesh (``ground_mesh``):
    ``meadow.edge_scale`` in the ground's frame (the field centred on its origin), its line straight
    (the far grass stands for the blades' mean; a few ground vertices on a ragged line rose as
    walls); None without one."""
    if float(params.field.edge) <= 0.0:
        return None
    grid = FieldGrid.of(params)
    half = 0.5 * np.asarray(grid.size, np.float64)
    return float(params.field.edge), lambda xy: meadow.edge_scale(xy, -half, grid.size, params, ragged=False)


def ground_mesh(name: str, size: tuple[float, float], heightfield=None, canopy: float = 0.0,
                top: float = 0.0, edge=None) -> bpy.types.Mesh:
    """Two layers covering the field, centred on the origin: the ground (material 0) and, ``canopy``
    metres above it, the plane of the far grass (material 1, ``materials.canopy_material``), with
    a fringe rising to ``top`` metres above the ground along the field's edge (material 1 too,
    where the tallest tips stand against the sky). The UV map ``wg_sward_z`` gives the canopy's
    height above the ground at each corner and marks the fringe (1, on the plane 0). Flat
    ground: one quad per layer (3 x 3 with a thinning edge); over a terrain (``heightfield``, in
    the field's frame) a grid of one quad per heightfield cell following its heights. ``edge``:
    (width m, scale): the field's thinning edge (``meadow.edge_scale``, a function of (n, 2)
    points), which brings the canopy and the fringe down towards the field's boundary as it does
    the blades, so the edge seen from outside is no wall."""
    mesh = bpy.data.meshes.new(name)
    fill_ground(mesh, size, heightfield, canopy, top, edge)
    return mesh


def fill_ground(mesh, size: tuple[float, float], heightfield=None, canopy: float = 0.0, top: float = 0.0,
                edge=None) -> None:
    """Give an empty mesh the ground's two layers and fringe (``ground_mesh``); its materials are
    kept (a painted field's ground grid is emptied before a save and made again after it)."""
    width, scale = edge if edge is not None else (0.0, None)
    if heightfield is not None:
        nx, ny = heightfield.nx, heightfield.ny
        u, v = np.meshgrid(np.linspace(0.0, 1.0, nx + 1), np.linspace(0.0, 1.0, ny + 1))
        xy = np.stack([(u - 0.5) * size[0], (v - 0.5) * size[1]], axis=-1)  # exactly the field's extent
        floor = np.empty((ny + 1, nx + 1, 3), np.float32)
        floor[..., :2] = xy
        floor[..., 2] = heightfield.sample(xy) + np.float32(GROUND_LIFT + heightfield.rise)
        smooth = True
    else:  # a quad, or with a thinning edge a ring of quads round the inner one
        hx, hy = 0.5 * size[0], 0.5 * size[1]
        inset = width if scale is not None and 0.0 < width < min(hx, hy) else 0.0
        xs = np.array([-hx, -hx + inset, hx - inset, hx] if inset else [-hx, hx])
        ys = np.array([-hy, -hy + inset, hy - inset, hy] if inset else [-hy, hy])
        nx, ny = len(xs) - 1, len(ys) - 1
        gx, gy = np.meshgrid(xs, ys)
        floor = np.stack([gx, gy, np.zeros_like(gx)], axis=-1).astype(np.float32)
        u, v = (gx + hx) / size[0], (gy + hy) / size[1]
        smooth = False
    floor = floor.reshape(-1, 3)
    corner = (np.arange(ny)[:, None] * (nx + 1) + np.arange(nx)[None, :]).ravel()
    faces = np.stack([corner, corner + 1, corner + nx + 2, corner + nx + 1], axis=1)
    uv_of_vertex = np.stack([np.ravel(u), np.ravel(v)], axis=1).astype(np.float32)
    ring = edge_ring(nx, ny)
    top = max(top, canopy)
    thin = np.ones(len(floor)) if scale is None else np.asarray(scale(floor[:, :2]), np.float64)
    plane_lift, rim_lift = (canopy * thin).astype(np.float32), (top * thin[ring]).astype(np.float32)
    plane = floor.copy()
    plane[:, 2] += plane_lift
    rim = floor[ring].copy()
    rim[:, 2] += rim_lift
    n = len(floor)
    verts = np.concatenate([floor, plane, rim])
    following = np.roll(np.arange(len(ring)), -1)
    skirt = np.stack([n + ring, n + ring[following], 2 * n + following, 2 * n + np.arange(len(ring))], axis=1)
    layer_faces = np.concatenate([faces, faces + n, skirt])
    # the fringe's UVs: where it stands on the field's edge (the canopy reads its paint map there)
    skirt_uv = uv_of_vertex[np.stack([ring, ring[following], ring[following], ring], axis=1).ravel()]
    uvs = np.concatenate([uv_of_vertex[faces.ravel()]] * 2 + [skirt_uv])
    fill_quads(mesh, len(verts), layer_faces, uvs, {}, (materials.UV_SWARD_Z,))
    lift = np.concatenate([np.zeros(n, np.float32), plane_lift, rim_lift])
    height = np.zeros((len(layer_faces), 4, 2), np.float32)
    height[len(faces):, :, 1] = lift[layer_faces[len(faces):]]  # each corner's height over the ground
    height[2 * len(faces):, :, 0] = 1.0  # the fringe
    write_uv(mesh, materials.UV_SWARD_Z, height.reshape(-1, 2))
    mesh.polygons.foreach_set("use_smooth", np.full(len(layer_faces), smooth))
    index = np.concatenate([np.zeros(len(faces), np.int32), np.ones(len(faces) + len(skirt), np.int32)])
    mesh.polygons.foreach_set("material_index", index)
    mesh.attributes["position"].data.foreach_set("vector", verts.ravel())
    # floor vertices, heights, grid, whether it is a heightfield's (update_paint_look, clear_ground)
    mesh["wg_layers"] = [n, canopy, top, nx, ny, int(heightfield is not None)]
    mesh.update()


def edge_ring(nx: int, ny: int) -> np.ndarray:
    """Floor vertex ids along the field's edge, counter-clockwise seen from above (the fringe
    faces outwards), of a grid of (nx + 1) x (ny + 1) vertices."""
    grid = np.arange((ny + 1) * (nx + 1)).reshape(ny + 1, nx + 1)
    return np.concatenate([grid[0, :-1], grid[:-1, -1], grid[-1, ::-1][:-1], grid[::-1, 0][:-1]])

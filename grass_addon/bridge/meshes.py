"""Meshes of a grass field written in bulk: quad meshes of slot topology, the ground and its layers."""

from __future__ import annotations

import bpy
import numpy as np

from . import materials

# The ground grid over a terrain sits this far above the heightfield, so it does not z-fight with
# the user's terrain mesh where both coincide, and more where the terrain's ridges rise above the
# heightfield's smooth sampling of it (``Heightfield.rise``); blade roots stay on the sampled surface
# (hidden by the lift).
GROUND_LIFT = 0.002


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
    mesh = bpy.data.meshes.new(name)
    fill_ground(mesh, size, heightfield, canopy, top)
    return mesh


def fill_ground(mesh, size: tuple[float, float], heightfield=None, canopy: float = 0.0, top: float = 0.0) -> None:
    """Give an empty mesh the ground's two layers and fringe (``ground_mesh``); its materials are
    kept (a painted field's ground grid is emptied before a save and made again after it)."""
    if heightfield is not None:
        nx, ny = heightfield.nx, heightfield.ny
        u, v = np.meshgrid(np.linspace(0.0, 1.0, nx + 1), np.linspace(0.0, 1.0, ny + 1))
        xy = np.stack([(u - 0.5) * size[0], (v - 0.5) * size[1]], axis=-1)  # exactly the field's extent
        floor = np.empty((ny + 1, nx + 1, 3), np.float32)
        floor[..., :2] = xy
        floor[..., 2] = heightfield.sample(xy) + np.float32(GROUND_LIFT + heightfield.rise)
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
    fill_quads(mesh, len(verts), layer_faces, uvs, {}, (materials.UV_SWARD_Z,))
    height = np.zeros((len(layer_faces), 4, 2), np.float32)
    height[len(faces):, :, 1] = canopy
    height[2 * len(faces):, :, 0] = 1.0  # the fringe
    height[2 * len(faces):, 2:, 1] = top  # its top corners
    mesh.uv_layers[materials.UV_SWARD_Z].data.foreach_set("uv", height.ravel())
    mesh.polygons.foreach_set("use_smooth", np.full(len(layer_faces), smooth))
    index = np.concatenate([np.zeros(len(faces), np.int32), np.ones(len(faces) + len(skirt), np.int32)])
    mesh.polygons.foreach_set("material_index", index)
    mesh.attributes["position"].data.foreach_set("vector", verts.ravel())
    # floor vertices, heights, grid (0, 0: one quad) for update_paint_look
    mesh["wg_layers"] = [n, canopy, top, nx, ny] if heightfield is not None else [n, canopy, top, 0, 0]
    mesh.update()


def edge_ring(nx: int, ny: int) -> np.ndarray:
    """Floor vertex ids along the field's edge, counter-clockwise seen from above (the fringe
    faces outwards), of a grid of (nx + 1) x (ny + 1) vertices."""
    grid = np.arange((ny + 1) * (nx + 1)).reshape(ny + 1, nx + 1)
    return np.concatenate([grid[0, :-1], grid[:-1, -1], grid[-1, ::-1][:-1], grid[::-1, 0][:-1]])

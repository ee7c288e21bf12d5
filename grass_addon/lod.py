"""Levels of detail (paper III.D, eqs 7-11) and block frustum culling.

Per cell, ``d`` is the distance from the viewpoint to the cell centre on the ground (z = 0, or
the terrain's height there, ``layout.cell_ground``):

* first transition region (blades -> cards), eqs 7-9:
  ``K_b = (d - d_g1) / (d_g2 - d_g1)``, ``K_g = 1 - K_b``, ``N = floor(num * K_g)``;
* second transition region (cards -> ground texture), eqs 10-11:
  ``K_t = (d - d_s1) / (d_s2 - d_s1)``, ``K'_b = 1 - K_t``.

All weights are clamped to [0, 1]. The card opacity is K_b in the first region, 1 between the
regions and K'_b in the second, i.e. ``min(K_b, K'_b)`` (the schema guarantees d_g2 <= d_s1).
When a region has zero width (d_g1 == d_g2) the weight is a step at that distance.

Blocks are culled against the camera's view volume: a perspective frustum (side planes, shifted
with the lens shift, and the plane through the eye), an orthographic box, or nothing for a
panoramic camera (it sees every direction). A block's box is its ground rectangle widened by how
far a blade or card can reach sideways, extruded from its lowest ground (``layout.block_z_range``)
to the tallest blade or card standing on its highest ground, so culling is conservative.

Several views at once (the 3D views an artist has open): a cell's distance is that to the nearest
eye, a block is visible when any view sees it (``views``).

The distances are chosen by how large a blade is on screen (``screen_scale``): those of the
settings are right for an image REFERENCE_PIXELS wide at REFERENCE_FOV (a blade of the schema's
width is about a pixel wide at blade_near); a view with more pixels per radian (a 4K frame, a long
lens) scales all four by its focal length in pixels over the reference's, up to SCREEN_SCALE_MAX
and never below 1 (``GrassField`` lowers it further to what its pools hold).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from .blocks import Species
from .errors import ParameterError
from .schema import Params

PERSPECTIVE, ORTHOGRAPHIC, PANORAMIC = "PERSP", "ORTHO", "PANO"
REFERENCE_PIXELS, REFERENCE_FOV = 960, math.radians(55.0)  # the image the LOD distances are set for
REFERENCE_FOCAL = 0.5 * REFERENCE_PIXELS / math.tan(0.5 * REFERENCE_FOV)  # its focal length in pixels (922)
SCREEN_SCALE_MAX = 4.0  # the LOD distances grow with the screen at most this much


@dataclass
class Camera:
    """A camera in world space (Blender's camera looks down its local -Z, up is local +Y).

    position, forward, up: (3,) arrays (forward and up need not be unit length or orthogonal);
    fov_x: horizontal field of view in radians; aspect: image width / height. ``projection``:
    PERSP (a pinhole), ORTHO (``ortho_width``: the image's width in metres; LOD distances are taken
    from ``position``) or PANO (every direction: nothing is culled by direction). ``shift``: the
    lens shift (x, y) as Blender gives it, in units of the image's larger side. ``pixels``: the
    image's width in pixels (0: not known; the LOD distances are then the settings').
    """

    position: np.ndarray
    forward: np.ndarray
    up: np.ndarray
    fov_x: float
    aspect: float
    projection: str = PERSPECTIVE
    ortho_width: float = 0.0
    shift: tuple[float, float] = (0.0, 0.0)
    pixels: float = 0.0

    @classmethod
    def look_at(cls, position, target, fov_x: float, aspect: float = 16.0 / 9.0, up=(0.0, 0.0, 1.0),
                pixels: float = 0.0) -> Camera:
        """Camera at ``position`` looking at ``target`` (headless scripts and tests)."""
        position = np.asarray(position, dtype=np.float64)
        return cls(position, np.asarray(target, dtype=np.float64) - position,
                   np.asarray(up, dtype=np.float64), float(fov_x), float(aspect), pixels=float(pixels))

    def focal_pixels(self) -> float:
        """Pixels per radian at the image's centre (its width over 2 tan(fov_x / 2)); 0 when the
        width is not known or the view is not a pinhole's."""
        if self.projection != PERSPECTIVE or not self.pixels > 0.0 or not 0.0 < self.fov_x < math.pi:
            return 0.0
        return 0.5 * float(self.pixels) / math.tan(0.5 * self.fov_x)

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Orthonormal (forward, right, up) of the view."""
        f = np.asarray(self.forward, dtype=np.float64)
        norm = np.linalg.norm(f)
        if not np.isfinite(norm) or norm == 0.0:
            raise ParameterError("camera", "the camera's forward direction is zero or not finite")
        f = f / norm
        right = np.cross(f, np.asarray(self.up, dtype=np.float64))
        if np.linalg.norm(right) < 1e-9:  # looking straight along `up`: any perpendicular will do
            right = np.cross(f, [0.0, 1.0, 0.0] if abs(f[1]) < 0.9 else [1.0, 0.0, 0.0])
        right /= np.linalg.norm(right)
        return f, right, np.cross(right, f)

    def half_spaces(self) -> tuple[np.ndarray, np.ndarray]:
        """(normals (m, 3), offsets (m,)): a point p relative to the eye is in view when
        ``normals @ p + offsets >= 0`` for every row (m = 0 for a panoramic camera).

        View coordinates x (right), y (up), z (forward). Perspective: the image at z = 1 spans
        x in [cx - tx, cx + tx], y in [cy - ty, cy + ty] with tx = tan(fov_x / 2), ty = tx / aspect
        and the shift's centre (cx, cy) = 2 shift max(tx, ty); inside when x0 z <= x <= x1 z,
        likewise y, and z >= 0. Orthographic: the same window in metres at any z >= 0.
        """
        if self.projection == PANORAMIC:
            return np.zeros((0, 3)), np.zeros(0)
        if not self.aspect > 0.0:
            raise ParameterError("camera", f"aspect ratio {self.aspect!r} must be > 0")
        f, r, u = self.basis()
        if self.projection == ORTHOGRAPHIC:
            if not self.ortho_width > 0.0:
                raise ParameterError("camera", f"orthographic width {self.ortho_width!r} must be > 0")
            tx = 0.5 * self.ortho_width
        else:
            if not (0.0 < self.fov_x < math.pi):
                raise ParameterError("camera.fov", f"{math.degrees(self.fov_x):g} deg is out of range (0 to 180 deg)")
            tx = math.tan(0.5 * self.fov_x)
        ty = tx / self.aspect
        big = max(tx, ty)
        cx, cy = 2.0 * float(self.shift[0]) * big, 2.0 * float(self.shift[1]) * big
        x0, x1, y0, y1 = cx - tx, cx + tx, cy - ty, cy + ty
        if self.projection == ORTHOGRAPHIC:
            normals = np.stack([r, -r, u, -u, f])
            return normals, np.array([-x0, x1, -y0, y1, 0.0])
        normals = np.stack([r - x0 * f, x1 * f - r, u - y0 * f, y1 * f - u, f])
        return normals, np.zeros(5)


@dataclass
class LodWeights:
    """Per-cell weights of eqs 7-11 and per-block visibility; see the module docstring."""

    k_geometry: np.ndarray  # (n_cells,) float32: K_g, eq 8
    k_billboard: np.ndarray  # (n_cells,) float32: card opacity min(K_b, K'_b), eqs 7, 11
    k_texture: np.ndarray  # (n_cells,) float32: K_t, eq 10
    blade_count: np.ndarray  # (n_cells,) int32: N, eq 9
    block_visible: np.ndarray  # (n_blocks,) bool: the block's box meets the view frustum
    block_distance: np.ndarray  # (n_blocks,) float32: eye to the nearest point of the block's ground box
    scale: float = 1.0  # the screen's scale of the LOD distances (``screen_scale``)


def lod_fewer(lod: LodWeights, amount: float) -> LodWeights:
    """``lod`` with ``amount`` (0-1) of each cell's blades (eq 9's N, rounded to the nearest): a
    viewport's Display Amount. The first slots stay, so a blade never moves, and the cards, which
    eq 7 weighs by distance, not by N, are those of the full field."""
    count = np.floor(lod.blade_count * np.float32(amount) + np.float32(0.5)).astype(np.int32)
    return replace(lod, blade_count=count)


def screen_scale(camera, params: Params) -> float:
    """How much the views' screens scale the LOD distances: the largest focal length in pixels of
    ``camera`` (one ``Camera``, several or None) over REFERENCE_FOCAL, within 1 ..
    SCREEN_SCALE_MAX; 1 with ``lod.screen_size`` off, LOD off or no known image width."""
    if not (params.lod.enabled and params.lod.screen_size):
        return 1.0
    focal = max((cam.focal_pixels() for cam in views(camera)), default=0.0)
    return float(min(SCREEN_SCALE_MAX, max(1.0, focal / REFERENCE_FOCAL)))


def scaled(params: Params, scale: float):
    """``params`` with the four LOD distances times ``scale`` (itself when 1)."""
    if scale == 1.0:
        return params
    lod = params.lod
    return params.replace({f"lod.{k}": float(getattr(lod, k)) * scale
                           for k in ("blade_near", "blade_far", "card_near", "card_far")})


def _ramp(d: np.ndarray, near: float, far: float) -> np.ndarray:
    """(d - near) / (far - near) clamped to [0, 1]; a step at `near` when far == near."""
    if far > near:
        w = (d - np.float32(near)) * np.float32(1.0 / (far - near))
        return np.clip(w, 0.0, 1.0, out=w)
    return (d >= np.float32(near)).astype(np.float32)


def block_reach(params: Params) -> tuple[float, float]:
    """(sideways reach, height) of anything standing in a block, from the parameters alone (the
    same for every block and every window): blades bend up to their length in any direction and
    cards stick out half their width plus their height past the cell."""
    species = Species(params)
    tallest_blade = species.longest if params.field.blades_per_cell else 0.0
    card_half = 0.5 * params.lod.card_width * params.field.cell_size
    height = max(tallest_blade, species.tallest_card)
    return max(tallest_blade, card_half + species.tallest_card), height


def camera_eye(camera: Camera) -> np.ndarray:
    """The camera's position as (3,) float64; a clear error when it is not 3 finite numbers."""
    eye = np.asarray(camera.position, dtype=np.float64)
    if eye.shape != (3,) or not np.all(np.isfinite(eye)):
        raise ParameterError("camera.position", f"{camera.position!r} is not 3 finite numbers")
    return eye


def views_key(camera) -> tuple:
    """What ``lod_weights`` reads of ``camera`` (one ``Camera``, several or None), as a tuple
    that compares equal for the same views: a still camera's LOD weights are worked out once."""
    return tuple(tuple(_comparable(getattr(cam, f.name)) for f in fields(cam)) for cam in views(camera))


def _comparable(value):
    """A ``Camera`` field's value as something ``==`` compares whole (arrays by their bits)."""
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes())
    return tuple(value) if isinstance(value, (list, tuple)) else value


def views(camera) -> list[Camera]:
    """``camera`` as a list of views: None gives none, a ``Camera`` itself, a sequence its items."""
    if camera is None:
        return []
    if isinstance(camera, Camera):
        return [camera]
    return list(camera)


def lod_weights(layout, camera, params: Params | None = None, scale: float = 1.0) -> LodWeights:
    """Eqs 7-11 for every cell of ``layout`` and culling of its blocks (vectorised).

    ``camera``: a ``Camera``, several (their nearest eye sets each cell's distance, a block is
    visible when one of them sees it) or None. No camera or ``lod.enabled`` false: every blade is
    geometry (K_g = 1, N = num, K_b = K_t = 0) and every block is visible. Each cell's and block's
    values depend on it and the cameras alone. ``scale``: the distances' screen scale
    (``screen_scale``, or less).
    """
    params = scaled(params if params is not None else layout.params, scale)
    lod = params.lod
    num = layout.blades_per_cell
    n_cells, n_blocks = layout.n_cells, layout.n_blocks
    cams = views(camera)
    eyes = [camera_eye(cam) for cam in cams]
    block_distance = _nearest(_block_distance(layout, eye) for eye in eyes)
    if not cams or not lod.enabled:
        return LodWeights(
            k_geometry=np.ones(n_cells, np.float32), k_billboard=np.zeros(n_cells, np.float32),
            k_texture=np.zeros(n_cells, np.float32), blade_count=np.full(n_cells, num, np.int32),
            block_visible=np.ones(n_blocks, bool),
            block_distance=np.zeros(n_blocks, np.float32) if block_distance is None else block_distance)

    # d: the nearest eye to the cell centre on the ground (plus the eye's height above the cell's ground)
    centre = layout.cell_center
    d = _nearest(_cell_distance(centre, layout.cell_ground, eye) for eye in eyes)

    k_b = _ramp(d, lod.blade_near, lod.blade_far)  # eq 7
    k_g = 1.0 - k_b  # eq 8
    # eq 9; the tiny epsilon keeps floor(num * 1.0) == num under float32 rounding
    blade_count = np.floor(num * k_g + np.float32(1e-5)).astype(np.int32)
    k_t = _ramp(d, lod.card_near, lod.card_far)  # eq 10
    k_b2 = 1.0 - k_t  # eq 11
    k_card = np.minimum(k_b, k_b2)
    visible = np.zeros(n_blocks, bool)
    for cam in cams:
        visible |= block_visible(layout.block_bounds, layout.block_z_range, cam, params)
    return LodWeights(k_geometry=k_g.astype(np.float32, copy=False), k_billboard=k_card,
                      k_texture=k_t, blade_count=blade_count, block_visible=visible,
                      block_distance=block_distance, scale=float(scale))


def views_eyes(camera) -> list[np.ndarray]:
    """The eyes of ``camera`` (one ``Camera``, several or None): (3,) float64 each."""
    return [camera_eye(cam) for cam in views(camera)]


def block_distances(layout, eyes) -> np.ndarray:
    """(n_blocks,) float32: the nearest of ``eyes`` to each block's ground box (``_block_distance``)."""
    return _nearest(_block_distance(layout, eye) for eye in eyes)


def cell_distances(centre: np.ndarray, ground: np.ndarray, eyes) -> np.ndarray:
    """(m,) float32: the nearest of ``eyes`` to cells at ``centre`` (m, 2) on ``ground`` (m,), as eq 7's d."""
    return _nearest(_cell_distance(centre, ground, eye) for eye in eyes)


def _nearest(distances):
    """Element-wise minimum of a sequence of distance arrays (None when empty)."""
    out = None
    for d in distances:
        out = d if out is None else np.minimum(out, d)
    return out


def _cell_distance(centre: np.ndarray, ground: np.ndarray, eye: np.ndarray) -> np.ndarray:
    dx = centre[:, 0] - np.float32(eye[0])
    dy = centre[:, 1] - np.float32(eye[1])
    dz = np.float32(eye[2]) - ground
    return np.sqrt(dx * dx + dy * dy + dz * dz)


def _block_distance(layout, eye: np.ndarray) -> np.ndarray:
    """Distance from the eye to the nearest point of each block's ground box: its rectangle,
    from its lowest to its highest ground (z = 0 on flat ground).

    It is <= the distance to any cell centre of the block (which lies on the ground inside that
    box), so a block with block_distance > lod.card_far holds nothing but ground texture.
    """
    b = layout.block_bounds.astype(np.float64)
    z = layout.block_z_range.astype(np.float64)
    nx = np.clip(eye[0], b[:, 0], b[:, 2]) - eye[0]
    ny = np.clip(eye[1], b[:, 1], b[:, 3]) - eye[1]
    nz = np.clip(eye[2], z[:, 0], z[:, 1]) - eye[2]
    return np.sqrt(nx * nx + ny * ny + nz * nz).astype(np.float32)


def block_visible(bounds, z_range, camera: Camera, params: Params, margin: float = 0.0) -> np.ndarray:
    """Box-vs-view-volume test of blocks (bounds (m, 4), z_range (m, 2)): a box is out when all 8
    corners lie outside one of the camera's half-spaces. ``margin`` widens every box by that many
    metres.

    For a plane normal n the corner farthest inside is centre + |n| . half (the "positive
    vertex"), so that single test is exact for the 8 corners.
    """
    reach, height = block_reach(params)
    reach += margin
    b = np.asarray(bounds, dtype=np.float64)
    z = np.asarray(z_range, dtype=np.float64)
    bottom, top = z[:, 0] - margin, z[:, 1] + height + margin  # lowest ground .. tallest blade
    centre = np.stack([(b[:, 0] + b[:, 2]) * 0.5, (b[:, 1] + b[:, 3]) * 0.5,
                       0.5 * (bottom + top)], axis=1) - np.asarray(camera.position, dtype=np.float64)
    half = np.stack([(b[:, 2] - b[:, 0]) * 0.5 + reach, (b[:, 3] - b[:, 1]) * 0.5 + reach,
                     0.5 * (top - bottom)], axis=1)
    normals, offsets = camera.half_spaces()  # (m, 3), (m,)
    best = centre @ normals.T + half @ np.abs(normals).T + offsets  # (n_blocks, m)
    return np.all(best >= 0.0, axis=1)

"""A USD bake made whole for renderers outside Blender (issue #36): what Blender's USD writer
leaves half-said, written with Pixar's own library (``pxr``, which Blender bundles).

* ``displayColor`` (and ``displayOpacity``) is declared on every mesh with no value: a blade
  strip gets its blade's colour per face-vertex, the species' tip colour (``wg_tint_rg`` r g,
  ``wg_tint_bs`` b) times its 0.7-1.3 value shade, as the blade material draws its tip; a card
  strip gets its material's viewport colour;
* the blade material's preview reads the 2-wide ``wg_tint_bs`` with a 3-wide vector reader (its
  blue and shade came out as red and green): it reads ``displayColor`` with a float3 reader.

numpy and pxr only: ``finish(path, colours)`` rewrites the file in place (a bake's partial file,
before it is put under its name).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .materials import UV_TINT_BS, UV_TINT_RG

READERS_3 = ("UsdPrimvarReader_vector", "UsdPrimvarReader_float3", "UsdPrimvarReader_normal",
             "UsdPrimvarReader_point")


def available() -> bool:
    """Whether this Blender's Python has Pixar's USD library (official builds bundle it)."""
    try:
        import pxr.Usd  # noqa: F401
    except ImportError:
        return False
    return True


def finish(path: Path, colours: dict[str, tuple[float, float, float]]) -> None:
    """Give every mesh of the USD file ``path`` its display colour (``colours``: a mesh prim's
    path -> linear RGB, for meshes without blade tints) and the blade material's preview a
    reader of it."""
    from pxr import Usd, UsdGeom, UsdShade

    stage = Usd.Stage.Open(str(path))
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh):
            _display(UsdGeom.PrimvarsAPI(prim), colours.get(str(prim.GetPath()), (0.1, 0.3, 0.05)))
        elif prim.IsA(UsdShade.Shader):
            _reader(UsdShade.Shader(prim))
    stage.GetRootLayer().Save()


def blade_colours(rg: np.ndarray, bs: np.ndarray) -> np.ndarray:
    """(n, 3) tip colours of blade face-vertices from their (n, 2) tints, value-shaded."""
    colour = np.column_stack([rg[:, 0], rg[:, 1], bs[:, 0]])
    return (colour * (0.7 + 0.6 * bs[:, 1:2])).astype(np.float32)


def _display(api, colour) -> None:
    from pxr import Sdf, UsdGeom, Vt

    rg, bs = api.GetPrimvar(UV_TINT_RG), api.GetPrimvar(UV_TINT_BS)
    shown = api.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray)
    if rg and bs and rg.HasValue() and bs.HasValue():
        shown.SetInterpolation(UsdGeom.Tokens.faceVarying)
        times = sorted({t for v in (rg, bs) for a in (v.GetAttr(), v.GetIndicesAttr()) for t in a.GetTimeSamples()})
        for time in times or [None]:  # (Blender writes the values once and their indices at the first frame)
            at = () if time is None else (time,)
            per_corner = blade_colours(np.array(rg.ComputeFlattened(*at), np.float32),
                                       np.array(bs.ComputeFlattened(*at), np.float32))
            values, index = np.unique(per_corner, axis=0, return_inverse=True)
            shown.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(values)), *at)
            shown.SetIndices(Vt.IntArray.FromNumpy(index.reshape(-1).astype(np.int32)), *at)
    else:
        shown.SetInterpolation(UsdGeom.Tokens.constant)
        shown.Set(Vt.Vec3fArray([tuple(float(c) for c in colour[:3])]))
    opacity = api.GetPrimvar("displayOpacity")
    if opacity and not opacity.HasValue():
        opacity.SetInterpolation(UsdGeom.Tokens.constant)
        opacity.Set(Vt.FloatArray([1.0]))


def _reader(shader) -> None:
    from pxr import Sdf

    varname = shader.GetInput("varname")
    if shader.GetIdAttr().Get() not in READERS_3 or varname is None or varname.Get() not in (UV_TINT_RG, UV_TINT_BS):
        return
    shader.SetShaderId("UsdPrimvarReader_float3")
    varname.Set("displayColor")
    result = shader.GetPrim().GetAttribute("outputs:result")
    if result:
        result.SetTypeName(Sdf.ValueTypeNames.Float3)

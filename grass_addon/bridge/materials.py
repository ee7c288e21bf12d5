"""Materials of a grass field: blade strips, billboard cards, the ground and the far canopy (paper III.A-D).

Node trees are built from node type ids and socket names that exist from Blender 4.2 to 5.x;
sockets are looked up through ``_socket`` so a renamed socket fails with a clear message.
All three materials work in EEVEE and in Cycles. Values that depend on the parameters (LOD
distances, colours) live in named nodes and are refreshed by ``update_materials``.

Per-frame data written by the runtime (``pools.py``) as UV maps (corner domain), which Alembic
caches keep per frame (a bake replays them in a Blender without Windgrass), read by the shaders
through Attribute nodes:
  ``wg_tint_rg``  (r, g)       species tip colour of the blade, red and green (blades)
  ``wg_tint_bs``  (b, shade)   its blue, and the per-blade 0..1 variation of hue and value (blades)
  ``wg_fade``     (K_b, K_b)   K_b of eqs 7/11, the card's opacity (cards)
and the point attribute ``velocity`` (m/s, motion blur). The ground mesh's static UV map
``wg_sward_z`` (x, z) holds the height z above the ground of the canopy plane and its fringe
(x: 0 on the plane, 1 on the fringe).
"""

from __future__ import annotations

import warnings

import bpy
import numpy as np

from .. import edit_parts, gusts, roles, sward
from ..grid import FieldGrid
from ..schema import Params
from . import textures

UV_TINT_RG = "wg_tint_rg"
UV_TINT_BS = "wg_tint_bs"
UV_FADE = "wg_fade"
UV_OF = {roles.TINT_RG: UV_TINT_RG, roles.TINT_BS: UV_TINT_BS, roles.FADE: UV_FADE}  # a role's corner data's UV map
UV_SWARD_Z = "wg_sward_z"  # ground mesh: (1 on the fringe, height above the ground) of the canopy
ATTR_VELOCITY = "velocity"  # m/s per point: motion blur of a mesh rewritten from Python

# The gust waves (gusts.py): the pattern image, its mapping (scale 1 / tile, offset the mean wind's
# displacement, set every frame by ``set_gust_offset``) and how much it brightens (update_materials).
NODE_GUST_IMAGE = "wg_gust_image"
NODE_GUST_MAPPING = "wg_gust_mapping"
NODE_GUST_AMOUNT = "wg_gust_amount"
NODE_GUST_MAPPING_2 = "wg_gust_mapping_2"  # a looped wind's other pattern (loop.py): its place and weight
NODE_GUST_IMAGE_2 = "wg_gust_image_2"
NODE_GUST_AMOUNT_2 = "wg_gust_amount_2"
# The far canopy's trampled trails (interaction.trail_map): the map, where the ray meets the canopy
# and where it meets the trail's floor further on (two mappings of the field's frame onto the map),
# whether a map is shown and how deep the sward is (the canopy's height).
NODE_TRAIL_IMAGE = "wg_trail_image"
NODE_TRAIL_NEAR = "wg_trail_near"
NODE_TRAIL_FAR = "wg_trail_far"
NODE_TRAIL_AMOUNT = "wg_trail_amount"
NODE_TRAIL_DEPTH = "wg_trail_depth"
# The meadow's patches (sward.patch_tint): the tint image over the field and its mapping (the
# field's frame onto the image, set by ``update_patches``).
NODE_PATCH_IMAGE = "wg_patch_image"
NODE_PATCH_MAPPING = "wg_patch_mapping"
GUST_SHADE = 1.0  # brightness swing of the far grass per unit of wind.gust_waves (stronger wind: lighter)
SHEEN_SLOPES, SHEEN_ABOVE = (0.1, 0.8), 2.0  # the canopy's gust swing, 1x at grazing slopes to 2x from above
GUST_REFERENCE_SPEED = 5.0  # m/s: the swing is full from this mean wind on, as (speed / it)^2 below (the bend)

# Node names that ``update_materials`` looks up.
NODE_KT = "wg_kt"  # Map Range: View Distance -> K_t of eq 10
NODE_CARD_DEPTH = "wg_card_depth"  # Value: transparent layers a ray crosses before a card stops it
NODE_HAZE_DISTANCE = "wg_haze_distance"  # Value: -1 / render.haze_distance (0: no haze)
NODE_HAZE_COLOUR = "wg_haze_colour"  # RGB: render.haze_color
NODE_SWARD_LOOK = "wg_sward_look"  # RGB Curves: the canopy's colour over the ray's slope (sward.sward_look)
NODE_FRINGE_COLOUR = "wg_fringe_colour"  # RGB: the tips standing above the plane (sward.fringe_colour)
NODE_SPECKLE_GRID = "wg_speckle_grid"  # Voronoi: a cell per flower seen from above (sward.flower_speckles)
NODE_SPECKLE_CUT = "wg_speckle_cut"  # Math: a flower's radius in the grid's units
NODE_SPECKLE_COLOURS = "wg_speckle_colours"  # Color Ramp: the flowers' colours at their running shares
NODE_SPECKLE_GAIN = "wg_speckle_gain"  # Value: 1 / the blades' mean brightness
# The tussocks' grain (sward.tussock_grain): Voronoi cells of the tussocks' size (its Scale), each
# brightened by 1 + c sqrt(3) (2 u - 1), u its random value (uniform: spread c), c the Value node.
NODE_FLOOR = "wg_floor"  # the ground's two floor colours in noise (sward.floor_colours)
NODE_TUSSOCKS = "wg_tussocks"
NODE_TUSSOCK_SPREAD = "wg_tussock_spread"
TUSSOCK_VALUE, TUSSOCK_RELIEF = 0.6, 0.8  # a tussock's brightness: its own value, its relief (``_tussocked``)
TUSSOCK_SMOOTHNESS = 1.0  # neighbouring tussocks merge over this share of a cell (Voronoi Smooth F1)
NODE_TUSSOCK_SEEN = "wg_tussock_seen"  # Float Curve: the share of the grain a ray's slope shows
NODE_SWARD_PROFILE = "wg_sward_profile"  # Float Curve: sward.sward_depth / its value at the ground
NODE_SWARD_TOP = "wg_sward_top"  # Map Range: height -> 0..1 along the profile (sward.sward_top)
NODE_SWARD_DEPTH = "wg_sward_depth"  # Value: sward.sward_depth at the ground
NODE_STAND_TOP = "wg_stand_top"  # Value: sward.sward_top (the edge's crossed stand, ``_crossed_stand``)
NODE_STAND_MAPPING = "wg_stand_mapping"  # Mapping: the field's frame onto the patch image, as NODE_PATCH_MAPPING
NODE_STAND_IMAGE = "wg_stand_image"  # Image Texture: the patch image read there
STAND_REACH = 10.0  # m: how far back along a ray the crossed stand is read at most
NODE_FIELD_HALF = "wg_field_half"  # Combine XYZ: half the field's extent along X and Y (m)
NODE_PAINT_MAP = "wg_paint_map"  # Image Texture: the paint map (R: share of blades that grow) over the ground's UVs
NODE_PAINTED = "wg_painted"  # Value: 1 when the field has a paint map, else 0
NODE_PAINT_MAPPING = "wg_paint_mapping"  # Mapping: the ground's UVs (the field) to the paint map's (its extent)

# Dark, slightly brown base of a blade (linear RGB): the root sits in the shade of the sward.
BLADE_BASE_COLOUR = (*sward.BLADE_BASE_COLOUR, 1.0)
# Ground under near grass: the floor of a meadow, dry thatch and green litter in the sward's shade
# (not bare earth, not a grey floor); matte (no specular sheen).
THATCH_COLOUR = (*sward.THATCH_COLOUR, 1.0)
LITTER_COLOUR = (*sward.LITTER_COLOUR, 1.0)
# The canopy is a horizontal plane that the sun and sky light whole, the blades it stands for are
# lit on their sides: its colour is SWARD_LIGHT times what rays see of the sward (sward.sward_look;
# fitted with sward.LIGHT_SLOPE to all-geometry renders, sun and overcast: headless/lod_compare.py).
SWARD_LIGHT = 0.55
LOOK_KNEE, VIEWPORT_SLOPE = sward.LOOK_KNEE, sward.VIEWPORT_SLOPE  # (the canopy's curves over the slope)
# Solid shading draws a card as its whole quad (no texture): see-through, the cards of a cell and its
# neighbours overlap into a grassy layer over the canopy; opaque, they read as shards (issue #59)
CARD_VIEWPORT_ALPHA = 0.4
# A trampled trail seen from afar (materials._trailed): where a ray meets its flattened floor the
# sward is TRAIL_FLOOR as bright, the standing grass just before it TRAIL_WALL (all-geometry
# renders of a ball's trail 41 m from a 6 m eye: 0.65-0.73 and 1.18-1.29).
TRAIL_FLOOR = 0.65
TRAIL_WALL = 1.25
TRAIL_SINK = 0.5  # share of the canopy's height a ray goes down into a trail before it meets its floor
# A card is lit as one flat plane where the blades it shows face every way and curve: its colour
# is scaled to come out as bright as those blades from any slope (all-geometry renders of long
# strips, sun and overcast: headless/lod_compare.py --views strip). Fitted at 1.15 with strips
# widened where blades drooped off the card; with blades wrapped round (atlas._draw_strip), cells
# chosen for the field's mix and its colour at every height (atlas.atlas_cells) and fading cards
# that shade one another 1.0: the default meadow's card band 0.93-1.14 of its blades' green from
# 1.1 m and 2.5 m, sun and overcast, seeds 7-9 (docs/performance.md), the paper's even field's
# within its seam bound (test_lod_fidelity).
CARD_LIGHT = 1.0
CARD_SPECULAR = 0.1  # the cards' specular level (blades: 0.35) and roughness (blades: 0.55)
CARD_ROUGHNESS = 0.8
TRANSLUCENCY = 0.3  # share of light a thin blade lets through (Translucent BSDF)
# Beyond this distance nothing is ever drawn: K_t of eq 10 stays 0 when the LOD is off.
FAR_AWAY = 1.0e9
# Raised whenever a material's nodes change: a field saved with older materials gets new ones.
MATERIALS_VERSION = 19


def _socket(sockets, *names: str):
    """First socket with one of ``names`` (identifier or display name)."""
    for name in names:
        for sock in sockets:
            if sock.identifier == name:
                return sock
        sock = sockets.get(name)
        if sock is not None:
            return sock
    raise KeyError(f"none of the sockets {names} exists on this Blender version")


def _pick(sockets, key):
    if isinstance(key, str):
        return _socket(sockets, *key.split("|"))
    return sockets[key] if isinstance(key, int) else key


def _set(node, value, *names: str) -> None:
    _socket(node.inputs, *names).default_value = value


def with_nodes(mat):
    """``mat`` with its node tree: a new material has one from Blender 5.0 on (``use_nodes`` is
    deprecated there and goes in Blender 6); before 5.0 it is switched on."""
    if mat.node_tree is None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            mat.use_nodes = True
    return mat


def _new_material(name: str, uid: str):
    mat = with_nodes(bpy.data.materials.new(name))
    mat.node_tree.nodes.clear()
    mat["wg_uid"] = uid
    mat["wg_version"] = MATERIALS_VERSION
    mat.use_backface_culling = False  # blades and cards are two-sided strips
    cycles = getattr(mat, "cycles", None)
    if cycles is not None and hasattr(cycles, "emission_sampling"):
        # The haze is an Emission mixed into every grass material: sampled as a light, every blade
        # triangle would be a lamp Cycles builds a light tree over each frame (issue #20: ~3 s of
        # "Updating Lights" a frame). It is seen, never a source of light for the rest.
        cycles.emission_sampling = "NONE"
    return mat


def is_current(mat) -> bool:
    """Whether ``mat`` was built by this version's node trees."""
    return mat.get("wg_version") == MATERIALS_VERSION


def _transparent(mat) -> None:
    """Alpha that works in EEVEE (4.2+: dithered, older: hashed) and Cycles (Transparent BSDF)."""
    if hasattr(mat, "surface_render_method"):
        mat.surface_render_method = "DITHERED"
    else:  # pragma: no cover - before Blender 4.2
        mat.blend_method = "HASHED"
    if hasattr(mat, "use_transparent_shadow"):
        mat.use_transparent_shadow = True


class _Tree:
    """Small helper to add and link nodes left to right."""

    def __init__(self, mat):
        self.nodes = mat.node_tree.nodes
        self.links = mat.node_tree.links

    def add(self, kind: str, x: float, y: float, name: str | None = None, **props):
        node = self.nodes.new(kind)
        node.location = (x, y)
        if name:
            node.name = node.label = name
        for key, value in props.items():
            setattr(node, key, value)
        return node

    def link(self, out_node, out_name, in_node, in_name):
        """Link an output to an input, each given as a socket, a name ("a|b": either) or an index."""
        out = _pick(out_node.outputs, out_name)
        inp = _pick(in_node.inputs, in_name)
        self.links.new(out, inp)

    def math(self, operation: str, a, b, x: float, y: float, clamp: bool = False, vector: bool = False):
        """A Math (or Vector Math) node of ``a`` and ``b``: each a number (a vector: a tuple),
        (node, output) to link, or None (an operation of one operand)."""
        node = self.add("ShaderNodeVectorMath" if vector else "ShaderNodeMath", x, y, operation=operation)
        if not vector:
            node.use_clamp = clamp
        for index, value in enumerate((a, b)):
            if value is None:
                continue
            if isinstance(value, tuple) and len(value) == 2 and not isinstance(value[0], (int, float)):
                self.link(value[0], value[1], node, index)
            else:
                node.inputs[index].default_value = value
        return node

    def attribute(self, name: str, x: float, y: float):
        return self.add("ShaderNodeAttribute", x, y, attribute_type="GEOMETRY", attribute_name=name)

    def mix_rgb(self, x, y, blend="MIX", a=None, b=None, factor=1.0, name=None):
        node = self.add("ShaderNodeMix", x, y, name=name, data_type="RGBA", blend_type=blend)
        _set(node, factor, "Factor_Float")
        if a is not None:
            _set(node, a, "A_Color")
        if b is not None:
            _set(node, b, "B_Color")
        return node

    def hazed(self, shader_node, shader_out: str, x: float, y: float):
        """``shader`` seen through the air: mixed with the haze's emission by
        1 - exp(-d / render.haze_distance) of the view distance d (aerial perspective). The
        distance and colour live in NODE_HAZE_DISTANCE / NODE_HAZE_COLOUR (update_materials)."""
        camera = self.add("ShaderNodeCameraData", x - 700, y - 250)
        inverse = self.add("ShaderNodeValue", x - 700, y - 450, name=NODE_HAZE_DISTANCE)  # -1 / distance
        inverse.outputs[0].default_value = 0.0
        scale = self.math("MULTIPLY", (camera, "View Distance"), (inverse, "Value"), x - 500, y - 250)
        transmitted = self.math("EXPONENT", (scale, "Value"), None, x - 350, y - 250)
        amount = self.math("SUBTRACT", 1.0, (transmitted, "Value"), x - 200, y - 250, clamp=True)
        colour = self.add("ShaderNodeRGB", x - 350, y - 450, name=NODE_HAZE_COLOUR)
        colour.outputs[0].default_value = (1.5, 1.5, 1.45, 1.0)
        glow = self.add("ShaderNodeEmission", x - 200, y - 450)
        self.link(colour, "Color", glow, "Color")
        mix = self.add("ShaderNodeMixShader", x, y)
        self.link(amount, "Value", mix, "Fac")
        self.link(shader_node, shader_out, mix, mix.inputs[1])
        self.link(glow, "Emission", mix, mix.inputs[2])
        return mix

    def matte(self, colour_node, colour_out: str) -> None:
        """The material's output: a matte, non-specular surface of the colour, hazed (``hazed``)."""
        bsdf = self.add("ShaderNodeBsdfPrincipled", -400, 0)
        _set(bsdf, 1.0, "Roughness")
        _set(bsdf, 0.0, "Specular IOR Level", "Specular")
        self.link(colour_node, colour_out, bsdf, "Base Color")
        shader = self.hazed(bsdf, "BSDF", -100, 0)
        out = self.add("ShaderNodeOutputMaterial", 150, 0)
        self.link(shader, "Shader", out, "Surface")

    def field_image(self, image, mapping_name: str, image_name: str, extension: str, x: float, y: float):
        """The Image Texture node of ``image`` read at the place (object coordinates: the field's
        frame) through the Mapping node ``mapping_name`` (its scale and offset set elsewhere)."""
        coord = self.add("ShaderNodeTexCoord", x - 400, y)
        mapping = self.add("ShaderNodeMapping", x - 200, y, name=mapping_name)
        self.link(coord, "Object", mapping, "Vector")
        tex = self.add("ShaderNodeTexImage", x, y, name=image_name, image=image, interpolation="Linear",
                       extension=extension)
        self.link(mapping, "Vector", tex, "Vector")
        return tex

    def gusted(self, colour_node, colour_out: str, gust_image, x: float, y: float, boost=None):
        """The colour brightened and darkened by the gust waves where they pass:
        colour * (1 + amount (2 g - 1) + amount_2 (2 g_2 - 1)), g the pattern at the place (object
        coordinates: the field's frame) moved back by the mean wind's displacement
        (NODE_GUST_MAPPING); g_2 the same at a looped wind's other displacement (``loop.py``;
        amount_2 is 0 without a loop). ``boost``: (node, output) both amounts are multiplied by."""
        tex = self.field_image(gust_image, NODE_GUST_MAPPING, NODE_GUST_IMAGE, "REPEAT", x - 400, y - 200)
        other = self.field_image(gust_image, NODE_GUST_MAPPING_2, NODE_GUST_IMAGE_2, "REPEAT", x - 400, y - 650)
        amount = self.add("ShaderNodeValue", x - 400, y - 450, name=NODE_GUST_AMOUNT)
        amount.outputs[0].default_value = 0.0
        amount_2 = self.add("ShaderNodeValue", x - 400, y - 900, name=NODE_GUST_AMOUNT_2)
        amount_2.outputs[0].default_value = 0.0
        swing = self.math("MULTIPLY_ADD", (tex, "Color"), 2.0, x - 200, y - 200)
        swing.inputs[2].default_value = -1.0
        swing_2 = self.math("MULTIPLY_ADD", (other, "Color"), 2.0, x - 200, y - 650)
        swing_2.inputs[2].default_value = -1.0
        if boost is not None:
            amount = self.math("MULTIPLY", (amount, "Value"), boost, x - 300, y - 450)
            amount_2 = self.math("MULTIPLY", (amount_2, "Value"), boost, x - 300, y - 900)
        part_2 = self.math("MULTIPLY_ADD", (swing_2, "Value"), (amount_2, "Value"), x - 100, y - 650)
        part_2.inputs[2].default_value = 1.0
        gain = self.math("MULTIPLY_ADD", (swing, "Value"), (amount, "Value"), x - 50, y - 200)
        self.link(part_2, "Value", gain, 2)
        out = self.mix_rgb(x + 100, y, blend="MULTIPLY")
        self.link(colour_node, colour_out, out, "A_Color")
        self.link(gain, "Value", out, "B_Color")
        return out

    def patched(self, colour_node, colour_out: str, patch_image, x: float, y: float):
        """The colour times the meadow's patch tint at the place (object coordinates: the field's
        frame, mapped onto the image by NODE_PATCH_MAPPING); no tint without an image."""
        if patch_image is None:
            return colour_node, colour_out
        tex = self.field_image(patch_image, NODE_PATCH_MAPPING, NODE_PATCH_IMAGE, "EXTEND", x - 200, y - 250)
        tint = self.add("ShaderNodeVectorMath", x - 100, y - 250, operation="SCALE")  # (the bytes hold tint / 3)
        self.link(tex, "Color", tint, 0)
        tint.inputs["Scale"].default_value = textures.PATCH_RANGE
        out = self.mix_rgb(x, y, blend="MULTIPLY")
        self.link(colour_node, colour_out, out, "A_Color")
        self.link(tint, "Vector", out, "B_Color")
        return out, "Result_Color"

    def foliage(self, colour_node, colour_out: str, x: float, y: float, specular: float = 0.35,
                roughness: float = 0.55):
        """Principled (reflection) + Translucent (light through the blade), mixed."""
        bsdf = self.add("ShaderNodeBsdfPrincipled", x, y + 150)
        _set(bsdf, roughness, "Roughness")
        _set(bsdf, specular, "Specular IOR Level", "Specular")
        trans = self.add("ShaderNodeBsdfTranslucent", x, y - 250)
        self.link(colour_node, colour_out, bsdf, "Base Color")
        self.link(colour_node, colour_out, trans, "Color")
        mix = self.add("ShaderNodeMixShader", x + 300, y)
        _set(mix, TRANSLUCENCY, "Fac")
        self.link(bsdf, "BSDF", mix, mix.inputs[1])
        self.link(trans, "BSDF", mix, mix.inputs[2])
        return mix


def blade_material(name: str, uid: str):
    """Blades: UV v gives a root-to-tip gradient from a dark base to the species colour
    (``wg_tint_rg``, ``wg_tint_bs``); the shade varies hue and value per blade; partly translucent."""
    mat = _new_material(name, uid)
    t = _Tree(mat)
    uv = t.add("ShaderNodeTexCoord", -1400, 200)
    sep = t.add("ShaderNodeSeparateXYZ", -1200, 200)
    t.link(uv, "UV", sep, "Vector")
    # Smooth gradient: the lower 70 % of the blade darkens towards the root.
    grad = t.add("ShaderNodeMapRange", -1000, 200, interpolation_type="SMOOTHSTEP")
    _set(grad, 0.0, "From Min")
    _set(grad, sward.GRADIENT_END, "From Max")
    t.link(sep, "Y", grad, "Value")
    rg = t.add("ShaderNodeSeparateXYZ", -1000, -50)
    t.link(t.attribute(UV_TINT_RG, -1200, -50), "Vector", rg, "Vector")
    bs = t.add("ShaderNodeSeparateXYZ", -1000, -300)
    t.link(t.attribute(UV_TINT_BS, -1200, -300), "Vector", bs, "Vector")
    tip = t.add("ShaderNodeCombineXYZ", -850, -100)
    t.link(rg, "X", tip, "X")
    t.link(rg, "Y", tip, "Y")
    t.link(bs, "X", tip, "Z")
    mix = t.mix_rgb(-750, 100, a=BLADE_BASE_COLOUR)
    t.link(grad, "Result", mix, "Factor_Float")
    t.link(tip, "Vector", mix, "B_Color")
    hue = t.add("ShaderNodeMapRange", -750, -300)  # shade 0..1 -> hue shift +-0.035 (+-13 degrees)
    _set(hue, 0.465, "To Min")
    _set(hue, 0.535, "To Max")
    value = t.add("ShaderNodeMapRange", -750, -550)  # shade 0..1 -> value x0.7 .. x1.3 (sward.shade_value)
    _set(value, sward.SHADE_LOW, "To Min")
    _set(value, sward.SHADE_LOW + sward.SHADE_SPAN, "To Max")
    t.link(bs, "Y", hue, "Value")
    t.link(bs, "Y", value, "Value")
    hsv = t.add("ShaderNodeHueSaturation", -500, 0)
    t.link(hue, "Result", hsv, "Hue")
    t.link(value, "Result", hsv, "Value")
    t.link(mix, "Result_Color", hsv, "Color")
    shader = t.hazed(t.foliage(hsv, "Color", -250, 0), "Shader", 150, 0)
    out = t.add("ShaderNodeOutputMaterial", 350, 0)
    t.link(shader, "Shader", out, "Surface")
    return mat


def set_card_image(mat, image) -> None:
    """Point the card material's texture node at ``image``."""
    for node in mat.node_tree.nodes:
        if node.bl_idname == "ShaderNodeTexImage":
            node.image = image


def card_material(name: str, uid: str, image, gust_image=None, patch_image=None):
    """Cards (paper III.B): the atlas of the field's own blades (``atlas.card_atlas``), shaded
    like the blades (the same foliage shader); its alpha times ``wg_fade`` (K_b of eqs 7 and 11)
    mixes that with a Transparent BSDF."""
    mat = _new_material(name, uid)
    _transparent(mat)
    t = _Tree(mat)
    uv = t.add("ShaderNodeTexCoord", -1300, 100)
    tex = t.add("ShaderNodeTexImage", -1100, 100, image=image, extension="CLIP")
    t.link(uv, "UV", tex, "Vector")
    fade = t.attribute(UV_FADE, -1300, -400)
    opacity = t.add("ShaderNodeSeparateXYZ", -1100, -400)
    t.link(fade, "Vector", opacity, "Vector")
    # After NODE_CARD_DEPTH transparent layers a ray stops at the next card (its colour there is
    # the grass's, see atlas.card_atlas): a sparse card (a few blades) is crossed many times
    # at grazing angles, and past the renderer's transparent-bounce limit a ray would turn black.
    path = t.add("ShaderNodeLightPath", -1300, -650)
    depth = t.add("ShaderNodeValue", -1300, -850, name=NODE_CARD_DEPTH)
    depth.outputs[0].default_value = 6.0
    deep = t.math("GREATER_THAN", (path, "Transparent Depth"), (depth, "Value"), -1100, -650)
    # (a fading card too: with the renderer's limit near, as Blender's default of 8, a ray through
    # the fading band would otherwise run out of layers and come out black)
    faded = t.math("MULTIPLY", (tex, "Alpha"), (opacity, "X"), -950, -500, clamp=True)
    stops = t.math("MAXIMUM", (faded, "Value"), (deep, "Value"), -800, -450)
    # Fading cards shade one another and the ground as the blades they stand for would. (Fading
    # cards that cast no shadow and hid no sky, so that the far canopy under them would not be
    # shaded twice, came out as lit as one card alone: the band's fade 1.15-1.33 times the blades'
    # red and green from 2.5 m in sun. In their shade the fade's rows seen from the default's eye
    # fall 0.009-0.023 short of the blades' blue: less sky reaches the canopy under them.)
    alpha = stops
    # A card is one flat plane where its blades turn every way: their highlights scatter, the
    # plane's would gather into a pale sheen, so the card reflects as a rougher, duller surface.
    lit = t.mix_rgb(-950, 300, blend="MULTIPLY", b=(CARD_LIGHT, CARD_LIGHT, CARD_LIGHT, 1.0))
    t.link(tex, "Color", lit, "A_Color")
    colour, colour_out = t.patched(lit, "Result_Color", patch_image, -880, 500)
    if gust_image is not None:
        colour, colour_out = t.gusted(colour, colour_out, gust_image, -800, 300), "Result_Color"
    shader = t.hazed(t.foliage(colour, colour_out, -500, 0, specular=CARD_SPECULAR, roughness=CARD_ROUGHNESS),
                     "Shader", -100, 0)
    clear = t.add("ShaderNodeBsdfTransparent", -200, 250)
    cut = t.add("ShaderNodeMixShader", 150, 0)
    t.link(alpha, "Value", cut, "Fac")
    t.link(clear, "BSDF", cut, cut.inputs[1])
    t.link(shader, "Shader", cut, cut.inputs[2])
    out = t.add("ShaderNodeOutputMaterial", 400, 0)
    t.link(cut, "Shader", out, "Surface")
    return mat


def ground_material(name: str, uid: str):
    """Ground under the grass: the floor of a meadow (thatch and green litter in noise), matte.
    The far grass is the canopy's (``canopy_material``), on a plane above this one."""
    mat = _new_material(name, uid)
    t = _Tree(mat)
    coord = t.add("ShaderNodeTexCoord", -1100, 0)
    noise = t.add("ShaderNodeTexNoise", -900, 0)
    _set(noise, 9.0, "Scale")
    _set(noise, 6.0, "Detail")
    t.link(coord, "Object", noise, "Vector")
    floor = t.mix_rgb(-650, 0, a=THATCH_COLOUR, b=LITTER_COLOUR, name=NODE_FLOOR)  # (update_floor)
    t.link(noise, "Fac", floor, "Factor_Float")
    t.matte(floor, "Result_Color")
    return mat


def land_material(name: str, colour, haze_distance: float, haze_colour):
    """The meadow past a field's edge, to the horizon (headless scenes): ``colour`` (linear RGB,
    the grass seen from the side) in patches of 5-30 m that are lusher or drier, matte, seen
    through ``haze_distance`` m of haze (``hazed``)."""
    mat = _new_material(name, "land")
    t = _Tree(mat)
    coord = t.add("ShaderNodeTexCoord", -1300, 0)
    patches = t.add("ShaderNodeTexNoise", -1100, 100)
    _set(patches, 1.0 / 8.0, "Scale")  # object coordinates are metres
    _set(patches, 7.0, "Detail")
    _set(patches, 0.62, "Roughness")  # tufts of a few decimetres in the patches
    t.link(coord, "Object", patches, "Vector")
    dry = t.add("ShaderNodeTexNoise", -1100, -150)
    _set(dry, 1.0 / 30.0, "Scale")
    _set(dry, 2.0, "Detail")
    t.link(coord, "Object", dry, "Vector")
    green = tuple(float(c) for c in colour)
    hay = tuple(0.55 * c + 0.45 * h for c, h in zip(green, sward.THATCH_COLOUR))
    tint = t.mix_rgb(-850, -100, a=(*green, 1.0), b=(*hay, 1.0))
    ramp = t.math("MULTIPLY_ADD", (dry, "Fac"), 3.0, -950, -300, clamp=True)
    ramp.inputs[2].default_value = -1.35  # the drier patches: where the slow noise is above 0.45
    t.link(ramp, "Value", tint, "Factor_Float")
    shade = t.math("MULTIPLY_ADD", (patches, "Fac"), 1.6, -850, 150)
    shade.inputs[2].default_value = 0.2  # lusher and thinner patches: about 0.7 to 1.3 times the colour
    lit = t.mix_rgb(-650, 0, blend="MULTIPLY")
    t.link(tint, "Result_Color", lit, "A_Color")
    t.link(shade, "Value", lit, "B_Color")
    t.matte(lit, "Result_Color")
    _write_haze(mat, haze_distance, haze_colour)
    return mat


def canopy_material(name: str, uid: str, gust_image=None, trail_image=None, patch_image=None):
    """Far grass (paper III.C): the sward seen from afar, on a plane at the canopy height
    (``sward.canopy_height``). Its colour is what a ray with the slope of the camera's ray sees
    of the sward (``sward.sward_look``, times SWARD_LIGHT) with fine streaks; its opacity rises
    with K_t of eq 10 = clamp((d - d_s1) / (d_s2 - d_s1)) from the Camera Data node's View
    Distance, so it appears where the cards fade (K'_b = 1 - K_t, eq 11) and is clear near the
    camera. Only the camera sees it."""
    mat = _new_material(name, uid)
    _transparent(mat)
    t = _Tree(mat)
    coord = t.add("ShaderNodeTexCoord", -1400, 0)
    view, view_z, slope = _view_slope(t, -2300, -1100)
    grass = _canopy_colour(t, coord, view, view_z, slope, trail_image)
    bsdf = t.add("ShaderNodeBsdfPrincipled", -450, 0)
    _set(bsdf, 1.0, "Roughness")
    _set(bsdf, 0.0, "Specular IOR Level", "Specular")
    grass, grass_out = t.patched(grass, "Result_Color", patch_image, -780, 500)
    if gust_image is not None:
        # seen from above the waves show more: a blade bent by a gust shows more of itself to a
        # steep ray (its area seen from above grows as the sine of its tilt) and its lighter side
        above = t.add("ShaderNodeMapRange", -1100, 300, clamp=True)
        t.link(slope, "Value", above, "Value")
        _set(above, SHEEN_SLOPES[0], "From Min")
        _set(above, SHEEN_SLOPES[1], "From Max")
        _set(above, 1.0, "To Min")
        _set(above, SHEEN_ABOVE, "To Max")
        grass, grass_out = t.gusted(grass, grass_out, gust_image, -700, 300, boost=(above, "Result")), "Result_Color"
    grass, grass_out = _speckled(t, coord, slope, grass, grass_out, -700, 800), "Result_Color"
    t.link(grass, grass_out, bsdf, "Base Color")
    # The fringe stands for the tips along the field's edge: partly translucent as theirs
    # (TRANSLUCENCY), so against the sun it glows as they do. (Opaque, the far edge of the
    # default meadow seen against the sun was a row 0.035-0.044 darker than its blades.)
    through = t.add("ShaderNodeBsdfTranslucent", -450, 250)
    t.link(grass, grass_out, through, "Color")
    fringe = t.add("ShaderNodeSeparateXYZ", -650, 350)
    t.link(t.attribute(UV_SWARD_Z, -850, 350), "Vector", fringe, "Vector")
    share = t.math("MULTIPLY", (fringe, "X"), TRANSLUCENCY, -450, 400)
    leaf = t.add("ShaderNodeMixShader", -250, 100)
    t.link(share, "Value", leaf, "Fac")
    t.link(bsdf, "BSDF", leaf, leaf.inputs[1])
    t.link(through, "BSDF", leaf, leaf.inputs[2])
    camera = t.add("ShaderNodeCameraData", -900, -650)
    kt = t.add("ShaderNodeMapRange", -700, -650, name=NODE_KT, clamp=True)  # eq 10
    t.link(camera, "View Distance", kt, "Value")
    _set(kt, 0.0, "To Min")
    _set(kt, 1.0, "To Max")
    opacity = _canopy_opacity(t, coord, kt, view, view_z, slope, patch_image)
    clear = t.add("ShaderNodeBsdfTransparent", -200, 250)
    cut = t.add("ShaderNodeMixShader", 50, 0)
    t.link(opacity, "Value", cut, "Fac")
    t.link(clear, "BSDF", cut, cut.inputs[1])
    t.link(t.hazed(leaf, "Shader", -100, 150), "Shader", cut, cut.inputs[2])
    out = t.add("ShaderNodeOutputMaterial", 300, 0)
    t.link(cut, "Shader", out, "Surface")
    return mat


def _speckled(t: _Tree, coord, slope, grass, grass_out: str, x: float, y: float):
    """The canopy's colour with the flowers seen from above (``sward.flower_speckles``): one in
    each cell of a Voronoi grid (NODE_SPECKLE_GRID: its scale the square root of the flowers per
    m²), a disc of their radius (NODE_SPECKLE_CUT) about the cell's point, coloured for the
    species the cell's random value falls to (NODE_SPECKLE_COLOURS, constant steps at the running
    shares); they come in over the ray's slopes ``sward.SPECKLE_SLOPES`` (grazing rays see the
    sward's look alone)."""
    grid = t.add("ShaderNodeTexVoronoi", x - 600, y, name=NODE_SPECKLE_GRID, voronoi_dimensions="2D",
                 feature="F1", distance="EUCLIDEAN")
    t.link(coord, "Object", grid, "Vector")
    _set(grid, 1.0, "Randomness")
    cut = t.math("LESS_THAN", (grid, "Distance"), 0.0, x - 400, y + 100)
    cut.name = cut.label = NODE_SPECKLE_CUT
    seen = t.add("ShaderNodeMapRange", x - 400, y - 150, clamp=True)
    t.link(slope, "Value", seen, "Value")
    _set(seen, sward.SPECKLE_SLOPES[0], "From Min")
    _set(seen, sward.SPECKLE_SLOPES[1], "From Max")
    shown = t.math("MULTIPLY", (cut, "Value"), (seen, "Result"), x - 200, y)
    pick = t.add("ShaderNodeSeparateColor", x - 400, y - 350)
    t.link(grid, "Color", pick, "Color")
    colours = t.add("ShaderNodeValToRGB", x - 250, y - 350, name=NODE_SPECKLE_COLOURS)
    colours.color_ramp.interpolation = "CONSTANT"
    t.link(pick, "Red", colours, "Fac")
    # a speck is its flower's colour as bright, against the blades' brightness, as the sward's
    # look there (lit and shaded as the grass round it: NODE_SPECKLE_GAIN is 1 / the blades'
    # mean brightness; the ramp holds the colours)
    gain = t.add("ShaderNodeValue", x - 250, y - 550, name=NODE_SPECKLE_GAIN)
    gain.outputs[0].default_value = 1.0
    bright = t.add("ShaderNodeRGBToBW", x - 300, y - 650)  # the look's brightness there
    t.link(grass, grass_out, bright, "Color")
    lit = t.math("MULTIPLY", (bright, "Val"), (gain, "Value"), x - 150, y - 600)
    speck = t.math("SCALE", (colours, "Color"), None, x - 100, y - 450, vector=True)
    t.link(lit, "Value", speck, "Scale")
    mix = t.mix_rgb(x, y)
    t.link(shown, "Value", mix, "Factor_Float")
    t.link(grass, grass_out, mix, "A_Color")
    t.link(speck, "Vector", mix, "B_Color")
    return mix


def update_speckles(params: Params, canopy) -> None:
    """The canopy's flowers from above for ``params`` (``_speckled``)."""
    nodes = canopy.node_tree.nodes
    grid, cut, colours = (nodes.get(n) for n in (NODE_SPECKLE_GRID, NODE_SPECKLE_CUT, NODE_SPECKLE_COLOURS))
    if grid is None or cut is None or colours is None:
        return
    density, radius, shares = sward.flower_speckles(params)
    scale = float(np.sqrt(density)) if density > 0.0 else 1.0
    _set(grid, scale, "Scale")
    cut.inputs[1].default_value = radius * scale if shares else 0.0
    species = sward.Species(params)
    blades = (species.p[:, None] * species.color).sum(axis=0)  # the blades' mean colour
    gain = nodes.get(NODE_SPECKLE_GAIN)
    if gain is not None:  # (Blender's RGB to BW: 0.2126 r + 0.7152 g + 0.0722 b)
        gain.outputs[0].default_value = 1.0 / max(float(np.dot(blades, (0.2126, 0.7152, 0.0722))), 1e-4)
    elements = colours.color_ramp.elements
    while len(elements) > 1:
        elements.remove(elements[-1])
    elements[0].position = 0.0
    elements[0].color = (*(shares[0][1] if shares else (0.0, 0.0, 0.0)), 1.0)
    for (start, _), (_, colour) in zip(shares, shares[1:]):  # (each from the share before it on)
        element = elements.new(min(start, 1.0))
        element.color = (*colour, 1.0)


def _canopy_colour(t, coord, view, view_z, slope, trail_image):
    """The canopy's colour: the sward's look at the ray's slope (``sward.sward_look`` over
    s / (s + LOOK_KNEE)), the fringe's tips where ``wg_sward_z`` X = 1, the trails, fine streaks."""
    grass_noise = t.add("ShaderNodeTexNoise", -1150, -50)
    _set(grass_noise, 40.0, "Scale")
    _set(grass_noise, 4.0, "Detail")
    t.link(coord, "Object", grass_noise, "Vector")
    # the look over x = s / (s + LOOK_KNEE), one curve per channel of a grey (x, x, x)
    knee = t.math("ADD", (slope, "Value"), LOOK_KNEE, -1700, -350)
    along = t.math("DIVIDE", (slope, "Value"), (knee, "Value"), -1550, -350)
    grey = t.add("ShaderNodeCombineXYZ", -1400, -350)
    for axis in "XYZ":
        t.link(along, "Value", grey, axis)
    grass_colour = t.add("ShaderNodeRGBCurve", -1250, -350, name=NODE_SWARD_LOOK)
    t.link(grey, "Vector", grass_colour, "Color")
    # the fringe (``wg_sward_z`` X = 1) shows the tips that stand above the plane
    fringe_colour = t.add("ShaderNodeRGB", -1150, -550, name=NODE_FRINGE_COLOUR)
    fringe_colour.outputs[0].default_value = (0.1, 0.25, 0.05, 1.0)
    on_fringe = t.add("ShaderNodeSeparateXYZ", -1150, -750)
    t.link(t.attribute(UV_SWARD_Z, -1350, -750), "Vector", on_fringe, "Vector")
    look, look_out = _trailed(t, coord, view, view_z, grass_colour, trail_image, -2300, 400)
    part = t.mix_rgb(-1000, -350)
    t.link(on_fringe, "X", part, "Factor_Float")
    t.link(look, look_out, part, "A_Color")
    t.link(fringe_colour, "Color", part, "B_Color")
    grass = t.mix_rgb(-900, -150, blend="MULTIPLY")
    t.link(part, "Result_Color", grass, "A_Color")
    ramp = t.add("ShaderNodeMapRange", -900, -400)  # noise 0..1 -> brightness 0.8 .. 1.2 (mean 1)
    _set(ramp, 0.8, "To Min")
    _set(ramp, 1.2, "To Max")
    t.link(grass_noise, "Fac", ramp, "Value")
    bright = t.add("ShaderNodeCombineXYZ", -700, -400)
    for axis in "XYZ":
        t.link(ramp, "Result", bright, axis)
    t.link(bright, "Vector", grass, "B_Color")
    return _tussocked(t, coord, grass, along, -2300, 800)


def _tussocked(t: _Tree, coord, colour_node, along, x: float, y: float):
    """The colour brightened tussock by tussock (NODE_TUSSOCKS, NODE_TUSSOCK_SPREAD), by the share
    of that grain a pixel at the ray's slope shows (NODE_TUSSOCK_SEEN over ``along``, the slope's
    s / (s + LOOK_KNEE): ``sward.grain_seen``): mean 1."""
    # Each tussock a mound: its random brightness (the cell's value) and its relief, lighter over
    # its middle (where its tips stand tallest, in the sun) and darker down its sides to the gaps
    # between tussocks (the Voronoi distance to its centre: about 0.5 of a cell on average). Flat
    # cells alone read from above as a camouflage pattern (issue #59); the two parts keep the grain's
    # spread (its standard deviation: 0.6 / sqrt 3 and 0.8 times that of 2 (0.5 - d), 0.26 each).
    cells = t.add("ShaderNodeTexVoronoi", x, y, name=NODE_TUSSOCKS, feature="SMOOTH_F1")
    _set(cells, TUSSOCK_SMOOTHNESS, "Smoothness")  # (mounds that merge, not cells with creases)
    t.link(coord, "Object", cells, "Vector")
    spread = t.add("ShaderNodeValue", x, y - 250, name=NODE_TUSSOCK_SPREAD)
    spread.outputs[0].default_value = 0.0
    seen = t.add("ShaderNodeFloatCurve", x, y - 450, name=NODE_TUSSOCK_SEEN)
    t.link(along, "Value", seen, "Value")
    u = t.add("ShaderNodeSeparateXYZ", x + 200, y)
    t.link(cells, "Color", u, "Vector")
    swing = t.math("MULTIPLY_ADD", (u, "X"), 2.0 * TUSSOCK_VALUE, x + 350, y)
    swing.inputs[2].default_value = -TUSSOCK_VALUE
    relief = t.math("MULTIPLY_ADD", (cells, "Distance"), -2.0 * TUSSOCK_RELIEF, x + 350, y + 200)
    relief.inputs[2].default_value = TUSSOCK_RELIEF
    both = t.math("ADD", (swing, "Value"), (relief, "Value"), x + 450, y + 100)
    shown = t.math("MULTIPLY", (spread, "Value"), (seen, "Value"), x + 200, y - 300)
    amount = t.math("MULTIPLY", (shown, "Value"), 3.0 ** 0.5, x + 350, y - 250)
    gain = t.math("MULTIPLY_ADD", (both, "Value"), (amount, "Value"), x + 500, y)
    gain.inputs[2].default_value = 1.0
    out = t.mix_rgb(x + 650, y, blend="MULTIPLY")
    t.link(colour_node, "Result_Color", out, "A_Color")
    t.link(gain, "Value", out, "B_Color")
    return out


def _canopy_opacity(t, coord, kt, view, view_z, slope, patch_image=None):
    """How much of the ray the canopy stops: 1 - (1 - K_t)^2, see-through at the field's edge as
    its blades would be, times the share of blades that grow (paint), for camera rays only."""
    # The canopy is the floor of the fading cards (K'_b = 1 - K_t): its opacity 1 - (1 - K_t)^2
    # rises twice as fast as K_t at first, so the dark ground does not show through both, and
    # levels off smoothly to 1 at the band's end (a kink in it shows as a line).
    left = t.math("SUBTRACT", 1.0, (kt, "Result"), -650, -450)
    gain = t.math("MULTIPLY_ADD", (left, "Value"), (left, "Value"), -600, -550, clamp=True)
    gain.inputs[2].default_value = 0.0
    gain = t.math("SUBTRACT", 1.0, (gain, "Value"), -550, -550, clamp=True)
    # Where rays leave the field (its edge against the sky) the sward is as see-through as the
    # share K_t of its blades that the canopy stands for (the cards carry the rest).
    edge = t.math("MINIMUM", (gain, "Value"),
                  (_sward_edge_opacity(t, coord, kt, view, view_z, slope, -1900, -1100, patch_image), "Value"),
                  -450, -650, clamp=True)
    grows = _painted_share(t)
    share = t.math("MULTIPLY", (edge, "Value"), (grows, "Result"), -350, -900, clamp=True)
    light_path = t.add("ShaderNodeLightPath", -700, -900)
    # Seen by the camera only: clear to shadow rays and to light bouncing (a plane over the whole
    # field would otherwise hide the sky from the ground under it, which shows dark through the
    # canopy where it starts to fade in: a dark line at the near edge of the card band)
    opacity = t.math("MULTIPLY", (share, "Value"), (light_path, "Is Camera Ray"), -300, -700, clamp=True)
    return opacity


def _painted_share(t):
    """The share of blades that grow at each place of a painted field (1 without paint)."""
    # Painted grass (paint.py): the canopy stands for the share of blades that grow at each place
    # (a path is bare ground to the horizon), from the field's paint map over the ground's UVs.
    paint_map = t.add("ShaderNodeTexImage", -900, -1250, name=NODE_PAINT_MAP)
    paint_map.mute = True  # until set_paint_map gives it an image
    paint_map.interpolation = "Linear"
    paint_map.extension = "EXTEND"
    # the ground's UVs span the field; the map spans what is painted (set_paint_map)
    to_map = t.add("ShaderNodeMapping", -1100, -1250, name=NODE_PAINT_MAPPING)
    t.link(t.attribute("UVMap", -1300, -1250), "Vector", to_map, "Vector")
    t.link(to_map, "Vector", paint_map, "Vector")
    density = t.add("ShaderNodeSeparateColor", -700, -1250)
    t.link(paint_map, "Color", density, "Color")
    painted = t.add("ShaderNodeValue", -700, -1450, name=NODE_PAINTED)  # 1 with a paint map, else 0
    painted.outputs[0].default_value = 0.0
    grows = t.add("ShaderNodeMapRange", -500, -1350)  # 1 - painted + painted * density
    t.link(painted, "Value", grows, "Value")
    _set(grows, 1.0, "To Min")
    t.link(density, density.outputs[0], grows, "To Max")
    return grows


def _trailed(t: _Tree, coord, view, view_z, look, trail_image, x: float, y: float):
    """(node, output): the canopy's ``look`` with the trampled trails (interaction.trail_map).
    A ray that meets the canopy plane at P goes on down by h = TRAIL_SINK times the canopy's
    height (where a trail's flattened floor shows) to P2 = P - Incoming h / Incoming.z. With f1,
    f2 the trail's flatness at P and P2, it meets the flattened floor where both lie on the trail
    (TRAIL_FLOOR darker by f1 f2), and standing grass lit from the open trail behind it where the
    trail lies ahead only (TRAIL_WALL brighter by max(f2 - f1, 0)). Seen low (h / s wider than
    the trail) neither shows: a trail is hidden behind the grass in front of it, as in
    all-geometry renders. The map is the field's frame (object coordinates) mapped onto the
    image; NODE_TRAIL_AMOUNT is 0 when none is shown."""
    amount = t.add("ShaderNodeValue", x, y - 400, name=NODE_TRAIL_AMOUNT)
    amount.outputs[0].default_value = 0.0
    depth = t.add("ShaderNodeValue", x, y - 550, name=NODE_TRAIL_DEPTH)
    depth.outputs[0].default_value = 0.2

    def flatness(vector_node, vector_out, name, yy):
        mapping = t.add("ShaderNodeMapping", x + 200, yy, name=name)
        t.link(vector_node, vector_out, mapping, "Vector")
        tex = t.add("ShaderNodeTexImage", x + 400, yy, image=trail_image, interpolation="Linear", extension="CLIP")
        t.link(mapping, "Vector", tex, "Vector")
        return t.math("MULTIPLY", (tex, "Color"), (amount, "Value"), x + 650, yy)

    near = flatness(coord, "Object", NODE_TRAIL_NEAR, y)
    rise = t.math("MAXIMUM", (view_z, "Z"), 1e-4, x + 800, y - 400)
    along = t.math("DIVIDE", (depth, "Value"), (rise, "Value"), x + 950, y - 300)
    step = t.add("ShaderNodeVectorMath", x + 1100, y - 300, operation="SCALE")
    t.link(view, "Vector", step, 0)
    t.link(along, "Value", step, "Scale")
    further = t.math("SUBTRACT", (coord, "Object"), (step, "Vector"), x + 1250, y - 300, vector=True)
    far = flatness(further, "Vector", NODE_TRAIL_FAR, y - 700)
    both = t.math("MULTIPLY", (near, "Value"), (far, "Value"), x + 1400, y)
    floor = t.math("MULTIPLY_ADD", (both, "Value"), TRAIL_FLOOR - 1.0, x + 1550, y)
    floor.inputs[2].default_value = 1.0
    ahead = t.math("SUBTRACT", (far, "Value"), (near, "Value"), x + 1400, y - 500, clamp=True)
    lit = t.math("MULTIPLY_ADD", (ahead, "Value"), TRAIL_WALL - 1.0, x + 1550, y - 500)
    lit.inputs[2].default_value = 1.0
    gain = t.math("MULTIPLY", (floor, "Value"), (lit, "Value"), x + 1700, y - 250)
    out = t.mix_rgb(x + 1850, y, blend="MULTIPLY")
    t.link(look, "Color", out, "A_Color")
    t.link(gain, "Value", out, "B_Color")
    return out, "Result_Color"


def set_trail(canopy, trail_map) -> None:
    """Show ``trail_map`` (interaction.TrailMap; its pixels already in the material's image) on
    the far canopy, or no trail (None)."""
    nodes = canopy.node_tree.nodes if canopy is not None and canopy.node_tree is not None else None
    if nodes is None or nodes.get(NODE_TRAIL_AMOUNT) is None:
        return
    amount = nodes[NODE_TRAIL_AMOUNT].outputs[0]
    shown = 0.0 if trail_map is None else 1.0
    if amount.default_value != shown:
        amount.default_value = shown
    if trail_map is None:
        return
    x0, y0, x1, y1 = trail_map.extent
    scale = (1.0 / (x1 - x0), 1.0 / (y1 - y0), 1.0)
    location = (-x0 / (x1 - x0), -y0 / (y1 - y0), 0.0)
    for name in (NODE_TRAIL_NEAR, NODE_TRAIL_FAR):
        _set(nodes[name], scale, "Scale")
        _set(nodes[name], location, "Location")


def _view_slope(t: _Tree, x: float, y: float):
    """(Incoming in the field's (object) frame, its Separate XYZ, the ray's slope s = |Incoming.z| /
    |Incoming.xy| (at least 1e-3)): nodes."""
    incoming = t.add("ShaderNodeNewGeometry", x, y)
    view = t.add("ShaderNodeVectorTransform", x + 180, y, vector_type="VECTOR",
                 convert_from="WORLD", convert_to="OBJECT")
    t.link(incoming, "Incoming", view, "Vector")
    view_z = t.add("ShaderNodeSeparateXYZ", x + 360, y - 250)
    t.link(view, "Vector", view_z, "Vector")
    flat = t.math("MULTIPLY", (view, "Vector"), (1.0, 1.0, 0.0), x + 360, y - 450, vector=True)
    run_len = t.math("LENGTH", (flat, "Vector"), None, x + 540, y - 450, vector=True)
    run_len = t.math("MAXIMUM", (run_len, "Value"), 1e-6, x + 720, y - 450)
    rise = t.math("ABSOLUTE", (view_z, "Z"), None, x + 540, y - 650)
    slope = t.math("DIVIDE", (rise, "Value"), (run_len, "Value"), x + 900, y - 550)
    slope = t.math("MAXIMUM", (slope, "Value"), 1e-3, x + 1080, y - 550)
    return view, view_z, slope


def _sward_edge_opacity(t: _Tree, coord, share, view, view_z, slope, x: float, y: float, patch_image=None):
    """Math node: how likely the sward stops the ray through this point of the canopy plane or
    its fringe, 1 - exp(-share tau(z_e) / s) (``sward.sward_depth``), where z_e is the height
    above the ground at which the ray leaves the field, s its slope and ``share`` (a node's
    "Result") the share of the blades that the canopy stands for; 1 when it meets the ground
    first or rises to this point (from a camera inside the sward). In the field's (object)
    frame the field spans +-NODE_FIELD_HALF around the origin: a ray at P going along
    d = -Incoming leaves it after t = min over X, Y of (half / |d| - P / d), having dropped
    Incoming.z * t. ``view``, ``view_z``, ``slope``: ``_view_slope``'s nodes. With the meadow's
    ``patch_image`` the depth is the local stand's, L tau(z_e / L): blades L times as long, L (its
    alpha, ``sward.patch_stands``) fitted to the patch's own profile, so a short or sparse stand
    lets more sky through than a tall, dense one."""
    # where the ray leaves the field: t = min over X, Y of (half / |d| - P / d), d = -Incoming
    d = t.math("MULTIPLY", (view, "Vector"), (-1.0, -1.0, -1.0), x + 360, y, vector=True)
    run = t.math("ABSOLUTE", (d, "Vector"), None, x + 540, y + 150, vector=True)
    run = t.math("MAXIMUM", (run, "Vector"), (1e-6, 1e-6, 1e-6), x + 720, y + 150, vector=True)
    half = t.add("ShaderNodeCombineXYZ", x + 720, y + 350, name=NODE_FIELD_HALF)
    to_wall = t.math("DIVIDE", (half, "Vector"), (run, "Vector"), x + 900, y + 250, vector=True)
    offset = t.math("DIVIDE", (coord, "Object"), (d, "Vector"), x + 900, y, vector=True)  # 0 where d is 0
    exits = t.math("SUBTRACT", (to_wall, "Vector"), (offset, "Vector"), x + 1080, y + 150, vector=True)
    exit_xy = t.add("ShaderNodeSeparateXYZ", x + 1260, y + 150)
    t.link(exits, "Vector", exit_xy, "Vector")
    leave = t.math("MINIMUM", (exit_xy, "X"), (exit_xy, "Y"), x + 1440, y + 150)
    leave = t.math("MAXIMUM", (leave, "Value"), 0.0, x + 1620, y + 150)
    drop = t.math("MULTIPLY", (leave, "Value"), (view_z, "Z"), x + 1800, y + 150)
    height = t.add("ShaderNodeSeparateXYZ", x + 1620, y - 100)
    t.link(t.attribute(UV_SWARD_Z, x + 1440, y - 100), "Vector", height, "Vector")
    z_exit = t.math("SUBTRACT", (height, "Y"), (drop, "Value"), x + 1980, y + 50)
    if patch_image is not None:
        stand = _crossed_stand(t, coord, patch_image, view, d, leave, z_exit, slope, x + 1620, y + 700)
        z_exit = t.math("DIVIDE", (z_exit, "Value"), (stand, "Value"), x + 2100, y + 250)
    # share * tau(z_e) / s, from the profile
    along = t.add("ShaderNodeMapRange", x + 2160, y + 50, name=NODE_SWARD_TOP, clamp=True)
    t.link(z_exit, "Value", along, "Value")
    profile = t.add("ShaderNodeFloatCurve", x + 2340, y + 50, name=NODE_SWARD_PROFILE)
    t.link(along, "Result", profile, "Value")
    depth = t.add("ShaderNodeValue", x + 2340, y - 250, name=NODE_SWARD_DEPTH)
    tau = t.math("MULTIPLY", (profile, "Value"), (depth, "Value"), x + 2520, y)
    if patch_image is not None:  # blades L times as long: L times the area over L times the heights
        tau = t.math("MULTIPLY", (tau, "Value"), (stand, "Value"), x + 2610, y + 150)
    tau = t.math("MULTIPLY", (tau, "Value"), (share, "Result"), x + 2700, y)
    crossed = t.math("DIVIDE", (tau, "Value"), (slope, "Value"), x + 2880, y)
    through = t.math("EXPONENT", (t.math("MULTIPLY", (crossed, "Value"), -1.0, x + 3060, y), "Value"), None,
                     x + 3240, y)
    stopped = t.math("SUBTRACT", 1.0, (through, "Value"), x + 3420, y, clamp=True)
    # stopped for sure: the ray meets the ground first, or rises to this point (a camera inside
    # the sward: it crossed the sward below)
    grounded = t.math("LESS_THAN", (z_exit, "Value"), 0.0, x + 3240, y - 250)
    rising = t.math("LESS_THAN", (view_z, "Z"), 0.0, x + 3240, y - 450)
    certain = t.math("MAXIMUM", (grounded, "Value"), (rising, "Value"), x + 3420, y - 350)
    opacity = t.math("MAXIMUM", (stopped, "Value"), (certain, "Value"), x + 3600, y)
    return opacity


def _crossed_stand(t: _Tree, coord, patch_image, view, d, leave, z_exit, slope, x: float, y: float):
    """Math node: the stand L (``sward.patch_stands``, the patch image's alpha) a ray crossed last
    before it leaves the field at height z_e: read where it leaves (P + d * leave), moved back
    towards the camera by half the run it took to sink from the sward's top to z_e (at most
    STAND_REACH m): the middle of what it crossed of the blades above z_e."""
    top = t.add("ShaderNodeValue", x, y, name=NODE_STAND_TOP)
    sink = t.math("SUBTRACT", (top, "Value"), (z_exit, "Value"), x + 180, y)
    sink = t.math("MAXIMUM", (sink, "Value"), 0.0, x + 360, y)
    reach = t.math("DIVIDE", (sink, "Value"), (slope, "Value"), x + 540, y)
    reach = t.math("MULTIPLY", (reach, "Value"), 0.5, x + 720, y)
    reach = t.math("MINIMUM", (reach, "Value"), STAND_REACH, x + 900, y)
    ahead = t.math("MULTIPLY", (d, "Vector"), (leave, "Value"), x + 180, y + 200, vector=True)
    exit_point = t.math("ADD", (coord, "Object"), (ahead, "Vector"), x + 360, y + 200, vector=True)
    towards = t.math("MULTIPLY", (view, "Vector"), (1.0, 1.0, 0.0), x + 360, y + 350, vector=True)
    towards = t.math("NORMALIZE", (towards, "Vector"), None, x + 540, y + 350, vector=True)
    back = t.math("MULTIPLY", (towards, "Vector"), (reach, "Value"), x + 1080, y + 300, vector=True)
    at = t.math("ADD", (exit_point, "Vector"), (back, "Vector"), x + 1260, y + 200, vector=True)
    mapping = t.add("ShaderNodeMapping", x + 1440, y + 200, name=NODE_STAND_MAPPING)
    t.link(at, "Vector", mapping, "Vector")
    tex = t.add("ShaderNodeTexImage", x + 1620, y + 200, name=NODE_STAND_IMAGE, image=patch_image,
                interpolation="Linear", extension="EXTEND")
    t.link(mapping, "Vector", tex, "Vector")
    stand = t.math("MULTIPLY", (tex, "Alpha"), textures.STAND_MAX, x + 1800, y + 100)
    return t.math("MAXIMUM", (stand, "Value"), 0.05, x + 1980, y + 100)


def set_card_depth(cards, transparent_bounces: int) -> None:
    """Cards stop rays two layers before the scene's transparent-bounce limit (Cycles)."""
    node = cards.node_tree.nodes.get(NODE_CARD_DEPTH) if cards is not None and cards.node_tree else None
    if node is not None:
        node.outputs[0].default_value = float(max(0, int(transparent_bounces) - 2))


def update_haze(params: Params, *mats) -> None:
    """Write render.haze_distance / haze_color into every material's aerial perspective."""
    for mat in mats:
        if mat is not None and mat.node_tree is not None:
            _write_haze(mat, float(params.render.haze_distance), params.render.haze_color)


def _write_haze(mat, distance: float, colour) -> None:
    """The aerial perspective of ``mat`` (``_Tree.hazed``): ``distance`` m to 63 % haze (0: none)."""
    node = mat.node_tree.nodes.get(NODE_HAZE_DISTANCE)
    if node is not None:
        node.outputs[0].default_value = -1.0 / distance if distance > 0.0 else 0.0
    node = mat.node_tree.nodes.get(NODE_HAZE_COLOUR)
    if node is not None:
        node.outputs[0].default_value = (*colour, 1.0)


def set_paint_map(canopy, image, field_extent=None, map_extent=None) -> None:
    """Let the canopy read the field's paint map ``image`` (None: no paint, the canopy is whole),
    which covers ``map_extent`` of the field's ``field_extent`` (both x0, y0, x1, y1)."""
    if canopy is None or canopy.node_tree is None:
        return
    nodes = canopy.node_tree.nodes
    node, flag, mapping = nodes.get(NODE_PAINT_MAP), nodes.get(NODE_PAINTED), nodes.get(NODE_PAINT_MAPPING)
    if node is not None:
        node.image = image
        node.mute = image is None  # (an Image Texture without an image is an error to Cycles from 5.2 on)
    if flag is not None:
        flag.outputs[0].default_value = 1.0 if image is not None else 0.0
    if mapping is not None and field_extent is not None and map_extent is not None:
        (fx0, fy0, fx1, fy1), (mx0, my0, mx1, my1) = field_extent, map_extent
        _set(mapping, ((fx1 - fx0) / (mx1 - mx0), (fy1 - fy0) / (my1 - my0), 1.0), "Scale")
        _set(mapping, ((fx0 - mx0) / (mx1 - mx0), (fy0 - my0) / (my1 - my0), 0.0), "Location")


def update_viewport_colours(params: Params, blades=None, cards=None, ground=None, canopy=None) -> None:
    """The colours Solid shading draws (``Material.diffuse_color``; it shows no node tree and no
    texture): the blades' mean tip colour, the cards (see-through: CARD_VIEWPORT_ALPHA) and the far
    canopy in the sward's colour seen from afar, the meadow floor under them; matte, so the field
    reads as a green meadow."""
    species = np.asarray([row["color"] for row in params.species()], dtype=np.float64)
    weights = np.asarray([row["weight"] for row in params.species()], dtype=np.float64)
    tips = (weights[:, None] * species).sum(axis=0) / max(weights.sum(), 1e-9)
    far = SWARD_LIGHT * sward.sward_look(params, [VIEWPORT_SLOPE])[0]
    floor = sward.ground_colours(params)
    for mat, rgb, alpha in ((blades, 0.85 * tips, 1.0), (cards, far, CARD_VIEWPORT_ALPHA), (canopy, far, 1.0),
                            (ground, floor[0], 1.0)):
        if mat is None:
            continue
        mat.diffuse_color = (*[float(c) for c in rgb], alpha)
        mat.roughness = 0.9
        mat.metallic = 0.0


def update_floor(params: Params, ground) -> None:
    """The ground's floor colours: a meadow's thatch and litter, or a lawn's turf (``field.floor``),
    under the leaves at the stems' foot (``sward.ground_colours``)."""
    node = ground.node_tree.nodes.get(NODE_FLOOR) if ground is not None and ground.node_tree is not None else None
    if node is not None:
        for name, colour in zip(("A_Color", "B_Color"), sward.ground_colours(params)):
            _set(node, (*colour, 1.0), name)


def gust_swing(params: Params, speed: float) -> float:
    """How much the gust waves brighten the far grass at a mean wind ``speed``: they show by the
    bend they cause, which grows as the speed squared (full from GUST_REFERENCE_SPEED on; calm
    air shows none)."""
    return GUST_SHADE * float(params.wind.gust_waves) * min(1.0, (speed / GUST_REFERENCE_SPEED) ** 2)


def update_gusts(params: Params, *mats) -> None:
    """The gust waves' brightness swing (at the settings' wind speed; ``set_gust_offset`` follows
    keyed wind every frame) and the pattern's scale (one tile per gusts.tile_metres)."""
    scale = 1.0 / gusts.tile_metres(params)
    for mat in mats:
        nodes = mat.node_tree.nodes if mat is not None and mat.node_tree is not None else None
        if nodes is None or nodes.get(NODE_GUST_AMOUNT) is None:
            continue
        nodes[NODE_GUST_AMOUNT].outputs[0].default_value = gust_swing(params, float(params.wind.speed))
        _set(nodes[NODE_GUST_MAPPING], (scale, scale, 1.0), "Scale")
        if nodes.get(NODE_GUST_MAPPING_2) is not None:
            _set(nodes[NODE_GUST_MAPPING_2], (scale, scale, 1.0), "Scale")


def update_patches(params: Params, *mats) -> None:
    """Map the field's frame onto the patch image (sward.patch_tint): (x - origin) / size."""
    grid = FieldGrid.of(params)
    size, origin = grid.size, grid.origin
    for mat in mats:
        nodes = mat.node_tree.nodes if mat is not None and mat.node_tree is not None else None
        if nodes is None:
            continue
        for mapping in (nodes.get(NODE_PATCH_MAPPING), nodes.get(NODE_STAND_MAPPING)):
            if mapping is not None:
                _set(mapping, (1.0 / size[0], 1.0 / size[1], 1.0), "Scale")
                _set(mapping, (-float(origin[0]) / size[0], -float(origin[1]) / size[1], 0.0), "Location")


def set_gust_offset(displacement, speed: float, other, weights, params: Params, *mats) -> None:
    """Carry the pattern downwind: the mapping's location is minus the mean wind's displacement
    (gusts.py), in tiles; the swing follows the mean wind's ``speed``; a looped wind's second
    pattern sits at the displacement ``other``, the two weighed by ``weights`` (``loop.py``;
    (1, 0) without a loop). Called every frame for fields with gust waves."""
    scale = 1.0 / gusts.tile_metres(params)
    swing = gust_swing(params, speed)
    for mat in mats:
        nodes = mat.node_tree.nodes if mat is not None and mat.node_tree else None
        if nodes is None:
            continue
        for mapping, amount, shift, weight in ((NODE_GUST_MAPPING, NODE_GUST_AMOUNT, displacement, weights[0]),
                                               (NODE_GUST_MAPPING_2, NODE_GUST_AMOUNT_2, other, weights[1])):
            node, value = nodes.get(mapping), nodes.get(amount)
            if node is None or value is None:
                continue
            socket = _socket(node.inputs, "Location")
            location = (-float(shift[0]) * scale, -float(shift[1]) * scale, 0.0)
            if weight and tuple(socket.default_value) != location:  # (a pattern that weighs nothing stays:
                socket.default_value = location  # each write updates the material's nodes)
            if value.outputs[0].default_value != swing * weight:
                value.outputs[0].default_value = swing * weight


LOOK_DIGEST = "wg_look"  # the canopy material's custom property: the settings its sward look was written for


def set_lod_scale(params: Params, canopy, scale: float = 1.0) -> None:
    """d_s1/d_s2 of eq 10 in the far grass, times the views' screen ``scale`` (``lod.screen_scale``:
    the frame's); written only when they change (a render's camera keeps them)."""
    kt = canopy.node_tree.nodes.get(NODE_KT) if canopy is not None and canopy.node_tree is not None else None
    if kt is None:
        return
    near, far = params.lod.card_near * scale, params.lod.card_far * scale
    if not params.lod.enabled:
        near, far = FAR_AWAY, 2.0 * FAR_AWAY  # LOD off: geometry everywhere, K_t = 0
    far = max(far, near + 1e-3)  # d_s1 == d_s2: a hard switch
    for value, names in ((near, ("From Min", "From_Min_FLOAT3")), (far, ("From Max", "From_Max_FLOAT3"))):
        if abs(float(_socket(kt.inputs, *names).default_value) - value) > 1e-6:
            _set(kt, value, names[0])


def update_materials(params: Params, canopy=None) -> None:
    """Write the parameter-dependent values: d_s1/d_s2 of eq 10 and the far grass's colour."""
    if canopy is not None and canopy.node_tree is not None:
        set_lod_scale(params, canopy)
        look_digest = edit_parts.digest_of(params, (edit_parts.LAYOUT, edit_parts.LOOK))
        if canopy.get(LOOK_DIGEST) == look_digest:
            return  # (the sward's look reads only these settings: a wind or LOD edit leaves it)
        canopy[LOOK_DIGEST] = look_digest
        depth = canopy.node_tree.nodes.get(NODE_TRAIL_DEPTH)
        if depth is not None:
            depth.outputs[0].default_value = TRAIL_SINK * sward.canopy_height(params)
        look = canopy.node_tree.nodes.get(NODE_SWARD_LOOK)
        along, slopes = sward.look_slopes()
        if look is not None:
            colours = SWARD_LIGHT * sward.sward_look(params, slopes)
            for channel in range(3):
                _set_curve(look.mapping.curves[channel], along, colours[:, channel])
            look.mapping.update()
        update_speckles(params, canopy)
        tips = canopy.node_tree.nodes.get(NODE_FRINGE_COLOUR)
        if tips is not None:
            tips.outputs[0].default_value = (*sward.fringe_colour(params), 1.0)
        cells, spread = canopy.node_tree.nodes.get(NODE_TUSSOCKS), canopy.node_tree.nodes.get(NODE_TUSSOCK_SPREAD)
        if cells is not None and spread is not None:
            size, spread.outputs[0].default_value = sward.tussock_grain(params)
            _set(cells, 1.0 / size, "Scale")
        seen = canopy.node_tree.nodes.get(NODE_TUSSOCK_SEEN)
        if seen is not None:
            _set_curve(seen.mapping.curves[0], along, sward.grain_seen(params, slopes))
            seen.mapping.update()
        update_sward_profile(params, canopy)


def update_sward_profile(params: Params, canopy) -> None:
    """Write the sward's silhouette depth profile and the field's extent into the canopy."""
    nodes = canopy.node_tree.nodes
    heights, depth = sward.sward_profile(params)
    top, ground = float(heights[-1]), float(max(depth[0], 1e-9))
    along = nodes.get(NODE_SWARD_TOP)
    if along is not None:
        _set(along, 0.0, "From Min")
        _set(along, top, "From Max")
    value = nodes.get(NODE_SWARD_DEPTH)
    if value is not None:
        value.outputs[0].default_value = ground
    stand_top = nodes.get(NODE_STAND_TOP)
    if stand_top is not None:
        stand_top.outputs[0].default_value = top
    half = nodes.get(NODE_FIELD_HALF)
    if half is not None:
        for axis, extent in zip("XY", FieldGrid.of(params).size):
            _set(half, 0.5 * extent, axis)
    profile = nodes.get(NODE_SWARD_PROFILE)
    if profile is not None:
        _set_curve(profile.mapping.curves[0], heights / top, depth / ground)
        profile.mapping.update()


def _set_curve(curve, xs, ys) -> None:
    """Make a curve mapping's ``curve`` pass through the points (xs, ys), straight between them."""
    while len(curve.points) > 2:
        curve.points.remove(curve.points[-1])
    while len(curve.points) < len(xs):
        curve.points.new(1.0, 0.0)
    for point, u, v in zip(curve.points, xs, ys):
        point.location = (float(u), float(v))
        point.handle_type = "VECTOR"

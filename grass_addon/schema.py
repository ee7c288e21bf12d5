"""The one parameter schema: defaults, ranges, units and help of every parameter.

The Blender properties (``grass_addon/bridge/properties.py``), the TOML scene files and the
command-line flags of ``headless/`` are all generated from ``PARAMS`` below. Add a parameter
here and it appears everywhere; never list a parameter anywhere else.

Values are stored in user units (metres, degrees, m/s, seconds). The engine converts degrees
to radians where it uses them.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import re
import stat
import tomllib
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from .errors import ParameterError, shown

WIND_TYPES = ("calm", "gentle_breeze", "moderate_breeze", "blast", "whirlwind")
FLOORS = ("thatch", "turf")  # what shows between the blades (sward.floor_colours)

# What choosing a wind type sets (paper IV's four types plus calm). Mean speeds follow the Beaufort
# scale: calm < 0.5 m/s, gentle breeze 3.4-5.4, moderate breeze 5.5-7.9; the turbulence (std of v',
# eq 12) grows with the mean, about a quarter of it as in the atmospheric surface layer. A TOML file
# that names a type but not these keys gets them from here.
WIND_TYPE_PRESETS = {
    "calm": {"speed": 0.3, "turbulence": 0.15},
    "gentle_breeze": {"speed": 4.4, "turbulence": 1.2},
    "moderate_breeze": {"speed": 6.7, "turbulence": 1.8},
    "blast": {"speed": 3.0, "turbulence": 0.8},
    "whirlwind": {"speed": 2.0, "turbulence": 0.6},
}
WIND_TYPE_SPEED = {kind: preset["speed"] for kind, preset in WIND_TYPE_PRESETS.items()}


def wind_preset(kind: str) -> dict[str, Any]:
    """Dotted overrides that a wind-type preset applies: ``{"wind.type": ..., "wind.speed": ...}``."""
    if kind not in WIND_TYPE_PRESETS:
        raise ParameterError("wind.type", f"unknown value {kind!r} (valid: one of {', '.join(WIND_TYPES)})")
    return {"wind.type": kind, **{f"wind.{k}": v for k, v in WIND_TYPE_PRESETS[kind].items()}}


# A field's size is bounded by float32 precision, not by memory (blocks are made on demand):
# vertex positions are float32 in field coordinates, whose spacing stays below a millimetre up to
# 8192 m from the centre (2**13 m * 2**-23).
MAX_FIELD_EXTENT = 16384.0  # m along X and along Y


@dataclass(frozen=True)
class Param:
    """One parameter. ``kind`` is one of: int, float, bool, enum, str, vec (floats), table_list,
    keys (a list of ``{time, position}`` points: a collider's path)."""

    section: str
    key: str
    kind: str
    default: Any
    help: str
    unit: str = ""
    minimum: float | None = None
    maximum: float | None = None
    soft_min: float | None = None
    soft_max: float | None = None
    choices: tuple[str, ...] = ()
    size: int = 0  # for kind == "vec"
    fields: tuple[Param, ...] = ()  # for kind == "table_list": the columns of each row
    label: str = ""
    applies_when: tuple[str, ...] = ()  # (enum key of the section, choice): only matters then
    path: bool = False  # a "str" that names a file: relative paths in a scene file are from its folder
    blender: bool = True  # False: scene files only (in Blender the field's collections give it)
    advanced: bool = False  # in Blender: in the section's collapsed Advanced panel
    components: tuple[str, ...] = ()  # for kind == "vec": the label of each number (X, Y, Z by default)

    @property
    def name(self) -> str:
        """Dotted name used in messages and TOML: ``wind.speed``."""
        return f"{self.section}.{self.key}" if self.section else self.key

    @property
    def cli_flag(self) -> str:
        """Command-line flag: ``--wind-speed``."""
        return "--" + self.name.replace(".", "-").replace("_", "-")

    @property
    def ui_name(self) -> str:
        return self.label or self.key.replace("_", " ").capitalize()

    def range_text(self) -> str:
        unit = f" {self.unit}" if self.unit and self.unit != "fraction" else ""
        if self.kind == "enum":
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind == "bool":
            return "true or false"
        if self.minimum is not None and self.maximum is not None:
            return f"{_fmt(self.minimum)} to {_fmt(self.maximum)}{unit}"
        if self.minimum is not None:
            return f">= {_fmt(self.minimum)}{unit}"
        return f"any number{unit}"


def _fmt(x: float) -> str:
    """A limit as a person writes it: 2147483647, 1e+06 stays 1000000, 1e-07 stays 1e-07."""
    if float(x).is_integer() and abs(x) < 1e16:
        return str(int(x))
    return f"{x:g}"


def _p(section: str, key: str, kind: str, default: Any, help: str, **kw: Any) -> Param:
    return Param(section=section, key=key, kind=kind, default=default, help=help, **kw)


# Columns of one ``[[blade.species]]`` row.
SPECIES_FIELDS: tuple[Param, ...] = (
    _p("", "name", "str", "meadow grass", "Species name shown in the list", label="Name"),
    _p("", "weight", "float", 1.0, "Relative share of blades of this species", minimum=0.0, maximum=1000.0,
       label="Share"),
    _p("", "length", "float", 0.32, "Typical height of this species' blades: their length from root to tip, "
       "standing (l_base, paper III.A)", unit="m", minimum=0.01, maximum=3.0, soft_max=1.5, label="Height"),
    _p("", "length_variation", "float", 0.07, "How much the blades' heights spread around the typical height: "
       "l = l_base + lambda * N(0,1) (lambda)", unit="m", minimum=0.0, maximum=1.0, soft_max=0.5, label="Variation"),
    _p("", "width", "float", 0.008, "Width of a blade at its root", unit="m", minimum=0.0005, maximum=0.1,
       soft_max=0.03, label="Width"),
    _p("", "stiffness", "float", 1.0, "Stiffness of this species relative to the field's stiffness: 2 is twice as "
       "stiff (multiplies mu_root, eq 1)", minimum=0.05, maximum=20.0, soft_max=5.0, label="Stiffness \u00d7"),
    _p("", "color", "vec", (0.12, 0.32, 0.05), "Colour of the blade tips (linear RGB)", minimum=0.0, maximum=1.0,
       size=3, label="Color"),
    _p("", "density_map", "str", "", "Where this species grows: a map that scales its share (white: its share, "
       "black: none). See paint.density for the sources", label="Density", path=True),
    _p("", "heads", "float", 0.0, "Share of this species' stems that carry a seed head or a flower at their tip",
       unit="fraction", minimum=0.0, maximum=1.0, label="Heads"),
    _p("", "head_color", "vec", (0.45, 0.36, 0.2), "Colour of the seed heads or flowers (linear RGB)", minimum=0.0,
       maximum=1.0, size=3, label="Head Color"),
    _p("", "head_size", "float", 3.0, "Width of a head as a multiple of the stem's width", unit="x width",
       minimum=1.0, maximum=30.0, soft_max=12.0, label="Head Size"),
    _p("", "head_shape", "enum", "seed", "A seed head is a spindle over the stem's top two segments, a spike "
       "(timothy's dense cylinder) or a panicle (meadow grass's open branches of spikelets) a mesh there; a flower "
       "opens at the tip of its top segment (a cup of the strip); a daisy (white rays round a yellow disc), a "
       "buttercup (five glossy cupped petals) or a clover head is a flower as a mesh riding the stem's tip",
       choices=("seed", "flower", "daisy", "buttercup", "clover", "spike", "panicle"), label="Head Shape"),
    _p("", "plant", "str", "", "A collection of your own (a flower, a fern, a clover clump) drawn for this "
       "species: on its flowering stems' tips as their heads, or, as a Plant, bent along each of its stems (its "
       "lowest point on the root, its height the stem's length). Empty: Windgrass's own", label="Own Plant"),
    _p("", "plant_mode", "enum", "head", "How the species' own collection is drawn: a head riding each flowering "
       "stem's tip, or the whole plant bent along every stem by the wind", choices=("head", "plant"),
       label="Drawn As"),
    _p("", "leaves", "enum", "none", "Short leaves at the foot of each stem, rocking with it: a grass tuft (narrow "
       "arching blades), a rosette (broad leaves lying out: plantain, daisy, buttercup) or clover leaves; they "
       "hide the soil as a real sward does, seen from above", choices=("none", "tuft", "rosette", "clover"),
       label="Leaves"),
    _p("", "leaf_size", "float", 0.45, "Length of the longest leaf at a stem's foot, as a share of the stem's "
       "length", unit="x height", minimum=0.05, maximum=3.0, soft_max=1.5, label="Leaf Size"),
)

# Columns of one ``[[keep_out.shapes]]`` row: where no grass grows.
KEEP_OUT_FIELDS: tuple[Param, ...] = (
    _p("", "shape", "enum", "box", "A rectangle or a disc on the ground", choices=("box", "disc"), label="Shape"),
    _p("", "center", "vec", (0.0, 0.0), "Its centre on the ground (the field's centre is 0, 0)", unit="m",
       minimum=-1e5, maximum=1e5, size=2, label="Center"),
    _p("", "size", "vec", (1.0, 1.0), "Box: its width (along X before turning) and depth", unit="m", minimum=0.0,
       maximum=1e5, size=2, label="Size"),
    _p("", "radius", "float", 1.0, "Disc: its radius", unit="m", minimum=0.0, maximum=1e5, label="Radius"),
    _p("", "angle", "float", 0.0, "Box: its turn, counter-clockwise", unit="deg", minimum=-3600.0, maximum=3600.0,
       label="Angle"),
)

# Columns of one ``[[colliders]]`` row (``[[interaction.colliders]]``): what moves through the grass.
COLLIDER_FIELDS: tuple[Param, ...] = (
    _p("", "shape", "enum", "sphere", "A ball, or a vertical capsule (a walker)", choices=("sphere", "capsule"),
       label="Shape"),
    _p("", "radius", "float", 0.3, "Radius of the sphere or of the capsule's ends", unit="m", minimum=0.01,
       maximum=100.0, label="Radius"),
    _p("", "length", "float", 0.0, "Capsule: distance between the centres of its ends (its middle follows the "
       "path)", unit="m", minimum=0.0, maximum=100.0, label="Length"),
    _p("", "path", "keys", (), "Keyed points {time = s, position = [x, y, z]}: straight between keys, held "
       "before the first and after the last (at least 2 keys, times increasing)", label="Path"),
)

EFFECTOR_TYPES = ("wind", "force", "vortex", "turbulence")

# Columns of one ``[[effectors]]`` row (``[[interaction.effectors]]``): Blender's force fields.
EFFECTOR_FIELDS: tuple[Param, ...] = (
    _p("", "type", "enum", "wind", "Blender's force field type: wind blows along the field's Z axis, force "
       "pushes away from its centre (negative: pulls), vortex turns around its Z axis, turbulence is noise",
       choices=EFFECTOR_TYPES, label="Type"),
    _p("", "position", "vec", (0.0, 0.0, 0.0), "Where the field is", unit="m", minimum=-1e5, maximum=1e5, size=3,
       label="Position"),
    _p("", "rotation", "vec", (0.0, 0.0, 0.0), "Its turn (Euler XYZ, as Blender's Rotation): Z points along "
       "the rotated Z axis", unit="deg", minimum=-3600.0, maximum=3600.0, size=3, label="Rotation"),
    _p("", "shape", "enum", "point", "Distances from its centre (point) or from its XY plane (plane)",
       choices=("point", "plane"), label="Shape"),
    _p("", "strength", "float", 5.0, "Blender's strength: on the grass, m/s of wind at full effect", minimum=-1000.0,
       maximum=1000.0, label="Strength"),
    _p("", "falloff", "float", 0.0, "Falloff power: the effect is (1 + d - min_distance)^-power", minimum=0.0,
       maximum=10.0, label="Falloff Power"),
    _p("", "falloff_type", "enum", "sphere", "Blender's falloff shape: by distance (sphere), by distance along Z "
       "and from the axis (tube), or by angle from Z (cone)", choices=("sphere", "tube", "cone"),
       label="Falloff Type"),
    _p("", "min_distance", "float", 0.0, "Full effect within this distance; 0: off", unit="m", minimum=0.0,
       maximum=1e5, label="Min Distance"),
    _p("", "max_distance", "float", 0.0, "No effect beyond this distance; 0: no limit", unit="m", minimum=0.0,
       maximum=1e5, label="Max Distance"),
    _p("", "noise", "float", 0.0, "Blender's noise: random change of the effect, a share of the strength",
       minimum=0.0, maximum=10.0, label="Noise"),
    _p("", "size", "float", 1.0, "Turbulence: size of its eddies", unit="m", minimum=0.01, maximum=1e4,
       label="Size"),
    _p("", "seed", "int", 1, "Seed of the noise", minimum=0, maximum=2**31 - 1, label="Seed"),
)

EXTENT_CORNERS = ("Min X", "Min Y", "Max X", "Max Y")  # the numbers of an extent [x0, y0, x1, y1]

MAP_SOURCES = ("A PNG file (paths in a scene file are from its folder); in Blender also vertex_group:NAME or "
               "attribute:NAME of the terrain mesh, or image:NAME of an image (over the terrain's UV map, else "
               "the extent)")

# Columns of one ``[[wind.keys]]`` row: the mean wind changes over time between keys.
WIND_KEY_FIELDS: tuple[Param, ...] = (
    _p("", "time", "float", 0.0, "When this key applies, in seconds from the first frame", unit="s", minimum=-1e6,
       maximum=1e6, label="Time"),
    _p("", "speed", "float", 4.4, "Mean wind speed from this key on", unit="m/s", minimum=0.0, maximum=60.0,
       label="Speed"),
    _p("", "direction", "float", 30.0, "Direction the wind blows towards, counter-clockwise from +X", unit="deg",
       minimum=-3600.0, maximum=3600.0, label="Direction"),
)

PARAMS: tuple[Param, ...] = (
    # --- [field] paper III: blocks (patches) of square cells -----------------------------------
    _p("field", "blocks_x", "int", 32, "Blocks along X: the field is made and drawn in square blocks, so its length "
       "is blocks x cells per block x cell size", minimum=1, maximum=1_638_400, soft_max=1024,
       advanced=True, label="Blocks X"),
    _p("field", "blocks_y", "int", 32, "Blocks along Y: the field is made and drawn in square blocks, so its width "
       "is blocks x cells per block x cell size", minimum=1, maximum=1_638_400, soft_max=1024,
       advanced=True, label="Blocks Y"),
    _p("field", "cells_per_block", "int", 16, "Cells along each side of a block", minimum=1, maximum=64, soft_max=32,
       advanced=True, label="Cells/Block"),
    _p("field", "cell_size", "float", 0.1, "Edge of a square cell; the blades of a cell bend together (paper V.B)",
       unit="m", minimum=0.01, maximum=10.0, soft_max=1.0, advanced=True, label="Cell Size"),
    _p("field", "blades_per_cell", "int", 2, "Blades growing in each cell: more is denser grass ('num' of eq 9)",
       minimum=0, maximum=64, soft_max=16, advanced=True, label="Blades/Cell"),
    _p("field", "seed", "int", 0, "Another seed grows the blades elsewhere and runs other gusts; the same seed gives "
       "the same field", minimum=0, maximum=2**31 - 1, label="Seed"),
    _p("field", "clumping", "float", 0.0, "Grass grows in tussocks: how far each blade is drawn towards its "
       "clump's centre (0: evenly spread, 1: all on the centre)", unit="fraction", minimum=0.0, maximum=0.95,
       label="Clumping"),
    _p("field", "clump_size", "float", 0.5, "Distance between neighbouring tussocks", unit="m", minimum=0.05,
       maximum=10.0, soft_max=2.0, label="Clump Size"),
    _p("field", "patchiness", "float", 0.0, "Patches where the grass grows taller or shorter and the species mix "
       "changes (0: the same everywhere)", unit="fraction", minimum=0.0, maximum=1.0, label="Patches"),
    _p("field", "patch_size", "float", 8.0, "Size of a patch", unit="m", minimum=0.5, maximum=1000.0,
       soft_max=50.0, label="Patch Size"),
    _p("field", "flower_drift", "float", 1.6, "How much more a flowering species' share changes from patch to patch "
       "than a grass's: flowers grow in drifts of yellow and white (1: as the grasses; the field's share of each "
       "species stays)", minimum=1.0, maximum=4.0, advanced=True, label="Flower Drifts"),
    _p("field", "edge", "float", 0.0, "How far in from the field's edge its grass grows to full height, along a ragged "
       "line (0: a hard edge, for fields laid side by side): a meadow's edge thins out instead of standing as a wall",
       unit="m", minimum=0.0, maximum=20.0, soft_max=3.0, label="Edge"),
    _p("field", "floor", "enum", "thatch", "What shows between the blades: a meadow's dry thatch and green litter, "
       "or a lawn's dense living turf (its thousands of shoots a square metre, more than the blades drawn)",
       choices=FLOORS, label="Floor"),
    # --- [blade] paper III.A, eqs 1-6 and V.A, eqs 14-32 ----------------------------------------
    _p("blade", "segments", "int", 5, "Rigid pieces per blade: more bend more smoothly and cost more (n)", minimum=1,
       maximum=12, advanced=True, label="Segments"),
    _p("blade", "tip_width", "float", 0.15, "Width of a blade at its tip, as a fraction of its width at the root",
       unit="fraction", minimum=0.0, maximum=1.0, advanced=True, label="Tip Width"),
    _p("blade", "inclination", "float", 18.0, "Largest random lean of a blade at rest (alpha, paper III.A)",
       unit="deg", minimum=0.0, maximum=80.0, label="Lean"),
    _p("blade", "root_stiffness", "float", 8.0e-4, "How stiff a blade is at its root: softer blades bend further in "
       "the same wind (mu_root of eq 1: stiffness mu = mu_root / (L + x) at distance L from the root)",
       unit="N*m^2/rad", minimum=1e-7, maximum=1.0, soft_max=0.01, advanced=True, label="Rigidity"),
    _p("blade", "stiffness_offset", "float", 0.05, "Keeps the stiffness at the root finite: larger makes a blade "
       "more evenly stiff along its length (x of eq 1)", unit="m", minimum=1e-4, maximum=1.0,
       advanced=True, label="Stiff. Offset"),
    _p("blade", "density", "float", 0.003, "Mass of a blade per metre of its length: heavier blades droop more "
       "(rho_grass of eq 2)", unit="kg/m", minimum=1e-5, maximum=1.0, soft_max=0.05,
       advanced=True, label="Mass/Length"),
    _p("blade", "nonlinear_stiffness", "float", 2.0e-3, "How much stiffer a blade grows the further it is bent (k of "
       "eq 23)", unit="N*m/rad^2", minimum=0.0, maximum=1.0, soft_max=0.05, advanced=True, label="Stiffening"),
    _p("blade", "response_torque", "float", 2.0e-2, "How quickly a blade follows the wind: the torque at which it "
       "closes the gap to its pose in the wind at the reference rate (gamma of eq 26)", unit="N*m", minimum=1e-7,
       maximum=10.0, soft_max=0.05, advanced=True, label="Response"),
    _p("blade", "twist_stiffness", "float", 0.6, "Resistance to twisting, as a fraction of the bending stiffness",
       unit="x bending", minimum=0.01, maximum=10.0, advanced=True, label="Twist"),
    _p("blade", "damping_mass", "float", 1.5, "How quickly a swaying blade comes to rest through the air's drag "
       "(alpha of eq 31: C = alpha M + beta K)", unit="1/s", minimum=0.0, maximum=100.0, soft_max=10.0,
       advanced=True, label="Air Damping"),
    _p("blade", "air_damping", "float", 0.3, "How strongly the wind's drag damps a swaying blade, as a share of "
       "the quasi-steady drag's 2 F / v (1: all of it, a blade that follows the gusts without a sway of its own; "
       "0: the paper's eq 31 alone). Measured grasses sway at their natural frequency (0.8-2.5 Hz) in wind",
       minimum=0.0, maximum=2.0, advanced=True, label="Drag Damp."),
    _p("blade", "damping_stiffness", "float", 0.004, "Damping by the blade's own material, growing with its "
       "stiffness (beta of eq 31)", unit="s", minimum=0.0, maximum=1.0, soft_max=0.05,
       advanced=True, label="Inner Damp."),
    _p("blade", "boundary_k", "float", 0.0, "Bend beyond which a blade starts to sway freely around its pose in the "
       "wind (k of eq 28)", minimum=0.0, maximum=3.0, advanced=True, label="Free Sway"),
    _p("blade", "boundary_lambda", "float", 20.0, "How fast the free sway grows past that bend (lambda of eq 28)",
       minimum=0.0, maximum=100.0, advanced=True, label="Sway Rate"),
    _p("blade", "dry_tips", "float", 0.0, "Share of the blades whose tips have dried to straw", unit="fraction",
       minimum=0.0, maximum=1.0, label="Dry Tips"),
    _p("blade", "species", "table_list", (), "Grass species mixed by their shares; none: one default species",
       fields=SPECIES_FIELDS, label="Species"),
    # --- [wind] paper IV, eqs 12-13 --------------------------------------------------------------
    _p("wind", "type", "enum", "gentle_breeze", "Kind of wind (paper IV): calm, a gentle or moderate breeze, a blast "
       "of gust fronts, a whirlwind", choices=WIND_TYPES, label="Type"),
    _p("wind", "speed", "float", 4.4, "Mean wind speed (a wind preset sets it)", unit="m/s", minimum=0.0, maximum=60.0,
       soft_max=20.0, label="Speed"),
    _p("wind", "direction", "float", 30.0, "Direction the wind blows towards, counter-clockwise from +X", unit="deg",
       minimum=-3600.0, maximum=3600.0, soft_min=-180.0, soft_max=360.0, label="Direction"),
    _p("wind", "turbulence", "float", 1.2, "How gusty the wind is: the spread of the turbulent wind around its mean "
       "(standard deviation of v', eq 12)", unit="m/s", minimum=0.0, maximum=30.0, soft_max=8.0, label="Gustiness"),
    _p("wind", "turbulence_scale", "float", 0.4, "Size of a gust patch (edge a of a turbulence unit, eq 13; the "
       "paper uses one cell): 0.4 m gives eddies a few metres long, which pass the grass in a light breeze at "
       "about its own sway frequency", unit="m", minimum=0.01, maximum=100.0, soft_max=10.0, advanced=True,
       label="Gust Size"),
    _p("wind", "turbulence_period", "float", 1.5, "Seconds between independent gust patterns", unit="s", minimum=0.05,
       maximum=600.0, soft_max=10.0, advanced=True, label="Gust Period"),
    _p("wind", "gust_speed", "float", 9.0, "Blast: extra speed at the centre of a gust front", unit="m/s", minimum=0.0,
       maximum=60.0, soft_max=25.0, applies_when=("type", "blast"), label="Gust Speed"),
    _p("wind", "gust_width", "float", 6.0, "Blast: width of a gust front", unit="m", minimum=0.1, maximum=1000.0,
       soft_max=50.0, applies_when=("type", "blast"), label="Gust Width"),
    _p("wind", "gust_interval", "float", 6.0, "Blast: seconds between gust fronts", unit="s", minimum=0.5,
       maximum=3600.0, soft_max=60.0, applies_when=("type", "blast"), label="Interval"),
    _p("wind", "vortex_radius", "float", 3.0, "Whirlwind: radius of the vortex's core", unit="m", minimum=0.1,
       maximum=1000.0, soft_max=30.0, applies_when=("type", "whirlwind"), label="Core Radius"),
    _p("wind", "vortex_speed", "float", 9.0, "Whirlwind: fastest swirl, at the core's radius", unit="m/s", minimum=0.0,
       maximum=60.0, soft_max=30.0, applies_when=("type", "whirlwind"), label="Swirl Speed"),
    _p("wind", "gust_waves", "float", 0.0, "Gust waves: patches of stronger and weaker wind, tens of metres wide, "
       "carried downwind; the mean wind's speed varies by up to this share, and the cards and the far field "
       "brighten and darken with them to the horizon (0: none)", unit="fraction", minimum=0.0, maximum=1.0,
       label="Gust Waves"),
    _p("wind", "gust_wave_size", "float", 30.0, "Size of a gust wave's patch", unit="m", minimum=2.0,
       maximum=1000.0, soft_max=200.0, advanced=True, label="Wave Size"),
    _p("wind", "gust_stretch", "float", 2.5, "How many times longer a gust wave's patch is across the wind than along "
       "it: 1, round patches; more, bands across the wind, as gusts are seen sweeping over a meadow", minimum=1.0,
       maximum=10.0, soft_max=5.0, advanced=True, label="Stretch"),
    _p("wind", "keys", "table_list", (), "Changes of the mean wind's speed and direction over time",
       fields=WIND_KEY_FIELDS, label="Keys"),
    # --- [lod] paper III.D, eqs 7-11 -------------------------------------------------------------
    _p("lod", "enabled", "bool", True, "Blades near the view, cards further out, the canopy far away (paper III.D); "
       "off: every blade is geometry", label="Enabled"),
    _p("lod", "blade_near", "float", 6.0, "Distance where blades start giving way to cards (d_g1, eq 7)", unit="m",
       minimum=0.0, maximum=10000.0, soft_max=100.0, label="Blades Fade"),
    _p("lod", "blade_far", "float", 12.0, "Distance beyond which no blade is drawn (d_g2, eq 7)", unit="m",
       minimum=0.0, maximum=10000.0, soft_max=100.0, label="Blades End"),
    _p("lod", "card_near", "float", 25.0, "Distance where cards start giving way to the far canopy (d_s1, eq 10)",
       unit="m", minimum=0.0, maximum=10000.0, soft_max=300.0, label="Cards Fade"),
    _p("lod", "card_far", "float", 40.0, "Distance beyond which no card is drawn (d_s2, eq 10)", unit="m", minimum=0.0,
       maximum=10000.0, soft_max=300.0, label="Cards End"),
    _p("lod", "screen_size", "bool", True, "Scale the four distances by how large a blade is on screen: they are "
       "right for an image 960 pixels wide at 55 degrees; a larger image or a longer lens draws blades and cards "
       "further out (up to 4 times, as far as the field's pools hold), so a 4K frame or a telephoto shot keeps the "
       "detail a person sees", label="Screen Size"),
    _p("lod", "viewport_amount", "float", 1.0, "Share of the near blades the 3D viewport draws (as Blender's "
       "particle Viewport Display Amount): fewer keep playback smooth on a large field; renders always draw every "
       "blade", unit="fraction", minimum=0.01, maximum=1.0, label="Viewport"),
    _p("lod", "card_width", "float", 1.6, "Width of a card in cells (above 1 cards overlap their neighbours)",
       unit="cells", minimum=0.1, maximum=10.0, advanced=True, label="Card Width"),
    _p("lod", "card_height", "float", 1.0, "Height of a card as a fraction of its cell's tallest blade at rest",
       unit="fraction", minimum=0.05, maximum=5.0, advanced=True, label="Card Height"),
    # --- [terrain] the ground of batch renders (in Blender: the field's terrain mesh) -----------------
    _p("terrain", "heightmap", "str", "", "Hills under the grass: a greyscale PNG over the extent, black the lowest "
       "ground, white terrain.height above it; empty: flat (in Blender a terrain mesh rules)", label="Heightmap",
       path=True),
    _p("terrain", "height", "float", 10.0, "How high the heightmap's white stands above its black", unit="m",
       minimum=0.0, maximum=10000.0, soft_max=200.0, label="Height"),
    _p("terrain", "extent", "vec", (0.0, 0.0, 0.0, 0.0), "The rectangle the heightmap covers, [x0, y0, x1, y1]; "
       "all 0: the field's extent", unit="m", minimum=-1e5, maximum=1e5, size=4, label="Extent",
       components=EXTENT_CORNERS),
    # --- [paint] where grass grows and how tall (paint.py) -------------------------------------------
    _p("paint", "density", "str", "", "Where grass grows: a map of the share of blades that grow (white: all, "
       "black: none). " + MAP_SOURCES, label="Density", path=True),
    _p("paint", "length", "str", "", "How long the grass grows: a map of the blades' length (mid grey: as grown, "
       "black: mown away, white: twice as long). " + MAP_SOURCES, label="Length", path=True),
    _p("paint", "extent", "vec", (0.0, 0.0, 0.0, 0.0), "The rectangle the map files cover, [x0, y0, x1, y1]; "
       "all 0: the field's extent", unit="m", minimum=-1e5, maximum=1e5, size=4, label="Extent",
       components=EXTENT_CORNERS),
    # --- [keep_out] footprints where nothing grows (houses, rocks, paths) ----------------------------
    _p("keep_out", "margin", "float", 0.1, "Bare ground kept around every footprint", unit="m", minimum=0.0,
       maximum=1000.0, soft_max=5.0, label="Margin"),
    _p("keep_out", "falloff", "float", 0.3, "Beyond the margin the grass thins back in over this distance", unit="m",
       minimum=0.0, maximum=1000.0, soft_max=10.0, label="Falloff"),
    _p("keep_out", "shapes", "table_list", (), "Boxes and discs where nothing grows (in Blender also the objects "
       "of the field's keep-out collection)", fields=KEEP_OUT_FIELDS, label="Shapes", maximum=256),
    # --- [interaction] colliders and force fields (interaction.py, forces.py) ------------------------
    _p("interaction", "recovery", "float", 4.0, "How long trampled grass takes to stand up again (it rises "
       "slowly, then sways back as the paper's blades recover)", unit="s", minimum=0.1, maximum=600.0,
       soft_max=60.0, label="Recovery"),
    _p("interaction", "tolerance", "float", 0.01, "How far a blade tip may reach into a collider", unit="m",
       minimum=0.0, maximum=1.0, soft_max=0.1, advanced=True, label="Tolerance"),
    _p("interaction", "colliders", "table_list", (), "Spheres and capsules moving along keyed paths (in Blender: "
       "the objects of the field's Colliders collection)", fields=COLLIDER_FIELDS, label="Colliders",
       blender=False),
    _p("interaction", "effectors", "table_list", (), "Force fields that add to the wind (in Blender: the force "
       "fields of the field's Force Fields collection)", fields=EFFECTOR_FIELDS, label="Force Fields",
       blender=False, maximum=32),
    # --- [camera] headless renders and LOD without a Blender camera ---------------------------------
    _p("camera", "mode", "enum", "flythrough", "Fly over the field (the paper's tests) or a fixed view",
       choices=("flythrough", "fixed"), label="Mode"),
    _p("camera", "height", "float", 1.6, "Eye height above the ground", unit="m", minimum=0.05, maximum=10000.0,
       soft_max=50.0, label="Height"),
    _p("camera", "fov", "float", 55.0, "Horizontal field of view", unit="deg", minimum=1.0, maximum=170.0,
       label="View Angle"),
    _p("camera", "speed", "float", 1.2, "Flythrough: speed along the path", unit="m/s", minimum=0.0, maximum=1000.0,
       soft_max=20.0, applies_when=("mode", "flythrough"), label="Speed"),
    _p("camera", "position", "vec", (0.0, -6.0, 1.6), "Fixed view: camera position (the field's centre is 0, 0)",
       unit="m", minimum=-1e5, maximum=1e5, size=3, applies_when=("mode", "fixed"), label="Position"),
    _p("camera", "target", "vec", (0.0, 4.0, 0.2), "Fixed view: the point the camera looks at", unit="m", minimum=-1e5,
       maximum=1e5, size=3, applies_when=("mode", "fixed"), label="Target"),
    # --- [render] ------------------------------------------------------------------------------
    _p("render", "engine", "enum", "cycles", "Render engine", choices=("cycles", "eevee"), label="Engine"),
    _p("render", "samples", "int", 16, "Samples per pixel", minimum=1, maximum=65536, soft_max=512, label="Samples"),
    _p("render", "resolution_x", "int", 640, "Image width", unit="px", minimum=16, maximum=16384, label="Width"),
    _p("render", "resolution_y", "int", 360, "Image height", unit="px", minimum=16, maximum=16384,
       label="Height"),
    _p("render", "fps", "int", 24, "Frames per second of the animation and of the simulation", minimum=1, maximum=240,
       label="Frame Rate"),
    _p("render", "fps_base", "float", 1.0, "Frame rate base: the frame rate is fps / fps_base (1.001 gives "
       "29.97 fps from 30), as Blender's", minimum=0.5, maximum=2.0, label="Base"),
    _p("render", "frame_start", "int", 1, "First frame", minimum=0, maximum=1_000_000, label="Frame Start"),
    _p("render", "frame_end", "int", 48, "Last frame", minimum=0, maximum=1_000_000, label="Frame End"),
    _p("render", "motion_blur", "bool", False, "Blur the grass (and the camera) along its simulated motion; in "
       "Blender the scene's own motion blur setting rules", label="Motion Blur"),
    _p("render", "shutter", "float", 0.5, "Motion blur shutter time, in frames", minimum=0.01, maximum=2.0,
       label="Shutter"),
    _p("render", "sun_elevation", "float", 35.0, "Sun elevation above the horizon", unit="deg", minimum=-10.0,
       maximum=90.0, label="Sun Height"),
    _p("render", "sun_azimuth", "float", 140.0, "Sun azimuth, counter-clockwise from +X", unit="deg", minimum=-360.0,
       maximum=360.0, label="Sun Turn"),
    _p("render", "haze_distance", "float", 0.0, "Aerial perspective: grass this far away shows 63 % haze (1 - 1/e); "
       "0: no haze", unit="m", minimum=0.0, maximum=1e6, soft_max=10000.0, label="Haze"),
    _p("render", "haze_color", "vec", (1.5, 1.5, 1.45), "Aerial perspective: the haze's radiance (linear RGB), about "
       "the sky's at the horizon", minimum=0.0, maximum=100.0, size=3, soft_max=5.0, label="Haze Color"),
    # --- [simulation] --------------------------------------------------------------------------------
    _p("simulation", "sub_steps", "int", 1, "Solver steps per frame at least (Windgrass adds more where stiff blades "
       "need them to stay stable)", minimum=1, maximum=64, advanced=True, label="Substeps"),
    _p("simulation", "preroll", "float", 3.0, "Seconds each stretch of simulation runs from rest before it is shown",
       unit="s", minimum=0.5, maximum=600.0, soft_max=10.0, label="Warm-up"),
    _p("simulation", "loop", "float", 0.0, "Seconds after which the wind, and so every blade, repeats exactly "
       "(0: never): a cycle to render or bake once and play in a loop (a whole number of frames; at least "
       "simulation.preroll)", unit="s", minimum=0.0, maximum=3600.0, soft_max=60.0, label="Loop"),
    _p("simulation", "epoch", "float", 6.0, "Seconds between the starts of the simulated stretches: any frame is at "
       "most warm-up + epoch seconds of simulation away", unit="s", minimum=0.5, maximum=1e6, soft_max=60.0,
       advanced=True, label="Epoch"),
    _p("simulation", "cache_mb", "int", 1024, "Memory for the blocks kept around the camera", unit="MB", minimum=16,
       maximum=1_000_000, advanced=True, label="Cache"),
    _p("simulation", "memory_mb", "int", 4096, "Memory a field may take in Blender in all (its meshes, simulation and "
       "blocks, and a render's copy of the meshes); settings that need more are refused, naming what fits",
       unit="MB", minimum=256, maximum=1_000_000, label="Memory"),
)

SECTIONS: tuple[str, ...] = tuple(dict.fromkeys(p.section for p in PARAMS))

# The layout of the settings a .blend keeps (its fields' properties): raised when a setting changes
# its meaning or unit, with an entry in ``bridge.properties.UPGRADES`` that brings an older file's
# settings to it, so a file saved by an earlier Windgrass opens with its grass as it was.
SETTINGS_VERSION = 2
BY_NAME: dict[str, Param] = {p.name: p for p in PARAMS}


# --------------------------------------------------------------------------------------------
# Views: what an artist decides, in their words, read from and written into the parameters above


@dataclass(frozen=True)
class View:
    """An artist's handle on some parameters of one section: ``read`` gives its value from their
    values, ``write`` the values that give it (the nearest the parameters can hold: a field is whole
    blocks, a cell whole blades). Never stored: the parameters are. Blender shows views first (the
    parameters go to the Advanced panel); scene files and flags take them as well."""

    param: Param  # its name, unit, range, label and help
    uses: tuple[str, ...]  # the keys of its section it writes (the first) and reads
    read: Callable[[Mapping[str, Any]], float]
    write: Callable[[Mapping[str, Any], float], dict[str, Any]]
    digits: int = 2  # decimals shown


def _block_metres(f: Mapping[str, Any]) -> float:
    return f["cells_per_block"] * f["cell_size"]


def _size_view(axis: str) -> View:
    key = f"blocks_{axis}"
    top = BY_NAME[f"field.{key}"].maximum
    assert top is not None  # (a field's blocks are bounded)
    return View(
        _p("field", f"size_{axis}", "float", 0.0, f"Size of the field along {axis.upper()}: whole blocks of cells per "
           "block x cell size (Advanced), the nearest to the size asked", unit="m", minimum=0.01,
           maximum=MAX_FIELD_EXTENT, soft_max=500.0, label=f"Size {axis.upper()}"),
        (key, "cells_per_block", "cell_size"),
        lambda f: f[key] * _block_metres(f),
        lambda f, v: {key: int(min(max(math.floor(v / _block_metres(f) + 0.5), 1), top))},
        digits=4)  # (Blender writes lengths with units to this many significant digits: 51.2 m)


# Stiffness felt: 0 is a blade of 1e-4 N*m^2/rad at its root (lies down in a breeze), 1 one of 1e-2
# (hardly moves in a gale), spaced evenly in log(mu_root): the default 8e-4 reads 0.45.
STIFFNESS_FEEL = (1e-4, 1e-2)


def _feel(f: Mapping[str, Any]) -> float:
    low, high = STIFFNESS_FEEL
    return min(max(math.log(f["root_stiffness"] / low) / math.log(high / low), 0.0), 1.0)


def _felt(f: Mapping[str, Any], v: float) -> dict[str, Any]:
    low, high = STIFFNESS_FEEL
    return {"root_stiffness": float(f"{low * (high / low) ** min(max(v, 0.0), 1.0):.3g}")}


VIEWS: tuple[View, ...] = (
    _size_view("x"),
    _size_view("y"),
    View(_p("field", "density", "float", 0.0, "Blades per square metre: whole blades per cell over the cell's "
            "area (Advanced), the nearest to the density asked", unit="1/m^2", minimum=0.0, maximum=1e6,
            soft_max=3000.0, label="Blades"),
         ("blades_per_cell", "cell_size"),
         lambda f: f["blades_per_cell"] / f["cell_size"] ** 2,
         lambda f, v: {"blades_per_cell": int(min(max(math.floor(v * f["cell_size"] ** 2 + 0.5), 0),
                                                   BY_NAME["field.blades_per_cell"].maximum))},
         digits=0),
    View(_p("blade", "stiffness", "float", 0.0, "How stiff the blades feel, 0 (they lie down in a breeze) to 1 (they "
            "hardly move in a gale); sets the root stiffness (Advanced)", unit="fraction", minimum=0.0, maximum=1.0,
            label="Stiffness"),
         ("root_stiffness",), _feel, _felt),
)
VIEW_BY_NAME: dict[str, View] = {v.param.name: v for v in VIEWS}


def named(name: str) -> Param:
    """The parameter or the view (its Param) called ``name`` ("field.size_x")."""
    return BY_NAME[name] if name in BY_NAME else VIEW_BY_NAME[name].param


def section_views(section: str) -> tuple[View, ...]:
    return tuple(v for v in VIEWS if v.param.section == section)


def section_params(section: str) -> tuple[Param, ...]:
    return tuple(p for p in PARAMS if p.section == section)


def blender_params(section: str) -> tuple[Param, ...]:
    """The section's parameters that are Blender properties (not those of scene files only)."""
    return tuple(p for p in PARAMS if p.section == section and p.blender)


# --------------------------------------------------------------------------------------------
# Values


if TYPE_CHECKING:
    from .params_typed import BladeSpeciesRow
    from .params_typed import Sections as _Sections
else:
    _Sections = object


class Section:
    """Read-only view of one section: ``params.wind.speed``."""

    __slots__ = ("_name", "_values")

    def __init__(self, name: str, values: Mapping[str, Any]):
        object.__setattr__(self, "_name", name)
        object.__setattr__(self, "_values", dict(values))

    def __getattr__(self, key: str) -> Any:
        try:
            return self._values[key]
        except KeyError:
            raise AttributeError(f"no parameter {self._name}.{key}") from None

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("Params are read-only; use Params.replace()")

    def as_dict(self) -> dict[str, Any]:
        return dict(self._values)


class Params(_Sections):
    """A complete, validated parameter set. Immutable; ``replace`` returns a new one. Its sections
    are typed for mypy (``params_typed.py``)."""

    def __init__(self, values: Mapping[str, Mapping[str, Any]]):
        self._values = {s: dict(values[s]) for s in SECTIONS}
        self._sections = {s: Section(s, self._values[s]) for s in SECTIONS}

    def __getattr__(self, section: str) -> Section:
        sections = self.__dict__.get("_sections")
        if sections is None or section not in sections:
            raise AttributeError(section)
        return sections[section]

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Params) and self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash(self.digest())

    def __repr__(self) -> str:
        return f"Params({self.digest()[:10]})"

    def get(self, name: str) -> Any:
        section, key = name.split(".", 1)
        return self._values[section][key]

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """Plain nested dict (lists for vectors and tables): TOML- and JSON-ready."""
        return {s: {k: _plain(v) for k, v in vals.items()} for s, vals in self._values.items()}

    def digest(self) -> str:
        """Stable hash of every value: the key of caches (state is f(params, seed, frame))."""
        text = json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha1(text.encode()).hexdigest()

    def replace(self, overrides: Mapping[str, Any] | None = None, **dotted: Any) -> Params:
        """New validated Params with ``{"wind.speed": 5.0}`` style overrides applied."""
        changes = {**(overrides or {}), **{k.replace("__", "."): v for k, v in dotted.items()}}
        if changes.get("wind.type", self.wind.type) != self.wind.type:
            # a new wind type brings its preset speed and turbulence unless those are given too
            changes = {**wind_preset(changes["wind.type"]), **changes}
        elif "wind.type" in changes:
            del changes["wind.type"]  # the same type keeps the speed and turbulence as they are
        nested: dict[str, dict[str, Any]] = {}
        for name, value in changes.items():
            if "." not in name:
                raise ParameterError(name, "expected a dotted name such as 'wind.speed'")
            section, key = name.split(".", 1)
            nested.setdefault(section, {})[key] = value
        return from_dict(nested, base=self)

    def species(self) -> tuple[BladeSpeciesRow, ...]:
        """The species table; one default species when the user gave none."""
        rows = self.blade.species
        if rows:
            return rows
        return (cast("BladeSpeciesRow", row_defaults(SPECIES_FIELDS)),)


def _plain(v: Any) -> Any:
    if isinstance(v, tuple):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    return v


def row_defaults(fields: Iterable[Param]) -> dict[str, Any]:
    return {f.key: f.default for f in fields}


def defaults() -> Params:
    return Params({s: {p.key: p.default for p in section_params(s)} for s in SECTIONS})


# --------------------------------------------------------------------------------------------
# Validation


class _Expect:
    """``valid: <range>`` for messages, formatted only when an error is raised (validation runs
    every frame in the add-on)."""

    __slots__ = ("param",)

    def __init__(self, param: Param):
        self.param = param

    def __str__(self) -> str:
        return f"valid: {self.param.range_text()}"

    def __format__(self, spec: str) -> str:
        return format(str(self), spec)


def _check_value(p: Param, value: Any, name: str | None = None) -> Any:
    """Return ``value`` converted to the parameter's type, or raise ParameterError."""
    name = name or p.name
    expect = _Expect(p)
    if p.kind == "bool":
        if not isinstance(value, bool):
            raise ParameterError(name, f"{shown(value)} is not true/false ({expect})")
        return value
    if p.kind == "str":
        if not isinstance(value, str):
            raise ParameterError(name, f"{shown(value)} is not a text string")
        return value
    if p.kind == "keys":
        return _check_keys(value, name)
    if p.kind == "enum":
        if not isinstance(value, str) or value not in p.choices:
            raise ParameterError(name, f"unknown value {shown(value)} ({expect})")
        return value
    if p.kind == "vec":
        if not isinstance(value, (list, tuple)) or len(value) != p.size:
            raise ParameterError(name, f"{shown(value)} is not a list of {p.size} numbers (each {p.range_text()})")
        return tuple(_check_number(p, v, f"{name}[{i}]", float) for i, v in enumerate(value))
    if p.kind == "table_list":
        if isinstance(value, dict):
            value = [value]
        if not isinstance(value, (list, tuple)):
            raise ParameterError(name, f"{shown(value)} is not a list of tables ([[{name}]] in TOML)")
        if p.maximum is not None and len(value) > p.maximum:
            raise ParameterError(name, f"{len(value)} rows; valid: at most {int(p.maximum)} (each costs every frame "
                                 "of every cell it reaches)")
        return tuple(_check_row(p, row, f"{name}[{i}]") for i, row in enumerate(value))
    return _check_number(p, value, name, int if p.kind == "int" else float)


_KEY_TIME = Param("", "time", "float", 0.0, "", unit="s", minimum=-1e7, maximum=1e7)
_KEY_POSITION = Param("", "position", "vec", (0.0, 0.0, 0.0), "", unit="m", minimum=-1e5, maximum=1e5, size=3)


def _check_keys(value: Any, name: str) -> tuple[dict[str, Any], ...]:
    """A keyed path: at least two ``{time, position}`` tables with increasing times."""
    if not isinstance(value, (list, tuple)):
        raise ParameterError(name, f"{shown(value)} is not a list of {{time = s, position = [x, y, z]}} keys")
    keys = []
    for i, key in enumerate(value):
        if not isinstance(key, Mapping) or set(key) != {"time", "position"}:
            raise ParameterError(f"{name}[{i}]", f"{shown(key)} is not a key {{time = s, position = [x, y, z]}}")
        keys.append({"time": _check_value(_KEY_TIME, key["time"], f"{name}[{i}].time"),
                     "position": _check_value(_KEY_POSITION, key["position"], f"{name}[{i}].position")})
    if len(keys) < 2:
        raise ParameterError(name, f"{len(keys)} key(s); a path needs at least 2 (time, position) keys")
    times = [k["time"] for k in keys]
    if any(b <= a for a, b in zip(times, times[1:])):
        raise ParameterError(name, f"times {times} are not increasing; each key's time must be later than "
                                   "the one before")
    return tuple(keys)


def _check_number(p: Param, value: Any, name: str, kind: type) -> float | int:
    expect = _Expect(p)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        what = "a whole number" if kind is int else "a number"
        raise ParameterError(name, f"{shown(value)} is not {what} ({expect})")
    if kind is int and isinstance(value, float):
        if not math.isfinite(value) or value != int(value):
            raise ParameterError(name, f"{shown(value)} is not a whole number ({expect})")
        value = int(value)
    if isinstance(value, float) and not math.isfinite(value):
        raise ParameterError(name, f"{shown(value)} is not a finite number ({expect})")
    if (p.minimum is not None and value < p.minimum) or (p.maximum is not None and value > p.maximum):
        raise ParameterError(name, f"{shown(value)} is out of range ({expect})")
    return kind(value)


def _check_row(p: Param, row: Any, name: str) -> dict[str, Any]:
    if not isinstance(row, Mapping):
        raise ParameterError(name, f"{shown(row)} is not a table")
    columns = {f.key: f for f in p.fields}
    for key in row:
        if key not in columns:
            raise ParameterError(f"{name}.{key}", f"unknown key (valid keys: {', '.join(columns)})")
    out = row_defaults(p.fields)
    for key, value in row.items():
        out[key] = _check_value(columns[key], value, f"{name}.{key}")
    return out


def from_dict(data: Mapping[str, Any], base: Params | None = None) -> Params:
    """Validate a nested dict (as read from TOML) on top of ``base`` (defaults if None)."""
    if not isinstance(data, Mapping):
        raise ParameterError("", f"expected a table of sections, got {type(data).__name__}")
    values = (base or defaults()).to_dict()
    data = _lift_tables(data)
    for section, entries in data.items():
        if section not in SECTIONS:
            raise ParameterError(section, f"unknown section [{section}] (valid: {', '.join(SECTIONS)})")
        if not isinstance(entries, Mapping):
            raise ParameterError(section, f"[{section}] must be a table of key = value lines")
        known = {p.key: p for p in section_params(section)}
        views = {v.param.key: v for v in section_views(section)}
        for key, value in entries.items():
            if key not in known and key not in views:
                raise ParameterError(f"{section}.{key}",
                                     f"unknown key in [{section}] (valid keys: {', '.join([*known, *views])})")
            if key in known:
                values[section][key] = _check_value(known[key], value)
        for key, view in views.items():  # after the parameters they read (cell size, ...)
            if key in entries:
                values[section].update(_apply_view(view, entries, values[section]))
        if section == "wind" and "type" in entries:
            for key, value in WIND_TYPE_PRESETS[values["wind"]["type"]].items():
                if key not in entries:
                    values["wind"][key] = value
    # Lists come back from to_dict() as lists; normalise every value through the checker once.
    checked = {s: {p.key: _check_value(p, values[s][p.key]) for p in section_params(s)} for s in SECTIONS}
    _check_relations(checked)
    return Params(checked)


def _apply_view(view: View, entries: Mapping[str, Any], values: Mapping[str, Any]) -> dict[str, Any]:
    """The parameter values that give ``view`` the value ``entries`` asks for. A view made of whole
    things (blocks, blades per cell) takes the nearest it can hold; asked for more or less than its
    parameter's range holds, it says so (``density = 1`` would be a field without a blade)."""
    p = view.param
    given = [key for key in view.write(values, view.read(values)) if key in entries]
    if given:
        raise ParameterError(p.name, f"given with {p.section}.{given[0]}, which it sets: give one of them")
    asked = _check_value(p, entries[p.key])
    out = view.write(values, asked)
    whole = BY_NAME[f"{p.section}.{view.uses[0]}"]
    if whole.kind == "int" and whole.minimum is not None and whole.maximum is not None:
        lo, hi = (view.read({**values, view.uses[0]: n}) for n in (whole.minimum, whole.maximum))
        step = view.read({**values, view.uses[0]: whole.minimum + 1}) - lo
        if not lo - step / 2 <= asked <= hi + step / 2 or (asked > 0 and view.read({**values, **out}) == 0):
            unit = f" {p.unit}" if p.unit else ""
            reads = ", ".join(f"{p.section}.{k} = {_fmt(values[k])}" for k in view.uses[1:])
            top = hi if p.maximum is None else min(hi, p.maximum)
            valid = f"{_fmt(max(lo, step))} to {_fmt(top)}{unit}{' (or 0)' if lo == 0 else ''}"
            raise ParameterError(p.name, f"{_fmt(asked)}{unit} cannot be made of whole {whole.key.split('_')[0]} "
                                 f"({whole.name}) with {reads}: valid {valid}")
    return out


def check_flags(flags: Mapping[str, Any]) -> None:
    """Each of ``{"wind.speed": 5.0}`` in its parameter's (or view's) own range, on its own."""
    for name, value in flags.items():
        _check_value(named(name), value, name)


def merge_flags(data: Mapping[str, Any], flags: Mapping[str, Any]) -> dict[str, Any]:
    """A scene file's sections with command-line ``flags`` ({"field.cell_size": 0.2}) put in, as if
    the file said them: a flag replaces the file's key and any view that sets the same parameter
    (``--field-blocks-x`` replaces ``size_x``), and a view the file gives keeps its meaning in the
    flag's terms (``size_x = 20`` stays 20 m with ``--field-cell-size 0.2``)."""
    out = {k: (dict(v) if isinstance(v, Mapping) else v) for k, v in _lift_tables(data).items()}
    for name, value in sorted(flags.items(), key=lambda kv: kv[0] != "wind.type"):  # (a type before its speed)
        section, key = name.split(".", 1)
        entries = out.setdefault(section, {})
        if not isinstance(entries, dict):
            continue  # (from_dict reports the file's section that is no table)
        if name == "wind.type" and value != entries.get("type", BY_NAME["wind.type"].default):
            # (another wind type brings its preset speed and turbulence, as in Params.replace)
            for k in WIND_TYPE_PRESETS[value] if value in WIND_TYPE_PRESETS else ():
                entries.pop(k, None)
        view = VIEW_BY_NAME.get(name)
        sets = {view.uses[0]} if view else {key}
        for other in section_views(section):
            if other.uses[0] in sets:
                entries.pop(other.param.key, None)
        for k in sets:
            entries.pop(k, None)
        entries[key] = value
    return out


TOP_LEVEL_TABLES = {"colliders": "interaction", "effectors": "interaction"}  # [[colliders]] = [[interaction.colliders]]


def _lift_tables(data: Mapping[str, Any]) -> dict[str, Any]:
    """A scene file's top-level ``[[colliders]]`` and ``[[effectors]]`` into their section."""
    out = {k: v for k, v in data.items() if k not in TOP_LEVEL_TABLES}
    for key, section in TOP_LEVEL_TABLES.items():
        if key in data:
            entries = dict(out.get(section) or {}) if isinstance(out.get(section, {}), Mapping) else out[section]
            if isinstance(entries, dict):
                if key in entries:
                    raise ParameterError(key, f"given twice: as [[{key}]] and as [[{section}.{key}]]")
                entries[key] = data[key]
            out[section] = entries
    return out


def _check_relations(v: Mapping[str, Mapping[str, Any]]) -> None:
    """Constraints between parameters, each reported with the parameter that breaks it."""
    f, lod = v["field"], v["lod"]
    for axis in ("x", "y"):
        extent = f[f"blocks_{axis}"] * f["cells_per_block"] * f["cell_size"]
        if extent > MAX_FIELD_EXTENT * (1.0 + 1e-9):
            limit = int(MAX_FIELD_EXTENT / (f["cells_per_block"] * f["cell_size"]) + 1e-9)
            raise ParameterError(
                f"field.blocks_{axis}",
                f"the field would be {extent:,.0f} m long along {axis.upper()}; float32 vertex positions keep "
                f"millimetre precision up to {MAX_FIELD_EXTENT:,.0f} m (valid: 1 to {limit:,} blocks of "
                f"{f['cells_per_block'] * f['cell_size']:g} m)")
    order = ("blade_near", "blade_far", "card_near", "card_far")
    for a, b in zip(order, order[1:]):
        if lod[b] < lod[a]:
            raise ParameterError(f"lod.{b}", f"{lod[b]:g} m must be >= lod.{a} ({lod[a]:g} m): "
                                 "valid: blade_near <= blade_far <= card_near <= card_far")
    sim = v["simulation"]
    if 0.0 < sim["loop"] < sim["preroll"]:
        raise ParameterError("simulation.loop", f"{sim['loop']:g} s is shorter than the solver's warm-up "
                             f"(simulation.preroll, {sim['preroll']:g} s), so the loop could not repeat it; valid: 0 "
                             f"(no loop) or at least {sim['preroll']:g} s (or a shorter warm-up)")
    if sim["epoch"] < sim["preroll"]:
        raise ParameterError("simulation.epoch", f"{sim['epoch']:g} s must be >= simulation.preroll "
                             f"({sim['preroll']:g} s)")
    r = v["render"]
    if not 1.0 <= r["fps"] / r["fps_base"] <= 240.0:
        raise ParameterError("render.fps_base", f"{r['fps']} / {r['fps_base']:g} is {r['fps'] / r['fps_base']:.4g} "
                             "fps (valid: a frame rate of 1 to 240 fps)")
    if r["frame_end"] < r["frame_start"]:
        raise ParameterError("render.frame_end",
                             f"{r['frame_end']} is before render.frame_start ({r['frame_start']})")
    species = v["blade"]["species"]
    if species and sum(s["weight"] for s in species) <= 0:
        raise ParameterError("blade.species", "the species weights add up to 0; give one a weight > 0")
    times = [k["time"] for k in v["wind"]["keys"]]
    if any(b <= a for a, b in zip(times, times[1:])):
        raise ParameterError("wind.keys", f"key times {times} must increase strictly")


# --------------------------------------------------------------------------------------------
# TOML and command line


MAX_SCENE_BYTES = 4 << 20  # a scene file of more is not one (the longest in scenes/ has a few KB)
MAX_KEY_DEPTH = 16  # parts of one dotted key or table name (the schema's deepest has 3)


def load_toml(path: str | Path, base: Params | None = None, flags: Mapping[str, Any] | None = None) -> Params:
    """Read a scene file; every problem is a ParameterError naming the file and the key. Only a
    regular file of at most MAX_SCENE_BYTES is read (a pipe would wait forever, a device never end)."""
    path = Path(path)
    try:
        info = path.stat()
    except OSError as exc:
        raise ParameterError("config", f"cannot read {path}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(info.st_mode):
        raise ParameterError("config", f"{path} is a folder, not a TOML scene file")
    if not stat.S_ISREG(info.st_mode):
        raise ParameterError("config", f"{path} is not a regular file (a pipe or a device); valid: a TOML scene file")
    if info.st_size > MAX_SCENE_BYTES:
        raise ParameterError("config", f"{path} has {info.st_size:,} bytes; a scene file has at most "
                             f"{MAX_SCENE_BYTES:,}")
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_SCENE_BYTES + 1)
        text = raw.decode("utf-8")
    except OSError as exc:
        raise ParameterError("config", f"cannot read {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise ParameterError("config", f"{path} is not UTF-8 text (a TOML scene file is UTF-8; "
                             "binary files and UTF-16 cannot be read)") from None
    return loads_toml(text, base, source=str(path), folder=path.resolve().parent, flags=flags)


# TOML's lexical pieces, each matched in time linear in its length (no nested repetition that can
# backtrack): a comment or a string is one token, so a dot inside it is no key part; a dotted key
# is a run of parts (bare words, quoted names) joined by dots. A float (1.5) counts as two parts:
# the count is an upper bound.
_TOML_TOKENS = re.compile(r'''
    (?P<comment>\#[^\n]*)
  | (?P<part>"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:[^"\\\n]+|\\.)*"|'[^'\n]*'|[A-Za-z0-9_\-]+)
  | (?P<dot>[ \t]*\.[ \t]*)
  | (?P<other>[^\#"'A-Za-z0-9_\-.]+|.)
''', re.VERBOSE | re.DOTALL)


def _deepest_key(text: str) -> int:
    """The most parts of a dotted key (a table's name, a key, a key inside an inline table) in a
    TOML text: an upper bound, in one pass over its tokens (quoted parts with spaces count too)."""
    deepest = parts = 0
    after_dot = False
    for match in _TOML_TOKENS.finditer(text):
        kind = match.lastgroup
        if kind == "part":
            parts = parts + 1 if after_dot else 1
            after_dot = False
            deepest = max(deepest, parts)
        elif kind == "dot":
            after_dot = parts > 0
        else:
            parts, after_dot = 0, False
    return max(deepest, 1)


def loads_toml(text: str, base: Params | None = None, source: str = "<toml>", folder: Path | None = None,
               flags: Mapping[str, Any] | None = None) -> Params:
    """Params of a scene file's text; ``folder``: where relative file paths in it start (the
    scene file's folder; None: the current folder); ``flags``: command-line values put in first
    (``merge_flags``). Keys dotted deeper than MAX_KEY_DEPTH are
    refused before parsing (Python's TOML parser takes time and memory growing as the depth squared)."""
    if len(text) > MAX_SCENE_BYTES:
        raise ParameterError("config", f"{source} has {len(text):,} characters; a scene file has at most "
                             f"{MAX_SCENE_BYTES:,}")
    depth = _deepest_key(text)
    if depth > MAX_KEY_DEPTH:
        raise ParameterError("config", f"{source} has a key of {depth} dotted parts; a scene file's keys have at "
                             f"most {MAX_KEY_DEPTH} (its settings have 2 or 3, e.g. wind.speed)")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError("config", f"{source} is not valid TOML: {exc}") from None
    except RecursionError:
        raise ParameterError("config", f"{source} nests arrays or tables too deeply to be a scene file") from None
    try:
        if folder is not None:
            _resolve_paths(data, Path(folder))
        return from_dict(merge_flags(data, flags) if flags else data, base)
    except ParameterError as exc:
        raise ParameterError(exc.key, f"{exc.message} (in {source})") from None


def _resolve_paths(data: Any, folder: Path) -> None:
    """File paths of a scene file (``Param.path``) made absolute from ``folder``, in place."""
    _map_paths(data, lambda value, name: _file_path(folder, value, name))


def _map_paths(data: Any, change) -> None:
    """Every file path setting of a scene's sections (``data``, as a TOML file or ``to_dict``
    holds them) replaced by ``change(value, setting's name)``, in place; empty values are kept."""
    if not isinstance(data, Mapping):
        return
    for p in PARAMS:
        section = data.get(p.section)
        if not isinstance(section, dict) or p.key not in section:
            continue
        if p.path and isinstance(section[p.key], str) and section[p.key]:
            section[p.key] = change(section[p.key], p.name)
        if p.kind == "table_list" and isinstance(section[p.key], list):
            for i, row in enumerate(section[p.key]):
                for f in p.fields:
                    if f.path and isinstance(row, dict) and isinstance(row.get(f.key), str) and row[f.key]:
                        row[f.key] = change(row[f.key], f"{p.name}[{i}].{f.key}")


def with_files(params: Params, change) -> Params:
    """``params`` with each file it names (maps, heightmap; not Blender's sources such as
    ``vertex_group:NAME``) replaced by ``change(path, setting's name)``: a scene moved with its
    files (a farm bundle carries them)."""
    data = params.to_dict()
    _map_paths(data, lambda value, name: value if value.startswith(BLENDER_SOURCES) else change(value, name))
    return from_dict(data)


# Map values that name a source inside Blender, not a file (bridge/maps.py): "vertex_group:NAME",
# "attribute:NAME", "image:NAME".
BLENDER_SOURCES = ("vertex_group:", "attribute:", "image:")


def _file_path(folder: Path, value: str, name: str) -> str:
    """A scene file's path ``value`` made absolute from ``folder`` (``~`` expanded); a Blender
    source (``vertex_group:NAME``, ...) is kept; a path no file system has is refused, named."""
    if value.startswith(BLENDER_SOURCES):
        return value
    if "\x00" in value:
        raise ParameterError(name, f"{value!r} holds a NUL character (valid: a file path)")
    try:
        return str((folder / Path(value).expanduser()).resolve())
    except RuntimeError as exc:  # ~user of no such user
        raise ParameterError(name, f"{value}: {exc} (valid: a file path, ~ for your own home folder)") from None
    except (OSError, ValueError) as exc:
        raise ParameterError(name, f"{value} is not a usable path: {exc} (valid: a file path)") from None


def dumps_toml(params: Params) -> str:
    """Write a complete scene file that ``loads_toml`` reads back to equal Params."""
    lines: list[str] = []
    tables: list[str] = []
    for section in SECTIONS:
        lines.append(f"[{section}]")
        for p in section_params(section):
            value = params.get(p.name)
            if p.kind == "table_list":
                for row in value:
                    tables.append(f"\n[[{p.name}]]")
                    tables.extend(f"{k} = {_toml_value(x)}" for k, x in row.items())
                continue
            lines.append(f"{p.key} = {_toml_value(value)}  # {p.help}" + (f" [{p.unit}]" if p.unit else ""))
        lines.append("")
    return "\n".join(lines + tables) + "\n"


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, Mapping):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, float):
        return repr(v)
    return str(v)


# A number on the command line: ASCII digits, an optional sign, point and exponent (5, -2.5, +7, 3.,
# .5, 1e-3); not Python's underscores (1_000) or other scripts' digits, which float() accepts.
_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


def cli_params() -> tuple[Param, ...]:
    """Parameters that have a command-line flag (tables only come from TOML files), views first."""
    return tuple(v.param for v in VIEWS) + tuple(p for p in PARAMS if p.kind != "table_list")


def add_cli_arguments(parser: Any) -> None:
    """Add one ``--section-key`` flag per parameter to an ``argparse`` parser."""
    for section in SECTIONS:
        group = parser.add_argument_group(f"[{section}] parameters")
        for p in [v.param for v in section_views(section)] + list(section_params(section)):
            if p.kind == "table_list":
                continue
            unit = f" [{p.unit}]" if p.unit else ""
            default = "from the settings below" if p.name in VIEW_BY_NAME else _toml_value(_plain(p.default))
            help_text = f"{p.help}{unit}; default {default}; valid {p.range_text()}"
            kw: dict[str, Any] = {"dest": p.name, "default": None, "help": help_text.replace("%", "%%")}
            if p.kind == "bool":
                kw["type"] = _parse_bool
                kw["metavar"] = "BOOL"
            elif p.kind == "enum":
                kw["metavar"] = "{" + ",".join(p.choices) + "}"
            elif p.kind == "vec":
                kw["nargs"] = p.size
                kw["metavar"] = "X"
            elif p.kind == "str":
                kw["metavar"] = "PATH" if p.path else "TEXT"
            else:
                kw["metavar"] = "N" if p.kind == "int" else "X"
            group.add_argument(p.cli_flag, **kw)


def _parse_bool(text: str) -> bool:
    """A flag's true/false; argparse shows the ArgumentTypeError's text after the flag's name."""
    low = text.lower()
    if low in ("1", "true", "yes", "on"):
        return True
    if low in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"{shown(text)} is not true or false (valid: true/false, yes/no, on/off, 1/0)")


def cli_overrides(namespace: Any) -> dict[str, Any]:
    """``{"wind.speed": 5.0}`` for every flag the user gave, parsed to the parameter's type.

    Values arrive as strings from argparse; they are converted here so that the range check
    in ``Params.replace`` names the flag's parameter.
    """
    out: dict[str, Any] = {}
    for p in cli_params():
        raw = getattr(namespace, p.name, None)
        if raw is None:
            continue
        out[p.name] = _parse_cli_value(p, raw)
    return out


def _parse_cli_value(p: Param, raw: Any) -> Any:
    if p.kind == "vec":
        return [_parse_cli_value(Param("", p.name, "float", 0.0, ""), x) for x in raw]
    if p.kind in ("bool", "enum", "str") or not isinstance(raw, str):
        return raw
    if not _NUMBER.fullmatch(raw):  # (Python's float() would also take 1_000 and non-ASCII digits)
        raise ParameterError(p.name, f"{shown(raw)} is not a number (flag {p.cli_flag}; valid: {p.range_text()}, "
                             "written like 5, -2.5 or 1e-3)")
    number = float(raw)
    if p.kind == "int" and number.is_integer():
        return int(number)
    return number


# --------------------------------------------------------------------------------------------
# The parameters' types for the type checker (``params_typed.py``, generated from PARAMS)

_PYTHON_TYPES = {"int": "int", "float": "float", "bool": "bool", "enum": "str", "str": "str",
                 "vec": "tuple[float, ...]", "keys": "tuple[KeyPoint, ...]"}


def _class_name(*parts: str) -> str:
    return "".join(word.capitalize() for part in parts for word in part.split("_"))


def _python_type(p: Param, owner: str) -> str:
    if p.kind == "table_list":
        return f"tuple[{_class_name(owner, p.key)}Row, ...]"
    return _PYTHON_TYPES[p.kind]


def typed_source() -> str:
    """The text of ``params_typed.py``: a class per section (and a TypedDict per table's rows)
    whose attributes are the parameters with their Python types, so mypy checks every read of a
    parameter (``params.wind.speed`` is a float; ``params.wind.sped`` an error). ``dev.py params``
    writes it; tests/core/test_schema.py checks that it is current."""
    lines = ['"""The parameters\' types for the type checker, generated from ``schema.PARAMS`` by',
             "``schema.typed_source`` (``python3.11 dev.py params`` writes it again): do not edit. Imported",
             '(by ``schema``) only while type checking; at run time a section is a ``schema.Section``."""',
             "", "from __future__ import annotations", "", "from typing import Any, TypedDict", "", "",
             "class KeyPoint(TypedDict):", "    time: float", "    position: tuple[float, ...]", "", "",
             "class Section:", "    def as_dict(self) -> dict[str, Any]:", "        raise NotImplementedError", ""]
    for section in SECTIONS:
        for p in section_params(section):
            if p.kind == "table_list":
                lines += ["", f"class {_class_name(section, p.key)}Row(TypedDict):"]
                lines += [f"    {f.key}: {_python_type(f, section)}" for f in p.fields]
                lines.append("")
        lines += ["", f"class {_class_name(section)}Section(Section):"]
        lines += [f"    {p.key}: {_python_type(p, section)}" for p in section_params(section)]
        lines.append("")
    lines += ["", "class Sections:", '    """What ``Params`` holds: one attribute per section."""', ""]
    lines += [f"    {section}: {_class_name(section)}Section" for section in SECTIONS]
    return "\n".join(lines) + "\n"

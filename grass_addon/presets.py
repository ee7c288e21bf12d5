"""Species presets: ready-made ``blade.species`` tables (numpy-free, no bpy).

Each preset is a list of rows whose keys are columns of ``schema.SPECIES_FIELDS``; ``species_rows``
validates a preset through the schema, so a preset can never hold a value the schema rejects.

Numbers are chosen from what the grass looks like outdoors:
- lawn: mown turf, 4-8 cm high (usual mowing heights), narrow dense blades;
- meadow: unmown hay meadow, 30-60 cm: fine and broad grasses with seed panicles, tall timothy
  stems, buttercups and daisies, some dry straw-coloured blades;
- wild: tall rough grass and reeds, 0.6-1.2 m.

The meadow's grasses grow tufts of short leaves at their stems' foot, its buttercups and daisies
rosettes (``tufts.py``): seen from above, a hay meadow shows leaves, not soil.

Stiffness: the weight torque at the root grows with the square of the blade length (eqs 2-4,
lever ~ L/2, weight ~ rho*g*L), while the root stiffness mu_root/x of eq 1 does not depend on
the length. Tall species therefore get a stiffness multiplier of about (L / 0.32 m)^2 relative to
the default 0.32 m species, so that they stand up at rest like the short ones do (tall grasses
and reeds have thicker, stiffer stems in reality too).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from . import schema
from .errors import ParameterError

if TYPE_CHECKING:
    from .params_typed import BladeSpeciesRow

# Rows per preset; keys are schema.SPECIES_FIELDS columns (missing ones take the schema default).
SPECIES_PRESETS: dict[str, tuple[dict[str, Any], ...]] = {
    "lawn": (
        {"name": "ryegrass", "weight": 0.6, "length": 0.07, "length_variation": 0.008,
         "width": 0.004, "stiffness": 1.0, "color": (0.07, 0.30, 0.04)},
        {"name": "red fescue", "weight": 0.4, "length": 0.055, "length_variation": 0.006,
         "width": 0.0018, "stiffness": 0.8, "color": (0.06, 0.24, 0.06)},
    ),
    "meadow": (
        # fine and broad grasses with seed panicles, tall flowering stems, flowers and some dry blades
        {"name": "meadow grass", "weight": 0.56, "length": 0.32, "length_variation": 0.07,
         "width": 0.006, "stiffness": 1.0, "color": (0.10, 0.30, 0.045),
         "heads": 0.06, "head_color": (0.26, 0.24, 0.13), "head_size": 2.0,
         "leaves": "tuft", "leaf_size": 0.6},
        {"name": "timothy", "weight": 0.12, "length": 0.6, "length_variation": 0.1,
         "width": 0.005, "stiffness": 3.5, "color": (0.16, 0.34, 0.06),
         "heads": 0.5, "head_color": (0.24, 0.26, 0.12), "head_size": 2.2,
         "leaves": "tuft", "leaf_size": 0.4},
        {"name": "cocksfoot", "weight": 0.18, "length": 0.42, "length_variation": 0.09,
         "width": 0.011, "stiffness": 1.8, "color": (0.09, 0.25, 0.07),
         "heads": 0.1, "head_color": (0.24, 0.22, 0.12), "head_size": 2.2,
         "leaves": "tuft", "leaf_size": 0.55},
        {"name": "buttercup", "weight": 0.05, "length": 0.4, "length_variation": 0.08,
         "width": 0.004, "stiffness": 1.6, "color": (0.11, 0.29, 0.05),
         "heads": 0.8, "head_color": (0.80, 0.55, 0.02), "head_size": 5.0,
         "head_shape": "buttercup", "leaves": "rosette", "leaf_size": 0.5},
        {"name": "ox-eye daisy", "weight": 0.04, "length": 0.45, "length_variation": 0.08,
         "width": 0.004, "stiffness": 2.0, "color": (0.12, 0.30, 0.06),
         "heads": 0.8, "head_color": (0.62, 0.62, 0.56), "head_size": 8.0,
         "head_shape": "daisy", "leaves": "rosette", "leaf_size": 0.4},
        {"name": "dry grass", "weight": 0.05, "length": 0.4, "length_variation": 0.08,
         "width": 0.006, "stiffness": 1.6, "color": (0.36, 0.30, 0.12),
         "heads": 0.1, "head_color": (0.34, 0.28, 0.14), "head_size": 2.0,
         "leaves": "tuft", "leaf_size": 0.5},
    ),
    "wild": (
        {"name": "tall grass", "weight": 0.5, "length": 0.8, "length_variation": 0.15,
         "width": 0.01, "stiffness": 6.0, "color": (0.13, 0.30, 0.05), "leaves": "tuft",
         "leaf_size": 0.3},
        {"name": "reed", "weight": 0.2, "length": 1.2, "length_variation": 0.15,
         "width": 0.015, "stiffness": 14.0, "color": (0.18, 0.33, 0.08)},
        {"name": "dry stalks", "weight": 0.3, "length": 0.6, "length_variation": 0.12,
         "width": 0.006, "stiffness": 3.5, "color": (0.40, 0.33, 0.14)},
    ),
}

PRESET_NAMES: tuple[str, ...] = tuple(SPECIES_PRESETS)

# The look each preset gives besides its species (meadow.py): a lawn is even over its dense turf,
# a meadow grows in tussocks and patches over thatch, with some dry tips; wild grass more so.
LOOKS: dict[str, dict[str, Any]] = {
    "lawn": {"field.clumping": 0.0, "field.patchiness": 0.0, "blade.dry_tips": 0.0, "field.floor": "turf"},
    "meadow": {"field.clumping": 0.3, "field.clump_size": 0.45, "field.patchiness": 0.7, "field.patch_size": 8.0,
               "blade.dry_tips": 0.12, "field.floor": "thatch"},
    "wild": {"field.clumping": 0.5, "field.clump_size": 0.7, "field.patchiness": 0.8, "field.patch_size": 12.0,
             "blade.dry_tips": 0.3, "field.floor": "thatch"},
}

PRESET_HELP: dict[str, str] = {
    "lawn": "Mown lawn: short (4-8 cm) narrow blades",
    "meadow": "Hay meadow: 30-60 cm grasses in tussocks and patches, seed heads, flowers, dry tips",
    "wild": "Wild field: tall grass (0.6-1.2 m) and reeds",
}


def species_rows(name: str) -> tuple[BladeSpeciesRow, ...]:
    """The validated species table of preset ``name`` (every SPECIES_FIELDS column filled in)."""
    if name not in SPECIES_PRESETS:
        raise ParameterError(
            "blade.species", f"unknown species preset {name!r} (valid: {', '.join(PRESET_NAMES)})")
    params = schema.defaults().replace({"blade.species": [dict(r) for r in SPECIES_PRESETS[name]]})
    return params.blade.species


def apply_preset(params: schema.Params, name: str) -> schema.Params:
    """``params`` with its species table and look (``LOOKS``) replaced by preset ``name``."""
    return params.replace({"blade.species": [dict(r) for r in species_rows(name)], **LOOKS[name]})

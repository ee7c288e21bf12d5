"""Blender settings generated from ``schema.PARAMS`` (never list a parameter here by hand).

One PropertyGroup per schema section (``item.wind.speed``), one row PropertyGroup per table
parameter (``item.blade.species[i].length``), the field item ``WINDGRASS_PG_field`` and the root
``Scene.windgrass``. Units follow the schema: 'm' -> DISTANCE, 'm/s' -> VELOCITY, 's' -> TIME,
'deg' -> ANGLE stored in radians (converted from/to the schema's degrees here).

Blender stores floats as float32; ``params_from_settings`` reads each float back as the shortest
decimal that maps onto the same stored float32, so values typed by a user or written by
``apply_params`` come back exactly (0.32 stays 0.32, not 0.3199999928).
"""

import contextlib
import json
import math
import re
from collections.abc import Callable, Iterator
from typing import Any

import bpy
import numpy as np

from .. import schema
from ..clock import Clock
from ..errors import ParameterError
from . import owned
from .registry import REGISTRY

# The runtime samples the F-curves of these parameters (WindField keys: time, speed, direction);
# keyframes on any other parameter would silently do nothing, so only these are animatable.
ANIMATED = frozenset({"wind.speed", "wind.direction"})

_FIELD_PATH = re.compile(r"windgrass\.fields\[(\d+)\]")
_PREFIX = "WINDGRASS_PG_"

# --------------------------------------------------------------------------------------------
# Units and conversion between schema values (user units) and Blender values


# Units Blender's unit system shows by itself (the subtypes above); the panel writes the others
# after the value (``unit_suffix``), so that labels stay short enough for the sidebar.
NATIVE_UNITS = frozenset({"", "m", "m/s", "s", "deg", "px", "fraction"})
PRETTY_UNITS = {"N*m^2/rad": "N\u00b7m\u00b2/rad", "N*m/rad^2": "N\u00b7m/rad\u00b2", "N*m": "N\u00b7m",
                "x bending": "\u00d7 bend", "1/m^2": "/m\u00b2"}


def ui_label(p: schema.Param) -> str:
    """The property's label in Blender: the schema's label (short: the sidebar is narrow)."""
    return p.ui_name


def unit_suffix(p: schema.Param) -> str:
    """The unit written after the value where Blender's unit system cannot show it (``kg/m``,
    ``MB``); empty for the units Blender shows."""
    return "" if p.unit in NATIVE_UNITS else PRETTY_UNITS.get(p.unit, p.unit)


def _float_subtype(p: schema.Param) -> dict[str, str]:
    if p.unit == "fraction":
        return {"subtype": "FACTOR"}
    if p.unit == "deg":
        return {"subtype": "ANGLE"}
    if p.unit == "m":
        return {"subtype": "DISTANCE"}
    if p.unit == "m/s":
        return {"unit": "VELOCITY"}
    if p.unit == "s":
        return {"subtype": "TIME_ABSOLUTE"}
    if p.unit == "px":
        return {"subtype": "PIXEL"}
    return {}


def _vector_subtype(p: schema.Param) -> dict[str, str]:
    if p.key == "color" or p.key.endswith("_color"):
        return {"subtype": "COLOR"}
    if p.unit == "m":
        return {"subtype": "TRANSLATION"}
    return {}


def to_blender(p: schema.Param, value: Any) -> Any:
    """Schema value (user units) -> the value the Blender property stores."""
    if p.kind == "float" and p.unit == "deg":
        return math.radians(value)
    if p.kind == "vec":
        return tuple(math.radians(v) if p.unit == "deg" else float(v) for v in value)
    return value


def _float_from_blender(p: schema.Param, raw: float) -> float:
    stored = np.float32(raw)
    if not np.isfinite(stored):
        return float(stored)
    if p.unit != "deg":
        return float(str(stored))  # numpy prints the shortest decimal that round-trips float32
    exact = math.degrees(float(stored))
    for digits in range(1, 10):  # shortest decimal degree value that stores as the same radians
        candidate = float(f"{exact:.{digits}g}")
        if np.float32(math.radians(candidate)) == stored:
            return candidate
    return exact


def from_blender(p: schema.Param, raw: Any) -> Any:
    """Blender property value -> schema value (user units); tables give lists of row dicts."""
    if p.kind == "float":
        return _float_from_blender(p, raw)
    if p.kind == "vec":
        return [_float_from_blender(p, v) for v in raw]
    if p.kind == "int":
        return int(raw)
    if p.kind == "bool":
        return bool(raw)
    if p.kind in ("enum", "str"):
        return str(raw)
    if p.kind == "table_list":
        return [{f.key: from_blender(f, getattr(row, f.key)) for f in p.fields} for row in raw]
    raise TypeError(f"{p.name}: unknown parameter kind {p.kind!r}")


def _precision(p: schema.Param) -> int:
    """Decimals shown: enough for the default (or minimum) to show two significant digits."""
    ref = p.default if p.kind == "float" else None
    if not ref and p.minimum:
        ref = p.minimum
    if not ref or p.unit == "deg":
        return 2 if p.unit != "deg" else 1
    return int(min(6, max(2, 1 - math.floor(math.log10(abs(ref))))))


def description(p: schema.Param) -> str:
    """Tooltip: help, unit and valid range (the same text the CLI and TOML errors use)."""
    unit = f" [{p.unit}]" if p.unit else ""
    if p.kind in ("str", "table_list") or (p.kind == "vec" and "color" in p.key):  # (a colour: its picker)
        return f"{p.help}{unit}"
    return f"{p.help}{unit}. Valid: {p.range_text()}"


# Called with (scene, item) when a field's settings change; the runtime sets it (runtime.mark_dirty)
# when the add-on registers, so this module needs no import of the runtime.
on_edit: Callable[..., None] | None = None


def notify(item: Any) -> None:
    """Tell the runtime that the settings of field ``item`` changed."""
    scene = item.id_data
    if on_edit is not None and isinstance(scene, bpy.types.Scene):
        on_edit(scene, item)


@contextlib.contextmanager
def batch(item: Any) -> Iterator[None]:
    """Write many settings of ``item`` with a single runtime update at the end (the runtime
    rebuilds on each update; intermediate states may also break relations such as lod order)."""
    REGISTRY.batch_depth += 1
    try:
        yield
    finally:
        REGISTRY.batch_depth -= 1
    if REGISTRY.batch_depth == 0:
        notify(item)


def _on_update(self: bpy.types.PropertyGroup, context: Any) -> None:
    """Update callback of every generated property: the owning field is dirty."""
    if REGISTRY.batch_depth or not isinstance(self.id_data, bpy.types.Scene):
        return
    match = _FIELD_PATH.match(self.path_from_id())
    if match is None:
        return
    fields = self.id_data.windgrass.fields
    index = int(match.group(1))
    if index < len(fields):
        notify(fields[index])


def _limits(p: schema.Param) -> dict[str, float]:
    """The parameter's min, max and soft limits (a soft one missing is the hard one), in schema units."""
    pairs = (("min", p.minimum), ("max", p.maximum),
             ("soft_min", p.soft_min if p.soft_min is not None else p.minimum),
             ("soft_max", p.soft_max if p.soft_max is not None else p.maximum))
    return {arg: limit for arg, limit in pairs if limit is not None}


def make_property(p: schema.Param, default: Any = None, update: Any = _on_update,
                  animatable: bool | None = None, skip_save: bool = False) -> Any:
    """The ``bpy.props`` definition of one schema parameter (used by operators too).

    ``default`` overrides the schema default (in schema units). Table parameters need their
    row class, so they are made by ``_section_class``.
    """
    value = p.default if default is None else default
    kw: dict[str, Any] = {"name": ui_label(p), "description": description(p)}
    if update is not None:
        kw["update"] = update
    if animatable is None:
        animatable = p.name in ANIMATED
    kw["options"] = ({"ANIMATABLE"} if animatable else set()) | ({"SKIP_SAVE"} if skip_save else set())
    limits = _limits(p)
    if p.kind == "int":
        subtype = {"subtype": "PIXEL"} if p.unit == "px" else {}
        return bpy.props.IntProperty(default=int(value), **{k: int(v) for k, v in limits.items()}, **subtype, **kw)
    if p.kind == "float":
        unit_limits = {k: to_blender(p, float(v)) for k, v in limits.items()}
        return bpy.props.FloatProperty(default=to_blender(p, float(value)), precision=_precision(p),
                                       **unit_limits, **_float_subtype(p), **kw)
    if p.kind == "vec":
        unit_limits = {k: to_blender(schema.Param("", "", "float", 0.0, "", unit=p.unit), float(v))
                       for k, v in limits.items()}
        return bpy.props.FloatVectorProperty(size=p.size, default=to_blender(p, value), precision=3,
                                             **unit_limits, **_vector_subtype(p), **kw)
    if p.kind == "bool":
        return bpy.props.BoolProperty(default=bool(value), **kw)
    if p.kind == "enum":
        items = [(c, c.replace("_", " ").capitalize(), f"{p.help}: {c}") for c in p.choices]
        return bpy.props.EnumProperty(items=items, default=value, **kw)
    if p.kind == "str":
        kw.pop("options")
        if p.path:  # a file browser button; the map picker (windgrass.map_pick) offers Blender's sources
            kw["subtype"] = "FILE_PATH"
        return bpy.props.StringProperty(default=str(value), **kw)
    raise TypeError(f"{p.name}: parameter kind {p.kind!r} has no single Blender property")


# --------------------------------------------------------------------------------------------
# Generated classes

# Sections whose name the field item already uses for something else: ``item.terrain`` is the
# terrain mesh, so the [terrain] section's settings are ``item.ground``.
SECTION_ATTRS = {"terrain": "ground"}


def group(item: Any, section: str) -> Any:
    """The PropertyGroup of ``section``'s settings on a field item (``group(item, "wind").speed``)."""
    return getattr(item, SECTION_ATTRS.get(section, section))

ROW_CLASSES: dict[str, type] = {}      # "blade.species" -> row PropertyGroup
SECTION_CLASSES: dict[str, type] = {}  # "wind" -> section PropertyGroup


def index_name(p: schema.Param) -> str:
    """Name of the UI list's active-row index of table parameter ``p`` (``species_index``)."""
    return f"{p.key}_index"


def _row_class(p: schema.Param) -> type:
    annotations = {f.key: make_property(f) for f in p.fields}
    name = f"{_PREFIX}row_{p.section}_{p.key}"
    return type(name, (bpy.types.PropertyGroup,), {"__annotations__": annotations,
                                                   "__doc__": f"One row of {p.name}: {p.help}"})


def _section_class(section: str) -> type:
    annotations: dict[str, Any] = {}
    for p in schema.blender_params(section):
        if p.kind == "table_list":
            row = ROW_CLASSES[p.name] = _row_class(p)
            annotations[p.key] = bpy.props.CollectionProperty(type=row, name=p.ui_name,
                                                              description=description(p))
            index = index_name(p)
            if any(q.key == index for q in schema.section_params(section)):
                raise RuntimeError(f"{section}.{index} is a parameter; rename the UI index")
            annotations[index] = bpy.props.IntProperty(name=f"Active {p.ui_name}", min=0,
                                                       options=set())
        else:
            annotations[p.key] = make_property(p)
    for view in schema.section_views(section):
        annotations[view.param.key] = _view_property(view)
    cls = type(f"{_PREFIX}section_{section}", (bpy.types.PropertyGroup,),
               {"__annotations__": annotations, "__doc__": f"Windgrass [{section}] settings"})
    SECTION_CLASSES[section] = cls
    return cls


def _view_property(view: schema.View) -> Any:
    """A view (``schema.VIEWS``) as a property that stores nothing: it reads the parameters it
    stands for and writes them (each write is the parameter's own edit: update, undo)."""
    p = view.param
    uses = [schema.BY_NAME[f"{p.section}.{key}"] for key in view.uses]

    def values(settings) -> dict[str, Any]:
        return {q.key: from_blender(q, getattr(settings, q.key)) for q in uses}

    def get(settings) -> float:
        return to_blender(p, float(view.read(values(settings))))

    def set_(settings, value: float) -> None:
        for key, new in view.write(values(settings), from_blender(p, value)).items():
            q = schema.BY_NAME[f"{p.section}.{key}"]
            if from_blender(q, getattr(settings, key)) != new:
                setattr(settings, key, to_blender(q, new))

    limits = {arg: to_blender(p, float(v)) for arg, v in _limits(p).items()}
    return bpy.props.FloatProperty(name=ui_label(p), description=description(p), get=get, set=set_,
                                   options=set(), precision=view.digits, **limits,
                                   **_float_subtype(p))


def _mesh_poll(self: Any, obj: bpy.types.Object) -> bool:
    return obj.type == "MESH"


for _section in schema.SECTIONS:
    _section_class(_section)

WINDGRASS_PG_field = type(f"{_PREFIX}field", (bpy.types.PropertyGroup,), {
    "__doc__": "Settings of one grass field",
    "__annotations__": {
        "name": bpy.props.StringProperty(name="Name", default="Grass", description="Name of the grass field"),
        "uid": bpy.props.StringProperty(name="UID", options={"HIDDEN"},
                                        description="Unique id of the field in its scene (keys the runtime)"),
        "collection": bpy.props.PointerProperty(type=bpy.types.Collection, name="Collection",
                                                description="Collection holding the field's objects"),
        "terrain": bpy.props.PointerProperty(type=bpy.types.Object, name="Terrain", poll=_mesh_poll,
                                             description="Mesh the blades are rooted on (empty: flat ground)"),
        "collider_collection": bpy.props.PointerProperty(
            type=bpy.types.Collection, name="Colliders", update=lambda self, context: notify(self),
            description="Objects that push the grass aside and trample it as they move through it (any mesh: a ball, "
                        "a character); their motion is sampled over the frame range and saved with the file"),
        "effector_collection": bpy.props.PointerProperty(
            type=bpy.types.Collection, name="Force Fields", update=lambda self, context: notify(self),
            description="Force fields (Wind, Force, Vortex, Turbulence) that blow the grass, as in Blender's particle "
                        "and cloth settings"),
        "keep_out_collection": bpy.props.PointerProperty(
            type=bpy.types.Collection, name="Keep Out", update=lambda self, context: notify(self),
            description="Objects whose ground outline grows no grass (houses, rocks, a path made of a curve with "
                        "a bevel), with the margin and falloff below"),
        **{SECTION_ATTRS.get(s, s): bpy.props.PointerProperty(type=SECTION_CLASSES[s], name=s.capitalize())
           for s in schema.SECTIONS},
    },
})

WINDGRASS_PG_scene = type(f"{_PREFIX}scene", (bpy.types.PropertyGroup,), {
    "__doc__": "Windgrass settings of a scene: its grass fields",
    "__annotations__": {
        "fields": bpy.props.CollectionProperty(type=WINDGRASS_PG_field, name="Grass Fields"),
        "active_index": bpy.props.IntProperty(name="Active Field", min=0, options=set()),
        "next_uid": bpy.props.IntProperty(name="Next UID", min=0, options={"HIDDEN"}),
    },
})

CLASSES: tuple[type, ...] = (*ROW_CLASSES.values(), *SECTION_CLASSES.values(), WINDGRASS_PG_field,
                             WINDGRASS_PG_scene)

# --------------------------------------------------------------------------------------------
# Settings <-> Params


# The scene's clock: inside Blender these come from the scene, not from the field's settings
# (which headless renders use to set up their scene).
SCENE_CLOCK = ("render.fps", "render.fps_base", "render.frame_start", "render.frame_end")


def params_from_settings(item: Any, scene: Any = None) -> schema.Params:
    """Validated Params of a field item; a bad value raises ParameterError naming its key.

    With ``scene`` the clock is the scene's (``Clock.of_scene``: its frame rate, 29.97 fps as
    30 / 1.001, and first frame) and so is the frame range."""
    data = {s: {p.key: from_blender(p, getattr(group(item, s), p.key)) for p in schema.blender_params(s)}
            for s in schema.SECTIONS}
    for name, value in json.loads(item.get(SCENE_FILE_KEY, "{}") or "{}").items():
        section, key = name.split(".", 1)
        data[section][key] = value
    if scene is not None:
        last = schema.BY_NAME["render.frame_end"].maximum
        clock = Clock.of_scene(scene)
        data["render"].update(fps=clock.fps, fps_base=clock.fps_base, frame_start=clock.frame_start,
                              frame_end=int(min(max(scene.frame_end, scene.frame_start), last)))
        try:
            return schema.from_dict(data)
        except ParameterError as exc:
            if exc.key in SCENE_CLOCK:
                raise ParameterError(exc.key, f"the scene's {exc.message}") from None
            raise
    return schema.from_dict(data)


# Settings of scene files only (a headless render's [[colliders]] and [[effectors]]), kept on the
# field item as JSON: Blender has no properties for them (its collections give them instead).
SCENE_FILE_KEY = "wg_scene_file"


def apply_params(item: Any, params: schema.Params) -> None:
    """Write every value of ``params`` into the field item's properties (one runtime update)."""
    scene_only = {p.name: params.to_dict()[p.section][p.key] for p in schema.PARAMS
                  if not p.blender and params.get(p.name)}
    if scene_only:
        item[SCENE_FILE_KEY] = json.dumps(scene_only)
    elif SCENE_FILE_KEY in item:
        del item[SCENE_FILE_KEY]
    with batch(item):
        for section in schema.SECTIONS:
            settings = group(item, section)
            for p in schema.blender_params(section):
                value = params.get(p.name)
                if p.kind == "table_list":
                    write_rows(item, p, value)
                else:
                    setattr(settings, p.key, to_blender(p, value))


TABLES: tuple[schema.Param, ...] = tuple(p for p in schema.PARAMS if p.kind == "table_list" and p.blender)


def table_param(name: str) -> schema.Param:
    """The table parameter called ``name`` ("blade.species"), or ParameterError."""
    p = schema.BY_NAME.get(name)
    if p is None or p.kind != "table_list":
        raise ParameterError(name, f"not a table parameter (valid: {', '.join(t.name for t in TABLES)})")
    return p


def table_rows(item: Any, name: str) -> tuple[schema.Param, Any, Any, str]:
    """(table parameter, its section group, its rows collection, active-index name) of ``item``."""
    p = table_param(name)
    settings = group(item, p.section)
    return p, settings, getattr(settings, p.key), index_name(p)


def write_rows(item: Any, p: schema.Param, rows: Any) -> None:
    """Replace the rows of table ``p`` of a field item by ``rows`` (dicts of schema values)."""
    collection = getattr(group(item, p.section), p.key)
    with batch(item):
        collection.clear()
        for values in rows:
            row = collection.add()
            for f in p.fields:
                setattr(row, f.key, to_blender(f, values.get(f.key, f.default)))
        setattr(group(item, p.section), index_name(p), 0)


_SPECIES_MAP = re.compile(r"blade\.species\[(\d+)\]\.density_map")


def map_owner(item: Any, setting: str) -> tuple[Any, str]:
    """(settings group, key) of a map setting: ``paint.density``, ``paint.length`` or
    ``blade.species[i].density_map``; ParameterError for anything else."""
    if setting in ("paint.density", "paint.length"):
        return group(item, "paint"), setting.split(".")[1]
    match = _SPECIES_MAP.fullmatch(setting)
    if match and int(match.group(1)) < len(item.blade.species):
        return item.blade.species[int(match.group(1))], "density_map"
    raise ParameterError(setting, "not a map setting (valid: paint.density, paint.length, "
                         "blade.species[i].density_map)")


def active_field(scene: bpy.types.Scene) -> Any | None:
    """The field item selected in the UI list, or None when the scene has no field."""
    root = getattr(scene, "windgrass", None)
    if root is None or not len(root.fields):
        return None
    return root.fields[min(max(root.active_index, 0), len(root.fields) - 1)]


def field_by_uid(scene: bpy.types.Scene, uid: str) -> Any | None:
    """The field item of ``scene`` with ``uid`` (look an item up again after the collection grew:
    ``fields.add()`` may move the items, and a Python reference to one is then dead)."""
    return next((f for f in scene.windgrass.fields if f.uid == uid), None)


def add_field(scene: bpy.types.Scene, params: schema.Params | None = None, name: str = "Grass") -> Any:
    """Append a field item (unique name and uid) holding ``params`` and make it active."""
    root = scene.windgrass
    taken = {f.name for f in root.fields}
    unique, n = name, 0
    base = re.sub(r"\.\d{3}$", "", name) if name in taken else name  # (Grass.001's copy: Grass.002, as Blender names)
    while unique in taken:
        n += 1
        unique = f"{base}.{n:03d}"
    # The uid tags the field's objects and data-blocks, which live in bpy.data across scenes:
    # keep it unique in the whole file, not only in this scene.
    used = {f.uid for s in bpy.data.scenes for f in owned.scene_fields(s)}
    number = root.next_uid
    while f"field-{number}" in used:
        number += 1
    item = root.fields.add()
    item.name = unique
    item.uid = f"field-{number}"
    root.next_uid = number + 1
    apply_params(item, params or schema.defaults())
    item[SETTINGS_VERSION_KEY] = schema.SETTINGS_VERSION
    root.active_index = len(root.fields) - 1
    return item


# The field item's custom property: the settings version (schema.SETTINGS_VERSION) its values are in.
# Fields saved before it existed hold version 1 (the settings as they were until versions began).
SETTINGS_VERSION_KEY = "wg_settings_version"

def _from_version_1(item: Any) -> None:
    """Version 2 added settings whose defaults change what a field of version 1 drew: its LOD by
    screen size, its gust waves' stretch across the wind, its flowers' drifts. A field of version 1
    keeps what it drew: none of them."""
    item.lod.screen_size = False
    item.wind.gust_stretch = 1.0
    item.field.flower_drift = 1.0


# version -> a function bringing a field item's settings from that version to the next; ``upgrade``
# runs them in order when a file is opened.
UPGRADES: dict[int, Callable[[Any], None]] = {1: _from_version_1}


def upgrade(item: Any) -> str | None:
    """Bring the settings of a field opened from a file to this version (``UPGRADES``); the
    warning to give when the file was saved by a newer Windgrass (its settings are read as they
    are: they may mean something else), else None."""
    saved = int(item.get(SETTINGS_VERSION_KEY, 1))
    if saved > schema.SETTINGS_VERSION:
        return (f"field '{item.name}' was saved by a newer Windgrass (settings version {saved}; this one reads up "
                f"to {schema.SETTINGS_VERSION}): its grass may differ; install the newer Windgrass to edit it")
    REGISTRY.batch_depth += 1  # (no edit to follow: the file's load brings every field to its settings next)
    try:
        for version in range(saved, schema.SETTINGS_VERSION):
            UPGRADES[version](item)
    finally:
        REGISTRY.batch_depth -= 1
    item[SETTINGS_VERSION_KEY] = schema.SETTINGS_VERSION
    return None


def remove_item(scene: bpy.types.Scene, item: Any) -> None:
    """Remove the settings item (the objects are removed by ``bridge.scene.remove_field``)."""
    root = scene.windgrass
    for index, other in enumerate(root.fields):
        if other.uid == item.uid:
            root.fields.remove(index)
            break
    root.active_index = min(root.active_index, max(len(root.fields) - 1, 0))


__all__ = ["ParameterError", "params_from_settings", "apply_params", "active_field", "add_field",
           "remove_item", "make_property", "write_rows", "table_param", "table_rows", "batch", "notify",
           "register", "unregister"]

# --------------------------------------------------------------------------------------------
# Registration

_registered = False


def register() -> None:
    global _registered
    if _registered:
        return
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.windgrass = bpy.props.PointerProperty(type=WINDGRASS_PG_scene, name="Windgrass")
    _registered = True


def unregister() -> None:
    global _registered
    if not _registered:
        return
    if hasattr(bpy.types.Scene, "windgrass"):
        del bpy.types.Scene.windgrass
    for cls in reversed(CLASSES):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
    _registered = False

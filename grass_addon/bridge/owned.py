"""What belongs to a grass field in Blender: its roles, tags and the record of its datablocks.

What belongs to a field is recorded on its settings item: the custom property ``wg_objects`` holds
ID pointers to its ground, slot objects, materials and images (Blender keeps them valid through
renames, save and reopen, and points a Full Copy of the scene at the copies; on the collection
itself such pointers crash Blender 4.2's Full Copy). Rebuild and Remove touch only those, so a
user's Shift+D copy of a grass object (tags and all) is never taken for a slot, never taken over and
never deleted, and a copied scene's field never touches the original's. Every datablock also carries
``wg_uid`` and ``wg_role`` custom properties (files of 0.1 are found through them, inside the
field's collection only).
"""

from __future__ import annotations

import bpy

from .. import roles

ROLE_COLLECTION = "collection"
ROLE_GROUND = "ground"
ROLE_BLADES = roles.BLADES  # the slot objects' roles: one a level of detail (roles.py)
ROLE_CARDS = roles.CARDS
ROLE_BLADE_MATERIAL = "blade_material"
ROLE_CARD_MATERIAL = "card_material"
ROLE_GROUND_MATERIAL = "ground_material"
ROLE_CANOPY_MATERIAL = "canopy_material"
ROLE_CARD_IMAGE = "card_image"
ROLE_GUST_IMAGE = "gust_image"
ROLE_TRAIL_IMAGE = "trail_image"
ROLE_PATCH_IMAGE = "patch_image"
ROLE_PAINT_MAP = "paint_map"
ROLE_HEAD = "head"  # a species' flower head object (in no scene: the heads' modifier draws it), key "head 003"
ROLE_HEAD_GROUP = "head_group"  # the node group of the heads' modifier on the blade slots
ROLE_HEAD_MATERIAL = "head_material"
ROLE_LEAVES = "leaves"  # a species' leaves at its stems' foot (in no scene: the heads' modifier draws it), "leaves 003"
ROLE_WIND_MAP = "wind_map"  # the wind the grass feels, for Blender's hair and cloth (in no scene: wind_force.py)
IN_NO_SCENE = (ROLE_HEAD, ROLE_LEAVES, ROLE_WIND_MAP)  # objects the field keeps outside its collection


# Roles stored in ``wg_role`` of the datablocks of a field.


def owner_tag(scene, item) -> str:
    """The ``wg_uid`` value on the field's datablocks.

    Field uids are unique per scene only, so the tag is ``"<scene name>/<uid>"`` at creation and
    is read back from the field's collection afterwards (a renamed scene keeps its fields).
    """
    coll = item.collection
    if coll is not None and coll.get("wg_uid"):
        return coll["wg_uid"]
    return f"{scene.name}/{item.uid}"


def unused_tag(base: str) -> str:
    taken = {d.get("wg_uid") for coll in (bpy.data.collections, bpy.data.objects, bpy.data.materials)
             for d in coll}
    tag, n = base, 0
    while tag in taken:
        n += 1
        tag = f"{base}#{n}"
    return tag


def tag(idblock, uid: str, role: str, index: int | None = None) -> None:
    idblock["wg_uid"] = uid
    idblock["wg_role"] = role
    if index is not None:
        idblock["wg_slot"] = index


def _owned(collection, uid: str, role: str | None = None) -> list:
    """Datablocks of ``collection`` (a bpy.data collection) made by the field ``uid``."""
    return [d for d in collection if d.get("wg_uid") == uid and (role is None or d.get("wg_role") == role)]

TOPOLOGY = "wg_topology"  # the collection's custom property: slots.topology_key it was built for

MADE_KEY = "wg_objects"  # the field item's custom property: {key: ID pointer} of what it made


def registered(item) -> dict:
    """{key: datablock} recorded on the field's settings item (keys ``ground``, ``blades 003``,
    ``cards 000``, ``blade_material``, ...); datablocks deleted since are left out."""
    group = item.get(MADE_KEY)
    if group is None or not hasattr(group, "items"):
        return _tagged(item)
    return {key: value for key, value in group.items() if isinstance(value, bpy.types.ID)}


def recorded(item, key: str):
    """The datablock recorded under ``key`` on the field's settings item (``registered``'s, read
    alone: what a frame reads every frame), or None."""
    group = item.get(MADE_KEY)
    if group is None or not hasattr(group, "items"):
        return _tagged(item).get(key)
    value = group.get(key)
    return value if isinstance(value, bpy.types.ID) else None


def was_built(item) -> bool:
    """Whether objects were ever made for the field (a field being added has none yet)."""
    return item.get(MADE_KEY) is not None or item.collection is not None


def _tagged(item) -> dict:
    """What a 0.1 file's field made, found by its tag: objects inside its collection only."""
    coll = item.collection
    uid = coll.get("wg_uid") if coll is not None else None
    if not uid:
        return {}
    found: dict = {}
    for obj in coll.objects:
        if obj.get("wg_uid") == uid and obj.get("wg_role"):
            role = obj["wg_role"]
            found.setdefault(role if role == ROLE_GROUND else slot_key(role, int(obj.get("wg_slot", -1))), obj)
    for data in _owned(bpy.data.materials, uid) + _owned(bpy.data.images, uid) + _owned(bpy.data.node_groups, uid):
        found.setdefault(data.get("wg_role"), data)
    for role in (ROLE_HEAD, ROLE_LEAVES):  # (in no collection)
        for obj in _owned(bpy.data.objects, uid, role):
            found.setdefault(slot_key(role, int(obj.get("wg_slot", -1))), obj)
    for obj in _owned(bpy.data.objects, uid, ROLE_WIND_MAP):
        found.setdefault(ROLE_WIND_MAP, obj)
    return found


def record(item, key: str, idblock) -> None:
    if item.get(MADE_KEY) is None or not hasattr(item[MADE_KEY], "items"):
        item[MADE_KEY] = _tagged(item)
    item[MADE_KEY][key] = idblock


def slot_key(role: str, index: int) -> str:
    return f"{role} {index:03d}"


def field_objects(item) -> list:
    """The field's own objects in its collection (never a user's tagged copies elsewhere; not the
    flower heads' and leaves' objects and the wind map, which are in no scene: ``bridge/heads.py`` and
    ``bridge/wind_force.py`` make and remove them)."""
    return [d for d in registered(item).values() if isinstance(d, bpy.types.Object)
            and d.get("wg_role") not in IN_NO_SCENE]


def slot_objects(item, role: str) -> dict[int, bpy.types.Object]:
    """{slot index: object} of the field's slots that still exist in its collection (the user may
    delete some; copies of them are not slots)."""
    coll = item.collection
    out: dict = {}
    if coll is None:
        return out
    prefix = slot_key(role, 0)[:-3]  # ("blades "): the record's keys name the role, read first
    for key, obj in registered(item).items():
        if key.startswith(prefix) and _is_slot(obj, role, coll):
            out[int(obj.get("wg_slot", -1))] = obj
    return out


def slot_object(item, role: str, index: int):
    """``slot_objects(item, role)[index]`` read alone (a frame's writes: the objects that changed),
    or None."""
    coll = item.collection
    obj = recorded(item, slot_key(role, index)) if coll is not None else None
    return obj if _is_slot(obj, role, coll, index) else None


def _is_slot(obj, role: str, coll, index: int | None = None) -> bool:
    """``obj`` is a mesh object of ``role`` (its slot ``index``, when given) still in the field's
    collection ``coll``."""
    return (isinstance(obj, bpy.types.Object) and obj.get("wg_role") == role and obj.type == "MESH"
            and (index is None or obj.get("wg_slot", -1) == index) and coll.objects.get(obj.name) is obj)


def ground_object(item):
    """The field's ground object (``recorded``'s: read alone, as every frame reads it), or None."""
    obj = recorded(item, ROLE_GROUND)
    return obj if isinstance(obj, bpy.types.Object) and obj.get("wg_role") == ROLE_GROUND else None


def scene_fields(scene) -> tuple:
    """The field items of ``scene``; none where the add-on's scene property is gone (a handler
    that runs while the add-on unregisters, or a scene Blender made before it registered)."""
    root = getattr(scene, "windgrass", None)
    return tuple(root.fields) if root is not None else ()


def orphans(scene) -> list:
    """Objects of ``scene`` tagged as a grass field's that no field records: Shift+D copies of a
    field's ground or slots, or a field's collection appended from another file without its scene
    (they are meshes that never move; they are not fields)."""
    recorded = set()
    for s in bpy.data.scenes:
        for item in scene_fields(s):
            recorded |= {o.as_pointer() for o in registered(item).values() if isinstance(o, bpy.types.Object)}
    return [obj for obj in scene.objects if obj.get("wg_role") in (ROLE_GROUND, *roles.NAMES)
            and obj.as_pointer() not in recorded]


def orphan_notes(scene, most: int = 3) -> list[str]:
    """Sentences for the panel about ``orphans`` (a few, and how many more)."""
    found = orphans(scene)
    notes = [f"'{obj.name}' is a copy of a grass field's {obj.get('wg_role')}, not a field: it does not sway "
             "(Duplicate Field copies a field; File > Append > Scene brings another file's fields)"
             for obj in found[:most]]
    if len(found) > most:
        notes.append(f"... and {len(found) - most} more such copies")
    return notes

"""The Blender datablocks of a grass field: its collection, ground, slot objects, materials and images.

One collection per field holds:
  * a ground plane the size of the field (far LOD, paper III.C); every other object of the
    field is parented to it, so moving the ground moves the field;
  * the blade slot objects: meshes of k copies of one block's topology (``slots.py`` sizes the
    pools from the LOD distances and assigns blocks to positions; ``pools.py`` writes them);
  * the card slot objects (paper III.B), likewise.

Over a terrain (``maps.sample_terrain``) the ground is a grid mesh following it. What belongs to a
field is recorded on its settings item (``owned.py``); the meshes are written in bulk
(``meshes.py``); what the ground shows of the paint is ``paint_look.py``'s.

This module builds and removes datablocks; when to build is ``lifecycle.py``'s business.
"""

from __future__ import annotations

import bpy

from .. import look, plants, roles, slots, sward
from ..grid import FieldGrid
from ..schema import Params
from . import heads, maps, materials, meshes, owned, paint_look, textures, wind_force

# --------------------------------------------------------------------------------------------
# Terrain


# --------------------------------------------------------------------------------------------
# Building


def ensure_collection(scene, item) -> bpy.types.Collection:
    """The field's collection, linked under the scene collection (created if needed)."""
    coll = item.collection
    if coll is None or not coll.get("wg_uid"):
        coll = bpy.data.collections.new(item.name or "Grass field")
        owned.tag(coll, owned.unused_tag(f"{scene.name}/{item.uid}"), owned.ROLE_COLLECTION)
        item.collection = coll
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)
    return coll


def _material(item, role: str, make):
    """The field's material of ``role``; made anew when missing or built by an older version."""
    found = owned.registered(item).get(role)
    if isinstance(found, bpy.types.Material) and materials.is_current(found):
        return found
    mat = make()
    mat["wg_role"] = role
    owned.record(item, role, mat)
    return mat


def field_materials(item):
    """(blade, card, ground, canopy) materials of the field, created once and recorded on ``item``."""
    uid, base_name = item.collection["wg_uid"], item.collection.name
    image = owned.registered(item).get(owned.ROLE_CARD_IMAGE)
    if not isinstance(image, bpy.types.Image):
        image = textures.ensure_card_image(f"{base_name} card texture")
        owned.tag(image, uid, owned.ROLE_CARD_IMAGE)
        owned.record(item, owned.ROLE_CARD_IMAGE, image)
    gusts = owned.registered(item).get(owned.ROLE_GUST_IMAGE)
    if not isinstance(gusts, bpy.types.Image):
        gusts = textures.ensure_gust_image(f"{base_name} gust waves")
        owned.tag(gusts, uid, owned.ROLE_GUST_IMAGE)
        owned.record(item, owned.ROLE_GUST_IMAGE, gusts)
    trails = owned.registered(item).get(owned.ROLE_TRAIL_IMAGE)
    if not isinstance(trails, bpy.types.Image):
        trails = textures.ensure_trail_image(f"{base_name} trails")
        owned.tag(trails, uid, owned.ROLE_TRAIL_IMAGE)
        owned.record(item, owned.ROLE_TRAIL_IMAGE, trails)
    patches = owned.registered(item).get(owned.ROLE_PATCH_IMAGE)
    if not isinstance(patches, bpy.types.Image) or patches.alpha_mode != "CHANNEL_PACKED":  # (older: no heights)
        patches = textures.ensure_patch_image(f"{base_name} patches")
        owned.tag(patches, uid, owned.ROLE_PATCH_IMAGE)
        owned.record(item, owned.ROLE_PATCH_IMAGE, patches)
    blade = _material(item, owned.ROLE_BLADE_MATERIAL, lambda: materials.blade_material(f"{base_name} blades", uid))
    card = _material(item, owned.ROLE_CARD_MATERIAL,
                     lambda: materials.card_material(f"{base_name} cards", uid, image, gusts, patches))
    ground = _material(item, owned.ROLE_GROUND_MATERIAL, lambda: materials.ground_material(f"{base_name} ground", uid))
    canopy = _material(item, owned.ROLE_CANOPY_MATERIAL,
                       lambda: materials.canopy_material(f"{base_name} canopy", uid, gusts, trails, patches))
    return blade, card, ground, canopy


MATERIALS_DIGEST = "wg_materials"  # the collection's custom property: what its materials show


def update_field_materials(item, params: Params, scene=None, later: bool = False) -> bool:
    """Refresh the parameter-dependent values (eq 10 distances, colours, the card atlas) of the
    materials, and the cards' layer limit from ``scene``'s transparent bounces (Cycles); nothing
    when they already show these. ``later`` (an edit in the UI): when the look of ``params`` takes
    time to work out (``look.ask``), it is worked out on a thread and nothing is written yet (False:
    ask again). True: the materials show ``params``."""
    cycles = getattr(scene, "cycles", None)
    bounces = cycles.transparent_max_bounces if cycles is not None else -1
    reg = owned.registered(item)
    own = heads.plant_shapes(params)  # (the artist's plants the cards draw: their triangles, read here)
    params = plants.seen_far(params, own)  # (and their colour the far grass shows: ``seen_far``)
    digest = f"{params.digest()}|{bounces}|" + ",".join(sorted(d.name for d in reg.values()
                                                               if isinstance(d, (bpy.types.Material, bpy.types.Image))))
    digest += repr(own) if own else ""
    coll = item.collection
    if coll is not None and coll.get(MATERIALS_DIGEST) == digest:
        return True
    if later and not look.ask(params, own):
        return False
    materials.update_materials(params, reg.get(owned.ROLE_CANOPY_MATERIAL))
    mats = [reg.get(role) for role in (owned.ROLE_BLADE_MATERIAL, owned.ROLE_CARD_MATERIAL, owned.ROLE_GROUND_MATERIAL,
                                       owned.ROLE_CANOPY_MATERIAL)]
    materials.update_haze(params, *mats)
    materials.update_viewport_colours(params, *mats)
    materials.update_floor(params, reg.get(owned.ROLE_GROUND_MATERIAL))
    heads.update_colours(item, params)
    if cycles is not None:
        materials.set_card_depth(reg.get(owned.ROLE_CARD_MATERIAL), cycles.transparent_max_bounces)
    image = reg.get(owned.ROLE_CARD_IMAGE)
    if isinstance(image, bpy.types.Image):
        textures.paint_card_image(image, params, own)
    gust_image = reg.get(owned.ROLE_GUST_IMAGE)
    if isinstance(gust_image, bpy.types.Image):
        textures.paint_gust_image(gust_image, params)
    materials.update_gusts(params, reg.get(owned.ROLE_CARD_MATERIAL), reg.get(owned.ROLE_CANOPY_MATERIAL))
    patch_image = reg.get(owned.ROLE_PATCH_IMAGE)
    if isinstance(patch_image, bpy.types.Image):
        textures.paint_patch_image(patch_image, params)
    materials.update_patches(params, reg.get(owned.ROLE_CARD_MATERIAL), reg.get(owned.ROLE_CANOPY_MATERIAL))
    if coll is not None:
        coll[MATERIALS_DIGEST] = digest
    return True


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


def build_slots(scene, item, params: Params, heightfield=None, terrain_centre=None, look_later: bool = False) -> bool:
    """(Re)create the ground and the blade/card slot objects of the field of ``params``
    (``slots.pool_shapes``); idempotent. ``heightfield``: its terrain in the field's frame (None:
    flat), ``terrain_centre``: the world XY the field is centred on over it. The collection records
    ``slots.topology_key``. Called by ``runtime.apply_settings`` only (datablocks change inside the
    operator or edit that asked for them, never between undo steps). Returns whether the
    materials show ``params`` (``update_field_materials``: ``look_later``, else always)."""
    grid = FieldGrid.of(params)
    coll = ensure_collection(scene, item)
    uid = coll["wg_uid"]
    base = coll.name
    blade_mat, card_mat, ground_mat, canopy_mat = field_materials(item)
    # The ground object stays (the artist's name for it, its place, parent and anything added to
    # it survive the rebuild); its mesh and the slot objects are made anew.
    ground = owned.ground_object(item)
    head_tree = heads.group_of(item) if coll.get(HEADS_KEY) == heads.sources_key(params) else None
    if head_tree is None:  # (kept while what they are made from holds: a density or size edit keeps them)
        heads.remove(item)
    _remove_objects([o for o in owned.field_objects(item) if o is not ground])
    _purge_orphan_meshes(uid)  # (slots deleted by hand): their names are free for the new ones
    for key, data in list(owned.registered(item).items()):  # (the artist's trees read the wind map: it stays)
        if not isinstance(data, (bpy.types.Material, bpy.types.Image)) and data is not ground \
                and key != owned.ROLE_WIND_MAP and not (head_tree is not None and heads.owns(data)):
            del item[owned.MADE_KEY][key]
    painted = paint_look.painted_settings(params, item)
    surface = paint_look.paint_ground(params, heightfield) if painted else heightfield
    heights = _sward_heights(seen_far(params), ground, look_later)
    mesh = meshes.ground_mesh(f"{base} ground", grid.size, surface, *heights, meshes.thinning_edge(params))
    mesh[GROUND_HEIGHTS] = heights
    paint_look.paint_map(item, uid, base, grid if painted else None, canopy_mat)
    if ground is None:
        ground = bpy.data.objects.new(f"{base} ground", mesh)
        _link(coll, ground, None)
    else:
        old_mesh, ground.data = ground.data, mesh
        if old_mesh is not None and old_mesh.users == 0:
            bpy.data.meshes.remove(old_mesh)
            mesh.name = f"{base} ground"
    mesh.materials.append(ground_mat)
    mesh.materials.append(canopy_mat)
    owned.tag(ground, uid, owned.ROLE_GROUND)
    owned.tag(ground.data, uid, owned.ROLE_GROUND)
    owned.record(item, owned.ROLE_GROUND, ground)
    centre = terrain_centre if heightfield is not None else None
    if centre is not None:
        # On a terrain the mesh places the field: centred on it, heights in world Z.
        from mathutils import Matrix

        ground.matrix_basis = Matrix.Translation((centre[0], centre[1], 0.0))
        coll["wg_terrain"] = item.terrain.name if item.terrain is not None else ""
    else:
        if "wg_terrain" in coll and heightfield is None and maps.terrain_object(scene, item) is None:
            del coll["wg_terrain"]

    if head_tree is None:
        head_tree = _build_heads(item, params, uid, base, blade_mat)
    material_of = {owned.ROLE_BLADES: blade_mat, owned.ROLE_CARDS: card_mat}
    for entry in roles.ROLES:
        role, material = entry.name, material_of[entry.name]
        spec = _SlotTopology(grid, params, role)
        first = None
        for i in range(spec.shape.objects):  # once per build, not per frame
            if first is None:
                mesh = first = meshes.quad_mesh(f"{base} {role} {i:03d}", spec.shape.verts_per_object, spec.faces,
                                                spec.uvs, material, spec.attributes, spec.data_uvs)
            else:  # (every slot of a role has the same quads: a copy is a tenth of the time)
                mesh = first.copy()
                mesh.name = f"{base} {role} {i:03d}"
            obj = bpy.data.objects.new(mesh.name, mesh)
            obj.visible_shadow = True
            if head_tree is not None and entry.heads:
                heads.attach(obj, head_tree)
            owned.tag(obj, uid, role, i)
            owned.tag(mesh, uid, role, i)
            leave_out_of_files((obj, mesh))
            _link(coll, obj, ground)
            owned.record(item, owned.slot_key(role, i), obj)
    coll[owned.TOPOLOGY] = topology(params, heightfield, painted)
    return update_field_materials(item, params, scene, later=look_later)


def seen_far(params: Params) -> Params:
    """``params`` as the far grass's look is worked out for them (``plants.seen_far``: an own
    plant's colour for its species), so that the ground's heights and the materials ask the
    look's kept parts for the same settings."""
    return plants.seen_far(params, heads.plant_shapes(params))


GROUND_HEIGHTS = "wg_sward_heights"  # the ground mesh's custom property: (canopy, fringe top) it was made with


def _sward_heights(params: Params, ground, look_later: bool) -> tuple[float, float]:
    """(canopy height, fringe top) of the ground mesh of ``params``: with ``look_later`` (an edit
    in the UI) while the sward's look is still to be worked out, those the ground had (``refit_ground``
    makes it again once the look is ready)."""
    if look_later and not (sward.canopy_height.known(params) and sward.fringe_top.known(params)):
        old = ground.data.get(GROUND_HEIGHTS) if ground is not None and ground.data is not None else None
        return (float(old[0]), float(old[1])) if old is not None and len(old) == 2 else (0.0, 0.0)
    return sward.canopy_height(params), sward.fringe_top(params)


def refit_ground(item, params: Params, heightfield) -> bool:
    """Make the ground mesh again when it was made with other sward heights than those of
    ``params`` (an edit that changes the blades' rest shapes but not the objects, a stiffness; or
    ``_sward_heights``: built while its look was worked out); returns whether it did (the paint's
    look on it is then to be written again)."""
    ground = owned.ground_object(item)
    if ground is None or ground.data is None:
        return False
    far = seen_far(params)
    heights = (sward.canopy_height(far), sward.fringe_top(far))
    old = ground.data.get(GROUND_HEIGHTS)
    if old is not None and tuple(float(h) for h in old) == heights:
        return False
    surface = paint_look.paint_ground(params, heightfield) if paint_look.painted_settings(params, item) \
        else heightfield
    ground.data.clear_geometry()
    meshes.fill_ground(ground.data, FieldGrid.of(params).size, surface, *heights, meshes.thinning_edge(params))
    ground.data[GROUND_HEIGHTS] = heights
    return True


HEADS_KEY = "wg_heads"  # the collection's custom property: heads.sources_key its heads' modifier draws


def _build_heads(item, params: Params, uid: str, base: str, blade_mat):
    """The heads' and leaves' objects and node group for ``params`` (None: no species has any)."""
    item.collection[HEADS_KEY] = heads.sources_key(params)
    return heads.build(item, params, uid, base, blade_mat)  # (None: no heads, leaves or plants)


def refresh_heads(item, params: Params) -> bool:
    """Make the field's heads, leaves and plants again when what its species carry changed (a
    head shape, leaves, an Own Plant: ``heads.sources_key``), its slot objects kept; returns
    whether it did."""
    coll = item.collection
    if coll is None or coll.get(HEADS_KEY) == heads.sources_key(params):
        return False
    blades = owned.slot_objects(item, owned.ROLE_BLADES).values()
    for obj in blades:
        for mod in [m for m in obj.modifiers if m.type == "NODES" and m.name == heads.MODIFIER]:
            obj.modifiers.remove(mod)
    heads.remove(item)
    tree = _build_heads(item, params, coll["wg_uid"], coll.name, owned.registered(item).get(owned.ROLE_BLADE_MATERIAL))
    if tree is not None:
        for obj in blades:
            heads.attach(obj, tree)
    return True


def topology(params: Params, heightfield, painted: bool) -> str:
    """What the field's objects are built for: ``slots.topology_key`` and whether it is painted
    (its ground a grid, its canopy reading a paint map)."""
    key = slots.topology_key(FieldGrid.of(params), params, heightfield)
    return key + (" painted" if painted else "")


class _SlotTopology:
    """What every slot object of a role holds: k copies of one block's quads (``slots.py``,
    ``roles.Role``)."""

    def __init__(self, grid, params: Params, role: str):
        entry = roles.BY_NAME[role]
        self.shape = slots.pool_shapes(grid, params)[role]
        faces, uvs = entry.faces(grid), entry.uvs(grid)
        self.data_uvs: tuple[str, ...] = tuple(materials.UV_OF[name] for name in entry.corner_data)
        self.faces, self.uvs = slots.tiled_topology(faces, uvs, self.shape.verts_per_block, self.shape.k)
        self.attributes = {materials.ATTR_VELOCITY: "FLOAT_VECTOR"}


def leave_out_of_files(blocks, out: bool = True) -> None:
    """Mark slot objects and meshes as runtime data (``out``): Blender writes them into no file it
    writes, saves, autosaves and quit.blend alike (tens of MB of geometry that ``build_slots`` makes
    again from the settings when the file is opened), while its undo steps keep them. A bake's
    slots carry its cache: they are saved (``out`` False)."""
    for block in blocks:
        if block is not None and block.is_runtime_data != out:
            block.is_runtime_data = out


def slot_blocks(item) -> list:
    """The field's slot objects and their meshes."""
    objects = [obj for role in roles.NAMES for obj in owned.slot_objects(item, role).values()]
    return objects + [obj.data for obj in objects]


def slots_missing(item, params: Params) -> bool:
    """Whether the field lacks a slot object its settings give: an opened file has none (they are
    never saved, ``leave_out_of_files``), or the artist deleted one."""
    shapes = slots.pool_shapes(FieldGrid.of(params), params)
    return any(len(owned.slot_objects(item, role)) < shape.objects for role, shape in shapes.items())


GROUND_REFILL = "wg_refill"  # the ground mesh's custom property: its grid was emptied for a save


def clear_ground(scene, item, params: Params) -> bool:
    """Empty the ground grid of a painted field on flat ground before a save (133,000 vertices at
    the default 256 cells a side: the file would grow 13 times); ``fill_ground`` makes it again
    from the settings. A terrain's ground (it follows the terrain mesh) is kept as it is. Returns
    whether it emptied it."""
    ground = owned.ground_object(item)
    layers = ground.data.get("wg_layers") if ground is not None else None
    if layers is None or not int(layers[5] if len(layers) > 5 else layers[3]) or not len(ground.data.vertices):
        return False
    if maps.terrain_object(scene, item) is not None or params.terrain.heightmap:
        return False
    ground.data.clear_geometry()
    ground.data[GROUND_REFILL] = True
    return True


def fill_ground(item, params: Params) -> bool:
    """Make again the ground grid ``clear_ground`` emptied; returns whether it did (the paint's
    look on it is then to be written again)."""
    ground = owned.ground_object(item)
    if ground is None or not ground.data.get(GROUND_REFILL) or len(ground.data.vertices):
        return False
    meshes.fill_ground(ground.data, FieldGrid.of(params).size, paint_look.paint_ground(params, None),
                       sward.canopy_height(params), sward.fringe_top(params), meshes.thinning_edge(params))
    del ground.data[GROUND_REFILL]
    return True


def fill_slots(item, params: Params) -> bool:
    """Give every empty slot mesh of the field its quads again (a file saved by Windgrass before
    slots were left out of files held them empty); returns whether any was filled (its positions
    are then to be written)."""
    grid, filled = FieldGrid.of(params), False
    for role in roles.NAMES:
        objects = owned.slot_objects(item, role)
        empty = [obj for obj in objects.values() if not len(obj.data.vertices)]
        if not empty:
            continue
        spec = _SlotTopology(grid, params, role)
        for obj in empty:
            meshes.fill_quads(obj.data, spec.shape.verts_per_object, spec.faces, spec.uvs, spec.attributes,
                              spec.data_uvs)
            filled = True
    return filled


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
    new_tag = owned.unused_tag(tag.split("#")[0])
    coll["wg_uid"] = new_tag
    reg = owned.registered(item)
    for key, data in list(reg.items()):  # the original's, in no scene (not copied): the copy makes its own
        if data.get("wg_role") in (*owned.IN_NO_SCENE, owned.ROLE_HEAD_GROUP):
            if item.get(owned.MADE_KEY) is not None and key in item[owned.MADE_KEY]:
                del item[owned.MADE_KEY][key]
            del reg[key]
    copies = {}
    for key, data in reg.items():
        if isinstance(data, (bpy.types.Material, bpy.types.Image)):
            copies[data] = data.copy()
            copies[data]["wg_uid"] = new_tag
            owned.record(item, key, copies[data])
    card_mat, image = copies.get(reg.get(owned.ROLE_CARD_MATERIAL)), copies.get(reg.get(owned.ROLE_CARD_IMAGE))
    if card_mat is not None and image is not None:
        materials.set_card_image(card_mat, image)
    for obj in owned.field_objects(item):
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
    reg = owned.registered(item)
    tags = {d.get("wg_uid") for d in reg.values()} | ({coll.get("wg_uid")} if coll is not None else set())
    heads.remove(item)
    wind_force.remove(item)
    _remove_objects(owned.field_objects(item))
    for tag in tags - {None}:
        _purge_orphan_meshes(tag)  # (they use the materials)
    if item.get(owned.MADE_KEY) is not None:
        del item[owned.MADE_KEY]  # its pointers count as users of the materials and the image
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

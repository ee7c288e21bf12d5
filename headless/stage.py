"""Stage for batch renders (paper VI): render settings, sun, sky world and the camera.

It serves the batch scripts (``render_field.py``, ``lod_compare.py``, the benchmarks) and the
tests, not the extension: an artist's scene has its own camera, sun and world.

``setup_stage(scene, params)`` turns the ``[render]`` and ``[camera]`` sections of the schema
into a complete Blender stage around a grass field and returns the camera object.

The paper's tests fly a camera along a predefined path over the field (VI). Here the path is a
pure function of the frame (``camera_pose``): the pose at frame N depends only on the
parameters and N, so any sub-range of frames renders exactly what the full run renders
(render-farm ready). The camera is keyframed on every frame of the scene's range (no handler,
no driver); a renderer that seeks frames should still call ``pose_camera`` before
``scene.frame_set`` because ``frame_change_pre`` handlers (the grass LOD, eqs 7-11) read the
camera before Blender evaluates the keyframes of the new frame.
"""

from __future__ import annotations

import math

import addon_loader
import bpy
import numpy as np
from mathutils import Euler, Vector

addon_loader.load_package()  # the add-on as ``windgrass`` (once), so its modules are imported by that name
from windgrass.grass_addon import sward  # noqa: E402
from windgrass.grass_addon.bridge import animation, materials  # noqa: E402
from windgrass.grass_addon.clock import Clock  # noqa: E402
from windgrass.grass_addon.errors import ParameterError  # noqa: E402
from windgrass.grass_addon.grid import FieldGrid  # noqa: E402

STAGE_TAG = "wg_stage"  # custom property on the objects and data made here

# Flythrough (paper VI "the fly-through path is predefined"). The camera looks this many
# degrees below the horizon: with a 55 deg horizontal view at 16:9 the horizon sits in the
# upper third, so the three LOD bands (blades, cards, ground texture) are all in view.
FLY_PITCH_DEG = 9.0
# Share of the field width between the two straights of the racetrack path, and the margin
# (m, at most) kept between the path and the field edge.
FLY_WIDTH_SHARE = 0.3
FLY_EDGE_MARGIN = 2.0
# Lateral sway of the straights (m, at most): a gentle S so the view is not a plain dolly.
FLY_SWAY = 1.5

SUN_STRENGTH = 4.0  # W/m^2: a clear day under AgX/Filmic without clipping the grass tips
SUN_ANGLE_DEG = 1.5  # angular diameter of the sun light (soft shadow edges of the blades)
SKY_STRENGTH = 0.1  # scale of the physical sky texture so that it matches SUN_STRENGTH
GROUND_HAZE = (0.1, 0.14, 0.08)  # linear RGB of the distant land below the horizon
# Hills on the horizon (setup_world): two ridges whose tops rise and fall with the bearing, in
# radians above the horizon per unit of noise over 0.3 (the far ridge) and 0.4 (the near one),
# seen through the sky's haze (their colour mixes this much of the land's into the sky's).
HILLS_FAR = (0.04, 0.3, 0.45)  # (height per unit noise, noise over which it stands, land's share)
HILLS_NEAR = (0.025, 0.4, 0.65)
HILLS_NOISE = (3.0, 8.0)  # noise scale over the unit circle of bearings: broad far hills, finer near
LAND_HAZE_M = 2500.0  # the land's haze where the scene sets none (render.haze_distance 0)
LAND_DROP_M = 0.05  # the land lies this far below the field's ground
# The land is a flat plane lit by the sun where the grass is blades in each other's shade: its
# colour is the blades' times this (trample.toml at 960x540: the field's last metres and the land
# beyond them come out within 10 % in sRGB).
LAND_LIGHT = 0.4


# --------------------------------------------------------------------------------------------
# Pure geometry (no bpy): the camera path


def field_extent(params) -> tuple[float, float]:
    """Edge lengths (m) of the field along X and Y."""
    return FieldGrid.of(params).size


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def flythrough_pose(params, frame: int | float) -> tuple[tuple[float, float, float], float, float]:
    """Camera ``(position, yaw, pitch)`` of the flythrough at ``frame`` (radians; yaw from +X
    counter-clockwise, pitch < 0 looks down). A pure function of (params, frame).

    The path is a racetrack inside the field: a straight along +Y at x = -w, a half circle of
    radius w, a straight back along -Y at x = +w and a half circle home, with a sin^2 sway on
    the straights (value and slope vanish at the ends, so position and heading are continuous).
    The camera covers ``camera.speed`` metres per second of ``t = (frame - frame_start) / fps``
    (DEVELOPERS.md time convention) at ``camera.height`` above the ground.
    """
    ex, ey = field_extent(params)
    margin = min(FLY_EDGE_MARGIN, 0.1 * min(ex, ey))
    w = max(0.5 * FLY_WIDTH_SHARE * ex, 1e-3)  # half distance between the straights = turn radius
    straight = max(ey - 2.0 * margin - 2.0 * w, 0.0)
    sway = min(FLY_SWAY, 0.15 * w, 0.1 * straight)
    turn = math.pi * w
    lap = 2.0 * straight + 2.0 * turn
    t = Clock.of(params).seconds(frame)
    s_total = params.camera.speed * t
    laps = math.floor(s_total / lap)
    s = s_total - laps * lap
    base = -2.0 * math.pi * laps  # clockwise: the heading loses one turn per lap
    half = 0.5 * straight

    def sway_at(u: float) -> tuple[float, float]:
        # sin^2 bump: offset and its slope d(offset)/du
        if straight <= 0.0:
            return 0.0, 0.0
        k = math.pi / straight
        return sway * math.sin(k * u) ** 2, sway * k * math.sin(2.0 * k * u)

    if s < straight:  # up the left straight, heading +Y
        d, dd = sway_at(s)
        x, y = -w + d, -half + s
        yaw = math.pi / 2 - math.atan(dd)
    elif s < straight + turn:  # top half circle, clockwise from angle pi to 0
        a = math.pi - (s - straight) / w
        x, y = w * math.cos(a), half + w * math.sin(a)
        yaw = a - math.pi / 2
    elif s < 2.0 * straight + turn:  # down the right straight, heading -Y
        u = s - straight - turn
        d, dd = sway_at(u)
        x, y = w - d, half - u
        yaw = -math.pi / 2 - math.atan(dd)
    else:  # bottom half circle, clockwise from angle 0 to -pi
        a = -(s - 2.0 * straight - turn) / w
        x, y = w * math.cos(a), -half + w * math.sin(a)
        yaw = a - math.pi / 2
    pitch = -math.radians(FLY_PITCH_DEG)
    return (x, y, params.camera.height), base + yaw, pitch


def fixed_pose(params) -> tuple[tuple[float, float, float], float, float]:
    """``(position, yaw, pitch)`` looking from camera.position at camera.target."""
    pos = tuple(float(v) for v in params.camera.position)
    target = tuple(float(v) for v in params.camera.target)
    dx, dy, dz = (target[i] - pos[i] for i in range(3))
    horizontal = math.hypot(dx, dy)
    if horizontal + abs(dz) < 1e-6:
        raise ParameterError("camera.target", f"{list(target)} is the camera position itself; "
                                              "the camera needs a point to look at")
    yaw = math.atan2(dy, dx) if horizontal > 1e-9 else math.pi / 2
    return (pos[0], pos[1], pos[2]), yaw, math.atan2(dz, horizontal)


def camera_pose(params, frame: int | float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """``(location, rotation_euler XYZ)`` of the render camera at ``frame``: a pure function.

    A Blender camera looks down its local -Z with +Y up: Euler X = 90 deg + pitch turns the view
    to the horizontal (+Y) and tilts it, Euler Z = yaw - 90 deg turns it to the heading.
    """
    if params.camera.mode == "fixed":
        pos, yaw, pitch = fixed_pose(params)
    else:
        pos, yaw, pitch = flythrough_pose(params, frame)
    return pos, (math.pi / 2 + pitch, 0.0, yaw - math.pi / 2)


# --------------------------------------------------------------------------------------------
# Blender


def eevee_engine_id() -> str:
    """The EEVEE identifier of this Blender: 'BLENDER_EEVEE_NEXT' (4.2-4.5) or 'BLENDER_EEVEE'."""
    prop = bpy.types.RenderSettings.bl_rna.properties["engine"]
    static = [item.identifier for item in prop.enum_items]
    for candidate in ("BLENDER_EEVEE_NEXT", "BLENDER_EEVEE"):
        if candidate in static:
            return candidate
    return "BLENDER_EEVEE_NEXT" if bpy.app.version < (5, 0, 0) else "BLENDER_EEVEE"


def _set_engine(scene, kind: str) -> None:
    if kind == "cycles":
        scene.render.engine = "CYCLES"
        return
    first = eevee_engine_id()
    for ident in (first, "BLENDER_EEVEE_NEXT", "BLENDER_EEVEE"):
        try:
            scene.render.engine = ident
            return
        except TypeError:
            continue
    raise RuntimeError("this Blender has no EEVEE render engine")


def _set_enum(owner, attr: str, *choices: str) -> str | None:
    """Set the first of ``choices`` that ``owner.attr`` accepts; return it (None if none)."""
    for choice in choices:
        try:
            setattr(owner, attr, choice)
            return choice
        except (TypeError, ValueError):
            continue
    return None


def _has_oidn() -> bool:
    try:
        import _cycles
    except ImportError:
        return False
    return bool(getattr(_cycles, "with_openimagedenoise", False))


def setup_render(scene, params) -> None:
    """Engine, samples, resolution, fps, frame range, colour management and PNG output."""
    r = params.render
    render = scene.render
    _set_engine(scene, r.engine)
    render.resolution_x = r.resolution_x
    render.resolution_y = r.resolution_y
    render.resolution_percentage = 100
    render.pixel_aspect_x = render.pixel_aspect_y = 1.0
    render.fps = r.fps
    render.fps_base = r.fps_base
    scene.frame_start = r.frame_start
    scene.frame_end = r.frame_end
    render.use_motion_blur = r.motion_blur  # the frame handler answers every sub-frame step
    render.motion_blur_shutter = r.shutter
    render.film_transparent = False
    settings = render.image_settings
    if hasattr(settings, "media_type"):
        settings.media_type = "IMAGE"
    settings.file_format = "PNG"
    settings.color_mode = "RGB"
    settings.color_depth = "8"
    settings.compression = 15
    # PNG metadata without wall-clock or host values (render_field.py also drops Cycles' render-time
    # text chunks): a frame is the same file on any machine.
    for stamp in ("use_stamp_date", "use_stamp_time", "use_stamp_render_time", "use_stamp_memory",
                  "use_stamp_hostname", "use_stamp_filename"):
        if hasattr(render, stamp):
            setattr(render, stamp, False)
    _set_enum(scene.view_settings, "view_transform", "AgX", "Filmic", "Standard")
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    if r.engine == "cycles":
        cycles = scene.cycles
        cycles.device = "CPU"
        # Keep Cycles' scene between frames: only the grass's edited meshes and the camera are
        # sent again (the ground, materials, atlas and world stay).
        render.use_persistent_data = True
        cycles.samples = r.samples
        cycles.preview_samples = min(r.samples, 32)
        cycles.seed = params.field.seed % (2**31)  # fixed: frame N renders the same on any node
        cycles.use_animated_seed = False
        cycles.use_adaptive_sampling = False  # every pixel gets the same sample count
        cycles.max_bounces = 4
        cycles.diffuse_bounces = 2
        cycles.glossy_bounces = 1
        cycles.transmission_bounces = 2
        # A card holds a few blades (III.B, atlas.card_atlas): a grazing ray crosses dozens of them
        # before one covers it; past this many layers a card stops the ray (materials.card_material),
        # which showed as dark dashes where the card band meets the far canopy from 1.1 m at 64.
        cycles.transparent_max_bounces = 128
        cycles.use_denoising = _has_oidn() and r.samples > 1  # OIDN on the CPU is deterministic
        if cycles.use_denoising:
            _set_enum(cycles, "denoiser", "OPENIMAGEDENOISE")
            cycles.denoising_use_gpu = False
    else:
        eevee = scene.eevee
        eevee.taa_render_samples = r.samples
        # Software GL (no GPU) pays for every megabyte of the pools: keep them modest.
        _set_enum(eevee, "shadow_pool_size", "128")
        _set_enum(eevee, "gi_irradiance_pool_size", "16")
        if hasattr(eevee, "use_raytracing"):
            eevee.use_raytracing = False


def sun_direction(params) -> Vector:
    """Unit vector from the ground towards the sun (render.sun_elevation/azimuth, degrees)."""
    el = math.radians(params.render.sun_elevation)
    az = math.radians(params.render.sun_azimuth)
    return Vector((math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)))


def _tagged(idblock):
    idblock[STAGE_TAG] = True
    return idblock


def setup_sun(scene, params) -> bpy.types.Object:
    """A sun light shining from render.sun_elevation/azimuth (a light shines down its -Z)."""
    data = _tagged(bpy.data.lights.new("Windgrass Sun", type="SUN"))
    data.energy = SUN_STRENGTH
    data.angle = math.radians(SUN_ANGLE_DEG)
    data.color = (1.0, 0.96, 0.9)
    obj = _tagged(bpy.data.objects.new("Windgrass Sun", data))
    scene.collection.objects.link(obj)
    obj.rotation_euler = sun_direction(params).to_track_quat("Z", "Y").to_euler()
    obj.location = (0.0, 0.0, 20.0)
    return obj


def _sky_node(nodes, params):
    """A physical sky texture with the sun where the sun light is; None if this Blender has none.

    Blender's sky models measure the sun rotation from +Y towards -X... as the world direction
    (atan2(x, y)) measures it: rotation = 90 deg - azimuth gives the sun light's direction.
    """
    try:
        sky = nodes.new("ShaderNodeTexSky")
    except RuntimeError:
        return None
    model = _set_enum(sky, "sky_type", "MULTIPLE_SCATTERING", "NISHITA", "HOSEK_WILKIE")
    if model is None:
        nodes.remove(sky)
        return None
    if model == "HOSEK_WILKIE":
        sky.sun_direction = sun_direction(params)
        sky.turbidity = 2.5
    else:
        sky.sun_disc = False  # the sun light draws the direct light; no second sun in the sky
        sky.sun_elevation = math.radians(max(params.render.sun_elevation, 0.0))
        sky.sun_rotation = math.radians(90.0 - params.render.sun_azimuth) % (2.0 * math.pi)
        for name, value in (("air_density", 1.0), ("ozone_density", 1.0), ("aerosol_density", 0.3),
                            ("dust_density", 0.3), ("altitude", 100.0)):
            if hasattr(sky, name):
                setattr(sky, name, value)
    return sky


def setup_world(scene, params, hills: bool = True) -> bpy.types.World:
    """Sky world for both engines: a physical sky above the horizon blended into a hazy land
    colour below it (the field ends; the world beyond it reads as distant land)."""
    world = _tagged(bpy.data.worlds.new("Windgrass Sky"))
    scene.world = world
    if bpy.app.version < (5, 0, 0):  # from 5.0 worlds always use nodes (the flag is deprecated)
        world.use_nodes = True
    tree = world.node_tree
    nodes, links = tree.nodes, tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputWorld")
    background = nodes.new("ShaderNodeBackground")
    links.new(background.outputs["Background"], out.inputs["Surface"])
    coords = nodes.new("ShaderNodeTexCoord")
    split = nodes.new("ShaderNodeSeparateXYZ")
    links.new(coords.outputs["Generated"], split.inputs["Vector"])
    sky = _sky_node(nodes, params)
    if sky is not None:
        sky_colour = sky.outputs["Color"]
        strength = SKY_STRENGTH
    else:
        # Gradient sky: pale horizon to blue zenith along the view direction's Z.
        ramp = nodes.new("ShaderNodeValToRGB")
        links.new(split.outputs["Z"], ramp.inputs["Fac"])
        ramp.color_ramp.elements[0].color = (0.75, 0.82, 0.9, 1.0)
        ramp.color_ramp.elements[1].position = 0.6
        ramp.color_ramp.elements[1].color = (0.18, 0.35, 0.75, 1.0)
        sky_colour = ramp.outputs["Color"]
        strength = 1.0
    land = tuple(LAND_LIGHT * c / strength for c in sward.fringe_colour(params))
    for i, (ridge, scale) in enumerate(zip((HILLS_FAR, HILLS_NEAR), HILLS_NOISE) if hills else ()):
        sky_colour = _hills(tree, split, sky_colour, ridge, scale, land, params.field.seed * 2 + i)
    # Below the horizon: the land colour from 0.25 deg down (direction Z < 0), so the strip
    # between the field edge and the horizon reads as distant land, not as dark sky.
    below = nodes.new("ShaderNodeMapRange")
    below.inputs["From Min"].default_value = 0.0
    below.inputs["From Max"].default_value = -0.004
    below.inputs["To Min"].default_value = 0.0
    below.inputs["To Max"].default_value = 1.0
    below.clamp = True
    links.new(split.outputs["Z"], below.inputs["Value"])
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    links.new(below.outputs["Result"], mix.inputs["Factor"])
    links.new(sky_colour, mix.inputs["A"])
    mix.inputs["B"].default_value = (*(c / strength for c in GROUND_HAZE), 1.0)
    links.new(mix.outputs["Result"], background.inputs["Color"])
    background.inputs["Strength"].default_value = strength
    return world


def _hills(tree, split, behind, ridge, scale: float, land, seed: int):
    """The colour ``behind`` (a socket) with a ridge of hills in front of it on the horizon: its
    top at ``ridge[0] * (noise - ridge[1])`` radians over the bearing, its colour the sky's with
    ``ridge[2]`` of ``land``'s (distant hills are hazed); the ridge moves with ``seed``."""
    nodes, links = tree.nodes, tree.links
    flat = nodes.new("ShaderNodeCombineXYZ")
    links.new(split.outputs["X"], flat.inputs["X"])
    links.new(split.outputs["Y"], flat.inputs["Y"])
    bearing = nodes.new("ShaderNodeVectorMath")
    bearing.operation = "NORMALIZE"
    links.new(flat.outputs["Vector"], bearing.inputs[0])
    noise = nodes.new("ShaderNodeTexNoise")
    noise.noise_dimensions = "4D"
    noise.inputs["W"].default_value = (seed % 997) * 0.731
    noise.inputs["Scale"].default_value = scale
    noise.inputs["Detail"].default_value = 4.0
    links.new(bearing.outputs["Vector"], noise.inputs["Vector"])
    top = nodes.new("ShaderNodeMath")
    top.operation = "MULTIPLY_ADD"
    links.new(noise.outputs["Fac"], top.inputs[0])
    top.inputs[1].default_value = ridge[0]
    top.inputs[2].default_value = -ridge[0] * ridge[1]
    edge = nodes.new("ShaderNodeMath")  # half a minute of arc of soft edge
    edge.operation = "SUBTRACT"
    links.new(top.outputs["Value"], edge.inputs[0])
    edge.inputs[1].default_value = 0.00015
    inside = nodes.new("ShaderNodeMapRange")
    inside.clamp = True
    links.new(split.outputs["Z"], inside.inputs["Value"])
    links.new(top.outputs["Value"], inside.inputs["From Min"])
    links.new(edge.outputs["Value"], inside.inputs["From Max"])
    colour = nodes.new("ShaderNodeMix")
    colour.data_type = "RGBA"
    colour.inputs["Factor"].default_value = ridge[2]
    links.new(behind, colour.inputs["A"])
    colour.inputs["B"].default_value = (*land, 1.0)
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    links.new(inside.outputs["Result"], mix.inputs["Factor"])
    links.new(behind, mix.inputs["A"])
    links.new(colour.outputs["Result"], mix.inputs["B"])
    return mix.outputs["Result"]


def setup_land(scene, params) -> bpy.types.Object:
    """The meadow past the field's edge: a plane to the camera's far clip around the field,
    ``LAND_DROP_M`` below its lowest ground, in the colour of its grass seen from the side, hazed with
    distance (``materials.land_material``), so a field smaller than the view does not end on bare
    ground and a hill-less world."""
    ex, ey = field_extent(params)
    reach = max(1000.0, 4.0 * math.hypot(ex, ey))  # the camera's clip_end (setup_camera)
    mesh = _tagged(bpy.data.meshes.new("Windgrass Land"))
    mesh.from_pydata([(-reach, -reach, 0.0), (reach, -reach, 0.0), (reach, reach, 0.0), (-reach, reach, 0.0)],
                     [], [(0, 1, 2, 3)])
    r = params.render
    haze = r.haze_distance if r.haze_distance > 0.0 else LAND_HAZE_M
    colour = [LAND_LIGHT * c for c in sward.fringe_colour(params)]
    mesh.materials.append(_tagged(materials.land_material("Windgrass Land", colour, haze, r.haze_color)))
    obj = _tagged(bpy.data.objects.new("Windgrass Land", mesh))
    obj.location = (0.0, 0.0, -LAND_DROP_M)  # a heightmap's black is the ground's 0
    scene.collection.objects.link(obj)
    return obj


def setup_camera(scene, params) -> bpy.types.Object:
    """The render camera, keyframed on every frame of the scene's range from ``camera_pose``."""
    data = _tagged(bpy.data.cameras.new("Windgrass Camera"))
    data.sensor_fit = "HORIZONTAL"
    data.angle = math.radians(params.camera.fov)
    ex, ey = field_extent(params)
    data.clip_start = 0.05
    data.clip_end = max(1000.0, 4.0 * math.hypot(ex, ey))
    obj = _tagged(bpy.data.objects.new("Windgrass Camera", data))
    scene.collection.objects.link(obj)
    scene.camera = obj
    obj.rotation_mode = "XYZ"
    key_camera_path(obj, params, scene.frame_start, scene.frame_end)
    pose_camera(scene, params, scene.frame_current)
    return obj


def key_camera_path(obj, params, first: int, last: int) -> None:
    """A key on every frame from ``first`` to ``last`` for the camera's location and rotation,
    written in bulk (a 10,000-frame range keys in a fraction of a second)."""
    frames = np.arange(first, last + 1, dtype=np.float32)
    poses = [camera_pose(params, int(f)) for f in frames]
    values = {"location": np.array([p[0] for p in poses], np.float32),
              "rotation_euler": np.array([p[1] for p in poses], np.float32)}
    obj.location, obj.rotation_euler = poses[0][0], Euler(poses[0][1], "XYZ")
    obj.keyframe_insert("location", frame=first)
    obj.keyframe_insert("rotation_euler", frame=first)
    for fcurve in animation.action_fcurves(obj.animation_data):
        column = values.get(fcurve.data_path)
        if column is None:
            continue
        points = fcurve.keyframe_points
        points.clear()
        points.add(len(frames))
        points.foreach_set("co", np.stack([frames, column[:, fcurve.array_index]], axis=1).ravel())
        fcurve.update()  # sort, and the automatic handles of the new keys


def pose_camera(scene, params, frame: int) -> None:
    """Put the scene camera at its pose of ``frame`` now (before ``scene.frame_set(frame)``, so
    that frame handlers, the grass LOD among them, already see the new view)."""
    cam = scene.camera
    location, rotation = camera_pose(params, frame)
    cam.location = location
    cam.rotation_euler = Euler(rotation, "XYZ")
    view_layer = bpy.context.view_layer if bpy.context.scene == scene else scene.view_layers[0]
    view_layer.update()


def setup_stage(scene, params, surroundings: bool = True) -> bpy.types.Object:
    """Render settings, sun, sky world, the scene file's colliders and camera for ``params``;
    returns the camera object. ``surroundings``: the hills and the land past the field (off for
    comparisons of the grass alone: ``lod_compare.py``)."""
    setup_render(scene, params)
    setup_sun(scene, params)
    setup_world(scene, params, hills=surroundings)
    if surroundings:
        setup_land(scene, params)
    setup_colliders(scene, params)
    return setup_camera(scene, params)


def setup_colliders(scene, params) -> list:
    """A visible ball or capsule for each ``[[colliders]]`` row, keyed along its path (straight
    between keys, as the grass feels it). The grass reads the rows themselves, not these objects."""
    clock = Clock.of(params)
    material = bpy.data.materials.get("Windgrass Collider") or bpy.data.materials.new("Windgrass Collider")
    material.diffuse_color = (0.55, 0.12, 0.08, 1.0)
    materials.with_nodes(material)
    bsdf = material.node_tree.nodes.get("Principled BSDF")
    if bsdf is not None:
        bsdf.inputs["Base Color"].default_value = (0.55, 0.12, 0.08, 1.0)
        bsdf.inputs["Roughness"].default_value = 0.6
    made = []
    for i, row in enumerate(params.interaction.colliders):
        name = f"Collider {i + 1}"
        mesh = bpy.data.meshes.new(name)
        _capsule_mesh(mesh, row["radius"], row["length"] if row["shape"] == "capsule" else 0.0)
        mesh.materials.append(material)
        obj = bpy.data.objects.new(name, mesh)
        scene.collection.objects.link(obj)
        for key in row["path"]:
            obj.location = key["position"]
            obj.keyframe_insert("location", frame=clock.frame_at(key["time"]))
        for fc in animation.action_fcurves(obj.animation_data):
            for point in fc.keyframe_points:
                point.interpolation = "LINEAR"
        made.append(obj)
    return made


def _capsule_mesh(mesh, radius: float, length: float, rings: int = 12, segments: int = 24) -> None:
    """A UV sphere of ``radius``, its halves ``length`` apart along Z (a capsule when > 0)."""
    verts, faces = [], []
    for r in range(rings + 1):
        phi = math.pi * r / rings
        z = radius * math.cos(phi) + (0.5 * length if r <= rings // 2 else -0.5 * length)
        for k in range(segments):
            a = 2.0 * math.pi * k / segments
            verts.append((radius * math.sin(phi) * math.cos(a), radius * math.sin(phi) * math.sin(a), z))
    for r in range(rings):
        for k in range(segments):
            a, b = r * segments + k, r * segments + (k + 1) % segments
            faces.append((a, b, b + segments, a + segments))
    mesh.from_pydata(verts, [], faces)
    for poly in mesh.polygons:
        poly.use_smooth = True
    mesh.update()

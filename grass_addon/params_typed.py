"""The parameters' types for the type checker, generated from ``schema.PARAMS`` by
``schema.typed_source`` (``python3.11 dev.py params`` writes it again): do not edit. Imported
(by ``schema``) only while type checking; at run time a section is a ``schema.Section``."""

from __future__ import annotations

from typing import Any, TypedDict


class KeyPoint(TypedDict):
    time: float
    position: tuple[float, ...]


class Section:
    def as_dict(self) -> dict[str, Any]:
        raise NotImplementedError


class FieldSection(Section):
    blocks_x: int
    blocks_y: int
    cells_per_block: int
    cell_size: float
    blades_per_cell: int
    seed: int
    clumping: float
    clump_size: float
    patchiness: float
    patch_size: float
    flower_drift: float
    edge: float
    floor: str


class BladeSpeciesRow(TypedDict):
    name: str
    weight: float
    length: float
    length_variation: float
    width: float
    stiffness: float
    color: tuple[float, ...]
    density_map: str
    heads: float
    head_color: tuple[float, ...]
    head_size: float
    head_shape: str
    plant: str
    plant_mode: str
    leaves: str
    leaf_size: float


class BladeSection(Section):
    segments: int
    tip_width: float
    inclination: float
    root_stiffness: float
    stiffness_offset: float
    density: float
    nonlinear_stiffness: float
    response_torque: float
    twist_stiffness: float
    damping_mass: float
    air_damping: float
    damping_stiffness: float
    boundary_k: float
    boundary_lambda: float
    dry_tips: float
    species: tuple[BladeSpeciesRow, ...]


class WindKeysRow(TypedDict):
    time: float
    speed: float
    direction: float


class WindSection(Section):
    type: str
    speed: float
    direction: float
    turbulence: float
    turbulence_scale: float
    turbulence_period: float
    gust_speed: float
    gust_width: float
    gust_interval: float
    vortex_radius: float
    vortex_speed: float
    gust_waves: float
    gust_wave_size: float
    gust_stretch: float
    keys: tuple[WindKeysRow, ...]


class LodSection(Section):
    enabled: bool
    blade_near: float
    blade_far: float
    card_near: float
    card_far: float
    screen_size: bool
    viewport_amount: float
    card_width: float
    card_height: float


class TerrainSection(Section):
    heightmap: str
    height: float
    extent: tuple[float, ...]


class PaintSection(Section):
    density: str
    length: str
    extent: tuple[float, ...]


class KeepOutShapesRow(TypedDict):
    shape: str
    center: tuple[float, ...]
    size: tuple[float, ...]
    radius: float
    angle: float


class KeepOutSection(Section):
    margin: float
    falloff: float
    shapes: tuple[KeepOutShapesRow, ...]


class InteractionCollidersRow(TypedDict):
    shape: str
    radius: float
    length: float
    path: tuple[KeyPoint, ...]


class InteractionEffectorsRow(TypedDict):
    type: str
    position: tuple[float, ...]
    rotation: tuple[float, ...]
    shape: str
    strength: float
    falloff: float
    falloff_type: str
    min_distance: float
    max_distance: float
    noise: float
    size: float
    seed: int


class InteractionSection(Section):
    recovery: float
    tolerance: float
    colliders: tuple[InteractionCollidersRow, ...]
    effectors: tuple[InteractionEffectorsRow, ...]


class CameraSection(Section):
    mode: str
    height: float
    fov: float
    speed: float
    position: tuple[float, ...]
    target: tuple[float, ...]


class RenderSection(Section):
    engine: str
    samples: int
    resolution_x: int
    resolution_y: int
    fps: int
    fps_base: float
    frame_start: int
    frame_end: int
    motion_blur: bool
    shutter: float
    sun_elevation: float
    sun_azimuth: float
    haze_distance: float
    haze_color: tuple[float, ...]


class SimulationSection(Section):
    sub_steps: int
    preroll: float
    loop: float
    epoch: float
    cache_mb: int
    memory_mb: int


class Sections:
    """What ``Params`` holds: one attribute per section."""

    field: FieldSection
    blade: BladeSection
    wind: WindSection
    lod: LodSection
    terrain: TerrainSection
    paint: PaintSection
    keep_out: KeepOutSection
    interaction: InteractionSection
    camera: CameraSection
    render: RenderSection
    simulation: SimulationSection

"""What a field costs in memory in Blender, and the refusal of settings that need more than allowed.

A field's memory follows what the camera can reach, not the field's size: the slot meshes of its
two pools (sized from ``lod.blade_far`` and ``lod.card_far``, ``slots.pool_shapes``), the blocks and
solver states of the window within the card range, and the saved states of its trajectories. It
grows with ``lod.card_far`` squared: at 100 m the card pool alone holds 13 million vertices.
``estimate`` adds these up from the parameters; ``check`` refuses, before anything is built, a
field whose estimate exceeds ``simulation.memory_mb`` or the machine's memory, naming
``lod.card_far`` and the longest card range that fits.

Blender's cost of a slot mesh per vertex was measured on Blender 5.0 (positions, edges, loops,
three UV maps, velocity: about 160 bytes) and Cycles' copy of it for a render (about 270 bytes);
the simulation is counted for a window of the whole disc within the card range (a panoramic
camera or several 3D views need it; one camera needs about a fifth), so the estimate is an upper
bound: the default scene renders in 2.0 GB at lod.card_far 40 m (estimate 2.9 GB), 3.0 GB at 60 m
(4.6 GB).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from . import images, paint, slots
from .clock import Clock
from .errors import ParameterError
from .grid import FieldGrid
from .lod import block_reach
from .schema import Params
from .simulation import CHECKPOINT_FRAMES, MAX_CHECKPOINT_BYTES, seek_cost_bound

SLOT_BYTES_PER_VERTEX = 430  # a slot mesh's vertex in Blender (about 160 B) and in the renderer (about 270 B)
BASE_BYTES = 600 << 20  # Blender, Python and numpy with the add-on loaded, before any field
STATE_FLOATS_PER_JOINT = 8  # bend, bend rate, bend equilibrium (2 each), twist, twist rate
TRAJECTORIES = 2  # live at once: an epoch's and, over its last half-warm-up, the next one's
BLOCK_BYTES_PER_BLADE = 4 * 16  # a block's blade arrays (root, facing, length, width, ... rest tilt)


@dataclass(frozen=True)
class Estimate:
    """Bytes a field takes: its slot meshes and vertex buffers, its blocks and simulation."""

    meshes: int
    buffers: int
    simulation: int
    maps: int = 0  # decoding the largest of its PNG maps (they are read one at a time)

    @property
    def total(self) -> int:
        return BASE_BYTES + self.meshes + self.buffers + self.simulation + self.maps


def map_files(params: Params) -> list[tuple[str, str]]:
    """(setting, path) of every PNG file the field reads (maps and the heightmap)."""
    named = paint.map_settings(params) + [("terrain.heightmap", params.terrain.heightmap)]
    return [(name, path) for name, path in named if path and not path.startswith(paint.BLENDER_SOURCES)]


def maps_bytes(params: Params, resolve=str) -> tuple[int, str | None]:
    """(bytes, setting) of the largest PNG map to decode (``resolve``: a path as the file system
    knows it, e.g. Blender's ``//`` paths made absolute); (0, None) without maps."""
    largest, name = 0, None
    for setting, path in map_files(params):
        size = images.peek_size(resolve(path))
        if size is not None and images.decoded_bytes(*size) > largest:
            largest, name = images.decoded_bytes(*size), setting
    return largest, name


def estimate(params: Params, grid: FieldGrid | None = None, resolve=str) -> Estimate:
    """What a field of ``params`` takes in Blender at most (bytes), from its parameters and the
    headers of its PNG maps (``resolve``: see ``maps_bytes``)."""
    grid = grid or FieldGrid.of(params)
    vertices = sum(shape.positions * shape.verts_per_block for shape in slots.pool_shapes(grid, params).values())
    buffers = vertices * 12 * 3  # float32 xyz: the frame's vertices, velocities and the later pose
    window = slots.blocks_within(grid, params.lod.card_far + block_reach(params)[0] + 2 * grid.block_size)
    if not params.lod.enabled:
        window = grid.n_blocks
    cells = window * grid.cells_per_block_total
    state = cells * grid.segments * STATE_FLOATS_PER_JOINT * 4
    every = max(CHECKPOINT_FRAMES, round(Clock.of(params).rate))
    checkpoints = min(MAX_CHECKPOINT_BYTES, state * (seek_cost_bound(params) // every + 1))
    blocks = window * (grid.blades_per_block * (BLOCK_BYTES_PER_BLADE + 4 * grid.segments)
                       + grid.cells_per_block_total * 4 * (16 + grid.segments))
    simulation = blocks + state * (TRAJECTORIES + 1) + TRAJECTORIES * checkpoints
    return Estimate(meshes=vertices * SLOT_BYTES_PER_VERTEX, buffers=buffers, simulation=simulation,
                    maps=maps_bytes(params, resolve)[0])


def machine_bytes() -> int | None:
    """This machine's physical memory (bytes), or None where the system does not say."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def _mb(n: float) -> str:
    return f"{n / 2**20:,.0f} MB"


def longest_card_far(params: Params, allowed: int) -> float:
    """The longest ``lod.card_far`` (m, at least ``lod.card_near``) whose estimate fits ``allowed``
    bytes; ``lod.card_near`` itself when even that does not fit."""
    low, high = float(params.lod.card_near), float(params.lod.card_far)
    if estimate(params.replace({"lod.card_far": low})).total > allowed:
        return low
    for _ in range(40):
        mid = 0.5 * (low + high)
        if estimate(params.replace({"lod.card_far": mid})).total <= allowed:
            low = mid
        else:
            high = mid
    return low


def check(params: Params, resolve=str) -> Estimate:
    """The field's estimate, or ParameterError (naming ``lod.card_far``) when it needs more than
    ``simulation.memory_mb`` allows or this machine has; the message suggests only values that
    fit the machine."""
    need = estimate(params, resolve=resolve)
    allowed = int(params.simulation.memory_mb) << 20
    machine = machine_bytes()
    limit = allowed if machine is None else min(allowed, int(0.8 * machine))
    if need.total <= limit:
        return need
    if need.total - need.maps <= limit:  # the field fits: a map is too large for what is left
        _, setting = maps_bytes(params, resolve)  # (need.maps > 0: some map is the largest)
        raise ParameterError(setting or "paint", f"decoding this map takes about {_mb(need.maps)}, and with the "
                             f"field's "
                             f"{_mb(need.total - need.maps)} that is more than {_mb(limit)}; valid: a map of "
                             "fewer pixels (8-bit grey is enough for a map), or more simulation.memory_mb")
    card_far = max(float(params.lod.card_near), math.floor(longest_card_far(params, limit)))  # a value that fits
    where = (f"this machine has {_mb(machine)}" if machine is not None and limit != allowed
             else f"simulation.memory_mb allows {_mb(allowed)}")
    more = ""
    if machine is not None and need.total <= 0.8 * machine:
        more = f", or raise simulation.memory_mb to at least {need.total / 2**20:,.0f}"
    raise ParameterError(
        "lod.card_far",
        f"{params.lod.card_far:g} m of cards needs about {_mb(need.total)} in Blender (meshes {_mb(need.meshes)}, "
        f"simulation {_mb(need.simulation)}) but {where}; valid: lod.card_far up to {card_far:.0f} m{more}")

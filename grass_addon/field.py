"""The engine facade: one grass field = blocks + wind + simulation + LOD + kinematics.

Used by the add-on's runtime (one ``GrassField`` per field object) and by the headless scripts.
The field works on a window of blocks (``layout``): the blocks the camera can see within the card
range (``view``), or, without a camera, the whole field when it is small enough
(``WHOLE_FIELD_CELLS``) and else the blocks around its centre (``notice`` says so). Blocks come
from a cache bounded by ``simulation.cache_mb``; nothing is made for the whole field.

What the settings decide is made once (``FieldModel``: parameters, clock, grid of blocks, the slot
pools' shapes, whether the field is simulated whole); the ``GrassField`` holds what changes (the
window, the wind, the simulation, the colliders, the frame buffers).

One frame is one call, ``frame(frame, subframe, views, blur)``: the window of blocks the views
need, the state (wind, solver, cell data with the colliders' push and trample), LOD (eqs 7-11),
which blocks each role shows, their vertices (colliders cleared: ``clearance.py``; bare cells
collapsed) and velocities, the gust offset and the trail map, as a ``frame.Frame`` the bridge
only writes. ``blade_vertices`` and ``card_vertices`` give any blocks' vertices by the same fill.
"""

from __future__ import annotations

import copy
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from . import clearance, edit_parts, forces, interaction, loop, slots, wind_map
from .blocks import BlockCache, Species
from .celldata import CellData
from .clock import Clock
from .errors import ParameterError
from .far_sway import WindowSim
from .frame import BLADES, CARDS, Frame, RoleFrame, block_distance, needs
from .grid import FieldGrid
from .kinematics import carry_constants
from .layout import FieldLayout, build_layout, window_layout
from .lod import (
    Camera,
    LodWeights,
    block_reach,
    block_visible,
    camera_eye,
    lod_fewer,
    lod_weights,
    screen_scale,
    views,
    views_key,
)
from .roles import BY_NAME as ROLE_OF
from .roles import ROLES, Role
from .schema import Params
from .wind import WindField
from .wind_map import FieldMap, MapGrid, most_common, nearest_points, point_mean

RECENT_FRAMES = 4  # states kept by cells_at (frames N - 1 .. N + 1, and the one before)
WHOLE_FIELD_CELLS = 1 << 18  # without a camera (or with LOD off) fields this small (51 m) are simulated whole
WINDOW_MARGIN_BLOCKS = 1.0  # the window reaches this many blocks past what the camera needs
GLIMPSE_S = 0.75  # seconds of wind a first look simulates (``GrassField.first_look``)
FIRST_LOOK_BLOCKS = 256  # a new field's first look draws its levels of detail only as far as the
# nearest this many blocks the views see reach (``GrassField.most_blocks``; a 100 m field's window from
# eye level at 1920 x 1080: 920): it makes those first, the far canopy drawn from nearer, and shows in half the time
WINDOW_SLACK = 2.0  # a window is kept while it holds at most this many times the blocks needed


@dataclass(frozen=True)
class FieldModel:
    """What a field's settings decide, derived once and never changed (the immutable half of a
    ``GrassField``, like the constants of a Warp example's simulation object)."""

    params: Params
    clock: Clock  # the scene's frame rate and first frame: seconds of a frame
    grid: FieldGrid  # blocks and cells
    shapes: dict[str, slots.PoolShape]  # role -> the slot pool's shape (slots.pool_shapes)
    whole: bool  # small enough (WHOLE_FIELD_CELLS) to simulate whole without a camera
    loop: int  # P: the wind repeats after this many frames (loop.py); 0: never

    @classmethod
    def of(cls, params: Params) -> FieldModel:
        grid = FieldGrid.of(params)
        return cls(params, Clock.of(params), grid, slots.pool_shapes(grid, params),
                   grid.n_blocks * grid.cells_per_block ** 2 <= WHOLE_FIELD_CELLS, loop.loop_frames(params))


@dataclass(eq=False)
class _RoleBuffers:
    """One role's frame arrays, kept between frames: float32 (positions x verts_per_block, 3), zero
    beyond the rows filled; ``velocity`` and ``ahead`` (the later pose) made when motion blur first
    asks."""

    vertices: np.ndarray
    velocity: np.ndarray | None = None
    ahead: np.ndarray | None = None
    rows: int = 0  # rows of ``vertices`` filled last frame
    velocity_rows: int = 0  # and of ``velocity``
    filled: tuple | None = None  # (frame, count, cells, LOD weights, blocks) ``vertices`` holds, but motion's

    def holds(self, frame: int, count: int, *objects) -> bool:
        """``vertices`` holds the fill of ``frame`` for these ``count`` blocks and these objects
        (the cell data, the LOD weights, the blocks' positions: the same objects, not equal ones)."""
        filled = self.filled
        return (filled is not None and filled[:2] == (frame, count)
                and all(a is b for a, b in zip(filled[2:], objects, strict=True)))

    def motion(self) -> tuple[np.ndarray, np.ndarray]:
        """(velocity, ahead), made at first use."""
        if self.velocity is None or self.ahead is None:
            self.velocity, self.ahead = np.zeros_like(self.vertices), np.empty_like(self.vertices)
        return self.velocity, self.ahead


class GrassField:
    """``GrassField(params, wind_keys=None, terrain=None, paint=None, colliders=None,
    effectors=None)``; wind_keys: None (params.wind) or (time_s, speed, deg) rows; terrain: a
    ``terrain.Heightfield`` in the field's frame or None (flat); paint: a ``paint.Paint`` (where
    grass grows, how tall) or None; colliders: objects with ``at(t) -> interaction.Spheres``
    (None: the scene file's ``[[colliders]]``); effectors: an object with ``at(t) -> [forces.Effector]``
    (None: the scene file's ``[[effectors]]``); before: the block cache (a ``fork``) of a field
    whose settings differ only in the blades' rest shapes (``blocks.reshapes``: a stiffness edit),
    its blocks made again from the blades they grew."""

    def __init__(self, params: Params, wind_keys=None, terrain=None, paint=None, colliders=None, effectors=None,
                 progress=None, before: BlockCache | None = None):
        self.model = model = FieldModel.of(params)
        self._buffers: dict[str, _RoleBuffers] = {}  # role -> its frame arrays
        self._cells_frame: int | None = None  # the frame ``cells`` holds
        self.cache = BlockCache(params, terrain, budget=int(params.simulation.cache_mb) << 20, paint=paint,
                                before=before)
        self._check_budget(params)
        self.notice: str | None = None
        cells = self.grid.n_blocks * self.grid.cells_per_block ** 2
        if model.whole:
            layout = build_layout(params, terrain, cache=self.cache)
        else:  # blocks are made when the first view (a camera, or none: the centre) asks for them
            layout = window_layout(self.cache, [])
            self.notice = (f"the field has {cells:,} cells, too many to simulate whole without a camera; "
                           f"the blocks within lod.card_far ({params.lod.card_far:g} m) of its centre are used")
        self._viewed = self.whole
        self._scale = 1.0  # the views' screen scale of the LOD distances (``lod_scale``)
        self.layout: FieldLayout = layout
        self.wind = WindField(layout, params, keys=wind_keys)
        self._wind_keys = wind_keys
        self.interaction: interaction.Interaction | None = None
        self.effectors = None
        self._progress = progress  # (done, total) of a long seek, or None
        self._twin = False  # a twin not yet retuned: it shares its simulation with its original
        self._colours: tuple[object, dict] = (None, {})  # (window, {role: its slots' data kept: RoleFrame.colours})
        self._map_kept: tuple | None = None  # (window, map grid, the field map's parts: _map_static)
        self._lod_kept: tuple | None = None  # (window, settings, (scale, amount, views), LodWeights: ``lod``)
        self._shown_kept: dict[str, tuple] = {}  # role -> (window, LOD weights, distances, its blocks' positions)
        self._view_kept: tuple | None = None  # (window, settings, run, views) of the last ``view``: none to do again
        self.sim = self._simulation(self.wind)
        self.cells: CellData | None = None  # cell data of the last seek
        self._recent: OrderedDict[int, CellData] = OrderedDict()  # states of frames around the shown one
        self.set_interaction(interaction.colliders_from_params(params) if colliders is None else colliders,
                             forces.effectors_from_params(params) if effectors is None else effectors)

    # ------------------------------------------------------------------ what the settings decide (the model's)

    @property
    def params(self) -> Params:
        return self.model.params

    @property
    def clock(self) -> Clock:
        return self.model.clock

    @property
    def grid(self) -> FieldGrid:
        return self.model.grid

    @property
    def shapes(self) -> dict[str, slots.PoolShape]:
        return self.model.shapes

    @property
    def whole(self) -> bool:
        return self.model.whole

    @classmethod
    def of_scene(cls, params: Params, wind_keys=None) -> GrassField:
        """The field of a scene file's settings with its ``[terrain]`` heightmap and ``[paint]``
        maps read from disk (the numpy-only scripts; in Blender the bridge reads them)."""
        from . import images, paint, terrain

        return cls(params, wind_keys, terrain=terrain.from_params(params, images.read_map),
                   paint=paint.from_params(params, images.read_map))

    # ------------------------------------------------------------------ the window of blocks

    def _check_budget(self, params: Params) -> None:
        """The blocks a camera can see within the card range of ``params`` must fit the cache."""
        radius = params.lod.card_far + block_reach(params)[0] + 2 * WINDOW_MARGIN_BLOCKS * self.grid.block_size
        need = slots.blocks_within(self.grid, radius)
        if need > self.cache.capacity():
            mb = -(-need * self.cache.block_bytes() // 2**20)
            raise ParameterError(
                "simulation.cache_mb",
                f"{params.simulation.cache_mb} MB holds {self.cache.capacity():,} blocks, but a camera can see "
                f"{need:,} within lod.card_far ({params.lod.card_far:g} m); valid: at least {mb} MB "
                "(or a shorter lod.card_far)")

    # ------------------------------------------------------------------ edits in place

    def can_retune(self, params: Params) -> bool:
        """``params`` changes no block of this field (``edit_parts``): ``retune`` takes it in place."""
        return edit_parts.LAYOUT not in edit_parts.changed_parts(self.params, params)

    def reruns(self, params: Params, wind_keys=None) -> bool:
        """``retune`` to ``params`` (and the animated wind ``wind_keys``) simulates again: the wind or
        the solver changed (the costly edits in place: ``twin`` does them elsewhere)."""
        return bool(edit_parts.changed_parts(self.params, params) & edit_parts.SIMULATED) \
            or wind_keys is not self._wind_keys

    def twin(self, progress=None) -> GrassField:
        """A twin to ``retune`` with a new run on another thread (``bridge/builds.py``) while this
        field goes on showing its frames: it shares the blocks made so far (never changed once
        made) and its own cache, frame buffers and, once retuned, window, wind and simulation; this
        field is left as it is. ``progress``: the twin's long seeks report to it."""
        twin = copy.copy(self)
        twin.cache = self.cache.fork()
        twin._buffers, twin._recent, twin._colours, twin._map_kept = {}, OrderedDict(), (None, {}), None
        twin._shown_kept = {}
        twin.cells, twin._cells_frame = None, None
        twin._progress = progress
        twin._twin = True
        return twin

    most_blocks = 0  # the blocks its views see within its LOD distances, at most (``view``; 0: any number)

    def first_look(self, seconds: float = GLIMPSE_S, most_blocks: int = 0) -> GrassField:
        """A first look of this field's run, to show while the run works out its first frame (an
        edit's new run or new field, ``bridge/builds.py``): a twin with its own wind and run whose
        trajectories each start from rest ``seconds`` before the frame first asked of them and step
        three frames at a time (``Simulation.glimpse``), so that frame costs a few steps, not the
        warm-up's and the epoch's frames. Its blades lean as far as this field's do (their mean bend
        within a few per cent) and sway in the same wind, but their phases are not its frames (a
        third of their bend apart): it is shown, never made an engine. ``most_blocks``: its LOD
        distances shortened until its views see so many blocks within them (a new field's,
        ``FIRST_LOOK_BLOCKS``: fewer blocks to make before it shows; 0: this field's)."""
        look = self.twin()
        look.most_blocks = int(most_blocks)
        colliders = [] if self.interaction is None else self.interaction.colliders
        look.retune(self.params, wind_keys=self._wind_keys, colliders=colliders, effectors=self.effectors)
        look.sim.glimpse = max(1, self.clock.frames(seconds))
        return look

    def retune(self, params: Params, wind_keys=None, colliders=None, effectors=None) -> frozenset[str]:
        """Take the settings ``params`` (``can_retune``) in place: the blocks are kept; the wind
        and the solver's run are made again only when the wind, the solver or the animated wind
        (``wind_keys``, a new object) changed (always for a ``twin``); a colour or LOD edit keeps
        the run. Frames are then the bits a new ``GrassField`` of these settings gives.
        ``colliders`` and ``effectors`` as in ``__init__`` (the effectors are taken only with a
        new run). Returns the parts changed."""
        parts = edit_parts.changed_parts(self.params, params)
        if edit_parts.LAYOUT in parts:
            raise ValueError("retune: these settings change the field's blocks; make a new GrassField")
        self._check_budget(params)  # (before anything changes)
        rerun = self._twin or self.reruns(params, wind_keys)
        self._twin = False  # (its own run from here on)
        self._map_kept = None
        old_shapes, old_layout = self.shapes, self.layout
        self.model = FieldModel.of(params)
        species = Species(params)
        self.cache.params, self.cache.species = params, species
        # the same blocks and cells: the layout's arrays and the blades' constants are kept
        layout = old_layout.retitled(params, species.color, species.head_color)
        carry_constants(old_layout, layout)
        if edit_parts.LOOK not in parts:  # (the slots' colours and marks hold)
            self._colours = (layout, self._colours[1]) if self._colours[0] is old_layout else (None, {})
        self.layout = layout
        if rerun:
            self.wind = WindField(layout, params, keys=wind_keys)
            self._wind_keys = wind_keys
            forces.check_count(effectors)
            self.effectors = effectors
            self.sim = self._simulation(forces.ForcedWind(self.wind, effectors) if effectors is not None else self.wind)
        else:  # a look or LOD edit: the run goes on as it is
            self.sim.retitle(layout)
        colliders = interaction.colliders_from_params(params) if colliders is None else colliders
        self.set_interaction(colliders, self.effectors)
        if self.shapes != old_shapes:
            self._buffers = {}
        self.cells, self._cells_frame = None, None
        return parts

    def _centre_blocks(self) -> np.ndarray:
        return self.grid.blocks_near(np.zeros(2), self.params.lod.card_far + block_reach(self.params)[0])

    def blocks_for(self, camera, margin: float = 0.0) -> np.ndarray:
        """Ids (ascending) of the blocks that ``camera`` (a ``lod.Camera``, several, or None)
        needs: in a camera's view and within the card range of its eye (plus ``margin`` metres);
        every block when LOD is off or without a camera on a small field."""
        cams = views(camera)
        if not cams:
            return (np.arange(self.grid.n_blocks, dtype=np.int64) if self.whole else self._centre_blocks())
        if not self.params.lod.enabled:
            if not self.whole:
                raise ParameterError("lod.enabled", "every blade as geometry needs a field of at most "
                                     f"{WHOLE_FIELD_CELLS:,} cells; turn LOD on or make the field smaller")
            return np.arange(self.grid.n_blocks, dtype=np.int64)
        reach = block_reach(self.params)[0]
        found = []
        for cam in cams:
            eye = camera_eye(cam)
            ids = self.grid.blocks_near(eye[:2], self.params.lod.card_far * self._scale + reach + margin)
            if ids.size == 0:
                continue
            z = self._z_ranges(ids)
            # the eye's height above the ground can only add distance: cells past card_far hold no cards
            found.append(ids[block_visible(self.grid.block_bounds(ids), z, cam, self.params, margin)])
        ids = np.unique(np.concatenate(found)) if found else np.zeros(0, np.int64)
        if self.cache.paint is not None and self.cache.paint.thins and ids.size:
            # blocks painted out hold nothing to simulate or draw (the far canopy shows them bare)
            ids = ids[[not block.empty for block in self.cache.get(ids)]]
        return ids

    def _z_ranges(self, ids: np.ndarray) -> np.ndarray:
        terrain = self.cache.terrain
        if terrain is None:
            return np.zeros((ids.size, 2))
        return terrain.box_z_range(self.grid.block_bounds(ids))

    def view(self, camera, frame: int | None = None) -> bool:
        """Make the window hold the blocks ``camera`` (one ``lod.Camera``, several or None) needs
        (returns True when it changed). With
        LOD on, the window reaches a block further than needed and is kept while it still holds
        every needed block and is not much larger, so a moving camera changes it every few frames.
        ``frame``: the frame about to be shown (trajectories not needed there are not caught up)."""
        key = (self.layout, self.params, self.sim, views_key(camera))
        kept = self._view_kept
        if kept is not None and all(a is b for a, b in zip(kept[:3], key[:3])) and kept[3] == key[3]:
            return False  # (the same views of the same window and run: a still camera's frames)
        self._viewed = True
        self._scale = self.lod_scale(camera)
        if self.most_blocks:
            self._scale = self._scale_for(views(camera), self.most_blocks, self._scale)
        moved = self._move_window(camera, frame)
        if self.sim.look(views(camera), self._scale, frame) and not moved:  # (far_sway: near blocks, band)
            self.cells = None
            self._recent.clear()
        self._view_kept = (self.layout, self.params, self.sim, key[3])
        return moved

    def _move_window(self, camera, frame: int | None) -> bool:
        needed = self.blocks_for(camera)
        current = self.layout.block_ids
        if np.array_equal(needed, current):
            return False
        windowed = bool(views(camera)) and self.params.lod.enabled
        if windowed and np.isin(needed, current).all() and current.size <= WINDOW_SLACK * needed.size + 16:
            return False
        if not windowed and self.whole:
            layout = build_layout(self.params, self.cache.terrain, cache=self.cache)
        else:
            wanted = self.blocks_for(camera, margin=WINDOW_MARGIN_BLOCKS * self.grid.block_size) if windowed \
                else needed
            layout = window_layout(self.cache, wanted)
        self.sim.set_layout(layout, frame=frame, cameras=views(camera), scale=self._scale)
        self.layout = layout
        self.cells = None
        self._recent.clear()
        return True

    def repaint(self, paint, frame: int | None = None) -> int:
        """Grow by ``paint`` (a ``paint.Paint`` or None) from now on, making again only the blocks
        its change touches (``paint.changed_region``); their cells are simulated again where the
        blades' lengths changed, so the state is what a field made with this paint would have.
        Returns how many blocks were made again."""
        from .paint import EVERYWHERE, changed_region

        old, new = self.cache.paint, (None if paint is None or paint.empty else paint)
        region = changed_region(old, new)
        if region is None:
            return 0
        if (old is None) != (new is None):  # every block gains (or loses) its blades' growing flags
            region = EVERYWHERE
        shapes = changed_region(old, new, shapes=True)  # where the blades' lengths or species changed
        self.cache.paint = new
        touched = self.cache.drop(region)
        renewed = self.layout.block_ids[self._touching(self.layout.block_ids, shapes)] if shapes else ()
        if self.whole:
            layout = build_layout(self.params, self.cache.terrain, cache=self.cache)
        else:
            ids = self.layout.block_ids
            if new is not None and new.thins and ids.size:
                ids = ids[[not block.empty for block in self.cache.get(ids)]]
            layout = window_layout(self.cache, ids)
        self.sim.set_layout(layout, frame=frame, renewed=renewed)
        self.layout = layout
        self.cells = None
        self._recent.clear()
        return touched

    def _touching(self, ids: np.ndarray, region) -> np.ndarray:
        """(len(ids),) bool: the block's ground rectangle meets the box ``region``."""
        b = self.grid.block_bounds(ids)
        x0, y0, x1, y1 = region
        return (b[:, 2] >= x0) & (b[:, 0] <= x1) & (b[:, 3] >= y0) & (b[:, 1] <= y1)

    def set_interaction(self, colliders, effectors) -> None:
        """Colliders (a list, empty for none) and effectors (None for none) from now on. New
        effectors change the wind the solver steps in, so the simulation starts again; colliders
        only change what is shown on top of it."""
        colliders = list(colliders or [])
        if colliders:
            terrain = self.cache.terrain
            ground = (lambda xy: np.zeros(len(xy))) if terrain is None else terrain.sample
            top = max(float(sp["length"]) for sp in self.params.species())
            self.interaction = interaction.Interaction(colliders, self.params, self.grid, ground, top)
        else:
            self.interaction = None
        if effectors is not self.effectors:
            forces.check_count(effectors)
            self.effectors = effectors
            wind = forces.ForcedWind(self.wind, effectors) if effectors is not None else self.wind
            self.sim = self._simulation(wind)
        self.cells = None
        self._recent.clear()

    def update_colliders(self, colliders, effectors) -> None:
        """The colliders' motion was sampled again: the force fields stay as they are (their
        settings are part of what made this field) unless they appeared or went (a damaged
        stored motion sampled again)."""
        kept = self.effectors
        self.set_interaction(colliders, kept if (kept is None) == (effectors is None) else effectors)

    def loop_notes(self) -> list[str]:
        """What keeps this field's frames from repeating with its ``simulation.loop`` (``loop.notes``)."""
        return loop.notes(self.params, self.wind.keyed, self.interaction is not None, self.effectors)

    def report_progress(self, progress) -> None:
        """Long seeks report ``progress(done, total)`` from now on (None: not at all)."""
        self._progress = progress
        self.sim.progress = progress

    def _simulation(self, wind) -> WindowSim:
        """A new run in ``wind``; a field already seen starts it with the blocks its views need
        simulated cell by cell (``far_sway``)."""
        before = getattr(self, "sim", None)
        sim = WindowSim(self.layout, self.params, wind, near_ids=before.seen_near() if before is not None else None)
        sim.progress = self._progress
        return sim

    def _cell_data(self, frame: int, state, wind: np.ndarray) -> CellData:
        """The cell data of ``state`` at ``frame`` (``celldata.cell_data``'s, views, no copy), with
        the colliders' push and trample on top when there are colliders."""
        if self.interaction is not None:
            omega2, damping = self.sim.recovery_oscillator()
            over = self.interaction.bend(frame, self.layout, state.bend_t, omega2, damping)
            if over is not None:
                state = state.overlaid(over)
        return CellData(wind=wind, bend_t=state.bend_t, twist_t=state.twist_t, state=state,
                        card_height=self.layout.card_height)

    # ------------------------------------------------------------------ time

    def seek(self, frame: int, camera: Camera | None = None) -> CellData:
        """Deterministic state at `frame` (a function of params, seed and frame only) of the
        window's cells; ``camera``: move the window to what it needs first."""
        if camera is not None or not self._viewed:
            self.view(camera, frame)
        self.sim.seek(int(frame))
        self.cells = self._cell_data(int(frame), self.sim.state, self.sim.cell_wind)
        self._cells_frame = int(frame)
        return self.cells

    def cells_at(self, frame: int) -> CellData:
        """Cell data of ``frame`` from its own copy of the state, kept with those of the few frames
        around it (motion blur reads frames N - 1, N and N + 1); deterministic like ``seek``."""
        frame = int(frame)
        cells = self._recent.get(frame)
        if cells is None:
            self.sim.seek(frame)
            cells = self._cell_data(frame, self.sim.state.copy(), self.sim.cell_wind.copy())
            self._recent[frame] = cells
            while len(self._recent) > RECENT_FRAMES:
                self._recent.popitem(last=False)
        return cells

    def motion(self, frame: int, subframe: float, vertices, out: np.ndarray, velocity: np.ndarray,
               ahead: np.ndarray) -> None:
        """Vertices at ``frame + subframe`` and their velocity in m/s, for motion blur.

        ``vertices(frame, cells, out)`` writes the vertices of some blocks for cell data ``cells``
        of ``frame``; ``ahead`` (shaped as ``out``) is scratch space for the later pose. The path
        through the frames' poses is piecewise linear: between frames the vertices move at the
        slope of their segment; at a whole frame the velocity is the central difference
        (P(N + 1) - P(N - 1)) fps / 2. Frames are computed in ascending order (cheap seeks)."""
        frame, fps = int(frame), self.clock.rate
        wanted: tuple[int, ...] = (frame - 1, frame, frame + 1) if subframe == 0.0 else (frame, frame + 1)
        cells = [self.cells_at(f) for f in wanted]
        if subframe == 0.0:
            vertices(wanted[0], cells[0], velocity)  # P(N - 1)
            vertices(wanted[2], cells[2], ahead)  # P(N + 1)
            vertices(wanted[1], cells[1], out)  # P(N)
            np.subtract(ahead, velocity, out=velocity)
            velocity *= np.float32(0.5 * fps)
        else:
            vertices(wanted[0], cells[0], out)  # P(N)
            vertices(wanted[1], cells[1], ahead)  # P(N + 1)
            np.subtract(ahead, out, out=velocity)  # one frame's motion
            out += velocity * np.float32(subframe)
            velocity *= np.float32(fps)

    def _current(self) -> tuple[int, CellData]:
        """(frame, cell data) of the current frame (computed when not yet)."""
        if self.cells is None or self._cells_frame is None:
            self.cells = self._cell_data(self.sim.frame, self.sim.state, self.sim.cell_wind)
            self._cells_frame = self.sim.frame
        return self._cells_frame, self.cells

    # ------------------------------------------------------------------ one frame

    def frame(self, frame: int, subframe: float = 0.0, views=None, blur: bool = False, amount: float = 1.0) -> Frame:
        """Everything drawn of the field at ``frame + subframe`` seen from ``views`` (one
        ``lod.Camera``, several, or None: every block as geometry from the field's centre): the
        window of blocks, the state, LOD, each role's blocks and vertices, with their velocities
        when ``blur`` (the scene's motion blur) or at a sub-frame. ``amount``: the share of each
        cell's blades (eq 9's N) drawn (``lod.viewport_amount`` in the viewport; 1 in renders).
        The arrays are the field's own, rewritten by the next call."""
        frame, subframe = int(frame), float(subframe)
        self.view(views, frame)  # the same window: no work
        if self.cells is None or self._cells_frame != frame:
            self.seek(frame)  # (the same frame seen from other views reuses its state)
        lod = self.lod(views, amount)
        distance = block_distance(self.layout, lod, views)
        motion = blur or subframe != 0.0
        parts = {role.name: self._role_frame(role, frame, subframe, lod, distance, motion) for role in ROLES}
        t = self.clock.seconds(frame, subframe)
        gust = self._gust(frame, subframe) if self.params.wind.gust_waves > 0.0 else None
        return Frame(frame, subframe, t, lod, parts, gust, self._trail(frame, views))

    def _gust(self, frame: int, subframe: float) -> tuple:
        """What the far grass's gust shading reads at ``frame + subframe``: (displacement, mean
        speed, the displacement of the loop's other pattern, (its weight now, the other's));
        without a loop the other pattern weighs 0 (``loop.py``: the loop's time from its frame, so
        frames a loop apart read the same bits)."""
        wind = self.wind
        t = self.clock.seconds(loop.wind_frame(frame, self.clock.frame_start, self.model.loop), subframe)
        if not wind.loop:
            shift = wind.displacement(t)
            return shift, wind.mean(t)[0], shift, (1.0, 0.0)
        tau, w = loop.phase(t, wind.loop)
        return wind.displacement(tau), wind.mean(tau)[0], wind.displacement(tau - wind.loop), loop.weights(w)

    def _role_frame(self, role: Role, frame: int, subframe: float, lod, distance, motion: bool) -> RoleFrame:
        """One role's blocks (the nearest that need it, up to the pool's positions, in block
        order), their vertices and, with ``motion``, velocities."""
        shape, layout = self.shapes[role.name], self.layout
        known = self._shown_kept.get(role.name)
        if known is not None and known[0] is layout and known[1] is lod and known[2] is distance:
            shown, local, count = known[3:]  # (the same window and LOD weights: the same blocks)
        else:
            chosen = slots.nearest_blocks(needs(role.name, layout, lod), distance, shape.positions)
            shown = slots.assign_positions(shape.positions, layout.block_ids[chosen])
            count = len(chosen)
            local = np.full(shown.shape, slots.FREE, dtype=np.int64)
            local[:count] = np.searchsorted(layout.block_ids, shown[:count])
            self._shown_kept[role.name] = (layout, lod, distance, shown, local, count)
        buffers = self._role_buffers(role.name)
        vertices, velocity = buffers.vertices, None
        rows = count * shape.verts_per_block
        blocks = local[:count]

        def fill(f, cells, out):
            self._fill(role, f, cells, blocks, lod, out)

        if motion:
            velocity, ahead = buffers.motion()
            if count:
                self.motion(frame, subframe, fill, vertices[:rows], velocity[:rows], ahead[:rows])
            velocity[rows:buffers.velocity_rows] = 0.0
            buffers.velocity_rows = rows
        elif count and not buffers.holds(frame, count, self.cells, lod, local):  # (asked again: no fill)
            fill(frame, self.cells, vertices[:rows])
        buffers.filled = None if motion else (frame, count, self.cells, lod, local)
        vertices[rows:buffers.rows] = 0.0  # FREE positions are zero (those beyond were zero already)
        buffers.rows = rows
        kept = None
        if role.data_by_blocks:  # (kept while the window and its blocks' slots hold)
            if self._colours[0] is not layout:
                self._colours = (layout, {})
            kept = self._colours[1].setdefault(role.name, {})
            if len(kept) > 4 * shape.objects:
                kept = self._colours[1][role.name] = {}
        return RoleFrame(role.name, shape, layout, lod, shown, local, count, vertices, velocity, colours=kept)

    def prepare_frame(self, frame: int, views=None) -> None:
        """Work out ``frame`` seen from ``views`` ahead (a background build, ``bridge/builds.py``):
        its state and the data of every slot kept by its blocks (the blades' colours and marks), so
        that writing it after is quick."""
        for part in self.frame(frame, 0.0, views).roles():
            if ROLE_OF[part.role].data_by_blocks:
                for index in range(part.shape.objects):
                    part.attributes(index, True)

    def _role_buffers(self, role: str) -> _RoleBuffers:
        """``role``'s frame arrays (made at first use)."""
        buffers = self._buffers.get(role)
        if buffers is None:
            shape = self.shapes[role]
            buffers = self._buffers[role] = _RoleBuffers(np.zeros((shape.positions * shape.verts_per_block, 3),
                                                                  np.float32))
        return buffers

    def _trail(self, frame: int, cameras):
        """The trail map the far canopy shows (None: no colliders, LOD off, or nothing trampled
        where the canopy is drawn, beyond lod.card_near of the views ``cameras``)."""
        if self.interaction is None or not self.params.lod.enabled:
            return None
        eyes = [camera_eye(cam) for cam in views(cameras)]
        return self.interaction.trail_map(frame, eyes, float(self.params.lod.card_near) * self._scale)

    def wind_map(self, frame: int) -> tuple[wind_map.MapGrid, np.ndarray]:
        """The wind the grass feels at ``frame`` on a grid over the window of blocks, at half the
        grass's height (``wind_map.py``: what Blender's hair and cloth blow with): (grid, (points,
        2) float32 m/s)."""
        ids = self.layout.block_ids
        if len(ids):
            b = self.grid.block_bounds(ids)
            bounds = (b[:, 0].min(), b[:, 1].min(), b[:, 2].max(), b[:, 3].max())
        else:  # (no block in the window: the field's own rectangle)
            o, s = self.grid.origin, self.grid.block_size
            bounds = (o[0], o[1], o[0] + s * self.grid.blocks_x, o[1] + s * self.grid.blocks_y)
        grid = wind_map.map_grid(bounds)
        xy = grid.points()
        height = 0.5 * float(np.mean(self.layout.cell_length)) if self.layout.n_cells else 0.0
        points = np.column_stack([xy, np.full(len(xy), height)])
        return grid, self.sim.wind_at(int(frame), points)

    def field_map(self, frame: int) -> FieldMap:
        """What an artist's node trees read of the field at ``frame`` on the wind map's grid
        (``wind_map.FieldMap``): the wind there, and the height, bend, flatness, tops and species
        of the simulated cells nearest each point."""
        frame = int(frame)
        grid, wind = self.wind_map(frame)
        lay = self.layout
        cells = self.cells if self.cells is not None and self._cells_frame == frame else self.cells_at(frame)
        ground, height, species, at, grows, base = self._map_static(grid)
        bend_sum = np.add.reduce(cells.bend_t, axis=0)  # (2, C): eq 33's summed bend vector
        omega = np.hypot(bend_sum[0], bend_sum[1])
        flat = np.zeros(grid.count)
        if self.interaction is not None:
            omega2, damping = self.sim.recovery_oscillator()
            flat = point_mean(grid, at, self.interaction.flatness(frame, lay, omega2, damping), grows)
        tip = base + point_mean(grid, at, cells.card_offset, grows)  # eq 34: the cards' tops M' on their feet
        bend = point_mean(grid, at, omega, grows)
        return FieldMap(grid, ground, wind, height, bend.astype(np.float32), flat.astype(np.float32),
                        tip.astype(np.float32), species)

    def _map_static(self, grid: MapGrid):
        """The field map's parts that hold while the window and its grid do: (the ground's height,
        the grass's height, the main species at each point, each cell's nearest point, each cell's
        weight: the share of its blades that grow, the cards' feet at each point: the ground where
        none grows)."""
        lay = self.layout
        kept = self._map_kept
        if kept is not None and kept[0] is lay and kept[1] == grid:
            return kept[2]
        xy = grid.points()
        ground = lay.terrain.sample(xy).astype(np.float64) if lay.terrain is not None else np.zeros(grid.count)
        at = nearest_points(grid, lay.cell_center)
        grows = (lay.cell_density.astype(np.float64) if lay.cell_density is not None else np.ones(lay.n_cells))
        height = point_mean(grid, at, lay.card_height, grows).astype(np.float32)  # (a card stands as tall as its cell)
        alive = lay.blade_alive if lay.blade_alive is not None else slice(None)
        blade_at = nearest_points(grid, lay.blade_root[alive, :2])
        species = most_common(grid, blade_at, lay.blade_species[alive].astype(np.int64), len(lay.species_color))
        feet = np.column_stack([lay.cell_center, lay.cell_ground + lay.card_height])
        base = point_mean(grid, at, feet, grows)
        none = np.bincount(at, grows, minlength=grid.count) <= 0
        base[none] = np.column_stack([xy, ground])[none]
        parts = (ground, height, species, at, grows, base)
        self._map_kept = (lay, grid, parts)
        return parts

    # ------------------------------------------------------------------ LOD

    def lod(self, camera, amount: float = 1.0) -> LodWeights:
        """Eqs 7-11 per cell and culling per block for one camera or several (all geometry when
        camera is None), the distances scaled for their screens (``lod_scale``, found by ``view``);
        ``amount`` < 1: that share of each cell's blades (``lod_fewer``). Kept while the window,
        the settings and the views hold: a still camera's weights are worked out once, and the
        same object tells the slots their LOD-weighted data (the cards' opacity) still hold."""
        key = (self._scale, float(amount), views_key(camera))
        kept = self._lod_kept
        if kept is not None and kept[0] is self.layout and kept[1] is self.params and kept[2] == key:
            return kept[3]
        lod = lod_weights(self.layout, camera, self.params, self._scale)
        if amount < 1.0:
            lod = lod_fewer(lod, amount)
        self._lod_kept = (self.layout, self.params, key, lod)
        return lod

    def lod_scale(self, camera) -> float:
        """The views' screen scale of the LOD distances (``lod.screen_scale``), lowered until the
        blocks they see within the scaled blade and card ranges fit the pools' positions and the
        window the block cache: the detail a person sees, at a bounded cost. Depends on the views
        and the settings alone."""
        cams = views(camera)
        scale = screen_scale(cams, self.params)
        if scale <= 1.0:
            return 1.0
        lod, reach = self.params.lod, block_reach(self.params)[0]
        distance = self._seen_distances(cams, lod.card_far * scale + reach)
        room = self.cache.capacity() // 2  # (the window's margin and the blocks kept around it)
        for role in ROLES:  # (the cards' window is also bounded by the block cache: ``room``)
            far, positions = float(getattr(lod, role.far)), min(self.shapes[role.name].positions, room)
            scale = _nearest(distance, positions, far, scale)
        return max(1.0, scale)

    def _scale_for(self, cams, blocks: int, scale: float) -> float:
        """``scale`` lowered until the views see at most ``blocks`` blocks within the card range."""
        far = float(self.params.lod.card_far)
        return _nearest(self._seen_distances(cams, far * scale + block_reach(self.params)[0]), blocks, far, scale)

    def _seen_distances(self, cams, radius: float) -> np.ndarray:
        """(m,) ascending: the distance from the nearest eye to each block some view sees within
        ``radius`` of its eye (its ground box's nearest point, as ``lod._block_distance``)."""
        found_ids, found_d = [np.zeros(0, np.int64)], [np.zeros(0)]
        for cam in cams:
            eye = camera_eye(cam)
            ids = self.grid.blocks_near(eye[:2], radius)
            if ids.size == 0:
                continue
            ids = ids[block_visible(self.grid.block_bounds(ids), self._z_ranges(ids), cam, self.params)]
            b, z = self.grid.block_bounds(ids), self._z_ranges(ids)
            found_ids.append(ids)
            found_d.append(np.sqrt((np.clip(eye[0], b[:, 0], b[:, 2]) - eye[0]) ** 2
                                   + (np.clip(eye[1], b[:, 1], b[:, 3]) - eye[1]) ** 2
                                   + (np.clip(eye[2], z[:, 0], z[:, 1]) - eye[2]) ** 2))
        ids, d = np.concatenate(found_ids), np.concatenate(found_d)
        if len(cams) > 1 and ids.size:  # a block several views see: its nearest eye's
            order = np.lexsort((d, ids))
            ids, d = ids[order], d[order]
            d = d[np.concatenate([[True], ids[1:] != ids[:-1]])]
        return np.sort(d)

    def all_blocks(self) -> np.ndarray:
        """Every block of the window, as local ids 0 .. n_blocks-1."""
        return np.arange(self.layout.n_blocks, dtype=np.int64)

    # ------------------------------------------------------------------ geometry

    def _fill(self, role: Role, frame: int, cells: CellData, blocks, lod, out):
        """The vertices of ``blocks`` (local ids) of ``role`` for ``cells`` of ``frame``, as drawn
        (``roles.Role``): blades hidden beyond N (eq 9) and bent out of the colliders; cards of
        bare cells collapsed."""
        blocks = np.asarray(blocks, np.int64).reshape(-1)
        out = role.vertices(self.layout, cells, blocks, lod, out)
        if role.cleared and self.interaction is not None:
            self._clear_colliders(self.interaction, frame, blocks, out)
        density = self.layout.cell_density
        if role.bare_collapsed and density is not None and len(blocks):
            # a cell where nothing grows shows nothing: its quad collapsed onto its first corner
            bare = density[self.layout.block_cells[blocks]] <= 0.0
            quads = out.reshape(len(blocks), self.layout.cells_per_block_total, -1, 3)
            quads[bare] = quads[bare][:, :1]
        return out

    def _clear_colliders(self, touch: interaction.Interaction, frame: int, blocks: np.ndarray,
                         vertices: np.ndarray) -> None:
        """Blades of ``blocks`` still reaching into a collider at ``frame`` are bent out of every
        sphere at once (``clearance.clear_blades``: roots fixed, lengths kept, above the ground).
        Only the blocks within a sphere's reach are looked at."""
        spheres = touch.spheres(self.clock.seconds(frame))
        if not len(spheres) or not len(blocks):
            return
        reach = float(np.max(self.layout.cell_length, initial=0.0)) * 1.5 + touch.tolerance
        b = self.grid.block_bounds(self.layout.block_ids[blocks])[:, None, :]
        c, r = spheres.centres[None], spheres.radii[None] + reach
        near = ((b[..., 0] <= c[..., 0] + r) & (b[..., 2] >= c[..., 0] - r)
                & (b[..., 1] <= c[..., 1] + r) & (b[..., 3] >= c[..., 1] - r)).any(axis=1)
        rows = np.flatnonzero(near)
        if not len(rows):
            return
        n, bpb = self.layout.segments, self.layout.blades_per_block
        view = vertices.reshape(len(blocks), bpb, n + 1, 2, 3)
        strips = view[rows].reshape(len(rows) * bpb, n + 1, 2, 3)
        if clearance.clear_blades(strips, spheres.centres, spheres.radii, touch.tolerance, touch.ground):
            view[rows] = strips.reshape(len(rows), bpb, n + 1, 2, 3)

    def blade_vertices(self, blocks, lod: LodWeights | None = None, out: np.ndarray | None = None) -> np.ndarray:
        """Blade strip vertices of ``blocks`` at the current frame as drawn (``_fill``)."""
        frame, cells = self._current()
        return self._fill(ROLE_OF[BLADES], frame, cells, blocks, lod, out)

    def card_vertices(self, blocks, out: np.ndarray | None = None) -> np.ndarray:
        """Card vertices of ``blocks`` at the current frame (paper III.B, eq 34), bare cells collapsed."""
        frame, cells = self._current()
        return self._fill(ROLE_OF[CARDS], frame, cells, blocks, None, out)


def _nearest(distance: np.ndarray, count: int, far: float, scale: float) -> float:
    """``scale`` lowered, where needed, so that only the nearest ``count`` blocks (``distance``:
    ascending) are within ``far`` times it (those nearer)."""
    if far > 0.0 and len(distance) > count and distance[count] < far * scale:
        return float(distance[count]) / far
    return scale

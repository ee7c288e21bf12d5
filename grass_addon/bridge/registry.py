"""The one piece of module-level state of the add-on: one live record per field, by key, and a few flags.

A key is ``(scene.session_uid, field uid)``: Blender keeps a scene's session uid through renames
and undo and gives a copied scene a new one. Nothing in the .blend refers to a record: the
registry is emptied on file load and each field is resolved again from its stored settings (the
state at frame N is a function of the parameters, the seed and N). A field's record goes as one
(``forget_missing``), so nothing of a deleted field is left behind.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..roles import BLADES, CARDS

if TYPE_CHECKING:
    from ..clock import Clock
    from ..field import GrassField
    from ..schema import Params
    from .pools import SlotPool

Key = tuple[int, str]


def key_of(scene, item) -> Key:
    return scene.session_uid, str(item.uid)


@dataclass(frozen=True, eq=False)
class Engine:
    """A field's engine (``GrassField``), its slot pools (one a role, ``roles.ROLES``) and what it
    was built from (one ``resolve._build``): a new one replaces it whole."""

    field: GrassField
    params: Params  # validated, with the scene's clock (without the animated wind's values)
    digest: str  # of the parameters, the animated wind, the topology, the force fields, the terrain
    ground: str  # of the force fields and the terrain alone: an engine kept through edits in place needs the same
    wind_fingerprint: str  # of the animated wind's F-curves ("" when not animated)
    wind_keys: tuple | None
    terrain_key: str  # maps.terrain_key of the terrain the engine grows on ("" for none)
    topology: str  # slots.topology_key: what the slot objects must be built for
    pools: dict[str, SlotPool]  # role -> its slot pool

    @property
    def blades(self) -> SlotPool:
        return self.pools[BLADES]

    @property
    def cards(self) -> SlotPool:
        return self.pools[CARDS]


@dataclass(eq=False)
class LiveField:
    """Everything the add-on keeps of one field between frames and edits.

    Its engine (``resolve.resolve`` makes it; ``built`` until ``drop``) with the paint and motion it
    was told of since; what its objects show now; the inputs sampled from Blender and kept
    (terrain, paint); and what waits: an edit to settle (``pending``), settings to resolve again
    (``stale``), a stroke or collider motion to apply. The methods say what happened; the frame
    pass and the timers read what it means. ``field``, ``params``, ``blades``, ... are the
    engine's (a field used before it is resolved is a fault of the add-on: LookupError)."""

    key: Key
    engine: Engine | None = None
    clock: tuple[Clock, int] | None = None  # the scene's clock and frame_end it was resolved with
    painted: str = ""  # paint.fingerprint of the paint the engine grows
    track: str = ""  # tracks.fingerprint of the stored collider motion the engine uses
    last_repaint: tuple = ()  # (seconds, blocks made again) of the last stroke applied
    # what its objects show now (frame_pass)
    frame: int | None = None  # the frame last written (None: write it again)
    subframe: float = 0.0  # and its sub-frame (motion-blur steps)
    camera_signature: tuple | None = None
    blades_drawn: int | None = None  # how many blades its objects draw now (the panel says it)
    paint_shown: str | None = None  # paint.fingerprint of the paint the ground and paint map show
    trail: Any = None  # the trail map the far canopy shows (interaction.TrailMap | None)
    trail_written: bool = False  # the canopy's trail image and mapping were written for ``trail``
    lod_scale: float = 1.0  # the screen's scale of the LOD distances its far canopy shows (lod.screen_scale)
    # inputs sampled from Blender and kept
    terrain: tuple | None = None  # (terrain key, heightfield, centre) as sampled
    paint: tuple | None = None  # (what it was read from, paint.Paint | None)
    paint_deps: frozenset = frozenset()  # (ID type, name) of the datablocks its paint reads
    strokes: int = 0  # edits of those datablocks so far (painting)
    # what waits, and the UI's
    error: str | None = None  # why the field cannot be simulated now (its grass is hidden)
    stale: bool = False  # its settings were edited since it was resolved: resolve again
    pending: float | None = None  # time.monotonic() of an edit waiting to settle (UI), else None
    waiting_since: float | None = None  # time.monotonic() of the first edit waiting (a drag's first step)
    stroked: bool = False  # a stroke waits to be shown
    stroke_s: float = 0.0  # seconds its last stroke took to show
    moved: bool = False  # its colliders or force fields were edited: look at their stored motion
    hidden_for_paint: bool | None = None  # hidden in the viewport while its terrain is painted (None: not yet set)
    building: Any = None  # builds.Build of its new engine on a thread (UI edits), else None
    look_waiting: bool = False  # its materials wait for their look, worked out on a thread (look.ask)

    @property
    def built(self) -> bool:
        """Its engine is resolved (and not dropped since)."""
        return self.engine is not None

    @property
    def resolved(self) -> Engine:
        if self.engine is None:
            raise LookupError(f"the field {self.key} is used before it is resolved")
        return self.engine

    @property
    def field(self) -> GrassField:
        return self.resolved.field

    @property
    def params(self) -> Params:
        return self.resolved.params

    @property
    def digest(self) -> str:
        return self.resolved.digest

    @property
    def topology(self) -> str:
        return self.resolved.topology

    @property
    def wind_keys(self) -> tuple | None:
        return self.resolved.wind_keys

    @property
    def pools(self) -> dict[str, SlotPool]:
        """Its slot pools, one a role (``roles.ROLES``)."""
        return self.resolved.pools

    @property
    def blades(self) -> SlotPool:
        return self.resolved.blades

    @property
    def cards(self) -> SlotPool:
        return self.resolved.cards

    @property
    def heightfield(self):
        """The terrain the engine grows on (``terrain.Heightfield``), None on flat ground."""
        return self.field.cache.terrain

    def edited(self) -> None:
        """Its settings (or what its engine is built from) changed: resolve it again before the next write."""
        self.stale = True

    # -- what the engine was made or told of (resolve.py)

    def resolved_at(self, clock) -> None:
        """Its engine is resolved for the settings now, on the scene's ``clock`` (clock, frame_end)."""
        self.stale = False
        self.clock = clock

    def engine_made(self, engine: Engine, painted: str, track: str, kept: bool = False) -> None:
        """``engine`` replaces its engine, grown with the paint ``painted`` and the collider motion
        ``track``; ``kept``: the same ``GrassField`` retuned (its objects keep what they show but for
        the frame), else a new one (nothing of it is shown yet)."""
        self.engine, self.painted, self.track = engine, painted, track
        self.frame, self.camera_signature = None, None
        if not kept:
            self.subframe, self.last_repaint = 0.0, ()
            self.paint_shown, self.trail, self.trail_written = None, None, False

    def colliders_told(self, track: str) -> None:
        """Its engine took the collider motion ``track``: the frame is written again."""
        self.track, self.frame = track, None

    def repainted(self, painted: str, seconds: float, made: int) -> None:
        """Its engine grows the paint ``painted`` now (``made`` blocks made again in ``seconds``)."""
        self.painted, self.frame = painted, None
        self.last_repaint = (seconds, made)

    def sampled_terrain(self, terrain: tuple) -> None:
        """(terrain key, heightfield, centre) as just sampled."""
        self.terrain = terrain

    def sampled_paint(self, signature, paint, deps: frozenset) -> None:
        """The paint as just read from what ``signature`` names, and the datablocks it read."""
        self.paint, self.paint_deps = (signature, paint), deps

    def build_started(self, job) -> None:
        """Its new engine is being made on a thread (``builds.Build``)."""
        self.building = job

    def build_dropped(self) -> None:
        """The build that ran is taken (or no longer wanted)."""
        self.building = None

    # -- what its objects show (frame_pass.py, lifecycle.py, handlers.py)

    def written(self, frame: int, subframe: float, camera_signature, blades_drawn: int | None = None) -> None:
        """Its objects show ``frame + subframe`` seen from the views of ``camera_signature``,
        ``blades_drawn`` blades."""
        self.frame, self.subframe, self.camera_signature = frame, subframe, camera_signature
        self.blades_drawn = blades_drawn

    def unwritten(self) -> None:
        """Its objects show no frame of it now (hidden, or rebuilt): the next update writes one."""
        self.frame = None

    def lod_scaled(self, scale: float) -> None:
        """The far canopy shows the LOD distances times ``scale`` (the frame's screen scale)."""
        self.lod_scale = scale

    def trail_shown(self, trail) -> None:
        """The far canopy's trail image and mapping show ``trail`` (None: no trails)."""
        self.trail, self.trail_written = trail, True

    def paint_look_shown(self) -> None:
        """The ground and the paint map show the paint its engine grows."""
        self.paint_shown = self.painted

    def paint_look_lost(self) -> None:
        """The painted ground was made again (emptied by a save): its look is written again."""
        self.paint_shown = None

    def shown_while_painting(self, hidden: bool) -> None:
        """Its objects are hidden in the viewport (``hidden``) while its terrain is painted, or not."""
        self.hidden_for_paint = hidden

    def no_error(self) -> None:
        """An update found nothing against it."""
        self.error = None

    # -- what waits (edits.py)

    def motion_looked_at(self) -> None:
        """Its colliders' and force fields' stored motion was looked at after their edit."""
        self.moved = False

    def stroke_shown(self, seconds: float | None) -> None:
        """The strokes that waited are shown (``seconds``: how long it took, None: none waited)."""
        self.stroked = False
        if seconds is not None:
            self.stroke_s = seconds

    def look_waits(self, waiting: bool) -> None:
        """Its materials wait for the look of its settings (``look.ask``), or show it."""
        self.look_waiting = waiting

    def edit_waits(self, now: float) -> None:
        """An edit in the UI waits to be shown (at ``now``): shown once the edits settle, or while
        a drag goes on every ``edits.FOLLOW_S``."""
        self.pending = now
        if self.waiting_since is None:
            self.waiting_since = now

    def edit_shown(self) -> None:
        """The edits that waited are shown (or the field is gone)."""
        self.pending = self.waiting_since = None

    def stroke(self) -> None:
        """A datablock its paint reads was edited (a stroke): read the paint again and show it."""
        self.strokes += 1
        self.stroked = True
        self.stale = True

    def motion_edited(self) -> None:
        """Its colliders or force fields were edited: their stored motion is looked at again."""
        self.moved = True

    def slots_changed(self) -> None:
        """Its slot meshes hold something else now (rebuilt, undo): the pools write every slot."""
        if self.engine is not None:
            for pool in self.engine.pools.values():
                pool.state.forget()
        if self.building is not None:  # (nor do its first look's)
            self.building.look_pools = None
        self.frame = None

    def building_percent(self) -> int | None:
        """How far its background build is (0-100), None when none runs."""
        return None if self.building is None else self.building.percent()

    def drop(self, error: str | None = None) -> None:
        """Forget its engine (resolved again from the settings at the next update) and say why
        it cannot be simulated (``error``), or that nothing is known against it (None)."""
        self.engine = None
        self.frame = None
        self.error = error


@dataclass
class Registry:
    states: dict[Key, LiveField] = field(default_factory=dict)
    warned: set[str] = field(default_factory=set)  # console messages already printed
    saved_bakes: set = field(default_factory=set)  # cache files the .blend on disk refers to
    bake_root: str | None = None  # <blend>_windgrass of the open file
    tracks: dict[str, tuple] = field(default_factory=dict)  # stored motion decoded: fingerprint -> (colliders, fields)
    sampling: bool = False  # tracks.sample is stepping the scene's frames: the handlers stay out
    rendering: bool = False  # between render_pre and render_post/render_cancel: the scene camera rules
    batch_depth: int = 0  # > 0 while properties.batch writes many settings: one update at the end
    # the open file is as saved or loaded, but for the grass the add-on wrote since (its own writes
    # mark the file dirty: refilling the slots after a save, every frame's vertices)
    unchanged: bool = False
    # the 3D views drawing a field with EEVEE now: the overlays turned off in each (floor.py)
    floors: dict[int, tuple] = field(default_factory=dict)
    emptied: list[Key] = field(default_factory=list)  # fields whose ground grid a save is writing empty

    def live(self, key: Key) -> LiveField:
        """The record of the field ``key`` (made when there is none)."""
        found = self.states.get(key)
        if found is None:
            found = self.states[key] = LiveField(key)
        return found

    def built(self, key: Key) -> LiveField | None:
        """The field's record when its engine is resolved, else None."""
        found = self.states.get(key)
        return found if found is not None and found.built else None

    @property
    def fields(self) -> dict[Key, LiveField]:
        """{key: record} of the fields resolved now."""
        return {key: s for key, s in self.states.items() if s.built}

    def clear(self) -> None:
        self.states.clear()
        self.tracks.clear()
        self.warned.clear()
        self.floors.clear()  # (another file's views, or none)

    def forget_missing(self, alive: set[Key]) -> None:
        """Drop the records of scenes or fields that no longer exist."""
        for key in [k for k in self.states if k not in alive]:
            del self.states[key]


REGISTRY = Registry()


def warn_once(text: str) -> None:
    """Report a problem in the console once; a frame handler must never raise into Blender."""
    if text not in REGISTRY.warned:
        REGISTRY.warned.add(text)
        print(f"Windgrass: {text}")

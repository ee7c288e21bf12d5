"""Angles -> float32 vertex arrays of blade strips and cards (paper III.A-B, V.B).

Blade strip of blade b in cell c (paper III.A, Fig. 3): segment j is rigid and tilted by the 2-D
tilt vector

    T_j = blade_rest_tilt[b, j] * d_b + sum_{k<=j} bend[c, k],    d_b = (cos facing_b, sin facing_b)

whose magnitude is the angle from the vertical and whose direction is the way it leans; its
direction is (sin|T| T/|T|, cos|T|). Joints: p_0 = root, p_{j+1} = p_j + (length/n) dir_j, so
segment lengths never change. The ground stops a segment: its tilt |T| is held at the ground's
(blade.GROUND_TILT on flat ground, the local slope on a terrain), so no vertex goes below it.
Twist (paper V.A) turns the strip about the blade: joint j's side
vector is s_j = (-sin(facing + Phi_j), cos(facing + Phi_j), 0) with the cumulative twist
Phi_j = sum_{k<=j} twist[c, k]. Joint j is the bottom edge of segment j, so every segment's bottom
edge faces the way the solver turns that segment (solver.py: azimuth facing + sum_{k<=j} twist);
the tip joint n, the top edge of the last segment, takes Phi_{n-1}.
The width tapers linearly from blade_width at the root to blade.tip_width * blade_width at the tip.

Every joint has two vertices [left = p - s w/2, right = p + s w/2]. That is a single quad strip:
Blender draws both faces of a polygon, so the strip is two-sided (paper III.A) without duplicated
vertices. Blades with slot >= blade_count[cell] (eq 9) collapse onto their root (zero area).

Cards (paper III.B, V.B): one vertical quad per cell, centred on the cell centre, horizontal
direction (cos card_facing, sin card_facing), width lod.card_width * cell_size (wider than a cell,
so cards overlap their neighbours), bottom edge on the ground; the top edge is lifted by the card
height, moved by the deformation vector M' of eq 34 (CellData.card_offset) and turned about the
vertical axis by the cell's total twist.

Every block has the same topology, so the output for blocks [b0, b1, ...] is the concatenation of
per-block arrays. The work runs over chunks of blocks with preallocated scratch arrays, on the
engine's shared thread pool (workers.py; numpy releases the GIL), whose lanes take chunks from a
shared queue; each output row is written by exactly one chunk, so results do not depend on the threading. The kernel is
blade-major like the output (blade, joint): per-(blade, joint) work is contiguous passes and the
vertices are written straight into `out`. Cell data comes joint-major from the solver
(CellData.bend_t/twist_t) and is gathered per chunk, one strided copy per run of blocks of a
block row; per-cell rows are expanded over the slots by bitwise record copies.
"""

from __future__ import annotations

import threading
import weakref

import numpy as np

from . import blade, heads, meadow, workers

CHUNK_BLADES = 16384  # blades per chunk (measured best on 2 cores: fewer numpy calls, arrays in L2/L3)
THREADS = workers.THREADS  # lanes on the engine's shared pool (1: all in the calling thread)

_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


# --------------------------------------------------------------------------------------------
# Topology: faces and UVs of one block


def blade_faces(layout) -> np.ndarray:
    """(blades_per_block * n, 4) int32: quad of segment j = (left_j, right_j, right_j+1, left_j+1).

    Counter-clockwise seen from the facing side: the quad's normal (right - left) x up points to
    the blade's facing azimuth, the way it leans at rest."""
    n = layout.segments
    blade = np.arange(layout.blades_per_block, dtype=np.int32)[:, None] * (2 * (n + 1))
    left = blade + 2 * np.arange(n, dtype=np.int32)[None, :]
    faces = np.stack([left, left + 1, left + 3, left + 2], axis=-1)
    return np.ascontiguousarray(faces.reshape(-1, 4), dtype=np.int32)


def blade_uvs(layout) -> np.ndarray:
    """(blades_per_block * n * 4, 2) float32 per face corner: u = 0 left .. 1 right, v = 0 root .. 1 tip."""
    n = layout.segments
    v0 = np.arange(n, dtype=np.float32) / n
    v1 = np.arange(1, n + 1, dtype=np.float32) / n
    one = np.stack([np.stack([np.zeros(n), v0], 1), np.stack([np.ones(n), v0], 1),
                    np.stack([np.ones(n), v1], 1), np.stack([np.zeros(n), v1], 1)], axis=1)  # (n, 4, 2)
    return np.ascontiguousarray(np.tile(one.reshape(-1, 2), (layout.blades_per_block, 1)), dtype=np.float32)


def card_faces(layout) -> np.ndarray:
    """(cells_per_block**2, 4) int32: (bottom-left, bottom-right, top-right, top-left) of each card."""
    base = np.arange(layout.cells_per_block_total, dtype=np.int32)[:, None] * 4
    return np.ascontiguousarray(base + np.arange(4, dtype=np.int32)[None, :], dtype=np.int32)


def blade_vertex_count(layout, n_blocks: int) -> int:
    return n_blocks * layout.blades_per_block * (layout.segments + 1) * 2


def card_vertex_count(layout, n_blocks: int) -> int:
    return n_blocks * layout.cells_per_block_total * 4


# --------------------------------------------------------------------------------------------
# Per-layout constants in the kernel's layout: blade-major, (block, blade-in-block, joint)


def _void(array: np.ndarray) -> np.ndarray:
    """The last axis of a C-contiguous-rows array as one opaque record (bitwise copies)."""
    return array.view(np.dtype((np.void, array.shape[-1] * array.itemsize)))[..., 0]


class _Constants:
    """Per-blade values that never change, blade-major like the output: (n_blocks, blade in
    block = cell * num + slot, joint/segment), so every per-(blade, joint) operation is one
    contiguous pass and the vertex writes go straight to `out`. Per-cell values (bend, twist)
    are expanded over the slots by bitwise record copies. Horizontal 2-D vectors are complex64
    x + iy: one numpy call handles both components, and rotations by the twist are complex
    products. A block's values are worked out the first time its blades are drawn (``ready``):
    a window's far blocks, drawn as cards, never need them."""

    def __init__(self, layout):
        n, num, P = layout.segments, layout.blades_per_cell, layout.cells_per_block_total
        nb = layout.n_blocks
        bpb = P * num
        self.n, self.num, self.P, self.nb = n, num, P, nb
        # the layout's arrays each block's values are worked out from (not the layout: a cache's
        # value must not hold its key)
        self.facing, self.rest_tilt = layout.blade_facing, layout.blade_rest_tilt
        self.length, self.width, self.flower = layout.blade_length, layout.blade_width, layout.blade_flower
        self.root, self.ground_slope = layout.blade_root, layout.blade_ground_slope
        self.blade_alive = layout.blade_alive
        # linear taper of the width along the blade, per joint (multiplies the per-cell e^{i Phi})
        self.taper = blade.joint_widths(layout.params.blade.tip_width, n).astype(np.float32)
        # a seed head widens the strip at its last joint but one, a flower its top two joints (meadow.py)
        # (a flower or seed head that is a mesh rides the tip: its stem is not widened, heads.py)
        self.widened = [(joint, meadow.head_widening(width, layout.params.blade.tip_width, n, joint))
                        for joint, width in meadow.widened_joints(n, heads.strip_heads(layout),
                                                                  heads.strip_flowers(layout)) if width.any()]
        self.ready = np.zeros(nb, bool)
        c64, f32 = np.complex64, np.float32
        self.rest = np.empty((nb, bpb, n), c64)  # rest tilt vector blade_rest_tilt * d_b
        self.seg = np.empty((nb, bpb, n), f32)  # each segment's length
        self.w_side = np.empty((nb, bpb, n + 1), c64)  # side offset at each joint
        self.root_xy = np.empty((nb, bpb), c64)
        self.root_z = np.empty((nb, bpb), f32)
        # The ground stops each segment (blade.GROUND_TILT): flat ground as one row of the limit;
        # on a terrain the conjugate slope conj(g) at each root (the limit depends on the lean).
        self.slope = None if self.ground_slope is None else np.empty((nb, bpb, 1), c64)
        # blades that grow (paint.py): 1, the others 0 (they collapse onto their root); None: all grow
        self.alive = None if self.blade_alive is None else np.empty((nb, bpb), f32)
        self.slot = np.arange(num, dtype=np.int32)[None, :]  # (1, num)
        # Cells of block b = by * blocks_x + bx are the cpb x cpb square at (by, bx) of the
        # row-major field (layout.py): gathers of consecutive blocks of a block row are then
        # strided copies instead of per-cell takes.
        cpb, bx = layout.cells_per_block, layout.blocks_x
        by_, bx_ = np.divmod(np.arange(nb), bx)
        ly, lx = np.divmod(np.arange(P), cpb)
        square = ((by_[:, None] * cpb + ly) * (bx * cpb) + bx_[:, None] * cpb + lx)
        self.grid = ((layout.blocks_y, cpb, bx, cpb) if np.array_equal(square, layout.block_cells) else None)
        self.k_max = max(1, CHUNK_BLADES // max(1, bpb))
        self.taper_rows = np.ascontiguousarray(np.broadcast_to(self.taper, (self.k_max * P, n + 1)))
        # floor of |T| as a full array: np.maximum runs ~3x faster than with a scalar operand
        self.tiny = np.full((self.k_max * bpb, n), 1e-30, dtype=np.float32)
        self.ground_tilt = np.full((self.k_max * bpb, n), blade.GROUND_TILT, dtype=np.float32)
        self._scratch: list[dict[str, np.ndarray]] = []
        self._lock = threading.Lock()
        self.call_lock = threading.Lock()

    def make_ready(self, blocks: np.ndarray) -> None:
        """Work out the values of those of ``blocks`` not yet worked out (under ``call_lock``)."""
        todo = np.unique(blocks[~self.ready[blocks]])
        if not todo.size:
            return
        n, bpb = self.n, self.P * self.num
        blades = (todo[:, None] * bpb + np.arange(bpb)).ravel()
        facing = self.facing[blades].astype(np.float64)
        d_b = np.exp(1j * facing)[:, None]  # d_b = (cos f, sin f) as cos f + i sin f
        self.rest[todo] = (self.rest_tilt[blades].astype(np.float64) * d_b).astype(np.complex64).reshape(-1, bpb, n)
        # l/n, but a flower's head is its short top segments (meadow.segment_shares)
        length = self.length[blades]
        shares = meadow.segment_shares(n, length, self.width[blades], self.flower[blades])
        self.seg[todo] = (length.astype(np.float64)[:, None] * shares).astype(np.float32).reshape(-1, bpb, n)
        # Side offset at the root, h = -s w/2 with s = (-sin f, cos f) = i e^{i f}: h = -i (w/2) e^{i f},
        # repeated for every joint.
        w_side = (-1j * 0.5 * self.width[blades].astype(np.float64) * d_b[:, 0]).astype(np.complex64)
        rows = np.repeat(w_side.reshape(-1, 1), n + 1, axis=1)
        for joint, widening in self.widened:
            rows[:, joint] *= widening[blades]
        self.w_side[todo] = rows.reshape(-1, bpb, n + 1)
        root = self.root[blades].astype(np.float64)
        self.root_xy[todo] = (root[:, 0] + 1j * root[:, 1]).astype(np.complex64).reshape(-1, bpb)
        self.root_z[todo] = root[:, 2].astype(np.float32).reshape(-1, bpb)
        if self.slope is not None:
            slope = self.ground_slope[blades]
            self.slope[todo] = (slope[:, 0] - 1j * slope[:, 1]).astype(np.complex64).reshape(-1, bpb, 1)
        if self.alive is not None:
            self.alive[todo] = self.blade_alive[blades].astype(np.float32).reshape(-1, bpb)
        self.ready[todo] = True

    def scratch(self, index: int) -> dict[str, np.ndarray]:
        """Working arrays of worker `index` for chunks of up to k_max blocks (allocated once)."""
        with self._lock:
            while len(self._scratch) <= index:
                k, n, num, P = self.k_max, self.n, self.num, self.P
                cells, blades = k * P, k * P * num
                f32, c64 = np.float32, np.complex64
                self._scratch.append({
                    "k_max": k,
                    "tw": np.empty((cells, n), f32),  # twist per cell
                    "phi": np.empty((cells, n + 1), f32),  # cumulative twist per cell and joint
                    "trig": np.empty((cells, n + 1), f32),
                    "rot": np.empty((cells, n + 1), c64),  # taper_j e^{i Phi_j}
                    "cb_blade": np.empty((cells, num, n), c64),  # cb of each blade's cell
                    "rot_blade": np.empty((cells, num, n + 1), c64),
                    "t": np.empty((blades, n), c64),  # T, then the horizontal steps
                    "a": np.empty((blades, n), f32),
                    "b": np.empty((blades, n), f32),
                    "dz": np.empty((blades, n), f32),
                    "p": np.empty((blades, n + 1), c64),  # joints, x + iy
                    "pz": np.empty((blades, n + 1), f32),
                    "h": np.empty((blades, n + 1), c64),  # side offset -s w/2
                    "mask": np.empty((cells, num), f32),
                    "seg": np.empty((blades, n), f32),
                    "w_side": np.empty((blades, n + 1), c64),
                })
            return self._scratch[index]


def _constants(layout) -> _Constants:
    c = _CACHE.get(layout)
    if c is None:
        c = _Constants(layout)
        _CACHE[layout] = c
    return c


def carry_constants(old, new) -> None:
    """``new`` (``old.retitled``: the same blocks, settings that change none of them) shares the
    per-blade values of ``old``: those worked out for either serve both."""
    _CACHE[new] = _constants(old)


def _check_blocks(layout, blocks) -> np.ndarray:
    blocks = np.asarray(blocks, dtype=np.int64).ravel()
    if blocks.size and (blocks.min() < 0 or blocks.max() >= layout.n_blocks):
        raise IndexError(f"block ids must be in 0..{layout.n_blocks - 1}")
    return blocks


def _output(out, rows: int) -> np.ndarray:
    if out is None:
        return np.empty((rows, 3), np.float32)
    if (not isinstance(out, np.ndarray) or out.dtype != np.float32 or out.ndim != 2 or out.shape[1] != 3
            or out.shape[0] < rows or not out.flags.c_contiguous):
        raise ValueError(f"out must be a C-contiguous float32 array of at least ({rows}, 3)")
    return out[:rows]


def _chunks(blocks: np.ndarray, k_max: int) -> list[tuple[int, np.ndarray]]:
    """(position in `blocks`, block ids) of each chunk."""
    return [(i, blocks[i:i + k_max]) for i in range(0, len(blocks), k_max)]


def _consecutive(ids: np.ndarray) -> slice | None:
    """The slice ids[0]:ids[-1]+1 when ids are consecutive, else None."""
    if ids[-1] - ids[0] + 1 == len(ids) and (len(ids) < 3 or np.all(np.diff(ids) == 1)):
        return slice(int(ids[0]), int(ids[-1]) + 1)
    return None


def _select(array: np.ndarray, ids: np.ndarray, run: slice | None, scratch: dict, name: str):
    """array[ids] along axis 0: a view when ids are consecutive (run), else gathered into scratch."""
    if run is not None:
        return array[run]
    buf = scratch.get(name)
    if buf is None:  # first gather of this kind: allocate once for the largest chunk
        buf = scratch[name] = np.empty((scratch["k_max"],) + array.shape[1:], array.dtype)
    return np.take(array, ids, axis=0, out=buf[: len(ids)])


def _view(array: np.ndarray, shape: tuple) -> np.ndarray:
    """``array`` seen with ``shape``, never a copy (writes through it reach ``array``): a ValueError
    where only a copy could have that shape (numpy 2.5 deprecates assigning ``ndarray.shape``,
    and numpy 1.26 has no ``reshape(copy=False)``)."""
    view = array.reshape(shape)
    if not np.may_share_memory(view, array):
        raise ValueError(f"an array of shape {array.shape} cannot be seen as {shape} without a copy")
    return view


def _gather_cells(layout, const: _Constants, src: np.ndarray, ids: np.ndarray, dst: np.ndarray) -> None:
    """Cell-major copy of joint-major data: dst[i * P + c] = src[..., block_cells[ids[i], c]] for
    src (R..., C) and dst (k * P, R...). Runs of consecutive blocks of one block row are one
    strided copy each (the field's rows of cells, no index arrays)."""
    rest = src.shape[:-1]
    if const.grid is None:
        np.copyto(dst, np.moveaxis(np.take(src, layout.block_cells[ids].ravel(), axis=-1), -1, 0))
        return
    _, cpb, bx, _ = const.grid
    field = _view(src, rest + const.grid)  # (R..., blocks_y, cpb, blocks_x, cpb)
    squares = _view(dst, (len(ids), cpb, cpb) + rest)
    r = len(rest)
    order = (r + 1, r, r + 2) + tuple(range(r))  # (R..., ly, m, lx) -> (m, ly, lx, R...)
    breaks = np.flatnonzero((np.diff(ids) != 1) | (np.diff(ids // bx) != 0)) + 1
    for start, stop in zip([0, *breaks.tolist()], [*breaks.tolist(), len(ids)]):
        y, x = divmod(int(ids[start]), bx)
        block_row = field[(Ellipsis, y, slice(None), slice(x, x + stop - start), slice(None))]
        np.copyto(squares[start:stop], block_row.transpose(order))


# --------------------------------------------------------------------------------------------
# Blade strips


def _joint_major(layout, cells) -> tuple[np.ndarray, np.ndarray]:
    """(bend (n, 2, C), twist (n, C)) float32: CellData's joint-major arrays (the solver's own,
    no copy) when present, else transposed from the cell-major bend (C, n, 2) and twist (C, n)."""
    C, n = layout.n_cells, layout.segments
    bend_t, twist_t = getattr(cells, "bend_t", None), getattr(cells, "twist_t", None)
    if bend_t is None or twist_t is None:
        bend, twist = np.asarray(cells.bend), np.asarray(cells.twist)
        if bend.shape != (C, n, 2) or twist.shape != (C, n):
            raise ValueError(f"cell data must have bend {(C, n, 2)} and twist {(C, n)}, "
                             f"got {bend.shape} and {twist.shape}")
        bend_t = np.asarray(bend, dtype=np.float32).transpose(1, 2, 0)  # views: the gathers read them
        twist_t = np.asarray(twist, dtype=np.float32).T
    bend_t, twist_t = np.asarray(bend_t, dtype=np.float32), np.asarray(twist_t, dtype=np.float32)
    if bend_t.shape != (n, 2, C) or twist_t.shape != (n, C):
        raise ValueError(f"cell data must have bend_t {(n, 2, C)} and twist_t {(n, C)}, "
                         f"got {bend_t.shape} and {twist_t.shape}")
    return bend_t, twist_t


def blade_vertices(layout, cells, blocks, blade_count=None, out=None) -> np.ndarray:
    """(len(blocks) * blades_per_block * (n + 1) * 2, 3) float32; see the module docstring.

    cells: CellData (bend (C, n, 2), twist (C, n)); blade_count: (C,) int N of eq 9 or None (all).
    """
    blocks = _check_blocks(layout, blocks)
    rows = blade_vertex_count(layout, len(blocks))
    result = _output(out, rows)
    if rows == 0:
        return result
    const = _constants(layout)
    bend, twist = _joint_major(layout, cells)
    counts = None if blade_count is None else np.asarray(blade_count)
    per_block = layout.blades_per_block * (layout.segments + 1) * 2
    chunks = _chunks(blocks, const.k_max)
    view = result.reshape(len(blocks), per_block, 3)

    # Workers take the next chunk from a shared queue (on a busy machine a static split waits
    # for the slower thread); each chunk writes its own rows, so the result never depends on it.
    queue = iter(chunks)
    queue_lock = threading.Lock()

    def work(worker: int) -> None:
        s = const.scratch(worker)
        while True:
            with queue_lock:
                item = next(queue, None)
            if item is None:
                return
            start, ids = item
            _blade_chunk(layout, const, s, ids, bend, twist, counts, view[start:start + len(ids)])

    with const.call_lock:  # the scratch arrays serve one call at a time
        const.make_ready(blocks)
        workers.run_lanes(work, min(THREADS, len(chunks)))
    return result


def _blade_chunk(layout, const: _Constants, s: dict, ids: np.ndarray, bend: np.ndarray, twist: np.ndarray,
                 counts, out: np.ndarray) -> None:
    """Vertices of the blades of blocks `ids` into `out` (k, blades_per_block * (n+1) * 2, 3)."""
    k, n, num, P = len(ids), const.n, const.num, const.P
    cells, blades = k * P, k * P * num
    cb_blade, rot_blade = _cell_shapes(layout, const, s, ids, bend, twist)
    run = _consecutive(ids)
    rest = _select(const.rest, ids, run, s, "sel_rest").reshape(blades, n)
    seg = _select(const.seg, ids, run, s, "sel_seg").reshape(blades, n)
    w_side = _select(const.w_side, ids, run, s, "sel_w_side").reshape(blades, n + 1)
    root_xy = _select(const.root_xy, ids, run, s, "sel_root_xy").reshape(blades)
    root_z = _select(const.root_z, ids, run, s, "sel_root_z").reshape(blades)
    if counts is not None or const.alive is not None:
        mask = s["mask"][:cells]
        if counts is not None:  # eq 9: slots >= N collapse onto the root
            np.less(const.slot, counts[layout.block_cells[ids]].reshape(cells, 1), out=mask)
        else:
            mask.fill(1.0)
        if const.alive is not None:  # blades painted out collapse too
            mask *= _select(const.alive, ids, run, s, "sel_alive").reshape(cells, num)
        mask = mask.reshape(blades, 1)
        seg = np.multiply(seg, mask, out=s["seg"][:blades])
        w_side = np.multiply(w_side, mask, out=s["w_side"][:blades])
    t, dz = _segment_steps(const, s, ids, run, rest, cb_blade, seg, blades)
    _write_joints(s, t, dz, root_xy, root_z, w_side, rot_blade, blades, n, out)


def _cell_shapes(layout, const: _Constants, s: dict, ids: np.ndarray, bend: np.ndarray, twist: np.ndarray):
    """(cumulative bend, twist rotation) of every blade of blocks ``ids``, (cells, num, n) and
    (cells, num, n + 1) complex: a cell's values, shared by its blades (paper V.B).

    Per cell: the cumulative bend sum_{k<=j} bend[c, k] (complex) and the cumulative twist
    Phi_j = sum_{k<=j} twist[c, k] (Phi_n = Phi_{n-1}) as taper_j e^{i Phi_j}, computed in slot 0
    and copied to the other slots as whole records."""
    n, num, cells = const.n, const.num, len(ids) * const.P
    cb_blade = s["cb_blade"][:cells]
    cb = cb_blade[:, 0]  # (cells, n) complex
    _gather_cells(layout, const, bend, ids, cb_blade.view(np.float32).reshape(cells, num, n, 2)[:, 0])
    for j in range(1, n):
        np.add(cb[:, j - 1], cb[:, j], out=cb[:, j])
    tw, phi = s["tw"][:cells], s["phi"][:cells]
    _gather_cells(layout, const, twist, ids, tw)
    np.copyto(phi[:, 0], tw[:, 0])
    for j in range(1, n):
        np.add(phi[:, j - 1], tw[:, j], out=phi[:, j])
    np.copyto(phi[:, n], phi[:, n - 1])  # the tip edge belongs to the top segment
    rot, trig, taper = s["rot"][:cells], s["trig"][:cells], const.taper_rows[:cells]
    np.cos(phi, out=trig)  # contiguous: trig functions run faster than into strided halves
    np.multiply(trig, taper, out=rot.real)
    np.sin(phi, out=trig)
    np.multiply(trig, taper, out=rot.imag)
    # Every blade of a cell shares the cell's values: whole rows copied as records, per slot.
    rot_blade = s["rot_blade"][:cells]
    records = _void(cb_blade)  # (cells, num): one record per blade
    for slot in range(num):
        if slot:
            np.copyto(records[:, slot], records[:, 0])
        np.copyto(_void(rot_blade)[:, slot], _void(rot))
    return cb_blade, rot_blade


def _segment_steps(const: _Constants, s: dict, ids, run, rest, cb_blade, seg, blades: int):
    """(horizontal steps dx + i dy, vertical steps dz) of every segment, (blades, n) each.

    Tilt vector T_j = rest + cumulative bend; the tilt |T| is stopped by the ground at theta_g:
    GROUND_TILT on flat ground; on a slope g, the direction (sin theta u, cos theta) stays above
    the ground plane while cos theta >= sin theta (g . u), i.e. theta <= atan2(1, g . u), less
    the same clearance (g . u |T| = Re(conj(g) T), so no division). The segment's direction is
    (sin theta T/|T|, cos theta) times l/n."""
    n = const.n
    t, a, b, dz = s["t"][:blades], s["a"][:blades], s["b"][:blades], s["dz"][:blades]
    np.add(rest, cb_blade.reshape(blades, n), out=t)
    np.abs(t, out=a)  # |T|
    if const.slope is None:
        np.minimum(a, const.ground_tilt[:blades], out=b)  # theta
    else:
        along = s["p"][:blades, :n]  # (p is free until the joints are written)
        slope = _select(const.slope, ids, run, s, "sel_slope").reshape(blades, 1)
        np.multiply(t, slope, out=along)
        np.arctan2(a, along.real, out=b)
        b -= np.float32(0.5 * np.pi - blade.GROUND_TILT)
        np.minimum(b, a, out=b)  # theta
    np.cos(b, out=dz)
    np.multiply(dz, seg, out=dz)  # dz = l/n cos theta
    np.sin(b, out=b)
    np.maximum(a, const.tiny[:blades], out=a)  # |T| = 0: sin theta = 0, so the horizontal step is 0
    np.divide(b, a, out=b)
    np.multiply(b, seg, out=b)  # l/n sin theta / |T|
    np.multiply(t, b, out=t)  # horizontal steps dx + i dy
    return t, dz


def _write_joints(s: dict, t, dz, root_xy, root_z, w_side, rot_blade, blades: int, n: int, out) -> None:
    """Joints p_0 = root, p_{j+1} = p_j + step_j, each as its left and right vertex, into ``out``."""
    p, pz = s["p"][:blades], s["pz"][:blades]
    np.copyto(p[:, 0], root_xy)
    np.copyto(pz[:, 0], root_z)
    for j in range(n):
        np.add(p[:, j], t[:, j], out=p[:, j + 1])
        np.add(pz[:, j], dz[:, j], out=pz[:, j + 1])

    # Side offset h = -s w/2 = -i (w/2) e^{i (f + Phi)} taper: one complex product.
    h = s["h"][:blades]
    np.multiply(w_side, rot_blade.reshape(blades, n + 1), out=h)

    # Write (blade, joint, [left xyz, right xyz]) straight into `out`, which has the same order:
    # left = p - s w/2 = p + h, right = p - h. (Lx, Ly) is an aligned 8-byte pair: one complex add.
    v = out.reshape(blades, n + 1, 6)
    np.add(p, h, out=out.reshape(-1).view(np.complex64).reshape(blades, n + 1, 3)[..., 0])
    np.copyto(v[..., 2], pz)
    np.subtract(p.real, h.real, out=v[..., 3])
    np.subtract(p.imag, h.imag, out=v[..., 4])
    np.copyto(v[..., 5], pz)


# --------------------------------------------------------------------------------------------
# Cards


_CARDS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class _CardConstants:
    """What of each card of a layout never moves: its bottom edge (bottom-left xyz, bottom-right
    xyz: one row a card, as ``card_vertices`` writes them) and its top's height at rest."""

    def __init__(self, layout):
        centre, ground = layout.card_center, layout.cell_ground
        self.half = half = np.float32(0.5 * layout.params.lod.card_width * layout.cell_size)
        bx, by = np.cos(layout.card_facing) * half, np.sin(layout.card_facing) * half
        self.bottom = np.stack([centre[:, 0] - bx, centre[:, 1] - by, ground,
                                centre[:, 0] + bx, centre[:, 1] + by, ground], axis=1).astype(np.float32)
        self.bottom_records = self.bottom.view(np.dtype((np.void, 24)))[:, 0]
        self.rest_top = ground + layout.card_height


def _card_constants(layout) -> _CardConstants:
    c = _CARDS.get(layout)
    if c is None:
        c = _CARDS[layout] = _CardConstants(layout)
    return c


def card_vertices(layout, cells, blocks, out=None) -> np.ndarray:
    """(len(blocks) * cells_per_block**2 * 4, 3) float32: bottom-left, bottom-right, top-right,
    top-left of each card (paper III.B), top moved by M' of eq 34 and turned by the total twist.
    The bottom edges are the layout's (``_CardConstants``); ``card_vertices_plain`` is its twin."""
    blocks = _check_blocks(layout, blocks)
    rows = card_vertex_count(layout, len(blocks))
    result = _output(out, rows)
    if rows == 0:
        return result
    const = _card_constants(layout)
    cell_ids = layout.block_cells[blocks].ravel()
    # (gathers by np.take, the bottom edge as one 24-byte record a card: several times faster
    # than fancy indexing of rows)
    corners = result.reshape(-1).view(np.dtype((np.void, 24))).reshape(-1, 2)  # a card a row
    corners[:, 0] = np.take(const.bottom_records, cell_ids)
    v = result.reshape(-1, 12)
    top_facing = np.take(layout.card_facing, cell_ids) + np.take(_total_twist(cells), cell_ids)
    tx, ty = np.cos(top_facing) * const.half, np.sin(top_facing) * const.half
    offset = np.take(np.asarray(cells.card_offset, dtype=np.float32), cell_ids, axis=0)  # M', eq 34 (x, y, z)
    centre = np.take(layout.card_center, cell_ids, axis=0)
    topx = centre[:, 0] + offset[:, 0]
    topy = centre[:, 1] + offset[:, 1]
    np.add(np.take(const.rest_top, cell_ids), offset[:, 2], out=v[:, 8])
    v[:, 11] = v[:, 8]
    np.add(topx, tx, out=v[:, 6])
    np.add(topy, ty, out=v[:, 7])
    np.subtract(topx, tx, out=v[:, 9])
    np.subtract(topy, ty, out=v[:, 10])
    return result


def _total_twist(cells) -> np.ndarray:
    """(C,) float32 the sum of the twist of every joint of each cell."""
    twist_t = getattr(cells, "twist_t", None)  # joint-major (n, C) when present: no transpose
    if twist_t is not None:
        return np.add.reduce(np.asarray(twist_t, dtype=np.float32), axis=0)
    return np.add.reduce(np.asarray(cells.twist, dtype=np.float32), axis=1)


def card_vertices_plain(layout, cells, blocks) -> np.ndarray:
    """``card_vertices`` stated plainly, corner by corner (the tests hold the fast one to it)."""
    blocks = _check_blocks(layout, blocks)
    cell_ids = layout.block_cells[blocks].ravel()
    centre = layout.card_center[cell_ids]  # (m, 2) the card's foot inside its cell
    half = np.float32(0.5 * layout.params.lod.card_width * layout.cell_size)
    facing = layout.card_facing[cell_ids]
    offset = np.asarray(cells.card_offset, dtype=np.float32)[cell_ids]  # M', eq 34 (x, y, z)
    ground = layout.cell_ground[cell_ids]  # terrain height at the cell centre
    bx, by = np.cos(facing) * half, np.sin(facing) * half
    top_facing = facing + _total_twist(cells)[cell_ids]
    tx, ty = np.cos(top_facing) * half, np.sin(top_facing) * half
    top = np.stack([centre[:, 0] + offset[:, 0], centre[:, 1] + offset[:, 1],
                    ground + layout.card_height[cell_ids] + offset[:, 2]], axis=1)
    corners = [np.stack([centre[:, 0] - bx, centre[:, 1] - by, ground], axis=1),  # bottom-left
               np.stack([centre[:, 0] + bx, centre[:, 1] + by, ground], axis=1),  # bottom-right
               top + np.stack([tx, ty, np.zeros_like(tx)], axis=1),  # top-right
               top - np.stack([tx, ty, np.zeros_like(tx)], axis=1)]  # top-left
    return np.stack(corners, axis=1).reshape(-1, 3).astype(np.float32)

"""A wind that loops (``simulation.loop``, seconds; 0: off): every blade repeats exactly after it.

Frame N is a function of the settings and N with a bounded history (``simulation.py``), so a wind
whose every input repeats with period L gives a meadow whose every blade repeats with it:

* the clock of the wind is wrapped: the wind of frame f is sampled at the time of frame
  ``frame_start + (f - frame_start) mod P``, P = L fps frames (``wind_frame``, ``loop_frames``), so frames f and
  f + P get the same bits;
* the solver's epochs divide P (``epoch_frames`` in ``simulation.py``): trajectory k + P / E starts
  P frames after trajectory k, from rest, in the same wind, and so holds the same states;
* the turbulence and the gust waves, which travel with the mean wind and never come back, are
  looped as a flow map is in games (``blend``): the wind's moving part at time tau in [0, L) is
  (1 - w) F(tau) + w F(tau - L), w = tau / L, scaled by 1 / sqrt((1 - w)^2 + w^2) to keep its
  spread; at tau = 0 it is F(0), and as tau reaches L it is F(0) again. Each of the two is the
  paper's frozen turbulence carried at the mean wind's speed, so waves keep their speed;
* the far grass's gust shading blends the same two patterns (``frame.Frame.gust``).

What cannot repeat is said (``notes``): a keyed wind that changes over the loop, colliders
moving through the grass, moving force fields.
"""

from __future__ import annotations

import math

import numpy as np

from .clock import Clock
from .schema import Params


def loop_frames(params: Params) -> int:
    """P: the loop's length in frames (0: no loop)."""
    seconds = float(params.simulation.loop)
    return Clock.of(params).frames(seconds) if seconds > 0.0 else 0


def loop_seconds(params: Params) -> float:
    """L: the loop's length in seconds, a whole number of frames (0.0: no loop)."""
    frames = loop_frames(params)
    return frames / Clock.of(params).rate if frames else 0.0


def wind_frame(frame: int, start: int, period: int) -> int:
    """The frame whose time the wind of ``frame`` is sampled at: ``frame`` itself without a loop
    (``period`` 0), else its place in the first loop from ``start`` (``render.frame_start``)."""
    if not period:
        return int(frame)
    return start + (int(frame) - start) % period


def phase(t: float, period: float) -> tuple[float, float]:
    """(tau, w): ``t`` wrapped into [0, period) and its share of the period."""
    tau = t - period * math.floor(t / period)
    return tau, tau / period


def weights(w: float) -> tuple[float, float]:
    """The blend's weights of F(tau) and F(tau - L) at share ``w``, keeping the spread."""
    norm = 1.0 / math.sqrt((1.0 - w) ** 2 + w * w)
    return (1.0 - w) * norm, w * norm


def blend(now: np.ndarray, now_mean: np.ndarray, before: np.ndarray, before_mean: np.ndarray,
          mean: np.ndarray, w: float) -> np.ndarray:
    """The looped wind (m, 2) float32 from the wind ``now`` = v(tau) and ``before`` = v(tau - L)
    (their means ``now_mean``, ``before_mean``): mean + a (now - now_mean) + b (before - before_mean),
    (a, b) = ``weights(w)``. Writes into ``now``."""
    a, b = (np.float32(v) for v in weights(w))
    now -= now_mean.astype(np.float32)
    now *= a
    before = before - before_mean.astype(np.float32)
    before *= b
    now += before
    now += mean.astype(np.float32)
    return now


def notes(params: Params, keyed: bool = False, colliders=(), effectors=None) -> list[str]:
    """What keeps the frames from repeating with the loop (empty without a loop or when all
    repeats): ``keyed``, the mean wind changes over time (keys, an animated wind)."""
    if not loop_frames(params):
        return []
    out = []
    if keyed:
        out.append("the wind is keyed: each loop plays its keys from the start, with a seam where the keys at the "
                   f"loop's end ({loop_seconds(params):g} s) differ from their start; key it to repeat, or remove "
                   "the keys")
    if colliders:
        out.append("colliders move through the grass on the scene's own time: where they pass, frames do not "
                   "repeat with the loop")
    if effectors is not None:
        out.append("force fields are read on the loop's time: one that moves jumps back at the loop's end")
    return out

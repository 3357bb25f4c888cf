"""Boom-angle setpoints over time: trajectories through knots, and moves at a top speed.

A :class:`SetpointPath` runs through knots (time s, angle rad, rate rad/s), as
ros2_control's joint_trajectory_controller interpolates a JointTrajectory: between knots
the angle is linear when the knots carry no rates, and a cubic Hermite segment when they
do. Before the first knot it holds the first angle, after the last the last one (rate 0).

A move to a target (:func:`move`) is a quintic segment (zero acceleration at both ends, so
the boom is not asked to stop in an instant) from the current setpoint to the target at
rest, timed so that its peak rate, 1.875 |delta| / T, is the top speed. Timed moves
(:func:`timed_moves`, the headless ``angle`` scenario) chain moves: each starts where the
setpoint is at its time, also while the previous one is still under way.

Knots may differ per parameter set: every array has shape (knots, sets).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..jit import jitable

#: The peak rate of a quintic rest-to-rest segment over duration T is PEAK_RATIO |delta| / T.
PEAK_RATIO = 1.875
#: Interpolation between knots: linear (positions only), cubic or quintic Hermite.
LINEAR, CUBIC, QUINTIC = 1, 3, 5


@dataclass(frozen=True)
class SetpointPath:
    """Knots of a boom-angle setpoint; arrays of shape (knots, sets)."""

    times_s: np.ndarray
    angles_rad: np.ndarray
    rates_rad_s: np.ndarray
    order: int  # LINEAR, CUBIC or QUINTIC (with zero accelerations at the knots)

    @staticmethod
    def of(times_s: Any, angles_rad: Any, rates_rad_s: Any = None, order: int | None = None) -> SetpointPath:
        """A path through knots; without rates, linear between them, with rates cubic (or ``order``)."""
        times = np.atleast_1d(np.asarray(times_s, dtype=float))
        angles = np.atleast_1d(np.asarray(angles_rad, dtype=float))
        times, angles = np.broadcast_arrays(times.reshape(len(times), -1), angles.reshape(len(angles), -1))
        rates = (
            np.zeros_like(angles)
            if rates_rad_s is None
            else np.broadcast_to(np.asarray(rates_rad_s, dtype=float).reshape(len(angles), -1), angles.shape)
        )
        if order is None:
            order = LINEAR if rates_rad_s is None else CUBIC
        return SetpointPath(times.copy(), angles.copy(), np.array(rates), order)

    @property
    def end_s(self) -> np.ndarray:
        """When the last knot is reached, per set."""
        return self.times_s[-1]

    def evaluate(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Setpoint angle and rate at ``t_s``, one entry per set."""
        times, angles, rates = self.times_s, self.angles_rad, self.rates_rad_s
        k = len(times)
        if k == 1:
            return angles[0], np.zeros_like(angles[0])
        index = np.clip((times <= t_s).sum(axis=0) - 1, 0, k - 2)[None, :]
        t0, t1 = np.take_along_axis(times, index, 0)[0], np.take_along_axis(times, index + 1, 0)[0]
        a0, a1 = np.take_along_axis(angles, index, 0)[0], np.take_along_axis(angles, index + 1, 0)[0]
        r0, r1 = np.take_along_axis(rates, index, 0)[0], np.take_along_axis(rates, index + 1, 0)[0]
        span = t1 - t0
        inside = (t_s > times[0]) & (t_s < times[-1]) & (span > 0.0)
        span = np.where(span > 0.0, span, 1.0)
        w = np.clip((t_s - t0) / span, 0.0, 1.0)
        angle, rate = segment(self.order, w, span, a0, a1, r0, r1)
        last = np.where(t_s >= times[-1], angles[-1], angles[0])
        return np.where(inside, angle, last), np.where(inside, rate, 0.0)

    def at(self, t_s: float) -> tuple[float, float]:
        """Setpoint angle and rate at ``t_s`` of a single-set path, as floats (without numpy:
        the node and the closed loop ask once per physics step)."""
        times, angles, rates = self._knots()
        return setpoint_at(times, angles, rates, self.order, t_s)

    def _knots(self) -> tuple[list[float], list[float], list[float]]:
        """The first set's knots as lists (cached)."""
        cached = self.__dict__.get("_lists")
        if cached is None:
            cached = (self.times_s[:, 0].tolist(), self.angles_rad[:, 0].tolist(), self.rates_rad_s[:, 0].tolist())
            object.__setattr__(self, "_lists", cached)
        return cached


@jitable
def last_at_or_before(times_s: Any, t: float) -> int:
    """Index of the last of the ascending ``times_s`` at or before ``t`` (-1 if none), as
    bisect_right - 1 (written out: numba compiles it)."""
    low, high = 0, len(times_s)
    while low < high:
        middle = (low + high) // 2
        if t < times_s[middle]:
            high = middle
        else:
            low = middle + 1
    return low - 1


@jitable
def setpoint_at(times_s: Any, angles_rad: Any, rates_rad_s: Any, order: int, t_s: float) -> tuple[float, float]:
    """Angle and rate at ``t_s`` of one set's knots (sequences of floats): the scalar form of
    :meth:`SetpointPath.evaluate`, which the compiled run kernel also calls."""
    at_rest, angle, w, span, a0, a1, r0, r1 = segment_at(times_s, angles_rad, rates_rad_s, t_s)
    if at_rest:
        return angle, 0.0
    return segment(order, w, span, a0, a1, r0, r1)


@jitable
def segment_at(times_s: Any, angles_rad: Any, rates_rad_s: Any, t_s: float) -> tuple:
    """Where ``t_s`` falls on one set's knots: (True, the angle held, then zeros) before the
    first knot or from the last on; else (False, 0.0, w, span, a0, a1, r0, r1), the arguments
    of :func:`segment` for the segment it falls in."""
    last = len(times_s) - 1
    if t_s <= times_s[0] or last == 0:
        return True, float(angles_rad[0]), 0.0, 1.0, 0.0, 0.0, 0.0, 0.0
    if t_s >= times_s[last]:
        return True, float(angles_rad[last]), 0.0, 1.0, 0.0, 0.0, 0.0, 0.0
    i = last_at_or_before(times_s, t_s)
    span = times_s[i + 1] - times_s[i]
    w = (t_s - times_s[i]) / span
    return False, 0.0, w, span, angles_rad[i], angles_rad[i + 1], rates_rad_s[i], rates_rad_s[i + 1]


@jitable
def segment(order: int, w: Any, span: Any, a0: Any, a1: Any, r0: Any, r1: Any) -> tuple[Any, Any]:
    """Angle and rate at fraction ``w`` of a segment of duration ``span`` from (a0, r0) to
    (a1, r1): linear, cubic Hermite, or quintic Hermite with zero end accelerations."""
    if order == LINEAR:
        return a0 + w * (a1 - a0), (a1 - a0) / span
    w2, w3 = w * w, w * w * w
    if order == CUBIC:  # Hermite basis on w in [0, 1], and its derivatives
        h00, h10, h01, h11 = 2 * w3 - 3 * w2 + 1, w3 - 2 * w2 + w, -2 * w3 + 3 * w2, w3 - w2
        d00, d10, d01, d11 = 6 * w2 - 6 * w, 3 * w2 - 4 * w + 1, -6 * w2 + 6 * w, 3 * w2 - 2 * w
    else:  # quintic Hermite with zero end accelerations
        w4, w5 = w3 * w, w3 * w2
        h01 = 10 * w3 - 15 * w4 + 6 * w5
        h00, h10, h11 = 1 - h01, w - 6 * w3 + 8 * w4 - 3 * w5, -4 * w3 + 7 * w4 - 3 * w5
        d01 = 30 * w2 - 60 * w3 + 30 * w4
        d00, d10, d11 = -d01, 1 - 18 * w2 + 32 * w3 - 15 * w4, -12 * w2 + 28 * w3 - 15 * w4
    return h00 * a0 + h10 * span * r0 + h01 * a1 + h11 * span * r1, (d00 * a0 + d01 * a1) / span + d10 * r0 + d11 * r1


def knot_offsets_ns(path: SetpointPath, t0_s: float) -> list[int]:
    """The knot times of a single-set ``path`` after ``t0_s``, in whole nanoseconds (as a
    JointTrajectory's time_from_start carries them)."""
    return [round((t - t0_s) * 1e9) for t in path.times_s[:, 0].tolist()]


def path_from_offsets(
    t0_s: float, offsets_ns: Sequence[int], angles_rad: Sequence[float], rates_rad_s: Sequence[float], order: int
) -> SetpointPath:
    """A single-set path whose knots come ``offsets_ns`` after ``t0_s``: the node follows its
    paths so (:func:`on_whole_ns`), and boom-resim rebuilds a recorded one so, bit for bit,
    from the same ``t0_s``; ``rates_rad_s`` is not read for a LINEAR path."""
    times = [t0_s + n * 1e-9 for n in offsets_ns]
    return SetpointPath.of(times, list(angles_rad), None if order == LINEAR else list(rates_rad_s), order)


def on_whole_ns(path: SetpointPath, t0_s: float) -> SetpointPath:
    """A single-set ``path`` with its knot times moved to whole nanoseconds after ``t0_s`` (by at
    most half a nanosecond): what a recording of it (offsets in ns) rebuilds exactly."""
    return path_from_offsets(
        t0_s,
        knot_offsets_ns(path, t0_s),
        path.angles_rad[:, 0].tolist(),
        path.rates_rad_s[:, 0].tolist(),
        path.order,
    )


def move_duration_s(start_rad: Any, target_rad: Any, max_speed_rad_s: Any) -> np.ndarray:
    """Duration of a rest-to-rest quintic move whose peak rate is ``max_speed_rad_s``."""
    return PEAK_RATIO * np.abs(np.asarray(target_rad) - np.asarray(start_rad)) / np.asarray(max_speed_rad_s)


def move(t0_s: float, start_rad: Any, start_rate_rad_s: Any, target_rad: Any, max_speed_rad_s: Any) -> SetpointPath:
    """A quintic move from (``start_rad``, ``start_rate_rad_s``) at ``t0_s`` to ``target_rad`` at rest."""
    end = t0_s + move_duration_s(start_rad, target_rad, max_speed_rad_s)
    start, target = np.broadcast_arrays(np.asarray(start_rad, dtype=float), np.asarray(target_rad, dtype=float))
    return SetpointPath.of(
        [np.full_like(start, t0_s), end + 0.0 * start],
        [start, target],
        [start_rate_rad_s + 0.0 * start, 0.0 * start],
        QUINTIC,
    )


def timed_moves(
    start_rad: Any, times_s: Sequence[float], targets_rad: Sequence[float], max_speed_rad_s: Any
) -> SetpointPath:
    """At each of ``times_s``, a move to the matching target from where the setpoint is then
    (``start_rad`` at rest before the first); per set where ``start_rad`` or the speed is an array."""
    start = np.atleast_1d(np.asarray(start_rad, dtype=float))
    speed = np.broadcast_to(np.asarray(max_speed_rad_s, dtype=float), start.shape)
    path = SetpointPath.of([np.zeros_like(start)], [start])
    for t_i, target in zip(times_s, targets_rad):
        angle, rate = path.evaluate(t_i)
        nxt = move(t_i, angle, rate, np.full_like(start, target), speed)
        # knots after t_i give way: they end where the new move starts
        times = np.minimum(path.times_s, t_i)
        cut = path.times_s > t_i
        angles = np.where(cut, angle, path.angles_rad)
        rates = np.where(cut, rate, path.rates_rad_s)
        path = SetpointPath(
            np.concatenate([times, nxt.times_s]),
            np.concatenate([angles, nxt.angles_rad]),
            np.concatenate([rates, nxt.rates_rad_s]),
            QUINTIC,
        )
    return path

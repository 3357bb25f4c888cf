"""The design metrics of a run, taken sample by sample while it runs (streaming).

One accumulator (a float array, :func:`accumulator`) takes every sample of a run in turn
(:func:`add_sample`) and holds only running values: peaks, sums, the lift angle's crossing,
the hold after the valve closes and the turning points of its ringing. :func:`finish`
turns it into the metrics :data:`NAMES`. Memory stays the same however long the run: the
compiled batch kernel runs this for every parameter set while integrating, and
:mod:`metrics` runs it over stored signals (a bag, a trajectory), so both give the same
numbers. Written in the subset of Python that numba compiles (marked jitable: the
run loop of :mod:`kernel` compiles it into itself).

Definitions (SI):

- ``lift_completed``, ``lift_time_s``: whether and when the boom elevation first rose by
  the lift angle, from the first opening command (u > 0; from the first sample if the
  valve never opens), interpolated between samples; ``lift_energy_j`` and
  ``lift_valve_loss_j``: the supply energy and valve loss at that moment.
- ``rise_deg``, ``lift_m``: largest rise of the elevation and of q1 above their start.
- ``peak_speed_m_s``, ``rms_speed_m_s``: of the rod over all samples.
- The hold: from the first sample after the first opening where u <= 0, until u changes.
  ``overshoot_m``: its highest q1 above q1 at its end (needs more than 4 samples).
- The ringing of p1 in that hold (at least 16 samples): its turning points, each
  confirmed once p1 has come back from it by more than ``RIPPLE_PA``.
  ``oscillation_hz`` = (maxima - 1) / (time from the first to the last maximum);
  ``damping_ratio`` = d / sqrt(4 pi^2 + d^2), with d the logarithmic decrement per cycle of
  the swings between turning points (first to last swing of each direction, averaged over
  both directions). Both NaN with fewer than two maxima (a single hump settles, it does
  not ring).
- ``peak_pressure_pa``, ``min_pressure_pa``: over both chambers; ``cavitation_s``,
  ``relief_s``: time with the flag set (each sample's flag holds until the next sample).
- Closed loop (a move to ``target`` from ``move_start_s`` until ``move_end_s``), over the
  samples in that window: ``settling_s``, from its first sample until the elevation stays
  within 2 % of the step around the target (NaN if it is outside at the last sample);
  ``target_overshoot_deg``, how far it passed the target; ``target_error_deg``, target
  minus elevation at the window's last sample. NaN without a move.
- A work cycle's targets (the ``angle`` profile's: target i from ``command_times_s[i]`` until
  the next target's time, the last until the run ends; :func:`cycle_targets`), over the
  samples of each phase: ``worst_target_error_deg``, the largest |target - elevation| at a
  phase's last sample; ``worst_settle_time_s``, the longest time from a phase's start until
  the elevation stays within 2 % of its step around its target (the band of ``settling_s``,
  at least 0.1 degree), inf where a phase ends outside the band; ``set_down_error_deg``,
  the elevation above the target in effect (the ground, in a work cycle) at the last sample
  at or before the payload is released (the first time its share on the hook falls). NaN
  without targets (open loop) or a release; at most :data:`MAX_TARGETS` targets count.
- ``supply_energy_j``, ``valve_loss_energy_j``: at the last sample.
- The battery (docs/model.md, "Energy ledger"): ``battery_energy_j``, what it gave less what it
  took back over the run; ``battery_drawn_j``, ``battery_returned_j``, those two apart;
  ``lift_work_j``, the potential energy raised; ``efficiency``, that work over the battery's
  energy (NaN where the battery gave none); ``peak_battery_power_w``, the most it gave over
  an interval between samples (the change of what it gave less what it took back, over the
  interval: every step's mean power where a sample is taken every step). NaN in paper mode,
  for signals without the battery (a bag) and for a single sample.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..jit import jitable
from ..model.outputs import SAMPLE_NAMES

#: The metrics, in the order :func:`finish` writes them.
NAMES = (
    "lift_completed",
    "lift_time_s",
    "lift_energy_j",
    "lift_valve_loss_j",
    "rise_deg",
    "lift_m",
    "peak_speed_m_s",
    "rms_speed_m_s",
    "overshoot_m",
    "oscillation_hz",
    "damping_ratio",
    "peak_pressure_pa",
    "min_pressure_pa",
    "cavitation_s",
    "relief_s",
    "settling_s",
    "target_overshoot_deg",
    "target_error_deg",
    "worst_target_error_deg",
    "worst_settle_time_s",
    "set_down_error_deg",
    "supply_energy_j",
    "valve_loss_energy_j",
    "battery_energy_j",
    "battery_drawn_j",
    "battery_returned_j",
    "lift_work_j",
    "efficiency",
    "peak_battery_power_w",
)

#: The signals add_sample takes, in its order (names of simulation outputs; a model's ``samples``).
SAMPLE_SIGNALS = SAMPLE_NAMES

#: A turning point of the ringing counts once p1 has come back from it by more than this, Pa.
RIPPLE_PA = 1.0e3
#: Settling band of a closed-loop move, as a fraction of its step ...
SETTLING_BAND = 0.02
#: ... and, for a work cycle's targets, at least this (a target at the angle the boom holds), rad.
SETTLING_FLOOR_RAD = math.radians(0.1)
#: A hold needs more samples than this for an overshoot, and this many for a ringing.
HOLD_MIN_SAMPLES, RINGING_MIN_SAMPLES = 5, 16

#: A work cycle's targets the metrics follow, at most (the loader cycle has 4).
MAX_TARGETS = 16

# The settings of one run (see settings()): then the targets' times (s) and angles (rad)
LIFT_RAD, MOVE_START, MOVE_END, TARGET, RIPPLE, N_TARGETS, RELEASE = range(7)
TARGET_TIMES = 7
TARGET_ANGLES = TARGET_TIMES + MAX_TARGETS
N_SETTINGS = TARGET_ANGLES + MAX_TARGETS

# The accumulator's slots.
(COUNT, T0, Q0, ALPHA0, T_PREV, RISE_PREV, SUPPLY_PREV, LOSS_PREV, CAV_PREV, RELIEF_PREV) = range(10)
(Q_MAX, RISE_MAX, SPEED_MAX, V2_SUM, P_MAX, P_MIN, CAV_S, RELIEF_S, SUPPLY, LOSS) = range(10, 20)
# the lift's crossing, searched from the first sample (FROM_START) and from the first opening
(OPENED, T_OPEN, START_T, START_SUPPLY, START_LOSS, OPEN_T, OPEN_SUPPLY, OPEN_LOSS) = range(20, 28)
# the hold and its ringing
(PHASE, HOLD_U, HOLD_N, HOLD_Q_MAX, HOLD_Q_LAST, DIRECTION, EXTREME, EXTREME_T, LOW, HIGH) = range(28, 38)
(LAST_TURN, MAXIMA, FIRST_MAX_T, LAST_MAX_T, UP_N, UP_FIRST, UP_LAST, DOWN_N, DOWN_FIRST, DOWN_LAST) = range(38, 48)
# the closed-loop move
(MOVE_N, MOVE_T0, MOVE_STEP, OUTSIDE, EVER_OUTSIDE, SETTLED_T, PAST, MOVE_LAST) = range(48, 56)
# the battery
(DRAWN, RETURNED, LIFT_WORK, BATTERY_PEAK) = range(56, 60)
# the work cycle's targets: the phase now (-1: before the first), its samples, step, whether
# outside the band now and ever, when it last came inside, its last error; the worst so far
(PH, PH_N, PH_STEP, PH_OUTSIDE, PH_EVER, PH_SETTLED, PH_ERR, WORST_ERR, WORST_SETTLE, SET_DOWN) = range(60, 70)
SIZE = 70

# PHASE: before the first opening, opened, in the hold, after it
WAITING, OPEN, HOLDING, HELD = 0.0, 1.0, 2.0, 3.0


def settings(
    lift_angle_deg: float,
    move_start_s: float,
    move_end_s: float,
    target_rad: float,
    targets: tuple[Any, Any, float] = ((), (), math.nan),
) -> np.ndarray:
    """The settings of one run's metrics: the lift angle, the closed-loop move's window and
    target (``move_start_s`` NaN: no move), and a work cycle's ``targets`` (times s, angles
    rad, the payload's release s: :func:`cycle_targets`; none: open loop)."""
    out = np.full(N_SETTINGS, math.nan)
    out[LIFT_RAD] = math.radians(lift_angle_deg)
    out[MOVE_START] = move_start_s
    out[MOVE_END] = move_end_s
    out[TARGET] = target_rad
    out[RIPPLE] = RIPPLE_PA
    times, angles, release_s = targets
    n = min(len(times), len(angles), MAX_TARGETS)
    out[N_TARGETS] = n
    out[TARGET_TIMES : TARGET_TIMES + n] = times[:n]
    out[TARGET_ANGLES : TARGET_ANGLES + n] = angles[:n]
    out[RELEASE] = release_s
    return out


def cycle_targets(p: Any) -> tuple[tuple[float, ...], tuple[float, ...], float]:
    """(times s, angles rad, release s) of the targets of a closed-loop ``angle`` scenario
    (Parameters ``p``): each of ``command_angles_rad`` from its time in ``command_times_s``;
    the release is the first of ``command_payload_times_s`` where the payload's share on the
    hook falls (NaN: never). None of them for open loop."""
    if p is None or p.command_profile != "angle":
        return (), (), math.nan
    release, share = math.nan, 1.0
    for t, fraction in zip(p.command_payload_times_s, p.command_payload_fractions):
        if fraction < share:
            release = float(t)
            break
        share = fraction
    return tuple(map(float, p.command_times_s)), tuple(map(float, p.command_angles_rad)), release


def accumulator() -> np.ndarray:
    """An accumulator that has seen no sample."""
    m = np.full(SIZE, math.nan)
    m[COUNT] = 0.0
    return m


#: The boom rise (degrees) a lift has to achieve, unless the caller names another.
DEFAULT_LIFT_ANGLE_DEG = 20.0


def move_window(p: Any) -> tuple[float, float, float]:
    """(start s, end s, target rad) of the first move of a closed-loop ``angle`` scenario
    (Parameters ``p``): from its time until the next move's; NaN start for open loop."""
    if p is None or p.command_profile != "angle":
        return math.nan, math.inf, math.nan
    times = p.command_times_s
    return times[0], times[1] if len(times) > 1 else math.inf, p.command_angles_rad[0]


@jitable
def _crossing(
    m: np.ndarray, slot: int, first: bool, t: float, rise: float, level: float, supply: float, loss: float
) -> None:
    """Record in ``slot`` (time, supply, loss) where the rise first reaches ``level``: at this
    sample when it is the search's first, else interpolated from the previous sample."""
    if not math.isnan(m[slot]) or rise < level:
        return
    if first or rise == m[RISE_PREV]:
        m[slot], m[slot + 1], m[slot + 2] = t, supply, loss
        return
    t_prev = m[T_PREV]
    w = (level - m[RISE_PREV]) / (rise - m[RISE_PREV])
    time = t_prev + w * (t - t_prev)
    v = (time - t_prev) / (t - t_prev)
    m[slot] = time
    m[slot + 1] = m[SUPPLY_PREV] + v * (supply - m[SUPPLY_PREV])
    m[slot + 2] = m[LOSS_PREV] + v * (loss - m[LOSS_PREV])


@jitable
def _turn(m: np.ndarray, value: float, t: float, is_max: bool) -> None:
    """A confirmed turning point of the ringing: count maxima, log the swing from the last one."""
    if not math.isnan(m[LAST_TURN]):
        swing = math.log(abs(value - m[LAST_TURN]))
        n, first, last = (UP_N, UP_FIRST, UP_LAST) if is_max else (DOWN_N, DOWN_FIRST, DOWN_LAST)
        m[n] = 1.0 if math.isnan(m[n]) else m[n] + 1.0
        if m[n] == 1.0:
            m[first] = swing
        m[last] = swing
    m[LAST_TURN] = value
    if is_max:
        m[MAXIMA] = 1.0 if math.isnan(m[MAXIMA]) else m[MAXIMA] + 1.0
        if m[MAXIMA] == 1.0:
            m[FIRST_MAX_T] = t
        m[LAST_MAX_T] = t


@jitable
def _ringing(m: np.ndarray, t: float, x: float, ripple: float) -> None:
    """Follow ``x`` for turning points (a peak detector with hysteresis ``ripple``)."""
    if m[HOLD_N] == 1.0:
        m[DIRECTION], m[LOW], m[HIGH] = 0.0, x, x
        return
    if m[DIRECTION] == 0.0:  # no direction yet: the hold's start is no turning point
        if x > m[LOW] + ripple:
            m[DIRECTION], m[EXTREME], m[EXTREME_T] = 1.0, x, t
        elif x < m[HIGH] - ripple:
            m[DIRECTION], m[EXTREME], m[EXTREME_T] = -1.0, x, t
        else:
            m[LOW], m[HIGH] = min(m[LOW], x), max(m[HIGH], x)
    elif m[DIRECTION] > 0.0:  # rising: looking for a maximum
        if x > m[EXTREME]:
            m[EXTREME], m[EXTREME_T] = x, t
        elif x < m[EXTREME] - ripple:
            _turn(m, m[EXTREME], m[EXTREME_T], True)
            m[DIRECTION], m[EXTREME], m[EXTREME_T] = -1.0, x, t
    else:
        if x < m[EXTREME]:
            m[EXTREME], m[EXTREME_T] = x, t
        elif x > m[EXTREME] + ripple:
            _turn(m, m[EXTREME], m[EXTREME_T], False)
            m[DIRECTION], m[EXTREME], m[EXTREME_T] = 1.0, x, t


@jitable
def _move(m: np.ndarray, s: np.ndarray, t: float, alpha: float) -> None:
    """A sample inside the closed-loop move's window."""
    target = s[TARGET]
    if m[MOVE_N] == 0.0:
        m[MOVE_T0], m[MOVE_STEP] = t, target - alpha
        m[OUTSIDE], m[EVER_OUTSIDE], m[SETTLED_T], m[PAST] = 0.0, 0.0, 0.0, 0.0
    m[MOVE_N] += 1.0
    error = alpha - target
    if abs(error) > SETTLING_BAND * abs(m[MOVE_STEP]):
        m[OUTSIDE], m[EVER_OUTSIDE] = 1.0, 1.0
    elif m[OUTSIDE] == 1.0:
        m[OUTSIDE], m[SETTLED_T] = 0.0, t - m[MOVE_T0]
    m[PAST] = max(m[PAST], math.copysign(1.0, m[MOVE_STEP]) * error)
    m[MOVE_LAST] = alpha


@jitable
def _phase_result(m: np.ndarray) -> tuple[float, float]:
    """(|error| rad at its last sample, settling time s: inf if outside its band there) of the
    phase now, were it to end here; zeros for one without samples."""
    if m[PH] < 0.0 or m[PH_N] == 0.0:
        return 0.0, 0.0
    settle = math.inf if m[PH_OUTSIDE] == 1.0 else (m[PH_SETTLED] if m[PH_EVER] == 1.0 else 0.0)
    return abs(m[PH_ERR]), settle


@jitable
def _targets(m: np.ndarray, s: np.ndarray, t: float, alpha: float) -> None:
    """A sample of a work cycle with targets (see the module): follow the phase it falls in."""
    n = int(s[N_TARGETS])
    phase = int(m[PH])
    while phase + 1 < n and t >= s[TARGET_TIMES + phase + 1]:
        error, settle = _phase_result(m)  # the phase ends
        m[WORST_ERR], m[WORST_SETTLE] = max(m[WORST_ERR], error), max(m[WORST_SETTLE], settle)
        phase += 1
        m[PH], m[PH_N] = phase, 0.0
    if phase < 0:
        return
    target = s[TARGET_ANGLES + phase]
    error = alpha - target
    if m[PH_N] == 0.0:
        m[PH_STEP] = target - alpha
        m[PH_OUTSIDE], m[PH_EVER], m[PH_SETTLED] = 0.0, 0.0, 0.0
    m[PH_N] += 1.0
    if abs(error) > max(SETTLING_BAND * abs(m[PH_STEP]), SETTLING_FLOOR_RAD):
        m[PH_OUTSIDE], m[PH_EVER] = 1.0, 1.0
    elif m[PH_OUTSIDE] == 1.0:
        m[PH_OUTSIDE], m[PH_SETTLED] = 0.0, t - s[TARGET_TIMES + phase]
    m[PH_ERR] = error
    if t <= s[RELEASE]:
        m[SET_DOWN] = error


@jitable
def add_sample(
    m: np.ndarray,
    s: np.ndarray,
    t: float,
    q1: float,
    v: float,
    alpha: float,
    p1: float,
    p2: float,
    u: float,
    cavitation: float,
    relief: float,
    supply_j: float,
    loss_j: float,
    drawn_j: float,
    returned_j: float,
    lift_work_j: float,
) -> None:
    """Take the sample at ``t`` into the accumulator ``m`` (settings ``s``); flags are 0.0 or 1.0."""
    first = m[COUNT] == 0.0
    if first:
        m[T0], m[Q0], m[ALPHA0] = t, q1, alpha
        m[Q_MAX], m[RISE_MAX], m[SPEED_MAX], m[V2_SUM] = q1, 0.0, 0.0, 0.0
        m[P_MAX], m[P_MIN], m[CAV_S], m[RELIEF_S] = max(p1, p2), min(p1, p2), 0.0, 0.0
        m[OPENED], m[PHASE], m[HOLD_N], m[MOVE_N] = 0.0, WAITING, 0.0, 0.0
        m[PH], m[PH_N], m[WORST_ERR], m[WORST_SETTLE] = -1.0, 0.0, 0.0, 0.0
    else:
        m[CAV_S] += (t - m[T_PREV]) * m[CAV_PREV]
        m[RELIEF_S] += (t - m[T_PREV]) * m[RELIEF_PREV]
    m[COUNT] += 1.0
    rise = alpha - m[ALPHA0]
    m[Q_MAX] = max(m[Q_MAX], q1)
    m[RISE_MAX] = max(m[RISE_MAX], rise)
    m[SPEED_MAX] = max(m[SPEED_MAX], abs(v))
    m[V2_SUM] += v * v
    m[P_MAX] = max(m[P_MAX], max(p1, p2))
    m[P_MIN] = min(m[P_MIN], min(p1, p2))
    level = s[LIFT_RAD]
    _crossing(m, START_T, first, t, rise, level, supply_j, loss_j)
    opening = m[OPENED] == 0.0 and u > 0.0
    if opening:
        m[OPENED], m[T_OPEN] = 1.0, t
    if m[OPENED] == 1.0:
        _crossing(m, OPEN_T, opening, t, rise, level, supply_j, loss_j)
    # the hold after the first opening, and its ringing
    if m[PHASE] == WAITING and u > 0.0:
        m[PHASE] = OPEN
    elif m[PHASE] == OPEN and u <= 0.0:
        m[PHASE], m[HOLD_U] = HOLDING, u
    elif m[PHASE] == HOLDING and u != m[HOLD_U]:
        m[PHASE] = HELD
    if m[PHASE] == HOLDING:
        m[HOLD_N] += 1.0
        m[HOLD_Q_MAX] = q1 if m[HOLD_N] == 1.0 else max(m[HOLD_Q_MAX], q1)
        m[HOLD_Q_LAST] = q1
        _ringing(m, t, p1, s[RIPPLE])
    if not math.isnan(s[MOVE_START]) and s[MOVE_START] <= t < s[MOVE_END]:
        _move(m, s, t, alpha)
    if s[N_TARGETS] > 0.0:
        _targets(m, s, t, alpha)
    # the battery's mean power since the last sample (the battery's energy is a state: no
    # evaluation of the ledger per sample); NaN (no battery) stays NaN
    if first:
        m[BATTERY_PEAK] = 0.0 * drawn_j - math.inf
    elif t > m[T_PREV]:
        power = ((drawn_j - returned_j) - (m[DRAWN] - m[RETURNED])) / (t - m[T_PREV])
        if power > m[BATTERY_PEAK]:
            m[BATTERY_PEAK] = power
    m[T_PREV], m[RISE_PREV], m[SUPPLY_PREV], m[LOSS_PREV] = t, rise, supply_j, loss_j
    m[CAV_PREV], m[RELIEF_PREV] = cavitation, relief
    m[SUPPLY], m[LOSS] = supply_j, loss_j
    m[DRAWN], m[RETURNED], m[LIFT_WORK] = drawn_j, returned_j, lift_work_j


@jitable
def _decrement(n: float, first: float, last: float) -> float:
    """Logarithmic decrement per cycle from the first and last of ``n`` swings one cycle apart."""
    return (first - last) / (n - 1.0) if n >= 2.0 else math.nan


@jitable
def finish(m: np.ndarray, s: np.ndarray, out: np.ndarray) -> None:
    """Write the metrics :data:`NAMES` of the samples taken into ``out`` (NaN where undefined)."""
    for k in range(len(out)):
        out[k] = math.nan
    if m[COUNT] == 0.0:
        return
    opened = m[OPENED] == 1.0
    crossing = OPEN_T if opened else START_T
    start_t = m[T_OPEN] if opened else m[T0]
    out[0] = 0.0 if math.isnan(m[crossing]) else 1.0
    out[1] = m[crossing] - start_t
    out[2], out[3] = m[crossing + 1], m[crossing + 2]
    out[4] = math.degrees(m[RISE_MAX])
    out[5] = m[Q_MAX] - m[Q0]
    out[6] = m[SPEED_MAX]
    out[7] = math.sqrt(m[V2_SUM] / m[COUNT])
    if m[HOLD_N] >= HOLD_MIN_SAMPLES:
        out[8] = max(0.0, m[HOLD_Q_MAX] - m[HOLD_Q_LAST])
    if m[HOLD_N] >= RINGING_MIN_SAMPLES and m[MAXIMA] >= 2.0:
        out[9] = (m[MAXIMA] - 1.0) / (m[LAST_MAX_T] - m[FIRST_MAX_T])
        up = _decrement(m[UP_N], m[UP_FIRST], m[UP_LAST])
        down = _decrement(m[DOWN_N], m[DOWN_FIRST], m[DOWN_LAST])
        d = down if math.isnan(up) else (up if math.isnan(down) else 0.5 * (up + down))
        out[10] = d / math.sqrt(4.0 * math.pi * math.pi + d * d)
    out[11], out[12] = m[P_MAX], m[P_MIN]
    out[13], out[14] = m[CAV_S], m[RELIEF_S]
    if m[MOVE_N] > 0.0:
        if m[EVER_OUTSIDE] == 0.0:
            out[15] = 0.0
        elif m[OUTSIDE] == 0.0:
            out[15] = m[SETTLED_T]
        out[16] = math.degrees(m[PAST]) if m[MOVE_STEP] != 0.0 else 0.0
        out[17] = math.degrees(s[TARGET] - m[MOVE_LAST])
    if s[N_TARGETS] > 0.0 and m[PH] >= 0.0:  # the last phase ends with the run
        error, settle = _phase_result(m)
        out[18], out[19] = math.degrees(max(m[WORST_ERR], error)), max(m[WORST_SETTLE], settle)
        out[20] = math.degrees(m[SET_DOWN])
    out[21], out[22] = m[SUPPLY], m[LOSS]
    battery = m[DRAWN] - m[RETURNED]
    out[23], out[24], out[25], out[26] = battery, m[DRAWN], m[RETURNED], m[LIFT_WORK]
    if battery > 0.0:
        out[27] = m[LIFT_WORK] / battery
    if m[BATTERY_PEAK] > -math.inf:  # (NaN without a battery, as every battery figure)
        out[28] = m[BATTERY_PEAK]

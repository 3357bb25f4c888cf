"""Design metrics of a run, from its signals (a recorded bag or a simulated trajectory).

The metrics a sweep reports are defined once, in :mod:`streaming`, and taken sample by
sample; :func:`metrics` runs that over stored signals and adds the figures that need the
whole run at once. All SI (s, m, m/s, Pa, Hz, J, J/m).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..solve import streaming
from ..solve.streaming import DEFAULT_LIFT_ANGLE_DEG, cycle_targets, move_window

#: The battery's signals among the samples (the physical model's ledger).
BATTERY = ("battery_drawn", "battery_returned", "lift_work")


def streamed(
    signals: Mapping[str, np.ndarray],
    lift_angle_deg: float = DEFAULT_LIFT_ANGLE_DEG,
    move: tuple[float, float, float] = (math.nan, math.inf, math.nan),
    ripple: float = streaming.RIPPLE_PA,
    targets: tuple = ((), (), math.nan),
) -> dict[str, float]:
    """The metrics of :mod:`streaming` over stored ``signals`` (names of streaming.SAMPLE_SIGNALS; a
    missing one counts as 0, a missing battery signal as NaN: its metrics are unknown), with the
    closed-loop ``move`` (see :func:`move_window`), a work cycle's ``targets`` (see
    :func:`cycle_targets`) and the ringing's turning points counted beyond ``ripple``."""
    n = len(signals["t"])
    columns = [
        np.asarray(signals[k], dtype=float) if k in signals else np.full(n, math.nan if k in BATTERY else 0.0)
        for k in streaming.SAMPLE_SIGNALS
    ]
    s = streaming.settings(lift_angle_deg, *move, targets)
    s[streaming.RIPPLE] = ripple
    m = streaming.accumulator()
    for row in zip(*(c.tolist() for c in columns)):
        streaming.add_sample(m, s, *row)
    out = np.empty(len(streaming.NAMES))
    streaming.finish(m, s, out)
    return dict(zip(streaming.NAMES, out.tolist()))


def _first_opening(u: np.ndarray) -> int:
    opened = np.nonzero(u > 0.0)[0]
    return int(opened[0]) if len(opened) else 0


def oscillation(t: np.ndarray, x: np.ndarray, ripple: float = streaming.RIPPLE_PA) -> tuple[float, float]:
    """Frequency (Hz) and damping ratio of the ringing in ``x`` (p1 in Pa, say), from its
    turning points that stand out by more than ``ripple`` (see :mod:`streaming`): NaN where
    there are fewer than two maxima."""
    x = np.asarray(x, dtype=float)
    hold = np.zeros(len(x))
    hold[0] = 1.0  # opened at the first sample, closed from the second: the whole signal is the hold
    m = streamed({"t": t, "p1": x, "p2": x, "u": hold}, ripple=ripple)
    return m["oscillation_hz"], m["damping_ratio"]


def lift_metrics(signals: Mapping[str, np.ndarray], lift_angle_deg: float = DEFAULT_LIFT_ANGLE_DEG) -> dict[str, float]:
    """How the boom lifts through ``lift_angle_deg`` of rise above its start elevation:
    ``rise_deg``, ``lift_completed``, ``lift_time_s`` (from the first opening command),
    ``lift_energy_j`` and ``lift_valve_loss_j`` (see :mod:`streaming`)."""
    m = streamed(signals, lift_angle_deg)
    return {k: m[k] for k in ("rise_deg", "lift_completed", "lift_time_s", "lift_energy_j", "lift_valve_loss_j")}


def metrics(
    signals: Mapping[str, np.ndarray],
    target_fraction: float = 0.9,
    lift_angle_deg: float = DEFAULT_LIFT_ANGLE_DEG,
    params: Any = None,
) -> dict[str, float]:
    """The design metrics of one run: those of :mod:`streaming` (with the closed-loop move and
    the targets of ``params``' angle scenario, if given), plus figures of the whole run:

    - ``duration_s``;
    - ``time_to_target_s``: from the first opening command (u > 0) until q1 first reaches
      ``target_fraction`` of its largest rise;
    - ``supply_energy_per_m_j_m``, ``valve_loss_per_m_j_m``: per metre of that rise.
    """
    t, q, u = (np.asarray(signals[k], dtype=float) for k in ("t", "q1", "u"))
    out = streamed(signals, lift_angle_deg, move_window(params), targets=cycle_targets(params))
    lift = out["lift_m"]
    reached = np.nonzero(q >= q[0] + target_fraction * lift)[0] if lift > 0 else []
    out["duration_s"] = float(t[-1] - t[0])
    out["time_to_target_s"] = float(t[reached[0]] - t[_first_opening(u)]) if len(reached) else math.nan
    out["supply_energy_per_m_j_m"] = out["supply_energy_j"] / lift if lift > 0 else math.nan
    out["valve_loss_per_m_j_m"] = out["valve_loss_energy_j"] / lift if lift > 0 else math.nan
    return out


def step_response(times_s: np.ndarray, angles_rad: np.ndarray, target_rad: float, start_rad: float) -> dict[str, float]:
    """Figures of a closed-loop move to ``target_rad`` over the samples given (see
    :mod:`streaming`): ``settling_s``, ``overshoot`` (as a fraction of the step from
    ``start_rad``) and ``final_error_rad``."""
    t = np.asarray(times_s, dtype=float)
    m = streamed({"t": t, "alpha": angles_rad}, move=(float(t[0]), math.inf, target_rad))
    step = abs(target_rad - start_rad)
    past = math.radians(m["target_overshoot_deg"])
    return {
        "settling_s": m["settling_s"],
        "overshoot": past / step if step else 0.0,
        "final_error_rad": math.radians(m["target_error_deg"]),
    }


def move_metrics(p: Any, signals: Mapping[str, np.ndarray]) -> dict[str, float]:
    """The first move of a closed-loop ``angle`` scenario (Parameters ``p``), from its time
    until the next move's (or the end): ``start_deg``, ``target_deg``, ``settling_s``,
    ``target_overshoot_deg`` and ``target_error_deg``. NaN for an open-loop scenario."""
    names = ("settling_s", "target_overshoot_deg", "target_error_deg")
    out = dict.fromkeys(("start_deg", "target_deg", *names), math.nan)
    start_s, end_s, target = move_window(p)
    t = np.asarray(signals["t"], dtype=float)
    window = (t >= start_s) & (t < end_s)
    if math.isnan(start_s) or not window.any():
        return out
    m = streamed(signals, move=(start_s, end_s, target))
    out.update({k: m[k] for k in names})
    out.update(start_deg=math.degrees(float(np.asarray(signals["alpha"])[window][0])), target_deg=math.degrees(target))
    return out

"""Design metrics of a run, from its signals (a recorded bag or a simulated trajectory).

Each metric is defined in :func:`metrics`; all are SI (s, m, m/s, Pa, Hz, J, J/m).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

#: The boom rise (degrees) a lift has to achieve, unless the caller names another.
DEFAULT_LIFT_ANGLE_DEG = 20.0


def _first_opening(u: np.ndarray) -> int:
    opened = np.nonzero(u > 0.0)[0]
    return int(opened[0]) if len(opened) else 0


def _first_close_after_opening(u: np.ndarray) -> int | None:
    """Index where the valve command first returns to 0 after opening positively."""
    opened = np.nonzero(u > 0.0)[0]
    if not len(opened):
        return None
    after = np.nonzero(u[opened[0] :] <= 0.0)[0]
    return int(opened[0] + after[0]) if len(after) else None


def _segment_after(u: np.ndarray, start: int) -> slice:
    """From ``start`` until the command changes again (a hold)."""
    changes = np.nonzero(u[start:] != u[start])[0]
    return slice(start, start + int(changes[0]) if len(changes) else len(u))


def oscillation(t: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """Dominant frequency (Hz) and damping ratio of the oscillation in ``x``.

    Frequency: the highest peak of the spectrum of ``x`` minus its linear trend, from two
    cycles per window up. Damping: from the logarithmic decrement of successive positive
    peaks of the detrended signal, zeta = d / sqrt(4 pi^2 + d^2). Both NaN where there is
    no oscillation (fewer than two positive peaks).
    """
    if len(t) < 16:
        return math.nan, math.nan
    detrended = x - np.polyval(np.polyfit(t, x, 1), t)
    if np.ptp(detrended) <= 1e-12 * max(1.0, np.max(np.abs(x))):
        return math.nan, math.nan
    inner = detrended[1:-1]
    peaks = np.nonzero((inner > detrended[:-2]) & (inner >= detrended[2:]) & (inner > 0))[0] + 1
    if len(peaks) < 2:
        return math.nan, math.nan  # a single hump is a settling motion, not an oscillation
    dt = float(np.median(np.diff(t)))
    spectrum = np.abs(np.fft.rfft(detrended * np.hanning(len(detrended))))
    freqs = np.fft.rfftfreq(len(detrended), dt)
    # from two cycles per window up: the lowest bins hold what is left of a slow settling
    k = int(np.argmax(spectrum[2:]) + 2)
    frequency = float(freqs[k])
    amplitudes = detrended[peaks]
    decrement = float(np.mean(np.log(amplitudes[:-1] / amplitudes[1:])))
    return frequency, decrement / math.sqrt(4 * math.pi**2 + decrement**2)


def _crossing(t: np.ndarray, x: np.ndarray, level: float, start: int) -> tuple[float, int] | None:
    """Time at which ``x`` first reaches ``level`` at or after index ``start``, linearly
    interpolated between samples, and the index of the sample before the crossing."""
    above = np.nonzero(x[start:] >= level)[0]
    if not len(above):
        return None
    k = start + int(above[0])
    if k == start or x[k] == x[k - 1]:
        return float(t[k]), k
    w = (level - x[k - 1]) / (x[k] - x[k - 1])
    return float(t[k - 1] + w * (t[k] - t[k - 1])), k - 1


def _at(t: np.ndarray, y: np.ndarray, time: float, k: int) -> float:
    """``y`` at ``time`` (between samples k and k + 1), linearly interpolated."""
    if k + 1 >= len(t) or t[k + 1] == t[k]:
        return float(y[k])
    w = (time - t[k]) / (t[k + 1] - t[k])
    return float(y[k] + w * (y[k + 1] - y[k]))


def lift_metrics(signals: Mapping[str, np.ndarray], lift_angle_deg: float = DEFAULT_LIFT_ANGLE_DEG) -> dict[str, float]:
    """How the boom lifts through ``lift_angle_deg`` of rise above its start elevation.

    - ``rise_deg``: largest rise of the boom elevation alpha above its start value.
    - ``lift_completed``: 1.0 if the boom rose through the angle, else 0.0.
    - ``lift_time_s``: from the first opening command (u > 0) until alpha first reaches
      the start value plus the angle (interpolated between samples); NaN if it does not.
    - ``lift_energy_j``, ``lift_valve_loss_j``: energy drawn from the supply and dissipated
      in the valve (and relief valves) from the start until that moment: the energy of the lift.
    """
    t, alpha, u = (np.asarray(signals[k], dtype=float) for k in ("t", "alpha", "u"))
    rise = alpha - alpha[0]
    out = {
        "rise_deg": float(np.degrees(np.max(rise))),
        "lift_completed": 0.0,
        "lift_time_s": math.nan,
        "lift_energy_j": math.nan,
        "lift_valve_loss_j": math.nan,
    }
    opening = _first_opening(u)
    crossing = _crossing(t, rise, math.radians(lift_angle_deg), opening)
    if crossing is not None:
        time, k = crossing
        out["lift_completed"] = 1.0
        out["lift_time_s"] = time - float(t[opening])
        out["lift_energy_j"] = _at(t, np.asarray(signals["supply_energy"], float), time, k)
        out["lift_valve_loss_j"] = _at(t, np.asarray(signals["valve_loss_energy"], float), time, k)
    return out


def metrics(
    signals: Mapping[str, np.ndarray], target_fraction: float = 0.9, lift_angle_deg: float = DEFAULT_LIFT_ANGLE_DEG
) -> dict[str, float]:
    """The design metrics of one run.

    - ``lift_m``: largest rise of q1 above its start value.
    - ``time_to_target_s``: from the first opening command (u > 0) until q1 first reaches
      ``target_fraction`` of that rise.
    - ``peak_speed_m_s``, ``rms_speed_m_s``: of the rod.
    - ``overshoot_m``: after the valve first closes following an extension, how far q1
      rises above the value it settles to by the end of that hold.
    - ``oscillation_hz``, ``damping_ratio``: of p1 over that hold (see :func:`oscillation`).
    - ``peak_pressure_pa``, ``min_pressure_pa``: over both chambers.
    - ``cavitation_s``, ``relief_s``: time with the flag set.
    - ``supply_energy_j``, ``valve_loss_energy_j``: at the end; ``..._per_m``: per metre of lift.
    - with the boom elevation ``alpha`` among the signals, those of :func:`lift_metrics`.
    """
    t, q, v, u = (np.asarray(signals[k], dtype=float) for k in ("t", "q1", "v", "u"))
    p = np.concatenate([np.asarray(signals["p1"], float), np.asarray(signals["p2"], float)])
    dt = np.diff(t, append=t[-1])
    lift = float(np.max(q) - q[0])
    reached = np.nonzero(q >= q[0] + target_fraction * lift)[0] if lift > 0 else []
    out = {
        "duration_s": float(t[-1] - t[0]),
        "lift_m": lift,
        "time_to_target_s": float(t[reached[0]] - t[_first_opening(u)]) if len(reached) else math.nan,
        "peak_speed_m_s": float(np.max(np.abs(v))),
        "rms_speed_m_s": float(np.sqrt(np.mean(v * v))),
        "overshoot_m": math.nan,
        "oscillation_hz": math.nan,
        "damping_ratio": math.nan,
        "peak_pressure_pa": float(np.max(p)),
        "min_pressure_pa": float(np.min(p)),
        "cavitation_s": float(np.sum(dt[np.asarray(signals["cavitation"], bool)])),
        "relief_s": float(np.sum(dt[np.asarray(signals["relief_open"], bool)])),
        "supply_energy_j": float(signals["supply_energy"][-1]),
        "valve_loss_energy_j": float(signals["valve_loss_energy"][-1]),
    }
    out["supply_energy_per_m_j_m"] = out["supply_energy_j"] / lift if lift > 0 else math.nan
    out["valve_loss_per_m_j_m"] = out["valve_loss_energy_j"] / lift if lift > 0 else math.nan
    close = _first_close_after_opening(u)
    if close is not None:
        hold = _segment_after(u, close)
        q_hold = q[hold]
        if len(q_hold) > 4:
            settled = float(np.median(q_hold[-max(1, len(q_hold) // 4) :]))
            out["overshoot_m"] = max(0.0, float(np.max(q_hold)) - settled)
            out["oscillation_hz"], out["damping_ratio"] = oscillation(t[hold], np.asarray(signals["p1"], float)[hold])
    if "alpha" in signals:
        out.update(lift_metrics(signals, lift_angle_deg))
    return out


def step_response(
    times_s: np.ndarray, angles_rad: np.ndarray, target_rad: float, start_rad: float, band: float = 0.02
) -> dict[str, float]:
    """Figures of a closed-loop move from ``start_rad`` to ``target_rad``:

    - ``settling_s``: from the first sample until the angle stays within +-``band`` of the
      step around the target (NaN if it is outside at the end);
    - ``overshoot``: how far it passed the target, as a fraction of the step;
    - ``final_error_rad``: target minus angle at the last sample.
    """
    t, a = np.asarray(times_s, dtype=float), np.asarray(angles_rad, dtype=float)
    step = target_rad - start_rad
    error = a - target_rad
    outside = np.nonzero(np.abs(error) > band * abs(step))[0]
    if not len(outside):
        settle = 0.0
    elif outside[-1] + 1 >= len(t):
        settle = math.nan
    else:
        settle = float(t[outside[-1] + 1] - t[0])
    past = max(0.0, float(np.max(math.copysign(1.0, step) * error)))
    return {"settling_s": settle, "overshoot": past / abs(step) if step else 0.0, "final_error_rad": -float(error[-1])}


def move_metrics(p: Any, signals: Mapping[str, np.ndarray]) -> dict[str, float]:
    """The first move of a closed-loop ``angle`` scenario (Parameters ``p``): from its time until
    the next move's (or the end), with :func:`step_response`'s figures in degrees. NaN for an
    open-loop scenario."""
    out = dict.fromkeys(("start_deg", "target_deg", "settling_s", "target_overshoot_deg", "target_error_deg"), math.nan)
    if p.command_profile != "angle":
        return out
    t, alpha = np.asarray(signals["t"], dtype=float), np.asarray(signals["alpha"], dtype=float)
    end_s = p.command_times_s[1] if len(p.command_times_s) > 1 else math.inf
    window = (t >= p.command_times_s[0]) & (t < end_s)
    if not window.any():
        return out
    start, target = float(alpha[window][0]), p.command_angles_rad[0]
    figures = step_response(t[window], alpha[window], target, start)
    out.update(
        start_deg=math.degrees(start),
        target_deg=math.degrees(target),
        settling_s=figures["settling_s"],
        target_overshoot_deg=math.degrees(figures["overshoot"] * abs(target - start)),
        target_error_deg=math.degrees(figures["final_error_rad"]),
    )
    return out

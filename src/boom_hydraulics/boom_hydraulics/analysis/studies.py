"""The paper's studies, computed: statics over the stroke, the dynamic cases, the solver study."""

from __future__ import annotations

import time
import tracemalloc
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..model import geometry
from ..model.parameters import GEOMETRY_CLEARANCE_M, Parameters, with_updates
from ..solve.simulation import Simulator, Trajectory, simulate


def statics(p: Parameters, diameters_m: Sequence[float], points: int = 161) -> dict[str, np.ndarray]:
    """alpha, phi, static rod force and holding pressure per diameter over the open stroke (Figs. 3-5)."""
    low, high = geometry.triangle_bounds_m(p.a_m, p.b_m)
    q1 = np.linspace(low + GEOMETRY_CLEARANCE_M, high - GEOMETRY_CLEARANCE_M, points)
    force = geometry.static_rod_force_of(p, q1, np)
    out = {
        "q1": q1,
        "alpha": geometry.boom_angle_rad(q1, p.a_m, p.b_m, p.support_height_m, np),
        "phi": geometry.rod_boom_angle_rad(q1, p.a_m, p.b_m, np),
        "static_force": force,
    }
    for d in diameters_m:
        out[f"holding_pressure_D{d * 1000:g}mm"] = geometry.holding_pressure_pa(force, d)
    return out


_STATICS_UNITS = {"q1": "m", "alpha": "rad", "phi": "rad", "static_force": "N"}


def statics_header(table: dict[str, np.ndarray]) -> list[str]:
    """CSV column names with units of a :func:`statics` table (boom-sim statics and boom-study alike)."""
    return [f"{name} [{_STATICS_UNITS.get(name, 'Pa')}]" for name in table]


def dynamic_case(params: Parameters, duration_s: float) -> Trajectory:
    """A run with the valve fully open, up to ``duration_s`` or until the model stops
    (paper mode leaves the valid geometry when the rod reaches q1 = a + b)."""
    return Simulator(params).run(duration_s, lambda t: 1.0, stop_on_error=True)


def physical_counterpart(paper: Parameters) -> Parameters:
    """Physical mode with the paper case's piston diameter (rod 0.55 D) and the default components."""
    d = paper.piston_diameter_m
    return with_updates(Parameters(), piston_diameter_m=d, rod_diameter_m=0.55 * d, command_value=1.0)


@dataclass(frozen=True)
class SolverPoint:
    """One run of the solver study."""

    method: str
    dt_s: float
    error: float  # relative error of q1 at the end against the reference
    seconds: float  # wall time
    peak_mib: float  # peak memory, every point kept as the paper's listing keeps it


def solver_study(
    params: Parameters,
    duration_s: float,
    steps_s: dict[str, Sequence[float]],
    reference_dt_s: float = 1.25e-4,
) -> list[SolverPoint]:
    """Error in the final q1 against step size for each method, with time and memory."""
    reference = simulate(with_updates(params, method="rk4", time_step_s=reference_dt_s), duration_s, every=10**9)
    q_ref = float(reference["q1"][-1])
    points = []
    for method, dts in steps_s.items():
        for dt in dts:
            run = with_updates(params, method=method, time_step_s=dt)
            tracemalloc.start()
            t0 = time.perf_counter()
            trajectory = simulate(run, duration_s, every=1, jit=False)
            seconds = time.perf_counter() - t0
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            error = abs(float(trajectory["q1"][-1]) - q_ref) / abs(q_ref)
            points.append(SolverPoint(method, dt, error, seconds, peak / 2**20))
    return points

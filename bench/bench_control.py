"""What the position controller achieves with config/default.yaml's gains: step responses and
moves across the payload range.

    tools/with-env python bench/bench_control.py        # about half a minute

A 20-degree setpoint step (the hardest case: the valve saturates) up from q1 = 1.3 m and down
from q1 = 1.6 m, and a MoveBoom-style move to 30 degrees at control_max_speed_rad_s, at 0, 50
and 200 kg. Settling: into +-2 % of the step, for good. Overshoot: past the target. Error:
target minus angle after 5 s (the dead-band holds the boom within twice its width). These are
simulation results, not timings: they do not depend on the machine.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from tables import table

from boom_hydraulics.analysis.metrics import step_response
from boom_hydraulics.model import config
from boom_hydraulics.model.geometry import boom_angle_rad
from boom_hydraulics.model.parameters import with_updates
from boom_hydraulics.model.setpoints import SetpointPath, timed_moves
from boom_hydraulics.solve.closed_loop import PositionLoop
from boom_hydraulics.solve.simulation import Simulator

DEFAULT = config.load(Path(__file__).resolve().parents[1] / "config" / "default.yaml")
SECONDS = 5.0


def run(payload_kg: float, start_m: float, target: str) -> list[str]:
    p = with_updates(DEFAULT, payload_mass_kg=payload_kg, initial_length_m=start_m)
    start = boom_angle_rad(start_m, p.a_m, p.b_m, p.support_height_m)
    if target == "move to 30 deg":
        goal = math.radians(30.0)
        path = timed_moves(start, [0.0], [goal], p.control_max_speed_rad_s)
    else:
        goal = start + math.radians(20.0 if target == "step +20 deg" else -20.0)
        path = SetpointPath.of([0.0], [goal])
    trajectory = Simulator(p, jit=True).run(SECONDS, PositionLoop([p], path))
    figures = step_response(trajectory["t"], trajectory["alpha"], goal, start)
    u = trajectory["u"]
    switches = int(np.sum(np.diff((u != 0.0).astype(int)) != 0))
    return [
        target,
        f"{payload_kg:g}",
        f"{math.degrees(start):.1f} -> {math.degrees(goal):.1f}",
        f"{figures['settling_s']:.2f}",
        f"{math.degrees(figures['overshoot'] * abs(goal - start)):.3f}",
        f"{math.degrees(figures['final_error_rad']):+.3f}",
        f"{trajectory['p1'].max() / 1e6:.1f}",
        f"{trajectory['supply_energy'][-1] / 1e3:.2f}",
        str(switches),
    ]


def main() -> None:
    rows = [
        run(payload, start, target)
        for target, start in (("step +20 deg", 1.3), ("step -20 deg", 1.6), ("move to 30 deg", 1.37))
        for payload in (0.0, 50.0, 200.0)
    ]
    p = DEFAULT
    table(
        f"Position control, Kp {p.control_position_gain_1_rad:g} /rad, Ki {p.control_integral_gain_1_rad_s:g} "
        f"/(rad s), dead-band {p.control_deadband_rad:g} rad, moves at {p.control_max_speed_rad_s:g} rad/s "
        f"({SECONDS:g} s runs)",
        [
            "setpoint",
            "payload kg",
            "deg",
            "settling s (2 %)",
            "overshoot deg",
            "error deg",
            "peak p1 MPa",
            "supply kJ",
            "valve open/close",
        ],
        rows,
    )


if __name__ == "__main__":
    main()

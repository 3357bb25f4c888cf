"""How long a linear model takes: ``boom-sim linearize``'s work at one point, and the sweep's
linear metrics over many design points, against a run of the compiled model in the same process.

    tools/with-env python bench/bench_linearize.py        # about half a minute

Target: linearise at one point (operating point, Jacobian, modes, gains, Bode data; with the
controller's margins) in under 1 s, in a process where the model is compiled (numba). The
reference is a 1 s lift through the compiled run kernel (simulate()), measured in the same
run: the ratio says how many such runs one linearisation costs, whatever the machine's load.
"""

from __future__ import annotations

from pathlib import Path

from tables import best_of, table

from boom_hydraulics.analysis import linear_model as lm
from boom_hydraulics.analysis import linearization
from boom_hydraulics.analysis.operating_point import operating_point
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import with_updates
from boom_hydraulics.solve import accelerate
from boom_hydraulics.solve.simulation import simulate

DEFAULT = config.load(Path(__file__).resolve().parents[1] / "config" / "default.yaml")
TARGET_S = 1.0
SWEEP_POINTS = 1000


def main() -> None:
    assert accelerate.available(), "numba is needed: the target is for the compiled model"
    simulate(DEFAULT, 1.0)  # compile or load the run kernel first
    reference = best_of(lambda: simulate(DEFAULT, 1.0), repeat=5)

    def one(controller: bool) -> None:
        result = linearization.study(DEFAULT, 1.37, 0.0, controller=controller)
        linearization.responses(result)
        linearization.summary(result)

    one(True)  # python-control's first use loads its parts
    rows = []
    for what, fn in (
        ("operating point + A, B (centred valve)", lambda: lm.linearize(operating_point(DEFAULT, 1.37))),
        (
            "operating point + A, B (steady motion, u = 0.05)",
            lambda: lm.linearize(operating_point(DEFAULT, 1.37, 0.05)),
        ),
        ("linearize: modes, gains, Bode data", lambda: one(False)),
        ("linearize --controller: + loop gain, margins", lambda: one(True)),
    ):
        seconds = best_of(fn, repeat=5)
        rows.append([what, f"{seconds * 1e3:.1f} ms", f"{seconds / reference:.2f}", f"< {TARGET_S:g} s",
                     "yes" if seconds < TARGET_S else "NO"])  # fmt: skip
    sets = [with_updates(DEFAULT, payload_mass_kg=200.0 * k / SWEEP_POINTS) for k in range(SWEEP_POINTS)]
    seconds = best_of(lambda: lm.mid_stroke_modes(sets), repeat=3)
    rows.append([f"sweep metrics, {SWEEP_POINTS} points at once (numpy)", f"{seconds * 1e3:.1f} ms",
                 f"{seconds / reference:.2f}", "", ""])  # fmt: skip
    rows.append(["reference: 1 s lift, compiled run kernel (simulate)", f"{reference * 1e3:.1f} ms", "1.00", "", ""])
    table(
        "Linearisation at q1 = 1.37 m, default config (best of 5)",
        ["what", "time", "x reference", "target", "met"],
        rows,
    )


if __name__ == "__main__":
    main()

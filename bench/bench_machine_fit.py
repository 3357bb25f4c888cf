"""How long one re-simulation of a fit of a real machine's bag (no DriveState) takes when the
fit reads the state only at the time steps around its samples, against reading it at every
time step (the reference, measured in the same run: ``read_at_s=None``). Both give the same
simulated signals, bit for bit (test_calibrate holds them so).

    tools/with-env python bench/bench_machine_fit.py [--seconds 3] [--rate 100]

The bag: the default machine through a lift, hold, lowering and hold, its three sensors (rod
position, both pressures) at about ``--rate`` Hz each with jittered log times and noise
(test/machine_bags.py, as the calibration tests record it).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from tables import ROOT, best_of, table, write_results

sys.path.insert(0, str(ROOT / "test"))  # the tests' recorder of a machine's bag
from machine_bags import record_machine

from boom_hydraulics.calibration import fit

NOISE = {"q1": 2e-4, "p1": 5e4, "p2": 5e4}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="the bag's length, s")
    parser.add_argument("--rate", type=float, default=100.0, help="each sensor's rate, Hz")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        bag = record_machine(Path(tmp) / "bag", duration_s=args.seconds, rate_hz=args.rate, noise=NOISE)
        problem = fit.prepare(bag, ["bulk_modulus_pa"], ROOT / "config" / "default.yaml")
        theta = [1.05]
        problem.simulate(theta)  # compile or load the kernels first
        around = best_of(lambda: problem.simulate(theta), 5)
        read_at, problem.read_at_s = problem.read_at_s, None
        every = best_of(lambda: problem.simulate(theta), 5)
        problem.read_at_s = read_at
    rows = [
        ["read at every time step (reference)", f"{every * 1e3:.1f} ms", "1"],
        ["read at the steps around each sample", f"{around * 1e3:.1f} ms", f"{around / every:.2f}"],
    ]
    text = table(
        f"One re-simulation of a {args.seconds:g} s machine bag, 3 sensors at {args.rate:g} Hz "
        f"({len(read_at)} sample times), best of 5",
        ["what", "time", "x reference"],
        rows,
    )
    print(f"\n{write_results('machine-fit', text)}")


if __name__ == "__main__":
    main()

"""How long a calibration takes: three parameters fitted to a 9 s bag, against one
re-simulation of the same bag measured in the same run.

    tools/with-env python bench/bench_calibrate.py                  # records its bag with boom-demo first
    tools/with-env python bench/bench_calibrate.py --bag bags/<run>  # a bag of make run (9 s)

The bag is what ``make run`` records: the node through boom-demo's lift (3 s), hold (2 s),
lower (3 s) and hold. The fit starts from bulk_modulus_pa x 0.6, orifice_diameter_m x 1.2 and
coulomb_friction_n x 0.5 and fits those three from boom-calibrate's four default starts (its
own path, in this process), and says whether the fit can be trusted (calibration.verdict).
Target: under 60 s on this 2-core machine. The ratio to one re-simulation says how many
re-simulations' worth the fit took, whatever the machine's load.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import tempfile
import time
from pathlib import Path

from tables import table

from boom_hydraulics.calibration import fit, report
from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.resim.resimulation import Replay, read_recorded

TARGET_S = 60.0
FITTED = ("bulk_modulus_pa", "orifice_diameter_m", "coulomb_friction_n")
FACTORS = (0.6, 1.2, 0.5)


def record(folder: Path) -> Path:
    """A bag of boom-demo's 9 s cycle (a DDS domain of its own: no other node hears it)."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(90 + os.getpid() % 10))
    subprocess.run(["boom-demo", "--bags", str(folder)], check=True, env=env, capture_output=True, timeout=600)
    (bag,) = [p for p in folder.iterdir() if p.is_dir() and not p.name.endswith(".analysis")]
    return bag


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bag", type=Path, help="a 9 s bag of make run (default: record one with boom-demo)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        bag = args.bag or record(Path(tmp))
        run, values = read_recorded(bag)
        truth = Parameters()
        overrides = {n: f * getattr(truth, n) for n, f in zip(FITTED, FACTORS)}
        list(Replay(run, values))  # compile or load the kernels first
        began = time.perf_counter()
        list(Replay(run, values, overrides))
        reference = time.perf_counter() - began
        began = time.perf_counter()
        result = fit.calibrate(fit.prepare(bag, FITTED, None, overrides))
        seconds = time.perf_counter() - began
    duration = (run.end_ns - run.clock_origin_ns) * 1e-9
    rows = [
        [f"fit {len(FITTED)} parameters, {duration:.1f} s bag", f"{seconds:.1f} s", f"{seconds / reference:.0f}",
         f"< {TARGET_S:g} s", "yes" if seconds < TARGET_S else "NO"],
        ["reference: one re-simulation of the bag (resim.Replay)", f"{reference:.3f} s", "1", "", ""],
    ]  # fmt: skip
    table(f"Calibration of {bag.name} ({result.evaluations} re-simulations)",
          ["what", "time", "x reference", "target", "met"], rows)  # fmt: skip
    rows = [[n, f"{overrides[n]:.6g}", f"{result.fitted[n]:.6g}", f"{getattr(truth, n):.6g}",
             f"[{result.interval[n][0]:.6g}, {result.interval[n][1]:.6g}]"] for n in FITTED]  # fmt: skip
    table("Fitted values (recorded with the defaults)", ["parameter", "start", "fitted", "recorded with", "95 %"], rows)
    rows = [[s, f"{result.rms_before[s]:.4g}", f"{result.rms_after[s]:.4g}"] for s in result.problem.signals]
    table("RMS residual per signal (SI units)", ["signal", "start", "fitted"], rows)
    verdict = report.verdict_lines(result) or ["the fit can be trusted (exit status 0)"]
    print("\n".join(verdict))


if __name__ == "__main__":
    main()

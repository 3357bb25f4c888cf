"""What a sweep recommends does the job: a work cycle's targets streamed while it runs, each
rule rejecting the designs that break it, the per-drive summary lines under the same rules, and
the best design at an end of the searched range said so."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
from conftest import CONFIG, run_tool

from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.solve import streaming
from boom_hydraulics.sweeps import energy, sweep
from boom_hydraulics.sweeps.recommend import format_table, qualifying, recommend
from boom_hydraulics.sweeps.rules import Rules, range_edges
from boom_hydraulics.sweeps.runner import applicable
from boom_hydraulics.sweeps.sampling import parse_axis


def _table(**columns) -> dict[str, np.ndarray]:
    """A sweep table of ok rows with these columns; every other metric a harmless value (a
    closed-loop run that meets every rule) unless given."""
    n = len(next(iter(columns.values())))
    table: dict[str, np.ndarray] = {"point": np.arange(n), "status": np.array(["ok"] * n)}
    for name in sweep.METRIC_NAMES:
        table[name] = np.full(n, 1.0)
    table |= {"worst_target_error_deg": np.full(n, 0.2), "set_down_error_deg": np.full(n, 0.1)}
    table |= {"relief_s": np.zeros(n), "peak_pressure_pa": np.full(n, 10e6), "worst_settle_time_s": np.full(n, 2.0)}
    for name, values in columns.items():
        table[name] = np.asarray(values)
    return table


DEFAULTS = Rules()


def _qualifies(table, rules: Rules = DEFAULTS, columns=("piston_diameter_m",), across=()) -> list[bool]:
    return qualifying(table, applicable(rules.constraints(), table), columns, across).tolist()


D = [0.04, 0.05, 0.06]


def test_a_design_that_misses_a_target_is_not_recommended():
    table = _table(piston_diameter_m=D, worst_target_error_deg=[0.5, 1.5, 6.75])
    assert _qualifies(table) == [True, False, False]
    assert _qualifies(table, Rules(target_tolerance_deg=2.0)) == [True, True, False]
    text = format_table(recommend(table, Rules().constraints(), ("piston_diameter_m",)))
    assert "2 fail: a target missed by more than 1 deg at its phase's end" in text, text


def test_a_payload_put_down_above_or_below_the_ground_is_not_recommended():
    table = _table(piston_diameter_m=D, set_down_error_deg=[0.3, 2.9, -1.5])
    assert _qualifies(table) == [True, False, False]
    assert _qualifies(table, Rules(set_down_tolerance_deg=3.0)) == [True, True, True]
    assert _qualifies(table, Rules(target_tolerance_deg=3.0, set_down_tolerance_deg=0.5)) == [True, False, False]


def test_the_settling_time_counts_only_when_asked():
    table = _table(piston_diameter_m=D, worst_settle_time_s=[2.0, 4.0, math.inf])
    assert _qualifies(table) == [True, True, True]
    assert _qualifies(table, Rules(settle_time_s=3.0)) == [True, False, False]


def test_the_peak_pressure_and_a_port_relief_that_opened_reject_a_design():
    table = _table(piston_diameter_m=D, peak_pressure_pa=[12e6, 19e6, 12e6], relief_s=[0.0, 0.0, 0.03])
    assert _qualifies(table) == [True, True, False]
    assert _qualifies(table, Rules(max_pressure_pa=18e6)) == [True, False, False]
    assert _qualifies(table, Rules(max_pressure_pa=18e6, allow_relief=True)) == [True, False, True]


def test_the_rules_of_a_closed_loop_run_leave_an_open_loop_sweep_alone():
    """An open-loop run has no targets (NaN): its relief may open (the scenario slams the valve
    shut) and nothing is said of targets; its pressure still counts."""
    nan = np.full(3, math.nan)
    table = _table(piston_diameter_m=D, worst_target_error_deg=nan, set_down_error_deg=nan, worst_settle_time_s=nan,
                   relief_s=[0.0, 0.03, 0.0], peak_pressure_pa=[12e6, 12e6, 19e6])  # fmt: skip
    rules = Rules(settle_time_s=3.0, max_pressure_pa=18e6)
    assert _qualifies(table, rules) == [True, True, False]
    assert [str(c) for c in applicable(rules.constraints(), table)] == ["peak_pressure_pa <= 1.8e+07"]


def test_a_design_across_operators_qualifies_only_if_every_cycle_does():
    table = _table(operator=[1, 2, 1, 2], piston_diameter_m=[0.04, 0.04, 0.06, 0.06],
                   worst_target_error_deg=[0.2, 0.3, 0.2, 1.2])  # fmt: skip
    columns = ("operator", "piston_diameter_m")
    assert _qualifies(table, columns=columns, across=["operator"]) == [True, True, False, False]
    ranked = recommend(table, Rules().constraints(), columns, ["operator"])
    assert ranked.table["piston_diameter_m"][ranked.rows].tolist() == [0.04]
    assert "1 fail: a target missed" in format_table(ranked)


def test_the_best_design_at_an_end_of_a_searched_axis_says_which_way_to_extend_it():
    table = {"piston_diameter_m": np.array([0.032, 0.05, 0.1]), "drive": np.array(["a", "b", "c"]),
             "payload_mass_kg": np.array([0.0, 0.0, 100.0]), "operator": np.array([1, 2, 3])}  # fmt: skip
    axes = ["piston_diameter_m", "drive", "payload_mass_kg", "operator"]
    assert range_edges(table, axes, 0) == [
        "piston_diameter_m: best at the lower end 0.032; extend the range below 0.032"
    ]  # (no payload below 0 kg, no words, no operator's seed)
    assert range_edges(table, axes, 1) == []
    assert range_edges(table, axes, 2, "load_sensing's best") == [
        "piston_diameter_m: load_sensing's best at the upper end 0.1; extend the range above 0.1",
        "payload_mass_kg: load_sensing's best at the upper end 100; extend the range above 100",
    ]
    assert range_edges({"piston_diameter_m": np.array([0.05, 0.05])}, ["piston_diameter_m"], 0) == []


def test_a_best_no_better_than_a_design_inside_the_range_names_no_end():
    """The electro-mechanical actuator has no cylinder's oil: its designs over piston diameters
    score alike, and its best at an end of the range is no reason to extend it; a drive whose
    score falls towards the end still gets its line."""
    table = {"drive": np.array(["electro_mechanical"] * 3 + ["load_sensing"] * 3),
             "piston_diameter_m": np.array([0.07, 0.09, 0.11] * 2)}  # fmt: skip
    score = np.array([10.60e3, 10.6002e3, 10.6004e3, 40e3, 43e3, 45e3])
    axes = ["drive", "piston_diameter_m"]
    assert range_edges(table, axes, 0, score=score) == []
    assert range_edges(table, axes, 3, score=score) == [
        "piston_diameter_m: best at the lower end 0.07; extend the range below 0.07"
    ]
    assert range_edges(table, axes, 0) == ["piston_diameter_m: best at the lower end 0.07; extend the range below 0.07"]


def test_each_drives_best_line_honours_the_rules():
    """fixed_pump's least-energy design puts the payload down 2.9 deg above the ground and
    load_sensing's least-energy one is over the pressure limit: each line names the best design
    that qualifies, or says that none does."""
    drive = ["fixed_pump", "fixed_pump", "load_sensing", "load_sensing"]
    table = _table(drive=drive, piston_diameter_m=[0.05, 0.07, 0.032, 0.088], set_down_error_deg=[2.9, 2.0, 0.1, 0.1],
                   peak_pressure_pa=[10e6, 10e6, 19e6, 12e6], battery_energy_j=[250e3, 260e3, 14e3, 15e3],
                   cycles_per_charge=[72.0, 69.0, 1286.0, 1200.0])  # fmt: skip
    columns = ("drive", "piston_diameter_m")
    bands = energy.operator_bands(table, columns)
    constraints = applicable(Rules(max_pressure_pa=18e6).constraints(), table)
    qualifies = energy.qualifying_designs(table, columns, qualifying(table, constraints, columns))
    text = energy.summary(bands, columns, qualifies)
    assert "least battery energy with fixed_pump: none of its 2 designs meets every rule and constraint" in text, text
    assert "with load_sensing: 15 kJ per cycle" in text and "at piston_diameter_m=0.088" in text, text
    assert "piston_diameter_m: load_sensing's best at the upper end 0.088; extend the range above 0.088" in text, text
    from boom_hydraulics.sweeps import plots

    bars = plots._breakdown_bars(bands, columns, qualifies)  # energy_breakdown.png: each drive's best that qualifies
    assert [name for name, _, _ in bars] == ["load sensing\n88 mm"], bars


def _cycle_metrics(alpha_deg, t, targets) -> dict[str, float]:
    s = streaming.settings(20.0, math.nan, math.inf, math.nan, targets)
    m = streaming.accumulator()
    for time_s, angle in zip(t, np.radians(alpha_deg)):
        streaming.add_sample(m, s, time_s, 0.0, 0.0, angle, 1e5, 1e5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    out = np.empty(len(streaming.NAMES))
    streaming.finish(m, s, out)
    return dict(zip(streaming.NAMES, out.tolist()))


def test_the_streamed_targets_take_each_phases_end_and_the_release():
    """Two targets, 10 deg from 0 s and 0 deg from 5 s, the payload released at 8 s: the boom
    rises to 9.5 deg by 3 s, then falls to 0.4 deg at 8 s and 0.2 deg at the end."""
    t = np.arange(0.0, 10.001, 0.5)
    alpha = np.interp(t, [0.0, 3.0, 5.0, 7.0, 8.0, 10.0], [0.0, 9.5, 9.5, 0.6, 0.4, 0.2])
    targets = ((0.0, 5.0), (math.radians(10.0), 0.0), 8.0)
    m = _cycle_metrics(alpha, t, targets)
    assert m["worst_target_error_deg"] == pytest.approx(0.5)  # 9.5 of 10 at 4.5 s, the first phase's last sample
    assert m["set_down_error_deg"] == pytest.approx(0.4)
    assert m["worst_settle_time_s"] == math.inf  # 0.5 deg off is outside 2 % of the 10 deg step
    within = np.interp(t, [0.0, 3.0, 5.0, 7.0, 8.0, 10.0], [0.0, 9.9, 9.9, 0.1, 0.1, 0.1])
    assert _cycle_metrics(within, t, targets)["worst_settle_time_s"] == pytest.approx(3.0)  # first in at 3 s
    assert math.isnan(_cycle_metrics(alpha, t, ((), (), math.nan))["worst_target_error_deg"])  # open loop


def test_a_loader_cycle_sweep_streams_its_targets_and_sets_down(tmp_path):
    """A real sweep: the fixed pump's 100 mm cylinder does not reach its lift in the phase (its
    flow lifts so large a piston too slowly) and puts the payload down above the ground, 50 mm
    follows its cycle within a degree; the streamed figures are the recorded run's."""
    from boom_hydraulics.solve.simulation import simulate

    base = Parameters(drive="fixed_pump")
    axes = [parse_axis("piston_diameter=0.05,0.1")]
    plan = sweep.plan(sweep.request([("default", base)], axes, scenario="loader", duration_s=19.0))
    table = sweep.assemble(plan, [sweep.run_batch(b) for b in plan.batches])
    assert table["worst_target_error_deg"][0] < 1.0 and abs(table["set_down_error_deg"][0]) < 1.0
    assert table["worst_target_error_deg"][1] > 3.0 and table["set_down_error_deg"][1] > 1.0
    for point, params in enumerate(plan.batches[0].params):
        run = simulate(params, 19.0)
        t, alpha = np.asarray(run["t"]), np.asarray(run["alpha"])
        ends = [*params.command_times_s[1:], math.inf]
        errors = [abs(alpha[t < end][-1] - target) for end, target in zip(ends, params.command_angles_rad, strict=True)]
        assert math.degrees(max(errors)) == pytest.approx(table["worst_target_error_deg"][point], rel=1e-9)
        release = params.command_payload_times_s[0]
        expected = math.degrees(alpha[t <= release][-1] - params.command_angles_rad[1])
        assert expected == pytest.approx(table["set_down_error_deg"][point], rel=1e-9)


@pytest.mark.skipif(shutil.which("boom-sweep") is None, reason="boom-sweep not on PATH (run through tools/with-env)")
def test_boom_sweep_picks_each_drives_best_under_the_pressure_limit(tmp_path):
    """pump_controlled's 32 mm piston draws the least energy but peaks above 5 MPa; under
    --max-pressure-pa 5e6 its line names 60 mm, the upper end of the range searched."""
    out = tmp_path / "sweep"
    args = ["--config", CONFIG / "default.yaml", "--scenario", "loader", "--duration", "19", "--no-plots"]
    args += ["--vary", "drive=pump_controlled", "--vary", "piston_diameter=0.032,0.06", "--out", out]
    result = run_tool("boom-sweep", *args, "--max-pressure-pa", "5e6")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    best = next(line for line in lines if "least battery energy with pump_controlled" in line)
    assert best.endswith("at piston_diameter_m=0.06"), result.stdout
    assert "    piston_diameter_m: pump_controlled's best at the upper end 0.06; extend the range above 0.06" in lines
    assert "1 fail: a chamber pressure above 5 MPa" in result.stdout, result.stdout
    with np.load(out / "results.npz") as results:
        assert results["qualifies"].tolist() == [0, 1]


@pytest.mark.parametrize("option", ["--target-tolerance-deg", "--set-down-tolerance-deg", "--settle-time-s"])
def test_a_rule_that_cannot_be_met_is_refused_in_one_line(option, tmp_path):
    result = run_tool("boom-sweep", "--vary", "piston_diameter=0.04,0.05", option, "0", "--out", tmp_path / "sweep")
    assert result.returncode == 2
    assert result.stderr.strip() == f"boom-sweep: error: {option} must be > 0, got 0.0", result.stderr

"""Work cycles: the loader crane's cycle releases its payload within the cycle, ends where it
began, varies with the operator's seed, and a sweep over operators gives each design a band."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import ledger, physical
from boom_hydraulics.model.geometry import static_rod_force_of
from boom_hydraulics.model.parameters import Parameters, from_mapping, with_updates
from boom_hydraulics.solve import accelerate, commands, duty_cycles
from boom_hydraulics.solve.simulation import Simulator
from boom_hydraulics.sweeps import energy, recommend, sweep
from boom_hydraulics.sweeps.sampling import parse_axis

JIT = [False, True] if accelerate.available() else [False]
PAYLOAD_KG = 150.0


def _loader(drive: str, jit: bool | None = None, seed: int = 0, duration_s: float | None = None):
    """The loader cycle of ``seed`` with ``drive`` (default: the whole cycle and 2 s more)."""
    params = from_mapping(
        {"drive": drive, "payload_mass_kg": PAYLOAD_KG, **commands.scenario(f"loader:{seed}", 0.0, Parameters())}
    )
    sim = Simulator(params, jit=jit)
    duration = duty_cycles.loader_duration_s(seed) + 2.0 if duration_s is None else duration_s
    out = sim.run(duration, commands.from_parameters(params), every=10)
    return params, sim, out


def test_the_loader_puts_its_payload_down_and_holds_the_lighter_boom_with_less_pressure():
    params, sim, out = _loader("pressure_compensated")  # compiled where it can be: the same loop as interpreted
    release = params.command_payload_times_s[0]
    t, force, alpha = out["t"], out["f_hyd"], out["alpha"]
    before = force[(t > release - 0.3) & (t < release)].mean()  # resting at the ground, loaded
    after = force[(t > release + 0.2) & (t < release + 0.45)].mean()  # the same, empty (it rings a little)
    q1 = out["q1"][t < release][-1]
    # the oil holds the payload's weight no more: the static rod force of eq. 6 with and without it
    lighter = static_rod_force_of(params, q1) - static_rod_force_of(with_updates(params, payload_mass_kg=0.0), q1)
    assert before - after == pytest.approx(lighter, rel=0.05)
    # the cycle ends where it began, and the lifts rose by the cycle's 25 degrees
    assert math.degrees(alpha[-1] - alpha[0]) == pytest.approx(0.0, abs=0.5)
    assert math.degrees(alpha.max() - alpha[0]) == pytest.approx(duty_cycles.LOADER_RISE_DEG, abs=1.0)
    integrals = physical.ledger_integrals(sim.y)
    assert ledger.energies_of(integrals)["imbalance_ratio"] < 0.005
    assert abs(sim.energy_residual()) < 1e-3 * integrals["battery_drawn"]  # the payload's energy left with it


def test_the_eha_recovers_energy_on_the_loader_cycle_and_draws_less_than_load_sensing():
    *_, eha = _loader("pump_controlled")
    *_, sensing = _loader("load_sensing")
    net = {name: o["battery_drawn"][-1] - o["battery_returned"][-1] for name, o in (("eha", eha), ("ls", sensing))}
    assert eha["battery_returned"][-1] > 0.1 * eha["battery_drawn"][-1]
    assert net["eha"] < 0.5 * net["ls"], net


def test_operators_vary_the_cycle_within_their_bounds_and_a_seed_repeats_it():
    nominal = duty_cycles.loader(Parameters())
    varied = [duty_cycles.loader(Parameters(), seed) for seed in range(1, 21)]
    assert duty_cycles.loader(Parameters(), 7) == varied[6]  # the same seed, the same cycle
    assert len({tuple(v["command_times_s"]) for v in varied}) == 20
    ground = duty_cycles.ground_rad(Parameters())
    for cycle in varied:
        rises = np.degrees(np.array(cycle["command_angles_rad"])[[0, 2]] - ground)
        assert (np.abs(rises / duty_cycles.LOADER_RISE_DEG - 1.0) <= duty_cycles.RISE_VARIATION).all()
        assert cycle["command_angles_rad"][1] == cycle["command_angles_rad"][3] == ground
        length = np.diff(
            [*cycle["command_times_s"][:2], *cycle["command_payload_times_s"], *cycle["command_times_s"][2:]]
        )
        nominal_length = np.diff(duty_cycles.LOADER_TIMES_S)
        assert (np.abs(length / nominal_length - 1.0) <= duty_cycles.VARIATION + 1e-12).all()
    assert nominal["command_payload_fractions"] == [0.0]
    with pytest.raises(ConfigError, match="loader:SEED"):
        commands.scenario("loader:x", 10.0)


def test_a_payload_schedule_is_refused_where_it_cannot_act():
    with pytest.raises(ConfigError, match="command_payload_times_s must be strictly increasing"):
        from_mapping({"command_payload_times_s": [2.0, 1.0], "command_payload_fractions": [0.0, 1.0]})
    with pytest.raises(ConfigError, match="equal length"):
        from_mapping({"command_payload_times_s": [2.0], "command_payload_fractions": []})
    with pytest.raises(ConfigError, match="needs mode: physical"):
        from_mapping({"mode": "paper", "command_payload_times_s": [2.0], "command_payload_fractions": [0.0]})


def test_a_sweep_over_operators_gives_each_design_a_band_and_ranks_by_cycles_per_charge():
    axes = [parse_axis("drive=load_sensing,pump_controlled"), parse_axis("piston_diameter=0.045,0.055")]
    base = with_updates(Parameters(), payload_mass_kg=PAYLOAD_KG)
    asked = sweep.request([("default", base)], axes, scenario="loader", duration_s=22.0, operators=3)
    plan = sweep.plan(asked)
    assert plan.columns == ("operator", "drive", "piston_diameter_m") and plan.size == 12
    table = sweep.assemble(plan, [sweep.run_batch(b) for b in plan.batches])
    bands = energy.operator_bands(table, plan.columns)
    assert len(bands["cycles"]) == 4 and (bands["cycles"] == 3).all()
    for name, _, _ in energy.BANDED:
        low, mid, high = (bands[f"{name}_p{q}"] for q in energy.PERCENTILES)
        assert (low <= mid).all() and (mid <= high).all() and (low < high).any()  # the operators differ
    capacity_j = base.battery_capacity_kwh * 3.6e6
    assert bands["cycles_per_charge_p50"] == pytest.approx(capacity_j / bands["battery_energy_j_p50"], rel=1e-9)
    best = energy.best_per_drive(bands)
    assert set(best) == {"load_sensing", "pump_controlled"}
    rec = recommend.recommend(table, [], plan.columns, ["operator"], "cycles_per_charge")
    ranked = rec.table["cycles_per_charge"][rec.rows]
    assert (np.diff(ranked) <= 0).all() and rec.table["drive"][rec.rows[0]] == "pump_controlled"
    # the worst case over the operators is each design's fewest cycles per charge
    top = rec.rows[0]
    rows = (table["drive"] == rec.table["drive"][top]) & (
        table["piston_diameter_m"] == rec.table["piston_diameter_m"][top]
    )
    assert ranked[0] == np.min(table["cycles_per_charge"][rows])


@pytest.mark.skipif(not accelerate.available(), reason="numba is switched off")
def test_the_compiled_loop_changes_the_payload_as_the_interpreted_one_does():
    release = duty_cycles.loader(Parameters(), 3)["command_payload_times_s"][0]
    *_, compiled = _loader("pressure_compensated", True, seed=3, duration_s=release + 1.0)
    *_, interpreted = _loader("pressure_compensated", False, seed=3, duration_s=release + 1.0)
    for name in ("q1", "p1", "p2", "battery_drawn", "battery_returned"):
        scale = np.max(np.abs(interpreted[name]))
        assert np.max(np.abs(compiled[name] - interpreted[name])) <= 1e-9 * scale, name


def test_boom_sim_runs_the_loader_cycle_and_writes_the_battery(tmp_path):
    from conftest import run_tool

    out = tmp_path / "loader.csv"
    result = run_tool("boom-sim", "run", "--set", "drive=pump_controlled", "--profile", "loader:2", "--duration", "22",
                      "--every", "100", "--out", str(out))  # fmt: skip
    assert result.returncode == 0, result.stderr
    header = out.read_text().splitlines()[0].split(",")
    assert {"battery_power [W]", "battery_drawn [J]", "battery_returned [J]", "lift_work [J]"} <= set(header)
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    alpha = rows[:, header.index("alpha [rad]")]
    assert math.degrees(alpha.max() - alpha[0]) > 20.0 and math.degrees(abs(alpha[-1] - alpha[0])) < 0.5
    assert rows[-1, header.index("battery_returned [J]")] > 0.0


def test_a_loader_run_goes_on_after_the_release_and_starts_afresh_after_a_reset():
    params, sim, whole = _loader("pressure_compensated")
    duration = duty_cycles.loader_duration_s() + 2.0
    sim.reset()
    sim.run(10.0, commands.from_parameters(params), every=10)  # past the release at 9 s
    rest = sim.run(duration - 10.0, commands.from_parameters(params), every=10)
    # (the second run's controller starts afresh: the same cycle, not the same bits)
    assert rest["q1"][-1] == pytest.approx(whole["q1"][-1], abs=1e-4)
    assert rest["battery_drawn"][-1] == pytest.approx(whole["battery_drawn"][-1], rel=1e-3)
    assert rest["f_hyd"][-1] == pytest.approx(whole["f_hyd"][-1], rel=1e-2)  # the boom still without its payload
    assert abs(sim.energy_residual()) < 1e-3 * whole["battery_drawn"][-1]


@pytest.mark.parametrize("jit", JIT, ids=lambda j: "compiled" if j else "interpreted")
def test_a_python_command_steps_with_the_payload_the_schedule_leaves(jit):
    """A command the run loop cannot take into its kernel (a Python function) goes through the
    compiled step under the interpreted loop: it too steps with the released payload."""
    params = from_mapping({"command_payload_times_s": [0.0, 1.0], "command_payload_fractions": [1.0, 0.0]})
    sim = Simulator(params, jit=jit)
    out = sim.run(2.0, lambda t: 0.0, every=10)  # the valve shut: the boom holds, lighter after 1 s
    released = from_mapping({"payload_mass_kg": 0.0})
    lighter = static_rod_force_of(params, out["q1"][-1]) - static_rod_force_of(released, out["q1"][-1])
    t, force = out["t"], out["f_hyd"]
    assert force[t < 1.0][-1] - force[-1] == pytest.approx(lighter, rel=0.05)
    assert abs(sim.energy_residual()) < 1.0


def test_a_sweep_of_work_cycles_refuses_a_run_shorter_than_the_cycle():
    with pytest.raises(ConfigError, match=r"--duration 10 s is shorter than the loader cycle \(18\.5 s\)"):
        sweep.request([("default", Parameters())], [], scenario="loader", duration_s=10.0)
    longest = max(duty_cycles.loader_duration_s(seed) for seed in range(1, 6))
    with pytest.raises(ConfigError, match=r"the longest of the 5 operators'"):
        sweep.request([("default", Parameters())], [], scenario="loader", duration_s=longest - 0.1, operators=5)
    sweep.request([("default", Parameters())], [], scenario="loader", duration_s=longest, operators=5)


def test_the_operators_bands_are_numpys_percentiles_of_each_designs_cycles_inf_and_nan_included():
    """The bands of a sweep are taken per design in whole arrays; each is what numpy.percentile
    gives for that design's cycles (an infinite cycles per charge, a NaN, an empty design)."""
    import warnings

    from boom_hydraulics.sweeps.energy import grouped_percentile

    rng = np.random.default_rng(26)
    for trial in range(200):
        n_groups = int(rng.integers(1, 8))
        group = rng.integers(0, n_groups, int(rng.integers(0, 40)))
        values = rng.normal(size=len(group)) * 10.0
        if len(values):
            values[rng.integers(0, len(values), 2)] = (np.inf, -np.inf, np.nan)[trial % 3] if trial % 2 else 1.0
        sizes = np.bincount(group, minlength=n_groups)
        for q in (10, 50, 90):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                want = [np.percentile(values[group == g], q) if sizes[g] else np.nan for g in range(n_groups)]
            np.testing.assert_array_equal(grouped_percentile(values, group, sizes, q), want)


def test_the_battery_summary_gives_a_band_only_where_a_design_ran_several_cycles():
    def bands(cycles: int, low: float, high: float) -> dict[str, np.ndarray]:
        row = {"drive": np.array(["pump_controlled"]), "piston_diameter_m": np.array([0.05]),
               "cycles": np.array([cycles])}  # fmt: skip
        for name, lo, hi in (("battery_energy_j", low, high), ("cycles_per_charge", 3.6e7 / high, 3.6e7 / low)):
            for q, value in zip(energy.PERCENTILES, (lo, (lo + hi) / 2, hi), strict=True):
                row[f"{name}_p{q}"] = np.array([value])
        return row

    columns = ("operator", "drive", "piston_diameter_m")
    one = energy.summary(bands(1, 13_700.0, 13_700.0), columns)
    assert one == (
        "  least battery energy with pump_controlled: 13.7 kJ per cycle, 2628 cycles per charge"
        " (one cycle run: no band) at piston_diameter_m=0.05"
    )
    several = energy.summary(bands(5, 12_000.0, 15_000.0), columns)
    assert "13.5 kJ per cycle (12-15)" in several and "(2400-3000)" in several, several
    assert "median (10th-90th percentile) over its 5 cycles" in several, several

"""Design sweeps: batched points equal single runs, failures are recorded, the choice is right."""

from __future__ import annotations

import functools
import math
import operator
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.analysis import metrics as analysis
from boom_hydraulics.errors import BoomHydraulicsError, ConfigError
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.programs import CalledOffError, raise_pending
from boom_hydraulics.solve import accelerate, commands
from boom_hydraulics.solve.simulation import simulate
from boom_hydraulics.sweeps import sweep
from boom_hydraulics.sweeps.executors import SWITCH_INTERVAL_S, DaskExecutor, LocalExecutor
from boom_hydraulics.sweeps.recommend import (
    Constraint,
    format_value,
    non_dominated,
    parse_constraint,
    recommend,
    trade_off_front,
)
from boom_hydraulics.sweeps.runner import BatchCells, write_table
from boom_hydraulics.sweeps.sampling import parse_axis


def _plan(configs, axes, **settings) -> sweep.Plan:
    return sweep.plan(sweep.request(configs, axes, **settings))


def _table(plan: sweep.Plan) -> dict[str, np.ndarray]:
    return sweep.assemble(plan, [sweep.run_batch(b) for b in plan.batches])


def _same(a: float, b: float) -> bool:
    """Equal metrics of the (compiled) batch and an interpreted single run: the two differ in the
    last bit of some exp/sqrt results (1e-16 relative), which stays far below 1e-9 in these metrics."""
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12) or (math.isnan(a) and math.isnan(b))


@pytest.mark.parametrize("scenario", ["lift", "angle:0=20"])
def test_batched_metrics_equal_those_of_single_runs(scenario):
    axes = [parse_axis("piston_diameter=0.036,0.05,0.07"), parse_axis("payload=0,150")]
    plan = _plan([("default", Parameters())], axes, scenario=scenario, duration_s=2.0, lift_angle_deg=8.0, batch_size=4)
    assert [len(b.points) for b in plan.batches] == [4, 2]
    table = _table(plan)
    for batch in plan.batches:
        for point, params in zip(batch.points, batch.params):
            single = simulate(params, 2.0, commands.from_parameters(params), jit=False)
            expected = analysis.metrics(single.columns, lift_angle_deg=8.0, params=params)
            expected.update(analysis.move_metrics(params, single.columns))
            for name, _, _ in sweep.STREAMED_METRICS:  # the linear model's: test_linearize
                assert _same(table[name][point], expected[name]), (point, name)
    assert (table["status"] != "invalid").all()
    assert table["piston_diameter_m"].tolist() == [0.036, 0.036, 0.05, 0.05, 0.07, 0.07]
    closed_loop = scenario.startswith("angle")
    assert np.isfinite(table["target_error_deg"]).all() == closed_loop
    if closed_loop:  # 36 and 50 mm reach 20 degrees under control; 70 mm is too slow for 0.3 rad/s
        error, fast = table["target_error_deg"], table["piston_diameter_m"] < 0.06
        assert (np.abs(error[fast]) < 0.25).all() and (error[~fast] > 0.5).all()
        assert (table["target_overshoot_deg"] < 0.5).all()


def test_a_sweep_across_drives_equals_single_runs_and_counts_cycles_per_charge():
    axes = [
        parse_axis("drive=pressure_compensated,fixed_pump,load_sensing,pump_controlled"),
        parse_axis("piston_diameter=0.05"),
    ]
    scenario = "steps:0=1,1=0,1.4=-1,1.8=0"
    plan = _plan([("default", Parameters())], axes, scenario=scenario, duration_s=2.0, lift_angle_deg=8.0)
    table = _table(plan)
    for batch in plan.batches:
        for point, params in zip(batch.points, batch.params):
            single = simulate(params, 2.0, commands.from_parameters(params), jit=False)
            expected = analysis.metrics(single.columns, lift_angle_deg=8.0)
            for name, _, _ in sweep.STREAMED_METRICS:
                assert _same(table[name][point], expected[name]), (point, params.drive, name)
            energy = single["battery_drawn"][-1] - single["battery_returned"][-1]
            capacity_j = params.battery_capacity_kwh * 3.6e6
            assert table["cycles_per_charge"][point] == pytest.approx(capacity_j / energy, rel=1e-9)
    drawn = dict(zip(table["drive"], table["battery_energy_j"]))
    assert drawn["load_sensing"] < drawn["pressure_compensated"] < drawn["fixed_pump"], drawn  # the EHA: test_eha
    returned = dict(zip(table["drive"], table["battery_returned_j"]))
    assert returned["pump_controlled"] > 0.0 and returned["load_sensing"] == 0.0  # the EHA generates lowering
    assert np.isnan(table["natural_frequency_hz"][table["drive"] == "pump_controlled"]).all()
    assert (table["peak_battery_power_w"] > 0.0).all() and (table["efficiency"] < 1.0).all()


def test_the_paper_configs_keep_their_order_40mm_fastest_80mm_slower():
    configs = [(f"fig{i}", config.load(CONFIG / f"paper_fig{i}.yaml")) for i in (8, 9, 10)]
    plan = _plan(configs, [], scenario="lift:1.5", duration_s=3.0, lift_angle_deg=10.0)
    table = _table(plan)
    assert table["config"].tolist() == ["fig8", "fig9", "fig10"]
    assert (table["status"] == "ok").all()
    t8, t9, t10 = table["lift_time_s"]
    assert t8 < 0.7 * t9 and t8 < 0.7 * t10  # the 40 mm cylinder lifts fastest
    # 80 mm rings after the valve closes, faster by sqrt(10) with the tenfold bulk modulus
    f9, f10 = table["oscillation_hz"][1:]
    assert f10 / f9 == pytest.approx(math.sqrt(10), rel=0.1)


def test_failing_and_invalid_points_are_recorded_and_the_rest_finish():
    paper = config.load(CONFIG / "paper_fig8.yaml")
    # a rod wider than the piston is rejected before running; fig. 8 with the valve open
    # for 3 s runs the rod out of the geometry near 2.1 s, while 80 mm runs through
    axes = [parse_axis("piston_diameter=0.04,0.08"), parse_axis("rod_diameter_m=0.06")]
    plan = _plan([("fig8", paper)], axes, scenario="constant:1", duration_s=3.0)
    table = _table(plan)
    assert table["status"].tolist() == ["invalid", "ok"]
    assert np.isnan([table[m][0] for m in sweep.METRIC_NAMES]).all()
    assert "rod_diameter_m (0.06 m) must be smaller than piston_diameter_m" in table["reason"][0]
    plan = _plan([("fig8", paper)], [parse_axis("piston_diameter=0.04,0.08")], scenario="constant:1", duration_s=3)
    table = _table(plan)
    assert table["status"].tolist() == ["failed", "ok"]
    assert "leave the valid geometry (1, 1.8) m (paper mode has no end stops)" in table["reason"][0]
    assert 2.0 < table["failed_at_s"][0] < 2.3
    assert table["lift_completed"][0] == 1.0 and table["lift_time_s"][0] < table["lift_time_s"][1]


def test_the_table_formatted_as_its_batches_come_is_the_one_formatted_at_the_end(tmp_path):
    paper = config.load(CONFIG / "paper_fig8.yaml")
    axes = [parse_axis("piston_diameter=0.04,0.06,0.08"), parse_axis("rod_diameter_m=0.03,0.06")]
    configs = [("fig8", paper), ("default", Parameters())]
    plan = _plan(configs, axes, scenario="constant:1", duration_s=3.0, batch_size=2)
    parts = [sweep.run_batch(b) for b in plan.batches]
    cells = BatchCells(plan.size)
    for rows in parts[:0:-1]:  # in another order, and the first batch as if stored by an earlier run
        cells.add(rows)
    table = sweep.assemble(plan, parts)
    table["front"] = trade_off_front(table).astype(np.int64)
    assert {"invalid", "failed", "ok"} <= set(table["status"]) and any("," in r for r in table["reason"])
    write_table(table, tmp_path / "at_the_end.csv")
    write_table(table, tmp_path / "as_they_came.csv", cells=cells)
    assert (tmp_path / "as_they_came.csv").read_bytes() == (tmp_path / "at_the_end.csv").read_bytes()


def test_a_point_that_does_not_lift_far_enough_is_incomplete_with_the_reason():
    plan = _plan([("d", Parameters())], [parse_axis("payload=0")], duration_s=1.0, lift_angle_deg=60)
    table = _table(plan)
    assert table["status"][0] == "incomplete"
    assert table["reason"][0].startswith("rose ") and "of the 60 deg in 1 s" in table["reason"][0]
    assert math.isnan(table["lift_time_s"][0]) and table["lift_completed"][0] == 0.0


def test_plans_refuse_what_cannot_run():
    with pytest.raises(ConfigError, match=r"does not fit config 'fig8'.*paper's valve"):
        _plan([("fig8", config.load(CONFIG / "paper_fig8.yaml"))], [], scenario="cycle")
    with pytest.raises(ConfigError, match="fixed step"):
        _plan([("d", Parameters(method="rk45"))], [])
    with pytest.raises(ConfigError, match="unknown scenario"):
        _plan([("d", Parameters())], [], scenario="hover")


def test_batches_group_points_that_can_run_together():
    axes = [parse_axis("time_step_s=0.001,0.0005"), parse_axis("payload=0,100,200")]
    plan = _plan([("d", Parameters())], axes, batch_size=2)
    steps = [{p.time_step_s for p in b.params} for b in plan.batches]
    assert all(len(s) == 1 for s in steps)
    assert sorted(i for b in plan.batches for i in b.points) == list(range(6))


def _random_table(n: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    table = {
        "point": np.arange(n),
        "status": rng.choice(["ok", "ok", "ok", "incomplete", "failed"], n),
        "lift_time_s": rng.uniform(0.3, 3.0, n),
        "lift_energy_j": rng.uniform(1e3, 1e4, n),
        "peak_pressure_pa": rng.uniform(5e6, 2.2e7, n),
        "cavitation_s": np.where(rng.random(n) < 0.3, rng.uniform(0, 0.2, n), 0.0),
    }
    table["lift_energy_j"][rng.random(n) < 0.05] = np.nan
    return table


def test_the_recommendation_respects_every_constraint_and_misses_no_design():
    table = _random_table(400, seed=3)
    constraints = [
        parse_constraint("peak_pressure_pa<=18e6"),
        parse_constraint("lift_time_s < 2"),
        Constraint("cavitation_s", "==", 0.0),
    ]
    rec = recommend(table, constraints)
    rows = rec.rows
    assert len(rows) > 10
    assert (table["status"][rows] == "ok").all()
    assert (table["peak_pressure_pa"][rows] <= 18e6).all()
    assert (table["lift_time_s"][rows] < 2).all()
    assert (table["cavitation_s"][rows] == 0).all()
    assert (np.diff(table["lift_energy_j"][rows]) >= 0).all()  # ranked by energy
    meets_all = (
        (table["status"] == "ok")
        & (table["peak_pressure_pa"] <= 18e6)
        & (table["lift_time_s"] < 2)
        & (table["cavitation_s"] == 0)
        & np.isfinite(table["lift_energy_j"])
    )
    assert set(rows.tolist()) == set(np.nonzero(meets_all)[0].tolist())
    assert rec.passing["status ok"] == int((table["status"] == "ok").sum())


def test_a_design_across_conditions_must_qualify_at_every_one_and_ranks_by_its_worst_case():
    table = _random_table(240, seed=11)
    table["piston_diameter_m"] = np.repeat(np.linspace(0.03, 0.1, 40), 6)
    table["payload_mass_kg"] = np.tile(np.linspace(0, 200, 6), 40)
    table["min_pressure_pa"] = np.full(240, 1e5)
    rng = np.random.default_rng(12)
    table["status"] = np.where(rng.random(240) < 0.05, "incomplete", "ok")
    table["peak_pressure_pa"] = rng.uniform(5e6, 2.05e7, 240)
    table["lift_energy_j"] = rng.uniform(1e3, 1e4, 240)
    for name in set(sweep.METRIC_NAMES) - set(table):
        table[name] = np.zeros(240)
    constraints = [parse_constraint("peak_pressure_pa<=20e6"), parse_constraint("lift_time_s<=2.5")]
    rec = recommend(table, constraints, ["piston_diameter_m", "payload_mass_kg"], across=["payload_mass_kg"])
    assert rec.columns == ("design", "piston_diameter_m")
    designs = rec.table
    assert len(designs["design"]) == 40 and (designs["points"] == 6).all()
    expected = []
    for d in range(40):
        rows = slice(6 * d, 6 * d + 6)
        good = (
            (table["status"][rows] == "ok").all()
            and (table["peak_pressure_pa"][rows] <= 20e6).all()
            and (table["lift_time_s"][rows] <= 2.5).all()
            and np.isfinite(table["lift_energy_j"][rows]).all()
        )
        if good:
            expected.append(d)
            assert designs["lift_energy_j"][d] == np.max(table["lift_energy_j"][rows])
            assert designs["peak_pressure_pa"][d] == np.max(table["peak_pressure_pa"][rows])
    assert sorted(rec.rows.tolist()) == expected and 3 <= len(expected) < 30
    assert (np.diff(designs["lift_energy_j"][rec.rows]) >= 0).all()
    with pytest.raises(ConfigError, match="--across speed: not a varied parameter"):
        recommend(table, constraints, ["piston_diameter_m"], across=["speed"])


def test_the_front_is_exactly_the_non_dominated_designs():
    table = _random_table(300, seed=5)
    front = trade_off_front(table)
    objectives = np.column_stack([table[m] for m in ("lift_time_s", "lift_energy_j", "peak_pressure_pa")])
    ok = (table["status"] == "ok") & np.isfinite(objectives).all(axis=1)
    for i in range(len(front)):
        dominated = any(
            ok[j] and (objectives[j] <= objectives[i]).all() and (objectives[j] < objectives[i]).any()
            for j in range(len(front))
        )
        assert front[i] == (ok[i] and not dominated), i
    assert non_dominated(np.array([[1.0, 2.0], [1.0, 2.0], [2.0, 1.0], [2.0, 2.0]])).tolist() == [
        True,
        True,
        True,
        False,
    ]


def test_the_front_keeps_ties_and_drops_nan_rows_as_the_pairwise_definition_does():
    """Designs with equal figures (a coarse grid) are all on the front or all off it."""
    rng = np.random.default_rng(26)
    for trial in range(100):
        objectives = rng.integers(0, 4, (int(rng.integers(1, 40)), 3)).astype(float)
        objectives[rng.integers(0, len(objectives))] = (np.nan, np.inf, 1.0)[trial % 3]
        finite = np.isfinite(objectives).all(axis=1)
        expected = [
            bool(finite[i])
            and not any(
                finite[j] and (objectives[j] <= objectives[i]).all() and (objectives[j] < objectives[i]).any()
                for j in range(len(objectives))
            )
            for i in range(len(objectives))
        ]
        assert non_dominated(objectives).tolist() == expected, trial


@pytest.mark.parametrize(
    ("text", "message"),
    [("peak_pressure<=1", "unknown metric"), ("lift_time_s<=fast", "not a number"), ("lift_time_s 2", "METRIC OP")],
)
def test_bad_constraints_name_what_is_wrong(text, message):
    with pytest.raises(ConfigError, match=message):
        parse_constraint(text)


def test_named_scenarios_are_command_profiles():
    assert commands.scenario("lift", 5.0) == {
        "command_profile": "steps",
        "command_times_s": [0.0, 2.5],
        "command_values": [1.0, 0.0],
    }
    assert commands.scenario("lift:1.5", 5.0)["command_times_s"] == [0.0, 1.5]
    assert commands.scenario("cycle", 9.0)["command_values"] == [1.0, 0.0, -1.0, 0.0]
    assert commands.scenario("config", 5.0) == {}
    assert commands.scenario("ramp:0=0,1=1", 2.0)["command_profile"] == "ramp"
    with pytest.raises(ConfigError, match="opening time"):
        commands.scenario("lift:soon", 5.0)


def test_table_cells_keep_whole_numbers_whole():
    assert format_value(np.int64(12345)) == "12345"
    assert format_value(0.0660000001) == "0.066"
    assert format_value(np.nan) == "-"
    assert format_value(np.str_("paper_fig8")) == "paper_fig8"


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_this_process_delivers_every_result_in_order_and_a_failure_after_the_ones_before(threads):
    invert = functools.partial(operator.truediv, 1.0)
    assert list(LocalExecutor(threads).map(invert, [1.0, 2.0, 4.0, 8.0, 0.5])) == [
        (1.0, 1.0), (2.0, 0.5), (4.0, 0.25), (8.0, 0.125), (0.5, 2.0)
    ]  # fmt: skip
    delivered = []
    with pytest.raises(ZeroDivisionError):
        for item, result in LocalExecutor(threads).map(invert, [2.0, 4.0, 0.0, 8.0]):
            delivered.append((item, result))
    assert delivered == [(2.0, 0.5), (4.0, 0.25)]


def test_the_batches_threads_take_the_gil_in_turn_quickly_and_the_caller_gets_its_switch_interval_back():
    """While batches run in threads, CPython's switch interval is short (a batch whose kernel
    returned waits for the GIL no longer); once the map ends, done or stopped, it is the
    caller's again."""
    before = sys.getswitchinterval()
    seen = []

    def batch(index: int) -> int:
        seen.append(sys.getswitchinterval())
        return 1 // (3 - index)  # the fourth fails

    try:
        sys.setswitchinterval(0.004)
        assert [result for _, result in LocalExecutor(2).map(batch, range(3))] == [0, 0, 1]
        assert sys.getswitchinterval() == pytest.approx(0.004)
        with pytest.raises(ZeroDivisionError):
            list(LocalExecutor(2).map(batch, range(5)))
        assert sys.getswitchinterval() == pytest.approx(0.004)
        assert seen and all(s == pytest.approx(SWITCH_INTERVAL_S) for s in seen)
        first, second = LocalExecutor(2).map(batch, range(3)), LocalExecutor(2).map(batch, range(3))
        next(first), next(second)  # two maps at once: the first ends while the second runs
        assert list(first) and sys.getswitchinterval() == pytest.approx(SWITCH_INTERVAL_S)
        assert list(second) and sys.getswitchinterval() == pytest.approx(0.004)
    finally:
        sys.setswitchinterval(before)


@pytest.mark.parametrize("threads", [1, 2])
def test_each_kinds_kernel_loads_in_the_calling_thread_where_ctrl_c_can_stop_its_compile_then_its_batch_runs(threads):
    """The first batch of each kind has its kernel loaded first, in the calling thread (a stop
    signal interrupts a compile there), once the batches before it are delivered; then every
    batch runs as the others do (with threads, in the executor's), and all come in order."""
    caller = threading.get_ident()
    events: list[tuple[str, int]] = []

    def load(index: int) -> None:
        assert threading.get_ident() == caller
        events.append(("load", index))

    def batch(index: int) -> int:
        if threads > 1:
            assert threading.get_ident() != caller
        return -index

    items = [0, 1, 2, 3, 10, 11, 12, 20, 4]
    executor = LocalExecutor(threads, load=load, kind=lambda index: index // 10)  # (4 is of the first kind)
    for index, result in executor.map(batch, items):
        assert result == -index
        events.append(("delivered", index))
    assert [index for what, index in events if what == "delivered"] == items
    assert [index for what, index in events if what == "load"] == [0, 10, 20]
    for loaded in (10, 20):  # loaded once every batch before it was delivered
        before = items[: items.index(loaded)]
        place = events.index(("load", loaded))
        assert {index for what, index in events[:place] if what == "delivered"} == set(before)


#: A new process's batch of POINTS points: the signatures of its run kernel after
#: sweep.load_kernel, and after its run (a process of its own: nothing loaded before).
_LOADED_AHEAD = """
import sys
from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.solve import accelerate
from boom_hydraulics.sweeps import sweep
from boom_hydraulics.sweeps.sampling import parse_axis

from boom_hydraulics.model.parameters import from_mapping

points, mode, scenario = int(sys.argv[1]), sys.argv[2], sys.argv[3]
base = from_mapping({"mode": mode}, base=Parameters())
asked = sweep.request([("default", base)], [parse_axis(f"payload=0:100:{points}")], duration_s=0.05, scenario=scenario)
batch = sweep.plan(asked).batches[0]
p = batch.params[0]
kernels = accelerate.run_kernels(p.mode, p.method, len(batch.params))
before = sum(len(k.signatures) for k in kernels)
sweep.load_kernel(batch)
loaded = [set(k.signatures) for k in kernels]
status = set(sweep.run_batch(batch)["status"].tolist())
print(before, sum(map(len, loaded)), [set(k.signatures) for k in kernels] == loaded, sorted(status))
"""


@pytest.mark.skipif(not accelerate.available(), reason="numba not installed")
@pytest.mark.parametrize(
    ("points", "mode", "scenario"),
    [(3, "physical", "lift"), (10, "physical", "lift"), (10, "paper", "lift"), (5, "physical", "angle:0.01=30")],
)
def test_the_kernel_a_batch_has_loaded_ahead_is_the_one_its_run_calls(points, mode, scenario):
    """sweep.load_kernel loads what run_batch then calls: the batch's run kernel (blocks in
    lock-step from lanes.WIDTH sets on, one set per thread below; the paper model's; a position
    loop's) for the types it is called with; the batch's run adds no signature of its own, so
    that it neither compiles nor loads."""
    script = [sys.executable, "-c", _LOADED_AHEAD, str(points), mode, scenario]
    done = subprocess.run(script, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[:3] == ["0", "1", "True"], done.stdout


def test_a_kernel_that_fails_to_load_stops_the_map_after_the_batches_before_it():
    def load(index: int) -> None:
        if index == 10:
            raise ConfigError("no kernel")

    delivered = []
    with pytest.raises(ConfigError, match="no kernel"):
        for index, _ in LocalExecutor(2, load=load, kind=lambda index: index // 10).map(abs, [0, 1, 10, 11]):
            delivered.append(index)
    assert delivered == [0, 1]


def test_batches_running_beside_the_caller_stop_at_their_next_slice_once_it_stops_taking_results():
    """As a sweep whose disk filled up while storing a batch: the batches running in the
    executor's threads are called off (programs.raise_pending), not run to their end."""
    running = threading.Semaphore(0)
    called_off: list[int] = []

    def batch(index: int) -> int:
        if index < 2:
            return index
        running.release()
        deadline = time.monotonic() + 60  # (a batch that was not called off ends on its own)
        while time.monotonic() < deadline:  # a run's slices, each followed by raise_pending, as SetRun.slices
            try:
                raise_pending()
            except CalledOffError:
                called_off.append(index)
                raise
            time.sleep(0.001)
        return index

    results = LocalExecutor(2).map(batch, range(6))
    assert [next(results), next(results)] == [(0, 0), (1, 1)]
    for _ in range(2):  # batches 2 and 3 run in the two threads
        assert running.acquire(timeout=60)
    results.close()  # returns once the threads are idle
    assert sorted(called_off) == [2, 3]  # and batches 4 and 5 never started


def test_a_task_that_fails_on_a_worker_is_named_and_the_finished_ones_are_delivered():
    invert = functools.partial(operator.truediv, 1.0)
    assert list(LocalExecutor().map(invert, [2.0])) == [(2.0, 0.5)]
    delivered = []
    with DaskExecutor(workers=1) as executor:  # one worker, one thread: tasks run in submission order
        with pytest.raises(BoomHydraulicsError, match=r"a task failed on a local Dask cluster .*ZeroDivisionError"):
            for item, result in executor.map(invert, [2.0, 4.0, 0.0]):
                delivered.append((item, result))
    assert delivered == [(2.0, 0.5), (4.0, 0.25)]  # what finished before the failure was handed over

"""The ranking of a sweep's designs (sweeps/recommend.py) on small tables whose answer is known:
each operator of ``--require`` exactly at and one past its value, the ranking's direction for
each ``--rank-by``, a design's worst case over its conditions, and the table a user reads."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.sweeps.recommend import (
    LOWER_IS_WORSE,
    RANKINGS,
    Constraint,
    designs_of,
    failing,
    format_table,
    format_value,
    parse_constraint,
    qualifying,
    recommend,
    worst_case,
)
from boom_hydraulics.sweeps.sweep import METRIC_NAMES


def _table(n: int, **columns) -> dict[str, np.ndarray]:
    """n ok points, every metric 1.0 but ``columns``."""
    table: dict[str, np.ndarray] = {"point": np.arange(n), "status": np.array(["ok"] * n)}
    for name in METRIC_NAMES:
        table[name] = np.full(n, 1.0)
    for name, values in columns.items():
        table[name] = np.asarray(values)
    return table


@pytest.mark.parametrize(
    ("text", "holds"),
    [
        ("peak_pressure_pa<=20e6", [True, True, False]),
        ("peak_pressure_pa < 20e6", [True, False, False]),
        ("peak_pressure_pa>=20e6", [False, True, True]),
        (" peak_pressure_pa >20e6 ", [False, False, True]),
        ("peak_pressure_pa==20e6", [False, True, False]),
    ],
)
def test_each_operator_at_and_past_its_value(text, holds):
    table = _table(3, peak_pressure_pa=[20e6 - 1.0, 20e6, 20e6 + 1.0])
    constraint = parse_constraint(text)
    assert (constraint.metric, constraint.value) == ("peak_pressure_pa", 20e6)
    assert constraint.holds(table).tolist() == holds


def test_a_value_that_is_not_finite_never_meets_a_constraint():
    table = _table(3, lift_time_s=[math.nan, math.inf, -math.inf])
    assert parse_constraint("lift_time_s>=0").holds(table).tolist() == [False, False, False]
    assert parse_constraint("lift_time_s<=inf").holds(table).tolist() == [False, False, False]


def test_a_magnitude_constraint_judges_both_signs_and_says_so():
    c = Constraint("set_down_error_deg", "<=", 1.0, magnitude=True)
    table = _table(4, set_down_error_deg=[-1.0, 1.0, -1.5, 0.5])
    assert c.holds(table).tolist() == [True, True, False, True]
    assert str(c) == "|set_down_error_deg| <= 1"
    assert str(Constraint("peak_pressure_pa", "<", 2.05e7)) == "peak_pressure_pa < 2.05e+07"


def test_a_constraint_passes_the_rows_it_does_not_apply_to():
    c = Constraint("relief_s", "==", 0.0, only_where="worst_target_error_deg")
    table = _table(3, relief_s=[0.5, 0.5, 0.0], worst_target_error_deg=[math.nan, 0.2, 0.2])
    assert c.applies(table).tolist() == [False, True, True]
    assert c.holds(table).tolist() == [True, False, True]
    table["relief_s"] = np.array([0.0, 0.0, 0.5])  # where it does not apply a row passes, met or not
    assert c.holds(table).tolist() == [True, True, False]
    assert Constraint("relief_s", "==", 0.0).applies(table).tolist() == [True, True, True]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("lift_time_s<=nan", "--require 'lift_time_s<=nan': the value must be a number, not NaN"),
        ("lift_time_s=>2", "--require 'lift_time_s=>2': write METRIC OP VALUE, e.g. peak_pressure_pa<=20e6"),
        ("lift_time_s<=2 s", "write METRIC OP VALUE"),
        ("2lift<=2", "write METRIC OP VALUE"),
        ("lift_time_s<=2,5", "'2,5' is not a number"),
    ],
)
def test_a_bad_constraint_is_one_line_naming_what_is_wrong(text, message):
    with pytest.raises(ConfigError) as refused:
        parse_constraint(text)
    assert message in str(refused.value) and "\n" not in str(refused.value)


def test_a_constraint_over_a_column_of_the_callers():
    assert parse_constraint("my_figure>-3", ["my_figure"]) == Constraint("my_figure", ">", -3.0)
    with pytest.raises(ConfigError, match="unknown metric 'lift_time_s'; choose from my_figure"):
        parse_constraint("lift_time_s<1", ["my_figure"])


def test_rank_by_each_figure_in_its_direction():
    table = _table(
        4,
        lift_energy_j=[3.0, 1.0, 2.0, 4.0],
        cycles_per_charge=[10.0, 30.0, math.inf, math.nan],
        lift_time_s=[2.0, 3.0, 1.0, 0.5],
    )
    assert recommend(table, []).rows.tolist() == [1, 2, 0, 3]  # least lift energy first
    # most cycles first; a run that gave back more than it drew (inf) is the best, NaN is no rank
    assert recommend(table, [], rank_by="cycles_per_charge").rows.tolist() == [2, 1, 0]
    assert recommend(table, [], rank_by="lift_time_s").rows.tolist() == [3, 2, 0, 1]
    battery = _table(3, battery_energy_j=[5e3, 2e3, 9e3], peak_battery_power_w=[3e3, 8e3, 1e3])
    assert recommend(battery, [], rank_by="battery_energy_j").rows.tolist() == [1, 0, 2]  # the least first
    assert recommend(battery, [], rank_by="peak_battery_power_w").rows.tolist() == [2, 0, 1]
    assert RANKINGS["cycles_per_charge"][0] is True and not RANKINGS["lift_energy_j"][0]
    with pytest.raises(ConfigError, match="--rank-by speed: choose lift_energy_j, battery_energy_j, cycles_per"):
        recommend(table, [], rank_by="speed")


def test_equal_figures_keep_the_sweeps_order():
    table = _table(4, lift_energy_j=[2.0, 1.0, 2.0, 1.0])
    assert recommend(table, []).rows.tolist() == [1, 3, 0, 2]
    assert recommend(table, [], rank_by="cycles_per_charge").rows.tolist() == [0, 1, 2, 3]


def test_a_point_not_ok_is_never_recommended_and_each_constraint_is_counted():
    table = _table(
        4,
        status=np.array(["ok", "incomplete", "ok", "ok"]),
        peak_pressure_pa=[10e6, 10e6, 25e6, 10e6],
        lift_time_s=[1.0, 1.0, 1.0, 3.0],
    )
    constraints = [parse_constraint("peak_pressure_pa<=20e6"), parse_constraint("lift_time_s<2")]
    rec = recommend(table, constraints, ["piston_diameter_m"])
    assert rec.rows.tolist() == [0]
    assert rec.passing == {"status ok": 3, "peak_pressure_pa <= 2e+07": 3, "lift_time_s < 2": 3}
    assert rec.columns == ("point", "piston_diameter_m")
    assert failing(rec) == [
        "  status ok                        3 of 4",
        "  peak_pressure_pa <= 2e+07        3 of 4",
        "  lift_time_s < 2                  3 of 4",
    ]
    why = Constraint("lift_time_s", "<", 2.0, "too slow")
    assert failing(recommend(table, [why]))[1] == "  lift_time_s < 2                  3 of 4; 1 fail: too slow"
    everyone = Constraint("lift_time_s", "<", 9.0, "too slow")
    assert failing(recommend(table, [everyone]))[1] == "  lift_time_s < 9                  4 of 4"


def test_a_design_is_its_worst_case_over_its_conditions():
    table = _table(
        6,
        piston_diameter_m=[0.05, 0.05, 0.05, 0.07, 0.07, 0.07],
        payload_mass_kg=[0.0, 100.0, 200.0] * 2,
        lift_energy_j=[1.0, 3.0, 2.0, 2.5, 2.5, 2.5],
        min_pressure_pa=[3e5, 1e5, 2e5, 1e5, 1e5, 1e5],
        damping_ratio=[0.3, 0.2, math.nan, 0.1, 0.1, 0.1],
        status=np.array(["ok", "ok", "ok", "ok", "failed", "incomplete"]),
    )
    designs = worst_case(table, ["piston_diameter_m"])
    assert designs["design"].tolist() == [0, 1] and designs["points"].tolist() == [3, 3]
    assert designs["piston_diameter_m"].tolist() == [0.05, 0.07]
    assert designs["lift_energy_j"].tolist() == [3.0, 2.5]  # the most energy
    assert designs["min_pressure_pa"].tolist() == [1e5, 1e5]  # the lowest pressure
    assert math.isnan(designs["damping_ratio"][0]) and designs["damping_ratio"][1] == 0.1  # NaN is worst
    assert designs["status"].tolist() == ["ok", "failed"]  # failed is worse than incomplete
    assert "min_pressure_pa" in LOWER_IS_WORSE and "peak_pressure_pa" not in LOWER_IS_WORSE
    rec = recommend(table, [], ["piston_diameter_m", "payload_mass_kg"], across=["payload_mass_kg"])
    assert rec.columns == ("design", "piston_diameter_m") and rec.rows.tolist() == [0]
    assert rec.passing == {"status ok": 1}


def test_across_a_design_counts_each_constraint_over_all_its_points_and_ranks_by_its_worst():
    table = _table(
        6,
        piston_diameter_m=[0.05, 0.05, 0.07, 0.07, 0.09, 0.09],
        payload_mass_kg=[0.0, 100.0] * 3,
        lift_energy_j=[1.0, 5.0, 3.0, 4.0, 2.0, 2.0],
        peak_pressure_pa=[10e6, 10e6, 10e6, 10e6, 10e6, 25e6],
    )
    limit = parse_constraint("peak_pressure_pa<=20e6")
    rec = recommend(table, [limit], ["piston_diameter_m", "payload_mass_kg"], across=["payload_mass_kg"])
    assert rec.rows.tolist() == [1, 0]  # worst 4 J before worst 5 J; the 0.09 design fails at 100 kg
    assert rec.passing == {"status ok": 3, "peak_pressure_pa <= 2e+07": 2}
    text = format_table(rec)
    assert "designs meeting each at all their points" in text
    assert "2 of 3 designs meet every constraint; the 2 with the least worst-case lift energy" in text


def test_across_a_column_that_is_not_varied_is_refused_in_one_line():
    table = _table(2, lift_energy_j=[1.0, 2.0])
    with pytest.raises(ConfigError, match=r"--across payload_mass_kg: not a varied parameter; choose from none"):
        recommend(table, [], [], across=["payload_mass_kg"])
    with pytest.raises(ConfigError, match=r"--across operator, speed: not a varied parameter; choose from d, e$"):
        recommend(table, [], ["d", "e"], across=["speed", "operator", "d"])


def test_designs_in_the_order_they_first_appear():
    table = {"status": np.array(["ok"] * 5), "d": np.array([2, 1, 2, 3, 1]), "e": np.array(["a", "a", "b", "a", "a"])}
    assert designs_of(table, ["d"]) == {(2,): [0, 2], (1,): [1, 4], (3,): [3]}
    assert list(designs_of(table, ["d", "e"])) == [(2, "a"), (1, "a"), (2, "b"), (3, "a")]
    assert designs_of(table, []) == {(): [0, 1, 2, 3, 4]}


def test_the_table_a_user_reads():
    table = _table(
        3,
        piston_diameter_m=[0.05, 0.07, 0.09],
        lift_energy_j=[12_345.0, 9_000.0, 20_000.0],
        lift_time_s=[1.5, 2.5, 1.0],
        peak_pressure_pa=[15e6, 12e6, 18e6],
        cycles_per_charge=[100.0, 120.0, 80.0],
    )
    text = format_table(recommend(table, [], ["piston_diameter_m"]), top=2)
    lines = text.splitlines()
    assert lines[0] == "Constraints (designs meeting each):"
    assert lines[2].startswith("3 of 3 designs meet every constraint; the 2 with the least lift energy (* = on the")
    heading, first, second = lines[3].split(), lines[4].split(), lines[5].split()
    assert heading[:5] == ["rank", "point", "piston_diameter_m", "lift", "energy"]
    assert first[:5] == ["1", "1", "0.07", "9", "2.5"]  # kJ, s
    assert second[:5] == ["2", "0", "0.05", "12.35", "1.5"]
    assert first[5] == "12" and second[5] == "15"  # MPa
    assert first[-1] == "*" and second[-1] == "*"  # each beats the other in something: both on the front
    assert len(lines) == 6 and text.endswith("\n")
    assert len({len(line) for line in lines[3:]}) == 1  # right-aligned columns
    most = format_table(recommend(table, [], ["piston_diameter_m"], rank_by="cycles_per_charge"))
    assert "the 3 with the most cycles per charge" in most and most.splitlines()[4].split()[:2] == ["1", "1"]


def test_the_table_says_when_no_design_qualifies_and_marks_who_is_off_the_front():
    table = _table(2, lift_energy_j=[1.0, 2.0], lift_time_s=[1.0, 2.0], peak_pressure_pa=[1e6, 2e6])
    text = format_table(recommend(table, [Constraint("lift_time_s", "<", 0.5, "too slow")]))
    assert text.splitlines()[-1] == "No design meets every constraint; relax the tightest one above."
    assert "2 fail: too slow" in text
    lines = format_table(recommend(table, [])).splitlines()
    assert lines[4].endswith("*") and not lines[5].endswith("*")  # the second is dominated by the first


@pytest.mark.parametrize(
    ("value", "shown"),
    [(np.int64(12345), "12345"), (7, "7"), (0.0660000001, "0.066"), (123456.0, "1.235e+05"), (math.nan, "-"),
     (np.float32(2.5), "2.5"), ("load_sensing", "load_sensing"), (np.str_("paper_fig8"), "paper_fig8"),
     (math.inf, "inf"), (-0.00012345, "-0.0001234")],
)  # fmt: skip
def test_a_table_cell_for_people(value, shown):
    assert format_value(value) == shown


def test_the_table_shows_the_ten_best_by_default():
    table = _table(12, lift_energy_j=np.arange(12.0, 0.0, -1.0))
    lines = format_table(recommend(table, [])).splitlines()
    assert "12 of 12 designs meet every constraint; the 10 with the least lift energy" in lines[2]
    ranks = [line.split()[:2] for line in lines[4:]]
    assert ranks == [[str(k + 1), str(11 - k)] for k in range(10)]  # rank, point: the least energy first


def test_only_ok_points_qualify_whatever_their_figures():
    table = _table(4, status=np.array(["ok", "incomplete", "failed", "invalid"]))
    assert qualifying(table, []).tolist() == [True, False, False, False]
    assert qualifying(table, [], ["d"], across=["d"]).tolist() == [False] * 4  # one design: every point counts


def test_across_every_varied_parameter_the_whole_sweep_is_one_design():
    table = _table(3, payload_mass_kg=[0.0, 100.0, 200.0], lift_energy_j=[1.0, 3.0, 2.0])
    rec = recommend(table, [], ["payload_mass_kg"], across=["payload_mass_kg"])
    assert rec.columns == ("design",) and rec.rows.tolist() == [0]
    assert rec.table["lift_energy_j"].tolist() == [3.0] and rec.table["points"].tolist() == [3]


def test_a_constraint_every_one_of_many_designs_meets_names_no_failure():
    table = _table(300, lift_time_s=np.linspace(1.0, 2.0, 300))
    lines = failing(recommend(table, [Constraint("lift_time_s", "<", 9.0, "too slow")]))
    assert lines[1] == "  lift_time_s < 9                  300 of 300"


def test_each_column_of_the_table_in_its_display_unit():
    table = _table(
        1,
        lift_energy_j=[12_300.0],
        lift_time_s=[1.25],
        peak_pressure_pa=[18.5e6],
        min_pressure_pa=[0.35e6],
        overshoot_m=[0.0042],
        damping_ratio=[0.125],
        cavitation_s=[0.03],
        battery_energy_j=[45_600.0],
        cycles_per_charge=[321.0],
    )
    lines = format_table(recommend(table, [])).splitlines()
    assert lines[4].split() == ["1", "0", "12.3", "1.25", "18.5", "0.35", "4.2", "0.125", "0.03", "45.6", "321", "*"]

"""The rules every sweep applies (sweeps/rules.py) at their limits: a design exactly at a
tolerance qualifies and one just past it does not; each setting refuses zero, negative and
non-finite values in one line; and where a best design at an end of the searched range says
which way to extend it (not where the parameter can go no further, nor where the axis is flat)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.sweeps.recommend import qualifying
from boom_hydraulics.sweeps.rules import FLAT, TARGET_TOLERANCE_DEG, Rules, range_edges

PAST = 1e-9  # one past a limit: as little as a float shows


def _table(n: int, **columns) -> dict[str, np.ndarray]:
    """ok rows of a closed-loop sweep that meet every rule, but for ``columns``."""
    table = {
        "status": np.array(["ok"] * n),
        "worst_target_error_deg": np.full(n, 0.2),
        "set_down_error_deg": np.full(n, 0.1),
        "worst_settle_time_s": np.full(n, 2.0),
        "peak_pressure_pa": np.full(n, 10e6),
        "relief_s": np.zeros(n),
    }
    table |= {name: np.asarray(values, dtype=float) for name, values in columns.items()}
    return table


DEFAULTS = Rules()


def _qualifies(table, rules: Rules = DEFAULTS) -> list[bool]:
    return qualifying(table, rules.constraints()).tolist()


def test_a_target_error_exactly_at_the_tolerance_qualifies_and_one_past_does_not():
    assert TARGET_TOLERANCE_DEG == 1.0
    table = _table(3, worst_target_error_deg=[1.0, 1.0 + PAST, 0.0])
    assert _qualifies(table) == [True, False, True]
    assert _qualifies(table, Rules(target_tolerance_deg=0.5)) == [False, False, True]


def test_the_set_down_is_judged_by_its_magnitude_on_either_side_of_the_ground():
    table = _table(4, set_down_error_deg=[1.0, -1.0, 1.0 + PAST, -1.0 - PAST])
    assert _qualifies(table) == [True, True, False, False]
    # Its own tolerance, apart from the targets'; the targets' when not given.
    assert _qualifies(table, Rules(set_down_tolerance_deg=2.0)) == [True, True, True, True]
    assert _qualifies(table, Rules(target_tolerance_deg=2.0)) == [True, True, True, True]
    assert _qualifies(table, Rules(target_tolerance_deg=2.0, set_down_tolerance_deg=0.5)) == [False] * 4


def test_the_settle_time_and_peak_pressure_limits_are_inclusive():
    table = _table(2, worst_settle_time_s=[3.0, 3.0 + PAST])
    assert _qualifies(table, Rules(settle_time_s=3.0)) == [True, False]
    table = _table(2, peak_pressure_pa=[18e6, 18e6 + 1e-3])
    assert _qualifies(table, Rules(max_pressure_pa=18e6)) == [True, False]


def test_any_relief_flow_rejects_a_closed_loop_design_unless_allowed():
    table = _table(2, relief_s=[0.0, 1e-6])
    assert _qualifies(table) == [True, False]
    assert _qualifies(table, Rules(allow_relief=True)) == [True, True]


def test_a_closed_loop_run_that_releases_no_payload_is_not_judged_on_its_set_down():
    table = _table(2, set_down_error_deg=[math.nan, 5.0])
    assert _qualifies(table) == [True, False]
    # A run without targets (open loop) is judged by none of the rules of a closed loop.
    nan = [math.nan, math.nan]
    open_loop = _table(2, worst_target_error_deg=nan, worst_settle_time_s=nan, relief_s=[0.0, 0.5])
    assert _qualifies(open_loop, Rules(settle_time_s=1.0)) == [True, True]


def test_each_rule_says_what_a_failing_design_did():
    rules = Rules(set_down_tolerance_deg=0.5, settle_time_s=3.0, max_pressure_pa=18e6)
    found = {str(c): c.why for c in rules.constraints()}
    assert found == {
        "worst_target_error_deg <= 1": "a target missed by more than 1 deg at its phase's end",
        "|set_down_error_deg| <= 0.5": "the payload put down more than 0.5 deg from the ground",
        "worst_settle_time_s <= 3": "a target not reached and held within 3 s of its phase's start",
        "peak_pressure_pa <= 1.8e+07": "a chamber pressure above 18 MPa",
        "relief_s == 0": "a port relief valve opened",
    }
    assert [str(c) for c in Rules(allow_relief=True).constraints()] == [
        "worst_target_error_deg <= 1",
        "|set_down_error_deg| <= 1",
    ]


@pytest.mark.parametrize("name", ["target_tolerance_deg", "set_down_tolerance_deg", "settle_time_s", "max_pressure_pa"])
@pytest.mark.parametrize("value", [0.0, -1.0, math.inf, math.nan])
def test_a_rule_setting_that_is_not_a_positive_number_is_refused_in_one_line(name, value):
    with pytest.raises(ConfigError) as refused:
        Rules(**{name: value})
    option = "--" + name.replace("_", "-")
    assert str(refused.value) == f"{option} must be a positive number, got {value}"


def test_the_smallest_positive_settings_are_taken():
    rules = Rules(target_tolerance_deg=1e-6, set_down_tolerance_deg=1e-6, settle_time_s=1e-6, max_pressure_pa=1e-6)
    assert [c.value for c in rules.constraints()] == [1e-6, 1e-6, 1e-6, 1e-6, 0.0]


def test_a_best_at_an_end_names_it_unless_the_parameter_can_go_no_further():
    # boom_damping_ratio may lie in [0, 1]: a best at 1 cannot be extended above it, one at 0.8 can.
    table = {"boom_damping_ratio": np.array([0.0, 0.5, 1.0]), "payload_mass_kg": np.array([10.0, 50.0, 100.0])}
    axes = ["boom_damping_ratio", "payload_mass_kg"]
    assert range_edges(table, axes, 0) == [
        "payload_mass_kg: best at the lower end 10; extend the range below 10",
    ]
    assert range_edges(table, axes, 2) == [
        "payload_mass_kg: best at the upper end 100; extend the range above 100",
    ]
    table["boom_damping_ratio"] = np.array([0.1, 0.5, 0.8])
    assert range_edges(table, axes, 2)[0] == "boom_damping_ratio: best at the upper end 0.8; extend the range above 0.8"
    assert range_edges(table, axes, 0)[0] == "boom_damping_ratio: best at the lower end 0.1; extend the range below 0.1"


def test_range_edges_of_integer_columns_and_columns_with_failed_points():
    table = {"substeps": np.array([2, 4, 8]), "my_gain": np.array([math.nan, 1.0, 3.0])}
    assert range_edges(table, ["substeps"], 2) == ["substeps: best at the upper end 8; extend the range above 8"]
    # NaN is no end: the searched values are 1 and 3 (a column that is not a parameter: no limits).
    assert range_edges(table, ["my_gain"], 1) == ["my_gain: best at the lower end 1; extend the range below 1"]
    assert range_edges({"my_gain": np.array([math.nan, 2.0])}, ["my_gain"], 1) == []


def test_a_design_within_flat_of_the_best_along_an_axis_names_no_end():
    assert FLAT == 1e-3
    table = {"piston_diameter_m": np.array([0.05, 0.07, 0.09])}
    axes = ["piston_diameter_m"]
    line = ["piston_diameter_m: best at the lower end 0.05; extend the range below 0.05"]
    assert range_edges(table, axes, 0, score=np.array([1000.0, 1001.0, 2000.0])) == []  # exactly FLAT
    assert range_edges(table, axes, 0, score=np.array([1000.0, 1001.0 + 1e-6, 2000.0])) == line
    assert range_edges(table, axes, 0, score=np.array([-1000.0, -999.5, -500.0])) == []  # a score to maximise
    assert range_edges(table, axes, 0, score=np.array([1000.0, math.nan, 1000.5])) == []
    assert range_edges(table, axes, 0, score=np.array([1000.0, math.nan, math.inf])) == line
    assert range_edges(table, axes, 0, score=np.array([math.nan, 5.0, 5.0])) == line  # a best without a score
    # Another design at the same diameter (of another drive) is no neighbour along the diameter.
    table = {"drive": np.array(["a", "a", "b"]), "piston_diameter_m": np.array([0.05, 0.07, 0.05])}
    two = ["drive", "piston_diameter_m"]
    assert range_edges(table, two, 0, score=np.array([1000.0, 3000.0, 1000.0])) == line
    assert range_edges(table, two, 0, score=np.array([1000.0, 1000.0, 3000.0])) == []


def test_a_column_without_a_finite_value_names_no_end():
    table = {"piston_diameter_m": np.array([math.nan, math.nan]), "payload_mass_kg": np.array([10.0, 20.0])}
    assert range_edges(table, ["piston_diameter_m", "payload_mass_kg"], 1) == [
        "payload_mass_kg: best at the upper end 20; extend the range above 20"
    ]


def test_a_best_at_the_upper_end_flat_against_a_smaller_design_names_no_end():
    table = {"piston_diameter_m": np.array([0.05, 0.07, 0.09])}
    axes = ["piston_diameter_m"]
    assert range_edges(table, axes, 2, score=np.array([2000.0, 1000.5, 1000.0])) == []
    assert range_edges(table, axes, 2, score=np.array([2000.0, 1500.0, 1000.0])) == [
        "piston_diameter_m: best at the upper end 0.09; extend the range above 0.09"
    ]


@pytest.mark.parametrize("other", ["boom_mass_kg", "supply_pressure_pa"])  # named before and after the axis
def test_only_a_design_equal_in_every_other_column_is_a_neighbour_along_an_axis(other):
    """The 0.07 m pistons that score as well as the best have another (a smaller, a larger) boom mass
    or supply pressure: it is no neighbour of the best along the diameter, which is at its end."""
    table = {"piston_diameter_m": np.array([0.05, 0.07, 0.07, 0.07]), other: np.array([100.0, 100.0, 50.0, 150.0])}
    lines = range_edges(table, ["piston_diameter_m", other], 0, score=np.array([1000.0, 3000.0, 1000.0, 1000.0]))
    assert "piston_diameter_m: best at the lower end 0.05; extend the range below 0.05" in lines


def test_the_pressure_rule_says_its_limit_in_megapascals_to_the_digit():
    (rule,) = [c for c in Rules(max_pressure_pa=18.5e6).constraints() if c.metric == "peak_pressure_pa"]
    assert rule.why == "a chamber pressure above 18.5 MPa"


def test_range_edges_of_axes_named_on_the_command_line():
    # names built at run time (not the interned literals of a test): the operator's seed is no range
    operator, gain = "".join(["oper", "ator"]), "".join(["my_", "gain"])
    table = {operator: np.array([1, 2, 3]), gain: np.array([0.0, 1.0, 2.0])}
    assert range_edges(table, [operator, gain], 0) == ["my_gain: best at the lower end 0; extend the range below 0"]

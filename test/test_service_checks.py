"""The node's ~/pause and ~/step checks (ros/service_checks.py) at and past their limits, without
a node: what test_node.py and test_node_stamps.py ask through ROS, to the last step."""

from __future__ import annotations

import pytest

from boom_hydraulics.ros.service_checks import (
    STEP_CALL_LIMIT_S,
    pause_unchanged,
    step_limit,
    step_refusal,
    steps_asked,
)

NOT_PAUSED = "step works while paused; call ~/pause with data: true"


@pytest.mark.parametrize(
    ("time_step_s", "limit"),
    [
        (1e-3, 10_000),  # the default
        (1e-5, 1_000_000),  # 10 / 1e-5 is 999 999.9999999999 in floating point: still 10 s
        (1e-4, 100_000),
        (3e-3, 3333),  # not a whole number of steps: the steps within 10 s
        (0.7, 14),
        (10.0, 1),  # one step of the whole limit
        (25.0, 1),  # a step longer than the limit: still one step a call
    ],
)
def test_a_step_call_takes_ten_seconds_of_steps_and_refuses_one_more(time_step_s, limit):
    assert STEP_CALL_LIMIT_S == 10.0
    assert step_limit(time_step_s) == limit
    assert step_refusal(True, None, limit, time_step_s) is None
    refusal = step_refusal(True, None, limit + 1, time_step_s)
    assert refusal == (
        f"steps: {limit + 1} is {(limit + 1) * time_step_s:g} s of simulated time; one call takes at most "
        f"10 s ({limit} steps of {time_step_s:g} s): call ~/step again for more"
    )


def test_only_the_divisions_rounding_is_forgiven_not_a_part_of_a_step():
    """At the node's finest steps (1e-8 s: a billion to 10 s), a count 0.005 steps short of a
    whole number is the one below it: the allowance is a part in 1e12, not a part of a step."""
    short = STEP_CALL_LIMIT_S / (1e9 - 0.005)
    assert step_limit(short) == 999_999_999
    assert step_limit(STEP_CALL_LIMIT_S / 1e9) == 1_000_000_000


def test_the_refusal_names_the_request_and_the_way_there():
    assert step_refusal(True, None, 10_001, 1e-3) == (
        "steps: 10001 is 10.001 s of simulated time; one call takes at most 10 s (10000 steps of 0.001 s): "
        "call ~/step again for more"
    )
    assert step_refusal(True, None, 4_294_967_295, 1e-3).startswith("steps: 4294967295 is 4.29497e+06 s")


def test_zero_steps_are_one_and_others_as_asked():
    assert [steps_asked(n) for n in (0, 1, 2, 10_001)] == [1, 1, 2, 10_001]


def test_only_a_paused_running_simulation_steps():
    assert step_refusal(False, None, 1, 1e-3) == NOT_PAUSED
    assert step_refusal(False, "diverged", 1, 1e-3) == NOT_PAUSED  # running: that comes first
    assert step_refusal(True, "q1 left the geometry", 1, 1e-3) == (
        "simulation stopped: q1 left the geometry; call ~/reset"
    )
    assert step_refusal(True, "diverged", 10**9, 1e-3) == "simulation stopped: diverged; call ~/reset"
    assert step_refusal(True, None, 1, 1e-3) is None
    assert step_refusal(True, "", 1, 1e-3) is None  # no failure


def test_a_pause_that_changes_nothing_says_so_and_a_change_acts():
    assert pause_unchanged(True, True) == "already paused"
    assert pause_unchanged(False, False) == "already running"
    assert pause_unchanged(True, False) is None
    assert pause_unchanged(False, True) is None

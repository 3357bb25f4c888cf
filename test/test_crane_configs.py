"""The shipped crane configurations beside default.yaml: config/loader_crane_1t.yaml, a small
loader crane's main boom lifting 1 t at its tip (docs/loader-crane.md). It loads as it is
written, its cylinder holds the load below the port relief over the whole stroke, and the
loader work cycle lifts the tonne and puts it down with every drive."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.model import config, ledger, physical
from boom_hydraulics.model.geometry import holding_pressure_pa, static_rod_force_of
from boom_hydraulics.model.parameters import DRIVES, NAMES, describe, with_updates
from boom_hydraulics.solve import commands, duty_cycles
from boom_hydraulics.solve.simulation import Simulator

LOADER_CRANE = CONFIG / "loader_crane_1t.yaml"


@pytest.fixture(scope="module")
def crane():
    """The 1 t loader crane's parameters, read as the node and boom-sim read them."""
    return config.load(LOADER_CRANE)


def test_the_loader_crane_loads_without_warnings_and_names_only_known_parameters():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        params = config.load(LOADER_CRANE)
    values = config.read_values(LOADER_CRANE)
    assert set(values) <= set(NAMES), set(values) - set(NAMES)
    # every value it gives is the one the crane runs with; the rest are default.yaml's
    for name in NAMES:
        expected = values[name] if name in values else describe(name)["default"]
        assert getattr(params, name) == expected, name
    assert params.drive == "pressure_compensated" and params.payload_mass_kg == 1000.0


def test_ros_reads_the_loader_crane_as_the_model_does():
    """ROS 2's own params-file reader (PyYAML, YAML 1.1) types every value as the model does."""
    rclpy_parameter = pytest.importorskip("rclpy.parameter")
    loaded = rclpy_parameter.parameter_dict_from_yaml_file(str(LOADER_CRANE), use_wildcard=True)
    values = config.read_values(LOADER_CRANE)
    assert set(loaded) == set(values)
    for name, value in values.items():
        ros = loaded[name].value
        assert (ros.string_value if isinstance(value, str) else ros.double_value) == value, name


def test_the_cylinder_holds_the_tonne_below_the_port_relief_over_the_whole_stroke(crane):
    q1 = np.linspace(crane.cylinder_min_length_m, crane.cylinder_max_length_m, 401)
    force = static_rod_force_of(crane, q1, np)  # eq. 6
    p1 = holding_pressure_pa(force, crane.piston_diameter_m, crane.tank_pressure_pa, crane.rod_diameter_m)
    assert (force > 0.0).all()  # the boom hangs on the oil everywhere, the rod side drained
    # the piston was sized so that it holds below 70 % of the relief (the config's comment)
    assert p1.max() < 0.7 * crane.relief_pressure_pa
    assert p1.max() < crane.supply_pressure_pa  # the supply can lift it from anywhere in the stroke


#: The fixed pump as the paper builds it: the open centre it is shipped with, its motor on demand,
#: misses the cycle's targets by degrees (the open centre bleeds what a small opening passes;
#: docs/drives.md), and this test is of the crane, not of that circuit.
PAPERS_CIRCUIT = {"fixed_pump": {"valve_centre": "closed", "motor_strategy": "constant"}}


def _loader_cycle(crane, drive: str):
    """The nominal loader cycle with ``drive``, and 2 s to settle after it."""
    params = with_updates(crane, drive=drive, **PAPERS_CIRCUIT.get(drive, {}))
    params = with_updates(params, **commands.scenario("loader", 0.0, params))
    sim = Simulator(params)
    out = sim.run(duty_cycles.loader_duration_s() + 2.0, commands.from_parameters(params), every=5)
    return params, sim, out


@pytest.mark.parametrize("drive", DRIVES)
def test_the_loader_cycle_lifts_the_tonne_and_puts_it_down_with_every_drive(crane, drive):
    params, sim, out = _loader_cycle(crane, drive)
    t, rise = out["t"], np.degrees(out["alpha"] - out["alpha"][0])
    lower, lift_empty, lower_empty = params.command_times_s[1:]
    release = params.command_payload_times_s[0]
    loaded, empty = t < lower, (t >= lift_empty) & (t < lower_empty)
    for phase in (loaded, empty):  # each lift reaches the cycle's 25 degrees, overshooting a little
        assert duty_cycles.LOADER_RISE_DEG - 0.5 < rise[phase].max() < duty_cycles.LOADER_RISE_DEG + 3.0
    assert abs(rise[(t > release - 0.3) & (t < release)]).max() < 1.0  # the tonne is set down on the ground
    assert abs(rise[-1]) < 1.5  # and the cycle ends there
    # while the tonne hangs on it, no chamber reaches the port relief
    hanging = t < release
    assert max(out["p1"][hanging].max(), out["p2"][hanging].max()) < params.relief_pressure_pa
    assert not out["relief_open"][hanging].any()
    # the oil does not cavitate while the boom lifts, holds or lowers the tonne, nor once the empty
    # boom has settled; the payload dropped off the hook at once (a step of 9.8 kN at the tip) may
    # pull p1 to vapour for a moment, and the load-sensing pump, lagging behind the lowering
    # command, lets the rod chamber starve for a few hundredths of a second (docs/loader-crane.md)
    # (the elastic boom rings after the release, and load sensing's p1 touches vapour in its swings
    # for about a second: docs/loader-crane.md)
    cavitation = out["cavitation"].astype(bool)
    assert not cavitation[(t < release) | (t > release + 0.5)].any() or drive == "load_sensing"
    assert not cavitation[(t < lower) | (t > release + (1.2 if drive == "load_sensing" else 0.5))].any()
    assert cavitation[t < release].sum() * (t[1] - t[0]) < 0.1
    integrals = physical.ledger_integrals(sim.y)
    assert ledger.energies_of(integrals)["imbalance_ratio"] < 0.005
    # the tonne was raised by the cycle's 25 degrees at the boom's tip (and the boom with it)
    tip_rise_m = params.boom_length_m * (
        math.sin(out["alpha"][0] + math.radians(duty_cycles.LOADER_RISE_DEG)) - math.sin(out["alpha"][0])
    )
    assert integrals["lift_work"] > params.payload_mass_kg * params.gravity_m_s2 * tip_rise_m

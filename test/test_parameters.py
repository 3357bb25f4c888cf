"""Parameter validation and the params YAML format shared by node and CLI."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest
from conftest import CONFIG

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import (
    PLANT_FAULTS,
    Parameters,
    as_dict,
    from_mapping,
    plant_fault,
    plant_fault_message,
    stroke_limits_m,
    with_updates,
)
from boom_hydraulics.solve.simulation import Simulator


def test_default_yaml_spells_out_the_code_defaults():
    assert config.load(CONFIG / "default.yaml") == Parameters()


@pytest.mark.parametrize("name", ["paper_fig8", "paper_fig9", "paper_fig10"])
def test_paper_configs_are_paper_mode_with_printed_values(name):
    p = config.load(CONFIG / f"{name}.yaml")
    assert p.mode == "paper" and p.method == "rk4" and p.time_step_s == 0.001
    assert (p.a_m, p.b_m, p.boom_length_m, p.support_height_m) == (0.4, 1.4, 2.0, 1.307)
    assert (p.boom_mass_kg, p.payload_mass_kg, p.initial_length_m) == (100.0, 50.0, 1.37)
    assert p.piston_dead_volume_m3 == 2e-5 and p.spring_stiffness_n_m == 2000.0
    expected = {"paper_fig8": (0.04, 1.45e6), "paper_fig9": (0.08, 1.45e6), "paper_fig10": (0.08, 14.5e6)}
    assert (p.piston_diameter_m, p.bulk_modulus_pa) == expected[name]


def test_numbers_read_as_ros2_reads_them(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text(
        "boom_sim:\n  ros__parameters:\n    bulk_modulus_pa: 1.5e9\n    rtol: 1e-07\n    payload_mass_kg: 80\n"
    )
    p = config.load(f)
    assert p.bulk_modulus_pa == 1.5e9 and p.rtol == 1e-7 and p.payload_mass_kg == 80.0


def test_an_external_rod_force_in_a_params_file_pushes_either_way_and_must_be_finite(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text("/**:\n  ros__parameters:\n    external_rod_force_n: -1500\n")
    assert config.load(f).external_rod_force_n == -1500.0  # an integer is taken as the float
    assert Parameters().external_rod_force_n == 0.0
    for bad, message in ((math.nan, "must be finite"), (2e7, "must be <= 10000000.0"), (-2e7, "must be >=")):
        with pytest.raises(ConfigError, match=message):
            with_updates(Parameters(), external_rod_force_n=bad)


def test_wildcard_node_section_and_nested_names(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text("/**:\n  ros__parameters:\n    piston_diameter_m: 0.05\n")
    assert config.load(f).piston_diameter_m == 0.05


def test_unknown_key_names_the_closest_valid_ones():
    with pytest.raises(ConfigError, match=r"unknown parameter 'piston_diameter'.*did you mean piston_diameter_m"):
        from_mapping({"piston_diameter": 0.05})


@pytest.mark.parametrize(
    ("values", "pattern"),
    [
        ({"boom_mass_kg": "heavy"}, r"'boom_mass_kg' must be a number"),
        ({"substeps": 1.5}, r"'substeps' must be an integer"),
        ({"mode": "fast"}, r"choose one of physical, paper"),
        ({"command_values": "1,0"}, r"must be a list of numbers"),
        ({"boom_mass_kg": 0.0}, r"'boom_mass_kg'.*must be > 0"),
        ({"payload_mass_kg": -1.0}, r"'payload_mass_kg'.*must be >= 0"),
        ({"piston_diameter_m": -0.04}, r"'piston_diameter_m'.*must be > 0"),
        ({"orifice_diameter_m": 0.0}, r"'orifice_diameter_m'.*must be > 0"),
        ({"piston_dead_volume_m3": 0.0}, r"'piston_dead_volume_m3'.*must be > 0"),
        ({"bulk_modulus_pa": 0.0}, r"'bulk_modulus_pa'.*must be > 0"),
        ({"time_step_s": 0.0}, r"'time_step_s'.*must be > 0"),
        ({"time_step_s": float("nan")}, r"'time_step_s' must be finite"),
        ({"rod_diameter_m": 0.04}, r"rod_diameter_m .* must be smaller than piston_diameter_m"),
        ({"cylinder_min_length_m": 1.0}, r"degenerates at q1 = \|b - a\| = 1 m"),
        ({"cylinder_max_length_m": 1.8}, r"a \+ b = 1.8 m"),
        ({"cylinder_min_length_m": 1.6, "cylinder_max_length_m": 1.5}, r"increasing interval"),
        ({"initial_length_m": 1.77}, r"initial_length_m \(1.77 m\) lies outside the stroke"),
        ({"support_height_m": 1.5}, r"arccos\(h / b\)"),
        ({"relief_pressure_pa": 10e6}, r"relief_pressure_pa .* at least supply_pressure_pa"),
        ({"command_profile": "steps", "command_times_s": [0, 1], "command_values": [1.0]}, r"equal length"),
        ({"command_profile": "steps", "command_times_s": [1, 0], "command_values": [1, 0]}, r"strictly increasing"),
        ({"command_value": 1.5}, r"'command_value' is 1.5; it must be <= 1.0"),
        ({"payload_mass_kg": 1e300}, r"'payload_mass_kg' is 1e\+300 kg; it must be <= 100000.0"),
        ({"piston_diameter_m": 2.0}, r"'piston_diameter_m' is 2.0 m; it must be <= 1.0"),
        ({"command_profile": "sine", "command_offset": 0.8, "command_amplitude": 0.5}, r"valve opening 1.3 .* outside"),
        ({"mode": "paper", "command_value": -0.5}, r"outside \[0, 1\] \(paper mode"),
    ],
)
def test_invalid_values_are_refused_with_a_reason(values, pattern):
    with pytest.raises(ConfigError, match=pattern):
        from_mapping(values)
    base = from_mapping({"payload_mass_kg": 120.0})
    with pytest.raises(ConfigError, match=pattern):  # on a base, as a sweep makes its points
        from_mapping(values, base=base)
    assert base.payload_mass_kg == 120.0 and base == from_mapping({"payload_mass_kg": 120.0})


def test_updates_on_a_base_give_what_the_whole_set_gives():
    """A sweep's points are its base config with the point's values: checked field by field only
    where they changed, the result is the parameter set made and checked whole."""
    base = from_mapping({"drive": "load_sensing", "payload_mass_kg": 120.0, "command_profile": "steps"})
    updates = {"piston_diameter_m": 0.07, "rod_diameter_m": 0.04, "command_values": [1.0, 0.0], "substeps": 2}
    updates["command_times_s"] = [0.0, 1.0]
    point = from_mapping(updates, base=base)
    assert point == Parameters(**{**as_dict(base), **updates}) and point != base
    assert base.piston_diameter_m != 0.07  # the base is left as it was


def test_malformed_yaml_names_file_and_line(tmp_path):
    f = tmp_path / "bad.yaml"
    f.write_text("boom_sim:\n  ros__parameters:\n    a_m: [0.4\n    b_m: 1.4\n")
    with pytest.raises(ConfigError, match=r"bad.yaml: malformed YAML at line \d+"):
        config.load(f)


def test_missing_file_and_missing_section(tmp_path):
    with pytest.raises(ConfigError, match=r"nope.yaml: no such file"):
        config.load(tmp_path / "nope.yaml")
    f = tmp_path / "other.yaml"
    f.write_text("other_node:\n  ros__parameters: {}\n")
    with pytest.raises(ConfigError, match=r"no section for node 'boom_sim'"):
        config.load(f)


def test_error_leaves_nothing_half_applied():
    sim = Simulator(Parameters())
    before = sim.params
    with pytest.raises(ConfigError):
        sim.set_parameters(with_updates(before, payload_mass_kg=80.0, rod_diameter_m=0.05))
    assert sim.params is before and sim.params.payload_mass_kg == 50.0


def test_payload_changes_between_steps():
    sim = Simulator(Parameters())
    sim.step(0.0, 10)
    q_before = sim.y[0]
    sim.set_payload_mass(120.0)
    assert sim.params.payload_mass_kg == 120.0 and sim.y[0] == q_before
    sim.step(0.0, 200)  # the closed valve now holds a heavier boom: it sinks a little
    assert sim.y[0] < q_before


def test_every_parameter_is_in_one_group_by_what_it_configures():
    from boom_hydraulics.model.parameters import GROUPS, NAMES, group_of, names_in

    assert GROUPS == ("plant", "solver", "controller", "scenario")
    assert sorted(n for g in GROUPS for n in names_in(g)) == sorted(NAMES)  # each name once
    assert names_in("solver") == ("method", "time_step_s", "substeps", "rtol", "atol_scale")
    assert names_in("controller") == tuple(n for n in NAMES if n.startswith("control_"))
    assert names_in("scenario") == tuple(n for n in NAMES if n.startswith("command_"))
    assert group_of("mode") == group_of("payload_mass_kg") == "plant"
    with pytest.raises(ValueError, match="unknown parameter group 'valve'"):
        names_in("valve")


def test_the_method_names_live_in_the_model_without_the_solver():
    """model/ defines the names; the solver's registry implements exactly them (test_layers)."""
    from boom_hydraulics.model.parameters import METHOD_NAMES, METHODS, describe

    assert METHODS == tuple(METHOD_NAMES) == describe("method")["choices"] == ("euler", "rk4", "rk45", "ros2")
    assert all(METHOD_NAMES.values())


def test_the_sweep_batches_on_the_solver_keys_it_shares_and_the_scenario_group():
    from boom_hydraulics.model.parameters import names_in
    from boom_hydraulics.sweeps.sweep import BATCH_KEYS

    assert BATCH_KEYS == ("mode", "method", "time_step_s", "substeps", *names_in("scenario"))


def test_a_scenario_that_does_not_fit_the_plant_is_refused():
    """The scenario is checked against the plant it drives: its mode and its stroke."""
    with pytest.raises(ConfigError, match=r"'angle' \(closed-loop control\) needs mode: physical"):
        from_mapping({"mode": "paper", "command_profile": "angle"})
    with pytest.raises(ConfigError, match=r"target boom angle 1.5000 rad .* outside the stroke"):
        from_mapping({"command_profile": "angle", "command_angles_rad": [1.5]})


def test_plant_fault_numbers_the_first_check_that_fails_and_its_line_is_the_error():
    """plant_fault (which the native FMU compiles) gives k for the k-th check that fails, the
    first in the order written, and 0 for a set that fits; a set at fault k is refused with
    PLANT_FAULTS[k - 1] worded for it."""
    base = Parameters()
    hi = stroke_limits_m(base.a_m, base.b_m)[3]
    faults = {
        1: {"rod_diameter_m": base.piston_diameter_m},
        2: {"support_height_m": base.b_m},
        3: {"cylinder_max_length_m": hi + 0.01},
        4: {"initial_length_m": base.cylinder_max_length_m + 0.01},
        5: {"mode": "paper", "cylinder_max_length_m": hi - 0.02, "initial_length_m": hi + 0.001},
        6: {"supply_pressure_pa": base.tank_pressure_pa},
        7: {"relief_pressure_pa": 0.5 * base.supply_pressure_pa},
        8: {"cavitation_pressure_pa": base.tank_pressure_pa},
        9: {"mode": "paper", "drive": "fixed_pump"},
        10: {"static_friction_n": 0.5 * base.coulomb_friction_n},
        11: {"accumulator_gas_volume_m3": 1e-3, "accumulator_position": "supply"},
        12: {"mode": "paper", "hose_length_m": 0.5},
        13: {"hose_length_m": 2.0},
    }
    assert plant_fault(base) == 0
    assert set(faults) == set(range(1, len(PLANT_FAULTS) + 1))
    for k, values in faults.items():
        unchecked = SimpleNamespace(**{**as_dict(base), **values})
        assert plant_fault(unchecked) == k, values
        with pytest.raises(ConfigError) as said:
            from_mapping(values)
        assert str(said.value) == plant_fault_message(unchecked, k)
    assert plant_fault(SimpleNamespace(**{**as_dict(base), **faults[7], **faults[2]})) == 2
    assert "initial_length_m (" in plant_fault_message(SimpleNamespace(**{**as_dict(base), **faults[4]}), 4)

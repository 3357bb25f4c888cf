"""The node's parameter declarations and checks as a user meets them (``ros2 param describe``,
``ros2 param set``, ``-p NAME:=VALUE``, ``--params-file``, ``boom_sim --help``), called
directly: no node is started, so that each check runs in milliseconds (test_node_parameters.py
meets the same through a running node)."""

from __future__ import annotations

import array
import math
import sys
from typing import Any

import pytest
from conftest import CONFIG

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model.parameters import Parameters, describe

pytest.importorskip("rclpy.parameter")
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter

from boom_hydraulics.ros import node_parameters as np_

#: The node's own numeric parameters: name -> (low, high) as ``ros2 param describe`` and
#: docs/ros-api.md give them.
NODE_RANGES = {
    "publish_rate_hz": (1.0, 1000.0),
    "real_time_factor": (0.0, 1000.0),
    "command_timeout_s": (0.0, 3600.0),
    "max_catch_up_s": (0.001, 10.0),
    "record_chunk_kib": (1.0, 65536.0),
    "record_flush_s": (0.05, 60.0),
}
NODE_FLAGS = ("publish_clock", "jit", "record", "start_paused", "publish_robot_description")
#: What applies at start only (read_only once running), as docs/ros-api.md says.
START_ONLY_NODE = {"publish_clock", "jit", "record", "record_folder", "record_chunk_kib", "record_flush_s"} | {
    "start_paused",
    "publish_robot_description",
}


def _down(x: float) -> float:
    return math.nextafter(x, -math.inf)


def _up(x: float) -> float:
    return math.nextafter(x, math.inf)


# --- the node's own parameters: ranges, types, refusals ---------------------------------------------


@pytest.mark.parametrize("name", sorted(NODE_RANGES))
def test_a_node_number_is_taken_at_either_end_of_its_range_and_refused_one_past_it(name):
    low, high = NODE_RANGES[name]
    for value in (low, high, (low + high) / 2):
        np_.check_node_parameter(name, value)
    for value in (_down(low), _up(high)):
        with pytest.raises(ConfigError) as refused:
            np_.check_node_parameter(name, value)
        assert str(refused.value) == f"parameter '{name}' must be a number in [{low}, {high}], got {value!r}"


def test_an_integer_is_a_number_but_true_text_and_none_are_not():
    np_.check_node_parameter("publish_rate_hz", 50)
    np_.check_node_parameter("real_time_factor", 0)
    for value in (True, "50", None, [50.0]):
        with pytest.raises(ConfigError, match=r"'publish_rate_hz' must be a number in \[1\.0, 1000\.0\], got "):
            np_.check_node_parameter("publish_rate_hz", value)


@pytest.mark.parametrize("name", NODE_FLAGS)
def test_a_node_flag_takes_true_and_false_only(name):
    np_.check_node_parameter(name, True)
    np_.check_node_parameter(name, False)
    for value in (1, 0.0, "true"):
        with pytest.raises(ConfigError) as refused:
            np_.check_node_parameter(name, value)
        assert str(refused.value) == f"parameter '{name}' must be true or false, got {value!r}"


def test_the_record_folder_is_any_text_but_empty():
    for value in ("bags", "/tmp/x", "true"):
        np_.check_node_parameter("record_folder", value)
    for value in ("", 5, None):
        with pytest.raises(ConfigError) as refused:
            np_.check_node_parameter("record_folder", value)
        assert str(refused.value) == f"parameter 'record_folder' must be a non-empty string, got {value!r}"


def test_the_node_parameters_defaults_fit_their_own_checks():
    for name in np_.NODE_PARAMETERS:
        np_.check_node_parameter(name, np_.default(name))
    assert np_.default("publish_rate_hz") == 100.0 and np_.default("record_folder") == "bags"
    assert np_.default("jit") is True and np_.default("publish_clock") is False
    assert np_.default("payload_mass_kg") == 50.0 and np_.default("method") == "rk4"  # the model's, from the schema


# --- descriptors: what ros2 param describe shows -----------------------------------------------------


@pytest.mark.parametrize("name", sorted(NODE_RANGES))
def test_a_node_numbers_descriptor_is_a_double_with_its_range_and_unit(name):
    d = np_.descriptor(name)
    low, high = NODE_RANGES[name]
    assert d.name == name and d.type == ParameterType.PARAMETER_DOUBLE
    (r,) = d.floating_point_range
    assert (r.from_value, r.to_value) == (low, high)
    assert not d.integer_range
    assert d.read_only == (name in START_ONLY_NODE)
    unit = np_.NODE_PARAMETERS[name][1]
    assert d.description.endswith(f" [{unit}]") if unit else "[" not in d.description


def test_node_descriptors_name_units_types_and_start_only():
    rate = np_.descriptor("publish_rate_hz")
    assert rate.description == "State publish (tick) rate [Hz]" and not rate.read_only
    assert rate.additional_constraints == ""
    factor = np_.descriptor("real_time_factor")
    assert factor.description == "Simulated seconds per wall second; 0: as fast as possible"  # no unit, no []
    chunk = np_.descriptor("record_chunk_kib")
    assert chunk.read_only and chunk.description.endswith(" [KiB]")
    assert chunk.additional_constraints == "at start only: set it in a params file or with -p, then restart"
    for name in NODE_FLAGS:
        d = np_.descriptor(name)
        assert d.type == ParameterType.PARAMETER_BOOL and not d.floating_point_range and not d.integer_range
    folder = np_.descriptor("record_folder")
    assert folder.type == ParameterType.PARAMETER_STRING and folder.read_only
    for name in np_.NODE_PARAMETERS:
        assert np_.descriptor(name).read_only == (name in START_ONLY_NODE), name


def test_model_descriptors_give_the_schemas_range_open_ends_and_choices():
    step = np_.descriptor("time_step_s")
    assert step.type == ParameterType.PARAMETER_DOUBLE and step.description.endswith(" [s]")
    (r,) = step.floating_point_range
    assert (r.from_value, r.to_value) == (0.0, 0.1)
    assert step.additional_constraints == "greater than 0"  # rclpy's range is closed; 0 itself is refused
    assert not step.read_only
    payload = np_.descriptor("payload_mass_kg")  # a closed range: no "greater than"
    assert payload.additional_constraints == "" and payload.description.endswith(" [kg]")
    gain = np_.descriptor("ema_backdrive_efficiency")
    assert gain.additional_constraints == "greater than -1" and gain.floating_point_range[0].from_value == -1.0
    substeps = np_.descriptor("substeps")
    assert substeps.type == ParameterType.PARAMETER_INTEGER and not substeps.floating_point_range
    (i,) = substeps.integer_range
    assert (i.from_value, i.to_value, i.step) == (1, 10000, 1)
    method = np_.descriptor("method")
    assert method.type == ParameterType.PARAMETER_STRING and not method.floating_point_range
    assert method.additional_constraints == "one of: euler, rk4, rk45, ros2"
    assert method.description == describe("method")["description"]  # no unit: no "[]"


def test_a_start_only_model_parameter_is_read_only_and_says_so_after_its_other_constraints():
    drive = np_.descriptor("drive")
    assert drive.read_only and "drive" in np_.START_ONLY
    assert drive.additional_constraints == (
        "one of: pressure_compensated, fixed_pump, load_sensing, pump_controlled, electro_mechanical; "
        "at start only: set it in a params file or with -p, then restart"
    )
    hose = np_.descriptor("hose_inner_diameter_m")
    assert hose.read_only and hose.additional_constraints == (
        "greater than 0; at start only: set it in a params file or with -p, then restart"
    )
    assert not np_.descriptor("mode").read_only and "mode" not in np_.START_ONLY


def test_every_declared_parameter_has_a_descriptor_of_its_kind():
    ros_type = {
        "float": ParameterType.PARAMETER_DOUBLE,
        "int": ParameterType.PARAMETER_INTEGER,
        "bool": ParameterType.PARAMETER_BOOL,
        "str": ParameterType.PARAMETER_STRING,
    }
    names = np_.all_names()
    assert names[: len(np_.MODEL_NAMES)] == np_.MODEL_NAMES and names[len(np_.MODEL_NAMES) :] == tuple(
        np_.NODE_PARAMETERS
    )
    for name in names:
        d = np_.descriptor(name)
        value = np_.default(name)
        kind = {float: "float", int: "int", bool: "bool", str: "str"}[type(value)]
        assert d.type == ros_type[kind], name
        if d.floating_point_range:
            (r,) = d.floating_point_range
            assert r.from_value <= value <= r.to_value, name


# --- typing a value given as another type --------------------------------------------------------------


@pytest.mark.parametrize(
    ("given", "value"),
    [
        (Parameter("payload_mass_kg", Parameter.Type.INTEGER, 120), 120.0),
        (Parameter("payload_mass_kg", Parameter.Type.STRING, "2e-05"), 2e-05),
        (Parameter("payload_mass_kg", Parameter.Type.STRING, "1e16"), 1e16),
        (Parameter("publish_rate_hz", Parameter.Type.INTEGER, 50), 50.0),  # a node parameter too
    ],
)
def test_a_number_given_for_a_double_becomes_that_double(given, value):
    typed = np_.typed(given)
    assert (typed.name, typed.type_, typed.value) == (given.name, Parameter.Type.DOUBLE, value)
    assert isinstance(typed.value, float)


@pytest.mark.parametrize(
    ("given", "value"),
    [
        (Parameter("command_values", Parameter.Type.DOUBLE, 0.5), [0.5]),
        (Parameter("command_values", Parameter.Type.INTEGER, 1), [1.0]),
        (Parameter("command_times_s", Parameter.Type.INTEGER_ARRAY, [0, 2]), [0.0, 2.0]),
        (Parameter("command_times_s", Parameter.Type.STRING, "[0, 2.5]"), [0.0, 2.5]),
        (Parameter("command_times_s", Parameter.Type.STRING_ARRAY, ["0", "1e-05"]), [0.0, 1e-05]),
    ],
)
def test_a_number_or_numbers_given_for_a_list_become_a_list_of_doubles(given, value):
    typed = np_.typed(given)
    assert (typed.name, typed.type_) == (given.name, Parameter.Type.DOUBLE_ARRAY)
    assert list(typed.value) == value and all(isinstance(v, float) for v in typed.value)


@pytest.mark.parametrize(
    "given",
    [
        Parameter("payload_mass_kg", Parameter.Type.STRING, "[0,"),  # malformed YAML
        Parameter("payload_mass_kg", Parameter.Type.BOOL, True),
        Parameter("payload_mass_kg", Parameter.Type.DOUBLE_ARRAY, [1.0]),
        Parameter("substeps", Parameter.Type.DOUBLE, 2.0),  # an integer parameter: rclpy refuses the double
        Parameter("method", Parameter.Type.INTEGER, 4),
        Parameter("mode", Parameter.Type.STRING, "[1, 2]"),  # text that reads as numbers, for a text parameter
        Parameter("substeps", Parameter.Type.INTEGER_ARRAY, [1, 2]),
        Parameter("payload_mass_kg", Parameter.Type.INTEGER_ARRAY, [1, 2]),
        Parameter("jit", Parameter.Type.INTEGER, 1),  # a flag: rclpy refuses the integer, not as a double
        Parameter("command_times_s", Parameter.Type.STRING, "[0,"),
        Parameter("command_times_s", Parameter.Type.STRING, "abc"),
        Parameter("command_times_s", Parameter.Type.STRING_ARRAY, ["0", "true"]),
        Parameter("command_times_s", Parameter.Type.BOOL, True),
        Parameter("no_such_parameter", Parameter.Type.INTEGER, 5),
        Parameter("use_sim_time", Parameter.Type.INTEGER, 1),
    ],
    ids=lambda p: f"{p.name}-{p.type_.name}-{p.value}",
)
def test_a_value_that_is_no_number_of_the_kind_is_left_as_given_for_the_checks_to_refuse(given):
    typed = np_.typed(given)
    assert (typed.name, typed.type_, typed.value) == (given.name, given.type_, given.value)


def test_plain_turns_rclpys_arrays_and_tuples_into_lists_and_leaves_the_rest():
    assert np_.plain(array.array("d", [1.0, 2.0])) == [1.0, 2.0]
    assert isinstance(np_.plain((1.0,)), list)
    assert np_.plain(5.0) == 5.0 and np_.plain("x") == "x"


def test_scenario_values_given_as_rclpy_arrays_equal_to_their_defaults_are_not_reported():
    values: dict[str, Any] = {"command_times_s": array.array("d", [0.0]), "command_values": array.array("d", [1.0])}
    assert np_.ignored_scenario(values) == ()
    values["command_values"] = array.array("d", [0.5])
    values["command_offset"] = np_.default("command_offset")
    values["command_frequency_hz"] = np_.default("command_frequency_hz") + 1.0
    assert np_.ignored_scenario(values) == ("command_values", "command_frequency_hz")  # in the schema's order


# --- names: unknown, standard, undeclared ------------------------------------------------------------------


def test_an_unknown_key_is_refused_naming_the_closest_or_none():
    with pytest.raises(ConfigError) as typo:
        np_.check_known(["payload_mass_kgg"], argv=["boom_sim"])
    assert str(typo.value) == (
        "unknown parameter 'payload_mass_kgg' for boom_sim; did you mean 'payload_mass_kg'? "
        "(boom_sim --help lists them)"
    )
    with pytest.raises(ConfigError) as nothing_close:
        np_.check_known(["zz"], argv=["boom_sim"])
    assert str(nothing_close.value) == "unknown parameter 'zz' for boom_sim (boom_sim --help lists them)"


def test_every_key_is_checked_not_only_those_before_the_first_known_one():
    for names in (["payload_mass_kg", "payload_mass_kgg"], ["use_sim_time", "zz"], ["command_value", "zz"]):
        with pytest.raises(ConfigError, match=f"unknown parameter '{names[1]}'"):
            np_.check_known(names, argv=["boom_sim"])


def test_rclpys_own_parameters_and_qos_overrides_are_known():
    np_.check_known(
        ["use_sim_time", "start_type_description_service", "qos_overrides./drive_state.publisher.depth", "jit"],
        argv=["boom_sim"],
    )
    with pytest.raises(ConfigError, match=r"unknown parameter 'qos_override\.x'"):
        np_.check_known(["qos_override.x"], argv=["boom_sim"])


def test_the_overrides_are_checked_against_the_command_line_rclpy_read_by_default(monkeypatch):
    """check_known given rclpy's overrides and no argv reads sys.argv, as rclpy.init() does."""
    monkeypatch.setattr(sys, "argv", ["boom_sim", "--ros-args", "-p", "payload_mass_kg:=abc"])
    overrides = {"payload_mass_kg": Parameter("payload_mass_kg", value=50.0)}
    with pytest.raises(ConfigError, match="-p payload_mass_kg:=abc would not be used"):
        np_.check_known(overrides)
    np_.check_known(["payload_mass_kg"])  # names alone: nothing to compare with the command line
    np_.check_known(overrides, argv=["boom_sim"])  # an argv given is the one read


def test_a_set_of_a_name_the_node_does_not_declare_is_refused_with_the_closest():
    for name in ("payload_mass_kg", "publish_rate_hz", "use_sim_time", "qos_overrides./x.depth"):
        assert np_.undeclared(name) is None, name
    assert np_.undeclared("payload_mass_kgg") == (
        "boom_sim has no parameter 'payload_mass_kgg'; did you mean 'payload_mass_kg'? (boom_sim --help lists them)"
    )
    assert np_.undeclared("zz") == "boom_sim has no parameter 'zz' (boom_sim --help lists them)"
    assert np_.undeclared("command_offset") == (
        "boom_sim has no parameter 'command_offset': the command_* parameters are boom-sim's headless scenario, "
        "and the node takes its commands from topics"
    )  # no declared name is close to it
    reason = np_.undeclared("command_timeout")
    assert reason is not None and reason.endswith("(boom_sim --help lists them)")
    assert "did you mean 'command_timeout_s'?" in reason
    scenario = np_.undeclared("command_values")
    assert scenario is not None and "headless scenario" in scenario and "(boom_sim --help" not in scenario


# --- the command line: -p, --params-file, --help ---------------------------------------------------------


def test_the_p_values_for_this_node_are_read_with_their_position_and_text():
    args = [
        "boom_sim",
        "-p",
        "before_ros_args:=1",
        "--ros-args",
        "-p",
        "a:=1",
        "--param",
        "b:=x:=y",
        "-p",
        "boom_sim:c:=2",
        "-p",
        "/ns/boom_sim:d:=3",
        "-p",
        "**:e:=4",
        "-p",
        "*:f:=5",
        "-p",
        "other:g:=6",
        "-p",
        "/ns/other:h:=7",
        "-p",
        "no_assignment",
        "-r",
        "__ns:=/ns",
        "--",
        "-p",
        "after:=8",
        "--ros-args",
        "-p",
        "i:=",
        "-p",
    ]
    assert np_.assignments(args) == [
        (4, "a", "1"),
        (6, "b", "x:=y"),
        (8, "c", "2"),
        (10, "d", "3"),
        (12, "e", "4"),
        (14, "f", "5"),
        (28, "i", ""),
    ]
    assert [name for _, name, _ in np_.assignments(args, node_name="other")] == ["a", "b", "e", "f", "g", "h", "i"]


def test_a_long_command_line_ending_in_a_dangling_p_or_params_file_is_read_up_to_it():
    """A launch file may pass hundreds of -p: the last -p (or --params-file) without its value is left alone."""
    args = ["boom_sim", "--ros-args"]
    for k in range(150):
        args += ["-p", f"x{k}:=1"]
    assert len(np_.assignments([*args, "-p"])) == 150
    assert np_.params_files([*args, "--params-file"]) == []
    assert np_.params_files([*args, "--params-file", "a.yaml"]) == ["a.yaml"]


def test_a_refusal_naming_a_p_parameter_leads_with_what_the_user_typed():
    args = ["boom_sim", "--ros-args", "-p", "payload_mass_kg:=1", "-p", "jit:=maybe", "-p", "payload_mass_kg:=-5"]
    message = "parameter 'payload_mass_kg' must be at least 0"
    assert np_.on_command_line(message, args) == f"-p payload_mass_kg:=-5: {message}"  # the last one given
    assert np_.on_command_line("parameter 'jit' must be true or false", args) == (
        "-p jit:=maybe: parameter 'jit' must be true or false"
    )
    assert np_.on_command_line("parameter 'substeps' must be an integer", args) == (
        "parameter 'substeps' must be an integer"  # not given by -p: as it was
    )
    already = "-p payload_mass_kg:=-5 would not be used: ..."
    assert np_.on_command_line(already, args) == already  # it names the -p already
    assert np_.on_command_line("payload_mass_kg is bad", args) == "payload_mass_kg is bad"  # a name unquoted


def test_the_ros_arguments_are_not_the_users_and_the_params_files_are_read_from_them():
    args = [
        "boom_sim",
        "--help",
        "--params-file",
        "not_ros.yaml",
        "--ros-args",
        "--params-file",
        "a.yaml",
        "-p",
        "x:=1",
        "--",
        "-v",
        "--params-file",
        "b.yaml",
        "--ros-args",
        "--params-file",
        "c.yaml",
        "--params-file",
    ]
    assert np_.user_args(args) == [
        "boom_sim",
        "--help",
        "--params-file",
        "not_ros.yaml",
        "-v",
        "--params-file",
        "b.yaml",
    ]
    assert np_.params_files(args) == ["a.yaml", "c.yaml"]
    assert np_.user_args(["boom_sim", "--", "x"]) == ["boom_sim", "--", "x"]  # a -- outside --ros-args is the user's


def test_a_wildcard_p_and_a_param_stay_ros_arguments():
    """``-p '**:use_sim_time:=true'`` (ROS's any-node form) and ``--param NAME:=VALUE`` are ROS
    arguments like any other: neither ends the section nor names a params file."""
    args = [
        "boom_sim",
        "--ros-args",
        "-p",
        "**:use_sim_time:=true",
        "--param",
        "x:=1",
        "--help",
        "--params-file",
        "a.yaml",
    ]
    assert np_.user_args(args) == ["boom_sim"]
    assert np_.params_files(args) == ["a.yaml"]
    assert np_.params_files(["boom_sim", "--ros-args", "-p", "*:x:=1", "--params-file", "b.yaml"]) == ["b.yaml"]


def test_a_params_file_that_is_missing_or_not_ros_params_is_named_in_one_line(tmp_path):
    np_.check_params_file(str(CONFIG / "default.yaml"))
    missing = tmp_path / "missing.yaml"
    with pytest.raises(ConfigError) as refused:
        np_.check_params_file(str(missing))
    assert str(refused.value) == f"--params-file {missing}: no such file"
    expected = ": expected '/**: ros__parameters: {name: value, ...}' per node"
    for text in ("- 1\n", "/**:\n  payload_mass_kg: 1.0\n", "/**:\n  ros__parameters: 5\n", "/**: 5\n"):
        path = tmp_path / "bad.yaml"
        path.write_text(text)
        with pytest.raises(ConfigError) as refused:
            np_.check_params_file(str(path))
        assert str(refused.value) == f"--params-file {path}{expected}", text
    both = tmp_path / "two_nodes.yaml"
    both.write_text("/**:\n  ros__parameters: {a: 1}\nother:\n  ros__parameters: {b: 2}\n")
    np_.check_params_file(str(both))


def test_help_marks_the_start_only_parameters_and_lists_each_with_its_default_and_unit():
    lines = np_.usage().splitlines()
    assert lines[0].startswith("usage: boom_sim [--ros-args")
    heading = "Node parameters (* = at start only; read_only once running):"
    node = lines[lines.index(heading) + 1 : lines.index(heading) + 1 + len(np_.NODE_PARAMETERS)]
    starred = {line.split()[1] for line in node if line.startswith("  * ")}
    assert starred == START_ONLY_NODE  # the node's own: the model's start-only ones are in the reference
    # the columns line up: name, default, unit, description
    name_width = max(map(len, np_.NODE_PARAMETERS))  # publish_robot_description's, the longest
    assert name_width == 25
    assert node[0] == "    " + "publish_rate_hz".ljust(25) + " 100.0      Hz    State publish (tick) rate"
    assert (
        node[8]
        == "  * " + "record_chunk_kib".ljust(25) + " 1024.0     KiB   MCAP chunk size: the most a SIGKILL can lose"
    )
    assert node[2].startswith("  * " + "publish_clock".ljust(25) + " False            Publish /clock")
    assert {line[4 + name_width] for line in node} == {" "} and all(line[5 + name_width] != " " for line in node)
    model_heading = "Model parameters (config/default.yaml lists them; ros2 param describe gives ranges):"
    model = lines[lines.index(model_heading) + 1 :]
    model = model[: model.index("")]
    assert [line.split()[0] for line in model] == list(np_.MODEL_NAMES)
    payload = next(line for line in model if line.split()[0] == "payload_mass_kg")
    assert payload.split() == ["payload_mass_kg", "50.0", "kg"]
    width = max(map(len, np_.MODEL_NAMES))
    assert {line.index(line.split()[1], 4 + len(line.split()[0])) for line in model} == {4 + width + 1}
    unit_columns = {len(line) - len(describe(n)["unit"]) for line, n in zip(model, np_.MODEL_NAMES)}
    assert len(unit_columns) == 1  # the units too, after the widest default
    assert lines[-1] == "the node takes its valve commands from topics and ignores them."


# --- -p values rcl would not use -----------------------------------------------------------------------------


def _overrides(**values: Any) -> dict[str, Parameter]:
    return {name: Parameter(name, value=value) for name, value in values.items()}


def test_an_integer_after_a_params_files_double_is_what_rcl_keeps_and_passes():
    np_.check_overrides(_overrides(payload_mass_kg=60), ["boom_sim", "--ros-args", "-p", "payload_mass_kg:=60"])


def test_each_p_name_is_checked_and_counted_on_its_own():
    """A -p of a name rclpy did not hand over (another node's, a ROS argument) does not stop the
    check of the next; other names' -p do not count as this one's."""
    argv = ["boom_sim", "--ros-args", "-p", "a_m:=0.4", "-p", "boom_mass_kg:=90.0", "-p", "publish_rate_hz:=50.0"]
    argv += ["-p", "payload_mass_kg:=60.0"]
    overrides = _overrides(boom_mass_kg=90.0, publish_rate_hz=50.0, payload_mass_kg=60)
    with pytest.raises(ConfigError) as refused:
        np_.check_overrides(overrides, argv)
    assert "-p payload_mass_kg:=60.0 would not be used: a params file gives it before, and rcl keeps 60" in str(
        refused.value
    )


def test_a_params_file_after_the_ros_arguments_is_not_read_by_rcl_and_excuses_no_p(tmp_path):
    """``--ros-args -p x:=50.0 -p x:=abc -- --params-file f.yaml``: the file is the program's
    argument; rcl keeps 50.0, and the -p abc is refused (it was let through, and the node ran on 50.0)."""
    argv = ["boom_sim", "--ros-args", "-p", "payload_mass_kg:=50.0", "-p", "payload_mass_kg:=abc", "--"]
    with pytest.raises(ConfigError, match=r"-p payload_mass_kg:=abc would not be used: it is given 2 times"):
        np_.check_known(_overrides(payload_mass_kg=50.0), argv=[*argv, "--params-file", str(CONFIG / "default.yaml")])
    sets_payload = _params_file(tmp_path, "a.yaml", "/**:\n  ros__parameters:\n    payload_mass_kg: 50.0\n")
    with pytest.raises(ConfigError, match=r"-p payload_mass_kg:=abc would not be used"):
        np_.check_overrides(_overrides(payload_mass_kg=50.0), [*argv, "-v", sets_payload])


def test_a_p_double_that_rcl_kept_as_an_integer_is_refused_saying_a_params_file_gave_one_before():
    with pytest.raises(ConfigError) as refused:
        np_.check_overrides(_overrides(payload_mass_kg=60), ["boom_sim", "--ros-args", "-p", "payload_mass_kg:=60.0"])
    assert str(refused.value) == (
        "-p payload_mass_kg:=60.0 would not be used: a params file gives it before, and rcl keeps 60, an earlier "
        "value of another type; give payload_mass_kg once, as a number"
    )


@pytest.mark.parametrize(
    ("name", "kept", "text", "expected"),
    [
        ("substeps", 2, "abc", "an integer"),
        ("jit", True, "1", "true or false"),
        ("use_sim_time", False, "0", "true or false"),
        ("record_folder", "bags", "5", "text"),
        ("mode", "paper", "5", "text"),
        ("command_values", [1.0], "1", "a list of numbers"),
        ("qos_overrides./x.depth", 5, "abc", "one value"),
    ],
)
def test_a_refused_p_value_says_what_to_give_by_the_parameters_kind(name, kept, text, expected):
    argv = ["boom_sim", "--ros-args", "-p", f"{name}:=0.5", "-p", f"{name}:={text}"]
    with pytest.raises(ConfigError) as refused:
        np_.check_overrides(_overrides(**{name: kept}), argv)
    assert str(refused.value).startswith(f"-p {name}:={text} would not be used: it is given 2 times, and rcl keeps ")
    assert str(refused.value).endswith(f"; give {name} once, as {expected}")


def test_values_rcl_keeps_as_given_pass_nan_lists_and_empty_text_included():
    np_.check_overrides(_overrides(payload_mass_kg=math.nan), ["boom_sim", "--ros-args", "-p", "payload_mass_kg:=.nan"])
    argv = ["boom_sim", "--ros-args", "-p", "command_values:=[0.5, 1.0]"]
    np_.check_overrides({"command_values": Parameter("command_values", value=array.array("d", [0.5, 1.0]))}, argv)
    np_.check_overrides(_overrides(record_folder=""), ["boom_sim", "--ros-args", "-p", "record_folder:="])
    np_.check_overrides(_overrides(record_folder="[x"), ["boom_sim", "--ros-args", "-p", "record_folder:=[x"])
    np_.check_overrides({}, ["boom_sim", "--ros-args", "-p", "payload_mass_kg:=abc"])  # rclpy read none: nothing


def test_a_list_of_integers_where_rcl_kept_doubles_is_refused():
    argv = ["boom_sim", "--ros-args", "-p", "command_values:=[1, 0]"]
    with pytest.raises(ConfigError, match=r"rcl keeps \[1\.0, 0\.0\].*as a list of numbers"):
        np_.check_overrides({"command_values": Parameter("command_values", value=array.array("d", [1.0, 0.0]))}, argv)
    with pytest.raises(ConfigError, match=r"rcl keeps nan"):  # a NaN kept where a number was meant
        np_.check_overrides(
            _overrides(payload_mass_kg=math.nan), ["boom_sim", "--ros-args", "-p", "payload_mass_kg:=1.0"]
        )


def _params_file(tmp_path, name: str, text: str) -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def test_a_params_file_after_the_last_p_of_a_name_has_the_last_word_on_that_name_only(tmp_path):
    sets_payload = _params_file(tmp_path, "a.yaml", "boom_sim:\n  ros__parameters:\n    payload_mass_kg: 50.0\n")
    nested = _params_file(tmp_path, "n.yaml", "/**:\n  ros__parameters:\n    qos_overrides:\n      x: {depth: 5}\n")
    other = _params_file(tmp_path, "b.yaml", "/**:\n  ros__parameters:\n    boom_mass_kg: 90.0\n")
    overrides = _overrides(payload_mass_kg=50.0, **{"qos_overrides.x.depth": 5})
    p = ["-p", "payload_mass_kg:=abc"]
    np_.check_overrides(overrides, ["boom_sim", "--ros-args", *p, "--params-file", sets_payload])
    np_.check_overrides(
        overrides, ["boom_sim", "--ros-args", "-p", "qos_overrides.x.depth:=abc", "--params-file", nested]
    )
    for argv in (
        ["boom_sim", "--ros-args", "--params-file", sets_payload, *p],  # the file before: the -p is checked
        ["boom_sim", "--ros-args", *p, "--params-file", other],  # a file after that does not set it
        ["boom_sim", "--ros-args", *p, "--params-file", str(tmp_path / "missing.yaml")],
        ["boom_sim", "--ros-args", *p, "--params-file", _params_file(tmp_path, "l.yaml", "- 1\n")],
        ["boom_sim", "--ros-args", *p, "--params-file", _params_file(tmp_path, "s.yaml", "/**: 5\n")],
        [
            "boom_sim",
            "--ros-args",
            *p,
            "--params-file",
            _params_file(tmp_path, "r.yaml", "/**:\n  ros__parameters: 5\n"),
        ],
    ):
        with pytest.raises(ConfigError, match="-p payload_mass_kg:=abc would not be used"):
            np_.check_overrides(overrides, argv)


# --- the model parameters the node cannot step ------------------------------------------------------------


def test_the_finest_time_step_the_node_takes_is_a_nanosecond():
    np_.check_node_model(Parameters(time_step_s=1e-9))
    np_.check_node_model(Parameters())
    fine = _down(1e-9)
    with pytest.raises(ConfigError) as refused:
        np_.check_node_model(Parameters(time_step_s=fine))
    assert str(refused.value) == (
        f"parameter 'time_step_s' is {fine:g} s; boom_sim steps in real time and takes a step of at least 1e-09 s "
        f"({1 / fine:.3g} steps per simulated second could not be counted); boom-sim run takes finer ones"
    )


# --- the reference table -----------------------------------------------------------------------------------------


def test_the_reference_gives_each_kind_of_range():
    rows = np_.markdown_reference().splitlines()
    cells = {row.split(" | ")[0].strip("| `"): row.split(" | ") for row in rows[2:]}
    assert cells["publish_rate_hz"][1:7] == ["node", "float", "`100.0`", "Hz", "[1, 1000]", ""]
    assert cells["max_catch_up_s"][5] == "[0.001, 10]"
    assert cells["jit"][2:7] == ["bool", "`true`", "", "", "yes"]
    assert cells["substeps"][2:7] == ["int", "`1`", "", "[1, 10000]", ""]
    assert cells["drive"][5:7] == [
        "one of: pressure_compensated, fixed_pump, load_sensing, pump_controlled, electro_mechanical",
        "yes",
    ]
    assert cells["ema_backdrive_efficiency"][5] == "(-1, 1]"
    assert cells["command_values"][1:6] == ["scenario", "list", "`[1.0]`", "", "[-1, 1]"]
    assert cells["command_profile"][5].startswith("one of: ")


# --- the descriptors as rclpy enforces them (one node in-process, never spun) -----------------------------


@pytest.fixture(scope="module")
def declared(ros_context) -> Any:
    """A bare rclpy node with every parameter boom_sim declares, as it declares them."""
    from rclpy.node import Node

    node = Node("node_parameter_checks", automatically_declare_parameters_from_overrides=False)
    for name in np_.all_names():
        node.declare_parameter(name, np_.default(name), np_.descriptor(name))
    yield node
    node.destroy_node()


def _set(node: Any, name: str, value: Any) -> tuple[bool, str]:
    (result,) = node.set_parameters([Parameter(name, value=value)])
    return result.successful, result.reason


def _read_only(name: str) -> tuple[bool, str]:
    return False, f"Trying to set a read-only parameter: {name}."


@pytest.mark.parametrize("name", sorted(NODE_RANGES))
def test_rclpy_takes_a_node_number_at_its_limits_and_refuses_one_well_past_them(declared, name):
    """(rclpy allows a relative 1e-6 past a limit: check_node_parameter, above, refuses that)"""
    low, high = NODE_RANGES[name]
    if name in START_ONLY_NODE:
        assert _set(declared, name, high) == _read_only(name)
        return
    for value in (low, high):
        assert _set(declared, name, value) == (True, ""), (name, value)
    for value in (low - 0.01 * (high - low), high * 1.01):
        expected = f"Parameter {name} out of range Min: {low}, Max: {high}, value: {value}"
        assert _set(declared, name, value) == (False, expected)


def test_rclpy_refuses_every_start_only_parameter_at_run_time_and_sets_the_others(declared):
    for name in np_.all_names():
        if name in np_.START_ONLY:
            assert _set(declared, name, np_.default(name)) == _read_only(name)
        else:
            assert _set(declared, name, np_.default(name)) == (True, ""), name
    assert {"drive", "valve_centre", "accumulator_gas_volume_m3", "hose_length_m"} <= np_.START_ONLY
    assert not np_.START_ONLY & {"payload_mass_kg", "method", "mode", "publish_rate_hz", "time_step_s"}


def test_rclpy_takes_an_integer_parameter_at_its_limits_only(declared):
    assert _set(declared, "substeps", 10000) == (True, "")
    assert _set(declared, "substeps", 1) == (True, "")
    for value in (0, 10001):
        assert _set(declared, "substeps", value) == (
            False,
            f"Parameter substeps out of range. Min: 1, Max: 10000, value: {value}",
        )

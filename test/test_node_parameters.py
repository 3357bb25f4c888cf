"""The node's parameters as a ROS user meets them: params files, set, describe, dump and load."""

from __future__ import annotations

import signal
import subprocess
from collections.abc import Iterator

import pytest
from conftest import BOOM_SIM, CONFIG, start_node

rclpy = pytest.importorskip("rclpy")
import yaml  # noqa: E402
from rcl_interfaces.msg import ParameterType  # noqa: E402
from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters, SetParameters  # noqa: E402
from rclpy.parameter import Parameter, parameter_dict_from_yaml_file, parameter_value_to_python  # noqa: E402
from ros_client import Client  # noqa: E402

from boom_hydraulics.model import config  # noqa: E402
from boom_hydraulics.ros.node_parameters import SCENARIO, START_ONLY  # noqa: E402

pytestmark = [
    pytest.mark.usefixtures("ros_context"),
    pytest.mark.skipif(BOOM_SIM is None, reason="boom_sim not on PATH (run through tools/with-env)"),
]
NODE = "/crane1/boom_sim"


@pytest.fixture(scope="module")
def crane1(ros_context) -> Iterator[Client]:
    """A namespaced node started from a shipped params file (paper mode, fig. 8)."""
    # an integer for a float, on the command line, after a double (rcl keeps the integer: the last, as meant)
    payload = ("payload_mass_kg:=55.0", "payload_mass_kg:=60")
    proc = start_node(*payload, config_file="paper_fig8.yaml", ros_args=("-r", "__ns:=/crane1"))
    client = Client(NODE, namespace="/crane1")
    client.describe = client.node.create_client(DescribeParameters, f"{NODE}/describe_parameters")
    client.list = client.node.create_client(ListParameters, f"{NODE}/list_parameters")
    try:
        assert client.spin_until(lambda: len(client.states) > 3, timeout=30), "no state from /crane1/drive_state"
        yield client
    finally:
        client.node.destroy_node()
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=20)


def _get(client: Client, *names: str) -> list:
    return client.call(client.get_params, GetParameters.Request(names=list(names))).values


def _set(client: Client, *params: Parameter):
    request = SetParameters.Request(parameters=[p.to_parameter_msg() for p in params])
    return client.call(client.set_params, request).results


def test_a_namespaced_node_takes_the_shipped_params_file(crane1):
    mode, diameter, payload = _get(crane1, "mode", "piston_diameter_m", "payload_mass_kg")
    assert (mode.string_value, diameter.double_value) == ("paper", 0.04)
    assert (payload.type, payload.double_value) == (ParameterType.PARAMETER_DOUBLE, 60.0)  # -p 60 stays a double


def test_integers_for_floats_stay_doubles(crane1):
    (result,) = _set(crane1, Parameter("payload_mass_kg", Parameter.Type.INTEGER, 120))
    assert result.successful, result.reason
    (value,) = _get(crane1, "payload_mass_kg")
    assert (value.type, value.double_value) == (ParameterType.PARAMETER_DOUBLE, 120.0)


def test_the_node_declares_no_scenario_parameter(crane1):
    """The command_* keys are boom-sim's headless scenario: the node, which takes its commands
    from topics, lists none, and a set of one is refused naming it and why (rclpy's own reason
    was 'Invalid access to undeclared parameter(s): []')."""
    names = crane1.call(crane1.list, ListParameters.Request()).result.names
    assert "payload_mass_kg" in names and "control_position_gain_1_rad" in names and "method" in names
    assert not [name for name in names if name in SCENARIO]
    (result,) = _set(crane1, Parameter("command_values", Parameter.Type.DOUBLE_ARRAY, [0.5]))
    assert not result.successful
    assert "no parameter 'command_values'" in result.reason and "headless scenario" in result.reason, result.reason
    assert "did you mean '" in result.reason


def test_a_name_the_node_does_not_have_is_refused_naming_the_closest(crane1):
    """``ros2 param set /crane1/boom_sim payload_mass_kgg 80.0``: one reason that names the
    typo and the parameter meant; nothing else in the request is set."""
    request = SetParameters.Request(
        parameters=[
            Parameter("payload_mass_kgg", Parameter.Type.DOUBLE, 80.0).to_parameter_msg(),
        ]
    )
    (result,) = crane1.call(crane1.set_params, request).results
    assert not result.successful
    assert "no parameter 'payload_mass_kgg'; did you mean 'payload_mass_kg'?" in result.reason, result.reason
    (rate,) = _get(crane1, "publish_rate_hz")  # (the refusal's stand-in inside the node is not set either)
    assert rate.double_value == 100.0


def test_a_time_step_the_node_cannot_count_is_refused_at_run_time(crane1):
    """A SetParameters of time_step_s 1e-20 s (inside its documented range) was accepted, then
    stopped the simulation with an OverflowError: now refused, naming the parameter, and the
    node steps on."""
    (result,) = _set(crane1, Parameter("time_step_s", Parameter.Type.DOUBLE, 1e-20))
    assert not result.successful and "'time_step_s' is 1e-20 s" in result.reason, result.reason
    (step,) = _get(crane1, "time_step_s")
    assert step.double_value == 0.001
    count = len(crane1.states)
    assert crane1.spin_until(lambda: len(crane1.states) > count + 5, timeout=30), "the node stopped stepping"


def test_absurd_and_start_only_values_are_refused_with_the_reason(crane1):
    (absurd,) = _set(crane1, Parameter("payload_mass_kg", Parameter.Type.DOUBLE, 1e300))
    assert not absurd.successful and "payload_mass_kg" in absurd.reason
    (clock,) = _set(crane1, Parameter("publish_clock", Parameter.Type.BOOL, True))
    assert not clock.successful and "read-only" in clock.reason
    described = crane1.call(
        crane1.describe, DescribeParameters.Request(names=["piston_diameter_m", "publish_clock", "record_folder"])
    ).descriptors
    diameter, clock_desc, folder = described
    assert diameter.type == ParameterType.PARAMETER_DOUBLE and not diameter.read_only
    assert (diameter.floating_point_range[0].from_value, diameter.floating_point_range[0].to_value) == (0.0, 1.0)
    assert "[m]" in diameter.description
    assert clock_desc.read_only and folder.read_only and "at start only" in folder.additional_constraints


def _load_file(client: Client, path) -> tuple[list[Parameter], list]:
    """What ``ros2 param load`` does: rclpy's parameter_dict_from_yaml_file, then a set of each."""
    messages = parameter_dict_from_yaml_file(str(path), use_wildcard=True)
    loaded = [Parameter.from_parameter_msg(m) for m in messages.values()]
    return loaded, _set(client, *loaded)


def test_the_nodes_own_dump_loads_back_apart_from_read_only_ones(crane1, tmp_path):
    """``ros2 param dump`` then ``ros2 param load``: the dump is yaml.dump of every value; the load
    reads it back through rclpy (whose str() round trip makes 1e-06 the text '1e-06')."""
    names = crane1.call(crane1.list, ListParameters.Request()).result.names
    dump = {name: parameter_value_to_python(v) for name, v in zip(names, _get(crane1, *names))}
    dump = {name: list(v) if hasattr(v, "tolist") else v for name, v in dump.items()}
    assert dump["rtol"] == 1e-6  # one of the doubles a naive load gets back as text
    path = tmp_path / "dump.yaml"
    path.write_text(yaml.dump({NODE: {"ros__parameters": dump}}, default_flow_style=False))
    loaded, results = _load_file(crane1, path)
    failed = {p.name for p, r in zip(loaded, results) if not r.successful}
    assert failed == set(START_ONLY) | {"start_type_description_service"}  # rclpy refuses read-only ones
    assert all("read-only" in r.reason for r in results if not r.successful)
    values = _get(crane1, "rtol", "atol_scale", "valve_leakage_m3_s_pa", "load_holding_leakage_m3_s_pa")
    assert all(v.type == ParameterType.PARAMETER_DOUBLE for v in values)
    assert [v.double_value for v in values] == [dump[n] for n in ("rtol", "atol_scale")] + [
        dump["valve_leakage_m3_s_pa"],
        dump["load_holding_leakage_m3_s_pa"],
    ]


@pytest.mark.parametrize("name", ["paper_fig9.yaml", "default.yaml", "paper_fig8.yaml"])
def test_a_shipped_params_file_loads_into_the_running_node(crane1, name):
    """``ros2 param load /crane1/boom_sim config/NAME``: every value the node declares, as rclpy
    reads the file; the file's scenario (command_*, for boom-sim) is refused as undeclared, and
    its start-only values (``drive``) as read-only."""
    loaded, results = _load_file(crane1, CONFIG / name)
    failed = [(p.name, r.reason) for p, r in zip(loaded, results) if not r.successful]
    assert {n for n, _ in failed} == {p.name for p in loaded if p.name in SCENARIO or p.name in START_ONLY}, failed
    assert all(("headless scenario" if n in SCENARIO else "read-only") in reason for n, reason in failed), failed
    expected = {n: v for n, v in config.read_values(CONFIG / name).items() if n not in SCENARIO}
    got = _get(crane1, *expected)
    assert {n: parameter_value_to_python(v) for n, v in zip(expected, got)} == expected


@pytest.mark.parametrize(
    ("params_file", "extra", "message"),
    [
        ("/**:\n  ros__parameters:\n    payload_mass_kgg: 80.0\n", [], "unknown parameter 'payload_mass_kgg'"),
        (None, ["-p", "publish_rate:=50.0"], "did you mean 'publish_rate_hz'?"),
        ("/**:\n  ros__parameters:\n    a_m: [0.4\n", [], "malformed YAML at line"),
        ("MISSING", [], "no such file"),
        (None, ["-p", "payload_mass_kg:=1e300"], "'payload_mass_kg'"),
        (None, ["-p", "payload_mass_kg:=50.0", "-p", "payload_mass_kg:=abc"], "payload_mass_kg:=abc would not be used"),
        ("/**:\n  ros__parameters:\n    rtol: 1.0e-06\n", ["-p", "rtol:=tight"], "rtol:=tight would not be used"),
        # a --params-file after -- is the program's argument, which rcl does not read: it cannot excuse the -p
        (
            None,
            [
                "-p",
                "payload_mass_kg:=50.0",
                "-p",
                "payload_mass_kg:=abc",
                "--",
                "--params-file",
                str(CONFIG / "default.yaml"),
            ],
            "payload_mass_kg:=abc would not be used",
        ),
        ("/**:\n  ros__parameters:\n    command_value: 1.5\n", [], "'command_value' is 1.5"),  # checked, if ignored
        # a step too fine to count: one line, not a traceback (1e-20 s is inside the model's range)
        (None, ["-p", "time_step_s:=1.0e-20"], "-p time_step_s:=1.0e-20: parameter 'time_step_s' is 1e-20 s"),
        (None, ["-p", "time_step_s:=1.0e-300"], "at least 1e-09 s"),
        # no params file was given: the -p is named, not a params file
        (None, ["-p", "payload_mass_kg:=.nan"], "-p payload_mass_kg:=.nan: parameter 'payload_mass_kg' must be finite"),
    ],
)
def test_a_bad_start_is_one_line_and_exit_2(tmp_path, params_file, extra, message):
    args = [BOOM_SIM, "--ros-args", "-p", "record:=false"]
    if params_file == "MISSING":
        args += ["--params-file", str(tmp_path / "missing.yaml")]
    elif params_file:
        (tmp_path / "p.yaml").write_text(params_file)
        args += ["--params-file", str(tmp_path / "p.yaml")]
    args += extra  # after the file: a -p has the last word
    result = subprocess.run(args, capture_output=True, text=True, timeout=60)
    lines = (result.stdout + result.stderr).strip().splitlines()
    assert result.returncode == 2, lines
    assert len(lines) == 1 and lines[0].startswith("boom_sim: error:") and message in lines[0], lines
    if "kgg" in message:
        assert "did you mean 'payload_mass_kg'?" in lines[0]


def test_a_params_file_with_a_scenario_starts_the_node_which_says_once_it_ignores_it(tmp_path):
    """The command_* keys are boom-sim's: the node starts, declares none of them, and says so once."""
    path = tmp_path / "scenario.yaml"
    path.write_text("/**:\n  ros__parameters:\n    command_profile: steps\n    command_times_s: [0, 2]\n"
                    "    command_values: [1.0, 0.0]\n    payload_mass_kg: 60\n")  # fmt: skip
    args = [BOOM_SIM, "--ros-args", "--params-file", str(path), "-p", "record:=false"]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    try:
        for line in proc.stdout:  # up to the start-up line that names the mode (or the end of the output)
            lines.append(line)
            if "physical mode, rk4" in line:
                break
    finally:
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=20)
    assert "physical mode, rk4" in lines[-1], [*lines, rest]
    assert sum("describe boom-sim's headless scenario" in line for line in lines + rest.splitlines()) == 1

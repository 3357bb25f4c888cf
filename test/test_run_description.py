"""The run description a bag carries: the node's and boom-resim's custom data, one type."""

from __future__ import annotations

import pytest
import yaml

from boom_hydraulics.bags.recording import run_description
from boom_hydraulics.bags.run_description import RunDescription
from boom_hydraulics.model.parameters import as_dict, from_mapping

#: Custom data as the node wrote them before the type existed (keys, order and texts).
RECORDED = {
    "parameters": "mode: physical\ntime_step_s: 0.0005\npayload_mass_kg: 150.0\n",
    "clock_origin_ns": "1764614400123456789",
    "publish_rate_hz": "100.0",
    "command_timeout_s": "0.5",
    "node": "/crane1/boom_sim",
}


def test_recorded_custom_data_read_back_and_written_unchanged():
    description = RunDescription.from_custom_data(RECORDED)
    assert description.parameters == {"mode": "physical", "time_step_s": 0.0005, "payload_mass_kg": 150.0}
    assert description.clock_origin_ns == 1764614400123456789 and description.node == "/crane1/boom_sim"
    assert (description.publish_rate_hz, description.command_timeout_s, description.resimulated_from) == (
        100.0,
        0.5,
        None,
    )
    assert description.to_custom_data() == RECORDED
    assert list(description.to_custom_data()) == list(RECORDED)


def test_the_nodes_description_holds_every_parameter_in_the_schemas_order():
    params = from_mapping({"payload_mass_kg": 80.0})
    custom = run_description(params, 0, 50.0, 0.25, node="/boom_sim")
    assert list(custom) == ["parameters", "clock_origin_ns", "publish_rate_hz", "command_timeout_s", "node"]
    assert custom["parameters"] == yaml.safe_dump(as_dict(params), sort_keys=False)
    assert (custom["clock_origin_ns"], custom["publish_rate_hz"], custom["command_timeout_s"]) == ("0", "50.0", "0.25")
    resimulated = RunDescription.of(params, 0, 50.0, 0.25, resimulated_from="bags/run").to_custom_data()
    assert resimulated["resimulated_from"] == "bags/run" and "node" not in resimulated


@pytest.mark.parametrize(
    ("change", "error"),
    [
        ({"publish_rate_hz": None}, KeyError),
        ({"clock_origin_ns": "soon"}, ValueError),
        ({"parameters": "a: [1"}, yaml.YAMLError),
    ],
)
def test_an_unreadable_description_raises_what_boom_resim_reports(change, error):
    custom = {k: v for k, v in {**RECORDED, **change}.items() if v is not None}
    with pytest.raises(error):
        RunDescription.from_custom_data(custom)


def test_the_time_origin_alone_is_read_from_any_custom_data():
    assert RunDescription.origin_in({"clock_origin_ns": "42"}) == 42
    assert RunDescription.origin_in({}) is None

"""The node's energy ledger: ~/energy at 10 Hz and the battery's charge in /diagnostics, with
an electro-hydrostatic actuator that gives energy back on lowering; the bag keeps both."""

from __future__ import annotations

import pytest
from conftest import stop_process

rclpy = pytest.importorskip("rclpy")
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402

from boom_hydraulics.model import ledger  # noqa: E402
from boom_hydraulics.model.battery import J_PER_KWH  # noqa: E402
from boom_hydraulics.model.parameters import Parameters  # noqa: E402
from boom_hydraulics_msgs.msg import EnergyLedger  # noqa: E402


def _battery(diagnostic) -> dict[str, str] | None:
    for status in diagnostic.status:
        if status.name == "boom_sim: battery":
            return {kv.key: kv.value for kv in status.values}
    return None


@pytest.mark.parametrize(
    "drive",
    [
        ("drive:=pump_controlled",),
        # the actuator, with standby drawn whatever the load: the drive named at start, the ledger's new terms
        ("drive:=electro_mechanical", "inverter_standby_power_w:=20.0", "auxiliary_power_w:=40.0"),
    ],
    ids=["eha", "actuator"],
)
def test_the_node_publishes_its_ledger_and_the_battery_charge_and_records_them(nodes, client, tmp_path, drive):
    from bag_checks import check_bag
    from rosbags.highlevel import AnyReader

    from boom_hydraulics.bags.encoding import typestore
    from boom_hydraulics.bags.energy import ledger_of_message

    ledgers: list[EnergyLedger] = []
    client.node.create_subscription(
        EnergyLedger, "/boom_sim/energy", ledgers.append, QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    )
    capacity_j = Parameters().battery_capacity_kwh * J_PER_KWH
    proc = nodes.start(
        *drive, "battery_initial_soc:=0.8", "command_timeout_s:=0.0", f"record_folder:={tmp_path}",
        record=True,
    )  # fmt: skip
    try:
        client.handshake()
        start = client.last().rod_position_m
        assert client.spin_until(lambda: client.last().rod_position_m > start + 0.1, opening=0.5)  # lift
        assert client.spin_until(lambda: bool(ledgers) and ledgers[-1].battery_drawn_j > 0.0)
        lifted = ledgers[-1]
        # lower: the load drives the pump, the motor generates into the battery
        assert client.spin_until(lambda: ledgers[-1].battery_returned_j > 100.0, opening=-0.5)
        client.command(0.0)

        # an array made after the lowering gave energy back (arrays come once a second)
        def returned() -> dict[str, str] | None:
            arrays = (_battery(d) for d in reversed(client.diagnostics))
            return next((b for b in arrays if b and float(b["battery_returned_j"]) > 0.0), None)

        assert client.spin_until(lambda: returned() is not None)
        battery = returned()
    finally:
        out = stop_process(proc)
    last = ledgers[-1]
    assert list(last.terms) == list(ledger.TERM_NAMES) and len(last.power_w) == len(last.energy_j) == len(last.terms)
    net = last.battery_drawn_j - last.battery_returned_j
    assert last.state_of_charge == pytest.approx(0.8 - net / capacity_j, rel=1e-12)
    assert lifted.battery_power_w > 0.0 and lifted.lift_work_j > 0.0
    assert ledger.energies_of(ledger_of_message(last))["imbalance_ratio"] < 0.005  # the integrals balance
    # /diagnostics: the same charge, to its 4 decimals, and the energy the battery gave and took back
    spent = float(battery["battery_drawn_j"]) - float(battery["battery_returned_j"])
    assert float(battery["state_of_charge"]) == pytest.approx(0.8 - spent / capacity_j, abs=1e-4)
    assert 0.0 < float(battery["battery_returned_j"]) <= float(battery["battery_drawn_j"])
    # the bag keeps the ledger: every message the client got, readable with rosbags
    (bag,) = tmp_path.glob("*_boom_sim")
    counts = check_bag(bag)
    assert counts["/boom_sim/energy"] >= len(ledgers) > 0, out
    with AnyReader([bag], default_typestore=typestore()) as reader:
        connection = next(c for c in reader.connections if c.topic == "/boom_sim/energy")
        recorded = [reader.deserialize(raw, connection.msgtype) for _, _, raw in reader.messages([connection])]
    assert recorded[-1].battery_drawn_j >= last.battery_drawn_j
    # boom-analyze reads it; boom-resim writes it again, the same for the same parameters
    from boom_hydraulics.analysis.recordings import analyze
    from boom_hydraulics.bags.reading import read_energy_ledger
    from boom_hydraulics.resim.resimulation import resimulate

    again, _ = resimulate(bag, tmp_path / "again")
    # another cylinder for the EHA; for the actuator, which has no oil, another screw
    other = {"piston_diameter_m": 0.05} if "pump_controlled" in drive[0] else {"ema_forward_efficiency": 0.7}
    bigger, _ = resimulate(bag, tmp_path / "bigger", overrides=other)
    results = analyze([bag, again, bigger], tmp_path / "analysis")
    recorded_j = recorded[-1].battery_drawn_j - recorded[-1].battery_returned_j
    assert results[bag.name]["battery_energy_j"] == pytest.approx(recorded_j, rel=1e-12)
    assert results["again"]["battery_energy_j"] == pytest.approx(recorded_j, rel=1e-9)
    assert results["bigger"]["battery_energy_j"] != pytest.approx(recorded_j, rel=1e-3)  # another design
    assert (tmp_path / "analysis" / "energy.png").is_file()
    assert read_energy_ledger(again)["battery_returned"] > 0.0
    standby_w = sum(float(arg.split(":=")[1]) for arg in drive if arg.split(":=")[0].endswith("power_w"))
    at = list(last.terms).index("standby_loss")
    first = ledgers[0]
    seconds = (last.header.stamp.sec - first.header.stamp.sec) + 1e-9 * (
        last.header.stamp.nanosec - first.header.stamp.nanosec
    )
    drawn = last.energy_j[at] - first.energy_j[at]
    assert drawn == pytest.approx(standby_w * seconds, rel=1e-6, abs=1e-9)  # drawn all along, whatever the load


def test_the_node_warns_in_its_diagnostics_while_the_battery_cannot_give_what_the_drive_asks(nodes, client):
    """eq. D11: a 48 V battery behind 100 ohm gives at most 5.8 W, less than the drive asks with
    its valve open; the drive's status warns of it by name, and the ledger says why it does not close."""
    from boom_hydraulics.bags.diagnostics import WARN

    proc = nodes.start("battery_resistance_ohm:=100.0", "command_timeout_s:=0.0")

    def drive() -> object | None:
        arrays = (d for d in reversed(client.diagnostics))
        return next((s for d in arrays for s in d.status if s.name == "boom_sim: drive"), None)

    try:
        client.handshake()
        assert client.spin_until(lambda: (s := drive()) is not None and s.level == bytes([WARN]), opening=0.5)
    finally:
        stop_process(proc)
    assert "battery_overloaded" in drive().message.split(", ")

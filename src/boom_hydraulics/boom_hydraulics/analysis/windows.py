"""A recorded run analysed over a window of the node's clock: boom-demo's cycle, whatever
the node did before and after it.

The node runs for as long as it is left running (its start, then until it is stopped), and
how long that is depends on the machine; the cycle itself is a fixed window of its clock.
The signals are the DriveStates stamped within the window, with ``t`` from its start; the
energy ledger's figures are its integrals at the window's end less those at its start, each
taken from the last ledger message before the instant and carried on with that message's
power (the node publishes the ledger at 10 Hz; at the window's ends the valve is closed and
the powers are steady).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..bags.reading import read_custom_data, read_drive_states, read_energy_ledger_messages
from ..bags.run_description import RunDescription
from ..errors import BagError
from ..files import check_apart, json_text, results_folder
from . import metrics as analysis
from . import plots
from .recordings import bag_label, write_signals


def drive_states_in(bag: Path, start_ns: int, end_ns: int) -> dict[str, np.ndarray]:
    """The DriveStates of ``bag`` stamped in [start_ns, end_ns] of the node's clock, ``t`` in s from start_ns."""
    origin_ns = RunDescription.origin_in(read_custom_data(bag) or {})
    if origin_ns is None:
        raise BagError(f"{bag}: no time origin recorded; was it recorded by boom_sim?")
    signals = read_drive_states(bag, "origin")
    stamps_ns = origin_ns + np.round(signals["t"] * 1e9).astype(np.int64)
    inside = (stamps_ns >= start_ns) & (stamps_ns <= end_ns)
    if np.count_nonzero(inside) < 2:
        raise BagError(f"{bag}: fewer than 2 DriveState messages within the window to analyse")
    window = {name: values[inside] for name, values in signals.items()}
    window["t"] = (stamps_ns[inside] - start_ns).astype(float) * 1e-9
    return window


def _battery_at(messages: list[tuple[int, Any]], at_ns: int) -> dict[str, float] | None:
    """The battery's integrals (J) at ``at_ns``: the last message before it, carried on with its power."""
    before = [(stamp, msg) for stamp, msg in messages if stamp <= at_ns]
    if not before:
        return None
    stamp, msg = before[-1]
    dt_s = (at_ns - stamp) * 1e-9
    power = float(msg.battery_power_w)
    return {
        "battery_drawn": float(msg.battery_drawn_j) + max(power, 0.0) * dt_s,
        "battery_returned": float(msg.battery_returned_j) + max(-power, 0.0) * dt_s,
        "lift_work": float(msg.lift_work_j),  # the boom is at rest at the window's ends
        "state_of_charge": float(msg.state_of_charge),
    }


def battery_in(bag: Path, start_ns: int, end_ns: int) -> dict[str, float] | None:
    """The battery's figures over the window (J), as boom-analyze names them; None for a bag
    without an energy ledger (paper mode) or without one before the window."""
    messages = read_energy_ledger_messages(bag)
    start, end = _battery_at(messages, start_ns), _battery_at(messages, end_ns)
    if start is None or end is None:
        return None
    drawn = end["battery_drawn"] - start["battery_drawn"]
    returned = end["battery_returned"] - start["battery_returned"]
    return {
        "battery_energy_j": drawn - returned,
        "battery_drawn_j": drawn,
        "battery_returned_j": returned,
        "lift_work_j": end["lift_work"] - start["lift_work"],
        "state_of_charge": end["state_of_charge"],
    }


def analyze_window(
    bag: Path, out: Path, start_ns: int, end_ns: int, signals: Mapping[str, np.ndarray] | None = None
) -> dict[str, dict[str, float]]:
    """Analyse ``bag`` over [start_ns, end_ns] of the node's clock into ``out`` as boom-analyze
    analyses a whole bag (the window's signals, metrics and plots; only those files);
    ``signals``: the window's (:func:`drive_states_in`), if read already."""
    check_apart(out, [bag])
    label = bag_label(bag)
    if signals is None:
        signals = drive_states_in(bag, start_ns, end_ns)  # fails before writing
    battery = battery_in(bag, start_ns, end_ns)
    result: dict[str, Any] = analysis.metrics(signals)
    if battery is not None:
        result.update(battery)
    with results_folder(out) as tmp:
        write_signals(tmp, label, dict(signals))
        (tmp / f"{label}.metrics.json").write_text(json_text(result))
        runs = [(label, signals)]
        plots.dynamics(runs, tmp / "dynamics.png")
        plots.drive(runs, tmp / "drive.png")
    return {label: result}


def valve_acted(signals: Mapping[str, np.ndarray]) -> bool:
    """Whether the valve was commanded open at any sample of ``signals``."""
    return bool(np.any(np.asarray(signals["u"]) != 0.0))

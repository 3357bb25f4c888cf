"""Reading bags back, run metrics, and boom-analyze's outputs and errors."""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import subprocess

import figure_checks
import numpy as np
import pytest
from conftest import run_tool

pytest.importorskip("rclpy")
from rclpy.serialization import serialize_message

from boom_hydraulics.analysis import metrics as analysis
from boom_hydraulics.bags.reading import read_drive_states
from boom_hydraulics.bags.recording import BagRecorder, Topic
from boom_hydraulics.errors import BagError
from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.solve.commands import steps
from boom_hydraulics.solve.simulation import simulate
from boom_hydraulics_msgs.msg import DriveState, ValveCommand

BOOM_ANALYZE = shutil.which("boom-analyze")
COMMAND = steps([0.0, 1.0, 1.6], [1.0, 0.0, -0.5])


@pytest.fixture(scope="module")
def trajectory():
    """A lift, hold and lower of 2.5 s (every 10th step), computed once for the module's tests."""
    return simulate(Parameters(), 2.5, COMMAND, every=10, jit=False)


def _analyze(*args) -> subprocess.CompletedProcess:
    """boom-analyze's main in this process (conftest.run_tool; test_node_bags runs the real one)."""
    return run_tool("boom-analyze", *args)


def _record(folder, tr) -> None:
    """A bag of the trajectory's DriveStates, as the node writes them."""
    with BagRecorder(folder, [Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState")]) as rec:
        for i in range(len(tr)):
            msg = DriveState()
            ns = round(tr["t"][i] * 1e9)
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10**9)
            msg.rod_position_m, msg.rod_velocity_m_s, msg.rod_acceleration_m_s2 = tr["q1"][i], tr["v"][i], tr["a"][i]
            msg.boom_angle_rad, msg.piston_pressure_pa, msg.rod_pressure_pa = tr["alpha"][i], tr["p1"][i], tr["p2"][i]
            msg.hydraulic_force_n, msg.load_force_n = tr["f_hyd"][i], tr["f_load"][i]
            msg.valve_command, msg.valve_opening = tr["u"][i], tr["x_v"][i]
            msg.supply_power_w, msg.supply_energy_j = tr["power"][i], tr["supply_energy"][i]
            msg.valve_loss_energy_j = tr["valve_loss_energy"][i]
            msg.at_end_stop, msg.cavitation = bool(tr["at_end_stop"][i]), bool(tr["cavitation"][i])
            msg.relief_open = bool(tr["relief_open"][i])
            rec.write("/drive_state", ns, serialize_message(msg))


def test_a_bag_reads_back_to_the_signals_that_were_recorded(tmp_path, trajectory):
    tr = trajectory
    _record(tmp_path / "run", tr)
    for bag in (tmp_path / "run", tmp_path / "run" / "run_0.mcap"):  # folder or single file
        signals = read_drive_states(bag)
        for name in ("q1", "p1", "u", "supply_energy"):
            assert np.array_equal(signals[name], tr[name])
        assert np.allclose(signals["t"], tr["t"], atol=1e-9)


def test_metrics_of_a_lift(trajectory):
    tr = trajectory
    m = analysis.metrics(tr.columns)
    i_top = int(np.argmax(tr["q1"]))
    assert m["lift_m"] == pytest.approx(tr["q1"][i_top] - tr["q1"][0])
    reached = np.nonzero(tr["q1"] >= tr["q1"][0] + 0.9 * m["lift_m"])[0][0]
    assert m["time_to_target_s"] == pytest.approx(tr["t"][reached])  # the valve opens at t = 0
    assert m["peak_speed_m_s"] == pytest.approx(np.max(np.abs(tr["v"])))
    assert m["supply_energy_per_m_j_m"] == pytest.approx(tr["supply_energy"][-1] / m["lift_m"])
    assert m["min_pressure_pa"] >= Parameters().cavitation_pressure_pa


def test_oscillation_finds_frequency_and_damping_of_a_decaying_sine():
    t = np.arange(0, 4, 1e-3)
    zeta, f = 0.05, 3.0
    wd = 2 * math.pi * f
    x = 2.0 + 0.1 * t + np.exp(-zeta * wd / math.sqrt(1 - zeta**2) * t) * np.sin(wd * t)
    frequency, damping = analysis.oscillation(t, x, ripple=1e-3)
    assert frequency == pytest.approx(f, abs=0.05)  # from the times of the maxima, despite the trend
    assert damping == pytest.approx(zeta, rel=0.05)


@pytest.mark.skipif(BOOM_ANALYZE is None, reason="boom-analyze not on PATH")
def test_boom_analyze_writes_signals_metrics_and_plots(tmp_path, trajectory):
    tr = trajectory
    _record(tmp_path / "a", tr)
    _record(tmp_path / "b", tr)
    out = tmp_path / "results"
    result = _analyze(tmp_path / "a", tmp_path / "b", "--out", out)
    assert result.returncode == 0, result.stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["a.csv", "a.npz", "a.metrics.json", "b.csv", "b.npz", "b.metrics.json", "dynamics.png", "drive.png"]
    )
    with (out / "a.csv").open() as handle:
        header = next(csv.reader(handle))
    assert header[:3] == ["t [s]", "q1 [m]", "v [m/s]"] and "p1 [Pa]" in header
    metrics = json.loads((out / "a.metrics.json").read_text(), parse_constant=lambda c: pytest.fail(f"{c}: not JSON"))
    assert metrics["lift_m"] == pytest.approx(analysis.metrics(tr.columns)["lift_m"])
    expected = analysis.metrics(tr.columns)
    undefined = [name for name, value in expected.items() if not math.isfinite(value)]
    assert undefined and all(metrics[name] is None for name in undefined)  # null where a metric has no value
    for png in ("dynamics.png", "drive.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.skipif(BOOM_ANALYZE is None, reason="boom-analyze not on PATH")
@pytest.mark.parametrize("case", ["missing", "not_mcap", "truncated", "no_drive_state"])
def test_bad_bags_give_one_line_and_write_nothing(tmp_path, trajectory, case):
    if case == "missing":
        bag, message = tmp_path / "nope", "no such bag folder or file"
    elif case == "not_mcap":
        bag, message = tmp_path / "x.mcap", "not an MCAP file"
        bag.write_text("hello")
    elif case == "truncated":
        _record(tmp_path / "run", trajectory)
        data = (tmp_path / "run" / "run_0.mcap").read_bytes()
        bag, message = (
            tmp_path / "cut.mcap",
            "truncated (its recorder was killed, or its disk was full); run boom-bag-recover",
        )
        bag.write_bytes(data[: len(data) // 2])
    else:
        with BagRecorder(tmp_path / "other", [Topic("/valve_command", "boom_hydraulics_msgs/msg/ValveCommand")]) as rec:
            rec.write("/valve_command", 1, serialize_message(ValveCommand(opening=0.5)))
        bag, message = tmp_path / "other", "no boom_hydraulics_msgs/msg/DriveState topic"
    out = tmp_path / "results"
    result = _analyze(bag, "--out", out)
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in result.stderr
    assert not out.exists()
    with pytest.raises(BagError):
        read_drive_states(bag)


def test_lift_through_an_angle_is_timed_and_costed_between_samples():
    t = np.arange(0.0, 2.0, 0.1)
    u = np.where(t >= 0.2, 1.0, 0.0)
    alpha = 0.3 + np.radians(10.0) * np.clip(t - 0.2, 0.0, None)  # 10 deg/s from t = 0.2 s
    energy = 1000.0 * t
    signals = {"t": t, "alpha": alpha, "u": u, "supply_energy": energy, "valve_loss_energy": 0.5 * energy}
    m = analysis.lift_metrics(signals, lift_angle_deg=12.5)
    assert m["lift_completed"] == 1.0
    assert m["lift_time_s"] == pytest.approx(1.25)  # reached at t = 1.45 s, between two samples
    assert m["lift_energy_j"] == pytest.approx(1450.0)
    assert m["lift_valve_loss_j"] == pytest.approx(725.0)
    assert m["rise_deg"] == pytest.approx(17.0)
    short = analysis.lift_metrics(signals, lift_angle_deg=30.0)
    assert short["lift_completed"] == 0.0 and math.isnan(short["lift_time_s"]) and math.isnan(short["lift_energy_j"])


def test_a_settling_hump_is_not_an_oscillation():
    t = np.arange(0, 2, 1e-3)
    hump = 1.0 - np.exp(-3 * t) + 0.3 * np.exp(-((t - 0.5) ** 2) / 0.02)
    frequency, damping = analysis.oscillation(t, hump, ripple=1e-3)
    assert math.isnan(frequency) and math.isnan(damping)


@pytest.mark.skipif(BOOM_ANALYZE is None, reason="boom-analyze not on PATH")
@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a small tmpfs needs root")
def test_a_full_disk_names_the_result_file_and_leaves_no_staging_folder(tmp_path, trajectory):
    _record(tmp_path / "a", trajectory)
    disk = tmp_path / "disk"
    disk.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)], check=True)
    try:
        out = disk / "results"
        result = _analyze(tmp_path / "a", "--out", out)
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 1 and len(lines) == 1 and "Traceback" not in result.stderr
        assert lines[0].startswith(f"boom-analyze: error: {out}/") and "No space left on device" in lines[0]
        assert ".partial" not in lines[0]
        assert list(disk.iterdir()) == []  # neither the staging folder nor the results folder it made
    finally:
        subprocess.run(["umount", str(disk)], check=True)


@pytest.fixture
def written_figures(monkeypatch):
    """The figures boom-analyze's plots write, kept where they close them (as written)."""
    from boom_hydraulics.analysis import plots

    kept: list = []
    close = plots.plt.close
    monkeypatch.setattr(
        plots.plt, "close", lambda fig=None: kept.append(fig) if hasattr(fig, "savefig") else close(fig)
    )
    yield kept
    for fig in kept:
        close(fig)


#: Names of three bags, as boom-analyze labels them: a recording and two re-simulations.
BAGS = ("20261206-200849_boom_sim", "20261206-200849_boom_sim-63mm", "20261206-200849_boom_sim-pump_controlled")


def test_the_energy_plot_of_compared_runs_names_its_terms_in_words_and_fits(tmp_path, written_figures):
    from boom_hydraulics.analysis import labels, plots

    energies = {name: 1e3 * (k + 1) for k, name in enumerate(plots.BREAKDOWN_TERMS)} | {"battery_returned": 2e3}
    title = "Where the battery's energy went over each run (above each bar: drawn less returned)"
    for bags in (BAGS[:1], BAGS):
        plots.energy_breakdown([(bag, energies, 3e4) for bag in bags], title, tmp_path / "energy.png")
        fig = written_figures[-1]
        assert figure_checks.cut_titles(fig) == []  # the title whole, on one figure
        assert figure_checks.overlapping_tick_labels(fig) == []  # each run's name readable
        key = figure_checks.legend_texts(fig)
        assert key == [labels.term_words(n) for n in (*plots.BREAKDOWN_TERMS, "battery_returned")]
        assert figure_checks.code_names(key) == []  # in words: "motor and inverter", not motor_loss
        assert [t.get_text().replace("\n", "") for t in fig.axes[0].get_xticklabels()] == list(bags)


def test_the_runs_of_figs_8_to_10_are_named_where_they_cover_no_curve(tmp_path, trajectory, written_figures):
    from boom_hydraulics.analysis import plots

    plots.dynamics([(bag, trajectory.columns) for bag in BAGS], tmp_path / "dynamics.png")
    plots.drive([(bag, trajectory.columns) for bag in BAGS], tmp_path / "drive.png")
    for fig in written_figures:
        renderer = figure_checks.drawn(fig)
        key = [legend for ax in fig.axes if (legend := ax.get_legend()) is not None] + list(fig.legends)
        assert [t.get_text() for legend in key for t in legend.get_texts()] == list(BAGS)
        (box,) = [legend.get_window_extent(renderer) for legend in key]
        assert not any(box.overlaps(ax.get_window_extent(renderer)) for ax in fig.axes)  # over no panel
        assert figure_checks.cut_titles(fig) == []
        assert figure_checks.overlapping_axis_labels(fig) == []  # each panel's quantity readable
        for ax in fig.axes:
            assert ax.get_ylabel().endswith("]")  # with its unit

"""The sweep's plots: designs coloured by bands of a parameter or metric (sweeps.plots.bands),
or by drive, each named in words; axes with units; titles and labels that fit."""

from __future__ import annotations

import itertools

import figure_checks
import numpy as np
import pytest
from matplotlib.colors import to_rgba

from boom_hydraulics.analysis import labels
from boom_hydraulics.analysis import plots as analysis_plots
from boom_hydraulics.model import parameters
from boom_hydraulics.model.parameters import DRIVES
from boom_hydraulics.sweeps import plots, sweep


def _partition(colouring: plots.Colouring) -> list[np.ndarray]:
    """The groups' rows, each design in one group at most."""
    rows = [r for r, _ in colouring.groups]
    joined = np.sort(np.concatenate(rows)) if rows else np.array([], int)
    assert joined.tolist() == sorted(set(joined.tolist())), "a design drawn twice"
    return rows


def test_a_parameter_with_few_values_has_a_colour_for_each_and_the_bar_names_them():
    payload = np.array([0.0, 150.0, 75.0, 150.0, 0.0, 75.0])
    colouring = plots.banded(payload)
    rows = _partition(colouring)
    assert sorted(sorted(payload[r].tolist()) for r in rows) == [[0.0, 0.0], [75.0, 75.0], [150.0, 150.0]]
    assert len({tuple(colour) for _, colour in colouring.groups}) == 3  # three colours
    assert colouring.ticks.tolist() == [0.0, 75.0, 150.0]  # the colour bar's ticks at the values
    for r, colour in colouring.groups:  # each value's colour is the bar's colour at it
        mapped = plots.plt.get_cmap("viridis")(colouring.norm(payload[r][0]))
        assert colour == pytest.approx(mapped)


def test_many_values_fall_in_at_most_bands_bands_between_round_edges_that_hold_them_all():
    rng = np.random.default_rng(7)
    for values in (np.linspace(0.032, 0.08, 49), rng.uniform(7.47e6, 1.93e7, 5000), np.linspace(0, 200, 101)):
        edges, ticks = plots.bands(values)
        assert ticks is None and 2 <= len(edges) - 1 <= plots.BANDS
        assert edges[0] <= values.min() and edges[-1] >= values.max()
        steps = np.diff(edges)
        assert np.allclose(steps, steps[0])  # equal bands, at round values
        colouring = plots.banded(values)
        rows = _partition(colouring)
        assert sum(len(r) for r in rows) == len(values)  # every design drawn, once
        for r, _ in colouring.groups:  # a group's values lie in one band
            low, high = values[r].min(), values[r].max()
            assert any(a <= low and high <= b for a, b in itertools.pairwise(edges))


def test_a_value_that_is_not_a_number_is_not_drawn_and_one_value_is_one_band():
    colouring = plots.banded(np.array([1.0, np.nan, 1.0]))
    assert [r.tolist() for r, _ in colouring.groups] == [[0, 2]]
    edges, ticks = plots.bands(np.array([1.0, 1.0]))
    assert edges[0] < 1.0 < edges[1] and ticks.tolist() == [1.0]


def test_categories_each_have_their_colour_and_a_key():
    table = {"drive": np.array(["valve", "pump", "valve", "pump"]), "status": np.array(["ok"] * 4)}
    colouring = plots._colours(table, "drive", np.ones(4, bool))
    assert set(colouring.key) == {"pump", "valve"} and colouring.norm is None
    assert {tuple(r.tolist()) for r, _ in colouring.groups} == {(0, 2), (1, 3)}


def test_values_a_rounding_apart_share_a_band_and_one_value_has_a_band_around_it():
    edges, ticks = plots.bands(np.array([0.3, 0.1 * 3, 0.6]))
    assert np.all(np.diff(edges) > 0) and len(ticks) == 2  # no band without width
    edges, ticks = plots.bands(np.array([0.05, 0.05]))
    assert edges.tolist() == pytest.approx([0.025, 0.075]) and ticks.tolist() == [0.05]


# --- what a reader sees: drives told apart and named in words, units, titles and labels that fit


def _drives_table(operators: int = 2) -> tuple[dict[str, np.ndarray], tuple[str, ...]]:
    """A drives sweep's table as boom-sweep assembles it (--vary drive=... --vary
    piston_diameter=... --operators N), with made-up metrics: every drive, six pistons, a tenth
    of the points not ok."""
    rng = np.random.default_rng(52)
    rows = [(o, d, p) for o in range(1, operators + 1) for d in DRIVES for p in np.linspace(0.032, 0.1, 6)]
    n = len(rows)
    table: dict[str, np.ndarray] = {
        "operator": np.array([o for o, _, _ in rows]),
        "drive": np.array([d for _, d, _ in rows]),
        "piston_diameter_m": np.array([p for _, _, p in rows]),
    }
    for name, unit, _ in sweep.METRICS:
        scale = {"J": 1e4, "Pa": 1e7, "W": 1e3}.get(unit, 1.0)
        table[name] = rng.uniform(0.1, 1.0, n) * scale
    table["status"] = np.where(np.arange(n) % 10 == 3, "incomplete", "ok")
    return table, ("operator", "drive", "piston_diameter_m")


@pytest.fixture(scope="module")
def drives_plots(tmp_path_factory) -> dict[str, object]:
    """Each file plot_all writes for :func:`_drives_table`, with the figure it wrote there, kept
    as it was written (drawn here, in one process: the figures are taken where plot_all closes
    them)."""
    table, columns = _drives_table()
    kept: list[object] = []
    close = plots.plt.close
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(plots, "can_fork", lambda: False)
        patch.setattr(plots.plt, "close", lambda fig=None: kept.append(fig) if hasattr(fig, "savefig") else close(fig))
        paths = plots.plot_all(table, columns, tmp_path_factory.mktemp("drives"))
    assert len(paths) == len(kept) == 5
    yield {path.name: fig for path, fig in zip(paths, kept)}
    for fig in kept:
        close(fig)


def _rgba(colour) -> tuple[float, ...]:
    return tuple(np.round(to_rgba(colour), 4))


def _spot_colours(ax) -> set[tuple[float, ...]]:
    """The colours of an axes' filled spots (the ok designs)."""
    return {_rgba(line.get_color()) for line in ax.get_lines() if line.get_marker() == "o"}


def test_with_a_drive_axis_each_drive_has_its_colour_and_its_name_in_words_in_every_plot(drives_plots):
    drawn = drives_plots
    words = {"EHA (pump controlled)", "load sensing", "pressure compensated", "fixed pump"}
    words |= {"EMA (ball screw)"}
    assert set(labels.DRIVE_WORDS.values()) == words and set(labels.DRIVE_WORDS) == set(DRIVES)
    metrics = drawn["metrics_vs_piston_diameter_m.png"]
    key = [t for t in figure_checks.legend_texts(metrics) if not t.startswith("not ok")]
    assert key == [labels.DRIVE_WORDS[d] for d in DRIVES]  # the drives, not the operators' seeds
    assert "coloured by drive" in metrics._suptitle.get_text()
    key_colours = {
        text.get_text(): _rgba(handle.get_color())
        for legend in metrics.legends
        for text, handle in zip(legend.get_texts(), legend.legend_handles)
    }
    for ax in metrics.axes:  # every panel: a colour per drive, the key's
        assert _spot_colours(ax) == {key_colours[w] for w in key}
    battery = drawn["battery_energy.png"]
    (ax,) = battery.axes
    lines = {line.get_label(): _rgba(line.get_color()) for line in ax.get_lines()}
    assert lines == {w: key_colours[w] for w in key}  # each drive in the metrics plot's colour
    trade = drawn["trade_off.png"]
    assert [t for t in figure_checks.legend_texts(trade) if t != "non-dominated"] == key
    breakdown = drawn["energy_breakdown.png"]
    names = [t.get_text() for t in breakdown.axes[0].get_xticklabels()]
    assert [name.split("\n")[0] for name in names] == key and all(name.endswith(" mm") for name in names)
    for fig in drawn.values():  # nothing named as the code spells it
        assert figure_checks.code_names(figure_checks.legend_texts(fig)) == []
        assert figure_checks.code_names(t.get_text() for t in figure_checks.titles(fig)) == []


def test_the_axes_carry_their_quantities_in_words_with_units(drives_plots):
    drawn = drives_plots
    metrics = drawn["metrics_vs_piston_diameter_m.png"]
    assert {ax.get_xlabel() for ax in metrics.axes} == {"piston diameter [mm]"}
    assert max(float(t.get_text().replace("−", "-")) for t in metrics.axes[0].get_xticklabels()) > 50  # in mm
    (ax,) = drawn["battery_energy.png"].axes
    assert ax.get_xlabel() == "piston diameter [mm]" and ax.get_ylabel() == "battery energy per cycle [kJ]"
    assert drawn["energy_breakdown.png"].axes[0].get_ylabel() == "energy [kJ]"
    for fig in drawn.values():
        for ax in fig.axes:
            for label in (ax.get_xlabel(), ax.get_ylabel()):
                assert "_" not in label, label


def test_titles_fit_their_figures_and_no_tick_labels_overlap(drives_plots):
    assert "metrics_vs_operator.png" in drives_plots  # (the sweep's every plot)
    for name, fig in drives_plots.items():
        assert figure_checks.cut_titles(fig) == [], name
        assert figure_checks.overlapping_tick_labels(fig) == [], name


def test_the_front_designs_named_in_a_trade_off_are_named_with_units_and_apart():
    """Thirty pistons that all lie on the front, close together (a sweep of one cylinder over
    its bore): the names that would overlap are left out."""
    n = 30
    piston = np.linspace(0.032, 0.1, n)
    table = {"piston_diameter_m": piston, "payload_mass_kg": np.zeros(n), "status": np.array(["ok"] * n)}
    table.update(lift_time_s=np.linspace(0.4, 2.4, n), lift_energy_j=np.linspace(1.7e3, 1e4, n))
    table["peak_pressure_pa"] = np.linspace(1.8e7, 8e6, n)
    fig = plots.trade_off_figure(table, ["piston_diameter_m", "payload_mass_kg"])
    renderer = figure_checks.drawn(fig)
    names = [t for t in fig.axes[0].texts]
    assert 3 <= len(names) <= 12 and all(t.get_text().endswith(" mm") for t in names)
    boxes = [t.get_window_extent(renderer) for t in names]
    assert not any(a.overlaps(b) for k, a in enumerate(boxes) for b in boxes[k + 1 :])
    plots.plt.close(fig)


def test_a_breakdown_of_many_drives_or_long_names_keeps_its_bar_names_apart():
    energies = {"valve_loss": 2e4, "motor_loss": 1e4, "lift_work": 1e3, "battery_returned": 500.0}
    long = "pressure compensated\npiston diameter 43.7 mm\npayload mass 150 kg\nrod diameter 22 mm"
    for names in ([long] * 4, [f"20261206-200849_boom_sim-resimulated-{k}" for k in range(6)]):
        fig = analysis_plots.energy_breakdown_figure([(n, energies, 3e4) for n in names], plots.breakdown_title(True))
        assert figure_checks.overlapping_tick_labels(fig) == []
        assert figure_checks.cut_titles(fig) == []
        plots.plt.close(fig)


def test_every_term_a_breakdown_stacks_has_words_and_every_parameter_a_label_with_its_unit():
    for term in (*analysis_plots.BREAKDOWN_TERMS, "battery_returned"):
        assert term in labels.TERM_WORDS and "_" not in labels.term_words(term), term
    assert labels.quantity("piston_diameter_m") == ("piston diameter [mm]", 1e3)
    assert labels.quantity("supply_pressure_pa") == ("supply pressure [MPa]", 1e-6)
    assert labels.quantity("payload_mass_kg") == ("payload mass [kg]", 1.0)
    assert labels.quantity("valve_leakage_m3_s_pa").label == "valve leakage [m³/(s Pa)]"
    assert labels.value_with_unit("piston_diameter_m", np.float64(0.04372)) == "43.7 mm"
    for name in parameters.NAMES:
        label = labels.quantity(name).label
        assert "_" not in label, label
        if parameters.describe(name)["unit"]:
            assert label.endswith("]"), label


def test_a_plot_is_coloured_by_the_drive_else_by_a_design_axis_before_the_operators_seed():
    table, _ = _drives_table()
    table["config"] = np.array(["a", "b"] * (len(table["drive"]) // 2))
    assert plots.colour_column(table, ["operator", "config", "drive"]) == "drive"
    assert plots.colour_column(table, ["operator", "config"]) == "config"
    assert plots.colour_column(table, ["operator", "piston_diameter_m"]) == "piston_diameter_m"
    assert plots.colour_column(table, ["operator"]) == "operator"
    assert plots.colour_column(table, []) is None
    fig = plots.trade_off_figure(table, ["config", "operator", "drive", "piston_diameter_m"])
    key = [t for t in figure_checks.legend_texts(fig) if t != "non-dominated"]
    assert key == [labels.DRIVE_WORDS[d] for d in DRIVES]  # the drive's, not the config's
    plots.plt.close(fig)


def test_battery_energy_has_a_line_for_each_value_of_another_design_axis_named_with_its_unit():
    """A sweep of pistons and payloads (sweeps.md's): a line per payload, not one line
    zigzagging through them."""
    piston = np.repeat(np.linspace(0.032, 0.076, 4), 2)
    payload = np.tile([0.0, 150.0], 4)
    energy = 1e4 + 1e5 * piston + 10.0 * payload
    bands = {"piston_diameter_m": piston, "payload_mass_kg": payload, "cycles": np.ones(8, int)}
    bands |= {f"battery_energy_j_p{q}": energy for q in (10, 50, 90)}
    fig = plots.battery_energy_figure(bands, "piston_diameter_m", ["piston_diameter_m", "payload_mass_kg"])
    (ax,) = fig.axes
    assert [line.get_label() for line in ax.get_lines()] == ["0 kg", "150 kg"]
    for line, mass in zip(ax.get_lines(), (0.0, 150.0)):
        assert line.get_xdata().tolist() == pytest.approx([32, 46.67, 61.33, 76], abs=0.01)  # mm
        assert line.get_ydata() == pytest.approx((1e4 + 1e5 * np.linspace(0.032, 0.076, 4) + 10 * mass) * 1e-3)
    assert figure_checks.legend_texts(fig) == ["0 kg", "150 kg"] and figure_checks.cut_titles(fig) == []
    plots.plt.close(fig)

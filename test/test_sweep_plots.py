"""The sweep's plots colour designs by bands of a parameter or metric (sweeps.plots.bands)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from boom_hydraulics.sweeps import plots


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

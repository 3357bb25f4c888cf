"""Axes of a design sweep and how they are sampled into points."""

from __future__ import annotations

import numpy as np
import pytest

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.sweeps.sampling import parse_axis, resolve_name, sample_points


def test_names_resolve_from_an_unambiguous_beginning():
    assert resolve_name("piston_diameter") == "piston_diameter_m"
    assert resolve_name("payload") == "payload_mass_kg"
    assert resolve_name("bulk_modulus_pa") == "bulk_modulus_pa"
    with pytest.raises(ConfigError, match=r"could mean .*command_"):
        resolve_name("command_")
    with pytest.raises(ConfigError, match="did you mean piston_diameter_m"):
        resolve_name("piston_diamter")


def test_axis_forms():
    assert parse_axis("piston_diameter=0.032:0.1:15").values == tuple(np.linspace(0.032, 0.1, 15))
    log = parse_axis("bulk_modulus_pa=1e8:1e10:3:log")
    assert tuple(log.values) == pytest.approx((1e8, 1e9, 1e10))
    assert parse_axis("payload=0,100,200").values == (0.0, 100.0, 200.0)
    assert parse_axis("method=euler,rk4").values == ("euler", "rk4")
    ranged = parse_axis("payload=0:200")
    assert ranged.is_range and (ranged.low, ranged.high) == (0.0, 200.0)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("piston_diameter", "write NAME=START:STOP:COUNT"),
        ("nosuch=1,2", "unknown parameter 'nosuch'"),
        ("payload=0:200:2.5", "COUNT must be a whole number"),
        ("payload=0:x:3", "'x' is not a number"),
        ("payload=0:nan:3", "not a finite number"),
        ("payload=200:0", "LOW must be below HIGH"),
        ("bulk_modulus_pa=0:1e9:3:log", "log range needs positive ends"),
        ("command_values=1,2", "list parameters cannot be varied"),
        ("mode=physical:paper", "not numeric"),
    ],
)
def test_bad_axes_name_what_is_wrong(spec, message):
    with pytest.raises(ConfigError, match=message):
        parse_axis(spec)


def test_grid_is_every_combination_and_list_pairs_values():
    a, b = parse_axis("piston_diameter=0.04,0.06,0.08"), parse_axis("payload=0,200")
    grid = sample_points([a, b], "grid")
    assert len(grid) == 6
    assert {(p["piston_diameter_m"], p["payload_mass_kg"]) for p in grid} == {
        (d, m) for d in (0.04, 0.06, 0.08) for m in (0.0, 200.0)
    }
    listed = sample_points([a, parse_axis("payload=0,100,200")], "list")
    assert [(p["piston_diameter_m"], p["payload_mass_kg"]) for p in listed] == [
        (0.04, 0.0),
        (0.06, 100.0),
        (0.08, 200.0),
    ]
    with pytest.raises(ConfigError, match="lengths differ"):
        sample_points([a, b], "list")
    with pytest.raises(ConfigError, match="varied twice"):
        sample_points([a, parse_axis("piston_diameter_m=0.05")], "grid")


def test_latin_hypercube_uses_every_stratum_once_and_is_reproducible():
    axes = [parse_axis("piston_diameter=0.032:0.1"), parse_axis("payload=0:200")]
    points = sample_points(axes, "lhs", count=50, seed=7)
    assert points == sample_points(axes, "lhs", count=50, seed=7)
    assert points != sample_points(axes, "lhs", count=50, seed=8)
    d = np.array([p["piston_diameter_m"] for p in points])
    m = np.array([p["payload_mass_kg"] for p in points])
    assert sorted(np.floor((d - 0.032) / 0.068 * 50).astype(int)) == list(range(50))
    assert sorted(np.floor(m / 200 * 50).astype(int)) == list(range(50))


def test_random_sample_stays_in_its_ranges_also_in_log():
    points = sample_points([parse_axis("bulk_modulus_pa=1e8:1e10:log")], "random", count=200, seed=1)
    e = np.array([p["bulk_modulus_pa"] for p in points])
    assert (e >= 1e8).all() and (e <= 1e10).all()
    assert 0.3 < np.mean(e < 1e9) < 0.7  # log-uniform: half the points below the geometric middle


def test_samples_need_the_right_axes():
    with pytest.raises(ConfigError, match="needs --samples"):
        sample_points([parse_axis("payload=0:200")], "random")
    with pytest.raises(ConfigError, match="draws from ranges"):
        sample_points([parse_axis("payload=0,200")], "lhs", count=4)
    with pytest.raises(ConfigError, match="range without a count"):
        sample_points([parse_axis("payload=0:200")], "grid")

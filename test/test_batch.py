"""The batched path equals single runs; failing points are reported, not fatal."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve.batch import simulate_batch
from boom_hydraulics.solve.commands import steps
from boom_hydraulics.solve.simulation import simulate


def test_batched_results_equal_single_runs():
    base = Parameters()
    params = [
        with_updates(base, piston_diameter_m=d, rod_diameter_m=0.55 * d, payload_mass_kg=m, bulk_modulus_pa=e)
        for d, m, e in [(0.032, 0.0, 1e9), (0.05, 100.0, 1.5e9), (0.08, 200.0, 0.7e9)]
    ]
    command = steps([0.0, 1.0], [1.0, -0.5])
    batch = simulate_batch(params, 2.0, command, every=20)
    for k, p in enumerate(params):
        single = simulate(p, 2.0, command, every=20, jit=False)
        # the batch evaluates with numpy, a single run with math: exp, sqrt and pow may differ
        # in the last bit (1e-16 relative) on some inputs; this damped system keeps such
        # differences far below 1e-9 over 2000 steps, while a wrong element changes results
        # by orders of magnitude more
        for name in ("q1", "v", "p1", "p2", "supply_energy"):
            scale = np.max(np.abs(single[name]))
            np.testing.assert_allclose(batch[name][:, k], single[name], rtol=1e-9, atol=1e-12 * scale, err_msg=name)
        assert np.array_equal(batch["cavitation"][:, k], single["cavitation"])  # flags: the same decisions
    assert np.isnan(batch["failed_at_s"]).all()


def test_a_diverging_point_is_frozen_and_reported_while_the_others_finish():
    params = [config.load(CONFIG / f"paper_fig{i}.yaml") for i in (8, 9)]
    out = simulate_batch(params, 3.0, lambda t: 1.0, every=100)
    assert 2.0 < out["failed_at_s"][0] < 2.3  # fig. 8 leaves the geometry near q1 = 1.8 m
    assert np.isnan(out["failed_at_s"][1])
    assert np.isfinite(out["q1"]).all() and out["q1"][-1, 1] > 1.5


def test_batch_members_must_share_mode_method_and_step():
    with pytest.raises(ConfigError, match="must share time_step_s"):
        simulate_batch([Parameters(), with_updates(Parameters(), time_step_s=2e-3)], 0.1, lambda t: 0.0)
    with pytest.raises(ConfigError, match="fixed-step method"):
        simulate_batch([with_updates(Parameters(), method="rk45")], 0.1, lambda t: 0.0)


def test_a_batch_keeps_only_the_outputs_asked_for():
    params = [Parameters(), with_updates(Parameters(), payload_mass_kg=150.0)]
    out = simulate_batch(params, 0.2, lambda t: 1.0, every=10, outputs=("t", "q1"))
    assert set(out) == {"t", "q1", "failed_at_s", "failed_why", "substeps"}
    assert out["q1"].shape == (21, 2) and out["t"][-1, 0] == pytest.approx(0.2)
    assert out["q1"][-1, 0] > out["q1"][-1, 1] > out["q1"][0, 1]  # the heavier load lifts less
    with pytest.raises(ConfigError, match="unknown outputs"):
        simulate_batch(params, 0.1, lambda t: 0.0, outputs=("q1", "speed"))

"""The paper's studies: statics, dynamic cases that stop at the geometry, the solver study."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.analysis import studies
from boom_hydraulics.model import config, geometry
from boom_hydraulics.model.parameters import Parameters


def test_statics_cover_the_open_stroke_and_scale_with_the_area():
    s = studies.statics(Parameters(), (0.04, 0.08), points=50)
    assert 1.0 < s["q1"][0] < 1.01 and 1.79 < s["q1"][-1] < 1.8
    assert np.allclose(s["static_force"], geometry.static_rod_force_of(Parameters(), s["q1"], np))
    assert np.allclose(s["holding_pressure_D40mm"], 4 * s["holding_pressure_D80mm"])


def test_a_paper_case_stops_where_the_geometry_ends_and_says_why():
    tr = studies.dynamic_case(config.load(CONFIG / "paper_fig8.yaml"), 3.0)
    assert tr.stopped and "valid geometry" in tr.stopped
    assert 2.1 < tr["t"][-1] < 2.3 and np.isfinite(tr["q1"]).all() and tr["q1"][-1] < 1.8


def test_solver_study_rk4_beats_euler_by_orders_at_the_same_step():
    study = {"euler": [1e-3, 1e-4], "rk4": [1e-3]}
    euler, fine_euler, rk4 = studies.solver_study(config.load(CONFIG / "paper_fig8.yaml"), 0.5, study)
    assert rk4.error < 1e-6 < euler.error
    assert fine_euler.error < euler.error / 5  # first order: ten times smaller steps, about ten times smaller error
    # every point is kept: ten times the points (501 -> 5001) take several times the memory
    assert fine_euler.peak_mib > 3 * euler.peak_mib


@pytest.mark.skipif(shutil.which("boom-study") is None, reason="boom-study not on PATH")
def test_boom_study_paper_writes_every_figure(tmp_path):
    out = tmp_path / "figures"
    result = subprocess.run(["boom-study", "paper", "--out", out, "--duration", "1.0"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    names = {p.name for p in out.iterdir()}
    assert names == {
        "fig3_angles.png",
        "fig4_static_force.png",
        "fig5_holding_pressure.png",
        "fig8.png",
        "fig9.png",
        "fig10.png",
        "solver_study.png",
        "statics.csv",
        "solver_study.csv",
    }
    assert all((out / n).read_bytes()[:4] == b"\x89PNG" for n in names if n.endswith(".png"))

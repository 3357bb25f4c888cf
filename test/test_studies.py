"""The paper's studies: statics, dynamic cases that stop at the geometry, the solver study."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from conftest import CONFIG, ROOT, run_tool

from boom_hydraulics.analysis import paper_figures, studies
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


def test_boom_study_paper_writes_every_figure(tmp_path, monkeypatch):
    """Every figure and table, each whole. (The solver study without Euler's three finest
    steps, which take most of a minute interpreted: its errors are the test below's.)"""
    steps = {"euler": paper_figures.SOLVER_STEPS_S["euler"][:2], "rk4": paper_figures.SOLVER_STEPS_S["rk4"]}
    monkeypatch.setattr(paper_figures, "SOLVER_STEPS_S", steps)
    out = tmp_path / "figures"
    result = run_tool("boom-study", "paper", "--out", out, "--duration", "1.0")
    assert result.returncode == 0, result.stderr
    with (out / "solver_study.csv").open(newline="") as handle:
        assert len(list(csv.reader(handle))) == 1 + 7  # a row for each point of the study
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
        "fig8.csv",
        "fig9.csv",
        "fig10.csv",
        "solver_study.csv",
    }
    assert all((out / n).read_bytes()[:4] == b"\x89PNG" for n in names if n.endswith(".png"))


# --- the committed figures (docs/figures) show what the code computes today

FIGURES = ROOT / "docs" / "figures"
#: What to run when a test below fails: the committed figures are older than the model.
REGENERATE = "the committed figures are not today's model's: run tools/with-env boom-study paper --out docs/figures"


def _committed(name: str) -> tuple[list[str], list[list[str]]]:
    with (FIGURES / name).open(newline="") as handle:
        header, *rows = list(csv.reader(handle))
    return header, rows


def _close(committed: np.ndarray, fresh: np.ndarray, rtol: float) -> bool:
    """Whether two columns agree to ``rtol`` of the column's largest magnitude (a run's
    pressures to a few Pa in MPa, its time steps exactly)."""
    scale = max(float(np.max(np.abs(fresh))), 1e-300)
    return committed.shape == fresh.shape and bool(np.all(np.abs(committed - fresh) <= rtol * scale))


def test_the_committed_figs_8_to_10_show_the_dynamic_cases_as_the_model_runs_them_today():
    for name, file in paper_figures.CASES.items():
        runs = paper_figures.dynamic_runs(config.load(CONFIG / file), paper_figures.DURATION_S)
        header, rows = paper_figures.case_table(runs)
        committed_header, committed = _committed(f"{name}.csv")
        assert committed_header == header, REGENERATE
        assert [r[0] for r in committed] == [r[0] for r in rows], f"{name}: {REGENERATE}"  # the runs and their lengths
        for k, column in enumerate(header[1:], start=1):
            fresh = np.array([r[k] for r in rows], dtype=float)
            assert _close(np.array([r[k] for r in committed], dtype=float), fresh, 1e-6), (
                f"{name} {column}: {REGENERATE}"
            )


def test_the_committed_figs_3_to_5_show_the_statics_as_the_model_computes_them_today():
    statics = studies.statics(config.load(CONFIG / "default.yaml"), paper_figures.DIAMETERS_M)
    header, committed = _committed("statics.csv")
    assert header == studies.statics_header(statics), REGENERATE
    for k, (name, fresh) in enumerate(statics.items()):
        assert _close(np.array([r[k] for r in committed], dtype=float), fresh, 1e-9), f"{name}: {REGENERATE}"


def test_the_committed_solver_study_shows_the_errors_the_methods_make_today():
    """Its cheap points (RK4's largest steps, Euler's largest): the others take seconds."""
    steps = {"euler": [1e-3], "rk4": [2e-2, 1e-2]}
    fresh = studies.solver_study(config.load(CONFIG / "paper_fig8.yaml"), 1.0, steps)
    _, committed = _committed("solver_study.csv")
    errors = {(method, float(dt)): float(error) for method, dt, error, *_ in committed}
    assert set(paper_figures.SOLVER_STEPS_S) == {method for method, _ in errors}
    for point in fresh:
        assert errors[point.method, point.dt_s] == pytest.approx(point.error, rel=1e-6), REGENERATE

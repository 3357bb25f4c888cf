"""The physical model's compiled entry points (solve/physical_kernel.py) run as the Python they
are written in, put where Simulator and SetRun call the compiled code: each gives, bit for bit,
what the interpreted path gives (stepping, outputs, what a state publishes, a batch's run, the
position controller's run), and each method and layout of the state finds its own. Without
compiling anything: fast with numba or without, and what `make mutants` can measure of the
module. Not here: the lock-step blocks (blocks_*), whose numba intrinsics have no Python form."""

from __future__ import annotations

import types

import numpy as np
import pytest

from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import accelerate, commands, physical_kernel
from boom_hydraulics.solve.batch import SetRun
from boom_hydraulics.solve.closed_loop import PositionLoop
from boom_hydraulics.solve.simulation import Simulator

TABLES = ("STEPS", "OUTPUTS", "PUBLISHED", "BATCHES", "BLOCKS", "SETS")
#: the parameters without and with a model element (the elastic boom: its states in the whole layout)
LAYOUTS = {"base": {}, "elements": {"boom_bending_stiffness_n_m2": 2e5}}


@pytest.fixture
def python_kernels(monkeypatch):
    """accelerate hands out physical_kernel's entry points as Python (numba's py_func where
    numba made them), from the module's own tables."""

    def python(f):
        return getattr(f, "py_func", f)

    tables = {name: {key: python(f) for key, f in getattr(physical_kernel, name).items()} for name in TABLES}
    monkeypatch.setitem(accelerate.KERNELS, "physical", types.SimpleNamespace(**tables))
    monkeypatch.setattr(accelerate, "available", lambda: True)


def _params(method: str, layout: str, **updates) -> Parameters:
    return with_updates(Parameters(), method=method, **LAYOUTS[layout], **updates)


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize(("method", "steps"), [("euler", 40), ("rk4", 40), ("ros2", 8)])
def test_stepping_outputs_and_the_published_state_are_the_interpreted_models(python_kernels, method, steps, layout):
    params = _params(method, layout)
    assert accelerate.with_elements([params]) == (layout == "elements")
    kernel, interpreted = Simulator(params, jit=True), Simulator(params, jit=False)
    assert kernel.compiled and not interpreted.compiled
    for sim in (kernel, interpreted):
        sim.step(0.8, steps)
        sim.step(-0.3, 3)
    assert kernel.t == interpreted.t and kernel.most_substeps == interpreted.most_substeps
    assert kernel.y == interpreted.y
    assert kernel.outputs() == interpreted.outputs()
    assert kernel.published() == interpreted.published()
    assert kernel.y != Simulator(params, jit=False).y  # it moved


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("method", ["euler", "rk4"])
@pytest.mark.parametrize("sets", [1, 2])
def test_a_batchs_run_is_the_interpreted_loops(python_kernels, method, layout, sets):
    p = _params(method, layout, time_step_s=2e-4)
    params = [p, with_updates(p, payload_mass_kg=p.payload_mass_kg + 30.0)][:sets]
    runs = []
    for jit in (True, False):
        run = SetRun(params, 0.02, commands.from_parameters(p), every=7, store=True, jit=jit, slice_rows=5)
        rows = [(run.rows.copy(), run.taken.copy()) for _ in run.slices()]
        runs.append((run, rows))
    (kernel, kernel_rows), (interpreted, interpreted_rows) = runs
    assert kernel.compiled and not interpreted.compiled
    assert [k for k in range(sets) if kernel.reason(k) is not None] == []
    assert len(kernel_rows) == len(interpreted_rows) > 1
    for (a, taken_a), (b, taken_b) in zip(kernel_rows, interpreted_rows, strict=True):
        assert np.array_equal(taken_a, taken_b)
        for k in range(sets):
            assert np.array_equal(a[k, : taken_a[k]], b[k, : taken_b[k]])
    assert np.array_equal(kernel.state, interpreted.state)
    assert np.array_equal(kernel.metrics, interpreted.metrics, equal_nan=True)


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("method", ["euler", "rk4"])
def test_the_position_controllers_run_is_the_interpreted_loops(python_kernels, method, layout):
    params = _params(
        method, layout, time_step_s=2e-4, command_profile="angle", command_times_s=[0.0], command_angles_rad=[0.3]
    )
    kernel, interpreted = Simulator(params, jit=True), Simulator(params, jit=False)
    for sim in (kernel, interpreted):
        run = sim.following(PositionLoop.of_parameters([params]))
        assert run.compiled == sim.compiled
        for _ in range(3):
            sim.go_on(run, 7)
    assert kernel.t == interpreted.t == pytest.approx(0.0042)
    assert kernel.y == interpreted.y and kernel.u == interpreted.u != 0.0


@pytest.mark.parametrize("elements", [False, True])
@pytest.mark.parametrize("method", ["euler", "rk4"])
def test_from_a_block_of_sets_on_a_batch_runs_in_the_lock_step_kernel_of_its_method_and_layout(
    python_kernels, method, elements
):
    """(The blocks themselves run only compiled: here, which one a batch takes.)"""
    from boom_hydraulics.solve import lanes

    tail = "_elements" if elements else ""
    assert accelerate.batch_runner("physical", method, lanes.WIDTH, elements).__name__ == f"blocks_{method}{tail}"
    assert accelerate.batch_runner("physical", method, lanes.WIDTH - 1, elements).__name__ == f"batch_{method}{tail}"
    assert accelerate.batch_runner("physical", "ros2", lanes.WIDTH, elements) is None  # ros2 steps, no run kernel

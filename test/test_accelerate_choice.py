"""Which compiled entry point a run calls (solve/accelerate.py): the model, the method, the
number of sets and whether a set switches on a model element (an accumulator, hoses, an
elastic boom) pick the kernel, the state's layout with it. Nothing here compiles: the entries
are told apart by name (a kernel of the whole state is named ``..._elements``), so that these
tests run with numba switched off too (tools/mutants runs the model interpreted)."""

from __future__ import annotations

from typing import Any

import pytest

from boom_hydraulics import jit
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import accelerate, lanes

ACCUMULATOR = with_updates(Parameters(), accumulator_gas_volume_m3=1e-3)
HOSES = with_updates(Parameters(), hose_length_m=0.5)
ELASTIC_BOOM = with_updates(Parameters(), boom_bending_stiffness_n_m2=5e6)
PAPER = with_updates(Parameters(), mode="paper")


def name(entry: Any) -> str | None:
    """An entry point's name (a compiled one's Python function's), None for none."""
    if entry is None:
        return None
    return f"{entry.__module__.rsplit('.', 1)[-1]}.{getattr(entry, 'py_func', entry).__name__}"


@pytest.fixture
def numba_on(monkeypatch: pytest.MonkeyPatch) -> None:
    """accelerate as where numba is installed and switched on (its entries are picked, not called)."""
    monkeypatch.setattr(jit, "available", lambda: True)


def test_a_run_steps_the_elements_states_where_any_of_its_sets_switches_one_on():
    assert not accelerate.with_elements([Parameters()])
    assert not accelerate.with_elements([])
    assert not accelerate.with_elements([PAPER, Parameters()])
    for element in (ACCUMULATOR, HOSES, ELASTIC_BOOM):
        assert accelerate.with_elements([element])
        assert accelerate.with_elements([Parameters(), element, Parameters()])  # anywhere in the batch
    # the electro-mechanical actuator has no oil: an accumulator or hoses given to it are not in the model
    ema = with_updates(Parameters(), drive="electro_mechanical")
    assert not accelerate.with_elements([with_updates(ema, accumulator_gas_volume_m3=1e-3, hose_length_m=0.5)])
    assert accelerate.with_elements([with_updates(ema, boom_bending_stiffness_n_m2=5e6)])
    # the paper model has no elements: its state has no slots for them, whatever its parameters say
    assert not accelerate.with_elements([with_updates(PAPER, boom_bending_stiffness_n_m2=5e6)])


def test_a_set_read_from_a_file_steps_the_elements_it_switches_on(tmp_path):
    """The mode read from a file is a string equal to 'physical', not the program's own."""
    path = tmp_path / "accumulator.yaml"
    path.write_text("boom_sim:\n  ros__parameters:\n    mode: physical\n    accumulator_gas_volume_m3: 0.001\n")
    assert accelerate.with_elements([config.load(path)])


@pytest.mark.usefixtures("numba_on")
def test_each_model_method_and_layout_steps_with_its_own_kernel():
    for method in ("euler", "rk4"):
        assert name(accelerate.stepper("physical", method)) == f"physical_kernel.steps_{method}"
        assert name(accelerate.stepper("physical", method, True)) == f"physical_kernel.steps_{method}_elements"
        assert name(accelerate.stepper("paper", method)) == f"paper_kernel.steps_{method}"
    # ros2 keeps the whole state as a list: one kernel for both layouts
    assert name(accelerate.stepper("physical", "ros2")) == name(accelerate.stepper("physical", "ros2", True))
    assert name(accelerate.stepper("physical", "ros2")) == "physical_kernel.steps_ros2"
    assert accelerate.stepper("physical", "rk45") is None  # adaptive: no fixed step to compile
    assert accelerate.stepper("paper", "rk4", True) is None  # the paper model has no elements


@pytest.mark.usefixtures("numba_on")
def test_the_outputs_and_what_a_state_publishes_read_the_layout_the_run_steps():
    for method in ("euler", "rk4", "ros2"):
        assert name(accelerate.observer("physical", method)) == "physical_kernel.outputs_of"
        assert name(accelerate.observer("physical", method, True)) == "physical_kernel.outputs_of_elements"
        assert name(accelerate.publisher("physical", method)) == "physical_kernel.published_of"
        assert name(accelerate.publisher("physical", method, True)) == "physical_kernel.published_of_elements"
    assert name(accelerate.observer("paper", "rk4")) == "paper_kernel.outputs_of"
    assert name(accelerate.publisher("paper", "euler")) == "paper_kernel.published_of"
    # no compiled stepping, no compiled outputs: the run is interpreted throughout
    for mode, method, elements in (("physical", "rk45", False), ("physical", "rk45", True), ("paper", "rk4", True)):
        assert accelerate.observer(mode, method, elements) is None
        assert accelerate.publisher(mode, method, elements) is None


@pytest.mark.usefixtures("numba_on")
def test_a_batch_runs_in_lock_step_blocks_from_a_blocks_worth_of_sets_on():
    for method in ("euler", "rk4"):
        for elements, tail in ((False, ""), (True, "_elements")):
            one = accelerate.batch_runner("physical", method, 1, elements)
            assert name(one) == f"physical_kernel.batch_{method}{tail}"
            assert name(accelerate.batch_runner("physical", method, lanes.WIDTH - 1, elements)) == name(one)
            blocks = f"physical_kernel.blocks_{method}{tail}"
            assert name(accelerate.batch_runner("physical", method, lanes.WIDTH, elements)) == blocks
            assert name(accelerate.batch_runner("physical", method, lanes.WIDTH + 1, elements)) == blocks
            assert name(accelerate.set_runner("physical", method, elements)) == f"physical_kernel.set_{method}{tail}"
    # by default one set, the layout without the elements
    assert name(accelerate.batch_runner("physical", "rk4")) == "physical_kernel.batch_rk4"
    assert name(accelerate.set_runner("physical", "euler")) == "physical_kernel.set_euler"
    # the paper model has no blocks: its sets run one per thread however many
    assert name(accelerate.batch_runner("paper", "rk4", 2 * lanes.WIDTH)) == "paper_kernel.batch_rk4"
    # no run kernel for an implicit or adaptive method, nor one set's for the paper model
    assert accelerate.batch_runner("physical", "ros2", lanes.WIDTH) is None
    assert accelerate.batch_runner("physical", "rk45") is None
    assert accelerate.set_runner("physical", "ros2") is None
    assert accelerate.set_runner("paper", "rk4") is None


@pytest.mark.usefixtures("numba_on")
def test_a_run_waits_for_its_run_kernel_or_for_the_steps_its_interpreted_loop_calls():
    assert [name(k) for k in accelerate.run_kernels("physical", "rk4")] == ["physical_kernel.batch_rk4"]
    assert [name(k) for k in accelerate.run_kernels("physical", "euler", lanes.WIDTH, True)] == [
        "physical_kernel.blocks_euler_elements"
    ]
    assert [name(k) for k in accelerate.run_kernels("physical", "ros2", 1, True)] == ["physical_kernel.steps_ros2"]
    assert accelerate.run_kernels("physical", "rk45") == []


def test_with_numba_switched_off_nothing_is_compiled(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("BOOM_HYDRAULICS_JIT", "0")
    assert not accelerate.available()
    for elements in (False, True):
        assert accelerate.stepper("physical", "rk4", elements) is None
        assert accelerate.observer("physical", "rk4", elements) is None
        assert accelerate.publisher("physical", "rk4", elements) is None
        assert accelerate.batch_runner("physical", "rk4", lanes.WIDTH, elements) is None
        assert accelerate.set_runner("physical", "rk4", elements) is None
        assert accelerate.run_kernels("physical", "rk4", 1, elements) == []


def test_a_program_warns_of_a_compile_only_where_the_cache_lacks_a_kernel(monkeypatch: pytest.MonkeyPatch):
    held = {"loaded": True, "compiles": False, "cannot_tell": None}
    monkeypatch.setattr(jit, "in_cache", lambda entry: held[entry])
    assert not accelerate.not_in_cache([])
    assert not accelerate.not_in_cache([None, "loaded", "cannot_tell"])  # numba off or an unknown cache: no warning
    assert accelerate.not_in_cache(["loaded", "compiles"])
    assert accelerate.not_in_cache(["compiles", None])
    notice = accelerate.compiling_notice("physical", "rk4", "this sweep")
    assert "physical model's rk4" in notice and "for this sweep" in notice

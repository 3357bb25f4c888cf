"""boom-sim fmu's export in this process, and its FMU in fmpy here: a ros2 FMU, which allocates
(numba's runtime, held by the FMU's binary), steps as the Simulator does to the bit, with every
drive and its settings chosen before initialization. (Apart from test_fmu.py, whose host runs
the FMU in a Python of its own, so that the two compile beside each other.)"""

from __future__ import annotations

import sys
import zipfile
from pathlib import Path

import pytest

from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve.simulation import Simulator

OUTPUTS = ("q1", "v", "f_hyd", "p1", "p2", "alpha", "power", "supply_energy")
#: The ros2 FMU's settings: ros2's steps allocate (numba's runtime, held by the FMU's binary).
ROS2 = {"method": "ros2", "time_step_s": 0.002}


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str], list[str], list[str], Path]:
    """A ros2 FMU written by write_fmu in this process, with the kernels' cache as a user has it
    (jit.cache_folder, keyed on the model's sources): numba compiles its code where the cache
    lacks it (a machine's first run, or a changed source: about a minute), and the export
    takes it from the cache after. Its path, the folder's files after, sys.path before and
    after, and the cache folder of its object file."""
    from boom_hydraulics.fmu import native
    from boom_hydraulics.fmu.export import write_fmu

    folder = tmp_path_factory.mktemp("ros2")
    before = list(sys.path)
    write_fmu(with_updates(Parameters(), **ROS2), folder / "boom_drive.fmu")
    cached = native.cached_object_path("ros2")
    assert cached is not None
    return folder / "boom_drive.fmu", sorted(p.name for p in folder.iterdir()), before, list(sys.path), cached.parent


def _lifted_and_lowered(path: Path, name: str, changes: dict | None = None) -> list[float]:
    """The FMU at ``path`` in fmpy, in this process (instance ``name``, ``changes`` set before
    initialization), after 1 s at full command up and 1 s down in steps of 10 ms: its OUTPUTS."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    description = read_model_description(str(path))
    refs = {v.name: v.valueReference for v in description.modelVariables}
    instance = FMU2Slave(guid=description.guid, unzipDirectory=extract(str(path)), modelIdentifier="boom_drive",
                         instanceName=name)  # fmt: skip
    instance.instantiate()
    instance.setupExperiment(startTime=0.0)
    for key, value in (changes or {}).items():
        if isinstance(value, str):
            instance.setString([refs[key]], [value])
        else:
            instance.setReal([refs[key]], [value])
    instance.enterInitializationMode()
    instance.exitInitializationMode()
    for k in range(200):
        instance.setReal([refs["valve_command"]], [1.0 if k < 100 else -1.0])
        instance.doStep(k * 0.01, 0.01)
    got = instance.getReal([refs[key] for key in OUTPUTS])
    instance.terminate()
    instance.freeInstance()
    return got


def test_a_ros2_fmu_steps_as_the_simulator_and_its_export_leaves_nothing_behind(exported) -> None:
    """An FMU exported in this process with ros2 lifts and lowers as the Simulator does, to the
    bit; the export changes no sys.path and leaves nothing beside the FMU."""
    path, files, path_before, path_after, _ = exported
    assert path_after == path_before
    assert files == ["boom_drive.fmu"]
    params = with_updates(Parameters(), **ROS2)
    got = _lifted_and_lowered(path, "ros2")
    sim = Simulator(params)
    sim.step(1.0, 500)
    sim.step(-1.0, 500)
    assert got == [sim.outputs()[name] for name in OUTPUTS]


@pytest.mark.parametrize(
    "changes",
    [
        {"drive": "electro_mechanical"},
        {"drive": "pump_controlled", "eha_torque_limit_n_m": 55.0, "eha_holding_valve": "piston_side"},
        {"drive": "load_sensing", "motor_strategy": "speed_on_demand"},
        {"drive": "fixed_pump", "valve_centre": "open", "motor_strategy": "idle_stop"},
    ],
)
def test_the_drives_and_their_settings_chosen_before_initialization_step_as_the_simulator(
    exported, changes: dict
) -> None:
    """The FMU carries every drive and its settings: the actuator, the EHA as built, the valve
    drives' motor strategies and the open centre, set before initialization, lift and lower
    as the Simulator does, to the bit."""
    got = _lifted_and_lowered(exported[0], "drives", changes)
    params = with_updates(Parameters(), **ROS2, **changes)
    sim = Simulator(params)
    sim.step(1.0, round(1.0 / params.time_step_s))
    sim.step(-1.0, round(1.0 / params.time_step_s))
    assert got == [sim.outputs()[name] for name in OUTPUTS]


def test_a_second_export_takes_the_compiled_code_from_the_cache(exported, tmp_path, monkeypatch) -> None:
    """numba's object file, cached by an export, is what the next export of the method links,
    with other parameters too (they are the FMU's start values, not its code): nothing is
    compiled, and the binary is the first one's but for what the parameters change; another
    method is not taken from it."""
    from boom_hydraulics.fmu import export, native

    path, _, _, _, cache = exported
    cached = native.cached_object_path("ros2")
    assert cached is not None and cached.is_relative_to(cache) and cached.exists()
    assert native.cached_object_path("rk4") != cached

    def compiles(method: str) -> None:
        raise AssertionError(f"compiled {method} again")

    monkeypatch.setattr(native, "entry", compiles)
    export.write_fmu(with_updates(Parameters(), **ROS2), tmp_path / "again.fmu")
    with zipfile.ZipFile(path) as first, zipfile.ZipFile(tmp_path / "again.fmu") as again:
        assert again.read("binaries/linux64/boom_drive.so") == first.read("binaries/linux64/boom_drive.so")
    heavier = with_updates(Parameters(), **ROS2, payload_mass_kg=150.0)
    export.write_fmu(heavier, tmp_path / "heavier.fmu")
    got = _lifted_and_lowered(tmp_path / "heavier.fmu", "heavier")
    sim = Simulator(heavier)
    sim.step(1.0, 500)
    sim.step(-1.0, 500)
    assert got == [sim.outputs()[name] for name in OUTPUTS]

"""The numba-compiled model gives the interpreted model's trajectories."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.errors import SimulationError
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import accelerate
from boom_hydraulics.solve.commands import steps
from boom_hydraulics.solve.simulation import Simulator, simulate

pytestmark = pytest.mark.skipif(not accelerate.available(), reason="numba not installed")


@pytest.mark.parametrize(
    "params",
    [
        Parameters(),
        with_updates(Parameters(), method="euler", substeps=20, spool_time_constant_s=0.0),
        with_updates(Parameters(), method="ros2", piston_dead_volume_m3=1e-6, rod_dead_volume_m3=1e-6),
        config.load(CONFIG / "paper_fig10.yaml"),
    ],
    ids=["physical-rk4", "physical-euler-substeps", "physical-ros2-stiff", "paper-rk4"],
)
def test_compiled_and_interpreted_trajectories_agree(params):
    command = steps([0.0, 0.6, 0.9], [1.0, 0.0, -0.5]) if params.mode == "physical" else (lambda t: 1.0)
    interpreted = simulate(params, 1.2, command, jit=False)
    compiled = simulate(params, 1.2, command, jit=True)
    for name in ("q1", "v", "p1", "p2", "supply_energy"):
        ref = interpreted[name]
        scale = max(np.max(np.abs(ref)), 1e-9)
        assert np.max(np.abs(compiled[name] - ref)) <= 1e-9 * scale, name


def test_compiled_path_reports_leaving_the_geometry():
    sim = Simulator(config.load(CONFIG / "paper_fig8.yaml"), jit=True)
    with pytest.raises(SimulationError, match=r"non-finite.*valid geometry \(1, 1.8\) m"):
        sim.step(1.0, 3000)
    assert 1.7 < sim.y[0] < 1.8  # the last finite state is kept


#: A compiled run in a new process: the paper model's rk4 steps (the smallest kernel that goes
#: through jit.kernel's cache as the physical model's do, compiled in a fraction of its time).
_COMPILED_RUN = """
import sys
from boom_hydraulics.model import config
from boom_hydraulics.solve import accelerate
from boom_hydraulics.solve.simulation import Simulator
sim = Simulator(config.load(sys.argv[1]), jit=True)
sim.step(1.0, 1000)
stats = accelerate.stepper("paper", "rk4").stats
print(repr(sim.y[0]), sum(stats.cache_hits.values()), sum(stats.cache_misses.values()), stats.cache_path)
"""


def _compiled_run(env: dict) -> tuple[str, int, int, str]:
    import os
    import subprocess
    import sys

    result = subprocess.run(
        [sys.executable, "-c", _COMPILED_RUN, str(CONFIG / "paper_fig8.yaml")],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    q1, hits, misses, path = result.stdout.split()
    return q1, int(hits), int(misses), path


def test_the_compiled_model_is_cached_on_disk_and_a_new_process_loads_it(tmp_path):
    first = _compiled_run({"BOOM_HYDRAULICS_CACHE": str(tmp_path)})
    again = _compiled_run({"BOOM_HYDRAULICS_CACHE": str(tmp_path)})
    assert (first[1], first[2]) == (0, 1)  # compiled, and written
    assert (again[1], again[2]) == (1, 0)  # loaded, not compiled
    assert first[0] == again[0]  # bit for bit the same step
    (folder,) = [f for f in tmp_path.iterdir() if first[3].startswith(str(f))]  # keyed on a hash of the sources
    assert list(folder.rglob("paper_kernel.steps_rk4-*.nbi"))


def test_the_cache_folder_follows_every_source_of_the_kernel(tmp_path, monkeypatch):
    from boom_hydraulics import jit
    from boom_hydraulics.solve import physical_kernel

    monkeypatch.setenv("BOOM_HYDRAULICS_CACHE", str(tmp_path))
    copies = []
    for path in physical_kernel.SOURCES:  # the same files, one at a time with a changed line
        copy = tmp_path / "src" / path.relative_to(jit.PACKAGE)
        copy.parent.mkdir(parents=True, exist_ok=True)
        copy.write_bytes(path.read_bytes())
        copies.append(copy)
    monkeypatch.setattr(jit, "PACKAGE", tmp_path / "src")
    key = jit.cache_folder(copies)
    assert key == jit.cache_folder(copies) and key.parent == tmp_path
    for copy in copies:
        text = copy.read_bytes()
        copy.write_bytes(text + b"# changed\n")
        assert jit.cache_folder(copies) != key, copy.name
        copy.write_bytes(text)


def test_an_unwritable_cache_folder_falls_back_and_still_compiles(tmp_path):
    blocked = tmp_path / "a_file"
    blocked.write_text("")  # a folder cannot be made under a file, whoever runs this
    q1, hits, misses, path = _compiled_run({"BOOM_HYDRAULICS_CACHE": str(blocked / "cache")})
    assert float(q1) > 1.5 and hits + misses == 1  # lifted from its initial 1.37 m; compiled (or loaded)
    assert not path.startswith(str(blocked))


def test_in_cache_tells_a_kernel_its_first_call_compiles_from_one_it_loads(tmp_path):
    """What boom-sweep's 'not compiled on this machine yet' line rests on: numba's cache holds a
    kernel once a process compiled it, for that process and the next."""
    import os
    import subprocess
    import sys
    import textwrap

    (tmp_path / "tiny_kernel.py").write_text(
        textwrap.dedent(
            """
            from boom_hydraulics import jit
            from boom_hydraulics.model import geometry

            @jit.kernel(jit.module_sources(geometry))
            def twice(x):
                return 2.0 * x
            """
        )
    )
    script = (
        "import tiny_kernel as k; from boom_hydraulics import jit\n"
        "before = jit.in_cache(k.twice); k.twice(1.0); print(before, jit.in_cache(k.twice))"
    )
    env = {
        **os.environ,
        "BOOM_HYDRAULICS_CACHE": str(tmp_path / "cache"),
        "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]),
    }
    runs = [subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=120)
            for _ in range(2)]  # fmt: skip
    assert [r.stdout.split() for r in runs] == [["False", "True"], ["True", "True"]], [r.stderr for r in runs]


def test_a_simulator_tells_whether_its_warm_up_compiles(monkeypatch):
    """What the node's 'compiling ...' line rests on: after warm() the cache holds every kernel
    it stepped with; where the cache lacks one, the start compiles; interpreted, nothing does."""
    from boom_hydraulics import jit

    sim = Simulator(Parameters(), jit=True)
    sim.warm()
    # stepping, outputs, what a state publishes, the controller's run
    assert [jit.in_cache(k) for k in sim.warm_kernels()] == [True] * 4
    assert not sim.compiles_first()
    asked = []

    def first_held(entry: object) -> bool:
        asked.append(entry)
        return len(asked) == 1

    monkeypatch.setattr(jit, "in_cache", first_held)
    assert sim.compiles_first() and len(asked) >= 2  # the first kernel held, a later one not
    assert not Simulator(Parameters(), jit=False).compiles_first()


def test_a_run_asks_the_cache_for_what_it_calls_and_a_kernel_without_one_always_compiles():
    """run_kernels: a method the run loop compiles, its run kernel (blocks from 4 sets on); ros2,
    the compiled steps its interpreted loop calls. A kernel made without a cache folder compiles
    in every process: in_cache says so (False), where numba missing says nothing (None)."""
    import numba

    from boom_hydraulics import jit

    assert accelerate.run_kernels("physical", "rk4") == [accelerate.batch_runner("physical", "rk4")]
    assert accelerate.run_kernels("physical", "rk4", 4) == [accelerate.batch_runner("physical", "rk4", 4)]
    assert accelerate.batch_runner("physical", "ros2") is None
    assert accelerate.run_kernels("physical", "ros2") == [accelerate.stepper("physical", "ros2")]
    cacheless = numba.njit(cache=False)(lambda x: 2.0 * x)
    assert jit.in_cache(cacheless) is False
    cacheless(1.0)
    assert jit.in_cache(cacheless) is True  # compiled in this process: its next call does not wait
    assert jit.in_cache(None) is None and jit.in_cache(lambda x: x) is None

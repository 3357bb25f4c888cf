"""boom-sweep as a user runs it: outputs, Dask against local, resuming, interrupting, bad input."""

from __future__ import annotations

import csv
import os
import shlex
import shutil
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import CONFIG, ROOT, run_tool

BOOM_SWEEP = shutil.which("boom-sweep")
pytestmark = pytest.mark.skipif(BOOM_SWEEP is None, reason="boom-sweep not on PATH (run through tools/with-env)")

FOUR_POINTS = ["--vary", "piston_diameter=0.04,0.06", "--vary", "payload=0,150", "--duration", "1.5"]
FOUR_POINTS += ["--lift-angle-deg", "8", "--no-plots"]


def _sweep(*args: object) -> subprocess.CompletedProcess:
    """boom-sweep's main in this process (conftest.run_tool): the tests that signal it run the real one."""
    return run_tool("boom-sweep", *args)


def _load(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as data:
        return {name: data[name] for name in data.files}


def _assert_tables_equal(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert list(a) == list(b)
    for name in a:
        if a[name].dtype.kind == "f":
            assert np.array_equal(a[name], b[name], equal_nan=True), name
        else:
            assert (a[name] == b[name]).all(), name


def test_a_sweep_writes_its_table_plots_and_recommendation(tmp_path):
    out = tmp_path / "sweep"
    args = ["--config", CONFIG / "default.yaml", *FOUR_POINTS[:-1], "--out", out]
    result = _sweep(*args, "--recommend", "--max-pressure-pa", "30e6", "--require", "lift_time_s<=5")
    assert result.returncode == 0, result.stderr
    with (out / "results.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [(float(r["piston_diameter_m"]), float(r["payload_mass_kg"])) for r in rows] == [
        (0.04, 0.0),
        (0.04, 150.0),
        (0.06, 0.0),
        (0.06, 150.0),
    ]
    assert {r["status"] for r in rows} == {"ok"}
    times = [float(r["lift_time_s"]) for r in rows]
    assert times[0] < times[2] and times[0] < times[1]  # the small bore lifts the light load fastest
    for png in ("metrics_vs_piston_diameter_m.png", "metrics_vs_payload_mass_kg.png", "trade_off.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = (out / "recommendation.txt").read_text()
    assert "peak_pressure_pa <= 3e+07" in text and "lift_time_s <= 5" in text
    assert "4 of 4 designs meet every constraint" in text
    ranked = _load(out / "recommendation.npz")
    assert np.all(np.diff(ranked["lift_energy_j"]) >= 0)
    assert text in result.stdout

    # all batches done: a new question re-ranks the stored results without running anything
    worst_40mm, worst_60mm = max(times[:2]), max(times[2:])
    assert worst_40mm < worst_60mm
    again = _sweep(*args, "--resume", "--across", "payload", "--max-lift-time-s", worst_40mm)
    assert again.returncode == 0, again.stderr
    assert "1 done before, 0 to run" in again.stderr
    text = (out / "recommendation.txt").read_text()
    assert "1 of 2 designs meet every constraint" in text  # 40 mm lifts both payloads in time, 60 mm not
    designs = _load(out / "recommendation.npz")
    assert designs["piston_diameter_m"].tolist() == [0.04] and designs["points"].tolist() == [2]


def test_a_sweep_says_when_its_batches_compile_the_run_kernel(tmp_path, monkeypatch):
    """Without the kernel in numba's cache, the batches compile it for a minute: the sweep says
    so before, once for its model and method; with it there (as after this process ran one
    sweep), it says nothing."""
    from boom_hydraulics import jit
    from boom_hydraulics.solve import accelerate

    args = ["--config", CONFIG / "default.yaml", *FOUR_POINTS]
    assert _sweep(*args, "--out", tmp_path / "first").returncode == 0
    if accelerate.available():  # the cache holds the kernel of a batch of 4 (read from numba's own index)
        assert [jit.in_cache(k) for k in accelerate.run_kernels("physical", "rk4", 4)] == [True]
    line = (
        "boom-sweep: the physical model's rk4 is not compiled on this machine yet: compiling it for its batches takes"
    )
    cached = _sweep(*args, "--out", tmp_path / "cached")
    assert cached.returncode == 0 and "not compiled" not in cached.stderr, cached.stderr
    monkeypatch.setattr(jit, "in_cache", lambda run: False)
    five = ["--config", CONFIG / "default.yaml", "--vary", "payload=0:200:5", "--duration", "0.2", "--no-plots"]
    cold = _sweep(*five, "--batch-size", 4, "--out", tmp_path / "cold")  # a block of 4, then 1 set: two kernels
    assert cold.returncode == 0 and cold.stderr.count(line) == 1, cold.stderr


def test_a_sweep_loads_each_kernel_in_its_main_thread_before_the_batches_that_call_it(tmp_path, monkeypatch):
    """boom-sweep loads (or compiles) the run kernel of each kind of batch in its main thread,
    where a Ctrl-C stops a compile, once, before the first batch of that kind runs; the batches
    themselves run in the executor's threads. Five points in batches of 4: a block of 4 sets,
    then 1 set, two kernels."""
    import threading

    from boom_hydraulics.sweeps import sweep

    main, events = threading.get_ident(), []
    load_kernel, run_batch = sweep.load_kernel, sweep.run_batch

    def loading(batch):
        events.append(("load", batch.index, threading.get_ident() == main))
        load_kernel(batch)

    def running(batch):
        events.append(("run", batch.index, threading.get_ident() == main))
        return run_batch(batch)

    monkeypatch.setattr(sweep, "load_kernel", loading)
    monkeypatch.setattr(sweep, "run_batch", running)
    five = ["--config", CONFIG / "default.yaml", "--vary", "payload=0:200:5", "--duration", "0.2", "--no-plots"]
    done = _sweep(*five, "--batch-size", 4, "--out", tmp_path / "s")
    assert done.returncode == 0, done.stderr
    assert [e for e in events if e[0] == "load"] == [("load", 0, True), ("load", 1, True)]
    runs = [e for e in events if e[0] == "run"]
    assert sorted(index for _, index, _ in runs) == [0, 1] and not any(in_main for *_, in_main in runs)
    for index in (0, 1):  # each batch after its kernel's load
        assert events.index(("load", index, True)) < next(k for k, e in enumerate(events) if e[:2] == ("run", index))


def test_the_summary_says_what_a_status_other_than_ok_means(tmp_path):
    short = _sweep("--config", CONFIG / "default.yaml", "--vary", "payload=0,150", "--duration", "0.2", "--no-plots",
                   "--out", tmp_path / "short")  # fmt: skip
    assert short.returncode == 0, short.stderr
    assert "2 points: 2 incomplete (did not lift through --lift-angle-deg within --duration)" in short.stdout


def test_a_local_dask_cluster_gives_the_same_table_as_this_process(tmp_path):
    local = _sweep(*FOUR_POINTS, "--batch-size", "3", "--out", tmp_path / "local")
    assert local.returncode == 0, local.stderr
    dask = _sweep(*FOUR_POINTS, "--batch-size", "1", "--workers", "2", "--out", tmp_path / "dask")
    assert dask.returncode == 0, dask.stderr
    assert "on a local Dask cluster of 2 processes" in dask.stderr
    _assert_tables_equal(_load(tmp_path / "local" / "results.npz"), _load(tmp_path / "dask" / "results.npz"))


def test_resume_reuses_finished_batches_and_runs_only_the_rest(tmp_path):
    out = tmp_path / "sweep"
    first = _sweep(*FOUR_POINTS, "--batch-size", "1", "--out", out)
    assert first.returncode == 0, first.stderr
    complete = _load(out / "results.npz")
    batches = sorted((out / "batches").glob("[0-9]*.npz"))
    assert len(batches) == 4
    for path in batches[2:]:
        path.unlink()
    marked = _load(batches[0])  # a stored batch is taken as it is, not computed again
    marked["lift_time_s"] = np.array([123.0])
    np.savez(batches[0], **marked)

    again = _sweep(*FOUR_POINTS, "--batch-size", "1", "--out", out)
    assert again.returncode == 2 and "pass --resume" in again.stderr

    resumed = _sweep(*FOUR_POINTS, "--out", out, "--resume")  # in the batches it began with
    assert resumed.returncode == 0, resumed.stderr
    assert "2 done before, 2 to run" in resumed.stderr
    table = _load(out / "results.npz")
    point0 = int(marked["point"][0])
    assert table["lift_time_s"][point0] == 123.0
    others = [i for i in range(4) if i != point0]
    assert np.array_equal(table["lift_time_s"][others], complete["lift_time_s"][others])

    changed = _sweep(
        *FOUR_POINTS[:-3], "--lift-angle-deg", 9, "--no-plots", "--batch-size", 1, "--out", out, "--resume"
    )
    assert changed.returncode == 2 and "differs in: lift_angle_deg" in changed.stderr


@pytest.mark.parametrize(
    ("stop", "status", "why"),
    [(signal.SIGINT, 130, "interrupted (Ctrl-C)"), (signal.SIGTERM, 143, "terminated (SIGTERM)")],
)
def test_an_interrupted_sweep_keeps_its_finished_batches_and_says_how_to_resume(tmp_path, stop, status, why):
    out = tmp_path / "sweep"
    # 8 batches of a 10-minute lift: about half a second each, compiled, so the signal lands midway
    args = ["--vary", "payload=0:200:8", "--duration", "600", "--batch-size", "1", "--no-plots", "--out", out]
    process = subprocess.Popen([BOOM_SWEEP, *map(str, args)], stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    # finished batches only: a batch being written is a hidden .partial.npz until it is whole
    while not list((out / "batches").glob("[0-9]*.npz")) and time.monotonic() < deadline:
        time.sleep(0.1)
    process.send_signal(stop)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == status, stderr
    kept = list((out / "batches").glob("[0-9]*.npz"))
    assert 1 <= len(kept) < 8
    last = stderr.splitlines()[-1]
    assert last.startswith(f"boom-sweep: error: {why}; ") and f"of 8 batches are stored in {out}" in last, stderr
    hint = shlex.split(last.partition("finish with: ")[2])
    if "BOOM_HYDRAULICS_WITH_ENV" in os.environ:  # (the tests run through tools/with-env: the hint names it)
        assert Path(hint.pop(0)).resolve() == (ROOT / "tools" / "with-env").resolve(), last
    assert last.endswith(" --resume") and hint == ["boom-sweep", *map(str, args), "--resume"], last
    assert stderr.count("error") == 1 and "Traceback" not in stderr, stderr
    # nothing half-written: only whole batches and the description, no temporaries
    assert sorted(p.name for p in out.iterdir()) == ["batches", "sweep.json"]
    assert sorted(p.name for p in (out / "batches").iterdir()) == sorted(p.name for p in kept)
    resumed = _sweep(*args, "--resume")
    assert resumed.returncode == 0, resumed.stderr
    assert f"{len(kept)} done before, {8 - len(kept)} to run" in resumed.stderr
    assert len(_load(out / "results.npz")["point"]) == 8


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--vary", "piston_diamter=0.04,0.06"], "did you mean piston_diameter_m"),
        (["--vary", "payload=0:200"], "range without a count"),
        (["--config", "nosuch.yaml"], "nosuch.yaml"),
        (["--scenario", "hover"], "unknown scenario 'hover'"),
        (["--require", "peak<=1"], "unknown metric 'peak'"),
        (["--duration", "nan"], "--duration must be a finite number"),
        # it blamed the config's command_times_s, which the user never set
        (["--duration", "1e12"], "--duration 1e+12 s is longer than a scenario's commands can span"),
        (["--duration", "1000000.5"], "choose a duration of at most 1e+06 s"),
        (["--vary", "payload=0,100", "--across", "bulk_modulus"], "--across bulk_modulus_pa: not a varied parameter"),
        (["--workers", "2", "--scheduler", "tcp://localhost:8786"], "not allowed with argument"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, args, message):
    result = _sweep(*args, "--out", tmp_path / "sweep")
    assert result.returncode == 2
    assert message in result.stderr and result.stderr.count("\n") == 1, result.stderr
    assert not (tmp_path / "sweep").exists()


def test_an_unreachable_scheduler_is_named_and_leaves_no_folder(tmp_path):
    result = _sweep(
        "--vary", "payload=0", "--scheduler", "tcp://127.0.0.1:9", "--scheduler-timeout", "1", "--out", tmp_path / "s"
    )
    assert result.returncode == 2
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in result.stderr
    assert not (tmp_path / "s").exists()


def test_a_folder_holding_other_files_takes_the_sweep_and_keeps_them(tmp_path):
    """--out . is fine: the sweep writes only its own names beside the user's files."""
    (tmp_path / "notes.txt").write_text("mine")
    result = _sweep(
        "--vary", "payload=0", "--duration", "0.5", "--lift-angle-deg", "8", "--no-plots", "--out", tmp_path
    )
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "batches",
        "notes.txt",
        "results.csv",
        "results.npz",
        "sweep.json",
    ]


def test_a_folder_holding_a_file_of_the_sweeps_names_but_no_sweep_is_not_touched(tmp_path):
    (tmp_path / "results.csv").write_text("mine")
    result = _sweep("--vary", "payload=0", "--out", tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert "holds results.csv but no sweep.json" in result.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["results.csv"] and (tmp_path / "results.csv").read_text() == "mine"


SPREAD = ["--vary", "piston_diameter=0.032,0.06", "--vary", "payload=0,200", "--duration", "3"]
SPREAD += ["--lift-angle-deg", "8", "--no-plots"]


@pytest.mark.parametrize(
    ("flag", "keeps"),
    [
        (["--no-cavitation"], lambda r: r["cavitation_s"] == 0),
        (["--max-pressure-pa", "1e7"], lambda r: r["peak_pressure_pa"] <= 1e7),
        (["--max-lift-time-s", "0.6"], lambda r: r["lift_time_s"] <= 0.6),
        (["--require", "damping_ratio>=0.05"], lambda r: r["damping_ratio"] >= 0.05),  # nan: no ringing, out
    ],
)
def test_each_constraint_flag_keeps_exactly_the_designs_that_meet_it(tmp_path_factory, flag, keeps):
    """The four points differ in each metric (32 mm cavitates, 60 mm does not; peak pressures
    8-18 MPa; lift times 0.2-1.3 s; damping nan to 0.1): every flag picks another set."""
    out = tmp_path_factory.getbasetemp() / "spread"
    args = ["--config", CONFIG / "default.yaml", *SPREAD, "--out", out]
    if not (out / "results.npz").exists():
        assert _sweep(*args).returncode == 0
    result = _sweep(*args, "--resume", *flag)  # re-ranks the stored points
    assert result.returncode == 0, result.stderr
    table = _load(out / "results.npz")
    rows = [{name: table[name][i] for name in table} for i in range(len(table["status"]))]
    expected = {(r["piston_diameter_m"], r["payload_mass_kg"]) for r in rows if r["status"] == "ok" and keeps(r)}
    assert 0 < len(expected) < 4  # the flag matters here
    ranked = _load(out / "recommendation.npz")
    assert set(zip(ranked["piston_diameter_m"].tolist(), ranked["payload_mass_kg"].tolist())) == expected

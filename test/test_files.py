"""Results are written whole or not at all, and never over what a tool did not write."""

from __future__ import annotations

import os
import stat

import pytest

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.files import atomic_path, check_apart, results_folder, write_csv


def test_results_folder_replaces_only_the_files_it_names(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("the user's")
    (out / "old.csv").write_text("old result")
    (out / "keep").mkdir()
    with results_folder(out) as stage:
        (stage / "old.csv").write_text("new result")
        (stage / "new.png").write_bytes(b"png")
    assert (out / "mine.txt").read_text() == "the user's"
    assert (out / "keep").is_dir()
    assert (out / "old.csv").read_text() == "new result"
    assert sorted(p.name for p in out.iterdir()) == ["keep", "mine.txt", "new.png", "old.csv"]  # no staging left


def test_a_failing_run_leaves_the_folder_as_it_was(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.csv").write_text("old result")
    with pytest.raises(RuntimeError), results_folder(out) as stage:
        (stage / "old.csv").write_text("half")
        raise RuntimeError("plotting failed")
    assert [p.name for p in out.iterdir()] == ["old.csv"]
    assert (out / "old.csv").read_text() == "old result"


def test_a_failing_run_removes_only_the_folders_it_created(tmp_path):
    out = tmp_path / "a" / "b" / "out"
    with pytest.raises(RuntimeError), results_folder(out):
        raise RuntimeError("no")
    assert list(tmp_path.iterdir()) == []  # a/, a/b/ and out/ were this run's
    (tmp_path / "user").mkdir()
    with pytest.raises(RuntimeError), results_folder(tmp_path / "user" / "out"):
        raise RuntimeError("no")
    assert [p.name for p in tmp_path.iterdir()] == ["user"]  # the user's folder stays


def test_the_output_may_not_be_or_hold_an_input(tmp_path):
    bag = tmp_path / "run2"
    bag.mkdir()
    with pytest.raises(ConfigError, match="is the input"):
        check_apart(bag, [bag])
    with pytest.raises(ConfigError, match="holds the input"):
        check_apart(tmp_path, [bag])
    with pytest.raises(ConfigError, match="holds the input"):
        check_apart(tmp_path / ".", [tmp_path / "x" / ".." / "run2"])  # spelled differently, same place
    check_apart(tmp_path / "run2.analysis", [bag])  # beside it: fine
    check_apart(bag / "analysis", [bag])  # inside it adds files, holds nothing: fine


def test_a_file_is_whole_or_absent_and_gets_the_usual_mode(tmp_path):
    target = tmp_path / "run.csv"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("disk full")
    assert target.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["run.csv"]
    write_csv(target, ["a [m]"], [["1.0"]])
    assert target.read_text().splitlines() == ["a [m]", "1.0"]
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask  # not mkstemp's private 0600
    with pytest.raises(ConfigError, match="is a folder"):
        write_csv(tmp_path, ["a"], [])


def _dead_pid() -> int:
    import subprocess

    child = subprocess.Popen(["true"])
    child.wait()
    return child.pid


def test_a_stopped_runs_staging_folder_is_removed_and_an_old_one_named(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    stale = out / f".partial-{_dead_pid()}-k2j_x9"
    stale.mkdir()
    (stale / "a.csv").write_text("half")
    live = out / f".partial-{os.getpid()}-k2j_x9"  # a run of this process: still going
    live.mkdir()
    old = out / ".partial-q8w2e1"  # left by a version that put no process id in the name
    old.mkdir()
    with results_folder(out) as stage:
        (stage / "a.csv").write_text("whole")
    assert sorted(p.name for p in out.iterdir()) == sorted(["a.csv", live.name, old.name])
    err = capsys.readouterr().err
    assert f"removed {stale}" in err and f"{old} holds the unfinished results of an earlier run" in err


def test_an_os_error_names_the_target_not_the_temporary_file(tmp_path):
    import errno

    target = tmp_path / "result.csv"
    with pytest.raises(OSError) as caught, atomic_path(target) as tmp:
        raise OSError(errno.ENOSPC, "No space left on device")  # a write on a full disk names no file
    assert caught.value.errno == errno.ENOSPC and caught.value.filename == str(target)
    with pytest.raises(OSError) as caught, atomic_path(target) as tmp:
        tmp.write_text("x")
        raise OSError(errno.EIO, "Input/output error", str(tmp))
    assert caught.value.filename == str(target)
    with pytest.raises(OSError) as caught, results_folder(tmp_path / "out") as stage:
        raise OSError(errno.ENOSPC, "No space left on device", str(stage / "a.png"))
    assert caught.value.filename == str(tmp_path / "out" / "a.png")
    assert list(tmp_path.iterdir()) == []


def test_a_table_written_column_by_column_has_csv_writers_bytes(tmp_path, monkeypatch):
    import csv

    import numpy as np

    from boom_hydraulics import files

    text = np.array(["ok", "", 'say "hi"', "a, b", "two\nlines", "cr\rhere", "ok"])
    columns = [
        np.arange(7),
        np.array([0.1, np.nan, np.inf, -0.0, 1e300, 5e-324, 2.0]),
        np.array([True, False, True, True, False, False, True]),
        text,
        np.array([1, "x,y", 2.5, True, "", "q", "r"], dtype=object),
    ]
    header = ["point", "value", "flag", "reason", "mixed"]
    monkeypatch.setattr(files, "CSV_CHUNK_ROWS", 3)  # several chunks, the last a part one
    files.write_csv_columns(tmp_path / "columns.csv", header, columns)
    files.write_csv(tmp_path / "rows.csv", header, zip(*(files.csv_column(c) for c in columns)))
    assert (tmp_path / "columns.csv").read_bytes() == (tmp_path / "rows.csv").read_bytes()
    with (tmp_path / "columns.csv").open(newline="") as handle:
        read = list(csv.reader(handle))
    assert [row[3] for row in read[1:]] == text.tolist()

    files.write_csv_columns(tmp_path / "one.csv", ["reason"], [np.array(["", "a", ""])])
    files.write_csv(tmp_path / "one_rows.csv", ["reason"], [[""], ["a"], [""]])
    assert (tmp_path / "one.csv").read_bytes() == (tmp_path / "one_rows.csv").read_bytes()

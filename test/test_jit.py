"""jit.py, the project's two decorators and numba's cache of them, on tiny kernels: what a user
sees of it is the compiled model's speed, a first run's compile (once per machine and source)
and its cache folder. Each test compiles a function or two of a line, in a cache folder of
its own, never the model's kernels (see test_accelerate.py for those)."""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

from boom_hydraulics import jit
from boom_hydraulics.model import geometry, hydraulics

numba = pytest.importorskip("numba")

#: Sources for the tiny kernels' cache key (any files of the package do).
SOURCES = jit.module_sources(geometry)


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A cache folder of the test's own, numba switched on, the folder lookup not remembered."""
    monkeypatch.setenv("BOOM_HYDRAULICS_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("BOOM_HYDRAULICS_JIT", raising=False)
    remembered = jit._folder
    remembered.cache_clear()
    yield tmp_path / "cache"
    remembered.cache_clear()


def test_numba_is_on_unless_the_switch_says_0(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.delenv("BOOM_HYDRAULICS_JIT", raising=False)
    assert jit.available()
    for value, on in [("0", False), ("1", True), ("", True), ("no", True)]:
        monkeypatch.setenv("BOOM_HYDRAULICS_JIT", value)
        assert jit.available() is on, value
    monkeypatch.delenv("BOOM_HYDRAULICS_JIT")
    monkeypatch.setattr(jit, "numba", None)  # numba not installed
    assert not jit.available()


@jit.jitable
def _scaled(x: float) -> float:
    return 3.0 * x + 1.0


@jit.jitable(inline="always")
def _inlined(x: float) -> float:
    return _scaled(x) - 2.0


def test_a_jitable_function_stays_itself_and_compiled_code_calls_it():
    """@jitable and @jitable(inline=...) leave the Python function callable as written, and a
    compiled caller compiles it into itself (numba.extending.register_jitable)."""
    assert _scaled(2.0) == 7.0 and _inlined(2.0) == 5.0
    assert _scaled.__name__ == "_scaled" and _inlined.__name__ == "_inlined"

    @numba.njit
    def caller(x: float) -> float:
        return _scaled(x) + _inlined(x)

    assert caller(2.0) == 12.0


def test_tuple_like_is_the_rows_first_values_interpreted_and_compiled():
    row = np.arange(6.0)
    assert jit.tuple_like(row, (0.0,) * 3) == (0.0, 1.0, 2.0)
    assert jit.tuple_like(row, (0.0,) * 6) == tuple(row)

    @numba.njit
    def first_three(r: np.ndarray) -> tuple:
        return jit.tuple_like(r, (0.0, 0.0, 0.0))

    out = first_three(row)
    assert out == (0.0, 1.0, 2.0) and isinstance(out, tuple)
    assert str(first_three.nopython_signatures[0].return_type) == "UniTuple(float64 x 3)"  # on the stack
    with pytest.raises(numba.core.errors.TypingError):  # a template that is no tuple has no compiled form
        numba.njit(lambda r: jit.tuple_like(r, [0.0, 0.0]))(row)


def test_tuple_size_is_a_compiled_tuples_length_and_none_for_anything_else(monkeypatch: pytest.MonkeyPatch):
    assert jit.tuple_size(numba.typeof((1.0, 2.0, 3.0))) == 3
    assert jit.tuple_size(numba.typeof((1.0, 2))) == 2  # a tuple of mixed types too
    assert jit.tuple_size(numba.typeof(())) == 0
    assert jit.tuple_size(numba.types.List(numba.float64)) is None
    assert jit.tuple_size(numba.float64) is None
    monkeypatch.setattr(jit, "numba", None)
    assert jit.tuple_size((1.0, 2.0)) is None


def _counted(x: float) -> float:
    return x + 1.0


def test_compiled_as_gives_compiled_code_its_own_form_and_python_the_function(monkeypatch: pytest.MonkeyPatch):
    """The few primitives numba cannot compile as written run compiled by the registered form."""

    def _typing(x):  # no annotations: numba matches them against the implementation's
        def implementation(x):
            return x + 2.0

        return implementation

    assert jit.compiled_as(_counted)(_typing) is _typing  # the typing function itself is handed back
    assert _counted(1.0) == 2.0  # interpreted: the function as written
    assert numba.njit(lambda x: _counted(x))(1.0) == 3.0  # compiled: the registered form

    def _unregistered(x: float) -> float:
        return x

    monkeypatch.setattr(jit, "numba", None)  # without numba nothing is registered, nothing fails
    assert jit.compiled_as(_unregistered)(_typing) is _typing
    with pytest.raises(numba.core.errors.TypingError):  # no compiled form registered
        numba.njit(lambda x: _unregistered(x))(1.0)


def test_the_cache_key_follows_the_versions_and_the_sources_names_and_not_their_order(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """A numba or Python upgrade, a renamed or changed source gives a fresh folder (numba's own
    check reads only the entry point's file); the order sources are listed in does not."""
    monkeypatch.setenv("BOOM_HYDRAULICS_CACHE", str(tmp_path))
    two = jit.module_sources(geometry, hydraulics)
    key = jit.cache_folder(two)
    assert key.parent == tmp_path and len(key.name) == 16 and int(key.name, 16) >= 0
    assert jit.cache_folder(list(reversed(two))) == key
    assert jit.cache_folder(two[:1]) != key
    monkeypatch.setattr(numba, "__version__", numba.__version__ + ".post1")
    assert jit.cache_folder(two) != key
    monkeypatch.undo()
    monkeypatch.setenv("BOOM_HYDRAULICS_CACHE", str(tmp_path))
    monkeypatch.setattr(sys, "version", sys.version + " patched")
    assert jit.cache_folder(two) != key
    monkeypatch.setattr(sys, "version", sys.version.removesuffix(" patched"))
    assert jit.cache_folder(two) == key
    # the same text under another name in the package is another source
    package = tmp_path / "package"
    (package / "model").mkdir(parents=True)
    for path in two:
        (package / "model" / path.name).write_bytes(path.read_bytes())
    monkeypatch.setattr(jit, "PACKAGE", package)
    copies = [package / "model" / path.name for path in two]
    assert jit.cache_folder(copies) == key
    renamed = package / "model" / "renamed.py"
    copies[0].rename(renamed)
    assert jit.cache_folder([renamed, copies[1]]) != key
    assert list(key.iterdir()) == []  # the writability probe is not left behind


def test_the_cache_folder_is_the_configured_one_else_the_users_cache_else_the_temporary_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.delenv("BOOM_HYDRAULICS_CACHE", raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    key = jit.cache_folder(SOURCES).name
    users = tmp_path / "home" / ".cache" / "boom_hydraulics" / "numba" / key
    assert jit.cache_folder(SOURCES) == users
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    xdg = tmp_path / "xdg" / "boom_hydraulics" / "numba" / key
    assert jit.cache_folder(SOURCES) == xdg
    monkeypatch.setenv("BOOM_HYDRAULICS_CACHE", str(tmp_path / "mine"))
    assert jit.cache_folder(SOURCES) == tmp_path / "mine" / key  # the configured one, as it is named
    blocked = tmp_path / "a_file"
    blocked.write_text("")  # no folder can be made under a file, whoever runs this
    monkeypatch.setenv("BOOM_HYDRAULICS_CACHE", str(blocked / "cache"))
    fallback = tmp_path / "tmp" / f"boom_hydraulics-numba-{os.getuid()}" / key
    assert jit.cache_folder(SOURCES) == fallback  # not the user's cache: the one configured is not it
    monkeypatch.delenv("BOOM_HYDRAULICS_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocked / "xdg"))
    assert jit.cache_folder(SOURCES) == fallback
    monkeypatch.setattr(tempfile, "tempdir", str(blocked / "tmp"))
    assert jit.cache_folder(SOURCES) is None  # nowhere to write: the kernels compile uncached
    for folder in (users, xdg, tmp_path / "mine" / key, fallback):  # made, the writability probe not left in them
        assert folder.is_dir() and list(folder.iterdir()) == [], folder


def _inverse(x: float) -> float:
    return 1.0 / x


def _inverse_sum(values: np.ndarray) -> float:
    total = 0.0
    for i in jit.prange(values.size):
        total += 1.0 / values[i]
    return total


def test_a_batch_loop_is_numbas_parallel_range_where_compiled(monkeypatch: pytest.MonkeyPatch):
    """jit.prange, the loop over a batch's sets: numba's prange (a kernel made with parallel=True
    spreads it over the cores), Python's range without numba."""
    import importlib

    assert jit.prange is numba.prange
    monkeypatch.setitem(sys.modules, "numba", None)  # numba not installed
    try:
        without = importlib.reload(jit)
        assert without.prange is range and without.numba is None and not without.available()
    finally:
        monkeypatch.undo()
        importlib.reload(jit)
    assert jit.prange is numba.prange


def test_a_kernel_is_compiled_without_the_gil_with_numpys_division_and_cached_in_its_sources_folder(cache: Path):
    saved = numba.config.CACHE_DIR
    inverse = jit.kernel(SOURCES)(_inverse)
    assert numba.config.CACHE_DIR == saved  # numba's setting is put back
    assert inverse.targetoptions["nogil"] and not inverse.targetoptions["parallel"]
    assert not jit.in_cache(inverse)
    assert inverse(0.0) == np.inf  # numpy's error model: a division by 0 raises nothing
    assert inverse(4.0) == 0.25
    folder = jit.cache_folder(SOURCES)
    assert folder.parent == cache and list(folder.rglob("*_inverse-*.nbi"))
    # a new process (here a new dispatcher of the same function) loads it
    again = jit.kernel(SOURCES)(_inverse)
    assert again is not inverse and jit.in_cache(again) is True
    assert again(0.5) == 2.0 and again.stats.cache_hits and not again.stats.cache_misses
    summed = jit.kernel(SOURCES, parallel=True)(_inverse_sum)
    assert summed.targetoptions["parallel"] and summed.targetoptions["nogil"]
    assert summed(np.array([1.0, 2.0, 4.0])) == 1.75


def test_a_kernel_looks_its_folder_up_once_per_sources_and_compiles_uncached_where_none_is_writable(
    cache: Path, monkeypatch: pytest.MonkeyPatch
):
    looked = []
    real = jit.cache_folder

    def counted(sources: object) -> object:
        looked.append(sources)
        return real(sources)

    monkeypatch.setattr(jit, "cache_folder", counted)
    jit.kernel(SOURCES)(_inverse)
    jit.kernel(SOURCES)(_scaled_kernel)
    assert len(looked) == 1
    monkeypatch.setattr(jit, "_folder", lambda sources: None)
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(cache.parent / "numba-default"))  # where numba's own would go
    uncached = jit.kernel(SOURCES)(_inverse)
    assert jit.in_cache(uncached) is False and uncached(2.0) == 0.5
    assert jit.in_cache(uncached) is True  # compiled in this process: its next call does not wait
    assert uncached(0.0) == np.inf and uncached.targetoptions["nogil"]  # as a cached kernel is
    assert jit.in_cache(jit.kernel(SOURCES)(_inverse)) is False  # and the next process compiles it again
    summed = jit.kernel(SOURCES, parallel=True)(_inverse_sum)
    assert summed.targetoptions["parallel"] and summed(np.array([2.0, 2.0])) == 1.0
    assert not list(cache.parent.rglob("*.nbi"))  # nothing written, anywhere


def _scaled_kernel(x: float) -> float:
    return 2.0 * x


def test_switched_off_a_kernel_is_the_function_itself(cache: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("BOOM_HYDRAULICS_JIT", "0")
    assert jit.kernel(SOURCES)(_inverse) is _inverse
    with pytest.raises(ZeroDivisionError):
        jit.kernel(SOURCES)(_inverse)(0.0)
    assert not cache.exists()  # nothing looked up, nothing made


def test_in_cache_says_none_where_it_cannot_tell(cache: Path):
    assert jit.in_cache(None) is None  # no entry point: numba missing or switched off
    assert jit.in_cache(_inverse) is None  # a plain function

    class Otherwise:  # a numba whose cache is laid out otherwise
        signatures = ()
        _cache = object()

    assert jit.in_cache(Otherwise()) is None
    inverse = jit.kernel(SOURCES)(_inverse)
    inverse(1.0)
    (index,) = jit.cache_folder(SOURCES).rglob("*_inverse-*.nbi")
    index.write_bytes(b"not an index")  # a truncated or foreign index
    assert jit.in_cache(jit.kernel(SOURCES)(_inverse)) is None

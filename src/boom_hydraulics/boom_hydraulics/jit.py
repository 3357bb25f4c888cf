"""Compiling with numba, where it is installed: the project's two decorators.

- :func:`jitable` marks a function that compiled code may call (every element of the
  model, the steps, the run loop, the streaming metrics). It is
  ``numba.extending.register_jitable``: the function stays the plain Python function it is
  (interpreted callers call it as written), and a compiled caller compiles it into itself.
- :func:`kernel` makes an entry point that Python calls: ``numba.njit`` with
  ``error_model="numpy"`` (a division by zero gives inf or NaN, as in numpy, which the
  stepping then reports), compiled at its first call and cached on disk.

numba checks a cached entry point only against the file that defines it, not against the
files of the functions it compiled into itself. So the cache folder is keyed on a hash of
every source a kernel uses (:func:`cache_folder`): a change to any element gives a new
folder and a fresh compile. The folder is ``$BOOM_HYDRAULICS_CACHE/<hash>``, else
``$XDG_CACHE_HOME/boom_hydraulics/numba/<hash>`` (``~/.cache/...``); where that cannot be
written (a read-only home), a folder in the temporary directory; where neither can, the
kernels compile without caching.

Without numba, or with ``BOOM_HYDRAULICS_JIT=0`` in the environment, :func:`available` is
False and the interpreted path runs the same functions (about 20 times slower per step).
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TypeVar

try:  # numba is optional: the interpreted path gives the same results
    import numba
    from numba.extending import overload, register_jitable
except ImportError:  # pragma: no cover - exercised on machines without numba
    numba = None

F = TypeVar("F", bound=Callable[..., Any])

#: The loop over the sets of a batch: parallel where compiled with parallel=True.
prange = numba.prange if numba is not None else range

#: The package's root folder: kernel sources are named relative to it.
PACKAGE = Path(__file__).resolve().parent


def available() -> bool:
    """True when numba is installed and not switched off by BOOM_HYDRAULICS_JIT=0."""
    return numba is not None and os.environ.get("BOOM_HYDRAULICS_JIT", "1") != "0"


def jitable(function: F | None = None, *, inline: str = "never") -> Any:
    """Mark ``function`` as callable from compiled code (it stays the same Python function).

    ``inline="always"`` has numba inline it into its callers before optimising, so that
    what a caller does not use of its results is not computed (the model's terms), or so
    that a call in the run loop does not pass a block's constants and state by value at
    every step (kernel._commands, stepping.advance_lanes)."""

    def mark(f: F) -> F:
        return register_jitable(inline=inline)(f) if numba is not None else f

    return mark if function is None else mark(function)


def tuple_like(row: Any, template: tuple) -> tuple:
    """The first ``len(template)`` values of ``row`` (an array) as a tuple. Compiled, the size
    is the type of ``template`` (a tuple of that many floats), so that numba keeps the tuple on
    the stack (the model's state and constants) and compiles a kernel once per size (the
    model's state with or without the model elements)."""
    return tuple(row[i] for i in range(len(template)))


def tuple_size(numba_type: Any) -> int | None:
    """The size of a tuple as compiled code types it (a numba type), None for another type
    (a list): for a typing function that decides on a state's size (:func:`compiled_as`)."""
    return len(numba_type) if numba is not None and isinstance(numba_type, numba.types.BaseTuple) else None


if numba is not None:

    @overload(tuple_like)
    def _tuple_like_compiled(row: Any, template: Any) -> Any:
        """:func:`tuple_like` as compiled code runs it: numba's fixed-length tuple of an array."""
        length = tuple_size(template)
        if length is None:
            return None
        from numba.np.unsafe.ndarray import to_fixed_tuple

        def of(row: Any, template: Any) -> Any:
            return to_fixed_tuple(row, length)

        return of


def compiled_as(python_function: Callable[..., Any]) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Register the decorated typing function (numba's ``overload``) as how compiled code
    runs ``python_function``, for the few primitives whose Python form numba cannot compile
    (a state built element by element as a tuple). Without numba, nothing."""

    def register(typing: Callable[..., Any]) -> Callable[..., Any]:
        if numba is not None:
            overload(python_function)(typing)
        return typing

    return register


def cache_folder(sources: Sequence[Path]) -> Path | None:
    """A writable folder for numba's cache of kernels that use ``sources``, keyed on a hash
    of their text and of the numba and Python versions; None where none can be written."""
    digest = hashlib.sha256(f"{numba.__version__ if numba else ''}{sys.version}".encode())
    for path in sorted(sources):
        digest.update(str(path.relative_to(PACKAGE)).encode())
        digest.update(path.read_bytes())
    key = digest.hexdigest()[:16]
    configured = os.environ.get("BOOM_HYDRAULICS_CACHE")
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    candidates = [Path(configured)] if configured else [Path(base) / "boom_hydraulics" / "numba"]
    candidates.append(Path(tempfile.gettempdir()) / f"boom_hydraulics-numba-{os.getuid()}")
    for folder in candidates:
        try:
            folder = folder / key
            folder.mkdir(parents=True, exist_ok=True)
            probe = folder / f".probe-{os.getpid()}"
            probe.write_text("")
            probe.unlink()
            return folder
        except OSError:
            continue
    return None


def module_sources(*modules: Any) -> list[Path]:
    """The source files of ``modules`` (what a kernel compiles into itself)."""
    return [Path(module.__file__).resolve() for module in modules]


def kernel(sources: Sequence[Path], *, parallel: bool = False) -> Callable[[F], F]:
    """Make the decorated function a compiled entry point cached under :func:`cache_folder`
    of ``sources``; without numba (or switched off), the function itself.

    Compiled, it runs without the GIL (it touches no Python object), so that Python in other
    threads goes on beside it: boom-sweep prepares and stores batches while one runs."""

    def make(f: F) -> F:
        if not available():
            return f
        folder = _folder(tuple(sources))
        if folder is None:
            return numba.njit(cache=False, error_model="numpy", parallel=parallel, nogil=True)(f)
        # numba takes the folder when the function is made (its cache locator reads it then)
        saved = numba.config.CACHE_DIR
        numba.config.CACHE_DIR = str(folder)
        try:
            return numba.njit(cache=True, error_model="numpy", parallel=parallel, nogil=True)(f)
        finally:
            numba.config.CACHE_DIR = saved

    return make


@functools.cache
def _folder(sources: tuple[Path, ...]) -> Path | None:
    return cache_folder(sources)


def in_cache(entry: Callable[..., Any] | None) -> bool | None:
    """Whether numba's on-disk cache holds compiled code of the entry point ``entry`` (made by
    :func:`kernel`) for its sources as they are, so that its first call loads it instead of
    compiling: False where its first call will compile (for a tool to say so before it sits
    silent for a minute), as always where no cache folder could be written; None where it
    cannot tell (no entry point: numba missing or switched off; a numba whose cache is laid out
    otherwise; an index it cannot read, on which numba's own load fails as well). numba's index
    of compiled signatures (its FunctionCache) has no public reader: this reads it as numba's
    own load does, and an index written for other argument types than the call's still counts."""
    if entry is None:
        return None
    if getattr(entry, "signatures", None):  # compiled or loaded in this process already: no wait
        return True
    cache = getattr(entry, "_cache", None)
    if type(cache).__name__ == "NullCache":  # njit(cache=False): every process compiles
        return False
    try:
        index = cache._cache_file._load_index()  # type: ignore[union-attr]
    except AttributeError:
        return None
    except Exception:  # (e.g. a truncated index: numba raises on it too, at the first call)
        return None
    return bool(index)

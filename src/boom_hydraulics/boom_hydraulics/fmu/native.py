"""The drive's compiled code as one object file that C links: the model's own functions, compiled by numba.

The native FMU (docs/fmu.md) steps the same code boom-sim steps: one ``numba.cfunc``,
:func:`entry`, with a C signature over pointers to doubles, calls the functions the
Simulator's kernel calls (:func:`stepping.advance` with the method's step and the model's
``derivative``, ``stiffness_rate`` and ``energy``; the model's ``outputs``; the geometry's
``within_triangle``), the parameters' derivations that the Simulator runs in Python when it
starts or changes parameters (the model's ``constants`` and ``initial_state``), and the
checks that the plant's parameters fit together (parameters.py's ``plant_fault``). Each is
the model's function as written, marked jitable where it is defined: numba compiles it into
the entry point as it compiles the kernels.

A parameter set is a row of doubles in the order of :data:`ROW`: every scalar number field
of Parameters, then every string field as the index of its value among its choices. The
compiled code reads a row as :class:`Surrogate`, a named tuple of the same fields that the
model's functions read as they read Parameters (:func:`surrogate_of`). numba's code
library hands back the object file it compiled (a private API, used by numba's own cache:
``_get_compiled_object``, checked against numba 0.68, pinned in requirements.txt), which
is cached on disk beside the kernels (:func:`cached_object_path`), so that a later export
of the method links it without compiling again. The
C wrapper (native/fmi2_slave.c) calls the object's C-ABI wrapper (``cfunc.<mangled name>``)
as ``boom_native``, by an assembler label that export.py writes. Compiled code that raises
calls a few Python C-API and numba runtime functions on its way out; the C wrapper defines
them as stubs that flag the error. ros2's step and the state at rest allocate (arrays, a
list): the C wrapper holds the few functions of numba's runtime (NRT) that such code calls,
on malloc and free.

``boom_native(op, a, b, c, d) -> int32``, ``op`` one of :data:`OPERATIONS`; it returns 1 +
the operation's result (0: the compiled code raised).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import os
from collections import namedtuple
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..jit import jitable
from ..model import geometry
from ..model import physical as model
from ..model.outputs import OUTPUT_NAMES
from ..model.parameters import STROKE_LIMITS, Parameters, describe, plant_fault, stroke_limits_m
from ..solve import integrators, stepping
from ..solve.kernel import state_of
from ..solve.physical_kernel import WHOLE, constants_of, list_of

try:  # numba is optional for the package; object_code says that the FMU needs it
    from numba.cpython.unsafe.tuple import tuple_setitem
    from numba.np.unsafe.ndarray import to_fixed_tuple
except ImportError:  # pragma: no cover - exercised on machines without numba
    tuple_setitem = to_fixed_tuple = None

#: The C name of the entry point.
SYMBOL = "boom_native"
#: The operations of :func:`entry` (its first argument).
CONSTANTS, INITIAL_STATE, STEP, OUTPUTS, ENERGY, WITHIN, PLANT_FAULT = range(7)
OPERATIONS = {
    "CONSTANTS": CONSTANTS,
    "INITIAL_STATE": INITIAL_STATE,
    "STEP": STEP,
    "OUTPUTS": OUTPUTS,
    "ENERGY": ENERGY,
    "WITHIN": WITHIN,
    "PLANT_FAULT": PLANT_FAULT,
}
#: What the model's state, its Constants and its outputs hold.
N_STATE = len(model.STATE_NAMES)
N_CONSTANTS = len(model.Constants._fields)
N_OUTPUTS = len(OUTPUT_NAMES)
#: The arguments of a STEP: t, u, dt, min_substeps, limit, max_substeps, n, energy_index, energy_base.
STEP_ARGUMENTS = 9


def kind_of(name: str) -> str:
    """'str', 'int' or 'float': how a row's entry is read."""
    return describe(name)["type"]


def choices_of(name: str) -> tuple[str, ...]:
    """The values a string parameter takes, in the order of their codes in a row."""
    return tuple(describe(name)["choices"])


def _scalar_fields() -> tuple[str, ...]:
    defaults = Parameters()
    return tuple(f.name for f in dataclasses.fields(Parameters) if not isinstance(getattr(defaults, f.name), list))


#: The number fields of Parameters (float and int), then its string fields, in their order.
NUMBERS = tuple(name for name in _scalar_fields() if kind_of(name) != "str")
STRINGS = tuple(name for name in _scalar_fields() if kind_of(name) == "str")
#: The row of a parameter set: every scalar field of Parameters, its numbers first.
ROW = (*NUMBERS, *STRINGS)
#: The choices of each string field, padded with "" to one length (numba indexes a tuple of
#: tuples by a variable only where they are alike).
CHOICES = tuple(
    (*choices_of(name), *("",) * (max(len(choices_of(n)) for n in STRINGS) - len(choices_of(name)))) for name in STRINGS
)
_NO_STRINGS = ("",) * len(STRINGS)
_N_NUMBERS, _N_STRINGS = len(NUMBERS), len(STRINGS)


def row_of(params: Parameters) -> list[float]:
    """``params`` as a row (strings as the indices of their values)."""
    return [float(getattr(params, name)) for name in NUMBERS] + [
        float(choices_of(name).index(getattr(params, name))) for name in STRINGS
    ]


#: A stand-in for Parameters that compiled code builds from a row: a named tuple of the row's
#: fields (the numbers as floats), which the model's functions read by the fields' names.
Surrogate = namedtuple("Surrogate", ROW)  # type: ignore[misc]


@jitable
def whole_state(row: Any) -> tuple:
    """The whole state (with the model elements') as a tuple, as the FMU keeps it."""
    return state_of(row, WHOLE)


@jitable
def surrogate_of(row: Any) -> Any:
    """The Surrogate of ``row`` (an array of its doubles, its string codes checked in range)."""
    strings = _NO_STRINGS
    for j in range(_N_STRINGS):
        strings = tuple_setitem(strings, j, CHOICES[j][int(row[_N_NUMBERS + j])])
    return Surrogate(*(to_fixed_tuple(row, _N_NUMBERS) + strings))


def entry(method: str) -> Any:
    """The compiled ``boom_native`` of the physical model stepped by ``method`` (a fixed-step
    one: euler, rk4, or ros2 with the loop that takes a failed step again in halves, as the
    Simulator steps each)."""
    import numba
    from numba import carray, types

    step = integrators.METHODS[method].step
    halving = integrators.METHODS[method].halving  # ros2: its stages are arrays, its state a list
    loop = stepping.advance_halving if halving else stepping.advance
    state = list_of if halving else whole_state
    constants, initial_state = model.constants, model.initial_state
    derivative, stiffness_rate, energy, outputs = model.derivative, model.stiffness_rate, model.energy, model.outputs
    within_triangle = geometry.within_triangle
    n_row, n_state, n_constants, n_outputs = len(ROW), N_STATE, N_CONSTANTS, len(OUTPUT_NAMES)
    n_limits = len(STROKE_LIMITS)
    double_p = types.CPointer(types.float64)
    signature = types.int32(types.int32, double_p, double_p, double_p, double_p)

    @numba.cfunc(signature, error_model="numpy")
    def boom_native(op: int, a: Any, b: Any, c: Any, d: Any) -> int:
        if op == CONSTANTS:  # a: row -> b: constants
            values = constants(surrogate_of(carray(a, (n_row,))))
            out = carray(b, (n_constants,))
            for i in range(n_constants):
                out[i] = values[i]
            return 1
        if op == INITIAL_STATE:  # a: row -> b: state
            y0 = initial_state(surrogate_of(carray(a, (n_row,))))
            out = carray(b, (n_state,))
            for i in range(n_state):
                out[i] = y0[i]
            return 1
        if op == STEP:  # a: state (in and out), b: constants, c: STEP_ARGUMENTS, d: (steps taken, most substeps)
            y = carray(a, (n_state,))
            r = carray(c, (STEP_ARGUMENTS,))
            info = carray(d, (2,))
            done, outcome, most, y_new = loop(
                step, derivative, stiffness_rate, energy, r[0], state(y), constants_of(carray(b, (n_constants,))),
                r[1], r[2], int(r[3]), r[4], int(r[5]), int(r[6]), int(r[7]), r[8],
            )  # fmt: skip
            for i in range(n_state):
                y[i] = y_new[i]
            info[0] = done
            info[1] = most
            return 1 + outcome
        if op == OUTPUTS:  # a: state, b: constants, c: (t, u) -> d: outputs
            r = carray(c, (2,))
            values = outputs(r[0], whole_state(carray(a, (n_state,))), constants_of(carray(b, (n_constants,))), r[1])
            out = carray(d, (n_outputs,))
            for i in range(n_outputs):
                out[i] = values[i]
            return 1
        if op == ENERGY:  # a: state, b: constants -> d: the stored energy H, J
            out = carray(d, (1,))
            out[0] = energy(whole_state(carray(a, (n_state,))), constants_of(carray(b, (n_constants,))))
            return 1
        if op == WITHIN:  # a: (q1, a, b) -> whether q1 lies in the triangle of eq. 1
            r = carray(a, (3,))
            return 2 if within_triangle(r[0], r[1], r[2]) else 1
        if op == PLANT_FAULT:  # a: row -> b: the stroke's limits (STROKE_LIMITS); which check failed (0: none)
            p = surrogate_of(carray(a, (n_row,)))
            limits = stroke_limits_m(p.a_m, p.b_m)
            out = carray(b, (n_limits,))
            for i in range(n_limits):
                out[i] = limits[i]
            return 1 + plant_fault(p)
        return 0

    return boom_native


#: The numba whose code library hands back its object file as this module reads it.
NUMBA_VERSION = "0.68.1"


def cache_sources() -> list[Path]:
    """Every source the entry point may compile into itself (the model's and the stepping's
    modules, jit.py and this one): the on-disk cache of its object file is keyed on them."""
    from .. import jit

    return sorted(
        {*(jit.PACKAGE / "model").glob("*.py"), *(jit.PACKAGE / "solve").glob("*.py"), jit.PACKAGE / "jit.py",
         Path(__file__).resolve()}
    )  # fmt: skip


def cached_object_path(method: str) -> Path | None:
    """Where the object file of ``method``'s entry point is cached: in the kernels' cache folder
    for :func:`cache_sources` (jit.cache_folder: keyed on their text, numba's and Python's
    versions), named after the method and the machine code numba compiles for (its target and
    CPU, as numba keys its own cache); None where no cache folder can be written."""
    from numba.core.registry import cpu_target

    from .. import jit

    folder = jit.cache_folder(cache_sources())
    if folder is None:
        return None
    target = repr(cpu_target.target_context.codegen().magic_tuple()).encode()
    return folder / f"fmu-{method}-{hashlib.sha256(target).hexdigest()[:12]}.o"


def _read_cached(path: Path | None) -> tuple[bytes, str] | None:
    """The object file and its wrapper's name cached at ``path`` (the name, a line, then the
    object's bytes); None where there is none or it cannot be read."""
    try:
        data = path.read_bytes() if path is not None else b""
    except OSError:
        return None
    name, newline, code = data.partition(b"\n")
    if not newline or not code.startswith(b"\x7fELF") or not name.isascii():
        return None
    return code, name.decode("ascii")


def _write_cached(path: Path | None, code: bytes, name: str) -> None:
    """Cache ``code`` at ``path`` whole or not at all (a temporary renamed); a cache that cannot
    be written is left out (the next export compiles again)."""
    if path is None:
        return
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(name.encode("ascii") + b"\n" + code)
        os.replace(tmp, path)
    except OSError:
        with contextlib.suppress(OSError):
            tmp.unlink()


def object_code(method: str) -> tuple[bytes, str]:
    """The ELF object file numba compiled :func:`entry` of ``method`` into, and the name of
    its C-ABI wrapper; ConfigError where numba is missing or cannot hand the object back.
    numba compiles it once per machine and version of the sources (about 20 s on 2 cores):
    later exports read it from the on-disk cache (:func:`cached_object_path`)."""
    from .. import jit

    if jit.numba is None:
        raise ConfigError(
            "boom-sim fmu compiles the model with numba, which this Python lacks; install requirements.txt"
        )
    path = cached_object_path(method)
    cached = _read_cached(path)
    if cached is not None:
        return cached
    compiled = entry(method)
    try:
        code = compiled._library._get_compiled_object()
    except (AttributeError, RuntimeError) as exc:  # a private API: another numba may lay it out otherwise
        raise ConfigError(
            f"numba {jit.numba.__version__} does not hand back the compiled object file ({exc}); "
            f"boom-sim fmu needs numba {NUMBA_VERSION} (requirements.txt)"
        ) from None
    _write_cached(path, code, compiled.native_name)
    return code, compiled.native_name

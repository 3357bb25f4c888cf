"""Optional compilation of the scalar model with numba: the same source, compiled and cached.

numba compiles the element functions exactly as they are written (their ``xp`` argument
defaults to :mod:`math`, which numba supports). For each model and method, the source of
the element modules, the model and the stepping loop is put together into one real module
(:func:`module_source`): relative imports dropped, every function under
``njit(cache=True)``, and the loop's ``step``, ``derivative``, ... bound by name, so that
compiled code calls compiled code and numba can cache it on disk. Nothing is written twice:
the module is generated from the package's own source, and a test holds the compiled and
the interpreted trajectories equal.

The module's file name carries a hash of its source (and of the numba and Python
versions): numba checks a cache only against its defining file, so a changed model gets a
new file and a fresh cache. Files go to ``$BOOM_HYDRAULICS_CACHE``, else
``$XDG_CACHE_HOME/boom_hydraulics/numba`` (``~/.cache/...``); where that cannot be written
(a read-only home), to a folder in the temporary directory; where neither can, it compiles
without caching. The first compile takes a few seconds; a later process loads from the
cache. Without numba, or with ``BOOM_HYDRAULICS_JIT=0`` in the environment, :func:`stepper`
returns None and the interpreted path runs (about 20 times slower per step).
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib.util
import inspect
import os
import sys
import tempfile
import textwrap
import types
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..analysis import streaming
from ..model import MODELS, control, end_stops, friction, geometry, hydraulics, mechanics, setpoints
from . import integrators, kernel, outputs, profiles, stepping

try:  # numba is optional: the interpreted path gives the same results
    import numba
except ImportError:  # pragma: no cover - exercised on machines without numba
    numba = None

_ELEMENTS = (geometry, hydraulics, friction, end_stops, mechanics, integrators, stepping, outputs, streaming)
#: After the model: the controller, setpoints and profiles of the run kernel, and the kernel.
_COMMANDS = (control, setpoints, profiles, kernel)
_STEPS = {name: method.step.__name__ for name, method in integrators.METHODS.items() if method.step is not None}


def available() -> bool:
    """True when numba is installed and not switched off by BOOM_HYDRAULICS_JIT=0."""
    return numba is not None and os.environ.get("BOOM_HYDRAULICS_JIT", "1") != "0"


def _without_relative_imports(module: types.ModuleType, *transforms: ast.NodeTransformer) -> str:
    """The source of ``module`` without its docstring, ``from __future__`` and relative imports."""
    tree = ast.parse(inspect.getsource(module))
    body = [
        node
        for node in tree.body
        if not (isinstance(node, ast.ImportFrom) and (node.level > 0 or node.module == "__future__"))
        and not (isinstance(node, ast.Expr) and isinstance(getattr(node, "value", None), ast.Constant))
    ]
    tree = ast.Module(body=body, type_ignores=[])
    for transform in transforms:
        tree = transform.visit(tree)
    return ast.unparse(tree)


class _CallByName(ast.NodeTransformer):
    """``fun(...)`` -> ``derivative(...)`` and ``step(derivative, ...)`` -> ``step(...)``: numba
    caches a function that calls another by name, not one that is handed a function."""

    def visit_Name(self, node: ast.Name) -> ast.Name:
        return ast.Name(id="derivative", ctx=node.ctx) if node.id == "fun" else node

    def visit_Call(self, node: ast.Call) -> ast.Call:
        self.generic_visit(node)
        if isinstance(node.func, ast.Name) and node.func.id == "step" and node.args:
            node.args = node.args[1:]
        return node


class _AsTuples(ast.NodeTransformer):
    """State lists as tuples of the state's ``size``: ``[a, b, ...]`` -> ``(a, b, ...)`` and
    ``[f(a, b) for a, b in zip(x, y)]`` -> ``(f(x[0], y[0]), ..., f(x[n-1], y[n-1]))``. numba
    keeps a tuple of floats on the stack where a list goes to the heap: for the explicit
    methods, whose steps build their stages this way, a step costs about half as much."""

    def __init__(self, size: int) -> None:
        self.size = size

    def visit_List(self, node: ast.List) -> ast.AST:
        self.generic_visit(node)
        return ast.Tuple(elts=node.elts, ctx=node.ctx) if isinstance(node.ctx, ast.Load) else node

    def visit_ListComp(self, node: ast.ListComp) -> ast.AST:
        self.generic_visit(node)
        if len(node.generators) != 1 or node.generators[0].ifs:
            return node  # only the plain one-loop comprehensions of a state
        (generator,) = node.generators
        if isinstance(generator.target, ast.Name):
            names, sources = [generator.target.id], [generator.iter]
        elif isinstance(generator.iter, ast.Call) and getattr(generator.iter.func, "id", "") == "zip":
            names, sources = [element.id for element in generator.target.elts], generator.iter.args
        else:
            return node
        elements = []
        for i in range(self.size):
            items = {name: ast.Subscript(source, ast.Constant(i), ast.Load()) for name, source in zip(names, sources)}
            elements.append(_Substitute(items).visit(ast.parse(ast.unparse(node.elt), mode="eval").body))
        return ast.Tuple(elts=elements, ctx=ast.Load())


class _WithoutStore(ast.NodeTransformer):
    """Drop the ``if store:`` block: a kernel for the metrics alone, which takes only the
    outputs they need (numba inlines the outputs and leaves the rest uncomputed)."""

    def visit_If(self, node: ast.If) -> ast.AST | None:
        if isinstance(node.test, ast.Name) and node.test.id == "store":
            return None
        return self.generic_visit(node)


class _Substitute(ast.NodeTransformer):
    def __init__(self, items: dict[str, ast.AST]) -> None:
        self.items = items

    def visit_Name(self, node: ast.Name) -> ast.AST:
        return self.items.get(node.id, node)


#: Methods whose state may be tuples (their steps touch the state only through the comprehensions
#: _AsTuples unrolls); ros2 builds its stages with numpy and keeps lists.
_TUPLE_METHODS = ("euler", "rk4")


def _function_source(function: Callable, name: str) -> ast.FunctionDef:
    definition = ast.parse(textwrap.dedent(inspect.getsource(function))).body[0]
    definition.name = name
    return definition


def _bound_step_source(method: str, *transforms: ast.NodeTransformer) -> str:
    """The method's step as ``step(t, y, h, args)``, calling the model's ``derivative`` by name."""
    definition = _function_source(integrators.METHODS[method].step, "step")
    definition.args.args = definition.args.args[1:]  # (fun, t, y, h, args) -> (t, y, h, args)
    for transform in (_CallByName(), *transforms):
        definition = transform.visit(definition)
    return ast.unparse(definition)


def _inner_source(factory: Callable, inner: str, name: str, *transforms: ast.NodeTransformer) -> str:
    """The function ``inner`` that ``factory`` builds, as a top-level function ``name``
    calling the functions it closes over by name."""
    definition = _function_source(factory, factory.__name__)
    (found,) = [node for node in definition.body if isinstance(node, ast.FunctionDef) and node.name == inner]
    found.name = name
    for transform in (_CallByName(), *transforms):
        found = transform.visit(found)
    return ast.unparse(found)


def _observe_values_source(model: types.ModuleType) -> str:
    """The model's ``observe`` as ``observe_values``: a tuple of floats (1.0 x each value,
    flags too) in the order of OUTPUT_NAMES instead of a dict, which numba does not compile."""
    definition = _function_source(model.observe, "observe_values")
    (returned,) = [node for node in ast.walk(definition) if isinstance(node, ast.Return)]
    by_name = {key.value: value for key, value in zip(returned.value.keys, returned.value.values)}
    returned.value = ast.Tuple(
        elts=[ast.BinOp(ast.Constant(1.0), ast.Mult(), by_name[name]) for name in outputs.OUTPUT_NAMES],
        ctx=ast.Load(),
    )
    return ast.unparse(definition)


def _without_controller_source() -> str:
    """kernel.controller_value returning 0: the paper model has none of the Constants the
    controller reads, and closed_loop.PositionLoop refuses paper mode."""
    definition = _function_source(kernel.controller_value, "controller_value")
    definition.body = [ast.Return(ast.Constant(0.0))]
    return ast.unparse(definition)


def _constants_of_source(model: types.ModuleType) -> str:
    """``constants_of(row)``: the model's Constants from a row of floats (a batch's sets are rows)."""
    fields = ", ".join(f"row[{k}]" for k in range(len(model.Constants._fields)))
    return f"def constants_of(row):\n    return Constants({fields})"


#: The parallel loop over the sets of a batch, each run over the passes first ... last - 1
#: (kernel.set_runner): a run goes in slices, each call returning to Python.
_BATCH_SOURCE = """
def _run_batch(
    C, Y, kind, times_s, values, offset, amplitude, frequency_hz, KT, KA, KR, order, G, dt, min_substeps, limit,
    max_substeps, n_steps, every, energy_index, EB, S, M, ROWS, STATUS, TAKEN, first, last,
):
    store = ROWS.shape[1] > 0
    profile = (kind, times_s, values, offset, amplitude, frequency_hz)
    for k in _numba.prange(C.shape[0]):
        path = (KT[k], KA[k], KR[k], order, G[k])
        c = constants_of(C[k])
        rest = (dt, min_substeps, limit, max_substeps, n_steps, every, energy_index, EB[k], S[k], M[k], ROWS[k])
        if store:
            TAKEN[k] = run_set(c, Y[k], profile, path, *rest, STATUS[k], first, last)
        else:
            TAKEN[k] = run_metrics(c, Y[k], profile, path, *rest, STATUS[k], first, last)
"""


def module_source(mode: str, method: str) -> str:
    """One module with the elements, the model ``mode``, the loop of ``method`` and the run
    kernel, every function under ``njit(cache=...)`` and the batch loop parallel."""
    model = MODELS[mode]
    state = (_AsTuples(len(model.STATE_NAMES)),) if method in _TUPLE_METHODS else ()
    parts = [
        f"# generated by boom_hydraulics.solve.accelerate for mode {mode!r}, method {method!r}; do not edit",
        "from __future__ import annotations",
        "import types as _types",
        "import numba as _numba",
        "import numpy as _np",
        "from numba import njit as _njit",
    ]
    parts += [f"# --- {module.__name__}\n{_without_relative_imports(module)}" for module in _ELEMENTS]
    parts += [f"# --- {model.__name__}\n{_without_relative_imports(model, *state)}"]
    parts += [f"# --- {module.__name__}\n{_without_relative_imports(module)}" for module in _COMMANDS]
    parts += [
        "# --- the stepping loop and the run kernel, bound by name",
        _bound_step_source(method, *state),
        "broken = balance_broken",
        _inner_source(stepping.fixed_stepper, "run", "_loop"),
        _observe_values_source(model),
        _constants_of_source(model),
        *([] if mode == "physical" else [_without_controller_source()]),
        f"def tuple_of(y0):\n    return ({''.join(f'y0[{k}], ' for k in range(len(model.STATE_NAMES)))})",
        _inner_source(kernel.set_runner, "run_set", "run_set", *state),
        _inner_source(kernel.set_runner, "run_set", "run_metrics", *state, _WithoutStore()),
        "# the entry points take the constants as a row of floats: numba types an array at once,",
        "# a NamedTuple field by field on every call",
        "def observe_row(t, y0, crow, u):",
        f"    return observe_values(t, {'tuple_of(y0)' if state else '[v for v in y0]'}, constants_of(crow), u)",
        "def run(t, y0, crow, u, dt, min_substeps, limit, max_substeps, n, energy_index, energy_base):",
        "    c = constants_of(crow)",
        "    done, outcome, most, y = _loop(",
        f"        t, {'tuple_of(y0)' if state else '[v for v in y0]'}, c, u, dt, min_substeps, limit, max_substeps, n,",
        "        energy_index, energy_base,",
        "    )",
        "    return done, outcome, most, _np.array(y)",
        "_INLINED = ('observe_values', '_terms')",
        "for _name, _object in list(globals().items()):",
        "    if isinstance(_object, _types.FunctionType) and _object.__module__ == __name__:",
        "        _inline = 'always' if _name in _INLINED else 'never'",
        "        globals()[_name] = _njit(cache=CACHE, error_model='numpy', inline=_inline)(_object)",
        _BATCH_SOURCE,
        "run_batch = _njit(cache=CACHE, parallel=True)(_run_batch)",
    ]
    return "\n\n".join(parts) + "\n"


def cache_folder() -> Path | None:
    """A writable folder for the generated modules and numba's cache, or None."""
    configured = os.environ.get("BOOM_HYDRAULICS_CACHE")
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    candidates = [Path(configured)] if configured else [Path(base) / "boom_hydraulics" / "numba"]
    candidates.append(Path(tempfile.gettempdir()) / f"boom_hydraulics-numba-{os.getuid()}")
    for folder in candidates:
        try:
            folder.mkdir(parents=True, exist_ok=True)
            probe = folder / f".probe-{os.getpid()}"
            probe.write_text("")
            probe.unlink()
            return folder
        except OSError:
            continue
    return None


@functools.cache
def _load(mode: str, method: str) -> types.ModuleType:
    """The generated module of ``mode`` and ``method``, imported from the cache folder (written
    there once per source; where no folder can be written, from a private temporary one, uncached)."""
    source = module_source(mode, method)
    key = hashlib.sha256(f"{source}{numba.__version__}{sys.version}".encode()).hexdigest()[:16]
    name = f"boom_compiled_{mode}_{method}_{key}"
    folder = cache_folder()
    cache = folder is not None
    if folder is None:
        folder = Path(tempfile.mkdtemp(prefix="boom_hydraulics-numba-"))
    path = folder / f"{name}.py"
    if not path.exists():
        staging = folder / f".{name}.{os.getpid()}.partial"
        staging.write_text(source)
        os.replace(staging, path)  # whole or absent, also when two processes race
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    module.CACHE = cache
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def stepper(mode: str, method: str) -> Callable[..., tuple[int, int, int, np.ndarray]] | None:
    """The compiled stepping loop (:func:`stepping.fixed_stepper`) of one model and method, or None.

    ``run(t, y, constants, u, dt, min_substeps, limit, max_substeps, n, energy_index,
    energy_base) -> (steps taken, outcome, most substeps, y)`` with ``y`` and ``constants``
    (the model's Constants in order) numpy arrays.
    """
    if not available() or method not in _STEPS:
        return None
    return _load(mode, method).run


def observer(mode: str, method: str) -> Callable[..., tuple] | None:
    """The compiled outputs of one model: ``observe_row(t, y, constants, u)`` -> a tuple of
    floats in the order of OUTPUT_NAMES (flags 0.0 or 1.0), ``y`` and ``constants`` numpy
    arrays (as for :func:`stepper`); or None."""
    if not available() or method not in _STEPS:
        return None
    return _load(mode, method).observe_row


def batch_runner(mode: str, method: str) -> Callable[..., None] | None:
    """The compiled parallel run kernel (kernel.set_runner over the sets of a batch) of one
    model and method, or None (see batch.run_sets for its arguments)."""
    if not available() or method not in _STEPS:
        return None
    return _load(mode, method).run_batch

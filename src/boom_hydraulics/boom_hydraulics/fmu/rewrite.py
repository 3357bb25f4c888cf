"""The model's parameter derivations, compiled by numba from their own source.

The Simulator derives the model's Constants (model.physical.constants) and its state at rest
(model.physical.initial_state) in Python, from a Parameters set. The native FMU derives them
in compiled code when the host sets a parameter, from the same source: this module reads
each function's source, spells otherwise the few constructs numba cannot compile, and hands
it to numba with the function's own module namespace:

- keyword arguments whose values hold a conditional expression (numba refuses such a
  call): each value is computed first, in the order written, then passed by name;
- ``DRIVES[name].f(...)``, a drive's function picked from a dict of modules: a call of a
  generated function that picks it by name among model.drives.DRIVES;
- ``[a, b, *(0.0 for _ in SEQUENCE)]``, a list (numba's lists need its runtime, which the
  FMU does not carry): a tuple with ``len(SEQUENCE)`` copies of the element.

Every plain function of the package that the derivations call is registered with numba as
jitable (numba.extending.register_jitable), as the model's own decorator does. The result
is the same arithmetic in the same order (held equal by the tests, to the bit).
"""

from __future__ import annotations

import ast
import inspect
import textwrap
import types
from collections.abc import Callable
from typing import Any

from ..model import physical
from ..model.drives import DRIVES

#: The package whose plain functions a derivation may call (and that are made jitable).
PACKAGE = "boom_hydraulics."


class _Spelled(ast.NodeTransformer):
    """The constructs of the module docstring, spelled for numba."""

    def __init__(self, namespace: dict[str, Any]) -> None:
        self.namespace = namespace
        self.pickers: set[str] = set()
        self.count = 0

    def visit_FunctionDef(self, node: ast.FunctionDef) -> ast.FunctionDef:
        node.decorator_list = []
        node.returns = None
        for argument in (*node.args.posonlyargs, *node.args.args, *node.args.kwonlyargs):
            argument.annotation = None
        body: list[ast.stmt] = []
        for statement in node.body:
            body.extend(self._hoisted(statement))
        node.body = body
        self.generic_visit(node)
        return node

    def _hoisted(self, statement: ast.stmt) -> list[ast.stmt]:
        """``statement``, preceded by the assignments of its call's keyword values that hold a conditional."""
        value = getattr(statement, "value", None)
        if not isinstance(value, ast.Call):
            return [statement]
        before: list[ast.stmt] = []
        for keyword in value.keywords:
            if keyword.arg is not None and any(isinstance(n, ast.IfExp) for n in ast.walk(keyword.value)):
                self.count += 1
                name = f"_kw{self.count}_{keyword.arg}"
                before.append(ast.Assign(targets=[ast.Name(name, ast.Store())], value=keyword.value, lineno=0))
                keyword.value = ast.Name(name, ast.Load())
        return [*before, statement]

    def visit_Call(self, node: ast.Call) -> ast.AST:
        self.generic_visit(node)
        function = node.func
        if (
            isinstance(function, ast.Attribute)
            and isinstance(function.value, ast.Subscript)
            and isinstance(function.value.value, ast.Name)
            and function.value.value.id == "DRIVES"
        ):
            picker = f"_drives_{function.attr}"
            self.pickers.add(function.attr)
            return ast.Call(ast.Name(picker, ast.Load()), [function.value.slice, *node.args], node.keywords)
        return node

    def visit_List(self, node: ast.List) -> ast.AST:
        self.generic_visit(node)
        elements: list[ast.expr] = []
        for element in node.elts:
            generator = element.value if isinstance(element, ast.Starred) else None
            if isinstance(generator, ast.GeneratorExp) and len(generator.generators) == 1:
                source = generator.generators[0].iter
                if not isinstance(source, ast.Name) or source.id not in self.namespace:
                    raise ValueError(f"a starred generator over {ast.unparse(source)}: not a sequence of the module")
                elements.extend(generator.elt for _ in self.namespace[source.id])
            else:
                elements.append(element)
        return ast.Tuple(elements, ast.Load())


def _is_registered(function: Callable[..., Any]) -> bool:
    from numba.core.typing.templates import builtin_registry

    return any(registered is function for registered, _ in builtin_registry.globals)


def _make_jitable(function: Any, seen: set[int]) -> None:
    """Register ``function`` (a plain function of the package) and the plain functions of the
    package it calls as jitable, unless numba knows them already."""
    from numba.core.dispatcher import Dispatcher
    from numba.extending import register_jitable

    if id(function) in seen or isinstance(function, Dispatcher):
        return
    seen.add(id(function))
    if not isinstance(function, types.FunctionType) or not function.__module__.startswith(PACKAGE):
        return
    for name in function.__code__.co_names:
        callee = function.__globals__.get(name)
        if isinstance(callee, types.FunctionType):
            _make_jitable(callee, seen)
        elif isinstance(callee, types.ModuleType) and callee.__name__.startswith(PACKAGE):
            for attribute in function.__code__.co_names:
                member = getattr(callee, attribute, None)
                if isinstance(member, types.FunctionType):
                    _make_jitable(member, seen)
    if not _is_registered(function):
        register_jitable(function)


def _pickers(names: set[str], namespace: dict[str, Any], seen: set[int]) -> None:
    """``_drives_<f>(name, ...)`` for each ``f``: model.drives.DRIVES[name].f(...), jitable."""
    for attribute in sorted(names):
        lines = [f"def _drives_{attribute}(name, *args):"]
        for k, (name, module) in enumerate(DRIVES.items()):
            function = getattr(module, attribute)
            _make_jitable(function, seen)
            namespace[f"_drive{k}_{attribute}"] = function
            lines.append(f"    if name == {name!r}:")
            lines.append(f"        return _drive{k}_{attribute}(*args)")
        lines.append(f"    return _drive0_{attribute}(*args)")  # parameters refuse any other name
        exec(compile("\n".join(lines), f"<fmu.rewrite._drives_{attribute}>", "exec"), namespace)
        jitable_copy(namespace[f"_drives_{attribute}"])


def compiled_source(function: Callable[..., Any], replace: dict[str, Any] | None = None) -> Callable[..., Any]:
    """``function`` (a plain function of the model) as numba compiles it: its own source,
    spelled as the module docstring says, in a copy of its module's namespace with ``replace``."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(function)))
    namespace = dict(function.__globals__)
    namespace.update(replace or {})
    spelled = _Spelled(namespace)
    tree = ast.fix_missing_locations(spelled.visit(tree))
    seen: set[int] = set()
    _pickers(spelled.pickers, namespace, seen)
    for name in {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}:
        callee = namespace.get(name)
        if isinstance(callee, types.FunctionType) and callee is not function:
            _make_jitable(callee, seen)
    filename = f"<fmu.rewrite of {function.__module__}.{function.__qualname__}>"
    exec(compile(tree, filename, "exec"), namespace)
    return jitable_copy(namespace[function.__name__])


def jitable_copy(function: Callable[..., Any]) -> Callable[..., Any]:
    """``function`` registered as jitable (compiled into the compiled code that calls it)."""
    from numba.extending import register_jitable

    return register_jitable(function)


def model_constants() -> Callable[..., Any]:
    """model.physical.constants (and the drives' constants it calls), compiled from their source."""
    drive_constants = compiled_source(physical.drive_constants)
    return compiled_source(physical.constants, {"drive_constants": drive_constants})


def model_initial_state() -> Callable[..., Any]:
    """model.physical.initial_state (and the drives' constants it calls), compiled from their source."""
    drive_constants = compiled_source(physical.drive_constants)
    return compiled_source(physical.initial_state, {"drive_constants": drive_constants})

"""Lanes: several parameter sets in one value, so that the batch kernel runs a block of sets in
lock-step on the vector units (docs/performance.md, "Batch kernel and sweeps").

A ``Lanes`` value holds one float64 per set of a block (:data:`WIDTH` of them): compiled, an
LLVM vector ``<WIDTH x double>`` that arithmetic works on as a whole (AVX2, AVX-512). The
model is written once, for floats and numpy arrays alike (branches as operators: see
model/hydraulics), so the same functions compute a block's derivative when their state and
constants are tuples of Lanes: this module gives Lanes the operators and math functions the
model uses. Each operation is the one a float gets, lane by lane (``+ - * /``, ``sqrt``,
``abs`` and ``copysign`` as vector instructions; ``exp``, ``sin``, ``cos``, ``acos`` through
the float function, one lane after the other, but exp of a block of zeros, which is 1 exactly
without a call), so a lane's results equal, to the bit, those
of its set run alone (a test holds them so; a block whose sets use different drives runs each
drive's equations for all of them, weighted by 0 where a set does not use it: the same values,
where those are finite, with a zero's sign that can differ). A comparison gives a mask: Lanes of 1.0 where
it holds, 0.0 elsewhere, as the model multiplies by a comparison's outcome.

The run loop (:func:`kernel.run_set`) handles a block through the helpers below, which give
a float (or a tuple of floats) back unchanged, so the same loop runs one set of floats
(compiled or interpreted) and a block of Lanes:

- :func:`lane` (a set's float of a value, or its tuple of a tuple), :func:`with_lane`,
  :func:`spread` (every lane the same), :func:`choose` (lane by lane by a
  mask), :func:`most` (the largest lane) and :func:`width`.
"""

from __future__ import annotations

import functools
import math
import operator
from typing import Any

import numpy as np

from ..jit import numba

#: Sets in one block of the batch kernel: 4 fill a 256-bit AVX2 register, 8 an AVX-512 one.
WIDTH = 4


def lane(x: Any, j: int) -> Any:
    """Set ``j``'s value of ``x`` (Lanes; a tuple: each element's); a float, a tuple of floats
    (one set) as it is."""
    return x


def with_lane(x: Any, j: int, value: Any) -> Any:
    """``x`` with set ``j``'s value (or tuple) ``value``; for one set, ``value``."""
    return value


def spread(x: Any, template: Any) -> Any:
    """``x`` (a number, or a tuple of them) in every lane of ``template`` (Lanes); with a float
    ``template``, ``x`` as it is (a number as a float)."""
    return float(x) if isinstance(x, (int, float)) else x


def choose(mask: Any, a: Any, b: Any) -> Any:
    """``a`` where ``mask`` holds (is not 0), else ``b``, lane by lane (values or tuples alike)."""
    return a if mask else b


def most(x: Any) -> float:
    """The largest lane of ``x``; a float as it is."""
    return x


def width(x: Any) -> int:
    """How many sets ``x`` holds: 1 for a float."""
    return 1


if numba is not None:  # the type and its operations exist where compiled code runs
    from llvmlite import ir
    from numba.core import cgutils, types
    from numba.extending import intrinsic, models, register_model
    from numba.extending import overload as _overload

    def overload(function: Any) -> Any:
        """numba's overload of ``function``: numba asks the typing function and the
        implementation it gives to have the same parameters, annotations included, so both
        lose theirs (they are for the reader; a lambda has none)."""

        def register(typing: Any) -> Any:
            typing.__annotations__ = {}

            @functools.wraps(typing)
            def bare(*args: Any) -> Any:
                implementation = typing(*args)
                if implementation is not None:
                    implementation.__annotations__ = {}
                return implementation

            return _overload(function)(bare)

        return register

    class Lanes(types.Type):
        """numba's type of a value with one float64 per set of a block."""

        def __init__(self, count: int) -> None:
            self.count = count
            super().__init__(name=f"Lanes{count}")

    @register_model(Lanes)
    class _LanesModel(models.PrimitiveModel):
        def __init__(self, dmm: Any, fe_type: Lanes) -> None:
            super().__init__(dmm, fe_type, ir.VectorType(ir.DoubleType(), fe_type.count))

    _NUMBERS = (types.Float, types.Integer, types.Boolean)
    _I32 = ir.IntType(32)

    def _vector(count: int) -> ir.VectorType:
        return ir.VectorType(ir.DoubleType(), count)

    def _splat(context: Any, builder: Any, value: Any, of: Any, count: int) -> Any:
        """``value`` of numba type ``of`` as Lanes of ``count`` (Lanes stay as they are)."""
        if isinstance(of, Lanes):
            return value
        scalar = context.cast(builder, value, of, types.float64)
        undef = ir.Constant(_vector(count), ir.Undefined)
        one = builder.insert_element(undef, scalar, ir.Constant(_I32, 0))
        return builder.shuffle_vector(one, undef, ir.Constant(ir.VectorType(_I32, count), [0] * count))

    #: ``value`` of numba type ``of`` as Lanes of ``count`` in generated code (integrators' sums).
    spread_value = _splat

    def _operands(a: Any, b: Any) -> Lanes | None:
        """The Lanes type of an operation on ``a`` and ``b`` (one of them Lanes, the other
        Lanes of the same width or a number), or None."""
        if isinstance(a, Lanes) and (isinstance(b, _NUMBERS) or b == a):
            return a
        if isinstance(b, Lanes) and isinstance(a, _NUMBERS):
            return b
        return None

    def _mask(builder: Any, bits: Any, count: int) -> Any:
        """1.0 where ``bits`` holds, else 0.0 (a select: one masked move, where a conversion of the
        bits to floats took three instructions)."""
        return builder.select(
            bits, ir.Constant(_vector(count), [1.0] * count), ir.Constant(_vector(count), [0.0] * count)
        )

    def _holds(builder: Any, x: Any, count: int) -> Any:
        return builder.fcmp_unordered("!=", x, ir.Constant(_vector(count), [0.0] * count))

    def _finite(builder: Any, x: Any) -> Any:
        """Where ``x`` is finite: x - x is 0 there, NaN for an infinity or a NaN."""
        return builder.fcmp_ordered("==", builder.fsub(x, x), ir.Constant(x.type, [0.0] * x.type.count))

    def _vector_function(builder: Any, name: str, *args: Any) -> Any:
        """LLVM's vector intrinsic ``name`` (llvm.sqrt, llvm.fabs ...) on ``args``."""
        vector = args[0].type
        signature = ir.FunctionType(vector, [vector] * len(args))
        function = cgutils.get_or_insert_function(builder.module, signature, f"{name}.v{vector.count}f64")
        return builder.call(function, list(args))

    def _binary(emit: Any) -> Any:
        def typing(typingctx: Any, a: Any, b: Any) -> Any:
            out = _operands(a, b)
            if out is None:
                return None

            def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
                x = _splat(context, builder, args[0], signature.args[0], out.count)
                y = _splat(context, builder, args[1], signature.args[1], out.count)
                return emit(builder, x, y, out.count)

            return out(a, b), codegen

        return intrinsic(typing)

    def _unary(emit: Any) -> Any:
        def typing(typingctx: Any, a: Any) -> Any:
            if not isinstance(a, Lanes):
                return None
            return a(a), lambda context, builder, signature, args: emit(builder, args[0])

        return intrinsic(typing)

    def _compare(operation: str) -> Any:
        if operation == "!=":
            return _binary(lambda b, x, y, n: _mask(b, b.fcmp_unordered("!=", x, y), n))
        return _binary(lambda b, x, y, n: _mask(b, b.fcmp_ordered(operation, x, y), n))

    _BINARY = {
        operator.add: _binary(lambda b, x, y, n: b.fadd(x, y)),
        operator.sub: _binary(lambda b, x, y, n: b.fsub(x, y)),
        operator.mul: _binary(lambda b, x, y, n: b.fmul(x, y)),
        operator.truediv: _binary(lambda b, x, y, n: b.fdiv(x, y)),
        operator.lt: _compare("<"),
        operator.le: _compare("<="),
        operator.gt: _compare(">"),
        operator.ge: _compare(">="),
        operator.eq: _compare("=="),
        operator.ne: _compare("!="),
        operator.or_: _binary(lambda b, x, y, n: _mask(b, b.or_(_holds(b, x, n), _holds(b, y, n)), n)),
        operator.and_: _binary(lambda b, x, y, n: _mask(b, b.and_(_holds(b, x, n), _holds(b, y, n)), n)),
        math.copysign: _binary(lambda b, x, y, n: _vector_function(b, "llvm.copysign", x, y)),
    }
    _BINARY.update({
        operator.iadd: _BINARY[operator.add],
        operator.isub: _BINARY[operator.sub],
        operator.imul: _BINARY[operator.mul],
        operator.itruediv: _BINARY[operator.truediv],
    })  # fmt: skip
    _UNARY = {
        operator.neg: _unary(lambda b, x: b.fneg(x)),
        abs: _unary(lambda b, x: _vector_function(b, "llvm.fabs", x)),
        math.sqrt: _unary(lambda b, x: _vector_function(b, "llvm.sqrt", x)),
        math.ceil: _unary(lambda b, x: _vector_function(b, "llvm.ceil", x)),
        math.isfinite: _unary(lambda b, x: _mask(b, _finite(b, x), x.type.count)),
    }

    def _overload_binary(function: Any, implementation: Any) -> None:
        @overload(function)
        def typing(a: Any, b: Any) -> Any:
            if _operands(a, b) is not None:
                return lambda a, b: implementation(a, b)
            return None

    def _overload_unary(function: Any, implementation: Any) -> None:
        @overload(function)
        def typing(a: Any) -> Any:
            if isinstance(a, Lanes):
                return lambda a: implementation(a)
            return None

    for _function, _implementation in _BINARY.items():
        _overload_binary(_function, _implementation)
    for _function, _implementation in _UNARY.items():
        _overload_unary(_function, _implementation)

    @intrinsic
    def _get(typingctx: Any, x: Any, j: Any) -> Any:
        if not isinstance(x, Lanes):
            return None
        return types.float64(x, j), lambda context, builder, signature, args: builder.extract_element(*args)

    @intrinsic
    def _put(typingctx: Any, x: Any, j: Any, value: Any) -> Any:
        if not (isinstance(x, Lanes) and isinstance(value, _NUMBERS)):
            return None

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            scalar = context.cast(builder, args[2], signature.args[2], types.float64)
            return builder.insert_element(args[0], scalar, args[1])

        return x(x, j, value), codegen

    def _per_lane(function: Any, at_zero: float) -> None:
        """``function`` (a float function of numba's: exp, sin ...) of Lanes, lane after lane;
        where every lane is 0 (+0 or -0), ``at_zero`` in each (the exact value the function
        gives there, e.g. exp(0) = 1), without a call; NaN: no such shortcut."""

        @overload(function)
        def typing(x: Any) -> Any:
            if not isinstance(x, Lanes):
                return None
            count = x.count

            def each(x: Any) -> Any:
                if at_zero == at_zero:  # (a constant: compiled away where there is no shortcut)
                    zeros = 0
                    for j in range(count):
                        zeros += _get(x, j) == 0.0
                    if zeros == count:
                        return x * 0.0 + at_zero
                out = x
                for j in range(count):
                    out = _put(out, j, function(_get(x, j)))
                return out

            return each

    # exp(+-0) = 1 exactly: a chamber's volume within the stroke takes exp of 0 (physical.
    # chamber_volumes): 8 calls of a block's derivative, 32 of an RK4 step, nearly always 0;
    # log and expm1: the accumulator's gas (model/accumulator.py), expm1(+-0) = +-0
    for _function, _at_zero in (
        *((math.exp, 1.0), (math.sin, math.nan), (math.cos, math.nan), (math.acos, math.nan)),
        *((math.log, math.nan), (math.expm1, math.nan)),
    ):
        _per_lane(_function, _at_zero)

    @overload(np.any)
    def _any(x: Any) -> Any:
        """Whether any lane of a mask holds (the model's in_use of a block's drive flags)."""
        if not isinstance(x, Lanes):
            return None
        count = x.count

        def any_lane(x: Any) -> bool:
            for j in range(count):
                if _get(x, j) != 0.0:
                    return True
            return False

        return any_lane

    # -- tuples: the model's state, constants and results, element by element --------------

    def _elements(t: Any) -> list:
        return list(t.types) if isinstance(t, types.BaseTuple) else [t]

    def _rebuild(t: Any, elements: list) -> Any:
        """A tuple type like ``t`` (a NamedTuple stays one of its class) of ``elements``."""
        if isinstance(t, types.BaseNamedTuple):
            cls = t.instance_class
            if all(e == elements[0] for e in elements):
                return types.NamedUniTuple(elements[0], len(elements), cls)
            return types.NamedTuple(elements, cls)
        if all(e == elements[0] for e in elements):
            return types.UniTuple(elements[0], len(elements))
        return types.Tuple(elements)

    def _lanes_of(t: Any) -> bool:
        return any(isinstance(e, Lanes) for e in _elements(t))

    @intrinsic
    def _lane_of_tuple(typingctx: Any, t: Any, j: Any) -> Any:
        out = _rebuild(t, [types.float64 if isinstance(e, Lanes) else e for e in t.types])

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            value = context.get_constant_undef(out)
            for i, e in enumerate(t.types):
                element = builder.extract_value(args[0], i)
                if isinstance(e, Lanes):
                    element = builder.extract_element(element, args[1])
                value = builder.insert_value(value, element, i)
            return value

        return out(t, j), codegen

    @intrinsic
    def _put_tuple(typingctx: Any, t: Any, j: Any, value: Any) -> Any:
        if len(t) != len(value):
            return None

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            out = args[0]
            for i, (e, v) in enumerate(zip(t.types, value.types)):
                element = builder.extract_value(args[2], i)
                if isinstance(e, Lanes):
                    scalar = context.cast(builder, element, v, types.float64)
                    element = builder.insert_element(builder.extract_value(out, i), scalar, args[1])
                out = builder.insert_value(out, element, i)
            return out

        return t(t, j, value), codegen

    @intrinsic
    def _spread_tuple(typingctx: Any, t: Any, template: Any) -> Any:
        count = template.count
        out = _rebuild(t, [Lanes(count) if isinstance(e, _NUMBERS) else e for e in t.types])

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            value = context.get_constant_undef(out)
            for i, e in enumerate(t.types):
                element = builder.extract_value(args[0], i)
                if isinstance(e, _NUMBERS):
                    element = _splat(context, builder, element, e, count)
                value = builder.insert_value(value, element, i)
            return value

        return out(t, template), codegen

    @intrinsic
    def _spread_value(typingctx: Any, x: Any, template: Any) -> Any:
        count = template.count
        out = Lanes(count)
        return out(x, template), lambda context, builder, signature, args: _splat(context, builder, args[0], x, count)

    @intrinsic
    def _choose(typingctx: Any, mask: Any, a: Any, b: Any) -> Any:
        if not isinstance(mask, Lanes) or a != b:
            return None

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            holds = _holds(builder, args[0], mask.count)
            if not isinstance(a, types.BaseTuple):
                return builder.select(holds, args[1], args[2])
            out = args[1]
            for i, e in enumerate(a.types):
                if isinstance(e, Lanes):
                    chosen = builder.select(holds, builder.extract_value(args[1], i), builder.extract_value(args[2], i))
                    out = builder.insert_value(out, chosen, i)
            return out

        return a(mask, a, b), codegen

    @intrinsic
    def block(typingctx: Any) -> Any:
        """Lanes of WIDTH zeros: the template of a block of the batch kernel (compiled code)."""
        out = Lanes(WIDTH)
        return out(), lambda context, builder, signature, args: ir.Constant(_vector(WIDTH), [0.0] * WIDTH)

    @overload(lane)
    def _lane(x: Any, j: Any) -> Any:
        if isinstance(x, Lanes):
            return lambda x, j: _get(x, j)
        if isinstance(x, types.BaseTuple) and _lanes_of(x):
            return lambda x, j: _lane_of_tuple(x, j)
        return lambda x, j: x

    @overload(with_lane)
    def _with_lane(x: Any, j: Any, value: Any) -> Any:
        if isinstance(x, Lanes):
            return lambda x, j, value: _put(x, j, value)
        if isinstance(x, types.BaseTuple) and _lanes_of(x):
            return lambda x, j, value: _put_tuple(x, j, value)
        return lambda x, j, value: value

    @overload(spread)
    def _spread(x: Any, template: Any) -> Any:
        if isinstance(template, Lanes):
            if isinstance(x, types.BaseTuple):
                return lambda x, template: _spread_tuple(x, template)
            return lambda x, template: _spread_value(x, template)
        if isinstance(x, types.BaseTuple):
            return lambda x, template: x
        return lambda x, template: float(x)

    @overload(choose)
    def _choose_typing(mask: Any, a: Any, b: Any) -> Any:
        if isinstance(mask, Lanes):
            return lambda mask, a, b: _choose(mask, a, b)
        return lambda mask, a, b: a if mask else b

    @overload(most)
    def _most(x: Any) -> Any:
        if not isinstance(x, Lanes):
            return lambda x: x
        count = x.count

        def largest(x: Any) -> float:
            out = _get(x, 0)
            for j in range(1, count):
                out = max(out, _get(x, j))
            return out

        return largest

    @overload(width)
    def _width(x: Any) -> Any:
        count = x.count if isinstance(x, Lanes) else 1
        return lambda x: count

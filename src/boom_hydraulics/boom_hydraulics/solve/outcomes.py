"""How a run ends, and the one line that tells a user why it stopped.

The run loop (:func:`kernel.run_set`) and the stepping (:func:`stepping.advance`) end a step
with an outcome code: OK, or one of the failures below, and a step that fails is not
taken. :func:`message` is the one wording of each failure, for every caller that reports
one (the Simulator's SimulationError, a sweep point's ``reason``), from the parameters, the
time and the state of the last good step.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..model import MODELS
from ..model.geometry import triangle_bounds_m
from ..model.parameters import DRIVES, NAMES, Parameters
from ..model.parameters import describe as described
from . import integrators
from .stepping import ENERGY, ENERGY_TOLERANCE, HALVED_MOST, NONFINITE, OK, TOO_STIFF

#: The rod would leave the geometry of eq. 1 (q1 outside (|b - a|, a + b)), where the
#: triangle degenerates and the model cannot be evaluated (model.md, "Geometry").
OUT_OF_GEOMETRY = 4

#: Every outcome code, by name: OK (0) and the failures.
OUTCOMES = {"ok": OK, "non-finite": NONFINITE, "energy": ENERGY, "too stiff": TOO_STIFF, "geometry": OUT_OF_GEOMETRY}

#: Most substeps the stability bound may ask for in one time step before a run stops (TOO_STIFF);
#: ros2 takes a failed step again in at most stepping.HALVED_MOST.
MAX_SUBSTEPS = 10_000

__all__ = [
    "ENERGY", "MAX_SUBSTEPS", "NONFINITE", "OK", "OUTCOMES", "OUT_OF_GEOMETRY", "TOO_STIFF", "message",
    "substeps_cause",
]  # fmt: skip


def describe(p: Parameters, y: Sequence[float]) -> str:
    """The first five state components of ``y`` by name: ``q1 = 1.37, v = 0, ...``."""
    return ", ".join(f"{n} = {v:.6g}" for n, v in zip(MODELS[p.mode].STATE_NAMES[:5], y))


def step_advice(p: Parameters) -> str:
    """What to change when the integration diverged at the parameters' step."""
    if integrators.METHODS[p.method].halving:  # it has tried up to HALVED_MOST substeps itself
        return (
            f"the integration diverged: the step of {p.time_step_s:g} s ({p.method}, taken again in up to "
            f"{HALVED_MOST} substeps) is too large for these parameters; try a smaller time_step_s, or "
            "method rk4 (its stability bound sizes its substeps)"
        )
    return (
        f"the integration diverged: the step of {p.time_step_s:g} s ({p.method}, at least "
        f"{p.substeps} substeps) is too large for these parameters; try a smaller time_step_s or more "
        "substeps, or method ros2"
    )


def substeps_cause(method: str) -> str:
    """Why a step of ``method`` took more than its least substeps: its stability bound, or
    (ros2) a step that failed its checks taken again in halves."""
    return "failed steps taken again in halves" if integrators.METHODS[method].halving else "stability bound"


def likely_cause(p: Parameters) -> str:
    """Why a run leaves the geometry or blows up: paper mode has no end stops; in physical
    mode the end stops hold the rod, so the integration itself diverged."""
    if p.mode == "paper":
        low, high = triangle_bounds_m(p.a_m, p.b_m)
        return f"the rod is about to leave the valid geometry ({low:.4g}, {high:.4g}) m (paper mode has no end stops)"
    return step_advice(p)


def volume_advice(drive: str) -> str:
    """What else softens a stiff run of ``drive``: ", a larger <name>" for each oil volume of its
    own (its parameters in m^3, whose description begins with the drive's name: fixed_pump's
    supply line). This module names no drive, so that a drive is one module (docs/drives.md)."""
    own = [n for n in NAMES if described(n)["unit"] == "m^3" and described(n)["description"].startswith(f"{drive}:")]
    return "".join(f", a larger {name}" for name in own)


#: :func:`volume_advice` of each drive, in the order of parameters.DRIVES (the FMU's too).
VOLUME_ADVICE = tuple(volume_advice(drive) for drive in DRIVES)


def message(p: Parameters, outcome: int, t_s: float, y: Sequence[float], needed_substeps: int = 0) -> str:
    """Why a run of ``p`` stopped: the failure ``outcome`` of the step after ``t_s``, from the
    last good state ``y`` (at ``t_s``); ``needed_substeps``: what a TOO_STIFF step asked for."""
    state = describe(p, y)
    if outcome == NONFINITE:
        return (
            f"state became non-finite after t = {t_s:.6g} s (the next step; last finite state {state}); "
            f"{likely_cause(p)}"
        )
    if outcome == ENERGY:
        return (
            f"energy balance broken after t = {t_s:.6g} s: the change of the stored energy no longer "
            f"matches the energy that flowed, by more than {ENERGY_TOLERANCE:.0%} ({state}); {step_advice(p)}"
        )
    if outcome == TOO_STIFF:
        return (
            f"too stiff at t = {t_s:.6g} s: a stable {p.method} step of {p.time_step_s:g} s needs "
            f"{needed_substeps} substeps, more than {MAX_SUBSTEPS} ({state}); use method ros2 (implicit) "
            "or larger dead volumes"
            + VOLUME_ADVICE[DRIVES.index(p.drive)]
            + ", a lower bulk_modulus_pa or a smaller orifice"
        )
    if outcome == OUT_OF_GEOMETRY:
        low, high = triangle_bounds_m(p.a_m, p.b_m)
        return (
            f"rod left the valid geometry after t = {t_s:.6g} s ({state}): the next step takes q1 outside "
            f"({low:.4g}, {high:.4g}) m where the triangle of eq. 1 degenerates; {likely_cause(p)}"
        )
    raise ValueError(f"outcome {outcome} is not a failure (see OUTCOMES)")


def evaluation_message(p: Parameters, t_s: float, y: Sequence[float], error: Exception) -> str:
    """Why an interpreted run stopped where the model raised ``error`` (math.acos or sqrt
    outside its domain: a stage left the geometry of eq. 1) in the step after ``t_s``."""
    return f"the model cannot be evaluated near t = {t_s:.6g} s ({describe(p, y)}): {error}; {likely_cause(p)}"

"""The linear model of the physical drive at an operating point: dx/dt = A x + B u, y = C x + D u.

States x (deviations from the operating point): rod length q1, rod velocity v, the chamber
pressures p1 and p2, the spool position x_v and the seals' bristle deflection s; the model's
other states only count energy (they integrate power and never act back) and are left out.
Input u: the valve command. Outputs y: q1 (m), v (m/s), p1 and p2 (Pa).

A and B are the Jacobians of the model's own derivative (physical.derivative) with respect
to the state and the command, by :mod:`.jacobian`; C picks the outputs out of the state.
Frequency responses, gains and margins come from the ``control`` package (python-control):
:meth:`LinearModel.system` is a ``control.StateSpace`` a user can go on with.

The check on the hydraulic mode is the textbook natural frequency of a cylinder between two
oil springs (:func:`oil_spring_frequency_rad_s`), sqrt(E S1^2 / (m V1) + E S2^2 / (m V2))
with m = J k^2 the boom's inertia at the rod (eq. 8, 12, 13); near rest the seals add their
presliding stiffness F_s / z_ba (docs/model.md, "Friction").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..model.drives import DRIVES
from ..model.geometry import lever_rad_per_m
from ..model.mechanics import effective_mass_kg
from ..model.parameters import Parameters
from ..model.physical import chamber_volumes
from ..solve.simulator import scale_sizes
from .jacobian import CENTRAL, FORWARD, jacobian
from .operating_point import MODEL, SPOOL, OperatingPoint, centred_batch

if TYPE_CHECKING:
    import control  # imported where used: it takes seconds to load, and a sweep needs none of it

#: The states of the linear model: the physical model's states that act on the dynamics, then
#: those of the drive (:func:`states_of`: a drive whose supply stands still adds none) and of the
#: model elements that are on (the accumulator's, the hoses', the elastic boom's).
STATES: tuple[int, ...] = tuple(
    i
    for i, kind in enumerate(MODEL.STATE_SCALES)
    if kind != "energy" and i not in MODEL.DRIVE_STATES and i not in MODEL.ELEMENT_UNITS
)
STATE_NAMES: tuple[str, ...] = tuple(MODEL.STATE_NAMES[i] for i in STATES)
STATE_UNITS = {"q1": "m", "v": "m/s", "p1": "Pa", "p2": "Pa", "x_v": "1", "bristle": "1"}


def states_of(p: Parameters) -> tuple[int, ...]:
    """The model states of the linear model of ``p``: :data:`STATES`, the drive's own (its
    ``STATE_NAMES``) unless its supply stands still (``STEADY_SUPPLY``), then the model elements'
    that are on (physical.element_states: an accumulator's fill, the hoses', the elastic boom's)."""
    drive = DRIVES[p.drive]
    own = () if drive.STEADY_SUPPLY else MODEL.DRIVE_STATES[: len(drive.STATE_NAMES)]
    return STATES + own + MODEL.element_states(p)


def _own_names(p: Parameters, table: str) -> tuple[str, ...]:
    """The drive's states' names (``table`` STATE_NAMES) or units (STATE_UNITS) that
    :func:`states_of` keeps, then the elements' (model names and units)."""
    elements = MODEL.element_states(p)
    count = len(states_of(p)) - len(STATES) - len(elements)
    drive = tuple(getattr(DRIVES[p.drive], table)[:count])
    if table == "STATE_UNITS":
        return drive + tuple(MODEL.ELEMENT_UNITS[i] for i in elements)
    return drive + tuple(MODEL.STATE_NAMES[i] for i in elements)


def state_names_of(p: Parameters) -> tuple[str, ...]:
    """The names of :func:`states_of`: the model's, then the drive's own, then the elements'."""
    return STATE_NAMES + _own_names(p, "STATE_NAMES")


def state_units_of(p: Parameters) -> tuple[str, ...]:
    """The units of :func:`states_of`, in their order."""
    return tuple(STATE_UNITS[n] for n in STATE_NAMES) + _own_names(p, "STATE_UNITS")


#: The outputs (model state components), with their units.
OUTPUTS: tuple[tuple[str, str, str], ...] = (
    ("q1", "m", "rod position"),
    ("v", "m/s", "rod velocity"),
    ("p1", "Pa", "piston-chamber pressure"),
    ("p2", "Pa", "rod-chamber pressure"),
)
OUTPUT_NAMES = tuple(name for name, _, _ in OUTPUTS)
#: A mode this many times slower than the hydraulic one counts as slow (leakage, creep): the
#: quasi-static gains hold it still.
SLOW_RATIO = 100.0


def _state_scales(p: Parameters) -> list[float]:
    """The size of each state of :func:`states_of`, for differences and eigenvector shares: by
    the model's scale of each of :data:`STATES`, then by the drive's of its own."""
    sizes = scale_sizes(p)
    elements = MODEL.element_states(p)
    own = DRIVES[p.drive].STATE_SCALES[: len(states_of(p)) - len(STATES) - len(elements)]
    return (
        [sizes[MODEL.STATE_SCALES[i]] for i in STATES]
        + [sizes[kind] for kind in own]
        + [sizes[MODEL.STATE_SCALES[i]] for i in elements]
    )


@dataclass(frozen=True)
class Mode:
    """One eigenvalue of A: a complex pair counts once (the one with positive imaginary part)."""

    eigenvalue: complex  # 1/s
    natural_frequency_hz: float  # |lambda| / 2 pi
    damping_ratio: float  # -Re(lambda) / |lambda| (1 for a real mode)
    oscillatory: bool


@dataclass(frozen=True)
class Margins:
    """Stability margins of a loop gain L(s) (control.stability_margins)."""

    gain_margin: float  # the factor by which the gain may grow before the loop goes unstable (inf: never)
    phase_margin_deg: float
    crossover_hz: float  # where |L| = 1 (gain crossover)
    phase_crossover_hz: float  # where the phase of L is -180 deg (nan: nowhere)

    @property
    def gain_margin_db(self) -> float:
        return 20.0 * math.log10(self.gain_margin) if self.gain_margin > 0 else math.nan


@dataclass(frozen=True)
class LinearModel:
    """A, B, C, D of the drive at ``point`` (states :attr:`state_names`, outputs OUTPUT_NAMES, SI units)."""

    point: OperatingPoint
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray

    @property
    def states(self) -> tuple[int, ...]:
        """The model states this linear model keeps (:func:`states_of`)."""
        return states_of(self.point.params)

    @property
    def state_names(self) -> tuple[str, ...]:
        return state_names_of(self.point.params)

    @property
    def state_units(self) -> tuple[str, ...]:
        return state_units_of(self.point.params)

    def system(self) -> control.StateSpace:
        """The model as a python-control state space (input ``u``, outputs q1, v, p1, p2)."""
        import control

        return control.ss(
            self.A, self.B, self.C, self.D, inputs=["u"], outputs=list(OUTPUT_NAMES), states=list(self.state_names)
        )

    def modes(self) -> list[Mode]:
        """Every mode, slowest first."""
        out = []
        for lam in np.linalg.eigvals(self.A):
            if lam.imag < 0.0:
                continue
            size = abs(lam)
            out.append(Mode(complex(lam), size / (2 * math.pi), -lam.real / size if size else 1.0, lam.imag > 0.0))
        return sorted(out, key=lambda m: m.natural_frequency_hz)

    def hydraulic_mode(self) -> Mode | None:
        """The oscillation of the boom on its oil springs (see :func:`hydraulic_eigenvalue`)."""
        p = self.point.params
        tip = p.boom_length_m * lever_rad_per_m(self.point.q1_m, p.a_m, p.b_m)
        lam = hydraulic_eigenvalue(self.A[None], p, self.state_names, tip_m_per_m=tip)[0]
        if not np.isfinite(lam):
            return None
        size = abs(lam)
        return Mode(complex(lam), size / (2 * math.pi), -lam.real / size, True)

    def dc_gains(self) -> np.ndarray:
        """G(0), the static gain of each output per unit of valve command (control.dcgain, one
        output at a time): inf where a mode at s = 0 integrates the command, nan where it is
        undetermined (0/0)."""
        import control

        gains = []
        for row in range(len(OUTPUT_NAMES)):
            siso = control.ss(self.A, self.B, self.C[row : row + 1], self.D[row : row + 1])
            gains.append(float(np.real(siso.dcgain())))
        return np.array(gains)

    def quasi_static_gains(self) -> np.ndarray:
        """The gain of each output once the fast modes have settled while the slow ones (leakage,
        creep: SLOW_RATIO times slower than the hydraulic mode, or slower) have not yet moved:
        -C_f A_f^-1 B_f + D of the fast block, A split into fast and slow blocks by an ordered
        real Schur form and a Sylvester equation (no eigenvectors: robust where slow modes repeat),
        of the states each in units of its scale (:func:`_state_scales`): in Pa and metres at
        once, A's entries span ten decades and the Schur form lost the gains' fourth digit."""
        import scipy.linalg  # here: a sweep imports this module for its modes, which need no scipy

        mode = self.hydraulic_mode()
        limit = (abs(mode.eigenvalue) if mode else float(np.max(np.abs(np.linalg.eigvals(self.A))))) / SLOW_RATIO
        scales = np.array(_state_scales(self.point.params))
        a, b, c = self.A * scales[None, :] / scales[:, None], self.B / scales[:, None], self.C * scales[None, :]
        s, z, k = scipy.linalg.schur(a, output="real", sort=lambda re, im: math.hypot(re, im) >= limit)
        coupling = scipy.linalg.solve_sylvester(s[:k, :k], -s[k:, k:], -s[:k, k:])  # S11 X - X S22 = -S12
        fast = (z.T @ b)[:k] - coupling @ (z.T @ b)[k:]
        return -(c @ z[:, :k]) @ np.linalg.solve(s[:k, :k], fast)[:, 0] + self.D[:, 0]


def hydraulic_eigenvalue(
    a: np.ndarray,
    p: Parameters,
    names: Sequence[str] = STATE_NAMES,
    sizes: Sequence[float] | None = None,
    tip_m_per_m: Any = None,
) -> np.ndarray:
    """The hydraulic mode's eigenvalue of each matrix of the stack ``a`` (..., n, n) over the
    states ``names`` (of sizes ``sizes``, by default those of ``p``'s :func:`states_of`): of the
    oscillatory modes, the one whose eigenvector moves the boom's tip most against the other
    states (each in units of its scale); nan where every mode is real. The tip moves with the
    rod's velocity v (a rigid boom: the mode of the rod's velocity), and with the elastic boom's
    deflection rate too: L1 k(q1) v + eta' across the boom at its tip (docs/model.md, "Elastic
    boom"), ``tip_m_per_m`` being L1 k(q1), the rigid tip's speed per unit of the rod's (one per
    matrix; needed where ``names`` hold the deflection).
    By the rod alone the elastic crane's mode was its boom's root ringing on the oil beneath it
    (125 Hz), where the tonne at the tip stays put; the tonne's ringing is the one it shows."""
    values, vectors = np.linalg.eig(a)
    scales = np.array(_state_scales(p)[: len(names)] if sizes is None else sizes)
    scaled = np.abs(vectors) / scales[:, None]  # each component in units of its state's size
    v = names.index("v")
    tip = scaled[..., v, :]
    if "boom_deflection_rate" in names:  # the tip across the boom: its rotation's and its bending's
        lever = np.asarray(tip_m_per_m, dtype=float)
        across = lever[..., None] * vectors[..., v, :] + vectors[..., names.index("boom_deflection_rate"), :]
        tip = np.abs(across) / scales[v]
    share = tip / np.sum(scaled, axis=-2)
    share = np.where(values.imag > 0.0, share, -1.0)
    best = np.argmax(share, axis=-1)
    lam = np.take_along_axis(values, best[..., None], axis=-1)[..., 0]
    return np.where(np.take_along_axis(share, best[..., None], axis=-1)[..., 0] >= 0.0, lam, np.nan)


def _jacobian(
    c: Any,
    state: Sequence[Any],
    opening: Any,
    side: int,
    p: Parameters,
    xp: Any = math,
    states: Sequence[int] = STATES,
    sizes: Sequence[float] | None = None,
) -> np.ndarray:
    """[A | B]: the derivative's Jacobian over the linear model's ``states`` and the command at
    ``state`` (floats, or arrays of a batch with ``xp=numpy``); ``sizes`` the states' scales
    (default: :func:`_state_scales`)."""
    scales = _state_scales(p)[: len(states)] if sizes is None else list(sizes)

    def f(x: list) -> list:
        y = list(state)
        for i, xi in zip(states, x[:-1]):
            y[i] = xi
        d = MODEL.derivative(0.0, y, c, x[-1], xp)
        return [d[i] for i in states]

    x = [state[i] for i in states] + [opening]
    sides = [side if i == SPOOL else CENTRAL for i in states]
    sides.append(side)  # the command acts on the flows directly where there is no spool lag
    return jacobian(f, x, [*scales, 1.0], sides)


def linearize(point: OperatingPoint) -> LinearModel:
    """The linear model at ``point`` (A, B by differences of the model's derivative)."""
    p = point.params
    states = states_of(p)
    j = _jacobian(MODEL.constants(p), point.state, point.opening, point.kink_side, p, math, states)
    n = len(states)
    cmat = np.zeros((len(OUTPUT_NAMES), n))
    for row, name in enumerate(OUTPUT_NAMES):
        cmat[row, STATE_NAMES.index(name)] = 1.0
    return LinearModel(point, j[:, :n], j[:, n:], cmat, np.zeros((len(OUTPUT_NAMES), 1)))


def mid_stroke_modes(params: Sequence[Parameters]) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequency (Hz) and damping ratio of the hydraulic mode of each physical-mode
    parameter set at mid-stroke with the valve centred, all sets at once (numpy); nan for a
    paper-mode set, a drive without the valve (pump_controlled, whose rod side sits at the
    reservoir's pressure), one without an oscillating mode or one whose operating point was not found."""
    frequency, damping = np.full(len(params), np.nan), np.full(len(params), np.nan)
    chosen = [k for k, p in enumerate(params) if p.mode == "physical" and DRIVES[p.drive].VALVE]
    if not chosen:
        return frequency, damping
    sets = [params[k] for k in chosen]
    q1 = np.array([0.5 * (p.cylinder_min_length_m + p.cylinder_max_length_m) for p in sets])
    y, c, ok = centred_batch(sets, q1)
    # the elements' states where any set has them (a set without: rows and columns that stand still)
    elements = tuple(sorted({i for p in sets for i in MODEL.element_states(p)}))
    states = STATES + elements
    kinds = scale_sizes(sets[0])
    sizes = [kinds[MODEL.STATE_SCALES[i]] for i in states]
    a = _jacobian(c, y, np.zeros(len(sets)), FORWARD, sets[0], np, states, sizes)[..., :, : len(states)]
    names = [MODEL.STATE_NAMES[i] for i in states]
    tip = np.array([p.boom_length_m * lever_rad_per_m(q, p.a_m, p.b_m) for p, q in zip(sets, q1)])
    lam = np.where(ok, hydraulic_eigenvalue(a, sets[0], names, sizes, tip), np.nan)
    size = np.abs(lam)
    frequency[chosen] = size / (2 * math.pi)
    damping[chosen] = -lam.real / size
    return frequency, damping


def effective_mass_at(p: Parameters, q1_m: Any, xp: Any = math) -> Any:
    """m = J k^2: the boom and payload's inertia seen at the rod at length ``q1_m``, kg (eq. 8)."""
    c = MODEL.constants(p)
    return effective_mass_kg(c.inertia, lever_rad_per_m(q1_m, p.a_m, p.b_m, xp))


def oil_spring_frequency_rad_s(p: Parameters, q1_m: float, seals: bool = False) -> float:
    """sqrt(E S1^2 / (m V1) + E S2^2 / (m V2)) at rod length ``q1_m``, rad/s: the cylinder's mass
    between its two oil columns, V1 and V2 the chamber volumes there (eq. 12, 13), each with its
    hose's oil beside it at the hose's K_eff where there are hoses (their lumped limit); with
    ``seals``, plus their presliding stiffness F_s / z_ba (the LuGre bristles near rest)."""
    c = MODEL.constants(p)
    v1, v2, _, _ = chamber_volumes(q1_m, c)
    stiffness = c.bulk_modulus * (c.s1 * c.s1 / v1 + c.s2 * c.s2 / v2)
    if c.hose_on:  # each hose's oil a lumped volume at K_eff beside its chamber (eq. H1: the low-frequency limit)
        hose = c.hose_chamber_share / c.hose_modulus
        stiffness = c.s1 * c.s1 / (v1 / c.bulk_modulus + hose) + c.s2 * c.s2 / (v2 / c.bulk_modulus + hose)
    if seals:
        stiffness += c.static / c.presliding
    return math.sqrt(stiffness / effective_mass_at(p, q1_m))


def angle_gain(point: OperatingPoint) -> float:
    """d(alpha)/dq1 at the operating point, rad/m (the lever k of eq. 5)."""
    p = point.params
    return lever_rad_per_m(point.q1_m, p.a_m, p.b_m)


def loop_gain(model: LinearModel) -> control.TransferFunction:
    """L(s) of the position controller around the drive: the PI controller on the boom-angle
    error, (Kp + Ki / s) (model/control.py), times the drive from valve command to boom angle,
    k G_q1(s). The feedforward acts outside the loop; the dead-band (which closes the valve
    near the target) and the anti-windup (which stops the integral) are left out: the loop as
    it is while the controller works on an error."""
    import control

    p = model.point.params
    controller = control.tf(
        [p.control_position_gain_1_rad, p.control_integral_gain_1_rad_s], [1.0, 0.0], inputs="e", outputs="u"
    )
    plant = control.ss2tf(model.system()[OUTPUT_NAMES.index("q1"), 0]) * angle_gain(model.point)
    return controller * plant


def margins(loop: Any) -> Margins:
    """Gain and phase margins and the crossover frequencies of the loop gain ``loop``."""
    import control

    gm, pm, _, w_phase, w_gain, _ = control.stability_margins(loop)
    return Margins(float(gm), float(pm), float(w_gain) / (2 * math.pi), float(w_phase) / (2 * math.pi))

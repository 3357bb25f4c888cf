"""The elastic boom (docs/model.md, "Elastic boom"): its first bending mode against the
Euler-Bernoulli cantilever with a tip mass, its static tip deflection against P L^3 / (3 EI),
its energy in the ledger, and nothing moved where it is off."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
import scipy.linalg
from conftest import BOOM_SIM, CONFIG
from scipy.optimize import brentq

from boom_hydraulics.analysis import linear_model as lm
from boom_hydraulics.analysis.operating_point import operating_point
from boom_hydraulics.model import config, elastic_boom, ledger, physical
from boom_hydraulics.model.geometry import boom_angle_rad, lever_rad_per_m
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import commands
from boom_hydraulics.solve.simulator import Simulator

#: The 1 t loader crane (config/loader_crane_1t.yaml), its boom elastic (its accumulator and hoses off:
#: the closed forms are the bare cylinder's; the node and the live view run the crane as it ships).
CRANE = with_updates(config.load(CONFIG / "loader_crane_1t.yaml"), accumulator_gas_volume_m3=0.0, hose_length_m=0.0)
EI = CRANE.boom_bending_stiffness_n_m2
L = CRANE.boom_length_m


def cantilever_root(mass_ratio: float) -> float:
    """beta L, the first root of the Euler-Bernoulli cantilever with a tip mass M (mass_ratio =
    M / (rho A L)): 1 + cos(bL) cosh(bL) + r bL (cos(bL) sinh(bL) - sin(bL) cosh(bL)) = 0."""

    def equation(b: float) -> float:
        return (
            1.0
            + math.cos(b) * math.cosh(b)
            + mass_ratio * b * (math.cos(b) * math.sinh(b) - math.sin(b) * math.cosh(b))
        )

    return brentq(equation, 1e-3, 1.8752, xtol=1e-14)


def exact_frequency_rad_s(boom_mass_kg: float, payload_kg: float) -> float:
    """omega_1 = (beta L)^2 sqrt(EI / (rho A L^4)) of the cantilever with its tip mass."""
    b = cantilever_root(payload_kg / boom_mass_kg)
    return b * b * math.sqrt(EI / (boom_mass_kg * L**3))


def assumed_mode_frequency_rad_s(boom_mass_kg: float, payload_kg: float) -> float:
    """sqrt(k_eta / m_eta) of the module's own modal stiffness and mass (eq. E3), rotation held."""
    _, modal, _ = elastic_boom.modal_masses(boom_mass_kg, payload_kg, L)
    return math.sqrt(elastic_boom.modal_stiffness_n_m(EI, L) / modal)


#: Rayleigh's quotient with the static tip-load shape over-estimates omega_1 (it is an upper
#: bound); the error is largest without a tip mass: sqrt(3 / (33/140)) / 1.87510^2 - 1 = 1.46 %,
#: and falls as the tip mass dominates (the shape is then the exact static one).
RAYLEIGH_ERROR = math.sqrt(3.0 * 140.0 / 33.0) / 1.8751040687**2 - 1.0


@pytest.mark.parametrize("payload_kg", [0.0, 50.0, 200.0, 1000.0])
def test_the_first_mode_is_the_cantilever_with_its_tip_mass_from_above(payload_kg):
    boom_kg = CRANE.boom_mass_kg
    exact = exact_frequency_rad_s(boom_kg, payload_kg)
    error = assumed_mode_frequency_rad_s(boom_kg, payload_kg) / exact - 1.0
    assert 0.0 <= error <= RAYLEIGH_ERROR + 1e-9, error
    if payload_kg == 0.0:
        assert error == pytest.approx(RAYLEIGH_ERROR, rel=1e-6)  # the textbook 3.5675 against 3.5160
    if payload_kg >= 10.0 * boom_kg:
        assert error < 1e-3  # a tip mass ten times the boom's: the static shape is nearly exact


def _two_masses_hz(params: Parameters, q1_m: float) -> np.ndarray:
    """The two modes of the boom on its oil springs with its bending mode (eq. E1-E5, 12, 13):
    det(K - w^2 M) = 0, M = [[J, m_c], [m_c, m_eta]], K = diag(E (S1^2/V1 + S2^2/V2) / k^2, k_eta), Hz."""
    c = physical.constants(params)
    v1, v2, _, _ = physical.chamber_volumes(q1_m, c)
    k = lever_rad_per_m(q1_m, c.a, c.b)
    oil = c.bulk_modulus * (c.s1**2 / v1 + c.s2**2 / v2) / k**2  # the oil's stiffness at the boom, N m/rad
    coupling, modal, _ = elastic_boom.modal_masses(params.boom_mass_kg, params.payload_mass_kg, L)
    mass = np.array([[c.inertia, coupling], [coupling, modal]])
    return np.sqrt(scipy.linalg.eigh(np.diag([oil, c.boom_stiffness]), mass, eigvals_only=True)) / (2 * math.pi)


@pytest.mark.parametrize("bulk_modulus_pa", [1.0e9, 1.0e11])
def test_linearize_finds_the_boom_on_its_oil_coupled_to_its_bending_mode(bulk_modulus_pa):
    """The linear model's two oscillating modes are those of the two-mass model above to 0.3 %
    (what it leaves out: the weight's geometric stiffness, S g / k_eta of 1.7 % times sin(alpha),
    and the valve's flows). With real oil (1 GPa) the tonne rings at 2.66 Hz, the boom's root on
    the oil beneath it at 125 Hz; with oil a hundred times stiffer the rotation is held and the
    bending mode comes within 0.6 % of the clamped sqrt(k_eta / m_eta), so within the Rayleigh
    bound (plus that) of the Euler-Bernoulli cantilever with the tonne at its tip."""
    params = with_updates(CRANE, bulk_modulus_pa=bulk_modulus_pa, static_friction_n=0.0, coulomb_friction_n=0.0)
    q1 = 0.5 * (params.cylinder_min_length_m + params.cylinder_max_length_m)
    model = lm.linearize(operating_point(params, q1))
    assert model.state_names[-2:] == ("boom_deflection", "boom_deflection_rate")
    ringing = [m.natural_frequency_hz for m in model.modes() if m.oscillatory]
    assert len(ringing) == 2
    assert ringing == pytest.approx(list(_two_masses_hz(params, q1)), rel=3e-3)
    if bulk_modulus_pa >= 1.0e11:
        clamped = assumed_mode_frequency_rad_s(params.boom_mass_kg, params.payload_mass_kg) / (2 * math.pi)
        assert ringing[0] == pytest.approx(clamped, rel=6e-3) and ringing[0] < clamped
        exact = exact_frequency_rad_s(params.boom_mass_kg, params.payload_mass_kg) / (2 * math.pi)
        assert abs(ringing[0] / exact - 1.0) < RAYLEIGH_ERROR + 6e-3
    # off, the linear model keeps today's states
    assert "boom_deflection" not in lm.state_names_of(with_updates(CRANE, boom_bending_stiffness_n_m2=0.0))


def test_a_held_boom_settles_to_the_static_tip_deflection():
    """The valve closed, the empty boom at rest bent by its own weight; the tonne is hung on
    its tip and the boom rings down (20 % damping, to settle fast). At rest its tip deflects by
    P L^3 / (3 EI) under the payload's weight normal to the boom, P = mb g cos(alpha), plus
    q L^4 / (8 EI) under its own weight (both exact for the mode's static shape)."""
    params = with_updates(CRANE, boom_damping_ratio=0.2, payload_mass_kg=0.0)
    sim = Simulator(params)
    empty, empty_alpha = sim.outputs()["boom_deflection"], sim.outputs()["alpha"]
    sim.set_payload_mass(CRANE.payload_mass_kg)
    out = sim.outputs()
    while sim.t < 30.0 and (abs(out["boom_deflection_rate"]) > 1e-6 or abs(out["v"]) > 1e-7 or sim.t < 1.0):
        sim.step(0.0, 500)  # until the tip and the rod have come to rest
        out = sim.outputs()
    cos_alpha = math.cos(out["alpha"])
    g = params.gravity_m_s2
    tip_load = CRANE.payload_mass_kg * g * cos_alpha
    distributed = params.boom_mass_kg * g * cos_alpha / L
    own_weight = params.boom_mass_kg * g * math.cos(empty_alpha) / L
    assert empty == pytest.approx(-own_weight * L**4 / (8 * EI), rel=1e-9)  # the start: eq. E5 at rest
    assert out["boom_deflection"] == pytest.approx(
        -(tip_load * L**3 / (3 * EI) + distributed * L**4 / (8 * EI)), rel=2e-3
    )
    assert abs(out["boom_deflection_rate"]) < 1e-6 and abs(out["a"]) < 1e-4
    # the tonne's own share: P L^3 / (3 EI), 16.6 mm for this box at the horizontal
    assert tip_load * L**3 / (3 * EI) == pytest.approx(0.0166 * cos_alpha, rel=0.01)


def test_the_ledger_closes_with_the_elastic_boom_on_over_the_loader_cycle():
    """The loader cycle with the tonne: the ledger's integrals balance to 0.5 % of the battery's
    energy, the stored terms are the change of the boom's energy with its mode's, the structural
    damping took energy, and the stepping's energy check (W against H) held throughout."""
    params = with_updates(CRANE, **commands.scenario("loader", 0.0, CRANE))
    sim = Simulator(params)
    c = physical.constants(params)
    start = list(sim.y)
    out = sim.run(8.0, commands.from_parameters(params), every=10)
    end = list(sim.y)
    integrals = physical.ledger_integrals(end)
    energies = ledger.energies_of(integrals)
    assert energies["imbalance_ratio"] < 0.005, energies
    assert integrals["structural_loss"] > 0.0
    stored = integrals["kinetic_power"] + integrals["potential_power"]
    assert stored == pytest.approx(_mechanical(end, c) - _mechanical(start, c), abs=1e-4 * integrals["lift_work"])
    assert abs(sim.energy_residual()) < 1e-3 * integrals["battery_drawn"]
    # the tip rang while the boom moved: its deflection left the static one by millimetres
    swing = np.ptp(out["boom_deflection"] - _static_deflection(params, out["q1"]))
    assert swing > 1e-3


def _mechanical(y: list, c: physical.Constants) -> float:
    """Kinetic and potential energy of boom and payload with the bending mode's (eq. 8, 9, E1, E2), J."""
    k = lever_rad_per_m(y[0], c.a, c.b)
    alpha = boom_angle_rad(y[0], c.a, c.b, c.h)
    rigid = 0.5 * c.inertia * (k * y[1]) ** 2 + c.weight_coeff * math.sin(alpha)
    return rigid + 0.5 * c.spring * (y[0] - c.spring_free) ** 2 + physical._boom_energy(y, c, k * y[1], math)


def _static_deflection(params: Parameters, q1: np.ndarray) -> np.ndarray:
    return np.array([elastic_boom.static_deflection_m(params, float(q)) for q in q1])


def test_off_the_mode_stays_still_and_the_rod_moves_as_the_rigid_boom_bit_for_bit():
    """EI = 0 (the default): the boom's states' rates are exactly 0 and every other rate is the
    rigid boom's (mechanics.acceleration_at_lever's, with no term added) at random states."""
    p = Parameters()
    c = physical.constants(p)
    assert p.boom_bending_stiffness_n_m2 == 0.0 and c.boom_on == 0.0
    rng = np.random.default_rng(5)
    from boom_hydraulics.model.mechanics import acceleration_at_lever

    for _ in range(20):
        y = physical.initial_state(p, rng.uniform(p.cylinder_min_length_m, p.cylinder_max_length_m))
        y[1], y[2], y[3] = rng.uniform(-0.3, 0.3), rng.uniform(1e6, 1e7), rng.uniform(1e5, 1e6)
        t = physical._terms(y, c, rng.uniform(-1, 1), math)
        d = physical.derivative(0.0, y, c, 0.3)
        assert d[physical.BOOM_STATE] == 0.0 and d[physical.BOOM_STATE + 1] == 0.0
        rigid = acceleration_at_lever(y[1], t.f_rod, c.inertia, c.weight_coeff * t.cos_alpha, t.lever, t.lever_slope)
        assert t.acc == rigid  # bit for bit
        assert physical.ledger(0.0, y, c, 0.3).structural_loss == 0.0
    assert physical.initial_state(p)[physical.BOOM_STATE] == 0.0


def test_the_shape_s_integrals_and_the_modal_masses_are_the_shape_s_own_by_quadrature():
    """E1-E3 against the shape itself: phi(xi) = (3 xi^2 - xi^3)/2 bends from a clamp (phi(0) =
    phi'(0) = 0) to the tip (phi(1) = 1); its slope is its derivative; int phi, int xi phi, int
    phi^2 and int phi''^2 are the module's constants; the modal masses are the boom's mass
    m1/L1 per metre plus the tip mass against phi, x phi and phi^2, and k_eta is EI int phi''^2
    along the boom (Simpson's rule on 2001 points: exact for these polynomials to rounding)."""
    from scipy.integrate import simpson

    xi = np.linspace(0.0, 1.0, 2001)
    phi = elastic_boom.mode_shape(xi)
    assert phi[0] == 0.0 and phi[-1] == 1.0 and elastic_boom.mode_slope(0.0) == 0.0
    slope = elastic_boom.mode_slope(xi)
    assert np.allclose(slope[1:-1], (phi[2:] - phi[:-2]) / (xi[2:] - xi[:-2]), atol=1e-6)
    curvature = 3.0 * (1.0 - xi)  # phi'' of the cubic, and the slope's own derivative:
    assert np.allclose(curvature[1:-1], (slope[2:] - slope[:-2]) / (xi[2:] - xi[:-2]), atol=1e-6)
    assert simpson(phi, x=xi) == pytest.approx(elastic_boom.SHAPE_FIRST, rel=1e-12)
    assert simpson(xi * phi, x=xi) == pytest.approx(elastic_boom.SHAPE_MOMENT, rel=1e-12)
    assert simpson(phi * phi, x=xi) == pytest.approx(elastic_boom.SHAPE_SQUARE, rel=1e-12)
    assert simpson(curvature**2, x=xi) == pytest.approx(elastic_boom.SHAPE_CURVATURE, rel=1e-12)
    boom_kg, tip_kg, length = 180.0, 650.0, 4.2
    x = xi * length
    per_metre = boom_kg / length
    coupling, modal, participation = elastic_boom.modal_masses(boom_kg, tip_kg, length)
    assert coupling == pytest.approx(simpson(per_metre * x * phi, x=x) + tip_kg * length, rel=1e-12)
    assert modal == pytest.approx(simpson(per_metre * phi * phi, x=x) + tip_kg, rel=1e-12)
    assert participation == pytest.approx(simpson(per_metre * phi, x=x) + tip_kg, rel=1e-12)
    bending = 3.1e6
    along = simpson((curvature / length**2) ** 2, x=x)  # (d^2 phi / dx^2)^2 along the boom
    assert elastic_boom.modal_stiffness_n_m(bending, length) == pytest.approx(bending * along, rel=1e-12)
    short = 0.8  # a boom under a metre: the guard for a zero length leaves it alone
    assert elastic_boom.modal_stiffness_n_m(bending, short) == pytest.approx(3.0 * bending / short**3, rel=1e-12)
    assert elastic_boom.modal_stiffness_n_m(0.0, 0.0) == 0.0  # no boom, no mode (and no division by 0)


@pytest.mark.parametrize("damping_ratio", [0.0, 0.02, 3.0])
def test_the_modes_rate_bound_is_its_frequency_and_damping_rate_with_the_rotation_free(damping_ratio):
    """fastest_rate against the eigenvalues of the boom free to turn (E4 without the cylinder:
    masses [[J, m_c], [m_c, m_eta]], the mode's k_eta and c_eta): beside the rotation's two zero
    roots the mode's pair has lambda1 lambda2 = k_eta / m_f and -(lambda1 + lambda2) = c_eta / m_f,
    so the bound sqrt(k_eta / m_f) + c_eta / m_f is sqrt(|lambda1 lambda2|) + |lambda1 + lambda2|
    (undamped, underdamped and overdamped alike), which covers both roots."""
    boom_kg, tip_kg, length = 180.0, 650.0, 4.2
    inertia = (boom_kg / 3.0 + tip_kg) * length**2  # eq. 8
    coupling, modal, _ = elastic_boom.modal_masses(boom_kg, tip_kg, length)
    stiffness = elastic_boom.modal_stiffness_n_m(3.1e6, length)
    damping = elastic_boom.modal_damping_n_s_m(damping_ratio, stiffness, modal)
    masses = np.array([[inertia, coupling], [coupling, modal]])
    spring, dashpot = np.diag([0.0, stiffness]), np.diag([0.0, damping])
    system = np.block(
        [[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(masses, spring), -np.linalg.solve(masses, dashpot)]]
    )
    roots = sorted(np.linalg.eigvals(system), key=abs)
    assert abs(roots[0]) < 1e-9 and abs(roots[1]) < 1e-9  # the rotation, free
    pair = roots[2:]
    bound = elastic_boom.fastest_rate(inertia, coupling, modal, stiffness, damping)
    assert bound == pytest.approx(math.sqrt(abs(pair[0] * pair[1])) + abs(pair[0] + pair[1]), rel=1e-9)
    assert bound >= (1.0 - 1e-12) * max(abs(r) for r in pair)  # (undamped: equal, to rounding)


def test_the_static_tip_deflection_is_the_tip_load_s_and_the_boom_weight_s_closed_forms():
    """At rest (E5) the tip hangs P L^3 / (3 EI) + q L^4 / (8 EI) below the rigid boom, P and q
    the payload's and the boom's weight per metre normal to the boom (exact: the tip-load shape
    gives the uniform load's tip deflection too), and as far as it bends for a boom as soft as a rope
    (k_eta = 3 EI / L^3 under 1 N/m); a rigid boom (EI = 0) does not bend."""
    soft = with_updates(CRANE, boom_bending_stiffness_n_m2=2.0)
    assert elastic_boom.modal_stiffness_n_m(soft.boom_bending_stiffness_n_m2, L) < 1.0
    stroke = (CRANE.cylinder_min_length_m + 0.05, CRANE.initial_length_m, CRANE.cylinder_max_length_m - 0.05)
    for p, q1 in [*((CRANE, q1) for q1 in stroke), (soft, CRANE.initial_length_m)]:
        bending = p.boom_bending_stiffness_n_m2
        alpha = boom_angle_rad(q1, p.a_m, p.b_m, p.support_height_m)
        normal = p.gravity_m_s2 * math.cos(alpha)
        tip = p.payload_mass_kg * normal * L**3 / (3.0 * bending)
        spread = p.boom_mass_kg / L * normal * L**4 / (8.0 * bending)
        assert elastic_boom.static_deflection_m(p, q1) == pytest.approx(-(tip + spread), rel=1e-12), (bending, q1)
    assert elastic_boom.static_deflection_m(with_updates(CRANE, boom_bending_stiffness_n_m2=0.0), 1.9) == 0.0


def test_the_static_deflection_is_the_module_s_equilibrium():
    """initial_state's eta zeroes the mode's rate with the boom at rest (eq. E5)."""
    y = physical.initial_state(CRANE)
    alpha = boom_angle_rad(y[0], CRANE.a_m, CRANE.b_m, CRANE.support_height_m)
    _, _, participation = elastic_boom.modal_masses(CRANE.boom_mass_kg, CRANE.payload_mass_kg, L)
    k = elastic_boom.modal_stiffness_n_m(EI, L)
    assert y[physical.BOOM_STATE] == pytest.approx(-participation * CRANE.gravity_m_s2 * math.cos(alpha) / k)


# --- through ROS: the node with the 1 t crane (its boom elastic) -------------------------------


def _ros_tip(robot, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """(the boom_tip frame's position, the rigid boom's tip) in base_link, x and z (yourdfpy FK)."""
    pivot = robot.get_transform("boom", "base_link")[:3, 3]
    tip = robot.get_transform("boom_tip", "base_link")[:3, 3]
    return tip[[0, 2]], pivot[[0, 2]] + L * np.array([math.cos(alpha), math.sin(alpha)])


@pytest.mark.usefixtures("ros_context")
def test_through_ros_the_tip_frame_moves_by_the_deflection_and_the_hinge_force_is_published(nodes, client):
    """The node with the 1 t crane: its URDF's boom_tip joint is prismatic, joint_states gives
    it the tip's deflection, so that the tip frame (as robot_state_publisher computes it from
    both) lies off the rigid boom's tip by exactly that, normal to the boom; a lift makes the tip
    swing. hinge_wrench in frame boom holds the boom at rest: the pin's normal force is the
    weight's less what the cylinder's takes at the rod eye, M_g / a (eq. E4, E8 at rest)."""
    if BOOM_SIM is None:
        pytest.skip("boom_sim not on PATH (run through tools/with-env)")
    yourdfpy = pytest.importorskip("yourdfpy")
    from geometry_msgs.msg import WrenchStamped
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    node = nodes.start("command_timeout_s:=0.5", config_file="loader_crane_1t.yaml")
    descriptions: list[String] = []
    wrenches: list[WrenchStamped] = []
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    client.node.create_subscription(String, "robot_description", descriptions.append, latched)
    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    client.node.create_subscription(WrenchStamped, "hinge_wrench", wrenches.append, reliable)
    assert client.spin_until(lambda: descriptions and wrenches and len(client.joints) > 3), node.poll()
    robot = yourdfpy.URDF.load(
        io.StringIO(descriptions[-1].data), build_scene_graph=True, load_meshes=False, build_collision_scene_graph=False
    )
    joints = client.joints[-1]
    assert list(joints.name) == ["boom_joint", "cylinder_barrel_joint", "cylinder_joint", "boom_tip_joint"]
    values = dict(zip(joints.name, joints.position))
    robot.update_cfg(values)
    alpha, eta = values["boom_joint"], values["boom_tip_joint"]
    tip, rigid = _ros_tip(robot, alpha)
    assert eta < -0.01  # bent by the tonne: 16.6 mm cos(alpha) and the boom's own weight
    assert tip - rigid == pytest.approx(eta * np.array([-math.sin(alpha), math.cos(alpha)]), abs=1e-9)
    # at rest, the pin's force normal to the boom (the rigid statics within the mode's share)
    wrench = wrenches[-1]
    assert wrench.header.frame_id == "boom" and wrench.wrench.torque.y == 0.0
    g, mass = CRANE.gravity_m_s2, CRANE.boom_mass_kg + CRANE.payload_mass_kg
    first_moment = (0.5 * CRANE.boom_mass_kg + CRANE.payload_mass_kg) * L
    normal = mass * g * math.cos(alpha) - first_moment * g * math.cos(alpha) / CRANE.a_m
    assert wrench.wrench.force.z == pytest.approx(normal, rel=0.02)
    # a lift: the tip swings about its static deflection, and its frame with it
    client.handshake()
    swung = []

    def swinging() -> bool:
        j = client.joints[-1]
        swung.append(dict(zip(j.name, j.position))["boom_tip_joint"])
        return max(swung) - min(swung) > 1e-3

    assert client.spin_until(swinging, opening=1.0), (min(swung), max(swung))


def test_the_markers_draw_the_boom_to_its_deflected_tip():
    """The boom marker runs from the pivot to the tip moved by the deflection normal to the boom,
    the payload hangs there; a rigid boom's (no deflection in the outputs: an older bag) are as before."""
    from boom_hydraulics.bags.markers import CraneMarkers
    from boom_hydraulics.model.kinematics import chain, pivot_xz

    crane = CraneMarkers(CRANE)
    c = chain(CRANE, 1.8, 0.0)
    out = {"p1": 1e7, "p2": 1e5, "void1": 0.0, "void2": 0.0}
    rigid = {m.id: m for m in crane.fields(out, c)}
    bent = {m.id: m for m in crane.fields({**out, "boom_deflection": -0.02}, c)}
    shift = np.subtract(bent[2].position, rigid[2].position)  # the payload (marker id 2)
    assert shift == pytest.approx([0.02 * math.sin(c.boom_rad), 0.0, -0.02 * math.cos(c.boom_rad)], abs=1e-12)
    o = pivot_xz(CRANE)
    middle = np.array([bent[1].position[0], bent[1].position[2]])  # the boom's middle, half-way to the tip
    tip = np.array([bent[2].position[0], bent[2].position[2] + crane._drawing.payload_radius])
    assert middle == pytest.approx((np.array(o) + tip) / 2, abs=1e-12)


def test_live_shows_the_tip_ringing_in_its_plot_and_frames_and_boom_resim_repeats_its_bag(tmp_path):
    """boom-sim live with the 1 t crane: joint_states carries boom_tip_joint (the layout's tip
    plot), /tf moves boom_tip by it, a lift makes the tip ring; the bag it records, fed through
    boom-resim, gives the recorded run again (to within one tick's motion, as test_live's)."""
    import json

    from bag_checks import check_resim_within_a_tick
    from foxglove_client import FoxgloveClient, LiveServer

    layout = json.loads((CONFIG.parent / "src" / "boom_hydraulics" / "foxglove" / "boom_crane.json").read_text())
    (path,) = layout["configById"]["Plot!boom_tip"]["paths"]
    assert path["value"] == "/joint_states.position[3]"
    bag = tmp_path / "elastic_bag"
    live = LiveServer("--config", str(CONFIG / "loader_crane_1t.yaml"), "--record", str(bag), "--max-catch-up-s", "10")
    try:
        with FoxgloveClient(live.port) as client:
            client.subscribe("/tf")
            _, frames = client.next_message("/tf")
            (tip,) = [t for t in frames.transforms if t.child_frame_id == "boom_tip"]
            assert tip.header.frame_id == "boom" and tip.transform.translation.x == pytest.approx(L)
            assert tip.transform.translation.z < -0.01  # the tonne bends it
            client.subscribe("/joint_states")
            _, joints = client.next_message("/joint_states")
            assert list(joints.name)[3] == "boom_tip_joint" and joints.position[3] < -0.01
            client.advertise(1, "/commands", "json", "std_msgs/msg/Float64MultiArray")
            client.publish(1, {"data": [0.8]})
            start = joints.position[3]
            client.until("/joint_states", lambda j: abs(j.position[3] - start) > 1e-3)  # it rings as it lifts
            client.publish(1, {"data": [0.0]})
    finally:
        live.interrupt()
        status, _, err = live.wait()
    assert status == 0, err
    check_resim_within_a_tick(bag, tmp_path / "again")


def test_a_sweep_takes_the_bending_stiffness_as_an_axis(tmp_path):
    """boom-sweep --vary boom_bending_stiffness_n_m2: the rigid and the elastic 1 t crane side by
    side, both run through (the batch kernel steps the mode), and they differ."""
    import csv

    from conftest import run_tool

    out = tmp_path / "sweep"
    args = ["--config", CONFIG / "loader_crane_1t.yaml", "--vary", f"boom_bending_stiffness_n_m2=0,{EI}"]
    result = run_tool("boom-sweep", *args, "--duration", "1.5", "--lift-angle-deg", "8", "--no-plots", "--out", out)
    assert result.returncode == 0, result.stderr
    with (out / "results.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [float(r["boom_bending_stiffness_n_m2"]) for r in rows] == [0.0, EI]
    assert {r["status"] for r in rows} == {"ok"}
    assert float(rows[0]["peak_pressure_pa"]) != float(rows[1]["peak_pressure_pa"])


def test_the_fmu_offers_the_elastic_boom_s_parameters():
    """The FMU's parameters are the solvers' plant parameters: the elastic boom's among them
    (set through FMI as any other; docs/fmu.md)."""
    from boom_hydraulics.fmu import interface

    names = {v.name: v for v in interface.PARAMETERS}
    assert names["boom_bending_stiffness_n_m2"].unit == "N m^2" and "boom_damping_ratio" in names


def test_the_payload_released_from_the_tip_lets_the_boom_spring_up_and_the_ledger_still_closes():
    """The loader cycle sets the tonne down at 9 s in one step: the tip, bent by it, springs
    up past the empty boom's static deflection and rings about it; the stepping's energy check
    holds (the payload takes its energy with it) and the ledger balances over the whole run."""
    params = with_updates(CRANE, **commands.scenario("loader", 0.0, CRANE))
    (release,) = params.command_payload_times_s
    sim = Simulator(params)
    out = sim.run(release + 1.0, commands.from_parameters(params), every=1)
    after = out["t"] > release
    empty = _static_deflection(with_updates(params, payload_mass_kg=0.0), out["q1"][after])
    assert np.min(out["boom_deflection"][~after]) < -0.01  # under the tonne
    overshoot = out["boom_deflection"][after] - empty
    top = int(np.argmax(overshoot))
    assert overshoot[top] > 0.005  # it springs up past its rest ...
    assert overshoot[top:].min() < -0.002  # ... and back below it: it rings
    integrals = physical.ledger_integrals(sim.y)
    assert ledger.energies_of(integrals)["imbalance_ratio"] < 0.005

"""Hoses as lines with waves (model/hoses.py; docs/model.md, "Hoses"): their modes against
c / (4 L) and c / (2 L), today's lumped volume as their low-frequency limit, the energy they
store and lose, a hose-length sweep, a node's run with hoses resimulated, and the study of the
paper's Figs. 8-10 in docs/hoses-study.md held to a fresh computation."""

from __future__ import annotations

import csv
import math
import re

import numpy as np
import pytest
from conftest import CONFIG, ROOT, run_tool, stop_process

from boom_hydraulics.analysis import hose_study
from boom_hydraulics.analysis import linear_model as lm
from boom_hydraulics.analysis.operating_point import operating_point
from boom_hydraulics.model import hoses, ledger, physical
from boom_hydraulics.model.config import load
from boom_hydraulics.model.parameters import ConfigError, Parameters, with_updates

#: The 1 m hose of the paper's boom (docs/hoses-study.md): DN10, the default wall.
HOSE = with_updates(Parameters(), hose_length_m=1.0)


def _line_matrix(c: hoses.HoseConstants, chamber: str) -> np.ndarray:
    """A of one line alone, by central differences of hoses.line (linear above the cavitation
    floor): its port blocked (no flow from the drive) and its chamber either at a fixed pressure
    (``fixed``) or a blocked end: the half segment the chamber keeps, nothing else (``blocked``)."""
    p0 = 10.0e6
    n = 2 * hoses.SEGMENTS + (chamber == "blocked")

    def rates(x: np.ndarray) -> np.ndarray:
        z, q = tuple(x[:4]), tuple(x[4:8])
        end = x[8] if chamber == "blocked" else p0
        line = hoses.line(z, q, 0.0, end, c, 5.0e3, 1.0e5)
        own = [line.dz0, line.dz1, line.dz2, line.dz3, line.dq1, line.dq2, line.dq3, line.dq4]
        if chamber == "blocked":  # the last half segment's oil, fed by the last flow
            own.append(c.hose_modulus / (0.5 * c.hose_node_volume) * line.end_flow)
        return np.array(own)

    x0 = np.array([p0] * 4 + [0.0] * 4 + [p0] * (n - 8))
    steps = np.array([1.0e3] * 4 + [1.0e-6] * 4 + [1.0e3] * (n - 8))
    a = np.empty((n, n))
    for j in range(n):
        dx = np.zeros(n)
        dx[j] = steps[j]
        a[:, j] = (rates(x0 + dx) - rates(x0 - dx)) / (2.0 * steps[j])
    return a


def _first_mode_hz(a: np.ndarray) -> float:
    values = np.linalg.eigvals(a)
    return float(np.min(np.abs(values[values.imag > 1e-6]))) / (2.0 * math.pi)


@pytest.mark.parametrize("length_m", [0.5, 1.0, 3.0])
def test_a_lines_first_modes_are_the_quarter_and_half_wave_of_its_wave_speed(length_m):
    """One end at a fixed pressure and the other blocked: c / (4 L); both ends blocked:
    c / (2 L), c = sqrt(K_eff / rho). Four segments give exactly the staggered grid's
    dispersion (2 c / l) sin(kappa l / 2) (eq. H8), which lies below the line's by
    1 - (4N / pi) sin(pi / 4N) = 0.64 % and 1 - (2N / pi) sin(pi / 2N) = 2.6 %: the tolerance."""
    p = with_updates(HOSE, hose_length_m=length_m, piston_dead_volume_m3=1e-3, rod_dead_volume_m3=1e-3)
    modulus = hoses.effective_modulus_pa(p.bulk_modulus_pa, p.hose_wall_modulus_pa)
    frictionless = hoses.hose_constants(length_m, p.hose_inner_diameter_m, p.hose_wall_modulus_pa, 0.0, 1e9, 860.0)
    quarter, half = (
        _first_mode_hz(_line_matrix(frictionless, "fixed")),
        _first_mode_hz(_line_matrix(frictionless, "blocked")),
    )
    discrete = hoses.discrete_frequencies_hz(length_m, modulus, p.density_kg_m3)
    assert quarter == pytest.approx(discrete[0], rel=1e-6) and half == pytest.approx(discrete[1], rel=1e-6)
    exact = hoses.line_frequencies_hz(length_m, modulus, p.density_kg_m3)
    n = hoses.SEGMENTS
    bound_quarter = 1.0 - 4 * n / math.pi * math.sin(math.pi / (4 * n))
    bound_half = 1.0 - 2 * n / math.pi * math.sin(math.pi / (2 * n))
    assert 0.0 < 1.0 - quarter / exact[0] <= bound_quarter + 1e-9 and bound_quarter < 0.007
    assert 0.0 < 1.0 - half / exact[1] <= bound_half + 1e-9 and bound_half < 0.027
    # the oil's laminar friction (the parameters' 32 cSt) moves these modes by less than 0.1 %
    rough = physical.constants(p)
    assert _first_mode_hz(_line_matrix(rough, "fixed")) == pytest.approx(quarter, rel=1e-3)


def test_linearize_has_the_line_modes_between_the_quarter_and_the_half_wave():
    """In the whole model a hose ends in a chamber of finite volume, neither a fixed pressure nor
    a blocked end: the lines' first modes lie between the two (the valve closed blocks the port),
    far above the boom's hydraulic mode, which the hose's wall compliance lowers a little."""
    model = lm.linearize(operating_point(HOSE, 1.4))
    assert model.state_names[-len(hoses.STATE_NAMES) :] == hoses.STATE_NAMES
    modulus = hoses.effective_modulus_pa(HOSE.bulk_modulus_pa, HOSE.hose_wall_modulus_pa)
    quarter, half = hoses.discrete_frequencies_hz(1.0, modulus, HOSE.density_kg_m3)
    fast = sorted(m.natural_frequency_hz for m in model.modes() if m.oscillatory and m.natural_frequency_hz > 100.0)
    assert quarter < fast[0] <= fast[1] < half  # one per line
    lumped = lm.linearize(operating_point(Parameters(), 1.4)).hydraulic_mode().natural_frequency_hz
    assert 0.95 * lumped < model.hydraulic_mode().natural_frequency_hz < 0.995 * lumped


@pytest.mark.parametrize(("length_m", "tolerance"), [(0.05, 1e-5), (1.0, 1e-3)])
def test_a_stiff_hose_is_todays_lumped_volume_at_low_frequency(length_m, tolerance):
    """With a wall that does not give (K_eff = E), the hoses hold the oil the dead volumes gave up:
    the boom's hydraulic mode is today's, to the line's inertia (the lines' modes are 40 times
    faster and more for 1 m, 800 times for 5 cm)."""
    stiff = with_updates(Parameters(), hose_length_m=length_m, hose_wall_modulus_pa=1e12)
    for q1_m in (1.15, 1.4, 1.65):
        today = lm.linearize(operating_point(Parameters(), q1_m)).hydraulic_mode()
        hosed = lm.linearize(operating_point(stiff, q1_m)).hydraulic_mode()
        assert hosed.natural_frequency_hz == pytest.approx(today.natural_frequency_hz, rel=tolerance)
        assert hosed.damping_ratio == pytest.approx(today.damping_ratio, rel=10 * tolerance)


@pytest.mark.parametrize("q1_m", [1.15, 1.4, 1.65])
def test_a_compliant_hose_is_its_oil_lumped_at_k_eff_beside_the_chamber(q1_m):
    """With the hose's own wall (K_eff < E), the low-frequency limit is each chamber with its
    hose's oil beside it as a volume at K_eff: the oil-spring formula of that (linear_model,
    eq. H1) is the hydraulic mode, to the lines' inertia, and 2-3 % below today's."""
    frictionless = {"static_friction_n": 0.0, "coulomb_friction_n": 0.0}
    p = with_updates(HOSE, **frictionless)
    mode = lm.linearize(operating_point(p, q1_m)).hydraulic_mode().natural_frequency_hz
    assert mode == pytest.approx(lm.oil_spring_frequency_rad_s(p, q1_m) / (2 * math.pi), rel=1e-3)
    today = lm.oil_spring_frequency_rad_s(with_updates(Parameters(), **frictionless), q1_m) / (2 * math.pi)
    assert 0.95 * today < mode < 0.99 * today


def test_without_hoses_nothing_moves_and_the_dead_volumes_stay():
    p = Parameters()
    c = physical.constants(p)
    assert c.hose_on == 0.0 and c.v1_dead == p.piston_dead_volume_m3 and c.v2_dead == p.rod_dead_volume_m3
    y = physical.initial_state(p)
    y[1] = 0.1
    rates = physical.derivative(0.0, y, c, 0.7)
    assert all(rates[i] == 0.0 for i in physical.HOSE_STATES)
    assert physical.ledger(0.0, y, c, 0.7).line_loss == 0.0
    assert lm.states_of(p) == lm.STATES  # no hose states in the linear model
    hosed = physical.constants(HOSE)
    share = hoses.NODE_SEGMENTS * 0.25 * math.pi * HOSE.hose_inner_diameter_m**2 * 1.0 / hoses.SEGMENTS
    assert hosed.v1_dead == pytest.approx(p.piston_dead_volume_m3 - share, rel=1e-12)


def test_a_hose_that_holds_more_oil_than_the_dead_volume_or_in_paper_mode_is_refused():
    with pytest.raises(ConfigError, match="hoses' oil"):
        with_updates(Parameters(), hose_length_m=2.0)
    with pytest.raises(ConfigError, match="needs physical mode"):
        with_updates(Parameters(), mode="paper", hose_length_m=0.5)


def test_the_ledger_closes_at_every_instant_and_the_energy_rate_is_the_energys_derivative():
    """At a state away from rest (every line pressure and flow disturbed), the ledger's terms sum
    to the battery's power (residual ~ 0) and W is d/dt of physical.energy (central difference)."""
    c = physical.constants(HOSE)
    y = physical.initial_state(HOSE)
    rng = np.random.default_rng(5)
    for i in physical.HOSE_STATES:
        y[i] += rng.normal() * (1.0e6 if physical.STATE_SCALES[i] == "pressure" else 1.0e-4)
    y[1] = 0.05
    rates = physical.derivative(0.0, y, c, 0.6)
    terms = physical.ledger(0.0, y, c, 0.6)
    assert abs(ledger.residual_w(terms)) < 1e-9 * terms.battery_power and terms.line_loss > 0.0
    h = 1e-7
    ahead = physical.energy([a + h * b for a, b in zip(y, rates)], c)
    behind = physical.energy([a - h * b for a, b in zip(y, rates)], c)
    assert rates[physical.ENERGY_STATES[0]] == pytest.approx((ahead - behind) / (2 * h), rel=1e-5)


def test_the_lines_states_are_named_port_first_and_their_constants_are_their_definitions():
    """Each line's node pressures p0 (the port) .. p3 and flows q1 .. q4 (q4 into the chamber),
    as the CSV, the FMU and linearize name them; c = sqrt(K_eff / rho) (eq. H2), 1 / K_eff =
    1 / E + 1 / K_wall (eq. H1), and per segment l = L / 4 the oil A l, I = rho l / A and
    R = 128 rho nu l / (pi d^4) (eq. H3), each in round numbers."""
    line = ["p0", "p1", "p2", "p3", "q1", "q2", "q3", "q4"]
    assert hoses.STATE_NAMES == tuple(f"hose_{end}_{name}" for end in "ab" for name in line)
    assert hoses.STATE_UNITS == ("Pa",) * 4 + ("m^3/s",) * 4 + ("Pa",) * 4 + ("m^3/s",) * 4
    assert hoses.wave_speed_m_s(1.0e9, 1000.0) == pytest.approx(1000.0, rel=1e-15)
    assert hoses.wave_speed_m_s(4.0e9, 1000.0) == pytest.approx(2000.0, rel=1e-15)
    assert hoses.wave_speed_m_s(1.1e9, 870.0) == pytest.approx(math.sqrt(1.1e9 / 870.0), rel=1e-15)
    assert hoses.effective_modulus_pa(1.0e9, 1.0e9) == pytest.approx(0.5e9, rel=1e-15)
    assert hoses.effective_modulus_pa(1.0e9, 3.0e9) == pytest.approx(0.75e9, rel=1e-15)
    length, diameter, nu, rho = 2.0, 0.02, 4.0e-5, 900.0
    c = hoses.hose_constants(length, diameter, 3.0e9, nu, 1.0e9, rho)
    area, segment = math.pi * 0.01**2, 0.5
    assert c.hose_on == 1.0 and c.hose_modulus == pytest.approx(0.75e9, rel=1e-15)
    assert c.hose_node_volume == pytest.approx(area * segment, rel=1e-15, abs=0.0)
    assert c.hose_inertance == pytest.approx(rho * segment / area, rel=1e-15)
    assert c.hose_resistance == pytest.approx(128.0 * rho * nu * segment / (math.pi * diameter**4), rel=1e-15)
    assert c.hose_chamber_share == pytest.approx(3.5 * area * segment, rel=1e-15, abs=0.0)
    none = hoses.hose_constants(0.0, diameter, 3.0e9, nu, 1.0e9, rho)  # no hose: a 1 m one's finite constants
    assert none.hose_on == 0.0 and none.hose_chamber_share == 0.0
    assert none.hose_inertance == pytest.approx(rho * 0.25 / area, rel=1e-15)
    # eq. H7 and H8 at a K / rho that is no whole number (c = 1124.4 m/s)
    c_oil = math.sqrt(1.1e9 / 870.0)
    assert hoses.line_frequencies_hz(2.0, 1.1e9, 870.0) == pytest.approx((c_oil / 8.0, c_oil / 4.0), rel=1e-14)
    quarter = 2.0 * c_oil / 0.5 * math.sin(math.pi / 8.0 * 0.5) / (2.0 * math.pi)
    half = 2.0 * c_oil / 0.5 * math.sin(math.pi / 4.0 * 0.5) / (2.0 * math.pi)
    assert hoses.discrete_frequencies_hz(2.0, 1.1e9, 870.0) == pytest.approx((quarter, half), rel=1e-14)
    short = hoses.hose_constants(0.4, diameter, 3.0e9, nu, 1.0e9, rho)  # under a metre, its own
    assert short.hose_on == 1.0 and short.hose_node_volume == pytest.approx(area * 0.1, rel=1e-15, abs=0.0)


def test_a_steady_flow_drops_the_hagen_poiseuille_pressure_along_the_line():
    """A steady laminar flow Q through the whole line, port to chamber, loses
    128 mu L Q / (pi d^4) (mu = rho nu) in equal steps, and every rate is then 0; the line keeps
    no energy more or less (its energy rate is 0) and its friction R sum q^2 is Q times the drop."""
    length, diameter, nu, rho = 3.0, 0.0127, 3.2e-5, 870.0
    c = hoses.hose_constants(length, diameter, 3.2e9, nu, 1.4e9, rho)
    flow, chamber = 4.0e-4, 8.0e6
    drop = 128.0 * rho * nu * length * flow / (math.pi * diameter**4)  # the whole line's
    z = tuple(chamber + drop * (4 - k) / 4 for k in range(4))
    line = hoses.line(z, (flow,) * 4, flow, chamber, c, 5.0e3, 1.0e5)
    assert line.port_pressure == z[0] and line.end_flow == flow
    scale = drop / c.hose_inertance  # what one segment's drop would accelerate its flow by
    for rate in (line.dq1, line.dq2, line.dq3, line.dq4):
        assert abs(rate) < 1e-9 * scale
    for rate in (line.dz0, line.dz1, line.dz2, line.dz3):
        assert rate == 0.0
    assert line.loss == pytest.approx(flow * drop, rel=1e-12)
    assert abs(line.energy_rate) < 1e-9 * line.loss


def _along(z: tuple, q: tuple, line: hoses.Line, h: float) -> tuple[tuple, tuple]:
    """The line's states ``h`` seconds along its rates."""
    rates_z = (line.dz0, line.dz1, line.dz2, line.dz3)
    rates_q = (line.dq1, line.dq2, line.dq3, line.dq4)
    return tuple(a + h * b for a, b in zip(z, rates_z)), tuple(a + h * b for a, b in zip(q, rates_q))


def test_a_line_whose_nodes_cavitate_stores_what_its_energy_rate_says():
    """Nodes held at the cavitation floor keep their (floor) pressure while their voids fill or
    grow, so their oil stores nothing more: the line's energy rate is d/dt of line_energy along
    its rates (central differences), with nodes below, at and above the floor."""
    c = hoses.hose_constants(2.0, 0.0127, 3.2e9, 3.2e-5, 1.4e9, 870.0)
    p_cav, p_tank = 5.0e3, 1.0e5
    cases = [
        ((-2.0e5, 3.0e6, -1.0e5, 4.0e6), (1.0e-4, -2.0e-4, 3.0e-4, 1.0e-4)),
        ((2.0e6, -3.0e5, 1.0e6, -4.0e5), (-1.0e-4, 2.0e-4, -3.0e-4, 2.0e-4)),
        ((-1.0e6, -2.0e6, -3.0e6, -4.0e6), (3.0e-4, 1.0e-4, 2.0e-4, 1.0e-4)),  # all void
    ]
    for z, q in cases:
        line = hoses.line(z, q, 5.0e-4, 2.0e6, c, p_cav, p_tank)
        h = 1e-9
        ahead = hoses.line_energy(*_along(z, q, line, h), c, p_cav, p_tank)
        behind = hoses.line_energy(*_along(z, q, line, -h), c, p_cav, p_tank)
        assert line.energy_rate == pytest.approx((ahead - behind) / (2.0 * h), rel=1e-6, abs=1e-6), z


def test_a_batch_that_mixes_a_hose_and_none_gives_each_set_its_own_rates():
    """In a batch (the constants and the state an array per set, as boom-sweep's lock-step runs
    take them) the hoses' equations run for every set once any set has a hose: a set without
    one gets its own rates, finite, its hose states still, as when it runs alone."""
    from boom_hydraulics.solve.closed_loop import stacked_constants

    sets = [HOSE, Parameters(), with_updates(Parameters(), hose_length_m=0.4)]
    c = stacked_constants(sets)
    alone = []
    states = []
    for p in sets:
        y = physical.initial_state(p)
        y[1] = 0.05
        states.append(y)
        alone.append(physical.derivative(0.0, y, physical.constants(p), 0.6))
    y = [np.array(column) for column in zip(*states)]
    together = physical.derivative(0.0, y, c, 0.6, np)
    for k, own in enumerate(alone):
        got = [float(np.asarray(rate)[k]) if np.ndim(rate) else float(rate) for rate in together]
        assert np.all(np.isfinite(got)), k
        assert got == pytest.approx(list(own), rel=1e-12, abs=1e-12), k


def test_a_cycle_with_hoses_keeps_its_energy_balance_and_loses_energy_in_them(tmp_path):
    """boom-sim over a lift and lower with hoses: the energy check passes every step, the
    ledger's integrals balance, the hoses' friction is a loss > 0, and the stability bound takes
    substeps for the line's fastest mode (which rk4 at 1 ms would not survive)."""
    out = tmp_path / "hoses.csv"
    result = run_tool(
        "boom-sim", "run", "--config", CONFIG / "default.yaml", "--set", "hose_length_m=1.0",
        "--profile", "steps:0=1,1.5=0,2=-1,3=0", "--duration", "3.5", "--every", "50", "--out", out,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "substeps per step (stability bound)" in result.stdout
    with out.open() as handle:
        rows = list(csv.reader(handle))
    header = [name.split(" [")[0] for name in rows[0]]
    last = dict(zip(header, map(float, rows[-1])))
    integrals = {"battery_drawn": last["battery_drawn"], "battery_returned": last["battery_returned"]}
    integrals.update({name: last[f"{name}_j"] for name in ledger.TERM_NAMES[1:]})
    energies = ledger.energies_of(integrals)
    assert energies["imbalance_ratio"] < 1e-6, energies
    assert 0.0 < last["line_loss_j"] < 0.01 * last["battery_drawn"]


def test_boom_sweep_varies_the_hose_length(tmp_path):
    """hose_length is a --vary axis: no hose, and 1 m, each with its own hydraulic mode and loss."""
    out = tmp_path / "sweep"
    result = run_tool(
        "boom-sweep", "--config", CONFIG / "default.yaml", "--vary", "hose_length=0,1.0", "--duration", "1.5",
        "--lift-angle-deg", "8", "--no-plots", "--out", out,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    with (out / "results.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [float(r["hose_length_m"]) for r in rows] == [0.0, 1.0]
    assert {r["status"] for r in rows} == {"ok"}
    none, hose = (float(r["natural_frequency_hz"]) for r in rows)
    today = lm.mid_stroke_modes([Parameters()])[0][0]
    assert none == pytest.approx(today, rel=1e-9) and 0.95 * none < hose < 0.995 * none
    assert float(rows[0]["line_loss_j"]) == 0.0 < float(rows[1]["line_loss_j"])


def test_the_1t_crane_has_its_hoses_and_their_oil_fits_its_dead_volumes():
    crane = load(CONFIG / "loader_crane_1t.yaml")
    assert crane.hose_length_m > 0.0
    c = physical.constants(crane)
    assert c.hose_on == 1.0 and c.v1_dead > 0.1 * crane.piston_dead_volume_m3


def test_the_studys_numbers_are_a_fresh_computation():
    """docs/hoses-study.md's table is what `tools/hoses-study` computes now."""
    text = (ROOT / "docs" / "hoses-study.md").read_text()
    table = hose_study.markdown(hose_study.study())
    assert table in text, "docs/hoses-study.md is out of date: run tools/hoses-study and paste its table"
    assert re.search(r"tools/hoses-study", text)


def test_a_node_run_with_hoses_is_resimulated_as_it_ran(nodes, client, tmp_path):
    """boom_sim with hoses records a lift and a lowering; boom-resim writes the same run again."""
    rclpy = pytest.importorskip("rclpy")
    assert rclpy is not None
    from boom_hydraulics.bags.reading import read_drive_states
    from boom_hydraulics.resim.resimulation import resimulate

    proc = nodes.start("hose_length_m:=1.0", "command_timeout_s:=0.0", f"record_folder:={tmp_path}", record=True)
    try:
        client.handshake()
        start = client.last().rod_position_m
        assert client.spin_until(lambda: client.last().rod_position_m > start + 0.05, opening=0.8)
        assert client.spin_until(lambda: client.last().rod_position_m < start + 0.02, opening=-0.8)
        client.command(0.0)
    finally:
        stop_process(proc)
    (bag,) = tmp_path.glob("*_boom_sim")
    again, _ = resimulate(bag, tmp_path / "again")
    original, rerun = read_drive_states(bag), read_drive_states(again)
    n = min(len(original["q1"]), len(rerun["q1"]))
    assert n > 30
    assert np.max(np.abs(original["q1"][:n] - rerun["q1"][:n])) < 1e-12
    assert np.max(np.abs(original["p1"][:n] - rerun["p1"][:n])) < 1e-6
    without, _ = resimulate(bag, tmp_path / "without", overrides={"hose_length_m": 0.0})
    other = read_drive_states(without)
    assert np.max(np.abs(original["p1"][:n] - other["p1"][:n])) > 1e3  # the hoses changed the run

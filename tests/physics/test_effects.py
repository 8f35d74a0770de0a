"""Issue 4: the rigid contact model, Coulomb friction and the effects library."""

import math

import numpy as np
import pytest

from dice_sweep.physics.kernel import (
    REC_ENERGY,
    REC_KIND,
    REC_STATE,
    REC_T,
    SEG_PIVOT,
    SEG_PIVOT_ODE,
    STATUS_DECIDED,
    decided_side,
    shift_reference,
)
from dice_sweep.measured.fit import FIT_DRAG_MAX_STEP, FIT_DRAG_TOL
from dice_sweep.physics.flight import advance_flight
from dice_sweep.physics.params import FP_DRAG_MAX_STEP, FP_DRAG_TOL, FP_INERTIA
from dice_sweep.roll import roll_config, sample_path
from tests.physics.conftest import TABLE1_RADIUS, corner_impacts, make_config, make_params, random_states, run_batch, run_one

G = 9.81
R = TABLE1_RADIUS


def test_quadratic_drag_fall_matches_the_closed_form():
    """Straight down with a = -g - c |v| v: y(t) = y0 - (v_t^2/g) ln cosh(g t / v_t), v_t =
    sqrt(g/c); the corner pointing down touches when y = R."""
    c, y0 = 0.8, 0.5
    params = make_params(air_drag=c)
    _, _, _, _, rec, _ = run_one(params, [0.0, y0, -math.pi / 2, 0.0, 0.0, 0.0])
    v_t = math.sqrt(G / c)
    expected = v_t / G * math.acosh(math.exp((y0 - R) * G / v_t**2))
    assert math.isclose(rec[1, REC_T], expected, rel_tol=1e-10)
    assert rec[1, REC_T] > math.sqrt(2 * (y0 - R) / G)  # slower than free fall


def test_tiny_drag_delays_a_drop_by_its_first_order_amount_and_changes_no_outcome(rng):
    """A drag c small enough to change no outcome still acts: a straight drop from y0 reaches the
    table later by c g t0^3 / 12 (first order in c of y = y0 - g t^2/2 + c g^2 t^4/12), which a
    kernel ignoring the drag slot fails; and 200 random rolls keep their outcomes."""
    c, y0 = 1e-6, 0.3
    start = [0.0, y0, -math.pi / 2, 0.0, 0.0, 0.0]
    plain_time = run_one(make_params(), start)[4][1, REC_T]
    drag_time = run_one(make_params(air_drag=c), start)[4][1, REC_T]
    t0 = math.sqrt(2 * (y0 - R) / G)
    assert drag_time - plain_time == pytest.approx(c * G * t0**3 / 12, rel=1e-3)
    states = random_states(rng, 200, y_range=(0.03, 0.1), omega_max=20.0)
    plain, _, _, _ = run_batch(make_params(), states)
    tiny, _, _, _ = run_batch(make_params(air_drag=1e-12), states)
    assert np.mean(plain == tiny) > 0.99


@pytest.mark.parametrize("k", [0.0, 0.3, 2.0])
def test_speed_restitution_on_a_flat_landing(k):
    y0, beta_n = 0.15, 0.5
    _, _, _, _, rec, _ = run_one(make_params(beta_n=beta_n, speed_restitution=k), [0.0, y0, math.pi / 4, 0, 0, 0])
    vy = -math.sqrt(2 * G * (y0 - R * math.cos(math.pi / 4)))
    assert math.isclose(rec[1, REC_STATE + 4], -beta_n / (1 + k * abs(vy)) * vy, rel_tol=1e-9)


def test_world_g_is_the_kernels_g():
    params = make_params(g=9.44)
    _, _, _, _, rec, _ = run_one(params, [0.0, 0.2, -math.pi / 2, 0, 0, 0])
    assert math.isclose(rec[1, REC_T], math.sqrt(2 * (0.2 - R) / 9.44), rel_tol=1e-12)


def test_frictionless_table_keeps_horizontal_momentum(rng):
    """With mu = 0 every contact force is vertical: vx of the centre of mass never changes,
    through impacts and sliding pivots alike."""
    cfg = make_config(model="rigid", beta_t=0.0, friction=0.0)
    for state in random_states(rng, 20, y_range=(0.03, 0.1)):
        report = roll_config(cfg, state=state)
        vx = report.records[:, REC_STATE + 3]
        assert np.allclose(vx, vx[0], atol=1e-9), vx


@pytest.mark.parametrize("model", ["paper", "rigid"])
@pytest.mark.parametrize("friction, drag", [(0.3, 0.0), (math.inf, 0.5), (0.6, 0.3)])
def test_energy_never_increases_with_friction_and_drag(model, friction, drag, rng):
    """The recorded energy is that of the recorded motion (so the check below is on the die's
    energy, not on a number kept apart from it); it never rises from one segment to the next,
    and over the roll some is lost."""
    params = make_params(model=model, friction=friction, air_drag=drag, beta_t=0.0 if model == "rigid" else -0.35,
                         separation=0.06)
    inertia = params[0][FP_INERTIA]
    for state in random_states(rng, 25, y_range=(0.03, 0.12)):
        _, _, _, _, rec, _ = run_one(params, state)
        energy = rec[:, REC_ENERGY]
        _, y, _, vx, vy, omega = rec[:, REC_STATE : REC_STATE + 6].T
        assert np.allclose(energy, 0.5 * (vx * vx + vy * vy + inertia * omega * omega) + G * y, rtol=1e-12, atol=0)
        assert np.all(np.diff(energy) <= 1e-12 * np.abs(energy[:-1]) + 1e-15)
        assert energy.size >= 2 and energy[-1] < 0.99 * energy[0]


def test_sticking_pivot_ode_matches_the_closed_form():
    """A huge but finite friction sends pivots through the ODE path; they must reproduce the
    closed-form (elliptic) pivot: same transfers, same omega after each, to 1e-7."""
    sides = 6
    chi0 = math.pi / 2 + math.pi / sides - 1e-6
    omega0 = -math.sqrt(0.5 * G / R)
    state = [R * math.cos(chi0), R * math.sin(chi0), chi0 + math.pi,
             omega0 * -R * math.sin(chi0), omega0 * R * math.cos(chi0), omega0]
    exact = run_one(make_params(sides=sides, beta_n=0.0, beta_t=0.0), state)
    ode = run_one(make_params(sides=sides, beta_n=0.0, beta_t=0.0, friction=1e6), state)
    assert exact[0] == ode[0]
    assert math.isclose(exact[2], ode[2], rel_tol=1e-7)  # time of decision
    w_exact = exact[4][exact[4][:, REC_KIND] == SEG_PIVOT, REC_STATE + 5]
    w_ode = ode[4][ode[4][:, REC_KIND] == SEG_PIVOT_ODE, REC_STATE + 5]
    assert len(w_ode) == len(w_exact) >= 2  # the transfers happen at the same corners
    assert np.allclose(w_ode, w_exact, rtol=1e-7)  # with omega after each transfer


def test_low_friction_lets_a_pivoting_corner_slide():
    """A square rolling over a corner: with unlimited friction the corner stays put while the
    die turns about it; with mu = 0.05 it slides."""
    chi0 = math.pi / 2 + math.pi / 4 - 1e-6
    omega0 = -math.sqrt(0.7 * G / R)  # over the top, no lift-off (as in the rolling test)
    state = [R * math.cos(chi0), R * math.sin(chi0), chi0 + math.pi,
             omega0 * -R * math.sin(chi0), omega0 * R * math.cos(chi0), omega0]
    drift = {}
    for friction in (math.inf, 0.05):
        cfg = make_config(model="rigid", beta_t=0.0, friction=friction)
        report = roll_config(cfg, state=state)
        path = sample_path(cfg, report, np.linspace(0.0, 0.01, 11))
        corner_x = path[:, 0] + R * np.cos(path[:, 2])  # corner 0, the pivot
        drift[friction] = np.ptp(corner_x)
    assert drift[math.inf] < 1e-9
    assert drift[0.05] > 1e-5


def test_loaded_die_centre_wobbles_about_the_com_parabola():
    """Positions reported are the geometric centre's: in flight the centre of mass follows a
    parabola exactly, the centre does not (it turns around the centre of mass)."""
    offset = (0.004, 0.0)
    cfg = make_config(com_offset=offset)
    report = roll_config(cfg, state=[0.0, 0.3, 0.0, 0.0, 0.0, 30.0])
    t = np.linspace(0.0, 0.12, 50)
    centre = sample_path(cfg, report, t)
    phi = centre[:, 2]
    com_x = centre[:, 0] + offset[0] * np.cos(phi) - offset[1] * np.sin(phi)
    com_y = centre[:, 1] + offset[0] * np.sin(phi) + offset[1] * np.cos(phi)
    assert np.allclose(com_y, com_y[0] + (centre[0, 4] + 30.0 * offset[0]) * t - 0.5 * G * t * t, atol=1e-12)
    assert np.allclose(com_x, com_x[0], atol=1e-12)
    assert np.ptp(centre[:, 0]) > 0.007  # the centre circles the centre of mass


def test_loaded_die_prefers_the_heavy_side(rng):
    """A centre of mass moved towards side 2 of a square makes side 2 the most likely outcome
    and barrier heights follow the centre-of-mass distances."""
    states = random_states(rng, 800, y_range=(0.05, 0.2), omega_max=40.0)
    fair, _, _, _ = run_batch(make_params(), states)
    # side 2 of the square lies towards the body angle 5 pi/4 (between corners 2 and 3)
    offset = 0.005 * np.array([math.cos(5 * math.pi / 4), math.sin(5 * math.pi / 4)])
    loaded, status, _, _ = run_batch(make_params(com_offset=tuple(offset)), states)
    assert np.all(status == STATUS_DECIDED)
    share = np.bincount(loaded, minlength=4) / loaded.size
    assert share[2] == share.max() and share[2] > np.mean(fair == 2) + 0.05


def test_loaded_die_resting_flat_is_decided_on_its_side():
    fpar, _ = make_params(com_offset=(0.002, -0.003))
    centre = np.array([0.0, R * math.cos(math.pi / 4), math.pi / 4, 0.0, 0.0, 0.0])  # side 2 flat
    com = np.empty(6)
    shift_reference(centre, fpar, 1.0, com)
    assert decided_side(com, fpar, 4) == 2
    assert fpar[FP_INERTIA] == pytest.approx(R * R / 3 - (0.002**2 + 0.003**2), rel=1e-12)


def test_capped_impulse_sits_on_the_cone_edge_on_the_targets_side():
    """When the target impulse leaves the friction cone, friction takes the cone's edge on
    the target's side (as Chipmunk does), even when the normal impulse throws the corner
    back against its incoming slip (the case docs/dev/validation_history.md traced)."""
    from dice_sweep.physics.impact import corner_impulse

    inertia = R * R / 3
    seen_against_slip = 0
    for s, rx, ry in corner_impacts(np.random.default_rng(11), 3000, R):
        target = s.copy()
        corner_impulse(target, inertia, 0.2, 0.0, math.inf, rx, ry, 0.0, 1.0)
        capped = s.copy()
        corner_impulse(capped, inertia, 0.2, 0.0, 0.3, rx, ry, 0.0, 1.0)
        p_target = target[3] - s[3]
        p_t, p_n = capped[3] - s[3], capped[4] - s[4]
        if abs(p_target) > 0.3 * (target[4] - s[4]) * 1.01 and p_n > 0:
            assert math.copysign(1, p_t) == math.copysign(1, p_target)
            u_t = s[3] - s[5] * ry
            seen_against_slip += math.copysign(1, p_target) == math.copysign(1, u_t)
    assert seen_against_slip > 0  # the case the textbook branch gets wrong did occur


def test_flat_landing_while_sliding_slides_to_rest():
    """A square landing flat while moving sideways slides on its side under friction and is
    decided there (it once traded pivots between its two bottom corners until the event
    budget ran out); followed to rest, it slides v^2 / (2 mu g)."""
    from dice_sweep.physics.kernel import sample_batch
    from dice_sweep.physics.params import IP_CONTINUE

    mu, vx = 0.5, 0.4
    # side 2 down, 1e-10 m above the table: the landing itself (one corner, a short sliding
    # pivot, the other corner) then takes about 1e-4 of vx (one run: 6e-5)
    y0 = R * math.cos(math.pi / 4) + 1e-10
    state = np.array([[0.0, y0, math.pi / 4, vx, 0.0, 0.0]])
    fpar, ipar = make_params(model="rigid", beta_n=0.0, beta_t=0.0, friction=mu, t_max=1.0)
    outcome, status, _, _ = run_batch((fpar, ipar), state)
    assert outcome[0] == 2 and status[0] == STATUS_DECIDED
    ipar = ipar.copy()
    ipar[IP_CONTINUE] = 1
    out = np.zeros((1, 6))
    sample_batch(fpar, ipar, state, np.array([0.9]), np.array([0, 1]), out, np.zeros(1, np.int8))
    fall = math.sqrt(2 * 1e-10 / G)
    assert out[0, 0] == pytest.approx(vx * fall + vx**2 / (2 * mu * G), rel=1e-3)
    assert out[0, 3] == 0.0


def _drag_flight_reference(state, c, tau):
    """Flight with a = -g - c |v| v by SciPy's DOP853 at rtol 1e-13: an integrator that is not
    the kernel's."""
    from scipy.integrate import solve_ivp

    def rates(_, u):
        speed = math.hypot(u[2], u[3])
        return [u[2], u[3], -c * speed * u[2], -G - c * speed * u[3]]

    sol = solve_ivp(rates, (0.0, tau), [state[0], state[1], state[3], state[4]], method="DOP853", rtol=1e-13, atol=1e-15)
    return sol.y[:2, -1]


@pytest.mark.parametrize("c", [0.05, 0.5, 2.0])
def test_drag_flight_at_the_fits_tolerance_stays_within_a_nanometre(c):
    """The fit runs flights with drag at coarser Runge-Kutta steps than a sweep (FIT_DRAG_TOL,
    FIT_DRAG_MAX_STEP in fpar): the centre after 0.3 s stays within 1e-9 m of an independent
    integrator at both settings, and a far coarser setting is visibly worse (fpar is read)."""
    state = np.array([0.0, 0.6, 0.3, 1.5, 2.0, 12.0])
    tau = 0.3
    expected = _drag_flight_reference(state, c, tau)
    out = np.empty(6)
    for tol, max_step in [(None, None), (FIT_DRAG_TOL, FIT_DRAG_MAX_STEP)]:
        fpar, _ = make_params(air_drag=c)
        if tol is not None:
            fpar[FP_DRAG_TOL], fpar[FP_DRAG_MAX_STEP] = tol, max_step
        advance_flight(state, tau, fpar, out)
        assert np.abs(out[:2] - expected).max() < 1e-9, (tol, out[:2] - expected)
        assert math.isclose(out[2], state[2] + state[5] * tau, rel_tol=1e-12)  # rotation: omega constant
    fpar, _ = make_params(air_drag=c)
    fpar[FP_DRAG_TOL], fpar[FP_DRAG_MAX_STEP] = 1e-2, tau  # one step
    advance_flight(state, tau, fpar, out)
    assert np.abs(out[:2] - expected).max() > 1e-9

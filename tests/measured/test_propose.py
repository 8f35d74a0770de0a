"""Proposals (dice_sweep/measured/propose.py) on drops from the independent generator
(tests/measured/independent.py) with physics outside the library, each on two independent
draws: the declared model is fitted to the drops (multiple shooting), and the sparse formula
for what it leaves must name the missing physics by its terms, with the true coefficient in its
interval; on control drops (the library's own physics) nothing is proposed.

scripts/propose_null.py is the null calibration on many control sets (docs/measured_method.md).
``pytest -s tests/measured/test_propose.py`` prints each case's fitted model and proposals.
"""

import json
import math

import numpy as np
import pytest

from dice_sweep import effects as registry
from dice_sweep.config import parse_config
from dice_sweep.measured import fit as shooting
from dice_sweep.measured import propose
from dice_sweep.measured.diagnose import fit_from_starts
from dice_sweep.measured.tracks import load_tracks
from tests.measured.cases import DECLARED_RIGID, NOISE, TRUTH
from tests.measured.independent import Truth, simulate_drops, write_csv

TRACKS = 40
SEEDS = (31, 32)
G = 9.81


def proposals_for(tmp_path, seed, **physics):
    """propose_report on TRACKS drops of the generator with ``physics`` added to the control
    truth, the declared rigid model fitted to them first."""
    path = tmp_path / f"drops{seed}.csv"
    write_csv(path, simulate_drops(Truth(**{**TRUTH, **physics}), TRACKS, seed, rate=500.0, noise=NOISE, drop_prob=0.01,
                                   glitch_prob=0.002))
    cfg = parse_config(DECLARED_RIGID)
    trackset = load_tracks(path, sides=4, circumradius=cfg.die.circumradius)
    sigma = np.array([NOISE[0], NOISE[0], NOISE[1]])
    prepared = shooting.prepare_tracks(trackset, cfg, noise=sigma, table=0.0)
    # the loop's baseline fit: from the config's values and from calibrate's, the lower cost kept
    fit, _ = fit_from_starts(cfg, shooting.ModelSpec.of(cfg), shooting.Segments(prepared, cfg.world.g), trackset)
    report = propose.propose_report(trackset, cfg, fit, sigma=sigma, table=0.0, prepared=prepared, seed=seed)
    check_contract(report["proposals"], cfg.die.sides)
    found = {p["target"]: p for p in report["proposals"]}
    print(f"\n{physics or 'control'}, seed {seed}: fitted " + ", ".join(f"{k} {v:.4f}" for k, v in fit.params.items())
          + f"; proposals {describe(found) or 'none'}")  # pytest -s shows what each case proposes
    return found, report


def check_contract(proposals, sides):
    """Each proposal: a target of the six, terms of the libraries with coefficients inside their
    intervals, which exclude 0, a held-out gain; never an effect's name anywhere."""
    libraries = {"flight": set(propose.FLIGHT_TERMS), "impact": set(propose.impact_terms(sides))}
    for p in proposals:
        assert {"target", "terms", "ci95", "heldout_gain"} <= set(p)
        assert p["target"] in propose.TARGETS
        assert p["terms"] and set(p["terms"]) == set(p["ci95"])
        assert set(p["terms"]) <= libraries[p["target"].split(".")[0]]
        assert len(p["terms"]) <= propose.MAX_TERMS
        for term, value in p["terms"].items():
            low, high = p["ci95"][term]
            assert low <= value <= high and not low <= 0.0 <= high, (p["target"], term)
        assert 0.0 < p["heldout_gain"] <= 1.0
    text = json.dumps(proposals)
    assert not any(f'"{name}"' in text for name in registry.names())


def describe(found):
    return {t: (p["terms"], p["ci95"], round(p["heldout_gain"], 3)) for t, p in found.items()}


@pytest.mark.parametrize("seed", SEEDS)
def test_spin_drag_is_proposed_as_abs_omega_omega(tmp_path, seed):
    """Spin drag d omega/dt = -k |omega| omega in flight, k = 0.02 1/rad (no effect of the library
    changes the spin in flight): flight.phi_acc ~ abs(omega)*omega, -k in its interval."""
    k = 0.02
    found, _ = proposals_for(tmp_path, seed, spin_drag=k)
    assert "flight.phi_acc" in found, describe(found)
    phi = found["flight.phi_acc"]
    low, high = phi["ci95"]["abs(omega)*omega"]
    assert low <= -k <= high, describe(found)
    assert phi["heldout_gain"] > 0.5
    assert "flight.x_acc" not in found and "flight.y_acc" not in found, describe(found)


@pytest.mark.parametrize("seed", SEEDS)
def test_a_table_tilted_by_3_degrees_is_a_constant_x_acceleration(tmp_path, seed):
    """In the table's frame gravity has g sin(3 deg) = 0.513 m/s^2 along it: flight.x_acc ~ 1,
    that value in its interval (and the y part, g (1 - cos(3 deg)) = 0.013 m/s^2, if proposed)."""
    tilt = math.radians(3.0)
    found, _ = proposals_for(tmp_path, seed, table_tilt=tilt)
    assert "flight.x_acc" in found, describe(found)
    x = found["flight.x_acc"]
    low, high = x["ci95"]["1"]
    assert low <= G * math.sin(tilt) <= high, describe(found)
    assert x["heldout_gain"] > 0.5
    if "flight.y_acc" in found and "1" in found["flight.y_acc"]["terms"]:
        low, high = found["flight.y_acc"]["ci95"]["1"]
        assert low <= G * (1.0 - math.cos(tilt)) <= high, describe(found)


@pytest.mark.parametrize("seed", SEEDS)
def test_restitution_by_corner_is_proposed_on_that_corner(tmp_path, seed):
    """Corner 2 bounces with beta_normal 0.7, the others 0.4: impact.dvy is proposed on corner 2
    (it leaves faster than the fitted model says: dvy > 0 where u_n < 0)."""
    found, _ = proposals_for(tmp_path, seed, corner_beta_normal=(0.4, 0.4, 0.7, 0.4))
    assert "impact.dvy" in found, describe(found)
    terms = found["impact.dvy"]["terms"]
    assert "corner_2*u_n" in terms or "corner_2" in terms, describe(found)
    assert terms.get("corner_2*u_n", -1.0) < 0.0 and terms.get("corner_2", 1.0) > 0.0
    assert not any(t.startswith("flight.") for t in found), describe(found)


@pytest.mark.parametrize("seed", SEEDS)
def test_control_drops_get_no_proposal(tmp_path, seed):
    """The library's own physics, nothing missing: no proposal (any formula that got past the
    cross-validation is below the threshold)."""
    found, report = proposals_for(tmp_path, seed)
    assert not found, describe(found)
    assert all(r["z"] < report["threshold_z"] for r in report["targets"].values())


def test_sparse_fit_finds_a_planted_formula_and_nothing_in_noise():
    """Rows of 60 tracks: y = 0.5 - 2 a + noise, among five terms: the formula and its
    coefficients (in their intervals); pure noise: nothing."""
    rng = np.random.default_rng(4)
    rows, tracks = 1200, 60
    traj = rng.integers(0, tracks, rows)
    features = np.column_stack([np.ones(rows), rng.normal(size=(rows, 4))])
    terms = ("1", "a", "b", "c", "d")
    variance = rng.uniform(0.5, 2.0, rows)
    noise = rng.normal(size=rows) * np.sqrt(variance)
    fitted = propose.sparse_fit(0.5 - 2.0 * features[:, 1] + noise, variance, features, terms, traj)
    assert fitted["proposed"] and set(fitted["terms"]) == {"1", "a"}
    for term, true in (("1", 0.5), ("a", -2.0)):
        low, high = fitted["ci95"][term]
        assert low <= true <= high
    assert fitted["heldout_gain"] > 0.5
    empty = propose.sparse_fit(noise, variance, features, terms, traj)
    assert not empty["proposed"] and empty["z"] < propose.PROPOSAL_Z
    # a few wild rows do not make a formula (Huber weights)
    wild = noise.copy()
    wild[:5] += 200.0 * features[:5, 2]
    assert not propose.sparse_fit(wild, variance, features, terms, traj)["proposed"]

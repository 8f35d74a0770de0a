"""Which candidates and pairs a round of the loop tries, from the registry's declarations, and
when a candidate is fitted again at a bound.

Through diagnose's public helpers candidate_pairs, untried_effects and at_a_bound_off_null:
the loop's rules for a round, without running a round."""

from types import SimpleNamespace

from dice_sweep import effects as registry
from dice_sweep.config import default_config
from dice_sweep.measured.diagnose import at_a_bound_off_null, candidate_pairs, untried_effects
from dice_sweep.measured.fit import ModelSpec


def results(*zs):
    return [{"effect": name, "z": z} for name, z in zs]


def test_pairs_are_the_top_two_and_what_the_registry_says_acts_together():
    pairs = candidate_pairs(results(("air_drag", 1.5), ("inertia", 2.0), ("corner_impulse", -1.0), ("coulomb_friction", 0.5),
                           ("sliding_friction", 0.1), ("exact_coulomb", 0.2)))
    as_sets = [set(p) for p in pairs]
    assert as_sets[0] == {"inertia", "air_drag"}
    for pair in ({"coulomb_friction", "corner_impulse"}, {"sliding_friction", "coulomb_friction"}, {"exact_coulomb", "coulomb_friction"}):
        assert pair in as_sets
    assert {"sliding_friction", "exact_coulomb"} not in as_sets  # two values of one key
    assert len(as_sets) == len({frozenset(p) for p in as_sets}) == 4


def test_a_switch_the_model_has_thrown_is_not_tried_again():
    spec = ModelSpec((), ()).with_effect("exact_coulomb")
    tried = untried_effects(registry.names(), spec)
    assert "corner_impulse" not in tried  # exact_coulomb set the rigid model already
    assert "sliding_friction" not in tried  # another value of the same key
    assert {"coulomb_friction", "inertia", "rounded_corners"} <= set(tried)
    assert "corner_impulse" in untried_effects(registry.names(), ModelSpec((), ()))


def test_the_exact_impact_frees_no_tangential_restitution():
    assert "beta_tangential" in ModelSpec((), ()).param_names()
    names = ModelSpec(("exact_coulomb", "coulomb_friction"), ()).param_names()
    assert "beta_tangential" not in names and {"beta_normal", "friction"} <= set(names)


def test_a_bound_counts_for_a_refit_only_away_from_the_null():
    """fit_candidate refits a contact candidate at a bound, but not at its null bound (an absent
    effect): contact_time's bounds are 0 (its null) and 1e-3 s."""
    cfg = default_config()
    at = lambda value: SimpleNamespace(params={"contact_time": value}, at_bound={"contact_time": True})
    assert at_a_bound_off_null(at(1e-3), "flat_landing", cfg)
    assert not at_a_bound_off_null(at(0.0), "flat_landing", cfg)
    assert not at_a_bound_off_null(at(1e-10), "flat_landing", cfg)  # at the null bound within at_bound's tolerance
    assert not at_a_bound_off_null(SimpleNamespace(params={"contact_time": 5e-4}, at_bound={"contact_time": False}), "flat_landing", cfg)
    assert not at_a_bound_off_null(SimpleNamespace(params={}, at_bound={}), "corner_impulse", cfg)  # no parameter

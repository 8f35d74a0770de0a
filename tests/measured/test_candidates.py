"""Which candidates and pairs a round of the loop tries, from the registry's declarations."""

from dice_sweep import effects as registry
from dice_sweep.measured.diagnose import _pairs, _untried
from dice_sweep.measured.fit import ModelSpec


def results(*zs):
    return [{"effect": name, "z": z} for name, z in zs]


def test_pairs_are_the_top_two_and_what_the_registry_says_acts_together():
    pairs = _pairs(results(("air_drag", 1.5), ("inertia", 2.0), ("corner_impulse", -1.0), ("coulomb_friction", 0.5),
                           ("sliding_friction", 0.1), ("exact_coulomb", 0.2)))
    as_sets = [set(p) for p in pairs]
    assert as_sets[0] == {"inertia", "air_drag"}
    for pair in ({"coulomb_friction", "corner_impulse"}, {"sliding_friction", "coulomb_friction"}, {"exact_coulomb", "coulomb_friction"}):
        assert pair in as_sets
    assert {"sliding_friction", "exact_coulomb"} not in as_sets  # two values of one key
    assert len(as_sets) == len({frozenset(p) for p in as_sets}) == 4


def test_a_switch_the_model_has_thrown_is_not_tried_again():
    spec = ModelSpec((), ()).with_effect("exact_coulomb")
    tried = _untried(registry.names(), spec)
    assert "corner_impulse" not in tried  # exact_coulomb set the rigid model already
    assert "sliding_friction" not in tried  # another value of the same key
    assert {"coulomb_friction", "inertia", "rounded_corners"} <= set(tried)
    assert "corner_impulse" in _untried(registry.names(), ModelSpec((), ()))


def test_the_exact_impact_frees_no_tangential_restitution():
    assert "beta_tangential" in ModelSpec((), ()).param_names()
    names = ModelSpec(("exact_coulomb", "coulomb_friction"), ()).param_names()
    assert "beta_tangential" not in names and {"beta_normal", "friction"} <= set(names)

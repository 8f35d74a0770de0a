"""dice_sweep.physics.params: the kernel's vectors, and a config key's value written straight
into its slot (KeyWriter) against the config with that value set and packed."""

import math

import numpy as np
import pytest

from dice_sweep import effects
from dice_sweep.config import parse_config
from dice_sweep.physics.params import (BASE_KEY_SLOTS, FP_ALPHA, FP_COM_Y, FP_CORNERS, FP_G, FP_INERTIA, FP_RHO_MAX, INERTIA_KEY,
                                       KeyWriter, pack_params, slot)

# a rigid pentagon with every derived slot away from its plain value: loaded, rounded, heavier
CONFIG = ('[die]\nsides = 5\ncircumradius = 0.03\n[contact]\nmodel = "rigid"\nbeta_normal = 0.3\nbeta_tangential = -0.2\n'
          'friction = 0.4\n[effects]\nair_drag = 0.3\ncom_offset = [0.002, -0.001]\ninertia = 0.9\ncorner_radius = 0.002\n')

# every key a fit frees that the kernel reads, with a value away from the config's
MOVES = {"world.g": 9.5, "contact.beta_normal": 0.45, "contact.beta_tangential": 0.1, "contact.friction": math.inf,
         "effects.air_drag": 0.05, "effects.com_offset[0]": -0.003, "effects.com_offset[1]": 0.0015,
         "effects.speed_restitution": 0.4, "effects.contact_time": 2e-4, "effects.inertia": 1.1, "effects.corner_radius": 0.0}


def test_every_fitted_kernel_key_is_covered():
    kernel_keys = {p.key for p in effects.BASE_PARAMS + tuple(p for e in effects.EFFECTS for p in e.params)
                   if not p.key.startswith("tracking.")}
    assert kernel_keys == set(MOVES)


@pytest.mark.parametrize("key", sorted(MOVES))
def test_a_written_value_is_the_packed_config_bit_for_bit(key):
    cfg = parse_config(CONFIG)
    moved = effects.set_key(cfg, key, MOVES[key])
    got = KeyWriter(cfg).fpar_with({key: MOVES[key]})
    np.testing.assert_array_equal(got, pack_params(moved)[0])
    assert not np.array_equal(got, pack_params(cfg)[0])  # the value reached the vector


def test_all_values_at_once_and_the_writer_unchanged():
    cfg = parse_config(CONFIG)
    writer = KeyWriter(cfg)
    before = writer.fpar.copy()
    moved = cfg
    for key, value in MOVES.items():
        moved = effects.set_key(moved, key, value)
    np.testing.assert_array_equal(writer.fpar_with(MOVES), pack_params(moved)[0])
    np.testing.assert_array_equal(writer.fpar, before)  # each call writes into a copy
    np.testing.assert_array_equal(writer.fpar_with({}), before)


def test_derived_slots_follow_the_centre_of_mass_and_the_corners():
    cfg = parse_config(CONFIG)
    fpar = KeyWriter(cfg).fpar_with({"effects.com_offset[1]": 0.0, "effects.com_offset[0]": 0.0, "effects.corner_radius": 0.0})
    plain = pack_params(parse_config(CONFIG.replace("com_offset = [0.002, -0.001]", "").replace("corner_radius = 0.002", "")))[0]
    for index in (FP_INERTIA, FP_ALPHA, FP_RHO_MAX):
        assert fpar[index] == plain[index]
    np.testing.assert_array_equal(fpar[FP_CORNERS:], plain[FP_CORNERS:])


def test_slot_names_base_registry_and_array_keys():
    assert slot("world.g") == FP_G == BASE_KEY_SLOTS["world.g"]
    assert slot("effects.com_offset[1]") == FP_COM_Y == slot("effects.com_offset") + 1
    for bad in ("effects.com_offset[2]", "effects.inertia", "world.nothing", "contact.beta_normal[0]"):
        with pytest.raises(KeyError):
            slot(bad)
    with pytest.raises(KeyError, match="choice"):
        KeyWriter(parse_config(CONFIG)).fpar_with({"contact.friction_rule": 1.0})
    assert INERTIA_KEY == "effects.inertia"

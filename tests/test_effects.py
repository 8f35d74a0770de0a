"""The effect registry: every entry complete and consistent with the config and the kernel."""

import math

import numpy as np
import pytest

from dice_sweep import effects
from dice_sweep.config import parse_config
from dice_sweep.physics import pack_params
from dice_sweep.physics.layout import MODEL_RIGID
from dice_sweep.physics.params import FP_DRAG, FP_G, FP_KSR, FP_MU, IP_MODEL

CFG = parse_config("[die]\nsides = 4\ncircumradius = 0.0424\n")
NAMES = effects.names()


def test_names_are_unique_and_kinds_known():
    assert len(set(NAMES)) == len(NAMES)
    params = [p.name for e in effects.EFFECTS for p in e.params] + [p.name for p in effects.BASE_PARAMS]
    assert len(set(params)) == len(params)
    assert {e.kind for e in effects.EFFECTS} <= {"contact", "flight", "measurement"}


@pytest.mark.parametrize("name", NAMES)
def test_each_entry_is_complete(name):
    entry = effects.effect(name)
    assert entry.summary and entry.signature and entry.signature_note
    assert entry.params or entry.switch
    for p in entry.params:
        low, high = p.bounds_of(CFG)
        null = p.null_value(CFG)
        assert low < high
        assert low <= null <= high or math.isinf(null)
        for start in p.starts_of(CFG):
            assert low <= start <= high
        assert p.scale > 0 and p.unit
        effects.get_key(CFG, p.key)  # the key exists in a config
    assert not entry.is_declared(CFG)
    assert (entry.measurement is not None) == (entry.kind == "measurement")


@pytest.mark.parametrize("name", [e.name for e in effects.EFFECTS if e.kind != "measurement"])
def test_physical_effects_reach_the_kernel(name):
    """Switching an effect on at a value away from its null changes the kernel's parameters."""
    entry = effects.effect(name)
    values = {p.name: p.starts_of(CFG)[0] for p in entry.params}
    on = effects.with_values(CFG, (name,), values)
    if name != "gravity":  # g's null is the config's own value: it is never "declared"
        assert entry.is_declared(on)
    before, after = pack_params(CFG), pack_params(on)
    assert not (np.array_equal(before[0], after[0]) and np.array_equal(before[1], after[1]))


def test_kernel_reads_the_values_set():
    cfg = effects.with_values(CFG, ("corner_impulse",), {"friction": 0.3, "air_drag": 0.2, "speed_restitution": 0.5, "g": 9.5})
    fpar, ipar = pack_params(cfg)
    assert ipar[IP_MODEL] == MODEL_RIGID
    assert (fpar[FP_MU], fpar[FP_DRAG], fpar[FP_KSR], fpar[FP_G]) == (0.3, 0.2, 0.5, 9.5)


def test_measurement_maps_are_inverse_pairs():
    """A state taken file -> true and its pose true -> file is the pose it started from."""
    rng = np.random.default_rng(0)
    values = {"time_scale": 1.03, "length_scale": 0.97, "angle_offset": 0.05, "table_offset": 0.002}
    times_to_true, state_to_true, pose_to_file = effects.measurement_maps(CFG, values)
    states = rng.normal(size=(20, 6))
    back = pose_to_file(state_to_true(states)[:, :3])
    assert np.allclose(back, states[:, :3], atol=1e-14)
    # velocities: file velocity = length_scale / time_scale * true velocity
    true = state_to_true(states)
    assert np.allclose(true[:, 3], states[:, 3] * 1.03 / 0.97)
    assert np.allclose(true[:, 5], states[:, 5] * 1.03)
    assert np.allclose(times_to_true(np.array([1.03])), [1.0])


def test_declared_tracking_values_are_used():
    """Without a fitted value the maps apply the [tracking] value the config declares, to the
    angle alone (file phi = phi + offset) and back; a fitted value takes its place."""
    cfg = parse_config("[tracking]\nangle_offset = 0.1\n")
    states = np.random.default_rng(1).normal(size=(5, 6))
    given = states.copy()
    _, state_to_true, pose_to_file = effects.measurement_maps(cfg, {})
    true = state_to_true(states)
    assert np.array_equal(states, given)  # a new array: the file's states untouched
    assert np.array_equal(np.delete(true, 2, axis=1), np.delete(states, 2, axis=1))
    assert np.allclose(true[:, 2], states[:, 2] - 0.1, rtol=0, atol=1e-15)
    assert np.allclose(pose_to_file(true[:, :3]), states[:, :3], rtol=0, atol=1e-15)
    _, fitted_to_true, _ = effects.measurement_maps(cfg, {"angle_offset": 0.03})
    assert np.allclose(fitted_to_true(states)[:, 2], states[:, 2] - 0.03, rtol=0, atol=1e-15)
    assert effects.declared_effects(cfg) == ("angle_offset",)


def test_markdown_table_lists_every_effect():
    table = effects.markdown_table()
    for name in NAMES:
        assert f"| {name} |" in table


def test_docs_tables_are_regenerated_from_the_registry():
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parent.parent / "scripts" / "effects_doc.py"
    result = subprocess.run([sys.executable, str(script)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


def test_every_signature_is_measured_by_the_diagnosis():
    from dice_sweep.measured.diagnose import SIGNATURES

    for entry in effects.EFFECTS:
        assert entry.signature in SIGNATURES, entry.name

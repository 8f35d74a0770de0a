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
    assert {e.kind for e in effects.NOISE_MODELS} == {"noise"}
    assert not set(NAMES) & {e.name for e in effects.NOISE_MODELS}  # never a fit's or diagnosis's candidate


NOISE_KEYS = [key for e in effects.NOISE_MODELS for key in e.config_keys]


def test_noise_models_are_complete():
    """A noise model declares keys with units, ranges and defaults, the null values at which it
    is off (its params, bounded by its keys' ranges), and a residual signature."""
    for entry in effects.NOISE_MODELS:
        assert entry.summary and entry.signature and entry.signature_note and entry.params
        assert not entry.is_declared(CFG)
        keys = {key.dotted: key for key in entry.config_keys}
        for p in entry.params:
            key = keys[p.key]
            assert p.bounds_of(CFG) == (key.low, key.high) and p.null_value(CFG) == key.default
            on = effects.set_key(CFG, p.key, 0.5 * (key.low + key.high))
            assert entry.is_declared(on) and on.scatter.on


@pytest.mark.parametrize("key", NOISE_KEYS, ids=lambda key: key.dotted)
def test_noise_keys_are_config_keys_with_the_registrys_range(key):
    """Each noise key is read by the config with the range the registry gives it: its bounds
    parse, a value beyond either is refused naming the key and the registry's range."""
    cfg = parse_config("")
    assert effects.get_key(cfg, key.dotted) == key.default and type(effects.get_key(cfg, key.dotted)) is key.kind
    for value in (key.low, key.high):
        assert effects.get_key(parse_config(f"[{key.section}]\n{key.name} = {key.kind(value)!r}\n"), key.dotted) == value
    for value in (key.low - 1, key.high + 1 if key.high < 2**53 - 1 else 2**53):
        with pytest.raises(Exception) as error:
            parse_config(f"[{key.section}]\n{key.name} = {key.kind(value)!r}\n")
        assert key.dotted in str(error.value) and f"[{key.low:g}, {key.high:g}]" in str(error.value)


def test_the_scatter_section_is_the_registrys_keys():
    """The config's [scatter] dataclass has exactly the noise model's keys, in registry order
    (written configs keep that order), and is written back only when off its defaults."""
    from dice_sweep.config import Scatter, config_to_toml

    assert [f.name for f in __import__("dataclasses").fields(Scatter)] == [key.name for key in NOISE_KEYS]
    assert "[scatter]" not in config_to_toml(parse_config(""))
    cfg = parse_config("[scatter]\ncorner = 0.1\ndraws = 8\nseed = 3\n")
    assert parse_config(config_to_toml(cfg)) == cfg and "[scatter]" in config_to_toml(cfg)


def test_noise_slots_are_packed_from_the_registry():
    """Each slotted noise key reaches its kernel slot, a key in the die's own units times its
    scale (the floors: sqrt(g R)); and the config, the slots and the kernel's packing name no
    noise key themselves (one place declares them)."""
    from pathlib import Path

    from dice_sweep.physics.params import KeyWriter, slot

    cfg = CFG
    for i, key in enumerate(k for k in NOISE_KEYS if k.slot):
        cfg = effects.set_key(cfg, key.dotted, key.kind(0.1 * (i + 1) if key.kind is float else 7))
    fpar, _ = pack_params(cfg)
    writer = KeyWriter(CFG)
    for key in NOISE_KEYS:
        if not key.slot:
            continue
        value = effects.get_key(cfg, key.dotted)
        factor = math.sqrt(cfg.world.g * cfg.die.circumradius) if key.unit == "sqrt(g R)" else 1.0
        assert fpar[slot(key.dotted)] == pytest.approx(value * factor, rel=1e-15)
        assert writer.fpar_with({key.dotted: value})[slot(key.dotted)] == fpar[slot(key.dotted)]
    root = Path(effects.__file__).parent
    sources = (root / "config.py").read_text() + (root / "physics" / "params.py").read_text()
    for key in NOISE_KEYS:
        assert f'"{key.name}"' not in sources and (not key.slot or key.slot not in sources), key.dotted


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


# A probe every physical effect must show in: the rigid law capped by friction (so a switch of
# the contact law or of the friction rule matters), throws with spin, slip and a landing near
# flat (for flat_landing), between walls; sampled to 0.6 s, past the decision.
PROBE_CFG = parse_config(
    "[die]\nsides = 4\ncircumradius = 0.0424\n[contact]\nbeta_normal = 0.4\nbeta_tangential = 0.3\nfriction = 0.15\n"
    "[walls]\nseparation = 0.3\n[integrator]\nt_max = 0.6\n"
)
PROBE_STARTS = np.array([
    [0.0, 0.15, 0.3, 0.4, 0.0, 25.0],
    [0.01, 0.12, 1.1, -0.8, -0.5, -30.0],
    [0.0, 0.0424 * math.cos(math.pi / 4) + 0.02, math.pi / 4 + 0.002, 0.05, -1.0, 0.3],  # near flat
    [-0.02, 0.2, 2.0, 1.5, 1.0, 5.0],
])


def probe_paths(cfg):
    """Poses of the geometric centre of the probe throws every 5 ms, through the kernel."""
    from dice_sweep.physics.kernel import sample_batch
    from dice_sweep.physics.params import IP_CONTINUE

    fpar, ipar = pack_params(cfg)
    ipar[IP_CONTINUE] = 1
    times = np.arange(0.0, 0.6, 0.005)
    all_times = np.tile(times, len(PROBE_STARTS))
    starts = np.arange(len(PROBE_STARTS) + 1) * times.size
    out = np.empty((all_times.size, 6))
    sample_batch(fpar, ipar, PROBE_STARTS.copy(), all_times, starts, out, np.zeros(len(PROBE_STARTS), np.int8))
    return out


@pytest.mark.parametrize("name", [e.name for e in effects.EFFECTS if e.kind != "measurement"])
def test_physical_effects_change_a_roll(name):
    """Switching an effect on at its first start value changes the rolls of the probe: the
    kernel reads what the registry packs (a registry entry whose slot no kernel line reads
    fails here; so did `test_physical_effects_reach_the_kernel`'s successor on an unread slot)."""
    entry = effects.effect(name)
    values = {p.name: p.starts_of(PROBE_CFG)[0] for p in entry.params}
    on = effects.with_values(PROBE_CFG, (name,), values)
    if name != "gravity":  # g's null is the config's own value: it is never "declared"
        assert entry.is_declared(on)
    base = PROBE_CFG
    if entry.switch:  # compare with the same contact model, so that the effect alone differs
        for key, value in entry.switch[:-1]:
            base = effects.set_key(base, key, value)
    before, after = probe_paths(base), probe_paths(on)
    assert np.all(np.isfinite(after))
    assert np.max(np.abs(after[:, :2] - before[:, :2])) > 1e-6, f"{name} changed no roll by a micrometre"


@pytest.mark.parametrize("name", [e.name for e in effects.EFFECTS if e.kind == "measurement"])
def test_measurement_effects_leave_the_kernel_alone(name):
    """The tracker's view is not the die's motion: the kernel's parameters do not change."""
    (p,) = effects.effect(name).params
    on = effects.with_values(CFG, (name,), {p.name: p.starts_of(CFG)[0]})
    before, after = pack_params(CFG), pack_params(on)
    assert np.array_equal(before[0], after[0]) and np.array_equal(before[1], after[1])


def test_every_registry_slot_is_read_by_a_kernel():
    """Each kernel slot the registry declares is indexed by some kernel module besides the one
    that packs it (a slot that nothing reads is an effect that does nothing)."""
    import re
    from pathlib import Path

    from dice_sweep.physics.params import SLOTS

    sources = {path.name: path.read_text() for path in (Path(effects.__file__).parent / "physics").glob("*.py") if path.name != "params.py"}
    for name in SLOTS:
        readers = [f for f, text in sources.items() if re.search(rf"(fpar|ipar)\[{name}\b", text)]
        assert readers, f"{name}: no kernel module reads fpar[{name}] / ipar[{name}]"


def test_registry_slots_are_packed_from_the_config():
    from dice_sweep.physics.params import SLOTS, slot

    cfg = effects.with_values(CFG, ("exact_coulomb",), {"air_drag": 0.2, "com_dx": 0.001, "com_dy": -0.002})
    fpar, ipar = pack_params(cfg)
    assert fpar[slot("effects.air_drag")] == 0.2
    assert tuple(fpar[slot("effects.com_offset"):slot("effects.com_offset") + 2]) == (0.001, -0.002)
    assert ipar[slot("contact.friction_rule")] == effects.FRICTION_RULES.index("exact")
    indices = [(vector, index + i) for vector, index, key in SLOTS.values() for i in range(max(key.length, 1))]
    assert len(set(indices)) == len(indices)  # no two keys share a slot


def test_inertia_scales_the_kernels_moment_of_inertia():
    from dice_sweep.geometry import inertia_ratio
    from dice_sweep.physics.params import FP_INERTIA

    on = effects.with_values(CFG, ("inertia",), {"inertia": 0.8})
    assert pack_params(on)[0][FP_INERTIA] == pytest.approx(0.8 * inertia_ratio(4) * 0.0424**2, rel=1e-15)


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
    noise = effects.noise_table()
    for key in NOISE_KEYS:
        assert f"`{key.dotted}`" in noise and (not key.slot or f"`{key.slot}`" in noise)


def test_docs_tables_are_regenerated_from_the_registry():
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parent.parent / "scripts" / "effects_doc.py"
    result = subprocess.run([sys.executable, str(script)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


def test_every_signature_is_measured_by_the_diagnosis():
    from dice_sweep.measured.signatures import SIGNATURES

    for entry in effects.EFFECTS:
        assert entry.signature in SIGNATURES, entry.name


def test_the_worked_example_is_the_registry_entry():
    """docs/dev/adding.md's worked example (step 1) builds exactly the registry's entry: the code a
    contributor copies is the code that runs."""
    import re
    import textwrap
    from pathlib import Path

    text = (Path(__file__).resolve().parent.parent / "docs" / "dev" / "adding.md").read_text()
    block = re.search(r"1\. \*\*The entry\*\*.*?```python\n(.*?)```", text, re.S).group(1)
    example = eval(textwrap.dedent(block), vars(effects))  # the names the registry module has
    entry = effects.effect(example.name)

    def described(e):
        params = [(p.name, p.unit, p.key, p.bounds_of(CFG), p.null_value(CFG), p.starts_of(CFG), p.scale) for p in e.params]
        keys = [(k.dotted, k.default, k.unit, k.low, k.high, k.low_open, k.slot, k.choices) for k in e.config_keys]
        return (e.name, e.kind, e.summary, params, keys, e.switch, e.signature, e.signature_note)

    assert described(example) == described(entry)
    # and the kernel line the example shows is the kernel's
    impact_source = (Path(effects.__file__).parent / "physics" / "impact.py").read_text()
    assert "return fpar[FP_BN] / (1.0 + fpar[FP_KSR] * speed)" in impact_source


def test_the_worked_example_runs(tmp_path):
    """The example's roll command (docs/dev/adding.md) runs, and the effect changes the roll it prints."""
    from pathlib import Path

    from click.testing import CliRunner

    from dice_sweep.cli import main

    text = (Path(__file__).resolve().parent.parent / "docs" / "dev" / "adding.md").read_text()
    assert "`dice-sweep roll configs/table1.toml --set effects.speed_restitution=0.5`" in text
    runner = CliRunner()
    args = ["roll", "configs/table1.toml", "--json"]
    plain = runner.invoke(main, args)
    slowed = runner.invoke(main, args + ["--set", "effects.speed_restitution=0.5"])
    assert plain.exit_code == 0 and slowed.exit_code == 0, slowed.output
    assert plain.output != slowed.output


NEW_ENTRY = '''
import math, dataclasses
from dice_sweep import effects
entry = effects.Effect(
    "angular_drag", "flight", "spin damped in flight, d omega / dt = -k omega",
    params=(effects.Param("angular_drag", "1/s", "effects.angular_drag", effects._fixed(0.0, 10.0), 0.0, (0.5,), 0.1),),
    config_keys=(effects.ConfigKey("effects", "angular_drag", 0.0, "1/s", low=0.0, slot="FP_ANGULAR_DRAG"),),
    signature="flight_spin_change", signature_note="spin change in flight",
)
effects.EFFECTS = effects.EFFECTS + (entry,)
effects._BY_NAME[entry.name] = entry
effects._PARAMS["angular_drag"] = entry.params[0]
from dice_sweep.config import parse_config, config_to_toml
from dice_sweep.physics.params import pack_params, slot, FP_ANGULAR_DRAG
cfg = parse_config("[effects]\\nangular_drag = 0.25\\n")
assert cfg.effects.angular_drag == 0.25 and parse_config(config_to_toml(cfg)) == cfg
fpar, ipar = pack_params(cfg)
assert fpar[FP_ANGULAR_DRAG] == 0.25 == fpar[slot("effects.angular_drag")]
assert effects.with_values(parse_config(""), ("angular_drag",), {"angular_drag": 0.5}).effects.angular_drag == 0.5
try:
    parse_config("[effects]\\nangular_drag = -1\\n")
except Exception as error:
    assert "effects.angular_drag" in str(error) and "allowed range" in str(error), error
else:
    raise AssertionError("a negative angular_drag was accepted")
print("ok")
'''


def test_a_registry_entry_alone_makes_a_working_config_key_and_kernel_slot():
    """Issue 28: a new effect's registry entry alone made every config parse fail with a bare
    TypeError. Now the entry alone gives the config key (validated, written back, settable by
    a fit) and its kernel slot, packed; only the kernel lines that read the slot and a test are
    left to write (test_every_registry_slot_is_read_by_a_kernel fails until a kernel reads it)."""
    import subprocess
    import sys

    result = subprocess.run([sys.executable, "-c", NEW_ENTRY], capture_output=True, text=True)
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stdout + result.stderr

"""Tests of dice_sweep.config: defaults, validation messages, --set overrides, the TOML writer."""

import dataclasses
import math
import pathlib
import tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dice_sweep.config import (
    Axis,
    Config,
    Grid,
    Initial,
    MAX_ROLL_WORK,
    MAX_TABLE_SPEED,
    Walls,
    check_computable,
    check_initial_clear,
    config_to_toml,
    default_config,
    load_config,
    parse_config,
)
from dice_sweep.errors import ConfigError, DiceSweepError

CONFIG_DIR = pathlib.Path(__file__).resolve().parent.parent / "configs"
R = 0.019 / math.sqrt(2.0)  # Table I circumradius, m
GRID = """
[grid]
x = { param = "omega0", min = 0.0, max = 60.0, num = 8 }
y = { param = "y0", min = 0.02, max = 0.30, num = 4 }
"""


def config_error(text, overrides=(), source="bad.toml"):
    """The ConfigError that parsing ``text`` raises, checked to be one line naming the file."""
    with pytest.raises(ConfigError) as caught:
        parse_config(text, source, overrides)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(caught.value.file + ": " + caught.value.key + ": ")
    return caught.value


def test_defaults_are_table_one_of_the_paper():
    cfg = default_config()
    assert cfg.die.sides == 4
    assert cfg.die.circumradius == R
    assert (cfg.contact.model, cfg.contact.beta_normal, cfg.contact.beta_tangential) == ("paper", 0.2, -0.35)
    assert cfg.walls == Walls(separation=None)
    assert cfg.initial == Initial(x0=0.0, y0=0.1, phi0=0.0, vx0=0.0, vy0=0.0, omega0=10.0)
    assert cfg.world.g == 9.81
    assert (cfg.integrator.method, cfg.integrator.dt, cfg.integrator.t_max) == ("event", 0.001, 30.0)
    assert cfg.integrator.max_events == 100_000
    assert cfg.grid is None


def test_empty_walls_section_gives_the_default_separation():
    assert parse_config("[walls]").walls.separation == 0.20


@pytest.mark.parametrize("path", sorted(CONFIG_DIR.glob("*.toml")), ids=lambda path: path.name)
def test_every_shipped_config_loads_and_round_trips(path):
    cfg = load_config(path)
    assert cfg.source == str(path)
    assert parse_config(config_to_toml(cfg)) == cfg


def test_shipped_configs_exist():
    names = {path.name for path in CONFIG_DIR.glob("*.toml")}
    assert {"table1.toml", "demo.toml"} <= names


def test_table1_and_demo_configs():
    table1 = load_config(CONFIG_DIR / "table1.toml")
    assert (table1.initial.y0, table1.initial.omega0, table1.grid) == (0.15, 20.0, None)
    assert table1.die == default_config().die
    demo = load_config(CONFIG_DIR / "demo.toml")
    assert demo.grid == Grid(x=Axis("omega0", 0.0, 60.0, 128), y=Axis("y0", 0.02, 0.30, 128))


def test_int_is_accepted_for_a_float_key_and_stored_as_float():
    cfg = parse_config("[initial]\nomega0 = 20")
    assert cfg.initial.omega0 == 20.0
    assert isinstance(cfg.initial.omega0, float)


def test_source_takes_no_part_in_equality():
    assert parse_config("", source="a.toml") == parse_config("", source="b.toml")
    assert parse_config("", source="a.toml").source == "a.toml"


def test_with_initial_replaces_only_the_given_values():
    cfg = default_config().with_initial(omega0=20.0, y0=0.2)
    assert cfg.initial == dataclasses.replace(default_config().initial, omega0=20.0, y0=0.2)
    assert cfg.die == default_config().die
    assert default_config().initial.omega0 == 10.0  # the original is untouched (frozen)


def test_axis_values_are_cell_centres():
    np.testing.assert_allclose(Axis("y0", 0.0, 1.0, 4).values(), [0.125, 0.375, 0.625, 0.875])
    assert Axis("omega0", 2.0, 3.0, 1).values().tolist() == [2.5]


def test_grid_is_parsed():
    cfg = parse_config(GRID)
    assert cfg.grid == Grid(x=Axis("omega0", 0.0, 60.0, 8), y=Axis("y0", 0.02, 0.30, 4))
    assert isinstance(cfg.grid.x.min, float) and isinstance(cfg.grid.x.num, int)


# (toml text, dotted key named in the error, a fragment the message must contain)
BAD_CONFIGS = [
    ("[contact]\nbeta_normal = 1.5", "contact.beta_normal", "1.5 is outside the allowed range [0, 1]"),
    ("[contact]\nbeta_normal = -0.1", "contact.beta_normal", "allowed range [0, 1]"),
    ("[contact]\nbeta_tangential = -1.5", "contact.beta_tangential", "allowed range [-1, 1]"),
    ("[contact]\nbeta_norml = 0.5", "contact.beta_norml", "did you mean 'beta_normal'?"),
    ("[contact]\nmodel = \"elastic\"", "contact.model", "allowed values: paper, rigid"),
    ("[contact]\nfriction = -0.1", "contact.friction", "allowed range [0, inf]"),
    ("[contact]\nwindow = 0.01", "contact.window", "allowed range [0, 0.001] s"),
    ("[effects]\ncontact_time = -1e-4", "effects.contact_time", "allowed range [0, 0.001] s"),
    ("[effects]\ncom_offset = [0.02, 0.0]", "effects.com_offset", "|offset| < apothem"),
    ("[effects]\ncom_offset = [0.001]", "effects.com_offset", "2 numbers"),
    ("[effects]\nair_drag = -1.0", "effects.air_drag", "allowed range [0, inf) 1/m"),
    ("[contct]\nbeta_normal = 0.5", "contct", "did you mean 'contact'?"),
    ("[zzz]\nq = 1", "zzz", "allowed sections: die, contact, walls"),
    ("sides = 4", "sides", "unknown section"),
    ("[die]\nsides = 2", "die.sides", "2 is outside the allowed range [3, 127]"),
    ("[die]\nsides = 128", "die.sides", "allowed range [3, 127]"),
    ("[die]\nsides = 4.0", "die.sides", "expected an integer, got a float 4.0"),
    ("[die]\nsides = true", "die.sides", "expected an integer, got a boolean"),
    ("[die]\ncircumradius = 0.0", "die.circumradius", "allowed range [1e-09, inf) m"),
    ("[die]\ncircumradius = -0.01", "die.circumradius", "allowed range [1e-09, inf) m"),
    # issue 16: a radius whose square underflows was a ZeroDivisionError traceback packing the kernel's parameters
    ("[die]\ncircumradius = 1e-308", "die.circumradius", "allowed range [1e-09, inf) m"),
    ("[die]\ncircumradius = nan", "die.circumradius", "nan is not a finite number"),
    ("[die]\ncircumradius = \"big\"", "die.circumradius", "expected a number, got a string"),
    ("[initial]\nomega0 = true", "initial.omega0", "expected a number, got a boolean"),
    ("[initial]\nomega0 = inf", "initial.omega0", "inf is not a finite number"),
    ("[initial]\nvx0 = -inf", "initial.vx0", "is not a finite number"),
    ("[initial]\nvy0 = " + "9" * 400, "initial.vy0", "is not a finite number"),
    ("[world]\ng = 0", "world.g", "allowed range (0, inf) m/s^2"),
    ("[integrator]\nmethod = \"fixed\"", "integrator.method", "did you mean 'fixed_step'?"),
    ("[integrator]\ndt = 0", "integrator.dt", "allowed range (0, inf) s"),
    ("[integrator]\nt_max = -1", "integrator.t_max", "allowed range (0, inf) s"),
    ("[integrator]\nmax_events = 0", "integrator.max_events", "allowed range [1, 4.61169e+18]"),
    # issue 16: a count beyond int64 was an OverflowError traceback when the kernel's parameters were packed
    ("[integrator]\nmax_events = 99999999999999999999", "integrator.max_events", "allowed range [1, 4.61169e+18]"),
    ("[walls]\nseparation = 0.02", "walls.separation", "allowed range (0.0268701, inf) m"),
    ("[walls]\nseparation = 0.0", "walls.separation", "allowed range (0, inf) m"),
    ("[die]\n[die.extra]\na = 1", "die.extra", "unknown key 'extra'"),
    ("die = 3", "die", "expected a table, got an integer 3"),
    (GRID.replace("num = 8", "num = 0"), "grid.x.num", "0 is outside the allowed range [1, 100000]"),
    (GRID.replace("num = 8", "num = 8.0"), "grid.x.num", "expected an integer"),
    (GRID.replace("max = 60.0", "max = 0.0"), "grid.x.max", "allowed range: max > min"),
    (GRID.replace("max = 60.0", "max = -1.0"), "grid.x.max", "is not above min = 0.0"),
    (GRID.replace("min = 0.0,", "min = nan,"), "grid.x.min", "not a finite number"),
    (GRID.replace('"omega0"', '"y0"'), "grid.y.param", "'y0' is already swept by grid.x"),
    (GRID.replace('"omega0"', '"omega"'), "grid.x.param", "did you mean 'omega0'?"),
    (GRID.replace("num = 8 }", "num = 8, step = 1 }"), "grid.x.step", "allowed keys: param, min, max, num"),
    (GRID.replace("param = \"omega0\", ", ""), "grid.x.param", "missing"),
    ("[grid]\nx = { param = \"omega0\", min = 0.0, max = 60.0, num = 8 }", "grid.y", "missing"),
    ("[grid]\nx = 3\ny = 4", "grid.x", "expected a table"),
    ("[grid]\nz = 3", "grid.z", "allowed keys: x, y"),
    ("[scatter]\ncorner = 1.5", "scatter.corner", "allowed range [0, 1]"),
    ("[scatter]\nflat = -0.1", "scatter.flat", "allowed range [0, 1]"),
    ("[scatter]\ncorner_floor = 2", "scatter.corner_floor", "allowed range [0, 1] sqrt(g R)"),
    ("[scatter]\ndraws = 0", "scatter.draws", "allowed range [1, 4096]"),
    ("[scatter]\nseed = -1", "scatter.seed", "allowed range [0, 9.0072e+15]"),
    ("[scatter]\nspread = 0.1", "scatter.spread", "unknown key 'spread'"),
]


@pytest.mark.parametrize(("text", "key", "fragment"), BAD_CONFIGS)
def test_bad_config_is_one_line_error_naming_file_key_and_range(text, key, fragment):
    error = config_error(text)
    assert error.file == "bad.toml"
    assert error.key == key
    assert fragment in error.message
    assert isinstance(error, DiceSweepError)


def test_outside_range_message_matches_the_documented_form():
    error = config_error("[contact]\nbeta_normal = 1.5", source="configs/x.toml")
    assert str(error) == "configs/x.toml: contact.beta_normal: 1.5 is outside the allowed range [0, 1]"


def test_toml_syntax_error_names_the_line():
    error = config_error("[die]\nsides = 4\n[contact\n")
    assert error.key == "line 3"
    assert "TOML syntax error" in error.message


def test_toml_syntax_error_at_the_end_of_the_document():
    assert config_error("[die]\nsides =").key == "end of file"


def test_missing_file(tmp_path):
    path = tmp_path / "nope.toml"
    with pytest.raises(ConfigError) as caught:
        load_config(path)
    assert caught.value.file == str(path)
    assert "No such file" in str(caught.value)


def test_load_config_with_overrides(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("[initial]\nomega0 = 5.0\n")
    assert load_config(path, ["initial.omega0=7"]).initial.omega0 == 7.0
    assert load_config(str(path)).initial.omega0 == 5.0


# ---- start positions: no corner in the table or a wall --------------------------------------


def test_start_with_a_corner_in_the_table_is_refused():
    # phi0 = 0 puts corner 3 straight down, so the centre must be at least R high
    error = config_error("[initial]\ny0 = 0.01")
    assert error.key == "initial.y0"
    assert "into the table" in error.message
    assert f"y0 >= {R:g} m" in error.message


def test_start_touching_the_table_is_allowed():
    assert parse_config(f"[initial]\ny0 = {R!r}").initial.y0 == R
    apothem = R * math.cos(math.pi / 4)
    cfg = parse_config(f"[initial]\ny0 = {apothem!r}\nphi0 = {math.pi / 4!r}")  # flat on side 2
    assert cfg.initial.y0 == apothem


def test_flat_start_below_the_apothem_is_refused():
    error = config_error(f"[initial]\ny0 = 0.009\nphi0 = {math.pi / 4!r}")
    assert "into the table" in error.message


def test_start_in_either_wall_is_refused():
    right = config_error("[walls]\nseparation = 0.2\n[initial]\nx0 = 0.095")
    left = config_error("[walls]\nseparation = 0.2\n[initial]\nx0 = -0.095")
    assert right.key == left.key == "initial.x0"
    assert "right wall" in right.message and "left wall" in left.message
    limit = 0.1 - R
    assert f"{-limit:g} <= x0 <= {limit:g} m" in right.message


def test_start_next_to_a_wall_is_allowed_without_walls_only():
    assert parse_config("[initial]\nx0 = 0.095").initial.x0 == 0.095
    assert parse_config("[walls]\nseparation = 0.2\n[initial]\nx0 = 0.08").walls.separation == 0.2


def test_grid_of_heights_reaching_into_the_table_reports_the_first_bad_cell():
    # cell centres 0.0 + (i + 0.5) * 0.01: 0.005 is the first (and 0.015 > R is fine)
    text = GRID.replace("min = 0.02, max = 0.30, num = 4", "min = 0.0, max = 0.04, num = 4")
    error = config_error(text)
    assert error.key == "grid.y"
    assert "y0 = 0.005 m" in error.message
    # the same grid is fine for a higher start: the first cell is then above R
    parse_config(text.replace("min = 0.0,", "min = 0.02,"))


def test_grid_of_angles_reaching_into_the_table_names_the_angle_axis():
    # y0 = 0.011 m is between the apothem (0.0095 m) and R: only angles near pi/4 fit. For
    # phi0 in [0, pi/2] the square reaches R cos(min(phi0, pi/2 - phi0)) below its centre.
    text = "[initial]\ny0 = 0.011\n" + GRID.replace('"omega0", min = 0.0, max = 60.0', '"phi0", min = 0.5, max = 1.0')
    text = text.replace('"y0", min = 0.02, max = 0.30', '"omega0", min = 0.0, max = 1.0')
    # cell centres 0.61875 .. 0.88125: at most R cos(0.61875) = 0.01094 m deep
    parse_config(text.replace("min = 0.5, max = 1.0", "min = 0.6, max = 0.9"))
    error = config_error(text)
    assert error.key == "grid.x"
    # cell centres 0.53125, 0.59375, ...: the first reaches R cos(0.53125) = 0.01158 m down
    assert "phi0 = 0.53125 rad" in error.message


def test_grid_of_positions_reaching_into_a_wall_is_refused():
    text = "[walls]\nseparation = 0.2\n" + GRID.replace('"omega0", min = 0.0, max = 60.0', '"x0", min = -0.1, max = 0.1')
    error = config_error(text)
    assert error.key == "grid.x"
    assert "x0 = -0.0875 m" in error.message and "left wall" in error.message
    parse_config(text.replace("min = -0.1, max = 0.1", "min = -0.08, max = 0.08"))


def test_grid_start_check_uses_both_swept_axes():
    # heights and angles swept together: the first height that fails at some angle is reported
    text = GRID.replace('"omega0", min = 0.0, max = 60.0', '"phi0", min = 0.0, max = 1.57')
    text = text.replace("min = 0.02, max = 0.30", "min = 0.0, max = 0.04")
    error = config_error(text)
    assert error.key == "grid.y"
    assert "y0 = 0.005 m" in error.message


def test_initial_start_is_checked_for_roll_when_a_grid_sweeps_it():
    """`roll` starts from [initial] even when a [grid] sweeps y0: fig08 with initial.y0 = -1
    rolled "side 3 after 0 impacts" with exit 0. Loading accepts it (a sweep never uses it)."""
    cfg = parse_config("[initial]\ny0 = 0.1\n" + GRID, "bad.toml", ["initial.y0=-1"])
    with pytest.raises(ConfigError) as caught:
        check_initial_clear(cfg, ["initial.y0=-1"])
    assert caught.value.key == "initial.y0"
    assert "into the table" in str(caught.value) and "bad.toml with --set" in str(caught.value)


# a square with corners rounded to r keeps the apothem a: its arc centres sit sqrt(2) (a - r)
# from its centre (docs/physics.md, "Rounded corners"), so on a corner (phi0 = 0, corner 3
# straight down; corner 0 points at the right wall) it reaches sqrt(2) (a - r) + r < R
ROUND = 0.002  # m
ROUND_REACH = math.sqrt(2.0) * (R * math.cos(math.pi / 4) - ROUND) + ROUND


def test_rounded_die_may_start_where_its_sharp_corner_would_overlap():
    y0 = ROUND_REACH + 1e-9
    assert y0 < R - 1e-4  # the sharp die would be 0.8 mm into the table
    cfg = parse_config(f"[effects]\ncorner_radius = {ROUND}\n[initial]\ny0 = {y0!r}\nphi0 = 0.0")
    assert cfg.initial.y0 == y0
    check_initial_clear(cfg)
    x0 = 0.1 - ROUND_REACH - 1e-9  # and as close to the right wall
    walls = f"[walls]\nseparation = 0.2\n[effects]\ncorner_radius = {ROUND}\n[initial]\nphi0 = 0.0\n"
    assert parse_config(walls + f"x0 = {x0!r}").initial.x0 == x0
    assert parse_config(walls + f"x0 = {-x0!r}").initial.x0 == -x0


@pytest.mark.parametrize(
    ("start", "key", "surface", "allowed"),
    [
        (f"y0 = {ROUND_REACH - 1e-6!r}", "initial.y0", "the table", f"y0 >= {ROUND_REACH:g} m"),
        (f"x0 = {0.1 - ROUND_REACH + 1e-6!r}", "initial.x0", "the right wall", f"{ROUND_REACH - 0.1:g} <= x0 <= {0.1 - ROUND_REACH:g} m"),
    ],
)
def test_rounded_die_starting_into_a_surface_is_refused_with_its_own_range(start, key, surface, allowed):
    text = f"[walls]\nseparation = 0.2\n[effects]\ncorner_radius = {ROUND}\n[initial]\nphi0 = 0.0\n{start}"
    error = config_error(text)
    assert error.key == key
    assert f"1e-06 m into {surface} (allowed range at this phi0: {allowed})" in error.message


def test_roll_checks_a_rounded_die_at_its_rounded_reach():
    # a [grid] sweeping y0 leaves initial.y0 to `roll`'s own check
    text = f"[effects]\ncorner_radius = {ROUND}\n[initial]\nphi0 = 0.0\n" + GRID
    check_initial_clear(parse_config(text, overrides=[f"initial.y0={ROUND_REACH + 1e-9!r}"]))
    with pytest.raises(ConfigError) as caught:
        check_initial_clear(parse_config(text, overrides=[f"initial.y0={ROUND_REACH - 1e-6!r}"]))
    assert caught.value.key == "initial.y0" and f"y0 >= {ROUND_REACH:g} m" in caught.value.message


def test_sharp_die_is_checked_at_its_corners_as_before():
    y0 = ROUND_REACH + 1e-9  # clear for the rounded die, 0.8 mm into the table for the sharp one
    error = config_error(f"[effects]\ncorner_radius = 0.0\n[initial]\ny0 = {y0!r}\nphi0 = 0.0")
    assert error.key == "initial.y0"
    assert f"{R - y0:g} m into the table (allowed range at this phi0: y0 >= {R:g} m)" in error.message


# ---- --set overrides -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("override", "read", "expected"),
    [
        ("contact.beta_normal=0.3", lambda cfg: cfg.contact.beta_normal, 0.3),
        ("die.sides=5", lambda cfg: cfg.die.sides, 5),
        ("initial.omega0=20", lambda cfg: cfg.initial.omega0, 20.0),
        ("integrator.method=fixed_step", lambda cfg: cfg.integrator.method, "fixed_step"),
        ('integrator.method="fixed_step"', lambda cfg: cfg.integrator.method, "fixed_step"),
        (" initial.y0 = 0.2 ", lambda cfg: cfg.initial.y0, 0.2),
        ("walls.separation=0.3", lambda cfg: cfg.walls.separation, 0.3),
        ("grid.x.num=64", lambda cfg: cfg.grid.x.num, 64),
        ("grid.y.max=0.5", lambda cfg: cfg.grid.y.max, 0.5),
    ],
)
def test_override_values_are_parsed_as_toml_or_bare_strings(override, read, expected):
    cfg = parse_config(GRID, overrides=[override])
    assert read(cfg) == expected
    assert type(read(cfg)) is type(expected)


def test_overrides_apply_in_order_and_to_a_grid_written_inline():
    overrides = ['grid.y={param = "vx0", min = -1.0, max = 1.0, num = 2}', "initial.omega0=1", "initial.omega0=2"]
    cfg = parse_config(GRID, overrides=overrides)
    assert cfg.grid.y == Axis("vx0", -1.0, 1.0, 2)
    assert cfg.initial.omega0 == 2.0


def test_override_value_cannot_smuggle_in_other_keys():
    error = config_error("", overrides=['integrator.method="event"\ndt = 5'])
    assert error.key == "integrator.method"
    assert parse_config("").integrator.dt == 0.001


def test_override_is_validated_and_the_error_says_it_came_from_set():
    error = config_error("", overrides=["contact.beta_normal=1.5"], source="configs/x.toml")
    assert str(error) == "configs/x.toml with --set: contact.beta_normal: 1.5 is outside the allowed range [0, 1]"


def test_override_of_a_grid_key_without_a_grid_reports_the_missing_keys():
    error = config_error("", overrides=["grid.x.num=64"])
    assert error.key == "grid.x.param"


@pytest.mark.parametrize(
    ("override", "key", "fragment"),
    [
        ("contact.beta_normal", "contact.beta_normal", "expected section.key=value"),
        ("contact.beta_norml=0.3", "contact.beta_norml", "did you mean 'beta_normal'?"),
        ("contct.beta_normal=0.3", "contct.beta_normal", "did you mean 'contact'?"),
        ("grid.x.nm=64", "grid.x.nm", "did you mean 'num'?"),
        ("grid.z.num=64", "grid.z.num", "allowed keys: x, y"),
        ("die=4", "die", "a whole section cannot be set"),
        ("die.sides.x=4", "die.sides.x", "is a value, not a table"),
    ],
)
def test_malformed_override_names_set_and_the_key(override, key, fragment):
    error = config_error("", overrides=[override])
    assert error.file == "--set"
    assert error.key == key
    assert fragment in error.message


# ---- the TOML writer -----------------------------------------------------------------------


def test_written_config_has_every_key():
    cfg = parse_config("[walls]\n" + GRID)
    written = tomllib.loads(config_to_toml(cfg))
    assert set(written) == {"die", "contact", "walls", "initial", "world", "integrator", "effects", "tracking", "grid"}
    assert set(written["initial"]) == {"x0", "y0", "phi0", "vx0", "vy0", "omega0"}
    assert written["grid"]["x"] == {"param": "omega0", "min": 0.0, "max": 60.0, "num": 8}
    assert written["die"]["circumradius"] == R


def test_written_config_without_walls_or_grid_omits_them():
    written = tomllib.loads(config_to_toml(default_config()))
    assert "walls" not in written and "grid" not in written and "scatter" not in written


def test_scatter_section_is_read_written_and_packed():
    cfg = parse_config("[scatter]\ncorner = 0.07\nflat = 0.2\ndraws = 64\nseed = 5\n")
    assert (cfg.scatter.corner, cfg.scatter.flat, cfg.scatter.draws, cfg.scatter.seed) == (0.07, 0.2, 64, 5)
    assert cfg.scatter.on and not default_config().scatter.on
    assert parse_config(config_to_toml(cfg)) == cfg
    assert tomllib.loads(config_to_toml(cfg))["scatter"]["draws"] == 64


finite = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e300, max_value=1e300)
fraction = st.floats(min_value=0.0, max_value=1.0)


@settings(max_examples=200, deadline=None)
@given(
    sides=st.integers(3, 127),
    radius=st.floats(min_value=1e-9, max_value=10.0),
    coefficients=st.tuples(fraction, st.floats(min_value=-1.0, max_value=1.0)),
    x0=st.floats(min_value=-1.0, max_value=1.0),
    height=st.floats(min_value=0.0, max_value=100.0),
    velocities=st.tuples(finite, finite, finite, finite),
    gap=st.one_of(st.none(), st.floats(min_value=1e-6, max_value=10.0)),
    steps=st.tuples(st.floats(min_value=1e-300, max_value=1e300), st.floats(min_value=1e-300, max_value=1e300)),
    method=st.sampled_from(["event", "fixed_step"]),
    max_events=st.integers(1, 2**62),
    grid=st.booleans(),
)
def test_config_to_toml_round_trips_exactly(
    sides, radius, coefficients, x0, height, velocities, gap, steps, method, max_events, grid
):
    phi0, vx0, vy0, omega0 = velocities
    cfg = parse_config("")
    cfg = dataclasses.replace(
        cfg,
        die=dataclasses.replace(cfg.die, sides=sides, circumradius=radius),
        contact=dataclasses.replace(cfg.contact, beta_normal=coefficients[0], beta_tangential=coefficients[1]),
        # a start well clear of the table and walls, whatever the angle
        walls=Walls(None if gap is None else 2 * (abs(x0) + radius) + gap),
        integrator=dataclasses.replace(cfg.integrator, method=method, dt=steps[0], t_max=steps[1], max_events=max_events),
        grid=Grid(Axis("vy0", -1.5, 2.5e-7, 3), Axis("omega0", 1e-5, 1e5, 7)) if grid else None,
    ).with_initial(x0=x0, y0=radius * 1.001 + height, phi0=phi0, vx0=vx0, vy0=vy0, omega0=omega0)
    assert parse_config(config_to_toml(cfg)) == cfg


def test_round_trip_is_exact_for_awkward_floats():
    cfg = default_config().with_initial(vx0=0.1 + 0.2, vy0=1e-300, omega0=-5e-324, phi0=1e16)
    again = parse_config(config_to_toml(cfg))
    assert again.initial == cfg.initial
    assert again == cfg
    assert isinstance(again, Config)


# ---- keys from the effect registry ----------------------------------------------------------


def test_effects_and_tracking_keys_come_from_the_registry():
    from dice_sweep import effects
    from dice_sweep.config import Effects, Tracking

    specs = effects.config_key_specs()
    assert set(specs["effects"]) == {f.name for f in dataclasses.fields(Effects)}
    assert set(specs["tracking"]) == {f.name for f in dataclasses.fields(Tracking)}
    cfg = parse_config("[tracking]\ntime_scale = 1.03\n")
    assert cfg.tracking.time_scale == 1.03
    error = config_error("[tracking]\ntime_scale = 0\n")
    assert error.key == "tracking.time_scale" and "0" in error.message


def test_g_has_one_source():
    # files written before the registry hold `gravity = 0.0` (off): they still read
    assert parse_config("[effects]\ngravity = 0.0\n").world.g == 9.81
    error = config_error("[effects]\ngravity = 9.44\n")
    assert error.key == "effects.gravity" and "[world] g" in error.message


def test_event_budget_of_a_huge_fixed_step_count_fits_int64():
    """Issue 16: t_max / dt beyond int64 was an OverflowError traceback when the kernel's
    parameters were packed (`roll --set integrator.method=fixed_step --set integrator.dt=1e-9
    --set integrator.t_max=1e12`)."""
    from dice_sweep.config import MAX_EVENTS
    from dice_sweep.physics.params import event_budget, pack_params

    cfg = parse_config("[integrator]\nmethod = \"fixed_step\"\nt_max = 1e12\ndt = 1e-9")
    assert event_budget(cfg.integrator) == MAX_EVENTS
    pack_params(cfg)


# ---- values that cannot be computed, refused up front (issue 32) ---------------------------------

WIDE_GRID = "[grid]\nx = {{ param = \"omega0\", min = {low}, max = {high}, num = {num} }}\ny = {{ param = \"y0\", min = 0.05, max = 0.3, num = 4 }}\n"


@pytest.mark.parametrize(("low", "high", "num"), [(-1e308, 1e308, 10), (1.0, 1.0000000000000002, 4), (-1.7e308, 1.7e308, 1)])
def test_a_grid_whose_cell_centres_are_not_finite_distinct_numbers_is_refused(low, high, num):
    with pytest.raises(ConfigError) as error:
        parse_config(WIDE_GRID.format(low=low, high=high, num=num), source="g.toml")
    assert str(error.value).startswith("g.toml: grid.x: ") and "not finite, distinct numbers" in str(error.value)


def test_a_wide_grid_of_finite_centres_is_kept():
    """The control: centres far apart but finite are a grid like any other."""
    cfg = parse_config(WIDE_GRID.format(low=-1e300, high=1e300, num=10))
    assert np.isfinite(cfg.grid.x.values()).all()


@pytest.mark.parametrize(("text", "key", "fragment"), [
    ("[initial]\nvx0 = 1e200", "initial.vx0", "1e+200 m/s at the table"),
    ("[initial]\nomega0 = 1e300", "initial.omega0", "at most 1000 m/s"),
    ("[initial]\ny0 = 1e308", "initial.y0", "inf m/s at the table"),
    ("[initial]\nvy0 = -1001", "initial.vy0", "MAX_TABLE_SPEED"),
    (WIDE_GRID.format(low=0, high=1e9, num=4), "grid.x", "omega0 up to 1e+09 rad/s"),
    ("[integrator]\nmax_events = 4611686018427387904", "integrator.max_events", "4611686018427387904 events per roll"),
    ("[integrator]\nmethod = \"fixed_step\"\ndt = 1e-12", "integrator.dt", "t_max / dt = 3e+13 steps"),
])
def test_work_and_speeds_a_roll_cannot_finish_are_refused_with_the_limit(text, key, fragment):
    cfg = parse_config(text, source="c.toml")
    with pytest.raises(ConfigError) as error:
        check_computable(cfg)
    message = str(error.value)
    assert message.startswith(f"c.toml: {key}: ") and fragment in message, message
    assert "MAX_ROLL_WORK" in message or "MAX_TABLE_SPEED" in message


def test_the_limits_let_every_shipped_config_and_the_edges_through():
    for path in sorted(CONFIG_DIR.glob("*.toml")):
        check_computable(load_config(path))
    radius = default_config().die.circumradius
    check_computable(parse_config(f"[integrator]\nmax_events = {MAX_ROLL_WORK}"))
    check_computable(parse_config(f"[integrator]\nmethod = \"fixed_step\"\nt_max = 1.0\ndt = {1 / MAX_ROLL_WORK}"))
    check_computable(default_config().with_initial(y0=0.1, vx0=0.0, vy0=0.0, omega0=0.99 * MAX_TABLE_SPEED / radius - 1.0))


def test_a_fifo_as_config_is_refused_without_opening_it(tmp_path):
    import os

    fifo = tmp_path / "c.toml"
    os.mkfifo(fifo)
    with pytest.raises(ConfigError, match=r"c.toml: file: is a FIFO \(named pipe\), not a regular file"):
        load_config(fifo)

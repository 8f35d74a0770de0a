"""TOML configs -> frozen dataclasses, with validation, ``--set`` overrides and a TOML writer.

Every value is in SI units. The defaults are Table I of Smith 2014 (phi0 = 0, vx0 = 0,
beta_tangential = -0.35, beta_normal = 0.2, dt = 0.001 s, R = 1.9/sqrt(2) cm):

.. code-block:: toml

    [die]        # sides = 4, circumradius = 0.013435 (m)
    [contact]    # model = "paper" | "rigid", beta_normal = 0.2, beta_tangential = -0.35,
                 # friction = inf (Coulomb coefficient), window = 1e-6 (s): contacts
                 # arriving within it are one impact (a flat landing)
    [walls]      # separation = 0.20 (m); no [walls] section: no walls
    [initial]    # x0 = 0, y0 = 0.1 (m), phi0 = 0 (rad), vx0 = vy0 = 0 (m/s), omega0 = 10 (rad/s)
    [effects]    # air_drag = 0 (1/m), com_offset = [0, 0] (m), speed_restitution = 0 (s/m),
                 # contact_time = 0 (s); all off
    [tracking]   # angle_offset = 0 (rad), time_scale = 1, length_scale = 1: how the tracker saw
                 # the die (measured drops only; the kernel ignores it)
    [world]      # g = 9.81 (m/s^2): the one source of g
    [scatter]    # corner = 0, flat = 0 (1): relative spread of each impact's velocity jump,
                 # corner_floor = 0, flat_floor = 0 (sqrt(g R)): its floor (all 0: the
                 # deterministic law), draws = 1 per start, seed = 0 (docs/physics.md)

The keys of [effects], [tracking] and [scatter] come from the effect registry (dice_sweep/effects.py).
    [integrator] # method = "event" | "fixed_step", dt = 0.001 (s), t_max = 30 (s), max_events
    [grid]       # x = { param, min, max, num }, y = { ... }; no [grid]: a single roll

Everything is checked at load, before any work; each problem is a :class:`ConfigError` whose
text is one line naming the file, the dotted key and the allowed range or values.
"""

import dataclasses
import difflib
import json
import math
import re
import tomllib
from dataclasses import dataclass, field

import numpy as np

from dice_sweep import effects as effect_registry
from dice_sweep import geometry
from dice_sweep.effects import MAX_DRAWS, MAX_SCATTER, MAX_SEED  # noqa: F401  ([scatter]'s ranges, declared in the registry)
from dice_sweep.errors import ConfigError
from dice_sweep.inputs import not_a_file

__all__ = [
    "Die",
    "Contact",
    "Walls",
    "Initial",
    "World",
    "Integrator",
    "Effects",
    "Tracking",
    "Scatter",
    "Axis",
    "Grid",
    "Config",
    "CONTACT_MODELS",
    "INTEGRATOR_METHODS",
    "GRID_PARAMS",
    "PARAM_UNITS",
    "PARAM_LONG_NAMES",
    "load_config",
    "parse_config",
    "require_grid",
    "check_computable",
    "cell_centres",
    "config_to_toml",
    "default_config",
]

CONTACT_MODELS = ("paper", "rigid")
INTEGRATOR_METHODS = ("event", "fixed_step")
GRID_PARAMS = ("y0", "omega0", "vx0", "vy0", "phi0", "x0")
PARAM_UNITS = {"x0": "m", "y0": "m", "phi0": "rad", "vx0": "m/s", "vy0": "m/s", "omega0": "rad/s"}
PARAM_LONG_NAMES = {  # what each parameter is, as sweep files describe their axes (docs/hdf5.md)
    "x0": "initial horizontal position of the die's centre",
    "y0": "initial height of the die's centre",
    "phi0": "initial angle of the die",
    "vx0": "initial horizontal velocity",
    "vy0": "initial vertical velocity",
    "omega0": "initial angular velocity",
}
TABLE1_CIRCUMRADIUS = 0.019 / math.sqrt(2.0)  # m, Table I: 1.9/sqrt(2) cm
MAX_SIDES = 127  # sides are stored as int8 (docs/hdf5.md): 0..126 and -1, -128 the fill
MAX_GRID_NUM = 100_000  # cells per axis; keeps the start check's arrays (and sweeps) finite
MIN_CIRCUMRADIUS = 1e-9  # m; a smaller die underflows its moment of inertia per R^2 (1e-308 divided by zero)
MAX_EVENTS = 2**62  # events (fixed_step: steps) of one roll; the kernel counts them in int64
# What a roll or sweep may ask of the kernel (issue 32, docs/physics.md "Limits of a roll"):
MAX_ROLL_WORK = 10**8  # events (fixed_step: steps, t_max / dt) one roll may take: a minute of a core at worst
MAX_TABLE_SPEED = 1000.0  # m/s, sqrt(vx0^2 + vy0^2 + (omega0 R)^2 + 2 g y0): far past any throw, well inside float64
# a start whose corner reaches this far into a surface still counts as touching it, not inside
TOUCH_TOLERANCE = 1e-12  # relative to the circumradius
# Contact window (s): a real die's contact lasts about 1e-4 s (docs/physics.md), and a window
# beyond 1e-3 s would merge bounces of a rocking die that are separate events
MAX_CONTACT_WINDOW = 1e-3
DEFAULT_CONTACT_WINDOW = 1e-6  # s; docs/physics.md, "Two contacts at once", says why


@dataclass(frozen=True)
class Die:
    """A regular n-gon plate: ``sides`` n (3..127) and ``circumradius`` R (m)."""

    sides: int
    circumradius: float


@dataclass(frozen=True)
class _ContactBase:
    model: str
    beta_normal: float
    beta_tangential: float
    friction: float
    window: float = DEFAULT_CONTACT_WINDOW


def _registry_fields(section):
    """(name, type, field) of every key the effect registry declares in ``section``, in order."""
    keys = effect_registry.config_key_specs().get(section, {}).values()
    return [(key.name, key.kind, field(default=key.default)) for key in keys]


def _with_registry_fields(base, name, section, doc, namespace=None):
    """A frozen dataclass ``name``: ``base``'s fields (None: none), then the registry's keys of
    ``section``, and ``namespace``'s methods. The registry (dice_sweep/effects.py) is the one
    place an effect's keys are declared; the section's dataclass is derived from it, so adding
    an effect adds no field here.
    """
    own = [(f.name, f.type, f) for f in dataclasses.fields(base)] if base is not None else []
    derived = dataclasses.make_dataclass(name, own + _registry_fields(section), frozen=True, namespace=namespace)
    derived.__module__ = __name__  # pickling (worker pools) finds it here, as a module global
    keys = effect_registry.config_key_specs().get(section, {}).values()
    derived.__doc__ = doc + (" Keys from the effect registry: " + "; ".join(
        f"``{key.name}`` ({key.described}){': ' + key.help if key.help else ''}" for key in keys
    ) + "." if keys else "")
    return derived


Contact = _with_registry_fields(
    _ContactBase, "Contact", "contact",
    """Contact law: ``model`` ("paper" or "rigid"), ``beta_normal`` in [0, 1],
    ``beta_tangential`` in [-1, 1], Coulomb ``friction`` coefficient in [0, inf] (inf: no cap),
    ``window`` (s) in [0, 1e-3]: contacts arriving within it are one impact.""",
)
Effects = _with_registry_fields(None, "Effects", "effects", "Optional physics, all off by default (docs/effects.md).")
Tracking = _with_registry_fields(
    None, "Tracking", "tracking", "How a tracker saw the die (measured drops only; the kernel does not read it)."
)


@dataclass(frozen=True)
class Walls:
    """Vertical walls at x = -separation/2 and +separation/2 (m); ``separation`` None: no walls."""

    separation: float | None


@dataclass(frozen=True)
class Initial:
    """Initial state: centre (x0, y0) in m, angle phi0 in rad, (vx0, vy0) in m/s, omega0 in rad/s."""

    x0: float
    y0: float
    phi0: float
    vx0: float
    vy0: float
    omega0: float


@dataclass(frozen=True)
class World:
    """Gravitational acceleration ``g`` (m/s^2)."""

    g: float


_SCATTER_LAW = effect_registry.noise_model("scattered_impacts")
Scatter = _with_registry_fields(
    None, "Scatter", "scatter",
    """The stochastic impact law (docs/physics.md, "Scattered impacts"); all spreads and floors
    0 is the deterministic law. ``on``: a spread or a floor above 0.""",
    # the registry's null values say when the law is on
    {"on": property(lambda self: _SCATTER_LAW.is_on(lambda key: getattr(self, key.partition(".")[2])))},
)


@dataclass(frozen=True)
class Integrator:
    """``method`` ("event" or "fixed_step"), step ``dt`` (s), time limit ``t_max`` (s), ``max_events``."""

    method: str
    dt: float
    t_max: float
    max_events: int


def cell_centres(lo: float, hi: float, cells: int) -> np.ndarray:
    """Centres ``lo + (i + 0.5) (hi - lo) / cells``, i = 0 .. cells-1, of equal cells covering
    [lo, hi]: the one formula of every grid's values (a sweep's axes, refinement's levels)."""
    return lo + (np.arange(cells) + 0.5) * (hi - lo) / cells


def require_grid(cfg):
    """``cfg.grid``, or the one-line error of a config without one (a sweep needs it)."""
    if cfg.grid is None:
        raise ConfigError(cfg.source, "grid", "missing; sweep needs a [grid] with x = {...} and y = {...} (use roll for one roll)")
    return cfg.grid


@dataclass(frozen=True)
class Axis:
    """One swept initial value: ``param`` from ``min`` to ``max`` (its SI unit) in ``num`` cells."""

    param: str
    min: float
    max: float
    num: int

    def values(self):
        """Cell-centre values ``min + (i + 0.5) (max - min) / num``, i = 0 .. num-1.

        Returns
        -------
        ndarray, shape (num,)
            The swept values, in the unit of ``param`` (see ``PARAM_UNITS``).
        """
        return cell_centres(self.min, self.max, self.num)


@dataclass(frozen=True)
class Grid:
    """A two-dimensional sweep: ``x`` (image columns) and ``y`` (image rows) axes."""

    x: Axis
    y: Axis


@dataclass(frozen=True)
class Config:
    """A validated config. ``source`` (the file path or "<string>") takes no part in equality."""

    die: Die
    contact: Contact
    walls: Walls
    initial: Initial
    world: World
    integrator: Integrator
    grid: Grid | None
    effects: Effects = None  # filled by the loader; None only for hand-built configs
    tracking: Tracking = Tracking()
    scatter: Scatter = Scatter()
    source: str = field(default="<string>", compare=False)

    def with_initial(self, **values):
        """Return a copy with some initial values replaced, e.g. ``cfg.with_initial(omega0=20.0)``.

        Parameters
        ----------
        **values : float
            New values of fields of :class:`Initial` (SI units).

        Returns
        -------
        Config
            The copy (not validated again).
        """
        return dataclasses.replace(self, initial=dataclasses.replace(self.initial, **values))


@dataclass(frozen=True)
class _Spec:
    """What one config key accepts: its Python type, default and allowed range or values."""

    kind: type  # float, int or str
    default: object = None  # None: the key is required
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False  # True: the value must be above ``low``, not equal to it
    choices: tuple = ()
    unit: str = ""
    allow_inf: bool = False  # +inf is a meaningful value (an uncapped friction)
    length: int = 0  # > 0: an array of this many numbers


def _positive(default, unit):
    return _Spec(float, default, low=0.0, low_open=True, unit=unit)


_SECTION_SPECS = {
    "die": {
        "sides": _Spec(int, 4, low=3, high=MAX_SIDES),
        "circumradius": _Spec(float, TABLE1_CIRCUMRADIUS, low=MIN_CIRCUMRADIUS, unit="m"),
    },
    "contact": {
        "model": _Spec(str, "paper", choices=CONTACT_MODELS),
        "beta_normal": _Spec(float, 0.2, low=0.0, high=1.0),
        "beta_tangential": _Spec(float, -0.35, low=-1.0, high=1.0),
        "friction": _Spec(float, math.inf, low=0.0, allow_inf=True),
        "window": _Spec(float, DEFAULT_CONTACT_WINDOW, low=0.0, high=MAX_CONTACT_WINDOW, unit="s"),
    },
    "walls": {"separation": _positive(0.20, "m")},
    "initial": {
        "x0": _Spec(float, 0.0, unit="m"),
        "y0": _Spec(float, 0.1, unit="m"),
        "phi0": _Spec(float, 0.0, unit="rad"),
        "vx0": _Spec(float, 0.0, unit="m/s"),
        "vy0": _Spec(float, 0.0, unit="m/s"),
        "omega0": _Spec(float, 10.0, unit="rad/s"),
    },
    # [effects], [tracking] and [scatter]: from the effect registry, below
    "world": {"g": _positive(9.81, "m/s^2")},
    "integrator": {
        "method": _Spec(str, "event", choices=INTEGRATOR_METHODS),
        "dt": _positive(0.001, "s"),
        "t_max": _positive(30.0, "s"),
        "max_events": _Spec(int, 100_000, low=1, high=MAX_EVENTS),
    },
    "scatter": {},  # from the registry's noise model, below; here for its place in written configs
}
for _section, _keys in effect_registry.config_key_specs().items():
    _SECTION_SPECS.setdefault(_section, {}).update({
        key.name: _Spec(str, key.default, choices=key.choices) if key.choices else
        _Spec(int if key.kind is int else float, key.default, low=key.low, high=key.high, low_open=key.low_open, unit=key.unit,
              length=key.length)
        for key in _keys.values()
    })
_SECTION_CLASSES = {
    "die": Die,
    "contact": Contact,
    "walls": Walls,
    "initial": Initial,
    "world": World,
    "integrator": Integrator,
    "effects": Effects,
    "tracking": Tracking,
    "scatter": Scatter,
}
_AXIS_SPECS = {
    "param": _Spec(str, choices=GRID_PARAMS),
    "min": _Spec(float),
    "max": _Spec(float),
    "num": _Spec(int, low=1, high=MAX_GRID_NUM),
}
_GRID_AXES = ("x", "y")
_SECTIONS = (*_SECTION_SPECS, "grid")
_TYPE_NAMES = {bool: "a boolean", int: "an integer", float: "a float", str: "a string", list: "an array", dict: "a table"}


def _children(parts):
    """Names allowed below the dotted key ``parts`` (a tuple), or None if it is a leaf key."""
    if not parts:
        return _SECTIONS
    if parts[0] == "grid":
        return (_GRID_AXES, tuple(_AXIS_SPECS), None)[min(len(parts) - 1, 2)]
    return tuple(_SECTION_SPECS[parts[0]]) if len(parts) == 1 else None


def _key_text(name):
    """A config key as it would be written in TOML (quoted when it is not a bare key)."""
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else json.dumps(name)


def _dotted(parts):
    return ".".join(_key_text(part) for part in parts)


def _fmt(number):
    return "inf" if number == math.inf else "-inf" if number == -math.inf else f"{number:g}"


def _unknown_name_message(name, allowed, what):
    """``unknown key 'x'; did you mean 'y'? (allowed: ...)``, the suggestion only when close."""
    message = f"unknown {what} {name!r}"
    close = difflib.get_close_matches(name, allowed, n=1)
    if close:
        message += f"; did you mean {close[0]!r}?"
    return f"{message} (allowed {what}s: {', '.join(allowed)})"


class _Checker:
    """Raises one-line :class:`ConfigError` s naming the file (and --set, if values came from it)."""

    def __init__(self, source, overridden):
        self.source = source
        # the error may come from the command line rather than from the file: say so
        self.label = f"{source} with --set" if overridden else source

    def error(self, key, message):
        """The ConfigError for a dotted key."""
        return ConfigError(self.label, key, message)

    def check_known(self, table, parts):
        """Refuse names in ``table`` (found at dotted key ``parts``) that the schema does not know."""
        allowed = _children(parts)
        for name in table:
            if name not in allowed:
                raise self.error(_dotted((*parts, name)), _unknown_name_message(name, allowed, "key" if parts else "section"))

    def table(self, parent, parts, required):
        """The sub-table at ``parts`` (a section or grid axis), None when absent and optional."""
        value = parent.get(parts[-1])
        if value is None:
            if required:
                example = ", ".join(f"{name} = ..." for name in _children(parts))
                raise self.error(_dotted(parts), f"missing; required as {parts[-1]} = {{ {example} }}")
            return None
        if not isinstance(value, dict):
            raise self.error(_dotted(parts), f"expected a table, got {_type_name(value)} {value!r}")
        self.check_known(value, parts)
        return value

    def values(self, table, parts, specs):
        """Checked and converted values of every key of a section, defaults filled in."""
        result = {}
        for name, spec in specs.items():
            key = _dotted((*parts, name))
            if name not in table:
                if spec.default is None:
                    raise self.error(key, f"missing; required ({_allowed(spec)})")
                result[name] = spec.default
            else:
                result[name] = self.value(table[name], key, spec)
        return result

    def value(self, value, key, spec):
        """Check one value against its spec; return it converted (int -> float for float keys)."""
        if spec.length:
            if not isinstance(value, list) or len(value) != spec.length:
                raise self.error(key, f"expected an array of {spec.length} numbers, got {_type_name(value)} {value!r} ({_allowed(spec)})")
            item_spec = dataclasses.replace(spec, length=0)
            return tuple(self.value(item, key, item_spec) for item in value)
        if spec.kind is str:
            if not isinstance(value, str):
                raise self.error(key, f"expected a string, got {_type_name(value)} {value!r} ({_allowed(spec)})")
            if spec.choices and value not in spec.choices:
                raise self.error(key, _unknown_name_message(value, spec.choices, "value"))
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (spec.kind is int and isinstance(value, float)):
            expected = "an integer" if spec.kind is int else "a number"
            raise self.error(key, f"expected {expected}, got {_type_name(value)} {value!r} ({_allowed(spec)})")
        try:
            value = spec.kind(value)
        except OverflowError:  # an integer too large for a float
            value = math.inf
        if not math.isfinite(value) and not (spec.allow_inf and value == math.inf):
            raise self.error(key, f"{value!r} is not a finite number ({_allowed(spec)})")
        below = value <= spec.low if spec.low_open else value < spec.low
        if below or value > spec.high:
            raise self.error(key, f"{value!r} is outside the {_allowed(spec)}")
        return value


def _type_name(value):
    return _TYPE_NAMES.get(type(value), type(value).__name__)


def _allowed(spec):
    """The allowed range or values of a spec, for messages: ``allowed range [0, 1]``."""
    if spec.choices:
        return "allowed values: " + ", ".join(spec.choices)
    if spec.kind is str:
        return "allowed: a string"
    interval = f"{'(' if spec.low_open or spec.low == -math.inf else '['}{_fmt(spec.low)}, {_fmt(spec.high)}"
    interval += "]" if spec.high < math.inf or spec.allow_inf else ")"
    kind = ", an integer" if spec.kind is int else f", {spec.length} numbers" if spec.length else ""
    return f"allowed range {interval}{' ' + spec.unit if spec.unit else ''}{kind}"


def _parse_toml(text, source):
    """Parse TOML text; a syntax error becomes a ConfigError naming the line."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        where = re.search(r"\(at line (\d+), column \d+\)$", str(error))
        key = f"line {where.group(1)}" if where else "end of file"
        raise ConfigError(source, key, f"TOML syntax error: {error}") from None


def _parse_override_value(text):
    """A ``--set`` value as a TOML value (0.3, 4, "event", [1, 2], true), else a bare string."""
    try:
        parsed = tomllib.loads(f"value = {text}")
    except tomllib.TOMLDecodeError:
        return text
    # text with a newline could define more keys than the one value: keep it as it is
    return parsed["value"] if len(parsed) == 1 else text


def _apply_overrides(raw, overrides):
    """Apply ``section.key=value`` strings to the raw TOML dict, in place."""
    for override in overrides:
        dotted, equals, value_text = override.partition("=")
        dotted = dotted.strip()
        if not equals:
            raise ConfigError("--set", dotted, f"expected section.key=value, got {override!r} (e.g. --set initial.omega0=20)")
        parts = tuple(part.strip() for part in dotted.split("."))
        for depth, name in enumerate(parts):
            allowed = _children(parts[:depth])
            if allowed is None:
                raise ConfigError("--set", dotted, f"{_dotted(parts[:depth])} is a value, not a table (expected section.key=value)")
            if name not in allowed:
                raise ConfigError("--set", dotted, _unknown_name_message(name, allowed, "key" if depth else "section"))
        if len(parts) < 2:
            raise ConfigError("--set", dotted, "a whole section cannot be set; use section.key=value")
        table = raw
        for name in parts[:-1]:
            table = table.setdefault(name, {})
            if not isinstance(table, dict):
                raise ConfigError("--set", dotted, f"{name!r} in the file is not a table")
        table[parts[-1]] = _parse_override_value(value_text.strip())


def _grid(raw_grid, checker):
    """The [grid] section as a Grid (None if absent), axes checked."""
    if raw_grid is None:
        return None
    axes = {}
    for name in _GRID_AXES:
        table = checker.table(raw_grid, ("grid", name), required=True)
        values = checker.values(table, ("grid", name), _AXIS_SPECS)
        if values["min"] >= values["max"]:
            raise checker.error(f"grid.{name}.max", f"{values['max']!r} is not above min = {values['min']!r} (allowed range: max > min)")
        axis = Axis(**values)
        centres = axis.values()
        if not (np.isfinite(centres).all() and np.all(np.diff(centres) > 0)):
            raise checker.error(f"grid.{name}", f"the {axis.num} cell centres from min = {axis.min!r} to max = {axis.max!r} are not "
                                "finite, distinct numbers (allowed: max - min finite, below 1.8e308, and cells wider than the "
                                "spacing of floats)")
        axes[name] = axis
    if axes["x"].param == axes["y"].param:
        others = [param for param in GRID_PARAMS if param != axes["x"].param]
        raise checker.error("grid.y.param", f"{axes['y'].param!r} is already swept by grid.x (allowed values: {', '.join(others)})")
    return Grid(**axes)


def _start_values(initial, grid):
    """For x0, y0, phi0: (dotted key, 1-D array of every start value) over the grid if swept."""
    starts = {param: (f"initial.{param}", np.array([getattr(initial, param)])) for param in ("x0", "y0", "phi0")}
    for name in _GRID_AXES if grid is not None else ():
        axis = getattr(grid, name)
        if axis.param in starts:
            starts[axis.param] = (f"grid.{name}", axis.values())
    return starts


def _first_overlap(clearance, reach, tolerance):
    """First (i, j) with reach[j] > clearance[i] (a corner through a surface), or None."""
    blocked = np.flatnonzero(clearance < reach.max() - tolerance)
    if blocked.size == 0:
        return None
    i = blocked[0]
    return i, np.flatnonzero(reach > clearance[i] + tolerance)[0]


def _check_starts_clear(die, walls, initial, grid, corner_radius, checker):
    """Refuse any start (the initial state or any grid point) with a corner inside a surface.
    A rounded die (``corner_radius`` r > 0, m) reaches as far as the kernel's arcs, less far
    than its sharp corners."""
    starts = _start_values(initial, grid)
    phi_key, phi = starts["phi0"]

    def reach(direction, angle=phi):
        return geometry.support(die.sides, die.circumradius, angle, direction, corner_radius)

    surfaces = [("y0", "the table", starts["y0"][1], reach(geometry.DOWN))]
    if walls.separation is not None:
        half = 0.5 * walls.separation
        x = starts["x0"][1]
        surfaces += [("x0", "the right wall", half - x, reach(0.0)), ("x0", "the left wall", half + x, reach(np.pi))]
    tolerance = TOUCH_TOLERANCE * die.circumradius
    overlaps = [
        (param, surface, clearance, reach_along, *found)
        for param, surface, clearance, reach_along in surfaces
        if (found := _first_overlap(clearance, reach_along, tolerance)) is not None
    ]
    if not overlaps:
        return
    # the table first, then the first offending grid value, whichever wall it meets
    param, surface, clearance, reach_along, i, j = min(overlaps, key=lambda overlap: (overlap[0] != "y0", overlap[4]))
    position_key, position = starts[param]
    if param == "y0":
        allowed = f"y0 >= {_fmt(reach_along[j])} m"
    else:
        allowed = f"{_fmt(reach(np.pi, phi[j]) - half)} <= x0 <= {_fmt(half - reach(0.0, phi[j]))} m"
    # name the grid axis that holds the offending value, if any, since that is what to change
    key = position_key if position_key.startswith("grid.") or not phi_key.startswith("grid.") else phi_key
    raise checker.error(
        key,
        f"the start {param} = {position[i]:.10g} m, phi0 = {phi[j]:.10g} rad puts a corner "
        f"{_fmt(reach_along[j] - clearance[i])} m into {surface} (allowed range at this phi0: {allowed})",
    )


def _legacy_gravity(raw, checker):
    """``[effects] gravity`` is gone (g has one source, ``[world] g``). Files written before
    that hold ``gravity = 0.0`` (off), which still reads; any other value is an error."""
    effects = raw.get("effects")
    if not isinstance(effects, dict) or "gravity" not in effects:
        return
    if effects["gravity"] == 0:
        del effects["gravity"]
        return
    raise checker.error("effects.gravity", f"{effects['gravity']!r} is no longer a key: g has one source (allowed: [world] g = {effects['gravity']!r})")


def _build(raw, checker):
    """Check the raw TOML dict section by section and build the Config."""
    _legacy_gravity(raw, checker)
    checker.check_known(raw, ())
    sections = {}
    for name, specs in _SECTION_SPECS.items():
        table = checker.table(raw, (name,), required=False)
        if name == "walls" and table is None:
            sections[name] = Walls(separation=None)
            continue
        sections[name] = _SECTION_CLASSES[name](**checker.values(table or {}, (name,), specs))
    die, walls = sections["die"], sections["walls"]
    if walls.separation is not None and walls.separation <= 2.0 * die.circumradius:
        wider = dataclasses.replace(_SECTION_SPECS["walls"]["separation"], low=2.0 * die.circumradius)
        raise checker.error("walls.separation", f"{walls.separation!r} is outside the {_allowed(wider)} (more than twice the circumradius)")
    partial = Config(**sections, grid=None, source=checker.source)
    for keys in effect_registry.config_key_specs().values():
        for key in keys.values():
            allowed = key.check(partial) if key.check is not None else None
            if allowed is not None:
                raise checker.error(key.dotted, f"{effect_registry.get_key(partial, key.dotted)!r} is outside the {allowed}")
    grid = _grid(checker.table(raw, ("grid",), required=False), checker)
    _check_starts_clear(die, walls, sections["initial"], grid, sections["effects"].corner_radius, checker)
    return Config(**sections, grid=grid, source=checker.source)


def parse_config(text, source="<string>", overrides=()):
    """Parse and validate a TOML config given as text.

    Parameters
    ----------
    text : str
        The TOML text.
    source : str
        Where the text came from, named in error messages.
    overrides : sequence of str
        ``section.key=value`` strings (``grid.x.num=64`` for grid axes), applied before
        validation. The value is read as TOML, or as a bare string if that fails.

    Returns
    -------
    Config
        The validated config, defaults (Table I of the paper) filled in.

    Raises
    ------
    ConfigError
        On a TOML syntax error, a malformed override or any invalid value.
    """
    source = str(source)
    raw = _parse_toml(text, source)
    _apply_overrides(raw, overrides)
    return _build(raw, _Checker(source, overridden=bool(overrides)))


def check_initial_clear(cfg, overrides=()):
    """Refuse a config whose [initial] state has a corner inside a surface, for commands that
    start from it alone (`roll`): with a [grid], loading checks the swept starts, and a value
    the grid replaces may be anything (fig08 with initial.y0 = -1 rolled "side 3 after 0
    impacts", exit 0)."""
    _check_starts_clear(cfg.die, cfg.walls, cfg.initial, None, cfg.effects.corner_radius, _Checker(cfg.source, bool(overrides)))


def _extreme(cfg, param):
    """The largest |value| a roll of ``cfg`` starts from: its [initial] value, or the swept range's end."""
    grid = cfg.grid
    for axis in (grid.x, grid.y) if grid is not None else ():
        if axis.param == param:
            return f"grid.{'x' if axis is grid.x else 'y'}", max(abs(axis.min), abs(axis.max))
    return f"initial.{param}", abs(getattr(cfg.initial, param))


def check_computable(cfg, overrides=()):
    """Refuse, before any roll, a config the kernel cannot compute in reasonable time or in
    float64 (issue 32): a roll budget beyond :data:`MAX_ROLL_WORK` events or steps (fixed_step
    rolls t_max / dt steps; dt = 1e-12 never ended), or a start whose speed at the table,
    sqrt(vx0^2 + vy0^2 + (omega0 R)^2 + 2 g y0), exceeds :data:`MAX_TABLE_SPEED` (vx0 = 1e200
    answered with t_end = NaN). Swept values count at their largest."""
    checker = _Checker(cfg.source, bool(overrides))
    integrator = cfg.integrator
    steps = integrator.t_max / integrator.dt if integrator.method == "fixed_step" else 0.0
    if max(integrator.max_events, steps) > MAX_ROLL_WORK:
        key, what = ("integrator.dt", f"t_max / dt = {steps:.3g} steps") if steps > integrator.max_events else \
            ("integrator.max_events", f"{integrator.max_events} events")
        raise checker.error(key, f"{what} per roll is more work than a roll may take (allowed: at most {MAX_ROLL_WORK:.0e} events "
                                 "or steps per roll, MAX_ROLL_WORK)")
    radius, g = cfg.die.circumradius, cfg.world.g
    parts = {param: _extreme(cfg, param) for param in ("vx0", "vy0", "omega0", "y0")}
    speeds = {"vx0": parts["vx0"][1], "vy0": parts["vy0"][1], "omega0": parts["omega0"][1] * radius,
              "y0": math.sqrt(2.0 * g * parts["y0"][1]) if parts["y0"][1] < 1e300 / g else math.inf}
    speed = math.hypot(*speeds.values())
    if not speed <= MAX_TABLE_SPEED:
        param = max(speeds, key=speeds.get)
        key, value = parts[param]
        raise checker.error(key, f"{param} up to {value:g} {PARAM_UNITS[param]} starts the die at {speed:.3g} m/s at the table "
                                 f"(allowed: sqrt(vx0^2 + vy0^2 + (omega0 R)^2 + 2 g y0) at most {MAX_TABLE_SPEED:g} m/s, MAX_TABLE_SPEED)")


def load_config(path, overrides=()):
    """Read, parse and validate a TOML config file.

    Parameters
    ----------
    path : str or os.PathLike
        The config file.
    overrides : sequence of str
        ``section.key=value`` strings, as for :func:`parse_config`.

    Returns
    -------
    Config
        The validated config; ``source`` is ``str(path)``.

    Raises
    ------
    ConfigError
        If the file cannot be read or the config is invalid.
    """
    problem = not_a_file(path)  # a FIFO or /dev/zero would hang the reader
    if problem:
        raise ConfigError(path, "file", problem)
    try:
        with open(path, encoding="utf-8") as file:
            text = file.read()
    except OSError as error:
        raise ConfigError(path, "file", f"cannot read the config: {error.strerror or error}") from None
    except UnicodeDecodeError as error:
        raise ConfigError(path, "file", f"not UTF-8 text: {error.reason} at byte {error.start}") from None
    return parse_config(text, str(path), overrides)


def default_config():
    """The default config: Table I of Smith 2014, no walls, no grid.

    Returns
    -------
    Config
        Same as ``parse_config("")``.
    """
    return parse_config("", source="<defaults>")


def _toml_value(value):
    """One TOML value: repr for floats (round-trips exactly), JSON quoting for strings."""
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml_value(item) for item in value) + "]"
    if isinstance(value, Axis):
        items = (f"{name} = {_toml_value(getattr(value, name))}" for name in _AXIS_SPECS)
        return "{ " + ", ".join(items) + " }"
    return repr(value)


def config_to_toml(cfg):
    """Write the fully resolved config (every key) as TOML text.

    ``parse_config(config_to_toml(cfg)) == cfg`` holds for every valid config.

    Parameters
    ----------
    cfg : Config
        A validated config.

    Returns
    -------
    str
        TOML text; no [walls] without walls, no [grid] without a grid.
    """
    lines = []
    for name in _SECTIONS:
        section = getattr(cfg, name)
        # no [walls]: no walls; no [scatter]: the deterministic law (files as before it existed)
        if section is None or section == Walls(separation=None) or section == Scatter():
            continue
        lines.append(f"[{name}]")
        lines += [f"{item.name} = {_toml_value(getattr(section, item.name))}" for item in dataclasses.fields(section)]
        lines.append("")
    return "\n".join(lines)

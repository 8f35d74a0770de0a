"""The effect registry: every effect the measured-data loop can add, declared once.

An *effect* is a piece of physics (or of measurement) that a declared model may lack. Each
entry says what it is called, which config keys switch it on (with units and the values the
config accepts), which parameters a fit frees (bounds, the null value at which the effect
does nothing, start values, a typical size), how it reaches the kernel (through the config's
keys; measurement effects act on the comparison with the tracks instead) and which residual
signature points to it. Config validation (``[effects]`` and ``[tracking]`` keys), the fit,
the diagnosis, the CLI help and the docs read from here; docs/dev/adding.md walks through adding
one.

Kinds:

* ``contact``: changes what happens at an impact;
* ``flight``: acts between impacts (and so also on the states the fit gives each flight);
* ``measurement``: the tracker's view of the die (clock, scale, angle zero), not the die;
* ``noise``: a random law around the deterministic one (``NOISE_MODELS``, not ``EFFECTS``):
  its spreads are estimated from residuals' sizes, not fitted by least squares, so the fit and
  the diagnosis never take it as a candidate; config, kernel slots and docs read it as any entry.

There is one source of g: ``[world] g``; the ``gravity`` effect frees it.
"""

import dataclasses
import math
from dataclasses import dataclass

__all__ = ["ConfigKey", "Param", "Effect", "EFFECTS", "NOISE_MODELS", "BASE_PARAMS", "effect", "noise_model", "config_key_specs",
           "set_key", "get_key", "declared_effects", "with_values", "param", "names", "MAX_SCATTER", "MAX_DRAWS", "MAX_SEED",
           "MAX_POWER", "MAX_TAIL_FACTOR", "MAX_SPIN", "SCATTER_KINDS", "SCATTER_SHAPE", "scatter_spread_keys", "scatter_law_keys"]

MAX_SCATTER = 1.0  # relative spread of an impact's velocity jump: beyond 1 the jump exceeds the approach
MAX_DRAWS = 4096  # draws per start of a stochastic sweep
MAX_SEED = 2**53 - 1  # the kernel keeps the seed in a float64 slot, exact below 2^53
MAX_TAIL_FACTOR = 10.0  # the wide jumps' sd over the law's: 10 already reaches the approach speed at every real impact
MAX_SPIN = 5.0  # the spin component's sd over the other two's
MAX_POWER = 4.0  # the scatter's power of the approach speed: u^4 at sqrt(g R) ... 5 sqrt(g R) spans 600x, wider than any drop


@dataclass(frozen=True)
class ConfigKey:
    """A config key an effect owns: ``section.name`` with its default, range and unit.

    ``slot`` names the kernel parameter it fills (an ``fpar`` index constant ``FP_*``, or an
    ``ipar`` one ``IP_*`` for a choice, packed as the index of the value in ``choices``); an
    array key fills ``length`` consecutive slots from there. Empty: the kernel does not read
    the key itself (a measurement key, or one that enters a derived slot, as inertia enters
    FP_INERTIA). ``help`` is its text in docs and config docstrings. A key whose default is
    an int takes whole numbers. ``scale``: callable(cfg) -> the factor from the key's unit to
    the slot's SI one (a key in the die's own units, as sqrt(g R)); None: packed as it is.
    """

    section: str
    name: str
    default: object
    unit: str
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    length: int = 0  # > 0: an array of this many numbers
    choices: tuple = ()  # a string key: the values it accepts
    slot: str = ""
    help: str = ""
    # a range that depends on the die: callable(cfg) -> None when the value fits, else the
    # allowed range as text; config validation calls it once every section is read
    check: object = None
    scale: object = None

    @property
    def dotted(self):
        return f"{self.section}.{self.name}"

    @property
    def kind(self):
        """The Python type of its values: str (a choice), tuple (an array), int or float."""
        return str if self.choices else tuple if self.length else int if isinstance(self.default, int) else float

    @property
    def described(self):
        """Its unit, else its choices, else its type's name, for help texts."""
        return self.unit or "|".join(self.choices) or self.kind.__name__

    def packed(self, cfg, value):
        """``value`` of this key as its kernel slot holds it (``scale``d to SI)."""
        return value if self.scale is None else value * self.scale(cfg)


@dataclass(frozen=True)
class Param:
    """A fitted parameter.

    ``key`` is where it lives in a config (``section.name`` or ``section.name[i]``); ``bounds``
    maps a config to the (low, high) the fit may use; ``null`` is the value at which its
    effect does nothing (a callable of the config when it is the config's own value, as for g);
    ``starts`` are the start values of a multi-start fit; ``scale`` is a typical size (finite
    differences, printing).
    """

    name: str
    unit: str
    key: str
    bounds: object  # callable(cfg) -> (low, high)
    null: object  # float or callable(cfg) -> float
    starts: tuple
    scale: float

    def null_value(self, cfg):
        return float(self.null(cfg)) if callable(self.null) else float(self.null)

    def starts_of(self, cfg):
        """Start values (a callable of the config where they are relative to it, as for g)."""
        return tuple(self.starts(cfg)) if callable(self.starts) else tuple(self.starts)

    def bounds_of(self, cfg):
        low, high = self.bounds(cfg)
        return float(low), float(high)


@dataclass(frozen=True)
class Measurement:
    """How a measurement effect maps the die's true motion to what the tracker reports, for a
    parameter value v: ``times_to_true(t_file, v)``, ``state_to_true(states_file, v)`` (an
    (n, 6) array of x, y, phi, vx, vy, omega, returned as a new array) and
    ``pose_to_file(poses_true, v)`` ((rows, 3), returned as a new array). The fit applies the
    measurement effects file -> true in reverse registry order, and true -> file in registry
    order."""

    times_to_true: object = None
    state_to_true: object = None
    pose_to_file: object = None


def _scaled(columns, factor_of):
    """A map multiplying ``columns`` of an array by factor_of(v)."""
    def apply(array, value):
        out = array.astype(float)  # a copy (numpy arrays; numpy is not imported here, for a fast --help)
        out[:, columns] *= factor_of(value)
        return out
    return apply


def _shifted(column, sign):
    def apply(array, value):
        out = array.astype(float)
        out[:, column] += sign * value
        return out
    return apply


@dataclass(frozen=True)
class Effect:
    """One effect: its name, kind, parameters, config keys, switch, measurement map and
    residual signature."""

    name: str
    kind: str  # "contact", "flight", "measurement" or "noise"
    summary: str
    params: tuple = ()
    config_keys: tuple = ()  # ConfigKey entries this effect adds to the config schema
    switch: tuple = ()  # ((key, value), ...) set when the effect is added, e.g. contact.model = rigid
    measurement: Measurement = None  # measurement effects: how the tracker maps the motion
    # effects no motion can tell from this one (the loop names them together)
    equivalent: tuple = ()
    signature: str = ""  # the residual signature (diagnose) that points to this effect
    signature_note: str = ""
    # effects without which this one changes little (friction caps only the rigid law; a
    # friction rule matters only where friction caps): the loop fits such pairs together
    acts_with: tuple = ()
    # base parameters the model no longer has once this effect is on (the exact Coulomb
    # impact has no tangential restitution): a fit does not free them
    drops: tuple = ()

    def is_declared(self, cfg):
        """Whether a config already has this effect on (it is then not a candidate)."""
        return self.is_on(lambda key: get_key(cfg, key), cfg)

    def is_on(self, value_of, cfg=None):
        """Whether the values ``value_of(key)`` switch this effect on (a param off its null)."""
        if self.switch:  # the last pair is the one that tells this effect (the first may be shared)
            key, value = self.switch[-1]
            return value_of(key) == value
        return any(value_of(p.key) != p.null_value(cfg) for p in self.params)


def _uniform_inertia_ratio(sides):
    """Eq. 25: I / (M R^2) of a uniform regular n-gon plate about its centre (geometry's, imported
    here on use: this module is read for a fast --help, before numpy)."""
    from dice_sweep.geometry import inertia_ratio

    return float(inertia_ratio(sides))


def _apothem(cfg):
    return cfg.die.circumradius * math.cos(math.pi / cfg.die.sides)


def _inertia_allowed(cfg):
    """None if [effects] inertia fits the die: at most all the mass at the corners, and some
    inertia left about a loaded die's centre of mass; else the allowed range."""
    ratio = _uniform_inertia_ratio(cfg.die.sides)
    low = (cfg.effects.com_offset[0] ** 2 + cfg.effects.com_offset[1] ** 2) / (ratio * cfg.die.circumradius**2)
    if low < cfg.effects.inertia <= 1.0 / ratio:
        return None
    return f"allowed range ({low:.6g}, {1.0 / ratio:.6g}] for this die (above: more than all the mass at the corners; below: none about the centre of mass)"


def _com_offset_allowed(cfg):
    """None if a loaded die's centre of mass lies inside its inscribed circle; else the range."""
    dx, dy = cfg.effects.com_offset
    apothem = _apothem(cfg)
    return None if math.hypot(dx, dy) < apothem else f"allowed range |offset| < apothem = {apothem:.6g} m (inside the die)"


def _corner_radius_allowed(cfg):
    """None if [effects] corner_radius is below the apothem; else the allowed range."""
    apothem = _apothem(cfg)
    return None if cfg.effects.corner_radius < apothem else f"allowed range [0, {apothem:.6g}) m (below the apothem)"


def _fixed(low, high):
    return lambda cfg: (low, high)


def _declared_g(cfg):
    return cfg.world.g


FRICTION_RULES = ("aimed", "sliding", "exact")  # contact.friction_rule; index = the kernel's code
RESTITUTION_LAWS = ("newton", "energetic")  # contact.restitution; index = the kernel's code

# beta_normal and beta_tangential are freed in every fit: the declared model's own parameters
BASE_PARAMS = (
    Param("beta_normal", "1", "contact.beta_normal", _fixed(0.0, 1.0), math.nan, (), 0.1),
    Param("beta_tangential", "1", "contact.beta_tangential", _fixed(-1.0, 1.0), math.nan, (), 0.1),
)

EFFECTS = (
    Effect(
        "corner_impulse", "contact",
        "the impulse acts at the touching corner (the rigid law) instead of the paper's lever R below the centre",
        switch=(("contact.model", "rigid"),),
        signature="impact_prediction",
        signature_note="frames predicted through an impact miss by more than the flights the states were fitted to",
    ),
    Effect(
        "coulomb_friction", "contact",
        "the tangential impulse is capped at friction times the normal impulse (sliding contacts)",
        params=(Param("friction", "1", "contact.friction", _fixed(0.0, 3.0), math.inf, (0.1, 0.5), 0.1),),
        acts_with=("corner_impulse",),
        signature="impact_prediction",
        signature_note="frames predicted through an impact miss (sliding contacts: the horizontal motion after it)",
    ),
    Effect(
        "air_drag", "flight", "quadratic air drag on the centre of mass, a = -c |v| v",
        params=(Param("air_drag", "1/m", "effects.air_drag", _fixed(0.0, 5.0), 0.0, (0.05, 0.5), 0.05),),
        config_keys=(ConfigKey("effects", "air_drag", 0.0, "1/m", low=0.0, slot="FP_DRAG"),),
        signature="flight_deceleration",
        signature_note="median deceleration of the speed along the motion left in free flight",
    ),
    Effect(
        "com_offset", "flight", "a loaded die: the centre of mass sits (dx, dy) from the geometric centre, body frame",
        params=(
            Param("com_dx", "m", "effects.com_offset[0]", lambda cfg: (-0.5 * _apothem(cfg), 0.5 * _apothem(cfg)), 0.0, (0.002, -0.002), 1e-3),
            Param("com_dy", "m", "effects.com_offset[1]", lambda cfg: (-0.5 * _apothem(cfg), 0.5 * _apothem(cfg)), 0.0, (0.002, -0.002), 1e-3),
        ),
        config_keys=(ConfigKey("effects", "com_offset", (0.0, 0.0), "m", length=2, slot="FP_COM_X", check=_com_offset_allowed),),
        signature="flight_wobble_at_spin",
        signature_note="amplitude of the free-flight residual of the centre at the spin angle (cos phi, sin phi)",
    ),
    Effect(
        "speed_restitution", "contact", "restitution that falls with impact speed, beta_normal / (1 + k |u_n|)",
        params=(Param("speed_restitution", "s/m", "effects.speed_restitution", _fixed(0.0, 5.0), 0.0, (0.2, 1.0), 0.1),),
        config_keys=(ConfigKey("effects", "speed_restitution", 0.0, "s/m", low=0.0, slot="FP_KSR"),),
        signature="impact_prediction",
        signature_note="frames predicted through an impact miss, more after fast impacts than after slow ones",
    ),
    Effect(
        "flat_landing", "contact",
        "a second corner arriving within the contact time after the first shares the impact: the two-contact impulse "
        "takes the share 1 - delay / contact_time, the first corner's alone the rest",
        params=(Param("contact_time", "s", "effects.contact_time", _fixed(0.0, 1e-3), 0.0, (1e-4, 3e-4, 9e-4), 1e-5),),
        config_keys=(ConfigKey("effects", "contact_time", 0.0, "s", low=0.0, high=1e-3, slot="FP_CONTACT_TIME"),),
        signature="impact_prediction",
        signature_note="frames predicted through an impact miss, more after landings near flat than after tilted ones",
    ),
    Effect(
        "inertia", "contact",
        "the moment of inertia about the centre of mass is a factor times the uniform plate's (eq. 25): a die with pips, "
        "a hollow or a plated die; it acts at impacts and in pivots (free flight conserves the spin either way)",
        params=(Param("inertia", "1", "effects.inertia", lambda cfg: (0.3, min(2.0, 0.999 / _uniform_inertia_ratio(cfg.die.sides))), 1.0, (0.9, 1.1), 0.05),),
        config_keys=(ConfigKey("effects", "inertia", 1.0, "1", low=0.0, low_open=True, high=3.0, check=_inertia_allowed,
                               help="I_com / (M R^2) over eq. 25's value; at most 1 / eq. 25's ratio (all mass at the corners)"),),
        signature="impact_prediction",
        signature_note="frames predicted through an impact miss: the spin after an impact off in proportion to the lever",
    ),
    Effect(
        "sliding_friction", "contact",
        "the rigid law's Coulomb cap takes the textbook sliding branch: a capped tangential impulse opposes the incoming slip "
        "(instead of lying on the side of the impulse aimed at the restitution target)",
        switch=(("contact.model", "rigid"), ("contact.friction_rule", "sliding")),
        acts_with=("coulomb_friction",),
        config_keys=(
            ConfigKey("contact", "friction_rule", "aimed", "", choices=FRICTION_RULES, slot="IP_FRICTION_RULE",
                      help="how the rigid law meets the Coulomb cap: aimed (the cone's edge on the side of the aimed impulse), "
                           "sliding (opposing the incoming slip), exact (Routh's integration over the impact)"),
        ),
        signature="impact_prediction",
        signature_note="frames predicted through an impact miss after sliding impacts whose slip the normal impulse reverses",
    ),
    Effect(
        "exact_coulomb", "contact",
        "the exact Coulomb impact at the touching corner(s): the contact velocity integrated over the normal impulse "
        "(Routh's method) with slip, stick and slip reversal, Newton or energetic restitution ([contact] restitution); "
        "no tangential restitution; two contacts at once integrated with equal contact springs (docs/physics.md, \"Friction rules\")",
        switch=(("contact.model", "rigid"), ("contact.friction_rule", "exact")),
        config_keys=(
            ConfigKey("contact", "restitution", "newton", "", choices=RESTITUTION_LAWS, slot="IP_RESTITUTION",
                      help="restitution of the exact impact: newton (kinematic, u_n' = -beta_normal u_n) or energetic "
                           "(Stronge: the restitution phase's work is beta_normal^2 the compression's)"),
        ),
        acts_with=("coulomb_friction",),
        drops=("beta_tangential",),
        signature="impact_prediction",
        signature_note="frames predicted through an impact miss after impacts that stick or reverse their slip",
    ),
    Effect(
        "rounded_corners", "contact",
        "corners rounded to radius r (the sides keep the apothem): contact on the arc below its centre, so the lever, "
        "the rolling pivot and the barrier of each side change",
        params=(Param("corner_radius", "m", "effects.corner_radius", lambda cfg: (0.0, 0.5 * _apothem(cfg)), 0.0,
                      lambda cfg: (0.03 * cfg.die.circumradius, 0.1 * cfg.die.circumradius), 1e-3),),
        config_keys=(ConfigKey("effects", "corner_radius", 0.0, "m", low=0.0, slot="FP_CORNER_RADIUS", check=_corner_radius_allowed,
                               help="radius of the rounded corners; below the apothem"),),
        signature="impact_prediction",
        signature_note="frames predicted through an impact miss: impacts a little later and lower, with a shorter lever",
    ),
    Effect(
        "gravity", "flight", "the acceleration of free fall differs from the declared [world] g",
        params=(Param("g", "m/s^2", "world.g", lambda cfg: (0.5 * cfg.world.g, 1.5 * cfg.world.g), _declared_g,
                      lambda cfg: (0.96 * cfg.world.g, 1.04 * cfg.world.g), 0.1),),
        signature="flight_vertical_curvature",
        signature_note="median extra vertical acceleration in free flight, the same for every track",
        # sqrt(R/g) is the only time scale of the model (restitution, friction and quadratic
        # drag are scale-free; only speed_restitution's k carries one): a clock off by s
        # looks exactly like g / s^2 (tests/measured/test_diagnose.py found each named as the other)
        equivalent=("time_scale",),
    ),
    Effect(
        "angle_offset", "measurement", "the tracker's angle zero is off: file phi = phi + offset",
        params=(Param("angle_offset", "rad", "tracking.angle_offset", _fixed(-0.5, 0.5), 0.0, (0.02, -0.02), 0.01),),
        config_keys=(ConfigKey("tracking", "angle_offset", 0.0, "rad", low=-math.pi, high=math.pi),),
        measurement=Measurement(state_to_true=_shifted(2, -1.0), pose_to_file=_shifted(2, +1.0)),
        signature="impact_prediction",
        signature_note="frames predicted through an impact miss: the corner that touches is not where the tracked angle puts it",
    ),
    Effect(
        "time_scale", "measurement",
        "the tracker's clock runs off: file t = time_scale * true t (a frame rate that is not the stated one)",
        params=(Param("time_scale", "1", "tracking.time_scale", _fixed(0.8, 1.25), 1.0, (0.98, 1.02), 0.01),),
        config_keys=(ConfigKey("tracking", "time_scale", 1.0, "1", low=0.0, low_open=True),),
        # file t = s t: true time is t / s, true velocities s times the file's
        measurement=Measurement(times_to_true=lambda t, s: t / s, state_to_true=_scaled([3, 4, 5], lambda s: s)),
        signature="flight_vertical_curvature",
        signature_note="free-flight curvature off g by the same factor for every track, with the die's size right at contact",
        equivalent=("gravity",),
    ),
    Effect(
        "length_scale", "measurement",
        "the tracker's length scale is off: file x, y = length_scale * true x, y (angles unchanged)",
        params=(Param("length_scale", "1", "tracking.length_scale", _fixed(0.8, 1.25), 1.0, (0.97, 1.03), 0.01),),
        config_keys=(ConfigKey("tracking", "length_scale", 1.0, "1", low=0.0, low_open=True),),
        measurement=Measurement(state_to_true=_scaled([0, 1, 3, 4], lambda s: 1.0 / s), pose_to_file=_scaled([0, 1], lambda s: s)),
        signature="flight_vertical_curvature",
        signature_note="free-flight curvature off g by the same factor for every track, and impacts at a height off by a share of the die's size",
    ),
    Effect(
        "table_offset", "measurement", "the tracker's height zero is not the table: file y = true y + offset",
        params=(Param("table_offset", "m", "tracking.table_offset", lambda cfg: (-0.25 * cfg.die.circumradius, 0.25 * cfg.die.circumradius), 0.0, (0.001, -0.001), 1e-3),),
        config_keys=(ConfigKey("tracking", "table_offset", 0.0, "m"),),
        measurement=Measurement(state_to_true=_shifted(1, -1.0), pose_to_file=_shifted(1, +1.0)),
        signature="impact_prediction",
        signature_note="frames predicted through an impact miss: impacts happen at a height off by the same length every time",
    ),
)


def _free_fall_speed(cfg):
    """sqrt(g R) (m/s): the die's own speed, the unit of the scatter floors."""
    return math.sqrt(cfg.world.g * cfg.die.circumradius)


def _spread(name, help, slot, unit, scale=None):
    """A [scatter] spread: its config key (range [0, MAX_SCATTER], 0 = none) and the Param that
    states its null value and bounds (taken from the key, so they are declared once)."""
    key = ConfigKey("scatter", name, 0.0, unit, low=0.0, high=MAX_SCATTER, slot=slot, scale=scale, help=help)
    return key, Param(f"scatter_{name}", unit, key.dotted, lambda cfg: (key.low, key.high), key.default, (), 0.01)


SCATTER_KINDS = ("corner", "flat")  # the law's landing kinds, by tilt (physics/scatter.FLAT_TILT)
_SPREADS = (
    _spread("corner", "the velocity jump's sd over the approach speed at u = sqrt(g R), landings on a corner", "FP_SCATTER_CORNER",
            "(of the approach speed)"),
    _spread("flat", "the same for landings within 15 deg of flat and two contacts at once", "FP_SCATTER_FLAT",
            "(of the approach speed)"),
    _spread("corner_floor", "the jump's sd at a vanishing approach, landings on a corner", "FP_SCATTER_CORNER_FLOOR",
            "sqrt(g R)", _free_fall_speed),
    _spread("flat_floor", "the same for flat landings", "FP_SCATTER_FLAT_FLOOR", "sqrt(g R)", _free_fall_speed),
)
# The speed term's form, not its size: sd = spread sqrt(g R) (u / sqrt(g R))^power, both kinds.
# 1 (the null value, today's law) is sd = spread u; a scale on the law leaves it as it is.
_POWER = ConfigKey("scatter", "power", 1.0, "", low=0.0, high=MAX_POWER, slot="FP_SCATTER_POWER",
                   help="the power of the approach speed in the spread term, both kinds (1: spread u; 2: fast impacts scatter more)")


# The jump's shape, not its size (a scale on the law leaves these as they are); each null value
# is today's isotropic Gaussian, bit for bit. A share of impacts jumps wider (a two-component
# scale mixture: heavy tails), and the spin component may scatter more or less than the velocity.
_SHAPE = (
    ConfigKey("scatter", "tail_share", 0.0, "", low=0.0, high=1.0, slot="FP_SCATTER_TAIL_SHARE",
              help="the share of impacts whose jump is wide (0: every jump of the law's sd)"),
    ConfigKey("scatter", "tail_factor", 1.0, "", low=1.0, high=MAX_TAIL_FACTOR, slot="FP_SCATTER_TAIL_FACTOR",
              help="a wide jump's sd over the law's (1: no tail)"),
    ConfigKey("scatter", "spin", 1.0, "", low=0.0, high=MAX_SPIN, slot="FP_SCATTER_SPIN",
              help="the spin component's sd (of sqrt(I/M) omega) over the velocity components' (1: isotropic)"),
)
SCATTER_SHAPE = tuple(key.name for key in _SHAPE)  # the shape keys, in the registry's order


def scatter_spread_keys(kind=None):
    """The [scatter] keys a factor on the law multiplies (spreads and floors), of one landing
    kind (its spread, then its floor) or of all, kind by kind."""
    kinds = SCATTER_KINDS if kind is None else (kind,)
    return tuple(name for k in kinds for name in (k, f"{k}_floor"))


def scatter_law_keys():
    """Every [scatter] key of the law itself (spreads, floors, then its form), not draws or seed."""
    return scatter_spread_keys() + (_POWER.name,) + SCATTER_SHAPE


# Random laws around the deterministic one: declared like effects (keys, units, ranges, null
# values, kernel slots, signature), but never a fit's or a diagnosis's candidate
NOISE_MODELS = (
    Effect(
        "scattered_impacts", "noise",
        "each impact's velocity jump scattered around the deterministic law: a Gaussian of sd min(sqrt((spread sqrt(g R) "
        "(u / sqrt(g R))^power)^2 + (floor sqrt(g R))^2), u) per component of (vx, vy, sqrt(I/M) omega), u the touching corner's approach speed; "
        "a share tail_share of impacts tail_factor times wider (capped at u), the spin component spin times the others "
        "(docs/physics.md, \"Scattered impacts\"); a sweep rolls each start `draws` times on streams of `seed`",
        params=tuple(param for _, param in _SPREADS),
        config_keys=(
            *(key for key, _ in _SPREADS),
            _POWER,
            *_SHAPE,
            ConfigKey("scatter", "draws", 1, "", low=1, high=MAX_DRAWS, help="rolls per start of a sweep (> 1: a probability sweep)"),
            ConfigKey("scatter", "seed", 0, "", low=0, high=MAX_SEED, slot="FP_STREAM_SEED", help="the random streams' seed"),
        ),
        signature="impact_scatter",
        signature_note="impact residuals beyond the tracking noise's share, growing with the approach speed "
                       "(estimated by dice_sweep/measured/scatter.py, not by a least-squares fit)",
    ),
)

_BY_NAME = {e.name: e for e in EFFECTS}
_NOISE_BY_NAME = {e.name: e for e in NOISE_MODELS}
_PARAMS = {p.name: p for p in BASE_PARAMS + tuple(p for e in EFFECTS + NOISE_MODELS for p in e.params)}


def names():
    """Names of all effects, in registry order."""
    return tuple(_BY_NAME)


def effect(name):
    """The registry entry of ``name`` (KeyError if there is none)."""
    return _BY_NAME[name]


def noise_model(name):
    """The registry entry of the noise model ``name`` (KeyError if there is none)."""
    return _NOISE_BY_NAME[name]


def param(name):
    """The Param called ``name`` (a base parameter or an effect's)."""
    return _PARAMS[name]


def config_key_specs():
    """{section: {key: ConfigKey}} of every config key the registry owns."""
    specs = {}
    for entry in EFFECTS + NOISE_MODELS:
        for key in entry.config_keys:
            specs.setdefault(key.section, {})[key.name] = key
    return specs


def declared_effects(cfg):
    """Names of the effects a config already has on, in registry order."""
    return tuple(e.name for e in EFFECTS if e.is_declared(cfg))


def _split_key(key):
    section, _, rest = key.partition(".")
    if rest.endswith("]"):
        name, _, index = rest[:-1].partition("[")
        return section, name, int(index)
    return section, rest, None


def get_key(cfg, key):
    """The value at ``section.name`` or ``section.name[i]`` of a config."""
    section, name, index = _split_key(key)
    value = getattr(getattr(cfg, section), name)
    return value if index is None else value[index]


def set_key(cfg, key, value):
    """A copy of ``cfg`` with ``section.name`` (or ``section.name[i]``) set to ``value``."""
    section, name, index = _split_key(key)
    table = getattr(cfg, section)
    if index is not None:
        items = list(getattr(table, name))
        items[index] = value
        value = tuple(items)
    return dataclasses.replace(cfg, **{section: dataclasses.replace(table, **{name: value})})


def with_values(cfg, effect_names, values):
    """The config with ``effect_names`` switched on and fitted ``values`` (name -> value) set."""
    for name in effect_names:
        entry = _BY_NAME[name]
        for key, value in entry.switch:
            cfg = set_key(cfg, key, value)
    for name, value in values.items():
        cfg = set_key(cfg, _PARAMS[name].key, float(value))
    return cfg


def measurement_maps(cfg, values):
    """(times_to_true, state_to_true, pose_to_file) of all measurement effects together, at
    the fitted ``values`` where given and the config's [tracking] values elsewhere."""
    active = []
    for entry in EFFECTS:
        if entry.measurement is None:
            continue
        (p,) = entry.params
        value = values.get(p.name, get_key(cfg, p.key))
        if value != p.null_value(cfg):
            active.append((entry.measurement, value))

    def times_to_true(times):
        for m, value in reversed(active):
            if m.times_to_true is not None:
                times = m.times_to_true(times, value)
        return times

    def state_to_true(states):
        for m, value in reversed(active):
            if m.state_to_true is not None:
                states = m.state_to_true(states, value)
        return states

    def pose_to_file(poses):
        for m, value in active:
            if m.pose_to_file is not None:
                poses = m.pose_to_file(poses, value)
        return poses

    return times_to_true, state_to_true, pose_to_file


def markdown_table():
    """The registry as a Markdown table (docs/effects.md, docs/physics.md)."""
    lines = ["| effect | kind | what it changes | parameters (unit, null value) | config key | residual signature |", "|---|---|---|---|---|---|"]
    for e in EFFECTS:
        params = "; ".join(f"{p.name} ({p.unit}, null {p.null if not callable(p.null) else 'the declared value'})" for p in e.params) or "-"
        key = ", ".join([f"`{k} = \"{v}\"`" for k, v in e.switch] + [f"`{p.key}`" for p in e.params])
        summary = e.summary.replace("|", "\\|")  # a pipe would end the table cell
        if e.equivalent:
            summary += f" (no motion tells it from {', '.join(e.equivalent)})"
        lines.append(f"| {e.name} | {e.kind} | {summary} | {params} | {key} | {e.signature}: {e.signature_note} |")
    return "\n".join(lines)


def _range_text(key):
    low = "(" if key.low_open else "["
    return f"{low}{key.low:g}, {key.high:g}]" if math.isfinite(key.high) else f"{low}{key.low:g}, inf)"


def noise_table():
    """The noise models' keys as a Markdown table (docs/effects.md): each key's model, unit,
    allowed range, null value (default), kernel slot, and the model's residual signature."""
    lines = ["| noise model | config key | unit | allowed | null value (default) | kernel slot | meaning |", "|---|---|---|---|---|---|---|"]
    for e in NOISE_MODELS:
        for key in e.config_keys:
            slot = f"`{key.slot}`" + (" (x sqrt(g R), m/s)" if key.scale is not None else "") if key.slot else "- (the sweep reads it)"
            kind = ", an integer" if key.kind is int else ""
            lines.append(f"| {e.name} | `{key.dotted}` | {key.unit or '-'} | {_range_text(key)}{kind} | {key.default!r} | {slot} | {key.help} |")
    notes = [f"- **{e.name}** ({e.kind}): {e.summary.replace('|', chr(92) + '|')}. Residual signature {e.signature}: {e.signature_note}."
             for e in NOISE_MODELS]
    return "\n".join(lines + [""] + notes)

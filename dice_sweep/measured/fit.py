"""Fitting the model to tracked drops: parameters, initial states, residuals, errors.

A *model spec* is the config's declared model plus named effects. Each effect brings its
parameters (SI units):

| effect | parameters | what it changes |
|---|---|---|
| corner_impulse | - | ``[contact] model = "rigid"`` (impulse at the corner) |
| coulomb_friction | friction (1) | Coulomb cap of corner impulses and pivots |
| air_drag | air_drag (1/m) | a = -c abs(v) v |
| com_offset | com_dx, com_dy (m) | loaded die, body frame |
| speed_restitution | speed_restitution (s/m) | beta_normal / (1 + k abs(u_n)) |
| gravity | gravity (m/s^2) | the apparent g of the tracks |
| angle_offset | angle_offset (rad) | measurement: the tracker's angle zero is off |

Every fit also frees beta_normal and beta_tangential. The error metric is the RMS over frames
of sqrt(dx^2 + dy^2 + (R dphi)^2) (m) between tracked and simulated poses, from the first frame
to HORIZON_AFTER_IMPACT after the first impact: the first impact's physics is measured, the
chaos the later bounces amplify is not (docs/measured.md says why).
"""

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from dice_sweep.physics import pack_params
from dice_sweep.physics.kernel import sample_batch
from dice_sweep.physics.params import IP_CONTINUE

EFFECT_PARAMS = {
    "corner_impulse": (),
    "coulomb_friction": ("friction",),
    "air_drag": ("air_drag",),
    "com_offset": ("com_dx", "com_dy"),
    "speed_restitution": ("speed_restitution",),
    "gravity": ("gravity",),
    "angle_offset": ("angle_offset",),
}
EFFECTS = tuple(EFFECT_PARAMS)
BASE_PARAMS = ("beta_normal", "beta_tangential")
HORIZON_AFTER_IMPACT = 0.06  # s
IMPACT_WINDOW = 0.01  # m: a minimum of the lowest corner's height below this is an impact
IMPACT_DV = 0.5  # m/s: a jump of the vertical velocity between frames larger than this is one
MIN_FREE_FRAMES = 4
SPEED_RESTITUTION_START = 0.5  # s/m
TYPICAL_IMPACT_SPEED = 2.0  # m/s, of drops like the shared data's (about 0.15 m high)
ROBUST_SCALE = 0.003  # m: soft-L1 loss scale, about where tracking glitches begin to dominate


@dataclass(frozen=True)
class ModelSpec:
    """The declared model plus added effects, and how parameters map onto a config."""

    effects: tuple = ()

    def param_names(self):
        names = list(BASE_PARAMS)
        for effect in self.effects:
            names += EFFECT_PARAMS[effect]
        return names

    def with_effect(self, effect):
        return ModelSpec(self.effects + (effect,))


def declared_effects(cfg):
    """Effects the config already declares (they are not candidates)."""
    declared = []
    if cfg.contact.model == "rigid":
        declared.append("corner_impulse")
    if math.isfinite(cfg.contact.friction):
        declared.append("coulomb_friction")
    effects = cfg.effects
    if effects.air_drag:
        declared.append("air_drag")
    if any(effects.com_offset):
        declared.append("com_offset")
    if effects.speed_restitution:
        declared.append("speed_restitution")
    if effects.gravity:
        declared.append("gravity")
    return tuple(declared)


def start_values(cfg, spec):
    """Starting values: the config's, or a neutral guess for an effect it does not declare."""
    effects = cfg.effects
    guess = {
        "beta_normal": cfg.contact.beta_normal,
        "beta_tangential": cfg.contact.beta_tangential,
        "friction": cfg.contact.friction if math.isfinite(cfg.contact.friction) else 0.5,
        "air_drag": effects.air_drag or 0.05,
        "com_dx": effects.com_offset[0],
        "com_dy": effects.com_offset[1],
        "speed_restitution": effects.speed_restitution or 0.1,
        "gravity": effects.gravity or cfg.world.g,
        "angle_offset": 0.0,
    }
    return {name: guess[name] for name in spec.param_names()}


def param_bounds(cfg, name):
    """Allowed range of a fitted parameter."""
    apothem = cfg.die.circumradius * math.cos(math.pi / cfg.die.sides)
    return {
        "beta_normal": (0.0, 1.0),
        "beta_tangential": (-1.0, 1.0),
        "friction": (0.0, 3.0),
        "air_drag": (0.0, 5.0),
        "com_dx": (-0.5 * apothem, 0.5 * apothem),
        "com_dy": (-0.5 * apothem, 0.5 * apothem),
        "speed_restitution": (0.0, 5.0),
        "gravity": (0.5 * cfg.world.g, 1.5 * cfg.world.g),
        "angle_offset": (-0.5, 0.5),
    }[name]


def model_config(cfg, spec, values):
    """The config of a spec with fitted ``values`` (a dict by parameter name)."""
    contact = dataclasses.replace(cfg.contact, beta_normal=values["beta_normal"], beta_tangential=values["beta_tangential"])
    effects = cfg.effects
    if "corner_impulse" in spec.effects:
        contact = dataclasses.replace(contact, model="rigid")
    if "friction" in values:
        contact = dataclasses.replace(contact, friction=values["friction"])
    if "air_drag" in values:
        effects = dataclasses.replace(effects, air_drag=values["air_drag"])
    if "com_dx" in values:
        effects = dataclasses.replace(effects, com_offset=(values["com_dx"], values["com_dy"]))
    if "speed_restitution" in values:
        effects = dataclasses.replace(effects, speed_restitution=values["speed_restitution"])
    if "gravity" in values:
        effects = dataclasses.replace(effects, gravity=values["gravity"])
    return dataclasses.replace(cfg, contact=contact, effects=effects)


def gravity_of(cfg):
    return cfg.effects.gravity if cfg.effects.gravity > 0 else cfg.world.g


def lowest_corner_height(sides, radius, y, phi):
    """Height (m) of the lowest corner of poses (y, phi) of the geometric centre."""
    angles = np.asarray(phi)[..., None] + 2 * np.pi * np.arange(sides) / sides
    return np.asarray(y) + radius * np.sin(angles).min(axis=-1)


def first_impact_frame(t, pose, sides, radius):
    """Index of the first frame that may already follow the first impact (-1: none found).

    Two signs, the earlier wins: the first local minimum of the lowest corner's height below
    IMPACT_WINDOW (at 250 Hz the contact falls between frames, so no frame need come close to
    0), and the first jump of the vertical velocity between frames by more than IMPACT_DV (an
    impact changes it by metres per second, gravity by g dt). The second catches bounces whose
    lowest frame stays high; without it some tracks fitted a bounce as free flight
    (docs/figures/measured_residual.png showed their errors before the "first" impact).
    """
    low = lowest_corner_height(sides, radius, pose[:, 1], pose[:, 2])
    turning = np.flatnonzero((low[:-1] < IMPACT_WINDOW) & (low[1:] >= low[:-1]))
    first = turning[0] if turning.size else len(t)
    vy = np.diff(pose[:, 1]) / np.diff(t)
    jumps = np.flatnonzero(np.diff(vy) > IMPACT_DV) + 1  # vy[k] - vy[k-1]: interval k
    if jumps.size:
        first = min(first, jumps[0])
    return first if first < len(t) else -1


@dataclass(frozen=True)
class PreparedTrack:
    """One track reduced to what the fit needs (times from the track's first frame)."""

    traj: int
    t0: float  # s, time of the first frame in the file
    times: np.ndarray  # s from t0, usable frames up to the horizon
    pose: np.ndarray  # (frames, 3): x, y, phi measured
    free: np.ndarray  # bool per frame: free flight before the first impact
    t_impact: float  # s from t0, first impact (first frame below the clearance)


def prepare_tracks(trackset, cfg, horizon_after_impact=HORIZON_AFTER_IMPACT):
    """Usable frames (finite, not glitches) up to the horizon; tracks with too little free
    flight before their first impact are left out (they cannot give an initial state)."""
    sides = cfg.die.sides
    radius = cfg.die.circumradius
    prepared = []
    for track in trackset.tracks:
        ok = np.isfinite(track.x) & np.isfinite(track.y) & np.isfinite(track.phi) & ~track.glitch
        if ok.sum() < MIN_FREE_FRAMES + 2:
            continue
        t = track.t[ok] - track.t[0]
        pose = np.column_stack([track.x[ok], track.y[ok], track.phi[ok]])
        first = first_impact_frame(t, pose, sides, radius)
        if first < MIN_FREE_FRAMES:
            continue
        t_impact = t[first]
        keep = t <= t_impact + horizon_after_impact
        free = np.arange(t.size) < first  # frames before the minimum are surely before contact
        prepared.append(PreparedTrack(track.traj, float(track.t[0]), t[keep], pose[keep], free[keep], float(t_impact)))
    return prepared


def initial_states(prepared, g, angle_offset=0.0):
    """Initial states (x, y, phi, vx, vy, omega) at each track's first frame: least squares of
    the ballistic motion (x, phi linear; y with acceleration -g) over its free-flight frames."""
    states = np.zeros((len(prepared), 6))
    for i, track in enumerate(prepared):
        t = track.times[track.free]
        x, y, phi = track.pose[track.free].T
        design = np.column_stack([np.ones_like(t), t])
        (x0, vx), *_ = np.linalg.lstsq(design, x, rcond=None)
        (y0, vy), *_ = np.linalg.lstsq(design, y + 0.5 * g * t * t, rcond=None)
        (phi0, omega), *_ = np.linalg.lstsq(design, phi - angle_offset, rcond=None)
        states[i] = (x0, y0, phi0, vx, vy, omega)
    return states


class TrackModel:
    """Simulated poses of prepared tracks for a spec's parameter values."""

    def __init__(self, cfg, spec, prepared):
        self.cfg = cfg
        self.spec = spec
        self.prepared = prepared
        self.times = np.concatenate([track.times for track in prepared])
        self.starts = np.concatenate([[0], np.cumsum([track.times.size for track in prepared])]).astype(np.int64)
        self.measured = np.concatenate([track.pose for track in prepared])
        self.track_of_frame = np.repeat(np.arange(len(prepared)), np.diff(self.starts))

    def simulate(self, values):
        """(simulated poses (frames, 3), outcome per track, initial states)."""
        cfg = model_config(self.cfg, self.spec, values)
        offset = values.get("angle_offset", 0.0)
        states = initial_states(self.prepared, gravity_of(cfg), offset)
        horizon = float(self.times.max()) + 1e-3
        cfg = dataclasses.replace(cfg, integrator=dataclasses.replace(cfg.integrator, method="event", t_max=horizon))
        fpar, ipar = pack_params(cfg)
        ipar[IP_CONTINUE] = 1
        out = np.zeros((self.times.size, 6))
        outcome = np.zeros(len(self.prepared), np.int8)
        sample_batch(fpar, ipar, states, self.times, self.starts, out, outcome)
        poses = out[:, :3].copy()
        poses[:, 2] += offset  # the tracker's angle zero, if the spec fits one
        return poses, outcome, states

    def frame_errors(self, values):
        """Per-frame pose error sqrt(dx^2 + dy^2 + (R dphi)^2) (m)."""
        poses, _, _ = self.simulate(values)
        diff = poses - self.measured
        diff[:, 2] *= self.cfg.die.circumradius
        return np.sqrt((diff * diff).sum(axis=1))

    def residual_vector(self, values):
        poses, _, _ = self.simulate(values)
        diff = poses - self.measured
        diff[:, 2] *= self.cfg.die.circumradius
        return diff.ravel()


def rms(errors):
    return float(np.sqrt(np.mean(np.square(errors)))) if len(errors) else math.nan


@dataclass(frozen=True)
class FitResult:
    spec: ModelSpec
    params: dict
    train_error: float  # m, RMS pose error on the training tracks
    train_tracks: int
    evaluations: int


def fit_spec(cfg, spec, prepared_train, start=None):
    """Least squares (soft-L1 loss, scale ROBUST_SCALE) of the spec's parameters on the
    training tracks; returns a FitResult."""
    from scipy.optimize import least_squares

    names = spec.param_names()
    initial = start_values(cfg, spec)
    if start:
        initial.update({k: v for k, v in start.items() if k in initial})
        if "speed_restitution" in names and "speed_restitution" not in start:
            # keep the effective restitution at a typical impact speed where it was, so the
            # new parameter starts where it can move (a start at k = 0.1 stayed there)
            initial["speed_restitution"] = SPEED_RESTITUTION_START
            initial["beta_normal"] = min(start["beta_normal"] * (1.0 + SPEED_RESTITUTION_START * TYPICAL_IMPACT_SPEED), 1.0)
    bounds = np.array([param_bounds(cfg, name) for name in names]).T
    x0 = np.clip([initial[name] for name in names], bounds[0] + 1e-9, bounds[1] - 1e-9)
    model = TrackModel(cfg, spec, prepared_train)

    def residuals(x):
        return model.residual_vector(dict(zip(names, x)))

    solution = least_squares(
        residuals, x0, bounds=bounds, loss="soft_l1", f_scale=ROBUST_SCALE, diff_step=1e-3, max_nfev=60 * (len(names) + 1)
    )
    values = dict(zip(names, (float(v) for v in solution.x)))
    return FitResult(spec, values, rms(model.frame_errors(values)), len(prepared_train), int(solution.nfev))


def held_out_error(cfg, result, prepared_test):
    """RMS pose error (m) of a fit on held-out tracks."""
    return rms(TrackModel(cfg, result.spec, prepared_test).frame_errors(result.params))

"""The tracking noise of a track file and the noise floor the loop's errors are set against.

Measured on the free flights before anything is fitted: the table's height in the file (from
the dice at rest), then the sigmas of x, y and phi from quadratic fits over the flights
(:func:`dice_sweep.measured.flights.estimate_noise`), and the pose noise floor
sqrt(sx^2 + sy^2 + (R sphi)^2) with 95 % intervals (bootstrap over tracks).
"""

import math

import numpy as np

from dice_sweep.errors import DiceSweepError
from dice_sweep.measured.flights import estimate_noise
from dice_sweep.measured.impacts import rest_pose, table_level


def table_height(trackset, cfg):
    """Height of the table in the file (m): the median lowest-corner height of the dice that
    end at rest, 0 when none does. Flights are cut where a corner meets this level."""
    rests = [rest_pose(tr.x, tr.y, tr.phi, tr.usable, cfg.die.circumradius, tr.t) for tr in trackset.tracks]
    return table_level([p for p in rests if p is not None], sides=cfg.die.sides, circumradius=cfg.die.circumradius)


def noise_floor(trackset, cfg, table=0.0):
    """Tracking noise from the free flights (bootstrap over tracks): a dict with the sigmas of
    x, y (m) and phi (rad), the pose noise floor sqrt(sx^2 + sy^2 + (R sphi)^2) (m) and their
    95 % intervals."""
    est = estimate_noise(trackset.tracks, sides=cfg.die.sides, circumradius=cfg.die.circumradius, g=cfg.world.g, table=table)
    if not math.isfinite(est.pose):
        raise DiceSweepError(f"{trackset.path}: tracks: no free flight long enough to measure the tracking noise "
                             f"(allowed: tracks with flights of several frames)")
    return {"sigma_x": float(est.sigma[0]), "sigma_y": float(est.sigma[1]), "sigma_phi": float(est.sigma[2]),
            "sigma_ci95": [list(map(float, row)) for row in est.interval], "pose": float(est.pose),
            "pose_ci95": list(est.pose_interval), "tracks": est.tracks, "flights": est.flights, "frames": est.frames,
            "method": "pooled residuals of quadratic fits in t of x, y and R phi over the free flights (frames near the table "
                      "left out), degrees of freedom corrected; 95 % intervals by bootstrap over tracks"}


def tracking_noise(trackset, cfg):
    """(table height (m), :func:`noise_floor`'s dict, sigmas of x, y (m) and phi (rad) as an
    array): what every command on tracked drops measures before it fits."""
    table = table_height(trackset, cfg)
    noise = noise_floor(trackset, cfg, table)
    return table, noise, np.array([noise["sigma_x"], noise["sigma_y"], noise["sigma_phi"]])


def residual_sigmas(noise, cfg):
    """Sigmas of the residual's columns x, y and R phi (m) from :func:`noise_floor`'s dict."""
    return (noise["sigma_x"], noise["sigma_y"], cfg.die.circumradius * noise["sigma_phi"])

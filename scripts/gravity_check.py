"""Is the low free-fall g of the real drops a length or a time scale of the tracking?
Free-flight g of the first flight of each real drop, fitted several ways, with 95 % intervals
(bootstrap over tracks): ``python scripts/gravity_check.py``. Skips without ../shared/data.

A wrong clock (time_scale) scales every acceleration by 1/s^2 and leaves lengths right; a wrong
length scale scales accelerations and lengths alike, so the die's apparent size at rest and at
contact gives it away; air drag lowers the apparent g by about c v^2 while the die falls at v.
"""

import json
import sys
from pathlib import Path

import numpy as np

from dice_sweep.config import load_config
from dice_sweep.measured.noise import table_height
from dice_sweep.measured.flights import find_flights
from dice_sweep.measured.tracks import load_tracks

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT.parent / "shared" / "data" / "mcube_square_drops" / "drops.csv.gz"


def median_ci(values, rng):
    values = np.asarray(values)
    medians = [np.median(values[rng.integers(0, values.size, values.size)]) for _ in range(1000)]
    return {"median": float(np.median(values)), "ci95": [float(np.quantile(medians, 0.025)), float(np.quantile(medians, 0.975))], "tracks": int(values.size)}


def main():
    if not DATA.exists():
        print(f"skipped: {DATA} not found")
        return 0
    cfg = load_config(ROOT / "configs" / "square_drops.toml")
    tracks = load_tracks(DATA, sides=4, circumradius=cfg.die.circumradius, angle="auto")
    table = table_height(tracks, cfg)
    rng = np.random.default_rng(0)
    g = {"first_10_frames": [], "first_10_frames_without_frame_0": [], "first_flight": [], "first_flight_without_frame_0": []}
    speed, rest_height = [], []
    apothem = cfg.die.circumradius * np.cos(np.pi / cfg.die.sides)
    for track in tracks.tracks:
        t, y = track.t, track.y
        flights = find_flights(t, track.x, y, track.phi, track.usable, sides=4, circumradius=cfg.die.circumradius, table=table)
        if np.isfinite(y[:11]).all():
            g["first_10_frames"].append(-2 * np.polyfit(t[:10], y[:10], 2)[0])
            g["first_10_frames_without_frame_0"].append(-2 * np.polyfit(t[1:11], y[1:11], 2)[0])
        if flights and flights[0][0] == 0 and flights[0][1] >= 8:
            last = flights[0][1] + 1
            for key, first in (("first_flight", 0), ("first_flight_without_frame_0", 1)):
                ok = np.isfinite(y[first:last])
                coef = np.polyfit(t[first:last][ok], y[first:last][ok], 2)
                g[key].append(-2 * coef[0])
            speed.append(abs(np.polyval(np.polyder(coef), t[last - 1])))
        tail = y[-25:]
        if np.isfinite(tail).all() and np.ptp(tail) < 1e-3:
            rest_height.append(np.median(tail))
    out = {key: median_ci(values, rng) for key, values in g.items()}
    out["speed_at_first_impact_m_s"] = median_ci(speed, rng)
    out["rest_height_of_centre_m"] = median_ci(rest_height, rng)
    out["apothem_m"] = float(apothem)
    out["table_height_m"] = table
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

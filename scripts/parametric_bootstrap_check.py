"""Parametric bootstrap against the bootstrap over tracks and the first-order noise covariance
(reduced.noise_covariance) on one set of drops from the independent generator
(docs/dev/measured_intervals.md, issue 14): fit the true model, simulate the fitted model's poses
at the fitted states, add the measured tracking noise (one draw per frame: a frame is a row of
its flight's segment and of the segment before), refit warm, and compare the spreads.

    python scripts/parametric_bootstrap_check.py SEED DRAWS     (e.g. 3 30; about 10 s)

Needs the tests folder (a checkout). Development evidence, not a user command.
"""
import sys
import tempfile
import time
from pathlib import Path
import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from dice_sweep.config import parse_config
from dice_sweep.measured import fit as shooting, reduced
from dice_sweep.measured.noise import tracking_noise
from dice_sweep.measured.split import CONFIRM_FRACTION
from dice_sweep.measured.tracks import load_tracks
from tests.measured.cases import DECLARED_RIGID, NOISE, TRUE_COEFFICIENTS
from tests.measured.independent import Truth, simulate_drops, write_csv
truth = Truth(contact="rigid", **TRUE_COEFFICIENTS)
cfg = parse_config(DECLARED_RIGID)
folder = Path(tempfile.mkdtemp())
seed = int(sys.argv[1]); n = int(sys.argv[2])
path = folder / f"d{seed}.csv"
write_csv(path, simulate_drops(truth, 90, 100 + seed, rate=500.0, noise=NOISE, drop_prob=0.01, glitch_prob=0.002))
ts = load_tracks(path, sides=cfg.die.sides, circumradius=cfg.die.circumradius)
table, noise, sigma = tracking_noise(ts, cfg)
sel, conf = ts.split(CONFIRM_FRACTION, seed)
select = shooting.prepare_tracks(sel, cfg, noise=sigma, table=table)
seg = shooting.Segments(select, cfg.world.g)
spec = shooting.ModelSpec.of(cfg)
fit = shooting.fit_spec(cfg, spec, seg)
lin = shooting.linearise(cfg, fit, seg); red = reduced.reduce(lin, seg)
draws = reduced.bootstrap_params(red, seg, list(fit.free), fit.params, cfg, np.random.default_rng(seed))
sigmas = (sigma[0], sigma[1], cfg.die.circumradius * sigma[2])
first_order = np.sqrt(np.diag(reduced.noise_covariance(red, seg, sigmas)))
print("fit friction", fit.params["friction"], "track-bootstrap sd", draws[:, 2].std(), "sigma", sigma, flush=True)
model = shooting.ShootingModel(cfg, spec, seg)
clean, _ = model.simulate(fit.params, fit.states)
original = seg.measured.copy()
rng = np.random.default_rng(1)
est = []
t0 = time.time()
for b in range(n):
    seg.measured = clean + (rng.normal(size=(seg.frames, 3)) * sigma)[seg.frame_rows]
    r = shooting.fit_spec(cfg, spec, seg, start=fit.params, states=fit.states)
    est.append([r.params[k] for k in ("beta_normal", "beta_tangential", "friction")])
est = np.array(est)
print("parametric sd (bn, bt, f)", est.std(axis=0), "mean shift", est.mean(axis=0) - [fit.params[k] for k in ("beta_normal", "beta_tangential", "friction")], "track-bootstrap sd", draws.std(axis=0),
      "first-order noise sd", first_order, f"{time.time() - t0:.1f} s")

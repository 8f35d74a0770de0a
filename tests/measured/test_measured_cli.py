"""`dice-sweep fit` and `dice-sweep diagnose` end to end on a small synthetic CSV."""

import json

import numpy as np
from click.testing import CliRunner

from dice_sweep.cli import main
from tests.measured.synthetic import DECLARED, synthetic_tracks, true_config


def write_csv(trackset, path):
    rows = ["traj,t,x,y,phi"]
    for track in trackset.tracks:
        rows += [f"{track.traj},{t:.6f},{x:.7f},{y:.7f},{phi:.7f}" for t, x, y, phi in zip(track.t, track.x, track.y, track.phi)]
    path.write_text("\n".join(rows) + "\n")


def test_fit_and_diagnose_commands(tmp_path):
    data = tmp_path / "drops.csv"
    write_csv(synthetic_tracks(true_config(contact='model = "rigid"'), 24, seed=4), data)
    config = tmp_path / "die.toml"
    config.write_text(DECLARED)
    runner = CliRunner()
    result = runner.invoke(main, ["fit", str(data), "--config", str(config), "--effects", "corner_impulse",
                                  "--angle", "as-is", "--json", str(tmp_path / "fit.json")])
    assert result.exit_code == 0, result.output
    fit = json.loads((tmp_path / "fit.json").read_text())
    assert fit["model"] == "rigid" and fit["test_error"] < 1e-3
    result = runner.invoke(main, ["diagnose", str(data), "--config", str(config), "--angle", "as-is", "--quiet",
                                  "--json", str(tmp_path / "r.json"), "--md", str(tmp_path / "r.md"), "--png", str(tmp_path / "png")])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["best_effect"] == "corner_impulse"
    assert "## Chain" in (tmp_path / "r.md").read_text()
    assert (tmp_path / "png" / "residual_error_vs_time.png").stat().st_size > 1000
    assert np.isfinite(report["first_impact_velocity_error"]["after"])


def test_unknown_effect_is_a_one_line_error(tmp_path):
    config = tmp_path / "die.toml"
    config.write_text(DECLARED)
    data = tmp_path / "d.csv"
    data.write_text("traj,t,x,y,phi\n1,0,0,0.1,0\n")
    result = CliRunner().invoke(main, ["fit", str(data), "--config", str(config), "--effects", "magic"])
    assert result.exit_code == 2
    assert "--effects: unknown effect 'magic'" in result.output and "Traceback" not in result.output

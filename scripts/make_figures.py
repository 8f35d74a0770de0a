"""Regenerate every paper figure into docs/figures/ (``make figures``). Public API only.

Each configs/figNN.toml is swept into out/figures/figNN.h5 and drawn to
docs/figures/figNN.png; Figs 9 and 11 carry the box that Figs 10 and 12 zoom into (the box is
read from those configs, so the two can never disagree). Fig. 5 is one roll of
configs/table1.toml drawn like the paper's graphics window. Beyond the paper: fig08 with the
rigid contact law beside the paper's law, and a loaded die (configs/loaded_die.toml).

    python scripts/make_figures.py [--num 512] [--workers N]
"""

import argparse
from pathlib import Path

from dice_sweep.config import load_config
from dice_sweep.app.roll import roll
from dice_sweep.app.sweep import draw_sweep_file, draw_sweep_files
from dice_sweep.sweep import run_sweep

ROOT = Path(__file__).resolve().parent.parent
ZOOMS = {"fig09": "fig10", "fig11": "fig12"}  # parent figure -> the zoom drawn as a box on it


def zoom_box(name):
    grid = load_config(ROOT / "configs" / f"{name}.toml").grid
    return (grid.x.min, grid.x.max, grid.y.min, grid.y.max)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num", type=int, default=512, help="cells per axis (default 512)")
    parser.add_argument("--workers", type=int, default=None)
    args = parser.parse_args()
    data_dir = ROOT / "out" / "figures"
    fig_dir = ROOT / "docs" / "figures"
    data_dir.mkdir(parents=True, exist_ok=True)
    fig_dir.mkdir(parents=True, exist_ok=True)
    extra = [ROOT / "configs" / "loaded_die.toml"]
    for config_path in sorted((ROOT / "configs").glob("fig*.toml")) + extra:
        name = config_path.stem
        cfg = load_config(config_path, [f"grid.x.num={args.num}", f"grid.y.num={args.num}"])
        h5_path = data_dir / f"{name}.h5"
        h5_path.unlink(missing_ok=True)
        summary = run_sweep(cfg, h5_path, workers=args.workers, progress=False)
        box = zoom_box(ZOOMS[name]) if name in ZOOMS else None
        draw_sweep_file(h5_path, fig_dir / f"{name}.png", box=box)
        print(f"{name}: {summary.rolls_computed} rolls in {summary.seconds:.1f} s -> docs/figures/{name}.png")
    draw_sweep_files([data_dir / "fig08.h5", data_dir / "fig08_rigid.h5"], fig_dir / "fig08_paper_vs_rigid.png",
                    titles=["paper contact law (eqs 9-13)", "rigid contact law (impulse at the corner)"])
    print("fig08_paper_vs_rigid: side by side -> docs/figures/fig08_paper_vs_rigid.png")
    cfg = load_config(ROOT / "configs" / "table1.toml")
    roll(cfg, png_path=fig_dir / "fig05_roll.png")
    print("fig05_roll: one roll of configs/table1.toml -> docs/figures/fig05_roll.png")


if __name__ == "__main__":
    main()

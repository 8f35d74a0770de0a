"""Time `dice-sweep diagnose` on the 500 real drops (with intervals), the whole command in a
fresh process, as a user runs it: ``python scripts/bench_measured.py [--runs N]``.

``--timeline`` runs it once in this process instead and prints diagnose's log lines with the
wall time (s) at which each was written: where the time goes, phase by phase (the baseline fit,
each round's candidates, the pairs, the final checks; docs/dev/measured_speed.md).

Target (issue 14): at most 2 minutes on 2 cores. Skips cleanly without ../shared/data.
"""

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT.parent / "shared" / "data" / "mcube_square_drops" / "drops.csv.gz"
TARGET = 180.0  # s: issue 30, diagnose with cross-fitting, causes and proposals, on 2 cores


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--timeline", action="store_true", help="one run in this process, its log lines timed")
    args = parser.parse_args()
    if not DATA.exists():
        print(f"skipped: {DATA} not found")
        return 0
    if args.timeline:
        return timeline()
    times = []
    with tempfile.TemporaryDirectory() as folder:
        report = Path(folder) / "report.json"
        for _ in range(args.runs):
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "dice_sweep", "diagnose", str(DATA), "--config", str(ROOT / "configs" / "square_drops.toml"),
                            "--angle", "auto", "--quiet", "--json", str(report)], check=True)
            times.append(time.perf_counter() - start)
        result = json.loads(report.read_text())
    print(json.dumps({"diagnose_500_real_drops_s": times, "target_s": TARGET, "met": min(times) <= TARGET,
                      "verdict": result["verdict"], "effects_added": result["effects_added"]}))
    return 0


def timeline():
    """diagnose's log, each line prefixed with the wall time since the start (imports included)."""
    start = time.perf_counter()
    from dice_sweep.app.measured import run_diagnose
    from dice_sweep.config import load_config

    def log(line):
        print(f"[{time.perf_counter() - start:6.1f} s] {line}", flush=True)

    report = run_diagnose(DATA, load_config(ROOT / "configs" / "square_drops.toml"), angle="auto", log=log)
    print(json.dumps({"diagnose_500_real_drops_s": time.perf_counter() - start, "target_s": TARGET,
                      "verdict": report["verdict"], "effects_added": report["effects_added"]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Write (or check) the golden regression sweeps of tests/golden/.

    python scripts/make_golden.py            # regenerate every file
    python scripts/make_golden.py --check    # print how many pixels differ, write nothing
"""

import argparse
import tempfile
from pathlib import Path

from dice_sweep.golden import CASES, compare_with_golden, sweep_case

ROOT = Path(__file__).resolve().parent.parent
GOLDEN_DIR = ROOT / "tests" / "golden"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare only, write nothing")
    args = parser.parse_args()
    GOLDEN_DIR.mkdir(exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for case in CASES:
            new = Path(tmp) / f"{case.name}.h5"
            sweep_case(case, ROOT / "configs", new)
            target = GOLDEN_DIR / f"{case.name}.h5"
            if target.exists():
                print(case.name, compare_with_golden(new, target))
            if not args.check:
                target.write_bytes(new.read_bytes())
                print(f"wrote {target.relative_to(ROOT)}")


if __name__ == "__main__":
    main()

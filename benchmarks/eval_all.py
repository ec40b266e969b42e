"""Run ``mcahrs evaluate`` on every recording in ``../shared/data`` and print the tables.

Each recording is evaluated with ``--preset auto`` (ULog multirotor -> multirotor; comma2k19 and
the car drive -> ground) and the core presets as they are: one configuration per vehicle class,
never tuned per log. The NMEA captures (``nmea/``) are GNSS-only receiver logs without IMU
samples: there is nothing to evaluate there, and the run says so.

Run: python benchmarks/eval_all.py [--data DIR] [--plot DIR] [--no-golden] [extra evaluate options]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from mcahrs.evaluate import main_evaluate

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT / ".." / "shared" / "data"


def recordings(data: Path) -> list[Path]:
    """The recordings ``load`` understands, in a fixed order: ULog files, comma2k19, car."""
    out: list[Path] = sorted((data / "ulog").glob("*.ulg")) if (data / "ulog").is_dir() else []
    if (data / "comma2k19").is_dir():
        out.append(data / "comma2k19")
    if (data / "car").is_dir():
        out.append(data / "car")
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the shared data folder")
    ap.add_argument("--plot", metavar="DIR", help="write each recording's figures into DIR")
    args, extra = ap.parse_known_args()
    data = args.data.resolve()
    if not data.is_dir():
        print(f"{data}: no shared data folder; nothing to evaluate")
        return 0
    recs = recordings(data)
    status = 0
    for path in recs:
        t = time.perf_counter()
        argv = [str(path), *extra] + (["--plot", args.plot] if args.plot else [])
        rc = main_evaluate(argv)
        print(f"({path.relative_to(data)}: {time.perf_counter() - t:.1f} s, exit {rc})\n")
        status |= rc
    if (data / "nmea").is_dir():
        n = len(list((data / "nmea").glob("*.log")))
        print(f"nmea/: {n} GNSS-only receiver captures (no IMU samples): nothing to evaluate")
    return status


if __name__ == "__main__":
    sys.exit(main())

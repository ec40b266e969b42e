#!/usr/bin/env python3
"""What of the C core the golden vectors run: line, branch and function coverage of the core's
sources over every ``tests/vectors/*.mcav``.

    python scripts/vector_coverage.py                  # per source file, and the functions never run
    python scripts/vector_coverage.py --missed mca_nav.c   # and that file's lines never run

The vectors are what the Cortex-M4F runs under QEMU (``tests/python/test_firmware.py``), bit for bit
as the host replay does, so a core line the host replay never runs over them is one the target build
is never checked on. This builds the host replay program (``c_core/firmware``, the same sources) with
``--coverage -O0`` into ``build/fw-cov``, replays every vector, and reads gcov's JSON. A report, not
a goal: the public single-filter entry points (``mca_cs_axis_*``, ``mca_att_*``) that the navigation
top level calls through its unchecked variants, and error paths the vectors have no reason to reach,
stay at zero.
"""

from __future__ import annotations

import argparse
import gzip
import json
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import gen_vectors as gv  # noqa: E402

COV_BUILD = gv.REPO / "build" / "fw-cov"
CORE_SRC = gv.REPO / "c_core" / "src"


@dataclass
class FileCoverage:
    """One core source file: execution count per line, branch counts per line, and per function."""

    path: Path
    lines: dict[int, int]  # line number -> times executed (only lines with code)
    branches: dict[int, list[int]]  # line number -> times each of its branches was taken
    functions: dict[str, int]  # function name -> times called

    def line_of(self, snippet: str) -> int:
        """The number of the one source line holding ``snippet`` (ValueError if not exactly one)."""
        hits = [i for i, t in enumerate(self.path.read_text().splitlines(), 1) if snippet in t]
        if len(hits) != 1:
            raise ValueError(f"{self.path.name}: {snippet!r} is on {len(hits)} lines, not one")
        return hits[0]


def build(build_dir: Path = COV_BUILD) -> Path:
    """The host replay with gcov instrumentation, unoptimised (every line its own)."""
    subprocess.run(
        [
            "cmake",
            "-S",
            str(gv.FIRMWARE_DIR),
            "-B",
            str(build_dir),
            "-DCMAKE_BUILD_TYPE=Debug",
            "-DCMAKE_C_FLAGS=--coverage -O0",
            "-DCMAKE_EXE_LINKER_FLAGS=--coverage",
        ],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    subprocess.run(
        ["cmake", "--build", str(build_dir), "-j", "2", "--target", "replay"],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    return build_dir / "replay"


def measure(vectors: list[Path] | None = None, build_dir: Path = COV_BUILD) -> dict[str, FileCoverage]:
    """Build, replay ``vectors`` (default: every committed one) once, and read the counts: source
    file name (``mca_nav.c``) -> FileCoverage."""
    replay = build(build_dir)
    for gcda in build_dir.rglob("*.gcda"):
        gcda.unlink()  # counts of earlier runs
    with tempfile.TemporaryDirectory() as tmp:
        for vec in vectors if vectors is not None else gv.vector_files():
            gv.run_host(replay, vec, Path(tmp) / "out.mcao")
        objs = sorted((build_dir / "mcahrs_core").rglob("*.gcda"))
        subprocess.run(["gcov", "-j", "-b", *map(str, objs)], cwd=tmp, check=True, capture_output=True)
        out: dict[str, FileCoverage] = {}
        for js in Path(tmp).glob("*.gcov.json.gz"):
            data = json.loads(gzip.decompress(js.read_bytes()))
            for f in data["files"]:
                path = Path(f["file"])
                if not path.is_absolute():
                    path = Path(data["current_working_directory"]) / path
                if path.parent.resolve() != CORE_SRC.resolve() or path.suffix != ".c":
                    continue  # headers are reported with each includer: not summed here
                out[path.name] = FileCoverage(
                    path,
                    {ln["line_number"]: ln["count"] for ln in f["lines"]},
                    {ln["line_number"]: [b["count"] for b in ln["branches"]] for ln in f["lines"]},
                    {fn["name"]: fn["execution_count"] for fn in f["functions"]},
                )
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--missed", metavar="FILE", action="append", default=[], help="list FILE's lines never run"
    )
    args = ap.parse_args(argv)
    for tool in ("cmake", "gcov"):
        if shutil.which(tool) is None:
            sys.exit(f"{tool} is needed")
    cov = measure()
    print(f"C core run by the {len(gv.vector_files())} golden vectors (host replay, gcov):")
    print(f"  {'file':14s} {'lines':>14s} {'branches taken':>16s}  functions never called")
    for name in sorted(cov):
        c = cov[name]
        n_run = sum(1 for v in c.lines.values() if v > 0)
        br = [b for bs in c.branches.values() for b in bs]
        n_br = sum(1 for b in br if b > 0)
        never = sorted(f for f, n in c.functions.items() if n == 0)
        print(
            f"  {name:14s} {n_run:5d} / {len(c.lines):4d} {100 * n_run / max(1, len(c.lines)):3.0f} % "
            f"{n_br:5d} / {len(br):4d} {100 * n_br / max(1, len(br)):3.0f} %  {', '.join(never) or '-'}"
        )
    for name in args.missed:
        c = cov[name]
        src = c.path.read_text().splitlines()
        print(f"\n{name}: lines never run")
        for ln in sorted(k for k, v in c.lines.items() if v == 0):
            print(f"  {ln:5d}  {src[ln - 1].strip()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

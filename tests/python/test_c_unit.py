"""Build the host C core with CMake and run its C unit tests (ctest): once plain, once with
AddressSanitizer + UndefinedBehaviorSanitizer (both Debug), and once at Release (-O3, as the
Python extension is built: GCC 12 at -O3 once dropped a call the -O0 and -Os builds kept, see
mca_ins.c gnss_reset_block). Every build uses the core's full warning set with -Werror, so a
warning anywhere in the core fails here."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.skipif(
    shutil.which("cmake") is None, reason="cmake is not installed (scripts/setup.sh installs it)"
)
@pytest.mark.parametrize("variant", ["plain", "asan", "release"])
def test_host_c_unit_tests(variant: str) -> None:
    build = ROOT / "build" / f"ctest-{variant}"
    cfg = [
        "cmake",
        "-S",
        str(ROOT),
        "-B",
        str(build),
        f"-DCMAKE_BUILD_TYPE={'Release' if variant == 'release' else 'Debug'}",
        "-DMCA_BUILD_TESTS=ON",
        "-DMCA_BUILD_PYTHON=OFF",
        f"-DMCA_SANITIZE={'ON' if variant == 'asan' else 'OFF'}",
    ]
    subprocess.run(cfg, check=True, capture_output=True, text=True)
    b = subprocess.run(["cmake", "--build", str(build), "-j2"], capture_output=True, text=True)
    assert b.returncode == 0, b.stdout[-4000:] + b.stderr[-4000:]
    r = subprocess.run(
        ["ctest", "--test-dir", str(build), "--output-on-failure"], capture_output=True, text=True
    )
    print(r.stdout[-2000:])
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-4000:]
    assert "100% tests passed" in r.stdout

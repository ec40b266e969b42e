"""The Cortex-M4F build of the core replays the golden vectors under QEMU and agrees with the
host build of the same replay program (DESIGN.md 8; c_core/firmware/README.md).

Builds ``c_core/firmware`` twice (arm-none-eabi with cmake/arm-none-eabi-cortex-m4f.cmake, and
the host), runs every ``tests/vectors/*.mcav`` through ``fw.elf`` on ``qemu-system-arm -M
mps2-an386`` and through the host ``replay``, and compares:

* with libm pinned (``fw_pinned.elf`` / ``replay_pinned``, same math bits on both sides):
  outputs identical byte for byte, so code generation, float operations (-ffp-contract=off on
  both), FPU modes, struct layout and 64-bit conversions do not differ at all;
* with the real libm (newlib on the target, glibc on the host): identical byte for byte too,
  since the core calls no libm function that rounds differently (and links no libm member);
  and, as the diagnostic if that changes, statuses, flags, counters and times exactly,
  floats to ``gen_vectors.RTOL_LIBM`` (reason given there);
* the committed host outputs (``*.mcao``) against a fresh host run, to the same tolerance, so a
  change of filter output shows up in review (regenerate with ``python scripts/gen_vectors.py``).

The vectors cover the CS filter, the navigation top level and the loosely-coupled INS
(``ins_fixedwing_turns``). Also: the instruction counter is exact on a known loop, and the image
holds no allocator.
Skips when the cross compiler or QEMU is missing, except on CI (``CI`` set), which installs them.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))
import gen_vectors as gv  # noqa: E402

TOOLS = ("cmake", "arm-none-eabi-gcc", "arm-none-eabi-nm", "qemu-system-arm")
MISSING = [t for t in TOOLS if shutil.which(t) is None]
if MISSING and os.environ.get("CI"):
    raise RuntimeError(
        f"CI must run the firmware test, but these are missing: {', '.join(MISSING)} (scripts/setup.sh)"
    )
pytestmark = pytest.mark.skipif(
    bool(MISSING),
    reason=f"needs {', '.join(MISSING)} (Debian: gcc-arm-none-eabi libnewlib-arm-none-eabi "
    "qemu-system-arm; scripts/setup.sh installs them)",
)

VECTORS = gv.vector_files()
QEMU_TIMEOUT_S = 60


@pytest.fixture(scope="module")
def builds() -> dict[str, Path]:
    """Both builds in their own directories (Release, as gen_vectors builds the host twin)."""
    fw = gv.build_firmware(ROOT / "build" / "test-fw")
    host = gv.build_host_replay(ROOT / "build" / "test-fw-host")
    return {
        "fw": fw,
        "fw_pinned": fw.with_name("fw_pinned.elf"),
        "host": host,
        "host_pinned": host.with_name("replay_pinned"),
    }


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("firmware_runs")


def _qemu(elf: Path, vec: Path, out: Path, cost: Path | None = None) -> None:
    r = gv.run_qemu(elf, vec, out, cost, timeout=QEMU_TIMEOUT_S)
    assert r.returncode == 0, f"{elf.name} on {vec.name}: exit {r.returncode}\n{r.stdout}{r.stderr}"


def test_vector_files_are_present():
    assert len(VECTORS) >= 7, "tests/vectors/*.mcav missing: python scripts/gen_vectors.py"
    assert {v.stem for v in VECTORS} >= set(gv.SCENARIOS), "a scenario's vectors are missing"
    for v in VECTORS:
        assert v.with_suffix(".mcao").exists(), f"{v.name} has no host outputs: python scripts/gen_vectors.py"
        assert (
            v.stat().st_size < gv.MAX_FILE_BYTES and v.with_suffix(".mcao").stat().st_size < gv.MAX_FILE_BYTES
        )


def test_firmware_image_has_no_allocator(builds):
    for elf in (builds["fw"], builds["fw"].with_name("mca_core_only.elf")):
        syms = subprocess.run(
            ["arm-none-eabi-nm", str(elf)], check=True, capture_output=True, text=True
        ).stdout
        names = {line.split()[-1] for line in syms.splitlines() if line.strip()}
        heap = {
            "malloc",
            "free",
            "calloc",
            "realloc",
            "_malloc_r",
            "_free_r",
            "_calloc_r",
            "_realloc_r",
            "_sbrk",
        }
        assert not names & heap, f"{elf.name} links {sorted(names & heap)}"


def test_instruction_counter_is_exact(builds, run_dir):
    """rio_spin(n) is exactly 2n + 1 instructions; the measured count must be that plus the
    same call overhead (bl and the argument move) for every n, and a plain SysTick read must
    agree to one tick (40 instructions: -icount shift=0, 25 MHz processor clock)."""
    ns = [1, 2, 3, 7, 39, 40, 41, 100, 997, 12345, 250_000]
    w = gv.VecWriter()
    for n in ns:
        w.op("CAL_SPIN", "<I", n)
    vec, out, cost = run_dir / "cal.mcav", run_dir / "cal.mcao", run_dir / "cal.cost"
    w.write(vec)
    _qemu(builds["fw"], vec, out, cost)
    c = gv.read_costs(cost)
    assert c.meta["measured"] == 1 and c.meta["instr_per_tick"] == 40
    assert [int(x) for x in c.cal["a"]] == ns
    extra = {int(m) - (2 * n + 1) for n, m in zip(ns, c.cal["b"], strict=True)}
    assert len(extra) == 1 and 1 <= extra.pop() <= 4, f"counts {list(c.cal['b'])} for n = {ns}"
    for m, ticks in zip(c.cal["b"], c.cal["c"], strict=True):
        assert abs(int(ticks) * 40 - int(m)) <= 40 + 4


def test_core_links_nothing_from_libm(builds):
    # the core has its own exp, expm1, atan2, sin/cos and floor (mca_math.h): a libm member in
    # the core images means a new call that costs flash and host/target bit-identity
    for name in ("mca_core_nav.elf", "mca_core_only.elf"):
        text = builds["fw"].with_name(name + ".map").read_text()
        text = text[text.index("Linker script and memory map") :]
        members = sorted(set(re.findall(r"libm\.a\(([^)]+)\)", text)))
        used = [m for m in members if m != "lib_a-s_lib_ver.o"]  # empty (size 0) version stamp
        assert not used, f"{name} links libm members {used}"


@pytest.mark.parametrize("variant", ["pinned", "real"])
@pytest.mark.parametrize("vec", VECTORS, ids=[v.stem for v in VECTORS])
def test_qemu_equals_host_bit_for_bit(builds, run_dir, vec, variant):
    # pinned: the libm calls wrapped to replay_libm_pinned.c on both sides; real: the builds
    # as they ship, with no libm function left in the core whose rounding differs between glibc
    # and newlib (sqrtf and fabsf are exact on both), so they agree as the pinned ones do
    suffix = "_pinned" if variant == "pinned" else ""
    host, qemu = run_dir / f"{vec.stem}.{variant}.host", run_dir / f"{vec.stem}.{variant}.qemu"
    gv.run_host(builds["host" + suffix], vec, host)
    _qemu(builds["fw" + suffix], vec, qemu)
    assert host.read_bytes() == qemu.read_bytes(), gv.compare_outputs(host, qemu, rtol=0.0).problems


@pytest.mark.parametrize("vec", VECTORS, ids=[v.stem for v in VECTORS])
def test_qemu_matches_host_with_real_libm(builds, run_dir, vec):
    host, qemu, cost = (
        run_dir / f"{vec.stem}.host",
        run_dir / f"{vec.stem}.qemu",
        run_dir / f"{vec.stem}.cost",
    )
    gv.run_host(builds["host"], vec, host)
    _qemu(builds["fw"], vec, qemu, cost)
    cmp = gv.compare_outputs(host, qemu)
    print(
        f"{vec.stem}: {cmp.floats_identical}/{cmp.floats} floats bit-identical, "
        f"worst {cmp.worst:.2e} of scale "
        f"({cmp.worst_where})"
    )
    assert cmp.ok(), cmp.problems
    # every core call was measured, and none came near the end of the painted stack
    c = gv.read_costs(cost)
    assert len(c.calls) == sum(1 for op, _ in gv.read_records(qemu) if op != gv.OP["CAL_SPIN"])
    assert int(c.calls["b"].max()) < c.meta["stack_bytes"] // 2


@pytest.mark.parametrize("vec", VECTORS, ids=[v.stem for v in VECTORS])
def test_committed_host_outputs_are_current(builds, run_dir, vec):
    fresh = run_dir / f"{vec.stem}.fresh.mcao"
    gv.run_host(builds["host"], vec, fresh)
    cmp = gv.compare_outputs(vec.with_suffix(".mcao"), fresh)
    assert cmp.ok(), (
        f"{vec.with_suffix('.mcao').name} no longer matches the core: review the change and "
        f"regenerate with `python scripts/gen_vectors.py`: {cmp.problems}"
    )

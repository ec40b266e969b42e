"""What the golden vectors (``tests/vectors``, ``scripts/gen_vectors.py``) run of the C core, and that
the vectors made from simulator recordings are those recordings.

The M4F runs every vector under QEMU bit for bit as the host replay does (``test_firmware.py``), so
the vectors are what the target build is checked on. Measured here with a gcov build of the host
replay (``scripts/vector_coverage.py``): every robust mode's own code runs (``nav_modes``), and so do
the rules of fuzzy rows that the 9 s flights never reach (``nav_rows_*``: the taken flag, the release
by the held fixes' positions, the IMU increments past the history's newest entry on fixes without
latency; docs/ALGORITHMS.md 8, GPS steps 3-4), and the INS's GNSS outlier handling (``ins_outliers``).
Host only: needs cmake and gcov (CI has both).
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from mcahrs import core

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))
import gen_vectors as gv  # noqa: E402
import vector_coverage as vc  # noqa: E402

MISSING = [t for t in ("cmake", "gcov") if shutil.which(t) is None]
if MISSING and os.environ.get("CI"):
    raise RuntimeError(f"CI must run the vector coverage test, but these are missing: {', '.join(MISSING)}")


@pytest.fixture(scope="module")
def cov() -> dict[str, vc.FileCoverage]:
    if MISSING:
        pytest.skip(f"needs {', '.join(MISSING)}")
    return vc.measure(build_dir=ROOT / "build" / "test-fw-cov")


def test_vectors_run_every_robust_mode(cov: dict[str, vc.FileCoverage]) -> None:
    """FTA's inflation, AKF's R and Q scaling, the fuzzy detector, IGG-III's weights (ALGORITHMS.md 5),
    and GPS step 4's return at the end of a position fault the whole-update modes took in. Before
    nav_modes the vectors ran fuzzy rows and the plain filter only, and none of these."""
    robust, nav = cov["mca_robust.c"].functions, cov["mca_nav.c"].functions
    for fn in ("plan_fta", "plan_akf", "akf_row", "akf_q_scale", "plan_fuzzy", "plan_igg", "igg_weight"):
        assert robust[fn] > 0, f"no vector runs {fn} (mca_robust.c)"
    assert nav["pos_return"] > 0, "no vector runs GPS step 4's return (pos_return, mca_nav.c)"


def test_vectors_reach_the_fuzzy_rows_rules(cov: dict[str, vc.FileCoverage]) -> None:
    """The rules of GPS steps 3-4 that only the nav_rows_* vectors reach: the line and, where the rule
    is one arm of a condition, every branch of that line taken."""
    nav = cov["mca_nav.c"]
    # the taken flag: a held fix whose N and E position rows both went in (nav_rows_taken_2hz)
    taken = nav.line_of("nav->step_flags |= STEP_PIN;")
    assert nav.lines[taken] > 0, "no vector sets the taken flag"
    # the release by the positions (no_step) and the end of a fault (STEP_RET) (nav_rows_release_2hz)
    end = nav.line_of("nav->step_flags = (uint8_t)(no_step ? nav->step_flags : nav->step_flags | STEP_RET);")
    assert nav.branches[end] and all(b > 0 for b in nav.branches[end]), nav.branches[end]
    # the increments from the newest history entry to a fix after it (nav_rows_jitter)
    newest = nav.line_of("integrate(nav, e, -prev, inc);")
    assert nav.lines[newest] > 0, "no vector has a fix after the history's newest entry"


def test_vectors_run_the_ins_outlier_handling(cov: dict[str, vc.FileCoverage]) -> None:
    """The INS's GNSS blocks held out, tested on their own and reset by the lock-up guard
    (ALGORITHMS.md 10, GNSS update step 5; ins_outliers): ins_fixedwing_turns has no fault."""
    ins = cov["mca_ins.c"].functions
    for fn in ("gnss_hold_out", "gnss_block_t", "gnss_reset_block"):
        assert ins[fn] > 0, f"no vector runs {fn} (mca_ins.c)"


# vector -> (its recording and configuration, the Python replay of the two, the op family)
RECORDING_VECTORS = {
    **{name: ((lambda name=name: gv.rows_recording(name)), core.replay, "NAV") for name in gv.ROWS_VECTORS},
    "ins_outliers": (gv.ins_outliers_recording, core.ins_replay, "INS"),
}


@pytest.mark.parametrize("name", list(RECORDING_VECTORS))
def test_recording_vectors_replay_as_core_replay(name: str) -> None:
    """A vector made from a simulator recording is that recording: the committed host outputs after
    each IMU step are ``core.replay``'s (``core.ins_replay``'s) rows bit for bit (the same events in the
    same order, the same configuration through NAV_INIT_CONFIG's or INS_INIT_CONFIG's bytes)."""
    make, replay, family = RECORDING_VECTORS[name]
    rec, cfg = make()
    ref = replay(rec, cfg)
    rows, k, prev = [], -1, None
    for op, payload in gv.read_records(gv.VECTOR_DIR / f"{name}.mcao"):
        if op == gv.OP[f"{family}_OUTPUT"] and prev == gv.OP[f"{family}_IMU"]:
            rows.append((k, np.frombuffer(payload, gv.out_dtype(op))[0]))
        k += op == gv.OP[f"{family}_IMU"]
        prev = op
    assert len(rows) >= len(rec.imu) // gv.OUT_EVERY
    idx = np.array([i for i, _ in rows])
    out = np.array([o for _, o in rows])
    assert np.array_equal(out["t_us"], ref["t_us"][idx] + gv.ROWS_T0_US)
    fields = ("q_nb", "euler_rad", "pos_ned_m", "vel_ned_mps", "flags")
    for field in fields + (("acc_ned_mps2",) if family == "NAV" else ("p_diag", "gyro_bias_rps")):
        assert np.array_equal(out[field], ref[field][idx]), field

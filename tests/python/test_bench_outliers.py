"""The outlier benchmark's fault bookkeeping (benchmarks/bench_outliers.py): every injected fault
fix falls in exactly one fault class, and a class holds only faults of its kind and size, so the
per-class detection it prints counts what its name says."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_outliers.py"


@pytest.fixture(scope="module")
def bench():  # noqa: ANN201 - the benchmark module
    spec = importlib.util.spec_from_file_location("bench_outliers", _PATH)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["bench_outliers"] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("seed", [1, 7, 9, 40])
def test_every_fault_fix_has_one_class_of_its_kind_and_size(bench, seed: int) -> None:
    t_fix_s = np.arange(0.0, 900.0, 0.2)
    faults = bench.plan_faults(t_fix_s, 900.0, np.random.default_rng(seed + 1000))
    cls = bench.fault_classes(faults)
    np.testing.assert_array_equal(cls >= 0, faults.faulty)
    v = np.hypot(faults.vel_ned_mps[:, 0], faults.vel_ned_mps[:, 1])
    p = np.hypot(faults.pos_ned_m[:, 0], faults.pos_ned_m[:, 1])
    for c, name in enumerate(bench.FAULT_CLASSES):
        sel = cls == c
        kind = {"single": 1, "burst": 2, "100 s": 3}[name.split(",")[0]]
        assert np.all(faults.kind[sel] == kind), name
        if "velocity" in name:
            lo, hi = (1.0, 2.0) if "1-2 m/s" in name else (2.0, 5.0)
            assert np.all((v[sel] >= lo) & (v[sel] < hi + 1e-9)), name
        else:
            assert np.all(v[sel] == 0.0), name
        if "position" in name or "both" in name:
            assert np.all(p[sel] > 0.0), name
            if "5-20 m" in name:
                assert np.all(p[sel] < 20.0), name
            if "20-50 m" in name:
                assert np.all(p[sel] >= 20.0), name
        else:
            assert np.all(p[sel] == 0.0), name


def test_class_counts_add_up_to_the_detection_counts(bench) -> None:
    """score(): the per-class flagged and faulty fixes sum to the detected and faulty fixes."""
    t_fix_s = np.arange(0.0, 900.0, 0.2)
    faults = bench.plan_faults(t_fix_s, 900.0, np.random.default_rng(1003))
    rng = np.random.default_rng(5)
    flags = rng.random(t_fix_s.size) < 0.7
    valid = rng.random(t_fix_s.size) < 0.95
    det = bench.score(flags, faults, valid)
    assert sum(a for a, _ in det.by_class) == det.detected
    assert sum(b for _, b in det.by_class) == det.detected + det.missed
    both = bench.sum_classes([det.by_class, det.by_class])
    assert both == [(2 * a, 2 * b) for a, b in det.by_class]


def test_set_overrides_every_cs_run_after_the_profile(bench, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--set`` (NAV_OVERRIDES) reaches the configuration of every CS + gravity profile, after the
    profile's own overrides and the receiver model; without it the defaults stand."""
    from mcahrs import core

    res = type("Res", (), {"params": type("P", (), {"gps_rate_hz": 5.0})()})()
    monkeypatch.setattr(bench, "cs_receiver_model", lambda _res: {})
    default = core.nav_config("fixedwing").imu_acc_sigma_mps2
    assert bench.nav_cfg("fixedwing", "fuzzy-rows", False, res).imu_acc_sigma_mps2 == default
    monkeypatch.setitem(bench.NAV_OVERRIDES, "imu_acc_sigma_mps2", 0.125)
    monkeypatch.setitem(bench.NAV_OVERRIDES, "cs_h.coast", 0)
    for profile in ("plain", "fuzzy-rows"):
        cfg = bench.nav_cfg("fixedwing", profile, False, res)
        assert cfg.imu_acc_sigma_mps2 == 0.125, profile
        assert cfg.cs_h.coast == 0, profile  # after fuzzy-rows' coast = 1
    assert bench.nav_cfg("fixedwing", "fuzzy-rows", False, res).cs_h.robust.fuzzy_reject == 2


def test_two_hz_velocity_spike_does_not_start_a_position_hold(bench) -> None:
    """ALGORITHMS.md 8, GPS step 4, fuzzy rows' position hold: the 4.1 m/s single velocity spike of
    ``bench_outliers.py --sim gps_rate_hz=2`` seed 23 at 144.0 s (the fixed-wing), which the step test
    holds for its one fix. The trapezoids of that fix and of the one after it carried the spike's
    velocity into the hold's anchor, 2 m of its 0.5 s intervals, and the position hold then held the
    clean fixes until the next single fault at 156.0 s: 23 false alarms on every vehicle (measured
    before session 32). With the CS's predicted change on those two fixes, only the spike's fix
    alarms."""
    res = bench.scenario("fixedwing_turns", seed=23, duration_s=900.0, gps_rate_hz=2.0)
    rec = res.recording
    t = rec.gnss["t_us"] * 1e-6
    faults = bench.plan_faults(t, 900.0, np.random.default_rng(23 + 1000))
    spike = int(np.argmin(np.abs(t - 144.0)))
    assert faults.kind[spike] == 1 and np.hypot(*faults.vel_ned_mps[spike, :2]) > 4.0  # the scenario
    cfg = bench.nav_cfg("fixedwing", "fuzzy-rows", False, res)
    run = bench.replay(bench.inject(rec, faults), res, cfg)
    flags = bench.mode_flags(bench.profile_rule(bench.MODES[-1][1], "fuzzy-rows"), run)
    after = (t > 144.2) & (t < 155.9)
    print(flags[spike], flags[after].sum())
    assert flags[spike]
    assert not flags[after].any()


def test_a_receiver_without_latency_meets_the_goals(bench) -> None:
    """ALGORITHMS.md 8, GPS step 3, the increments past the newest history entry: the fixed-wing of seed
    1 with the fixes' latency 0 and the IMU times off by up to 0.6 ms (``--sim gps_latency_us=0 --sim
    imu_time_jitter_us=600``, a receiver that stamps its fixes at receipt, as the real car drive's).
    With the newest entry held for one spacing about a tenth of the fixes had no increments, so no
    IMU-aided test and no step test: fuzzy rows detected 80.2 % of the faulty fixes, raised 90 false
    alarms, and roll/pitch RMS was 1.44 times the outlier-free run's (measured before session 33).
    Held for two spacings, the issue's goals: detection 100 %, no false alarm, 1.07x."""
    sim = {"gps_latency_us": 0, "imu_time_jitter_us": 600}
    res = bench.scenario("fixedwing_turns", seed=1, duration_s=900.0, **sim)
    rec = res.recording
    faults = bench.plan_faults(rec.gnss["t_us"] * 1e-6, 900.0, np.random.default_rng(1 + 1000))
    cfg = bench.nav_cfg("fixedwing", "fuzzy-rows", False, res)
    clean = bench.replay(rec, res, cfg)
    run = bench.replay(bench.inject(rec, faults), res, cfg)
    rule = bench.profile_rule(bench.MODES[-1][1], "fuzzy-rows")
    sc = bench.score(bench.mode_flags(rule, run), faults, run.valid)
    ratio = bench.rms(run.rp_err[run.window]) / bench.rms(clean.rp_err[clean.window])
    print(sc.detected, sc.missed, sc.false_alarms, ratio)
    assert sc.detected >= 0.98 * (sc.detected + sc.missed)
    assert sc.false_alarms <= 10
    assert ratio <= 1.2

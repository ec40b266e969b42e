"""The C navigation filter (float32, ``core.replay``) against the float64 golden model
(``golden.nav.run``), step by step: every IMU output row of every simulator scenario
(docs/ALGORITHMS.md 7-9, DESIGN.md 8 "Golden model vs C").

Both sides are built from the same preset name and the same overrides, and their
configurations are first asserted equal field by field (this catches drift between the C
preset table and the golden one). Recordings are shortened (60-120 s) to keep the file fast.

Tolerances. Continuous quantities: the C core is float32 (eps 6e-8) in a stable filter, so
its gap to float64 stays small and does not grow; each bound below is a few times the
largest gap measured over the cases here (the numbers are in the comments of ``TOL``).
Discrete events (an observation gate or threshold) can flip on a float32 rounding: they are
counted, the count is bounded (see ``MAX_DISCRETE``), and the continuous comparison stops at
the first one rather than hiding it behind a loose tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np
import pytest

from mcahrs import core, sim
from mcahrs.golden import attitude as gatt
from mcahrs.golden import cs as gcs
from mcahrs.golden import nav as gnav
from mcahrs.samples import GNSS_HAS_ALT, GNSS_HAS_VEL_D, GNSS_HAS_VEL_NE, Recording

# --------------------------------------------------------------------------------------
# Cases
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One comparison: a simulator scenario, a preset, and overrides applied to both sides."""

    scenario: str
    preset: str
    duration_s: float
    sim_kw: dict[str, Any] = field(default_factory=dict)
    overrides: dict[str, Any] = field(default_factory=dict)  # top-level config fields
    seed: int = 1
    faults: bool = False  # inject bad and edge-case samples (_with_faults)
    nan_velocity: bool = False  # one fix with a NaN east velocity flagged present


CASES: dict[str, Case] = {
    # Ground vehicle, yaw from course over ground, each compensation mode.
    "car_cs": Case("car_accel_brake", "ground", 60.0),
    "car_plain": Case("car_accel_brake", "ground", 60.0, overrides={"comp_mode": 0}),
    "car_gpsdiff": Case("car_accel_brake", "ground", 60.0, overrides={"comp_mode": 2}),
    # Fixed wing in coordinated turns (aligned in the 10 s of steady straight flight first).
    "fixedwing_turns": Case("fixedwing_turns", "fixedwing", 90.0),
    # Multirotor, yaw from the magnetometer, no centripetal term.
    "multirotor_mag": Case("multirotor_aggressive", "multirotor", 60.0),
    # GPS outages of 30 s (> CS dt_max 10 s: re-initialisation at the first fix after it):
    # lost-GPS observations with the decaying CS acceleration and the centripetal term.
    "outage_fixedwing": Case("gps_outage", "fixedwing", 100.0, {"vehicle": "fixedwing", "outage_s": 30.0}),
    "outage_car_gpsdiff": Case(
        "gps_outage", "ground", 100.0, {"vehicle": "car", "outage_s": 30.0}, {"comp_mode": 2}
    ),
    "outage_multirotor": Case("gps_outage", "multirotor", 100.0, {"vehicle": "multirotor", "outage_s": 30.0}),
    # Short outages (longer than gps_timeout, shorter than the CS dt_max) in turns: the CS
    # predicts across them; in mode 2 the first fix after one has no usable previous fix.
    "short_outages_cs": Case(
        "fixedwing_turns", "fixedwing", 80.0, {"gps_outages": ((25.0, 31.0), (50.0, 53.0))}
    ),
    "short_outages_gpsdiff": Case(
        "fixedwing_turns", "fixedwing", 80.0, {"gps_outages": ((25.0, 31.0), (50.0, 53.0))}, {"comp_mode": 2}
    ),
    # Bad and edge-case inputs injected (statuses, re-anchoring, saturation, defaults, zero mag).
    "faults_car": Case("car_accel_brake", "ground", 60.0, faults=True),
    "faults_multirotor": Case("multirotor_aggressive", "multirotor", 60.0, faults=True),
    "nan_velocity_fix": Case("car_accel_brake", "ground", 40.0, nan_velocity=True),
    # The receiver model (ALGORITHMS.md 8, GPS step 4): R from the white parts, below the
    # simulator's reported 2.52 / 5.02 m.
    "car_receiver_model": Case(
        "car_accel_brake", "ground", 60.0, overrides={"gps_pos_white_m": 0.3, "gps_alt_white_m": 0.5}
    ),
    # At rest: no course over ground (speed 0), yaw unobserved, roll/pitch only.
    "static": Case("static", "ground", 60.0, {"roll_deg": 5.0, "pitch_deg": -3.0, "yaw_deg": 40.0}),
    # Constant velocity from t = 0 (a car never at rest, aligned while moving straight).
    "steady_car": Case("steady", "ground", 60.0, {"vehicle": "car", "speed_mps": 15.0}),
}


def _with_nan_velocity(rec: Recording) -> Recording:
    """A copy with one fix whose east velocity is NaN although flagged present (NONFINITE)."""
    gn = rec.gnss.copy()
    gn["vel_ned_mps"][len(gn) // 4 + 6, 1] = math.nan
    return Recording(rec.name + "+nan_velocity", rec.imu, gn, rec.mag, rec.ref, rec.meta)


def _with_faults(rec: Recording) -> Recording:
    """A copy of a recording with bad and edge-case samples injected at fixed places."""
    imu, gn, mag = rec.imu.copy(), rec.gnss.copy(), rec.mag.copy()
    n = len(imu)
    imu["gyro_rps"][n // 3, 0] = math.nan  # NONFINITE, nothing changes
    imu["accel_mps2"][n // 3 + 50, 1] = math.inf  # NONFINITE
    imu["accel_mps2"][n // 2, 2] = -200.0  # saturated (>= 156.9): sticky flag, its entry skipped
    imu["t_us"][n // 2 + 400] = imu["t_us"][n // 2 + 399]  # repeated time: TIME_BACKWARDS
    gap = slice(2 * n // 3, 2 * n // 3 + 60)  # 150 ms without IMU: BAD_DT and re-anchor
    imu = np.delete(imu, np.arange(n)[gap])
    k = len(gn)
    gn["fix_type"][k // 4] = 1  # BAD_ARG
    gn["lat_e7"][k // 4 + 3] = 900_000_001  # RANGE
    gn["t_us"][k // 4 + 9] = gn["t_us"][k // 4 + 8]  # same validity time: TIME_BACKWARDS
    gn["h_acc_m"][k // 3 : k // 3 + 10] = math.nan  # defaults used
    gn["s_acc_mps"][k // 3 + 5 : k // 3 + 15] = -1.0  # <= 0: default (COG sigma too)
    gn["v_acc_m"][k // 3 + 10 : k // 3 + 20] = 0.0
    gn["flags"][k // 2 : k // 2 + 5] &= ~np.uint8(GNSS_HAS_ALT)  # home altitude used, D axis skipped
    gn["flags"][k // 2 + 10 : k // 2 + 15] &= ~np.uint8(GNSS_HAS_VEL_D)
    gn["flags"][k // 2 + 20 : k // 2 + 25] &= ~np.uint8(GNSS_HAS_VEL_NE | GNSS_HAS_VEL_D)  # no COG
    gn["fix_type"][k // 2 + 30 : k // 2 + 35] = 2  # 2D: no D position row
    if len(mag):
        m = len(mag)
        mag["mag_b"][m // 3] = 0.0  # zero vector: skipped, OK
        mag["mag_b"][m // 3 + 7 : m // 3 + 9] = 0.0
        mag["mag_b"][m // 2, 2] = math.nan  # NONFINITE
    return Recording(rec.name + "+faults", imu, gn, mag, rec.ref, rec.meta)


# --------------------------------------------------------------------------------------
# Configurations: the same preset on both sides, asserted equal
# --------------------------------------------------------------------------------------

# Golden CsAxisConfig field -> C mca_cs_config_t field where the names differ.
_CS_NAMES = {"v0_var_m2s2": "v0_var_m2ps2", "a0_var_m2s4": "a0_var_m2ps4"}
# Float32 config values vs float64 ones: a constant such as radians(2)^2 computed in float32
# may differ from the float64 value rounded to float32 by an ulp or two (eps 6e-8).
_CFG_RTOL = 3e-7


def _config_mismatches(golden: Any, c: dict[str, Any], path: str, names: dict[str, str]) -> list[str]:
    """Field-by-field differences between a golden config dataclass and a C config dict."""
    bad: list[str] = []
    g_names = {names.get(f.name, f.name): f.name for f in fields(golden)}
    c_names = set(c) - {"robust"}
    for extra in sorted(c_names - set(g_names)):
        bad.append(f"{path}.{extra}: in the C config only")
    for extra in sorted(set(g_names) - c_names):
        bad.append(f"{path}.{extra}: in the golden config only")
    if "robust" in c and c["robust"]["mode"] != 0:
        # The golden navigation model makes plain section-1 updates only (golden/nav.py, choice 13).
        bad.append(f"{path}.robust.mode = {c['robust']['mode']}, only plain (0) is modelled")
    for c_name in sorted(c_names & set(g_names)):
        gv, cv = getattr(golden, g_names[c_name]), c[c_name]
        if isinstance(gv, (gcs.CsAxisConfig, gatt.AttConfig)):
            bad += _config_mismatches(gv, cv, f"{path}.{c_name}", _CS_NAMES)
        elif not math.isclose(float(gv), float(cv), rel_tol=_CFG_RTOL, abs_tol=0.0):
            bad.append(f"{path}.{c_name}: golden {gv!r} != C {cv!r}")
    return bad


@pytest.mark.parametrize("preset", ["ground", "fixedwing", "multirotor"])
def test_golden_and_c_presets_are_equal_field_by_field(preset: str) -> None:
    bad = _config_mismatches(
        gnav.NavConfig.preset(preset), core.config_dict(core.nav_config(preset)), preset, {}
    )
    assert not bad, "\n".join(bad)


def _configs(case: Case) -> tuple[Any, gnav.NavConfig]:
    c_cfg = core.nav_config(case.preset, **case.overrides)
    g_cfg = replace(gnav.NavConfig.preset(case.preset), **case.overrides)
    bad = _config_mismatches(g_cfg, core.config_dict(c_cfg), case.preset, {})
    assert not bad, "\n".join(bad)
    return c_cfg, g_cfg


# --------------------------------------------------------------------------------------
# Runs and gaps
# --------------------------------------------------------------------------------------

_RUNS: dict[str, tuple[dict[str, np.ndarray], dict[str, np.ndarray]]] = {}


def _runs(name: str) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """(C output, golden output) of a case, computed once per session."""
    if name not in _RUNS:
        case = CASES[name]
        rec = sim.scenario(case.scenario, seed=case.seed, duration_s=case.duration_s, **case.sim_kw).recording
        if case.faults:
            rec = _with_faults(rec)
        if case.nan_velocity:
            rec = _with_nan_velocity(rec)
        c_cfg, g_cfg = _configs(case)
        _RUNS[name] = (core.replay(rec, c_cfg), gnav.run(rec, g_cfg))
    return _RUNS[name]


def _attitude_gap_rad(q_c: np.ndarray, q_g: np.ndarray) -> np.ndarray:
    """Rotation angle of q_c^-1 (x) q_g per row (q_c renormalised in float64)."""
    qc = q_c.astype(np.float64)
    qc /= np.linalg.norm(qc, axis=1, keepdims=True)
    w1, v1 = qc[:, 0], -qc[:, 1:]  # conjugate of q_c
    w2, v2 = q_g[:, 0], q_g[:, 1:]
    w = w1 * w2 - np.sum(v1 * v2, axis=1)
    v = w1[:, None] * v2 + w2[:, None] * v1 + np.cross(v1, v2)
    return 2.0 * np.arctan2(np.linalg.norm(v, axis=1), np.abs(w))


def _rel(c: np.ndarray, g: np.ndarray, floor: float) -> float:
    """max |c - g| / max(|g|, floor) over the entries finite on both sides."""
    c = c.astype(np.float64)
    ok = np.isfinite(c) & np.isfinite(g)
    if not np.any(ok):
        return 0.0
    return float(np.max(np.abs(c[ok] - g[ok]) / np.maximum(np.abs(g[ok]), floor)))


# Per-IMU-row outputs of core.replay (the statuses of fixes and magnetometer samples are not rows).
_ROW_KEYS_C = set(core.OUT_C_DTYPE.names) | {"imu_status"}


def _gaps(c: dict[str, np.ndarray], g: dict[str, np.ndarray]) -> dict[str, float]:
    """Every measured gap between the C and golden outputs (one row per IMU sample)."""
    f64 = {k: v.astype(np.float64) for k, v in c.items() if v.dtype.kind == "f"}
    d_euler = f64["euler_rad"] - g["euler"]
    d_euler[:, 2] = np.angle(np.exp(1j * d_euler[:, 2]))  # yaw wraps at +-pi
    return {
        "attitude_rad": float(np.max(_attitude_gap_rad(c["q_nb"], g["q"]))),
        "euler_rad": float(np.max(np.abs(d_euler))),
        "gyro_bias_rps": float(np.max(np.abs(f64["gyro_bias_rps"] - g["gyro_bias"]))),
        "pos_m": float(np.max(np.abs(f64["pos_ned_m"] - g["pos_ned"]))),
        "vel_mps": float(np.max(np.abs(f64["vel_ned_mps"] - g["vel_ned"]))),
        "acc_mps2": float(np.max(np.abs(f64["acc_ned_mps2"] - g["acc_ned"]))),
        "att_var_rel": _rel(c["att_var"], g["att_P_diag"], 1e-12),
        "cs_var_rel": _rel(c["cs_var"], g["cs_P_diag"], 1e-12),
        "rp_T_rel": _rel(c["rp_t"], g["rp_T"], 1.0),
        "gps_T_rel": _rel(c["gps_t"], g["gps_T"], 1.0),
    }


def _events(diff: np.ndarray) -> np.ndarray:
    """Rows where a per-row difference (counter offset, flag XOR) takes a new nonzero value."""
    prev = np.concatenate([[0], diff[:-1]])
    return np.flatnonzero((diff != 0) & (diff != prev))


def _discrete(c: dict[str, np.ndarray], g: dict[str, np.ndarray]) -> tuple[dict[str, int], int]:
    """Discrete differences, counted as events (a flip that persists is one event), and the
    first row at which any observation decision differs (len(rows) when none does)."""
    n = len(g["t_us"])
    made = _events(c["n_grav_obs"].astype(np.int64) - g["n_grav_made"])
    skipped = _events(c["n_grav_skip"].astype(np.int64) - g["n_grav_skipped"])
    flags = _events(c["flags"].astype(np.int64) ^ g["flags"].astype(np.int64))
    first = min([n] + [int(e[0]) for e in (made, skipped, flags) if len(e)])
    counts = {
        "t_us": int(np.count_nonzero(c["t_us"].astype(np.int64) != g["t_us"])),
        "grav_made_events": len(made),
        "grav_skipped_events": len(skipped),
        "flag_events": len(flags),
        "nan_pattern_T": int(
            np.count_nonzero(np.isnan(c["rp_t"]) != np.isnan(g["rp_T"]))
            + np.count_nonzero(np.isnan(c["gps_t"]) != np.isnan(g["gps_T"]))
        ),
        "imu_status": int(np.count_nonzero(c["imu_status"].astype(np.int64) != g["imu_status"])),
        "gps_status": int(np.count_nonzero(c["gps_status"].astype(np.int64) != g["gps_status"])),
        "mag_status": int(np.count_nonzero(c["mag_status"].astype(np.int64) != g["mag_status"])),
    }
    return counts, first


# Largest gap allowed on any row of any case, with the reason. "measured": the largest over the
# passing cases above (seed 1). A spec change that either side misses shows up orders of
# magnitude above these (checked by hand: dropping the level-only roll/pitch correction gives
# 0.08 rad of attitude, dropping the lost-GPS centripetal term 0.06 rad, a 1.5x yaw-alignment
# variance 0.33 relative on the attitude P).
TOL: dict[str, float] = {
    # float32 quaternion in a stable filter: ~1e-7 per step, corrected by every observation;
    # measured 3.2e-5 rad (7.7e-5 before the structured attitude covariance predict).
    "attitude_rad": 3e-4,
    "euler_rad": 3e-4,  # the same error seen as roll, pitch, yaw (measured 2.8e-5)
    # bias = sum of float32 corrections of the gain; measured 2.2e-6 rad/s.
    "gyro_bias_rps": 1e-5,
    # float32 NED position: ulp 6e-5 m at 1 km, plus the CS state carried in float32 and the
    # constant-acceleration extrapolation to IMU time; measured 2.0e-3 m (2 km from home).
    "pos_m": 5e-3,
    "vel_mps": 3e-4,  # measured 1.3e-4 m/s (extrapolated after a 30 s outage re-initialisation)
    "acc_mps2": 5e-5,  # measured 1.0e-5 m/s^2
    # Attitude P diagonal, relative: the per-step process noise of an unobserved state (z gyro
    # bias at rest: +3e-7 relative per step at 400 Hz) is rounded to a few float32 ulps each
    # step, a systematic drift over 24 000 steps; measured 9.8e-4 (static), <= 3.1e-4 elsewhere.
    "att_var_rel": 3e-3,
    # CS P in float32. The C evaluates Joseph expanded, P - K U' - U K' + K S K' (O(n^2 m)); when a
    # fix after an outage shrinks P by ~1e3 that sum cancels to eps * P / P+ ~ 1e-4 (measured 5.8e-5)
    "cs_var_rel": 2e-4,
    # NIS = nu^T C^-1 nu with nu a small difference of float32 angles (relative to max(T, 1));
    # measured 7.5e-4 (fixedwing_turns).
    "rp_T_rel": 5e-3,
    # GPS NIS, since the IMU-aided test (ALGORITHMS.md 8, GPS step 3) the aided one: its velocity
    # variance (~0.012 m^2/s^2) is ~5x below the CS's own, so float32 velocity rounding (3e-5 m/s
    # at 30 m/s) moves T by ~2 nu dnu / C = 5e-4; measured 5.8e-4 (6.4e-5 on the CS's own T)
    "gps_T_rel": 1.5e-3,
}

# Discrete differences allowed per case, as events.
MAX_DISCRETE: dict[str, int] = {
    "t_us": 0,  # integer time, copied: must be identical
    # Observation decisions that read a float: the gravity gate (|g_b| in [0.5 g, 1.5 g]), the
    # tilt limit, the course-over-ground speed threshold, the alignment stillness test. One can
    # flip when its value lands within a float32 rounding (~1e-7 relative) of the threshold:
    # allow one such event per case (measured: 0 in every case). The history-entry choice, the
    # timers and the mode-2 usability test are integer-microsecond decisions and cannot flip.
    "grav_made_events": 1,
    "grav_skipped_events": 1,
    "flag_events": 1,
    "nan_pattern_T": 0,  # NaN until first set (ALGORITHMS.md 8, output): same rows on both sides
    "imu_status": 0,  # statuses are decided on integer times and finiteness: never a rounding
    "gps_status": 0,
    "mag_status": 0,
}


# Comparisons where the C path disagrees with the spec (reported to the lead; the golden follows
# ALGORITHMS.md). The C side was not read: each diagnosis is from the outputs and the public API.
def _case_params() -> list:
    # Two cases once found C-side deviations (course observation skipped after a skipped
    # differencing observation; a flagged NaN velocity passed to the C as 0 by core.gnss_to_c);
    # both are fixed and the cases are plain comparisons now.
    return list(CASES)


@pytest.mark.parametrize("name", _case_params())
def test_c_matches_golden_step_by_step(name: str) -> None:
    c, g = _runs(name)
    disc, first = _discrete(c, g)
    # After a flipped observation decision the two filters legitimately part (by the size of one
    # observation): the continuous comparison covers the rows before it (all rows when none).
    rows = slice(0, first)
    gaps = _gaps({k: v[rows] for k, v in c.items() if k in _ROW_KEYS_C}, {k: v[rows] for k, v in g.items()})
    print(f"\n{name}: " + ", ".join(f"{k} {v:.3g}" for k, v in gaps.items()))
    print(
        f"{name}: first differing decision at row {first} of {len(g['t_us'])}; "
        + ", ".join(f"{k} {v}" for k, v in disc.items())
    )
    over_d = {k: v for k, v in disc.items() if v > MAX_DISCRETE[k]}
    assert not over_d, f"{name}: discrete differences {over_d} (allowed {MAX_DISCRETE})"
    over = {k: v for k, v in gaps.items() if not v <= TOL[k]}
    assert not over, f"{name}: continuous gaps over tolerance {over} (tolerances {TOL})"

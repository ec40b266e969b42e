"""Real-data evaluation: ``mcahrs evaluate`` and ``mcahrs convert``.

``evaluate LOG`` loads a recording (:func:`mcahrs.io.loaders.load`: PX4 ULog, comma2k19 segment,
RTKLIB car drive) and runs on the same samples:

1. MCAHRS: the C core through cffi (:func:`mcahrs.core.replay`) and its float64 golden model
   (:func:`mcahrs.golden.nav.run`); their roll/pitch agreement on the log is reported;
2. compensation off (``comp_mode`` 0) and 3. GPS velocity differencing (``comp_mode`` 2), same preset;
4. the IMU-only filters of :mod:`mcahrs.baselines` (VQF, x-io Fusion);
5. the 15-state INS when :mod:`mcahrs.core` exposes one (``ins_replay``, with ``ins_config(preset)``
   when present), else a note.

One configuration per vehicle class: the core presets as they are (``--preset auto`` takes it from
the file type), never tuned per log.

Reference handling (roll and pitch only; yaw is not compared):

* the reference quaternion (EKF2 ``vehicle_attitude`` for ULog, the fused pose for comma2k19,
  which is the device's own attitude, so it is compared directly) is slerped to the IMU times;
* the time offset between the reference and the IMU clock is measured by matching the
  reference's body rates (from successive quaternions) with the gyro averaged over the same
  intervals (:func:`estimate_ref_lag`), reported, and applied (``--ref-lag auto``, the default;
  or a value in seconds);
* the alignment period is dropped: the statistics start ``--settle`` seconds (default 5) after
  MCAHRS reports aligned, the same window for every method;
* errors are split into calm and maneuvering rows by the horizontal acceleration measured from
  the GNSS velocity: ``|v_NE(t + 0.5 s) - v_NE(t - 0.5 s)| / 1 s`` (a 1 s central difference,
  linear interpolation between fixes), maneuvering when above ``--threshold`` (0.5 m/s^2).

Without a reference (the car drive), the reference-free measures:

* **stop tilt**: at every stop (horizontal GNSS speed < 0.1 m/s for >= 2 s, after the settle
  time), each filter's mean roll/pitch over the first 0.5 s of the stop against the tilt of
  the accelerometer averaged over the whole stop (the levelled accelerometer, true to its bias);
* **gravity residual** (every recording): at every fix while moving (speed > 1 m/s),
  ``|g_b| - g`` with ``g_b = -(f - C_bn a_n)``, ``f`` the 20 ms mean specific force (one history entry) at the
  observation time the core uses, ``a_n`` the method's compensation (0, the CS acceleration
  after the fix update paired at ``t_fix - cs_lag``, or the velocity difference at ``t_fix``);
  its spread (std, p95 of the absolute value) shows how much maneuver is left in the
  observation. Filters without GNSS (IMU-only, compensation off) share the raw row.

``convert LOG --out STREAM`` writes a recording in the MCAHRS wire format (:mod:`mcahrs.io.wire`:
NMEA GGA/RMC/GSA/GST + ``$PMCAV`` per fix at its arrival, ``$PMCAI``/``$PMCAM`` per sample at its
time). Replaying the stream (:func:`mcahrs.io.read_file` then :func:`mcahrs.core.replay`) gives
the loader's result to the wire's precision: IMU and magnetometer values and times, fix validity
times, positions and fix types are exact; velocities and speed accuracy are rounded to 5e-7 m/s
and position accuracies to 5e-5 m (a few float32 ulps at most in what the core sees); a fix's
arrival time becomes the last IMU sample at or before it (the replay order of fixes and IMU
samples is unchanged; a magnetometer sample between the two moves after the fix). Fixes that
arrive before the first IMU sample cannot be timed on the IMU clock and are left out (counted;
the car drive has 14). Measured effect on the whole shared logs: roll/pitch differences below
3e-5 deg (the test asserts < 1e-3 deg on cuts, ``tests/python/test_evaluate.py``).
"""

from __future__ import annotations

import argparse
import csv
import datetime as _dt
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from mcahrs.samples import GNSS_HAS_VEL_NE, Recording
from mcahrs.sim.truth import quat_conj, quat_mul  # the one vectorised quaternion algebra

DEG = 180.0 / math.pi

#: Maneuver split: horizontal GNSS acceleration threshold (m/s^2) and central-difference window (s).
MANEUVER_THRESHOLD_MPS2 = 0.5
MANEUVER_WINDOW_S = 1.0
#: Statistics start this long after MCAHRS is aligned (s).
SETTLE_S = 5.0
#: Stops: horizontal speed below this (m/s) for at least STOP_MIN_S; filter read over STOP_EARLY_S.
STOP_SPEED_MPS = 0.1
STOP_MIN_S = 2.0
STOP_EARLY_S = 0.5
#: "Moving" for the gravity residual (m/s), as the car README counts it.
MOVING_SPEED_MPS = 1.0
#: Largest |reference lag| searched (s) and the search step (s).
REF_LAG_MAX_S = 0.5
REF_LAG_STEP_S = 0.001
#: Reference samples further apart than this are not interpolated across (s).
REF_MAX_GAP_S = 1.0
#: Below this median IMU rate a recording is not fit for strapdown integration (esc_status_log: 9.6 Hz).
MIN_IMU_RATE_HZ = 50.0
#: One history entry of the core (ALGORITHMS.md 8), the averaging of f in the gravity residual.
HIST_DT_S = 0.02

PRESET_NAMES = ("ground", "fixedwing", "multirotor")

#: Method names (rows of the tables).
MCAHRS = "MCAHRS (CS)"
COMP_OFF = "compensation off"
VELDIFF = "velocity differencing"
VQF = "VQF"
FUSION = "Fusion"
INS = "INS 15-state"


# ================================================================ quaternions and angles


def quat_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of unit quaternions (N, 4), shortest way."""
    q = np.where(q[:, :1] < 0, -q, q)
    v = q[:, 1:]
    s = np.linalg.norm(v, axis=1)
    ang = 2.0 * np.arctan2(s, q[:, 0])
    scale = np.where(s > 1e-12, ang / np.maximum(s, 1e-300), 2.0)
    return v * scale[:, None]


def quat_from_rotvec(r: np.ndarray) -> np.ndarray:
    """Unit quaternions of rotation vectors (N, 3)."""
    a = np.linalg.norm(r, axis=1)
    half = 0.5 * a
    k = np.where(a > 1e-12, np.sin(half) / np.maximum(a, 1e-300), 0.5)
    return np.concatenate([np.cos(half)[:, None], r * k[:, None]], axis=1)


def down_in_body(q_nb: np.ndarray) -> np.ndarray:
    """Third row of C_nb(q): the NED down axis in body FRD axes (N, 3)."""
    w, x, y, z = (q_nb[:, i] for i in range(4))
    return np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1)


def quat_roll_pitch(q_nb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ZYX roll and pitch (rad) of q_nb (N, 4); NaN rows stay NaN."""
    d = down_in_body(np.asarray(q_nb, np.float64))
    return np.arctan2(d[:, 1], d[:, 2]), np.arctan2(-d[:, 0], np.hypot(d[:, 1], d[:, 2]))


def tilt_from_specific_force(f_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Roll and pitch (rad) of the accelerometer at rest: the down axis is -f (DESIGN.md 4)."""
    f = np.atleast_2d(np.asarray(f_b, np.float64))
    return np.arctan2(-f[:, 1], -f[:, 2]), np.arctan2(f[:, 0], np.hypot(f[:, 1], f[:, 2]))


def wrap_pi(a: np.ndarray) -> np.ndarray:
    """Angle difference into [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


GYRO_DRIFT_HORIZONS_S = (2.0, 5.0, 10.0)
GYRO_DRIFT_STEP_S = 10.0  # starts of the gyro-only drift diagnostic, this far apart
GYRO_DRIFT_MAX_STARTS = 30


def gyro_only_drift(rec: Recording, out: dict[str, np.ndarray], starts_us: Sequence[int],
                    horizons_s: Sequence[float] = GYRO_DRIFT_HORIZONS_S) -> np.ndarray:
    """How far the gyro alone takes the attitude from the filter's: from the filter's attitude
    ``q_nb`` and gyro bias at each start, the gyro (minus that bias, each sample over its interval)
    integrated alone, against the filter's roll/pitch ``horizons_s`` later. Returns
    (len(starts_us), len(horizons_s)) of the worst of roll and pitch (deg); NaN where a horizon
    passes the end. What leaving the gravity observation out for that long costs (README, GNSS
    outliers: the flagged-fix rule of docs/ALGORITHMS.md 8, GPS step 6)."""
    t = rec.imu["t_us"].astype(np.int64)
    w = np.asarray(rec.imu["gyro_rps"], np.float64)
    res = np.full((len(starts_us), len(horizons_s)), np.nan)
    for k, t0 in enumerate(starts_us):
        i0 = int(np.searchsorted(t, int(t0)))
        if i0 >= len(t) or not np.all(np.isfinite(out["q_nb"][i0])):
            continue
        qw, qx, qy, qz = (float(v) for v in out["q_nb"][i0])
        b = [float(v) for v in out["gyro_bias_rps"][i0]]
        marks = [int(t[i0] + round(h * 1e6)) for h in horizons_s]
        j = 0
        for i in range(i0 + 1, len(t)):
            dt = (t[i] - t[i - 1]) * 1e-6
            vx, vy, vz = ((w[i, a] - b[a]) * dt for a in range(3))
            ang = math.sqrt(vx * vx + vy * vy + vz * vz)
            if ang > 0.0:
                c, sn = math.cos(0.5 * ang), math.sin(0.5 * ang) / ang
                dw, dx, dy, dz = c, vx * sn, vy * sn, vz * sn
                qw, qx, qy, qz = (qw * dw - qx * dx - qy * dy - qz * dz,
                                  qw * dx + qx * dw + qy * dz - qz * dy,
                                  qw * dy - qx * dz + qy * dw + qz * dx,
                                  qw * dz + qx * dy - qy * dx + qz * dw)
                nq = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
                qw, qx, qy, qz = qw / nq, qx / nq, qy / nq, qz / nq
            while j < len(marks) and t[i] >= marks[j]:
                q = np.array([[qw, qx, qy, qz], out["q_nb"][i].astype(np.float64)])
                r, p = quat_roll_pitch(q)
                res[k, j] = float(np.degrees(max(abs(wrap_pi(r[0] - r[1])), abs(p[0] - p[1]))))
                j += 1
            if j == len(marks):
                break
    return res


def interp_quat(t_src_us: np.ndarray, q_src: np.ndarray, t_us: np.ndarray,
                max_gap_s: float = REF_MAX_GAP_S) -> np.ndarray:
    """Slerp unit quaternions ``q_src`` (at ``t_src_us``) to the times ``t_us``.

    Rows outside the source span, or inside a gap longer than ``max_gap_s``, are NaN.
    """
    ts = np.asarray(t_src_us, np.int64)
    t = np.asarray(t_us, np.int64)
    q = np.asarray(q_src, np.float64)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    n = len(ts)
    out = np.full((len(t), 4), np.nan)
    if n < 2:
        return out
    i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, n - 2)
    t0, t1 = ts[i], ts[i + 1]
    ok = (t >= ts[0]) & (t <= ts[-1]) & ((t1 - t0) <= max_gap_s * 1e6)
    u = ((t - t0) / np.maximum(t1 - t0, 1)).astype(np.float64)[:, None]
    q0, q1 = q[i], q[i + 1]
    dot = np.sum(q0 * q1, axis=1)
    q1 = np.where(dot[:, None] < 0, -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))[:, None]
    sin_t = np.sin(theta)
    small = sin_t < 1e-9
    w0 = np.where(small, 1.0 - u, np.sin((1.0 - u) * theta) / np.where(small, 1.0, sin_t))
    w1 = np.where(small, u, np.sin(u * theta) / np.where(small, 1.0, sin_t))
    r = w0 * q0 + w1 * q1
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    out[ok] = r[ok]
    return out


# ================================================================ reference time alignment


def _gyro_integral(t_s: np.ndarray, gyro: np.ndarray, interval_mean: bool) -> np.ndarray:
    """Cumulative integral of the gyro at the IMU times. ``interval_mean``: each rate is the mean
    over the interval it ends (PX4's ``gyro_rad``), else a point sample (trapezoid rule)."""
    g = np.zeros((len(t_s), 3))
    step = gyro[1:] if interval_mean else 0.5 * (gyro[1:] + gyro[:-1])
    g[1:] = np.cumsum(step * np.diff(t_s)[:, None], axis=0)
    return g


def ref_body_rates(t_ref_us: np.ndarray, q_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean body rates between successive reference quaternions: (t_start_s, t_end_s, w (N-1, 3))."""
    t = np.asarray(t_ref_us, np.int64)
    q = np.asarray(q_ref, np.float64)
    dq = quat_mul(quat_conj(q[:-1]), q[1:])  # body at k -> body at k+1
    dt = np.diff(t) * 1e-6
    w = quat_rotvec(dq) / np.maximum(dt, 1e-9)[:, None]
    return t[:-1] * 1e-6, t[1:] * 1e-6, w


def estimate_ref_lag(
    imu: np.ndarray,
    ref: np.ndarray,
    max_lag_s: float = REF_LAG_MAX_S,
    step_s: float = REF_LAG_STEP_S,
    interval_mean: bool = False,
) -> tuple[float, dict[str, Any]]:
    """How late the reference's time stamps are on the IMU clock (s).

    The reference body rate over each interval between its samples (from the quaternions) is
    compared with the gyro averaged over the same interval moved by ``-lag``; the lag with the
    smallest squared difference (per-axis mean difference, i.e. gyro bias, removed) is refined
    by a parabola through its neighbours. Intervals longer than 0.5 s, and those whose rate
    difference at lag 0 exceeds both 20 median absolute deviations and 1 rad/s (reference
    resets) are left out.
    ``interval_mean`` says how the gyro samples are read (see :func:`_gyro_integral`); the wrong
    choice biases the lag by half an IMU interval. Resolution: about a millisecond.
    Returns ``(lag_s, info)``; ``lag_s`` is NaN when there is not enough overlap.
    """
    t0 = int(imu["t_us"][0])
    ti = (imu["t_us"].astype(np.int64) - t0) * 1e-6
    gi = _gyro_integral(ti, np.asarray(imu["gyro_rps"], np.float64), interval_mean)
    ta, tb, w = ref_body_rates(ref["t_us"].astype(np.int64) - t0, ref["q_nb"])
    keep = (tb - ta > 0) & (tb - ta < 0.5) & (ta - max_lag_s >= ti[0]) & (tb + max_lag_s <= ti[-1])
    ta, tb, w = ta[keep], tb[keep], w[keep]
    info: dict[str, Any] = {"intervals": int(len(ta))}
    if len(ta) < 20:
        return float("nan"), info

    def avg(lag: float) -> np.ndarray:
        a, b = ta - lag, tb - lag
        ga = np.stack([np.interp(a, ti, gi[:, k]) for k in range(3)], axis=1)
        gb = np.stack([np.interp(b, ti, gi[:, k]) for k in range(3)], axis=1)
        return (gb - ga) / (b - a)[:, None]

    d0 = w - avg(0.0)
    d0 -= np.median(d0, axis=0)
    mad = np.median(np.abs(d0), axis=0) + 1e-9
    good = np.all(np.abs(d0) <= np.maximum(20.0 * mad, 1.0), axis=1)
    info["intervals_dropped"] = int((~good).sum())
    wg = w[good]
    lags = np.arange(-max_lag_s, max_lag_s + 0.5 * step_s, step_s)
    cost = np.empty(len(lags))
    for j, lag in enumerate(lags):
        d = wg - avg(lag)[good]
        d -= d.mean(axis=0)
        cost[j] = float(np.sum(d * d))
    j = int(np.argmin(cost))
    lag = float(lags[j])
    if 0 < j < len(lags) - 1:
        c0, c1, c2 = cost[j - 1], cost[j], cost[j + 1]
        den = c0 - 2 * c1 + c2
        if den > 0:
            lag += 0.5 * step_s * (c0 - c2) / den
    info["at_edge"] = j in (0, len(lags) - 1)
    d = wg - avg(lag)[good]
    info["rate_mean_diff_rps"] = d.mean(axis=0).tolist()  # gyro bias the reference removed (about)
    info["rate_std_diff_rps"] = d.std(axis=0).tolist()
    info["cost_ratio_at_0"] = float(np.interp(0.0, lags, cost) / max(cost[j], 1e-300))
    return lag, info


def imu_is_interval_mean(rec: Recording) -> bool:
    """True when the loader says each IMU value is a mean over the interval ending at its time (ULog)."""
    return "mean" in str(rec.meta.get("imu_sample_meaning", ""))


# ================================================================ GNSS-derived quantities


def _gnss_vel(gnss: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t_us, v_NE (N, 2)) of the fixes with a finite north/east velocity."""
    ok = ((gnss["flags"] & GNSS_HAS_VEL_NE) != 0) & np.all(np.isfinite(gnss["vel_ned_mps"][:, :2]), axis=1)
    ok &= gnss["fix_type"] >= 2
    return gnss["t_us"][ok].astype(np.int64), np.asarray(gnss["vel_ned_mps"][ok, :2], np.float64)


def horizontal_accel(gnss: np.ndarray, t_us: np.ndarray, window_s: float = MANEUVER_WINDOW_S) -> np.ndarray:
    """|a_h| (m/s^2) at ``t_us`` from the GNSS velocity: a ``window_s`` central difference of the
    linearly interpolated NE velocity; NaN where the window leaves the fixes' span."""
    tf, v = _gnss_vel(gnss)
    t = np.asarray(t_us, np.int64)
    out = np.full(len(t), np.nan)
    if len(tf) < 2:
        return out
    h = 0.5 * window_s * 1e6
    lo, hi = t - h, t + h
    ok = (lo >= tf[0]) & (hi <= tf[-1])
    dv = np.stack([np.interp(hi, tf, v[:, k]) - np.interp(lo, tf, v[:, k]) for k in range(2)], axis=1)
    out[ok] = np.hypot(dv[ok, 0], dv[ok, 1]) / window_s
    return out


def detect_stops(gnss: np.ndarray, speed_max_mps: float = STOP_SPEED_MPS,
                 min_s: float = STOP_MIN_S) -> list[tuple[int, int]]:
    """Stops as (t_first_us, t_last_us) of runs of fixes with horizontal speed < ``speed_max_mps``
    lasting at least ``min_s``."""
    tf, v = _gnss_vel(gnss)
    still = np.hypot(v[:, 0], v[:, 1]) < speed_max_mps
    stops: list[tuple[int, int]] = []
    i, n = 0, len(tf)
    while i < n:
        if not still[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and still[j + 1]:
            j += 1
        if (tf[j] - tf[i]) * 1e-6 >= min_s:
            stops.append((int(tf[i]), int(tf[j])))
        i = j + 1
    return stops


# ================================================================ statistics


def err_stats(e_deg: np.ndarray) -> dict[str, float]:
    """n, mean, std, RMS, 95th percentile and max of |e| over the finite entries (deg)."""
    e = np.asarray(e_deg, np.float64)
    e = e[np.isfinite(e)]
    if len(e) == 0:
        return dict.fromkeys(("mean", "std", "rms", "p95", "max"), float("nan")) | {"n": 0}
    a = np.abs(e)
    return {
        "n": int(len(e)),
        "mean": float(e.mean()),
        "std": float(e.std()),
        "rms": float(np.sqrt(np.mean(e * e))),
        "p95": float(np.percentile(a, 95)),
        "max": float(a.max()),
    }


# ================================================================ recordings


def cut_recording(rec: Recording, start_s: float | None = None, duration_s: float | None = None) -> Recording:
    """The part of ``rec`` from ``start_s`` after its first IMU sample, ``duration_s`` long.

    IMU and magnetometer by sample time, fixes by arrival time; the reference keeps 1 s more on
    each side so that it can be interpolated over the whole cut.
    """
    if start_s is None and duration_s is None:
        return rec
    t0 = int(rec.imu["t_us"][0]) + int(round((start_s or 0.0) * 1e6))
    t1 = t0 + int(round(duration_s * 1e6)) if duration_s is not None else np.iinfo(np.int64).max
    imu = rec.imu[(rec.imu["t_us"] >= t0) & (rec.imu["t_us"] < t1)]
    gnss = rec.gnss[(rec.gnss["t_rx_us"] >= t0) & (rec.gnss["t_rx_us"] < t1)]
    mag = rec.mag[(rec.mag["t_us"] >= t0) & (rec.mag["t_us"] < t1)] if rec.mag is not None else rec.mag
    ref = None
    if rec.ref is not None:
        m = 1_000_000
        ref = rec.ref[(rec.ref["t_us"] >= t0 - m) & (rec.ref["t_us"] < t1 + m)]
    meta = dict(rec.meta)
    meta["cut"] = {"start_s": start_s or 0.0, "duration_s": duration_s}
    if len(imu) < 2:
        raise ValueError(f"{rec.name}: the cut start={start_s} duration={duration_s} has < 2 IMU samples")
    return Recording(rec.name, imu, gnss, mag, ref, meta)


def _ulog_mav_type(path: Path) -> int | None:
    try:
        from pyulog import ULog

        v = ULog(str(path), []).initial_parameters.get("MAV_TYPE")
        return None if v is None else int(v)
    except Exception:  # noqa: BLE001 - a preset guess must not fail the evaluation
        return None


def auto_preset(rec: Recording, path: str | Path | None = None) -> tuple[str, str]:
    """(preset, why) from the loader meta and file type: ULog multirotor -> multirotor, ULog
    fixed-wing (``MAV_TYPE`` 1) -> fixedwing; comma2k19 and the car drive -> ground."""
    src = rec.meta.get("source", "")
    if src == "ulog":
        mt = _ulog_mav_type(Path(path)) if path is not None and Path(path).is_file() else None
        if mt == 1:
            return "fixedwing", "ULog, MAV_TYPE 1 (fixed wing)"
        if mt in (2, 3, 4, 13, 14, 15):
            return "multirotor", f"ULog, MAV_TYPE {mt} (multirotor)"
        return "multirotor", f"ULog, MAV_TYPE {mt} (not fixed wing: multirotor assumed)"
    if src in ("comma2k19", "rtklib_car"):
        return "ground", f"{src}: road vehicle"
    return "ground", f"source {src or 'unknown'}: ground vehicle assumed"


def reference_kind(rec: Recording) -> str:
    """What the recording's reference is, in words."""
    src = rec.meta.get("source", "")
    if rec.ref is None or len(rec.ref) < 2:
        return "none"
    if src == "ulog":
        return "PX4 EKF2 attitude (vehicle_attitude)"
    if src == "comma2k19":
        return "comma2k19 fused pose (device attitude, mounting included)"
    return "recording's reference attitude"


# ================================================================ method runs


@dataclass
class MethodRun:
    """Roll/pitch of one method at every IMU sample (rad; NaN before it has an estimate)."""

    name: str
    roll: np.ndarray
    pitch: np.ndarray
    note: str = ""
    out: dict[str, np.ndarray] | None = None  # core output (MCAHRS runs)
    comp_mode: int | None = None


def run_core(rec: Recording, preset: str, comp_mode: int, robust: str | None = None) -> dict[str, np.ndarray]:
    """The C core on ``rec`` with a preset and only ``comp_mode`` changed, and with ``robust`` a
    robust profile (``core.robust_profile``, set up for the recording's median fix rate)."""
    from mcahrs import core

    over = {} if robust is None else core.robust_profile(robust, core.fix_rate_hz(rec))
    return core.replay(rec, core.nav_config(preset, comp_mode=comp_mode, **over))


def _core_run(name: str, rec: Recording, preset: str, comp_mode: int, robust: str | None = None) -> MethodRun:
    from mcahrs import core

    out = run_core(rec, preset, comp_mode, robust)
    e = out["euler_rad"].astype(np.float64)
    aligned = (out["flags"] & core.FLAG_BITS["aligned"]) != 0
    roll = np.where(aligned, e[:, 0], np.nan)
    pitch = np.where(aligned, e[:, 1], np.nan)
    how = f"C core, preset {preset}, comp_mode {comp_mode}" + (f", robust profile {robust}" if robust else "")
    return MethodRun(name, roll, pitch, how, out, comp_mode)


def run_golden(rec: Recording, preset: str) -> dict[str, np.ndarray]:
    """The float64 golden model with the same preset (comp_mode 1)."""
    from mcahrs.golden import nav as gnav

    return gnav.run(rec, replace(gnav.NavConfig.preset(preset), comp_mode=1))


def golden_agreement(c_out: dict[str, np.ndarray], g_out: dict[str, np.ndarray]) -> dict[str, float]:
    """RMS and max of C - golden roll and pitch (deg) over the rows where both are aligned."""
    from mcahrs import core

    ok = ((c_out["flags"] & core.FLAG_BITS["aligned"]) != 0) & ((g_out["flags"] & 1) != 0)
    d = c_out["euler_rad"][ok, :2].astype(np.float64) - g_out["euler"][ok, :2]
    d[:, 0] = wrap_pi(d[:, 0])
    d *= DEG
    if not len(d):
        return {"n": 0, "roll_rms": float("nan"), "roll_max": float("nan"),
                "pitch_rms": float("nan"), "pitch_max": float("nan")}
    return {
        "n": int(len(d)),
        "roll_rms": float(np.sqrt(np.mean(d[:, 0] ** 2))),
        "roll_max": float(np.abs(d[:, 0]).max()),
        "pitch_rms": float(np.sqrt(np.mean(d[:, 1] ** 2))),
        "pitch_max": float(np.abs(d[:, 1]).max()),
    }


# Floors of the receiver's reported accuracies for the INS on real recordings, PX4 EKF2's defaults
# (EKF2_GPS_P_NOISE 0.5 m, EKF2_GPS_V_NOISE 0.3 m/s). Real receivers report optimistic
# accuracies (the car's RTK fixes 1.4 cm, the PX4 log's speed accuracy 0.013 m/s): without the
# floors the INS's GNSS T is 20 (car) and 219 (PX4) in the median on 6 rows, and a robust mode
# rejects most real fixes. The simulator's receiver reports its true accuracy and runs without.
REAL_RECEIVER_FLOORS = {"gps_pos_noise_min_m": 0.5, "gps_vel_noise_min_mps": 0.3}

# Process noise of the INS on real recordings, PX4 EKF2's defaults (EKF2_GYR_NOISE 0.015 rad/s,
# EKF2_ACC_NOISE 0.35 m/s^2 a step of its 100 Hz prediction: densities 0.015 sqrt(0.01 s) and
# 0.35 sqrt(0.01 s)). The INS defaults are an IMU's white noise with margin, right for the
# simulator; a vehicle's IMU also sees vibration, coning and scale-factor errors at its rates. On
# the PX4 log with the defaults the fuzzy detector rejects 44 % of the fixes (the plain INS's
# GNSS T 4.2 in the median; 16 without the log's missing IMU samples put back); with these T is
# 1.5 and it rejects none (tests/python/test_ins.py).
REAL_IMU_NOISE = {"gyro_noise_rps": 1.5e-3, "accel_noise_mps2": 3.5e-2}

# What the INS runs real recordings with: both of the above.
REAL_INS = REAL_RECEIVER_FLOORS | REAL_IMU_NOISE


def run_ins(rec: Recording, preset: str) -> tuple[MethodRun, str]:
    """The 15-state INS of the C core on the same samples, with :data:`REAL_INS` (what it
    evaluates are real recordings); roll and pitch NaN until it is aligned."""
    from mcahrs import core

    out = core.ins_replay(rec, core.ins_config(preset, **REAL_INS))
    e = np.asarray(out["euler_rad"], np.float64)
    aligned = (np.asarray(out["flags"]) & core.INS_FLAG_BITS["aligned"]) != 0
    roll, pitch = np.where(aligned, e[:, 0], np.nan), np.where(aligned, e[:, 1], np.nan)
    how = f"core.ins_replay with core.ins_config({preset!r}) and EKF2's defaults {REAL_INS}"
    return MethodRun(INS, roll, pitch, how, dict(out)), f"15-state INS: {how} (C core, same samples)"


def _baseline_run(name: str, fn: Any, rec: Recording) -> tuple[MethodRun | None, str]:
    try:
        r = fn(rec)
    except ImportError as exc:
        return None, f"{name}: skipped, package missing ({exc}); pip install vqf imufusion"
    return MethodRun(name, r["roll_rad"], r["pitch_rad"], r["note"]), f"{name}: {r['note']}"


# ================================================================ reference-free measures


def _mean_in(t_us: np.ndarray, x: np.ndarray, a_us: int, b_us: int) -> np.ndarray:
    m = (t_us >= a_us) & (t_us <= b_us)
    return np.nanmean(x[m], axis=0) if m.any() else np.full(x.shape[1:], np.nan)


def stop_tilt(rec: Recording, runs: Sequence[MethodRun], stops: Sequence[tuple[int, int]],
              early_s: float = STOP_EARLY_S) -> list[dict[str, Any]]:
    """Per stop: accelerometer tilt averaged over the stop, and each method's mean roll/pitch over
    the first ``early_s`` of it minus that tilt (deg)."""
    t = rec.imu["t_us"].astype(np.int64)
    f = np.asarray(rec.imu["accel_mps2"], np.float64)
    rows = []
    for a, b in stops:
        fm = _mean_in(t, f, a, b)
        r0, p0 = (v[0] for v in tilt_from_specific_force(fm))
        row: dict[str, Any] = {"t0_us": a, "t1_us": b, "acc_roll_deg": r0 * DEG, "acc_pitch_deg": p0 * DEG,
                               "err": {}}
        e = int(a + early_s * 1e6)
        for run in runs:
            rp = _mean_in(t, np.stack([run.roll, run.pitch], axis=1), a, e)
            row["err"][run.name] = (float(wrap_pi(rp[0] - r0) * DEG), float((rp[1] - p0) * DEG))
        rows.append(row)
    return rows


def _hist_mean_f(t_us: np.ndarray, f: np.ndarray, t_end_us: np.ndarray) -> np.ndarray:
    """Mean specific force over the 20 ms ending at each ``t_end_us`` (one history entry)."""
    cs = np.concatenate([np.zeros((1, 3)), np.cumsum(f, axis=0)])
    hi = np.searchsorted(t_us, t_end_us, side="right")
    lo = np.searchsorted(t_us, t_end_us - int(HIST_DT_S * 1e6), side="right")
    n = np.maximum(hi - lo, 1)
    out = (cs[hi] - cs[lo]) / n[:, None]
    out[hi - lo <= 0] = np.nan
    return out


def _c_bn_times(q_nb: np.ndarray, a_n: np.ndarray) -> np.ndarray:
    """C_nb(q)^T a_n per row (NED vector into body axes)."""
    qc = quat_conj(q_nb)
    v = np.concatenate([np.zeros((len(a_n), 1)), a_n], axis=1)
    return quat_mul(quat_mul(qc, v), q_nb)[:, 1:]


def gravity_residual(rec: Recording, runs: Sequence[MethodRun], g_mps2: float, cs_lag_s: float,
                     t_from_us: int) -> dict[str, dict[str, float]]:
    """``|g_b| - g`` at the fixes while moving, per compensation (see the module docstring)."""
    t = rec.imu["t_us"].astype(np.int64)
    f = np.asarray(rec.imu["accel_mps2"], np.float64)
    gn = rec.gnss
    ok = ((gn["flags"] & GNSS_HAS_VEL_NE) != 0) & (gn["fix_type"] >= 2) & (gn["t_rx_us"] >= t_from_us)
    ok &= np.all(np.isfinite(gn["vel_ned_mps"][:, :2]), axis=1)
    gn = gn[ok]
    res: dict[str, dict[str, float]] = {}
    if len(gn) < 3:
        return res
    speed = np.hypot(gn["vel_ned_mps"][:, 0], gn["vel_ned_mps"][:, 1])
    drive = speed > MOVING_SPEED_MPS
    t_fix = gn["t_us"].astype(np.int64)
    t_rx = gn["t_rx_us"].astype(np.int64)

    def summary(dev: np.ndarray) -> dict[str, float]:
        d = dev[np.isfinite(dev)]
        if not len(d):
            return {"n": 0, "mean": float("nan"), "std": float("nan"), "p95": float("nan")}
        return {"n": int(len(d)), "mean": float(d.mean()), "std": float(d.std()),
                "p95": float(np.percentile(np.abs(d), 95))}

    raw = np.linalg.norm(_hist_mean_f(t, f, np.clip(t_rx, t[0], t[-1])), axis=1) - g_mps2
    res["raw (no compensation)"] = summary(raw[drive])
    for run in runs:
        if run.out is None or run.comp_mode not in (1, 2):
            continue
        q_all = run.out["q_nb"].astype(np.float64)
        if run.comp_mode == 1:
            t_d = t_fix - int(round(cs_lag_s * 1e6))
            row_after = np.clip(np.searchsorted(t, t_rx, side="left"), 0, len(t) - 1)
            a_n = run.out["acc_ned_mps2"][row_after].astype(np.float64)
        else:
            t_d = t_fix.copy()
            v = np.asarray(gn["vel_ned_mps"], np.float64)
            vd = np.where(np.isfinite(v[:, 2]), v[:, 2], 0.0)
            v = np.stack([v[:, 0], v[:, 1], vd], axis=1)
            a_n = np.full((len(gn), 3), np.nan)
            dt = np.diff(t_fix) * 1e-6
            a_n[1:] = np.diff(v, axis=0) / dt[:, None]
            if not np.all(np.isfinite(np.asarray(gn["vel_ned_mps"], np.float64)[:, 2])):
                a_n[:, 2] = 0.0  # no vertical velocity: the core compensates N/E only
        row_d = np.clip(np.searchsorted(t, t_d, side="right") - 1, 0, len(t) - 1)
        f_d = _hist_mean_f(t, f, t_d)
        g_b = -(f_d - _c_bn_times(q_all[row_d], a_n))
        dev = np.linalg.norm(g_b, axis=1) - g_mps2
        res[run.name] = summary(dev[drive])
    return res


# ================================================================ the evaluation


@dataclass
class Evaluation:
    """Everything ``evaluate`` computed for one recording (see :func:`evaluate`)."""

    name: str
    source: str
    preset: str
    preset_why: str
    ref_kind: str
    t_us: np.ndarray
    runs: list[MethodRun]
    notes: list[str] = field(default_factory=list)
    eval_mask: np.ndarray | None = None
    t_eval0_us: int = 0
    ref_roll: np.ndarray | None = None
    ref_pitch: np.ndarray | None = None
    ref_lag_s: float = float("nan")
    ref_lag_info: dict[str, Any] = field(default_factory=dict)
    man_acc: np.ndarray | None = None
    threshold_mps2: float = MANEUVER_THRESHOLD_MPS2
    stats: dict[str, dict[str, dict[str, dict[str, float]]]] = field(default_factory=dict)
    golden: dict[str, float] | None = None
    stops: list[dict[str, Any]] = field(default_factory=list)
    grav_res: dict[str, dict[str, float]] = field(default_factory=dict)
    imu_rate_hz: float = float("nan")
    diagnostics: dict[str, Any] = field(default_factory=dict)
    goals: list[str] = field(default_factory=list)
    robust: str | None = None  # the MCAHRS runs' robust profile (None: the preset's, plain)

    def run(self, name: str) -> MethodRun:
        return next(r for r in self.runs if r.name == name)




def evaluate(rec: Recording, preset: str = "auto", *, path: str | Path | None = None,
             settle_s: float = SETTLE_S, ref_lag: float | str = "auto",
             threshold_mps2: float = MANEUVER_THRESHOLD_MPS2, golden: bool = True,
             baselines: bool = True, robust: str | None = None) -> Evaluation:
    """Run every method on ``rec`` and compute the statistics (see the module docstring).
    ``robust``: the MCAHRS runs in that robust profile (``core.robust_profile``; the INS and the
    other baselines as they are; no golden comparison, the golden model has no robust modes)."""
    from mcahrs import core

    why = "given"
    if preset == "auto":
        preset, why = auto_preset(rec, path)
    if preset not in PRESET_NAMES:
        raise ValueError(f"unknown preset {preset!r}; known: auto, {', '.join(PRESET_NAMES)}")
    t = rec.imu["t_us"].astype(np.int64)
    ev = Evaluation(rec.name, str(rec.meta.get("source", "?")), preset, why, reference_kind(rec), t, [])
    ev.threshold_mps2 = threshold_mps2
    ev.robust = robust
    dt = np.diff(t) * 1e-6
    ev.imu_rate_hz = float(1.0 / np.median(dt)) if len(dt) else float("nan")
    if ev.imu_rate_hz < MIN_IMU_RATE_HZ:
        ev.notes.append(
            f"WARNING: IMU at {ev.imu_rate_hz:.1f} Hz (median): too slow for strapdown integration; "
            "results shown for completeness, goals not assessed"
        )

    filled = int(rec.meta.get("imu_filled_samples", 0))
    if filled:
        ev.notes.append(f"IMU: {filled} samples missing from the log put back by the loader (the mean of "
                        "the two before and the two after; the loader's fill_dropped)")
    if robust is not None and robust != "plain":
        if golden:
            ev.notes.append(f"robust profile {robust}: no golden-model comparison (the golden model "
                            "has no robust modes)")
        golden = False
    runs = [_core_run(MCAHRS, rec, preset, 1, robust), _core_run(COMP_OFF, rec, preset, 0, robust),
            _core_run(VELDIFF, rec, preset, 2, robust)]
    if baselines:
        from mcahrs import baselines as bl

        for name, fn in ((VQF, bl.run_vqf), (FUSION, bl.run_fusion)):
            r, note = _baseline_run(name, fn, rec)
            ev.notes.append(note)
            if r is not None:
                runs.append(r)
    ins, note = run_ins(rec, preset)
    ev.notes.append(note)
    runs.append(ins)
    ev.runs = runs
    mc = runs[0]
    assert mc.out is not None
    if golden:
        ev.golden = golden_agreement(mc.out, run_golden(rec, preset))

    aligned = np.isfinite(mc.roll)
    if not aligned.any():
        ev.notes.append("MCAHRS never aligned: nothing to evaluate")
        ev.eval_mask = np.zeros(len(t), bool)
        return ev
    ev.t_eval0_us = int(t[np.argmax(aligned)] + round(settle_s * 1e6))
    mask = (t >= ev.t_eval0_us) & aligned
    for r in runs:
        mask &= np.isfinite(r.roll) & np.isfinite(r.pitch)
    ev.eval_mask = mask
    ev.man_acc = horizontal_accel(rec.gnss, t)

    cfgd = core.config_dict(core.nav_config(preset))
    g_home = float("nan")
    if len(rec.gnss):
        g0 = rec.gnss[0]
        g_home = core.normal_gravity(math.radians(g0["lat_e7"] * 1e-7), g0["alt_mm"] * 1e-3)
    ev.diagnostics.update(_diagnostics(rec, mc, ev))

    if ev.ref_kind != "none":
        assert rec.ref is not None
        lag, info = estimate_ref_lag(rec.imu, rec.ref, interval_mean=imu_is_interval_mean(rec))
        ev.ref_lag_info = info
        applied = lag if ref_lag == "auto" else float(ref_lag)
        if not math.isfinite(applied):
            applied = 0.0
        ev.ref_lag_s = applied
        ev.ref_lag_info["measured_s"] = lag
        q_ref = interp_quat(rec.ref["t_us"].astype(np.int64) - int(round(applied * 1e6)), rec.ref["q_nb"], t)
        ev.ref_roll, ev.ref_pitch = quat_roll_pitch(q_ref)
        ia = int(np.argmax(aligned))
        ev.diagnostics["align_err_deg"] = (float(wrap_pi(mc.roll[ia] - ev.ref_roll[ia]) * DEG),
                                           float((mc.pitch[ia] - ev.ref_pitch[ia]) * DEG))
        mask &= np.isfinite(ev.ref_roll)
        man = ev.man_acc > threshold_mps2
        calm = ev.man_acc <= threshold_mps2
        for r in runs:
            er = wrap_pi(r.roll - ev.ref_roll) * DEG
            ep = (r.pitch - ev.ref_pitch) * DEG
            ev.stats[r.name] = {
                axis: {"all": err_stats(e[mask]), "calm": err_stats(e[mask & calm]),
                       "maneuver": err_stats(e[mask & man])}
                for axis, e in (("roll", er), ("pitch", ep))
            }
    else:
        ev.stops = stop_tilt(rec, runs, [s for s in detect_stops(rec.gnss) if s[0] >= ev.t_eval0_us])
    ev.grav_res = gravity_residual(rec, runs, g_home, float(cfgd["cs_lag_s"]), ev.t_eval0_us)
    ev.goals = _goals(ev)
    return ev


def _diagnostics(rec: Recording, mc: MethodRun, ev: Evaluation) -> dict[str, Any]:
    """Numbers that help explain a missed goal: vibration, GPS NIS, observation counts."""
    from mcahrs import core

    out = mc.out
    assert out is not None
    d: dict[str, Any] = {}
    f = np.asarray(rec.imu["accel_mps2"], np.float64)
    w = np.asarray(rec.imu["gyro_rps"], np.float64)
    d["accel_std_mps2"] = f.std(axis=0).tolist()
    d["gyro_std_rps"] = w.std(axis=0).tolist()
    gt = out["gps_t"].astype(np.float64)
    # one value per fix: the rows where the statistic changes
    chg = np.any(np.diff(gt, axis=0) != 0, axis=1)
    rows = np.concatenate([[False], chg])
    if rows.any():
        d["gps_nis_median"] = np.nanmedian(gt[rows], axis=0).tolist()
        d["gps_nis_p95"] = np.nanpercentile(gt[rows], 95, axis=0).tolist()
    rpt = out["rp_t"].astype(np.float64)
    rchg = np.concatenate([[False], np.diff(rpt) != 0]) & np.isfinite(rpt)
    if rchg.any():
        d["rp_nis_median"] = float(np.median(rpt[rchg]))
        d["rp_nis_mean"] = float(np.mean(rpt[rchg]))
    d["grav_obs_made"] = int(out["n_grav_obs"][-1])
    d["grav_obs_skipped"] = int(out["n_grav_skip"][-1])
    d["gps_lost_fraction"] = float(np.mean((out["flags"] & core.FLAG_BITS["gps_lost"]) != 0))
    d["gyro_bias_end_dps"] = (out["gyro_bias_rps"][-1].astype(np.float64) * DEG).tolist()
    if ev.t_eval0_us > 0:
        span = float(ev.t_us[-1] - ev.t_eval0_us) * 1e-6 - GYRO_DRIFT_HORIZONS_S[-1]
        n = min(GYRO_DRIFT_MAX_STARTS, int(span // GYRO_DRIFT_STEP_S) + 1) if span >= 0.0 else 0
        if n > 0:
            starts = [ev.t_eval0_us + round(k * GYRO_DRIFT_STEP_S * 1e6) for k in range(n)]
            drift = gyro_only_drift(rec, out, starts)
            d["gyro_only_drift_deg"] = {"horizons_s": list(GYRO_DRIFT_HORIZONS_S), "starts": n,
                                        "median": np.nanmedian(drift, axis=0).tolist(),
                                        "max": np.nanmax(drift, axis=0).tolist()}
    aligned = (out["flags"] & core.FLAG_BITS["aligned"]) != 0
    if aligned.any():
        ia = int(np.argmax(aligned))
        cfg = core.config_dict(core.nav_config(ev.preset))
        d["align_t_s"] = float((ev.t_us[ia] - ev.t_us[0]) * 1e-6)
        d["align_by_timeout"] = bool(d["align_t_s"] >= float(cfg["init_timeout_s"]) - 1e-3)
        d["align_rp_deg"] = (float(mc.roll[ia] * DEG), float(mc.pitch[ia] * DEG))
    if ev.source == "ulog":
        d["gps_delay_applied_ms"] = rec.meta.get("gps_delay_us_applied", 0) / 1e3
        px4 = rec.meta.get("px4_ekf2_gps_delay_us")
        d["px4_gps_delay_ms"] = None if px4 is None else px4 / 1e3
    return d


# ---------------------------------------------------------------- goals


def _rms(ev: Evaluation, name: str, axis: str, part: str) -> float:
    return ev.stats.get(name, {}).get(axis, {}).get(part, {}).get("rms", float("nan"))


def stop_summary(ev: Evaluation) -> dict[str, dict[str, float]]:
    """Per method: mean, RMS and max of the stop-tilt error over the stops (deg), per axis."""
    out: dict[str, dict[str, float]] = {}
    for r in ev.runs:
        e = np.array([s["err"][r.name] for s in ev.stops], np.float64).reshape(-1, 2)
        row = {}
        for k, axis in enumerate(("roll", "pitch")):
            x = e[:, k][np.isfinite(e[:, k])]
            row[f"{axis}_mean"] = float(x.mean()) if len(x) else float("nan")
            row[f"{axis}_rms"] = float(np.sqrt(np.mean(x * x))) if len(x) else float("nan")
            row[f"{axis}_max"] = float(np.abs(x).max()) if len(x) else float("nan")
        out[r.name] = row
    return out


def _goals(ev: Evaluation) -> list[str]:
    lines: list[str] = []
    if ev.imu_rate_hz < MIN_IMU_RATE_HZ:
        return ["not assessed: IMU too slow for strapdown integration"]

    def mark(ok: bool) -> str:
        return "MET   " if ok else "MISSED"

    others = [n for n in (COMP_OFF, VELDIFF, VQF, FUSION) if any(r.name == n for r in ev.runs)]
    if ev.stats:
        r_rms, p_rms = _rms(ev, MCAHRS, "roll", "all"), _rms(ev, MCAHRS, "pitch", "all")
        if ev.source == "ulog":
            lines.append(f"{mark(max(r_rms, p_rms) <= 1.0)} roll/pitch RMS within 1.0 deg of EKF2: "
                         f"roll {r_rms:.2f}, pitch {p_rms:.2f} deg")
            for n in (VQF, FUSION):
                if n in ev.stats:
                    rr, pp = _rms(ev, n, "roll", "maneuver"), _rms(ev, n, "pitch", "maneuver")
                    lines.append(f"       (context) {n} maneuvering RMS roll {rr:.2f}, pitch {pp:.2f} deg "
                                 "(expected 1.3-3.3 deg on the maneuvering axis)")
        if ev.source == "comma2k19":
            lines.append(f"{mark(p_rms < 0.5)} pitch RMS < 0.5 deg: {p_rms:.2f} deg")
            for n in (VQF, FUSION):
                if n in ev.stats:
                    lines.append(f"       (context) {n} pitch RMS {_rms(ev, n, 'pitch', 'all'):.2f}, max "
                                 f"{ev.stats[n]['pitch']['all']['max']:.2f} deg (expected ~2.3, up to 9)")
        for axis in ("roll", "pitch"):
            mine = _rms(ev, MCAHRS, axis, "maneuver")
            theirs = {n: _rms(ev, n, axis, "maneuver") for n in others}
            if not math.isfinite(mine):
                lines.append(f"n/a    MCAHRS best in maneuvering segments ({axis}): no maneuvering rows")
                continue
            worse = [n for n, v in theirs.items() if math.isfinite(v) and v <= mine]
            txt = ", ".join(f"{n} {v:.2f}" for n, v in theirs.items())
            lines.append(f"{mark(not worse)} MCAHRS best in maneuvering segments ({axis}): {mine:.2f} deg "
                         f"vs {txt}" + (f"; not better than {', '.join(worse)}" if worse else ""))
    elif ev.stops:
        ss = stop_summary(ev)
        m = ss[MCAHRS]
        ok = max(m["roll_rms"], m["pitch_rms"]) < 0.5
        lines.append(f"{mark(ok)} tilt error at stops < 0.5 deg (RMS over {len(ev.stops)} stops): "
                     f"roll {m['roll_rms']:.2f}, pitch {m['pitch_rms']:.2f} deg")
        for axis in ("roll", "pitch"):
            mine = m[f"{axis}_rms"]
            theirs = {n: ss[n][f"{axis}_rms"] for n in others}
            worse = [n for n, v in theirs.items() if math.isfinite(v) and v <= mine]
            txt = ", ".join(f"{n} {v:.2f}" for n, v in theirs.items())
            lines.append(f"{mark(not worse)} MCAHRS best stop tilt after maneuvers ({axis}): {mine:.2f} deg "
                         f"vs {txt}" + (f"; not better than {', '.join(worse)}" if worse else ""))
    else:
        lines.append("not assessed: no reference and no stops in the evaluated window")
    return lines


# ================================================================ report


def _fmt(x: float, w: int = 6, p: int = 2) -> str:
    return f"{x:{w}.{p}f}" if math.isfinite(x) else " " * (w - 3) + "n/a"


def format_report(ev: Evaluation) -> str:
    """The printed tables."""
    t = ev.t_us
    t0 = t[0]
    robust = f"; robust profile {ev.robust}" if ev.robust else ""
    lines = [f"=== {ev.name}  [{ev.source}; preset {ev.preset} ({ev.preset_why}){robust}]"]
    dur = (t[-1] - t0) * 1e-6
    lines.append(f"IMU {len(t)} samples, {dur:.1f} s, {ev.imu_rate_hz:.1f} Hz median; "
                 f"reference: {ev.ref_kind}")
    for n in ev.notes:
        lines.append("  " + n)
    if ev.golden is not None:
        g = ev.golden
        lines.append(
            f"C core vs golden model (float64), roll/pitch over {g['n']} aligned rows: roll diff RMS "
            f"{g['roll_rms']:.2e} max {g['roll_max']:.2e} deg; pitch diff RMS {g['pitch_rms']:.2e} "
            f"max {g['pitch_max']:.2e} deg"
        )
    mask = ev.eval_mask if ev.eval_mask is not None else np.zeros(len(t), bool)
    if mask.any():
        tm = t[mask]
        lines.append(
            f"Evaluated window: {(tm[0] - t0) * 1e-6:.1f}-{(tm[-1] - t0) * 1e-6:.1f} s from the first IMU "
            "sample "
            f"({mask.sum()} rows; alignment period dropped: MCAHRS aligned + settle)"
        )
    if ev.man_acc is not None:
        ma = ev.man_acc[mask]
        fin = np.isfinite(ma)
        n_man = int((ma[fin] > ev.threshold_mps2).sum())
        lines.append(
            f"Maneuver split: |a_h| from GNSS velocity, {MANEUVER_WINDOW_S:g} s central difference, "
            f"threshold {ev.threshold_mps2:g} m/s^2: maneuvering {n_man / max(len(ma), 1):.0%} of rows, calm "
            f"{(fin.sum() - n_man) / max(len(ma), 1):.0%}"
            + (f", max {np.nanmax(ma):.2f} m/s^2" if fin.any() else "")
        )
    if ev.ref_kind != "none":
        info = ev.ref_lag_info
        lines.append(
            f"Reference time offset (ref stamps late by; gyro vs reference rates): measured "
            f"{info.get('measured_s', float('nan')) * 1e3:+.1f} ms, applied {ev.ref_lag_s * 1e3:+.1f} ms"
            f" ({info.get('intervals', 0)} intervals)"
        )
    if ev.stats:
        lines.append("")
        hdr = f"{'roll/pitch error vs reference [deg]':36s}|{'all':^35s}|{'calm':^21s}|{'maneuvering':^21s}"
        lines.append(hdr)
        lines.append(
            f"{'method':28s}{'axis':>8s}|{'mean':>7s}{'std':>7s}{'RMS':>7s}{'p95':>7s}{'max':>7s}|"
            f"{'RMS':>7s}{'p95':>7s}{'max':>7s}|{'RMS':>7s}{'p95':>7s}{'max':>7s}"
        )
        lines.append("-" * len(hdr))
        for r in ev.runs:
            for axis in ("roll", "pitch"):
                s = ev.stats[r.name][axis]
                a, c, m = s["all"], s["calm"], s["maneuver"]
                cells = [a["mean"], a["std"], a["rms"], a["p95"], a["max"]]
                lines.append(
                    f"{r.name if axis == 'roll' else '':28s}{axis:>8s}|" + "".join(_fmt(v, 7) for v in cells)
                    + "|" + "".join(_fmt(c[k], 7) for k in ("rms", "p95", "max"))
                    + "|" + "".join(_fmt(m[k], 7) for k in ("rms", "p95", "max"))
                )
    if ev.ref_kind == "none":
        lines.append("")
        lines.append(
            f"Stop tilt: stops = horizontal GNSS speed < {STOP_SPEED_MPS:g} m/s for >= {STOP_MIN_S:g} s "
            f"after the settle time; error = method's mean roll/pitch over the first {STOP_EARLY_S:g} s "
            "minus the tilt of the accelerometer averaged over the stop [deg]"
        )
        if ev.stops:
            names = [r.name for r in ev.runs]
            lines.append(f"{'stop':>4s}{'t [s]':>8s}{'len':>6s}{'acc roll':>9s}{'pitch':>7s} | "
                         + " | ".join(f"{n[:21]:^13s}" for n in names))
            for k, s in enumerate(ev.stops):
                cells = " | ".join(f"{s['err'][n][0]:+6.2f}{s['err'][n][1]:+7.2f}" for n in names)
                lines.append(
                    f"{k + 1:4d}{(s['t0_us'] - t0) * 1e-6:8.1f}{(s['t1_us'] - s['t0_us']) * 1e-6:6.1f}"
                    f"{s['acc_roll_deg']:9.2f}{s['acc_pitch_deg']:7.2f} | {cells}"
                )
            ss = stop_summary(ev)
            lines.append(f"{'method':28s}{'roll mean':>10s}{'RMS':>7s}{'max':>7s}"
                         f"{'pitch mean':>12s}{'RMS':>7s}{'max':>7s}")
            for n in names:
                m = ss[n]
                lines.append(f"{n:28s}{_fmt(m['roll_mean'], 10)}{_fmt(m['roll_rms'], 7)}"
                             f"{_fmt(m['roll_max'], 7)}{_fmt(m['pitch_mean'], 12)}{_fmt(m['pitch_rms'], 7)}"
                             f"{_fmt(m['pitch_max'], 7)}")
        else:
            lines.append("  no stops in the evaluated window")
    if ev.grav_res:
        lines.append("")
        lines.append(
            f"Gravity residual |g_b| - g at the fixes while moving (speed > {MOVING_SPEED_MPS:g} m/s), "
            "f = 20 ms mean at the observation time [m/s^2]"
        )
        lines.append(f"{'compensation':28s}{'n':>6s}{'mean':>8s}{'std':>8s}{'p95 |.|':>9s}")
        for name, s in ev.grav_res.items():
            lines.append(f"{name:28s}{s['n']:6d}{_fmt(s['mean'], 8, 3)}{_fmt(s['std'], 8, 3)}"
                         f"{_fmt(s['p95'], 9, 3)}")
        lines.append("  (IMU-only filters and compensation off use the raw accelerometer: the 'raw' row)")
    d = ev.diagnostics
    if d:
        lines.append("")
        lines.append(
            "Diagnostics: accel std " + "/".join(f"{v:.2f}" for v in d["accel_std_mps2"])
            + " m/s^2, gyro std " + "/".join(f"{v:.3f}" for v in d["gyro_std_rps"])
            + " rad/s (x/y/z, whole log); "
            f"gravity observations {d['grav_obs_made']} made, {d['grav_obs_skipped']} skipped; "
            f"GPS lost {d['gps_lost_fraction']:.0%} of rows"
        )
        if "gps_nis_median" in d:
            lines.append(
                "  GPS NIS per axis N/E/D: median " + "/".join(f"{v:.2f}" for v in d["gps_nis_median"])
                + ", p95 " + "/".join(f"{v:.1f}" for v in d["gps_nis_p95"])
                + (f"; roll/pitch NIS median {d['rp_nis_median']:.2f} (mean {d['rp_nis_mean']:.2f}; chi2(2) "
                   "median 1.39, mean 2)" if "rp_nis_median" in d else "")
            )
        lines.append("  MCAHRS gyro bias at the end: " + "/".join(f"{v:+.3f}" for v in d["gyro_bias_end_dps"])
                     + " deg/s")
        if "gyro_only_drift_deg" in d:
            g = d["gyro_only_drift_deg"]
            lines.append(
                "  gyro alone from MCAHRS's attitude and bias, off it after "
                + "/".join(f"{h:g}" for h in g["horizons_s"]) + " s: median "
                + "/".join(f"{v:.2f}" for v in g["median"]) + ", worst "
                + "/".join(f"{v:.2f}" for v in g["max"]) + f" deg over {g['starts']} starts"
                + " (what a robust profile's gravity hold costs: README, GNSS outliers)"
            )
        if "align_t_s" in d:
            how = "init timeout (no still window)" if d["align_by_timeout"] else "still window"
            txt = (f"  MCAHRS aligned at {d['align_t_s']:.2f} s by {how}: roll {d['align_rp_deg'][0]:+.1f}, "
                   f"pitch {d['align_rp_deg'][1]:+.1f} deg")
            if "align_err_deg" in d:
                er, ep = d["align_err_deg"]
                txt += f" (error vs reference {er:+.1f} / {ep:+.1f} deg)"
            lines.append(txt)
        if "gps_delay_applied_ms" in d:
            delay = d["gps_delay_applied_ms"]
            lines.append(f"  GNSS validity time: publication time - {delay:g} ms (loader); the autopilot's "
                         f"EKF2_GPS_DELAY is {d['px4_gps_delay_ms']} ms (--gps-delay-ms applies it)")
    lines.append("")
    lines.append("Goals (printed, not asserted):")
    lines.extend("  " + g for g in ev.goals)
    return "\n".join(lines)


def write_csv(ev: Evaluation, path: str | Path) -> None:
    """One row per IMU sample: time, reference and every method's roll/pitch (deg), |a_h|, in window."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    t0 = ev.t_us[0]
    cols = ["t_s", "in_window", "man_acc_mps2"]
    data: list[np.ndarray] = [(ev.t_us - t0) * 1e-6, (ev.eval_mask if ev.eval_mask is not None else
                                                      np.zeros(len(ev.t_us), bool)).astype(int),
                              ev.man_acc if ev.man_acc is not None else np.full(len(ev.t_us), np.nan)]
    if ev.ref_roll is not None and ev.ref_pitch is not None:
        cols += ["ref_roll_deg", "ref_pitch_deg"]
        data += [ev.ref_roll * DEG, ev.ref_pitch * DEG]
    for r in ev.runs:
        key = r.name.lower().replace(" ", "_").replace("(", "").replace(")", "")
        cols += [f"{key}_roll_deg", f"{key}_pitch_deg"]
        data += [r.roll * DEG, r.pitch * DEG]
    with open(p, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for row in zip(*data, strict=True):
            w.writerow([f"{v:.6g}" if isinstance(v, (float, np.floating)) else v for v in row])


def make_plots(ev: Evaluation, out_dir: str | Path) -> list[Path]:
    """Figures: roll/pitch of every method with the reference; error over time; maneuver
    acceleration; GPS innovation statistic. Returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mcahrs import core

    d = Path(out_dir)
    d.mkdir(parents=True, exist_ok=True)
    stem = ev.name.replace("/", "_")
    t0 = ev.t_us[0]
    ts = (ev.t_us - t0) * 1e-6
    mask = ev.eval_mask if ev.eval_mask is not None else np.ones(len(ts), bool)
    x0 = (ev.t_eval0_us - t0) * 1e-6
    files: list[Path] = []

    def shade(ax: Any) -> None:
        ax.axvspan(ts[0], x0, color="0.9", lw=0, label="_alignment (dropped)")
        if ev.man_acc is not None:
            man = np.nan_to_num(ev.man_acc) > ev.threshold_mps2
            ax.fill_between(ts, 0, 1, where=man, transform=ax.get_xaxis_transform(), color="tab:orange",
                            alpha=0.12, lw=0)
        for s in ev.stops:
            a, b = (s["t0_us"] - t0) * 1e-6, (s["t1_us"] - t0) * 1e-6
            ax.axvspan(a, b, color="tab:green", alpha=0.15, lw=0)

    fig, axs = plt.subplots(2, 1, sharex=True, figsize=(12, 7))
    for k, axis in enumerate(("roll", "pitch")):
        ax = axs[k]
        shade(ax)
        if ev.ref_roll is not None and ev.ref_pitch is not None:
            ax.plot(ts, (ev.ref_roll if k == 0 else ev.ref_pitch) * DEG, "k", lw=1.6, label="reference")
        for r in ev.runs:
            ax.plot(ts, (r.roll if k == 0 else r.pitch) * DEG, lw=0.8, label=r.name)
        ax.set_ylabel(f"{axis} [deg]")
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize=8, ncol=3)
    axs[0].set_title(f"{ev.name}: roll/pitch (orange: maneuvering, grey: alignment dropped, green: stops)")
    axs[1].set_xlabel("time from first IMU sample [s]")
    files.append(d / f"{stem}_attitude.png")
    fig.savefig(files[-1], dpi=110, bbox_inches="tight")
    plt.close(fig)

    fig, axs = plt.subplots(2, 1, sharex=True, figsize=(12, 7))
    for k, axis in enumerate(("roll", "pitch")):
        ax = axs[k]
        shade(ax)
        for r in ev.runs:
            if ev.ref_roll is not None and ev.ref_pitch is not None:
                e = wrap_pi(r.roll - ev.ref_roll) if k == 0 else r.pitch - ev.ref_pitch
            else:  # no reference: against the accelerometer tilt averaged over each stop, inside stops
                e = np.full(len(ts), np.nan)
                for s in ev.stops:
                    m = (ev.t_us >= s["t0_us"]) & (ev.t_us <= s["t1_us"])
                    acc = math.radians(s["acc_roll_deg"] if k == 0 else s["acc_pitch_deg"])
                    e[m] = (wrap_pi(r.roll[m] - acc) if k == 0 else r.pitch[m] - acc)
            line = ax.plot(ts, np.where(mask, e * DEG, np.nan), lw=0.8, label=r.name)
            if ev.ref_roll is None:
                xs = [(s["t0_us"] - t0) * 1e-6 + 0.5 * STOP_EARLY_S for s in ev.stops]
                ys = [s["err"][r.name][k] for s in ev.stops]
                ax.plot(xs, ys, "o", color=line[0].get_color(), ms=5)
        ax.set_ylabel(f"{axis} error [deg]")
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize=8, ncol=3)
    what = ("reference" if ev.ref_roll is not None else
            f"accelerometer tilt averaged over each stop (no reference; dots: first {STOP_EARLY_S:g} s mean)")
    axs[0].set_title(f"{ev.name}: error against the {what}")
    axs[1].set_xlabel("time from first IMU sample [s]")
    files.append(d / f"{stem}_error.png")
    fig.savefig(files[-1], dpi=110, bbox_inches="tight")
    plt.close(fig)

    mc = ev.run(MCAHRS)
    assert mc.out is not None
    fig, axs = plt.subplots(2, 1, sharex=True, figsize=(12, 7))
    ax = axs[0]
    shade(ax)
    if ev.man_acc is not None:
        ax.plot(ts, ev.man_acc, "k", lw=1.2, label="|a_h| from GNSS velocity (1 s difference)")
    a = mc.out["acc_ned_mps2"].astype(np.float64)
    ax.plot(ts, np.hypot(a[:, 0], a[:, 1]), "tab:blue", lw=0.8, label="|a_h| MCAHRS CS filter")
    ax.axhline(ev.threshold_mps2, color="tab:red", ls="--", lw=0.8, label="maneuver threshold")
    ax.set_ylabel("horizontal acceleration [m/s^2]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title(f"{ev.name}: maneuver acceleration and GPS innovation statistic (MCAHRS)")
    ax = axs[1]
    gt = mc.out["gps_t"].astype(np.float64)
    chg = np.concatenate([[False], np.any(np.diff(gt, axis=0) != 0, axis=1)])
    for k, axis in enumerate("NED"):
        ax.semilogy(ts[chg], np.maximum(gt[chg, k], 1e-4), ".", ms=3, label=f"GPS NIS {axis}")
    ax.axhline(core.chi2_quantile(2, 1e-2), color="tab:red", ls="--", lw=0.8, label="chi2(2) 99%")
    ax.set_ylabel("normalised innovation squared")
    ax.set_xlabel("time from first IMU sample [s]")
    ax.legend(fontsize=8, ncol=4)
    ax.grid(alpha=0.3)
    files.append(d / f"{stem}_maneuver_gps.png")
    fig.savefig(files[-1], dpi=110, bbox_inches="tight")
    plt.close(fig)
    return files


# ================================================================ command line


def _load(path: str, **kw: Any) -> Recording:
    from mcahrs.io.loaders import load

    return load(path, **kw)


IMU_AS_LOGGED_HELP = ("ULog only: the IMU samples as logged (default: the loader puts back the samples "
                      "missing from a full-rate topic)")


def _is_ulog(path: str) -> bool:
    return str(path).lower().endswith((".ulg", ".ulog"))


def _as_logged(path: str, as_logged: bool) -> dict[str, bool]:
    """The loader keyword of ``--imu-as-logged``; ValueError on a recording that is not a ULog."""
    if not as_logged:
        return {}
    if not _is_ulog(path):
        raise ValueError("--imu-as-logged applies to ULog files only")
    return {"fill_dropped": False}


def main_evaluate(argv: list[str] | None = None) -> int:
    """``mcahrs evaluate LOG [--preset ...] [--plot DIR] [--csv FILE] [--start S --duration S]``."""
    ap = argparse.ArgumentParser(prog="mcahrs evaluate",
                                 description="Roll/pitch of MCAHRS and baselines on a real recording.")
    ap.add_argument("log", help=".ulg file, comma2k19 segment folder, or car drive folder/file")
    ap.add_argument("--preset", default="auto", choices=("auto", *PRESET_NAMES))
    ap.add_argument("--plot", metavar="DIR", help="write figures (PNG) into DIR")
    ap.add_argument("--csv", metavar="FILE", help="write per-sample roll/pitch of every method to FILE")
    ap.add_argument("--start", type=float, default=None, metavar="S",
                    help="start S seconds after the first IMU sample")
    ap.add_argument("--duration", type=float, default=None, metavar="S", help="evaluate S seconds only")
    ap.add_argument("--settle", type=float, default=SETTLE_S, metavar="S",
                    help=f"statistics start S seconds after MCAHRS is aligned (default {SETTLE_S:g})")
    ap.add_argument("--ref-lag", default="auto", metavar="auto|S",
                    help="reference time offset: measured ('auto', default) or seconds (0: as logged)")
    ap.add_argument("--threshold", type=float, default=MANEUVER_THRESHOLD_MPS2, metavar="A",
                    help=f"maneuvering when |a_h| > A m/s^2 (default {MANEUVER_THRESHOLD_MPS2:g})")
    ap.add_argument("--no-golden", action="store_true", help="skip the golden-model run (slow on long logs)")
    from mcahrs.core import ROBUST_PROFILES

    ap.add_argument("--robust", choices=ROBUST_PROFILES, default=None, metavar="PROFILE",
                    help="the MCAHRS runs in this robust profile (mcahrs.core.robust_profile; default plain)")
    ap.add_argument("--gps-delay-ms", type=float, default=None, metavar="MS",
                    help="ULog only: fix validity = publication time - MS (default: the loader's, 0)")
    ap.add_argument("--imu-as-logged", action="store_true", help=IMU_AS_LOGGED_HELP)
    args = ap.parse_args(argv)
    from mcahrs.io.loaders import LoaderError

    try:
        ref_lag: float | str = "auto" if args.ref_lag == "auto" else float(args.ref_lag)
    except ValueError:
        print(f"mcahrs evaluate: --ref-lag {args.ref_lag!r}: expected 'auto' or seconds", file=sys.stderr)
        return 2
    kw = {} if args.gps_delay_ms is None else {"gps_delay_us": int(round(args.gps_delay_ms * 1e3))}
    try:
        if kw and not _is_ulog(args.log):
            raise ValueError("--gps-delay-ms applies to ULog files only")
        kw |= _as_logged(args.log, args.imu_as_logged)
        rec = cut_recording(_load(args.log, **kw), args.start, args.duration)
    except (LoaderError, ValueError, OSError) as exc:
        print(f"mcahrs evaluate: {exc}", file=sys.stderr)
        return 2
    ev = evaluate(rec, args.preset, path=args.log, settle_s=args.settle, ref_lag=ref_lag,
                  threshold_mps2=args.threshold, golden=not args.no_golden, robust=args.robust)
    print(format_report(ev))
    if args.csv:
        write_csv(ev, args.csv)
        print(f"CSV: {args.csv}")
    if args.plot:
        files = make_plots(ev, args.plot)
        print("Plots: " + ", ".join(str(f) for f in files))
    return 0


def _utc_offset_us(rec: Recording) -> tuple[int, _dt.date]:
    """(offset, date0) so that UTC = t_us + offset microseconds after midnight of date0, when the
    loader meta tells it; else (0, 2000-01-01): the wire needs a UTC field, the reader groups by it."""
    m = rec.meta
    epoch = _dt.date(1970, 1, 1)
    if "utc_minus_boot_us_median" in m:  # ULog: UTC of the GPS fixes minus boot time
        return int(m["utc_minus_boot_us_median"]), epoch
    if "gps_tow_minus_boot_s" in m and "gps_week" in m and "gnss_leap_s" in m:  # comma2k19
        gps_unix = 315964800 + int(m["gps_week"]) * 604800 + float(m["gps_tow_minus_boot_s"])
        return int(round((gps_unix - int(m["gnss_leap_s"])) * 1e6)), epoch
    if m.get("source") == "rtklib_car" and "gps_week" in m:  # t_us: GPST since the start of the week
        from mcahrs.io.loaders._common import gps_minus_utc_s

        week_unix = 315964800 + int(m["gps_week"]) * 604800
        leap = gps_minus_utc_s(float(week_unix))
        return int((week_unix - leap) * 1_000_000), epoch
    return 0, _dt.date(2000, 1, 1)


def convert(rec: Recording, out_path: str | Path) -> dict[str, Any]:
    """Write ``rec`` as a wire-format stream (see the module docstring); returns what was written."""
    from mcahrs.io.wire import write_recording

    t_first = int(rec.imu["t_us"][0])
    gn = rec.gnss
    early = (gn["t_rx_us"] < t_first) & (gn["fix_type"] != 0)
    nofix = gn["fix_type"] == 0
    keep = Recording(rec.name, rec.imu, gn[~early], rec.mag, None, rec.meta)
    off, date0 = _utc_offset_us(rec)
    with open(out_path, "wb") as fh:
        nbytes = write_recording(keep, fh, utc_offset_us=off, date0=date0)
    return {"bytes": nbytes, "imu": len(rec.imu), "mag": 0 if rec.mag is None else len(rec.mag),
            "fixes": int((~early & ~nofix).sum()), "fixes_before_first_imu": int(early.sum()),
            "fixes_no_fix": int(nofix.sum()), "utc_offset_us": off, "date0": date0.isoformat()}


def main_convert(argv: list[str] | None = None) -> int:
    """``mcahrs convert LOG --out STREAM [--start S --duration S]``."""
    ap = argparse.ArgumentParser(
        prog="mcahrs convert",
        description="Write a recording as an MCAHRS wire-format stream (NMEA + IMU sentences).",
    )
    ap.add_argument("log", help=".ulg file, comma2k19 segment folder, or car drive folder/file")
    ap.add_argument("--out", required=True, metavar="STREAM", help="output file")
    ap.add_argument("--start", type=float, default=None, metavar="S")
    ap.add_argument("--duration", type=float, default=None, metavar="S")
    ap.add_argument("--imu-as-logged", action="store_true", help=IMU_AS_LOGGED_HELP)
    args = ap.parse_args(argv)
    from mcahrs.io.loaders import LoaderError

    try:
        kw = _as_logged(args.log, args.imu_as_logged)
        rec = cut_recording(_load(args.log, **kw), args.start, args.duration)
        info = convert(rec, args.out)
    except (LoaderError, ValueError, OSError) as exc:
        print(f"mcahrs convert: {exc}", file=sys.stderr)
        return 2
    print(
        f"{args.out}: {info['bytes']} bytes; {info['imu']} IMU, {info['mag']} magnetometer samples, "
        f"{info['fixes']} fixes"
        + (f"; {info['fixes_before_first_imu']} fixes before the first IMU sample left out (no IMU time base)"
           if info["fixes_before_first_imu"] else "")
        + (f"; {info['fixes_no_fix']} no-fix epochs left out" if info["fixes_no_fix"] else "")
    )
    return 0

"""Helpers shared by the recording loaders: the error type, time constants, rotations, checks.

Nothing here reads files. Rotation conventions follow DESIGN.md section 2: Hamilton
quaternions ``[w, x, y, z]``; ``q_nb`` and ``C_nb`` rotate body FRD vectors into NED.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mcahrs.samples import GNSS_DTYPE, IMU_DTYPE


class LoaderError(ValueError):
    """A recording file is missing, malformed or lacks a needed field. The message names file and field."""


#: GPS time origin (1980-01-06 00:00:00) in Unix seconds, i.e. as RTKLIB's ``gtime_t`` counts GPST.
GPS_EPOCH_UNIX_S = 315964800
SECONDS_PER_WEEK = 604800

# GPS - UTC (leap seconds), from the date each value took effect (Unix seconds, UTC).
_LEAP_TABLE = (
    (1230768000, 15),  # 2009-01-01
    (1341100800, 16),  # 2012-07-01
    (1435708800, 17),  # 2015-07-01
    (1483228800, 18),  # 2017-01-01 (still in force at the time of writing)
)


def gps_minus_utc_s(unix_utc_s: float, source: str = "") -> int:
    """Leap seconds GPS - UTC at a UTC instant (2009 onwards, which covers every recording we load)."""
    if unix_utc_s < _LEAP_TABLE[0][0]:
        raise LoaderError(
            f"{source}: UTC time {unix_utc_s:.0f} s is before 2009; leap-second table does not cover it"
        )
    leap = _LEAP_TABLE[0][1]
    for start, value in _LEAP_TABLE:
        if unix_utc_s >= start:
            leap = value
    return leap


def need(cond: bool, source: str | Path, what: str) -> None:
    """Raise :class:`LoaderError` naming the source and what is wrong, unless ``cond`` holds."""
    if not cond:
        raise LoaderError(f"{source}: {what}")


def deg_to_e7(deg: np.ndarray, source: str, field: str, limit: float) -> np.ndarray:
    """Degrees (float64) to int32 1e-7 degrees, rejecting non-finite or out-of-range values."""
    deg = np.asarray(deg, np.float64)
    bad = ~np.isfinite(deg) | (np.abs(deg) > limit)
    need(not bad.any(), source, f"field {field!r} has {int(bad.sum())} non-finite or out-of-range values")
    return np.round(deg * 1e7).astype(np.int32)


def m_to_mm(m: np.ndarray, source: str, field: str) -> np.ndarray:
    """Metres (float) to int32 millimetres, rejecting non-finite values or heights beyond +-2000 km."""
    m = np.asarray(m, np.float64)
    bad = ~np.isfinite(m) | (np.abs(m) > 2.0e6)
    need(not bad.any(), source, f"field {field!r} has {int(bad.sum())} non-finite or out-of-range values")
    return np.round(m * 1e3).astype(np.int32)


def wrap_2pi(rad: np.ndarray) -> np.ndarray:
    """Angle to [0, 2 pi); NaN stays NaN."""
    out = np.mod(np.asarray(rad, np.float64), 2.0 * np.pi)
    return np.where(out >= 2.0 * np.pi, 0.0, out)


def rate_stats(t_us: np.ndarray) -> dict:
    """Count, duration and rates of a time series (median rate from the median interval)."""
    t = np.asarray(t_us, np.int64)
    if t.size < 2:
        return {
            "n": int(t.size),
            "duration_s": 0.0,
            "rate_median_hz": float("nan"),
            "rate_mean_hz": float("nan"),
        }
    dt = np.diff(t)
    dur = (t[-1] - t[0]) * 1e-6
    return {
        "n": int(t.size),
        "duration_s": float(dur),
        "rate_median_hz": float(1e6 / np.median(dt)),
        "rate_mean_hz": float((t.size - 1) / dur) if dur > 0 else float("nan"),
        "dt_max_ms": float(dt.max() * 1e-3),
    }


def sort_unique(t_us: np.ndarray) -> tuple[np.ndarray, int]:
    """Indices that sort ``t_us`` and keep the first of equal times; also how many were dropped."""
    order = np.argsort(t_us, kind="stable")
    ts = np.asarray(t_us)[order]
    keep = np.ones(ts.size, bool)
    keep[1:] = ts[1:] != ts[:-1]
    return order[keep], int((~keep).sum())


def quat_to_dcm(q: np.ndarray) -> np.ndarray:
    """(N,4) Hamilton [w,x,y,z] to (N,3,3) rotation matrices R(q) (v_to = R v_from)."""
    q = np.asarray(q, np.float64)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    r = np.empty((q.shape[0], 3, 3))
    r[:, 0, 0] = 1 - 2 * (y * y + z * z)
    r[:, 0, 1] = 2 * (x * y - w * z)
    r[:, 0, 2] = 2 * (x * z + w * y)
    r[:, 1, 0] = 2 * (x * y + w * z)
    r[:, 1, 1] = 1 - 2 * (x * x + z * z)
    r[:, 1, 2] = 2 * (y * z - w * x)
    r[:, 2, 0] = 2 * (x * z - w * y)
    r[:, 2, 1] = 2 * (y * z + w * x)
    r[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def dcm_to_quat(c: np.ndarray) -> np.ndarray:
    """(N,3,3) rotation matrices to unit (N,4) Hamilton [w,x,y,z] with R(q) = C (Shepperd's method)."""
    c = np.asarray(c, np.float64)
    n = c.shape[0]
    tr = c[:, 0, 0] + c[:, 1, 1] + c[:, 2, 2]
    cand = np.stack([tr, c[:, 0, 0], c[:, 1, 1], c[:, 2, 2]], axis=1)
    k = np.argmax(cand, axis=1)
    q = np.empty((n, 4))
    m = k == 0
    s = np.sqrt(1.0 + tr[m]) * 2.0
    q[m] = np.stack(
        [
            0.25 * s,
            (c[m, 2, 1] - c[m, 1, 2]) / s,
            (c[m, 0, 2] - c[m, 2, 0]) / s,
            (c[m, 1, 0] - c[m, 0, 1]) / s,
        ],
        axis=1,
    )
    m = k == 1
    s = np.sqrt(1.0 + c[m, 0, 0] - c[m, 1, 1] - c[m, 2, 2]) * 2.0
    q[m] = np.stack(
        [
            (c[m, 2, 1] - c[m, 1, 2]) / s,
            0.25 * s,
            (c[m, 0, 1] + c[m, 1, 0]) / s,
            (c[m, 0, 2] + c[m, 2, 0]) / s,
        ],
        axis=1,
    )
    m = k == 2
    s = np.sqrt(1.0 + c[m, 1, 1] - c[m, 0, 0] - c[m, 2, 2]) * 2.0
    q[m] = np.stack(
        [
            (c[m, 0, 2] - c[m, 2, 0]) / s,
            (c[m, 0, 1] + c[m, 1, 0]) / s,
            0.25 * s,
            (c[m, 1, 2] + c[m, 2, 1]) / s,
        ],
        axis=1,
    )
    m = k == 3
    s = np.sqrt(1.0 + c[m, 2, 2] - c[m, 0, 0] - c[m, 1, 1]) * 2.0
    q[m] = np.stack(
        [
            (c[m, 1, 0] - c[m, 0, 1]) / s,
            (c[m, 0, 2] + c[m, 2, 0]) / s,
            (c[m, 1, 2] + c[m, 2, 1]) / s,
            0.25 * s,
        ],
        axis=1,
    )
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def quat_continuous(q: np.ndarray) -> np.ndarray:
    """Unit-normalise and flip signs so consecutive quaternions lie in the same hemisphere (w >= 0 first)."""
    q = np.asarray(q, np.float64)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    if q.shape[0] == 0:
        return q
    sgn = np.ones(q.shape[0])
    sgn[0] = -1.0 if q[0, 0] < 0 else 1.0
    sgn[1:] = np.where(np.einsum("ij,ij->i", q[1:], q[:-1]) < 0, -1.0, 1.0)
    return q * np.cumprod(sgn)[:, None]


def euler_zyx_to_quat(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """ZYX Euler angles (rad) of body w.r.t. NED to (N,4) q_nb (DESIGN.md 2)."""
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return np.stack(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ],
        axis=1,
    )


def c_ne(lat_rad: np.ndarray, lon_rad: np.ndarray) -> np.ndarray:
    """(N,3,3) rotation ECEF -> local NED at each latitude/longitude (v_ned = C_ne v_ecef)."""
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    so, co = np.sin(lon_rad), np.cos(lon_rad)
    c = np.empty((np.size(lat_rad), 3, 3))
    c[:, 0] = np.stack([-sl * co, -sl * so, cl], axis=1)
    c[:, 1] = np.stack([-so, co, np.zeros_like(so)], axis=1)
    c[:, 2] = np.stack([-cl * co, -cl * so, -sl], axis=1)
    return c


def imu_array_from(t_us: np.ndarray, gyro_rps: np.ndarray, accel_mps2: np.ndarray, source: str) -> np.ndarray:
    """Build an ``IMU_DTYPE`` array (the caller sorts); non-finite gyro/accel values are an error."""
    bad = ~(np.isfinite(gyro_rps).all(axis=1) & np.isfinite(accel_mps2).all(axis=1))
    need(not bad.any(), source, f"{int(bad.sum())} IMU rows with non-finite gyro/accel values")
    out = np.zeros(len(t_us), IMU_DTYPE)
    out["t_us"] = t_us
    out["gyro_rps"] = gyro_rps
    out["accel_mps2"] = accel_mps2
    return out


def empty_gnss() -> np.ndarray:
    """A zero-length ``GNSS_DTYPE`` array."""
    return np.zeros(0, GNSS_DTYPE)

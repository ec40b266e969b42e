"""comma2k19 segment folders -> :class:`~mcahrs.samples.Recording`.

A segment folder holds ``processed_log/`` and ``global_pose/``; every file is a plain ``.npy``
without extension (see ``data/comma2k19/README.md``). What this loader assumes, per that README:

* One clock: device boot seconds, shared by every ``t`` array and ``global_pose/frame_times``.
  ``t_us`` = round(boot seconds * 1e6) for IMU, magnetometer, reference and GNSS arrival.
* IMU (``processed_log/IMU``): specific force m/s^2 and rate rad/s in the device FRD frame, which is
  also the frame of the reference pose, so no mounting rotation is applied. ``gyro`` has Android's
  bias removed (``raw_gyro=True`` takes ``gyro_uncalibrated``).
* GNSS (``live_gnss_ublox``, or ``live_gnss_qcom``): columns lat deg, lon deg, speed m/s,
  ``utc_timestamp`` ms since 1970 UTC (the fix epoch), altitude m (ellipsoidal per the README),
  course deg. ``t_us`` is the epoch mapped to boot time through GPS time
  (GPS = UTC + leap seconds; boot = GPS TOW - (frame_gps_times TOW - frame_times)); ``t_rx_us`` is
  the arrival ``t``. Velocity N/E = speed * (cos, sin)(course); D and all accuracies: NaN.
* Reference (``global_pose``): ``frame_orientations`` q maps device FRD into ECEF; with the NED
  frame at each ``frame_positions`` point, ``C_nb = C_ne(lat, lon) R(q)``.
* Magnetometer (``processed_log/IMU/magnetometer``, optional): microtesla, as stored. Its axes and
  calibration are NOT verified: rotated with the reference attitude, the example segment's field
  points 36 deg up, where the real field dips 61 deg down. ``meta['mag_warning']`` says so.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mcahrs.samples import (
    GNSS_DTYPE,
    GNSS_HAS_ALT,
    GNSS_HAS_COURSE,
    GNSS_HAS_VEL_NE,
    MAG_DTYPE,
    REF_DTYPE,
    Recording,
)

from ._common import (
    GPS_EPOCH_UNIX_S,
    SECONDS_PER_WEEK,
    LoaderError,
    c_ne,
    dcm_to_quat,
    deg_to_e7,
    gps_minus_utc_s,
    imu_array_from,
    m_to_mm,
    need,
    quat_continuous,
    quat_to_dcm,
    rate_stats,
    sort_unique,
    wrap_2pi,
)


def is_segment(path: Path) -> bool:
    """True when ``path`` is a comma2k19 segment folder (has ``processed_log/IMU``)."""
    return (path / "processed_log" / "IMU").is_dir()


def find_segment(path: str | Path) -> Path:
    """The segment folder at ``path``, or its only segment sub-folder (searched two levels down)."""
    path = Path(path)
    if is_segment(path):
        return path
    cands = [p for p in sorted(path.glob("*")) + sorted(path.glob("*/*")) if p.is_dir() and is_segment(p)]
    need(
        len(cands) == 1,
        path,
        f"expected one comma2k19 segment (folder with processed_log/IMU), found {len(cands)}",
    )
    return cands[0]


def _npy(seg: Path, rel: str, ncols: int | None = None) -> np.ndarray:
    """Load ``seg/rel`` as .npy, checking it exists, is numeric and has ``ncols`` columns."""
    f = seg / rel
    need(f.is_file(), f, "file not found")
    try:
        a = np.load(f, allow_pickle=False)
    except (ValueError, OSError) as exc:
        raise LoaderError(f"{f}: not a readable .npy file ({exc})") from exc
    need(a.dtype.kind in "fiu", f, f"expected a numeric array, got dtype {a.dtype}")
    if ncols is not None:
        need(a.ndim == 2 and a.shape[1] == ncols, f, f"expected shape (N, {ncols}), got {a.shape}")
    return a.astype(np.float64)


def _times_us(seg: Path, rel: str, n: int) -> np.ndarray:
    t = _npy(seg, rel)
    need(t.ndim == 1 and t.size == n, seg / rel, f"expected {n} times, got shape {t.shape}")
    need(bool(np.isfinite(t).all()), seg / rel, "non-finite times")
    return np.round(t * 1e6).astype(np.int64)


def _gps_minus_boot(seg: Path) -> tuple[float, int]:
    """(GPS TOW - boot seconds, GPS week) from global_pose; the README measures it constant to 4e-11 s."""
    ft = _npy(seg, "global_pose/frame_times")
    fg = _npy(seg, "global_pose/frame_gps_times", 2)
    need(
        ft.size == fg.shape[0] and ft.size > 0,
        seg / "global_pose/frame_gps_times",
        "row count differs from frame_times",
    )
    weeks = np.unique(fg[:, 0])
    off = fg[:, 1] + (fg[:, 0] - weeks[0]) * SECONDS_PER_WEEK - ft
    need(float(np.ptp(off)) < 1e-3, seg / "global_pose/frame_gps_times", "GPS - boot offset is not constant")
    return float(np.median(off)), int(weeks[0])


def _load_gnss(seg: Path, receiver: str, gps_minus_boot_s: float, week: int, meta: dict) -> np.ndarray:
    rel = f"processed_log/GNSS/live_gnss_{receiver}"
    v = _npy(seg, f"{rel}/value", 6)
    t_rx = _times_us(seg, f"{rel}/t", v.shape[0])
    src = str(seg / rel / "value")
    utc_s = v[:, 3] * 1e-3  # utc_timestamp is in ms (upstream says s; README section 5)
    need(bool(np.isfinite(utc_s).all()), src, "non-finite utc_timestamp (column 3)")
    leap = gps_minus_utc_s(float(utc_s[0]), src)
    tow = utc_s - GPS_EPOCH_UNIX_S + leap - week * SECONDS_PER_WEEK
    n = v.shape[0]
    out = np.zeros(n, GNSS_DTYPE)
    out["t_us"] = np.round((tow - gps_minus_boot_s) * 1e6).astype(np.int64)
    out["t_rx_us"] = t_rx
    out["lat_e7"] = deg_to_e7(v[:, 0], src, "latitude (column 0)", 90.0)
    out["lon_e7"] = deg_to_e7(v[:, 1], src, "longitude (column 1)", 180.0)
    out["alt_mm"] = m_to_mm(v[:, 4], src, "altitude (column 4)")
    speed, course = v[:, 2], np.deg2rad(v[:, 5])
    out["vel_ned_mps"] = np.stack(
        [speed * np.cos(course), speed * np.sin(course), np.full(n, np.nan)], axis=1
    )
    out["speed_mps"] = speed
    out["course_rad"] = wrap_2pi(course)
    out["h_acc_m"] = out["v_acc_m"] = out["s_acc_mps"] = np.nan
    out["fix_type"] = 3  # not given; the dataset keeps only fixes, assumed 3D
    out["num_sv"] = 0  # not given
    out["flags"] = GNSS_HAS_ALT | GNSS_HAS_VEL_NE | GNSS_HAS_COURSE
    lat_s = (out["t_rx_us"] - out["t_us"]) * 1e-6
    meta["gnss_leap_s"] = leap
    meta["gnss_arrival_latency_s"] = {
        "min": float(lat_s.min()),
        "mean": float(lat_s.mean()),
        "max": float(lat_s.max()),
    }
    late = out["t_rx_us"] < out["t_us"]
    meta["gnss_arrival_before_epoch"] = int(late.sum())
    out["t_rx_us"] = np.maximum(out["t_rx_us"], out["t_us"])
    idx, ndup = sort_unique(out["t_us"])
    meta["gnss_dropped_duplicate_time"] = ndup
    return out[idx]


def _load_ref(seg: Path) -> np.ndarray:
    import pymap3d  # local import: only this loader needs it

    t = _npy(seg, "global_pose/frame_times")
    pos = _npy(seg, "global_pose/frame_positions", 3)
    qe = _npy(seg, "global_pose/frame_orientations", 4)
    n = t.size
    need(pos.shape[0] == n and qe.shape[0] == n, seg / "global_pose", "frame_* files differ in row count")
    need(
        bool(np.isfinite(pos).all() and np.isfinite(qe).all()), seg / "global_pose", "non-finite pose values"
    )
    lat, lon, _ = pymap3d.ecef2geodetic(pos[:, 0], pos[:, 1], pos[:, 2], deg=False)
    nrm = np.linalg.norm(qe, axis=1)
    need(
        bool(np.all(np.abs(nrm - 1.0) < 1e-3)),
        seg / "global_pose/frame_orientations",
        "quaternions not unit norm",
    )
    c_eb = quat_to_dcm(qe / nrm[:, None])  # device FRD -> ECEF
    c_nb = np.einsum("nij,njk->nik", c_ne(np.asarray(lat), np.asarray(lon)), c_eb)
    idx, _ = sort_unique(np.round(t * 1e6).astype(np.int64))
    out = np.zeros(idx.size, REF_DTYPE)
    out["t_us"] = np.round(t[idx] * 1e6).astype(np.int64)
    out["q_nb"] = quat_continuous(dcm_to_quat(c_nb[idx]))
    return out


def load_comma2k19(path: str | Path, *, receiver: str = "ublox", raw_gyro: bool = False) -> Recording:
    """Load a comma2k19 segment folder (or a folder holding exactly one segment).

    ``receiver`` is ``"ublox"`` (10 Hz, default) or ``"qcom"`` (phone receiver, 0.5 Hz).
    ``raw_gyro=True`` loads ``gyro_uncalibrated`` instead of the bias-removed ``gyro``.
    """
    need(receiver in ("ublox", "qcom"), str(path), f"receiver must be 'ublox' or 'qcom', not {receiver!r}")
    seg = find_segment(path)
    gyro_name = "gyro_uncalibrated" if raw_gyro else "gyro"
    acc = _npy(seg, "processed_log/IMU/accelerometer/value", 3)
    gyr = _npy(seg, f"processed_log/IMU/{gyro_name}/value", 3)
    t_acc = _times_us(seg, "processed_log/IMU/accelerometer/t", acc.shape[0])
    t_gyr = _times_us(seg, f"processed_log/IMU/{gyro_name}/t", gyr.shape[0])
    need(np.array_equal(t_acc, t_gyr), seg / "processed_log/IMU", f"accelerometer/t and {gyro_name}/t differ")
    idx, ndup = sort_unique(t_acc)
    imu = imu_array_from(t_acc[idx], gyr[idx], acc[idx], str(seg / "processed_log/IMU"))

    gps_minus_boot_s, week = _gps_minus_boot(seg)
    meta: dict = {
        "source": "comma2k19",
        "segment": seg.name,
        "time_base": "device boot time, integer microseconds (one clock for IMU, mag, GNSS arrival, pose)",
        "gps_week": week,
        "gps_tow_minus_boot_s": gps_minus_boot_s,
        "imu_frame": "device FRD (EON); the reference pose is of the same rigid device: no mounting applied",
        "imu_gyro": f"{gyro_name} ({'raw' if raw_gyro else 'Android bias removed'})",
        "imu_dropped_duplicate_time": ndup,
        "mounting": "none applied; the device sits about -3.75 deg pitch, +1.25 deg roll in the car (README)",
        "lever_arm": "unknown; u-blox fixes sit about 2 m north (along-track) of the pose (README)",
        "gnss_receiver": receiver,
        "gnss_notes": "t_us from utc_timestamp (fix epoch); vel N/E from speed+course, no D; "
        "no accuracy fields (NaN); fix_type assumed 3, num_sv unknown (0); altitude ellipsoidal",
        "mag_unit": "uT (Android-calibrated; axes as stored)",
        "mag_warning": "frame/calibration unverified: with the reference attitude the example "
        "segment's field points 36 deg UP (IGRF there: 61 deg down); do not use it for heading",
        "ref_source": "global_pose: device->ECEF quaternion rotated into local NED at frame_positions",
    }
    gnss = _load_gnss(seg, receiver, gps_minus_boot_s, week, meta)
    if (seg / "processed_log/IMU/magnetometer/value").is_file():
        mv = _npy(seg, "processed_log/IMU/magnetometer/value", 3)
        mt = _times_us(seg, "processed_log/IMU/magnetometer/t", mv.shape[0])
        ok = np.isfinite(mv).all(axis=1)
        midx, _ = sort_unique(mt[ok])
        mag = np.zeros(midx.size, MAG_DTYPE)
        mag["t_us"] = mt[ok][midx]
        mag["mag_b"] = mv[ok][midx]
    else:
        mag = np.zeros(0, MAG_DTYPE)
        meta["mag_unit"] = "none (no processed_log/IMU/magnetometer)"
    ref = _load_ref(seg)
    meta["imu"] = rate_stats(imu["t_us"])
    meta["gnss"] = rate_stats(gnss["t_us"])
    meta["mag"] = rate_stats(mag["t_us"])
    meta["ref"] = rate_stats(ref["t_us"])
    return Recording(f"comma2k19/{seg.name}", imu, gnss, mag, ref, meta)

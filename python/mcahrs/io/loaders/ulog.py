"""PX4 ULog flight logs -> :class:`~mcahrs.samples.Recording` (via pyulog).

Topics read (multi-instance 0):

* IMU ``sensor_combined`` (required): ``gyro_rad`` (older: ``gyro_rad_s``) and
  ``accelerometer_m_s2``, body FRD, SI, board rotation and calibration already applied by PX4.
  Each value is the mean over ``*_integral_dt`` ending at ``timestamp``; ``t_us`` is that
  ``timestamp``. Rows whose ``accelerometer_timestamp_relative`` is PX4's "invalid" marker are
  dropped; a non-zero relative accel time is reported in ``meta`` but not resampled. Samples
  missing from a full-rate topic (time no sample's ``*_integral_dt`` covers) are put
  back with the local mean rate and specific force (``_fill_dropped``; ``fill_dropped=False``
  keeps the samples as logged).
* GNSS ``vehicle_gps_position`` or ``sensor_gps`` (required): both field layouts
  (``lat``/``lon`` int 1e-7 deg and ``alt`` mm up to PX4 1.14; ``latitude_deg``/``longitude_deg``
  float64 deg and ``altitude_*_m`` from 1.15). Validity time ``t_us`` is ``timestamp_sample``
  when the topic has it and it is non-zero, else the old ``timestamp_position``, else
  ``timestamp - gps_delay_us``; ``t_rx_us`` is ``timestamp`` (publication on the autopilot,
  which already contains the receiver latency). Fixes with ``fix_type`` < 2 are dropped.
* Magnetometer (optional): ``vehicle_magnetometer.magnetometer_ga`` (calibrated, body), else
  the old ``sensor_combined.magnetometer_ga``, else ``sensor_mag`` x/y/z (uncalibrated board
  frame, used only when ``SENS_BOARD_ROT`` is 0). Gauss.
* Reference (optional): ``vehicle_attitude.q``, EKF2's Hamilton [w,x,y,z] body FRD -> NED
  (older logs without ``q``: from ``roll``/``pitch``/``yaw``). Time ``timestamp_sample`` if
  filled, else ``timestamp``.

All times stay on the autopilot boot clock (integer microseconds), which is the IMU clock.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np

from mcahrs.samples import (
    GNSS_DTYPE,
    GNSS_HAS_ALT,
    GNSS_HAS_COURSE,
    GNSS_HAS_VEL_D,
    GNSS_HAS_VEL_NE,
    MAG_DTYPE,
    REF_DTYPE,
    Recording,
)

from ._common import (
    LoaderError,
    deg_to_e7,
    euler_zyx_to_quat,
    imu_array_from,
    m_to_mm,
    need,
    quat_continuous,
    rate_stats,
    sort_unique,
    wrap_2pi,
)

IMU_TOPIC = "sensor_combined"
GPS_TOPICS = ("vehicle_gps_position", "sensor_gps")
_TOPICS = [IMU_TOPIC, *GPS_TOPICS, "vehicle_magnetometer", "sensor_mag", "vehicle_attitude"]
_REL_INVALID = 0x7FFFFFFF  # PX4 RELATIVE_TIMESTAMP_INVALID


def _vec(data: dict, names: tuple[str, ...], n: int, topic: str, source: str) -> np.ndarray:
    """Stack ``name[0..n-1]`` of the first of ``names`` that the topic has, as float64 (N, n)."""
    for name in names:
        if f"{name}[0]" in data:
            return np.stack([np.asarray(data[f"{name}[{i}]"], np.float64) for i in range(n)], axis=1)
    raise LoaderError(f"{source}: topic {topic!r} has none of the fields {', '.join(names)}")


def _nonzero_field(data: dict, name: str) -> np.ndarray | None:
    """The int64 field if present with at least one non-zero value, else None."""
    if name in data:
        v = np.asarray(data[name]).astype(np.int64)
        if np.any(v != 0):
            return v
    return None


def _sw_version(info: dict) -> str:
    rel = info.get("ver_sw_release")
    if isinstance(rel, int) and rel:
        return f"v{(rel >> 24) & 0xFF}.{(rel >> 16) & 0xFF}.{(rel >> 8) & 0xFF}"
    return str(info.get("ver_sw", "unknown"))


def _fill_dropped(
    t: np.ndarray, gyro: np.ndarray, acc: np.ndarray, dt_us: np.ndarray, meta: dict
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Put back the samples missing from a full-rate IMU topic.

    Each sample is the mean over its ``*_integral_dt`` ending at its time, so time that no
    sample covers (``t_i - t_(i-1) - dt_i``, at least half the median ``dt``) is samples the
    log lacks (log_61: 1106 next to its 14631, 7.3 % of the time; the ULog records no logger
    dropout, so the logged ``sensor_combined`` itself skipped them, while EKF2 integrates each
    IMU's own ``vehicle_imu``). Left alone, the replay takes the next sample's rate over the gap too.
    Each one is put back at its place, ``round(gap / median dt)`` samples ending at
    ``t_i - dt_i``, with the mean of the two samples before the gap and the two after it: the
    vibration averaged out (log_61's gyro has a lag-1 autocorrelation of -0.55 in flight, so a
    neighbour alone is the worse guess). On log_61 the gyro alone, from EKF2's attitude and
    bias, drifts from EKF2 by 0.83 degrees in 10 s with them, 1.73 without (worst of roll and
    pitch, mean of 20 starts; ``docs/OUTLIERS.md``, session 30). Only a full-rate topic is
    filled (median spacing within 1.5 median ``dt``): a throttled log (esc_status_log, 4 ms
    means 104 ms apart) is left as it is. ``meta["imu_filled_samples"]`` counts them."""
    med = float(np.median(dt_us))
    meta["imu_filled_samples"] = 0
    if t.size < 4 or not med > 0.0 or float(np.median(np.diff(t))) > 1.5 * med:
        return t, gyro, acc
    gap = (t[1:] - t[:-1]).astype(np.float64) - dt_us[1:]
    n = np.where(gap >= 0.5 * med, np.rint(gap / med), 0.0).astype(np.int64)
    after = np.flatnonzero(n) + 1  # the sample after each gap
    if after.size == 0:
        return t, gyro, acc
    counts = n[after - 1]
    rank = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)  # 0..n-1 in a gap
    at = np.repeat(after, counts)
    end = t[at] - np.rint(dt_us[at]).astype(np.int64)
    start = t[at - 1]
    k = np.repeat(counts, counts)
    t_new = start + np.rint((end - start) * (rank + 1) / k).astype(np.int64)
    near = np.clip(at[:, None] + np.arange(-2, 2)[None, :], 0, t.size - 1)
    g_new, a_new = gyro[near].mean(axis=1), acc[near].mean(axis=1)
    ok = (t_new > start) & (t_new < t[at]) & (end - start >= k)  # distinct, inside the gap
    meta["imu_filled_samples"] = int(ok.sum())
    order = np.argsort(np.concatenate([t, t_new[ok]]), kind="stable")
    return (
        np.concatenate([t, t_new[ok]])[order],
        np.concatenate([gyro, g_new[ok]])[order],
        np.concatenate([acc, a_new[ok]])[order],
    )


def _load_imu(data: dict, source: str, meta: dict, fill_dropped: bool = True) -> np.ndarray:
    t = np.asarray(data["timestamp"]).astype(np.int64)
    ts = _nonzero_field(data, "timestamp_sample")
    if ts is not None:
        t = np.where(ts > 0, ts, t)
    gyro = _vec(data, ("gyro_rad", "gyro_rad_s"), 3, IMU_TOPIC, source)
    acc = _vec(data, ("accelerometer_m_s2",), 3, IMU_TOPIC, source)
    keep = np.ones(t.size, bool)
    if "accelerometer_timestamp_relative" in data:
        rel = np.asarray(data["accelerometer_timestamp_relative"]).astype(np.int64)
        keep &= rel != _REL_INVALID
        meta["imu_accel_time_relative_max_us"] = int(np.abs(rel[keep]).max()) if keep.any() else 0
        meta["imu_dropped_invalid_accel"] = int((~keep).sum())
    sel = np.flatnonzero(keep)
    order, ndup = sort_unique(t[sel])
    idx = sel[order]
    meta["imu_dropped_duplicate_time"] = ndup
    need(idx.size >= 2, source, f"topic {IMU_TOPIC!r} has fewer than 2 usable samples")
    t, gyro, acc = t[idx], gyro[idx], acc[idx]
    if "gyro_integral_dt" in data:
        dt = np.asarray(data["gyro_integral_dt"], np.float64)
        # PX4 <= 1.6 logged the integral dt as float seconds, later as uint32 microseconds.
        dt_us = (dt * 1e6 if np.asarray(data["gyro_integral_dt"]).dtype.kind == "f" else dt)[idx]
        meta["imu_integral_dt_median_us"] = float(np.median(dt_us))
        if fill_dropped:
            t, gyro, acc = _fill_dropped(t, gyro, acc, dt_us, meta)
    if "gyro_clipping" in data:
        meta["imu_gyro_clipping_samples"] = int(np.count_nonzero(np.asarray(data["gyro_clipping"])))
    if "accelerometer_clipping" in data:
        meta["imu_accel_clipping_samples"] = int(np.count_nonzero(np.asarray(data["accelerometer_clipping"])))
    return imu_array_from(t, gyro, acc, source)


def _load_gnss(data: dict, topic: str, source: str, gps_delay_us: int, meta: dict) -> np.ndarray:
    t_rx = np.asarray(data["timestamp"]).astype(np.int64)
    t_fix = t_rx - int(gps_delay_us)
    how = f"timestamp - {int(gps_delay_us)} us (arrival on the autopilot minus gps_delay_us)"
    for name in ("timestamp_sample", "timestamp_position"):
        v = _nonzero_field(data, name)
        if v is not None:
            t_fix = np.where(v > 0, v, t_fix)
            how = f"{name} (rows where it is 0: timestamp - {int(gps_delay_us)} us)"
            break
    meta["gnss_time_source"] = how

    if "lat" in data:
        lat = deg_to_e7(np.asarray(data["lat"], np.float64) * 1e-7, source, f"{topic}.lat", 90.0)
        lon = deg_to_e7(np.asarray(data["lon"], np.float64) * 1e-7, source, f"{topic}.lon", 180.0)
    elif "latitude_deg" in data:
        lat = deg_to_e7(data["latitude_deg"], source, f"{topic}.latitude_deg", 90.0)
        lon = deg_to_e7(data["longitude_deg"], source, f"{topic}.longitude_deg", 180.0)
    else:
        raise LoaderError(f"{source}: topic {topic!r} has neither lat/lon nor latitude_deg/longitude_deg")

    # Height: ellipsoidal if the log has it (non-zero), else MSL.
    alt_m = None
    for name, scale in (
        ("alt_ellipsoid", 1e-3),
        ("altitude_ellipsoid_m", 1.0),
        ("alt", 1e-3),
        ("altitude_msl_m", 1.0),
    ):
        if name in data and np.any(np.asarray(data[name]) != 0):
            alt_m = np.asarray(data[name], np.float64) * scale
            meta["gnss_alt_field"] = name
            break
    if alt_m is None:
        raise LoaderError(f"{source}: topic {topic!r} has no non-zero altitude field")
    alt = m_to_mm(alt_m, source, f"{topic}.{meta['gnss_alt_field']}")
    if "alt_ellipsoid" in data and "alt" in data and np.array_equal(data["alt_ellipsoid"], data["alt"]):
        meta["gnss_alt_note"] = "alt_ellipsoid equals alt (MSL) in every fix: the height is probably MSL"

    n = t_rx.size
    out = np.zeros(n, GNSS_DTYPE)
    out["t_us"] = t_fix
    out["t_rx_us"] = np.maximum(t_rx, t_fix)
    out["lat_e7"], out["lon_e7"], out["alt_mm"] = lat, lon, alt
    flags = np.full(n, GNSS_HAS_ALT, np.uint8)
    vel = np.full((n, 3), np.nan)
    if all(f"vel_{a}_m_s" in data for a in "ned"):
        valid = (
            np.asarray(data["vel_ned_valid"]).astype(bool) if "vel_ned_valid" in data else np.ones(n, bool)
        )
        for i, a in enumerate("ned"):
            vel[valid, i] = np.asarray(data[f"vel_{a}_m_s"], np.float64)[valid]
        flags[valid] |= GNSS_HAS_VEL_NE | GNSS_HAS_VEL_D
    out["vel_ned_mps"] = vel
    if "vel_m_s" in data and "cog_rad" in data:
        out["speed_mps"] = np.asarray(data["vel_m_s"], np.float64)
        out["course_rad"] = wrap_2pi(np.asarray(data["cog_rad"], np.float64))
        flags |= GNSS_HAS_COURSE
    else:
        out["speed_mps"] = np.nan
        out["course_rad"] = np.nan
    out["flags"] = flags
    for dst, src in (("h_acc_m", "eph"), ("v_acc_m", "epv"), ("s_acc_mps", "s_variance_m_s")):
        out[dst] = np.asarray(data[src], np.float64) if src in data else np.nan
    fix = np.asarray(data["fix_type"]).astype(np.int64) if "fix_type" in data else np.full(n, 3)
    out["fix_type"] = np.where(fix <= 1, 0, np.minimum(fix, 6))  # PX4 0/1 = no fix
    if "satellites_used" in data:
        out["num_sv"] = np.clip(np.asarray(data["satellites_used"]).astype(np.int64), 0, 255)

    good = fix >= 2
    meta["gnss_dropped_no_fix"] = int((~good).sum())
    out = out[good]
    idx, ndup = sort_unique(out["t_us"])
    meta["gnss_dropped_duplicate_time"] = ndup
    return out[idx]


def _load_mag(ds: dict, imu_data: dict, params: dict, source: str, meta: dict) -> np.ndarray:
    t = mag = None
    if ("vehicle_magnetometer", 0) in ds:
        d = ds[("vehicle_magnetometer", 0)]
        t = np.asarray(d["timestamp"]).astype(np.int64)
        ts = _nonzero_field(d, "timestamp_sample")
        t = np.where(ts > 0, ts, t) if ts is not None else t
        mag = _vec(d, ("magnetometer_ga",), 3, "vehicle_magnetometer", source)
        meta["mag_source"] = "vehicle_magnetometer.magnetometer_ga (calibrated, body FRD, gauss)"
    elif "magnetometer_ga[0]" in imu_data:
        t = np.asarray(imu_data["timestamp"]).astype(np.int64)
        if "magnetometer_timestamp_relative" in imu_data:
            rel = np.asarray(imu_data["magnetometer_timestamp_relative"]).astype(np.int64)
            ok = rel != _REL_INVALID
            t = t[ok] + rel[ok]
            mag = _vec(imu_data, ("magnetometer_ga",), 3, IMU_TOPIC, source)[ok]
        else:
            mag = _vec(imu_data, ("magnetometer_ga",), 3, IMU_TOPIC, source)
        meta["mag_source"] = "sensor_combined.magnetometer_ga (old layout, body FRD, gauss)"
    elif ("sensor_mag", 0) in ds and int(params.get("SENS_BOARD_ROT", 0)) == 0:
        d = ds[("sensor_mag", 0)]
        t = np.asarray(d["timestamp"]).astype(np.int64)
        ts = _nonzero_field(d, "timestamp_sample")
        t = np.where(ts > 0, ts, t) if ts is not None else t
        mag = np.stack([np.asarray(d[a], np.float64) for a in "xyz"], axis=1)
        meta["mag_source"] = "sensor_mag[0] x/y/z (UNCALIBRATED, board frame = body since SENS_BOARD_ROT=0)"
    else:
        meta["mag_source"] = "none (no vehicle_magnetometer; sensor_mag not usable as body frame)"
        return np.zeros(0, MAG_DTYPE)
    ok = np.isfinite(mag).all(axis=1)
    idx, _ = sort_unique(t[ok])
    out = np.zeros(idx.size, MAG_DTYPE)
    out["t_us"] = t[ok][idx]
    out["mag_b"] = mag[ok][idx]
    return out


def _load_ref(d: dict, source: str, meta: dict) -> np.ndarray:
    t = np.asarray(d["timestamp"]).astype(np.int64)
    ts = _nonzero_field(d, "timestamp_sample")
    if ts is not None:
        t = np.where(ts > 0, ts, t)
    if "q[0]" in d:
        q = _vec(d, ("q",), 4, "vehicle_attitude", source)
        meta["ref_source"] = "vehicle_attitude.q (EKF2, Hamilton [w,x,y,z], body FRD -> NED)"
    elif all(k in d for k in ("roll", "pitch", "yaw")):
        q = euler_zyx_to_quat(*(np.asarray(d[k], np.float64) for k in ("roll", "pitch", "yaw")))
        meta["ref_source"] = "vehicle_attitude roll/pitch/yaw (old layout) -> q_nb"
    else:
        raise LoaderError(f"{source}: topic 'vehicle_attitude' has neither q[0..3] nor roll/pitch/yaw")
    nrm = np.linalg.norm(q, axis=1)
    ok = np.isfinite(q).all(axis=1) & (np.abs(nrm - 1.0) < 0.01)
    meta["ref_dropped_invalid"] = int((~ok).sum())
    if "quat_reset_counter" in d:
        rc = np.asarray(d["quat_reset_counter"]).astype(np.int64)
        meta["ref_quat_resets"] = int(np.count_nonzero(np.diff(rc)))
    idx, _ = sort_unique(t[ok])
    out = np.zeros(idx.size, REF_DTYPE)
    out["t_us"] = t[ok][idx]
    out["q_nb"] = quat_continuous(q[ok][idx])
    return out


def load_ulog(
    path: str | Path,
    *,
    gps_topic: str | None = None,
    gps_delay_us: int | None = None,
    fill_dropped: bool = True,
) -> Recording:
    """Load a PX4 ULog file.

    ``gps_topic`` forces ``"vehicle_gps_position"`` or ``"sensor_gps"`` (default: the first of the
    two that the log has). ``gps_delay_us`` is subtracted from the publication ``timestamp`` to
    get the fix validity time when the topic has no usable ``timestamp_sample``. Default: the
    receiver latency the autopilot itself was configured with (``EKF2_GPS_DELAY``, recorded in
    the log: a fact of the recording, not a tuning), else 0; ``meta["gps_delay_us_applied"]``.
    ``fill_dropped`` puts back the IMU samples missing from the log (``_fill_dropped``; False: the
    samples as logged).
    Raises :class:`LoaderError` when the file is unreadable or a required topic is missing.
    """
    from pyulog import ULog  # local import: pyulog is only needed for ULog files

    path = Path(path)
    source = str(path)
    need(path.is_file(), source, "file not found")
    try:
        ulog = ULog(str(path), _TOPICS)
    except Exception as exc:  # pyulog raises assorted types on corrupt input
        raise LoaderError(f"{source}: not a readable ULog file ({type(exc).__name__}: {exc})") from exc

    ds = {(d.name, d.multi_id): d.data for d in ulog.data_list}
    present = sorted({name for name, _ in ds})
    need((IMU_TOPIC, 0) in ds, source, f"required topic {IMU_TOPIC!r} is missing (topics read: {present})")
    if gps_topic is None:
        gps_topic = next((t for t in GPS_TOPICS if (t, 0) in ds), None)
        need(
            gps_topic is not None,
            source,
            f"required GNSS topic missing: none of {', '.join(GPS_TOPICS)} (topics read: {present})",
        )
    need((gps_topic, 0) in ds, source, f"requested GNSS topic {gps_topic!r} is missing")
    assert gps_topic is not None

    params = ulog.initial_parameters
    if gps_delay_us is None:
        gps_delay_us = int(round(float(params["EKF2_GPS_DELAY"]) * 1000)) if "EKF2_GPS_DELAY" in params else 0
    meta: dict = {
        "source": "ulog",
        "file": path.name,
        "px4_version": _sw_version(ulog.msg_info_dict),
        "hardware": ulog.msg_info_dict.get("ver_hw", "unknown"),
        "time_base": "PX4 boot time (autopilot clock), integer microseconds; IMU, GNSS, mag and ref share it",
        "log_start_us": int(ulog.start_timestamp),
        "log_end_us": int(ulog.last_timestamp),
        "logger_dropouts": len(ulog.dropouts),
        "imu_topic": IMU_TOPIC,
        "imu_frame": "body FRD (PX4 applies SENS_BOARD_ROT, trims and calibration before logging)",
        "imu_sample_meaning": "mean rate / mean specific force over *_integral_dt ending at t_us",
        "gnss_topic": gps_topic,
        "gnss_t_rx_meaning": "timestamp: when the fix was published on the autopilot",
        "px4_sens_board_rot": int(params.get("SENS_BOARD_ROT", 0)),
        "px4_ekf2_gps_delay_us": int(round(float(params["EKF2_GPS_DELAY"]) * 1000))
        if "EKF2_GPS_DELAY" in params
        else None,  # the autopilot's own GNSS latency setting (ms param)
        "gps_delay_us_applied": int(gps_delay_us),
        "mounting": "none applied here (already in body FRD)",
    }
    imu_data = ds[(IMU_TOPIC, 0)]
    imu = _load_imu(imu_data, source, meta, fill_dropped)
    gdata = ds[(gps_topic, 0)]
    gnss = _load_gnss(gdata, gps_topic, source, gps_delay_us, meta)
    if "time_utc_usec" in gdata:
        tu = np.asarray(gdata["time_utc_usec"]).astype(np.int64)
        ok = tu > 0
        if ok.any():
            ts = np.asarray(gdata["timestamp"]).astype(np.int64)[ok]
            meta["utc_minus_boot_us_median"] = int(np.median(tu[ok] - ts))
            meta["utc_first_fix"] = _dt.datetime.fromtimestamp(tu[ok][0] * 1e-6, _dt.timezone.utc).isoformat()
    mag = _load_mag(ds, imu_data, params, source, meta)
    ref = _load_ref(ds[("vehicle_attitude", 0)], source, meta) if ("vehicle_attitude", 0) in ds else None
    if ref is None:
        meta["ref_source"] = "none (no vehicle_attitude topic)"
    meta["imu"] = rate_stats(imu["t_us"])
    meta["gnss"] = rate_stats(gnss["t_us"])
    meta["mag"] = rate_stats(mag["t_us"])
    meta["ref"] = rate_stats(ref["t_us"]) if ref is not None else None
    return Recording(path.stem, imu, gnss, mag, ref, meta)

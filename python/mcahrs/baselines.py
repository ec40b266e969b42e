"""IMU-only attitude filters users reach for, run on a :class:`~mcahrs.samples.Recording`.

These are the baselines ``mcahrs evaluate`` compares MCAHRS against. Neither uses GNSS, so
neither can tell a maneuver acceleration from gravity; their yaw is meaningless here and only
roll and pitch are compared. Each returns ``{"t_us", "q", "roll_rad", "pitch_rad", "note"}``,
one row per IMU sample. ``q`` is the filter's own quaternion (body -> its earth frame);
roll and pitch are computed from the down direction in body axes, so the filter's earth-frame
convention (ENU for VQF, NED for Fusion) does not matter.

* **VQF** (``vqf`` package, the online C++ ``VQF`` class, causal like MCAHRS): gyro rad/s,
  specific force m/s^2, any body frame. It needs a constant sample time: ``Ts`` is the median
  IMU interval and a sample that closes a gap of ``k`` intervals is fed ``k`` times (the
  ULog loader puts back the 5 ms samples missing from a PX4 log, so on log_61 there are none
  left). 9D when the recording has a magnetometer (``updateMag`` at each magnetometer
  sample, ``magTs`` its median interval), else 6D. VQF's magnetometer only turns heading
  (its 9D quaternion is the 6D one rotated about the vertical), so roll/pitch are the same.
* **x-io Fusion** (``imufusion`` >= 1.3, the revised Madgwick AHRS of Madgwick's thesis, ch. 7), NED
  convention, gyro deg/s, accelerometer in g, the variable IMU interval per sample, with the
  settings its README calls appropriate for most applications: gain 0.5, acceleration
  rejection 10 deg, rejection timeout 5 s, gyroscope range 2000 deg/s, and its gyroscope
  offset (bias) algorithm in front. Without a magnetometer (yaw is not compared).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mcahrs.samples import Recording

STANDARD_GRAVITY = 9.80665

#: x-io Fusion settings (README "Algorithm settings": values "appropriate for most applications").
FUSION_GAIN = 0.5
FUSION_ACCEL_REJECTION_DEG = 10.0
FUSION_REJECTION_TIMEOUT_S = 5.0
FUSION_GYRO_RANGE_DPS = 2000.0


def down_to_roll_pitch(d_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Roll and pitch (rad, ZYX, DESIGN.md 2) from the down direction in body FRD axes (N, 3).

    ``d_b`` is the third row of ``C_nb`` (any positive scale).
    """
    d = np.asarray(d_b, np.float64)
    roll = np.arctan2(d[:, 1], d[:, 2])
    pitch = np.arctan2(-d[:, 0], np.hypot(d[:, 1], d[:, 2]))
    return roll, pitch


def _quat_rot_t_ez(q: np.ndarray) -> np.ndarray:
    """R(q)^T [0, 0, 1] for Hamilton [w, x, y, z] (N, 4): the earth z axis in body axes."""
    w, x, y, z = (q[:, i] for i in range(4))
    return np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1)


def _gap_repeats(t_us: np.ndarray) -> tuple[float, np.ndarray]:
    """Median interval (s) and how many times each sample is fed to a fixed-rate filter."""
    dt = np.diff(t_us.astype(np.int64)) * 1e-6
    ts = float(np.median(dt))
    k = np.ones(len(t_us), np.int64)
    k[1:] = np.maximum(1, np.rint(dt / ts).astype(np.int64))
    return ts, k


def run_vqf(rec: Recording) -> dict[str, Any]:
    """VQF (online, causal) on the recording's IMU (and magnetometer when present)."""
    from vqf import VQF  # optional dependency (extra "data")

    imu = rec.imu
    t = imu["t_us"].astype(np.int64)
    ts, k = _gap_repeats(t)
    gyr = np.ascontiguousarray(imu["gyro_rps"], np.float64)
    acc = np.ascontiguousarray(imu["accel_mps2"], np.float64)
    mag = rec.mag if rec.mag is not None and len(rec.mag) >= 2 else None
    n = len(t)
    q = np.zeros((n, 4))
    if mag is None:
        f = VQF(ts)
        idx = np.repeat(np.arange(n), k)
        out = f.updateBatch(np.ascontiguousarray(gyr[idx]), np.ascontiguousarray(acc[idx]))
        last = np.cumsum(k) - 1  # row of the last repeat of each sample
        q = out["quat6D"][last]
        note = f"VQF 6D (no magnetometer), Ts {ts * 1e3:.2f} ms, {int((k > 1).sum())} gaps filled by repeats"
    else:
        mag_t = mag["t_us"].astype(np.int64)
        mag_ts = float(np.median(np.diff(mag_t))) * 1e-6
        f = VQF(ts, ts, mag_ts)
        j = 0
        m_b = np.ascontiguousarray(mag["mag_b"], np.float64)
        for i in range(n):
            for _ in range(int(k[i])):
                f.updateGyr(gyr[i])
            f.updateAcc(acc[i])
            while j < len(mag_t) and mag_t[j] <= t[i]:
                if np.all(np.isfinite(m_b[j])):
                    f.updateMag(m_b[j])
                j += 1
            q[i] = f.getQuat9D()
        note = (
            f"VQF 9D (magnetometer at {1.0 / mag_ts:.1f} Hz; roll/pitch equal 6D by construction), "
            f"Ts {ts * 1e3:.2f} ms, {int((k > 1).sum())} gaps filled by repeats"
        )
    down = -_quat_rot_t_ez(q)  # VQF's earth frame is z-up: down is -z
    roll, pitch = down_to_roll_pitch(down)
    return {"t_us": t, "q": q, "roll_rad": roll, "pitch_rad": pitch, "note": note}


def run_fusion(rec: Recording) -> dict[str, Any]:
    """x-io Fusion AHRS (NED, acceleration rejection on, gyro offset algorithm) on the IMU."""
    import imufusion  # optional dependency (extra "data")

    if not hasattr(imufusion, "AhrsSettings"):  # 1.2.x had Settings/Offset and a dt argument
        raise ImportError(f"imufusion >= 1.3 is needed (AhrsSettings/Bias API); found {imufusion.__file__}")
    imu = rec.imu
    t = imu["t_us"].astype(np.int64)
    dt = np.empty(len(t))
    dt[1:] = np.diff(t) * 1e-6
    ts = float(np.median(dt[1:]))
    dt[0] = ts
    rate = 1.0 / ts
    s = imufusion.AhrsSettings()
    s.convention = imufusion.CONVENTION_NED
    s.gain = FUSION_GAIN
    s.gyroscope_range = FUSION_GYRO_RANGE_DPS
    s.acceleration_rejection = FUSION_ACCEL_REJECTION_DEG
    s.magnetic_rejection = 0.0
    s.rejection_timeout = FUSION_REJECTION_TIMEOUT_S
    s.sample_rate = rate
    ahrs = imufusion.Ahrs()
    ahrs.set_settings(s)
    bs = imufusion.BiasSettings()
    bs.sample_rate = rate
    bias = imufusion.Bias()
    bias.set_settings(bs)
    gyr_dps = np.degrees(np.asarray(imu["gyro_rps"], np.float64))
    acc_g = np.asarray(imu["accel_mps2"], np.float64) / STANDARD_GRAVITY
    n = len(t)
    q = np.zeros((n, 4))
    for i in range(n):
        g = bias.update(gyr_dps[i])
        ahrs.set_sample_period(float(dt[i]))
        ahrs.update_no_magnetometer(g, acc_g[i])
        q[i] = ahrs.get_quaternion()
    down = _quat_rot_t_ez(q)  # NED: earth z is down
    roll, pitch = down_to_roll_pitch(down)
    note = (
        f"Fusion NED, gain {FUSION_GAIN}, acceleration rejection {FUSION_ACCEL_REJECTION_DEG:g} deg, "
        f"timeout {FUSION_REJECTION_TIMEOUT_S:g} s, gyro offset algorithm, no magnetometer"
    )
    return {"t_us": t, "q": q, "roll_rad": roll, "pitch_rad": pitch, "note": note}

"""Recording loaders (python/mcahrs/io/loaders) on the shared real recordings and on synthetic files.

Expectations come from the data READMEs (``../shared/data/*/README.md``: counts, rates, ranges),
from physics (normal gravity, the geomagnetic field) or from computations done here independently
of the loaders (own rotation matrices, pymap3d geodesy). Tests on real data skip, naming the
missing path, when ``../shared/data`` (relative to the repository root) is absent.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pymap3d
import pytest

from mcahrs.io.loaders import LoaderError, load, load_comma2k19, load_rtklib_car, load_ulog
from mcahrs.io.loaders import ulog as ulog_mod
from mcahrs.samples import (
    GNSS_DTYPE,
    GNSS_HAS_COURSE,
    GNSS_HAS_VEL_D,
    GNSS_HAS_VEL_NE,
    IMU_DTYPE,
    MAG_DTYPE,
    REF_DTYPE,
    Recording,
)

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / ".." / "shared" / "data"
ULOG61 = DATA / "ulog" / "log_61_2024-2-6-16-27-02.ulg"
ULOG_ESC = DATA / "ulog" / "esc_status_log.ulg"
COMMA = DATA / "comma2k19" / "comma2k19_example1"
CAR = DATA / "car"

GPS_EPOCH_UNIX = 315964800  # 1980-01-06 in Unix seconds


def _need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"shared data not present: {path}")
    return path


# ---------------------------------------------------------------- independent helpers


def rot(q: np.ndarray) -> np.ndarray:
    """R(q) of Hamilton [w,x,y,z] quaternions, (N,4) -> (N,3,3)."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        -1,
    )


def roll_pitch_yaw_deg(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ZYX angles from q_nb, the formulas of data/ulog/README.md."""
    w, x, y, z = q.T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1, 1))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.degrees(roll), np.degrees(pitch), np.degrees(yaw)


def normal_gravity(lat_deg: float, h_m: float) -> float:
    """WGS84 Somigliana normal gravity with the free-air height term."""
    s2 = np.sin(np.radians(lat_deg)) ** 2
    return 9.7803253359 * (1 + 0.00193185265241 * s2) / np.sqrt(1 - 0.00669437999013 * s2) - 3.086e-6 * h_m


def ref_at(rec: Recording, t_us: np.ndarray) -> np.ndarray:
    """Reference q_nb linearly interpolated (then normalised) at ``t_us``; fine at 20-30 Hz, small steps."""
    assert rec.ref is not None
    q = np.stack([np.interp(t_us, rec.ref["t_us"], rec.ref["q_nb"][:, k]) for k in range(4)], axis=1)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def gyro_propagation_error_deg(rec: Recording, conjugate: bool = False, span_s: float = 1.0) -> np.ndarray:
    """Propagate each reference sample ``span_s`` ahead with the gyro; angle to the reference there.

    ``q <- q (x) dq(w dt)`` is right if q is q_nb (body FRD -> NED); ``conjugate`` propagates as if the
    stored q were the opposite (NED -> body) quaternion, ``q <- conj(dq) (x) q``.
    """
    assert rec.ref is not None
    tr, qr = rec.ref["t_us"], rec.ref["q_nb"]
    t, w = rec.imu["t_us"], rec.imu["gyro_rps"]
    step = max(1, int(round(span_s * 1e6 / np.median(np.diff(tr)))))
    starts = np.arange(0, tr.size - step, step)
    ends = starts + step
    q = qr[starts].copy()
    t_prev = tr[starts].astype(np.int64)
    k = np.searchsorted(t, t_prev, side="right")
    while True:
        active = (k < t.size) & (t[np.minimum(k, t.size - 1)] <= tr[ends])
        if not active.any():
            break
        kk = k[active]
        dt = (t[kk] - t_prev[active]) * 1e-6
        a = w[kk] * dt[:, None]
        ang = np.linalg.norm(a, axis=1)
        half = np.where(ang > 0, np.sin(ang / 2) / np.where(ang > 0, ang, 1), 0.5)
        dq = np.concatenate([np.cos(ang / 2)[:, None], a * half[:, None]], axis=1)
        q[active] = qmul(dq * np.array([1, -1, -1, -1]), q[active]) if conjugate else qmul(q[active], dq)
        t_prev[active] = t[kk]
        k[active] += 1
    qe = qmul(q * np.array([1, -1, -1, -1]), qr[ends])
    return np.degrees(2 * np.arccos(np.clip(np.abs(qe[:, 0]) / np.linalg.norm(qe, axis=1), 0, 1)))


def velocity_vs_positions(gnss: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(velocity from differenced positions, mean reported velocity of the two fixes), both (N-1, 3) NED."""
    lat, lon, h = gnss["lat_e7"] * 1e-7, gnss["lon_e7"] * 1e-7, gnss["alt_mm"] * 1e-3
    n, e, d = pymap3d.geodetic2ned(lat, lon, h, lat[0], lon[0], h[0])
    dt = np.diff(gnss["t_us"]) * 1e-6
    vdiff = np.stack([np.diff(n), np.diff(e), np.diff(d)], axis=1) / dt[:, None]
    vrep = 0.5 * (gnss["vel_ned_mps"][1:] + gnss["vel_ned_mps"][:-1])
    return vdiff, vrep


def check_common(rec: Recording) -> None:
    """Properties every loader must give, whatever the recording."""
    assert rec.imu.dtype == IMU_DTYPE and rec.gnss.dtype == GNSS_DTYPE and rec.mag.dtype == MAG_DTYPE
    for arr in (rec.imu, rec.gnss, rec.mag) + ((rec.ref,) if rec.ref is not None else ()):
        assert np.all(np.diff(arr["t_us"]) > 0), "time must strictly increase"
    assert np.isfinite(rec.imu["gyro_rps"]).all() and np.isfinite(rec.imu["accel_mps2"]).all()
    assert np.all(rec.gnss["t_rx_us"] >= rec.gnss["t_us"])
    # GNSS and IMU cover (nearly) the same span: overlap > 90 % of the shorter one.
    lo = max(rec.imu["t_us"][0], rec.gnss["t_us"][0])
    hi = min(rec.imu["t_us"][-1], rec.gnss["t_us"][-1])
    shorter = min(np.ptp(rec.imu["t_us"]), np.ptp(rec.gnss["t_us"]))
    assert hi - lo > 0.9 * shorter
    if rec.ref is not None:
        assert rec.ref.dtype == REF_DTYPE
        assert np.allclose(np.linalg.norm(rec.ref["q_nb"], axis=1), 1.0, atol=1e-9)
    for key in ("source", "imu", "gnss", "time_base"):
        assert key in rec.meta


# ---------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def ulog61() -> Recording:
    return load(_need(ULOG61))


@pytest.fixture(scope="module")
def ulog61_logged() -> Recording:
    """log_61's samples as logged, without the missing ones put back."""
    return load(_need(ULOG61), fill_dropped=False)


@pytest.fixture(scope="module")
def ulog_esc() -> Recording:
    return load(_need(ULOG_ESC))


@pytest.fixture(scope="module")
def comma() -> Recording:
    return load(_need(COMMA))


@pytest.fixture(scope="module")
def car() -> Recording:
    _need(CAR / "imu_1934.csv")
    return load(CAR)


# ---------------------------------------------------------------- ULog: log_61 (PX4 v1.14)


def test_ulog61_counts_rates_and_gnss_fields_match_readme(ulog61_logged: Recording) -> None:
    check_common(ulog61_logged)
    imu, gnss = ulog61_logged.imu, ulog61_logged.gnss
    dt_ms = np.diff(imu["t_us"]) * 1e-3
    assert np.median(dt_ms) == pytest.approx(5.0, abs=0.05)  # README: 200 Hz nominal
    assert (imu.size - 1) / (np.ptp(imu["t_us"]) * 1e-6) == pytest.approx(186, abs=1.5)  # README: 186 Hz mean
    assert dt_ms.max() <= 10.6  # README: max interval 10.5 ms
    assert np.count_nonzero(dt_ms > 10) == 654  # README: 654 intervals > 10 ms
    assert np.ptp(imu["t_us"]) * 1e-6 == pytest.approx(78.9, abs=0.5)  # README: 78.9 s log
    assert np.median(np.diff(gnss["t_us"])) * 1e-6 == pytest.approx(0.5, abs=0.11)  # README: 2 Hz (0.4/0.6 s)
    assert np.all(gnss["fix_type"] == 3) and np.all(gnss["num_sv"] == 18)  # README: 3D, 18 satellites
    assert 0.55 <= gnss["h_acc_m"].min() and gnss["h_acc_m"].max() <= 0.62  # README: eph 0.58-0.60
    assert 1.0 <= gnss["v_acc_m"].min() and gnss["v_acc_m"].max() <= 1.16  # README: epv 1.03-1.14
    assert 0.005 <= gnss["s_acc_mps"].min() and gnss["s_acc_mps"].max() <= 0.055  # README: 0.01-0.05
    assert np.all(gnss["flags"] & GNSS_HAS_VEL_NE) and np.all(gnss["flags"] & GNSS_HAS_VEL_D)
    lat, lon = gnss["lat_e7"] * 1e-7, gnss["lon_e7"] * 1e-7
    assert abs(lat.mean() - 22.885) < 0.01 and abs(lon.mean() - 113.847) < 0.01  # README location
    ref, mag = ulog61_logged.ref, ulog61_logged.mag
    assert np.median(np.diff(ref["t_us"])) * 1e-6 == pytest.approx(0.05, abs=0.002)  # README: 20 Hz
    assert mag.size > 100 and np.median(np.diff(mag["t_us"])) * 1e-6 < 0.6  # README: 2 Hz
    assert ulog61_logged.meta["px4_ekf2_gps_delay_us"] == 110_000  # README: EKF2_GPS_DELAY 110 ms
    # README: timestamp_sample of the GPS topic is 0 here, so the fix time is its publication time
    # minus the latency the autopilot was configured with (the loader's default).
    assert np.array_equal(gnss["t_us"], gnss["t_rx_us"] - 110_000)


def test_ulog61_dropped_samples_are_put_back_where_no_sample_covers(
    ulog61: Recording, ulog61_logged: Recording
) -> None:
    """Each logged sample is the mean over gyro_integral_dt ending at its time; time no sample
    covers is samples the log lacks. Counted here from the raw topic, independently."""
    from pyulog import ULog

    raw = ULog(str(ULOG61), ["sensor_combined"]).data_list[0].data
    t = np.asarray(raw["timestamp"], np.int64)
    idt = np.asarray(raw["gyro_integral_dt"], np.int64)
    uncovered = np.diff(t) - idt[1:]
    assert uncovered.min() > -2  # the means tile the time (to the microsecond) between the gaps
    dropped = int(np.sum(np.rint(uncovered[uncovered >= 2500] / 5000.0)))
    assert dropped == 1106 == ulog61.meta["imu_filled_samples"]  # 7.3 % of the time: 92.7 % covered
    logged, filled = ulog61_logged.imu, ulog61.imu
    assert filled.size == logged.size + dropped
    # every logged sample is there unchanged, and what was put back sits inside a gap
    keep = np.isin(filled["t_us"], logged["t_us"])
    assert np.array_equal(filled[keep], logged)
    new = filled[~keep]
    k = np.searchsorted(logged["t_us"], new["t_us"])
    assert np.all((k > 0) & (k < logged.size))
    assert np.all(new["t_us"] <= logged["t_us"][k] - idt[1:][k - 1] + 1)  # before the next sample's own span
    # each is the mean of the two samples before its gap and the two after it
    near = logged["gyro_rps"][np.clip(k[:, None] + np.arange(-2, 2), 0, logged.size - 1)]
    assert np.allclose(new["gyro_rps"], near.mean(axis=1), rtol=0, atol=1e-6)
    assert np.diff(filled["t_us"]).max() * 1e-3 < 5.5  # no interval left longer than a sample's
    # the gyro then carries EKF2's attitude closer to EKF2's own (the vibration, lag-1
    # autocorrelation -0.55, made the next sample a poor stand-in for the dropped one)
    for span in (1.0, 5.0):
        e_filled = np.median(gyro_propagation_error_deg(ulog61, span_s=span))
        e_logged = np.median(gyro_propagation_error_deg(ulog61_logged, span_s=span))
        assert e_filled < 0.7 * e_logged


def test_ulog_fill_leaves_a_throttled_or_complete_topic_alone() -> None:
    t = np.arange(0, 1_000_000, 5000, dtype=np.int64)
    gyro = np.zeros((t.size, 3))
    gyro[:, 0] = 0.1 + 0.3 * (-1.0) ** np.arange(t.size)  # a constant rate under alternating vibration
    acc = np.tile([0.0, 0.0, -9.8], (t.size, 1))
    dt = np.full(t.size, 5000.0)
    meta: dict = {}
    # complete: nothing to put back
    t2, g2, a2 = ulog_mod._fill_dropped(t, gyro, acc, dt, meta)
    assert meta["imu_filled_samples"] == 0 and np.array_equal(t2, t) and np.array_equal(g2, gyro)
    # throttled (4 ms means 100 ms apart, like esc_status_log): left as it is
    sl = slice(None, None, 20)
    t3, _, _ = ulog_mod._fill_dropped(t[sl], gyro[sl], acc[sl], np.full(t[sl].size, 4000.0), meta)
    assert meta["imu_filled_samples"] == 0 and np.array_equal(t3, t[sl])
    # 1 in 10 dropped: put back, and the integrated angle nearer the true one
    keep = np.arange(t.size) % 10 != 5
    t4, g4, _ = ulog_mod._fill_dropped(t[keep], gyro[keep], acc[keep], dt[keep], meta)
    assert meta["imu_filled_samples"] == int((~keep).sum()) and np.array_equal(t4, t)
    truth = float(np.sum(gyro[1:, 0]) * 0.005)
    angle = lambda tt, g: float(np.sum(g[1:, 0] * np.diff(tt) * 1e-6))  # noqa: E731
    # the local mean is off by the vibration's amplitude, the next sample by twice it
    assert abs(angle(t4, g4) - truth) < 0.55 * abs(angle(t[keep], gyro[keep]) - truth)


def test_ulog_esc_is_not_filled(ulog_esc: Recording) -> None:
    assert ulog_esc.meta["imu_filled_samples"] == 0  # logged at ~10 Hz: 4 ms means, not a full-rate topic


def test_ulog61_static_start_reads_minus_g_on_body_down(ulog61: Recording) -> None:
    imu = ulog61.imu
    first = imu["t_us"] < imu["t_us"][0] + 1_000_000  # README: on the ground for ~2.2 s after log start
    f = imu["accel_mps2"][first].mean(axis=0)
    g = normal_gravity(22.885, 40.0)
    assert np.linalg.norm(f) == pytest.approx(g, rel=0.02)  # calibrated PX4 accel: 2 % covers bias + tilt
    assert f[2] < -0.98 * g  # level-ish vehicle: nearly all of it on body down, negative (specific force)
    # Motors spin (vibration), so only the mean rate is small: < 0.02 rad/s is > 10x a PX4 gyro bias margin.
    assert np.linalg.norm(imu["gyro_rps"][first].mean(axis=0)) < 0.02


def test_ulog61_reference_is_body_to_ned_as_gyro_propagation_shows(ulog61: Recording) -> None:
    err = gyro_propagation_error_deg(ulog61)
    err_conj = gyro_propagation_error_deg(ulog61, conjugate=True)
    assert np.median(err) < 1.0  # README: 0.4 deg median with the right convention
    assert np.median(err_conj) > 3 * np.median(err)
    roll, pitch, _ = roll_pitch_yaw_deg(ulog61.ref["q_nb"])
    assert np.abs(roll).max() == pytest.approx(9.1, abs=0.2)  # README: max |roll| 9.1 deg
    assert np.abs(pitch).max() == pytest.approx(14.8, abs=0.2)  # README: max |pitch| 14.8 deg
    # README: accelerometer rotated by q gives a mean NED specific force of about [0, 0, -9.8].
    f_n = np.einsum("nij,nj->ni", rot(ref_at(ulog61, ulog61.imu["t_us"])), ulog61.imu["accel_mps2"])
    assert f_n.mean(axis=0) == pytest.approx([0, 0, -9.78], abs=0.1)


def test_ulog61_magnetometer_points_north_and_down(ulog61: Recording) -> None:
    m_n = np.einsum("nij,nj->ni", rot(ref_at(ulog61, ulog61.mag["t_us"])), ulog61.mag["mag_b"])
    norm = np.linalg.norm(ulog61.mag["mag_b"], axis=1)
    incl = np.degrees(np.arctan2(m_n[:, 2], np.hypot(m_n[:, 0], m_n[:, 1])))
    decl = np.degrees(np.arctan2(m_n[:, 1], m_n[:, 0]))
    # Shenzhen, 2024 (IGRF): F ~0.45 G, inclination ~+31 deg, declination ~-3 deg. Motor currents and
    # calibration leave several degrees, so the bands only catch unit, axis or sign mistakes.
    assert 0.3 < np.median(norm) < 0.6
    assert 20 < np.median(incl) < 45
    assert abs(np.median(decl)) < 15


def test_ulog61_gnss_velocity_matches_differenced_positions(ulog61: Recording) -> None:
    vdiff, vrep = velocity_vs_positions(ulog61.gnss)
    rms = np.sqrt(np.mean((vdiff - vrep) ** 2, axis=0))
    # 0.4-0.6 s differences of ~1 cm-precision u-blox positions at <= 3.5 m/s^2: well under 0.3 m/s.
    assert np.all(rms[:2] < 0.15) and rms[2] < 0.3
    # North carries the motion (README: legs along N-S); a swapped or sign-flipped axis fails here.
    slope = np.dot(vdiff[:, 0], vrep[:, 0]) / np.dot(vrep[:, 0], vrep[:, 0])
    assert slope == pytest.approx(1.0, abs=0.05)


# ---------------------------------------------------------------- ULog: esc_status_log (PX4 v1.9, old layout)


def test_ulog_esc_old_layout_counts_rates_and_fix(ulog_esc: Recording) -> None:
    check_common(ulog_esc)
    imu, gnss = ulog_esc.imu, ulog_esc.gnss
    assert np.median(np.diff(imu["t_us"])) * 1e-3 == pytest.approx(104, abs=1)  # README: median 104 ms
    assert np.diff(imu["t_us"]).max() * 1e-3 == pytest.approx(416, abs=1)  # README: max gap 416 ms
    assert np.median(np.diff(gnss["t_us"])) * 1e-6 == pytest.approx(0.2, abs=0.01)  # README: 5 Hz
    assert np.all(gnss["fix_type"] == 4)  # README: DGNSS the whole time
    assert gnss["num_sv"].min() >= 14 and gnss["num_sv"].max() <= 16  # README: 14-16 satellites
    assert 0.42 <= gnss["h_acc_m"].min() and gnss["h_acc_m"].max() <= 0.5  # README: eph 0.43-0.49
    assert np.median(np.diff(ulog_esc.ref["t_us"])) * 1e-3 == pytest.approx(32, abs=1)  # README: 31 Hz
    # README: no timestamp_sample in v1.9: publication time minus the logged EKF2_GPS_DELAY
    delay = ulog_esc.meta["px4_ekf2_gps_delay_us"] or 0
    assert f"timestamp - {delay} us" in ulog_esc.meta["gnss_time_source"]
    roll, pitch, _ = roll_pitch_yaw_deg(ulog_esc.ref["q_nb"])
    assert np.abs(roll).max() == pytest.approx(25.2, abs=0.2)  # README: max |roll| 25.2 deg
    assert np.abs(pitch).max() == pytest.approx(27.6, abs=0.2)  # README: max |pitch| 27.6 deg


def test_ulog_esc_frames_agree_with_specific_force_and_magnetic_field(ulog_esc: Recording) -> None:
    f_n = np.einsum("nij,nj->ni", rot(ref_at(ulog_esc, ulog_esc.imu["t_us"])), ulog_esc.imu["accel_mps2"])
    # README: aliased vibration makes the in-air mean NED-down specific force -10.8, not -9.8.
    assert -11.5 < f_n[:, 2].mean() < -9.8
    m_n = np.einsum("nij,nj->ni", rot(ref_at(ulog_esc, ulog_esc.mag["t_us"])), ulog_esc.mag["mag_b"])
    incl = np.degrees(np.arctan2(m_n[:, 2], np.hypot(m_n[:, 0], m_n[:, 1])))
    decl = np.degrees(np.arctan2(m_n[:, 1], m_n[:, 0]))
    # Zurich, 2019 (IGRF): inclination ~63 deg, declination ~+2.5 deg, F ~0.48 G.
    assert np.median(incl) == pytest.approx(63, abs=4)
    assert np.median(decl) == pytest.approx(2.5, abs=6)
    assert np.median(np.linalg.norm(ulog_esc.mag["mag_b"], axis=1)) == pytest.approx(0.48, abs=0.06)
    vdiff, vrep = velocity_vs_positions(ulog_esc.gnss)
    rms = np.sqrt(np.mean((vdiff - vrep) ** 2, axis=0))
    assert np.all(rms < 0.3)  # 0.2 s differences of DGNSS positions at up to 5.8 m/s^2
    for ax in range(2):
        slope = np.dot(vdiff[:, ax], vrep[:, ax]) / np.dot(vrep[:, ax], vrep[:, ax])
        assert slope == pytest.approx(1.0, abs=0.05)


def test_ulog_missing_topics_raise_naming_the_topic(tmp_path: Path) -> None:
    from pyulog import ULog

    src = _need(ULOG_ESC)
    no_imu = tmp_path / "no_imu.ulg"
    ULog(str(src), ["vehicle_gps_position", "vehicle_attitude"]).write_ulog(str(no_imu))
    with pytest.raises(LoaderError, match="sensor_combined"):
        load_ulog(no_imu)
    no_gps = tmp_path / "no_gps.ulg"
    ULog(str(src), ["sensor_combined", "vehicle_attitude"]).write_ulog(str(no_gps))
    with pytest.raises(LoaderError, match="vehicle_gps_position"):
        load_ulog(no_gps)
    # Optional topics may be absent: no attitude -> ref None, no magnetometer -> empty.
    only = tmp_path / "imu_gps.ulg"
    ULog(str(src), ["sensor_combined", "vehicle_gps_position"]).write_ulog(str(only))
    rec = load_ulog(only)
    assert rec.ref is None and rec.mag.size == 0 and rec.imu.size > 0
    junk = tmp_path / "junk.ulg"
    junk.write_bytes(b"not a ulog file at all" * 10)
    with pytest.raises(LoaderError, match="junk.ulg"):
        load_ulog(junk)


def test_ulog_gnss_new_px4_layout_float_degrees_and_timestamp_sample() -> None:
    """PX4 >= 1.15 sensor_gps: latitude_deg / altitude_*_m float64 and a filled timestamp_sample."""
    n = 3
    data = {
        "timestamp": np.array([1_000_000, 1_200_000, 1_400_000], np.uint64),
        "timestamp_sample": np.array([900_000, 1_100_000, 0], np.uint64),
        "latitude_deg": np.array([47.123456789, 47.1234568, 47.1234569]),
        "longitude_deg": np.array([-122.987654321, -122.9876543, -122.9876542]),
        "altitude_msl_m": np.full(n, 400.0),
        "altitude_ellipsoid_m": np.full(n, 447.25),
        "vel_n_m_s": np.ones(n, np.float32),
        "vel_e_m_s": np.zeros(n, np.float32),
        "vel_d_m_s": np.full(n, -0.5, np.float32),
        "vel_ned_valid": np.array([1, 1, 0], np.uint8),
        "vel_m_s": np.ones(n, np.float32),
        "cog_rad": np.array([-0.1, 0.0, 0.1], np.float32),
        "eph": np.full(n, 0.5, np.float32),
        "epv": np.full(n, 0.8, np.float32),
        "s_variance_m_s": np.full(n, 0.2, np.float32),
        "fix_type": np.array([3, 6, 1], np.uint8),
        "satellites_used": np.array([20, 21, 0], np.uint8),
    }
    meta: dict = {}
    g = ulog_mod._load_gnss(data, "sensor_gps", "synthetic", 110_000, meta)
    assert g.size == 2  # fix_type 1 (no fix) dropped
    assert list(g["lat_e7"]) == [471234568, 471234568] and g["lon_e7"][0] == -1229876543
    assert list(g["alt_mm"]) == [447250, 447250]  # ellipsoidal preferred
    assert list(g["t_us"]) == [900_000, 1_100_000] and list(g["t_rx_us"]) == [1_000_000, 1_200_000]
    assert g["course_rad"][0] == pytest.approx(2 * np.pi - 0.1, abs=1e-6)  # wrapped to [0, 2 pi)
    assert np.all(g["flags"] & GNSS_HAS_COURSE) and g["vel_ned_mps"][1, 2] == pytest.approx(-0.5)
    assert list(g["fix_type"]) == [3, 6] and list(g["num_sv"]) == [20, 21]
    with pytest.raises(LoaderError, match="latitude"):
        ulog_mod._load_gnss(
            {**data, "latitude_deg": np.array([91.0, 0, 0])}, "sensor_gps", "synthetic", 0, {}
        )


# ---------------------------------------------------------------- comma2k19


def test_comma_counts_rates_and_time_bases_match_readme(comma: Recording) -> None:
    check_common(comma)
    imu, gnss = comma.imu, comma.gnss
    assert imu.size == 6256  # README: 6256 rows
    assert np.median(np.diff(imu["t_us"])) * 1e-3 == pytest.approx(9.5825, abs=0.005)  # README: dt 9.5825 ms
    assert np.diff(imu["t_us"]).max() * 1e-3 < 9.65  # README: max 9.64 ms, no gaps
    assert imu["t_us"][0] == pytest.approx(46408.5800e6, abs=100)  # README: first sample at boot 46408.5800 s
    assert gnss.size == 579  # README: 579 u-blox fixes
    steps = np.round(np.diff(gnss["t_us"]) * 1e-5).astype(int)  # in 0.1 s
    assert np.count_nonzero(steps == 1) == 559 and np.count_nonzero(steps == 2) == 19  # README
    assert comma.ref is not None and comma.ref.size == 1200  # README: 1200 poses at 20 Hz
    assert np.median(np.diff(comma.ref["t_us"])) * 1e-6 == pytest.approx(0.05, abs=1e-4)
    assert comma.mag.size == 592 and np.median(np.diff(comma.mag["t_us"])) * 1e-6 == pytest.approx(
        0.1, abs=1e-3
    )
    # README: arrival is 0.18-0.24 s after the fix epoch, and u-blox epochs sit on the 0.1 s GPS-time
    # grid, where GPS TOW = boot + 357697.849502 s.
    latency = (gnss["t_rx_us"] - gnss["t_us"]) * 1e-6
    assert 0.175 < latency.min() and latency.max() < 0.245
    tow = gnss["t_us"] * 1e-6 + 357697.849502
    assert np.abs(tow * 10 - np.round(tow * 10)).max() < 0.01  # within 1 ms of the grid
    assert tow[0] == pytest.approx(404106.4, abs=0.11)  # README: TOW 404106.4-404166.4
    assert np.all(np.isnan(gnss["h_acc_m"])) and np.all(np.isnan(gnss["vel_ned_mps"][:, 2]))
    assert not np.any(gnss["flags"] & GNSS_HAS_VEL_D)


def test_comma_units_and_frames_of_the_imu(comma: Recording) -> None:
    f = comma.imu["accel_mps2"]
    # README: mean over the drive (-0.57, -0.13, -9.66) m/s^2, |f| mean 9.73 (FRD, specific force).
    assert f.mean(axis=0) == pytest.approx([-0.57, -0.13, -9.66], abs=0.01)
    assert np.linalg.norm(f, axis=1).mean() == pytest.approx(9.73, abs=0.01)
    rate = np.degrees(comma.imu["gyro_rps"])
    assert rate[:, 1].min() == pytest.approx(-18.9, abs=0.1)  # README: rate y -18.9...+10.1 deg/s
    assert rate[:, 1].max() == pytest.approx(10.1, abs=0.1)


def test_comma_reference_roll_pitch_yaw_match_readme_and_gyro(comma: Recording) -> None:
    roll, pitch, yaw = roll_pitch_yaw_deg(comma.ref["q_nb"])
    # README section 6: roll +0.36...+1.80, pitch -6.20...-0.27, yaw 0.95...2.19 deg.
    assert roll.min() == pytest.approx(0.36, abs=0.02) and roll.max() == pytest.approx(1.80, abs=0.02)
    assert pitch.min() == pytest.approx(-6.20, abs=0.02) and pitch.max() == pytest.approx(-0.27, abs=0.02)
    assert yaw.min() == pytest.approx(0.95, abs=0.02) and yaw.max() == pytest.approx(2.19, abs=0.02)
    err = gyro_propagation_error_deg(comma)
    # README: gyro and reference rates agree to < 0.0006 rad/s mean, 0.018 rad/s std over 0.5 s.
    assert np.median(err) < 0.3
    assert np.median(gyro_propagation_error_deg(comma, conjugate=True)) > 3 * np.median(err)


def test_comma_gnss_velocity_course_and_reference_agree(comma: Recording) -> None:
    gnss = comma.gnss
    vdiff, vrep = velocity_vs_positions(gnss)
    rms = np.sqrt(np.mean((vdiff[:, :2] - vrep[:, :2]) ** 2, axis=0))
    assert np.all(rms < 0.3)  # 0.1-0.2 s differences at up to 2.6 m/s^2 plus u-blox noise
    slope = np.dot(vdiff[:, 0], vrep[:, 0]) / np.dot(vrep[:, 0], vrep[:, 0])
    assert slope == pytest.approx(1.0, abs=0.05)  # driving north (README: heading 1-2 deg)
    # Reference velocity (README: NED velocity = C_ne . frame_velocities), computed here with pymap3d.
    pose = COMMA / "global_pose"
    t_ref = np.load(pose / "frame_times") * 1e6
    pos = np.load(pose / "frame_positions")
    vel = np.load(pose / "frame_velocities")
    lat, lon, _ = pymap3d.ecef2geodetic(pos[:, 0], pos[:, 1], pos[:, 2])
    vn, ve, vd = pymap3d.ecef2nedv(vel[:, 0], vel[:, 1], vel[:, 2], lat, lon)
    speed_ref = np.interp(gnss["t_us"], t_ref, np.hypot(vn, ve))
    inside = (gnss["t_us"] > t_ref[0]) & (gnss["t_us"] < t_ref[-1])
    dv = gnss["speed_mps"][inside] - speed_ref[inside]
    assert abs(dv.mean()) < 0.03 and dv.std() < 0.12  # README: +0.005 +- 0.080 m/s at the fix epoch
    _, _, yaw = roll_pitch_yaw_deg(ref_at(comma, gnss["t_us"][inside]))
    dcourse = np.degrees(np.angle(np.exp(1j * (gnss["course_rad"][inside] - np.radians(yaw)))))
    assert np.median(np.abs(dcourse)) < 1.5  # README: heading equals the GNSS course within about 1 deg


def test_comma_magnetometer_unit_is_microtesla_and_flagged(comma: Recording) -> None:
    assert np.linalg.norm(comma.mag["mag_b"], axis=1).mean() == pytest.approx(42.5, abs=0.5)  # README
    assert "mag_warning" in comma.meta


def test_comma_phone_receiver_option() -> None:
    rec = load_comma2k19(_need(COMMA), receiver="qcom")
    assert rec.gnss.size == 30  # README: 30 rows, one fix every 2.0 s
    assert np.median(np.diff(rec.gnss["t_us"])) * 1e-6 == pytest.approx(2.0, abs=0.01)


def _save_npy(path: Path, arr: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:  # no .npy extension, as in comma2k19
        np.save(fh, arr)


def test_comma_synthetic_pose_converts_to_ned_and_errors_name_files(tmp_path: Path) -> None:
    seg = tmp_path / "seg"
    rng = np.random.default_rng(7)
    n = 50
    t = 1000.0 + 0.01 * np.arange(n)
    _save_npy(seg / "processed_log/IMU/accelerometer/t", t)
    _save_npy(seg / "processed_log/IMU/accelerometer/value", np.tile([0.0, 0.0, -9.8], (n, 1)))
    _save_npy(seg / "processed_log/IMU/gyro/t", t)
    _save_npy(seg / "processed_log/IMU/gyro/value", np.zeros((n, 3)))
    lat0, lon0, h0 = -33.9, 151.2, 50.0
    week, gps_minus_boot = 2100, 300000.0
    # A fix at GPS TOW 301000.3 -> boot 1000.3 s; its UTC ms is GPS - 18 s leap (valid in 2020).
    tow = 301000.3
    utc_ms = (GPS_EPOCH_UNIX + week * 604800 + tow - 18) * 1e3
    _save_npy(seg / "processed_log/GNSS/live_gnss_ublox/t", np.array([1000.5]))
    _save_npy(
        seg / "processed_log/GNSS/live_gnss_ublox/value", np.array([[lat0, lon0, 3.0, utc_ms, h0, 90.0]])
    )
    ft = t[::5]
    q_eb = rng.normal(size=(ft.size, 4))
    q_eb /= np.linalg.norm(q_eb, axis=1, keepdims=True)
    x, y, z = pymap3d.geodetic2ecef(lat0, lon0, h0)
    _save_npy(seg / "global_pose/frame_times", ft)
    _save_npy(seg / "global_pose/frame_gps_times", np.stack([np.full(ft.size, week), ft + gps_minus_boot], 1))
    _save_npy(seg / "global_pose/frame_positions", np.tile([x, y, z], (ft.size, 1)))
    _save_npy(seg / "global_pose/frame_orientations", q_eb)
    rec = load_comma2k19(tmp_path)  # finds the one segment below
    # Expected: columns of C_en are the NED unit vectors in ECEF, taken from pymap3d.
    c_en = np.stack([np.array(pymap3d.ned2ecef(*u, lat0, lon0, h0)) - [x, y, z] for u in np.eye(3)], axis=1)
    c_nb_expected = np.einsum("ij,njk->nik", c_en.T, rot(q_eb))
    assert np.allclose(rot(rec.ref["q_nb"]), c_nb_expected, atol=1e-6)
    assert rec.gnss["t_us"][0] == 1_000_300_000 and rec.gnss["t_rx_us"][0] == 1_000_500_000
    assert rec.gnss["vel_ned_mps"][0, :2] == pytest.approx([0.0, 3.0], abs=1e-9)  # course 90 deg = east
    assert rec.mag.size == 0  # optional
    (seg / "processed_log/IMU/gyro/value").unlink()
    with pytest.raises(LoaderError, match="gyro/value"):
        load_comma2k19(seg)


# ---------------------------------------------------------------- car (RTKLIB)


def test_car_counts_rates_durations_match_readme(car: Recording) -> None:
    check_common(car)
    imu, gnss = car.imu, car.gnss
    assert imu.size == 54860  # README: 54,860 rows
    dt_ms = np.diff(imu["t_us"]) * 1e-3
    assert np.median(dt_ms) == pytest.approx(10, abs=0.05)  # README: 100 Hz, dt median 10 ms
    assert dt_ms.min() > 7.5 and dt_ms.max() < 11.5  # README: dt 8-11 ms, no gaps (ticks are whole ms)
    assert np.ptp(imu["t_us"]) * 1e-6 == pytest.approx(548.6, abs=0.1)  # README: 548.6 s
    assert gnss.size == 2197 and np.all(np.diff(gnss["t_us"]) == 250_000)  # README: 2197 epochs at 4 Hz
    assert np.count_nonzero(gnss["fix_type"] == 6) == 2189  # README: Q = 1 (fix) in 2189 epochs
    assert np.count_nonzero(gnss["fix_type"] == 5) == 8  # README: Q = 2 (float) in 8
    # README: 19:34:18.5-19:43:27.5 GPST on 2025-07-08, a Tuesday: TOW = 2 days + time of day.
    tow0 = 2 * 86400 + 19 * 3600 + 34 * 60 + 18.5
    assert gnss["t_us"][0] * 1e-6 == pytest.approx(tow0, abs=0.01)
    assert np.ptp(gnss["t_us"]) * 1e-6 == pytest.approx(549.0, abs=0.01)
    assert car.ref is None
    # Not checked: the README's speed figures (max 12.8 m/s, mean 3.2) are hypot(vn, vu), not hypot(vn, ve);
    # horizontal speed peaks at 16.3 m/s (test_car_gnss_velocity_matches_differenced_positions covers it).


def test_car_static_start_is_level_with_minus_g_on_body_down(car: Recording) -> None:
    imu = car.imu
    first = imu["t_us"] < imu["t_us"][0] + 5_000_000  # README: static at the start (GNSS speed ~0)
    f = imu["accel_mps2"][first].mean(axis=0)
    g = normal_gravity(40.097, 1600.0)
    assert np.linalg.norm(f) == pytest.approx(g, rel=0.03)  # README: z reads 1.005 g at rest -> MEMS scale
    roll = np.degrees(np.arctan2(-f[1], -f[2]))
    pitch = np.degrees(np.arctan2(f[0], np.hypot(f[1], f[2])))
    assert f[2] < 0 and abs(roll) < 3 and abs(pitch) < 3  # mounting removes the sensor's ~6.8 deg pitch
    assert np.linalg.norm(imu["gyro_rps"][first].mean(axis=0)) < 0.01  # at rest: bias only
    static_gnss = car.gnss["t_us"] < car.gnss["t_us"][0] + 20_000_000
    assert np.abs(car.gnss["vel_ned_mps"][static_gnss]).max() < 0.1


def test_car_yaw_rate_sign_scale_and_time_alignment_match_gnss_course(car: Recording) -> None:
    """Body z gyro (down) against the GNSS course rate: same sign, unit gain, no time offset."""
    gnss = car.gnss
    t = gnss["t_us"] * 1e-6
    vn, ve = gnss["vel_ned_mps"][:, 0], gnss["vel_ned_mps"][:, 1]
    an, ae = np.gradient(vn, t), np.gradient(ve, t)
    speed = np.hypot(vn, ve)
    moving = speed > 3.0
    course_rate = (vn * ae - ve * an) / np.maximum(speed, 1e-3) ** 2  # d/dt atan2(ve, vn)
    ti = car.imu["t_us"] * 1e-6
    yaw_rate = np.convolve(
        car.imu["gyro_rps"][:, 2], np.ones(50) / 50, mode="same"
    )  # ~ 0.5 s like the gradient
    lags = np.arange(-0.5, 0.5001, 0.025)
    corr = [np.corrcoef(np.interp(t[moving] + lag, ti, yaw_rate), course_rate[moving])[0, 1] for lag in lags]
    best = lags[int(np.argmax(corr))]
    assert max(corr) > 0.95
    assert abs(best) <= 0.1  # tag-file clock mapping and the -0.125 s offset put IMU on GPST
    y = np.interp(t[moving], ti, yaw_rate)
    gain = np.dot(y, course_rate[moving]) / np.dot(y, y)
    assert gain == pytest.approx(1.0, abs=0.05)  # deg/s -> rad/s conversion and body z = down
    # Lateral specific force in turns is v * yaw rate (right turn: +y), from the IMU alone.
    v = np.interp(ti, t, speed)
    fy = np.convolve(car.imu["accel_mps2"][:, 1], np.ones(50) / 50, mode="same")
    sel = v > 3.0
    assert np.corrcoef(v[sel] * yaw_rate[sel], fy[sel])[0, 1] > 0.9


def test_car_gnss_velocity_matches_differenced_positions(car: Recording) -> None:
    vdiff, vrep = velocity_vs_positions(car.gnss)
    rms = np.sqrt(np.mean((vdiff - vrep) ** 2, axis=0))
    assert np.all(rms < 0.2)  # RTK cm positions over 0.25 s, up to 2.7 m/s^2 (README)
    for ax in range(3):  # includes vd = -vu: a sign slip would give slope -1
        slope = np.dot(vdiff[:, ax], vrep[:, ax]) / np.dot(vrep[:, ax], vrep[:, ax])
        assert slope == pytest.approx(1.0, abs=0.1)
    assert np.allclose(
        car.gnss["h_acc_m"][:5], np.hypot(0.0098995, 0.0098995), atol=1e-7
    )  # first rows' sdn/sde


# ---------------------------------------------------------------- car: synthetic files


def _passive(axis: int, deg: float) -> np.ndarray:
    """Elementary frame rotation (passive) about x, y or z."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m = np.eye(3)
    m[i, i] = m[j, j] = c
    m[i, j], m[j, i] = s, -s
    return m


def _write_car(folder: Path, crlf_file: bool, tick0: int = 5000, n: int = 200) -> dict:
    """imu_9.csv (+ .tag written as str2str would for a CRLF stream) and gnss_9.pos."""
    folder.mkdir()
    rows = [f"0.100,-0.050,1.000,1.000,-2.000,10.000,{tick0 + 10 * i}" for i in range(n)]
    eol = b"\r\n" if crlf_file else b"\n"
    (folder / "imu_9.csv").write_bytes(b"".join(r.encode() + eol for r in rows))
    week, tow_open = 2300, 200000.0
    hdr = b"TIMETAG RTKLIB demo5".ljust(60, b"\0")
    tag = hdr + struct.pack("<IId", 123456, GPS_EPOCH_UNIX + week * 604800 + int(tow_open), 0.5)
    pos = 0
    latency_ms = 40
    for i, r in enumerate(rows):  # the stream had CRLF, so positions count 2 bytes per line end
        pos += len(r) + 2
        tag += struct.pack("<II", 300 + 10 * i + latency_ms, pos)
    (folder / "imu_9.csv.tag").write_bytes(tag)
    cols = (
        "latitude(deg) longitude(deg) height(m) Q ns sdn(m) sde(m) sdu(m) sdne(m) sdeu(m) sdun(m) age(s) "
        "ratio vn(m/s) ve(m/s) vu(m/s) sdvn sdve sdvu sdvne sdveu sdvun"
    )
    tail = "0.0300 0.0400 0.0500 0 0 0 0.00 0.0 1.0000 2.0000 0.5000 0.0600 0.0800 0.1000 0 0 0"
    (folder / "gnss_9.pos").write_text(
        f"% program   : test\n%  GPST                  {cols}\n"
        f"2024/02/06 07:33:20.000   45.0000000   7.0000000   100.0000   1  12 {tail}\n"
        f"2024/02/06 07:33:20.250   45.0000100   7.0000000   100.0000   2  11 {tail}\n"
    )
    return {"week": week, "tow_open": tow_open + 0.5, "tick0": tick0, "n": n, "latency_ms": latency_ms}


@pytest.mark.parametrize("crlf_file", [True, False], ids=["crlf-file", "lf-checkout-of-crlf-stream"])
def test_car_synthetic_tag_timing_mounting_and_pos(tmp_path: Path, crlf_file: bool) -> None:
    info = _write_car(tmp_path / "car", crlf_file)
    rec = load_rtklib_car(tmp_path / "car" / "imu_9.csv", imu_time_offset_s=-0.125)
    # Row i arrives 300 + 10 i + 40 ms after file open; the fitted line is exact, then -0.125 s.
    i = np.arange(info["n"])
    expected = np.round((info["tow_open"] + (300 + 10 * i + info["latency_ms"]) * 1e-3 - 0.125) * 1e6)
    assert np.array_equal(rec.imu["t_us"], expected.astype(np.int64))
    assert rec.meta["tag_crlf_corrected"] is (not crlf_file)
    c_sb = _passive(0, 180) @ _passive(1, -6.79) @ _passive(2, 185.35)  # R1(roll) R2(pitch) R3(yaw)
    assert rec.imu["accel_mps2"][0] == pytest.approx(c_sb @ (np.array([0.1, -0.05, 1.0]) * 9.80665), abs=1e-9)
    assert rec.imu["gyro_rps"][0] == pytest.approx(c_sb @ np.radians([1.0, -2.0, 10.0]), abs=1e-12)
    # 2024-02-06 was a Tuesday: TOW = 2 days + 07:33:20 = 200000 s, in the same week as the tag.
    g = rec.gnss
    assert list(g["t_us"]) == [200_000_000_000, 200_000_250_000] and np.array_equal(g["t_rx_us"], g["t_us"])
    assert g["vel_ned_mps"][0] == pytest.approx([1.0, 2.0, -0.5])  # vd = -vu
    assert g["h_acc_m"][0] == pytest.approx(0.05) and g["v_acc_m"][0] == pytest.approx(0.05)
    assert g["s_acc_mps"][0] == pytest.approx(0.1)
    assert list(g["fix_type"]) == [6, 5] and list(g["num_sv"]) == [12, 11]
    assert g["lat_e7"][1] == 450000100 and g["alt_mm"][0] == 100_000
    assert np.all(np.isnan(g["course_rad"]))


def test_car_malformed_inputs_raise_naming_file_and_field(tmp_path: Path) -> None:
    _write_car(tmp_path / "a", crlf_file=True)
    csv = tmp_path / "a" / "imu_9.csv"
    lines = csv.read_bytes().split(b"\r\n")
    lines[50] = b"0.1,0.2,oops,1,2,3,5500"
    csv.write_bytes(b"\r\n".join(lines))
    with pytest.raises(LoaderError, match=r"imu_9\.csv.*line"):
        load_rtklib_car(csv)
    _write_car(tmp_path / "b", crlf_file=True)
    tag = tmp_path / "b" / "imu_9.csv.tag"
    tag.write_bytes(b"NOT A TAG" + tag.read_bytes()[9:])
    with pytest.raises(LoaderError, match=r"imu_9\.csv\.tag.*TIMETAG"):
        load_rtklib_car(tmp_path / "b")
    _write_car(tmp_path / "c", crlf_file=True)
    pos = tmp_path / "c" / "gnss_9.pos"
    pos.write_text(pos.read_text().replace("   1  12", "   1"))
    with pytest.raises(LoaderError, match=r"gnss_9\.pos.*line 3"):
        load_rtklib_car(tmp_path / "c")


# ---------------------------------------------------------------- dispatch


def test_load_dispatches_and_rejects_unknown_paths(tmp_path: Path) -> None:
    with pytest.raises(LoaderError, match="no such file"):
        load(tmp_path / "missing.ulg")
    (tmp_path / "empty").mkdir()
    with pytest.raises(LoaderError, match="not a recognised recording"):
        load(tmp_path / "empty")
    _write_car(tmp_path / "car", crlf_file=False)
    for p in ("car", "car/imu_9.csv", "car/imu_9.csv.tag", "car/gnss_9.pos"):
        assert load(tmp_path / p).meta["source"] == "rtklib_car"

"""Sensor models (IMU, GNSS, magnetometer), WGS84 normal gravity and NED -> geodetic conversion.

Every random draw comes from a ``numpy.random.Generator`` the caller seeds; each sensor has
its own generator, so changing one sensor's settings leaves the others' noise unchanged.

Noise conventions (the ones Allan-variance analysis and the IEEE 952/1431 models use):

* white noise density ``N`` (gyro: angle random walk, rad/s/sqrt(Hz); accel: velocity random
  walk, m/s^2/sqrt(Hz)) gives a per-sample standard deviation ``N * sqrt(f_s)``;
  Allan variance ``N^2 / tau``;
* bias random walk ``K`` (rate random walk, rad/s/sqrt(s); m/s^2/sqrt(s)) gives bias
  increments of standard deviation ``K * sqrt(dt)``; Allan variance ``K^2 tau / 3``;
* first-order Gauss-Markov with standard deviation ``sigma`` and correlation time ``tau``:
  ``x[k+1] = phi x[k] + w[k]``, ``phi = exp(-dt/tau)``, ``var(w) = sigma^2 (1 - phi^2)``,
  started from its stationary distribution, so ``E[x[k] x[k+L]] = sigma^2 phi^L``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from mcahrs.samples import (
    GNSS_DTYPE,
    GNSS_HAS_ALT,
    GNSS_HAS_COURSE,
    GNSS_HAS_VEL_D,
    GNSS_HAS_VEL_NE,
    IMU_DTYPE,
    MAG_DTYPE,
)
from mcahrs.sim.truth import Truth, quat_conj, quat_rotate

__all__ = [
    "G0_MPS2",
    "WGS84_A_M",
    "WGS84_F",
    "SimParams",
    "gauss_markov",
    "gnss_model",
    "imu_model",
    "mag_model",
    "ned_to_geodetic",
    "ned_to_geodetic_wgs84",
    "normal_gravity",
    "snap_epochs",
]

G0_MPS2 = 9.80665  # standard gravity: the unit of an accelerometer's "16 g" range and LSB
WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_GM = 3.986004418e14  # m^3/s^2
WGS84_OMEGA_RPS = 7.292115e-5  # earth rotation rate
WGS84_GAMMA_E = 9.7803253359  # normal gravity at the equator, m/s^2
WGS84_GAMMA_P = 9.8321849378  # normal gravity at the poles, m/s^2

_DEG = math.pi / 180.0


@dataclass(frozen=True)
class SimParams:
    """Every sensor and timing parameter of a simulation run (recorded in ``SimResult.params``).

    Defaults describe a typical small-UAV MEMS IMU (ICM-42688/MPU-6000 class, +-2000 deg/s and
    +-16 g, 16-bit) and a single-frequency u-blox class GNSS receiver.
    ``g_mps2 = None`` means "WGS84 normal gravity at home" (:func:`normal_gravity`); the run's
    ``params`` always hold the value actually used.
    """

    # timing
    imu_rate_hz: float = 400.0
    # reported IMU times off the sampling instants by a uniform integer in [-j, j] us (a driver's
    # timestamps: intervals that sum to a little under a span as often as over it); < half a sample
    imu_time_jitter_us: int = 0
    gps_rate_hz: float = 5.0
    mag_rate_hz: float = 50.0  # 0 disables the magnetometer
    # home (tangent point of the NED frame); height is ellipsoidal (WGS84)
    home_lat_deg: float = 30.5
    home_lon_deg: float = 114.3
    home_alt_m: float = 50.0
    g_mps2: float | None = None
    # gyro (rad/s)
    gyro_noise_rps_rthz: float = 0.005 * _DEG  # ARW density, 0.005 deg/s/sqrt(Hz)
    gyro_bias_rw_rps_rts: float = 1.0e-5  # rate random walk, rad/s/sqrt(s)
    gyro_bias_sigma_rps: float = 0.3 * _DEG  # 1-sigma of the constant (turn-on) bias, drawn per axis
    gyro_bias_rps: tuple[float, float, float] | None = None  # fixed constant bias (overrides the draw)
    gyro_bias_gm_sigma_rps: float = 0.0  # optional Gauss-Markov bias ("bias instability")
    gyro_bias_gm_tau_s: float = 300.0
    gyro_scale_ppm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_lsb_rps: float = 2000.0 * _DEG / 32768.0  # 0: no quantization
    gyro_range_rps: float = 2000.0 * _DEG  # saturation; inf: none
    earth_rate: bool = False  # add the earth rotation rate (flat-earth: at home latitude) to the gyro
    # accelerometer (m/s^2)
    accel_noise_mps2_rthz: float = 2.0e-3  # VRW density (~200 ug/sqrt(Hz))
    accel_bias_rw_mps2_rts: float = 1.0e-4
    accel_bias_sigma_mps2: float = 0.05
    accel_bias_mps2: tuple[float, float, float] | None = None
    accel_bias_gm_sigma_mps2: float = 0.0
    accel_bias_gm_tau_s: float = 300.0
    accel_scale_ppm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_lsb_mps2: float = 16.0 * G0_MPS2 / 32768.0
    accel_range_mps2: float = 16.0 * G0_MPS2
    accel_vibration_mps2: float = 0.0  # amplitude of a sinusoidal vibration on each axis (random phase)
    accel_vibration_hz: float = 120.0
    # GNSS
    gps_pos_sigma_h_m: float = 2.5  # Gauss-Markov 1-sigma, each of N and E
    gps_pos_sigma_v_m: float = 5.0  # Gauss-Markov 1-sigma, D
    gps_pos_tau_s: float = 60.0
    gps_pos_white_h_m: float = 0.3  # extra white noise, each of N and E
    gps_pos_white_v_m: float = 0.5
    gps_vel_sigma_h_mps: float = 0.1  # white, each of N and E
    gps_vel_sigma_v_mps: float = 0.15
    gps_latency_us: int = 100_000  # t_rx_us - t_us
    gps_latency_jitter_us: int = 0  # extra uniform [0, jitter] latency per fix
    gps_start_s: float = 0.0  # first fix epoch
    gps_outages: tuple[tuple[float, float], ...] = ()  # [start, end) windows in s with no fixes
    gps_lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0)  # antenna in body FRD
    gps_num_sv: int = 12
    # magnetometer (uT)
    mag_field_ut: float = 50.0
    mag_inclination_deg: float = 45.0  # positive down
    mag_declination_deg: float = 0.0  # positive east
    mag_noise_ut: float = 0.3  # white, per axis, per sample
    mag_hard_iron_ut: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mag_soft_iron: tuple[tuple[float, float, float], ...] | None = None  # 3x3 matrix; None: identity

    #: fields that are sensor errors; :meth:`ideal` zeroes them
    ERROR_FIELDS = (
        "gyro_noise_rps_rthz", "gyro_bias_rw_rps_rts", "gyro_bias_sigma_rps", "gyro_bias_gm_sigma_rps",
        "gyro_lsb_rps", "accel_noise_mps2_rthz", "accel_bias_rw_mps2_rts", "accel_bias_sigma_mps2",
        "accel_bias_gm_sigma_mps2", "accel_lsb_mps2", "accel_vibration_mps2", "gps_pos_sigma_h_m",
        "gps_pos_sigma_v_m", "gps_pos_white_h_m", "gps_pos_white_v_m", "gps_vel_sigma_h_mps",
        "gps_vel_sigma_v_mps", "mag_noise_ut",
    )  # fmt: skip

    def ideal(self) -> SimParams:
        """A copy with every sensor error off (noise, biases, scale factors, quantization, saturation,
        vibration, hard/soft iron, latency and IMU time jitter). Latency and rates are kept."""
        kw = {name: 0.0 for name in self.ERROR_FIELDS}
        kw.update(
            gyro_bias_rps=(0.0, 0.0, 0.0), accel_bias_mps2=(0.0, 0.0, 0.0),
            gyro_scale_ppm=(0.0, 0.0, 0.0), accel_scale_ppm=(0.0, 0.0, 0.0),
            gyro_range_rps=math.inf, accel_range_mps2=math.inf,
            mag_hard_iron_ut=(0.0, 0.0, 0.0), mag_soft_iron=None, gps_latency_jitter_us=0,
            imu_time_jitter_us=0,
        )  # fmt: skip
        return replace(self, **kw)

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @property
    def mag_ned(self) -> np.ndarray:
        """Earth field in NED (uT) from total intensity, inclination and declination."""
        inc, dec = self.mag_inclination_deg * _DEG, self.mag_declination_deg * _DEG
        return self.mag_field_ut * np.array(
            [math.cos(inc) * math.cos(dec), math.cos(inc) * math.sin(dec), math.sin(inc)]
        )


# --------------------------------------------------------------------------- gravity, geodesy
def normal_gravity(lat_deg: float, h_m: float) -> float:
    """WGS84 normal gravity (m/s^2) at geodetic latitude and ellipsoidal height.

    Somigliana's closed formula on the ellipsoid (NIMA TR8350.2, eq. 4-1)::

        gamma_0 = gamma_e (1 + k sin^2 L) / sqrt(1 - e^2 sin^2 L),   k = b gamma_p / (a gamma_e) - 1

    with the second-order free-air correction above the ellipsoid (TR8350.2, eq. 4-3)::

        gamma_h = gamma_0 [1 - 2/a (1 + f + m - 2 f sin^2 L) h + 3 h^2 / a^2],   m = omega^2 a^2 b / GM
    """
    a, f = WGS84_A_M, WGS84_F
    b = a * (1.0 - f)
    e2 = f * (2.0 - f)
    k = b * WGS84_GAMMA_P / (a * WGS84_GAMMA_E) - 1.0
    m = WGS84_OMEGA_RPS**2 * a * a * b / WGS84_GM
    s2 = math.sin(lat_deg * _DEG) ** 2
    g0 = WGS84_GAMMA_E * (1.0 + k * s2) / math.sqrt(1.0 - e2 * s2)
    return g0 * (1.0 - 2.0 / a * (1.0 + f + m - 2.0 * f * s2) * h_m + 3.0 * h_m * h_m / (a * a))


def ned_to_geodetic_wgs84(n, e, d, lat0_deg: float, lon0_deg: float, h0_m: float):
    """NED offsets (m) from a WGS84 point to geodetic (lat deg, lon deg, ellipsoidal height m).

    Exact: home -> ECEF, NED -> ECEF rotation, then ECEF -> geodetic by Bowring's iteration
    (6 rounds: converged to < 1e-15 rad and < 1e-8 m within 100 km of the surface).
    """
    a, f = WGS84_A_M, WGS84_F
    e2 = f * (2.0 - f)
    b = a * (1.0 - f)
    ep2 = e2 / (1.0 - e2)
    la, lo = lat0_deg * _DEG, lon0_deg * _DEG
    sl, cl, so, co = math.sin(la), math.cos(la), math.sin(lo), math.cos(lo)
    n0 = a / math.sqrt(1.0 - e2 * sl * sl)
    x0, y0, z0 = (n0 + h0_m) * cl * co, (n0 + h0_m) * cl * so, (n0 * (1.0 - e2) + h0_m) * sl
    n, e, d = (np.asarray(v, np.float64) for v in (n, e, d))
    # columns of C_e^n^T: north, east, down unit vectors in ECEF
    x = x0 - sl * co * n - so * e - cl * co * d
    y = y0 - sl * so * n + co * e - cl * so * d
    z = z0 + cl * n - sl * d
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    beta = np.arctan2(z * a, p * b)  # parametric latitude, first guess
    for _ in range(6):
        lat = np.arctan2(z + ep2 * b * np.sin(beta) ** 3, p - e2 * a * np.cos(beta) ** 3)
        beta = np.arctan2((1.0 - f) * np.sin(lat), np.cos(lat))
    lat = np.arctan2(z + ep2 * b * np.sin(beta) ** 3, p - e2 * a * np.cos(beta) ** 3)
    sl_, cl_ = np.sin(lat), np.cos(lat)
    nn = a / np.sqrt(1.0 - e2 * sl_ * sl_)
    h = p * cl_ + z * sl_ - a * a / nn  # valid at every latitude
    return lat / _DEG, lon / _DEG, h


def ned_to_geodetic(n, e, d, lat0_deg: float, lon0_deg: float, h0_m: float):
    """NED -> geodetic via ``pymap3d.ned2geodetic`` when installed, else :func:`ned_to_geodetic_wgs84`."""
    try:
        import pymap3d
    except ImportError:
        return ned_to_geodetic_wgs84(n, e, d, lat0_deg, lon0_deg, h0_m)
    lat, lon, h = pymap3d.ned2geodetic(n, e, d, lat0_deg, lon0_deg, h0_m, deg=True)
    return np.asarray(lat, np.float64), np.asarray(lon, np.float64), np.asarray(h, np.float64)


# --------------------------------------------------------------------------- random processes
def gauss_markov(
    rng: np.random.Generator, n: int, dt_s: float, tau_s: float, sigma: float, dim: int = 3
) -> np.ndarray:
    """``n`` samples (n, dim) of a stationary first-order Gauss-Markov process (module docstring).

    Vectorised: the AR(1) recursion is solved in blocks with a scaled cumulative sum,
    ``x[s+j] = phi^j (phi x[s-1] + sum_i phi^-i w[s+i])``, each block short enough that
    ``phi^-j`` stays below e^30.
    """
    if sigma == 0.0 or n == 0:
        return np.zeros((n, dim))
    if not (tau_s > 0.0 and dt_s > 0.0):
        raise ValueError("Gauss-Markov tau_s and dt_s must be > 0")
    lam = dt_s / tau_s
    phi = math.exp(-lam)
    w = rng.standard_normal((n, dim)) * (sigma * math.sqrt(-math.expm1(-2.0 * lam)))
    w[0] = rng.standard_normal(dim) * sigma  # stationary start
    if phi < 1e-12:
        return w
    blk = max(1, min(n, int(30.0 / lam)))
    j = np.arange(blk, dtype=np.float64)
    up, down = np.exp(j * lam)[:, None], np.exp(-j * lam)[:, None]
    out = np.empty_like(w)
    prev = np.zeros(dim)
    for s in range(0, n, blk):
        m = min(blk, n - s)
        acc = np.cumsum(w[s : s + m] * up[:m], axis=0)
        if s > 0:
            acc += phi * prev
        out[s : s + m] = down[:m] * acc
        prev = out[s + m - 1]
    return out


def _random_walk(rng: np.random.Generator, t_s: np.ndarray, k: float) -> np.ndarray:
    """Brownian motion (n, 3) starting at 0 with increments ``N(0, k^2 dt)``."""
    out = np.zeros((t_s.size, 3))
    if k != 0.0 and t_s.size > 1:
        inc = rng.standard_normal((t_s.size - 1, 3)) * (k * np.sqrt(np.diff(t_s)))[:, None]
        np.cumsum(inc, axis=0, out=out[1:])
    return out


def _quantize_saturate(x: np.ndarray, full_scale: float, lsb: float) -> np.ndarray:
    """Round to whole LSB counts, then clip to +-full scale (a saturated axis reads exactly the limit)."""
    if lsb > 0.0:
        np.multiply(np.round(x / lsb), lsb, out=x)
    if math.isfinite(full_scale):
        np.clip(x, -full_scale, full_scale, out=x)
    return x


# --------------------------------------------------------------------------- sensors
def _bias(rng, t_s, n, const_sigma, const_value, rw, gm_sigma, gm_tau, rate_hz) -> np.ndarray:
    b0 = (
        np.asarray(const_value, np.float64)
        if const_value is not None
        else rng.standard_normal(3) * const_sigma
    )
    b = np.broadcast_to(b0, (n, 3)) + _random_walk(rng, t_s, rw)
    if gm_sigma:
        b += gauss_markov(rng, n, 1.0 / rate_hz, gm_tau, gm_sigma)
    return b


def imu_model(
    truth: Truth, p: SimParams, rng_gyro: np.random.Generator, rng_accel: np.random.Generator
) -> np.ndarray:
    """IMU samples (``IMU_DTYPE``) from the truth; fills ``truth.gyro_bias_rps`` / ``accel_bias_mps2``.

    ``gyro = sat_q((1 + s_g) omega_b [+ C_n^b omega_ie^n] + b_g(t) + n_g)``,
    ``accel = sat_q((1 + s_a) f_b + b_a(t) + vibration + n_a)``; ``sat_q`` rounds to the LSB and
    clips to the range. Samples are instantaneous (not averaged over the interval).
    """
    t_s = truth.t_us * 1e-6
    n = t_s.size
    sq_fs = math.sqrt(p.imu_rate_hz)
    truth.gyro_bias_rps = _bias(
        rng_gyro, t_s, n, p.gyro_bias_sigma_rps, p.gyro_bias_rps, p.gyro_bias_rw_rps_rts,
        p.gyro_bias_gm_sigma_rps, p.gyro_bias_gm_tau_s, p.imu_rate_hz,
    )  # fmt: skip
    truth.accel_bias_mps2 = _bias(
        rng_accel, t_s, n, p.accel_bias_sigma_mps2, p.accel_bias_mps2, p.accel_bias_rw_mps2_rts,
        p.accel_bias_gm_sigma_mps2, p.accel_bias_gm_tau_s, p.imu_rate_hz,
    )  # fmt: skip
    gyro = truth.omega_b_rps * (1.0 + 1e-6 * np.asarray(p.gyro_scale_ppm))
    if p.earth_rate:
        lat = p.home_lat_deg * _DEG
        w_ie_n = WGS84_OMEGA_RPS * np.array([math.cos(lat), 0.0, -math.sin(lat)])
        gyro += quat_rotate(quat_conj(truth.q_nb), np.broadcast_to(w_ie_n, (n, 3)))
    gyro += truth.gyro_bias_rps
    if p.gyro_noise_rps_rthz:
        gyro += rng_gyro.standard_normal((n, 3)) * (p.gyro_noise_rps_rthz * sq_fs)
    accel = truth.specific_force_b_mps2 * (1.0 + 1e-6 * np.asarray(p.accel_scale_ppm)) + truth.accel_bias_mps2
    if p.accel_noise_mps2_rthz:
        accel += rng_accel.standard_normal((n, 3)) * (p.accel_noise_mps2_rthz * sq_fs)
    if p.accel_vibration_mps2:
        phase = rng_accel.uniform(0.0, 2.0 * math.pi, 3)
        accel += p.accel_vibration_mps2 * np.sin(2.0 * math.pi * p.accel_vibration_hz * t_s[:, None] + phase)
    out = np.zeros(n, IMU_DTYPE)
    out["t_us"] = truth.t_us
    out["gyro_rps"] = _quantize_saturate(gyro, p.gyro_range_rps, p.gyro_lsb_rps)
    out["accel_mps2"] = _quantize_saturate(accel, p.accel_range_mps2, p.accel_lsb_mps2)
    return out


def snap_epochs(truth: Truth, rate_hz: float, start_s: float, imu_rate_hz: float) -> np.ndarray:
    """Indices of the IMU samples nearest to ``start_s + k / rate_hz`` (epochs snapped to the IMU grid,
    so the truth is exact at every GNSS or magnetometer epoch)."""
    if rate_hz <= 0.0:
        return np.zeros(0, np.int64)
    t_end = truth.t_us[-1] * 1e-6
    k = np.arange(int(math.floor((t_end - start_s) * rate_hz + 1e-9)) + 1)
    idx = np.rint((start_s + k / rate_hz) * imu_rate_hz).astype(np.int64)
    idx = idx[(idx >= 0) & (idx < truth.t_us.size)]
    return idx if np.all(idx[1:] > idx[:-1]) else np.unique(idx)


def gnss_model(truth: Truth, p: SimParams, rng: np.random.Generator) -> np.ndarray:
    """GNSS fixes (``GNSS_DTYPE``) from the truth.

    Position error per NED axis: Gauss-Markov (sigma_h, sigma_h, sigma_v; tau) plus white;
    velocity error: white. ``h_acc_m``/``v_acc_m`` carry the modelled per-axis total sigma
    ``sqrt(sigma_gm^2 + sigma_white^2)`` (horizontal: each of N and E). The error processes run
    through outages (time passes); fixes inside an outage window or arriving after the end of
    the recording are dropped.
    """
    idx = snap_epochs(truth, p.gps_rate_hz, p.gps_start_s, p.imu_rate_hz)
    m = idx.size
    dt = 1.0 / p.gps_rate_hz if p.gps_rate_hz > 0 else 1.0
    sig_gm = np.array([p.gps_pos_sigma_h_m, p.gps_pos_sigma_h_m, p.gps_pos_sigma_v_m])
    sig_w = np.array([p.gps_pos_white_h_m, p.gps_pos_white_h_m, p.gps_pos_white_v_m])
    sig_v = np.array([p.gps_vel_sigma_h_mps, p.gps_vel_sigma_h_mps, p.gps_vel_sigma_v_mps])
    pos_err = gauss_markov(rng, m, dt, p.gps_pos_tau_s, 1.0) * sig_gm + rng.standard_normal((m, 3)) * sig_w
    vel_err = rng.standard_normal((m, 3)) * sig_v
    q = truth.q_nb[idx]
    lever = np.broadcast_to(np.asarray(p.gps_lever_arm_b_m, np.float64), (m, 3))
    pos = truth.pos_ned_m[idx] + quat_rotate(q, lever) + pos_err
    vel = truth.vel_ned_mps[idx] + quat_rotate(q, np.cross(truth.omega_b_rps[idx], lever)) + vel_err
    lat, lon, h = ned_to_geodetic(
        pos[:, 0], pos[:, 1], pos[:, 2], p.home_lat_deg, p.home_lon_deg, p.home_alt_m
    )
    t_us = truth.t_us[idx]
    t_rx = t_us + int(p.gps_latency_us)
    if p.gps_latency_jitter_us:
        t_rx = t_rx + rng.integers(0, int(p.gps_latency_jitter_us) + 1, m)
    keep = t_rx <= truth.t_us[-1]
    for start, end in p.gps_outages:
        keep &= ~((t_us >= round(start * 1e6)) & (t_us < round(end * 1e6)))
    out = np.zeros(m, GNSS_DTYPE)
    out["t_us"] = t_us
    out["t_rx_us"] = t_rx
    out["lat_e7"] = np.round(lat * 1e7).astype(np.int32)
    out["lon_e7"] = np.round(lon * 1e7).astype(np.int32)
    out["alt_mm"] = np.round(h * 1e3).astype(np.int32)
    out["vel_ned_mps"] = vel
    out["speed_mps"] = np.hypot(vel[:, 0], vel[:, 1])
    course = np.mod(np.arctan2(vel[:, 1], vel[:, 0]), 2.0 * np.pi)
    out["course_rad"] = np.where(course >= 2.0 * np.pi, 0.0, course)
    out["h_acc_m"] = math.hypot(p.gps_pos_sigma_h_m, p.gps_pos_white_h_m)
    out["v_acc_m"] = math.hypot(p.gps_pos_sigma_v_m, p.gps_pos_white_v_m)
    out["s_acc_mps"] = p.gps_vel_sigma_h_mps
    out["fix_type"] = 3
    out["num_sv"] = p.gps_num_sv
    out["flags"] = GNSS_HAS_VEL_NE | GNSS_HAS_VEL_D | GNSS_HAS_ALT | GNSS_HAS_COURSE
    out = out[keep]
    return out[np.argsort(out["t_rx_us"], kind="stable")]  # replay order (differs only if jitter > period)


def mag_model(truth: Truth, p: SimParams, rng: np.random.Generator) -> np.ndarray:
    """Magnetometer samples (``MAG_DTYPE``, uT): ``m_b = S C_n^b m_n + b_hi + noise``."""
    idx = snap_epochs(truth, p.mag_rate_hz, 0.0, p.imu_rate_hz)
    m = idx.size
    mb = quat_rotate(quat_conj(truth.q_nb[idx]), np.broadcast_to(p.mag_ned, (m, 3)))
    if p.mag_soft_iron is not None:
        mb = mb @ np.asarray(p.mag_soft_iron, np.float64).T
    mb = mb + np.asarray(p.mag_hard_iron_ut, np.float64)
    if p.mag_noise_ut:
        mb += rng.standard_normal((m, 3)) * p.mag_noise_ut
    out = np.zeros(m, MAG_DTYPE)
    out["t_us"] = truth.t_us[idx]
    out["mag_b"] = mb
    return out

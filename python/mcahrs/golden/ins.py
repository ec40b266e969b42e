"""Loosely-coupled INS: float64 golden model of ALGORITHMS.md 10 (DESIGN.md 6).

Written from the specification, not from the C: attitudes are ``scipy.spatial.transform.Rotation``
objects, the position is a plain float64 ``(L, lambda, h)`` (float64 needs none of the C core's
integer-plus-offset folding), the discretisation is written as the spec's series and checked against
the Van Loan matrix exponential (:func:`van_loan`), the measurement update is the golden
:func:`mcahrs.golden.robust.robust_update`, and home-frame NED comes from ``pymap3d``.

One block of functions per block of the spec:

* frames and rates: :func:`radii`, :func:`earth_rate`, :func:`transport_rate`, :func:`gravity`;
* mechanization: :meth:`Ins._mechanize` (steps 1-8);
* error model: :func:`error_matrix` (the F table), :func:`process_noise_density` (Qc),
  :func:`discretize` (the second-order Phi and Qd) and :func:`van_loan` (the exact reference);
* alignment, navigation start, yaw: :meth:`Ins._align_step`, :meth:`Ins._start_nav`,
  :meth:`Ins._yaw_turn`, :func:`mag_heading`, :func:`yaw_row`;
* history and latency: :meth:`Ins.solution_at`;
* GNSS update: :func:`gnss_rows` and :meth:`Ins.gps`.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np
import pymap3d
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from mcahrs.errors import (
    BadArgError,
    BadConfigError,
    BadDtError,
    NonFiniteError,
    TimeBackwardsError,
)
from mcahrs.golden import geo
from mcahrs.golden.nav import check_accuracies, check_fix_velocity
from mcahrs.golden.robust import (
    RobustConfig,
    RobustReport,
    RobustState,
    chi2_quantile,
    kf_update,
    robust_update,
)

__all__ = [
    "HIST_DT_US",
    "HIST_LEN",
    "NX",
    "Ins",
    "InsConfig",
    "discretize",
    "earth_rate",
    "error_matrix",
    "gnss_rows",
    "gravity",
    "mag_heading",
    "process_noise_density",
    "radii",
    "replay",
    "transport_rate",
    "van_loan",
    "yaw_row",
]

NX = 15
DR, DV, PHI, BG, BA = 0, 3, 6, 9, 12
HIST_LEN = 50
HIST_DT_US = 20_000
OMEGA_E = 7.292115e-5  # rad/s
GRAV_GRAD = 3.086e-6  # -dg/dh of the normal gravity, 1/s^2
COS_FLOOR = 0.01
LAT_MAX_RAD = math.radians(89.9)
MAG_MAX_TILT = math.radians(80.0)
STILL_SPEED = 0.5  # m/s: GNSS ground speed below which a still window may re-level
G0 = 9.80665
YAW_NONE, YAW_MAG, YAW_COG = 0, 1, 2
FIX_VEL_NE, FIX_VEL_D, FIX_ALT = 1, 2, 4  # mca_gps_fix_t flags (ALGORITHMS.md 8)
# GNSS update step 1 (the fix velocity and accuracy checks) is mcahrs.golden.nav's GPS step 1.

FLAG_ALIGNED, FLAG_HOME_SET, FLAG_NAV, FLAG_YAW_ALIGNED = 1, 2, 4, 8
FLAG_GPS_LOST, FLAG_HIST_MISS, FLAG_REJECTED, FLAG_SATURATED = 16, 32, 64, 128
FLAG_DETECTED, FLAG_RESET = 256, 512

_DEG = math.pi / 180.0


# ------------------------------------------------------------------------------ configuration


@dataclass
class InsConfig:
    """The table of ALGORITHMS.md 10 (names and defaults of ``mca_ins_config_t``)."""

    gyro_noise_rps: float = 3e-4
    accel_noise_mps2: float = 3e-3
    gyro_bias_rw_rps2: float = 2e-5
    accel_bias_rw_mps3: float = 2e-4
    gyro_bias_tau_s: float = 1000.0
    accel_bias_tau_s: float = 1000.0
    att0_var_rad2: float = (2.0 * _DEG) ** 2
    yaw0_var_rad2: float = (30.0 * _DEG) ** 2
    yaw0_rad: float = 0.0
    gyro_bias0_var_rps2: float = (0.5 * _DEG) ** 2
    gyro_bias_still_var_rps2: float = (0.05 * _DEG) ** 2
    att_still_var_rad2: float = (0.2 * _DEG) ** 2
    accel_bias0_var_mps4: float = 0.1**2
    vel0_var_m2ps2: float = 1.0
    lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    cov_dt_s: float = 0.01
    earth_rate: int = 1
    transport_rate: int = 1
    yaw_source: int = YAW_COG
    gravity_mps2: float = 0.0
    imu_dt_max_s: float = 0.1
    init_still_s: float = 1.0
    init_gyro_still_rps: float = 0.05
    init_acc_still_mps2: float = 0.5
    init_timeout_s: float = 5.0
    accel_sat_mps2: float = 156.9
    gps_timeout_s: float = 1.5
    gps_pos_sigma_m: float = 2.5
    gps_alt_sigma_m: float = 5.0
    gps_vel_sigma_mps: float = 0.2
    mag_declination_rad: float = 0.0
    mag_yaw_sigma_rad: float = 0.05
    mag_period_s: float = 0.1
    cog_min_speed_mps: float = 3.0
    cog_sigma0_rad: float = 0.05
    gps_pos_noise_min_m: float = 0.0  # floor of h_acc and v_acc (EKF2_GPS_P_NOISE), 0: none
    gps_vel_noise_min_mps: float = 0.0  # floor of s_acc (EKF2_GPS_V_NOISE), 0: none
    gnss_reset_s: float = 30.0  # no block fused this long: a rejected block is reset to the fix (0: off)
    gnss_block_reset_s: float = 120.0  # one block not fused this long: the same (0: off)
    # receiver position error: correlation time of its slow part (0: off, accuracies white) and
    # its white part, N and E each and D
    gps_pos_tau_s: float = 0.0
    gps_pos_white_m: float = 0.3
    gps_alt_white_m: float = 0.5
    # the INS dead-reckons through rejected fixes: its time guards replace the count guard
    robust: RobustConfig = field(default_factory=lambda: RobustConfig(reject_reset_n=0))

    @classmethod
    def preset(cls, name: str = "ground", **overrides: Any) -> InsConfig:
        base = {"ground": {}, "fixedwing": {"cog_min_speed_mps": 5.0}, "multirotor": {"yaw_source": YAW_MAG}}
        if name not in base:
            raise BadConfigError(f"unknown preset {name!r}")
        return replace(cls(), **{**base[name], **overrides})

    def validate(self) -> None:
        def fin(name: str) -> float:
            v = getattr(self, name)
            if not math.isfinite(v):
                raise BadConfigError(f"{name} must be finite")
            return v

        for name in (
            "gyro_noise_rps",
            "accel_noise_mps2",
            "gyro_bias_rw_rps2",
            "accel_bias_rw_mps3",
            "gravity_mps2",
            "init_gyro_still_rps",
            "init_acc_still_mps2",
            "mag_period_s",
            "cog_min_speed_mps",
            "cov_dt_s",
        ):
            if fin(name) < 0.0:
                raise BadConfigError(f"{name} must be >= 0")
        for name in (
            "att0_var_rad2",
            "att_still_var_rad2",
            "yaw0_var_rad2",
            "gyro_bias0_var_rps2",
            "gyro_bias_still_var_rps2",
            "accel_bias0_var_mps4",
            "vel0_var_m2ps2",
            "imu_dt_max_s",
            "init_still_s",
            "init_timeout_s",
            "accel_sat_mps2",
            "gps_timeout_s",
            "gps_pos_sigma_m",
            "gps_alt_sigma_m",
            "gps_vel_sigma_mps",
            "mag_yaw_sigma_rad",
            "cog_sigma0_rad",
            "gps_pos_white_m",
            "gps_alt_white_m",
        ):
            if not fin(name) > 0.0:
                raise BadConfigError(f"{name} must be > 0")
        for name in ("gyro_bias_tau_s", "accel_bias_tau_s", "gps_pos_tau_s"):
            v = fin(name)
            if not (v == 0.0 or v >= 1.0):
                raise BadConfigError(f"{name} must be 0 or >= 1")
        if self.gps_pos_tau_s > 3600.0:
            raise BadConfigError("gps_pos_tau_s must be <= 3600")
        fin("yaw0_rad")
        fin("mag_declination_rad")
        if self.cov_dt_s > 0.1 or self.earth_rate not in (0, 1) or self.transport_rate not in (0, 1):
            raise BadConfigError("cov_dt_s, earth_rate or transport_rate out of range")
        if self.yaw_source not in (YAW_NONE, YAW_MAG, YAW_COG):
            raise BadConfigError("yaw_source out of range")
        if any(not math.isfinite(x) or abs(x) > 10.0 for x in self.lever_arm_b_m):
            raise BadConfigError("lever_arm_b_m out of range")
        for name in ("gps_pos_noise_min_m", "gps_vel_noise_min_mps"):
            if not fin(name) >= 0.0:
                raise BadConfigError(f"{name} must be >= 0")
        for name in ("gnss_reset_s", "gnss_block_reset_s"):
            if not 0.0 <= fin(name) <= 600.0:
                raise BadConfigError(f"{name} must be in [0, 600]")
        self.robust.validate()


def config_from_c(cfg_dict: dict[str, Any]) -> InsConfig:
    """An :class:`InsConfig` from ``core.config_dict`` of a C ``mca_ins_config_t`` (float32 values
    widened to float64, so both models run the same numbers)."""
    from mcahrs.golden.robust import MODES

    kw: dict[str, Any] = {}
    for f in fields(InsConfig):
        v = cfg_dict[f.name]
        if f.name == "robust":
            kw["robust"] = RobustConfig(
                mode=MODES[int(v["mode"])],
                fuzzy_reject=int(v["fuzzy_reject"]),
                akf_window=int(v["akf_window"]),
                akf_forget=float(v["akf_forget"]),
                akf_q_min=float(v["akf_q_min"]),
                akf_q_max=float(v["akf_q_max"]),
                igg_k0=float(v["igg_k0"]),
                igg_k1=float(v["igg_k1"]),
                reject_reset_n=int(v["reject_reset_n"]),
                row_reset_n=int(v["row_reset_n"]),
            )
        elif f.name == "lever_arm_b_m":
            kw[f.name] = tuple(float(x) for x in v)
        elif f.name in ("earth_rate", "transport_rate", "yaw_source"):
            kw[f.name] = int(v)
        else:
            kw[f.name] = float(v)
    return InsConfig(**kw)


def _us(seconds: float) -> int:
    """A configured duration in integer microseconds (ALGORITHMS.md 8, Times). The C rounds the
    float32 value; the configs compared here are exactly representable or differ by < 1 us."""
    return int(math.floor(seconds * 1e6 + 0.5))


# ------------------------------------------------------------------------------ frames and rates


def skew(a: np.ndarray) -> np.ndarray:
    """[a x], the cross-product matrix."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def radii(lat: float, h: float) -> tuple[float, float]:
    """(R_M + h, R_N + h): meridian and prime-vertical radii of curvature plus height."""
    s2 = math.sin(lat) ** 2
    w = 1.0 - geo.WGS84_E2 * s2
    return geo.WGS84_A * (1.0 - geo.WGS84_E2) / w**1.5 + h, geo.WGS84_A / math.sqrt(w) + h


def _cos_floored(lat: float) -> float:
    return max(math.cos(lat), COS_FLOOR)


def earth_rate(lat: float, on: bool = True) -> np.ndarray:
    """w_ie in NED."""
    return OMEGA_E * np.array([math.cos(lat), 0.0, -math.sin(lat)]) if on else np.zeros(3)


def transport_rate(lat: float, h: float, v: np.ndarray, on: bool = True) -> np.ndarray:
    """w_en in NED."""
    if not on:
        return np.zeros(3)
    rm, rn = radii(lat, h)
    tan_l = math.sin(lat) / _cos_floored(lat)
    return np.array([v[1] / rn, -v[0] / rm, -v[1] * tan_l / rn])


def gravity(cfg: InsConfig, lat: float, h: float) -> float:
    return cfg.gravity_mps2 if cfg.gravity_mps2 > 0.0 else geo.normal_gravity(lat, h)


# ------------------------------------------------------------------------------ error model


def error_matrix(
    cfg: InsConfig, lat: float, h: float, v: np.ndarray, c_nb: np.ndarray, f_n: np.ndarray
) -> np.ndarray:
    """F of the ALGORITHMS.md 10 table (15 x 15)."""
    w_ie = earth_rate(lat, bool(cfg.earth_rate))
    w_en = transport_rate(lat, h, v, bool(cfg.transport_rate))
    F = np.zeros((NX, NX))
    F[DR : DR + 3, DV : DV + 3] = np.eye(3)
    if not cfg.gravity_mps2 > 0.0:
        F[DV + 2, DR + 2] = GRAV_GRAD
    F[DV : DV + 3, DV : DV + 3] = -skew(2.0 * w_ie + w_en)
    F[DV : DV + 3, PHI : PHI + 3] = -skew(np.asarray(f_n, float))
    F[DV : DV + 3, BA : BA + 3] = -c_nb
    if cfg.transport_rate:
        rm, rn = radii(lat, h)
        tan_l = math.sin(lat) / _cos_floored(lat)
        F[PHI : PHI + 3, DV : DV + 3] = -np.array(
            [[0.0, 1.0 / rn, 0.0], [-1.0 / rm, 0.0, 0.0], [0.0, -tan_l / rn, 0.0]]
        )
    F[PHI : PHI + 3, PHI : PHI + 3] = -skew(w_ie + w_en)
    F[PHI : PHI + 3, BG : BG + 3] = -c_nb
    for blk, tau in ((BG, cfg.gyro_bias_tau_s), (BA, cfg.accel_bias_tau_s)):
        if tau > 0.0:
            F[blk : blk + 3, blk : blk + 3] = -np.eye(3) / tau
    return F


def process_noise_density(cfg: InsConfig, q_scale: float = 1.0) -> np.ndarray:
    """Qc (15 x 15, diagonal): 0, VRW^2, ARW^2, gyro and accel bias driving noise^2, times q_scale."""
    d = np.concatenate(
        [
            np.zeros(3),
            np.full(3, cfg.accel_noise_mps2**2),
            np.full(3, cfg.gyro_noise_rps**2),
            np.full(3, cfg.gyro_bias_rw_rps2**2),
            np.full(3, cfg.accel_bias_rw_mps3**2),
        ]
    )
    return np.diag(q_scale * d)


def discretize(F: np.ndarray, Qc: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:  # noqa: N803
    """The spec's second-order discretisation:
    Phi = I + F T + (F T)^2/2, Qd = Qc T + (F Qc + Qc F^T) T^2/2."""
    A = F * T
    return np.eye(len(F)) + A + 0.5 * A @ A, Qc * T + 0.5 * (F @ Qc + Qc @ F.T) * T * T


def van_loan(F: np.ndarray, Qc: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:  # noqa: N803
    """Exact discretisation (Van Loan 1978): expm([[-F, Qc], [0, F^T]] T) = [[., Phi^-1 Qd], [0, Phi^T]]."""
    n = len(F)
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -F, Qc, F.T
    E = expm(M * T)
    phi = E[n:, n:].T
    return phi, phi @ E[:n, n:]


# ------------------------------------------------------------------------------ observations


def mag_heading(rot: Rotation, mag_b: np.ndarray, declination: float) -> float:
    """Tilt-compensated magnetic heading (ALGORITHMS.md 7) plus declination."""
    _, pitch, roll = rot.as_euler("ZYX")
    m_l = Rotation.from_euler("ZYX", [0.0, pitch, roll]).apply(np.asarray(mag_b, float))
    return math.atan2(-m_l[1], m_l[0]) + declination


def yaw_row(c_nb: np.ndarray) -> np.ndarray:
    """d psi / d phi of psi = atan2(C21, C11) under the left error (1 x 15)."""
    d = c_nb[0, 0] ** 2 + c_nb[1, 0] ** 2
    h = np.zeros(NX)
    h[PHI : PHI + 3] = [-c_nb[0, 0] * c_nb[2, 0] / d, -c_nb[1, 0] * c_nb[2, 0] / d, 1.0]
    return h


def wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def yaw_of(rot: Rotation) -> float:
    return float(rot.as_euler("ZYX")[0])


@dataclass
class Solution:
    """The INS solution at one time: home NED position, velocity, attitude, bias-corrected body rate."""

    t_us: int
    r: np.ndarray
    v: np.ndarray
    rot: Rotation
    w: np.ndarray


def gnss_rows(
    sol: Solution, lever_b: np.ndarray, ned_fix: np.ndarray, vel_fix: np.ndarray, rows: list[tuple[str, int]]
) -> tuple[np.ndarray, np.ndarray]:
    """H (m x 15) and innovation of GNSS rows ("p"/"v", axis) against ``sol`` (ALGORITHMS.md 10,
    GNSS update step 4)."""
    c = sol.rot.as_matrix()
    cl = c @ lever_b
    cwl = c @ np.cross(sol.w, lever_b)
    H = np.zeros((len(rows), NX))
    nu = np.zeros(len(rows))
    for k, (kind, i) in enumerate(rows):
        if kind == "p":
            H[k, DR + i] = 1.0
            H[k, PHI : PHI + 3] = -skew(cl)[i]
            nu[k] = ned_fix[i] - sol.r[i] - cl[i]
        else:
            H[k, DV + i] = 1.0
            H[k, PHI : PHI + 3] = -skew(cwl)[i]
            H[k, BG : BG + 3] = (c @ skew(lever_b))[i]
            nu[k] = vel_fix[i] - sol.v[i] - cwl[i]
    return H, nu


# ------------------------------------------------------------------------------ the filter


@dataclass
class _HistEntry:
    t_us: int
    r: np.ndarray
    v: np.ndarray
    rot: Rotation
    w: np.ndarray


def _accuracy(v: Any, default: float) -> float:
    v = float(v)
    return v if math.isfinite(v) and v > 0.0 else default


class Ins:
    """The INS of ALGORITHMS.md 10, float64. Steps raise the :mod:`mcahrs.errors` exception of the C
    status (state unchanged) or return; ``output()`` mirrors ``mca_ins_output_t``."""

    def __init__(self, cfg: InsConfig | None = None) -> None:
        self.cfg = cfg if cfg is not None else InsConfig()
        self.cfg.validate()
        self.rot = Rotation.identity()
        self.v = np.zeros(3)
        self.lat = self.lon = self.h = 0.0
        self.bg = np.zeros(3)
        self.ba = np.zeros(3)
        self.P = np.zeros((NX, NX))
        self.rs = RobustState()  # position block; its AKF factor scales Q
        self.rs_v = RobustState()  # velocity block
        self.t_fuse_pos = self.t_fuse_vel = 0
        self.pos_out = self.vel_out = False  # the last fix's block rejected or held out
        self.rx_q = np.zeros(2)  # receiver slow-error growth 2 c^2 / tau of the last fix (N/E, D)
        self.home: tuple[int, int, int] | None = None
        self.hist: deque[_HistEntry] = deque(maxlen=HIST_LEN)
        self.t_imu = self.t_first = self.t_lastfix = self.t_lastmag = 0
        self.cov_dv = np.zeros(3)
        self.cov_acc_us = 0
        self.hist_acc_us = 0
        self.init_f, self.init_w, self.init_us, self.init_n = np.zeros(3), np.zeros(3), 0, 0
        self.init_all_f, self.init_all_n = np.zeros(3), 0
        self.w_last = np.zeros(3)
        self.f_last = np.zeros(3)
        self.yaw_var_align = self.cfg.yaw0_var_rad2
        self.bg0_var = self.cfg.gyro_bias0_var_rps2
        self.g_home = G0
        self.level_still = False
        self.fix_speed = -1.0
        self.have_imu = self.aligned = self.nav = self.yaw_aligned = self.have_fix = self.have_mag = False
        self.flags = 0
        self.last_gps_t, self.last_gps_m = math.nan, 0
        self.n_upd = self.n_rej = self.n_skip = 0
        self.last_report: Any = None  # the position block's
        self.last_report_v: Any = None

    # ---------------------------------------------------------------- position helpers

    def _move(self, d_ned: np.ndarray, lat: float | None = None, h: float | None = None) -> None:
        """Move the position by metres along NED with the radii at (lat, h) (default: current)."""
        lat = self.lat if lat is None else lat
        h = self.h if h is None else h
        rm, rn = radii(lat, h)
        self.lat += d_ned[0] / rm
        self.lon += d_ned[1] / (rn * _cos_floored(lat))
        self.h -= d_ned[2]
        self.lat = min(max(self.lat, -LAT_MAX_RAD), LAT_MAX_RAD)
        self.lon = (self.lon + math.pi) % (2.0 * math.pi) - math.pi

    def pos_ned(self) -> np.ndarray:
        """Home NED of the current position (pymap3d, WGS84, float64)."""
        assert self.home is not None
        n, e, d = pymap3d.geodetic2ned(
            self.lat,
            self.lon,
            self.h,
            self.home[0] * 1e-7 * _DEG,
            self.home[1] * 1e-7 * _DEG,
            self.home[2] * 1e-3,
            deg=False,
        )
        return np.array([float(n), float(e), float(d)])

    # ---------------------------------------------------------------- IMU

    def _g_still(self) -> float:
        if self.cfg.gravity_mps2 > 0.0:
            return self.cfg.gravity_mps2
        return self.g_home if self.home is not None else G0

    def imu(self, t_us: int, gyro_rps: Any, accel_mps2: Any) -> None:
        w = np.asarray(gyro_rps, float).reshape(3)
        f = np.asarray(accel_mps2, float).reshape(3)
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(f))):
            raise NonFiniteError("imu: non-finite sample")
        t_us = int(t_us)
        if not self.have_imu:
            self.have_imu, self.t_imu, self.t_first = True, t_us, t_us
            return
        if t_us <= self.t_imu:
            raise TimeBackwardsError(f"imu: {t_us} <= {self.t_imu}")
        dt_us = t_us - self.t_imu
        self.t_imu = t_us
        if dt_us > _us(self.cfg.imu_dt_max_s):
            self.nav = False  # position and velocity unknown after a gap; the next fix restarts
            raise BadDtError(f"imu: step of {dt_us} us")
        dt = dt_us * 1e-6
        if np.any(np.abs(f) >= self.cfg.accel_sat_mps2):
            self.flags |= FLAG_SATURATED
        self.f_last = f - self.ba
        if not self.aligned:
            self._align_step(dt_us, w, f)
        elif not self.nav:
            # attitude only until navigation starts; a sample completing a still window re-levels
            if not self._align_step(dt_us, w, f):
                self.w_last = w - self.bg
                self.rot = self.rot * Rotation.from_rotvec(self.w_last * dt)
        else:
            self._mechanize(w, f, dt, dt_us)

    def imu_delta(self, t_us: int, dtheta_rad: Any, dv_mps: Any) -> None:
        """Increments over (previous time, t_us], converted to rates (ALGORITHMS.md 10)."""
        dth = np.asarray(dtheta_rad, float)
        dv = np.asarray(dv_mps, float)
        t_us = int(t_us)
        if (
            self.have_imu
            and t_us > self.t_imu
            and t_us - self.t_imu <= _us(self.cfg.imu_dt_max_s)
            and np.all(np.isfinite(dth))
            and np.all(np.isfinite(dv))
        ):
            dt = (t_us - self.t_imu) * 1e-6
            return self.imu(t_us, dth / dt, dv / dt)
        return self.imu(t_us, dth, dv)

    def _align_step(self, dt_us: int, w: np.ndarray, f: np.ndarray) -> bool:
        """The still-window rule of ALGORITHMS.md 8, IMU step 4, with section 10's timeout fallback
        (mean of every sample) and re-levelling while waiting to navigate. True when this sample
        aligned or re-levelled."""
        cfg = self.cfg
        self.init_all_f = self.init_all_f + f
        self.init_all_n += 1
        still = (
            np.linalg.norm(w) <= cfg.init_gyro_still_rps
            and abs(np.linalg.norm(f) - self._g_still()) <= cfg.init_acc_still_mps2
        )
        if still:
            self.init_f = self.init_f + f
            self.init_w = self.init_w + w
            self.init_n += 1
            self.init_us += dt_us
        else:
            self.init_f, self.init_w, self.init_n, self.init_us = np.zeros(3), np.zeros(3), 0, 0
        if self.init_n > 0 and self.init_us >= _us(cfg.init_still_s):
            if not self.aligned:
                self._align(self.init_f / self.init_n, self.init_w / self.init_n, True)
                return True
            stopped = (
                self.have_fix
                and 0.0 <= self.fix_speed < STILL_SPEED
                and self.t_imu - self.t_lastfix <= _us(cfg.gps_timeout_s)
            )
            if stopped:  # re-level while waiting to navigate, the GNSS agreeing the vehicle is stopped
                self._level(self.init_f / self.init_n, self.init_w / self.init_n, yaw_of(self.rot), True)
                return True
            self.init_f, self.init_w, self.init_n, self.init_us = np.zeros(3), np.zeros(3), 0, 0
            return False
        if not self.aligned and self.t_imu - self.t_first >= _us(cfg.init_timeout_s):
            f_mean = self.init_f / self.init_n if self.init_n else self.init_all_f / self.init_all_n
            self._align(f_mean, np.zeros(3), False)
            return True
        return False

    def _level(self, f_mean: np.ndarray, bias: np.ndarray, yaw: float, still: bool) -> None:
        """Roll and pitch from a mean specific force, the given yaw, the gyro bias; window emptied."""
        roll = math.atan2(-f_mean[1], -f_mean[2])
        pitch = math.atan2(f_mean[0], math.hypot(f_mean[1], f_mean[2]))
        self.rot = Rotation.from_euler("ZYX", [yaw, pitch, roll])
        self.bg = np.array(bias, float)
        self.ba = np.zeros(3)
        self.bg0_var = self.cfg.gyro_bias_still_var_rps2 if still else self.cfg.gyro_bias0_var_rps2
        self.level_still = still
        self.init_f, self.init_w, self.init_n, self.init_us = np.zeros(3), np.zeros(3), 0, 0

    def _align(self, f_mean: np.ndarray, bias: np.ndarray, still: bool) -> None:
        self._level(f_mean, bias, self.cfg.yaw0_rad, still)
        self.aligned = True
        self.yaw_aligned = self.cfg.yaw_source == YAW_NONE
        self.yaw_var_align = self.cfg.yaw0_var_rad2

    def _mechanize(self, w_m: np.ndarray, f_m: np.ndarray, dt: float, dt_us: int) -> None:
        """ALGORITHMS.md 10, Mechanization steps 1-8."""
        cfg = self.cfg
        lat, h = self.lat, self.h
        w_ie = earth_rate(lat, bool(cfg.earth_rate))
        w_en = transport_rate(lat, h, self.v, bool(cfg.transport_rate))
        g_n = np.array([0.0, 0.0, gravity(cfg, lat, h)])
        dtheta = (w_m - self.bg) * dt
        du = (f_m - self.ba) * dt
        dv_f = self.rot.apply(du + 0.5 * np.cross(dtheta, du))
        v_new = self.v + dv_f + (g_n - np.cross(2.0 * w_ie + w_en, self.v)) * dt
        self._move(0.5 * (self.v + v_new) * dt, lat, h)
        self.v = v_new
        self.rot = Rotation.from_rotvec(-(w_ie + w_en) * dt) * self.rot * Rotation.from_rotvec(dtheta)
        self.w_last = w_m - self.bg
        self.cov_dv = self.cov_dv + dv_f
        self.cov_acc_us += dt_us
        if self.cov_acc_us >= _us(cfg.cov_dt_s):
            T = self.cov_acc_us * 1e-6
            self._propagate(T, self.cov_dv / T)
            self.cov_dv, self.cov_acc_us = np.zeros(3), 0
        self.hist_acc_us += dt_us
        if self.hist_acc_us >= HIST_DT_US:
            self.hist.append(
                _HistEntry(self.t_imu, self.pos_ned(), self.v.copy(), self.rot, self.w_last.copy())
            )
            self.hist_acc_us = 0

    def F(self, f_n: Any) -> np.ndarray:  # noqa: N802
        """F at the current state with NED specific force f_n."""
        return error_matrix(self.cfg, self.lat, self.h, self.v, self.rot.as_matrix(), np.asarray(f_n, float))

    def _propagate(self, T: float, f_n: np.ndarray) -> None:  # noqa: N803
        phi, qd = discretize(self.F(f_n), process_noise_density(self.cfg, self.rs.q_scale), T)
        P = phi @ self.P @ phi.T + qd
        tau = self.cfg.gps_pos_tau_s
        if tau > 0.0:
            # receiver slow error: dr grows as 2 c^2 (1 - exp(-a / tau)), a the time since the
            # position was last applied (ALGORITHMS.md 10, GNSS update step 3)
            g = T * math.exp(-max(self.t_imu - self.t_fuse_pos, 0) * 1e-6 / tau)
            P[[0, 1, 2], [0, 1, 2]] += g * self.rx_q[[0, 0, 1]]
        self.P = 0.5 * (P + P.T)

    # ---------------------------------------------------------------- history

    def solution_at(self, t_us: int) -> Solution | None:
        """ALGORITHMS.md 10, The INS solution at t_fix; None on a history miss."""
        cur = Solution(self.t_imu, self.pos_ned(), self.v.copy(), self.rot, self.w_last.copy())
        if t_us >= self.t_imu:
            return cur
        pts = [Solution(e.t_us, e.r, e.v, e.rot, e.w) for e in self.hist] + [cur]
        if t_us < pts[0].t_us:
            return None
        for a, b in zip(pts[:-1], pts[1:], strict=True):
            if a.t_us <= t_us < b.t_us:
                d, tab = (t_us - a.t_us) * 1e-6, (b.t_us - a.t_us) * 1e-6
                dv = b.v - a.v
                near = b if (t_us - a.t_us) > (b.t_us - t_us) else a
                return Solution(
                    t_us, a.r + a.v * d + dv * d * d / (2.0 * tab), a.v + dv * d / tab, near.rot, near.w
                )
        return None

    # ---------------------------------------------------------------- corrections

    def _yaw_turn(self, dpsi: float, var: float) -> None:
        turn = Rotation.from_rotvec([0.0, 0.0, dpsi])
        self.rot = turn * self.rot
        for e in self.hist:
            e.rot = turn * e.rot
        if self.nav:
            self.P[PHI + 2, :] = 0.0
            self.P[:, PHI + 2] = 0.0
            self.P[PHI + 2, PHI + 2] = var
        self.yaw_aligned = True
        self.yaw_var_align = var

    def _correct(self, dx: np.ndarray) -> None:
        dx = np.array(dx, float)
        turn = Rotation.from_rotvec(dx[PHI : PHI + 3])
        self._move(dx[DR : DR + 3])
        self.v = self.v + dx[DV : DV + 3]
        self.rot = turn * self.rot
        self.bg = self.bg + dx[BG : BG + 3]
        self.ba = self.ba + dx[BA : BA + 3]
        for e in self.hist:
            e.r = e.r + dx[DR : DR + 3]
            e.v = e.v + dx[DV : DV + 3]
            e.rot = turn * e.rot

    # ---------------------------------------------------------------- GNSS

    def gps(self, fix: Any) -> None:
        """GNSS step with a fix as a mapping or object with the ``mca_gps_fix_t`` fields."""

        def get(key: str) -> Any:
            return (
                getattr(fix, key) if hasattr(fix, key) and not isinstance(fix, (dict, np.void)) else fix[key]
            )

        if int(get("fix_type")) < 2:
            raise BadArgError("fix_type < 2")
        flags = int(get("flags"))
        has_alt, has_vne, has_vd = bool(flags & FIX_ALT), bool(flags & FIX_VEL_NE), bool(flags & FIX_VEL_D)
        lat_e7, lon_e7, alt_mm = int(get("lat_e7")), int(get("lon_e7")), int(get("alt_mm"))
        geo.check_geodetic(lat_e7, lon_e7, alt_mm if has_alt else 0)
        vel_in = np.asarray(get("vel_ned_mps"), float)
        check_fix_velocity(vel_in, (has_vne, has_vne, has_vd))  # NONFINITE (first), then RANGE
        # every accuracy after the defaults, before the noise minimum of step 3, used by the fix or not
        h_acc = _accuracy(get("h_acc_m"), self.cfg.gps_pos_sigma_m)
        v_acc = _accuracy(get("v_acc_m"), self.cfg.gps_alt_sigma_m)
        s_acc = _accuracy(get("s_acc_mps"), self.cfg.gps_vel_sigma_mps)
        check_accuracies(h_acc_m=h_acc, v_acc_m=v_acc, s_acc_mps=s_acc)
        t_fix = int(get("t_us"))
        if self.have_fix and t_fix <= self.t_lastfix:
            raise TimeBackwardsError(f"fix time {t_fix} <= {self.t_lastfix}")
        vel = np.array(
            [vel_in[0] if has_vne else 0.0, vel_in[1] if has_vne else 0.0, vel_in[2] if has_vd else 0.0]
        )
        vmask = (has_vne, has_vne, has_vd)
        p_min, v_min = self.cfg.gps_pos_noise_min_m, self.cfg.gps_vel_noise_min_mps
        h_acc, v_acc, s_acc = max(h_acc, p_min), max(v_acc, p_min), max(s_acc, v_min)
        r_pos, rx_q = self._receiver_error(h_acc, v_acc)
        if self.home is None:
            self.home = (lat_e7, lon_e7, alt_mm if has_alt else 0)
            self.g_home = geo.normal_gravity(lat_e7 * 1e-7 * _DEG, self.home[2] * 1e-3)
        alt = alt_mm if has_alt else self.home[2]
        if not self.aligned:
            self.n_skip += 1
        elif not self.nav:  # navigation starts with the heading known
            self._cog_align(vel, has_vne, s_acc, self.rot)
            if self.yaw_aligned:
                self._start_nav(t_fix, lat_e7, lon_e7, alt, vel, vmask, h_acc, v_acc, s_acc)
            else:
                self.n_skip += 1
        else:
            sol = self.solution_at(t_fix)
            if sol is None:
                self.flags |= FLAG_HIST_MISS
                self.n_skip += 1
            else:
                self.flags &= ~FLAG_HIST_MISS
                rows = [("p", 0), ("p", 1)] + ([("p", 2)] if has_alt and int(get("fix_type")) >= 3 else [])
                rows += [("v", i) for i in range(3) if vmask[i]]
                ned = geo.ned_from_home(lat_e7, lon_e7, alt, *self.home)
                H, nu = gnss_rows(sol, np.asarray(self.cfg.lever_arm_b_m, float), ned, vel, rows)
                R = np.array([r_pos[0 if i < 2 else 1] if k == "p" else s_acc**2 for k, i in rows])
                self._gnss_update(t_fix, H, nu, R, sum(k == "p" for k, _ in rows))
        self.have_fix = True
        self.t_lastfix = t_fix
        self.rx_q = rx_q
        self.fix_speed = math.hypot(vel[0], vel[1]) if has_vne else -1.0

    def _receiver_error(self, h_acc: float, v_acc: float) -> tuple[np.ndarray, np.ndarray]:
        """GNSS update step 3: with ``gps_pos_tau_s`` > 0 the fix's h_acc^2 and v_acc^2 split into
        the configured white part (at most the whole), the rows' R, and a slow Gauss-Markov part
        c^2, whose growth rate 2 c^2 / tau the covariance propagation applies; else R is all of it."""
        cfg = self.cfg
        var = np.array([h_acc**2, v_acc**2])
        white = np.array([cfg.gps_pos_white_m**2, cfg.gps_alt_white_m**2])
        if cfg.gps_pos_tau_s <= 0.0:
            return var, np.zeros(2)
        r = np.minimum(var, white)
        return r, 2.0 * (var - r) / cfg.gps_pos_tau_s

    def _gnss_update(self, t_fix: int, H: np.ndarray, nu: np.ndarray, R: np.ndarray, mp: int) -> None:
        """GNSS update step 5 (ALGORITHMS.md 10): the velocity block, then the position block on
        the correction the first left, each in the robust mode with its own memory. Hold-outs
        (rejected without being offered to the mode, whose memory stays): a velocity block after a
        rejected one while the position block alone is not consistent (T >= chi2_m(0.025)), and,
        while the velocity is rejected, a position block not applied on the fix before. Lock-up
        guards: a block its mode rejects although it was last fused more than
        ``gnss_block_reset_s`` ago, or with no block fused for ``gnss_reset_s``, is reset to the
        fix instead (its states take the fix, their covariance R, uncorrelated; its memory
        cleared). One correction with what both did."""
        cfg = self.cfg
        stale_any = cfg.gnss_reset_s > 0.0 and t_fix - max(self.t_fuse_pos, self.t_fuse_vel) > _us(
            cfg.gnss_reset_s
        )
        dx, P = np.zeros(NX), self.P

        def own_t(sel: slice) -> tuple[float, np.ndarray]:  # the block alone against the prior
            C = H[sel] @ P @ H[sel].T + np.diag(R[sel])
            return float(nu[sel] @ np.linalg.solve(C, nu[sel])), C

        applied, t_sum, flags, vel_rejected = False, 0.0, 0, False
        blocks = (
            (slice(mp, len(nu)), "vel", "rs_v", "last_report_v"),
            (slice(0, mp), "pos", "rs", "last_report"),
        )
        for sel, name, rs_name, rep_name in blocks:
            m_b = sel.stop - sel.start
            if m_b == 0:
                continue
            guard = stale_any or (
                cfg.gnss_block_reset_s > 0.0
                and t_fix - getattr(self, f"t_fuse_{name}") > _us(cfg.gnss_block_reset_s)
            )
            if name == "vel":
                hold = self.vel_out and mp > 0 and not own_t(slice(0, mp))[0] < chi2_quantile(0.025, mp)
            else:
                hold = vel_rejected and self.pos_out
            if hold and not guard:
                t_b, C = own_t(sel)
                rep = RobustReport(
                    m=m_b,
                    nu=nu[sel].copy(),
                    C=C,
                    T=t_b,
                    factor=1.0,
                    w=np.ones(m_b),
                    q_scale=1.0,
                    detected=name == "vel",  # the position's disagreement is a detection
                    rejected=True,
                    alarm=False,
                )
                setattr(self, rep_name, rep)
                setattr(self, f"{name}_out", True)
                t_sum += t_b
                flags |= FLAG_REJECTED | (FLAG_DETECTED if rep.detected else 0)
                vel_rejected = vel_rejected or name == "vel"
                continue
            try:
                dx_b, P_b, rep = robust_update(
                    dx, P, H[sel], nu[sel], R[sel], cfg.robust, getattr(self, rs_name)
                )
            except Exception:
                self.n_rej += 1
                if applied:  # the velocity block stands
                    self.P = P
                    self._correct(dx)
                    self.n_upd += 1
                    self._set_gnss_flags(flags)
                raise
            if guard and rep.rejected:  # left out too long: reset to the fix
                dx_b, P_b = dx.copy(), P.copy()
                for i, row in zip(range(sel.start, sel.stop), H[sel], strict=True):
                    k = int(np.flatnonzero(row[: DV + 3] == 1.0)[0])  # the dr or dv entry of the row
                    dx_b[k] = nu[i]
                    P_b[k, :] = 0.0
                    P_b[:, k] = 0.0
                    P_b[k, k] = R[i]
                setattr(self, rs_name, RobustState())
                rep = replace(rep, reset=True, rejected=False)
            setattr(self, rep_name, rep)
            t_sum += rep.T
            flags |= (FLAG_REJECTED if rep.rejected else 0) | (FLAG_DETECTED if rep.detected else 0)
            flags |= FLAG_RESET if rep.reset else 0
            setattr(self, f"{name}_out", rep.rejected)
            if name == "vel":
                vel_rejected = rep.rejected
            if not rep.rejected:
                dx, P, applied = dx_b, P_b, True
                setattr(self, f"t_fuse_{name}", t_fix)
        if applied:
            self.P = P
            self._correct(dx)
            self.n_upd += 1
        if flags & FLAG_REJECTED:
            self.n_rej += 1
        self._set_gnss_flags(flags)
        self.last_gps_t, self.last_gps_m = t_sum, len(nu)

    def _set_gnss_flags(self, flags: int) -> None:
        self.flags = (self.flags & ~(FLAG_REJECTED | FLAG_DETECTED | FLAG_RESET)) | flags

    def _start_nav(
        self,
        t_fix: int,
        lat_e7: int,
        lon_e7: int,
        alt_mm: int,
        vel: np.ndarray,
        vmask: tuple[bool, bool, bool],
        h_acc: float,
        v_acc: float,
        s_acc: float,
    ) -> None:
        cfg = self.cfg
        self.lat, self.lon, self.h = lat_e7 * 1e-7 * _DEG, lon_e7 * 1e-7 * _DEG, alt_mm * 1e-3
        self.v = vel.copy()
        if self.t_imu > t_fix:  # carried to the present with the newest sample's acceleration
            d = (self.t_imu - t_fix) * 1e-6
            a = self.rot.apply(self.f_last) + np.array([0.0, 0.0, gravity(self.cfg, self.lat, self.h)])
            self._move(vel * d + 0.5 * a * d * d)
            self.v = vel + a * d
        vv = [s_acc**2 if m else cfg.vel0_var_m2ps2 for m in vmask]
        yaw_var = self.yaw_var_align
        self.P = np.diag(
            [
                h_acc**2,
                h_acc**2,
                v_acc**2,
                *vv,
                cfg.att0_var_rad2,
                cfg.att0_var_rad2,
                yaw_var,
                *[self.bg0_var] * 3,
                *[cfg.accel_bias0_var_mps4] * 3,
            ]
        )
        if self.level_still:
            # the levelled tilt absorbed the accelerometer bias: [phi_N, phi_E] = M db_a
            g = gravity(cfg, self.lat, self.h)
            M = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]) @ self.rot.as_matrix() / g
            sb2 = cfg.accel_bias0_var_mps4
            self.P[PHI : PHI + 2, PHI : PHI + 2] = sb2 * M @ M.T + cfg.att_still_var_rad2 * np.eye(2)
            self.P[PHI : PHI + 2, BA : BA + 3] = sb2 * M
            self.P[BA : BA + 3, PHI : PHI + 2] = sb2 * M.T
        self.cov_dv, self.cov_acc_us, self.hist_acc_us = np.zeros(3), 0, 0
        self.hist.clear()
        self.nav = True
        self.rs, self.rs_v = RobustState(), RobustState()
        self.t_fuse_pos = self.t_fuse_vel = t_fix
        self.pos_out = self.vel_out = False

    def _cog_align(self, vel: np.ndarray, has_vne: bool, s_acc: float, rot_fix: Rotation) -> Rotation:
        """Course-over-ground yaw alignment when due; returns rot_fix turned likewise."""
        if self.cfg.yaw_source != YAW_COG or self.yaw_aligned or not has_vne:
            return rot_fix
        speed = math.hypot(vel[0], vel[1])
        if not speed > 0.0 or speed < self.cfg.cog_min_speed_mps:
            return rot_fix
        dpsi = wrap(math.atan2(vel[1], vel[0]) - yaw_of(rot_fix))
        self._yaw_turn(dpsi, self.cfg.cog_sigma0_rad**2 + (s_acc / speed) ** 2)
        return Rotation.from_rotvec([0.0, 0.0, dpsi]) * rot_fix

    # ---------------------------------------------------------------- magnetometer

    def mag(self, t_us: int, mag_b: Any) -> None:
        m = np.asarray(mag_b, float).reshape(3)
        if not np.all(np.isfinite(m)):
            raise NonFiniteError("mag: non-finite sample")
        cfg = self.cfg
        if cfg.yaw_source != YAW_MAG or not self.aligned:
            return
        if self.have_mag and (t_us < self.t_lastmag or t_us - self.t_lastmag < _us(cfg.mag_period_s)):
            return
        if self.yaw_aligned and not self.nav:
            return
        _, pitch, _ = self.rot.as_euler("ZYX")
        if not np.linalg.norm(m) > 0.0 or abs(pitch) > MAG_MAX_TILT:
            return
        psi_m = mag_heading(self.rot, m, cfg.mag_declination_rad)
        nu = wrap(psi_m - yaw_of(self.rot))
        if not self.yaw_aligned:
            self._yaw_turn(nu, cfg.mag_yaw_sigma_rad**2)
        else:
            dx, P, _ = kf_update(
                np.zeros(NX), self.P, yaw_row(self.rot.as_matrix())[None, :], [nu], [cfg.mag_yaw_sigma_rad**2]
            )
            self.P = P
            self._correct(dx)
        self.have_mag = True
        self.t_lastmag = int(t_us)

    # ---------------------------------------------------------------- output

    def output(self) -> dict[str, Any]:
        yaw, pitch, roll = self.rot.as_euler("ZYX")
        lost = not self.have_fix or (
            self.t_imu > self.t_lastfix and self.t_imu - self.t_lastfix > _us(self.cfg.gps_timeout_s)
        )
        flags = (
            self.flags
            | (FLAG_ALIGNED if self.aligned else 0)
            | (FLAG_HOME_SET if self.home else 0)
            | (FLAG_NAV if self.nav else 0)
            | (FLAG_YAW_ALIGNED if self.yaw_aligned else 0)
            | (FLAG_GPS_LOST if lost else 0)
        )
        q = self.rot.as_quat(scalar_first=True)
        return {
            "t_us": self.t_imu,
            "q_nb": q * (1.0 if q[0] >= 0 else -1.0),
            "euler_rad": np.array([roll, pitch, yaw]),
            "pos_ned_m": self.pos_ned() if self.nav else np.zeros(3),
            "vel_ned_mps": self.v.copy(),
            "gyro_bias_rps": self.bg.copy(),
            "accel_bias_mps2": self.ba.copy(),
            "p_diag": np.diag(self.P).copy(),
            "gps_t": self.last_gps_t,
            "gps_m": self.last_gps_m,
            "flags": flags,
            "n_gps_upd": self.n_upd,
            "n_gps_rej": self.n_rej,
            "n_gps_skip": self.n_skip,
        }


def replay(
    recording: Any,
    cfg: InsConfig | None = None,
    fix_records: Any = None,
    keys: tuple[str, ...] = (
        "q_nb",
        "euler_rad",
        "pos_ned_m",
        "vel_ned_mps",
        "gyro_bias_rps",
        "accel_bias_mps2",
        "p_diag",
        "flags",
    ),
) -> dict[str, np.ndarray]:
    """Run a recording in the event order of ALGORITHMS.md 9; one row of ``keys`` per IMU sample.

    ``fix_records``: the fixes as ``mca_gps_event_t``-like records (``core.gnss_to_c``), default
    built from ``recording.gnss`` with the same flag mapping. Statuses: 0 or the C code of the
    exception raised (``imu_status``, ``gps_status``, ``mag_status``)."""
    from mcahrs.golden.nav import status_code

    ins = Ins(cfg)
    imu, mag = recording.imu, recording.mag
    if fix_records is None:
        raise BadArgError("fix_records required (core.gnss_to_c(recording.gnss))")
    n = len(imu)
    out = {k: [] for k in keys}
    st = {
        "imu_status": np.zeros(n, np.uint8),
        "gps_status": np.zeros(len(fix_records), np.uint8),
        "mag_status": np.zeros(len(mag), np.uint8),
    }
    i = j = k = 0
    big = np.iinfo(np.int64).max
    while i < n or j < len(fix_records) or k < len(mag):
        ti = int(imu["t_us"][i]) if i < n else big
        tg = int(fix_records["t_rx_us"][j]) if j < len(fix_records) else big
        tm = int(mag["t_us"][k]) if k < len(mag) else big
        try:
            if i < n and ti <= tg and ti <= tm:
                kind = "imu_status"
                idx = i
                i += 1
                ins.imu(ti, imu["gyro_rps"][idx], imu["accel_mps2"][idx])
            elif j < len(fix_records) and tg <= tm:
                kind, idx = "gps_status", j
                j += 1
                ins.gps(fix_records["fix"][idx])
            else:
                kind, idx = "mag_status", k
                k += 1
                ins.mag(tm, mag["mag_b"][idx])
        except Exception as exc:  # noqa: BLE001 - every status is recorded, as the C replay does
            st[kind][idx] = status_code(exc)
        if kind == "imu_status":
            o = ins.output()
            for key in keys:
                out[key].append(o[key])
    res = {key: np.array(v) for key, v in out.items()}
    res.update(st)
    return res

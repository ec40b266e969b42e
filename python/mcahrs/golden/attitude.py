"""Attitude EKF: float64 golden model of DESIGN.md 4 and ALGORITHMS.md 7.

Nominal state: ``q`` (q_nb, Hamilton ``[w, x, y, z]``, body FRD -> NED, unit) and gyro bias
``b`` (rad/s). Error state ``dx = [dtheta (3), db (3)]`` with ``q_true = q (x) exp(dtheta)``
(attitude error in **body** axes), covariance ``P`` (6 x 6), multiplicative EKF.

Euler angles ZYX (DESIGN.md 2): roll ``phi`` in (-pi, pi], pitch ``theta`` in [-pi/2, pi/2],
yaw ``psi`` in (-pi, pi]; ``C_nb = R_z(psi) R_y(theta) R_x(phi)``.

Quaternions are plain tuples of 4 floats (cheap at IMU rate), matrices NumPy arrays.
Every function is pure: it returns new values and never modifies its arguments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

from mcahrs.errors import BadConfigError, NonFiniteError
from mcahrs.golden.robust import RobustConfig, RobustState, kf_update, robust_update

__all__ = [
    "AttConfig",
    "ObsResult",
    "Quat",
    "correct",
    "covariance_transition",
    "delay_transport",
    "euler_from_quat",
    "euler_rate_rows",
    "gravity_body",
    "initial_covariance",
    "mag_heading",
    "process_noise_diag",
    "propagate",
    "propagate_quat",
    "quat_exp",
    "quat_from_euler",
    "quat_mul",
    "quat_normalize",
    "dcm_from_quat",
    "roll_pitch_from_gravity",
    "roll_pitch_noise",
    "roll_pitch_update",
    "skew",
    "wrap_pi",
    "level_only",
    "yaw_align",
    "yaw_row",
    "yaw_update",
]

Quat = tuple[float, float, float, float]

_I3 = np.eye(3)


# --------------------------------------------------------------------------------------
# Configuration (ALGORITHMS.md 7 table)
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AttConfig:
    """Attitude EKF configuration. ``yaw0_var_rad2`` defaults to the no-yaw-source value."""

    gyro_noise_rps: float = 3e-3  # gyro white noise density, rad/s/sqrt(Hz)
    gyro_bias_rw_rps2: float = 1e-4  # gyro bias random walk density, rad/s^2/sqrt(Hz)
    att0_var_rad2: float = math.radians(2.0) ** 2  # initial roll/pitch variance
    yaw0_var_rad2: float = math.radians(180.0) ** 2  # initial yaw variance (30 deg)^2 with a yaw source
    bias0_var_rps2: float = math.radians(0.5) ** 2  # initial bias variance
    rp_sigma0_rad: float = 0.03  # base std of the roll/pitch observation
    rp_k_dev: float = 1.0  # std added per unit of | |g_b| - g | / g
    max_tilt_obs_rad: float = math.radians(80.0)  # no roll/pitch/yaw observation above this |pitch|
    # robust mode of the roll/pitch observations (ALGORITHMS.md 5: the attitude filter feeds it
    # each roll/pitch observation; yaw observations are plain)
    robust: RobustConfig = field(default_factory=RobustConfig)

    def validate(self) -> None:
        """Raise BadConfigError unless every value is finite and > 0, and max tilt < pi/2."""
        if not isinstance(self.robust, RobustConfig):
            raise BadConfigError(f"robust must be a RobustConfig, got {self.robust!r}")
        self.robust.validate()
        for f in fields(self):
            if f.name == "robust":
                continue
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise BadConfigError(f"{f.name} must be a number, got {v!r}")
            if not (math.isfinite(v) and v > 0.0):
                raise BadConfigError(f"{f.name} must be finite and > 0, got {v!r}")
        if not self.max_tilt_obs_rad < 0.5 * math.pi:
            raise BadConfigError("max_tilt_obs_rad must be < pi/2")


# --------------------------------------------------------------------------------------
# Rotation helpers
# --------------------------------------------------------------------------------------


def quat_mul(p: Quat, q: Quat) -> Quat:
    """Hamilton product p (x) q."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


def quat_exp(r: tuple[float, float, float] | np.ndarray) -> Quat:
    """Unit quaternion of rotation vector r: [cos(|r|/2), sin(|r|/2) r/|r|] (identity at r = 0)."""
    rx, ry, rz = float(r[0]), float(r[1]), float(r[2])
    n = math.sqrt(rx * rx + ry * ry + rz * rz)
    if n == 0.0:
        return (1.0, 0.0, 0.0, 0.0)
    k = math.sin(0.5 * n) / n
    return (math.cos(0.5 * n), k * rx, k * ry, k * rz)


def quat_normalize(q: Quat) -> Quat:
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def dcm_from_quat(q: Quat) -> np.ndarray:
    """C_nb (body -> NED) of a unit quaternion, 3 x 3."""
    w, x, y, z = q
    return np.array(
        [
            [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
            [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
            [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
        ]
    )


def euler_from_quat(q: Quat) -> tuple[float, float, float]:
    """(phi, theta, psi) ZYX of a unit quaternion; theta = -asin(C_nb[2, 0]) clamped to [-1, 1]."""
    w, x, y, z = q
    phi = math.atan2(2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y))
    s = 2.0 * (w * y - x * z)
    theta = math.asin(min(1.0, max(-1.0, s)))
    psi = math.atan2(2.0 * (x * y + w * z), 1.0 - 2.0 * (y * y + z * z))
    return phi, theta, psi


def quat_from_euler(phi: float, theta: float, psi: float) -> Quat:
    """q_nb of ZYX Euler angles: q = q_z(psi) (x) q_y(theta) (x) q_x(phi)."""
    cr, sr = math.cos(0.5 * phi), math.sin(0.5 * phi)
    cp, sp = math.cos(0.5 * theta), math.sin(0.5 * theta)
    cy, sy = math.cos(0.5 * psi), math.sin(0.5 * psi)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def skew(w: tuple[float, float, float] | np.ndarray) -> np.ndarray:
    """Cross-product matrix [w x]: skew(w) @ v = w x v."""
    wx, wy, wz = float(w[0]), float(w[1]), float(w[2])
    return np.array([[0.0, -wz, wy], [wz, 0.0, -wx], [-wy, wx, 0.0]])


def wrap_pi(a: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


def initial_covariance(cfg: AttConfig) -> np.ndarray:
    """P at alignment: diag(att0, att0, yaw0, bias0 x 3) (ALGORITHMS.md 8, IMU step 4)."""
    return np.diag([cfg.att0_var_rad2, cfg.att0_var_rad2, cfg.yaw0_var_rad2] + [cfg.bias0_var_rps2] * 3)


# --------------------------------------------------------------------------------------
# Propagation, every IMU sample (ALGORITHMS.md 7)
# --------------------------------------------------------------------------------------


def propagate_quat(q: Quat, w: tuple[float, float, float], dt: float) -> Quat:
    """Step 1: q = q (x) exp(w dt), normalised (w = gyro - bias)."""
    return quat_normalize(quat_mul(q, quat_exp((w[0] * dt, w[1] * dt, w[2] * dt))))


def covariance_transition(w: tuple[float, float, float], dt: float) -> np.ndarray:
    """Step 2: F = [[I - [w x] dt, -I dt], [0, I]] (6 x 6)."""
    F = np.eye(6)
    F[:3, :3] -= skew(w) * dt
    F[0, 3] = F[1, 4] = F[2, 5] = -dt
    return F


def process_noise_diag(dt: float, cfg: AttConfig, q_scale: float = 1.0) -> np.ndarray:
    """Step 2: diagonal of Qd = diag(q_scale gyro_noise^2 dt I3, gyro_bias_rw^2 dt I3): the AKF
    mode's scale (ALGORITHMS.md 5; 1 otherwise) multiplies the angle block only (section 7)."""
    qa = q_scale * cfg.gyro_noise_rps**2 * dt
    qb = cfg.gyro_bias_rw_rps2**2 * dt
    return np.array([qa, qa, qa, qb, qb, qb])


_DIAG6 = np.diag_indices(6)


def propagate(
    q: Quat,
    b: tuple[float, float, float],
    P: np.ndarray,
    gyro: tuple[float, float, float],
    dt: float,
    cfg: AttConfig,
    q_scale: float = 1.0,
) -> tuple[Quat, np.ndarray]:
    """One IMU sample (ALGORITHMS.md 7, propagation): returns (q, P); b is unchanged. ``q_scale``
    (the robust memory's AKF scale) multiplies Qd's angle block.

    Raises NonFiniteError when the result is not finite (inputs unchanged).
    """
    w = (gyro[0] - b[0], gyro[1] - b[1], gyro[2] - b[2])
    q_new = propagate_quat(q, w, dt)
    F = covariance_transition(w, dt)
    P_new = F @ P @ F.T
    P_new[_DIAG6] += process_noise_diag(dt, cfg, q_scale)
    P_new = 0.5 * (P_new + P_new.T)
    if not (all(math.isfinite(v) for v in q_new) and np.isfinite(P_new).all()):
        raise NonFiniteError("attitude propagation produced a non-finite state")
    return q_new, P_new


# --------------------------------------------------------------------------------------
# Error-state correction (ALGORITHMS.md 7)
# --------------------------------------------------------------------------------------


def correct(
    q: Quat, b: tuple[float, float, float], dx: np.ndarray
) -> tuple[Quat, tuple[float, float, float]]:
    """q = q (x) exp(dtheta), normalised; b = b + db. (dx is then 0; P is left as updated.)"""
    q_new = quat_normalize(quat_mul(q, quat_exp(dx[:3])))
    b_new = (b[0] + float(dx[3]), b[1] + float(dx[4]), b[2] + float(dx[5]))
    return q_new, b_new


# --------------------------------------------------------------------------------------
# Roll/pitch observation from compensated gravity (ALGORITHMS.md 7, DESIGN.md 4)
# --------------------------------------------------------------------------------------


def gravity_body(f_b: np.ndarray, a_n: np.ndarray, q_d: Quat) -> np.ndarray:
    """Step 1: a_b = C_nb(q_d)^T a_n, g_b = -(f - a_b)."""
    a_b = dcm_from_quat(q_d).T @ np.asarray(a_n, dtype=np.float64)
    return -(np.asarray(f_b, dtype=np.float64) - a_b)


def roll_pitch_from_gravity(g_b: np.ndarray) -> tuple[float, float]:
    """Step 2: phi_m = atan2(g_y, g_z), theta_m = atan2(-g_x, sqrt(g_y^2 + g_z^2))."""
    gx, gy, gz = float(g_b[0]), float(g_b[1]), float(g_b[2])
    return math.atan2(gy, gz), math.atan2(-gx, math.sqrt(gy * gy + gz * gz))


def euler_rate_rows(phi: float, theta: float) -> np.ndarray:
    """Step 5: E = [[1, s phi t theta, c phi t theta], [0, c phi, -s phi]] (d(phi, theta)/d dtheta)."""
    sp, cp, tt = math.sin(phi), math.cos(phi), math.tan(theta)
    return np.array([[1.0, sp * tt, cp * tt], [0.0, cp, -sp]])


def yaw_row(phi: float, theta: float) -> np.ndarray:
    """Yaw row [0, s phi / c theta, c phi / c theta] (d psi / d dtheta)."""
    ct = math.cos(theta)
    return np.array([0.0, math.sin(phi) / ct, math.cos(phi) / ct])


def delay_transport(q_d: Quat, q: Quat) -> np.ndarray:
    """Step 5: C_D = C_nb(q_d)^T C_nb(q): current body axes to body axes at t_d."""
    return dcm_from_quat(q_d).T @ dcm_from_quat(q)


def roll_pitch_noise(G: float, g: float, r_acc: float, cfg: AttConfig) -> float:
    """Step 6: r = rp_sigma0^2 + (rp_k_dev |G - g| / g)^2 + r_acc (rad^2)."""
    return cfg.rp_sigma0_rad**2 + (cfg.rp_k_dev * abs(G - g) / g) ** 2 + r_acc


@dataclass(frozen=True)
class ObsResult:
    """Outcome of an observation. made False: skipped for ``reason``, q/b/P are the inputs."""

    made: bool
    reason: str  # "" when made; "grav_rejected", "tilt" otherwise
    q: Quat
    b: tuple[float, float, float]
    P: np.ndarray
    T: float = math.nan
    nu: np.ndarray | None = None
    rejected: bool = False  # the robust mode rejected the update (made, q/b/P unchanged)


def level_only(q: Quat, dtheta: np.ndarray) -> np.ndarray:
    """Step 7: dtheta - (u . dtheta) u, u = C_nb(q)^T [0, 0, 1] (the NED vertical in body axes).

    Roll and pitch carry no yaw information: the vertical component of a roll/pitch correction
    would only be cross-covariance leaking into yaw.
    """
    u = dcm_from_quat(q)[2, :]  # row 2 of C_nb = C_nb^T e_down
    d = np.asarray(dtheta, dtype=np.float64)
    return d - float(u @ d) * u


def _update_and_correct(
    q: Quat,
    b: tuple[float, float, float],
    P: np.ndarray,
    H: np.ndarray,
    nu: np.ndarray,
    r: float,
    level: bool = False,
    robust: RobustConfig | None = None,
    state: RobustState | None = None,
) -> ObsResult:
    """Section-1 update of dx from 0 with z = nu, then the error-state correction.

    level: remove the vertical component of dtheta first (roll/pitch observations, step 7).
    P is the section-1 result either way. With ``robust`` and ``state`` the update is the
    section-5 one in that mode (``state`` changed in place on success); a rejection is made with
    q, b, P unchanged. Raises SingularError / NonFiniteError (inputs unchanged).
    """
    m = H.shape[0]
    if robust is not None and state is not None:
        dx, P_new, report = robust_update(np.zeros(6), P, H, nu, np.full(m, r), robust, state)
        if report.rejected:
            return ObsResult(True, "", q, b, P, report.T, report.nu, rejected=True)
    else:
        dx, P_new, report = kf_update(np.zeros(6), P, H, nu, np.full(m, r))
    if level:
        dx = np.concatenate([level_only(q, dx[:3]), dx[3:]])
    q_new, b_new = correct(q, b, dx)
    if not (all(math.isfinite(v) for v in q_new) and all(math.isfinite(v) for v in b_new)):
        raise NonFiniteError("attitude correction produced a non-finite state")
    return ObsResult(True, "", q_new, b_new, P_new, report.T, report.nu)


def roll_pitch_update(
    q: Quat,
    b: tuple[float, float, float],
    P: np.ndarray,
    f_b: np.ndarray,
    a_n: np.ndarray,
    q_d: Quat,
    r_acc: float,
    g: float,
    cfg: AttConfig,
    state: RobustState | None = None,
) -> ObsResult:
    """Roll/pitch observation at t_d (attitude q_d) carried to now (attitude q), steps 1-7.

    f_b: mean specific force at t_d (body); a_n: maneuver acceleration (NED); r_acc: extra
    variance (rad^2); g: gravity magnitude. ``state``: the attitude filter's robust memory; the
    update is then made in ``cfg.robust``'s mode (ALGORITHMS.md 5), plain without it. Raises
    SingularError / NonFiniteError.
    """
    g_b = gravity_body(f_b, a_n, q_d)  # step 1
    G = float(np.linalg.norm(g_b))
    if not (0.5 * g <= G <= 1.5 * g):
        return ObsResult(False, "grav_rejected", q, b, P)
    phi_m, theta_m = roll_pitch_from_gravity(g_b)  # step 2
    phi_d, theta_d, _ = euler_from_quat(q_d)  # step 3
    if abs(theta_d) > cfg.max_tilt_obs_rad:
        return ObsResult(False, "tilt", q, b, P)
    nu = np.array([wrap_pi(phi_m - phi_d), theta_m - theta_d])  # step 4
    H = np.zeros((2, 6))  # step 5
    H[:, :3] = euler_rate_rows(phi_d, theta_d) @ delay_transport(q_d, q)
    r = roll_pitch_noise(G, g, r_acc, cfg)  # step 6
    robust = cfg.robust if state is not None else None
    return _update_and_correct(q, b, P, H, nu, r, level=True, robust=robust, state=state)  # step 7


# --------------------------------------------------------------------------------------
# Yaw observations (ALGORITHMS.md 7)
# --------------------------------------------------------------------------------------


def mag_heading(q: Quat, m_b: np.ndarray, declination_rad: float) -> float:
    """psi_m = atan2(-m_l.y, m_l.x) + declination, m_l = C_nb(q_level) m_b, q_level = (phi, theta, 0)."""
    phi, theta, _ = euler_from_quat(q)
    m_l = dcm_from_quat(quat_from_euler(phi, theta, 0.0)) @ np.asarray(m_b, dtype=np.float64)
    return math.atan2(-float(m_l[1]), float(m_l[0])) + declination_rad


def yaw_update(
    q: Quat,
    b: tuple[float, float, float],
    P: np.ndarray,
    psi_m: float,
    sigma2: float,
    q_d: Quat,
    cfg: AttConfig,
) -> ObsResult:
    """Yaw observation psi_m (variance sigma2) of the attitude q_d (q_d = q when not delayed).

    nu = wrap(psi_m - psi(q_d)), H = [yaw_row(q_d) C_D, 0 0 0]; skipped ("tilt") when
    |theta(q_d)| > max_tilt_obs. Raises SingularError / NonFiniteError.
    """
    phi_d, theta_d, psi_d = euler_from_quat(q_d)
    if abs(theta_d) > cfg.max_tilt_obs_rad:
        return ObsResult(False, "tilt", q, b, P)
    nu = np.array([wrap_pi(psi_m - psi_d)])
    H = np.zeros((1, 6))
    H[0, :3] = yaw_row(phi_d, theta_d) @ delay_transport(q_d, q)
    return _update_and_correct(q, b, P, H, nu, sigma2)


def yaw_align(q: Quat, P: np.ndarray, psi_m: float, sigma2: float) -> tuple[Quat, np.ndarray]:
    """Yaw alignment on the first yaw observation (ALGORITHMS.md 7): returns (q, P).

    q = quaternion of (phi, theta, psi_m), phi and theta of the current q; row and column 2 of
    P zeroed and P[2][2] = sigma2 (body z taken as the yaw axis, a small-tilt approximation).
    """
    phi, theta, _ = euler_from_quat(q)
    q_new = quat_from_euler(phi, theta, psi_m)
    P_new = np.array(P, dtype=np.float64)
    P_new[2, :] = 0.0
    P_new[:, 2] = 0.0
    P_new[2, 2] = sigma2
    return q_new, P_new

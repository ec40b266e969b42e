"""Truth trajectories: motion models, vehicle attitude rules, and the kinematic truth arrays.

Frames and conventions (DESIGN.md 2): NED navigation frame on the tangent plane at home
(flat earth, constant gravity ``g_n = [0, 0, +g]``), FRD body frame, ZYX Euler angles
(roll phi, pitch theta, yaw psi), Hamilton quaternion ``q_nb = qz(psi) qy(theta) qx(phi)``
rotating body vectors into NED. Truth rate ``omega_b`` is the body rate relative to NED.

How the truth stays self-consistent
-----------------------------------
* Velocity, acceleration and jerk come from :class:`~mcahrs.sim.profiles.Channel` profiles
  and their *exact* derivatives (analytic chain rule, no differencing).
* Position is the integral of that velocity, by 3-point Gauss-Legendre quadrature on each
  IMU interval (exact for degree-5 polynomials; the profiles are C3, so the error per
  interval is ~dt^5 times a jump of the 4th derivative: below 1e-10 m at 400 Hz).
* Euler angles and their rates come analytically from velocity, acceleration and jerk
  (vehicle rules below); the body rate is the exact map from Euler rates
  ``p = phi' - psi' sin(theta)``, ``q = theta' cos(phi) + psi' sin(phi) cos(theta)``,
  ``r = -theta' sin(phi) + psi' cos(phi) cos(theta)``.

Vehicle attitude rules
----------------------
* ``car``: yaw = heading of travel, pitch = road grade (flight-path angle), roll 0; optional
  suspension: ``pitch += k_pitch * a_long`` (squat when accelerating, dive when braking),
  ``roll = -k_roll * a_lat`` (body leans out of the turn). Defaults zero.
* ``fixedwing``: nose along the velocity (yaw = course, pitch = flight-path angle, zero angle
  of attack and sideslip) and roll chosen so the body-y specific force is zero (coordinated
  flight). In a level turn this is ``tan(phi) = V psi' / g``.
* ``multirotor``: thrust along body -z produces the whole specific force,
  ``a_n - g_n = C_nb [0, 0, -T/m]``; yaw is a free profile.
* ``fixed``: constant Euler angles (static tests).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mcahrs.sim.profiles import Channel

__all__ = [
    "AxisMotion",
    "PathMotion",
    "Truth",
    "build_truth",
    "euler_rates_to_body",
    "euler_to_quat",
    "quat_conj",
    "quat_mul",
    "quat_rotate",
    "quat_to_euler",
]

# 3-point Gauss-Legendre nodes on [-1, 1] and weights.
_GL_X = np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_GL_W = np.array([5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0])


# --------------------------------------------------------------------------- rotations
def euler_to_quat(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """ZYX Euler angles (rad) to Hamilton ``q_nb = qz(yaw) qy(pitch) qx(roll)``, shape (..., 4)."""
    cr, sr = np.cos(0.5 * roll), np.sin(0.5 * roll)
    cp, sp = np.cos(0.5 * pitch), np.sin(0.5 * pitch)
    cy, sy = np.cos(0.5 * yaw), np.sin(0.5 * yaw)
    return np.stack(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ],
        axis=-1,
    )


def quat_to_euler(q: np.ndarray) -> np.ndarray:
    """``q_nb`` [w, x, y, z] to ZYX Euler (roll, pitch, yaw) in rad; yaw in (-pi, pi]."""
    w, x, y, z = np.moveaxis(np.asarray(q, np.float64), -1, 0)
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=-1)


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugate (inverse of a unit quaternion)."""
    return np.asarray(q) * np.array([1.0, -1.0, -1.0, -1.0])


def quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` (broadcasting over leading axes)."""
    pw, px, py, pz = np.moveaxis(np.asarray(p, np.float64), -1, 0)
    qw, qx, qy, qz = np.moveaxis(np.asarray(q, np.float64), -1, 0)
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` by unit quaternions ``q``: ``C(q) v`` (``q_nb``: body -> NED)."""
    q = np.asarray(q, np.float64)
    v = np.asarray(v, np.float64)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def euler_rates_to_body(euler: np.ndarray, euler_dot: np.ndarray) -> np.ndarray:
    """Body rate (p, q, r) from ZYX Euler angles (roll, pitch, yaw) and their time derivatives."""
    phi, theta = euler[:, 0], euler[:, 1]
    dphi, dtheta, dpsi = euler_dot[:, 0], euler_dot[:, 1], euler_dot[:, 2]
    sf, cf = np.sin(phi), np.cos(phi)
    st, ct = np.sin(theta), np.cos(theta)
    return np.stack([dphi - dpsi * st, dtheta * cf + dpsi * sf * ct, -dtheta * sf + dpsi * cf * ct], axis=1)


# --------------------------------------------------------------------------- motions
@dataclass
class PathMotion:
    """Speed / course / flight-path-angle motion (car, fixed-wing).

    ``v_n = V [cos(gamma) cos(psi), cos(gamma) sin(psi), -sin(gamma)]``. ``speed`` and
    ``course`` are order-1 channels (their steps are acceleration and turn-rate pulses);
    ``gamma`` is order 0 (smooth steps of the flight-path / road-grade angle).
    """

    speed: Channel = field(default_factory=lambda: Channel(1))
    course: Channel = field(default_factory=lambda: Channel(1))
    gamma: Channel = field(default_factory=lambda: Channel(0))

    def velocity(self, t: np.ndarray) -> np.ndarray:
        v, psi, gam = self.speed.eval(t), self.course.eval(t), self.gamma.eval(t)
        cg = np.cos(gam)
        return np.stack([v * cg * np.cos(psi), v * cg * np.sin(psi), -v * np.sin(gam)], axis=1)

    def kinematics(self, t: np.ndarray) -> dict[str, np.ndarray]:
        v, v1, v2 = (self.speed.eval(t, k) for k in range(3))
        psi, p1, p2 = (self.course.eval(t, k) for k in range(3))
        gam, g1, g2 = (self.gamma.eval(t, k) for k in range(3))
        cp, sp, cg, sg = np.cos(psi), np.sin(psi), np.cos(gam), np.sin(gam)
        z = np.zeros_like(t)
        u = np.stack([cg * cp, cg * sp, -sg], axis=1)
        u_p = np.stack([-cg * sp, cg * cp, z], axis=1)  # du/dpsi
        u_g = np.stack([-sg * cp, -sg * sp, -cg], axis=1)  # du/dgamma
        u_pp = np.stack([-cg * cp, -cg * sp, z], axis=1)
        u_pg = np.stack([sg * sp, -sg * cp, z], axis=1)
        c = lambda a: a[:, None]  # noqa: E731
        du = c(p1) * u_p + c(g1) * u_g
        ddu = c(p2) * u_p + c(g2) * u_g + c(p1 * p1) * u_pp + c(2.0 * p1 * g1) * u_pg - c(g1 * g1) * u
        return {
            "vel": c(v) * u,
            "acc": c(v1) * u + c(v) * du,
            "jerk": c(v2) * u + c(2.0 * v1) * du + c(v) * ddu,
            "yaw": psi,
            "yaw_d": p1,
            "gamma": gam,
            "gamma_d": g1,
        }


@dataclass
class AxisMotion:
    """Independent N/E/D velocity channels (order 1: steps are acceleration pulses) and a yaw channel
    (order 1: steps are yaw-rate pulses). Used for multirotors and static cases."""

    vel: tuple[Channel, Channel, Channel] = field(
        default_factory=lambda: (Channel(1), Channel(1), Channel(1))
    )
    yaw: Channel = field(default_factory=lambda: Channel(1))

    def velocity(self, t: np.ndarray) -> np.ndarray:
        return np.stack([ch.eval(t) for ch in self.vel], axis=1)

    def kinematics(self, t: np.ndarray) -> dict[str, np.ndarray]:
        return {
            "vel": self.velocity(t),
            "acc": np.stack([ch.eval(t, 1) for ch in self.vel], axis=1),
            "jerk": np.stack([ch.eval(t, 2) for ch in self.vel], axis=1),
            "yaw": self.yaw.eval(t),
            "yaw_d": self.yaw.eval(t, 1),
        }


# --------------------------------------------------------------------------- attitude rules
def _rz_t(yaw: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``Rz(-yaw) v``: an NED vector expressed in the heading frame (x along yaw, level)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([c * v[:, 0] + s * v[:, 1], -s * v[:, 0] + c * v[:, 1], v[:, 2]], axis=1)


def _heading_frame(kin: dict, g: float) -> tuple[np.ndarray, np.ndarray]:
    """Specific force ``w = Rz(-yaw)(a - g_n)`` in the heading frame and its time derivative."""
    yaw, yaw_d = kin["yaw"], kin["yaw_d"]
    f = kin["acc"] - np.array([0.0, 0.0, g])
    w = _rz_t(yaw, f)
    w_d = _rz_t(yaw, kin["jerk"]) + yaw_d[:, None] * np.stack([w[:, 1], -w[:, 0], np.zeros_like(yaw)], axis=1)
    return w, w_d


def _rule_car(
    kin: dict, g: float, k_pitch: float = 0.0, k_roll: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    a_h, a_h_d = _heading_frame(kin, 0.0)  # kinematic acceleration in the heading frame
    pitch = kin["gamma"] + k_pitch * a_h[:, 0]
    pitch_d = kin["gamma_d"] + k_pitch * a_h_d[:, 0]
    roll = -k_roll * a_h[:, 1]
    roll_d = -k_roll * a_h_d[:, 1]
    return (np.stack([roll, pitch, kin["yaw"]], axis=1), np.stack([roll_d, pitch_d, kin["yaw_d"]], axis=1))


def _rule_fixedwing(kin: dict, g: float) -> tuple[np.ndarray, np.ndarray]:
    # Body y axis: C_nb[:, 1] = Rz(psi) [sin(theta) sin(phi), cos(phi), cos(theta) sin(phi)]. Coordinated
    # flight: f . y_b = sin(phi) A + cos(phi) B = 0, with w = Rz(-psi) f, A = sin(theta) w_x + cos(theta) w_z
    # (f along the un-rolled body z) and B = w_y (f along the un-rolled body y). tan(phi) = -B / A.
    theta, theta_d = kin["gamma"], kin["gamma_d"]
    w, w_d = _heading_frame(kin, g)
    st, ct = np.sin(theta), np.cos(theta)
    a = st * w[:, 0] + ct * w[:, 2]
    a_d = st * w_d[:, 0] + ct * w_d[:, 2] + theta_d * (ct * w[:, 0] - st * w[:, 2])
    b = w[:, 1]
    b_d = w_d[:, 1]
    roll = np.arctan2(b, -a)  # a < 0 in normal (upright) flight; level turn: tan(phi) = a_lat / g
    roll_d = (b * a_d - a * b_d) / (a * a + b * b)
    return (np.stack([roll, theta, kin["yaw"]], axis=1), np.stack([roll_d, theta_d, kin["yaw_d"]], axis=1))


def _rule_multirotor(kin: dict, g: float) -> tuple[np.ndarray, np.ndarray]:
    # Body z axis along -f (thrust along -z). In the heading frame z' = [cos phi sin theta,
    # -sin phi, cos phi cos theta] = -w/|w|; the common positive scale drops out of atan2.
    w, w_d = _heading_frame(kin, g)
    wx, wy, wz = w[:, 0], w[:, 1], w[:, 2]
    wx_d, wy_d, wz_d = w_d[:, 0], w_d[:, 1], w_d[:, 2]
    h2 = wx * wx + wz * wz
    h = np.sqrt(h2)
    pitch = np.arctan2(-wx, -wz)
    pitch_d = (wz * wx_d - wx * wz_d) / h2
    roll = np.arctan2(wy, h)
    h_d = (wx * wx_d + wz * wz_d) / h
    roll_d = (h * wy_d - wy * h_d) / (h2 + wy * wy)
    return (np.stack([roll, pitch, kin["yaw"]], axis=1), np.stack([roll_d, pitch_d, kin["yaw_d"]], axis=1))


def _rule_fixed(kin: dict, g: float, euler_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)):
    n = kin["vel"].shape[0]
    return np.tile(np.asarray(euler_rad, np.float64), (n, 1)), np.zeros((n, 3))


RULES = {"car": _rule_car, "fixedwing": _rule_fixedwing, "multirotor": _rule_multirotor, "fixed": _rule_fixed}


# --------------------------------------------------------------------------- truth
@dataclass
class Truth:
    """Kinematic truth at the IMU sample times (arrays of length N; vectors (N, 3))."""

    t_us: np.ndarray  # int64, IMU clock
    pos_ned_m: np.ndarray  # relative to home, tangent plane
    vel_ned_mps: np.ndarray
    acc_ned_mps2: np.ndarray  # kinematic acceleration (not specific force)
    q_nb: np.ndarray  # (N, 4) Hamilton [w, x, y, z], body FRD -> NED, w >= 0
    euler_rad: np.ndarray  # (N, 3) roll, pitch, yaw (yaw in (-pi, pi])
    omega_b_rps: np.ndarray  # body rate w.r.t. NED, FRD
    specific_force_b_mps2: np.ndarray  # C_n^b (a_n - g_n): what an ideal accelerometer reads
    gyro_bias_rps: np.ndarray  # true total gyro bias (constant + random walk + Gauss-Markov)
    accel_bias_mps2: np.ndarray  # true total accelerometer bias

    @property
    def t_s(self) -> np.ndarray:
        """Time in seconds (float64; for plotting and tests, not for storage)."""
        return self.t_us * 1e-6

    def index_of(self, t_us: np.ndarray) -> np.ndarray:
        """Indices of the given sample times (they must be IMU sample times)."""
        t_us = np.asarray(t_us, np.int64)
        idx = np.searchsorted(self.t_us, t_us)
        if np.any(idx >= self.t_us.size) or np.any(self.t_us[np.minimum(idx, self.t_us.size - 1)] != t_us):
            raise ValueError("times are not IMU sample times")
        return idx


def _integrate_position(motion, t: np.ndarray, pos0: np.ndarray) -> np.ndarray:
    """Position at ``t`` by Gauss-Legendre quadrature of ``motion.velocity`` on each interval."""
    h = np.diff(t)
    inc = np.zeros((t.size - 1, 3))
    for x, w in zip(_GL_X, _GL_W, strict=True):
        inc += (0.5 * w * h)[:, None] * motion.velocity(t[:-1] + 0.5 * (1.0 + x) * h)
    pos = np.empty((t.size, 3))
    pos[0] = pos0
    np.cumsum(inc, axis=0, out=pos[1:])
    pos[1:] += pos0
    return pos


def build_truth(
    motion: PathMotion | AxisMotion,
    rule: str,
    t_us: np.ndarray,
    g: float,
    pos0_ned_m,
    rule_kw: dict | None = None,
) -> Truth:
    """Evaluate a motion and a vehicle attitude rule at ``t_us``. Biases are left as zeros."""
    t = np.asarray(t_us, np.int64) * 1e-6
    kin = motion.kinematics(t)
    euler, euler_dot = RULES[rule](kin, g, **(rule_kw or {}))
    omega_b = euler_rates_to_body(euler, euler_dot)
    yaw = np.mod(euler[:, 2] + np.pi, 2.0 * np.pi) - np.pi
    yaw[yaw == -np.pi] = np.pi
    euler[:, 2] = yaw
    q = euler_to_quat(euler[:, 0], euler[:, 1], yaw)
    q *= np.where(q[:, :1] < 0.0, -1.0, 1.0)
    f_n = kin["acc"] - np.array([0.0, 0.0, g])
    f_b = quat_rotate(quat_conj(q), f_n)
    n = t.size
    return Truth(
        t_us=np.asarray(t_us, np.int64),
        pos_ned_m=_integrate_position(motion, t, np.asarray(pos0_ned_m, np.float64)),
        vel_ned_mps=kin["vel"],
        acc_ned_mps2=kin["acc"],
        q_nb=q,
        euler_rad=euler,
        omega_b_rps=omega_b,
        specific_force_b_mps2=f_b,
        gyro_bias_rps=np.zeros((n, 3)),
        accel_bias_mps2=np.zeros((n, 3)),
    )

"""Current-statistical (CS) maneuver filter: float64 golden model of DESIGN.md 3 and
ALGORITHMS.md 2-3.

One 5-state Kalman filter per NED axis, state ``x = [p, v, a, eps_p, eps_v]``.
Mean step: constant acceleration (``Phi1``, eq. 17). Covariance step: the exact CS
transition ``Phi`` and the exact Singer process noise ``Q``.

Small ``x = alpha T``
---------------------
``Phi13``, ``Phi23`` and the Singer block ``q11..q33`` written as in DESIGN.md 3 cancel
catastrophically when ``x = alpha T`` is small, in float64 too (measured against 50-digit
mpmath: the exact-form ``q11`` is wrong by 6e-11 relative at x = 0.1 and by 1e-2 at
x = 1e-3). Below ``SERIES_THRESHOLD`` every one of them is evaluated as a Taylor series in
``x`` instead; at and above it, the D3 formulas are used (with ``expm1`` for ``1 - e`` and
``1 - e^2``, which is free accuracy).

Each Singer entry is ``Q_ij = q T^(7-i-j) g_ij(x)`` (i, j = 1..3). ``Q = q int_0^T c c^T ds``
with ``c(s)`` the third column of ``Phi(s)``, ``c_k(s) = sum_n (-alpha)^n s^(n+3-k)/(n+3-k)!``,
and integrating the product term by term gives

    g_ij(x) = sum_N  S(M, a, b) / (M! (M + 1)) * (-x)^N,
    a = 3 - i, b = 3 - j, M = N + a + b,
    S(M, a, b) = 2^M - sum_{k<a} binom(M, k) - sum_{k<b} binom(M, k).

The coefficients are built in exact integer arithmetic at import (N = 0 gives the paper's
small-alpha T matrix: 1/20, 1/8, 1/6, 1/3, 1/2, 1). Likewise
``Phi13 = T^2 sum_n (-x)^n/(n+2)!``; ``Phi23 = -T expm1(-x)/x`` needs no series.

Threshold and term count: ``SERIES_THRESHOLD = 2.0``, ``SERIES_TERMS = 32`` (measured
against 50-digit mpmath; x = alpha T):

* At and above the threshold the exact forms lose about eps * (largest term) / (result).
  The worst entry, q11, is within 3.7e-16 relative for x >= 2, but 1.6e-15 at x = 1.5,
  5e-15 at 1 and 4e-14 at 0.5, growing like x^-5 (q11 ~ x^5 / 10 is left after the O(1)
  terms cancel).
* Below it the series alternate in sign, so Horner's rule loses at most
  g(-x)/g(x) <= e^(2x) ulps (<= 55 at x = 2; measured <= 1.8e-15, about 8 ulps). The
  slowest series is q33's, (2x)^N / (N! (N + 1)); with 32 terms the first omitted one at
  x = 2 is 4^32 / (32! 33) ~ 2e-18 absolute, ~1e-17 relative (30 terms would leave ~6e-16).
* Result: every entry within 1.8e-15 relative of the true value for x in [1e-7, 50]; the
  two branches differ by 9e-16 relative at the switch. A lower threshold trades series
  rounding for exact-form cancellation, which grows faster (x0 = 1, 24 terms: worst
  6.8e-15; x0 = 0.75: 2.4e-14); a higher one needs more terms and rounds worse like e^(2 x0).
"""

from __future__ import annotations

import copy
import math
import numbers
import operator
from dataclasses import dataclass, field, fields, replace
from fractions import Fraction
from typing import NamedTuple

import numpy as np

from mcahrs.errors import (
    BadArgError,
    BadConfigError,
    BadDtError,
    BadMaskError,
    McaError,
    NonFiniteError,
    NotInitError,
    SingularError,
)
from mcahrs.golden.robust import (
    FUZZY_ROWS,
    RobustConfig,
    RobustReport,
    RobustState,
    UpdateReport,
    fuzzy_rows_failed,
    kf_update,
    robust_update,
)

__all__ = [
    "MASK_POS",
    "MASK_VEL",
    "SERIES_TERMS",
    "SERIES_THRESHOLD",
    "AxisInc",
    "Cs3",
    "CsAxis",
    "CsAxisConfig",
    "UpdateReport",
    "cs_mean_transition",
    "cs_process_noise",
    "cs_transition",
    "maneuver_variance",
    "singer_q",
]

SERIES_THRESHOLD = 2.0  # alpha T below this: Taylor series (see module docstring)
SERIES_TERMS = 32  # terms kept in every series below the threshold

MASK_POS = 0x1  # update mask bit 0: position measured
MASK_VEL = 0x2  # update mask bit 1: velocity measured
_MASK_KNOWN = MASK_POS | MASK_VEL

H_POS = np.array([1.0, 0.0, 0.0, 1.0, 0.0])  # ALGORITHMS.md 2: z_p = p + eps_p
H_VEL = np.array([0.0, 1.0, 0.0, 0.0, 1.0])  # z_v = v + eps_v

N_STATE = 5


# --------------------------------------------------------------------------------------
# Series coefficients (exact integers -> float64 once, at import)
# --------------------------------------------------------------------------------------


def _singer_coefficient(i: int, j: int, n: int) -> Fraction:
    """Coefficient of (-x)^n in g_ij(x), i, j in 1..3 (module docstring)."""
    a, b = 3 - i, 3 - j
    m = n + a + b
    s = 2**m - sum(math.comb(m, k) for k in range(a)) - sum(math.comb(m, k) for k in range(b))
    return Fraction(s, math.factorial(m) * (m + 1))


# _SINGER_SERIES[i, j, n]: coefficient of (-x)^n of g_(i+1)(j+1).
_SINGER_SERIES = np.array(
    [
        [[float(_singer_coefficient(i, j, n)) for n in range(SERIES_TERMS)] for j in (1, 2, 3)]
        for i in (1, 2, 3)
    ]
)
# Coefficients of (-x)^n in (x - 1 + e^-x)/x^2 = Phi13 / T^2.
_PHI13_SERIES = np.array([1.0 / math.factorial(n + 2) for n in range(SERIES_TERMS)])
# Power of T in Q_ij = q T^(7-i-j) g_ij(alpha T).
_SINGER_T_POWER = np.array([[5, 4, 3], [4, 3, 2], [3, 2, 1]])


def _alternating_series(coefficients: np.ndarray, x: float) -> np.ndarray:
    """sum_n coefficients[..., n] (-x)^n by Horner's rule (vectorised over leading axes)."""
    y = -x
    acc = np.zeros(coefficients.shape[:-1])
    for c in np.moveaxis(coefficients, -1, 0)[::-1]:  # highest power first
        acc = acc * y + c
    return acc


# --------------------------------------------------------------------------------------
# Equation blocks of DESIGN.md 3
# --------------------------------------------------------------------------------------


def _check_rate_and_step(alpha: float, T: float) -> tuple[float, float]:
    alpha, T = float(alpha), float(T)
    if not (math.isfinite(alpha) and math.isfinite(T)):
        raise NonFiniteError("alpha and T must be finite")
    if alpha < 0.0 or T < 0.0:
        raise BadArgError("alpha and T must be >= 0")
    return alpha, T


def _phi13_normalised(x: float) -> float:
    """(x - 1 + e^-x)/x^2, so that Phi13 = T^2 * this (-> 1/2 as x -> 0)."""
    if x < SERIES_THRESHOLD:
        return float(_alternating_series(_PHI13_SERIES, x))
    return (x + math.expm1(-x)) / (x * x)


def _phi23_normalised(x: float) -> float:
    """(1 - e^-x)/x, so that Phi23 = T * this (-> 1 as x -> 0). expm1 has no cancellation."""
    if x == 0.0:
        return 1.0
    return -math.expm1(-x) / x


def cs_transition(alpha: float, beta: float, gamma: float, T: float) -> np.ndarray:
    """Exact CS transition Phi over T (DESIGN.md 3), 5 x 5.

    Phi13 = (alpha T - 1 + e)/alpha^2 and Phi23 = (1 - e)/alpha, e = exp(-alpha T), evaluated
    without cancellation (ALGORITHMS.md 2, predict step 5).
    """
    alpha, T = _check_rate_and_step(alpha, T)
    x = alpha * T
    phi = np.zeros((N_STATE, N_STATE))
    phi[0, 0] = 1.0
    phi[0, 1] = T
    phi[0, 2] = T * T * _phi13_normalised(x)
    phi[1, 1] = 1.0
    phi[1, 2] = T * _phi23_normalised(x)
    phi[2, 2] = math.exp(-x)
    phi[3, 3] = math.exp(-float(beta) * T)
    phi[4, 4] = math.exp(-float(gamma) * T)
    return phi


def cs_mean_transition(beta: float, gamma: float, T: float) -> np.ndarray:
    """Phi1 of eq. 17 (DESIGN.md 3): the mean step, constant acceleration, 5 x 5."""
    T = float(T)
    phi1 = np.zeros((N_STATE, N_STATE))
    phi1[0, :3] = [1.0, T, 0.5 * T * T]
    phi1[1, 1:3] = [1.0, T]
    phi1[2, 2] = 1.0
    phi1[3, 3] = math.exp(-float(beta) * T)
    phi1[4, 4] = math.exp(-float(gamma) * T)
    return phi1


def _singer_g_series(x: float) -> np.ndarray:
    """g_ij(x) (module docstring) by the Taylor series; used for 0 <= x < SERIES_THRESHOLD."""
    return _alternating_series(_SINGER_SERIES, x)


def _singer_g_exact(x: float) -> np.ndarray:
    """g_ij(x) = D3 bracket_ij / (2 x^(7-i-j)); used for x >= SERIES_THRESHOLD."""
    e = math.exp(-x)
    em = -math.expm1(-x)  # 1 - e
    em2 = -math.expm1(-2.0 * x)  # 1 - e^2
    x2, x3 = x * x, x * x * x
    b11 = em2 + 2.0 * x + 2.0 * x3 / 3.0 - 2.0 * x2 - 4.0 * x * e
    b12 = em * em + 2.0 * x * e - 2.0 * x + x2  # e^2 + 1 - 2e = (1 - e)^2
    b13 = em2 - 2.0 * x * e
    b22 = 4.0 * e - 3.0 - e * e + 2.0 * x
    b23 = em * em
    b33 = em2
    brackets = np.array([[b11, b12, b13], [b12, b22, b23], [b13, b23, b33]])
    return brackets / (2.0 * x**_SINGER_T_POWER)


def singer_q(alpha: float, T: float, s2: float) -> np.ndarray:
    """Exact Singer process noise of (p, v, a) over T, 3 x 3 (DESIGN.md 3, q11..q33).

    q = 2 alpha s2 is the white-noise density of w_a. Below ``SERIES_THRESHOLD`` in
    alpha T the entries come from their Taylor series, above it from the D3 formulas;
    either way accurate to ~2e-15 relative for alpha T in [1e-7, 50] (module docstring).
    """
    alpha, T = _check_rate_and_step(alpha, T)
    s2 = float(s2)
    if not math.isfinite(s2):
        raise NonFiniteError("s2 must be finite")
    if s2 < 0.0:
        raise BadArgError("s2 must be >= 0")
    x = alpha * T
    g = _singer_g_series(x) if x < SERIES_THRESHOLD else _singer_g_exact(x)
    q = 2.0 * alpha * s2
    return q * g * T**_SINGER_T_POWER


def cs_process_noise(
    alpha: float, beta: float, gamma: float, T: float, s2: float, sigma_p: float, sigma_v: float
) -> np.ndarray:
    """Block-diagonal Q over T, 5 x 5 (ALGORITHMS.md 2, predict step 5).

    Singer block with q = 2 alpha s2; q44 = sigma_p^2 (1 - exp(-2 beta T)),
    q55 = sigma_v^2 (1 - exp(-2 gamma T)).
    """
    Q = np.zeros((N_STATE, N_STATE))
    Q[:3, :3] = singer_q(alpha, T, s2)
    Q[3, 3] = -(float(sigma_p) ** 2) * math.expm1(-2.0 * float(beta) * float(T))
    Q[4, 4] = -(float(sigma_v) ** 2) * math.expm1(-2.0 * float(gamma) * float(T))
    return Q


def maneuver_variance(abar: float, cfg: CsAxisConfig) -> float:
    """Maneuver variance s2 used for the next step (ALGORITHMS.md 2, predict step 3).

    Fixed mode: sigma_a0^2. Adaptive (Zhou's current-statistical model): sigma_a0^2 when
    abar == 0 exactly, else (4 - pi)/pi (a_max - |clamp(abar, +-a_max)|)^2; in adaptive
    mode the result is floored at sigma_a_min^2.
    """
    if not cfg.adaptive:
        return cfg.sigma_a0_mps2**2
    abar = float(abar)
    if abar == 0.0:
        s2 = cfg.sigma_a0_mps2**2
    else:
        ac = min(max(abar, -cfg.a_max_mps2), cfg.a_max_mps2)
        s2 = (4.0 - math.pi) / math.pi * (cfg.a_max_mps2 - abs(ac)) ** 2
    return max(s2, cfg.sigma_a_min_mps2**2)


# --------------------------------------------------------------------------------------
# One axis
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CsAxisConfig:
    """Configuration of one CS axis (ALGORITHMS.md 2 table). Defaults: horizontal."""

    tau_a_s: float = 2.0  # maneuver correlation time, alpha = 1/tau_a
    tau_p_s: float = 60.0  # GPS position error correlation time, beta = 1/tau_p
    tau_v_s: float = 5.0  # GPS velocity error correlation time, gamma = 1/tau_v
    sigma_p_m: float = 1.5  # GPS position Gauss-Markov error std
    sigma_v_mps: float = 0.05  # GPS velocity Gauss-Markov error std
    sigma_a0_mps2: float = 0.5  # fixed maneuver std (and adaptive when abar == 0)
    a_max_mps2: float = 6.0  # maximum maneuver acceleration (adaptive)
    sigma_a_min_mps2: float = 0.05  # floor of the maneuver std (adaptive)
    adaptive: bool = False  # False: fixed sigma_a0; True: current-statistical adaptive
    p0_var_m2: float = 25.0  # initial variance of p
    v0_var_m2s2: float = 1.0  # initial variance of v
    a0_var_m2s4: float = 1.0  # initial variance of a
    dt_max_s: float = 10.0  # longest accepted predict step
    coast: bool = False  # coast on the IMU after an update that left the velocity row out (predict_coasting)
    # the robust mode of the axis' GPS updates (ALGORITHMS.md 5; Cs3.predict_aided / update_robust)
    robust: RobustConfig = field(default_factory=RobustConfig)

    @classmethod
    def horizontal(cls) -> CsAxisConfig:
        """Defaults of the N and E axes."""
        return cls()

    @classmethod
    def vertical(cls) -> CsAxisConfig:
        """Defaults of the D axis."""
        return replace(cls(), sigma_p_m=3.0, sigma_v_mps=0.08, sigma_a0_mps2=0.3, a_max_mps2=3.0)

    @property
    def alpha(self) -> float:
        return 1.0 / self.tau_a_s

    @property
    def beta(self) -> float:
        return 1.0 / self.tau_p_s

    @property
    def gamma(self) -> float:
        return 1.0 / self.tau_v_s

    def validate(self) -> None:
        """Raise BadConfigError unless every value is finite and > 0 (the Gauss-Markov error
        stds sigma_p, sigma_v >= 0: a receiver error taken as white), adaptive and coast 0/1/bool."""
        for flag in ("adaptive", "coast"):
            if getattr(self, flag) not in (0, 1):  # True/False compare equal to 1/0
                raise BadConfigError(f"{flag} must be 0 or 1, got {getattr(self, flag)!r}")
        if not isinstance(self.robust, RobustConfig):
            raise BadConfigError(f"robust must be a RobustConfig, got {self.robust!r}")
        self.robust.validate()
        for f in fields(self):
            if f.name in ("adaptive", "coast", "robust"):
                continue
            v = getattr(self, f.name)
            if not isinstance(v, (int, float, np.floating, np.integer)) or isinstance(v, bool):
                raise BadConfigError(f"{f.name} must be a number, got {v!r}")
            zero_ok = f.name in ("sigma_p_m", "sigma_v_mps")
            if not (math.isfinite(v) and (v >= 0.0 if zero_ok else v > 0.0)):
                raise BadConfigError(f"{f.name} must be finite and {'>=' if zero_ok else '>'} 0, got {v!r}")


def _check_dt(T: object, dt_max_s: float) -> float:
    """ALGORITHMS.md 2, predict step 1: 0 < T <= dt_max, finite; else BAD_DT."""
    if not isinstance(T, numbers.Real) or isinstance(T, bool):
        raise BadDtError(f"T must be a real number, got {T!r}")
    t = float(T)
    if not (math.isfinite(t) and 0.0 < t <= dt_max_s):
        raise BadDtError(f"T must be finite with 0 < T <= {dt_max_s}, got {t!r}")
    return t


def _check_mask(mask: object) -> int:
    """Mask must be an integer with bit 0 and/or bit 1 and no other bit; else BAD_MASK."""
    try:
        m = operator.index(mask)  # type: ignore[arg-type]
    except TypeError as exc:
        raise BadMaskError(f"mask must be an integer, got {mask!r}") from exc
    if m < 0 or m & ~_MASK_KNOWN:
        raise BadMaskError(f"mask has unknown bits: {m:#x}")
    return m


def _measurement_rows(
    mask: int, z_p: object, z_v: object, r_p: object, r_v: object
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(H, z, r) of the rows present in a nonzero, known mask, in the order position, velocity.

    A present value or variance not finite: NONFINITE; a present variance <= 0: BAD_ARG
    (non-finite checks of every present row come first). Absent rows are not looked at.
    """
    rows = [(H_POS, z_p, r_p, "position")] if mask & MASK_POS else []
    if mask & MASK_VEL:
        rows.append((H_VEL, z_v, r_v, "velocity"))
    try:
        z = np.array([float(r[1]) for r in rows])  # type: ignore[arg-type]
        r = np.array([float(r[2]) for r in rows])  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise BadArgError("measured values and variances must be numbers") from exc
    if not (np.all(np.isfinite(z)) and np.all(np.isfinite(r))):
        raise NonFiniteError("a measured value or its variance is not finite")
    if np.any(r <= 0.0):
        raise BadArgError("measurement variances must be > 0")
    H = np.array([row[0] for row in rows])
    return H, z, r


class CsAxis:
    """One CS axis: x (5,) = [p, v, a, eps_p, eps_v], P (5, 5), s2 last maneuver variance.

    Every method either succeeds or raises with x, P and s2 unchanged.
    """

    def __init__(self, cfg: CsAxisConfig | None = None) -> None:
        self.cfg = CsAxisConfig() if cfg is None else cfg
        self.cfg.validate()
        self.x = np.zeros(N_STATE)
        self.P = np.zeros((N_STATE, N_STATE))
        self.s2 = math.nan  # set by init()
        self.initialised = False
        self.clear_robust()

    def clear_robust(self) -> None:
        """The robust memory and the coasting marks as at start (Cs3.predict_aided, update_robust)."""
        self.mem = RobustState()  # the robust memory of the axis' GPS updates (ALGORITHMS.md 5)
        self.out = False  # the last update left the velocity row out or was rejected (coasting, section 2)
        self.left = False  # the last update left some row out or was rejected (mca_robust_left_out)
        self.prior: tuple[np.ndarray, np.ndarray] | None = None  # IMU-aided test prior (y, S), next update
        self.shift = np.zeros(2)  # that prior less the predicted [p + eps_p, v + eps_v]

    # -- init ----------------------------------------------------------------------------
    def _initial(self, p0: float, v0: float) -> tuple[np.ndarray, np.ndarray, float]:
        p0, v0 = float(p0), float(v0)
        if not (math.isfinite(p0) and math.isfinite(v0)):
            raise NonFiniteError("initial position and velocity must be finite")
        c = self.cfg
        x = np.array([p0, v0, 0.0, 0.0, 0.0])
        P = np.diag([c.p0_var_m2, c.v0_var_m2s2, c.a0_var_m2s4, c.sigma_p_m**2, c.sigma_v_mps**2])
        # Reported s2 before the first predict: the value abar = x[2] = 0 would give.
        return x, P, maneuver_variance(0.0, c)

    def init(self, p0: float = 0.0, v0: float = 0.0) -> None:
        """x = [p0, v0, 0, 0, 0], P = diag(p0_var, v0_var, a0_var, sigma_p^2, sigma_v^2)."""
        self.x, self.P, self.s2 = self._initial(p0, v0)
        self.initialised = True

    # -- predict -------------------------------------------------------------------------
    def _predicted(self, T: float, q_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, float]:
        """Pure predict over an already validated T (ALGORITHMS.md 2, predict steps 2-5); ``q_scale``
        multiplies Q (the AKF mode's scale, ALGORITHMS.md 5; 1 otherwise)."""
        c = self.cfg
        s2 = maneuver_variance(self.x[2], c)  # step 2-3: abar = x[2] (eq. 16)
        x = cs_mean_transition(c.beta, c.gamma, T) @ self.x  # step 4 (eq. 17)
        phi = cs_transition(c.alpha, c.beta, c.gamma, T)  # step 5
        Q = q_scale * cs_process_noise(c.alpha, c.beta, c.gamma, T, s2, c.sigma_p_m, c.sigma_v_mps)
        P = phi @ self.P @ phi.T + Q
        P = 0.5 * (P + P.T)
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
            raise NonFiniteError("predict produced a non-finite state")
        return x, P, s2

    def _require_init(self) -> None:
        if not self.initialised:
            raise NotInitError("CsAxis.init() has not been called")

    def aided_prior(self, T: float, dp: float, dv: float, acc_var: float) -> tuple[np.ndarray, np.ndarray]:
        """IMU-aided prediction of the GPS measurement [p + eps_p, v + eps_v] after a predict over T
        from the current posterior (ALGORITHMS.md 2, IMU-aided test prior): the IMU's position and
        velocity increments ``dp``, ``dv`` replace the acceleration state; ``acc_var`` is the
        variance of the IMU acceleration error, held over the interval.

        Returns (y (2,), S (2, 2)); S does not include R.
        """
        c = self.cfg
        eb, eg = math.exp(-c.beta * T), math.exp(-c.gamma * T)
        G = np.array([[1.0, T, 0.0, eb, 0.0], [0.0, 1.0, 0.0, 0.0, eg]])
        y = G @ self.x + np.array([dp, dv])
        S = G @ self.P @ G.T
        S += np.diag([c.sigma_p_m**2 * (1.0 - eb * eb), c.sigma_v_mps**2 * (1.0 - eg * eg)])
        S += acc_var * np.array([[T**4 / 4.0, T**3 / 2.0], [T**3 / 2.0, T**2]])
        return y, S

    def predict_coasting(self, T: float, dp: float, dv: float, acc_var: float, q_scale: float = 1.0) -> float:
        """Coasting predict over T (ALGORITHMS.md 2, coasting): p and v move with the IMU's
        increments ``dp`` (position, less the initial velocity's share) and ``dv`` instead of
        the acceleration state, whose mean stays; the covariance propagates with the CS
        transition less its p-a and v-a couplings, and gains the IMU error ``acc_var`` held
        over the interval: acc_var [[T^4/4, T^3/2], [T^3/2, T^2]] on (p, v). The process noise
        Q is the CS filter's own (times ``q_scale``, the AKF scale). Returns s2, as :meth:`predict`.
        """
        self._require_init()
        t = _check_dt(T, self.cfg.dt_max_s)
        c = self.cfg
        s2 = maneuver_variance(self.x[2], c)
        x = cs_mean_transition(c.beta, c.gamma, t) @ self.x
        x[0] = self.x[0] + t * self.x[1] + dp
        x[1] = self.x[1] + dv
        phi = cs_transition(c.alpha, c.beta, c.gamma, t)
        phi[0, 2] = phi[1, 2] = 0.0  # the IMU, not a, moves p and v
        Q = q_scale * cs_process_noise(c.alpha, c.beta, c.gamma, t, s2, c.sigma_p_m, c.sigma_v_mps)
        Q[:2, :2] += acc_var * np.array([[t**4 / 4.0, t**3 / 2.0], [t**3 / 2.0, t**2]])
        P = phi @ self.P @ phi.T + Q
        P = 0.5 * (P + P.T)
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
            raise NonFiniteError("predict produced a non-finite state")
        self.x, self.P, self.s2 = x, P, s2
        return s2

    def predict(self, T: float) -> float:
        """Predict over T seconds. Returns the maneuver variance s2 used (also self.s2).

        Raises NotInitError, BadDtError (T not finite, <= 0 or > dt_max_s), NonFiniteError.
        """
        self._require_init()
        t = _check_dt(T, self.cfg.dt_max_s)
        self.x, self.P, self.s2 = self._predicted(t)
        return self.s2

    # -- update --------------------------------------------------------------------------
    def _updated(
        self, mask: int, z_p: float, z_v: float, r_p: float, r_v: float
    ) -> tuple[np.ndarray, np.ndarray, UpdateReport]:
        H, z, r = _measurement_rows(mask, z_p, z_v, r_p, r_v)
        return kf_update(self.x, self.P, H, z, r)

    def update(
        self, z_p: float, z_v: float, r_p: float, r_v: float, mask: int = MASK_POS | MASK_VEL
    ) -> UpdateReport:
        """GPS update (ALGORITHMS.md 2, update). mask bit 0: z_p measured, bit 1: z_v.

        Values of rows not in the mask are ignored (may be NaN). Raises NotInitError,
        BadMaskError (0 or unknown bits), NonFiniteError, BadArgError (variance <= 0),
        SingularError.
        """
        self._require_init()
        m = _check_mask(mask)
        if m == 0:
            raise BadMaskError("mask is 0: nothing measured")
        self.x, self.P, report = self._updated(m, z_p, z_v, r_p, r_v)
        return report


# --------------------------------------------------------------------------------------
# Robust updates of the three axes, IMU-aided test and coasting (ALGORITHMS.md 2, 3, 5)
# --------------------------------------------------------------------------------------


class AxisInc(NamedTuple):
    """IMU increments of one axis over a predict interval (ALGORITHMS.md 2, IMU-aided test prior):
    ``dp``, ``dv``, the IMU acceleration error variance ``qa`` of the test and ``qc`` of a coast."""

    dp: float
    dv: float
    qa: float
    qc: float


def _is_fuzzy_rows(cfg: RobustConfig) -> bool:
    return cfg.mode == "fuzzy" and cfg.fuzzy_reject == FUZZY_ROWS


def _predict_aided_axis(ax: CsAxis, t: float, inc: AxisInc | None) -> None:
    """One axis of :meth:`Cs3.predict_aided` (T validated)."""
    q_scale = float(ax.mem.q_scale)
    if inc is None:
        ax.x, ax.P, ax.s2 = ax._predicted(t, q_scale)
        ax.prior = None
        return
    y, S = ax.aided_prior(t, inc.dp, inc.dv, inc.qa)  # from the posterior, before the predict
    if ax.cfg.coast and ax.out:
        ax.predict_coasting(t, inc.dp, inc.dv, inc.qc, q_scale)
    else:
        ax.x, ax.P, ax.s2 = ax._predicted(t, q_scale)
    ax.prior = (y, S)
    ax.shift = y - np.array([ax.x[0] + ax.x[3], ax.x[1] + ax.x[4]])


# --------------------------------------------------------------------------------------
# Three axes N, E, D (ALGORITHMS.md 3)
# --------------------------------------------------------------------------------------


def _three(name: str, a: object) -> list:
    seq = list(np.asarray(a, dtype=object).reshape(-1))
    if len(seq) != 3:
        raise BadArgError(f"{name} must have 3 entries (N, E, D), got {len(seq)}")
    return seq


class Cs3:
    """Three independent CS axes N, E, D; N and E use cfg_h, D uses cfg_v.

    Every method validates all three axes before changing any, and computes all three
    results before committing any: on an error no axis changes.
    """

    def __init__(self, cfg_h: CsAxisConfig | None = None, cfg_v: CsAxisConfig | None = None) -> None:
        cfg_h = CsAxisConfig.horizontal() if cfg_h is None else cfg_h
        cfg_v = CsAxisConfig.vertical() if cfg_v is None else cfg_v
        self.axes = [CsAxis(cfg_h), CsAxis(cfg_h), CsAxis(cfg_v)]

    def init(self, p0: object = (0.0, 0.0, 0.0), v0: object = (0.0, 0.0, 0.0)) -> None:
        """Initialise the three axes with position p0 (3,) and velocity v0 (3,), NED."""
        new = [
            ax._initial(p, v) for ax, p, v in zip(self.axes, _three("p0", p0), _three("v0", v0), strict=True)
        ]
        for ax, (x, P, s2) in zip(self.axes, new, strict=True):
            ax.x, ax.P, ax.s2 = x, P, s2
            ax.initialised = True
            ax.clear_robust()  # a (re)start clears the memories and the coasting marks (nav.py, choice 17)

    def predict(self, T: float) -> np.ndarray:
        """Predict all axes over T (validated once against every axis' dt_max_s).

        Returns the three maneuver variances s2 used.
        """
        for ax in self.axes:
            ax._require_init()
        t = _check_dt(T, min(ax.cfg.dt_max_s for ax in self.axes))
        new = [ax._predicted(t) for ax in self.axes]
        for ax, (x, P, s2) in zip(self.axes, new, strict=True):
            ax.x, ax.P, ax.s2 = x, P, s2
        return np.array([s2 for (_, _, s2) in new])

    def _checked_rows(
        self, z_p: object, z_v: object, r_p: object, r_v: object, mask: object
    ) -> tuple[list[int], list]:
        """Every axis initialised, every mask known and not all 0, then each axis' rows (H, z, r) or
        None for mask 0, checked N, E, D (``_measurement_rows``); raises with nothing changed."""
        for ax in self.axes:
            ax._require_init()
        masks = [_check_mask(m) for m in _three("mask", mask)]
        if not any(masks):
            raise BadMaskError("mask is 0 on all three axes")
        zp, zv, rp, rv = _three("z_p", z_p), _three("z_v", z_v), _three("r_p", r_p), _three("r_v", r_v)
        rows = [_measurement_rows(m, zp[i], zv[i], rp[i], rv[i]) if m else None for i, m in enumerate(masks)]
        return masks, rows

    def update(
        self, z_p: object, z_v: object, r_p: object, r_v: object, mask: object
    ) -> list[UpdateReport | None]:
        """Update with per-axis position, velocity, variances and masks, each (3,), N E D.

        An axis whose mask is 0 is skipped (its report is None); all three masks 0, or any
        mask with unknown bits, is BadMaskError. Order of checks: every mask, then each
        axis' values and variances (N, E, D), then the updates; nothing changes on error.
        """
        masks, rows = self._checked_rows(z_p, z_v, r_p, r_v, mask)
        new = [
            kf_update(ax.x, ax.P, *row) if row is not None else None
            for ax, row in zip(self.axes, rows, strict=True)
        ]
        reports: list[UpdateReport | None] = []
        for ax, result in zip(self.axes, new, strict=True):
            if result is None:
                reports.append(None)
                continue
            ax.x, ax.P, report = result
            reports.append(report)
        return reports

    def predict_aided(self, T: float, incs: list[AxisInc | None]) -> None:
        """Predict all axes over T, each with its IMU increments or None (ALGORITHMS.md 2): an axis
        with increments keeps the IMU-aided test prior of its next update (from the posterior, before
        the covariance is predicted) and coasts when it is marked (``coast`` set, the last update left
        the velocity row out or was rejected); one without them predicts as :meth:`predict` and has no
        prior. The AKF memory's ``q_scale`` multiplies Q. Nothing changes on an error."""
        for ax in self.axes:
            ax._require_init()
        t = _check_dt(T, min(ax.cfg.dt_max_s for ax in self.axes))
        saved = [(ax.x, ax.P, ax.s2, ax.prior, ax.shift) for ax in self.axes]
        try:
            for ax, inc in zip(self.axes, incs, strict=True):
                _predict_aided_axis(ax, t, inc)
        except Exception:
            for ax, (x, P, s2, prior, shift) in zip(self.axes, saved, strict=True):
                ax.x, ax.P, ax.s2, ax.prior, ax.shift = x, P, s2, prior, shift
            raise

    def update_robust(
        self,
        z_p: object,
        z_v: object,
        r_p: object,
        r_v: object,
        mask: object,
        vel_held: bool = False,
    ) -> list[RobustReport | None]:
        """Update all axes in their robust modes (ALGORITHMS.md 3 and 5), checked as :meth:`update`.

        An axis with an IMU-aided prior (:meth:`predict_aided`) tests ``z - y`` with ``S + R`` (its
        rows of the prior), and consumes the prior; one without tests its own innovation. When N and E
        both run fuzzy rows and both test position and velocity, each one's plan is made first on its
        own test (``fuzzy_rows_failed``) and its failing rows go out of the other's update too (the N/E
        pair), with the velocity rows of both when ``vel_held`` (the velocity step test held the fix,
        ALGORITHMS.md 8 GPS step 3). After each update the axis is marked ``out`` (coasting) when it was
        rejected or left its velocity row out, and ``left`` when it was rejected or left any row out;
        with ``coast`` set, a coast that starts at an aided update starts from the prior
        (``p``, ``v`` += the prior's shift). Every result is computed before any axis changes; an axis
        update that fails (SINGULAR, NONFINITE) raises with no axis changed (see
        :meth:`update_robust_partial` for the navigation filter's GPS step 4)."""
        reports, failures = self._robust_results(z_p, z_v, r_p, r_v, mask, vel_held)
        for err in failures:
            if err is not None:
                raise err
        return self._commit_robust(reports)

    def update_robust_partial(
        self,
        z_p: object,
        z_v: object,
        r_p: object,
        r_v: object,
        mask: object,
        vel_held: bool = False,
    ) -> tuple[list[RobustReport | None], list[McaError | None]]:
        """:meth:`update_robust` as the navigation filter's GPS step 4 runs it (ALGORITHMS.md 8): the
        inputs are checked as there (nothing changes on a bad one), but an axis update that fails
        numerically (SINGULAR, NONFINITE: a corrupted covariance) leaves that axis as predicted (its
        state, memory and coasting marks; its prior is consumed) while the other axes update. Returns
        the reports (None for an axis not updated or failed) and each axis' failure (None if none)."""
        results, failures = self._robust_results(z_p, z_v, r_p, r_v, mask, vel_held)
        for ax, err in zip(self.axes, failures, strict=True):
            if err is not None:
                ax.prior = None  # the prior was this interval's: consumed
        return self._commit_robust(results), failures

    def _commit_robust(self, results: list) -> list[RobustReport | None]:
        reports: list[RobustReport | None] = []
        for ax, result in zip(self.axes, results, strict=True):
            if result is None:
                reports.append(None)
                continue
            ax.x, ax.P, rep, ax.mem, ax.out, ax.left = result
            ax.prior = None
            reports.append(rep)
        return reports

    def _robust_results(
        self, z_p: object, z_v: object, r_p: object, r_v: object, mask: object, vel_held: bool
    ) -> tuple[list, list[McaError | None]]:
        """Every axis' robust update result (x, P, report, memory, out, left), None for an axis not
        updated or failed, and each axis' numerical failure; raises on a bad input, nothing changed."""
        masks, rows = self._checked_rows(z_p, z_v, r_p, r_v, mask)
        tests: list[tuple[np.ndarray, np.ndarray] | None] = []
        for ax, m, row in zip(self.axes, masks, rows, strict=True):
            if row is None or ax.prior is None:
                tests.append(None)
                continue
            keep = [k for k, bit in enumerate((MASK_POS, MASK_VEL)) if m & bit]
            y, S = ax.prior
            _, z, r = row
            tests.append((z - y[keep], S[np.ix_(keep, keep)] + np.diag(r)))
        pair: list[tuple[bool, ...] | None] = [None, None, None]
        n_ax, e_ax = self.axes[0], self.axes[1]
        if (
            _is_fuzzy_rows(n_ax.cfg.robust)
            and _is_fuzzy_rows(e_ax.cfg.robust)
            and masks[0] == masks[1] == MASK_POS | MASK_VEL
            and tests[0] is not None
            and tests[1] is not None
        ):
            failed: list[tuple[bool, ...]] = []
            for i, ax in enumerate((n_ax, e_ax)):
                try:
                    failed.append(fuzzy_rows_failed(ax.cfg.robust, ax.mem, *tests[i]))  # type: ignore[misc]
                except (SingularError, NonFiniteError):  # that axis' own update fails the same way
                    failed.append((False, False))
            held = (False, bool(vel_held))
            pair[0] = tuple(a or b for a, b in zip(failed[1], held, strict=True))
            pair[1] = tuple(a or b for a, b in zip(failed[0], held, strict=True))
        new: list = []
        failures: list[McaError | None] = []
        for i, (ax, m, row) in enumerate(zip(self.axes, masks, rows, strict=True)):
            failures.append(None)
            if row is None:
                new.append(None)
                continue
            H, z, r = row
            mem = copy.deepcopy(ax.mem)
            try:
                x, P, rep = robust_update(
                    ax.x, ax.P, H, z, r, ax.cfg.robust, mem, test=tests[i], pair_out=pair[i]
                )
            except (SingularError, NonFiniteError) as err:
                failures[i] = err
                new.append(None)
                continue
            k = H.shape[0]
            # rows left out by this update: the memory counts them (an update that keeps a row sets its
            # count to 0; a reset clears the memory and applied every row)
            left_rows = [rep.rejected or mem.n_removed[j] > 0 for j in range(k)]
            vel_row = k - 1 if m & MASK_VEL else None
            out = bool(rep.rejected) or (vel_row is not None and left_rows[vel_row])
            if ax.cfg.coast and out and not ax.out and ax.prior is not None:
                x = np.array(x)
                x[:2] += ax.shift  # the coast starts from the IMU-aided prediction
            new.append((x, P, rep, mem, out, bool(rep.rejected) or any(left_rows)))
        return new, failures

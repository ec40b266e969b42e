"""Measurement update shared by every filter: ALGORITHMS.md section 1 (plain mode), and
its robust and adaptive modes, ALGORITHMS.md section 5 (DESIGN.md 5).

Float64 golden model. ``kf_update`` is NumPy only; the robust modes also need chi-square
quantiles, taken from ``scipy.stats.chi2.ppf(1 - a, m)`` (imported lazily, so importing
this module and calling ``kf_update`` does not need scipy). Inputs are never modified,
and ``robust_update`` changes its memory only when it succeeds, so on any error the
caller's state is exactly what it was.

Robust modes, one block of functions per paper, each read like the equations:

* FTA, paper 000: ``fta_gamma`` (eq. 13), gain on ``gamma C`` (eq. 15), Joseph with ``R`` (eq. 16).
* AKF, paper 004: ``akf_row_statistics`` (recursive eq. 15-16), ``akf_inflated_noise``
  (eq. 15), ``akf_q_scale`` (eq. 18-19).
* Fuzzy three-threshold detector, paper 001: ``fuzzy_thresholds``, ``fuzzy_memberships``
  (eq. 10), ``fuzzy_mu`` (eq. 11), ``fuzzy_detector_step`` (eq. 12 and the alarm rules).
* IGG-III, paper 003: ``igg_weight`` (the three-segment weight) and ``igg_reweight``
  (the largest-first iteration).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

import numpy as np

from mcahrs.errors import BadArgError, BadConfigError, NonFiniteError, SingularError

__all__ = [
    "AKF_ALPHA",
    "FTA_ALPHA",
    "FUZZY_TD1_ALPHA",
    "FUZZY_TD2_ALPHA",
    "FUZZY_TD3_OVER_TD2",
    "MODES",
    "MODE_NUMBERS",
    "M_MAX",
    "RobustConfig",
    "RobustReport",
    "RobustState",
    "UpdateReport",
    "akf_alpha",
    "akf_inflated_noise",
    "akf_q_scale",
    "akf_row_statistics",
    "chi2_quantile",
    "fta_gamma",
    "fuzzy_detector_step",
    "fuzzy_memberships",
    "fuzzy_mu",
    "fuzzy_thresholds",
    "igg_reweight",
    "igg_weight",
    "kf_update",
    "robust_update",
]

# Relative asymmetry tolerated in P and R (they are documented as symmetric; this only
# catches a caller passing something that is not a covariance at all).
_SYMMETRY_RTOL = 1e-12


@dataclass(frozen=True)
class UpdateReport:
    """What every update reports (ALGORITHMS.md 1).

    m: measurement size; nu: innovation z - H x (m,); C: innovation covariance
    H P H^T + R (m, m); T: normalised innovation squared nu^T C^-1 nu (chi^2(m) when
    the model holds).
    """

    m: int
    nu: np.ndarray
    C: np.ndarray
    T: float


def _as_float_array(name: str, a: object, ndim: int) -> np.ndarray:
    arr = np.array(a, dtype=np.float64)  # a copy: nothing below can alias the caller's data
    if arr.ndim != ndim:
        raise BadArgError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    return arr


def _check_symmetric(name: str, a: np.ndarray) -> None:
    scale = float(np.max(np.abs(a))) if a.size else 0.0
    if float(np.max(np.abs(a - a.T), initial=0.0)) > _SYMMETRY_RTOL * scale:
        raise BadArgError(f"{name} is not symmetric")


def _forward_substitution(L: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve L y = b, L lower triangular (b may have several columns)."""
    y = np.array(b, dtype=np.float64)
    for i in range(L.shape[0]):
        y[i] = (y[i] - L[i, :i] @ y[:i]) / L[i, i]
    return y


def _back_substitution(U: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve U y = b, U upper triangular (b may have several columns)."""
    y = np.array(b, dtype=np.float64)
    for i in reversed(range(U.shape[0])):
        y[i] = (y[i] - U[i, i + 1 :] @ y[i + 1 :]) / U[i, i]
    return y


def kf_update(
    x: np.ndarray, P: np.ndarray, H: np.ndarray, z: np.ndarray, R: np.ndarray
) -> tuple[np.ndarray, np.ndarray, UpdateReport]:
    """Kalman measurement update, Joseph form (ALGORITHMS.md 1, steps 1-6).

    Args:
        x: state (n,).
        P: state covariance (n, n), symmetric.
        H: measurement rows (m, n).
        z: measurement (m,).
        R: measurement noise, full symmetric (m, m) or its diagonal (m,).

    Returns:
        (x_plus, P_plus, report): new arrays; the inputs are not modified.

    Raises:
        BadArgError: shapes inconsistent, m == 0, or P / R not symmetric.
        NonFiniteError: an input is NaN/Inf, or x+ / P+ would be (step 6).
        SingularError: C = H P H^T + R is not positive definite (step 2).
    """
    x, P, H, z, R = _checked_inputs(x, P, H, z, R, m_max=None)
    n, m = x.shape[0], z.shape[0]

    # Step 1: innovation and its covariance.
    nu = z - H @ x
    C = H @ P @ H.T + R

    # Step 2: C symmetric positive definite <=> its Cholesky factor exists.
    L = _cholesky(C)

    # Step 3: T = nu^T C^-1 nu = |L^-1 nu|^2.
    y = _forward_substitution(L, nu)
    T = float(y @ y)

    # Step 4: K = P H^T C^-1, i.e. K^T = C^-1 (H P) = L^-T L^-1 (H P) (C and P symmetric).
    K = _back_substitution(L.T, _forward_substitution(L, H @ P)).T
    x_plus = x + K @ nu

    # Step 5: Joseph form, then symmetrise.
    I_KH = np.eye(n) - K @ H
    P_plus = I_KH @ P @ I_KH.T + K @ R @ K.T
    P_plus = 0.5 * (P_plus + P_plus.T)

    # Step 6.
    if not (np.all(np.isfinite(x_plus)) and np.all(np.isfinite(P_plus))):
        raise NonFiniteError("update produced a non-finite state")

    return x_plus, P_plus, UpdateReport(m=m, nu=nu, C=C, T=T)


# ======================================================================================
# Robust and adaptive modes (ALGORITHMS.md 5, DESIGN.md 5)
# ======================================================================================

MODES = ("plain", "fta", "akf", "fuzzy", "igg3")
MODE_NUMBERS = {name: number for number, name in enumerate(MODES)}  # mca_robust_config_t.mode
M_MAX = 6  # largest measurement size of a robust update; memory keeps one entry per row

FTA_ALPHA = 1e-4  # paper 000: significance level of the FTA test
AKF_ALPHA = 1e-2  # ALGORITHMS.md 5: significance level of the AKF detection
FUZZY_TD1_ALPHA = 0.025  # paper 001: TD1 = chi2_m(0.025), "no outlier" below it
FUZZY_TD2_ALPHA = 0.005  # paper 001: TD2 = chi2_m(0.005), the usual single threshold
FUZZY_TD3_OVER_TD2 = 10.0  # paper 001: TD3 = 10 TD2, "outlier" above it
FUZZY_ROWS = 2  # fuzzy_reject value of the rows variant (ALGORITHMS.md 5)
FUZZY_LAST_ROW_ALPHA = 1e-4  # fuzzy rows: the last row standing fails above 2 chi2_1(this) (ALGORITHMS.md 5)
FUZZY_GATE_ALPHA = 1e-4  # fuzzy rows without an alarm: a row past 2 chi2_1(this) is gated (ALGORITHMS.md 5)
RESET_N_DEFAULT = 5  # the default lock-up guard, and fuzzy rows' without a test innovation


@dataclass
class RobustConfig:
    """Run-time choice of the update mode and its parameters (``mca_robust_config_t``).

    mode: one of ``MODES``; fuzzy_reject: while the fuzzy detector alarms, reject the update
    (True or 1), inflate it as FTA with ``gamma = max(1, T / TD2)`` (False or 0), or (2, rows)
    leave out the rows that fail their own test (ALGORITHMS.md 5); akf_window: n, the
    number of epochs of eq. 18; akf_forget: b, the forgetting factor of the AKF row
    statistics; akf_q_min / akf_q_max: clamp of the Q scale of eq. 19; igg_k0 / igg_k1: the
    IGG-III thresholds on the standardised residual.
    """

    mode: str = "plain"
    fuzzy_reject: int = 1  # 0 (or False) inflate, 1 (or True) reject, 2 rows
    akf_window: int = 8
    akf_forget: float = 0.2
    akf_q_min: float = 0.5
    akf_q_max: float = 10.0
    igg_k0: float = 1.5
    igg_k1: float = 3.0
    reject_reset_n: int = RESET_N_DEFAULT  # lock-up guard: the n-th rejection in a row updates plain (0: off)
    row_reset_n: int = 50  # row lock-up guard: a row removed the n-th time in a row, the same (0: off)

    def validate(self) -> None:
        """Raise BadConfigError unless every field is in its documented range.

        All fields are checked whatever the mode (a configuration is valid or not as a whole).
        The upper bound of akf_window is the C core's compile-time MCA_AKF_WINDOW; the golden
        model has no such limit.
        """
        if self.mode not in MODES:
            raise BadConfigError(f"mode must be one of {MODES}, got {self.mode!r}")
        if self.fuzzy_reject not in (0, 1, FUZZY_ROWS):  # True/False compare equal to 1/0
            raise BadConfigError(f"fuzzy_reject must be a bool or 2 (rows), got {self.fuzzy_reject!r}")
        n = self.akf_window
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise BadConfigError(f"akf_window must be an integer >= 1, got {n!r}")
        numbers = {
            name: getattr(self, name) for name in ("akf_forget", "akf_q_min", "akf_q_max", "igg_k0", "igg_k1")
        }
        for name, v in numbers.items():
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise BadConfigError(f"{name} must be a number, got {v!r}")
            if not math.isfinite(v):
                raise BadConfigError(f"{name} must be finite, got {v!r}")
        if not 0.0 < self.akf_forget <= 1.0:
            raise BadConfigError(f"akf_forget must be in (0, 1], got {self.akf_forget!r}")
        if not 0.0 < self.akf_q_min <= self.akf_q_max:
            raise BadConfigError(
                f"need 0 < akf_q_min <= akf_q_max, got {self.akf_q_min!r}, {self.akf_q_max!r}"
            )
        if not 0.0 < self.igg_k0 < self.igg_k1:
            raise BadConfigError(f"need 0 < igg_k0 < igg_k1, got {self.igg_k0!r}, {self.igg_k1!r}")
        for name in ("reject_reset_n", "row_reset_n"):
            v = getattr(self, name)
            if not (isinstance(v, int) and 0 <= v <= 255):
                raise BadConfigError(f"{name} must be an integer in [0, 255], got {v!r}")


@dataclass
class RobustState:
    """Memory of one filter's robust update (``mca_robust_state_t``), changed in place.

    win: the last ``akf_window`` values of ``e = nu^T nu - tr(R)`` (oldest first);
    nu_mean, nu_var: per-row running innovation mean r_i and variance s_i (AKF, M_MAX rows); in
    the fuzzy mode nu_mean holds the last tested innovation (fuzzy rows' return rule);
    q_scale: the AKF process-noise scale the filter applies at its next predict;
    d_k: the fuzzy detector's smoothed statistic D; alarm: the fuzzy alarm;
    started: the AKF row statistics have seen their first update;
    caller_out: fuzzy rows, per row: the caller's rows (ALGORITHMS.md 5, the N/E pair: the spec's
    memory ``started``, unused by the fuzzy modes), out of the next update with the pair's and whatever
    its alarm; that update clears them (the navigation filter's position hold, ALGORITHMS.md 8 GPS step 4).
    """

    win: list[float] = field(default_factory=list)
    nu_mean: np.ndarray = field(default_factory=lambda: np.zeros(M_MAX))
    nu_var: np.ndarray = field(default_factory=lambda: np.zeros(M_MAX))
    q_scale: float = 1.0
    d_k: float = 0.0
    alarm: bool = False
    started: bool = False
    n_reject: int = 0  # updates rejected in a row (lock-up guard)
    n_removed: list[int] = field(default_factory=lambda: [0] * M_MAX)  # per row: removed in a row
    caller_out: list[bool] = field(default_factory=lambda: [False] * M_MAX)  # fuzzy rows: the caller's rows


@dataclass(frozen=True)
class RobustReport(UpdateReport):
    """What a robust update reports (ALGORITHMS.md 5), on top of ``UpdateReport``.

    factor: FTA gamma, the fuzzy gamma applied, AKF tr(R*)/tr(R); 1 where not used.
    w: IGG-III weight of each row (m,); 1 where not used.
    q_scale: the AKF Q scale after this update; 1 in the other modes.
    detected: FTA gamma > 1, AKF T > chi2_m(1e-2), fuzzy alarm, IGG-III any w_i < 1; else False.
    rejected: the update was not applied (x and P unchanged): fuzzy alarm with reject, or
    IGG-III with every row removed.
    alarm: the fuzzy alarm after this epoch's test; False in the other modes.
    """

    factor: float
    w: np.ndarray
    q_scale: float
    detected: bool
    rejected: bool
    alarm: bool
    reset: bool = False  # the lock-up guard replaced a rejection by a plain update
    tested: bool = False  # T and the mode's decisions came from a test innovation


# --------------------------------------------------------------------------------------
# Chi-square quantiles
# --------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=64)
def chi2_quantile(a: float, m: int) -> float:
    """chi2_m(a): the upper-a quantile of chi-square with m degrees of freedom."""
    from scipy.stats import chi2  # lazy: only the robust modes need scipy

    return float(chi2.ppf(1.0 - a, m))


# --------------------------------------------------------------------------------------
# FTA (paper 000)
# --------------------------------------------------------------------------------------


def fta_gamma(T: float, m: int) -> float:
    """Eq. 13: gamma = 1 if T <= chi2_m(1e-4), else T / chi2_m(1e-4) (T >= 0, so |T| = T)."""
    threshold = chi2_quantile(FTA_ALPHA, m)
    return 1.0 if T <= threshold else T / threshold


# --------------------------------------------------------------------------------------
# AKF (paper 004)
# --------------------------------------------------------------------------------------


def akf_row_statistics(
    r: np.ndarray, s: np.ndarray, nu: np.ndarray, b: float, first: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Recursive eq. 15-16 with forgetting b: per row mean r_i and variance s_i.

    First update of a memory: r = nu, s = 0. Then r = (1 - b) r + b nu and
    s = (1 - b) s + b (nu - r)^2 with the new r. Returns new arrays.
    """
    nu = np.asarray(nu, dtype=np.float64)
    if first:
        return nu.copy(), np.zeros_like(nu)
    r_new = (1.0 - b) * np.asarray(r, dtype=np.float64) + b * nu
    s_new = (1.0 - b) * np.asarray(s, dtype=np.float64) + b * (nu - r_new) ** 2
    return r_new, s_new


def akf_inflated_noise(R: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Eq. 15 at a detected outlier: R* = R + diag(s_i)."""
    return np.asarray(R, dtype=np.float64) + np.diag(np.asarray(s, dtype=np.float64))


def akf_alpha(window: list[float] | np.ndarray, trace_hph: float) -> float:
    """Eq. 18: alpha = tr(mean of the last n nu nu^T - R) / tr(H P H^T) = mean(window) / tr(H P H^T).

    IEEE division: a zero denominator gives +-inf (0/0: NaN), which eq. 19 maps into its clamp.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.float64(np.mean(window)) / np.float64(trace_hph))


def akf_q_scale(alpha: float, q_min: float, q_max: float) -> float:
    """Eq. 19: Q <- log2(alpha + 1) Q, the factor clamped to [q_min, q_max].

    log2 of max(alpha + 1, tiny), so alpha <= -1 (and NaN, like C's fmax) give q_min.
    """
    arg = float(np.fmax(alpha + 1.0, np.finfo(np.float64).tiny))
    return min(max(math.log2(arg), q_min), q_max)


# --------------------------------------------------------------------------------------
# Fuzzy three-threshold detector (paper 001)
# --------------------------------------------------------------------------------------


def fuzzy_thresholds(m: int) -> tuple[float, float, float]:
    """TD1 = chi2_m(0.025), TD2 = chi2_m(0.005), TD3 = 10 TD2 (section 2.3 of the paper)."""
    td2 = chi2_quantile(FUZZY_TD2_ALPHA, m)
    return chi2_quantile(FUZZY_TD1_ALPHA, m), td2, FUZZY_TD3_OVER_TD2 * td2


def fuzzy_memberships(T: float, td1: float, td2: float, td3: float) -> tuple[float, float, float]:
    """Eq. 10: degrees of membership (DOM_H, DOM_M, DOM_D) of T; each piecewise linear."""
    if T < td1:
        dom_h = 1.0
    elif T <= td2:
        dom_h = (td2 - T) / (td2 - td1)
    else:
        dom_h = 0.0

    if td1 < T <= td2:
        dom_m = (T - td1) / (td2 - td1)
    elif td2 <= T < td3:
        dom_m = (td3 - T) / (td3 - td2)
    else:
        dom_m = 0.0

    if T < td2:
        dom_d = 0.0
    elif T <= td3:
        dom_d = (T - td2) / (td3 - td2)
    else:
        dom_d = 1.0
    return dom_h, dom_m, dom_d


def fuzzy_mu(T: float, m: int) -> float:
    """Eq. 11: mu = a_H DOM_H + a_M DOM_M + a_D DOM_D with a_H = TD1/TD3, a_M = 0.5, a_D = 1.

    So mu(TD1) = a_H, mu(TD2) = 0.5, mu(T >= TD3) = 1.
    """
    td1, td2, td3 = fuzzy_thresholds(m)
    dom_h, dom_m, dom_d = fuzzy_memberships(T, td1, td2, td3)
    return (td1 / td3) * dom_h + 0.5 * dom_m + 1.0 * dom_d


def fuzzy_detector_step(
    d_prev: float, alarm_prev: bool, T: float, m: int, rows: bool = False
) -> tuple[float, bool, float]:
    """Eq. 12 and the alarm rules of paper 001 section 2.2. Returns (D_k, alarm, mu_k).

    D_k = D_{k-1} / 2 + mu_k. No alarm and D_k > 1: alarm. Alarm, T < TD2 and D_k < 1:
    release and D_k = 0. (From D = 0, two consecutive T > TD3 give D = 1 then 1.5: alarm on
    the second, as the paper states; after clean epochs D ~ 2 a_H, so one T > TD3 alarms.)
    ``rows`` (the fuzzy rows variant, ALGORITHMS.md 5): alarm at D_k >= 1, so that one T past
    TD3 right after a release (D = 0) alarms too.
    """
    _, td2, _ = fuzzy_thresholds(m)
    mu = fuzzy_mu(T, m)
    d = d_prev / 2.0 + mu
    alarm = bool(alarm_prev)
    if not alarm and (d >= 1.0 if rows else d > 1.0):
        alarm = True
    elif alarm and T < td2 and d < 1.0:
        alarm = False
        d = 0.0
    return d, alarm, mu


# --------------------------------------------------------------------------------------
# IGG-III (paper 003)
# --------------------------------------------------------------------------------------


def igg_weight(s: float, k0: float, k1: float) -> float:
    """IGG-III weight of a standardised residual s: 1 (s <= k0), (k0/s)((k1 - s)/(k1 - k0))^2
    (k0 < s <= k1), 0 (s > k1)."""
    if s <= k0:
        return 1.0
    if s <= k1:
        return (k0 / s) * ((k1 - s) / (k1 - k0)) ** 2
    return 0.0


def igg_reweight(
    nu: np.ndarray, hph: np.ndarray, R: np.ndarray, k0: float, k1: float
) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The IGG-III iteration of ALGORITHMS.md 5: largest standardised residual first.

    At most m rounds: among rows whose weight is not fixed yet, take the largest
    s_i = |nu_i| / sqrt(C_ii) (lowest index on ties); stop if it is <= k0; else fix
    w_i = w(s_i) and replace R_ii by R_ii / w_i (w_i = 0 removes the row); recompute C over
    the kept rows and the s of the others.

    Note: with innovation residuals C_ii = (H P H^T)_ii + R_ii depends on row i alone, so the
    recomputed s of the rows not yet weighted never changes; the result equals one pass of
    w(s_i) over all rows. The loop is kept as written so the C core's loop can be checked
    against it (and so the order is reported).

    Returns (w (m,), R_eq (m, m) equivalent noise, valid on the kept rows w > 0, order of the
    rows weighted).
    """
    nu = np.asarray(nu, dtype=np.float64)
    m = nu.shape[0]
    w = np.ones(m)
    fixed = np.zeros(m, dtype=bool)
    R_eq = np.array(R, dtype=np.float64)
    order: list[int] = []
    for _ in range(m):
        kept = w > 0.0
        C = hph + R_eq  # over the kept rows; removed rows are masked out below
        s = np.full(m, -np.inf)
        open_rows = kept & ~fixed
        s[open_rows] = np.abs(nu[open_rows]) / np.sqrt(np.diag(C)[open_rows])
        if not open_rows.any():
            break
        i = int(np.argmax(s))  # first maximum: lowest index on ties
        if s[i] <= k0:
            break
        w[i] = igg_weight(float(s[i]), k0, k1)
        fixed[i] = True
        order.append(i)
        if w[i] > 0.0:
            R_eq[i, i] = R_eq[i, i] / w[i]
    return w, R_eq, order


# --------------------------------------------------------------------------------------
# Shared steps of section 1
# --------------------------------------------------------------------------------------


def _checked_inputs(
    x: object, P: object, H: object, z: object, R: object, m_max: int | None = M_MAX
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The argument checks of every update: shapes, finiteness, symmetry; and m <= m_max (a robust
    update's memory holds M_MAX rows; kf_update has no limit)."""
    x = _as_float_array("x", x, 1)
    P = _as_float_array("P", P, 2)
    H = _as_float_array("H", H, 2)
    z = _as_float_array("z", z, 1)
    R = np.array(R, dtype=np.float64)
    n, m = x.shape[0], z.shape[0]
    if R.ndim == 1:
        R = np.diag(R)
    if m == 0 or P.shape != (n, n) or H.shape != (m, n) or R.shape != (m, m):
        raise BadArgError(
            f"inconsistent shapes: x {x.shape}, P {P.shape}, H {H.shape}, z {z.shape}, R {R.shape}"
        )
    if m_max is not None and m > m_max:
        raise BadArgError(f"a robust update takes at most {m_max} rows, got {m}")
    for name, a in (("x", x), ("P", P), ("H", H), ("z", z), ("R", R)):
        if not np.all(np.isfinite(a)):
            raise NonFiniteError(f"{name} is not finite")
    _check_symmetric("P", P)
    _check_symmetric("R", R)
    return x, P, H, z, R


def _cholesky(C: np.ndarray) -> np.ndarray:
    """Section 1 step 2: C = L L^T (reads the lower triangle), or SINGULAR; NONFINITE on overflow."""
    if not np.all(np.isfinite(C)):
        raise NonFiniteError("innovation covariance overflowed")
    try:
        L = np.linalg.cholesky(C)
    except np.linalg.LinAlgError as exc:
        raise SingularError("innovation covariance is not positive definite") from exc
    if not np.all(np.diag(L) > 0.0):
        raise SingularError("innovation covariance is not positive definite")
    return L


def _innovation(
    x: np.ndarray, P: np.ndarray, H: np.ndarray, z: np.ndarray, R: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """Section 1 steps 1-3 with the nominal R: nu, C = H P H^T + R, T = nu^T C^-1 nu.

    An innovation that overflows (finite x and z far apart) is NONFINITE here, before any mode
    runs: kf_update would end at step 6 with a non-finite x+ anyway, and this keeps the modes
    alike (IGG-III would otherwise silently remove an infinite residual's row).
    """
    with np.errstate(over="ignore", invalid="ignore"):
        nu = z - H @ x
    if not np.all(np.isfinite(nu)):
        raise NonFiniteError("innovation overflowed")
    C = H @ P @ H.T + R
    y = _forward_substitution(_cholesky(C), nu)
    return nu, C, float(y @ y)


def _gain_update(
    x: np.ndarray, P: np.ndarray, H: np.ndarray, nu: np.ndarray, C_gain: np.ndarray, R_joseph: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Section 1 steps 4-6: K = P H^T C_gain^-1, x+ = x + K nu, Joseph with R_joseph, symmetrise.

    Plain: C_gain = C, R_joseph = R. FTA: gamma C and the nominal R (Joseph holds for any gain).
    AKF: H P H^T + R* and R*. IGG-III: the kept rows and their equivalent R.
    """
    L = _cholesky(C_gain)
    K = _back_substitution(L.T, _forward_substitution(L, H @ P)).T
    x_plus = x + K @ nu
    I_KH = np.eye(x.shape[0]) - K @ H
    P_plus = I_KH @ P @ I_KH.T + K @ R_joseph @ K.T
    P_plus = 0.5 * (P_plus + P_plus.T)
    if not (np.all(np.isfinite(x_plus)) and np.all(np.isfinite(P_plus))):
        raise NonFiniteError("update produced a non-finite state")
    return x_plus, P_plus


# --------------------------------------------------------------------------------------
# The modes
# --------------------------------------------------------------------------------------


@dataclass
class _Step:
    """One update's inputs after steps 1-3 (shared by every mode)."""

    x: np.ndarray
    P: np.ndarray
    H: np.ndarray
    R: np.ndarray
    nu: np.ndarray
    C: np.ndarray
    T: float
    nu_test: np.ndarray  # what the mode tests: nu itself, or the caller's test innovation
    C_test: np.ndarray  # its covariance (incl. R)
    pair_out: tuple[bool, ...] | None = None  # fuzzy rows: rows out whatever the alarm

    @property
    def m(self) -> int:
        return int(self.nu.shape[0])


@dataclass(frozen=True)
class _Outcome:
    """What a mode adds to the report; the defaults are the values of a mode that does not use them."""

    w: np.ndarray
    factor: float = 1.0
    q_scale: float = 1.0
    detected: bool = False
    rejected: bool = False
    alarm: bool = False
    left_out: tuple[bool, ...] | None = None  # rows the update did not use, if not those with w == 0


_Result = tuple[np.ndarray, np.ndarray, _Outcome]


def _outcome(
    m: int,
    w: np.ndarray | None = None,
    factor: float = 1.0,
    q_scale: float = 1.0,
    detected: bool = False,
    rejected: bool = False,
    alarm: bool = False,
    left_out: tuple[bool, ...] | None = None,
) -> _Outcome:
    """The outcome of an m-row update; w defaults to all ones."""
    w = np.ones(m) if w is None else w
    return _Outcome(w, float(factor), float(q_scale), bool(detected), bool(rejected), bool(alarm), left_out)


def _update_plain(step: _Step, cfg: RobustConfig, memory: RobustState) -> _Result:
    """Mode 0: section 1."""
    x, P = _gain_update(step.x, step.P, step.H, step.nu, step.C, step.R)
    return x, P, _outcome(step.m)


def _update_fta(step: _Step, cfg: RobustConfig, memory: RobustState) -> _Result:
    """Mode 1, paper 000: K = P H^T (gamma C)^-1 (eq. 15), Joseph with the nominal R (eq. 16)."""
    gamma = fta_gamma(step.T, step.m)
    x, P = _gain_update(step.x, step.P, step.H, step.nu, gamma * step.C, step.R)
    return x, P, _outcome(step.m, factor=gamma, detected=gamma > 1.0)


def _update_akf(step: _Step, cfg: RobustConfig, memory: RobustState) -> _Result:
    """Mode 2, paper 004 (ALGORITHMS.md 5 AKF steps 1-4)."""
    m = step.m
    # 1. Row statistics of the innovation (rows 0..m-1 of this update; the others keep theirs).
    r, s = akf_row_statistics(
        memory.nu_mean[:m], memory.nu_var[:m], step.nu_test, cfg.akf_forget, first=not memory.started
    )
    memory.nu_mean[:m], memory.nu_var[:m], memory.started = r, s, True
    # 2. Detection and R* (eq. 14-15).
    detected = step.T > chi2_quantile(AKF_ALPHA, m)
    R_star = akf_inflated_noise(step.R, s) if detected else step.R
    tr_r, tr_r_star = float(np.trace(step.R)), float(np.trace(R_star))
    if tr_r > 0.0:
        factor = tr_r_star / tr_r
    else:  # R = 0: no ratio; 1 when R* is R, else unbounded
        factor = 1.0 if tr_r_star == tr_r else math.inf
    # 3. Window of e = nu^T nu - tr(R), alpha (eq. 18) and the Q scale (eq. 19), for the next predict.
    e = float(step.nu @ step.nu) - tr_r
    memory.win = ([*memory.win, e])[-cfg.akf_window :]
    hph = step.H @ step.P @ step.H.T
    memory.q_scale = akf_q_scale(akf_alpha(memory.win, float(np.trace(hph))), cfg.akf_q_min, cfg.akf_q_max)
    # 4. Section 1 steps 4-6 with R*.
    x, P = _gain_update(step.x, step.P, step.H, step.nu, hph + R_star, R_star)
    return x, P, _outcome(m, factor=factor, q_scale=memory.q_scale, detected=detected)


def _update_fuzzy(step: _Step, cfg: RobustConfig, memory: RobustState) -> _Result:
    """Mode 3, paper 001: test first, then reject / inflate while alarmed, else section 1."""
    rows = cfg.fuzzy_reject == FUZZY_ROWS
    # the return rule of fuzzy rows reads the epoch before: its D, alarm and tested innovation
    onset = not memory.alarm and memory.d_k >= 0.5
    nu_prev = np.array(memory.nu_mean[: step.m], dtype=np.float64)
    memory.d_k, memory.alarm, _ = fuzzy_detector_step(memory.d_k, memory.alarm, step.T, step.m, rows)
    memory.nu_mean[: step.m] = step.nu_test  # the last tested innovation (read by fuzzy rows)
    pair = step.pair_out if rows and step.pair_out is not None else (False,) * step.m
    if rows and memory.alarm:
        out = _fuzzy_rows_out(step, memory, nu_prev if onset else None, paired=any(pair))
        return _rows_update(step, [o or p for o, p in zip(out, pair, strict=True)], alarm=True)
    if rows:
        out = [g or p for g, p in zip(_fuzzy_rows_gated(step), pair, strict=True)]
        if any(out):
            return _rows_update(step, out, alarm=False)
    if not memory.alarm:
        x, P = _gain_update(step.x, step.P, step.H, step.nu, step.C, step.R)
        return x, P, _outcome(step.m)
    if cfg.fuzzy_reject:
        return step.x, step.P, _outcome(step.m, detected=True, rejected=True, alarm=True)
    _, td2, _ = fuzzy_thresholds(step.m)
    gamma = max(1.0, step.T / td2)
    x, P = _gain_update(step.x, step.P, step.H, step.nu, gamma * step.C, step.R)
    return x, P, _outcome(step.m, factor=gamma, detected=True, alarm=True)


def _fuzzy_rows_out(
    step: _Step, memory: RobustState, nu_prev: np.ndarray | None, paired: bool = False
) -> list[bool]:
    """The rows fuzzy rows leaves out while alarmed (ALGORITHMS.md 5): a row fails when its own
    standardised test residual, nu_t,i^2 / C_t,ii, exceeds chi2_1(0.005) (2 chi2_1(1e-4) for the
    last row standing, see ``_fuzzy_row_tests``); while any row fails, the
    rows the last two updates left out (rejected, or removed) stay out too: one failure by chance
    (0.5 % of clean rows) does not keep a row out. No row failing leaves every row out (the
    joint test alone singles out none), unless the N/E pair has rows out of this update (``paired``;
    the caller adds them to these): then none more, and the rows neither failing nor paired are
    applied (session 28: the position hold of ALGORITHMS.md 8, GPS step 4, puts the position rows out
    while they pass their own test, and the velocity stays in).

    ``nu_prev``: at the alarm's first epoch after an applied epoch past TD2 (D_{k-1} >= 0.5), that
    epoch's tested innovation; a row whose innovation has the opposite sign, and is no larger, is
    the return from the outlier that epoch took in: it does not count as failing (if only such
    rows fail, the update takes every row)."""
    m = step.m
    fails, bad = _fuzzy_row_tests(step.nu_test, step.C_test, nu_prev, memory.n_removed)
    if not any(fails):
        return [not paired] * m
    if any(bad):
        # n_removed counts the updates in a row that left row i out (a rejection leaves every row out)
        were_out = [memory.n_removed[i] > 1 for i in range(m)]
        return [f or w for f, w in zip(bad, were_out, strict=True)]
    return [False] * m  # only returns fail: the update takes every row


def _fuzzy_rows_gated(step: _Step) -> list[bool]:
    """The rows fuzzy rows leaves out of an update that does not alarm (ALGORITHMS.md 5, the
    gate): a row whose test residual is past 2 chi2_1(1e-4), nu_t,i^2 > 30.3 C_t,ii, where the
    filter's own prediction agrees with the test's, (nu_i - nu_t,i)^2 <= C_t,ii. A fault the
    three-threshold rule does not alarm on at its first epoch (T between TD2 and TD3) is not
    taken in whole; a filter whose own prediction lags what the test's sees (a hard braking the
    CS acceleration has not caught up with) is not gated on that lag."""
    level = 2.0 * chi2_quantile(FUZZY_GATE_ALPHA, 1)
    return [
        float(step.nu_test[i]) ** 2 > level * float(step.C_test[i, i])
        and (float(step.nu[i]) - float(step.nu_test[i])) ** 2 <= float(step.C_test[i, i])
        for i in range(step.m)
    ]


def _fuzzy_row_tests(
    nu_t: np.ndarray, C_t: np.ndarray, nu_prev: np.ndarray | None, n_removed: list[int]
) -> tuple[list[bool], list[bool]]:
    """Per row of the test innovation: fails its own test; fails and is not a return (see
    ``_fuzzy_rows_out``). The level is chi2_1(0.005), or 2 chi2_1(1e-4) = 30.3 for the last row
    standing: the one row not out on the last two updates while every other row was
    (``n_removed``; a row the gate held out once does not make another row stand)."""
    m = int(nu_t.shape[0])
    was_out = [n_removed[i] > 1 for i in range(m)]
    standing = [
        not was_out[i] and m > 1 and all(was_out[j] for j in range(m) if j != i) for i in range(m)
    ]
    level = [
        2.0 * chi2_quantile(FUZZY_LAST_ROW_ALPHA, 1) if standing[i] else chi2_quantile(FUZZY_TD2_ALPHA, 1)
        for i in range(m)
    ]
    back = [
        nu_prev is not None
        and float(nu_t[i]) * float(nu_prev[i]) < 0.0
        and abs(float(nu_t[i])) <= abs(float(nu_prev[i]))
        for i in range(m)
    ]
    fails = [float(nu_t[i]) ** 2 > level[i] * float(C_t[i, i]) for i in range(m)]
    return fails, [f and not b for f, b in zip(fails, back, strict=True)]


def _test_statistic(nu_t: np.ndarray, C_t: np.ndarray) -> tuple[np.ndarray, float]:
    """The symmetrised test covariance and T = nu_t^T C_t^-1 nu_t (ALGORITHMS.md 5, test
    innovation)."""
    C_t = 0.5 * (C_t + C_t.T)
    y = _forward_substitution(_cholesky(C_t), nu_t)
    return C_t, float(y @ y)


def _rows_update(step: _Step, out: list[bool], alarm: bool) -> _Result:
    """Section 1 on the rows not in ``out``; every row out rejects the update. The report's w
    stays 1."""
    m = step.m
    kept = [i for i in range(m) if not out[i]]
    if not kept:
        everything = (True,) * m
        return step.x, step.P, _outcome(m, detected=alarm, rejected=True, alarm=alarm, left_out=everything)
    H_k, R_k = step.H[kept], step.R[np.ix_(kept, kept)]
    x, P = _gain_update(step.x, step.P, H_k, step.nu[kept], H_k @ step.P @ H_k.T + R_k, R_k)
    return x, P, _outcome(m, detected=alarm, alarm=alarm, left_out=tuple(out))


def fuzzy_rows_failed(
    cfg: RobustConfig, state: RobustState, nu_t: np.ndarray, C_t: np.ndarray
) -> tuple[bool, ...]:
    """The rows a fuzzy-rows update tested on (nu_t, C_t) would leave out, if it alarms, for
    failing their own test, and the rows it keeps out that went out with them (ALGORITHMS.md 5,
    the N/E pair); none when no row fails or the detector does not alarm. Reads ``state``,
    changes nothing."""
    nu_t = _as_float_array("test nu", nu_t, 1)
    C_t = _as_float_array("test C", C_t, 2)
    m = int(nu_t.shape[0])
    if cfg.mode != "fuzzy" or cfg.fuzzy_reject != FUZZY_ROWS:
        return (False,) * m
    C_t, T = _test_statistic(nu_t, C_t)
    _, alarm, _ = fuzzy_detector_step(state.d_k, state.alarm, T, m, True)
    if not alarm:
        return (False,) * m
    onset = not state.alarm and state.d_k >= 0.5
    nu_prev = np.array(state.nu_mean[:m], dtype=np.float64) if onset else None
    _, bad = _fuzzy_row_tests(nu_t, C_t, nu_prev, state.n_removed)
    if not any(bad):
        return (False,) * m
    # with them, the rows kept out (out on the last two updates) that went out no later than the
    # longest-out failing row: the other part of a fault of both, not a row out on its own since
    longest = max(state.n_removed[i] for i in range(m) if bad[i])
    return tuple(bad[i] or (state.n_removed[i] > 1 and state.n_removed[i] >= longest) for i in range(m))


def _update_igg3(step: _Step, cfg: RobustConfig, memory: RobustState) -> _Result:
    """Mode 4, paper 003: reweight rows, then section 1 on the kept rows with the equivalent R."""
    # rows weighted by the tested residuals; C_test - R plays H P H^T's part in the iteration
    w, R_eq, _ = igg_reweight(step.nu_test, step.C_test - step.R, step.R, cfg.igg_k0, cfg.igg_k1)
    detected = bool(np.any(w < 1.0))
    kept = np.flatnonzero(w > 0.0)
    if kept.size == 0:
        return step.x, step.P, _outcome(step.m, w=w, detected=True, rejected=True)
    H_k, R_k = step.H[kept], R_eq[np.ix_(kept, kept)]
    x, P = _gain_update(step.x, step.P, H_k, step.nu[kept], H_k @ step.P @ H_k.T + R_k, R_k)
    return x, P, _outcome(step.m, w=w, detected=detected)


_MODE_UPDATES = {
    "plain": _update_plain,
    "fta": _update_fta,
    "akf": _update_akf,
    "fuzzy": _update_fuzzy,
    "igg3": _update_igg3,
}


def _working_copy(state: RobustState) -> RobustState:
    """A checked deep copy of the memory: the mode works on it, the caller's is replaced on success."""
    nu_mean = np.array(state.nu_mean, dtype=np.float64)
    nu_var = np.array(state.nu_var, dtype=np.float64)
    if nu_mean.shape != (M_MAX,) or nu_var.shape != (M_MAX,):
        raise BadArgError(f"state.nu_mean and state.nu_var must have shape ({M_MAX},)")
    memory = RobustState(
        win=[float(v) for v in state.win],
        nu_mean=nu_mean,
        nu_var=nu_var,
        q_scale=float(state.q_scale),
        d_k=float(state.d_k),
        alarm=bool(state.alarm),
        started=bool(state.started),
        n_reject=int(state.n_reject),  # read by fuzzy rows; the guard below counts on from the caller's
        n_removed=[int(v) for v in state.n_removed],
        caller_out=[bool(v) for v in state.caller_out],
    )
    if not _memory_is_finite(memory):
        raise NonFiniteError("robust state is not finite")
    return memory


def _memory_is_finite(memory: RobustState) -> bool:
    scalars = [*memory.win, memory.q_scale, memory.d_k]
    return bool(
        np.all(np.isfinite(memory.nu_mean))
        and np.all(np.isfinite(memory.nu_var))
        and np.all(np.isfinite(scalars))
    )


def robust_update(
    x: np.ndarray,
    P: np.ndarray,
    H: np.ndarray,
    z: np.ndarray,
    R: np.ndarray,
    cfg: RobustConfig,
    state: RobustState,
    test: tuple[np.ndarray, np.ndarray] | None = None,
    pair_out: tuple[bool, ...] | None = None,
) -> tuple[np.ndarray, np.ndarray, RobustReport]:
    """Measurement update in the mode ``cfg.mode`` (ALGORITHMS.md 5).

    ``pair_out`` (fuzzy rows only; m flags): rows this update leaves out whatever its alarm, the
    paired horizontal axis' failing rows (``fuzzy_rows_failed``; ALGORITHMS.md 5, the N/E pair), to
    which the memory's ``caller_out`` rows are added (the caller's rows; the update clears them). While
    alarmed with no row failing, any such row out applies the rows neither failing nor paired instead of
    rejecting the update (session 28).

    ``test = (nu_t, C_t)``: the mode tests this innovation and covariance (incl. R) instead of
    the update's own (ALGORITHMS.md 5, test innovation): T, IGG-III residuals and AKF row
    statistics come from it; gain, correction, Joseph and the AKF Q window keep the nominal
    ones. The report's T is the tested one, its nu and C the nominal ones.

    Steps 1-3 of section 1 with the nominal R (nu, C, Cholesky, T), then the mode. ``state``
    is updated in place, and only when the whole update succeeds.

    Args:
        x, P, H, z, R: as ``kf_update`` (R full (m, m) or its diagonal (m,)); m <= M_MAX.
        cfg: the mode and its parameters.
        state: the filter's robust memory.

    Returns:
        (x_plus, P_plus, report): new arrays (a rejected update returns copies of x and P).

    Raises:
        BadConfigError: cfg out of range.
        BadArgError: shapes inconsistent, m == 0 or m > M_MAX, P / R not symmetric, or a
            state of the wrong shape.
        NonFiniteError: an input or the state is NaN/Inf, the innovation overflows, or x+, P+
            or the memory would be non-finite.
        SingularError: C (or the gain's innovation covariance) is not positive definite.
    """
    cfg.validate()
    x, P, H, z, R = _checked_inputs(x, P, H, z, R)
    memory = _working_copy(state)
    nu, C, T = _innovation(x, P, H, z, R)
    nu_t, C_t = nu, C
    if test is not None:
        nu_t = _as_float_array("test nu", test[0], 1)
        C_t = _as_float_array("test C", test[1], 2)
        if nu_t.shape != nu.shape or C_t.shape != C.shape:
            raise BadArgError(f"test innovation shapes {nu_t.shape}, {C_t.shape} do not match m = {nu.size}")
        if not (np.all(np.isfinite(nu_t)) and np.all(np.isfinite(C_t))):
            raise NonFiniteError("test innovation is not finite")
        C_t, T = _test_statistic(nu_t, C_t)
    if pair_out is not None and len(pair_out) != nu.size:
        raise BadArgError(f"pair_out has {len(pair_out)} rows, the update {nu.size}")
    if len(memory.caller_out) != M_MAX:
        raise BadArgError(f"state.caller_out must have {M_MAX} entries")
    pair = None if pair_out is None else tuple(bool(v) for v in pair_out)
    if cfg.mode == "fuzzy" and cfg.fuzzy_reject == FUZZY_ROWS and any(memory.caller_out[: nu.size]):
        # the caller's rows go out with the pair's: the memory carries them into this update (ALGORITHMS.md 5)
        caller = tuple(memory.caller_out[: nu.size])
        pair = caller if pair is None else tuple(a or b for a, b in zip(pair, caller, strict=True))
    memory.caller_out = [False] * M_MAX  # this update clears them
    step = _Step(
        x=x,
        P=P,
        H=H,
        R=R,
        nu=nu,
        C=C,
        T=T,
        nu_test=nu_t,
        C_test=C_t,
        pair_out=pair,
    )
    with np.errstate(over="ignore", invalid="ignore"):  # every result is checked for finiteness
        x_plus, P_plus, outcome = _MODE_UPDATES[cfg.mode](step, cfg, memory)
    # Lock-up guard (ALGORITHMS.md 5): the reject_reset_n-th rejection in a row, or the
    # row_reset_n-th removal in a row of one row, becomes a plain update with the nominal R and
    # the memory starts afresh.
    removed = list(outcome.left_out) if outcome.left_out is not None else [bool(w == 0.0) for w in outcome.w]
    n_removed = [int(v) for v in state.n_removed]
    # Fuzzy rows' long guard presumes a caller that coasts on the prediction it tests against;
    # an update without a test innovation runs on the filter's own mean: the default guard.
    guard = cfg.reject_reset_n
    if cfg.mode == "fuzzy" and cfg.fuzzy_reject == FUZZY_ROWS and test is None:
        guard = min(guard, RESET_N_DEFAULT)
    reset = bool(outcome.rejected) and 0 < guard <= int(state.n_reject) + 1
    reset = reset or any(r and 0 < cfg.row_reset_n <= n_removed[i] + 1 for i, r in enumerate(removed))
    if reset:
        x_plus, P_plus, plain = kf_update(x, P, H, z, R)
        memory = RobustState()
        nu, C = plain.nu, plain.C  # T stays the tested one
        outcome = replace(
            outcome, factor=1.0, w=np.ones(step.m), q_scale=1.0, detected=False, rejected=False, alarm=False
        )
    else:
        memory.n_reject = min(int(state.n_reject) + 1, 254) if outcome.rejected else 0
        for i, r in enumerate(removed):
            n_removed[i] = min(n_removed[i] + 1, 254) if r else 0
        memory.n_removed = n_removed
    # Step 6 extended to the memory: an update that would leave it non-finite (AKF e = nu^T nu
    # overflowing) changes nothing, like one that would leave x+ or P+ non-finite.
    if not _memory_is_finite(memory):
        raise NonFiniteError("update would leave a non-finite robust memory")
    # Commit: the only place the caller's memory changes.
    state.win, state.nu_mean, state.nu_var = memory.win, memory.nu_mean, memory.nu_var
    state.q_scale, state.d_k, state.alarm, state.started, state.n_reject = (
        memory.q_scale,
        memory.d_k,
        memory.alarm,
        memory.started,
        memory.n_reject,
    )
    state.n_removed = list(memory.n_removed)
    state.caller_out = list(memory.caller_out)
    return (
        x_plus,
        P_plus,
        RobustReport(
            m=step.m,
            nu=nu,
            C=C,
            T=T,
            factor=float(outcome.factor),
            w=outcome.w,
            q_scale=float(outcome.q_scale),
            detected=bool(outcome.detected),
            rejected=bool(outcome.rejected),
            alarm=bool(outcome.alarm),
            reset=reset,
            tested=test is not None,
        ),
    )

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
from dataclasses import dataclass, field

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
    for name, a in (("x", x), ("P", P), ("H", H), ("z", z), ("R", R)):
        if not np.all(np.isfinite(a)):
            raise NonFiniteError(f"{name} is not finite")
    _check_symmetric("P", P)
    _check_symmetric("R", R)

    # Step 1: innovation and its covariance.
    nu = z - H @ x
    C = H @ P @ H.T + R
    if not np.all(np.isfinite(C)):
        raise NonFiniteError("innovation covariance overflowed")

    # Step 2: C symmetric positive definite <=> its Cholesky factor exists.
    try:
        L = np.linalg.cholesky(C)  # C = L L^T, reads the lower triangle
    except np.linalg.LinAlgError as exc:
        raise SingularError("innovation covariance is not positive definite") from exc
    if not np.all(np.diag(L) > 0.0):  # LAPACK accepts an exact-zero pivot on some builds
        raise SingularError("innovation covariance is not positive definite")

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

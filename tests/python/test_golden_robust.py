"""Golden robust and adaptive updates (python/mcahrs/golden/robust.py, ALGORITHMS.md 5) against
hand-worked numbers, the papers' own statements (000 FTA, 004 AKF, 001 fuzzy detector, 003
IGG-III) and the plain ``kf_update`` of section 1."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from mcahrs.errors import BadArgError, BadConfigError, NonFiniteError, SingularError
from mcahrs.golden.robust import (
    MODES,
    RobustConfig,
    RobustReport,
    RobustState,
    UpdateReport,
    akf_alpha,
    akf_q_scale,
    akf_row_statistics,
    chi2_quantile,
    fta_gamma,
    fuzzy_detector_step,
    fuzzy_memberships,
    fuzzy_mu,
    fuzzy_rows_failed,
    fuzzy_thresholds,
    igg_reweight,
    igg_weight,
    kf_update,
    robust_update,
)

# Hand-worked floating point agrees with the model to a few ulps of O(1) numbers.
TIGHT = dict(rtol=1e-13, atol=1e-13)


def _random_problem(rng: np.random.Generator, n: int, m: int, outlier: float = 0.0) -> tuple[np.ndarray, ...]:
    """A well-conditioned random update: x (n), P (n, n) SPD, H (m, n), z (m), R (m,) diagonal."""
    A = rng.normal(size=(n, n))
    P = A @ A.T + 0.5 * np.eye(n)
    H = rng.normal(size=(m, n))
    x = rng.normal(size=n)
    R = rng.uniform(0.2, 2.0, size=m)
    C = H @ P @ H.T + np.diag(R)
    z = H @ x + np.linalg.cholesky(C) @ rng.normal(size=m)
    z[0] += outlier
    return x, P, H, z, R


def _state_fields(state: RobustState) -> tuple:
    return (
        list(state.win),
        np.array(state.nu_mean).tolist(),
        np.array(state.nu_var).tolist(),
        state.q_scale,
        state.d_k,
        state.alarm,
        state.started,
    )


# A 2-state, 1-row problem whose numbers can be worked by hand: C = 4 + 1 = 5, T = z^2 / 5.
X0 = np.array([0.0, 0.0])
P0 = np.array([[4.0, 1.0], [1.0, 2.0]])
H0 = np.array([[1.0, 0.0]])
R0 = np.array([1.0])


# --------------------------------------------------------------------------------------
# Configuration, memory, report
# --------------------------------------------------------------------------------------


def test_config_and_state_defaults_are_the_documented_ones() -> None:
    cfg = RobustConfig()
    assert (cfg.mode, cfg.fuzzy_reject, cfg.akf_window, cfg.akf_forget) == ("plain", True, 8, 0.2)
    assert (cfg.akf_q_min, cfg.akf_q_max, cfg.igg_k0, cfg.igg_k1) == (0.5, 10.0, 1.5, 3.0)
    st = RobustState()
    assert st.win == [] and st.q_scale == 1.0 and st.d_k == 0.0 and not st.alarm and not st.started
    assert np.array_equal(st.nu_mean, np.zeros(6)) and np.array_equal(st.nu_var, np.zeros(6))


@pytest.mark.parametrize(
    "bad",
    [
        dict(mode="huber"),
        dict(mode=1),
        dict(akf_window=0),
        dict(akf_window=2.5),
        dict(akf_forget=0.0),
        dict(akf_forget=1.5),
        dict(akf_q_min=0.0),
        dict(akf_q_min=11.0),
        dict(akf_q_max=math.inf),
        dict(igg_k0=3.0),
        dict(igg_k1=math.nan),
    ],
)
def test_config_out_of_range_is_bad_config(bad: dict) -> None:
    with pytest.raises(BadConfigError):
        RobustConfig(**bad).validate()


def test_report_extends_update_report_and_uses_neutral_values_where_unused() -> None:
    _, _, rep = robust_update(X0, P0, H0, [1.0], R0, RobustConfig("plain"), RobustState())
    assert isinstance(rep, RobustReport) and isinstance(rep, UpdateReport)
    assert rep.m == 1 and rep.T == pytest.approx(0.2, rel=1e-15)
    assert (rep.factor, rep.q_scale, rep.detected, rep.rejected, rep.alarm) == (1.0, 1.0, False, False, False)
    assert np.array_equal(rep.w, [1.0])


def test_chi2_quantiles_are_the_papers_thresholds() -> None:
    # Paper 001, 2.3: m = 6, TD1 = 14.45 (0.025), TD2 = 18.55 (0.005); printed to 2 decimals.
    td1, td2, td3 = fuzzy_thresholds(6)
    assert td1 == pytest.approx(14.45, abs=0.005)
    assert td2 == pytest.approx(18.55, abs=0.005)
    assert td3 == 10.0 * td2
    # Upper quantile, not lower: P(chi2_1 > 3.8415) = 0.05.
    assert chi2_quantile(0.05, 1) == pytest.approx(3.841458820694124, rel=1e-12)


# --------------------------------------------------------------------------------------
# Plain (mode 0) and the Joseph covariance of every mode
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("m", [1, 2, 3, 6])
def test_plain_mode_equals_kf_update_bit_for_bit(m: int) -> None:
    rng = np.random.default_rng(10 + m)
    for outlier in (0.0, 50.0):
        x, P, H, z, R = _random_problem(rng, 7, m, outlier)
        st = RobustState()
        xr, Pr, rep = robust_update(x, P, H, z, R, RobustConfig("plain"), st)
        xk, Pk, rk = kf_update(x, P, H, z, R)
        # Same operations in the same order: identical, not merely close.
        assert np.array_equal(xr, xk) and np.array_equal(Pr, Pk)
        assert rep.T == rk.T and np.array_equal(rep.nu, rk.nu) and np.array_equal(rep.C, rk.C)
        assert _state_fields(st) == _state_fields(RobustState())  # plain keeps no memory


@pytest.mark.parametrize("mode", MODES)
def test_joseph_covariance_is_symmetric_psd_and_never_grows(mode: str) -> None:
    rng = np.random.default_rng(2024)
    cfg = RobustConfig(mode, fuzzy_reject=False)  # fuzzy: exercise the inflated gain too
    st = RobustState()
    for k in range(200):
        m = int(rng.integers(1, 7))
        outlier = float(rng.choice([0.0, 0.0, 5.0, 40.0, 400.0]))
        x, P, H, z, R = _random_problem(rng, 6, m, outlier)
        _, Pn, _ = robust_update(x, P, H, z, R, cfg, st)
        assert np.array_equal(Pn, Pn.T), k
        scale = np.linalg.norm(P)
        # Every mode's gain is K = P H^T C'^-1 with C' >= H P H^T + R_joseph, so P+ <= P and
        # P+ >= 0; 1e-12 relative is rounding of 6x6 products of O(scale) numbers.
        assert np.linalg.eigvalsh(Pn).min() >= -1e-12 * scale, k
        assert np.linalg.eigvalsh(P - Pn).min() >= -1e-12 * scale, k


# --------------------------------------------------------------------------------------
# FTA (mode 1, paper 000)
# --------------------------------------------------------------------------------------


def test_fta_gamma_and_gain_on_a_crafted_outlier() -> None:
    z = 30.0  # T = 900 / 5 = 180 against chi2_1(1e-4) = 15.1367
    xn, Pn, rep = robust_update(X0, P0, H0, [z], R0, RobustConfig("fta"), RobustState())
    gamma = 180.0 / 15.136705226623606  # eq. 13 (quantile: scipy, checked to 1e-12 below)
    assert chi2_quantile(1e-4, 1) == pytest.approx(15.136705226623606, rel=1e-12)
    assert rep.T == pytest.approx(180.0, rel=1e-15)
    assert rep.factor == pytest.approx(gamma, rel=1e-12) and rep.detected and not rep.rejected
    # Eq. 15 by hand: K = P H^T / (gamma C) = [4, 1] / (5 gamma).
    K = np.array([4.0, 1.0]) / (5.0 * gamma)
    assert np.allclose(xn, K * z, **TIGHT)
    # Eq. 16, Joseph with the nominal R = 1.
    I_KH = np.eye(2) - np.outer(K, H0[0])
    assert np.allclose(Pn, I_KH @ P0 @ I_KH.T + np.outer(K, K), **TIGHT)
    # The outlier moves the state 1/gamma as far as the plain filter lets it.
    xk, _, _ = kf_update(X0, P0, H0, [z], R0)
    assert np.allclose(xn, xk / gamma, **TIGHT)


def test_fta_is_plain_at_and_below_the_threshold() -> None:
    thr = chi2_quantile(1e-4, 2)
    assert fta_gamma(thr, 2) == 1.0 and fta_gamma(0.0, 2) == 1.0
    assert fta_gamma(2.0 * thr, 2) == pytest.approx(2.0, rel=1e-15)
    z = [math.sqrt(5.0 * 15.0)]  # T = 15 < 15.1367
    xn, Pn, rep = robust_update(X0, P0, H0, z, R0, RobustConfig("fta"), RobustState())
    xk, Pk, _ = kf_update(X0, P0, H0, z, R0)
    assert rep.factor == 1.0 and not rep.detected
    assert np.array_equal(xn, xk) and np.array_equal(Pn, Pk)


# --------------------------------------------------------------------------------------
# AKF (mode 2, paper 004)
# --------------------------------------------------------------------------------------


def test_akf_row_statistics_start_at_the_first_innovation_then_forget_exponentially() -> None:
    r, s = akf_row_statistics(np.zeros(2), np.zeros(2), np.array([1.0, -2.0]), 0.2, first=True)
    assert np.array_equal(r, [1.0, -2.0]) and np.array_equal(s, [0.0, 0.0])
    r2, s2 = akf_row_statistics(r, np.array([0.5, 0.1]), np.array([3.0, 0.0]), 0.2, first=False)
    assert np.allclose(r2, [0.8 * 1.0 + 0.2 * 3.0, 0.8 * -2.0], **TIGHT)  # [1.4, -1.6]
    assert np.allclose(s2, [0.8 * 0.5 + 0.2 * 1.6**2, 0.8 * 0.1 + 0.2 * 1.6**2], **TIGHT)


def test_akf_raises_r_by_the_innovation_variance_on_detection() -> None:
    rng = np.random.default_rng(4)
    x, P, H, z, R = _random_problem(rng, 5, 2)
    st = RobustState(nu_mean=np.array([0.3, -0.2, 9, 9, 9, 9.0]), nu_var=np.array([0.4, 0.1, 9, 9, 9, 9.0]))
    st.started = True
    z = z + np.array([25.0, -8.0])  # an outlier on both rows
    nu = z - H @ x
    r = 0.8 * np.array([0.3, -0.2]) + 0.2 * nu
    s = 0.8 * np.array([0.4, 0.1]) + 0.2 * (nu - r) ** 2
    R_star = np.diag(R) + np.diag(s)  # eq. 15
    xn, Pn, rep = robust_update(x, P, H, z, R, RobustConfig("akf"), st)
    assert rep.T > chi2_quantile(1e-2, 2) and rep.detected
    xk, Pk, _ = kf_update(x, P, H, z, R_star)
    assert np.allclose(xn, xk, **TIGHT) and np.allclose(Pn, Pk, **TIGHT)
    assert rep.factor == pytest.approx(np.trace(R_star) / R.sum(), rel=1e-14)
    assert np.allclose(st.nu_mean[:2], r, **TIGHT) and np.allclose(st.nu_var[:2], s, **TIGHT)
    assert np.array_equal(st.nu_mean[2:], [9, 9, 9, 9]), "rows beyond m keep their memory"
    # Report C and T are the nominal ones (the test statistic, not the inflated covariance).
    assert np.allclose(rep.C, H @ P @ H.T + np.diag(R), **TIGHT)


def test_akf_without_detection_uses_the_nominal_r_but_still_learns() -> None:
    st = RobustState()
    xn, Pn, rep = robust_update(X0, P0, H0, [1.0], R0, RobustConfig("akf"), st)
    xk, Pk, _ = kf_update(X0, P0, H0, [1.0], R0)
    assert not rep.detected and rep.factor == 1.0
    assert np.allclose(xn, xk, **TIGHT) and np.allclose(Pn, Pk, **TIGHT)
    assert st.started and st.nu_mean[0] == 1.0 and st.nu_var[0] == 0.0 and st.win == [0.0]


@pytest.mark.parametrize(
    ("nu", "expected"),
    [
        (math.sqrt(10.0), 2.0),  # e = 10 - 1 = 9, alpha = 9 / 3 = 3: log2(4) = 2
        (2.0, 1.0),  # e = 3, alpha = 1: log2(2) = 1, Q unchanged
        (0.0, 0.5),  # e = -1, alpha = -1/3: log2(2/3) < 0 -> q_min
        (100.0, 10.0),  # log2(1 + 9999/3) = 11.7 -> q_max
    ],
)
def test_akf_q_scale_is_log2_alpha_plus_one_clamped(nu: float, expected: float) -> None:
    # m = 1, H P H^T = 3, R = 1: e = nu^2 - 1, alpha = mean(e) / 3 (eq. 18), q = log2(alpha + 1).
    P = np.array([[3.0]])
    st = RobustState()
    cfg = RobustConfig("akf")
    for _ in range(12):  # more than the window: only the last 8 count
        _, _, rep = robust_update([0.0], P, [[1.0]], [nu], [1.0], cfg, st)
    # Each epoch sees the same (x, P), so every window entry is the same e.
    assert rep.q_scale == pytest.approx(expected, rel=1e-14) and st.q_scale == rep.q_scale
    assert len(st.win) == 8 and np.allclose(st.win, nu * nu - 1.0, rtol=1e-15)


def test_akf_window_keeps_the_last_n_epochs_and_its_mean_drives_alpha() -> None:
    st = RobustState()
    cfg = RobustConfig("akf", akf_window=3)
    nus = [1.0, 2.0, 3.0, 4.0, 5.0]
    for nu in nus:
        _, _, rep = robust_update([0.0], [[1.0]], [[1.0]], [nu], [1.0], cfg, st)
    e = [v * v - 1.0 for v in nus[-3:]]  # [8, 15, 24]
    assert st.win == e
    assert rep.q_scale == pytest.approx(math.log2(np.mean(e) / 1.0 + 1.0), rel=1e-15)  # log2(16.67)
    # Eq. 18-19 building blocks, including the degenerate denominators (IEEE, then the clamp).
    assert akf_alpha([3.0, 5.0], 2.0) == 2.0
    assert akf_q_scale(3.0, 0.5, 10.0) == 2.0
    assert akf_q_scale(-1.0, 0.5, 10.0) == 0.5 and akf_q_scale(-5.0, 0.5, 10.0) == 0.5
    assert akf_q_scale(akf_alpha([1.0], 0.0), 0.5, 10.0) == 10.0
    assert akf_q_scale(akf_alpha([0.0], 0.0), 0.5, 10.0) == 0.5


# --------------------------------------------------------------------------------------
# Fuzzy three-threshold detector (mode 3, paper 001)
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("m", [1, 2, 3, 4, 5, 6])
def test_fuzzy_mu_is_a_h_half_and_one_at_the_three_thresholds(m: int) -> None:
    td1, td2, td3 = fuzzy_thresholds(m)
    a_h = td1 / td3
    assert fuzzy_mu(td1, m) == pytest.approx(a_h, rel=1e-15)
    assert fuzzy_mu(td2, m) == pytest.approx(0.5, rel=1e-15)
    assert fuzzy_mu(td3, m) == pytest.approx(1.0, rel=1e-15)
    assert fuzzy_mu(0.0, m) == pytest.approx(a_h, rel=1e-15) and fuzzy_mu(5 * td3, m) == 1.0
    # The memberships are a partition of unity and mu is continuous and non-decreasing.
    ts = np.concatenate([np.linspace(0, 1.2 * td3, 4001), [td1, td2, td3]])
    for t in ts:
        assert sum(fuzzy_memberships(t, td1, td2, td3)) == pytest.approx(1.0, abs=1e-15)
    mus = [fuzzy_mu(t, m) for t in np.sort(ts)]
    assert np.all(np.diff(mus) >= -1e-15)
    for t in (td1, td2, td3):  # no jump at a threshold: slopes are < 1 per unit of T
        assert abs(fuzzy_mu(t + 1e-9, m) - fuzzy_mu(t - 1e-9, m)) < 1e-8


def test_fuzzy_alarm_needs_two_consecutive_t_above_td3_from_d0() -> None:
    """Paper 001, 2.2: 'when T_k exceeds TD3 twice in a row, D_k > 1 must hold'."""
    _, _, td3 = fuzzy_thresholds(1)
    big = 2.0 * td3
    d, alarm, mu = fuzzy_detector_step(0.0, False, big, 1)
    assert (d, alarm, mu) == (1.0, False, 1.0)  # D = 1 is not > 1
    d, alarm, _ = fuzzy_detector_step(d, alarm, big, 1)
    assert (d, alarm) == (1.5, True)

    # The same through robust_update: x and P are passed unchanged each call, so T is set by z.
    z = [math.sqrt(5.0 * big)]  # T = z^2 / 5 = big
    st = RobustState()
    x1, P1, rep1 = robust_update(X0, P0, H0, z, R0, RobustConfig("fuzzy"), st)
    xk, Pk, _ = kf_update(X0, P0, H0, z, R0)
    assert not rep1.alarm and not rep1.rejected and np.array_equal(x1, xk) and np.array_equal(P1, Pk)
    x2, P2, rep2 = robust_update(X0, P0, H0, z, R0, RobustConfig("fuzzy"), st)
    assert rep2.alarm and rep2.detected and rep2.rejected and st.alarm and st.d_k == 1.5
    assert np.array_equal(x2, X0) and np.array_equal(P2, P0)  # rejected: unchanged


def test_fuzzy_single_large_outlier_alarms_after_clean_history() -> None:
    # Clean epochs drive D to 2 a_H; then one T > TD3 gives D = a_H + 1 > 1 (not in the paper's
    # text, a consequence of eq. 12: the "two in a row" statement is sufficient, not necessary).
    td1, _, td3 = fuzzy_thresholds(2)
    d, alarm = 0.0, False
    for _ in range(60):
        d, alarm, _ = fuzzy_detector_step(d, alarm, 1.0, 2)
    assert d == pytest.approx(2.0 * td1 / td3, rel=1e-12) and not alarm
    d, alarm, _ = fuzzy_detector_step(d, alarm, 1.5 * td3, 2)
    assert alarm and d == pytest.approx(1.0 + td1 / td3, rel=1e-12)


def test_fuzzy_release_needs_t_below_td2_and_d_below_one_then_clears_d() -> None:
    td1, td2, td3 = fuzzy_thresholds(2)
    a_h = td1 / td3
    # From D = 1.5 (just alarmed), one clean epoch: D = 0.75 + a_H < 1 and T < TD2: release, D = 0.
    assert fuzzy_detector_step(1.5, True, 0.5, 2) == (0.0, False, pytest.approx(a_h))
    # From D = 2 (a long fault), the first clean epoch leaves D = 1 + a_H: still alarmed...
    d, alarm, _ = fuzzy_detector_step(2.0, True, 0.5, 2)
    assert alarm and d == pytest.approx(1.0 + a_h, rel=1e-15)
    # ...the second releases.
    d, alarm, _ = fuzzy_detector_step(d, alarm, 0.5, 2)
    assert (d, alarm) == (0.0, False)
    # Alarmed with D < 1 after the step but T >= TD2: no release (both conditions needed).
    t = td2 + 0.2 * (td3 - td2)  # mu = 0.6
    d, alarm, mu = fuzzy_detector_step(0.0, True, t, 2)
    assert mu == pytest.approx(0.6, rel=1e-12) and d < 1.0 and alarm
    # T < TD2 but D >= 1: no release either.
    d, alarm, _ = fuzzy_detector_step(1.96, True, td2 - 1e-9, 2)
    assert d > 1.0 and alarm
    # Not alarmed: D < 1 just decays, never cleared by the release rule.
    d, alarm, _ = fuzzy_detector_step(0.9, False, 0.5, 2)
    assert d == pytest.approx(0.45 + a_h) and not alarm


def test_fuzzy_release_epoch_is_applied_and_inflate_option_uses_t_over_td2() -> None:
    _, td2, td3 = fuzzy_thresholds(1)
    st = RobustState(d_k=1.5, alarm=True)
    xn, Pn, rep = robust_update(X0, P0, H0, [1.0], R0, RobustConfig("fuzzy"), st)
    xk, Pk, _ = kf_update(X0, P0, H0, [1.0], R0)
    assert not rep.alarm and not rep.rejected and st.d_k == 0.0
    assert np.array_equal(xn, xk) and np.array_equal(Pn, Pk)

    st = RobustState(d_k=1.5, alarm=True)
    z = math.sqrt(5.0 * 3.0 * td3)  # T = 3 TD3
    xn, _, rep = robust_update(X0, P0, H0, [z], R0, RobustConfig("fuzzy", fuzzy_reject=False), st)
    gamma = 3.0 * td3 / td2  # = 30
    assert rep.alarm and not rep.rejected and rep.factor == pytest.approx(gamma, rel=1e-12)
    assert np.allclose(xn, np.array([4.0, 1.0]) / (5.0 * gamma) * z, **TIGHT)


def test_fuzzy_rows_long_guard_holds_only_with_a_test_innovation() -> None:
    """ALGORITHMS.md 5, lock-up guard: fuzzy rows' guard of reject_reset_n rejections in a row
    presumes a caller that coasts on the prior it tests against; an update without a test
    innovation (the filter runs on its own mean) gets the default guard of 5."""
    cfg = RobustConfig("fuzzy", fuzzy_reject=2, reject_reset_n=100, row_reset_n=0)
    H, R = np.eye(2), np.diag([0.1, 0.1])
    x, P, z = np.zeros(2), np.eye(2), np.array([100.0, 50.0])  # both rows fail every update
    for tested in (False, True):
        st = RobustState()
        test = (z - H @ x, H @ P @ H.T + R) if tested else None
        first_reset = None
        for k in range(1, 13):
            xn, _, rep = robust_update(x, P, H, z, R, cfg, st, test=test)
            if rep.reset:
                first_reset = k
                assert xn[0] > 50.0 and xn[1] > 25.0  # the plain update
                break
            assert rep.rejected and np.array_equal(xn, x)
        # every update rejected (fuzzy rows alarm at D = 1): the default guard's fifth is update 5
        assert first_reset == (None if tested else 5)


def test_fuzzy_rows_alarm_at_d_one_and_keep_a_row_out_after_two_updates() -> None:
    """ALGORITHMS.md 5, fuzzy rows, two independent rows (H = I, P = I, R = 0.1 I): one epoch past
    TD3 from D = 0 alarms (D = 1; the reject variant waits for a second, the paper's rule); while
    alarmed the failing row is left out and the other applied; a row out on the last two updates
    stays out while another fails, a row out on one only comes back."""
    H, R, P = np.eye(2), np.diag([0.1, 0.1]), np.eye(2)
    far, both = np.array([100.0, 0.1]), np.array([100.0, 50.0])
    st_rej = RobustState()
    _, _, rep = robust_update(np.zeros(2), P, H, far, R, RobustConfig("fuzzy"), st_rej)
    assert not rep.alarm and st_rej.d_k == pytest.approx(1.0)
    cfg = RobustConfig("fuzzy", fuzzy_reject=2)
    st = RobustState()
    # z; then alarm, rejected, x[0] / x[1] moved
    steps = [
        (far, True, False, False, True),  # D = 1: alarm; row 0 out, row 1 applied
        (both, True, True, False, False),  # both fail: rejected
        (far, True, False, False, True),  # row 1 passes, out on one update only: applied
        (both, True, True, False, False),
        (both, True, True, False, False),  # row 1 out on two updates in a row
        (far, True, True, False, False),  # row 1 passes but stays out while row 0 fails
    ]
    for k, (z, alarm, rejected, moved0, moved1) in enumerate(steps):
        xn, _, rep = robust_update(np.zeros(2), P, H, z, R, cfg, st)
        assert (rep.alarm, rep.rejected, xn[0] != 0.0, xn[1] != 0.0) == (alarm, rejected, moved0, moved1), k


# --------------------------------------------------------------------------------------
# IGG-III (mode 4, paper 003)
# --------------------------------------------------------------------------------------


def test_igg_weight_function_has_three_segments_and_is_continuous() -> None:
    k0, k1 = 1.5, 3.0
    assert igg_weight(0.0, k0, k1) == 1.0 and igg_weight(k0, k0, k1) == 1.0
    assert igg_weight(2.0, k0, k1) == pytest.approx((1.5 / 2.0) * (1.0 / 1.5) ** 2, rel=1e-15)  # 1/3
    assert igg_weight(k1, k0, k1) == 0.0 and igg_weight(10.0, k0, k1) == 0.0
    assert igg_weight(k0 + 1e-9, k0, k1) == pytest.approx(1.0, abs=1e-8)
    s = np.linspace(k0, k1, 1001)
    assert np.all(np.diff([igg_weight(v, k0, k1) for v in s]) <= 0.0)


def test_igg_iteration_downweights_the_largest_first_and_updates_with_the_equivalent_r() -> None:
    # P = I, H = I, R = I: C = 2 I, s_i = |nu_i| / sqrt(2). Standardised residuals [2, 5, 1].
    s = np.array([2.0, 5.0, 1.0])
    x, P, H, R = np.zeros(3), np.eye(3), np.eye(3), np.ones(3)
    z = s * math.sqrt(2.0)
    w, _, order = igg_reweight(z, np.eye(3), np.eye(3), 1.5, 3.0)
    assert order == [1, 0]  # 5 > k1 first (removed), then 2; 1 <= k0 stops
    st = RobustState()
    xn, Pn, rep = robust_update(x, P, H, z, R, RobustConfig("igg3"), st)
    assert np.allclose(rep.w, [1.0 / 3.0, 0.0, 1.0], **TIGHT) and rep.detected and not rep.rejected
    assert rep.factor == 1.0
    # Row 1 removed, row 0 with R_00 / w_0 = 3: the plain update of rows 0 and 2.
    xk, Pk, _ = kf_update(x, P, H[[0, 2]], z[[0, 2]], [3.0, 1.0])
    assert np.allclose(xn, xk, **TIGHT) and np.allclose(Pn, Pk, **TIGHT)
    assert _state_fields(st) == _state_fields(RobustState())  # IGG-III keeps no memory


def test_igg_ties_take_the_lowest_index_and_all_clean_rows_are_plain() -> None:
    nu = np.array([2.0, 1.0, 2.0]) * math.sqrt(2.0)  # C = 2 I: s = [2, 1, 2]
    w, _, order = igg_reweight(nu, np.eye(3), np.eye(3), 1.5, 3.0)
    assert order == [0, 2] and np.allclose(w, [1.0 / 3.0, 1.0, 1.0 / 3.0], **TIGHT)
    rng = np.random.default_rng(7)
    x, P, H, z, R = _random_problem(rng, 5, 3)
    C = H @ P @ H.T + np.diag(R)
    z = H @ x + 0.5 * np.sqrt(np.diag(C))  # every s_i = 0.5 <= k0
    xn, Pn, rep = robust_update(x, P, H, z, R, RobustConfig("igg3"), RobustState())
    xk, Pk, _ = kf_update(x, P, H, z, R)
    assert not rep.detected and np.array_equal(rep.w, np.ones(3))
    assert np.array_equal(xn, xk) and np.array_equal(Pn, Pk)


def test_igg_recomputed_residuals_equal_one_pass_weighting() -> None:
    # With innovation residuals C_ii depends on row i alone, so the iteration's recomputation
    # never changes a pending s_i: the weights are w(s_i) of the nominal C, even for correlated
    # H P H^T and full R (documented in igg_reweight).
    rng = np.random.default_rng(11)
    for _ in range(50):
        x, P, H, z, R = _random_problem(rng, 6, 6)
        Rf = np.diag(R) + 0.05 * np.ones((6, 6))
        z = z + rng.choice([0.0, 3.0, 6.0, 20.0], size=6) * rng.choice([-1, 1], size=6)
        nu = z - H @ x
        C = H @ P @ H.T + Rf
        s = np.abs(nu) / np.sqrt(np.diag(C))
        w, _, order = igg_reweight(nu, H @ P @ H.T, Rf, 1.5, 3.0)
        assert np.allclose(w, [igg_weight(v, 1.5, 3.0) for v in s], **TIGHT)
        assert order == sorted(np.flatnonzero(s > 1.5), key=lambda i: -s[i])


def test_igg_all_rows_removed_is_a_rejected_update() -> None:
    xn, Pn, rep = robust_update(X0, P0, H0, [100.0], R0, RobustConfig("igg3"), RobustState())
    assert rep.rejected and rep.detected and np.array_equal(rep.w, [0.0])
    assert np.array_equal(xn, X0) and np.array_equal(Pn, P0)


# --------------------------------------------------------------------------------------
# Errors leave the memory (and the inputs) unchanged
# --------------------------------------------------------------------------------------


def _warm_state(mode: str) -> RobustState:
    """A memory that has seen clean epochs and outliers (fuzzy: alarmed)."""
    st = RobustState()
    cfg = RobustConfig(mode)
    for z in (0.5, -1.0, 2.0, 60.0, 60.0):
        robust_update(X0, P0, H0, [z], R0, cfg, st)
    return st


@pytest.mark.parametrize("mode", MODES)
def test_errors_leave_state_and_inputs_unchanged(mode: str) -> None:
    st = _warm_state(mode)
    if mode == "fuzzy":
        assert st.alarm
    if mode == "akf":
        assert st.started and len(st.win) == 5
    before = _state_fields(st)
    cfg = RobustConfig(mode)
    P_in = P0.copy()
    cases = [
        (BadArgError, (X0, P0, H0, [1.0, 2.0], R0, cfg)),  # z of the wrong size
        (BadArgError, (np.zeros(7), np.eye(7), np.ones((7, 7)), np.zeros(7), np.ones(7), cfg)),  # m > 6
        (BadArgError, (X0, np.array([[4.0, 1.0], [0.0, 2.0]]), H0, [1.0], R0, cfg)),  # P not symmetric
        (NonFiniteError, (X0, P0, H0, [math.nan], R0, cfg)),
        (NonFiniteError, (X0, P0, H0, [1.0], [math.inf], cfg)),
        (SingularError, (X0, np.zeros((2, 2)), H0, [1.0], [0.0], cfg)),
        (SingularError, (X0, P0, H0, [1.0], [-4.0], cfg)),  # C = 0
        # z - H x overflows: NONFINITE in every mode, before the mode runs.
        (NonFiniteError, (np.array([1e308, 0.0]), P0, H0, [-1e308], R0, cfg)),
        (BadConfigError, (X0, P0, H0, [1.0], R0, RobustConfig("bogus"))),
        (BadConfigError, (X0, P0, H0, [1.0], R0, RobustConfig(mode, igg_k1=1.0))),
    ]
    for exc, args in cases:
        with pytest.raises(exc):
            robust_update(*args, st)
        assert _state_fields(st) == before, exc
    assert np.array_equal(P_in, P0)


def test_akf_memory_overflow_is_nonfinite_and_discards_the_epoch() -> None:
    # nu = 1.4e154: T, the row variance and the update stay finite, but e = nu^2 - tr(R)
    # overflows; the update must fail as a whole, leaving the window as it was.
    st = _warm_state("akf")
    before = _state_fields(st)
    with pytest.raises(NonFiniteError):
        robust_update(X0, P0, H0, [1.4e154], R0, RobustConfig("akf"), st)
    assert _state_fields(st) == before
    # The same epoch in plain mode is a finite (if absurd) update: the memory check is the cause.
    xn, _, _ = robust_update(X0, P0, H0, [1.4e154], R0, RobustConfig("plain"), RobustState())
    assert np.all(np.isfinite(xn))


def test_bad_state_is_rejected_without_change() -> None:
    st = RobustState(nu_mean=np.zeros(3))
    with pytest.raises(BadArgError):
        robust_update(X0, P0, H0, [1.0], R0, RobustConfig("akf"), st)
    assert st.nu_mean.shape == (3,)
    st = RobustState(d_k=math.nan)
    with pytest.raises(NonFiniteError):
        robust_update(X0, P0, H0, [1.0], R0, RobustConfig("fuzzy"), st)
    assert math.isnan(st.d_k)


def test_inputs_are_not_modified_and_outputs_do_not_alias_them() -> None:
    x, P = X0.copy(), P0.copy()
    snapshot = copy.deepcopy((x, P))
    for mode in MODES:
        xn, Pn, _ = robust_update(x, P, H0, [100.0], R0, RobustConfig(mode), _warm_state(mode))
        xn[0] += 1.0
        Pn[0, 0] += 1.0
        assert np.array_equal(x, snapshot[0]) and np.array_equal(P, snapshot[1]), mode


def test_fuzzy_rows_apply_the_return_from_a_spike() -> None:
    """ALGORITHMS.md 5, fuzzy rows' return rule: at the alarm's first epoch after an applied epoch
    past TD2, a failing row whose tested innovation has the opposite sign of that epoch's, and is
    no larger, is the return from the outlier it took in, and is applied; with the same sign, or
    larger, it is left out. Row 1 fails on its own (6 / sqrt(1.1) = 5.7 sigma) in each case."""
    H, R, P = np.eye(2), np.diag([0.1, 0.1]), np.eye(2)
    cfg = RobustConfig("fuzzy", fuzzy_reject=2)
    st = RobustState()
    for _ in range(6):  # D settles near 2 TD1 / TD3
        robust_update(np.zeros(2), P, H, np.array([0.1, 0.1]), R, cfg, st)
    xn, _, rep = robust_update(np.zeros(2), P, H, np.array([5.0, 0.0]), R, cfg, st)
    assert not rep.alarm and xn[0] > 4.0 and 0.5 < st.d_k < 1.0  # T = 23, under the gate: taken in
    for nu0, applied in ((-5.0, True), (-4.0, True), (5.0, False), (-5.5, False)):
        st2 = copy.deepcopy(st)
        xn, _, rep = robust_update(np.zeros(2), P, H, np.array([nu0, 6.0]), R, cfg, st2)
        assert rep.alarm and rep.rejected == (not applied) and xn[1] == 0.0
        assert (xn[0] != 0.0) == applied and (st2.n_removed[0] > 0) == (not applied)


def test_fuzzy_rows_gate() -> None:
    """ALGORITHMS.md 5, fuzzy rows' gate: an update that does not alarm leaves out a row past
    2 chi2_1(1e-4) = 30.3 of its test, if the filter's own innovation is within one test sigma
    of the tested one; the other rows are applied. H = I, P = I, R = 0.1 I: C = 1.1 I."""
    H, R, P, x0 = np.eye(2), np.diag([0.1, 0.1]), np.eye(2), np.zeros(2)
    cfg = RobustConfig("fuzzy", fuzzy_reject=2)
    level = 2.0 * chi2_quantile(1e-4, 1) * 1.1  # nu^2 at the gate
    for nu0, gated in ((math.sqrt(level) * 0.99, False), (math.sqrt(level) * 1.01, True)):
        st = RobustState()
        xn, _, rep = robust_update(x0, P, H, np.array([nu0, 0.5]), R, cfg, st)
        assert not rep.alarm and not rep.rejected  # T < TD3: the three-threshold rule does not alarm
        assert (xn[0] == 0.0) == gated and xn[1] != 0.0 and st.n_removed[:2] == [int(gated), 0]
    # the own innovation 1.2 test sigmas from the tested one: not gated
    nu_own = np.array([math.sqrt(level) * 1.01 + 1.2 * math.sqrt(1.1), 0.5])
    st = RobustState()
    test = (np.array([math.sqrt(level) * 1.01, 0.5]), 1.1 * np.eye(2))
    xn, _, rep = robust_update(x0, P, H, nu_own, R, cfg, st, test=test)
    assert not rep.alarm and xn[0] != 0.0 and st.n_removed[:2] == [0, 0]
    # every row past the gate: the update rejected, not alarmed
    st = RobustState()
    xn, _, rep = robust_update(x0, P, H, np.array([6.0, 6.0]), R, cfg, st)
    assert rep.T < fuzzy_thresholds(2)[2] and not rep.alarm and rep.rejected and not xn.any()
    # the modes without rows are not gated
    xn, _, rep = robust_update(x0, P, H, np.array([6.0, 0.5]), R, RobustConfig("fuzzy"), RobustState())
    assert not rep.alarm and xn[0] != 0.0


def test_fuzzy_rows_pair() -> None:
    """The N/E pair of fuzzy rows (ALGORITHMS.md 5): ``fuzzy_rows_failed`` gives the rows an
    alarmed update would leave out for failing alone, with the rows kept out that went out no
    later, reads the memory and changes nothing; an
    update's ``pair_out`` rows go out whether or not it alarms. H = I, P = I, R = 0.1 I."""
    cfg = RobustConfig("fuzzy", fuzzy_reject=2)
    C = 1.1 * np.eye(2)
    st = RobustState()
    assert fuzzy_rows_failed(cfg, st, [0.1, 0.1], C) == (False, False)  # no alarm
    assert fuzzy_rows_failed(cfg, st, [100.0, 0.1], C) == (True, False)  # past TD3: row 0
    assert fuzzy_rows_failed(RobustConfig("fuzzy"), st, [100.0, 0.1], C) == (False, False)  # reject mode
    assert st.d_k == 0.0 and not st.alarm and not st.nu_mean.any() and st.n_removed == [0] * len(st.n_removed)
    st.alarm, st.d_k = True, 1.9
    assert fuzzy_rows_failed(cfg, st, [2.6, 2.6], C) == (False, False)  # nothing singled out
    st.n_removed[1] = 2  # kept out, not failing: with row 0 if it went out no later
    assert fuzzy_rows_failed(cfg, st, [100.0, 0.1], C) == (True, True)
    st.n_removed[0] = 5  # row 1 went out on its own, after row 0
    assert fuzzy_rows_failed(cfg, st, [100.0, 0.1], C) == (True, False)

    H, R, x0, P0 = np.eye(2), 0.1 * np.eye(2), np.zeros(2), np.eye(2)
    st = RobustState()
    x, _, rep = robust_update(x0, P0, H, [0.1, 0.1], R, cfg, st, pair_out=(True, False))
    assert not rep.alarm and not rep.rejected and x[0] == 0.0 and x[1] != 0.0 and st.n_removed[:2] == [1, 0]
    x, _, rep = robust_update(x0, P0, H, [0.1, 0.1], R, cfg, st, pair_out=(True, True))
    assert rep.rejected and not rep.alarm and not x.any() and st.n_reject == 1
    x, _, rep = robust_update(x0, P0, H, [100.0, 0.1], R, cfg, RobustState(), pair_out=(False, True))
    assert rep.alarm and rep.rejected  # row 0 fails, row 1 for the pair
    with pytest.raises(BadArgError):
        robust_update(x0, P0, H, [0.1, 0.1], R, cfg, RobustState(), pair_out=(True,))


def test_fuzzy_rows_apply_the_rows_beside_the_pairs() -> None:
    """ALGORITHMS.md 5, fuzzy rows while alarmed (session 28): with no row failing its own test (only the
    joint T does) the update is rejected, unless the N/E pair has a row out of it (``pair_out``, or the
    caller's rows the memory carries, ``caller_out``, which the update clears): then the rows neither failing
    nor paired are applied, and none kept out (the rows the last two updates left out stay out only while a
    row fails). H = I, P = I, R = 0.1 I: C = 1.1 I; z = 2.6 on each row is 6.1 of chi2_1(0.005) = 7.9 a row,
    T = 12.3 past TD2 = 10.6, so the alarm stays."""
    cfg = RobustConfig("fuzzy", fuzzy_reject=2)
    H, R, P, x0, z = np.eye(2), 0.1 * np.eye(2), np.eye(2), np.zeros(2), np.array([2.6, 2.6])

    def alarmed(n_removed: tuple[int, int] = (0, 0)) -> RobustState:
        st = RobustState(alarm=True, d_k=1.9)
        st.n_removed[:2] = list(n_removed)
        return st

    st = alarmed()
    x, _, rep = robust_update(x0, P, H, z, R, cfg, st)
    assert rep.alarm and rep.rejected and not x.any() and st.n_removed[:2] == [1, 1]
    for pair in ((True, False), (False, True)):  # the other row applied
        st = alarmed()
        x, _, rep = robust_update(x0, P, H, z, R, cfg, st, pair_out=pair)
        assert rep.alarm and not rep.rejected and [v == 0.0 for v in x] == list(pair)
        assert st.n_removed[:2] == [int(v) for v in pair] and st.n_reject == 0
    st = alarmed()
    x, _, rep = robust_update(x0, P, H, z, R, cfg, st, pair_out=(True, True))  # every row out
    assert rep.rejected and not x.any()
    st = alarmed(n_removed=(0, 5))  # row 1 out for 5 updates, row 0 paired: no row fails, row 1 applied
    x, _, rep = robust_update(x0, P, H, z, R, cfg, st, pair_out=(True, False))
    assert not rep.rejected and x[0] == 0.0 and x[1] != 0.0 and st.n_removed[:2] == [1, 0]
    st = alarmed()
    st.caller_out[0] = True  # the caller's row, carried by the memory
    x, _, rep = robust_update(x0, P, H, z, R, cfg, st)
    assert rep.alarm and not rep.rejected and x[0] == 0.0 and x[1] != 0.0
    assert st.n_removed[:2] == [1, 0] and not any(st.caller_out)  # cleared by the update
    x, _, rep = robust_update(x0, P, H, z, R, cfg, st)  # the next update: no caller's row, rejected again
    assert rep.rejected and not x.any()
    # a row failing its own test: the pair's rows out with it, and the rows kept out stay out
    st = alarmed(n_removed=(0, 5))
    x, _, rep = robust_update(x0, P, H, np.array([6.0, 2.6]), R, cfg, st, pair_out=(False, False))
    assert rep.rejected and not x.any()

/* Host tests of the robust/adaptive update modes of mca_kf_update (docs/ALGORITHMS.md 5)
 * that need no golden model: the chi-square table against a closed form computed here,
 * each mode's decision on crafted inputs with hand-derivable results, bad input leaving
 * x, P and the memory untouched in every mode, P staying symmetric positive definite. */
#include <string.h>

#include "mca_kf_rows.h" /* private: mca_kf_fuzzy_failed */
#include "mca_test.h"
#include "mcahrs/mca_robust.h"

#define NMAX 15
#define WS_MAX MCA_KF_WS_LEN(NMAX, MCA_MEAS_MAX)

static float g_ws[WS_MAX];

/* ---------------------------------------------------------------- chi-square table */

/* Upper tail Q(x; m) = P[chi2_m > x], closed form for integer m:
 * even m: exp(-x/2) sum_{k < m/2} (x/2)^k / k!;
 * odd m:  erfc(sqrt(x/2)) + exp(-x/2) sum_{k=0}^{(m-3)/2} (x/2)^(k+1/2) / Gamma(k + 3/2). */
static double chi2_sf(double x, int m)
{
    const double h = 0.5 * x;
    double sum, term;
    if (m % 2 == 0) {
        sum = 0.0;
        term = 1.0;
        for (int k = 0; k < m / 2; ++k) {
            sum += term;
            term *= h / (double)(k + 1);
        }
        return exp(-h) * sum;
    }
    sum = erfc(sqrt(h));
    term = sqrt(h) / tgamma(1.5); /* (x/2)^(1/2) / Gamma(3/2) */
    for (int k = 0; k <= (m - 3) / 2; ++k) {
        sum += exp(-h) * term;
        term *= h / ((double)k + 1.5); /* Gamma(k + 5/2) = (k + 3/2) Gamma(k + 3/2) */
    }
    return sum;
}

/* chi2_m(a) by bisection of the decreasing Q(x; m) = a, to double precision. */
static double chi2_isf(double a, int m)
{
    double lo = 0.0, hi = 200.0;
    for (int it = 0; it < 200; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (chi2_sf(mid, m) > a) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return 0.5 * (lo + hi);
}

static void test_chi2_table_matches_closed_form(void)
{
    const double levels[MCA_CHI2_LEVELS] = {1e-4, 1e-2, 5e-3, 2.5e-2}; /* mca_chi2_level_t order */
    for (int m = 1; m <= MCA_MEAS_MAX; ++m) {
        for (int k = 0; k < MCA_CHI2_LEVELS; ++k) {
            const double ref = chi2_isf(levels[k], m);
            const float got = mca_chi2_quantile((size_t)m, (mca_chi2_level_t)k);
            /* float32 rounding of the quantile is 6e-8 relative; 1e-6 leaves margin */
            CHECK_CLOSE(got / ref, 1.0, 1e-6);
        }
    }
    /* scipy.stats.chi2.ppf(1 - a, m) literal spot values (scipy 1.17.1): */
    CHECK_CLOSE(mca_chi2_quantile(1, MCA_CHI2_1E4), 15.136705226623606, 2e-6);
    CHECK_CLOSE(mca_chi2_quantile(2, MCA_CHI2_1E2), 9.210340371976182, 1e-6);
    CHECK_CLOSE(mca_chi2_quantile(6, MCA_CHI2_2P5E2), 14.44937533544792, 2e-6);
    /* closed form sanity: m = 2 is exactly -2 ln a */
    CHECK_CLOSE(chi2_isf(5e-3, 2), -2.0 * log(5e-3), 1e-9);
    /* out of range: 0 */
    CHECK(mca_chi2_quantile(0, MCA_CHI2_1E4) == 0.0f);
    CHECK(mca_chi2_quantile(MCA_MEAS_MAX + 1, MCA_CHI2_1E4) == 0.0f);
    CHECK(mca_chi2_quantile(1, MCA_CHI2_LEVELS) == 0.0f);
}

/* ---------------------------------------------------------------- helpers */

static void cfg_mode(mca_robust_config_t *rc, mca_robust_mode_t mode)
{
    mca_robust_config_default(rc);
    rc->mode = (uint8_t)mode;
}

static void eye(float *a, int n, float s)
{
    memset(a, 0, sizeof(float) * (size_t)(n * n));
    for (int i = 0; i < n; ++i) {
        a[i * n + i] = s;
    }
}

static int spd(const float *p, int n)
{
    float l[NMAX * NMAX];
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
            if (p[i * n + j] != p[j * n + i]) {
                return 0;
            }
        }
    }
    return mca_cholesky(l, p, (size_t)n) == MCA_OK;
}

static unsigned g_seed = 2024u;

/* Uniform in [-0.5, 0.5) from an LCG: deterministic, no libc rand. */
static float urand(void)
{
    g_seed = g_seed * 1103515245u + 12345u;
    return (float)((g_seed >> 8) & 0xffffffu) / 16777216.0f - 0.5f;
}

/* ---------------------------------------------------------------- FTA */

static void test_fta_gamma_on_crafted_outlier(void)
{
    /* n = 2, m = 1, x = 0, P = I, H = [1 0], R = 1: C = 2, T = z^2 / 2 */
    mca_robust_config_t rc;
    cfg_mode(&rc, MCA_ROBUST_FTA);
    float x[2] = {0.0f, 0.0f}, p[4];
    eye(p, 2, 1.0f);
    const float h[2] = {1.0f, 0.0f}, r[1] = {1.0f}, z[1] = {10.0f};
    mca_update_report_t rep;
    CHECK_EQ_INT(mca_kf_update(x, p, 2, h, z, r, 1, &rc, NULL, g_ws, WS_MAX, &rep), MCA_OK);
    const double thr = 15.136705226623606; /* scipy chi2.ppf(1 - 1e-4, 1) */
    const double gamma = 50.0 / thr;
    CHECK_CLOSE(rep.t_stat, 50.0, 1e-4);
    CHECK_CLOSE(rep.factor, gamma, 1e-5);
    CHECK_EQ_INT(rep.detected, 1);
    CHECK_EQ_INT(rep.rejected, 0);
    CHECK_EQ_INT(rep.mode, MCA_ROBUST_FTA);
    /* K = P H^T (gamma C)^-1 = 1 / (2 gamma); Joseph with the nominal R */
    const double k = 1.0 / (2.0 * gamma);
    CHECK_CLOSE(x[0], k * 10.0, 1e-5);
    CHECK_CLOSE(x[1], 0.0, 0.0);
    CHECK_CLOSE(p[0], (1.0 - k) * (1.0 - k) + k * k, 1e-6);
    CHECK_CLOSE(p[3], 1.0, 0.0);

    /* below the threshold: gamma = 1 and bit for bit the plain update */
    float x1[2] = {0.0f, 0.0f}, p1[4], x2[2] = {0.0f, 0.0f}, p2[4];
    eye(p1, 2, 1.0f);
    eye(p2, 2, 1.0f);
    const float z_in[1] = {3.0f}; /* T = 4.5 */
    mca_robust_config_t plain;
    cfg_mode(&plain, MCA_ROBUST_PLAIN);
    CHECK_EQ_INT(mca_kf_update(x1, p1, 2, h, z_in, r, 1, &rc, NULL, g_ws, WS_MAX, &rep), MCA_OK);
    CHECK_EQ_INT(rep.detected, 0);
    CHECK(rep.factor == 1.0f);
    CHECK_EQ_INT(mca_kf_update(x2, p2, 2, h, z_in, r, 1, &plain, NULL, g_ws, WS_MAX, NULL), MCA_OK);
    CHECK(memcmp(x1, x2, sizeof(x1)) == 0 && memcmp(p1, p2, sizeof(p1)) == 0);
}

/* ---------------------------------------------------------------- fuzzy */

/* Expected mu of the three-threshold memberships, written out in double. */
static double fuzzy_mu(double t, double td1, double td2)
{
    const double td3 = 10.0 * td2;
    double dh = 0.0, dm = 0.0, dd = 0.0;
    if (t < td1) {
        dh = 1.0;
    } else if (t <= td2) {
        dh = (td2 - t) / (td2 - td1);
    }
    if (t > td1 && t <= td2) {
        dm = (t - td1) / (td2 - td1);
    } else if (t > td2 && t < td3) {
        dm = (td3 - t) / (td3 - td2);
    }
    if (t > td3) {
        dd = 1.0;
    } else if (t >= td2) {
        dd = (t - td2) / (td3 - td2);
    }
    return td1 / td3 * dh + 0.5 * dm + dd;
}

/* One fuzzy epoch from a fixed prior (x = 0, P = 1, H = 1, R = 1: C = 2) with T = t. */
static void fuzzy_step(const mca_robust_config_t *rc, mca_robust_state_t *rs, double t, mca_update_report_t *rep,
                       float *x_out, float *p_out)
{
    float x[1] = {0.0f}, p[1] = {1.0f};
    const float h[1] = {1.0f}, r[1] = {1.0f};
    const float z[1] = {(float)sqrt(2.0 * t)};
    CHECK_EQ_INT(mca_kf_update(x, p, 1, h, z, r, 1, rc, rs, g_ws, WS_MAX, rep), MCA_OK);
    *x_out = x[0];
    *p_out = p[0];
}

static void test_fuzzy_alarm_after_two_outliers_and_release(void)
{
    /* m = 1 thresholds (scipy chi2.ppf): TD1 = chi2_1(0.025), TD2 = chi2_1(0.005), TD3 = 10 TD2 */
    const double td1 = 5.023886187314888, td2 = 7.879438576622417;
    mca_robust_config_t rc;
    cfg_mode(&rc, MCA_ROBUST_FUZZY);
    mca_robust_state_t rs;
    mca_robust_state_init(&rs);
    mca_update_report_t rep;
    float x, p;
    /* T > TD3 (78.8) twice from D = 0: D = 1 (not > 1), then 1.5 > 1: alarm */
    const double ts[] = {200.0, 200.0, 7.0, 1.0, 1.0, 20.0, 200.0, 200.0, 20.0, 1.0};
    double d = 0.0;
    int alarm = 0;
    for (size_t k = 0; k < sizeof(ts) / sizeof(ts[0]); ++k) {
        d = 0.5 * d + fuzzy_mu(ts[k], td1, td2);
        if (!alarm && d > 1.0) {
            alarm = 1;
        } else if (alarm && ts[k] < td2 && d < 1.0) {
            alarm = 0;
            d = 0.0;
        }
        fuzzy_step(&rc, &rs, ts[k], &rep, &x, &p);
        CHECK_CLOSE(rep.t_stat, ts[k], 1e-5 * ts[k]);
        CHECK_CLOSE(rs.d_k, d, 1e-5);
        CHECK_EQ_INT(rs.alarm, alarm);
        CHECK_EQ_INT(rep.alarm, alarm);
        CHECK_EQ_INT(rep.detected, alarm);
        CHECK_EQ_INT(rep.rejected, alarm);
        CHECK(rep.factor == 1.0f);
        if (alarm) { /* rejected: x, P unchanged */
            CHECK(x == 0.0f && p == 1.0f);
        } else { /* plain: K = 1/2 */
            CHECK_CLOSE(p, 0.5, 1e-6);
        }
    }
    /* the hand-derived sequence: step 0 D = 1 no alarm; step 1 alarm; step 2 (T = 7 < TD2 but
     * D = 0.75 + 0.366 > 1) stays; step 3 releases (D < 1, T < TD2) and D = 0 */
    mca_robust_state_init(&rs);
    fuzzy_step(&rc, &rs, 200.0, &rep, &x, &p);
    CHECK_CLOSE(rs.d_k, 1.0, 1e-6);
    CHECK_EQ_INT(rs.alarm, 0);
    fuzzy_step(&rc, &rs, 200.0, &rep, &x, &p);
    CHECK_CLOSE(rs.d_k, 1.5, 1e-6);
    CHECK_EQ_INT(rs.alarm, 1);
    fuzzy_step(&rc, &rs, 7.0, &rep, &x, &p);
    CHECK(rs.d_k > 1.0f);
    CHECK_EQ_INT(rs.alarm, 1);
    fuzzy_step(&rc, &rs, 1.0, &rep, &x, &p);
    CHECK(rs.d_k == 0.0f);
    CHECK_EQ_INT(rs.alarm, 0);
    CHECK_EQ_INT(rep.rejected, 0);

    /* inflate instead of reject: gamma = max(1, T / TD2) */
    rc.fuzzy_reject = 0u;
    mca_robust_state_init(&rs);
    fuzzy_step(&rc, &rs, 200.0, &rep, &x, &p);
    fuzzy_step(&rc, &rs, 200.0, &rep, &x, &p);
    CHECK_EQ_INT(rep.alarm, 1);
    CHECK_EQ_INT(rep.rejected, 0);
    const double g = 200.0 / td2;
    CHECK_CLOSE(rep.factor, g, 1e-5 * g);
    const double k = 1.0 / (2.0 * g);
    CHECK_CLOSE(x, k * sqrt(400.0), 1e-5);
    CHECK_CLOSE(p, (1.0 - k) * (1.0 - k) + k * k, 1e-6);
    /* alarmed with T < TD2: gamma = 1 (plain) */
    fuzzy_step(&rc, &rs, 7.0, &rep, &x, &p);
    CHECK_EQ_INT(rep.alarm, 1);
    CHECK(rep.factor == 1.0f);
    CHECK_CLOSE(p, 0.5, 1e-6);
}

/* ---------------------------------------------------------------- IGG-III */

static void test_igg_weights_on_crafted_residuals(void)
{
    /* n = m = 3, x = 0, P = H = R = I: C = 2 I, s_i = |z_i| / sqrt(2) = {1, 2, 4} */
    mca_robust_config_t rc;
    cfg_mode(&rc, MCA_ROBUST_IGG3);
    float x[3] = {0.0f, 0.0f, 0.0f}, p[9], h[9], r[9];
    eye(p, 3, 1.0f);
    eye(h, 3, 1.0f);
    eye(r, 3, 1.0f);
    const float s2 = 1.41421356f;
    const float z[3] = {1.0f * s2, -2.0f * s2, 4.0f * s2};
    mca_update_report_t rep;
    CHECK_EQ_INT(mca_kf_update(x, p, 3, h, z, r, 3, &rc, NULL, g_ws, WS_MAX, &rep), MCA_OK);
    /* w(2) = (1.5 / 2) ((3 - 2) / 1.5)^2 = 1/3; s = 4 > k1: 0 (row removed) */
    CHECK(rep.w[0] == 1.0f);
    CHECK_CLOSE(rep.w[1], 1.0 / 3.0, 1e-6);
    CHECK(rep.w[2] == 0.0f);
    CHECK_EQ_INT(rep.detected, 1);
    CHECK_EQ_INT(rep.rejected, 0);
    CHECK(rep.factor == 1.0f);
    /* row 0: K = 1/2; row 1: R = 1 / w = 3, K = 1/4; row 2: no update */
    CHECK_CLOSE(x[0], 0.5 * z[0], 1e-6);
    CHECK_CLOSE(x[1], 0.25 * z[1], 1e-5);
    CHECK(x[2] == 0.0f);
    CHECK_CLOSE(p[0], 0.5, 1e-6);
    CHECK_CLOSE(p[4], 0.5625 + 0.0625 * 3.0, 1e-6);
    CHECK(p[8] == 1.0f);
    CHECK(p[1] == 0.0f && p[2] == 0.0f && p[5] == 0.0f);

    /* every row above k1: rejected, x and P unchanged */
    float x0[3] = {0.5f, 0.5f, 0.5f}, xr[3], pr[9];
    memcpy(xr, x0, sizeof(xr));
    eye(pr, 3, 1.0f);
    const float zr[3] = {10.0f, -10.0f, 10.0f};
    CHECK_EQ_INT(mca_kf_update(xr, pr, 3, h, zr, r, 3, &rc, NULL, g_ws, WS_MAX, &rep), MCA_OK);
    CHECK_EQ_INT(rep.rejected, 1);
    CHECK(rep.w[0] == 0.0f && rep.w[1] == 0.0f && rep.w[2] == 0.0f);
    CHECK(memcmp(xr, x0, sizeof(xr)) == 0 && p[8] == 1.0f);
    float pe[9];
    eye(pe, 3, 1.0f);
    CHECK(memcmp(pr, pe, sizeof(pe)) == 0);

    /* all inliers: weights 1, bit for bit the plain update */
    float xa[3] = {0}, pa[9], xb[3] = {0}, pb[9];
    eye(pa, 3, 1.0f);
    eye(pb, 3, 1.0f);
    const float zi[3] = {0.5f, -1.0f, 2.0f};
    CHECK_EQ_INT(mca_kf_update(xa, pa, 3, h, zi, r, 3, &rc, NULL, g_ws, WS_MAX, &rep), MCA_OK);
    CHECK_EQ_INT(rep.detected, 0);
    CHECK_EQ_INT(mca_kf_update(xb, pb, 3, h, zi, r, 3, NULL, NULL, g_ws, WS_MAX, NULL), MCA_OK);
    CHECK(memcmp(xa, xb, sizeof(xa)) == 0 && memcmp(pa, pb, sizeof(pa)) == 0);
}

/* ---------------------------------------------------------------- AKF */

/* One AKF epoch from x = 0, P = 1, H = 1, R = 1 with innovation nu. */
static void akf_step(const mca_robust_config_t *rc, mca_robust_state_t *rs, float nu, mca_update_report_t *rep,
                     float *x_out, float *p_out)
{
    float x[1] = {0.0f}, p[1] = {1.0f};
    const float h[1] = {1.0f}, r[1] = {1.0f}, z[1] = {nu};
    CHECK_EQ_INT(mca_kf_update(x, p, 1, h, z, r, 1, rc, rs, g_ws, WS_MAX, rep), MCA_OK);
    *x_out = x[0];
    *p_out = p[0];
}

static void test_akf_q_scale_clamped_and_r_star(void)
{
    mca_robust_config_t rc;
    cfg_mode(&rc, MCA_ROBUST_AKF);
    mca_robust_state_t rs;
    mca_update_report_t rep;
    float x, p;
    /* e = nu^2 - R, tr(H P H^T) = 1: alpha = nu^2 - 1 */
    mca_robust_state_init(&rs);
    akf_step(&rc, &rs, 2.0f, &rep, &x, &p); /* alpha = 3: log2(4) = 2 */
    CHECK_CLOSE(rep.q_scale, 2.0, 1e-6);
    CHECK(rs.q_scale == rep.q_scale);
    CHECK_EQ_INT(rs.win_n, 1);
    CHECK_EQ_INT(rep.detected, 0); /* T = 2 < chi2_1(0.01) = 6.63 */
    CHECK(rep.factor == 1.0f);
    CHECK_CLOSE(x, 1.0, 1e-6); /* K = 1/2 with R* = R */
    /* the first update seeds the row statistics: r = nu, s = 0 */
    CHECK(rs.nu_mean[0] == 2.0f && rs.nu_var[0] == 0.0f && rs.started == 1u);

    mca_robust_state_init(&rs);
    akf_step(&rc, &rs, 100.0f, &rep, &x, &p); /* alpha = 9999: log2 = 13.3 > 10 */
    CHECK(rep.q_scale == rc.akf_q_max);
    CHECK_EQ_INT(rep.detected, 1);
    CHECK(rep.factor == 1.0f); /* s = 0 on the first update: R* = R */

    mca_robust_state_init(&rs);
    akf_step(&rc, &rs, 0.0f, &rep, &x, &p); /* alpha = -1: log2(tiny) -> q_min */
    CHECK(rep.q_scale == rc.akf_q_min);
    akf_step(&rc, &rs, 1.2f, &rep, &x, &p); /* mean(e) = (-1 + 0.44) / 2 < 0: q_min */
    CHECK(rep.q_scale == rc.akf_q_min);

    /* R* on detection: r = 0.8 nu1 + 0.2 nu2, s = 0.2 (nu2 - r)^2 */
    const double nu1 = 0.5, nu2 = 8.0, b = 0.2;
    mca_robust_state_init(&rs);
    akf_step(&rc, &rs, (float)nu1, &rep, &x, &p);
    akf_step(&rc, &rs, (float)nu2, &rep, &x, &p); /* T = 32 > 6.63 */
    const double rm = (1.0 - b) * nu1 + b * nu2;
    const double s = b * (nu2 - rm) * (nu2 - rm);
    CHECK_EQ_INT(rep.detected, 1);
    CHECK_CLOSE(rep.factor, 1.0 + s, 1e-5 * (1.0 + s));
    CHECK_CLOSE(rs.nu_mean[0], rm, 1e-6);
    CHECK_CLOSE(rs.nu_var[0], s, 1e-5 * s);
    const double k = 1.0 / (2.0 + s); /* gain with H P H^T + R* */
    CHECK_CLOSE(x, k * nu2, 1e-5);
    CHECK_CLOSE(p, (1.0 - k) * (1.0 - k) + k * k * (1.0 + s), 1e-6);
    /* window mean of e: ((0.25 - 1) + (64 - 1)) / 2, alpha / 1 -> log2(32.125) = 5.006 */
    CHECK_CLOSE(rep.q_scale, log2(1.0 + 0.5 * (-0.75 + 63.0)), 1e-5);

    /* eq. 19's log2 (the core's own) against libm's double log2 over 1 < arg < 1e30:
     * window 1, H = P = R = 1, so arg = (nu^2 - 1) + 1 in float exactly as the core forms it */
    mca_robust_config_t wide = rc;
    wide.akf_window = 1u;
    wide.akf_q_min = 1e-6f;
    wide.akf_q_max = 200.0f;
    double worst = 0.0;
    for (int i = 0; i < 400; ++i) {
        const float nu = powf(10.0f, -1.9f + 0.04f * (float)i); /* 0.0126 .. 1.1e14 */
        mca_robust_state_init(&rs);
        akf_step(&wide, &rs, nu, &rep, &x, &p);
        const float arg = (nu * nu - 1.0f) + 1.0f;
        if (arg > 1.0f + 1e-6f) {
            const double ref = log2((double)arg);
            const double err = fabs((double)rep.q_scale - ref) / (ref > 1.0 ? ref : 1.0);
            worst = err > worst ? err : worst;
        }
    }
    CHECK(worst < 3e-7); /* a few float32 ulps */

    /* the window keeps the last akf_window values: after 8 x e = 3 and then 8 x e = 0, alpha = 0 */
    rc.akf_window = 4u;
    mca_robust_state_init(&rs);
    for (int i = 0; i < 8; ++i) {
        akf_step(&rc, &rs, 2.0f, &rep, &x, &p);
    }
    CHECK_CLOSE(rep.q_scale, 2.0, 1e-6);
    for (int i = 0; i < 3; ++i) {
        akf_step(&rc, &rs, 1.0f, &rep, &x, &p);
    }
    CHECK_CLOSE(rep.q_scale, log2(1.0 + 0.75), 1e-6); /* (3 + 0 + 0 + 0) / 4 */
    akf_step(&rc, &rs, 1.0f, &rep, &x, &p);
    CHECK(rep.q_scale == rc.akf_q_min); /* log2(1) = 0 -> q_min */
    CHECK_EQ_INT(rs.win_n, MCA_AKF_WINDOW);
}

/* ---------------------------------------------------------------- errors */

static const mca_robust_mode_t k_modes[] = {MCA_ROBUST_PLAIN, MCA_ROBUST_FTA, MCA_ROBUST_AKF, MCA_ROBUST_FUZZY,
                                            MCA_ROBUST_IGG3};

static void test_bad_input_leaves_state_in_every_mode(void)
{
    enum { N = 3, M = 2 };
    for (size_t mi = 0; mi < sizeof(k_modes) / sizeof(k_modes[0]); ++mi) {
        mca_robust_config_t rc;
        cfg_mode(&rc, k_modes[mi]);
        mca_robust_state_t rs;
        mca_robust_state_init(&rs);
        float x[N] = {1.0f, -2.0f, 0.5f}, p[N * N];
        eye(p, N, 2.0f);
        p[1] = p[3] = 0.3f;
        const float h[M * N] = {1.0f, 0.0f, 0.5f, 0.0f, 1.0f, 0.0f};
        const float r[M * M] = {1.0f, 0.1f, 0.1f, 2.0f};
        const float z[M] = {40.0f, -1.0f};
        /* a few good updates first, so the memory is not trivial */
        for (int k = 0; k < 3; ++k) {
            CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, M, &rc, &rs, g_ws, WS_MAX, NULL), MCA_OK);
        }
        float x0[N], p0[N * N];
        mca_robust_state_t rs0;
        memcpy(x0, x, sizeof(x));
        memcpy(p0, p, sizeof(p));
        memcpy(&rs0, &rs, sizeof(rs));
        const float znan[M] = {NAN, 0.0f}, rnan[M * M] = {1.0f, 0.0f, 0.0f, INFINITY};
        const float hnan[M * N] = {1.0f, 0.0f, NAN, 0.0f, 1.0f, 0.0f};
        const float rsing[M * M] = {-100.0f, 0.0f, 0.0f, 1.0f}; /* C not positive definite */
        mca_update_report_t rep;
        CHECK_EQ_INT(mca_kf_update(NULL, p, N, h, z, r, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_NULL);
        CHECK_EQ_INT(mca_kf_update(x, NULL, N, h, z, r, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_NULL);
        CHECK_EQ_INT(mca_kf_update(x, p, N, NULL, z, r, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_NULL);
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, NULL, r, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_NULL);
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, NULL, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_NULL);
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, M, &rc, &rs, NULL, WS_MAX, &rep), MCA_ERR_NULL);
        const int needs_rs = k_modes[mi] == MCA_ROBUST_AKF || k_modes[mi] == MCA_ROBUST_FUZZY;
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, M, &rc, NULL, g_ws, WS_MAX, &rep),
                     needs_rs ? MCA_ERR_NULL : MCA_OK);
        if (!needs_rs) { /* that call was a good update: undo it */
            memcpy(x, x0, sizeof(x));
            memcpy(p, p0, sizeof(p));
        }
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, 0, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_BAD_ARG);
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, MCA_MEAS_MAX + 1, &rc, &rs, g_ws, WS_MAX, &rep),
                     MCA_ERR_BAD_ARG);
        CHECK_EQ_INT(mca_kf_update(x, p, 0, h, z, r, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_BAD_ARG);
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, M, &rc, &rs, g_ws, MCA_KF_WS_LEN(N, M) - 1, &rep),
                     MCA_ERR_BAD_ARG);
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, znan, r, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_NONFINITE);
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, rnan, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_NONFINITE);
        CHECK_EQ_INT(mca_kf_update(x, p, N, hnan, z, r, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_NONFINITE);
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, rsing, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_SINGULAR);
        /* non-finite x or P */
        float xb[N], pb[N * N];
        memcpy(xb, x, sizeof(x));
        memcpy(pb, p, sizeof(p));
        xb[2] = NAN;
        pb[8] = INFINITY;
        mca_robust_state_t rs1;
        memcpy(&rs1, &rs, sizeof(rs));
        CHECK_EQ_INT(mca_kf_update(xb, p, N, h, z, r, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_NONFINITE);
        CHECK_EQ_INT(mca_kf_update(x, pb, N, h, z, r, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_NONFINITE);
        /* and without a report (plain mode: the row-by-row path, which checks through its result) */
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, znan, r, M, &rc, &rs, g_ws, WS_MAX, NULL), MCA_ERR_NONFINITE);
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, rnan, M, &rc, &rs, g_ws, WS_MAX, NULL), MCA_ERR_NONFINITE);
        CHECK_EQ_INT(mca_kf_update(x, p, N, hnan, z, r, M, &rc, &rs, g_ws, WS_MAX, NULL), MCA_ERR_NONFINITE);
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, rsing, M, &rc, &rs, g_ws, WS_MAX, NULL), MCA_ERR_SINGULAR);
        CHECK_EQ_INT(mca_kf_update(xb, p, N, h, z, r, M, &rc, &rs, g_ws, WS_MAX, NULL), MCA_ERR_NONFINITE);
        CHECK_EQ_INT(mca_kf_update(x, pb, N, h, z, r, M, &rc, &rs, g_ws, WS_MAX, NULL), MCA_ERR_NONFINITE);
        {
            const float r_offnan[M * M] = {1.0f, NAN, NAN, 1.0f};
            const float h_inf[M * N] = {INFINITY, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f};
            CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r_offnan, M, &rc, &rs, g_ws, WS_MAX, NULL), MCA_ERR_NONFINITE);
            CHECK_EQ_INT(mca_kf_update(x, p, N, h_inf, z, r, M, &rc, &rs, g_ws, WS_MAX, NULL), MCA_ERR_NONFINITE);
            const float z_inf[M] = {INFINITY, 0.0f};
            CHECK_EQ_INT(mca_kf_update(x, p, N, h, z_inf, r, M, &rc, &rs, g_ws, WS_MAX, NULL), MCA_ERR_NONFINITE);
        }
        /* bad configuration */
        mca_robust_config_t bad = rc;
        bad.mode = 5u;
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, M, &bad, &rs, g_ws, WS_MAX, &rep), MCA_ERR_BAD_CONFIG);
        /* a field out of range: refused by every mode but plain, which reads no other field
         * (and then makes the update: undone) */
        const int plain = k_modes[mi] == MCA_ROBUST_PLAIN;
        bad = rc;
        bad.igg_k1 = bad.igg_k0;
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, M, &bad, &rs, g_ws, WS_MAX, &rep),
                     plain ? MCA_OK : MCA_ERR_BAD_CONFIG);
        bad = rc;
        bad.akf_window = MCA_AKF_WINDOW + 1u;
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, M, &bad, &rs, g_ws, WS_MAX, &rep),
                     plain ? MCA_OK : MCA_ERR_BAD_CONFIG);
        if (plain) {
            memcpy(x, x0, sizeof(x));
            memcpy(p, p0, sizeof(p));
            memcpy(&rs, &rs0, sizeof(rs));
        }
        /* a corrupt memory, in the modes that read it */
        if (needs_rs) {
            mca_robust_state_t bad_rs = rs;
            bad_rs.win_n = MCA_AKF_WINDOW + 1u;
            CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, M, &rc, &bad_rs, g_ws, WS_MAX, &rep), MCA_ERR_BAD_ARG);
            bad_rs = rs;
            bad_rs.nu_var[1] = -1.0f;
            CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, M, &rc, &bad_rs, g_ws, WS_MAX, &rep), MCA_ERR_BAD_ARG);
            bad_rs = rs;
            bad_rs.d_k = NAN;
            CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, M, &rc, &bad_rs, g_ws, WS_MAX, &rep), MCA_ERR_BAD_ARG);
        }
        CHECK(memcmp(x, x0, sizeof(x)) == 0);
        CHECK(memcmp(p, p0, sizeof(p)) == 0);
        CHECK(memcmp(&rs, &rs0, sizeof(rs)) == 0);
        CHECK(memcmp(&rs1, &rs0, sizeof(rs)) == 0);
        /* and a good update still works */
        CHECK_EQ_INT(mca_kf_update(x, p, N, h, z, r, M, &rc, &rs, g_ws, WS_MAX, &rep), MCA_OK);
        CHECK_EQ_INT(rep.mode, k_modes[mi]);
    }
}

/* ---------------------------------------------------------------- m > n, exact scratch */

static void test_more_rows_than_states(void)
{
    /* n = 1, m = 6, every row observes x, R = I, P = 1: information form
     * P+ = 1 / (1 + 6), x+ = P+ (x + sum z). Scratch exactly MCA_KF_WS_LEN(1, 6) (ASan). */
    static float ws_exact[MCA_KF_WS_LEN(1, 6)];
    float x[1] = {0.5f}, p[1] = {1.0f}, h[6], r[36];
    eye(r, 6, 1.0f);
    const float z[6] = {0.1f, 0.2f, -0.3f, 0.4f, 0.0f, 0.6f};
    for (int i = 0; i < 6; ++i) {
        h[i] = 1.0f;
    }
    CHECK_EQ_INT(mca_kf_update(x, p, 1, h, z, r, 6, NULL, NULL, ws_exact, MCA_KF_WS_LEN(1, 6), NULL), MCA_OK);
    CHECK_CLOSE(p[0], 1.0 / 7.0, 1e-6);
    CHECK_CLOSE(x[0], (0.5 + 1.0) / 7.0, 1e-6);
    /* every mode runs on it, IGG removing the outlier row 5 */
    for (size_t mi = 0; mi < sizeof(k_modes) / sizeof(k_modes[0]); ++mi) {
        mca_robust_config_t rc;
        cfg_mode(&rc, k_modes[mi]);
        mca_robust_state_t rs;
        mca_robust_state_init(&rs);
        float xm[1] = {0.0f}, pm[1] = {1.0f};
        const float zo[6] = {0.1f, 0.2f, -0.3f, 0.4f, 0.0f, 60.0f};
        mca_update_report_t rep;
        CHECK_EQ_INT(mca_kf_update(xm, pm, 1, h, zo, r, 6, &rc, &rs, ws_exact, MCA_KF_WS_LEN(1, 6), &rep), MCA_OK);
        CHECK(spd(pm, 1));
        if (k_modes[mi] == MCA_ROBUST_IGG3) {
            CHECK(rep.w[5] == 0.0f);
            /* the other five: P+ = 1/6, x+ = 0.4 / 6 */
            CHECK_CLOSE(pm[0], 1.0 / 6.0, 1e-6);
            CHECK_CLOSE(xm[0], 0.4 / 6.0, 1e-6);
        }
    }
}

/* ---------------------------------------------------------------- long runs */

static void test_long_run_p_stays_spd_every_mode(void)
{
    enum { N = 6, M = 2 };
    for (size_t mi = 0; mi < sizeof(k_modes) / sizeof(k_modes[0]); ++mi) {
        for (int reject = 0; reject < 2; ++reject) {
            mca_robust_config_t rc;
            cfg_mode(&rc, k_modes[mi]);
            rc.fuzzy_reject = (uint8_t)reject;
            mca_robust_state_t rs;
            mca_robust_state_init(&rs);
            float x[N] = {0}, p[N * N], tmp[N * N];
            eye(p, N, 1.0f);
            int ok = 1, n_det = 0, n_rej = 0;
            for (int k = 0; k < 3000; ++k) {
                /* predict: damped velocity pairs (x0,x1), (x2,x3), (x4,x5), dt = 0.1, Q scaled by
                 * the AKF factor (1 in the other modes); damped so the unobserved x3, x5 stay bounded */
                float f[N * N];
                eye(f, N, 0.98f);
                f[0 * N + 1] = f[2 * N + 3] = f[4 * N + 5] = 0.1f;
                mca_mat_mul(tmp, f, p, N, N, N);
                mca_mat_mul_bt(p, tmp, f, N, N, N);
                for (int i = 0; i < N; ++i) {
                    p[i * N + i] += 0.01f * rs.q_scale;
                }
                mca_mat_symmetrize(p, N);
                float h[M * N] = {0};
                h[0 * N + 0] = 1.0f;
                h[0 * N + 2] = 0.3f;
                h[1 * N + 1] = 1.0f;
                h[1 * N + 4] = -0.5f;
                const float r[M * M] = {0.5f, 0.05f, 0.05f, 0.2f};
                float z[M] = {urand(), 0.5f * urand()};
                if (k % 37 == 5 || k % 37 == 6) {
                    z[0] += 40.0f; /* outliers, sometimes two in a row */
                }
                if (k % 53 == 7) {
                    z[1] -= 25.0f;
                }
                mca_update_report_t rep;
                const int st = mca_kf_update(x, p, N, h, z, r, M, &rc, &rs, g_ws, WS_MAX, &rep);
                const int good = st == MCA_OK && spd(p, N) && mca_all_finite(p, N * N) && mca_all_finite(x, N) &&
                                 rep.factor >= 1.0f;
                if (!good && ok) {
                    fprintf(stderr, "mode %d reject %d step %d: status %d factor %g\n", (int)k_modes[mi], reject, k,
                            st, (double)rep.factor);
                }
                ok &= good;
                n_det += rep.detected;
                n_rej += rep.rejected;
            }
            CHECK(ok);
            if (k_modes[mi] != MCA_ROBUST_PLAIN) {
                CHECK(n_det > 50); /* the outliers are seen */
            }
            if (k_modes[mi] == MCA_ROBUST_FUZZY && reject) {
                CHECK(n_rej > 10);
            }
        }
    }
}

/* ---------------------------------------------------------------- test innovation */

/* mca_kf_update_tested (ALGORITHMS.md 5): FTA decides on the test innovation, the update
 * itself is the nominal one; a bad test changes nothing and says why. */
static void test_tested_update_decides_on_the_test_innovation(void)
{
    mca_robust_config_t rc;
    cfg_mode(&rc, MCA_ROBUST_FTA);
    const float h[2] = {1.0f, 0.0f}, r[1] = {1.0f}, z[1] = {10.0f}; /* nominal T = 50: an outlier */
    const float nu_quiet[1] = {1.0f}, c_t[1] = {2.0f};              /* tested T = 0.5 */
    float x[2] = {0.0f, 0.0f}, p[4], xp[2] = {0.0f, 0.0f}, pp[4];
    eye(p, 2, 1.0f);
    eye(pp, 2, 1.0f);
    mca_update_report_t rep;
    CHECK_EQ_INT(mca_kf_update_tested(x, p, 2, h, z, r, 1, &rc, NULL, nu_quiet, c_t, g_ws, WS_MAX, &rep), MCA_OK);
    CHECK_CLOSE(rep.t_stat, 0.5, 1e-6);
    CHECK_EQ_INT(rep.tested, 1);
    CHECK_EQ_INT(rep.detected, 0);
    CHECK_CLOSE(rep.nu[0], 10.0, 0.0); /* the nominal innovation is reported and applied */
    CHECK_EQ_INT(mca_kf_update(xp, pp, 2, h, z, r, 1, NULL, NULL, g_ws, WS_MAX, NULL), MCA_OK);
    CHECK(memcmp(x, xp, sizeof(x)) == 0 && memcmp(p, pp, sizeof(p)) == 0);

    const float nu_gross[1] = {10.0f}, c_bad[1] = {-1.0f}, nu_nan[1] = {NAN};
    float x0[2] = {0.5f, -0.5f}, p0[4], xs[2], ps[4];
    eye(p0, 2, 1.0f);
    memcpy(xs, x0, sizeof(xs));
    memcpy(ps, p0, sizeof(ps));
    CHECK_EQ_INT(mca_kf_update_tested(xs, ps, 2, h, z, r, 1, &rc, NULL, nu_gross, NULL, g_ws, WS_MAX, &rep),
                 MCA_ERR_NULL);
    CHECK_EQ_INT(mca_kf_update_tested(xs, ps, 2, h, z, r, 1, &rc, NULL, nu_gross, c_bad, g_ws, WS_MAX, &rep),
                 MCA_ERR_SINGULAR);
    CHECK_EQ_INT(mca_kf_update_tested(xs, ps, 2, h, z, r, 1, &rc, NULL, nu_nan, c_t, g_ws, WS_MAX, &rep),
                 MCA_ERR_NONFINITE);
    CHECK(memcmp(xs, x0, sizeof(xs)) == 0 && memcmp(ps, p0, sizeof(ps)) == 0);
    /* the gross test innovation is an outlier for FTA although the nominal one is quiet */
    const float z_quiet[1] = {1.0f};
    CHECK_EQ_INT(mca_kf_update_tested(xs, ps, 2, h, z_quiet, r, 1, &rc, NULL, nu_gross, c_t, g_ws, WS_MAX, &rep),
                 MCA_OK);
    CHECK_EQ_INT(rep.detected, 1);
    CHECK(rep.factor > 1.0f);
}

/* ---------------------------------------------------------------- row by row vs joint */

/* With a diagonal R the update runs row by row (ALGORITHMS.md 1, sequential form). Checked
 * against the joint update written out in double, P+ = P - K C K^T, K = P H^T C^-1 (which is
 * Joseph for the optimal gain), and against the joint float path (an R with a 1e-30 off-diagonal
 * entry takes it). The report-free path and the reporting path must give the same bits. */
static void test_row_by_row_equals_joint_update(void)
{
    enum { N = 5, M = 2 };
    float p0[N * N];
    const float a[N * N] = {1.0f,  0.2f, 0.0f, 0.9f, 0.0f, 0.1f, 0.5f,  0.1f, 0.0f, 0.3f, 0.0f, 0.2f, 0.3f,
                            0.0f,  0.1f, 0.4f, 0.0f, 0.0f, 2.0f, 0.0f, 0.0f, 0.2f, 0.0f, 0.1f, 0.2f};
    for (int i = 0; i < N; ++i) { /* P0 = A A^T + 0.01 I: SPD with strong p/eps_p-like coupling */
        for (int j = 0; j < N; ++j) {
            float s = i == j ? 0.01f : 0.0f;
            for (int k = 0; k < N; ++k) {
                s += a[i * N + k] * a[j * N + k];
            }
            p0[i * N + j] = s;
        }
    }
    const float x0[N] = {1.0f, -0.5f, 0.2f, 0.3f, 0.0f};
    const float h[M * N] = {1.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 1.0f};
    const float z[M] = {2.5f, 0.4f};
    const float r[M * M] = {0.8f, 0.0f, 0.0f, 0.05f};
    const float r_full[M * M] = {0.8f, 1e-30f, 1e-30f, 0.05f};
    mca_robust_state_t rs1, rs2;
    mca_robust_state_init(&rs1);
    mca_robust_state_init(&rs2);
    mca_update_report_t rep;
    float x1[N], p1[N * N], x2[N], p2[N * N], x3[N], p3[N * N];
    memcpy(x1, x0, sizeof(x1));
    memcpy(p1, p0, sizeof(p1));
    memcpy(x2, x0, sizeof(x2));
    memcpy(p2, p0, sizeof(p2));
    memcpy(x3, x0, sizeof(x3));
    memcpy(p3, p0, sizeof(p3));
    CHECK_EQ_INT(mca_kf_update(x1, p1, N, h, z, r, M, NULL, &rs1, g_ws, WS_MAX, NULL), MCA_OK);
    CHECK_EQ_INT(mca_kf_update(x2, p2, N, h, z, r, M, NULL, &rs2, g_ws, WS_MAX, &rep), MCA_OK);
    CHECK(memcmp(x1, x2, sizeof(x1)) == 0 && memcmp(p1, p2, sizeof(p1)) == 0);
    CHECK_EQ_INT(mca_kf_update(x3, p3, N, h, z, r_full, M, NULL, NULL, g_ws, WS_MAX, NULL), MCA_OK);

    /* the joint update in double */
    double u[N][M], c[M][M], ci[M][M], k[N][M], nu[M];
    for (int j = 0; j < M; ++j) {
        double hx = 0.0;
        for (int l = 0; l < N; ++l) {
            hx += (double)h[j * N + l] * (double)x0[l];
        }
        nu[j] = (double)z[j] - hx;
        for (int i = 0; i < N; ++i) {
            u[i][j] = 0.0;
            for (int l = 0; l < N; ++l) {
                u[i][j] += (double)p0[i * N + l] * (double)h[j * N + l];
            }
        }
    }
    for (int i = 0; i < M; ++i) {
        for (int j = 0; j < M; ++j) {
            c[i][j] = (double)r[i * M + j];
            for (int l = 0; l < N; ++l) {
                c[i][j] += (double)h[i * N + l] * u[l][j];
            }
        }
    }
    const double det = c[0][0] * c[1][1] - c[0][1] * c[1][0];
    ci[0][0] = c[1][1] / det;
    ci[1][1] = c[0][0] / det;
    ci[0][1] = -c[0][1] / det;
    ci[1][0] = -c[1][0] / det;
    double t_ref = 0.0;
    for (int i = 0; i < M; ++i) {
        for (int j = 0; j < M; ++j) {
            t_ref += nu[i] * ci[i][j] * nu[j];
        }
    }
    for (int i = 0; i < N; ++i) {
        for (int j = 0; j < M; ++j) {
            k[i][j] = u[i][0] * ci[0][j] + u[i][1] * ci[1][j];
        }
    }
    for (int i = 0; i < N; ++i) {
        const double xr = (double)x0[i] + k[i][0] * nu[0] + k[i][1] * nu[1];
        CHECK_CLOSE(x1[i], xr, 2e-6);
        CHECK_CLOSE(x3[i], xr, 2e-6);
        for (int j = 0; j < N; ++j) {
            const double pr = (double)p0[i * N + j] - (k[i][0] * u[j][0] + k[i][1] * u[j][1]);
            CHECK_CLOSE(p1[i * N + j], pr, 2e-6);
            CHECK_CLOSE(p3[i * N + j], pr, 2e-6);
            CHECK(p1[i * N + j] == p1[j * N + i]);
        }
    }
    /* T from the rows (no report) and from C's factor (report) */
    CHECK_CLOSE(rs1.t_stat, t_ref, 1e-5 * t_ref);
    CHECK_CLOSE(rep.t_stat, t_ref, 1e-5 * t_ref);
    CHECK_CLOSE(rs2.t_stat, t_ref, 1e-5 * t_ref);
}

/* The test statistic of a test innovation: m <= 2 in closed form, larger m and indefinite C_t
 * through the Cholesky factor. Checked against T in double on the row path (no report, the
 * navigation's CS updates) and the general path (report), and SINGULAR / NONFINITE for an
 * indefinite or non-finite C_t or nu_t. */
/* A CS-axis-like prior (5 states, position and its GPS error correlated) for the row tests. */
static const float k_x5[5] = {1.0f, -0.5f, 0.2f, 0.3f, 0.0f};

static void prior5(float p0[25])
{
    for (int i = 0; i < 25; ++i) {
        p0[i] = 0.0f;
    }
    for (int i = 0; i < 5; ++i) {
        p0[i * 5 + i] = 0.5f + 0.25f * (float)i;
    }
    p0[0 * 5 + 3] = p0[3 * 5 + 0] = 0.2f;
}

static void test_plain_test_statistic_small_m(void)
{
    enum { N = 5 };
    const float *const x0 = k_x5;
    float p0[N * N];
    prior5(p0);
    const float h[2 * N] = {1.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 1.0f};
    const float z[2] = {2.5f, 0.4f};
    const float r[4] = {0.8f, 0.0f, 0.0f, 0.05f};
    const float nu_t[2] = {1.7f, -0.9f};
    /* C_t not exactly symmetric: the statistic uses its symmetric part */
    const float c_t[4] = {1.3f, 0.31f, 0.29f, 0.6f};
    for (size_t m = 1; m <= 2; ++m) {
        double t_ref;
        if (m == 1) {
            t_ref = (double)nu_t[0] * (double)nu_t[0] / (double)c_t[0];
        } else {
            const double a = c_t[0], b = 0.5 * ((double)c_t[1] + (double)c_t[2]), d = c_t[3];
            const double n0 = nu_t[0], n1 = nu_t[1];
            t_ref = (d * n0 * n0 - 2.0 * b * n0 * n1 + a * n1 * n1) / (a * d - b * b);
        }
        const float c1[1] = {c_t[0]};
        const float *cm = m == 1 ? c1 : c_t;
        float r1[1] = {r[0]};
        const float *rm = m == 1 ? r1 : r;
        mca_robust_state_t rs;
        mca_robust_state_init(&rs);
        mca_update_report_t rep;
        float x1[N], p1[N * N], x2[N], p2[N * N];
        memcpy(x1, x0, sizeof(x1));
        memcpy(p1, p0, sizeof(p1));
        memcpy(x2, x0, sizeof(x2));
        memcpy(p2, p0, sizeof(p2));
        CHECK_EQ_INT(mca_kf_update_tested(x1, p1, N, h, z, rm, m, NULL, &rs, nu_t, cm, g_ws, WS_MAX, NULL), MCA_OK);
        CHECK_EQ_INT(mca_kf_update_tested(x2, p2, N, h, z, rm, m, NULL, NULL, nu_t, cm, g_ws, WS_MAX, &rep), MCA_OK);
        CHECK_CLOSE(rs.t_stat, t_ref, 4e-7 * t_ref);
        CHECK_CLOSE(rep.t_stat, t_ref, 4e-7 * t_ref);
        CHECK(memcmp(x1, x2, sizeof(x1)) == 0 && memcmp(p1, p2, sizeof(p1)) == 0); /* the update itself */
    }
    /* a non-finite test innovation or covariance, m = 1 and 2: NONFINITE, nothing written */
    const float nu_nan[2] = {NAN, 0.5f}, nu_inf[2] = {0.5f, INFINITY};
    const float c_inf[4] = {1.3f, INFINITY, -INFINITY, 0.6f}, c_nan0[4] = {NAN, 0.0f, 0.0f, 1.0f};
    const float *nus[4] = {nu_nan, nu_inf, nu_t, nu_t};
    const float *cs[4] = {c_t, c_t, c_inf, c_nan0};
    for (size_t m = 1; m <= 2; ++m) {
        for (int k = 0; k < 4; ++k) {
            if (m == 1u && (k == 1 || k == 2)) {
                continue; /* m = 1 reads nu_t[0] and c_t[0] only */
            }
            mca_robust_state_t rs;
            mca_robust_state_init(&rs);
            float x1[N], p1[N * N];
            memcpy(x1, x0, sizeof(x1));
            memcpy(p1, p0, sizeof(p1));
            CHECK_EQ_INT(mca_kf_update_tested(x1, p1, N, h, z, r, m, NULL, &rs, nus[k], cs[k], g_ws, WS_MAX, NULL),
                         MCA_ERR_NONFINITE);
            CHECK(memcmp(x1, x0, sizeof(x1)) == 0 && memcmp(p1, p0, sizeof(p1)) == 0);
        }
    }
    /* indefinite C_t (det < 0), and a non-positive first pivot: SINGULAR, nothing written */
    const float c_bad[4] = {1.0f, 2.0f, 2.0f, 1.0f};
    const float c_neg[4] = {-1.0f, 0.0f, 0.0f, 1.0f};
    const float *bads[2] = {c_bad, c_neg};
    for (int k = 0; k < 2; ++k) {
        mca_robust_state_t rs;
        mca_robust_state_init(&rs);
        float x1[N], p1[N * N];
        memcpy(x1, x0, sizeof(x1));
        memcpy(p1, p0, sizeof(p1));
        CHECK_EQ_INT(mca_kf_update_tested(x1, p1, N, h, z, r, 2, NULL, &rs, nu_t, bads[k], g_ws, WS_MAX, NULL),
                     MCA_ERR_SINGULAR);
        CHECK(memcmp(x1, x0, sizeof(x1)) == 0 && memcmp(p1, p0, sizeof(p1)) == 0);
    }
}

/* mca_kf_test_stat is the T mca_kf_update_tested takes (same bits, m = 1, 2 closed form and
 * m = 3 from the factor); mca_kf_update_plain is its plain row update (same x, P, memory) and
 * returns gains that reproduce x+ row by row; bad arguments are refused. */
static void test_plain_gains_and_test_stat(void)
{
    enum { N = 5 };
    const float *const x0 = k_x5;
    float p0[N * N];
    prior5(p0);
    p0[1 * N + 4] = p0[4 * N + 1] = -0.1f;
    const float h[3 * N] = {1.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f};
    const float z[3] = {2.5f, 0.4f, -0.3f};
    const float r[9] = {0.8f, 0.0f, 0.0f, 0.0f, 0.05f, 0.0f, 0.0f, 0.0f, 0.3f};
    const float nu_t[3] = {1.7f, -0.9f, 0.4f};
    const float c_t[9] = {1.3f, 0.31f, 0.1f, 0.29f, 0.6f, 0.0f, 0.1f, 0.0f, 0.9f};
    for (size_t m = 1; m <= 3; ++m) {
        float rm[9] = {0}, cm[9] = {0};
        for (size_t i = 0; i < m; ++i) {
            for (size_t j = 0; j < m; ++j) {
                rm[i * m + j] = r[i * 3 + j];
                cm[i * m + j] = c_t[i * 3 + j];
            }
        }
        for (int tested = 0; tested <= 1; ++tested) {
            const float *nt = tested ? nu_t : NULL, *ct = tested ? cm : NULL;
            mca_robust_state_t rs1, rs2;
            mca_robust_state_init(&rs1);
            mca_robust_state_init(&rs2);
            float x1[N], p1[N * N], x2[N], p2[N * N], gains[3 * (N + 1)];
            memcpy(x1, x0, sizeof(x1));
            memcpy(p1, p0, sizeof(p1));
            memcpy(x2, x0, sizeof(x2));
            memcpy(p2, p0, sizeof(p2));
            CHECK_EQ_INT(mca_kf_update_tested(x1, p1, N, h, z, rm, m, NULL, &rs1, nt, ct, g_ws, WS_MAX, NULL), MCA_OK);
            CHECK_EQ_INT(mca_kf_update_plain(x2, p2, N, h, z, rm, m, &rs2, nt, ct, g_ws, WS_MAX, gains), MCA_OK);
            CHECK(memcmp(x1, x2, sizeof(x1)) == 0 && memcmp(p1, p2, sizeof(p1)) == 0);
            CHECK(memcmp(&rs1, &rs2, sizeof(rs1)) == 0);
            /* the gains, applied to x0 row by row as the row update does, give x+ */
            float x3[N];
            memcpy(x3, x0, sizeof(x3));
            for (size_t row = 0; row < m; ++row) {
                float hx = 0.0f;
                for (size_t l = 0; l < N; ++l) {
                    if (h[row * N + l] != 0.0f) {
                        hx += h[row * N + l] * x3[l];
                    }
                }
                const float nu = z[row] - hx;
                for (size_t i = 0; i < N; ++i) {
                    x3[i] = x3[i] + gains[row * (N + 1) + i] * nu;
                }
                CHECK(gains[row * (N + 1) + N] > 0.0f);
            }
            CHECK(memcmp(x3, x2, sizeof(x3)) == 0);
            if (tested) {
                float t = -1.0f;
                CHECK_EQ_INT(mca_kf_test_stat(nu_t, cm, m, g_ws, &t), MCA_OK);
                CHECK(memcmp(&t, &rs1.t_stat, sizeof(t)) == 0);
            }
        }
    }
    /* refused: an off-diagonal R, NULL gains, m out of range; an indefinite C_t */
    float x1[N], p1[N * N], gains[3 * (N + 1)], t;
    memcpy(x1, x0, sizeof(x1));
    memcpy(p1, p0, sizeof(p1));
    const float r_full[4] = {0.8f, 0.1f, 0.1f, 0.05f};
    CHECK_EQ_INT(mca_kf_update_plain(x1, p1, N, h, z, r_full, 2, NULL, NULL, NULL, g_ws, WS_MAX, gains),
                 MCA_ERR_BAD_ARG);
    CHECK_EQ_INT(mca_kf_update_plain(x1, p1, N, h, z, r, 1, NULL, NULL, NULL, g_ws, WS_MAX, NULL), MCA_ERR_NULL);
    CHECK_EQ_INT(mca_kf_update_plain(x1, p1, N, h, z, r, 0, NULL, NULL, NULL, g_ws, WS_MAX, gains), MCA_ERR_BAD_ARG);
    CHECK(memcmp(x1, x0, sizeof(x1)) == 0 && memcmp(p1, p0, sizeof(p1)) == 0);
    const float c_bad[4] = {1.0f, 2.0f, 2.0f, 1.0f};
    CHECK_EQ_INT(mca_kf_test_stat(nu_t, c_bad, 2, g_ws, &t), MCA_ERR_SINGULAR);
    CHECK_EQ_INT(mca_kf_test_stat(nu_t, c_t, 0, g_ws, &t), MCA_ERR_BAD_ARG);
    CHECK_EQ_INT(mca_kf_test_stat(NULL, c_t, 1, g_ws, &t), MCA_ERR_NULL);
}

/* Fuzzy rows (fuzzy_reject 2, ALGORITHMS.md 5) on two independent rows (H = I, P = I,
 * R = 0.1 I): one epoch past TD3 from D = 0 alarms (D = 1; the paper's rule, kept by the other
 * fuzzy variants, waits for a second); while alarmed the failing row is left out and the other
 * applied; a row out on the last two updates stays out while another fails, a row out on one
 * only does not; every row failing, or none (only the joint test), rejects. One row (m = 1)
 * failing rejects. */
static void test_fuzzy_rows_leave_out_the_failing_row(void)
{
    mca_robust_config_t rc;
    cfg_mode(&rc, MCA_ROBUST_FUZZY);
    rc.fuzzy_reject = 2u;
    CHECK_EQ_INT(mca_robust_config_check(&rc), MCA_OK);
    rc.fuzzy_reject = 3u;
    CHECK_EQ_INT(mca_robust_config_check(&rc), MCA_ERR_BAD_CONFIG);
    rc.fuzzy_reject = 2u;
    mca_robust_state_t rs;
    mca_robust_state_init(&rs);
    mca_update_report_t rep;
    const float h[4] = {1.0f, 0.0f, 0.0f, 1.0f}, r[4] = {0.1f, 0.0f, 0.0f, 0.1f};
    /* z, then: alarm, rejected, x[0] / x[1] moved, rows left out after the update */
    const struct {
        float z0, z1;
        int alarm, rejected, moved0, moved1, out0, out1;
    } steps[] = {
        {100.0f, 0.1f, 1, 0, 0, 1, 1, 0},  /* D = 1: alarm; row 0 out, row 1 applied */
        {100.0f, 50.0f, 1, 1, 0, 0, 1, 1}, /* both fail: rejected */
        {100.0f, 0.1f, 1, 0, 0, 1, 1, 0},  /* row 1 passes, out on one update only: applied */
        {100.0f, 50.0f, 1, 1, 0, 0, 1, 1}, /* both fail */
        {100.0f, 50.0f, 1, 1, 0, 0, 1, 1}, /* both fail: row 1 out on two updates in a row */
        {100.0f, 0.1f, 1, 1, 0, 0, 1, 1},  /* row 1 passes but stays out while row 0 fails */
    };
    for (size_t k = 0; k < sizeof steps / sizeof steps[0]; ++k) {
        float x[2] = {0.0f, 0.0f}, p[4];
        eye(p, 2, 1.0f);
        const float z[2] = {steps[k].z0, steps[k].z1};
        CHECK_EQ_INT(mca_kf_update(x, p, 2, h, z, r, 2, &rc, &rs, g_ws, WS_MAX, &rep), MCA_OK);
        CHECK_EQ_INT(rep.alarm, steps[k].alarm);
        CHECK_EQ_INT(rep.rejected, steps[k].rejected);
        CHECK_EQ_INT(x[0] != 0.0f, steps[k].moved0);
        CHECK_EQ_INT(x[1] != 0.0f, steps[k].moved1);
        CHECK_EQ_INT(p[0] < 1.0f, steps[k].moved0); /* a row left out leaves its variance */
        CHECK_EQ_INT(rs.n_removed[0] > 0u || rs.n_reject > 0u, steps[k].out0);
        CHECK_EQ_INT(rs.n_removed[1] > 0u || rs.n_reject > 0u, steps[k].out1);
        CHECK_EQ_INT(mca_robust_left_out(&rs, 2u), steps[k].out0 || steps[k].out1);
        CHECK(rep.w[0] == 1.0f && rep.w[1] == 1.0f);
    }
    /* alarmed, nothing fails alone but the joint T: rejected (both rows at 2.5 sigma alone) */
    mca_robust_state_init(&rs);
    rs.alarm = 1u;
    rs.d_k = 1.9f;
    float x[2] = {0.0f, 0.0f}, p[4];
    eye(p, 2, 1.0f);
    const float zj[2] = {2.6f, 2.6f}; /* each 2.48 sigma (< 2.81), T = 12.3 > TD2 = 10.6 */
    CHECK_EQ_INT(mca_kf_update(x, p, 2, h, zj, r, 2, &rc, &rs, g_ws, WS_MAX, &rep), MCA_OK);
    CHECK_EQ_INT(rep.alarm, 1);
    CHECK_EQ_INT(rep.rejected, 1);
    CHECK(x[0] == 0.0f && x[1] == 0.0f);
    /* m = 1, alarmed and failing: rejected */
    float fuzzy_x, fuzzy_p;
    mca_robust_state_init(&rs);
    fuzzy_step(&rc, &rs, 200.0, &rep, &fuzzy_x, &fuzzy_p);
    fuzzy_step(&rc, &rs, 200.0, &rep, &fuzzy_x, &fuzzy_p);
    CHECK_EQ_INT(rep.alarm, 1);
    CHECK_EQ_INT(rep.rejected, 1);
    CHECK(fuzzy_x == 0.0f && fuzzy_p == 1.0f);
}

/* Fuzzy rows' long guard holds only for an update tested against a prior its caller coasts on
 * (ALGORITHMS.md 5, lock-up guard): without a test innovation the default guard applies. */
static void test_fuzzy_rows_long_guard_needs_a_test_innovation(void)
{
    mca_robust_config_t rc;
    cfg_mode(&rc, MCA_ROBUST_FUZZY);
    rc.fuzzy_reject = 2u;
    rc.reject_reset_n = 100u;
    rc.row_reset_n = 0u;
    const float h[4] = {1.0f, 0.0f, 0.0f, 1.0f}, r[4] = {0.1f, 0.0f, 0.0f, 0.1f};
    const float z[2] = {100.0f, 50.0f}; /* both rows fail on every update */
    for (int tested = 0; tested < 2; ++tested) {
        mca_robust_state_t rs;
        mca_robust_state_init(&rs);
        mca_update_report_t rep;
        int first_reset = 0;
        for (int k = 1; k <= 12 && first_reset == 0; ++k) {
            float x[2] = {0.0f, 0.0f}, p[4];
            eye(p, 2, 1.0f);
            const float nu_t[2] = {100.0f, 50.0f}, c_t[4] = {1.1f, 0.0f, 0.0f, 1.1f}; /* the prior x, P */
            CHECK_EQ_INT(mca_kf_update_tested(x, p, 2, h, z, r, 2, &rc, &rs, tested ? nu_t : NULL,
                                              tested ? c_t : NULL, g_ws, WS_MAX, &rep),
                         MCA_OK);
            if (rep.reset) {
                first_reset = k;
                CHECK(x[0] > 50.0f && x[1] > 25.0f); /* the plain update */
            } else {
                CHECK_EQ_INT(rep.rejected, 1);
                CHECK(x[0] == 0.0f && x[1] == 0.0f);
            }
        }
        /* every update rejected (fuzzy rows alarm on the first, D = 1): the default guard's 5th
         * rejection is update 5; with the test innovation the long guard keeps rejecting */
        CHECK_EQ_INT(first_reset, tested ? 0 : (int)MCA_ROBUST_RESET_N_DEFAULT);
    }
}

/* Fuzzy rows' return rule (ALGORITHMS.md 5): at the alarm's first epoch after an applied epoch
 * past TD2, a failing row whose innovation has the opposite sign of that epoch's, and is no
 * larger, is the return from the outlier that epoch took in and is applied; with the same sign,
 * or larger, it is left out. Two independent rows (H = I, P = I, R = 0.1 I), x and P afresh each
 * update, the memory kept; row 1 fails on its own (5.7 sigma) in each case. */
static void test_fuzzy_rows_apply_the_return_from_a_spike(void)
{
    mca_robust_config_t rc;
    cfg_mode(&rc, MCA_ROBUST_FUZZY);
    rc.fuzzy_reject = 2u;
    mca_robust_state_t rs;
    mca_robust_state_init(&rs);
    mca_update_report_t rep;
    const float h[4] = {1.0f, 0.0f, 0.0f, 1.0f}, r[4] = {0.1f, 0.0f, 0.0f, 0.1f};
    float x[2], p[4];
    const float quiet[2] = {0.1f, 0.1f}, spike[2] = {5.0f, 0.0f};
    for (int k = 0; k < 6; ++k) { /* D settles near 2 TD1 / TD3 */
        x[0] = x[1] = 0.0f;
        eye(p, 2, 1.0f);
        CHECK_EQ_INT(mca_kf_update(x, p, 2, h, quiet, r, 2, &rc, &rs, g_ws, WS_MAX, &rep), MCA_OK);
    }
    x[0] = x[1] = 0.0f;
    eye(p, 2, 1.0f);
    /* T = 23 (TD2 10.6 < T < TD3 106, under the gate's 30.3): D = 0.63, no alarm, taken in */
    CHECK_EQ_INT(mca_kf_update(x, p, 2, h, spike, r, 2, &rc, &rs, g_ws, WS_MAX, &rep), MCA_OK);
    CHECK_EQ_INT(rep.alarm, 0);
    CHECK(x[0] > 4.0f && rs.d_k > 0.5f && rs.d_k < 1.0f);
    const struct {
        float nu0;
        int applied;
    } cases[] = {{-5.0f, 1}, {-4.0f, 1}, {5.0f, 0}, {-5.5f, 0}}; /* row 0 fails (T_0 >= 14.5) */
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        mca_robust_state_t rs2 = rs;
        x[0] = x[1] = 0.0f;
        eye(p, 2, 1.0f);
        const float z[2] = {cases[k].nu0, 6.0f}; /* T >= 47: alarmed */
        CHECK_EQ_INT(mca_kf_update(x, p, 2, h, z, r, 2, &rc, &rs2, g_ws, WS_MAX, &rep), MCA_OK);
        CHECK_EQ_INT(rep.alarm, 1);
        CHECK_EQ_INT(rep.rejected, !cases[k].applied);
        CHECK(x[1] == 0.0f);                               /* row 1 out either way */
        CHECK_EQ_INT(x[0] != 0.0f, cases[k].applied);      /* row 0: applied when it returns */
        CHECK_EQ_INT(rs2.n_removed[0] > 0u, !cases[k].applied);
    }
}

/* Fuzzy rows' last row standing (ALGORITHMS.md 5): the one row not out on the last two updates
 * while every other row was fails above 2 chi2_1(1e-4) = 30.3 instead of chi2_1(0.005) = 7.88.
 * H = I, P = I, R = 0.1 I: C = 1.1 I; row 0 fails at 91 sigma, row 1 at nu^2 / C = 11, 25 or 40. */
static void test_fuzzy_rows_last_row_standing(void)
{
    mca_robust_config_t rc;
    cfg_mode(&rc, MCA_ROBUST_FUZZY);
    rc.fuzzy_reject = 2u;
    rc.reject_reset_n = 100u;
    mca_update_report_t rep;
    const float h[4] = {1.0f, 0.0f, 0.0f, 1.0f}, r[4] = {0.1f, 0.0f, 0.0f, 0.1f};
    const struct {
        uint8_t out0, out1, n_reject; /* the memory: updates in a row that left each row out */
        float s2;                     /* row 1's nu^2 / C */
        int applied1;
    } cases[] = {
        {3u, 0u, 0u, 11.0f, 1}, /* row 0 out, row 1 applied: row 1 stands alone, 11 < 30.3 */
        {3u, 0u, 0u, 25.0f, 1}, /* 25 < 30.3 (> chi2_1(1e-4) = 15.1) */
        {0u, 0u, 0u, 11.0f, 0}, /* nothing out before: 11 > 7.88 */
        {3u, 3u, 3u, 11.0f, 0}, /* both out (rejected): no row stands alone */
        {3u, 0u, 0u, 40.0f, 0}, /* alone, but 40 > 30.3 */
        {1u, 0u, 0u, 11.0f, 0}, /* row 0 out on one update only (the gate): 11 > 7.88 */
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        mca_robust_state_t rs;
        mca_robust_state_init(&rs);
        rs.alarm = 1u;
        rs.d_k = 1.9f;
        rs.n_removed[0] = cases[k].out0;
        rs.n_removed[1] = cases[k].out1;
        rs.n_reject = cases[k].n_reject;
        float x[2] = {0.0f, 0.0f}, p[4];
        eye(p, 2, 1.0f);
        const float z[2] = {100.0f, sqrtf(cases[k].s2 * 1.1f)};
        CHECK_EQ_INT(mca_kf_update(x, p, 2, h, z, r, 2, &rc, &rs, g_ws, WS_MAX, &rep), MCA_OK);
        CHECK_EQ_INT(rep.alarm, 1);
        CHECK(x[0] == 0.0f);                          /* row 0 out */
        CHECK_EQ_INT(x[1] != 0.0f, cases[k].applied1); /* row 1 applied or out */
        CHECK_EQ_INT(rep.rejected, !cases[k].applied1);
        CHECK_EQ_INT(rs.n_removed[1] == 0u, cases[k].applied1);
    }
}

/* Fuzzy rows' gate (ALGORITHMS.md 5): an update that does not alarm leaves out a row past
 * 2 chi2_1(1e-4) = 30.3 of its test where the own innovation is within one test sigma of the
 * tested one; every row past it rejects the update. H = I, P = I, R = 0.1 I: C = 1.1 I. */
static void test_fuzzy_rows_gate(void)
{
    mca_robust_config_t rc;
    cfg_mode(&rc, MCA_ROBUST_FUZZY);
    rc.fuzzy_reject = 2u;
    mca_update_report_t rep;
    const float h[4] = {1.0f, 0.0f, 0.0f, 1.0f}, r[4] = {0.1f, 0.0f, 0.0f, 0.1f};
    const float c_t[4] = {1.1f, 0.0f, 0.0f, 1.1f};
    const float gate = sqrtf(2.0f * 15.137f * 1.1f); /* |nu| at the gate, 2 chi2_1(1e-4) = 30.27 */
    const struct {
        float z0, nu_t0; /* row 0's own innovation and tested one (row 1: 0.5, tested 0.5) */
        int tested, out0;
    } cases[] = {
        {0.99f * gate, 0.0f, 0, 0},                     /* under the gate: applied */
        {1.01f * gate, 0.0f, 0, 1},                     /* past it: out, row 1 applied */
        {1.01f * gate + 0.9f * 1.0488f, 1.01f * gate, 1, 1}, /* own 0.9 test sigma from the tested */
        {1.01f * gate + 1.2f * 1.0488f, 1.01f * gate, 1, 0}, /* 1.2 test sigma: not gated */
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        mca_robust_state_t rs;
        mca_robust_state_init(&rs);
        float x[2] = {0.0f, 0.0f}, p[4];
        eye(p, 2, 1.0f);
        const float z[2] = {cases[k].z0, 0.5f}, nu_t[2] = {cases[k].nu_t0, 0.5f};
        CHECK_EQ_INT(mca_kf_update_tested(x, p, 2, h, z, r, 2, &rc, &rs, cases[k].tested ? nu_t : NULL,
                                          cases[k].tested ? c_t : NULL, g_ws, WS_MAX, &rep),
                     MCA_OK);
        CHECK_EQ_INT(rep.alarm, 0); /* T < TD3 = 106: the three-threshold rule does not alarm */
        CHECK_EQ_INT(x[0] == 0.0f, cases[k].out0);
        CHECK(x[1] != 0.0f);
        CHECK_EQ_INT(rs.n_removed[0], cases[k].out0);
        CHECK_EQ_INT(rs.n_removed[1], 0);
    }
    /* both rows past the gate, T = 65 < TD3: rejected without an alarm; plain fuzzy: applied */
    mca_robust_state_t rs;
    mca_robust_state_init(&rs);
    float x[2] = {0.0f, 0.0f}, p[4];
    eye(p, 2, 1.0f);
    const float z[2] = {6.0f, 6.0f};
    CHECK_EQ_INT(mca_kf_update(x, p, 2, h, z, r, 2, &rc, &rs, g_ws, WS_MAX, &rep), MCA_OK);
    CHECK(rep.alarm == 0u && rep.rejected == 1u && x[0] == 0.0f && x[1] == 0.0f && rs.n_reject == 1u);
    rc.fuzzy_reject = 1u;
    mca_robust_state_init(&rs);
    CHECK_EQ_INT(mca_kf_update(x, p, 2, h, z, r, 2, &rc, &rs, g_ws, WS_MAX, &rep), MCA_OK);
    CHECK(rep.alarm == 0u && rep.rejected == 0u && x[0] != 0.0f);
}

/* Fuzzy rows' N/E pair (ALGORITHMS.md 5): mca_kf_fuzzy_failed gives the rows an alarmed update
 * would leave out for failing their own test, with the rows kept out that went out no later
 * (none without an alarm or when no row fails alone), and changes nothing; the rows in
 * rs.started go out of the next fuzzy-rows update, alarmed or not, which then clears them.
 * H = I, P = I, R = 0.1 I: the test innovation is z, C = 1.1 I. */
static void test_fuzzy_rows_pair(void)
{
    mca_robust_config_t rc;
    cfg_mode(&rc, MCA_ROBUST_FUZZY);
    rc.fuzzy_reject = 2u;
    mca_robust_state_t rs;
    mca_robust_state_init(&rs);
    const float c_t[4] = {1.1f, 0.0f, 0.0f, 1.1f}, c_bad[4] = {-1.0f, 0.0f, 0.0f, 1.1f};
    const float quiet[2] = {0.1f, 0.1f}, big0[2] = {100.0f, 0.1f}, both[2] = {2.6f, 2.6f};
    CHECK_EQ_INT((int)mca_kf_fuzzy_failed(&rc, &rs, quiet, c_t, 2u, g_ws), 0); /* no alarm */
    CHECK_EQ_INT((int)mca_kf_fuzzy_failed(&rc, &rs, big0, c_t, 2u, g_ws), 1);  /* T past TD3: row 0 */
    CHECK_EQ_INT((int)mca_kf_fuzzy_failed(&rc, &rs, big0, c_bad, 2u, g_ws), 0); /* C refused */
    CHECK(rs.d_k == 0.0f && rs.alarm == 0u && rs.started == 0u);             /* nothing written */
    rs.alarm = 1u;
    rs.d_k = 1.9f;
    /* each row 2.48 sigma alone (< 2.81), T = 12.3 > TD2: alarmed, nothing singled out */
    CHECK_EQ_INT((int)mca_kf_fuzzy_failed(&rc, &rs, both, c_t, 2u, g_ws), 0);
    /* row 1 kept out (out on the last two updates, not failing): with row 0 when it went out no
     * later than row 0, not when it went out on its own after row 0 */
    rs.n_removed[1] = 2u;
    CHECK_EQ_INT((int)mca_kf_fuzzy_failed(&rc, &rs, big0, c_t, 2u, g_ws), 3);
    rs.n_removed[0] = 5u;
    CHECK_EQ_INT((int)mca_kf_fuzzy_failed(&rc, &rs, big0, c_t, 2u, g_ws), 1);
    rs.n_removed[0] = 2u;
    CHECK_EQ_INT((int)mca_kf_fuzzy_failed(&rc, &rs, big0, c_t, 2u, g_ws), 3);

    const float h[4] = {1.0f, 0.0f, 0.0f, 1.0f}, r[4] = {0.1f, 0.0f, 0.0f, 0.1f};
    mca_update_report_t rep;
    /* z, pair rows, then: alarm, rejected, x[0] / x[1] moved */
    const struct {
        const float *z;
        uint8_t pair;
        int alarm, rejected, moved0, moved1;
    } steps[] = {
        {quiet, 1u, 0, 0, 0, 1}, /* not alarmed: row 0 out for the pair, row 1 applied */
        {quiet, 3u, 0, 1, 0, 0}, /* both: rejected without an alarm */
        {quiet, 0u, 0, 0, 1, 1}, /* the pair rows were for one update: everything applied */
        {big0, 2u, 1, 1, 0, 0},  /* alarmed, row 0 fails, row 1 for the pair: rejected */
    };
    mca_robust_state_init(&rs);
    for (size_t k = 0; k < sizeof steps / sizeof steps[0]; ++k) {
        float x[2] = {0.0f, 0.0f}, p[4];
        eye(p, 2, 1.0f);
        rs.started = steps[k].pair;
        CHECK_EQ_INT(mca_kf_update(x, p, 2, h, steps[k].z, r, 2, &rc, &rs, g_ws, WS_MAX, &rep), MCA_OK);
        CHECK_EQ_INT(rep.alarm, steps[k].alarm);
        CHECK_EQ_INT(rep.rejected, steps[k].rejected);
        CHECK_EQ_INT(x[0] != 0.0f, steps[k].moved0);
        CHECK_EQ_INT(x[1] != 0.0f, steps[k].moved1);
        CHECK_EQ_INT(rs.n_removed[0] > 0u || rs.n_reject > 0u, !steps[k].moved0);
        CHECK_EQ_INT(rs.started, 0);
    }
    /* a memory whose started is no row mask is refused, and left as it was */
    mca_robust_state_init(&rs);
    rs.started = (uint8_t)(1u << MCA_MEAS_MAX);
    float x[2] = {0.0f, 0.0f}, p[4];
    eye(p, 2, 1.0f);
    CHECK_EQ_INT(mca_kf_update(x, p, 2, h, quiet, r, 2, &rc, &rs, g_ws, WS_MAX, &rep), MCA_ERR_BAD_ARG);
    CHECK(x[0] == 0.0f && rs.started == (uint8_t)(1u << MCA_MEAS_MAX));
}

int main(void)
{
    test_chi2_table_matches_closed_form();
    test_fta_gamma_on_crafted_outlier();
    test_fuzzy_alarm_after_two_outliers_and_release();
    test_igg_weights_on_crafted_residuals();
    test_akf_q_scale_clamped_and_r_star();
    test_bad_input_leaves_state_in_every_mode();
    test_more_rows_than_states();
    test_long_run_p_stays_spd_every_mode();
    test_tested_update_decides_on_the_test_innovation();
    test_row_by_row_equals_joint_update();
    test_plain_test_statistic_small_m();
    test_plain_gains_and_test_stat();
    test_fuzzy_rows_leave_out_the_failing_row();
    test_fuzzy_rows_long_guard_needs_a_test_innovation();
    test_fuzzy_rows_apply_the_return_from_a_spike();
    test_fuzzy_rows_last_row_standing();
    test_fuzzy_rows_gate();
    test_fuzzy_rows_pair();
    TEST_MAIN_END();
}

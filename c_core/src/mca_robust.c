/* The one Kalman measurement update and its robust/adaptive modes (docs/ALGORITHMS.md
 * sections 1 and 5). See mca_robust.h. */
#include "mcahrs/mca_robust.h"
#include "mca_cold.h"
#include "mca_defaults.h"
#include "mca_kf_rows.h"

#include <math.h>
#include <string.h>

/* static const float mca_chi2_table[6][4]: rows m = 1..6, columns mca_chi2_level_t. */
#include "mca_chi2_table.inc"

/* The generated table must cover every measurement size and every level. */
typedef char mca_chi2_rows_ok[(sizeof(mca_chi2_table) / sizeof(mca_chi2_table[0]) == MCA_MEAS_MAX) ? 1 : -1];
typedef char mca_chi2_cols_ok[(sizeof(mca_chi2_table[0]) / sizeof(float) == (size_t)MCA_CHI2_LEVELS) ? 1 : -1];
/* Row bit masks below are unsigned ints. */
typedef char mca_meas_bits_ok[(MCA_MEAS_MAX <= 16) ? 1 : -1];

void mca_robust_config_default(mca_robust_config_t *cfg)
{
    static const mca_robust_config_t d = MCA_ROBUST_CONFIG_INIT;
    mca_copy_bytes(cfg, &d, sizeof d);
}

mca_status_t mca_robust_config_check(const mca_robust_config_t *c)
{
    if (c == NULL) {
        return MCA_ERR_NULL;
    }
    /* akf_q_min > 0 also makes the AKF "tiny" of eq. 19 irrelevant (see akf_q_scale). */
    if (c->mode > (uint8_t)MCA_ROBUST_IGG3 || c->fuzzy_reject > 2u || c->akf_window < 1u ||
        c->akf_window > MCA_AKF_WINDOW || !(c->akf_forget > 0.0f && c->akf_forget <= 1.0f) ||
        !(c->akf_q_min > 0.0f) || !(c->akf_q_max >= c->akf_q_min) || !(c->igg_k0 > 0.0f) ||
        !(c->igg_k1 > c->igg_k0) || !mca_finite(c->akf_q_max) || !mca_finite(c->igg_k1)) {
        return MCA_ERR_BAD_CONFIG;
    }
    return MCA_OK;
}

void mca_robust_state_init(mca_robust_state_t *st)
{
    mca_zero_bytes(st, sizeof(*st));
    st->q_scale = 1.0f;
}

int mca_robust_left_out(const mca_robust_state_t *rs, size_t m)
{
    int out = rs->n_reject > 0u;
    for (size_t i = 0; i < m && i < MCA_MEAS_MAX; ++i) {
        out |= rs->n_removed[i] > 0u;
    }
    return out;
}

float mca_chi2_quantile(size_t m, mca_chi2_level_t level)
{
    if (m < 1u || m > MCA_MEAS_MAX || (unsigned)level >= (unsigned)MCA_CHI2_LEVELS) {
        return 0.0f;
    }
    return mca_chi2_table[m - 1u][(unsigned)level];
}

size_t mca_kf_ws_len(size_t n, size_t m)
{
    return (size_t)MCA_KF_WS_LEN(n, m);
}

/* ---------------------------------------------------------------- memory */

/* 1 when rs is a memory that mca_robust_state_init and mca_kf_update can have produced
 * (counters in range, alarm 0/1, started a row mask, statistics finite, variances >= 0,
 * 0 < q_scale, D_k >= 0).
 * Only the modes that use the memory check it. */
static int memory_ok(const mca_robust_state_t *rs)
{
    if (rs->win_n > MCA_AKF_WINDOW || rs->win_head >= MCA_AKF_WINDOW || rs->alarm > 1u ||
        rs->started >= (1u << MCA_MEAS_MAX) || rs->n_reject == UINT8_MAX) {
        return 0;
    }
    for (size_t i = 0; i < MCA_MEAS_MAX; ++i) {
        if (rs->n_removed[i] == UINT8_MAX) {
            return 0;
        }
    }
    if (!mca_all_finite(rs->win, MCA_AKF_WINDOW) || !mca_all_finite(rs->nu_mean, MCA_MEAS_MAX) ||
        !mca_all_finite(rs->nu_var, MCA_MEAS_MAX) || !mca_finite(rs->q_scale) || !mca_finite(rs->d_k)) {
        return 0;
    }
    for (size_t i = 0; i < MCA_MEAS_MAX; ++i) {
        if (rs->nu_var[i] < 0.0f) {
            return 0;
        }
    }
    return rs->q_scale > 0.0f && rs->d_k >= 0.0f;
}

/* AKF step 1 for row i (ALGORITHMS.md 5): exponential forgetting of the innovation mean r_i
 * and variance s_i, the recursive form of eq. 15-16, the variance about the new mean. Pure:
 * called once to build R* and again to commit, with the same float operations, so both
 * calls give the same bits and nothing needs storing in between. Statistics are kept per row
 * index (ALGORITHMS.md 5 does not say what happens when m changes between updates, e.g. a CS
 * axis with position-only then position+velocity fixes): row i < m is updated, rows >= m
 * keep their values, and "first update" means the first of the memory (started), so a row
 * first seen later starts from the initial zero mean and variance with forgetting. Not inlined
 * into its two callers: 36 B of flash less. */
MCA_NOINLINE static void akf_row(const mca_robust_state_t *rs, float b, size_t i, float nu, float *r_new,
                                 float *s_new)
{
    if (rs->started == 0u) {
        *r_new = nu; /* first update of a memory */
        *s_new = 0.0f;
        return;
    }
    const float r = (1.0f - b) * rs->nu_mean[i] + b * nu;
    const float d = nu - r;
    *r_new = r;
    *s_new = (1.0f - b) * rs->nu_var[i] + b * (d * d);
}

/* AKF step 3: mean over the last min(win_n + 1, akf_window) values of e, the new one e_new
 * included, oldest first. The ring always has MCA_AKF_WINDOW slots (win_head the next one),
 * so a changed akf_window reads the last values correctly. */
static float akf_window_mean(const mca_robust_state_t *rs, size_t window, float e_new)
{
    size_t k = (size_t)rs->win_n + 1u;
    if (k > window) {
        k = window;
    }
    /* k - 1 stored values before the slot e_new goes to */
    float sum = 0.0f;
    for (size_t j = k - 1u; j > 0u; --j) {
        const size_t slot = ((size_t)rs->win_head + MCA_AKF_WINDOW - j) % MCA_AKF_WINDOW;
        sum += rs->win[slot];
    }
    sum += e_new;
    return sum / (float)k;
}

/* log2(v) for v > 0 (normal or +inf), the core's own (+, -, *, / and bit operations only),
 * so host and target compute the same bits (no libm log2f, whose last ulp differs between
 * glibc and newlib). v = 2^e m, m in [sqrt(1/2), sqrt(2)); ln m = 2 atanh(u), u = (m-1)/(m+1),
 * |u| < 0.172, five odd terms (first dropped term < 4e-10 relative). Error ~2 ulp. */
static float log2_pos(float v)
{
    if (!(v <= 3.4028235e38f)) {
        return v; /* +inf (or NaN) */
    }
    uint32_t bits;
    memcpy(&bits, &v, sizeof(bits));
    int32_t e = (int32_t)((bits >> 23) & 0xffu) - 127;
    bits = (bits & 0x007fffffu) | 0x3f800000u; /* mantissa in [1, 2) */
    float m;
    memcpy(&m, &bits, sizeof(m));
    if (m > 1.41421356f) {
        m *= 0.5f;
        ++e;
    }
    const float u = (m - 1.0f) / (m + 1.0f);
    const float u2 = u * u;
    const float ln_m =
        u * (2.0f + u2 * (0.666666667f + u2 * (0.4f + u2 * (0.285714286f + u2 * 0.222222222f))));
    return (float)e + ln_m * 1.44269504f; /* 1 / ln 2 */
}

/* AKF eq. 18-19: alpha = mean(window) / tr(H P H^T); q = clamp(log2(max(alpha + 1, tiny)),
 * q_min, q_max). Because q_min > 0 (config check), any log2 argument <= 1 clamps to q_min,
 * so "tiny" only keeps log2 away from 0, negatives and NaN; 1e-30f (a normal float) is
 * used. A zero tr(H P H^T) (no predicted spread) gives alpha = +inf for a positive mean
 * (q_max) and -inf otherwise (q_min). */
static float akf_q_scale(const mca_robust_config_t *rc, float mean_e, float tr_hph)
{
    float alpha;
    if (tr_hph > 0.0f) {
        alpha = mean_e / tr_hph;
    } else {
        alpha = mean_e > 0.0f ? INFINITY : -INFINITY;
    }
    float arg = alpha + 1.0f;
    if (!(arg > 1e-30f)) {
        arg = 1e-30f;
    }
    float q = log2_pos(arg); /* +inf for arg = +inf, clamped below */
    if (q < rc->akf_q_min) {
        q = rc->akf_q_min;
    }
    if (q > rc->akf_q_max) {
        q = rc->akf_q_max;
    }
    return q;
}

/* ---------------------------------------------------------------- modes */

/* What a mode asks of the common gain/Joseph step (section-1 steps 4-6). The gain uses
 * C_eff = gamma (C + diag(d)) over the kept rows, Joseph uses R_eff = R + diag(d) (rows not
 * kept get a zero gain column, so their R entries do not matter). d lives in ws. */
typedef struct {
    float gamma;       /* gain covariance scale (FTA, fuzzy inflation); 1 otherwise */
    unsigned keep;     /* bit i set: row i is used */
    int use_d;         /* d (per-row R diagonal increment) is non-zero somewhere */
    int rejected;      /* no update at all */
    float factor;      /* reported inflation */
    uint8_t detected;  /* reported */
    uint8_t alarm;     /* fuzzy: alarm after this update */
    float d_k;         /* fuzzy: D_k after this update */
    float q_scale;     /* AKF: Q factor after this update; 1 in other modes */
    float e_new;       /* AKF: this epoch's nu^T nu - tr(R) */
    unsigned failed;   /* fuzzy rows, for the pair: rows out for failing, and those kept out with
                          them (none without an alarm) */
} mca_plan_t;

/* FTA (paper 000): gamma = T / chi2_m(1e-4) above the threshold, else 1. */
static void plan_fta(mca_plan_t *pl, size_t m, float t_stat)
{
    const float thr = mca_chi2_table[m - 1u][MCA_CHI2_1E4];
    pl->gamma = t_stat <= thr ? 1.0f : t_stat / thr;
    pl->factor = pl->gamma;
    pl->detected = pl->gamma > 1.0f ? 1u : 0u; /* "detected = gamma > 1", as specified */
}

/* Fuzzy three-threshold detector (paper 001). Memberships of T as ALGORITHMS.md 5 writes
 * them; where two pieces meet (T = TD1, TD2, TD3) both give the same value. pair: rows a
 * fuzzy-rows update leaves out whatever its alarm (the paired axis', ALGORITHMS.md 5); own: the
 * update's own innovation (nu itself without a test innovation). */
static void plan_fuzzy(mca_plan_t *pl, const mca_robust_config_t *rc, const mca_robust_state_t *rs, size_t m,
                       float t_stat, const float *nu, const float *c, unsigned pair, const float *own)
{
    const float td1 = mca_chi2_table[m - 1u][MCA_CHI2_2P5E2]; /* 1 <= m <= MCA_MEAS_MAX (checked) */
    const float td2 = mca_chi2_table[m - 1u][MCA_CHI2_5E3];
    const float td3 = 10.0f * td2;
    /* mu = (TD1 / TD3) mu_H + mu_M / 2 + mu_D, piece by piece: a membership that is 0 on a piece
     * adds +0, so each piece is that sum's bits */
    float mu = 0.0f; /* a NaN T (refused by the update before it gets here) */
    if (t_stat < td1) {
        mu = td1 / td3;
    } else if (t_stat <= td2) {
        mu = (td1 / td3) * ((td2 - t_stat) / (td2 - td1)) + 0.5f * ((t_stat - td1) / (td2 - td1));
    } else if (t_stat < td3) {
        mu = 0.5f * ((td3 - t_stat) / (td3 - td2)) + (t_stat - td2) / (td3 - td2);
    } else if (t_stat >= td3) {
        mu = 1.0f;
    }
    float d = 0.5f * rs->d_k + mu; /* D_k = D_{k-1} / 2 + mu_k */
    uint8_t alarm = rs->alarm;
    const int rows = rc->fuzzy_reject == 2u;
    if (alarm == 0u && (rows ? d >= 1.0f : d > 1.0f)) { /* rows: one epoch past TD3 after a release */
        alarm = 1u;
    } else if (alarm != 0u && t_stat < td2 && d < 1.0f) {
        alarm = 0u; /* release */
        d = 0.0f;
    }
    pl->d_k = d;
    pl->alarm = alarm;
    pl->detected = alarm;
    if (rows) {
        /* rows (ALGORITHMS.md 5): without an alarm, out goes a row past 2 chi2_1(1e-4) whose
         * own innovation is within one test sigma of the tested one (the gate). While alarmed,
         * out go the rows whose own standardised test residual fails chi2_1(0.005) (2
         * chi2_1(1e-4) for the last row standing: the one row not out on the last two updates
         * while every other was) and, while any does, the rows out on the last two updates;
         * none or every row failing rejects the whole update. At the alarm's first epoch after an
         * applied one past TD2 (D_{k-1} >= 0.5), a row whose innovation has the opposite sign of
         * that epoch's, and is no larger, is the return from the outlier it took in: applied. The
         * pair rows go out alarmed or not. */
        unsigned drop = pair;
        const float k2 = mca_chi2_table[0][MCA_CHI2_5E3], k4 = mca_chi2_table[0][MCA_CHI2_1E4]; /* m = 1 */
        const int onset = alarm != 0u && rs->alarm == 0u && rs->d_k >= 0.5f;
        unsigned fail = 0u, out = 0u, was = 0u, n_out = 2u;
        for (size_t j = 0; j < m; ++j) {
            was |= rs->n_removed[j] > 1u ? 1u << j : 0u;
        }
        for (size_t j = 0; j < m; ++j) {
            const unsigned n = rs->n_removed[j], bit = 1u << j;
            const float cj = c[j * m + j], dl = own[j] - nu[j];
            const float kj = alarm == 0u || (was != 0u && bit == (~was & ((1u << m) - 1u))) ? k4 + k4 : k2;
            if (nu[j] * nu[j] > kj * cj && (alarm != 0u || dl * dl <= cj)) {
                fail |= bit;
                const float prev = rs->nu_mean[j];
                if (!(onset && nu[j] * prev < 0.0f && nu[j] * nu[j] <= prev * prev)) {
                    out |= bit;
                    n_out = n > n_out ? n : n_out;
                }
            }
        }
        drop |= alarm == 0u ? out : (fail | pair) == 0u ? pl->keep : out != 0u ? out | was : 0u;
        /* for the pair, alarmed: the failing rows, and the rows kept out that went out no later
         * than any of them (a fault of both), not a row that went out on its own after them */
        out = alarm != 0u ? out : 0u;
        for (size_t j = 0; j < m && out != 0u; ++j) {
            pl->failed |= rs->n_removed[j] >= n_out ? 1u << j : 0u;
        }
        pl->failed |= out;
        pl->keep &= ~drop;
        pl->rejected = pl->keep == 0u;
    } else if (alarm != 0u) {
        if (rc->fuzzy_reject != 0u) {
            pl->rejected = 1;
        } else {
            const float g = t_stat / td2;
            pl->gamma = g > 1.0f ? g : 1.0f;
            pl->factor = pl->gamma;
        }
    }
}

/* AKF (paper 004), steps 1-3; step 4 is the common update with R* = R + diag(d). */
/* nu_s: the innovation the row statistics follow (the test innovation when one is given);
 * nu: the update's own, for the Q window (ALGORITHMS.md 5, test innovation). */
static void plan_akf(mca_plan_t *pl, const mca_robust_config_t *rc, const mca_robust_state_t *rs, size_t n,
                     size_t m, const float *h, const float *pht, const float *r, const float *nu,
                     const float *nu_s, float t_stat, float *d)
{
    const float b = rc->akf_forget;
    /* step 2: detection with the chi2_m(1e-2) test; R* = R + diag(s_i) with the new s_i */
    const int det = t_stat > mca_chi2_table[m - 1u][MCA_CHI2_1E2];
    float tr_r = 0.0f, tr_rs = 0.0f, nu2 = 0.0f, tr_hph = 0.0f;
    for (size_t i = 0; i < m; ++i) {
        float r_new, s_new;
        akf_row(rs, b, i, nu_s[i], &r_new, &s_new);
        d[i] = det ? s_new : 0.0f;
        tr_r += r[i * m + i];
        tr_rs += r[i * m + i] + d[i];
        nu2 += nu[i] * nu[i];
        /* (H P H^T)_ii with the same sum as mca_mat_mul */
        float s = 0.0f;
        for (size_t l = 0; l < n; ++l) {
            s += h[i * n + l] * pht[l * m + i];
        }
        tr_hph += s;
    }
    pl->use_d = det;
    pl->detected = det ? 1u : 0u;
    /* factor = tr(R*) / tr(R); exactly 1 without detection. A non-positive tr(R) (R is
     * documented positive definite, only C is checked) reports 1. */
    pl->factor = (det && tr_r > 0.0f) ? tr_rs / tr_r : 1.0f;
    /* step 3: e = nu^T nu - tr(R) into the window, q_scale from its mean (eq. 18-19) */
    pl->e_new = nu2 - tr_r;
    pl->q_scale = akf_q_scale(rc, akf_window_mean(rs, rc->akf_window, pl->e_new), tr_hph);
}

/* IGG-III weight of a standardised residual s > k0 (paper 003). */
static float igg_weight(float s, float k0, float k1)
{
    if (s > k1) {
        return 0.0f;
    }
    const float q = (k1 - s) / (k1 - k0);
    return (k0 / s) * (q * q);
}

/* IGG-III (paper 003). c holds C (m x m) and gets R_ii / w_i - R_ii added to the diagonal
 * of each down-weighted row (the equivalent C); d the same increments (for R_eff); w (may be
 * NULL) the per-row weights, for the report. Only the weighted row's diagonal changes, so
 * the remaining rows' s are unchanged by the spec's "recompute"; they are recomputed from
 * c anyway (m^2 sqrtf, m <= 6). With a full R only R_ii is replaced, as written: the
 * off-diagonal R_ij of a down-weighted row stay (a larger diagonal keeps R positive definite).
 * "detected" is any w_i < 1 as computed (an s a hair above k0 whose weight rounds to 1.0f
 * does not count). Not inlined into update_general, whose frame and register pressure it
 * otherwise adds to: 28 B of flash less. */
MCA_NOINLINE static void plan_igg(mca_plan_t *pl, const mca_robust_config_t *rc, size_t m, const float *r,
                                  const float *nu, float *c, float *d, float *w)
{
    unsigned weighted = 0u;
    for (size_t i = 0; i < m; ++i) {
        d[i] = 0.0f;
    }
    for (size_t it = 0; it < m; ++it) {
        size_t imax = m;
        float smax = 0.0f;
        for (size_t j = 0; j < m; ++j) {
            if ((weighted & (1u << j)) != 0u) {
                continue;
            }
            const float s = fabsf(nu[j]) / sqrtf(c[j * m + j]);
            if (imax == m || s > smax) { /* strict: lowest index on ties */
                imax = j;
                smax = s;
            }
        }
        if (imax == m || smax <= rc->igg_k0) {
            break;
        }
        weighted |= 1u << imax;
        float wi = igg_weight(smax, rc->igg_k0, rc->igg_k1);
        const float rii = r[imax * m + imax];
        const float r_eq = wi > 0.0f ? rii / wi : 0.0f;
        if (!(wi > 0.0f) || !isfinite(r_eq)) {
            /* weight 0, or so small that R_ii / w overflows float: the row is removed */
            wi = 0.0f;
            pl->keep &= ~(1u << imax);
        } else {
            d[imax] = r_eq - rii;
            c[imax * m + imax] += d[imax];
            pl->use_d = 1;
        }
        if (wi < 1.0f) {
            pl->detected = 1u; /* any w_i < 1 */
        }
        if (w != NULL) {
            w[imax] = wi;
        }
    }
    if (pl->keep == 0u) {
        pl->rejected = 1; /* every row removed */
    }
}

/* ---------------------------------------------------------------- scratch layout
 *
 * The update's scratch (MCA_KF_WS_LEN(n, m) floats), block by block: pn (n x n): P+ being
 * built; kk (n x m): P H^T, then K in place (the row path: u); a (n x m): U = P H^T for the
 * Joseph step; b (n x m): K S; t (n x m): C^-1 nu, then the per-row R
 * increments d (m); c, l (m x m): C and its factor; xn (n): x+; y (m): nu; ct, lt (m x m): the
 * test covariance (IGG-III re-weights it) and its factor. Every m-vector fits in t (n >= 1).
 * update_general and apply carve it block after block; the row path reaches its blocks by
 * these offsets (floats from the start): */
#define WS_XN(n, m) ((n) * (n) + 4u * (n) * (m) + 2u * (m) * (m))
#define WS_Y(n, m) (WS_XN(n, m) + (n))
#define WS_CT(n, m) (WS_Y(n, m) + (m))
#define WS_LT(n, m) (WS_CT(n, m) + (m) * (m))

/* ---------------------------------------------------------------- products with H
 *
 * The measurement rows are sparse (a CS row has two ones in five columns, the roll/pitch
 * rows three entries in six). The row path (apply_rows, every plain update and the robust ones
 * with an unscaled gain) runs over the non-zero entries of H only. Skipping a zero entry is
 * exact, not an approximation: its product with a finite value is +-0, every sum there starts
 * at +0 and so is never -0 (in round-to-nearest x + (-x) = +0 and +0 + -0 = +0), and adding +-0
 * to such a sum changes no bit. The robust modes' joint path (update_general, apply) takes the
 * dense mca_mat_mul products, the same bits in the same order: until session 28 it had sparse
 * copies of them and its own gain solve (the reciprocals of the factor's diagonal taken once),
 * 404 B of flash for a few hundred instructions of a robust update, which no speed goal asks for
 * (scripts/fw_report.py: the goals are the plain filter's). */

static int nonzero(float v)
{
    return v > 0.0f || v < 0.0f;
}

/* nu^T C^-1 nu from the Cholesky factor l of C; t (m) is scratch. */
static float nis(const float *l, const float *nu, float *t, size_t m)
{
    mca_copyf(t, nu, m);
    mca_cholesky_solve(l, t, m);
    float s = 0.0f;
    for (size_t i = 0; i < m; ++i) {
        s += nu[i] * t[i];
    }
    return s;
}

/* The scratch blocks update_general carved (layout above) that apply works in, passed as one
 * pointer rather than as 9 stack arguments. */
typedef struct {
    float *pn, *kk, *a, *b, *t, *c, *l, *xn;
    const float *y;
} mca_ws_blocks_t;

/* Section-1 steps 4-6 with the plan: gain from C_eff = gamma (C + diag(d)) over the kept rows
 * (zero gain column for the others), x+ = x + K nu, Joseph with R_eff = R + diag(d),
 * symmetrised, finite check, then x and p written. c holds C (for IGG already with d on its
 * diagonal: c_has_d), l scratch for C_eff's factor, kk P H^T, t the increments d, y nu. */
static mca_status_t apply(float *x, float *p, size_t n, const float *h, const float *r, size_t m,
                          const mca_plan_t *pl, const mca_ws_blocks_t *w, int c_has_d)
{
    float *pn = w->pn, *kk = w->kk, *a = w->a, *b = w->b, *t = w->t, *c = w->c, *l = w->l, *xn = w->xn;
    const float *y = w->y;
    const float *d = t;
    if (pl->use_d && !c_has_d) {
        for (size_t i = 0; i < m; ++i) {
            c[i * m + i] += d[i];
        }
    }
    size_t mk = 0u;
    for (size_t i = 0; i < m; ++i) {
        mk += (pl->keep >> i) & 1u;
    }
    /* Compact the kept rows and columns to mk x mk at the start of c, scaled by gamma.
     * Destination index <= source index and both increase: safe in place. */
    size_t ik = 0u;
    for (size_t i = 0; i < m; ++i) {
        if ((pl->keep & (1u << i)) == 0u) {
            continue;
        }
        size_t jk = 0u;
        for (size_t j = 0; j < m; ++j) {
            if ((pl->keep & (1u << j)) != 0u) {
                c[ik * mk + jk] = pl->gamma * c[i * m + j];
                ++jk;
            }
        }
        ++ik;
    }
    if (!mca_all_finite(c, mk * mk)) {
        return MCA_ERR_NONFINITE; /* gamma C overflowed float (T near FLT_MAX) */
    }
    if (mca_cholesky(l, c, mk) != MCA_OK) {
        return MCA_ERR_SINGULAR;
    }
    /* U = P H^T kept in a (n x m) for the Joseph step below */
    float *u = a;
    mca_copyf(u, kk, n * m);
    /* K = P H^T C_eff^-1, row by row in place: C_eff k_i = (P H^T)_i over the kept columns */
    for (size_t i = 0; i < n; ++i) {
        float *row = &kk[i * m];
        size_t jk = 0u;
        for (size_t j = 0; j < m; ++j) { /* gather forward */
            if ((pl->keep & (1u << j)) != 0u) {
                row[jk++] = row[j];
            }
        }
        mca_cholesky_solve(l, row, mk);
        for (size_t j = m; j-- > 0u;) { /* scatter backward, zero for removed rows */
            row[j] = (pl->keep & (1u << j)) != 0u ? row[--jk] : 0.0f;
        }
    }
    /* R_eff into c (C and its compaction are no longer needed; d is read before t is reused) */
    mca_copyf(c, r, m * m);
    if (pl->use_d) {
        for (size_t i = 0; i < m; ++i) {
            c[i * m + i] += d[i];
        }
    }
    /* x+ = x + K nu */
    mca_mat_mul(xn, kk, y, n, m, 1u);
    for (size_t i = 0; i < n; ++i) {
        xn[i] += x[i];
    }
    /* Joseph, expanded: (I - K H) P (I - K H)^T + K R_eff K^T
     *   = P - K U^T - U K^T + K S K^T = P + A K^T + K A^T,  A = K S / 2 - U,
     * U = P H^T, S = H P H^T + R_eff: an identity for any gain K (so it keeps Joseph's
     * first-order insensitivity to gain errors) that costs O(n^2 m) instead of three
     * n x n x n products, and is symmetric by construction: the upper triangle is computed
     * and mirrored. */
    float *s = l; /* the Cholesky factor is no longer needed once K is solved */
    mca_mat_mul(s, h, u, m, n, m); /* H P H^T */
    for (size_t i = 0; i < m * m; ++i) {
        s[i] += c[i];
    }
    mca_mat_mul(b, kk, s, n, m, m); /* K S (n x m), then A = K S / 2 - U in place */
    for (size_t i = 0; i < n * m; ++i) {
        b[i] = 0.5f * b[i] - u[i];
    }
    float fin = 0.0f; /* sum of acc * 0: +0 while every entry is finite, NaN after one that is not */
    for (size_t i = 0; i < n; ++i) {
        const float *ai = &b[i * m], *ki = &kk[i * m];
        for (size_t j = i; j < n; ++j) {
            const float *aj = &b[j * m], *kj = &kk[j * m];
            float acc = p[i * n + j];
            for (size_t k = 0; k < m; ++k) {
                acc += ai[k] * kj[k] + ki[k] * aj[k];
            }
            pn[i * n + j] = acc;
            pn[j * n + i] = acc;
            fin += acc * 0.0f;
        }
    }
    /* the lower triangle is the mirror of the upper one: checking the upper one checks P+ */
    if (!mca_all_finite(xn, n) || !isfinite(fin)) {
        return MCA_ERR_NONFINITE;
    }
    mca_copyf(x, xn, n);
    mca_copyf(p, pn, n * n);
    return MCA_OK;
}

/* 1 when every entry of x (n) and P (n x n) is finite. */
static int state_finite(const float *x, const float *p, size_t n)
{
    return mca_all_finite(x, n) && mca_all_finite(p, n * n);
}

/* 1 when every entry of R (m x m) off its diagonal is +-0 (a NaN there is not: such an R goes
 * to the general path, whose input check reports it). */
static int r_diagonal(const float *r, size_t m)
{
    for (size_t i = 1; i < m; ++i) {
        for (size_t j = 0; j < i; ++j) {
            const float a = r[i * m + j], b = r[j * m + i];
            if (!(a >= 0.0f && a <= 0.0f && b >= 0.0f && b <= 0.0f)) {
                return 0;
            }
        }
    }
    return 1;
}

/* One row of apply_rows after its s: x+ = x + k nu and the upper triangle of P+ = P - k u^T,
 * each value written twice (mirrored into the lower triangle), k = u inv. In place (xn = xs,
 * pn = ps) a mirrored write is below the diagonal, never read later by this row. Returns the
 * sum of v * 0 over the values written (NaN after a non-finite one). Its own function: the
 * inner loop keeps its five pointers in registers (inlined into apply_rows, it spilled). The
 * attitude filter's plain rows call it too (mca_att.c; declared in mca_kf_rows.h). */
MCA_NOINLINE float mca_kf_row_apply(const float *xs, const float *ps, float *xn, float *pn, const float *u,
                                    size_t n, float inv, float nu)
{
    float fin = 0.0f;
    const float *const uend = &u[n];
    for (size_t i = 0; i < n; ++i) {
        const float ki = u[i] * inv;
        const float xv = xs[i] + ki * nu;
        xn[i] = xv;
        fin += xv * 0.0f;
        const float *pr = &ps[i * n + i], *uj = &u[i];
        float *pw = &pn[i * n + i], *pc = pw;
        do { /* n - i >= 1 values; do-while: -Os compiles it one branch shorter */
            const float v = *pr++ - ki * *uj++;
            *pw++ = v;
            *pc = v;
            pc += n;
            fin += v * 0.0f;
        } while (uj != uend);
    }
    return fin;
}

/* Section-1 steps 4-6 one row at a time (ALGORITHMS.md 1, sequential form): for a diagonal
 * R_eff = R + diag(d) and an unscaled gain (gamma 1) the joint update equals the kept rows
 * applied one after the other as scalar updates, each on the state and covariance the previous
 * one left. Row i: u = P h_i^T, s = h_i u + R_eff,ii, k = u / s, x += k (z_i - h_i x),
 * P -= k u^T. For this gain (the Kalman gain of the row) Joseph's form is the same matrix:
 * (I - k h) P (I - k h)^T + k r k^T = P - k u^T - u k^T + k s k^T = P - k u^T, as k s = u; only
 * the inflated gains of FTA and fuzzy need Joseph (the joint path). Each row computes P's upper
 * triangle (k_i u_j for j >= i: symmetric by construction, n(n+1)/2 multiplies a row) and
 * writes every value twice, mirrored, so the next row reads P h^T from whole rows of P (one
 * contiguous loop per non-zero of h) and the result is one copy. No m x m factor, no gain
 * solve: O(n^2) per row instead of O(n^2 m + n m^2) with an m x m Cholesky. The input P is
 * read as symmetric: its upper triangle and the rows h uses. keep: bit i
 * set, row i is applied; d: the R increments (NULL: none). Works in ws (general layout: pn, then
 * u in the kk block, xn in its own) and writes x, p only when every row's s is positive
 * and the result is finite. t_rows: the sum of the rows' nu_i^2 / s_i, which is
 * T = nu^T C^-1 nu (the s_i are the squared pivots of C's Cholesky factor, nu_i / sqrt(s_i)
 * its forward substitution of nu). */
MCA_NOINLINE static mca_status_t apply_rows(float *x, float *p, size_t n, const float *h, const float *z,
                                            const float *r, size_t m, unsigned keep, const float *d, float *ws,
                                            float *t_rows, float *gains)
{
    float *pn = ws;
    float *u = pn + n * n;
    float *xn = ws + WS_XN(n, m);
    /* The first row reads x and P and writes xn, pn; the later ones work in place there. P H^T
     * is read from the rows of P that H uses (P symmetric). Every entry of x, of P's upper
     * triangle and of the rows read reaches x+ or P+ through a sum, so the final check also
     * catches a non-finite input there. */
    const float *xs = x, *ps = p;
    float t_sum = 0.0f, fin = 0.0f;
    for (size_t row = 0; row < m; ++row) {
        if ((keep & (1u << row)) == 0u) {
            continue;
        }
        const float *hr = &h[row * n];
        for (size_t i = 0; i < n; ++i) {
            u[i] = 0.0f;
        }
        float hx = 0.0f;
        for (size_t l = 0; l < n; ++l) {
            const float hv = hr[l];
            if (!nonzero(hv)) {
                continue;
            }
            hx += hv * xs[l];
            const float *pl = &ps[l * n]; /* row l of the symmetric P is its column l */
            for (size_t i = 0; i < n; ++i) {
                u[i] += pl[i] * hv;
            }
        }
        float s = r[row * m + row] + (d != NULL ? d[row] : 0.0f);
        for (size_t l = 0; l < n; ++l) {
            s += hr[l] * u[l];
        }
        if (!(s > 0.0f)) { /* not positive: SINGULAR; NaN (from a non-finite input): NONFINITE */
            return s <= 0.0f ? MCA_ERR_SINGULAR : MCA_ERR_NONFINITE;
        }
        if (!(s <= 3.4028235e38f)) {
            return MCA_ERR_NONFINITE; /* an infinite R_ii or P H^T */
        }
        const float inv = 1.0f / s, nu = z[row] - hx;
        t_sum += nu * (nu * inv);
        if (gains != NULL) { /* mca_kf_row_apply's gain, the same product */
            for (size_t i = 0; i < n; ++i) {
                gains[i] = u[i] * inv;
            }
            gains[n] = inv;
            gains += n + 1u;
        }
        fin += mca_kf_row_apply(xs, ps, xn, pn, u, n, inv, nu);
        xs = xn;
        ps = pn;
    }
    /* xs, ps: the result (x and P themselves when no row was kept: nothing to copy).
     * fin, the sum of v * 0 over every value any row wrote (one VMLA each), is +0 while all were
     * finite (v * 0 is +0 or -0) and NaN after one that was not. */
    if (!isfinite(fin)) {
        return MCA_ERR_NONFINITE;
    }
    if (ps != p) {
        mca_copyf(x, xs, n);
        mca_copyf(p, ps, n * n);
    }
    *t_rows = t_sum;
    return MCA_OK;
}

/* T of a test innovation with m <= 2 in closed form from the symmetric ct (inverse by the
 * determinant): 1 when ct is positive definite with a finite determinant, 0 otherwise. A CS
 * axis (m = 2) costs ~20 flops instead of the factor and two triangular solves. */
static int small_test_stat(const float *nu_t, const float *ct, size_t m, float *t_stat)
{
    const float a = ct[0];
    if (m > 2u || !(a > 0.0f)) {
        return 0;
    }
    if (m == 1u) {
        *t_stat = nu_t[0] * nu_t[0] / a;
        return 1;
    }
    const float b = ct[1], d = ct[3];
    const float det = a * d - b * b;
    if (!(det > 0.0f) || !(det <= 3.4028235e38f)) {
        return 0;
    }
    *t_stat = (d * nu_t[0] * nu_t[0] - 2.0f * b * nu_t[0] * nu_t[1] + a * nu_t[1] * nu_t[1]) / det;
    return 1;
}

/* T = nu_t^T C_t^-1 nu_t of a test innovation: C_t symmetrised into ct (what the modes read);
 * for m <= 2 in closed form, else (or when that refuses ct) factored into lt, t (m) scratch.
 * SINGULAR when C_t is not positive definite. */
static mca_status_t test_stat(const float *nu_t, const float *c_t, float *ct, float *lt, float *t, size_t m,
                              float *t_stat)
{
    for (size_t i = 0; i < m * m; ++i) {
        ct[i] = c_t[i];
    }
    mca_mat_symmetrize(ct, m);
    if (small_test_stat(nu_t, ct, m, t_stat)) {
        return MCA_OK;
    }
    if (mca_cholesky(lt, ct, m) != MCA_OK) {
        return MCA_ERR_SINGULAR;
    }
    *t_stat = nis(lt, nu_t, t, m);
    return MCA_OK;
}

mca_status_t mca_kf_test_stat(const float *nu_t, const float *c_t, size_t m, float *ws, float *t_stat)
{
    if (nu_t == NULL || c_t == NULL || ws == NULL || t_stat == NULL) {
        return MCA_ERR_NULL;
    }
    if (m == 0u || m > MCA_MEAS_MAX) {
        return MCA_ERR_BAD_ARG;
    }
    return test_stat(nu_t, c_t, ws, ws + m * m, ws + 2u * m * m, m, t_stat);
}

unsigned mca_kf_fuzzy_failed(const mca_robust_config_t *rc, const mca_robust_state_t *rs, const float *nu_t,
                             const float *c_t, size_t m, float *ws)
{
    float t_stat;
    if (test_stat(nu_t, c_t, ws, ws + m * m, ws + 2u * m * m, m, &t_stat) != MCA_OK || !isfinite(t_stat)) {
        return 0u;
    }
    mca_plan_t pl; /* plan_fuzzy reads only keep; failed is written only when alarmed */
    pl.keep = (1u << m) - 1u;
    pl.failed = 0u;
    plan_fuzzy(&pl, rc, rs, m, t_stat, nu_t, c_t, 0u, nu_t);
    return pl.failed;
}

MCA_NOINLINE void mca_kf_plain_memory(mca_robust_state_t *rs, size_t m, float t_stat)
{
    if (rs != NULL) {
        rs->n_reject = 0u;
        for (size_t i = 0; i < m; ++i) {
            rs->n_removed[i] = 0u;
        }
        rs->t_stat = t_stat;
        rs->detected = 0u;
    }
}

/* Plain mode, diagonal R, no report: the rows one by one (apply_rows), T from them or from the
 * test innovation, and the memory's counters as the general path leaves them in plain mode.
 * ws in the general layout. */
MCA_NOINLINE static mca_status_t update_plain_rows(float *x, float *p, size_t n, const float *h, const float *z,
                                                   const float *r, size_t m, mca_robust_state_t *rs,
                                                   const float *nu_t, const float *c_t, float *ws, float *gains)
{
    float *ct = ws + WS_CT(n, m);
    float t_stat = 0.0f;
    /* A finite T comes only from finite nu_t and C_t (every entry enters it): the explicit
     * finite check runs only when T is not finite or C_t was refused. */
    if (nu_t != NULL) {
        const mca_status_t s = test_stat(nu_t, c_t, ct, ws + WS_LT(n, m), ws + WS_Y(n, m), m, &t_stat);
        if (s != MCA_OK || !isfinite(t_stat)) {
            if (!mca_all_finite(nu_t, m) || !mca_all_finite(c_t, m * m)) {
                return MCA_ERR_NONFINITE;
            }
            if (s != MCA_OK) {
                return s;
            }
        }
    }
    float t_rows;
    const mca_status_t st = apply_rows(x, p, n, h, z, r, m, (1u << m) - 1u, NULL, ws, &t_rows, gains);
    if (st != MCA_OK) {
        return st;
    }
    mca_kf_plain_memory(rs, m, nu_t == NULL ? t_rows : t_stat);
    return MCA_OK;
}

/* ---------------------------------------------------------------- the update */

mca_status_t mca_kf_update(float *x, float *p, size_t n, const float *h, const float *z,
                           const float *r, size_t m, const mca_robust_config_t *rc,
                           mca_robust_state_t *rs, float *ws, size_t ws_len,
                           mca_update_report_t *rep)
{
    return mca_kf_update_tested(x, p, n, h, z, r, m, rc, rs, NULL, NULL, ws, ws_len, rep);
}

mca_status_t mca_kf_update_plain(float *x, float *p, size_t n, const float *h, const float *z, const float *r,
                                 size_t m, mca_robust_state_t *rs, const float *nu_t, const float *c_t, float *ws,
                                 size_t ws_len, float *gains)
{
    if (x == NULL || p == NULL || h == NULL || z == NULL || r == NULL || ws == NULL || gains == NULL ||
        (nu_t != NULL && c_t == NULL)) {
        return MCA_ERR_NULL;
    }
    if (m == 0u || m > MCA_MEAS_MAX || n == 0u || ws_len < (size_t)MCA_KF_WS_LEN(n, m) || !r_diagonal(r, m)) {
        return MCA_ERR_BAD_ARG;
    }
    return update_plain_rows(x, p, n, h, z, r, m, rs, nu_t, c_t, ws, gains);
}

/* Every mode, any R: nominal nu and C, the mode's plan on T (or the test's), the lock-up
 * guard, the row-by-row or the joint update, the memory committed. Arguments checked. */
MCA_NOINLINE static mca_status_t update_general(float *x, float *p, size_t n, const float *h, const float *z,
                                                const float *r, size_t m, const mca_robust_config_t *rc,
                                                mca_robust_state_t *rs, const float *nu_t, const float *c_t,
                                                float *ws, mca_update_report_t *rep);

mca_status_t mca_robust_inputs_check(const mca_robust_config_t *rc, const mca_robust_state_t *rs)
{
    /* Plain mode reads no other field of rc: the range check is for the modes that do (an
     * unknown mode is not plain, so it is refused there). */
    if (rc == NULL || rc->mode == (uint8_t)MCA_ROBUST_PLAIN) {
        return MCA_OK;
    }
    if (mca_robust_config_check(rc) != MCA_OK) {
        return MCA_ERR_BAD_CONFIG;
    }
    if (rc->mode == (uint8_t)MCA_ROBUST_AKF || rc->mode == (uint8_t)MCA_ROBUST_FUZZY) {
        if (rs == NULL) {
            return MCA_ERR_NULL;
        }
        if (!memory_ok(rs)) {
            return MCA_ERR_BAD_ARG;
        }
    }
    return MCA_OK;
}

mca_status_t mca_kf_update_tested(float *x, float *p, size_t n, const float *h, const float *z,
                                  const float *r, size_t m, const mca_robust_config_t *rc,
                                  mca_robust_state_t *rs, const float *nu_t, const float *c_t,
                                  float *ws, size_t ws_len, mca_update_report_t *rep)
{
    if (x == NULL || p == NULL || h == NULL || z == NULL || r == NULL || ws == NULL || (nu_t != NULL && c_t == NULL)) {
        return MCA_ERR_NULL;
    }
    if (m == 0u || m > MCA_MEAS_MAX || n == 0u || ws_len < (size_t)MCA_KF_WS_LEN(n, m)) {
        return MCA_ERR_BAD_ARG;
    }
    const mca_status_t st = mca_robust_inputs_check(rc, rs);
    if (st != MCA_OK) {
        return st;
    }
    return mca_kf_update_tested_nocheck(x, p, n, h, z, r, m, rc, rs, nu_t, c_t, ws, rep, NULL);
}

mca_status_t mca_kf_update_tested_nocheck(float *x, float *p, size_t n, const float *h, const float *z,
                                          const float *r, size_t m, const mca_robust_config_t *rc,
                                          mca_robust_state_t *rs, const float *nu_t, const float *c_t, float *ws,
                                          mca_update_report_t *rep, float *gains)
{
    const mca_robust_mode_t mode = rc != NULL ? (mca_robust_mode_t)rc->mode : MCA_ROBUST_PLAIN;
    /* Plain mode with a diagonal R needs neither nu nor C before the update: the rows give T.
     * They are formed only for a report (the general path). The row-by-row update checks its
     * inputs through what it computes: every entry of H and of R's diagonal reaches its row's s
     * (checked finite and positive), every entry of x, z and P's upper triangle reaches x+ or P+
     * (checked finite before anything is written), so a non-finite input is NONFINITE there too;
     * so does the test innovation (update_plain_rows). */
    if (mode == MCA_ROBUST_PLAIN && rep == NULL && r_diagonal(r, m)) {
        return update_plain_rows(x, p, n, h, z, r, m, rs, nu_t, c_t, ws, gains);
    }
    /* the general path checks the test innovation, z, R and H here; x and P before the joint
     * update, a rejection, or a SINGULAR status (which a non-finite P causes), else through the
     * row-by-row result */
    if ((nu_t != NULL && (!mca_all_finite(nu_t, m) || !mca_all_finite(c_t, m * m))) || !mca_all_finite(z, m) ||
        !mca_all_finite(r, m * m) || !mca_all_finite(h, m * n)) {
        return MCA_ERR_NONFINITE;
    }
    return update_general(x, p, n, h, z, r, m, rc, rs, nu_t, c_t, ws, rep);
}

/* An empty plan: every row kept, no inflation (the plain update). Not inlined into
 * update_general's two calls: 20 B of flash less. */
MCA_NOINLINE static void plan_init(mca_plan_t *pl, size_t m)
{
    pl->gamma = 1.0f; /* field by field: a memset call on every update's path otherwise */
    pl->keep = (1u << m) - 1u;
    pl->use_d = 0;
    pl->rejected = 0;
    pl->factor = 1.0f;
    pl->detected = 0u;
    pl->alarm = 0u;
    pl->d_k = 0.0f;
    pl->q_scale = 1.0f;
    pl->e_new = 0.0f;
    pl->failed = 0u;
}

/* C = H (P H^T) + R, symmetrised; u = P H^T (n x m). */
static void form_c(float *c, const float *h, const float *u, const float *r, size_t n, size_t m)
{
    mca_mat_mul(c, h, u, m, n, m);
    for (size_t i = 0; i < m * m; ++i) {
        c[i] += r[i];
    }
    mca_mat_symmetrize(c, m);
}

static mca_status_t update_general(float *x, float *p, size_t n, const float *h, const float *z, const float *r,
                                   size_t m, const mca_robust_config_t *rc, mca_robust_state_t *rs,
                                   const float *nu_t, const float *c_t, float *ws, mca_update_report_t *rep)
{
    const int tested = nu_t != NULL;
    const mca_robust_mode_t mode = rc != NULL ? (mca_robust_mode_t)rc->mode : MCA_ROBUST_PLAIN;
    /* the scratch blocks (layout above) */
    float *pn = ws;
    float *kk = pn + n * n;
    float *a = kk + n * m;
    float *b = a + n * m;
    float *t = b + n * m;
    float *c = t + n * m;
    float *l = c + m * m;
    float *xn = l + m * m;
    float *y = xn + n;
    float *ct = y + m;
    float *lt = ct + m * m;

    /* nu = z - H x -> y; C = H P H^T + R (ALGORITHMS.md 1, step 1) */
    mca_mat_mul(y, h, x, m, n, 1u);
    for (size_t i = 0; i < m; ++i) {
        y[i] = z[i] - y[i];
    }
    mca_mat_mul_bt(kk, p, h, n, n, m); /* P H^T (P symmetric) */
    form_c(c, h, kk, r, n, m);
    if (rep != NULL) {
        mca_zero_bytes(rep, sizeof(*rep));
        rep->m = (uint8_t)m;
        rep->mode = (uint8_t)mode;
        rep->factor = 1.0f;
        rep->q_scale = 1.0f;
        for (size_t i = 0; i < m; ++i) {
            rep->w[i] = 1.0f;
        }
        mca_copyf(rep->nu, y, m);
        mca_copyf(rep->c, c, m * m);
    }
    /* step 2: C positive definite */
    if (mca_cholesky(l, c, m) != MCA_OK) {
        return state_finite(x, p, n) ? MCA_ERR_SINGULAR : MCA_ERR_NONFINITE;
    }
    /* step 3: T = nu^T C^-1 nu */
    float t_stat = nis(l, y, t, m);
    /* The innovation the mode tests: the update's own, or the caller's test innovation. */
    const float *nu_m = y;
    float *c_m = c;
    if (tested) {
        const mca_status_t s = test_stat(nu_t, c_t, ct, lt, t, m, &t_stat);
        if (s != MCA_OK) {
            return s;
        }
        nu_m = nu_t;
        c_m = ct;
    }
    if (rep != NULL) {
        rep->t_stat = t_stat;
        rep->tested = tested ? 1u : 0u;
    }
    if (mode != MCA_ROBUST_PLAIN && !isfinite(t_stat)) {
        return MCA_ERR_NONFINITE; /* every robust test needs T (plain mode never reads it) */
    }

    /* The mode's plan (ALGORITHMS.md 5). Nothing outside ws (and rep->w) is written here. */
    mca_plan_t pl;
    plan_init(&pl, m);
    float *d = t; /* per-row R diagonal increment, m values */
    switch (mode) {
    case MCA_ROBUST_FTA:
        plan_fta(&pl, m, t_stat);
        break;
    case MCA_ROBUST_AKF:
        plan_akf(&pl, rc, rs, n, m, h, kk, r, y, nu_m, t_stat, d);
        break;
    case MCA_ROBUST_FUZZY:
        plan_fuzzy(&pl, rc, rs, m, t_stat, nu_m, c_m, rs->started, y);
        break;
    case MCA_ROBUST_IGG3:
        plan_igg(&pl, rc, m, r, nu_m, c_m, d, rep != NULL ? rep->w : NULL);
        break;
    case MCA_ROBUST_PLAIN:
    default:
        break;
    }

    /* Lock-up guard (ALGORITHMS.md 5): the reject_reset_n-th rejection in a row is replaced by
     * a plain update and the memory is cleared, so a filter whose innovations only grow while
     * it is rejecting (a maneuver taken for an outlier) cannot run open loop for ever. */
    const unsigned removed = ~pl.keep & ((1u << m) - 1u); /* rows the mode removed (IGG-III) */
    int reset = 0;
    if (rs != NULL && rc != NULL) {
        /* fuzzy rows' long guard presumes that the caller coasts on the prediction it tests
         * against (the CS axes on the IMU); without a test innovation the filter runs on its own
         * mean while it rejects: the default guard */
        const int own_mean = mode == MCA_ROBUST_FUZZY && rc->fuzzy_reject == 2u && !tested;
        const unsigned cap = own_mean ? MCA_ROBUST_RESET_N_DEFAULT : 255u;
        const unsigned guard = rc->reject_reset_n < cap ? rc->reject_reset_n : cap;
        reset = pl.rejected && guard > 0u && (unsigned)rs->n_reject + 1u >= guard;
        for (size_t i = 0; i < m && rc->row_reset_n > 0u; ++i) {
            if (((removed >> i) & 1u) != 0u && (unsigned)rs->n_removed[i] + 1u >= (unsigned)rc->row_reset_n) {
                reset = 1;
            }
        }
    }
    int c_has_d = mode == MCA_ROBUST_IGG3 && !tested; /* IGG-III re-weighted c_m */
    if (reset) {
        plan_init(&pl, m);
        /* C and its factor again without any IGG increment (kk still holds P H^T) */
        form_c(c, h, kk, r, n, m);
        if (mca_cholesky(l, c, m) != MCA_OK) {
            return MCA_ERR_SINGULAR;
        }
        c_has_d = 0;
        if (rep != NULL) {
            for (size_t i = 0; i < m; ++i) {
                rep->w[i] = 1.0f;
            }
        }
    }
    if (!pl.rejected && !(pl.gamma > 1.0f) && r_diagonal(r, m)) {
        /* an unscaled gain with a diagonal R_eff: row by row (its result check covers x and P) */
        float t_rows;
        const mca_status_t st = apply_rows(x, p, n, h, z, r, m, pl.keep, pl.use_d ? t : NULL, ws, &t_rows, NULL);
        if (st != MCA_OK) {
            return st; /* x, p, rs untouched */
        }
    } else if (!state_finite(x, p, n)) {
        return MCA_ERR_NONFINITE; /* nothing is committed from a non-finite state */
    } else if (!pl.rejected) {
        const mca_ws_blocks_t wb = {pn, kk, a, b, t, c, l, xn, y};
        const mca_status_t st = apply(x, p, n, h, r, m, &pl, &wb, c_has_d);
        if (st != MCA_OK) {
            return st;
        }
    }
    /* Commit the memory (the update, if any, is already in x, p). */
    if (reset) {
        mca_robust_state_init(rs);
    } else if (mode == MCA_ROBUST_AKF) {
        for (size_t i = 0; i < m; ++i) {
            float r_new, s_new;
            akf_row(rs, rc->akf_forget, i, nu_m[i], &r_new, &s_new);
            rs->nu_mean[i] = r_new;
            rs->nu_var[i] = s_new;
        }
        rs->started = 1u;
        rs->win[rs->win_head] = pl.e_new;
        rs->win_head = (uint8_t)((rs->win_head + 1u) % MCA_AKF_WINDOW);
        if (rs->win_n < MCA_AKF_WINDOW) {
            ++rs->win_n;
        }
        rs->q_scale = pl.q_scale;
    } else if (mode == MCA_ROBUST_FUZZY) {
        rs->d_k = pl.d_k;
        rs->alarm = pl.alarm;
        rs->started = 0u; /* the pair rows are for one update */
        mca_copyf(rs->nu_mean, nu_m, m); /* the last tested innovation (fuzzy rows' return rule) */
    }
    if (rs != NULL && !reset) {
        rs->n_reject = pl.rejected ? (uint8_t)(rs->n_reject < 254u ? rs->n_reject + 1u : 254u) : 0u;
        for (size_t i = 0; i < m && i < MCA_MEAS_MAX; ++i) { /* m <= MCA_MEAS_MAX (checked): the
                                                                 bound is for the compiler */
            const uint8_t k = rs->n_removed[i];
            rs->n_removed[i] = ((removed >> i) & 1u) != 0u ? (uint8_t)(k < 254u ? k + 1u : 254u) : 0u;
        }
    }
    if (rs != NULL) {
        rs->t_stat = t_stat;
        rs->detected = pl.detected;
    }
    if (rep != NULL) {
        rep->reset = reset ? 1u : 0u;
        rep->factor = pl.rejected ? 1.0f : pl.factor;
        rep->detected = pl.detected;
        rep->rejected = pl.rejected ? 1u : 0u;
        rep->alarm = mode == MCA_ROBUST_FUZZY ? pl.alarm : 0u;
        rep->q_scale = mode == MCA_ROBUST_AKF ? pl.q_scale : 1.0f;
        /* rep->w: 1 from the start, IGG-III wrote its weights */
    }
    return MCA_OK;
}

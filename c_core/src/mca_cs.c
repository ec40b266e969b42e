/* Current-statistical maneuver filter (DESIGN.md 3, docs/ALGORITHMS.md 2-3). See mca_cs.h. */
#include "mcahrs/mca_cs.h"
#include "mca_cold.h"
#include "mca_defaults.h"
#include "mca_cs_nocheck.h"
#include "mca_kf_rows.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

#include "mca_cs_series.inc"

#define MCA_PI_F 3.14159265358979f

MCA_COLD void mca_cs_config_default_h(mca_cs_config_t *cfg)
{
    static const mca_cs_config_t d = MCA_CS_CONFIG_H_INIT(MCA_CS_SIGMA_A0_H);
    mca_copy_bytes(cfg, &d, sizeof d);
}

MCA_COLD void mca_cs_config_default_v(mca_cs_config_t *cfg)
{
    static const mca_cs_config_t d = MCA_CS_CONFIG_V_INIT;
    mca_copy_bytes(cfg, &d, sizeof d);
}

MCA_COLD mca_status_t mca_cs_config_check(const mca_cs_config_t *cfg)
{
    if (cfg == NULL) {
        return MCA_ERR_NULL;
    }
    /* every float field > 0, but the Gauss-Markov error stds sigma_p, sigma_v >= 0 */
    static const uint16_t off[] = {
        offsetof(mca_cs_config_t, tau_a_s),       offsetof(mca_cs_config_t, tau_p_s),
        offsetof(mca_cs_config_t, tau_v_s),       offsetof(mca_cs_config_t, sigma_p_m),
        offsetof(mca_cs_config_t, sigma_v_mps),   offsetof(mca_cs_config_t, sigma_a0_mps2),
        offsetof(mca_cs_config_t, a_max_mps2),    offsetof(mca_cs_config_t, sigma_a_min_mps2),
        offsetof(mca_cs_config_t, p0_var_m2),     offsetof(mca_cs_config_t, v0_var_m2ps2),
        offsetof(mca_cs_config_t, a0_var_m2ps4),  offsetof(mca_cs_config_t, dt_max_s)};
    if (!mca_fields_ok(cfg, off, sizeof off / sizeof off[0], 0x18u) || cfg->adaptive > 1u || cfg->coast > 1u ||
        mca_robust_config_check(&cfg->robust) != MCA_OK) {
        return MCA_ERR_BAD_CONFIG;
    }
    return MCA_OK;
}

/* mca_cs_axis_init past its checks */
static void axis_init(mca_cs_axis_t *ax, const mca_cs_config_t *cfg, float p0_m, float v0_mps)
{
    mca_zero_bytes(ax, sizeof(*ax));
    mca_copy_bytes(&ax->cfg, cfg, sizeof(ax->cfg));
    ax->x[0] = p0_m;
    ax->x[1] = v0_mps;
    ax->p[0] = cfg->p0_var_m2;
    ax->p[6] = cfg->v0_var_m2ps2;
    ax->p[12] = cfg->a0_var_m2ps4;
    ax->p[18] = cfg->sigma_p_m * cfg->sigma_p_m;
    ax->p[24] = cfg->sigma_v_mps * cfg->sigma_v_mps;
    ax->s2_m2ps4 = cfg->sigma_a0_mps2 * cfg->sigma_a0_mps2;
    ax->rs.q_scale = 1.0f; /* the memory of mca_robust_state_init: the rest is zeroed above */
}

MCA_COLD mca_status_t mca_cs_axis_init(mca_cs_axis_t *ax, const mca_cs_config_t *cfg, float p0_m, float v0_mps)
{
    if (ax == NULL || cfg == NULL) {
        return MCA_ERR_NULL;
    }
    const mca_status_t st = mca_cs_config_check(cfg);
    if (st != MCA_OK) {
        return st;
    }
    if (!isfinite(p0_m) || !isfinite(v0_mps)) {
        return MCA_ERR_NONFINITE;
    }
    axis_init(ax, cfg, p0_m, v0_mps);
    return MCA_OK;
}

float mca_cs_maneuver_var(const mca_cs_config_t *cfg, float abar)
{
    const float s20 = cfg->sigma_a0_mps2 * cfg->sigma_a0_mps2;
    if (cfg->adaptive == 0u || !(abar > 0.0f || abar < 0.0f)) {
        return s20; /* fixed mode, or abar == 0 exactly (docs/ALGORITHMS.md 2, step 3) */
    }
    const float amax = cfg->a_max_mps2;
    float ac = fabsf(abar);
    ac = ac > amax ? amax : ac;
    /* (a_max - abar)^2 for abar > 0, (a_max + abar)^2 for abar < 0: both (a_max - |abar|)^2 */
    float s2 = (4.0f - MCA_PI_F) / MCA_PI_F * (amax - ac) * (amax - ac);
    const float floor2 = cfg->sigma_a_min_mps2 * cfg->sigma_a_min_mps2;
    return s2 > floor2 ? s2 : floor2;
}

/* Terms of the series that keep the dropped tail below 2^-27 of the value for every entry,
 * for 0 <= x < MCA_CS_SERIES_X (measured from the exact rational coefficients of
 * scripts/gen_singer_series.py; the Van Loan test covers every band). */
#define SERIES_TERMS_MAX 20u
static size_t series_terms(float x)
{
    return x <= 0.05f ? 5u : x <= 0.2f ? 8u : x <= 0.5f ? 10u : x <= 1.0f ? 14u : SERIES_TERMS_MAX;
}
/* The generated tables hold exactly the terms series_terms can ask for: one more would be flash
 * never read. */
typedef char mca_cs_series_len_ok[(MCA_CS_SERIES_TERMS == SERIES_TERMS_MAX) ? 1 : -1];

/* Horner evaluation of sum_{k<n} c[k] x^k, n = series_terms(x). */
static float series(const float *c, float x)
{
    const size_t n = series_terms(x);
    float s = 0.0f;
    for (size_t k = n; k-- > 0;) {
        s = s * x + c[k];
    }
    return s;
}

/* mca_cs_singer_q with em1 = expm1(-alpha t) given (the transition has it already), the 3 x 3
 * block written at q with row stride n (3: Q33 itself; 5: the block of the transition's Q, no copy). */
static void singer_q_em1(float alpha, float t, float s2, float em1, float *q, size_t n)
{
    const float qc = 2.0f * alpha * s2; /* white-noise density of w_a */
    const float x = alpha * t;
    float q11, q12, q13, q22, q23, q33v;
    /* (1 - e)^2 and 1 - e^2 are cancellation-free through expm1: e^2 - 1 = (e - 1)(e + 1) */
    const float em2 = em1 * (em1 + 2.0f); /* e^2 - 1 */
    if (x < MCA_CS_SERIES_X) {
        /* q_ij = q T^p / 2 * g_ij(x)/x^p, series of scripts/gen_singer_series.py */
        const float t2 = t * t, t3 = t2 * t;
        q11 = 0.5f * qc * t3 * t2 * series(mca_cs_series_g11, x);
        q12 = 0.5f * qc * t2 * t2 * series(mca_cs_series_g12, x);
        q13 = 0.5f * qc * t3 * series(mca_cs_series_g13, x);
        q22 = 0.5f * qc * t3 * series(mca_cs_series_g22, x);
    } else {
        /* DESIGN.md 3, exact Singer forms; no cancellation worth a bit for x >= 2 */
        const float e = 1.0f + em1, e2 = e * e;
        const float a2 = alpha * alpha, a3 = a2 * alpha, a4 = a3 * alpha, a5 = a4 * alpha;
        q11 = qc / (2.0f * a5) *
              (1.0f - e2 + 2.0f * x + 2.0f * x * x * x / 3.0f - 2.0f * x * x - 4.0f * x * e);
        q12 = qc / (2.0f * a4) * (e2 + 1.0f - 2.0f * e + 2.0f * x * e - 2.0f * x + x * x);
        q13 = qc / (2.0f * a3) * (1.0f - e2 - 2.0f * x * e);
        q22 = qc / (2.0f * a3) * (4.0f * e - 3.0f - e2 + 2.0f * x);
    }
    q23 = qc / (2.0f * alpha * alpha) * em1 * em1;
    q33v = -qc / (2.0f * alpha) * em2;
    q[0] = q11;
    q[1] = q12;
    q[2] = q13;
    q[n] = q12;
    q[n + 1u] = q22;
    q[n + 2u] = q23;
    q[2u * n] = q13;
    q[2u * n + 1u] = q23;
    q[2u * n + 2u] = q33v;
}

void mca_cs_singer_q(float alpha, float t, float s2, float q33[9])
{
    singer_q_em1(alpha, t, s2, mca_expm1f(-alpha * t), q33, 3u);
}

/* mca_cs_transition's entries that can be non-zero (A3 of Phi, its diagonal, Q's 3 x 3 block and
 * Q44, Q55); the others are left as they are. The predicts read no other entry. */
static void transition_nz(const mca_cs_config_t *cfg, float t, float s2, float phi[25], float q[25])
{
    const float alpha = 1.0f / cfg->tau_a_s;
    const float beta = 1.0f / cfg->tau_p_s;
    const float gamma = 1.0f / cfg->tau_v_s;
    const float x = alpha * t;
    const float em1 = mca_expm1f(-x); /* e - 1 */
    phi[0] = 1.0f;
    phi[1] = t;
    /* Phi13 = (alpha T - 1 + e)/alpha^2 = T^2 (x - 1 + e)/x^2 */
    phi[2] = (x < MCA_CS_SERIES_X) ? t * t * series(mca_cs_series_phi13, x)
                                   : (x + em1) / (alpha * alpha);
    phi[6] = 1.0f;
    phi[7] = -em1 / alpha; /* (1 - e)/alpha */
    phi[12] = 1.0f + em1;  /* e */
    /* Gauss-Markov blocks from one expm1 each: exp(-b T) = 1 + m, 1 - exp(-2 b T) = -m (m + 2) */
    const float mb = mca_expm1f(-beta * t), mg = mca_expm1f(-gamma * t);
    phi[18] = 1.0f + mb;
    phi[24] = 1.0f + mg;
    singer_q_em1(alpha, t, s2, em1, q, 5u);
    const float sp2 = cfg->sigma_p_m * cfg->sigma_p_m, sv2 = cfg->sigma_v_mps * cfg->sigma_v_mps;
    q[18] = -sp2 * (mb * (mb + 2.0f)); /* sigma_p^2 (1 - exp(-2 beta T)) */
    q[24] = -sv2 * (mg * (mg + 2.0f)); /* sigma_v^2 (1 - exp(-2 gamma T)) */
}

void mca_cs_transition(const mca_cs_config_t *cfg, float t, float s2, float phi[25], float q[25])
{
    for (size_t i = 0; i < 25u; ++i) {
        phi[i] = 0.0f;
        q[i] = 0.0f;
    }
    transition_nz(cfg, t, s2, phi, q);
}

static int dt_ok(const mca_cs_config_t *cfg, float t)
{
    return isfinite(t) && t > 0.0f && t <= cfg->dt_max_s;
}

/* rows 0..2 of P (stride 5) <- A3 rows, A3 = [[1, t, f13], [0, 1, f23], [0, 0, e]] */
static void a3_rows(float *p, float t, float f13, float f23, float e)
{
    for (size_t j = 0; j < 5u; ++j) {
        const float x0 = p[j], x1 = p[5u + j], x2 = p[10u + j];
        p[j] = x0 + t * x1 + f13 * x2;
        p[5u + j] = x1 + f23 * x2;
        p[10u + j] = e * x2;
    }
}

/* columns 0..2 of rows 0..2 of P <- times A3^T (rows 3, 4 there are below the diagonal) */
static void a3_cols(float *p, float t, float f13, float f23, float e)
{
    for (size_t i = 0; i < 3u; ++i) {
        float *r = &p[5u * i];
        const float x0 = r[0], x1 = r[1], x2 = r[2];
        r[0] = x0 + t * x1 + f13 * x2;
        r[1] = x1 + f23 * x2;
        r[2] = e * x2;
    }
}

static mca_status_t inc_check(const mca_cs_inc_t *inc)
{
    if (inc == NULL) {
        return MCA_OK;
    }
    const float v[4] = {inc->dp_m, inc->dv_mps, inc->acc_var_m2ps4, inc->coast_var_m2ps4};
    if (!mca_all_finite(v, 4u)) {
        return MCA_ERR_NONFINITE;
    }
    return inc->acc_var_m2ps4 >= 0.0f && inc->coast_var_m2ps4 >= 0.0f ? MCA_OK : MCA_ERR_BAD_ARG;
}

/* The IMU-aided test prior from the posterior about to be predicted over t (ALGORITHMS.md 2),
 * with e_b = Phi44, e_g = Phi55 and sigma_p^2 (1 - e_b^2) = Q44, sigma_v^2 (1 - e_g^2) = Q55 of
 * the predict's own transition. Only p, v, eps_p, eps_v enter: the IMU increments replace the
 * acceleration state. */
static void axis_aid(mca_cs_axis_t *ax, float t, const float phi[25], const float q[25], const mca_cs_inc_t *inc)
{
    const float *x = ax->x, *p = ax->p;
    const float eb = phi[18], eg = phi[24];
    /* G = [[1, t, 0, eb, 0], [0, 1, 0, 0, eg]]; s = G P G^T over the four states it reads */
    float pgp[5], pgv[5]; /* P G^T, columns */
    for (size_t i = 0; i < 5u; ++i) {
        pgp[i] = p[5u * i] + t * p[5u * i + 1u] + eb * p[5u * i + 3u];
        pgv[i] = p[5u * i + 1u] + eg * p[5u * i + 4u];
    }
    const float spp = pgp[0] + t * pgp[1] + eb * pgp[3];
    const float spv = pgv[0] + t * pgv[1] + eb * pgv[3];
    const float svv = pgv[1] + eg * pgv[4];
    const float t2 = t * t, qa = inc->acc_var_m2ps4;
    ax->aid.y[0] = x[0] + t * x[1] + inc->dp_m + eb * x[3];
    ax->aid.y[1] = x[1] + inc->dv_mps + eg * x[4];
    ax->aid.s[0] = spp + q[18] + qa * 0.25f * t2 * t2;
    ax->aid.s[1] = spv + qa * 0.5f * t2 * t;
    ax->aid.s[2] = ax->aid.s[1];
    ax->aid.s[3] = svv + q[24] + qa * t2;
    ax->aid.valid = 1u;
}

/* Predict with a T already validated, Phi and Q1 of mca_cs_transition(&ax->cfg, t, 1), and
 * s2 = mca_cs_maneuver_var(&ax->cfg, ax->x[2]): the Singer block of Q is s2 times that of Q1
 * (the Gauss-Markov entries do not depend on s2), so axes of one configuration share Phi, Q1.
 * Phi is block diagonal, [[A3, 0], [0, diag(eb, eg)]], so Phi P Phi^T is done in place by rows
 * then columns on the upper triangle and mirrored (~50 multiplies instead of 250). */
static void axis_predict_with(mca_cs_axis_t *ax, float t, float s2, const float phi[25], const float q1[25],
                              const mca_cs_inc_t *inc)
{
    ax->aid.valid = 0u;
    if (inc != NULL) {
        axis_aid(ax, t, phi, q1, inc); /* from the posterior, before it is predicted */
    }
    /* coasting (ALGORITHMS.md 2): after an update that left the velocity row out, p and v follow
     * the IMU increments instead of the acceleration state, and P takes the IMU's persisting error
     * variance va */
    const int coast = inc != NULL && ax->cfg.coast != 0u && ax->aid.out != 0u;
    /* mean: eq. 17, Phi1 = constant acceleration + Gauss-Markov decay of eps */
    const float a = ax->x[2];
    const float dp = coast ? inc->dp_m : 0.5f * t * t * a, dv = coast ? inc->dv_mps : t * a;
    const float va = coast ? inc->coast_var_m2ps4 : 0.0f;
    ax->x[0] += t * ax->x[1] + dp;
    ax->x[1] += dv;
    ax->x[3] *= phi[18];
    ax->x[4] *= phi[24];
    /* covariance: Phi P Phi^T + Q on the upper triangle, D = diag(exp(-beta T), exp(-gamma T)):
     * [[A3 P33 A3^T, A3 P3e D], [., D Pee D]] */
    float *p = ax->p;
    const float eb = phi[18], eg = phi[24];
    const float f13 = coast ? 0.0f : phi[2], f23 = coast ? 0.0f : phi[7];
    a3_rows(p, t, f13, f23, phi[12]);
    a3_cols(p, t, f13, f23, phi[12]);
    for (size_t i = 0; i < 3u; ++i) {
        p[5u * i + 3u] *= eb;
        p[5u * i + 4u] *= eg;
    }
    p[18] = p[18] * eb * eb; /* the products in the order of the full scaling (the same bits) */
    p[19] = p[19] * eg * eb;
    p[24] = p[24] * eg * eg;
    const float qs = ax->rs.q_scale; /* AKF (ALGORITHMS.md 5); 1 in the other modes */
    const float qa = qs * s2;
    for (size_t i = 0; i < 3u; ++i) {
        for (size_t j = i; j < 3u; ++j) {
            p[5u * i + j] += qa * q1[5u * i + j];
        }
    }
    p[18] += qs * q1[18];
    p[24] += qs * q1[24];
    const float t2 = t * t; /* coasting; + 0 otherwise (P's diagonal and P_pv are never -0) */
    p[0] += va * 0.25f * t2 * t2;
    p[1] += va * 0.5f * t2 * t;
    p[6] += va * t2;
    /* the upper triangle mirrored: P exactly symmetric (the update reads rows of it) */
    for (size_t i = 1; i < 5u; ++i) {
        for (size_t j = 0; j < i; ++j) {
            p[5u * i + j] = p[5u * j + i];
        }
    }
    ax->s2_m2ps4 = s2;
}

static void axis_predict(mca_cs_axis_t *ax, float t, const mca_cs_inc_t *inc)
{
    float phi[25], q1[25];
    transition_nz(&ax->cfg, t, 1.0f, phi, q1);
    axis_predict_with(ax, t, mca_cs_maneuver_var(&ax->cfg, ax->x[2]) /* eq. 16: abar = a_hat */, phi, q1, inc);
}

/* Bit equality of two float arrays (a -0 and a +0 differ, as they may in what follows). */
static int same_bits(const float *a, const float *b, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        uint32_t ua, ub;
        memcpy(&ua, &a[i], sizeof ua);
        memcpy(&ub, &b[i], sizeof ub);
        if (ua != ub) {
            return 0;
        }
    }
    return 1;
}

/* The model fields, the first five of a configuration, are floats with no padding between. */
typedef char mca_cs_model_fields_ok[(offsetof(mca_cs_config_t, tau_a_s) == 0u &&
                                     offsetof(mca_cs_config_t, sigma_v_mps) == 4u * sizeof(float))
                                        ? 1
                                        : -1];

/* 1 when mca_cs_transition gives the same Phi and Q for a and b at any T and s2: the fields it
 * reads (tau_a, tau_p, tau_v, sigma_p, sigma_v) have the same bits. Equal values that differ in
 * bits (+0 and -0) only cost a transition computed again. */
static int same_model(const mca_cs_config_t *a, const mca_cs_config_t *b)
{
    return same_bits((const float *)(const void *)a, (const float *)(const void *)b, 5u);
}

mca_status_t mca_cs_axis_predict_aided(mca_cs_axis_t *ax, float t, const mca_cs_inc_t *inc)
{
    if (ax == NULL) {
        return MCA_ERR_NULL;
    }
    if (!dt_ok(&ax->cfg, t)) {
        return MCA_ERR_BAD_DT;
    }
    const mca_status_t st = inc_check(inc);
    if (st != MCA_OK) {
        return st;
    }
    axis_predict(ax, t, inc);
    return MCA_OK;
}

mca_status_t mca_cs_axis_predict(mca_cs_axis_t *ax, float t)
{
    return mca_cs_axis_predict_aided(ax, t, NULL);
}

/* Validate one axis' update inputs (docs/ALGORITHMS.md 2, Update). */
static mca_status_t check_update(float z_p, float z_v, float r_p, float r_v, uint8_t mask)
{
    if (mask == 0u || (mask & (uint8_t)~(MCA_CS_POS | MCA_CS_VEL)) != 0u) {
        return MCA_ERR_BAD_MASK;
    }
    if (((mask & MCA_CS_POS) != 0u && !isfinite(z_p)) || ((mask & MCA_CS_VEL) != 0u && !isfinite(z_v))) {
        return MCA_ERR_NONFINITE;
    }
    if (((mask & MCA_CS_POS) != 0u && !mca_positive(r_p)) || ((mask & MCA_CS_VEL) != 0u && !mca_positive(r_v))) {
        return MCA_ERR_BAD_ARG;
    }
    return MCA_OK;
}

/* The test innovation of an aided update (docs/ALGORITHMS.md 2): nu_t = z - y and C_t = s + R
 * over the rows in use (rows[i]: 0 position, 1 velocity; zq, rq indexed by that, R diagonal). */
static void aid_test(const mca_cs_aid_t *aid, const float zq[MCA_CS_NZ], const float rq[MCA_CS_NZ],
                     const size_t *rows, size_t m, float *nu_t, float *c_t)
{
    for (size_t i = 0; i < m; ++i) {
        nu_t[i] = zq[rows[i]] - aid->y[rows[i]];
        for (size_t j = 0; j < m; ++j) {
            c_t[i * m + j] = aid->s[rows[i] * MCA_CS_NZ + rows[j]];
        }
        c_t[i * m + i] += rq[rows[i]];
    }
}

/* mca_cs_axis_update on inputs its callers have checked (pointers, check_update); with gains
 * (plain mode, no report) the update also returns the rows' gains, as mca_kf_update_plain does
 * (gains may lie in ws past the update's own scratch, which is all the update is given). */
MCA_NOINLINE static mca_status_t axis_update(mca_cs_axis_t *ax, float z_p, float z_v, float r_p, float r_v,
                                             uint8_t mask, float *ws, mca_update_report_t *rep, float *gains)
{
    /* rows in mask order: 0 position (p + eps_p), 1 velocity (v + eps_v) */
    float h[MCA_CS_NZ * MCA_CS_NX];
    float z[MCA_CS_NZ], r[MCA_CS_NZ * MCA_CS_NZ];
    const float zq[MCA_CS_NZ] = {z_p, z_v}, rq[MCA_CS_NZ] = {r_p, r_v};
    size_t rows[MCA_CS_NZ], m = 0u;
    for (size_t i = 0; i < MCA_CS_NZ * MCA_CS_NX; ++i) { /* every entry written: no memset call */
        h[i] = 0.0f;
    }
    for (size_t i = 0; i < MCA_CS_NZ * MCA_CS_NZ; ++i) {
        r[i] = 0.0f;
    }
    for (size_t q = 0; q < MCA_CS_NZ; ++q) {
        if ((mask & (1u << q)) != 0u) {
            h[m * MCA_CS_NX + q] = 1.0f;
            h[m * MCA_CS_NX + 3u + q] = 1.0f;
            z[m] = zq[q];
            rows[m++] = q;
        }
    }
    for (size_t i = 0; i < m; ++i) {
        r[i * m + i] = rq[rows[i]];
    }
    /* after an aided predict the mode tests z against the IMU-aided prediction, covariance s + R */
    const int aided = ax->aid.valid != 0u;
    float nu_t[MCA_CS_NZ], c_t[MCA_CS_NZ * MCA_CS_NZ];
    /* the IMU-aided prediction less the CS one (p, v): this interval's IMU increments in place of
     * the CS acceleration's, the move of a coast that starts at this update */
    float shift[MCA_CS_NZ];
    for (size_t q = 0; q < MCA_CS_NZ; ++q) {
        shift[q] = ax->aid.y[q] - ax->x[3u + q] - ax->x[q];
    }
    if (aided) {
        aid_test(&ax->aid, zq, rq, rows, m, nu_t, c_t);
    }
    const mca_status_t su = mca_kf_update_tested_nocheck(ax->x, ax->p, MCA_CS_NX, h, z, r, m, &ax->cfg.robust,
                                                         &ax->rs, aided ? nu_t : NULL, aided ? c_t : NULL, ws, rep,
                                                         gains);
    if (su == MCA_OK) {
        ax->aid.valid = 0u;
        /* coasting (ALGORITHMS.md 2) while the velocity row is out or the update was rejected; a
         * coast that starts at an aided update starts from the IMU-aided prediction: p and v
         * moved by shift after the rows applied (none when rejected, the position otherwise) */
        const uint8_t out =
            (uint8_t)(ax->rs.n_reject > 0u || ((mask & MCA_CS_VEL) != 0u && ax->rs.n_removed[m - 1u] > 0u));
        if (out != 0u && aided && ax->aid.out == 0u && ax->cfg.coast != 0u) {
            ax->x[0] += shift[0];
            ax->x[1] += shift[1];
        }
        ax->aid.out = out;
    }
    return su;
}

mca_status_t mca_cs_axis_update(mca_cs_axis_t *ax, float z_p, float z_v, float r_p, float r_v,
                                uint8_t mask, float *ws, mca_update_report_t *rep)
{
    if (ax == NULL || ws == NULL) {
        return MCA_ERR_NULL;
    }
    mca_status_t st = check_update(z_p, z_v, r_p, r_v, mask);
    if (st == MCA_OK) {
        st = mca_robust_inputs_check(&ax->cfg.robust, &ax->rs);
    }
    if (st != MCA_OK) {
        return st;
    }
    return axis_update(ax, z_p, z_v, r_p, r_v, mask, ws, rep, NULL);
}

MCA_COLD mca_status_t mca_cs3_init(mca_cs3_t *cs, const mca_cs_config_t *cfg_h, const mca_cs_config_t *cfg_v,
                          const float pos_ned_m[3], const float vel_ned_mps[3])
{
    if (cs == NULL || cfg_h == NULL || cfg_v == NULL) {
        return MCA_ERR_NULL;
    }
    mca_status_t st = mca_cs_config_check(cfg_h);
    if (st == MCA_OK) {
        st = mca_cs_config_check(cfg_v);
    }
    if (st != MCA_OK) {
        return st;
    }
    if ((pos_ned_m != NULL && !mca_all_finite(pos_ned_m, 3u)) ||
        (vel_ned_mps != NULL && !mca_all_finite(vel_ned_mps, 3u))) {
        return MCA_ERR_NONFINITE;
    }
    mca_cs3_init_nocheck(cs, cfg_h, cfg_v, pos_ned_m, vel_ned_mps);
    return MCA_OK;
}

void mca_cs3_init_nocheck(mca_cs3_t *cs, const mca_cs_config_t *cfg_h, const mca_cs_config_t *cfg_v,
                          const float pos_ned_m[3], const float vel_ned_mps[3])
{
    for (size_t i = 0; i < 3u; ++i) {
        const float p0 = pos_ned_m != NULL ? pos_ned_m[i] : 0.0f;
        const float v0 = vel_ned_mps != NULL ? vel_ned_mps[i] : 0.0f;
        axis_init(&cs->axis[i], i < 2u ? cfg_h : cfg_v, p0, v0);
    }
}

mca_status_t mca_cs3_predict_aided(mca_cs3_t *cs, float t, const mca_cs_inc_t *const inc[3])
{
    if (cs == NULL) {
        return MCA_ERR_NULL;
    }
    for (size_t i = 0; i < 3u; ++i) {
        if (!dt_ok(&cs->axis[i].cfg, t)) {
            return MCA_ERR_BAD_DT;
        }
        const mca_status_t st = inc_check(inc != NULL ? inc[i] : NULL);
        if (st != MCA_OK) {
            return st;
        }
    }
    mca_cs3_predict_aided_nocheck(cs, t, inc);
    return MCA_OK;
}

void mca_cs3_predict_aided_nocheck(mca_cs3_t *cs, float t, const mca_cs_inc_t *const inc[3])
{
    /* N and E share the horizontal configuration: an axis whose model equals the previous
     * axis' reuses its Phi and Q1 (3 expm1 calls and the Singer block saved, the same bits as
     * its own; the maneuver variance scales Q1 in axis_predict_with). */
    float phi[25], q1[25];
    const mca_cs_config_t *cfg_prev = NULL;
    for (size_t i = 0; i < 3u; ++i) {
        mca_cs_axis_t *ax = &cs->axis[i];
        if (cfg_prev == NULL || !same_model(cfg_prev, &ax->cfg)) {
            transition_nz(&ax->cfg, t, 1.0f, phi, q1);
            cfg_prev = &ax->cfg;
        }
        axis_predict_with(ax, t, mca_cs_maneuver_var(&ax->cfg, ax->x[2]) /* eq. 16: abar = a_hat */, phi, q1,
                          inc != NULL ? inc[i] : NULL);
    }
}

mca_status_t mca_cs3_predict(mca_cs3_t *cs, float t)
{
    return mca_cs3_predict_aided(cs, t, NULL);
}

/* Bit equality of two axes' covariances, read on the upper triangle: every writer of an axis'
 * P (init, predict, the updates) leaves it exactly symmetric. */
static int same_cov(const float *a, const float *b)
{
    for (size_t i = 0; i < MCA_CS_NX; ++i) {
        if (!same_bits(&a[i * MCA_CS_NX + i], &b[i * MCA_CS_NX + i], MCA_CS_NX - i)) {
            return 0;
        }
    }
    return 1;
}

/* The E axis of mca_cs3_update when its P had the same bits as N's before N's update, with the
 * same mask and R, both plain: N's update left the covariance (p_post) and the gains (gains,
 * mca_kf_update_plain) that E's own update would compute, so E applies the gains to its
 * state row by row (nu from the state the previous row left, as the row update does) and takes
 * p_post: x, P and T are the bits mca_cs_axis_update gives. 1 when done; 0 (nothing changed)
 * when the result or T is not finite or the test statistic refuses C_t: the caller then runs
 * the ordinary update, which reports it. */
MCA_NOINLINE static int axis_update_shared(mca_cs_axis_t *ax, const float p_post[MCA_CS_NX * MCA_CS_NX],
                                           const float *gains, float z_p, float z_v, float r_p, float r_v,
                                           uint8_t mask, float *ws)
{
    const float zq[MCA_CS_NZ] = {z_p, z_v}, rq[MCA_CS_NZ] = {r_p, r_v};
    float x[MCA_CS_NX], nu_t[MCA_CS_NZ], c_t[MCA_CS_NZ * MCA_CS_NZ];
    float t_stat = 0.0f, fin = 0.0f;
    size_t m = 0u, rows[MCA_CS_NZ];
    mca_copyf(x, ax->x, MCA_CS_NX);
    for (size_t q = 0; q < MCA_CS_NZ; ++q) {
        if ((mask & (1u << q)) == 0u) {
            continue;
        }
        const float *g = &gains[m * (MCA_CS_NX + 1u)];
        const float nu = zq[q] - ((0.0f + x[q]) + x[3u + q]); /* h x, summed as the row update */
        t_stat += nu * (nu * g[MCA_CS_NX]);
        for (size_t i = 0; i < MCA_CS_NX; ++i) {
            x[i] = x[i] + g[i] * nu;
            fin += x[i] * 0.0f;
        }
        rows[m++] = q;
    }
    if (ax->aid.valid != 0u) { /* the tested T, formed as mca_cs_axis_update forms it */
        aid_test(&ax->aid, zq, rq, rows, m, nu_t, c_t);
        if (mca_kf_test_stat(nu_t, c_t, m, ws, &t_stat) != MCA_OK) {
            return 0;
        }
    }
    if (!isfinite(fin) || !isfinite(t_stat)) {
        return 0;
    }
    mca_copyf(ax->x, x, MCA_CS_NX);
    mca_copyf(ax->p, p_post, MCA_CS_NX * MCA_CS_NX);
    mca_kf_plain_memory(&ax->rs, m, t_stat); /* the memory as a plain update leaves it */
    ax->aid.valid = 0u;
    ax->aid.out = 0u;
    return 1;
}

/* Fuzzy rows on N and E, both tested against their IMU-aided predictions on position and
 * velocity (docs/ALGORITHMS.md 5, the N/E pair): the rows an alarmed axis' update will leave out
 * for failing their own test, with the rows it keeps out that went out with them, go out of the
 * other axis' update too (rs.started). A GNSS fault moves the horizontal solution as one; how it
 * splits between N and E is the fault's azimuth. Nothing is written unless both axes qualify. */
MCA_NOINLINE static void pair_rows(mca_cs3_t *cs, const float pos[3], const float vel[3], const float r_pos[3],
                                   const float r_vel[3], const uint8_t mask[3], float *ws)
{
    static const size_t rows[MCA_CS_NZ] = {0u, 1u};
    unsigned failed[2];
    for (size_t i = 0; i < 2u; ++i) {
        const mca_cs_axis_t *ax = &cs->axis[i];
        if (ax->cfg.robust.mode != (uint8_t)MCA_ROBUST_FUZZY || ax->cfg.robust.fuzzy_reject != 2u ||
            ax->aid.valid == 0u || mask[i] != (MCA_CS_POS | MCA_CS_VEL)) {
            return;
        }
        const float zq[MCA_CS_NZ] = {pos[i], vel[i]}, rq[MCA_CS_NZ] = {r_pos[i], r_vel[i]};
        float nu_t[MCA_CS_NZ], c_t[MCA_CS_NZ * MCA_CS_NZ];
        aid_test(&ax->aid, zq, rq, rows, MCA_CS_NZ, nu_t, c_t);
        failed[i] = mca_kf_fuzzy_failed(&ax->cfg.robust, &ax->rs, nu_t, c_t, MCA_CS_NZ, ws);
    }
    cs->axis[0].rs.started |= (uint8_t)failed[1];
    cs->axis[1].rs.started |= (uint8_t)failed[0];
}

mca_status_t mca_cs3_update(mca_cs3_t *cs, const float pos[3], const float vel[3], const float r_pos[3],
                            const float r_vel[3], const uint8_t mask[3], float *ws, mca_update_report_t rep[3])
{
    if (cs == NULL || pos == NULL || vel == NULL || r_pos == NULL || r_vel == NULL || mask == NULL || ws == NULL) {
        return MCA_ERR_NULL;
    }
    if ((mask[0] | mask[1] | mask[2]) == 0u) {
        return MCA_ERR_BAD_MASK;
    }
    for (size_t i = 0; i < 3u; ++i) {
        if (mask[i] != 0u) {
            mca_status_t st = check_update(pos[i], vel[i], r_pos[i], r_vel[i], mask[i]);
            if (st == MCA_OK) {
                st = mca_robust_inputs_check(&cs->axis[i].cfg.robust, &cs->axis[i].rs);
            }
            if (st != MCA_OK) {
                return st;
            }
        }
    }
    if (rep == NULL) {
        return mca_cs3_update_nocheck(cs, pos, vel, r_pos, r_vel, mask, ws);
    }
    /* Axes are independent; C = H P H^T + R is positive definite whenever P is PSD and
     * R > 0 (checked above), so an update can fail now only by float overflow, which
     * leaves that axis unchanged (mca_kf_update is atomic). With reports every axis updates on
     * its own; without them, mca_cs3_update_nocheck (whose callers never ask for one, so that a
     * link-time optimised image holds no report code on the navigation filter's path). */
    mca_status_t result = MCA_OK;
    pair_rows(cs, pos, vel, r_pos, r_vel, mask, ws);
    for (size_t i = 0; i < 3u; ++i) {
        mca_status_t st = MCA_OK;
        if (mask[i] == 0u) {
            mca_zero_bytes(&rep[i], sizeof(rep[i]));
        } else {
            st = axis_update(&cs->axis[i], pos[i], vel[i], r_pos[i], r_vel[i], mask[i], ws, &rep[i], NULL);
        }
        result = result == MCA_OK ? st : result;
    }
    return result;
}

mca_status_t mca_cs3_update_nocheck(mca_cs3_t *cs, const float pos[3], const float vel[3], const float r_pos[3],
                                    const float r_vel[3], const uint8_t mask[3], float *ws)
{
    mca_status_t result = MCA_OK;
    pair_rows(cs, pos, vel, r_pos, r_vel, mask, ws);
    /* No reports: N and E share one covariance update when they can (axis_update_shared); in
     * fixed mode their P stay the same bits while both take every fix plainly. */
    const mca_cs_axis_t *an = &cs->axis[0], *ae = &cs->axis[1];
    const int share = mask[0] != 0u && mask[0] == mask[1] && an->cfg.robust.mode == (uint8_t)MCA_ROBUST_PLAIN &&
                      ae->cfg.robust.mode == (uint8_t)MCA_ROBUST_PLAIN && same_bits(&r_pos[0], &r_pos[1], 1u) &&
                      same_bits(&r_vel[0], &r_vel[1], 1u) && same_cov(an->p, ae->p);
    float *const gains = ws + MCA_KF_WS_LEN(MCA_CS_NX, MCA_CS_NZ); /* N's rows, for E: past the update's scratch */
    for (size_t i = 0; i < 3u; ++i) {
        if (mask[i] == 0u || (i == 1u && share && result == MCA_OK &&
                              axis_update_shared(&cs->axis[1], cs->axis[0].p, gains, pos[1], vel[1], r_pos[1],
                                                 r_vel[1], mask[1], ws))) {
            continue;
        }
        const mca_status_t st = axis_update(&cs->axis[i], pos[i], vel[i], r_pos[i], r_vel[i], mask[i], ws, NULL,
                                            (i == 0u && share) ? gains : NULL);
        result = result == MCA_OK ? st : result;
    }
    return result;
}

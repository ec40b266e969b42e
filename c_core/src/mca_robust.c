/* The one Kalman measurement update (docs/ALGORITHMS.md section 1). See mca_robust.h. */
#include "mcahrs/mca_robust.h"

#include <string.h>

void mca_robust_config_default(mca_robust_config_t *cfg)
{
    memset(cfg, 0, sizeof(*cfg));
    cfg->mode = (uint8_t)MCA_ROBUST_PLAIN;
    cfg->fuzzy_reject = 1u;
    cfg->akf_window = MCA_AKF_WINDOW;
    cfg->akf_forget = 0.2f;
    cfg->akf_q_min = 0.5f;
    cfg->akf_q_max = 10.0f;
    cfg->igg_k0 = 1.5f;
    cfg->igg_k1 = 3.0f;
}

mca_status_t mca_robust_config_check(const mca_robust_config_t *c)
{
    if (c == NULL) {
        return MCA_ERR_NULL;
    }
    if (c->mode > (uint8_t)MCA_ROBUST_IGG3 || c->fuzzy_reject > 1u || c->akf_window < 1u ||
        c->akf_window > MCA_AKF_WINDOW || !(c->akf_forget > 0.0f && c->akf_forget <= 1.0f) ||
        !(c->akf_q_min > 0.0f) || !(c->akf_q_max >= c->akf_q_min) || !(c->igg_k0 > 0.0f) ||
        !(c->igg_k1 > c->igg_k0) || !mca_finite(c->akf_q_max) || !mca_finite(c->igg_k1)) {
        return MCA_ERR_BAD_CONFIG;
    }
    return MCA_OK;
}

void mca_robust_state_init(mca_robust_state_t *st)
{
    memset(st, 0, sizeof(*st));
    st->q_scale = 1.0f;
}

mca_status_t mca_kf_update(float *x, float *p, size_t n, const float *h, const float *z,
                           const float *r, size_t m, const mca_robust_config_t *rc,
                           mca_robust_state_t *rs, float *ws, size_t ws_len,
                           mca_update_report_t *rep)
{
    (void)rc; /* modes other than plain: robust-layer work, ALGORITHMS.md 5 */
    (void)rs;
    if (x == NULL || p == NULL || h == NULL || z == NULL || r == NULL || ws == NULL) {
        return MCA_ERR_NULL;
    }
    if (m == 0u || m > MCA_MEAS_MAX || n == 0u || ws_len < (size_t)MCA_KF_WS_LEN(n, m)) {
        return MCA_ERR_BAD_ARG;
    }
    if (!mca_all_finite(z, m) || !mca_all_finite(r, m * m)) {
        return MCA_ERR_NONFINITE;
    }
    /* Scratch layout: a, b, pn (n x n); pht, k (n x m); c, l (m x m); xn (n); y (m). */
    float *a = ws;
    float *b = a + n * n;
    float *pn = b + n * n;
    float *pht = pn + n * n;
    float *k = pht + n * m;
    float *c = k + n * m;
    float *l = c + m * m;
    float *xn = l + m * m;
    float *y = xn + n;

    /* nu = z - H x -> y; C = H P H^T + R */
    mca_mat_mul(xn, h, x, m, n, 1u);
    for (size_t i = 0; i < m; ++i) {
        y[i] = z[i] - xn[i];
    }
    mca_mat_mul_bt(pht, p, h, n, n, m);  /* P H^T (P symmetric) */
    mca_mat_mul(c, h, pht, m, n, m);     /* H P H^T */
    for (size_t i = 0; i < m * m; ++i) {
        c[i] += r[i];
    }
    mca_mat_symmetrize(c, m);
    if (rep != NULL) {
        memset(rep, 0, sizeof(*rep));
        rep->m = (uint8_t)m;
        rep->mode = (uint8_t)MCA_ROBUST_PLAIN;
        rep->factor = 1.0f;
        rep->q_scale = 1.0f;
        for (size_t i = 0; i < m; ++i) {
            rep->w[i] = 1.0f;
        }
        memcpy(rep->nu, y, m * sizeof(float));
        memcpy(rep->c, c, m * m * sizeof(float));
    }
    if (mca_cholesky(l, c, m) != MCA_OK) {
        return MCA_ERR_SINGULAR;
    }
    /* T = nu^T C^-1 nu; solve into xn (free again) */
    float *sol = xn;
    memcpy(sol, y, m * sizeof(float));
    mca_cholesky_solve(l, sol, m);
    float t_stat = 0.0f;
    for (size_t i = 0; i < m; ++i) {
        t_stat += y[i] * sol[i];
    }
    if (rep != NULL) {
        rep->t_stat = t_stat;
    }
    /* K = P H^T C^-1, row by row: C k_i = (P H^T)_i */
    for (size_t i = 0; i < n; ++i) {
        memcpy(&k[i * m], &pht[i * m], m * sizeof(float));
        mca_cholesky_solve(l, &k[i * m], m);
    }
    /* x+ = x + K nu */
    mca_mat_mul(xn, k, y, n, m, 1u);
    for (size_t i = 0; i < n; ++i) {
        xn[i] += x[i];
    }
    /* Joseph: A = I - K H; P+ = A P A^T + K R K^T */
    mca_mat_mul(a, k, h, n, m, n);
    for (size_t i = 0; i < n * n; ++i) {
        a[i] = -a[i];
    }
    for (size_t i = 0; i < n; ++i) {
        a[i * n + i] += 1.0f;
    }
    mca_mat_mul(b, a, p, n, n, n);
    mca_mat_mul_bt(pn, b, a, n, n, n);
    mca_mat_mul(pht, k, r, n, m, m); /* K R into pht (free) */
    mca_mat_mul_bt(b, pht, k, n, m, n);
    for (size_t i = 0; i < n * n; ++i) {
        pn[i] += b[i];
    }
    mca_mat_symmetrize(pn, n);
    if (!mca_all_finite(xn, n) || !mca_all_finite(pn, n * n)) {
        return MCA_ERR_NONFINITE;
    }
    memcpy(x, xn, n * sizeof(float));
    memcpy(p, pn, n * n * sizeof(float));
    return MCA_OK;
}

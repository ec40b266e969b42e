/* Attitude EKF (DESIGN.md 4, docs/ALGORITHMS.md 7). See mca_att.h. */
#include "mcahrs/mca_att.h"
#include "mca_att_nocheck.h"
#include "mca_cold.h"
#include "mca_defaults.h"
#include "mca_kf_rows.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

#define DEG 0.0174532925199433f

MCA_COLD void mca_att_config_default(mca_att_config_t *cfg)
{
    static const mca_att_config_t d = MCA_ATT_CONFIG_INIT((180.0f * DEG) * (180.0f * DEG));
    mca_copy_bytes(cfg, &d, sizeof d);
}

MCA_COLD mca_status_t mca_att_config_check(const mca_att_config_t *c)
{
    if (c == NULL) {
        return MCA_ERR_NULL;
    }
    /* noise densities and rp_k_dev >= 0, the rest > 0 */
    static const uint16_t off[] = {
        offsetof(mca_att_config_t, gyro_noise_rps), offsetof(mca_att_config_t, gyro_bias_rw_rps2),
        offsetof(mca_att_config_t, att0_var_rad2),  offsetof(mca_att_config_t, yaw0_var_rad2),
        offsetof(mca_att_config_t, bias0_var_rps2), offsetof(mca_att_config_t, rp_sigma0_rad),
        offsetof(mca_att_config_t, rp_k_dev),       offsetof(mca_att_config_t, max_tilt_obs_rad)};
    if (!mca_fields_ok(c, off, sizeof off / sizeof off[0], 0x43u) || c->max_tilt_obs_rad >= 1.5707963f ||
        mca_robust_config_check(&c->robust) != MCA_OK) {
        return MCA_ERR_BAD_CONFIG;
    }
    return MCA_OK;
}

MCA_COLD mca_status_t mca_att_init(mca_att_t *att, const mca_att_config_t *cfg, const float q_nb[4], const float bias[3])
{
    if (att == NULL || cfg == NULL || q_nb == NULL || bias == NULL) {
        return MCA_ERR_NULL;
    }
    const mca_status_t st = mca_att_config_check(cfg);
    if (st != MCA_OK) {
        return st;
    }
    if (!mca_all_finite(q_nb, 4u) || !mca_all_finite(bias, 3u)) {
        return MCA_ERR_NONFINITE;
    }
    mca_att_init_nocheck(att, cfg, q_nb, bias);
    return MCA_OK;
}

MCA_COLD void mca_att_init_nocheck(mca_att_t *att, const mca_att_config_t *cfg, const float q_nb[4], const float bias[3])
{
    mca_zero_bytes(att, sizeof(*att));
    mca_copy_bytes(&att->cfg, cfg, sizeof(att->cfg));
    att->sin_max_tilt = mca_sinf(cfg->max_tilt_obs_rad);
    memcpy(att->q_nb, q_nb, sizeof(att->q_nb));
    mca_quat_normalize(att->q_nb);
    memcpy(att->bias_rps, bias, sizeof(att->bias_rps));
    att->p[0] = cfg->att0_var_rad2;
    att->p[7] = cfg->att0_var_rad2;
    att->p[14] = cfg->yaw0_var_rad2;
    att->p[21] = cfg->bias0_var_rps2;
    att->p[28] = cfg->bias0_var_rps2;
    att->p[35] = cfg->bias0_var_rps2;
    att->rs.q_scale = 1.0f; /* the memory of mca_robust_state_init: the rest is zeroed above */
}

/* q_nb <- normalize(q_nb (x) q(rv)): the gyro step and the error-state correction. One copy for
 * both (the correction is inlined into its one caller otherwise). */
MCA_NOINLINE static void rotate_by(mca_att_t *att, const float rv[3])
{
    float dq[4], qn[4];
    mca_quat_from_rotvec(dq, rv);
    mca_quat_mul(qn, att->q_nb, dq);
    mca_quat_normalize(qn);
    memcpy(att->q_nb, qn, sizeof(qn));
}

/* out = A M, A = I + [[0, r2, -r1], [-r2, 0, r0], [r1, -r0, 0]] = I - [r x] (r = w dt, the error
 * state's first-order rotation), M 3 x 3 read with row stride rs and column stride cs (6, 1: a
 * block of the 6 x 6 P; 1, 3: the transpose of a row-major 3 x 3); out row-major. Two
 * multiply-adds an entry instead of three, no loop over A. */
static void a_times(float out[9], const float r[3], const float *m, size_t rs, size_t cs)
{
    for (size_t j = 0; j < 3u; ++j) {
        const float m0 = m[j * cs], m1 = m[rs + j * cs], m2 = m[2u * rs + j * cs];
        out[j] = m0 + r[2] * m1 - r[1] * m2;
        out[3u + j] = m1 - r[2] * m0 + r[0] * m2;
        out[6u + j] = m2 + r[1] * m0 - r[0] * m1;
    }
}

mca_status_t mca_att_propagate(mca_att_t *att, const float gyro[3], float dt)
{
    if (att == NULL || gyro == NULL) {
        return MCA_ERR_NULL;
    }
    if (!mca_all_finite(gyro, 3u)) {
        return MCA_ERR_NONFINITE;
    }
    if (!isfinite(dt) || !(dt > 0.0f)) {
        return MCA_ERR_BAD_DT;
    }
    mca_att_propagate_nocheck(att, gyro, dt);
    return MCA_OK;
}

/* Not inlined into mca_nav_imu: 8 B of flash less. */
MCA_NOINLINE void mca_att_propagate_nocheck(mca_att_t *att, const float gyro[3], float dt)
{
    const float w[3] = {gyro[0] - att->bias_rps[0], gyro[1] - att->bias_rps[1], gyro[2] - att->bias_rps[2]};
    const float rv[3] = {w[0] * dt, w[1] * dt, w[2] * dt};
    rotate_by(att, rv);
    /* F = [[A, -I dt], [0, I]], A = I - [w x] dt. P = F P F^T + Qd, written out by blocks
     * [[P11, P12], [P21, P22]] so no 6x6 temporaries are needed:
     *   P11' = A P11 A^T - dt (A P12 + P21 A^T) + dt^2 P22
     *   P12' = A P12 - dt P22,  P22' = P22 (+ Qd)
     * The products by A use its structure (a_times); P11' is formed on its upper triangle and
     * mirrored, P12' written to both blocks, so P' is exactly symmetric without a pass. */
    float *p = att->p;
    float ap12[9], t1[9], t2[9];
    a_times(ap12, rv, &p[3], 6u, 1u); /* A P12 */
    a_times(t1, rv, p, 6u, 1u);       /* A P11 */
    a_times(t2, rv, t1, 1u, 3u);      /* A (A P11)^T = A P11 A^T (P11 symmetric) */
    const float dt2 = dt * dt;
    for (size_t i = 0; i < 3u; ++i) {
        for (size_t j = 0; j < 3u; ++j) {
            const float p22 = p[(i + 3u) * 6u + j + 3u];
            if (j >= i) {
                /* (A P12)_ij + (P21 A^T)_ij, P21 A^T = (A P12)^T */
                const float cross = ap12[i * 3u + j] + ap12[j * 3u + i];
                const float n11 = t2[i * 3u + j] - dt * cross + dt2 * p22;
                p[i * 6u + j] = n11;
                p[j * 6u + i] = n11;
            }
            const float n12 = ap12[i * 3u + j] - dt * p22;
            p[i * 6u + j + 3u] = n12;
            p[(j + 3u) * 6u + i] = n12;
        }
    }
    /* AKF of the roll/pitch observation scales the process noise (1 in other modes) */
    const float qg = att->rs.q_scale * att->cfg.gyro_noise_rps * att->cfg.gyro_noise_rps * dt;
    const float qb = att->cfg.gyro_bias_rw_rps2 * att->cfg.gyro_bias_rw_rps2 * dt;
    for (size_t i = 0; i < 3u; ++i) {
        att->p[i * 7u] += qg;
        att->p[(i + 3u) * 7u] += qb;
    }
}

/* Apply the error-state correction dx (ALGORITHMS.md 7). */
static void correct(mca_att_t *att, const float dx[6])
{
    rotate_by(att, dx);
    for (size_t i = 0; i < 3u; ++i) {
        att->bias_rps[i] += dx[3u + i];
    }
}

/* d = C_nb(q)^T e_down, the down direction in body axes: the last row of C_nb, straight from q,
 * [-sin theta, sin phi cos theta, cos phi cos theta]. The roll/pitch residuals, the yaw row and
 * the level-only correction all read it. */
static void down_in_body(float d[3], const float q[4])
{
    d[0] = 2.0f * (q[1] * q[3] - q[0] * q[2]);
    d[1] = 2.0f * (q[2] * q[3] + q[0] * q[1]);
    d[2] = 1.0f - 2.0f * (q[1] * q[1] + q[2] * q[2]);
}

/* Plain mode without a report: the section-1 update from dx = 0 in its sequential form
 * (ALGORITHMS.md 1), R = r I. The rows h_k = [e'_k, 0 0 0] touch only the attitude columns, so
 * u = P h_k^T reads P's first three columns (rows, P symmetric) and s three of its values; the
 * row's x and P step is the CS filter's (mca_kf_row_apply); dx starts zero. The first row
 * reads P and writes ws, the second works there; P is written only when every s is positive
 * and every value of dx and P+ is finite. The memory (rs, NULL for none) ends as
 * mca_kf_update's plain path leaves it. */
MCA_NOINLINE static mca_status_t att_update_plain(mca_att_t *att, const float *h, size_t m, const float *nu,
                                                  float r, float dx[MCA_ATT_NX], float *ws,
                                                  mca_robust_state_t *rs)
{
    enum { N = MCA_ATT_NX };
    float *u = ws, *pn = ws + N;
    const float *ps = att->p;
    float t_stat = 0.0f, fin = 0.0f;
    for (size_t k = 0; k < m; ++k) {
        const float *e = &h[k * N];
        for (size_t i = 0; i < N; ++i) {
            const float *pi = &ps[i * N];
            u[i] = pi[0] * e[0] + pi[1] * e[1] + pi[2] * e[2];
        }
        const float s = r + e[0] * u[0] + e[1] * u[1] + e[2] * u[2];
        if (!(s > 0.0f) || !(s <= 3.4028235e38f)) {
            return s <= 0.0f ? MCA_ERR_SINGULAR : MCA_ERR_NONFINITE;
        }
        const float inv = 1.0f / s;
        const float v = nu[k] - (e[0] * dx[0] + e[1] * dx[1] + e[2] * dx[2]);
        t_stat += v * (v * inv);
        fin += mca_kf_row_apply(dx, ps, dx, pn, u, N, inv, v);
        ps = pn;
    }
    if (!isfinite(fin) || !isfinite(t_stat)) {
        return MCA_ERR_NONFINITE;
    }
    mca_copyf(att->p, pn, N * N);
    mca_kf_plain_memory(rs, m, t_stat);
    return MCA_OK;
}

/* Update of the error state from zero with rows e (m x 3, at q_d), residual nu, diag R.
 * level_only: remove the vertical component of the attitude correction (ALGORITHMS.md 7,
 * roll/pitch step 7). */
static mca_status_t euler_update(mca_att_t *att, const float *e_rows, size_t m, const float *nu, float r,
                                 const float q_d[4], int robust, int level_only, float *ws,
                                 mca_update_report_t *rep)
{
    /* Rows at the current attitude: h_k = e_k C_D with C_D = C_nb(q_d)^T C_nb(q) = C(q_d^-1 (x) q)
     * (current body to body at t_d), i.e. h_k^T = C_D^T e_k^T, the rotation of e_k by
     * (q_d^-1 (x) q)^-1 = q^-1 (x) q_d: no 3 x 3 matrix. */
    float h[2u * MCA_ATT_NX], dx[MCA_ATT_NX], rm[4];
    const float *q = att->q_nb;
    float q_back[4];
    /* q^-1 in dx, free until it is zeroed below (16 B less on the deepest stack path) */
    dx[0] = q[0];
    dx[1] = -q[1];
    dx[2] = -q[2];
    dx[3] = -q[3];
    mca_quat_mul(q_back, dx, q_d);
    /* every entry written (no memset calls): the rows see no gyro bias, R is r I */
    for (size_t k = 0; k < m; ++k) {
        mca_quat_rotate(&h[k * MCA_ATT_NX], q_back, &e_rows[k * 3u]);
        for (size_t j = 3u; j < MCA_ATT_NX; ++j) {
            h[k * MCA_ATT_NX + j] = 0.0f;
        }
        for (size_t j = 0; j < m; ++j) {
            rm[k * m + j] = j == k ? r : 0.0f;
        }
    }
    for (size_t i = 0; i < MCA_ATT_NX; ++i) {
        dx[i] = 0.0f;
    }
    mca_status_t st;
    if (rep == NULL && (!robust || att->cfg.robust.mode == (uint8_t)MCA_ROBUST_PLAIN)) {
        st = att_update_plain(att, h, m, nu, r, dx, ws, robust ? &att->rs : NULL);
    } else {
        /* the tested update past its checks: the robust inputs are checked where they enter (init,
         * mca_att_update_gravity), the rest is this filter's own */
        st = mca_kf_update_tested_nocheck(dx, att->p, MCA_ATT_NX, h, nu, rm, m, robust ? &att->cfg.robust : NULL,
                                          robust ? &att->rs : NULL, NULL, NULL, ws, rep, NULL);
    }
    if (st == MCA_OK) {
        if (level_only) {
            float u[3];
            down_in_body(u, q);
            const float dot = u[0] * dx[0] + u[1] * dx[1] + u[2] * dx[2];
            for (size_t i = 0; i < 3u; ++i) {
                dx[i] -= dot * u[i];
            }
        }
        correct(att, dx);
    }
    return st;
}

/* The roll/pitch measurement of mca_att_update_gravity (ALGORITHMS.md 7, gravity steps 1-5):
 * residual nu, the rows e (at q_d) and R, or the gate's MCA_ERR_BAD_ARG. Its own frame: the
 * gravity vector and the Euler angles are not on the stack during the update. */
MCA_NOINLINE static mca_status_t gravity_measure(const mca_att_t *att, const float f[3], const float acc_n[3],
                                                 const float q_d[4], float g, float r_acc, float nu[2],
                                                 float e_rows[6], float *r)
{
    /* a_b = C_nb^T a_n (rotation by the conjugate, no 3 x 3 matrix); g_b = -(f - a_b) */
    const float qd_inv[4] = {q_d[0], -q_d[1], -q_d[2], -q_d[3]};
    float gb[3];
    mca_quat_rotate(gb, qd_inv, acc_n);
    for (size_t i = 0; i < 3u; ++i) {
        gb[i] -= f[i];
    }
    const float gn = sqrtf(gb[0] * gb[0] + gb[1] * gb[1] + gb[2] * gb[2]);
    if (!(gn >= 0.5f * g && gn <= 1.5f * g)) { /* also refuses a NaN */
        return MCA_ERR_BAD_ARG;
    }
    /* Roll and pitch of q_d as the down axis in body axes, d = C_nb^T e_down = [-sin theta,
     * sin phi cos theta, cos phi cos theta]: s = sin theta, (dy, dz) = cos theta (sin phi,
     * cos phi). */
    float d[3];
    down_in_body(d, q_d);
    const float dy = d[1], dz = d[2];
    float s = -d[0];
    s = s > 1.0f ? 1.0f : (s < -1.0f ? -1.0f : s);
    if (fabsf(s) > att->sin_max_tilt) { /* |pitch of q_d| > max_tilt_obs: sin is monotonic there */
        return MCA_ERR_BAD_ARG;
    }
    const float ct = sqrtf(1.0f - s * s);
    /* The residuals as the angles from the predicted to the measured direction, one atan2 each
     * (phi_m - phi wrapped, theta_m - theta; both pitches lie in (-90, 90) deg):
     * phi_m = atan2(gy, gz), theta_m = atan2(-gx, hypot(gy, gz)). */
    const float hg = sqrtf(gb[1] * gb[1] + gb[2] * gb[2]);
    nu[0] = mca_atan2f(gb[1] * dz - gb[2] * dy, gb[1] * dy + gb[2] * dz);
    nu[1] = mca_atan2f(-gb[0] * ct - hg * s, hg * ct - gb[0] * s);
    const float ict = 1.0f / ct; /* cos theta > 0: |theta| <= max_tilt_obs < 90 deg */
    const float sp = dy * ict, cp = dz * ict, tt = s * ict;
    e_rows[0] = 1.0f;
    e_rows[1] = sp * tt;
    e_rows[2] = cp * tt;
    e_rows[3] = 0.0f;
    e_rows[4] = cp;
    e_rows[5] = -sp;
    const float dev = att->cfg.rp_k_dev * fabsf(gn - g) / g;
    *r = att->cfg.rp_sigma0_rad * att->cfg.rp_sigma0_rad + dev * dev + r_acc;
    return MCA_OK;
}

/* mca_att_update_gravity after its argument checks */
static mca_status_t gravity_update(mca_att_t *att, const float f[3], const float acc_n[3], const float q_d[4], float g,
                                   float r_acc, float *ws, mca_update_report_t *rep)
{
    float nu[2], e_rows[6], r;
    const mca_status_t sm = gravity_measure(att, f, acc_n, q_d, g, r_acc, nu, e_rows, &r);
    if (sm != MCA_OK) {
        return sm;
    }
    return euler_update(att, e_rows, 2u, nu, r, q_d, 1, 1, ws, rep);
}

mca_status_t mca_att_update_gravity(mca_att_t *att, const float f[3], const float acc_n[3], const float q_d[4],
                                    float g, float r_acc, float *ws, mca_update_report_t *rep)
{
    if (att == NULL || f == NULL || acc_n == NULL || q_d == NULL || ws == NULL) {
        return MCA_ERR_NULL;
    }
    if (!mca_all_finite(f, 3u) || !mca_all_finite(acc_n, 3u) || !mca_all_finite(q_d, 4u) || !isfinite(g) ||
        !isfinite(r_acc)) {
        return MCA_ERR_NONFINITE;
    }
    if (!(g > 0.0f) || r_acc < 0.0f) {
        return MCA_ERR_BAD_ARG;
    }
    const mca_status_t st = mca_robust_inputs_check(&att->cfg.robust, &att->rs);
    if (st != MCA_OK) {
        return st;
    }
    return gravity_update(att, f, acc_n, q_d, g, r_acc, ws, rep);
}

mca_status_t mca_att_gravity_nocheck(mca_att_t *att, const float f[3], const float acc_n[3], const float q_d[4],
                                     float g, float r_acc, float *ws)
{
    return gravity_update(att, f, acc_n, q_d, g, r_acc, ws, NULL);
}

mca_status_t mca_att_gravity_measure_nocheck(const mca_att_t *att, const float f[3], const float acc_n[3], float g,
                                             float r_acc, float nu[2], float e_rows[6], float *r)
{
    return gravity_measure(att, f, acc_n, att->q_nb, g, r_acc, nu, e_rows, r);
}

mca_status_t mca_att_gravity_apply_nocheck(mca_att_t *att, const float nu[2], const float e_rows[6], float r, float *ws)
{
    return euler_update(att, e_rows, 2u, nu, r, att->q_nb, 1, 1, ws, NULL);
}

/* mca_att_update_yaw after its argument checks */
static mca_status_t yaw_update(mca_att_t *att, float psi_m, float r, const float q_d[4], float *ws,
                               mca_update_report_t *rep, float gate)
{
    /* d psi / d(body error angles) = [0, sin(phi), cos(phi)] / cos(theta) = [0, c32, c33] /
     * cos^2(theta) with c32 = sin(phi) cos(theta), c33 = cos(phi) cos(theta) from the last row of
     * C_nb(q_d), cos^2(theta) = c32^2 + c33^2: the same row without trigonometry (ALGORITHMS.md 7) */
    float d[3];
    down_in_body(d, q_d); /* d[0] = -sin(theta), d[1] = c32, d[2] = c33 */
    if (fabsf(d[0]) > att->sin_max_tilt) { /* |pitch of q_d| > max_tilt_obs */
        return MCA_ERR_BAD_ARG;
    }
    float eul[3];
    mca_quat_to_euler_part(eul, q_d, 4u); /* yaw */
    const float k = 1.0f / (d[1] * d[1] + d[2] * d[2]);
    const float e_row[3] = {0.0f, d[1] * k, d[2] * k};
    const float nu[1] = {mca_wrap_pi(psi_m - eul[2])};
    if (nu[0] * nu[0] > gate * (att->p[2u * MCA_ATT_NX + 2u] + r)) { /* P[2][2] + r: S for small tilt */
        return MCA_ERR_BAD_ARG;
    }
    return euler_update(att, e_row, 1u, nu, r, q_d, 0, 0, ws, rep);
}

mca_status_t mca_att_update_yaw(mca_att_t *att, float psi_m, float r, const float q_d[4], float *ws,
                                mca_update_report_t *rep)
{
    if (att == NULL || q_d == NULL || ws == NULL) {
        return MCA_ERR_NULL;
    }
    if (!isfinite(psi_m) || !isfinite(r) || !mca_all_finite(q_d, 4u)) {
        return MCA_ERR_NONFINITE;
    }
    if (!(r > 0.0f)) {
        return MCA_ERR_BAD_ARG;
    }
    return yaw_update(att, psi_m, r, q_d, ws, rep, INFINITY);
}

mca_status_t mca_att_yaw_nocheck(mca_att_t *att, float psi_m, float r, const float q_d[4], float *ws, float gate)
{
    return yaw_update(att, psi_m, r, q_d, ws, NULL, gate);
}

mca_status_t mca_att_align_yaw(mca_att_t *att, float psi_m, float r)
{
    if (att == NULL) {
        return MCA_ERR_NULL;
    }
    if (!isfinite(psi_m) || !isfinite(r)) {
        return MCA_ERR_NONFINITE;
    }
    if (!(r > 0.0f)) {
        return MCA_ERR_BAD_ARG;
    }
    mca_att_align_yaw_nocheck(att, psi_m, r);
    return MCA_OK;
}

void mca_att_align_yaw_nocheck(mca_att_t *att, float psi_m, float r)
{
    float eul[3];
    mca_quat_to_euler_part(eul, att->q_nb, 3u); /* roll and pitch kept, yaw set */
    eul[2] = mca_wrap_pi(psi_m);
    mca_quat_from_euler(att->q_nb, eul);
    for (size_t i = 0; i < MCA_ATT_NX; ++i) {
        att->p[2u * MCA_ATT_NX + i] = 0.0f;
        att->p[i * MCA_ATT_NX + 2u] = 0.0f;
    }
    att->p[2u * MCA_ATT_NX + 2u] = r;
}

mca_status_t mca_att_mag_heading(const mca_att_t *att, const float m[3], float decl, float *psi_m)
{
    if (att == NULL || m == NULL || psi_m == NULL) {
        return MCA_ERR_NULL;
    }
    if (!mca_all_finite(m, 3u) || !isfinite(decl)) {
        return MCA_ERR_NONFINITE;
    }
    return mca_att_mag_heading_nocheck(att, m, decl, psi_m);
}

mca_status_t mca_att_mag_heading_nocheck(const mca_att_t *att, const float m[3], float decl, float *psi_m)
{
    if (!(m[0] * m[0] + m[1] * m[1] + m[2] * m[2] > 0.0f)) {
        return MCA_ERR_BAD_ARG;
    }
    float eul[3], ql[4], ml[3];
    mca_quat_to_euler_part(eul, att->q_nb, 3u); /* roll and pitch; yaw 0 */
    mca_quat_from_euler(ql, eul);
    mca_quat_rotate(ml, ql, m); /* the field levelled: C_nb(roll, pitch, 0) m */
    *psi_m = mca_wrap_pi(mca_atan2f(-ml[1], ml[0]) + decl);
    return MCA_OK;
}

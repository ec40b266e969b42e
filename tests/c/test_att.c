/* Host C unit tests of the attitude filter's updates (mca_att.c): the plain path without a report
 * against the general update with one, the two halves of the navigation filter's no-GPS
 * observation, the tilt gates, bad input, and the yaw update's gate (the course gate). */
#include "mca_test.h"
#include "mcahrs/mca_att.h"
#include "mca_att_nocheck.h"
#include "mcahrs/mca_math.h"
#include "mcahrs/mca_robust.h"

#include <math.h>
#include <string.h>

static float g_ws[MCA_ATT_WS_LEN];

/* A filter with a full, coupled covariance: P = A A^T + 1e-4 I from a fixed A, a tilted q. */
static void make_att(mca_att_t *att, unsigned seed)
{
    mca_att_config_t cfg;
    mca_att_config_default(&cfg);
    const float q0[4] = {0.98f, 0.12f, -0.08f, 0.15f};
    const float b0[3] = {0.002f, -0.001f, 0.003f};
    CHECK_EQ_INT(mca_att_init(att, &cfg, q0, b0), MCA_OK);
    float a[36];
    unsigned s = seed * 2654435761u + 12345u;
    for (int i = 0; i < 36; ++i) {
        s = s * 1103515245u + 12345u;
        a[i] = (float)((s >> 8) & 0xffffu) / 65535.0f * 0.2f - 0.1f;
    }
    for (int i = 0; i < 6; ++i) {
        for (int j = 0; j < 6; ++j) {
            float v = i == j ? 1e-4f : 0.0f;
            for (int k = 0; k < 6; ++k) {
                v += a[i * 6 + k] * a[j * 6 + k];
            }
            att->p[i * 6 + j] = v;
        }
    }
}

static float max_abs_diff(const float *a, const float *b, int n)
{
    float m = 0.0f;
    for (int i = 0; i < n; ++i) {
        const float d = fabsf(a[i] - b[i]);
        m = d > m ? d : m;
    }
    return m;
}

/* Without a report the plain mode takes the attitude rows' own path; with one, mca_kf_update's
 * general (joint, Joseph) path. The same update: equal to rounding, and the memory's T equals
 * the report's. */
static void test_plain_path_equals_general_update(void)
{
    const float f[3] = {0.6f, -1.9f, -9.5f};
    const float acc[3] = {0.4f, -0.2f, 0.1f};
    const float q_d[4] = {0.979f, 0.118f, -0.081f, 0.152f}; /* a delayed attitude, near q */
    for (unsigned seed = 1u; seed <= 5u; ++seed) {
        mca_att_t a, b;
        make_att(&a, seed);
        b = a;
        mca_update_report_t rep;
        CHECK_EQ_INT(mca_att_update_gravity(&a, f, acc, q_d, 9.80665f, 1e-4f, g_ws, NULL), MCA_OK);
        CHECK_EQ_INT(mca_att_update_gravity(&b, f, acc, q_d, 9.80665f, 1e-4f, g_ws, &rep), MCA_OK);
        CHECK(max_abs_diff(a.q_nb, b.q_nb, 4) <= 2e-6f);
        CHECK(max_abs_diff(a.bias_rps, b.bias_rps, 3) <= 1e-7f);
        CHECK(max_abs_diff(a.p, b.p, 36) <= 1e-6f);
        CHECK_CLOSE(a.rs.t_stat, rep.t_stat, 1e-4 * fabs((double)rep.t_stat) + 1e-6);
        for (int i = 0; i < 6; ++i) { /* exactly symmetric */
            for (int j = 0; j < 6; ++j) {
                CHECK(a.p[i * 6 + j] == a.p[j * 6 + i]);
            }
        }
        /* yaw: one row, no memory */
        mca_att_t c = a, d = a;
        CHECK_EQ_INT(mca_att_update_yaw(&c, 0.45f, 0.01f, q_d, g_ws, NULL), MCA_OK);
        CHECK_EQ_INT(mca_att_update_yaw(&d, 0.45f, 0.01f, q_d, g_ws, &rep), MCA_OK);
        CHECK(max_abs_diff(c.q_nb, d.q_nb, 4) <= 2e-6f);
        CHECK(max_abs_diff(c.p, d.p, 36) <= 1e-6f);
    }
}

/* The navigation filter's two halves equal the observation at once, bit for bit, when nothing
 * changes the filter in between (ALGORITHMS.md 8, IMU step 6); a gate refuses in the first. */
static void test_two_halves_equal_the_whole_observation(void)
{
    const float f[3] = {0.6f, -1.9f, -9.5f};
    const float acc[3] = {0.4f, -0.2f, 0.1f};
    mca_att_t a, b;
    make_att(&a, 7u);
    b = a;
    CHECK_EQ_INT(mca_att_gravity_nocheck(&a, f, acc, a.q_nb, 9.80665f, 2e-4f, g_ws), MCA_OK);
    float nu[2], rows[6], r;
    CHECK_EQ_INT(mca_att_gravity_measure_nocheck(&b, f, acc, 9.80665f, 2e-4f, nu, rows, &r), MCA_OK);
    CHECK_EQ_INT(mca_att_gravity_apply_nocheck(&b, nu, rows, r, g_ws), MCA_OK);
    CHECK(memcmp(a.q_nb, b.q_nb, sizeof(a.q_nb)) == 0);
    CHECK(memcmp(a.bias_rps, b.bias_rps, sizeof(a.bias_rps)) == 0);
    CHECK(memcmp(a.p, b.p, sizeof(a.p)) == 0);
    CHECK(memcmp(&a.rs, &b.rs, sizeof(a.rs)) == 0);
    const float free_fall[3] = {0.0f, 0.0f, 0.0f};
    CHECK_EQ_INT(mca_att_gravity_measure_nocheck(&b, free_fall, free_fall, 9.80665f, 2e-4f, nu, rows, &r),
                 MCA_ERR_BAD_ARG);
}

/* The tilt gates compare sin(pitch) with sin(max_tilt_obs): a pitch just inside is observed,
 * just outside refused, state unchanged. */
static void test_tilt_gates(void)
{
    mca_att_config_t cfg;
    mca_att_config_default(&cfg);
    const float lim = cfg.max_tilt_obs_rad;
    const float bias[3] = {0.0f, 0.0f, 0.0f};
    for (int side = 0; side < 2; ++side) {
        const float th = side == 0 ? lim - 0.01f : lim + 0.01f;
        const float q[4] = {cosf(0.5f * th), 0.0f, sinf(0.5f * th), 0.0f}; /* pitch th */
        mca_att_t att;
        CHECK_EQ_INT(mca_att_init(&att, &cfg, q, bias), MCA_OK);
        /* the specific force of a vehicle at rest at that pitch */
        const float f[3] = {9.80665f * sinf(th), 0.0f, -9.80665f * cosf(th)};
        const float zero[3] = {0.0f, 0.0f, 0.0f};
        const mca_att_t before = att;
        const mca_status_t sg = mca_att_update_gravity(&att, f, zero, q, 9.80665f, 0.0f, g_ws, NULL);
        const mca_status_t sy = mca_att_update_yaw(&att, 0.1f, 0.01f, q, g_ws, NULL);
        if (side == 0) {
            CHECK_EQ_INT(sg, MCA_OK);
            CHECK_EQ_INT(sy, MCA_OK);
        } else {
            CHECK_EQ_INT(sg, MCA_ERR_BAD_ARG);
            CHECK_EQ_INT(sy, MCA_ERR_BAD_ARG);
            CHECK(memcmp(&before, &att, sizeof(att)) == 0);
        }
    }
}

/* Bad input: the public functions report it; the unchecked ones, fed a non-finite vector that
 * got there anyway, still refuse it (a non-finite yaw measurement is the caller's to keep out:
 * mca_wrap_pi makes it a zero residual). Either way the filter is unchanged. */
static void test_bad_input_leaves_state(void)
{
    const float nan = NAN;
    const float f[3] = {0.6f, -1.9f, -9.5f};
    const float f_nan[3] = {0.6f, nan, -9.5f};
    const float f_inf[3] = {INFINITY, 0.0f, -9.5f};
    const float acc[3] = {0.0f, 0.0f, 0.0f};
    const float q_nan[4] = {nan, 0.0f, 0.0f, 0.0f};
    mca_att_t att;
    make_att(&att, 3u);
    const mca_att_t before = att;
    CHECK_EQ_INT(mca_att_update_gravity(&att, f_nan, acc, att.q_nb, 9.80665f, 0.0f, g_ws, NULL), MCA_ERR_NONFINITE);
    CHECK_EQ_INT(mca_att_update_gravity(&att, f, acc, q_nan, 9.80665f, 0.0f, g_ws, NULL), MCA_ERR_NONFINITE);
    CHECK_EQ_INT(mca_att_update_yaw(&att, nan, 0.01f, att.q_nb, g_ws, NULL), MCA_ERR_NONFINITE);
    CHECK(mca_att_gravity_nocheck(&att, f_nan, acc, att.q_nb, 9.80665f, 0.0f, g_ws) != MCA_OK);
    CHECK(mca_att_gravity_nocheck(&att, f_inf, acc, att.q_nb, 9.80665f, 0.0f, g_ws) != MCA_OK);
    CHECK(mca_att_gravity_nocheck(&att, f, acc, q_nan, 9.80665f, 0.0f, g_ws) != MCA_OK);
    CHECK(mca_att_gravity_nocheck(&att, f, acc, att.q_nb, 9.80665f, INFINITY, g_ws) != MCA_OK);
    CHECK(mca_att_yaw_nocheck(&att, 0.2f, 0.01f, q_nan, g_ws, INFINITY) != MCA_OK);
    CHECK(memcmp(&before, &att, sizeof(att)) == 0);
}

/* The gravity update's robust inputs are checked by mca_att_update_gravity, since the filter's
 * own path skips them (mca_robust_inputs_check): a fuzzy memory no update can have left, or an
 * unknown mode, is refused and nothing changes; the same observation with good ones is taken. */
static void test_gravity_update_refuses_bad_robust_inputs(void)
{
    const float f[3] = {0.6f, -1.9f, -9.5f};
    const float acc[3] = {0.0f, 0.0f, 0.0f};
    mca_att_t att;
    make_att(&att, 4u);
    att.cfg.robust.mode = (uint8_t)MCA_ROBUST_FUZZY;
    for (int k = 0; k < 2; ++k) {
        mca_att_t bad = att;
        if (k == 0) {
            bad.rs.d_k = -1.0f; /* D is never negative */
        } else {
            bad.cfg.robust.mode = 9u;
        }
        const mca_att_t copy = bad;
        CHECK_EQ_INT(mca_att_update_gravity(&bad, f, acc, bad.q_nb, 9.80665f, 1e-4f, g_ws, NULL),
                     k == 0 ? MCA_ERR_BAD_ARG : MCA_ERR_BAD_CONFIG);
        CHECK(memcmp(&bad, &copy, sizeof bad) == 0);
    }
    CHECK_EQ_INT(mca_att_update_gravity(&att, f, acc, att.q_nb, 9.80665f, 1e-4f, g_ws, NULL), MCA_OK);
}

/* The course gate's half (ALGORITHMS.md 7): the unchecked yaw update refuses, nothing changed,
 * a residual with nu^2 > gate (P[2][2] + r), takes one just inside, and with gate INFINITY (the
 * magnetometer, plain mode) takes the one it refused. */
static void test_yaw_gate(void)
{
    const float r = 0.0025f;
    const float gate = mca_chi2_quantile(1u, MCA_CHI2_1E4);
    for (unsigned seed = 1u; seed <= 3u; ++seed) {
        mca_att_t att;
        make_att(&att, seed);
        float eul[3];
        mca_quat_to_euler_part(eul, att.q_nb, 4u);
        const float bound = sqrtf(gate * (att.p[14] + r));
        const mca_att_t before = att;
        CHECK_EQ_INT(mca_att_yaw_nocheck(&att, eul[2] + 1.05f * bound, r, att.q_nb, g_ws, gate), MCA_ERR_BAD_ARG);
        CHECK(memcmp(&before, &att, sizeof(att)) == 0);
        CHECK_EQ_INT(mca_att_yaw_nocheck(&att, eul[2] - 1.05f * bound, r, att.q_nb, g_ws, gate), MCA_ERR_BAD_ARG);
        CHECK(memcmp(&before, &att, sizeof(att)) == 0);
        CHECK_EQ_INT(mca_att_yaw_nocheck(&att, eul[2] + 0.95f * bound, r, att.q_nb, g_ws, gate), MCA_OK);
        CHECK(memcmp(&before, &att, sizeof(att)) != 0);
        att = before;
        CHECK_EQ_INT(mca_att_yaw_nocheck(&att, eul[2] + 1.05f * bound, r, att.q_nb, g_ws, INFINITY), MCA_OK);
        float eul2[3];
        mca_quat_to_euler_part(eul2, att.q_nb, 4u);
        CHECK(eul2[2] > eul[2]); /* the update moved yaw toward the measurement */
    }
}

int main(void)
{
    test_plain_path_equals_general_update();
    test_two_halves_equal_the_whole_observation();
    test_tilt_gates();
    test_bad_input_leaves_state();
    test_gravity_update_refuses_bad_robust_inputs();
    test_yaw_gate();
    TEST_MAIN_END();
}

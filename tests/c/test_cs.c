/* Host tests of mca_cs that need no golden model: bad input leaves the state unchanged and
 * finite, the series/exact switch is continuous, P stays symmetric positive definite. */
#include <math.h>
#include <string.h>

#include "mca_test.h"
#include "mcahrs/mca_cs.h"

static void test_bad_input_leaves_state(void)
{
    mca_cs_config_t h, v;
    mca_cs_config_default_h(&h);
    mca_cs_config_default_v(&v);
    mca_cs3_t cs;
    float ws[MCA_CS_WS_LEN];
    const float p0[3] = {1.0f, 2.0f, 3.0f};
    CHECK_EQ_INT(mca_cs3_init(&cs, &h, &v, p0, NULL), MCA_OK);
    CHECK_EQ_INT(mca_cs3_predict(&cs, 0.2f), MCA_OK);
    mca_cs3_t before;
    memcpy(&before, &cs, sizeof(cs));
    CHECK_EQ_INT(mca_cs3_predict(&cs, 0.0f), MCA_ERR_BAD_DT);
    CHECK_EQ_INT(mca_cs3_predict(&cs, -1.0f), MCA_ERR_BAD_DT);
    CHECK_EQ_INT(mca_cs3_predict(&cs, 7200.0f), MCA_ERR_BAD_DT);
    CHECK_EQ_INT(mca_cs3_predict(&cs, NAN), MCA_ERR_BAD_DT);
    CHECK_EQ_INT(mca_cs3_predict(&cs, INFINITY), MCA_ERR_BAD_DT);
    const float pos[3] = {1.0f, 2.0f, 3.0f}, vel[3] = {0.0f, 0.0f, 0.0f};
    const float rp[3] = {4.0f, 4.0f, 9.0f}, rv[3] = {0.01f, 0.01f, 0.01f};
    const float pos_nan[3] = {1.0f, NAN, 3.0f}, rv_bad[3] = {0.01f, 0.0f, 0.01f};
    const uint8_t none[3] = {0, 0, 0}, both[3] = {3, 3, 1}, unknown[3] = {3, 4, 1};
    CHECK_EQ_INT(mca_cs3_update(&cs, pos, vel, rp, rv, none, ws, NULL), MCA_ERR_BAD_MASK);
    CHECK_EQ_INT(mca_cs3_update(&cs, pos, vel, rp, rv, unknown, ws, NULL), MCA_ERR_BAD_MASK);
    CHECK_EQ_INT(mca_cs3_update(&cs, pos_nan, vel, rp, rv, both, ws, NULL), MCA_ERR_NONFINITE);
    CHECK_EQ_INT(mca_cs3_update(&cs, pos, vel, rp, rv_bad, both, ws, NULL), MCA_ERR_BAD_ARG);
    CHECK(memcmp(&before.axis, &cs.axis, sizeof(cs.axis)) == 0);
    /* a good update still works afterwards */
    mca_update_report_t rep[3];
    CHECK_EQ_INT(mca_cs3_update(&cs, pos, vel, rp, rv, both, ws, rep), MCA_OK);
    CHECK_EQ_INT(rep[0].m, 2);
    CHECK_EQ_INT(rep[2].m, 1);
    CHECK(rep[0].t_stat >= 0.0f);
}

/* Relative gap of the Singer Q across the series switch, per entry. */
static void test_series_switch_continuous(void)
{
    const float t = 1.0f, s2 = 1.0f;
    const float x_lo = MCA_CS_SERIES_X * (1.0f - 1e-6f), x_hi = MCA_CS_SERIES_X * (1.0f + 1e-6f);
    float qa[9], qb[9];
    mca_cs_singer_q(x_lo / t, t, s2, qa);
    mca_cs_singer_q(x_hi / t, t, s2, qb);
    for (int i = 0; i < 9; ++i) {
        /* x moves by 2e-6 relative; each entry moves by at most a few times that, the
         * rest is float32 rounding of the two forms (a few ulp). */
        CHECK_CLOSE(qa[i] / qb[i], 1.0, 2e-5);
    }
}

static int spd(const float *p, int n)
{
    float l[25];
    return mca_cholesky(l, p, (size_t)n) == MCA_OK;
}

static void test_long_run_stays_spd(void)
{
    mca_cs_config_t h;
    mca_cs_config_default_h(&h);
    mca_cs_axis_t ax;
    float ws[MCA_CS_WS_LEN];
    CHECK_EQ_INT(mca_cs_axis_init(&ax, &h, 0.0f, 0.0f), MCA_OK);
    unsigned seed = 12345u;
    int ok = 1;
    for (int k = 0; k < 100000; ++k) {
        /* 400 Hz predicts, a fix every 80 steps, a crude deterministic noise */
        ok &= mca_cs_axis_predict(&ax, 0.0025f) == MCA_OK;
        if (k % 80 == 79) {
            seed = seed * 1103515245u + 12345u;
            const float n = (float)((seed >> 16) & 0x7fff) / 32768.0f - 0.5f;
            ok &= mca_cs_axis_update(&ax, 3.0f * n, 0.1f * n, 6.25f, 0.01f, 3, ws, NULL) == MCA_OK;
        }
        if (k % 997 == 0) {
            ok &= spd(ax.p, 5);
            ok &= mca_all_finite(ax.p, 25) && mca_all_finite(ax.x, 5);
        }
    }
    CHECK(ok);
}

/* The shared N/E covariance update of mca_cs3_update (no reports) gives the same bits as
 * updating the axes one by one (mca_cs_axis_update, which never shares), aided or not, every
 * mask, and still when N and E stop having the same P. */
static void test_shared_ne_update_same_bits(void)
{
    mca_cs_config_t h, v;
    mca_cs_config_default_h(&h);
    mca_cs_config_default_v(&v);
    mca_cs3_t a, b;
    float ws[MCA_CS_WS_LEN];
    const float p0[3] = {3.0f, -2.0f, 1.0f}, v0[3] = {4.0f, -1.0f, 0.5f};
    CHECK_EQ_INT(mca_cs3_init(&a, &h, &v, p0, v0), MCA_OK);
    memcpy(&b, &a, sizeof(a));
    const uint8_t masks[4][3] = {{3, 3, 3}, {1, 1, 1}, {2, 2, 2}, {3, 3, 0}};
    for (int k = 0; k < 60; ++k) {
        const float t = 0.2f;
        const float dv[3] = {0.3f * sinf(0.1f * (float)k), -0.2f, 0.05f};
        const float dp[3] = {0.5f * dv[0] * t, 0.5f * dv[1] * t, 0.5f * dv[2] * t};
        mca_cs_inc_t inc[3];
        const mca_cs_inc_t *use[3] = {NULL, NULL, NULL};
        for (int i = 0; i < 3; ++i) {
            inc[i].dp_m = dp[i];
            inc[i].dv_mps = dv[i];
            inc[i].acc_var_m2ps4 = 0.09f;
            inc[i].coast_var_m2ps4 = 0.09f;
            use[i] = (k % 3 != 0) ? &inc[i] : NULL; /* aided two fixes in three */
        }
        CHECK_EQ_INT(mca_cs3_predict_aided(&a, t, use), MCA_OK);
        CHECK_EQ_INT(mca_cs3_predict_aided(&b, t, use), MCA_OK);
        const float ft = (float)k;
        const float pos[3] = {3.0f + 0.8f * ft + 1.7f * sinf(ft), -2.0f - 0.2f * ft + cosf(3.0f * ft),
                              1.0f + 0.1f * sinf(ft)};
        const float vel[3] = {4.0f + 0.2f * sinf(7.0f * ft), -1.0f + 0.1f * cosf(ft), 0.5f};
        float rp[3] = {2.25f, 2.25f, 9.0f};
        const float rv[3] = {0.04f, 0.04f, 0.09f};
        if (k == 40) {
            rp[1] = 4.0f; /* E weighted differently once: from here on P_N and P_E differ */
        }
        const uint8_t *mask = masks[(k / 5) % 4];
        for (int i = 0; i < 3; ++i) {
            if (mask[i] != 0u) {
                CHECK_EQ_INT(mca_cs_axis_update(&a.axis[i], pos[i], vel[i], rp[i], rv[i], mask[i], ws, NULL), MCA_OK);
            }
        }
        CHECK_EQ_INT(mca_cs3_update(&b, pos, vel, rp, rv, mask, ws, NULL), MCA_OK);
        for (int i = 0; i < 3; ++i) {
            CHECK(memcmp(a.axis[i].x, b.axis[i].x, sizeof(a.axis[i].x)) == 0);
            CHECK(memcmp(a.axis[i].p, b.axis[i].p, sizeof(a.axis[i].p)) == 0);
            CHECK(memcmp(&a.axis[i].rs, &b.axis[i].rs, sizeof(a.axis[i].rs)) == 0);
            CHECK_EQ_INT(a.axis[i].aid.valid, b.axis[i].aid.valid);
        }
    }
    /* the weighting at k = 40 made the two axes differ: the later fixes took the unshared path */
    CHECK(memcmp(a.axis[0].p, a.axis[1].p, sizeof(a.axis[0].p)) != 0);
}

/* Coasting (ALGORITHMS.md 2): after an update that left a row out, an aided predict moves p and
 * v with the IMU increments (a kept) and adds the IMU error to P; with coast off, or without
 * increments, the predict is the ordinary one bit for bit. */
static void test_coasting_predict(void)
{
    mca_cs_config_t h;
    mca_cs_config_default_h(&h);
    h.coast = 1u;
    CHECK_EQ_INT(mca_cs_config_check(&h), MCA_OK);
    h.coast = 2u;
    CHECK_EQ_INT(mca_cs_config_check(&h), MCA_ERR_BAD_CONFIG);
    h.coast = 1u;
    mca_cs_axis_t ax, plain;
    CHECK_EQ_INT(mca_cs_axis_init(&ax, &h, 10.0f, 5.0f), MCA_OK);
    ax.x[2] = 2.0f; /* an acceleration the coast must not use */
    plain = ax;
    const mca_cs_inc_t inc = {0.03f, 0.2f, 0.09f, 0.04f}; /* the coast accumulates 0.04 of the 0.09 */
    const float t = 0.2f;
    /* out clear: the ordinary predict */
    CHECK_EQ_INT(mca_cs_axis_predict_aided(&ax, t, &inc), MCA_OK);
    CHECK_EQ_INT(mca_cs_axis_predict_aided(&plain, t, &inc), MCA_OK);
    CHECK(memcmp(ax.x, plain.x, sizeof ax.x) == 0 && memcmp(ax.p, plain.p, sizeof ax.p) == 0);
    CHECK_CLOSE(ax.x[1], 5.0 + 0.2 * 2.0, 1e-6);
    /* out set: coasting */
    mca_cs_axis_t before = ax;
    ax.aid.out = 1u;
    plain = ax;
    plain.cfg.coast = 0u;
    CHECK_EQ_INT(mca_cs_axis_predict_aided(&ax, t, &inc), MCA_OK);
    CHECK_CLOSE(ax.x[0], before.x[0] + t * before.x[1] + 0.03f, 1e-5);
    CHECK_CLOSE(ax.x[1], before.x[1] + 0.2f, 1e-6);
    CHECK(ax.x[2] == before.x[2]);
    CHECK(ax.p[1] == ax.p[5]);
    /* coast off: the ordinary predict although out is set */
    CHECK_EQ_INT(mca_cs_axis_predict_aided(&plain, t, &inc), MCA_OK);
    CHECK_CLOSE(plain.x[1], before.x[1] + t * before.x[2], 1e-6);
    /* P: without the a coupling, with the IMU error; the p-a covariance is not moved by a */
    CHECK(ax.p[6] >= before.p[6] + 0.04f * t * t - 1e-7f);
    CHECK(ax.p[6] < plain.p[6]); /* P_aa t^2 is larger than qa t^2 here */
    /* the coast accumulates the persisting variance; the test prior takes the whole one */
    mca_cs_axis_t nocv = before;
    nocv.aid.out = 1u;
    const mca_cs_inc_t inc0 = {0.03f, 0.2f, 0.09f, 0.0f};
    CHECK_EQ_INT(mca_cs_axis_predict_aided(&nocv, t, &inc0), MCA_OK);
    CHECK_CLOSE(ax.p[6] - nocv.p[6], 0.04 * 0.2 * 0.2, 1e-6);
    CHECK(ax.aid.s[3] == nocv.aid.s[3] && ax.aid.valid == 1u);
    /* a bad coast variance: refused, nothing changes */
    mca_cs_axis_t bad = before;
    mca_cs_inc_t binc = inc;
    binc.coast_var_m2ps4 = NAN;
    CHECK_EQ_INT(mca_cs_axis_predict_aided(&bad, t, &binc), MCA_ERR_NONFINITE);
    binc.coast_var_m2ps4 = -0.01f;
    CHECK_EQ_INT(mca_cs_axis_predict_aided(&bad, t, &binc), MCA_ERR_BAD_ARG);
    CHECK(memcmp(bad.x, before.x, sizeof bad.x) == 0 && memcmp(bad.p, before.p, sizeof bad.p) == 0);
    /* without increments: the ordinary predict */
    mca_cs_axis_t noinc = before, ref = before;
    noinc.aid.out = 1u;
    CHECK_EQ_INT(mca_cs_axis_predict_aided(&noinc, t, NULL), MCA_OK);
    CHECK_EQ_INT(mca_cs_axis_predict_aided(&ref, t, NULL), MCA_OK);
    CHECK(memcmp(noinc.x, ref.x, sizeof ref.x) == 0 && memcmp(noinc.p, ref.p, sizeof ref.p) == 0);
}

/* Which updates start a coast (ALGORITHMS.md 2, coasting; fuzzy rows, ALGORITHMS.md 5): a
 * position left out while the velocity is applied does not; a rejected update does, and the
 * coast starts from the IMU-aided prediction, not the acceleration state's; a velocity out on
 * one update only comes back while the position still fails, and the coast ends. */
/* The horizontal defaults with the fuzzy-rows profile (docs/ALGORITHMS.md 5): fuzzy rows,
 * coasting, the 20 s guard at 5 Hz, no row guard. */
static void fuzzy_rows_config(mca_cs_config_t *h)
{
    mca_cs_config_default_h(h);
    h->coast = 1u;
    h->robust.mode = (uint8_t)MCA_ROBUST_FUZZY;
    h->robust.fuzzy_reject = 2u;
    h->robust.reject_reset_n = 100u;
    h->robust.row_reset_n = 0u;
}

static void test_coast_starts_when_the_velocity_is_out(void)
{
    mca_cs_config_t h;
    fuzzy_rows_config(&h);
    CHECK_EQ_INT(mca_cs_config_check(&h), MCA_OK);
    mca_cs_axis_t ax;
    CHECK_EQ_INT(mca_cs_axis_init(&ax, &h, 0.0f, 5.0f), MCA_OK);
    const mca_cs_inc_t inc = {0.0f, 0.0f, 0.09f, 0.09f}; /* the IMU: no acceleration */
    const float t = 0.2f;
    float ws[MCA_CS_WS_LEN];
    mca_update_report_t rep;
    size_t n = 0u; /* fixes so far, 5 m/s on a straight line */
    for (; n < 30u; ++n) { /* converge on clean fixes first */
        CHECK_EQ_INT(mca_cs_axis_predict_aided(&ax, t, &inc), MCA_OK);
        CHECK_EQ_INT(mca_cs_axis_update(&ax, 5.0f * t * (float)(n + 1u), 5.0f, 1.0f, 0.01f,
                                        MCA_CS_POS | MCA_CS_VEL, ws, &rep),
                     MCA_OK);
        CHECK_EQ_INT(rep.alarm, 0);
    }
    /* z_p offset, z_v offset; then rejected, coasting after the update */
    const struct {
        float dp, dv;
        int rejected, coasting;
    } steps[] = {
        {50.0f, 0.0f, 0, 0},  /* alarm (D = 1): position out, velocity applied, no coast */
        {50.0f, 5.0f, 1, 1},  /* both fail: rejected, the coast starts */
        {50.0f, 0.0f, 0, 0},  /* the velocity, out once, passes and is applied: the coast ends */
    };
    for (size_t k = 0; k < sizeof steps / sizeof steps[0]; ++k) {
        ax.x[2] = 2.0f; /* an acceleration the IMU does not see */
        const int coasted = ax.aid.out != 0u;
        CHECK_EQ_INT(mca_cs_axis_predict_aided(&ax, t, &inc), MCA_OK);
        const float v_prior = ax.x[1];             /* the predict's: the CS model's unless coasting */
        const float v_imu = ax.aid.y[1] - ax.x[4]; /* the IMU-aided prediction */
        CHECK(coasted ? v_prior == v_imu : v_prior - v_imu > 0.3f);
        const float p_true = 5.0f * t * (float)(++n);
        CHECK_EQ_INT(mca_cs_axis_update(&ax, p_true + steps[k].dp, 5.0f + steps[k].dv, 1.0f, 0.01f,
                                        MCA_CS_POS | MCA_CS_VEL, ws, &rep),
                     MCA_OK);
        CHECK_EQ_INT(rep.alarm, 1);
        CHECK_EQ_INT(rep.rejected, steps[k].rejected);
        CHECK_EQ_INT(ax.aid.out, steps[k].coasting);
        if (steps[k].rejected) {
            CHECK(ax.x[1] == v_imu); /* the coast starts from the aided prediction */
        } else {
            CHECK(fabsf(ax.x[1] - 5.0f) < 0.5f * fabsf(v_prior - 5.0f)); /* the velocity applied */
        }
    }
}

/* A coast that starts with the velocity row out and the position applied starts from the
 * IMU-aided prediction too (ALGORITHMS.md 2, coasting): the state is the position-only update's,
 * moved by the aided prediction less the CS one (here the CS acceleration's 0.1 m/s over the
 * interval, which the IMU did not see: a maneuver onset the CS lags). */
static void test_coast_start_with_the_position_applied(void)
{
    mca_cs_config_t h;
    fuzzy_rows_config(&h);
    mca_cs_axis_t ax;
    CHECK_EQ_INT(mca_cs_axis_init(&ax, &h, 0.0f, 5.0f), MCA_OK);
    const mca_cs_inc_t inc = {0.0f, 0.0f, 0.09f, 0.09f};
    const float t = 0.2f;
    float ws[MCA_CS_WS_LEN];
    mca_update_report_t rep;
    float p = 0.0f;
    for (size_t n = 0; n < 30u; ++n) {
        p += 5.0f * t;
        CHECK_EQ_INT(mca_cs_axis_predict_aided(&ax, t, &inc), MCA_OK);
        CHECK_EQ_INT(mca_cs_axis_update(&ax, p, 5.0f, 1.0f, 0.01f, MCA_CS_POS | MCA_CS_VEL, ws, &rep), MCA_OK);
    }
    ax.x[2] = 0.5f;
    p += 5.0f * t;
    CHECK_EQ_INT(mca_cs_axis_predict_aided(&ax, t, &inc), MCA_OK);
    const float shift_p = ax.aid.y[0] - ax.x[3] - ax.x[0], shift_v = ax.aid.y[1] - ax.x[4] - ax.x[1];
    CHECK_CLOSE(shift_v, -0.1, 1e-5);
    mca_cs_axis_t ref = ax; /* the same prior, the position row alone */
    CHECK_EQ_INT(mca_cs_axis_update(&ax, p, 8.0f, 1.0f, 0.01f, MCA_CS_POS | MCA_CS_VEL, ws, &rep), MCA_OK);
    CHECK_EQ_INT(rep.rejected, 0);
    CHECK_EQ_INT(ax.aid.out, 1); /* a 3 m/s velocity fault left out: the coast starts */
    CHECK_EQ_INT(mca_cs_axis_update(&ref, p, 0.0f, 1.0f, 0.01f, MCA_CS_POS, ws, &rep), MCA_OK);
    CHECK_CLOSE(ax.x[0], ref.x[0] + shift_p, 1e-5);
    CHECK_CLOSE(ax.x[1], ref.x[1] + shift_v, 1e-5);
    for (size_t i = 2; i < MCA_CS_NX; ++i) {
        CHECK_CLOSE(ax.x[i], ref.x[i], 1e-6);
    }
}

/* Fuzzy rows' N/E pair (ALGORITHMS.md 5): a 50 m north jump that N alarms on, with a 4 m east
 * share that E alone lets in (its T of 12 is below TD3 on a first epoch), leaves E's position
 * out too when both axes test position and velocity against the IMU; E's velocity stays in. With
 * a position-only east fix (the axes' rows differ) there is no pair. Both mca_cs3_update paths
 * (with and without reports) pair the same way. */
static void test_ne_pair_leaves_the_partner_rows_out(void)
{
    mca_cs_config_t h, v;
    fuzzy_rows_config(&h);
    mca_cs_config_default_v(&v);
    const float t = 0.2f;
    const mca_cs_inc_t inc = {0.0f, 0.0f, 0.09f, 0.09f}; /* the IMU: no acceleration */
    const mca_cs_inc_t *const incs[3] = {&inc, &inc, &inc};
    float ws[MCA_CS_WS_LEN];
    mca_update_report_t rep[3];
    const float r_pos[3] = {1.0f, 1.0f, 4.0f}, r_vel[3] = {0.01f, 0.01f, 0.04f};
    for (int variant = 0; variant < 3; ++variant) { /* 0, 1: paired (reports, none); 2: E position only */
        mca_cs3_t cs;
        const float p0[3] = {0.0f, 0.0f, 0.0f}, v0[3] = {5.0f, 0.0f, 0.0f};
        CHECK_EQ_INT(mca_cs3_init(&cs, &h, &v, p0, v0), MCA_OK);
        const uint8_t both = MCA_CS_POS | MCA_CS_VEL;
        const uint8_t mask[3] = {both, variant == 2 ? (uint8_t)MCA_CS_POS : both, both};
        float pos[3] = {0.0f, 0.0f, 0.0f};
        const float vel[3] = {5.0f, 0.0f, 0.0f};
        for (int n = 1; n <= 31; ++n) { /* 30 clean fixes, then the jump */
            CHECK_EQ_INT(mca_cs3_predict_aided(&cs, t, incs), MCA_OK);
            pos[0] = 5.0f * t * (float)n + (n == 31 ? 50.0f : 0.0f);
            pos[1] = n == 31 ? 4.0f : 0.0f;
            const float e_prior = cs.axis[1].x[0];
            CHECK_EQ_INT(mca_cs3_update(&cs, pos, vel, r_pos, r_vel, mask, ws, variant == 1 ? NULL : rep), MCA_OK);
            if (n < 31) {
                continue;
            }
            CHECK_EQ_INT(cs.axis[0].rs.alarm, 1);        /* N alarms: its position out */
            CHECK_EQ_INT(cs.axis[0].rs.n_removed[0], 1);
            CHECK_EQ_INT(cs.axis[1].rs.alarm, 0);        /* E does not alarm on its 4 m */
            CHECK_EQ_INT(cs.axis[1].rs.started, 0);      /* the pair rows were for this update */
            CHECK_EQ_INT(cs.axis[1].aid.out, 0);         /* E's velocity applied: no coast */
            if (variant < 2) {
                CHECK_EQ_INT(cs.axis[1].rs.n_removed[0], 1); /* out for the pair */
                CHECK(fabsf(cs.axis[1].x[0] - e_prior) < 0.05f);
            } else {
                CHECK_EQ_INT(cs.axis[1].rs.n_removed[0], 0); /* no pair: E takes part of it */
                CHECK(cs.axis[1].x[0] - e_prior > 0.5f);
            }
        }
    }
}

/* The N/E pair shares the rows kept out that went out with the failing ones (a fault of both:
 * N's velocity, out with its position, passes again while the position fails; E leaves its
 * velocity out too), not a row that went out on its own later (N's velocity failing twice well
 * into a position fault; E keeps its velocity). */
static void test_ne_pair_shares_the_rows_out_with_the_failing_ones(void)
{
    mca_cs_config_t h, v;
    fuzzy_rows_config(&h);
    mca_cs_config_default_v(&v);
    const float t = 0.2f;
    const mca_cs_inc_t inc = {0.0f, 0.0f, 0.09f, 0.09f};
    const mca_cs_inc_t *const incs[3] = {&inc, &inc, &inc};
    float ws[MCA_CS_WS_LEN];
    const float r_pos[3] = {1.0f, 1.0f, 4.0f}, r_vel[3] = {0.01f, 0.01f, 0.04f};
    const uint8_t both = MCA_CS_POS | MCA_CS_VEL, mask[3] = {both, both, both};
    /* N's offsets from fix 31 on: position, velocity; then E's velocity row out after that fix */
    const struct {
        float dp, dv;
        int e_vel_out;
    } together[] = {{50.0f, 3.0f, 1}, {50.0f, 3.0f, 1}, {50.0f, 0.0f, 1}, {50.0f, 0.0f, 1}},
      later[] = {{50.0f, 0.0f, 0}, {50.0f, 0.0f, 0}, {50.0f, 0.0f, 0}, {50.0f, 0.0f, 0}, {50.0f, 0.0f, 0},
                 {50.0f, 3.0f, 1}, {50.0f, 3.0f, 1}, {50.0f, 0.0f, 0}};
    for (int c = 0; c < 2; ++c) {
        mca_cs3_t cs;
        const float p0[3] = {0.0f, 0.0f, 0.0f}, v0[3] = {5.0f, 0.0f, 0.0f};
        CHECK_EQ_INT(mca_cs3_init(&cs, &h, &v, p0, v0), MCA_OK);
        const size_t n_steps = c == 0 ? sizeof together / sizeof together[0] : sizeof later / sizeof later[0];
        for (size_t n = 1; n <= 30u + n_steps; ++n) {
            CHECK_EQ_INT(mca_cs3_predict_aided(&cs, t, incs), MCA_OK);
            const size_t k = n > 30u ? n - 31u : 0u;
            const float dp = n > 30u ? (c == 0 ? together[k].dp : later[k].dp) : 0.0f;
            const float dv = n > 30u ? (c == 0 ? together[k].dv : later[k].dv) : 0.0f;
            const float pos[3] = {5.0f * t * (float)n + dp, 0.0f, 0.0f}, vel[3] = {5.0f + dv, 0.0f, 0.0f};
            CHECK_EQ_INT(mca_cs3_update(&cs, pos, vel, r_pos, r_vel, mask, ws, NULL), MCA_OK);
            if (n > 30u) {
                CHECK_EQ_INT(cs.axis[0].rs.n_removed[0], (int)k + 1); /* N's position out throughout */
                CHECK_EQ_INT(cs.axis[1].rs.n_removed[1] > 0u, c == 0 ? together[k].e_vel_out : later[k].e_vel_out);
            }
        }
        /* N keeps its own velocity out either way: it was out on the last two updates */
        CHECK(cs.axis[0].rs.n_removed[1] > 0u);
    }
}

/* The robust inputs (configuration and memory) the update reads are checked by the public
 * entries, since the filters' own paths skip them (mca_robust_inputs_check): a corrupted memory
 * or an unknown mode is refused by mca_cs_axis_update and mca_cs3_update, and nothing changes. */
static void test_public_updates_refuse_bad_robust_inputs(void)
{
    mca_cs_config_t h, v;
    fuzzy_rows_config(&h);
    mca_cs_config_default_v(&v);
    mca_cs3_t cs;
    const float p0[3] = {0.0f, 0.0f, 0.0f};
    CHECK_EQ_INT(mca_cs3_init(&cs, &h, &v, p0, NULL), MCA_OK);
    CHECK_EQ_INT(mca_cs3_predict(&cs, 0.2f), MCA_OK);
    float ws[MCA_CS_WS_LEN];
    const float pos[3] = {1.0f, 2.0f, 3.0f}, vel[3] = {0.5f, 0.5f, 0.0f};
    const float rp[3] = {1.0f, 1.0f, 4.0f}, rv[3] = {0.01f, 0.01f, 0.01f};
    const uint8_t both[3] = {MCA_CS_POS | MCA_CS_VEL, MCA_CS_POS | MCA_CS_VEL, MCA_CS_POS};
    mca_update_report_t rep;
    for (int k = 0; k < 2; ++k) {
        mca_cs3_t bad = cs;
        if (k == 0) {
            bad.axis[1].rs.alarm = 7u; /* a memory no update can have left */
        } else {
            bad.axis[1].cfg.robust.mode = 9u; /* no such mode */
        }
        const mca_status_t want = k == 0 ? MCA_ERR_BAD_ARG : MCA_ERR_BAD_CONFIG;
        const mca_cs3_t copy = bad;
        CHECK_EQ_INT(mca_cs3_update(&bad, pos, vel, rp, rv, both, ws, NULL), want);
        CHECK_EQ_INT(mca_cs_axis_update(&bad.axis[1], pos[1], vel[1], rp[1], rv[1], both[1], ws, &rep), want);
        CHECK(memcmp(&bad, &copy, sizeof bad) == 0);
    }
    CHECK_EQ_INT(mca_cs3_update(&cs, pos, vel, rp, rv, both, ws, NULL), MCA_OK); /* the control */
}

int main(void)
{
    test_shared_ne_update_same_bits();
    test_bad_input_leaves_state();
    test_series_switch_continuous();
    test_long_run_stays_spd();
    test_coasting_predict();
    test_coast_starts_when_the_velocity_is_out();
    test_coast_start_with_the_position_applied();
    test_ne_pair_leaves_the_partner_rows_out();
    test_ne_pair_shares_the_rows_out_with_the_failing_ones();
    test_public_updates_refuse_bad_robust_inputs();
    TEST_MAIN_END();
}

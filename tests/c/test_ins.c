/* Host tests of the loosely-coupled INS (docs/ALGORITHMS.md 10) that need no golden model:
 * configuration checks, static alignment, a synthetic straight run tracked to centimetres,
 * the integer position across the antimeridian, the increment input, the structure of F,
 * and bad input to every entry point leaving the whole state byte for byte unchanged. */
#include <string.h>

#include "mca_test.h"
#include "mcahrs/mca_ins.h"

#define DEG_D 0.017453292519943295
#define G_TEST 9.8f

static mca_ins_t g_ins, g_copy;

static int state_finite(const mca_ins_t *s)
{
    return mca_all_finite(s->q_nb, 4u) && mca_all_finite(s->vel_ned_mps, 3u) && mca_all_finite(s->off_ned_m, 3u) &&
           mca_all_finite(s->bg_rps, 3u) && mca_all_finite(s->ba_mps2, 3u) &&
           mca_all_finite(s->p, MCA_INS_NX * MCA_INS_NX);
}

static int p_symmetric_psd_diag(const mca_ins_t *s)
{
    for (size_t i = 0; i < MCA_INS_NX; ++i) {
        if (!(s->p[i * (MCA_INS_NX + 1u)] >= 0.0f)) {
            return 0;
        }
        for (size_t j = 0; j < MCA_INS_NX; ++j) {
            if (s->p[i * MCA_INS_NX + j] != s->p[j * MCA_INS_NX + i]) {
                return 0;
            }
        }
    }
    return 1;
}

/* A flat, non-rotating test world: constant gravity, no earth or transport rate. */
static void flat_config(mca_ins_config_t *c)
{
    mca_ins_config_default(c);
    c->earth_rate = 0u;
    c->transport_rate = 0u;
    c->gravity_mps2 = G_TEST;
    c->yaw_source = MCA_YAW_NONE;
    c->yaw0_var_rad2 = 1e-4f;
}

static mca_gps_fix_t make_fix(uint64_t t_us, double lat_deg, double lon_deg, double alt_m, const float vel[3])
{
    mca_gps_fix_t f;
    memset(&f, 0, sizeof(f));
    f.t_us = t_us;
    f.lat_e7 = (int32_t)floor(lat_deg * 1e7 + 0.5);
    f.lon_e7 = (int32_t)floor(lon_deg * 1e7 + 0.5);
    f.alt_mm = (int32_t)floor(alt_m * 1e3 + 0.5);
    memcpy(f.vel_ned_mps, vel, sizeof(f.vel_ned_mps));
    f.h_acc_m = 0.5f;
    f.v_acc_m = 0.8f;
    f.s_acc_mps = 0.05f;
    f.flags = MCA_FIX_VEL_NE | MCA_FIX_VEL_D | MCA_FIX_ALT;
    f.fix_type = 3u;
    return f;
}

static void test_config(void)
{
    mca_ins_config_t c;
    mca_ins_config_default(&c);
    CHECK_EQ_INT(mca_ins_config_check(&c), MCA_OK);
    mca_ins_config_fixedwing(&c);
    CHECK_EQ_INT(mca_ins_config_check(&c), MCA_OK);
    mca_ins_config_multirotor(&c);
    CHECK_EQ_INT(mca_ins_config_check(&c), MCA_OK);
    CHECK_EQ_INT(c.yaw_source, MCA_YAW_MAG);
    CHECK_EQ_INT(mca_ins_config_check(NULL), MCA_ERR_NULL);
    /* one bad field at a time */
    mca_ins_config_t b;
    mca_ins_config_default(&b);
    b.gyro_noise_rps = -1.0f;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    b.gyro_bias_tau_s = 0.5f; /* neither 0 nor >= 1 s */
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    b.gyro_bias_tau_s = 0.0f; /* random walk: allowed */
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_OK);
    mca_ins_config_default(&b);
    b.cov_dt_s = 0.2f;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    b.lever_arm_b_m[1] = NAN;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    b.yaw_source = 3u;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    b.robust.mode = 9u;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    b.att0_var_rad2 = 0.0f;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    CHECK_EQ_INT(b.robust.reject_reset_n, 0); /* the time guards replace the count guard */
    b.gnss_reset_s = 0.0f;                    /* guards off: allowed */
    b.gnss_block_reset_s = 0.0f;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_OK);
    b.gnss_reset_s = 601.0f;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    b.gnss_block_reset_s = NAN;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    b.gnss_block_reset_s = -1.0f;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    CHECK(b.gps_pos_noise_min_m == 0.0f && b.gps_vel_noise_min_mps == 0.0f); /* accuracies as given */
    b.gps_vel_noise_min_mps = -0.1f;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    b.gps_pos_noise_min_m = NAN;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    CHECK(b.gps_pos_tau_s == 0.0f); /* receiver error model off: accuracies white */
    b.gps_pos_tau_s = 60.0f;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_OK);
    const float bad_tau[] = {0.5f, -1.0f, 3601.0f, NAN, INFINITY};
    for (size_t i = 0; i < sizeof(bad_tau) / sizeof(bad_tau[0]); ++i) {
        b.gps_pos_tau_s = bad_tau[i];
        CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    }
    mca_ins_config_default(&b);
    b.gps_pos_white_m = 0.0f;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    b.gps_alt_white_m = NAN;
    CHECK_EQ_INT(mca_ins_config_check(&b), MCA_ERR_BAD_CONFIG);
    mca_ins_config_default(&b);
    b.att0_var_rad2 = 0.0f;
    /* init with a bad configuration touches nothing */
    memset(&g_ins, 0x5a, sizeof(g_ins));
    memcpy(&g_copy, &g_ins, sizeof(g_ins));
    CHECK_EQ_INT(mca_ins_init(&g_ins, &b), MCA_ERR_BAD_CONFIG);
    CHECK(memcmp(&g_ins, &g_copy, sizeof(g_ins)) == 0);
    CHECK_EQ_INT(mca_ins_init(NULL, &c), MCA_ERR_NULL);
    CHECK_EQ_INT(mca_ins_init(&g_ins, NULL), MCA_ERR_NULL);
    printf("sizeof(mca_ins_t) = %u bytes (history %u, P %u, scratch %u), sizeof(mca_ins_output_t) = %u\n",
           (unsigned)sizeof(mca_ins_t), (unsigned)sizeof(g_ins.hist), (unsigned)sizeof(g_ins.p),
           (unsigned)sizeof(g_ins.ws), (unsigned)sizeof(mca_ins_output_t));
}

static void test_static_alignment(void)
{
    mca_ins_config_t c;
    flat_config(&c);
    CHECK_EQ_INT(mca_ins_init(&g_ins, &c), MCA_OK);
    /* roll 5 deg, pitch -3 deg: f_b = C_bn [0, 0, -g] */
    const float phi = 5.0f * (float)DEG_D, th = -3.0f * (float)DEG_D;
    const float f[3] = {G_TEST * sinf(th), -G_TEST * cosf(th) * sinf(phi), -G_TEST * cosf(th) * cosf(phi)};
    const float w[3] = {0.002f, -0.001f, 0.003f};
    uint64_t t = 1000000u;
    for (int k = 0; k < 500; ++k) {
        CHECK_EQ_INT(mca_ins_imu(&g_ins, t, w, f), MCA_OK);
        t += 2500u;
    }
    mca_ins_output_t o;
    mca_ins_output(&g_ins, &o);
    CHECK((o.flags & MCA_INS_FLAG_ALIGNED) != 0u);
    CHECK((o.flags & MCA_INS_FLAG_NAV) == 0u);
    CHECK((o.flags & MCA_INS_FLAG_GPS_LOST) != 0u);
    CHECK_CLOSE(o.euler_rad[0], phi, 1e-5);
    CHECK_CLOSE(o.euler_rad[1], th, 1e-5);
    CHECK_CLOSE(o.gyro_bias_rps[2], 0.003, 1e-7); /* the still window's mean gyro */
    /* the aligned attitude then follows the gyro minus bias: no change */
    CHECK_CLOSE(o.euler_rad[2], 0.0, 1e-4);
}

/* Level flight north at 10 m/s over a flat earth, exact fixes at 5 Hz with 100 ms latency: the
 * INS must stay on the track to centimetres and keep its covariance symmetric and finite. */
static void test_straight_run(void)
{
    mca_ins_config_t c;
    flat_config(&c);
    c.init_timeout_s = 0.5f; /* moving from the start: timeout alignment */
    CHECK_EQ_INT(mca_ins_init(&g_ins, &c), MCA_OK);
    const double lat0 = 30.5, lon0 = 114.3, h = 50.0, v = 10.0;
    /* metres per degree of latitude at lat0, h (the INS integrates along the meridian) */
    const double e2 = 6.69437999014e-3, a = 6378137.0, s = sin(lat0 * DEG_D);
    const double rm = a * (1.0 - e2) / pow(1.0 - e2 * s * s, 1.5) + h;
    const float vel[3] = {(float)v, 0.0f, 0.0f};
    const float w[3] = {0.0f, 0.0f, 0.0f}, f[3] = {0.0f, 0.0f, -G_TEST};
    uint64_t t = 0u;
    int fixes = 0;
    for (int k = 1; k <= 400 * 30; ++k) {
        t = (uint64_t)k * 2500u;
        CHECK_EQ_INT(mca_ins_imu(&g_ins, t, w, f), MCA_OK);
        if (k % 80 == 40) { /* arrival 100 ms after validity */
            const uint64_t t_fix = t - 100000u;
            const double lat = lat0 + v * (double)t_fix * 1e-6 / rm / DEG_D;
            mca_gps_fix_t fx = make_fix(t_fix, lat, lon0, h, vel);
            CHECK_EQ_INT(mca_ins_gps(&g_ins, &fx), MCA_OK);
            ++fixes;
        }
    }
    mca_ins_output_t o;
    mca_ins_output(&g_ins, &o);
    CHECK((o.flags & MCA_INS_FLAG_NAV) != 0u);
    /* fixes before the (timeout) alignment are skipped, the first after it starts navigation */
    CHECK_EQ_INT(o.n_gps_skip, 3);
    CHECK_EQ_INT(o.n_gps_upd + o.n_gps_skip + 1u, fixes);
    const double north_true = v * (double)t * 1e-6;
    CHECK_CLOSE(o.pos_ned_m[0], north_true, 0.05);
    CHECK_CLOSE(o.pos_ned_m[1], 0.0, 0.05);
    CHECK_CLOSE(o.pos_ned_m[2], 0.0, 0.05);
    CHECK_CLOSE(o.vel_ned_mps[0], v, 0.01);
    CHECK_CLOSE(o.vel_ned_mps[1], 0.0, 0.01);
    CHECK(state_finite(&g_ins));
    CHECK(p_symmetric_psd_diag(&g_ins));
    CHECK(o.gps_t >= 0.0f && o.gps_m == 6u);
}

/* Free inertial east at 50 m/s across the antimeridian: the longitude wraps, the home-frame
 * position stays continuous, the offsets stay below one count. */
static void test_antimeridian(void)
{
    mca_ins_config_t c;
    flat_config(&c);
    c.init_timeout_s = 0.1f;
    CHECK_EQ_INT(mca_ins_init(&g_ins, &c), MCA_OK);
    const float w[3] = {0.0f, 0.0f, 0.0f}, f[3] = {0.0f, 0.0f, -G_TEST};
    const float vel[3] = {0.0f, 50.0f, 0.0f};
    uint64_t t = 0u;
    int k = 0;
    for (; k < 80; ++k) {
        t += 2500u;
        (void)mca_ins_imu(&g_ins, t, w, f);
    }
    mca_gps_fix_t fx = make_fix(t, 10.0, 179.9995, 0.0, vel);
    CHECK_EQ_INT(mca_ins_gps(&g_ins, &fx), MCA_OK); /* home */
    fx.t_us = t + 1u;
    CHECK_EQ_INT(mca_ins_gps(&g_ins, &fx), MCA_OK); /* start */
    float prev_e = 0.0f;
    int jumps = 0;
    for (int n = 0; n < 400 * 4; ++n) {
        t += 2500u;
        CHECK_EQ_INT(mca_ins_imu(&g_ins, t, w, f), MCA_OK);
        mca_ins_output_t o;
        mca_ins_output(&g_ins, &o);
        if (fabsf(o.pos_ned_m[1] - prev_e) > 0.2f) {
            ++jumps;
        }
        prev_e = o.pos_ned_m[1];
        CHECK(fabsf(g_ins.off_ned_m[1]) < 0.02f);
    }
    CHECK_EQ_INT(jumps, 0);
    CHECK(g_ins.lon_e7 < 0); /* crossed */
    CHECK_CLOSE(prev_e, 50.0 * 4.0, 0.2);
}

static void test_increments_match_rates(void)
{
    static mca_ins_t a, b;
    mca_ins_config_t c;
    flat_config(&c);
    c.init_timeout_s = 0.1f;
    CHECK_EQ_INT(mca_ins_init(&a, &c), MCA_OK);
    CHECK_EQ_INT(mca_ins_init(&b, &c), MCA_OK);
    const float vel[3] = {3.0f, -2.0f, 0.5f};
    uint64_t t = 0u;
    for (int k = 0; k < 400; ++k) {
        t += 2500u;
        const float w[3] = {0.1f * sinf(0.01f * (float)k), 0.05f, -0.2f};
        const float f[3] = {0.5f, -0.3f * cosf(0.02f * (float)k), -G_TEST};
        const float dth[3] = {w[0] * 0.0025f, w[1] * 0.0025f, w[2] * 0.0025f};
        const float dv[3] = {f[0] * 0.0025f, f[1] * 0.0025f, f[2] * 0.0025f};
        CHECK_EQ_INT(mca_ins_imu(&a, t, w, f), MCA_OK);
        CHECK_EQ_INT(mca_ins_imu_delta(&b, t, dth, dv), MCA_OK);
        if (k == 100) {
            mca_gps_fix_t fx = make_fix(t, 30.0, 114.0, 10.0, vel);
            CHECK_EQ_INT(mca_ins_gps(&a, &fx), MCA_OK);
            CHECK_EQ_INT(mca_ins_gps(&b, &fx), MCA_OK);
            fx.t_us = t + 1u;
            CHECK_EQ_INT(mca_ins_gps(&a, &fx), MCA_OK);
            CHECK_EQ_INT(mca_ins_gps(&b, &fx), MCA_OK);
        }
    }
    for (size_t i = 0; i < 4u; ++i) {
        CHECK_CLOSE(a.q_nb[i], b.q_nb[i], 1e-5); /* w dt / dt vs w: an ulp per sample */
    }
    for (size_t i = 0; i < 3u; ++i) {
        CHECK_CLOSE(a.vel_ned_mps[i], b.vel_ned_mps[i], 1e-4);
    }
}

static void test_error_model_structure(void)
{
    mca_ins_config_t c;
    mca_ins_config_default(&c);
    CHECK_EQ_INT(mca_ins_init(&g_ins, &c), MCA_OK);
    g_ins.lat_e7 = 450000000;
    g_ins.vel_ned_mps[0] = 10.0f;
    g_ins.vel_ned_mps[1] = 5.0f;
    static float f[MCA_INS_NX * MCA_INS_NX];
    const float fn[3] = {1.0f, 2.0f, -9.8f};
    CHECK_EQ_INT(mca_ins_error_model(&g_ins, fn, f), MCA_OK);
    const float nanv[3] = {NAN, 0.0f, 0.0f};
    CHECK_EQ_INT(mca_ins_error_model(&g_ins, nanv, f), MCA_ERR_NONFINITE);
    CHECK_EQ_INT(mca_ins_error_model(NULL, fn, f), MCA_ERR_NULL);
#define F(i, j) f[(i) * MCA_INS_NX + (j)]
    for (int i = 0; i < 3; ++i) {
        CHECK(F(i, 3 + i) == 1.0f);                   /* dr' = dv */
        CHECK(F(6 + i, 9 + i) == -1.0f);              /* phi' = -C db_g, C = I */
        CHECK(F(3 + i, 12 + i) == -1.0f);             /* dv' = -C db_a */
        CHECK_CLOSE(F(9 + i, 9 + i), -1e-3, 1e-9);    /* -1/tau_g */
    }
    /* dv' = -[f_n x] phi: (phi x f_n) */
    CHECK(F(3, 7) == fn[2] && F(3, 8) == -fn[1] && F(4, 6) == -fn[2]);
    CHECK_CLOSE(F(5, 2), 3.086e-6, 1e-12);           /* gravity gradient */
    /* transport-rate coupling of phi to dv at 45 deg */
    CHECK(F(6, 4) < 0.0f && F(7, 3) > 0.0f && F(8, 4) > 0.0f);
    CHECK_CLOSE(F(8, 4) / -F(6, 4), 1.0, 1e-5);       /* tan 45 deg */
#undef F
}

/* A navigating INS with history, for the bad-input tests. */
static uint64_t running_ins(void)
{
    mca_ins_config_t c;
    mca_ins_config_default(&c);
    c.yaw_source = MCA_YAW_NONE;
    CHECK_EQ_INT(mca_ins_init(&g_ins, &c), MCA_OK);
    const float w[3] = {0.001f, -0.002f, 0.0005f}, f[3] = {0.1f, -0.2f, -9.79f};
    const float vel[3] = {0.0f, 0.0f, 0.0f};
    uint64_t t = 1000000u;
    for (int k = 0; k < 1600; ++k) {
        t += 2500u;
        CHECK_EQ_INT(mca_ins_imu(&g_ins, t, w, f), MCA_OK);
        if (k % 80 == 79) {
            mca_gps_fix_t fx = make_fix(t - 100000u, 30.5, 114.3, 50.0, vel);
            CHECK_EQ_INT(mca_ins_gps(&g_ins, &fx), MCA_OK);
        }
    }
    CHECK(g_ins.nav && g_ins.hist_count > 0u);
    return t;
}

static void test_bad_input_leaves_state_unchanged(void)
{
    const uint64_t t = running_ins();
    memcpy(&g_copy, &g_ins, sizeof(g_ins));
    const float ok3[3] = {0.0f, 0.0f, -9.8f}, nan3[3] = {NAN, 0.0f, 0.0f}, inf3[3] = {0.0f, INFINITY, 0.0f};
    CHECK_EQ_INT(mca_ins_imu(&g_ins, t + 2500u, nan3, ok3), MCA_ERR_NONFINITE);
    CHECK_EQ_INT(mca_ins_imu(&g_ins, t + 2500u, ok3, inf3), MCA_ERR_NONFINITE);
    CHECK_EQ_INT(mca_ins_imu(&g_ins, t, ok3, ok3), MCA_ERR_TIME_BACKWARDS);
    CHECK_EQ_INT(mca_ins_imu(&g_ins, t - 1u, ok3, ok3), MCA_ERR_TIME_BACKWARDS);
    CHECK_EQ_INT(mca_ins_imu_delta(&g_ins, t + 2500u, nan3, ok3), MCA_ERR_NONFINITE);
    CHECK_EQ_INT(mca_ins_imu(NULL, t + 2500u, ok3, ok3), MCA_ERR_NULL);
    CHECK_EQ_INT(mca_ins_imu(&g_ins, t + 2500u, NULL, ok3), MCA_ERR_NULL);
    const float vel[3] = {0.0f, 0.0f, 0.0f};
    mca_gps_fix_t fx = make_fix(t - 50000u, 30.5, 114.3, 50.0, vel);
    mca_gps_fix_t bad = fx;
    bad.fix_type = 1u;
    CHECK_EQ_INT(mca_ins_gps(&g_ins, &bad), MCA_ERR_BAD_ARG);
    bad = fx;
    bad.lat_e7 = 900000001;
    CHECK_EQ_INT(mca_ins_gps(&g_ins, &bad), MCA_ERR_RANGE);
    bad = fx;
    bad.alt_mm = 200000000;
    CHECK_EQ_INT(mca_ins_gps(&g_ins, &bad), MCA_ERR_RANGE);
    bad = fx;
    bad.vel_ned_mps[2] = NAN;
    CHECK_EQ_INT(mca_ins_gps(&g_ins, &bad), MCA_ERR_NONFINITE);
    bad = fx;
    bad.t_us = g_ins.t_lastfix_us; /* repeated fix time */
    CHECK_EQ_INT(mca_ins_gps(&g_ins, &bad), MCA_ERR_TIME_BACKWARDS);
    CHECK_EQ_INT(mca_ins_gps(&g_ins, NULL), MCA_ERR_NULL);
    CHECK_EQ_INT(mca_ins_mag(&g_ins, t, nan3), MCA_ERR_NONFINITE);
    CHECK_EQ_INT(mca_ins_mag(&g_ins, t, NULL), MCA_ERR_NULL);
    CHECK(memcmp(&g_ins, &g_copy, sizeof(g_ins)) == 0);
    /* a velocity flagged absent may be NaN: not read */
    bad = fx;
    bad.vel_ned_mps[2] = NAN;
    bad.flags = MCA_FIX_VEL_NE | MCA_FIX_ALT;
    CHECK_EQ_INT(mca_ins_gps(&g_ins, &bad), MCA_OK);
    CHECK(state_finite(&g_ins));
    /* a fix older than the history (2 s of IMU later, valid just after the last fix): skipped
     * with the miss flag, nothing else changes */
    const uint64_t t_last = g_ins.t_lastfix_us;
    uint64_t t1 = t;
    for (int k = 0; k < 800; ++k) {
        t1 += 2500u;
        CHECK_EQ_INT(mca_ins_imu(&g_ins, t1, ok3, ok3), MCA_OK);
    }
    fx = make_fix(t_last + 1000u, 30.5, 114.3, 50.0, vel);
    memcpy(&g_copy, &g_ins, sizeof(g_ins));
    CHECK_EQ_INT(mca_ins_gps(&g_ins, &fx), MCA_OK);
    mca_ins_output_t o;
    mca_ins_output(&g_ins, &o);
    CHECK((o.flags & MCA_INS_FLAG_HIST_MISS) != 0u);
    CHECK_EQ_INT(o.n_gps_skip, g_copy.n_gps_skip + 1u);
    CHECK(memcmp(g_ins.p, g_copy.p, sizeof(g_ins.p)) == 0 && memcmp(g_ins.q_nb, g_copy.q_nb, sizeof(g_ins.q_nb)) == 0);
    /* a huge gap: BAD_DT, the time re-anchored and navigation stopped; attitude and biases kept */
    memcpy(&g_copy, &g_ins, sizeof(g_ins));
    CHECK_EQ_INT(mca_ins_imu(&g_ins, t1 + 3600000000ull, ok3, ok3), MCA_ERR_BAD_DT);
    CHECK(g_ins.t_imu_us == t1 + 3600000000ull && !g_ins.nav);
    g_copy.t_imu_us = g_ins.t_imu_us;
    g_copy.nav = 0u;
    CHECK(memcmp(&g_ins, &g_copy, sizeof(g_ins)) == 0);
    /* the next fix restarts navigation there */
    fx = make_fix(t1 + 3600000000ull - 1000u, 30.6, 114.3, 50.0, vel);
    CHECK_EQ_INT(mca_ins_gps(&g_ins, &fx), MCA_OK);
    mca_ins_output(&g_ins, &o);
    CHECK((o.flags & MCA_INS_FLAG_NAV) != 0u);
    CHECK_CLOSE(o.pos_ned_m[0], 11085.0, 30.0); /* 0.1 deg north of home */
    /* extreme but finite input: saturated accelerometer, 1e6 rad/s, the state stays finite */
    const float huge_w[3] = {1e6f, -1e6f, 1e6f}, huge_f[3] = {1e6f, 1e6f, -1e6f};
    uint64_t t2 = g_ins.t_imu_us;
    for (int k = 0; k < 100; ++k) {
        t2 += 2500u;
        CHECK_EQ_INT(mca_ins_imu(&g_ins, t2, huge_w, huge_f), MCA_OK);
    }
    CHECK(state_finite(&g_ins));
    mca_ins_output(&g_ins, &o);
    CHECK((o.flags & MCA_INS_FLAG_SATURATED) != 0u);
    CHECK(mca_all_finite(o.pos_ned_m, 3u) && mca_all_finite(o.p_diag, MCA_INS_NX));
    /* replay with a missing array */
    CHECK_EQ_INT(mca_ins_replay(&g_ins, NULL, 3u, NULL, 0u, NULL, 0u, NULL, NULL, NULL, NULL), MCA_ERR_NULL);
    CHECK_EQ_INT(mca_ins_replay(NULL, NULL, 0u, NULL, 0u, NULL, 0u, NULL, NULL, NULL, NULL), MCA_ERR_NULL);
}

/* The straight and level run north at STRAIGHT_V m/s of the guard and hold-out tests: the flat
 * configuration in fuzzy mode, the IMU samples, and the fix at t_fix_us on the track moved north_m
 * north, with dv_mps more north velocity. */
#define STRAIGHT_V 10.0
static void straight_config(mca_ins_config_t *c)
{
    flat_config(c);
    c->init_timeout_s = 0.5f;
    c->robust.mode = MCA_ROBUST_FUZZY;
}

/* IMU sample k (400 Hz, still); 1 when a fix is due (5 Hz, 100 ms old), its time in *t_fix_us */
static int straight_step(int k, uint64_t *t_fix_us)
{
    const float w[3] = {0.0f, 0.0f, 0.0f}, f[3] = {0.0f, 0.0f, -G_TEST};
    const uint64_t t = (uint64_t)k * 2500u;
    CHECK_EQ_INT(mca_ins_imu(&g_ins, t, w, f), MCA_OK);
    *t_fix_us = t - 100000u;
    return k % 80 == 40;
}

static mca_gps_fix_t straight_fix(uint64_t t_fix_us, double north_m, float dv_mps)
{
    const double lat0 = 30.5, lon0 = 114.3, h = 50.0;
    const double e2 = 6.69437999014e-3, a = 6378137.0, s = sin(lat0 * DEG_D);
    const double rm = a * (1.0 - e2) / pow(1.0 - e2 * s * s, 1.5) + h;
    const double north = STRAIGHT_V * (double)t_fix_us * 1e-6 + north_m;
    const float vel[3] = {(float)STRAIGHT_V + dv_mps, 0.0f, 0.0f};
    return make_fix(t_fix_us, lat0 + north / rm / DEG_D, lon0, h, vel);
}

/* At the end of the 40 s run: the state finite, P symmetric with a non-negative diagonal, and
 * the INS on the track. */
static void straight_back_on_track(void)
{
    CHECK(state_finite(&g_ins));
    CHECK(p_symmetric_psd_diag(&g_ins));
    mca_ins_output_t o;
    mca_ins_output(&g_ins, &o);
    CHECK_CLOSE(o.pos_ned_m[0], STRAIGHT_V * 40.0, 1.0);
    CHECK_CLOSE(o.vel_ned_mps[0], STRAIGHT_V, 0.05);
}

/* Lock-up guards (ALGORITHMS.md 10, GNSS update step 5), fuzzy mode, straight and level north at
 * 10 m/s: a position-only fault longer than gnss_block_reset_s (velocity fused) resets the
 * position to the fix; a position and velocity fault longer than gnss_reset_s (nothing fused)
 * resets both; a reset leaves the state's covariance rows R on the diagonal, zero elsewhere. */
static void test_lockup_guards_reset_to_the_fix(void)
{
    mca_ins_config_t c;
    straight_config(&c);
    c.gnss_reset_s = 2.0f;
    c.gnss_block_reset_s = 4.0f;
    CHECK_EQ_INT(mca_ins_init(&g_ins, &c), MCA_OK);
    int resets_pos = 0, resets_both = 0, rejected = 0;
    for (int k = 1; k <= 400 * 40; ++k) {
        uint64_t t_fix;
        if (!straight_step(k, &t_fix)) {
            continue;
        }
        const double ts = (double)t_fix * 1e-6;
        /* 12-18 s: fix 30 m north (velocity good); 26-30 s: 30 m north and 3 m/s north */
        const int pos_fault = (ts >= 12.0 && ts < 18.0) || (ts >= 26.0 && ts < 30.0);
        const int vel_fault = ts >= 26.0 && ts < 30.0;
        mca_gps_fix_t fx = straight_fix(t_fix, pos_fault ? 30.0 : 0.0, vel_fault ? 3.0f : 0.0f);
        CHECK_EQ_INT(mca_ins_gps(&g_ins, &fx), MCA_OK);
        mca_ins_output_t o;
        mca_ins_output(&g_ins, &o);
        rejected += (o.flags & MCA_INS_FLAG_REJECTED) != 0u;
        if ((o.flags & MCA_INS_FLAG_RESET) != 0u) {
            /* the reset rows' covariance: R on the diagonal, nothing else in row and column */
            const float r_p = fx.h_acc_m * fx.h_acc_m;
            CHECK_CLOSE(g_ins.p[0], r_p, 1e-6 * r_p + 1e-4); /* propagated since the fix: P grows */
            for (size_t j = 1; j < MCA_INS_NX; ++j) {
                CHECK(fabsf(g_ins.p[j]) < 1e-3f && fabsf(g_ins.p[j * MCA_INS_NX]) < 1e-3f);
            }
            const int both = ts >= 26.0 && ts < 30.5;
            /* last fused just before each fault: the guard fires on the first fix past its time */
            resets_pos += (ts >= 12.0 + 4.0 && ts < 12.0 + 4.5) ? 1 : 0;
            resets_both += (both && ts >= 26.0 + 2.0 && ts < 26.0 + 2.5) ? 1 : 0;
            if (both && ts < 30.0) {
                CHECK_CLOSE(g_ins.vel_ned_mps[0], STRAIGHT_V + 3.0, 0.05); /* the velocity took the fix */
            }
        }
    }
    CHECK_EQ_INT(resets_pos, 1);
    CHECK_EQ_INT(resets_both, 1);
    CHECK(rejected > 40);
    straight_back_on_track(); /* 10 s after the last fault */
}

/* The receiver error model (ALGORITHMS.md 10, GNSS update step 3) and the hold-outs (step 5) on a
 * straight run: R is the white part and the rest of h_acc^2 its growth rate (the growth itself
 * against its closed form: tests/python/test_ins.py), and a 6 s fault of both position (20 m) and
 * velocity (2 m/s) is rejected from its second fix on with both blocks out, then the clean fixes
 * are taken again. */
static void test_receiver_model_and_hold_outs(void)
{
    mca_ins_config_t c;
    straight_config(&c);
    c.gps_pos_tau_s = 60.0f;
    c.gps_pos_white_m = 0.3f;
    c.gps_alt_white_m = 0.5f;
    CHECK_EQ_INT(mca_ins_init(&g_ins, &c), MCA_OK);
    const float c2_h = 0.5f * 0.5f - 0.3f * 0.3f; /* make_fix: h_acc 0.5 m */
    double t_out = -1.0; /* time of the first fix with both blocks out */
    int faulty = 0, faulty_out = 0, late_rejected = 0, checked_r = 0;
    for (int k = 1; k <= 400 * 40; ++k) {
        uint64_t t_fix;
        if (!straight_step(k, &t_fix)) {
            continue;
        }
        const double ts = (double)t_fix * 1e-6;
        const int fault = ts >= 20.0 && ts < 26.0;
        mca_gps_fix_t fx = straight_fix(t_fix, fault ? 20.0 : 0.0, fault ? 2.0f : 0.0f);
        CHECK_EQ_INT(mca_ins_gps(&g_ins, &fx), MCA_OK);
        mca_ins_output_t o;
        mca_ins_output(&g_ins, &o);
        if (g_ins.nav && !fault && ts > 5.0 && !checked_r) {
            /* the rows' R is the white part; the rest of h_acc^2 drives the growth */
            CHECK_CLOSE(g_ins.upd_r[0], 0.09f, 1e-6);
            CHECK_CLOSE(g_ins.rx_q[0], 2.0f * c2_h / 60.0f, 1e-7);
            checked_r = 1;
        }
        if (fault) {
            ++faulty;
            if (ts >= 20.1) {
                const int out = (o.flags & MCA_INS_FLAG_REJECTED) != 0u && g_ins.vel_out && g_ins.pos_out;
                faulty_out += out;
                t_out = (out && t_out < 0.0) ? ts : t_out;
            }
        } else if (ts >= 27.0) {
            late_rejected += (o.flags & MCA_INS_FLAG_REJECTED) != 0u;
        }
    }
    CHECK(checked_r);
    CHECK(faulty >= 29);
    /* the first faulty fix is applied (the three-threshold rule lets one through); from the
     * second on, which raises both alarms, both blocks are out */
    CHECK(t_out > 20.1 && t_out < 20.3);
    CHECK_EQ_INT(faulty_out, faulty - 1);
    CHECK_EQ_INT(late_rejected, 0);
    straight_back_on_track();
}

int main(void)
{
    test_config();
    test_static_alignment();
    test_straight_run();
    test_antimeridian();
    test_increments_match_rates();
    test_error_model_structure();
    test_bad_input_leaves_state_unchanged();
    test_lockup_guards_reset_to_the_fix();
    test_receiver_model_and_hold_outs();
    TEST_MAIN_END();
}

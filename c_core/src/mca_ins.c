/* Loosely-coupled INS (DESIGN.md 6, docs/ALGORITHMS.md 10). See mca_ins.h. */
#include "mcahrs/mca_ins.h"
#include "mca_cold.h"

#include <math.h>
#include <string.h>

#define NX MCA_INS_NX
#define DEG 0.0174532925199433f
#define G0 9.80665f
#define OMEGA_E 7.292115e-5f   /* earth rotation rate, rad/s */
#define WGS84_A 6378137.0f
#define WGS84_E2 6.69437999014e-3f
#define E7_TO_RAD 1.74532925199433e-9f
#define GRAV_GRAD 3.086e-6f    /* -dg/dh of the normal gravity (ALGORITHMS.md 6), 1/s^2 */
#define COS_FLOOR 0.01f        /* polar limit: cos L floored where it divides */
#define LAT_MAX_E7 899000000   /* polar limit: |L| <= 89.9 deg */
#define ALT_MIN_MM (-1000000)  /* section 6 range */
#define ALT_MAX_MM 100000000
#define MAG_MAX_TILT (80.0f * DEG)
#define STILL_SPEED 0.5f       /* GNSS ground speed below which a still window may re-level, m/s */
#define HALF_SPAN_US 3600000000LL /* 360 deg of longitude in 1e-7 deg */

/* compile-time checks: the propagation needs three 15 x 15 matrices of the update's scratch,
 * and a GNSS update has at most MCA_MEAS_MAX rows */
typedef char mca_ins_ws_fits_predict[(MCA_INS_WS_LEN >= 3 * NX * NX) ? 1 : -1];
typedef char mca_ins_rows_fit[(MCA_MEAS_MAX >= 6) ? 1 : -1];

/* ------------------------------------------------------------------------ configuration */

MCA_COLD void mca_ins_config_default(mca_ins_config_t *c)
{
    memset(c, 0, sizeof(*c));
    c->gyro_noise_rps = 3e-4f;
    c->accel_noise_mps2 = 3e-3f;
    c->gyro_bias_rw_rps2 = 2e-5f;
    c->accel_bias_rw_mps3 = 2e-4f;
    c->gyro_bias_tau_s = 1000.0f;
    c->accel_bias_tau_s = 1000.0f;
    c->att0_var_rad2 = (2.0f * DEG) * (2.0f * DEG);
    c->yaw0_var_rad2 = (30.0f * DEG) * (30.0f * DEG);
    c->yaw0_rad = 0.0f;
    c->gyro_bias0_var_rps2 = (0.5f * DEG) * (0.5f * DEG);
    c->gyro_bias_still_var_rps2 = (0.05f * DEG) * (0.05f * DEG);
    c->att_still_var_rad2 = (0.2f * DEG) * (0.2f * DEG);
    c->accel_bias0_var_mps4 = 0.1f * 0.1f;
    c->vel0_var_m2ps2 = 1.0f;
    c->cov_dt_s = 0.01f;
    c->earth_rate = 1u;
    c->transport_rate = 1u;
    c->yaw_source = MCA_YAW_COG;
    c->gravity_mps2 = 0.0f;
    c->imu_dt_max_s = 0.1f;
    c->init_still_s = 1.0f;
    c->init_gyro_still_rps = 0.05f;
    c->init_acc_still_mps2 = 0.5f;
    c->init_timeout_s = 5.0f;
    c->accel_sat_mps2 = 156.9f;
    c->gps_timeout_s = 1.5f;
    c->gps_pos_sigma_m = 2.5f;
    c->gps_alt_sigma_m = 5.0f;
    c->gps_vel_sigma_mps = 0.2f;
    c->mag_declination_rad = 0.0f;
    c->mag_yaw_sigma_rad = 0.05f;
    c->mag_period_s = 0.1f;
    c->cog_min_speed_mps = 3.0f;
    c->cog_sigma0_rad = 0.05f;
    c->gps_pos_noise_min_m = 0.0f; /* the receiver's accuracies as given (see the table) */
    c->gps_vel_noise_min_mps = 0.0f;
    c->gnss_reset_s = 30.0f;
    c->gnss_block_reset_s = 120.0f;
    c->gps_pos_tau_s = 0.0f; /* off: the receiver's accuracies taken as white */
    c->gps_pos_white_m = 0.3f;
    c->gps_alt_white_m = 0.5f;
    mca_robust_config_default(&c->robust);
    /* the INS dead-reckons on its IMU through rejected fixes: the time guards above replace the
     * count guard, which the CS filter needs (ALGORITHMS.md 10, GNSS update step 5) */
    c->robust.reject_reset_n = 0u;
}

MCA_COLD void mca_ins_config_fixedwing(mca_ins_config_t *c)
{
    mca_ins_config_default(c);
    c->cog_min_speed_mps = 5.0f;
}

MCA_COLD void mca_ins_config_multirotor(mca_ins_config_t *c)
{
    mca_ins_config_default(c);
    c->yaw_source = MCA_YAW_MAG; /* a multirotor does not move along its nose */
}

/* a Gauss-Markov time: 0 (random walk) or >= 1 s */
static int tau_ok(float v)
{
    return isfinite(v) && (v >= 1.0f || (v >= 0.0f && v <= 0.0f));
}

MCA_COLD mca_status_t mca_ins_config_check(const mca_ins_config_t *c)
{
    if (c == NULL) {
        return MCA_ERR_NULL;
    }
    int ok = mca_nonneg(c->gyro_noise_rps) && mca_nonneg(c->accel_noise_mps2) &&
             mca_nonneg(c->gyro_bias_rw_rps2) && mca_nonneg(c->accel_bias_rw_mps3) && tau_ok(c->gyro_bias_tau_s) &&
             tau_ok(c->accel_bias_tau_s) && mca_positive(c->att0_var_rad2) && mca_positive(c->yaw0_var_rad2) &&
             isfinite(c->yaw0_rad) && mca_positive(c->gyro_bias0_var_rps2) &&
             mca_positive(c->gyro_bias_still_var_rps2) && mca_positive(c->att_still_var_rad2) &&
             mca_positive(c->accel_bias0_var_mps4) && mca_positive(c->vel0_var_m2ps2) && mca_nonneg(c->cov_dt_s) &&
             c->cov_dt_s <= 0.1f && c->earth_rate <= 1u && c->transport_rate <= 1u && c->yaw_source <= MCA_YAW_COG &&
             mca_nonneg(c->gravity_mps2) && mca_positive(c->imu_dt_max_s) && mca_positive(c->init_still_s) &&
             mca_nonneg(c->init_gyro_still_rps) && mca_nonneg(c->init_acc_still_mps2) &&
             mca_positive(c->init_timeout_s) && mca_positive(c->accel_sat_mps2) && mca_positive(c->gps_timeout_s) &&
             mca_positive(c->gps_pos_sigma_m) && mca_positive(c->gps_alt_sigma_m) &&
             mca_positive(c->gps_vel_sigma_mps) && isfinite(c->mag_declination_rad) &&
             mca_positive(c->mag_yaw_sigma_rad) && mca_nonneg(c->mag_period_s) && mca_nonneg(c->cog_min_speed_mps) &&
             mca_positive(c->cog_sigma0_rad) && mca_nonneg(c->gps_pos_noise_min_m) &&
             mca_nonneg(c->gps_vel_noise_min_mps) && mca_nonneg(c->gnss_reset_s) && c->gnss_reset_s <= 600.0f &&
             mca_nonneg(c->gnss_block_reset_s) && c->gnss_block_reset_s <= 600.0f && tau_ok(c->gps_pos_tau_s) &&
             c->gps_pos_tau_s <= 3600.0f && mca_positive(c->gps_pos_white_m) && mca_positive(c->gps_alt_white_m) &&
             mca_robust_config_check(&c->robust) == MCA_OK;
    /* durations become uint32 microseconds (ALGORITHMS.md 8, Times): keep them far below 71 min */
    ok = ok && c->imu_dt_max_s <= 10.0f && c->init_still_s <= 600.0f && c->init_timeout_s <= 600.0f &&
         c->gps_timeout_s <= 600.0f && c->mag_period_s <= 600.0f;
    for (size_t i = 0; i < 3u; ++i) {
        ok = ok && isfinite(c->lever_arm_b_m[i]) && fabsf(c->lever_arm_b_m[i]) <= 10.0f;
    }
    return ok ? MCA_OK : MCA_ERR_BAD_CONFIG;
}

MCA_COLD mca_status_t mca_ins_init(mca_ins_t *ins, const mca_ins_config_t *cfg)
{
    if (ins == NULL || cfg == NULL) {
        return MCA_ERR_NULL;
    }
    const mca_status_t st = mca_ins_config_check(cfg);
    if (st != MCA_OK) {
        return st;
    }
    memset(ins, 0, sizeof(*ins));
    ins->cfg = *cfg;
    ins->q_nb[0] = 1.0f;
    ins->last_gps_t = NAN; /* no update yet */
    mca_robust_state_init(&ins->rs);
    mca_robust_state_init(&ins->rs_v);
    return MCA_OK;
}

/* ------------------------------------------------------------------------ small helpers */

/* A configured duration in integer microseconds (ALGORITHMS.md 8, Times). */
static uint32_t us(float s)
{
    return (uint32_t)(s * 1e6f + 0.5f);
}

/* Seconds from a to b (b >= a), saturating at 71 minutes (uint32 us). */
static float span_s(uint64_t a, uint64_t b)
{
    const uint64_t d = b - a;
    return (float)(d > (uint64_t)UINT32_MAX ? UINT32_MAX : (uint32_t)d) * 1e-6f;
}

static float norm3(const float v[3])
{
    return sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

static void cross3(float c[3], const float a[3], const float b[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static void mat3_vec(float y[3], const float m[9], const float x[3])
{
    for (size_t i = 0; i < 3u; ++i) {
        y[i] = m[i * 3u] * x[0] + m[i * 3u + 1u] * x[1] + m[i * 3u + 2u] * x[2];
    }
}

/* s * [a x] into the 3 x 3 block of the NX x NX matrix m at (r0, c0). */
static void put_skew(float *m, size_t r0, size_t c0, const float a[3], float s)
{
    float *b = &m[r0 * NX + c0];
    b[0] = 0.0f;
    b[1] = -s * a[2];
    b[2] = s * a[1];
    b[NX] = s * a[2];
    b[NX + 1u] = 0.0f;
    b[NX + 2u] = -s * a[0];
    b[2u * NX] = -s * a[1];
    b[2u * NX + 1u] = s * a[0];
    b[2u * NX + 2u] = 0.0f;
}

/* s * M (3 x 3 row-major) into the block at (r0, c0). */
static void put_mat3(float *m, size_t r0, size_t c0, const float a[9], float s)
{
    for (size_t i = 0; i < 3u; ++i) {
        for (size_t j = 0; j < 3u; ++j) {
            m[(r0 + i) * NX + c0 + j] = s * a[i * 3u + j];
        }
    }
}

/* q = p (x) q, normalised (p applied on the left: a navigation-frame rotation). */
static void quat_left(float q[4], const float p[4])
{
    float r[4];
    mca_quat_mul(r, p, q);
    mca_quat_normalize(r);
    memcpy(q, r, sizeof(r));
}

static float yaw_of(const float q[4])
{
    float e[3];
    mca_quat_to_euler(e, q);
    return e[2];
}

/* ------------------------------------------------------------------------ geodesy of the position */

/* Latitude, height and the quantities derived from them (ALGORITHMS.md 10, step 1). */
typedef struct {
    float s, c;     /**< sin L, cos L floored at COS_FLOOR */
    float tan_l;    /**< s / c */
    float h;        /**< ellipsoidal height, m */
    float rm_h;     /**< R_M + h */
    float rn_h;     /**< R_N + h */
    float root;     /**< sqrt(1 - e2 s^2) */
} ins_frame_t;

static void frame_of(const mca_ins_t *ins, ins_frame_t *fr)
{
    /* latitude in rad from 1e-7 deg, split so the float product keeps its precision */
    const int32_t whole = ins->lat_e7 / 10000000;
    const int32_t frac = ins->lat_e7 - whole * 10000000;
    const float lat = (float)whole * DEG + (float)frac * E7_TO_RAD;
    float s, c;
    mca_sincosf(lat, &s, &c);
    fr->s = s;
    fr->c = c < COS_FLOOR ? COS_FLOOR : c;
    fr->tan_l = s / fr->c;
    fr->h = (float)ins->alt_mm * 1e-3f - ins->off_ned_m[2];
    fr->root = sqrtf(1.0f - WGS84_E2 * s * s);
    const float rn = WGS84_A / fr->root;
    fr->rn_h = rn + fr->h;
    fr->rm_h = rn * (1.0f - WGS84_E2) / (fr->root * fr->root) + fr->h;
}

static float gravity_of(const mca_ins_t *ins, const ins_frame_t *fr)
{
    if (ins->cfg.gravity_mps2 > 0.0f) {
        return ins->cfg.gravity_mps2;
    }
    /* ALGORITHMS.md 6, Somigliana with the free-air term */
    return 9.7803253359f * (1.0f + 0.00193185265241f * fr->s * fr->s) / fr->root - GRAV_GRAD * fr->h;
}

/* Earth rate and transport rate in NED (0 where switched off). */
static void rates_of(const mca_ins_t *ins, const ins_frame_t *fr, float w_ie[3], float w_en[3])
{
    memset(w_ie, 0, 3u * sizeof(float));
    memset(w_en, 0, 3u * sizeof(float));
    if (ins->cfg.earth_rate) {
        w_ie[0] = OMEGA_E * fr->c;
        w_ie[2] = -OMEGA_E * fr->s;
    }
    if (ins->cfg.transport_rate) {
        const float *v = ins->vel_ned_mps;
        w_en[0] = v[1] / fr->rn_h;
        w_en[1] = -v[0] / fr->rm_h;
        w_en[2] = -v[1] * fr->tan_l / fr->rn_h;
    }
}

/* round(x) as int64 with |x| clamped to 1e9 (an absurd offset cannot overflow anything). */
static int64_t round_counts(float x)
{
    const float lim = 1e9f;
    x = x > lim ? lim : (x < -lim ? -lim : x);
    return (int64_t)(x >= 0.0f ? x + 0.5f : x - 0.5f);
}

/* Fold the metre offsets into the integer position (ALGORITHMS.md 10, Position in float32), with
 * the radii of fr. Keeps |off| below about one count; applies the polar and height clamps. */
static void fold(mca_ins_t *ins, const ins_frame_t *fr)
{
    const float m_lat = fr->rm_h * E7_TO_RAD;
    const float m_lon = fr->rn_h * fr->c * E7_TO_RAD;
    const int64_t kn = round_counts(ins->off_ned_m[0] / m_lat);
    const int64_t ke = round_counts(ins->off_ned_m[1] / m_lon);
    const int64_t kd = round_counts(ins->off_ned_m[2] * 1000.0f);
    ins->off_ned_m[0] -= (float)(int32_t)kn * m_lat;
    ins->off_ned_m[1] -= (float)(int32_t)ke * m_lon;
    ins->off_ned_m[2] -= (float)(int32_t)kd * 1e-3f;
    int64_t lat = (int64_t)ins->lat_e7 + kn;
    if (lat > LAT_MAX_E7 || lat < -LAT_MAX_E7) {
        lat = lat > 0 ? LAT_MAX_E7 : -LAT_MAX_E7;
        ins->off_ned_m[0] = 0.0f;
    }
    /* longitude into [-180, 180) deg: one modulo, no loop */
    int64_t lon = ((int64_t)ins->lon_e7 + ke + HALF_SPAN_US / 2) % HALF_SPAN_US;
    lon = (lon < 0 ? lon + HALF_SPAN_US : lon) - HALF_SPAN_US / 2;
    int64_t alt = (int64_t)ins->alt_mm - kd;
    if (alt > ALT_MAX_MM || alt < ALT_MIN_MM) {
        alt = alt > 0 ? ALT_MAX_MM : ALT_MIN_MM;
        ins->off_ned_m[2] = 0.0f;
    }
    ins->lat_e7 = (int32_t)lat;
    ins->lon_e7 = (int32_t)lon;
    ins->alt_mm = (int32_t)alt;
}

/* Home NED of the current position (section 6 of the integers plus the offsets). */
static void pos_home_ned(const mca_ins_t *ins, float r[3])
{
    if (mca_geo_to_ned(&ins->home, ins->lat_e7, ins->lon_e7, ins->alt_mm, r) != MCA_OK) {
        memset(r, 0, 3u * sizeof(float)); /* unreachable: fold keeps the position in range */
    }
    for (size_t i = 0; i < 3u; ++i) {
        r[i] += ins->off_ned_m[i];
    }
}

/* ------------------------------------------------------------------------ covariance */

static void error_model(const mca_ins_t *ins, const float f_n[3], float *f)
{
    ins_frame_t fr;
    frame_of(ins, &fr);
    float w_ie[3], w_en[3];
    rates_of(ins, &fr, w_ie, w_en);
    const float w_cor[3] = {2.0f * w_ie[0] + w_en[0], 2.0f * w_ie[1] + w_en[1], 2.0f * w_ie[2] + w_en[2]};
    const float w_in[3] = {w_ie[0] + w_en[0], w_ie[1] + w_en[1], w_ie[2] + w_en[2]};
    float c[9];
    mca_quat_to_dcm(c, ins->q_nb);
    memset(f, 0, NX * NX * sizeof(float));
    for (size_t i = 0; i < 3u; ++i) {
        f[(MCA_INS_DR + i) * NX + MCA_INS_DV + i] = 1.0f;
    }
    if (!(ins->cfg.gravity_mps2 > 0.0f)) {
        f[(MCA_INS_DV + 2u) * NX + MCA_INS_DR + 2u] = GRAV_GRAD;
    }
    put_skew(f, MCA_INS_DV, MCA_INS_DV, w_cor, -1.0f);
    put_skew(f, MCA_INS_DV, MCA_INS_PHI, f_n, -1.0f);
    put_mat3(f, MCA_INS_DV, MCA_INS_BA, c, -1.0f);
    if (ins->cfg.transport_rate) {
        f[(MCA_INS_PHI + 0u) * NX + MCA_INS_DV + 1u] = -1.0f / fr.rn_h;
        f[(MCA_INS_PHI + 1u) * NX + MCA_INS_DV + 0u] = 1.0f / fr.rm_h;
        f[(MCA_INS_PHI + 2u) * NX + MCA_INS_DV + 1u] = fr.tan_l / fr.rn_h;
    }
    put_skew(f, MCA_INS_PHI, MCA_INS_PHI, w_in, -1.0f);
    put_mat3(f, MCA_INS_PHI, MCA_INS_BG, c, -1.0f);
    const float tg = ins->cfg.gyro_bias_tau_s, ta = ins->cfg.accel_bias_tau_s;
    for (size_t i = 0; i < 3u; ++i) {
        f[(MCA_INS_BG + i) * (NX + 1u)] = tg > 0.0f ? -1.0f / tg : 0.0f;
        f[(MCA_INS_BA + i) * (NX + 1u)] = ta > 0.0f ? -1.0f / ta : 0.0f;
    }
}

mca_status_t mca_ins_error_model(const mca_ins_t *ins, const float f_n[3], float *f_out)
{
    if (ins == NULL || f_n == NULL || f_out == NULL) {
        return MCA_ERR_NULL;
    }
    if (!mca_all_finite(f_n, 3u)) {
        return MCA_ERR_NONFINITE;
    }
    error_model(ins, f_n, f_out);
    return MCA_OK;
}

/* P = Phi P Phi^T + Qd over t_s with the NED specific force f_n (ALGORITHMS.md 10, Discretisation).
 *
 * Block-sparse form. In 3 x 3 blocks [dr, dv, phi, b_g, b_a] (indices 0..4), A = F T has the
 * blocks of the table of section 10 only:
 *   row dr: dv          row dv: dr, dv, phi, b_a     row phi: dv, phi, b_g
 *   row b_g: b_g        row b_a: b_a
 * so Phi = I + A + A^2 / 2 has (I, A and the blocks reached by A^2)
 *   row dr: dr (diagonal: I + diag(0, 0, T^2 g'/2)), dv, phi, b_a       (Phi_dr,bg = 0)
 *   row dv, row phi: all five blocks
 *   row b_g: (1 + a + a^2/2) I, a = -T/tau_g; row b_a: likewise with tau_a (scalar blocks).
 * A^2 is formed block-wise over the nonzero blocks only, S = Phi P over Phi's nonzero blocks
 * (the diagonal ones as diagonals; of the bias rows only what the upper triangle reads), then
 * Phi P Phi^T = S Phi^T on the upper block triangle only (upper elements of the diagonal
 * blocks), Qd added there and the result mirrored, so P stays exactly symmetric (the
 * (P + P^T)/2 of the spec is the identity on it).
 * Scratch: ws[0..225) A, ws[225..450) Phi (only its nonzero blocks are written or read),
 * ws[450..675) S = Phi P. */
#define NB 5u /* 3 x 3 blocks per side */
#define BIT(b) (1u << (b))
/* nonzero blocks of F (A) by block row */
static const uint8_t F_NZ[NB] = {BIT(1), BIT(0) | BIT(1) | BIT(2) | BIT(4), BIT(1) | BIT(2) | BIT(3), BIT(3), BIT(4)};
/* nonzero blocks of Phi by block row; Phi_DIAG: the diagonal ones (dr,dr; b_g,b_g; b_a,b_a) */
static const uint8_t PHI_NZ[NB] = {BIT(0) | BIT(1) | BIT(2) | BIT(4), 0x1Fu, 0x1Fu, BIT(3), BIT(4)};
#define PHI_DIAG(i, k) ((i) == (k) && ((i) == 0u || (i) >= 3u))

/* first element of block (bi, bj) of a 15 x 15 row-major matrix */
static float *blk(float *m, size_t bi, size_t bj)
{
    return m + 3u * bi * NX + 3u * bj;
}

static const float *cblk(const float *m, size_t bi, size_t bj)
{
    return m + 3u * bi * NX + 3u * bj;
}

/* C += A B, 3 x 3 blocks with row stride NX */
static void mac3(float *c, const float *a, const float *b)
{
    for (size_t r = 0; r < 3u; ++r) {
        for (size_t j = 0; j < 3u; ++j) {
            float s = c[r * NX + j];
            for (size_t k = 0; k < 3u; ++k) {
                s += a[r * NX + k] * b[k * NX + j];
            }
            c[r * NX + j] = s;
        }
    }
}

/* C += A B^T, 3 x 3 blocks with row stride NX (B diagonal when b_diag); upper: only j >= r */
static void mac3_bt(float *c, const float *a, const float *b, int b_diag, int upper)
{
    for (size_t r = 0; r < 3u; ++r) {
        for (size_t j = upper ? r : 0u; j < 3u; ++j) {
            float s = c[r * NX + j];
            if (b_diag) {
                s += a[r * NX + j] * b[j * NX + j];
            } else {
                for (size_t k = 0; k < 3u; ++k) {
                    s += a[r * NX + k] * b[j * NX + k];
                }
            }
            c[r * NX + j] = s;
        }
    }
}

static void cov_propagate(mca_ins_t *ins, float t_s, const float f_n[3])
{
    float *a = ins->ws, *phi = ins->ws + NX * NX, *sp = ins->ws + 2u * NX * NX;
    float *p = ins->p;
    error_model(ins, f_n, a);
    /* A = F T and Phi = I + A + A^2 / 2 on the nonzero blocks */
    for (size_t bi = 0; bi < NB; ++bi) {
        for (size_t bj = 0; bj < NB; ++bj) {
            if ((F_NZ[bi] & BIT(bj)) != 0u) {
                float *ab = blk(a, bi, bj);
                for (size_t r = 0; r < 3u; ++r) {
                    for (size_t j = 0; j < 3u; ++j) {
                        ab[r * NX + j] *= t_s;
                    }
                }
            }
        }
    }
    for (size_t bi = 0; bi < NB; ++bi) {
        for (size_t bj = 0; bj < NB; ++bj) {
            if ((PHI_NZ[bi] & BIT(bj)) != 0u) {
                float *pb = blk(phi, bi, bj);
                for (size_t r = 0; r < 3u; ++r) {
                    memset(&pb[r * NX], 0, 3u * sizeof(float));
                }
            }
        }
        for (size_t bk = 0; bk < NB; ++bk) { /* (A^2)_ij = sum_k A_ik A_kj */
            if ((F_NZ[bi] & BIT(bk)) == 0u) {
                continue;
            }
            for (size_t bj = 0; bj < NB; ++bj) {
                if ((F_NZ[bk] & BIT(bj)) != 0u) {
                    mac3(blk(phi, bi, bj), cblk(a, bi, bk), cblk(a, bk, bj));
                }
            }
        }
        for (size_t bj = 0; bj < NB; ++bj) {
            if ((PHI_NZ[bi] & BIT(bj)) != 0u) {
                float *pb = blk(phi, bi, bj);
                const float *ab = cblk(a, bi, bj);
                for (size_t r = 0; r < 3u; ++r) {
                    for (size_t j = 0; j < 3u; ++j) {
                        pb[r * NX + j] = ab[r * NX + j] + 0.5f * pb[r * NX + j];
                    }
                }
                if (bi == bj) {
                    for (size_t r = 0; r < 3u; ++r) {
                        pb[r * (NX + 1u)] += 1.0f;
                    }
                }
            }
        }
    }
    /* S = Phi P, block row by block row over Phi's nonzero blocks (rows of P scaled and added);
     * of the bias rows only the columns the upper triangle reads (block column >= block row) */
    memset(sp, 0, NX * NX * sizeof(float));
    for (size_t bi = 0; bi < NB; ++bi) {
        const size_t j0 = (bi >= 3u) ? 3u * bi : 0u;
        for (size_t bk = 0; bk < NB; ++bk) {
            if ((PHI_NZ[bi] & BIT(bk)) == 0u) {
                continue;
            }
            const float *pb = cblk(phi, bi, bk);
            for (size_t r = 0; r < 3u; ++r) {
                float *srow = &sp[(3u * bi + r) * NX];
                for (size_t k = 0; k < 3u; ++k) {
                    if (PHI_DIAG(bi, bk) && k != r) {
                        continue;
                    }
                    const float coef = pb[r * NX + k];
                    const float *prow = &p[(3u * bk + k) * NX];
                    for (size_t j = j0; j < NX; ++j) {
                        srow[j] += coef * prow[j];
                    }
                }
            }
        }
    }
    /* upper block triangle of S Phi^T into P */
    for (size_t bi = 0; bi < NB; ++bi) {
        for (size_t bj = bi; bj < NB; ++bj) {
            float *pb = blk(p, bi, bj);
            for (size_t r = 0; r < 3u; ++r) {
                memset(&pb[r * NX], 0, 3u * sizeof(float));
            }
            for (size_t bk = 0; bk < NB; ++bk) {
                if ((PHI_NZ[bj] & BIT(bk)) != 0u) {
                    mac3_bt(pb, cblk(sp, bi, bk), cblk(phi, bj, bk), PHI_DIAG(bj, bk), bi == bj);
                }
            }
        }
    }
    /* Qd = Qc T + (F Qc + Qc F^T) T^2 / 2 with Qc diagonal: (A_ij qc_j + qc_i A_ji) T / 2,
     * on the upper triangle where A_ij or A_ji is nonzero */
    const mca_ins_config_t *c = &ins->cfg;
    const float s = ins->rs.q_scale; /* AKF (1 in the other modes) */
    float qc[NX];
    for (size_t i = 0; i < 3u; ++i) {
        qc[MCA_INS_DR + i] = 0.0f;
        qc[MCA_INS_DV + i] = s * c->accel_noise_mps2 * c->accel_noise_mps2;
        qc[MCA_INS_PHI + i] = s * c->gyro_noise_rps * c->gyro_noise_rps;
        qc[MCA_INS_BG + i] = s * c->gyro_bias_rw_rps2 * c->gyro_bias_rw_rps2;
        qc[MCA_INS_BA + i] = s * c->accel_bias_rw_mps3 * c->accel_bias_rw_mps3;
    }
    for (size_t bi = 0; bi < NB; ++bi) {
        for (size_t bj = bi; bj < NB; ++bj) {
            if (bi != bj && ((F_NZ[bi] & BIT(bj)) | (F_NZ[bj] & BIT(bi))) == 0u) {
                continue;
            }
            for (size_t r = 0; r < 3u; ++r) {
                const size_t i = 3u * bi + r;
                for (size_t j = (bi == bj) ? i : 3u * bj; j < 3u * bj + 3u; ++j) {
                    float q = 0.5f * t_s * (a[i * NX + j] * qc[j] + qc[i] * a[j * NX + i]);
                    if (i == j) {
                        q += qc[i] * t_s;
                    }
                    p[i * NX + j] += q;
                }
            }
        }
    }
    if (c->gps_pos_tau_s > 0.0f) {
        /* receiver slow error (GNSS update step 3): dr grows as 2 c^2 (1 - exp(-a / tau)) over the
         * time a since the position was last applied, the variance of the change of a
         * Gauss-Markov error of variance c^2 over a */
        const float age = ins->t_imu_us > ins->t_fuse_pos_us ? span_s(ins->t_fuse_pos_us, ins->t_imu_us) : 0.0f;
        const float g = t_s * mca_expf(-age / c->gps_pos_tau_s);
        for (size_t i = 0; i < 3u; ++i) {
            p[(MCA_INS_DR + i) * (NX + 1u)] += g * ins->rx_q[i < 2u ? 0u : 1u];
        }
    }
    for (size_t i = 0; i < NX; ++i) { /* mirror the upper triangle */
        for (size_t j = i + 1u; j < NX; ++j) {
            p[j * NX + i] = p[i * NX + j];
        }
    }
}
#undef PHI_DIAG
#undef BIT
#undef NB

/* ------------------------------------------------------------------------ history */

static void hist_push(mca_ins_t *ins)
{
    mca_ins_hist_t *e = &ins->hist[ins->hist_head];
    e->t_us = (uint32_t)ins->t_imu_us;
    pos_home_ned(ins, e->pos_ned_m);
    memcpy(e->vel_ned_mps, ins->vel_ned_mps, sizeof(e->vel_ned_mps));
    memcpy(e->q_nb, ins->q_nb, sizeof(e->q_nb));
    memcpy(e->w_b_rps, ins->w_last_rps, sizeof(e->w_b_rps));
    ins->t_hist_newest_us = ins->t_imu_us;
    ins->hist_head = (uint16_t)((ins->hist_head + 1u) % MCA_INS_HIST_LEN);
    if (ins->hist_count < MCA_INS_HIST_LEN) {
        ins->hist_count++;
    }
}

/* The INS solution at one time. */
typedef struct {
    float r[3], v[3], q[4], w[3];
} ins_sol_t;

/* IMU time of history entry k (ring index): entries span under MCA_INS_HIST_LEN intervals, so
 * the low 32 bits relative to the newest entry's full time are exact. */
static uint64_t hist_time(const mca_ins_t *ins, uint16_t k)
{
    const uint16_t newest = (uint16_t)((ins->hist_head + MCA_INS_HIST_LEN - 1u) % MCA_INS_HIST_LEN);
    return ins->t_hist_newest_us - (uint64_t)(uint32_t)(ins->hist[newest].t_us - ins->hist[k].t_us);
}

/* ALGORITHMS.md 10, The INS solution at t_fix. Returns 0 on a history miss. */
static int solution_at(const mca_ins_t *ins, uint64_t t, ins_sol_t *s)
{
    ins_sol_t cur;
    pos_home_ned(ins, cur.r);
    memcpy(cur.v, ins->vel_ned_mps, sizeof(cur.v));
    memcpy(cur.q, ins->q_nb, sizeof(cur.q));
    memcpy(cur.w, ins->w_last_rps, sizeof(cur.w));
    if (t >= ins->t_imu_us) {
        *s = cur;
        return 1;
    }
    if (ins->hist_count == 0u) {
        return 0;
    }
    const uint16_t oldest = (uint16_t)((ins->hist_head + MCA_INS_HIST_LEN - ins->hist_count) % MCA_INS_HIST_LEN);
    if (t < hist_time(ins, oldest)) {
        return 0;
    }
    for (uint16_t k = 0; k < ins->hist_count; ++k) { /* oldest to newest, then the current state */
        const uint16_t ia = (uint16_t)((oldest + k) % MCA_INS_HIST_LEN);
        const int last = k + 1u == ins->hist_count;
        const uint16_t ib = (uint16_t)((oldest + k + 1u) % MCA_INS_HIST_LEN);
        const mca_ins_hist_t *a = &ins->hist[ia];
        const uint64_t ta = hist_time(ins, ia);
        const uint64_t tb = last ? ins->t_imu_us : hist_time(ins, ib);
        if (t < ta || t >= tb) {
            continue;
        }
        const float *vb = last ? cur.v : ins->hist[ib].vel_ned_mps;
        const float d = span_s(ta, t);
        const float tab = span_s(ta, tb);
        for (size_t i = 0; i < 3u; ++i) {
            const float dvel = vb[i] - a->vel_ned_mps[i];
            s->v[i] = a->vel_ned_mps[i] + dvel * (d / tab);
            s->r[i] = a->pos_ned_m[i] + a->vel_ned_mps[i] * d + dvel * d * d / (2.0f * tab);
        }
        const int use_b = t - ta > tb - t; /* the nearer point, ties: a */
        memcpy(s->q, use_b ? (last ? cur.q : ins->hist[ib].q_nb) : a->q_nb, sizeof(s->q));
        memcpy(s->w, use_b ? (last ? cur.w : ins->hist[ib].w_b_rps) : a->w_b_rps, sizeof(s->w));
        return 1;
    }
    return 0; /* unreachable: t lies between the oldest entry and the current time */
}

/* ------------------------------------------------------------------------ corrections */

/* Turn the attitude (and the history's) about NED down by dpsi; P row/column 8 (ALGORITHMS.md 10). */
static void yaw_turn(mca_ins_t *ins, float dpsi, float var)
{
    float s, c;
    mca_sincosf(0.5f * dpsi, &s, &c);
    const float qz[4] = {c, 0.0f, 0.0f, s};
    quat_left(ins->q_nb, qz);
    for (uint16_t k = 0; k < ins->hist_count; ++k) {
        quat_left(ins->hist[k].q_nb, qz);
    }
    if (ins->nav) {
        for (size_t i = 0; i < NX; ++i) {
            ins->p[i * NX + MCA_INS_PHI + 2u] = 0.0f;
            ins->p[(MCA_INS_PHI + 2u) * NX + i] = 0.0f;
        }
        ins->p[(MCA_INS_PHI + 2u) * (NX + 1u)] = var;
    }
    ins->yaw_aligned = 1u;
    ins->yaw_var_align = var;
}

/* Apply the error-state estimate dx to the state and every history entry (ALGORITHMS.md 10). */
static void correct(mca_ins_t *ins, const float dx[NX])
{
    ins_frame_t fr;
    frame_of(ins, &fr);
    float dq[4];
    mca_quat_from_rotvec(dq, &dx[MCA_INS_PHI]);
    for (size_t i = 0; i < 3u; ++i) {
        ins->off_ned_m[i] += dx[MCA_INS_DR + i];
        ins->vel_ned_mps[i] += dx[MCA_INS_DV + i];
        ins->bg_rps[i] += dx[MCA_INS_BG + i];
        ins->ba_mps2[i] += dx[MCA_INS_BA + i];
    }
    fold(ins, &fr);
    quat_left(ins->q_nb, dq);
    for (uint16_t k = 0; k < ins->hist_count; ++k) {
        mca_ins_hist_t *e = &ins->hist[k];
        for (size_t i = 0; i < 3u; ++i) {
            e->pos_ned_m[i] += dx[MCA_INS_DR + i];
            e->vel_ned_mps[i] += dx[MCA_INS_DV + i];
        }
        quat_left(e->q_nb, dq);
    }
}

/* ------------------------------------------------------------------------ IMU */

static float g_still(const mca_ins_t *ins)
{
    if (ins->cfg.gravity_mps2 > 0.0f) {
        return ins->cfg.gravity_mps2;
    }
    return ins->home_set ? ins->g_align_mps2 : G0;
}

/* Roll and pitch from a mean specific force, yaw given; the gyro bias; the still-window state. */
static void level(mca_ins_t *ins, const float f_mean[3], const float bias[3], float yaw, int still)
{
    ins->bg0_var = still ? ins->cfg.gyro_bias_still_var_rps2 : ins->cfg.gyro_bias0_var_rps2;
    ins->level_still = still ? 1u : 0u;
    const float eul[3] = {mca_atan2f(-f_mean[1], -f_mean[2]),
                          mca_atan2f(f_mean[0], sqrtf(f_mean[1] * f_mean[1] + f_mean[2] * f_mean[2])), yaw};
    mca_quat_from_euler(ins->q_nb, eul);
    memcpy(ins->bg_rps, bias, sizeof(ins->bg_rps));
    memset(ins->ba_mps2, 0, sizeof(ins->ba_mps2));
    memset(ins->init_f_sum, 0, sizeof(ins->init_f_sum));
    memset(ins->init_w_sum, 0, sizeof(ins->init_w_sum));
    ins->init_n = 0u;
    ins->init_win_us = 0u;
}

static void align(mca_ins_t *ins, const float f_mean[3], const float bias[3], int still)
{
    level(ins, f_mean, bias, ins->cfg.yaw0_rad, still);
    ins->aligned = 1u;
    ins->yaw_aligned = ins->cfg.yaw_source == MCA_YAW_NONE ? 1u : 0u;
    ins->yaw_var_align = ins->cfg.yaw0_var_rad2;
}

/* ALGORITHMS.md 8, IMU step 4, with the INS's timeout fallback and re-levelling (section 10).
 * Returns 1 when this sample aligned or re-levelled (it is then not propagated). */
static int accumulate_alignment(mca_ins_t *ins, const float w[3], const float f[3], uint32_t dt_us)
{
    for (size_t i = 0; i < 3u; ++i) {
        ins->init_all_f_sum[i] += f[i]; /* every sample: the timeout fallback (ALGORITHMS.md 10) */
    }
    ins->init_all_n++;
    const int still =
        norm3(w) <= ins->cfg.init_gyro_still_rps && fabsf(norm3(f) - g_still(ins)) <= ins->cfg.init_acc_still_mps2;
    if (still) {
        for (size_t i = 0; i < 3u; ++i) {
            ins->init_f_sum[i] += f[i];
            ins->init_w_sum[i] += w[i];
        }
        ins->init_n++;
        ins->init_win_us += dt_us;
    } else {
        memset(ins->init_f_sum, 0, sizeof(ins->init_f_sum));
        memset(ins->init_w_sum, 0, sizeof(ins->init_w_sum));
        ins->init_n = 0u;
        ins->init_win_us = 0u;
    }
    const float zero[3] = {0.0f, 0.0f, 0.0f};
    if (ins->init_n > 0u && ins->init_win_us >= us(ins->cfg.init_still_s)) {
        const float inv = 1.0f / (float)ins->init_n;
        const float fm[3] = {ins->init_f_sum[0] * inv, ins->init_f_sum[1] * inv, ins->init_f_sum[2] * inv};
        const float wm[3] = {ins->init_w_sum[0] * inv, ins->init_w_sum[1] * inv, ins->init_w_sum[2] * inv};
        if (!ins->aligned) {
            align(ins, fm, wm, 1);
            return 1;
        }
        /* waiting for navigation: re-level (yaw kept) only when the GNSS says stopped too; the
         * still test alone passes a straight-line acceleration of 3 m/s^2 (| |f| - g | = 0.45) */
        const int stopped = ins->have_fix && ins->fix_speed_mps >= 0.0f && ins->fix_speed_mps < STILL_SPEED &&
                            ins->t_imu_us - ins->t_lastfix_us <= us(ins->cfg.gps_timeout_s);
        if (stopped) {
            level(ins, fm, wm, yaw_of(ins->q_nb), 1);
            return 1;
        }
        memset(ins->init_f_sum, 0, sizeof(ins->init_f_sum)); /* a new window */
        memset(ins->init_w_sum, 0, sizeof(ins->init_w_sum));
        ins->init_n = 0u;
        ins->init_win_us = 0u;
        return 0;
    }
    if (!ins->aligned && ins->t_imu_us - ins->t_first_us >= us(ins->cfg.init_timeout_s)) {
        if (ins->init_n > 0u) {
            const float inv = 1.0f / (float)ins->init_n;
            const float fm[3] = {ins->init_f_sum[0] * inv, ins->init_f_sum[1] * inv, ins->init_f_sum[2] * inv};
            align(ins, fm, zero, 0);
        } else {
            const float inv = 1.0f / (float)ins->init_all_n;
            const float fa[3] = {ins->init_all_f_sum[0] * inv, ins->init_all_f_sum[1] * inv,
                                 ins->init_all_f_sum[2] * inv};
            align(ins, fa, zero, 0);
        }
        return 1;
    }
    return 0;
}

/* ALGORITHMS.md 10, Mechanization steps 1-8. */
static void mechanize(mca_ins_t *ins, const float w_m[3], const float f_m[3], float dt, uint32_t dt_us)
{
    ins_frame_t fr;
    frame_of(ins, &fr);
    float w_ie[3], w_en[3];
    rates_of(ins, &fr, w_ie, w_en);
    const float g = gravity_of(ins, &fr);
    float dth[3], du[3], cr[3], u2[3], c[9], dvf[3], cor[3];
    for (size_t i = 0; i < 3u; ++i) {
        dth[i] = (w_m[i] - ins->bg_rps[i]) * dt;
        du[i] = (f_m[i] - ins->ba_mps2[i]) * dt;
    }
    cross3(cr, dth, du);
    for (size_t i = 0; i < 3u; ++i) {
        u2[i] = du[i] + 0.5f * cr[i];
    }
    mca_quat_to_dcm(c, ins->q_nb);
    mat3_vec(dvf, c, u2);
    const float w_cor[3] = {2.0f * w_ie[0] + w_en[0], 2.0f * w_ie[1] + w_en[1], 2.0f * w_ie[2] + w_en[2]};
    cross3(cor, w_cor, ins->vel_ned_mps);
    const float gn[3] = {0.0f, 0.0f, g};
    for (size_t i = 0; i < 3u; ++i) {
        const float v0 = ins->vel_ned_mps[i];
        const float v1 = v0 + dvf[i] + (gn[i] - cor[i]) * dt;
        ins->off_ned_m[i] += 0.5f * (v0 + v1) * dt;
        ins->vel_ned_mps[i] = v1;
    }
    fold(ins, &fr);
    /* q+ = exp(-w_in dt) (x) q (x) exp(dtheta) */
    const float rv_n[3] = {-(w_ie[0] + w_en[0]) * dt, -(w_ie[1] + w_en[1]) * dt, -(w_ie[2] + w_en[2]) * dt};
    float qb[4], qn[4], q1[4], q2[4];
    mca_quat_from_rotvec(qb, dth);
    mca_quat_from_rotvec(qn, rv_n);
    mca_quat_mul(q1, ins->q_nb, qb);
    mca_quat_mul(q2, qn, q1);
    mca_quat_normalize(q2);
    memcpy(ins->q_nb, q2, sizeof(q2));
    for (size_t i = 0; i < 3u; ++i) {
        ins->w_last_rps[i] = w_m[i] - ins->bg_rps[i];
        ins->cov_dv_n[i] += dvf[i];
    }
    ins->cov_acc_us += dt_us;
    if (ins->cov_acc_us >= us(ins->cfg.cov_dt_s)) {
        const float t = (float)ins->cov_acc_us * 1e-6f;
        const float f_n[3] = {ins->cov_dv_n[0] / t, ins->cov_dv_n[1] / t, ins->cov_dv_n[2] / t};
        cov_propagate(ins, t, f_n);
        memset(ins->cov_dv_n, 0, sizeof(ins->cov_dv_n));
        ins->cov_acc_us = 0u;
    }
    ins->hist_acc_us += dt_us;
    if (ins->hist_acc_us >= (uint32_t)MCA_INS_HIST_DT_US) {
        hist_push(ins);
        ins->hist_acc_us = 0u;
    }
}

mca_status_t mca_ins_imu(mca_ins_t *ins, uint64_t t_us, const float w[3], const float f[3])
{
    if (ins == NULL || w == NULL || f == NULL) {
        return MCA_ERR_NULL;
    }
    uint32_t dt_us; /* the clock rules shared with the navigation filter */
    const mca_status_t sc = mca_imu_clock_step(&ins->t_imu_us, &ins->t_first_us, &ins->have_imu, t_us, w, f,
                                               us(ins->cfg.imu_dt_max_s), &dt_us);
    if (sc == MCA_ERR_BAD_DT) {
        ins->nav = 0u; /* re-anchored; position and velocity unknown after the gap: the next fix restarts */
    }
    if (sc != MCA_OK || dt_us == 0u) {
        return sc; /* an error, or the first sample (clock anchored only) */
    }
    const float dt = (float)dt_us * 1e-6f;
    const float sat = ins->cfg.accel_sat_mps2;
    if (fabsf(f[0]) >= sat || fabsf(f[1]) >= sat || fabsf(f[2]) >= sat) {
        ins->flags |= MCA_INS_FLAG_SATURATED;
    }
    for (size_t i = 0; i < 3u; ++i) {
        ins->f_last_mps2[i] = f[i] - ins->ba_mps2[i];
    }
    if (!ins->aligned) {
        (void)accumulate_alignment(ins, w, f, dt_us);
        return MCA_OK;
    }
    if (!ins->nav) {
        /* attitude only until navigation starts (no position: no earth or transport rate); a
         * sample that completes a still window re-levels instead (ALGORITHMS.md 10) */
        if (accumulate_alignment(ins, w, f, dt_us)) {
            return MCA_OK;
        }
        float rv[3], dq[4], qn[4];
        for (size_t i = 0; i < 3u; ++i) {
            ins->w_last_rps[i] = w[i] - ins->bg_rps[i];
            rv[i] = ins->w_last_rps[i] * dt;
        }
        mca_quat_from_rotvec(dq, rv);
        mca_quat_mul(qn, ins->q_nb, dq);
        mca_quat_normalize(qn);
        memcpy(ins->q_nb, qn, sizeof(qn));
        return MCA_OK;
    }
    mechanize(ins, w, f, dt, dt_us);
    return MCA_OK;
}

mca_status_t mca_ins_imu_delta(mca_ins_t *ins, uint64_t t_us, const float dth[3], const float dv[3])
{
    if (ins == NULL || dth == NULL || dv == NULL) {
        return MCA_ERR_NULL;
    }
    if (ins->have_imu && t_us > ins->t_imu_us && t_us - ins->t_imu_us <= us(ins->cfg.imu_dt_max_s) &&
        mca_all_finite(dth, 3u) && mca_all_finite(dv, 3u)) {
        const float dt = (float)(uint32_t)(t_us - ins->t_imu_us) * 1e-6f;
        const float w[3] = {dth[0] / dt, dth[1] / dt, dth[2] / dt};
        const float f[3] = {dv[0] / dt, dv[1] / dt, dv[2] / dt};
        return mca_ins_imu(ins, t_us, w, f);
    }
    return mca_ins_imu(ins, t_us, dth, dv); /* first sample or an error: the values are not used */
}

/* ------------------------------------------------------------------------ GNSS */

/* Receiver position error (ALGORITHMS.md 10, GNSS update step 3): with gps_pos_tau_s > 0 the
 * fix's variances h_acc^2, v_acc^2 split into a white part (the configured one, at most the whole),
 * the rows' R, and a slow Gauss-Markov part c^2, which grows the INS position between the times
 * it is applied (rx_q = 2 c^2 / tau, which the state keeps for the covariance propagation once
 * the fix is taken); else all white. */
static void receiver_error(const mca_ins_config_t *c, float h_acc, float v_acc, float r_pos[2], float rx_q[2])
{
    const float acc[2] = {h_acc, v_acc}, white[2] = {c->gps_pos_white_m, c->gps_alt_white_m};
    for (size_t i = 0; i < 2u; ++i) {
        const float var = acc[i] * acc[i], w2 = white[i] * white[i];
        const int split = c->gps_pos_tau_s > 0.0f && var > w2;
        r_pos[i] = split ? w2 : var;
        rx_q[i] = split ? 2.0f * (var - w2) / c->gps_pos_tau_s : 0.0f;
    }
}

/* Start of navigation (ALGORITHMS.md 10, Initial alignment). */
static void start_nav(mca_ins_t *ins, const mca_gps_fix_t *fix, const float vel[3], uint8_t vmask, float h_acc,
                      float v_acc, float s_acc)
{
    const int has_alt = (fix->flags & MCA_FIX_ALT) != 0u;
    ins->lat_e7 = fix->lat_e7;
    ins->lon_e7 = fix->lon_e7;
    ins->alt_mm = has_alt ? fix->alt_mm : ins->home.alt_mm;
    memset(ins->off_ned_m, 0, sizeof(ins->off_ned_m));
    memcpy(ins->vel_ned_mps, vel, 3u * sizeof(float));
    if (ins->t_imu_us > fix->t_us) {
        /* carried to the present with the newest sample's acceleration a = C f + g_n */
        const float d = span_s(fix->t_us, ins->t_imu_us);
        ins_frame_t fr;
        frame_of(ins, &fr);
        float c[9], a[3];
        mca_quat_to_dcm(c, ins->q_nb);
        mat3_vec(a, c, ins->f_last_mps2);
        a[2] += gravity_of(ins, &fr);
        for (size_t i = 0; i < 3u; ++i) {
            ins->off_ned_m[i] = vel[i] * d + 0.5f * a[i] * d * d;
            ins->vel_ned_mps[i] = vel[i] + a[i] * d;
        }
        fold(ins, &fr);
    }
    memset(ins->p, 0, sizeof(ins->p));
    const mca_ins_config_t *c = &ins->cfg;
    const float d[NX] = {h_acc * h_acc,
                         h_acc * h_acc,
                         v_acc * v_acc,
                         (vmask & 1u) ? s_acc * s_acc : c->vel0_var_m2ps2,
                         (vmask & 2u) ? s_acc * s_acc : c->vel0_var_m2ps2,
                         (vmask & 4u) ? s_acc * s_acc : c->vel0_var_m2ps2,
                         c->att0_var_rad2,
                         c->att0_var_rad2,
                         ins->yaw_var_align,
                         ins->bg0_var,
                         ins->bg0_var,
                         ins->bg0_var,
                         c->accel_bias0_var_mps4,
                         c->accel_bias0_var_mps4,
                         c->accel_bias0_var_mps4};
    for (size_t i = 0; i < NX; ++i) {
        ins->p[i * (NX + 1u)] = d[i];
    }
    if (ins->level_still) {
        /* the levelled tilt absorbed the accelerometer bias: phi_N = (C db_a)_E / g,
         * phi_E = -(C db_a)_N / g (ALGORITHMS.md 10, Start of navigation) */
        ins_frame_t fr;
        frame_of(ins, &fr);
        const float g = gravity_of(ins, &fr), sb2 = c->accel_bias0_var_mps4;
        float cn[9], m[6];
        mca_quat_to_dcm(cn, ins->q_nb);
        for (size_t j = 0; j < 3u; ++j) {
            m[j] = cn[3u + j] / g;       /* row phi_N */
            m[3u + j] = -cn[j] / g;      /* row phi_E */
        }
        for (size_t i = 0; i < 2u; ++i) {
            for (size_t j = 0; j < 2u; ++j) {
                const float mm = m[i * 3u] * m[j * 3u] + m[i * 3u + 1u] * m[j * 3u + 1u] + m[i * 3u + 2u] * m[j * 3u + 2u];
                ins->p[(MCA_INS_PHI + i) * NX + MCA_INS_PHI + j] = sb2 * mm + (i == j ? c->att_still_var_rad2 : 0.0f);
            }
            for (size_t j = 0; j < 3u; ++j) {
                ins->p[(MCA_INS_PHI + i) * NX + MCA_INS_BA + j] = sb2 * m[i * 3u + j];
                ins->p[(MCA_INS_BA + j) * NX + MCA_INS_PHI + i] = sb2 * m[i * 3u + j];
            }
        }
    }
    memset(ins->cov_dv_n, 0, sizeof(ins->cov_dv_n));
    ins->cov_acc_us = 0u;
    ins->hist_acc_us = 0u;
    ins->hist_head = 0u;
    ins->hist_count = 0u;
    ins->nav = 1u;
    mca_robust_state_init(&ins->rs);
    mca_robust_state_init(&ins->rs_v);
    ins->t_fuse_pos_us = fix->t_us;
    ins->t_fuse_vel_us = fix->t_us;
    ins->pos_out = 0u;
    ins->vel_out = 0u;
}

/* Course-over-ground yaw alignment when due (ALGORITHMS.md 10, Yaw); q_fix is turned too. */
static void cog_align(mca_ins_t *ins, const float vel[3], int has_vne, float s_acc, float q_fix[4])
{
    if (ins->cfg.yaw_source != MCA_YAW_COG || ins->yaw_aligned || !has_vne) {
        return;
    }
    const float speed = sqrtf(vel[0] * vel[0] + vel[1] * vel[1]);
    if (!(speed > 0.0f) || speed < ins->cfg.cog_min_speed_mps) {
        return;
    }
    const float dpsi = mca_wrap_pi(mca_atan2f(vel[1], vel[0]) - yaw_of(q_fix));
    const float var = ins->cfg.cog_sigma0_rad * ins->cfg.cog_sigma0_rad + (s_acc / speed) * (s_acc / speed);
    yaw_turn(ins, dpsi, var);
    float s, c;
    mca_sincosf(0.5f * dpsi, &s, &c);
    const float qz[4] = {c, 0.0f, 0.0f, s};
    quat_left(q_fix, qz);
}

/* Rows, innovation and noise of one fix (ALGORITHMS.md 10, GNSS update steps 3-4) into the
 * update scratch of the state: position rows first (*m_pos of them, R r_pos[0] on N and E,
 * r_pos[1] on D), then velocity rows (s_acc^2); R as
 * two diagonal blocks one after the other (m_pos x m_pos at upd_r, then the velocity block).
 * Returns the number of rows. */
static MCA_NOINLINE size_t gnss_rows(mca_ins_t *ins, const mca_gps_fix_t *fix, const ins_sol_t *s,
                                     const float vel[3], uint8_t vmask, const float r_pos[2], float s_acc,
                                     size_t *m_pos)
{
    const int has_alt = (fix->flags & MCA_FIX_ALT) != 0u;
    float ned[3], c[9], cl[3], wl[3], cwl[3], lx[9], clx[9];
    (void)mca_geo_to_ned(&ins->home, fix->lat_e7, fix->lon_e7, has_alt ? fix->alt_mm : ins->home.alt_mm, ned);
    const float *l = ins->cfg.lever_arm_b_m;
    mca_quat_to_dcm(c, s->q);
    mat3_vec(cl, c, l);
    cross3(wl, s->w, l);
    mat3_vec(cwl, c, wl);
    /* C [l x] */
    const float lsk[9] = {0.0f, -l[2], l[1], l[2], 0.0f, -l[0], -l[1], l[0], 0.0f};
    memcpy(lx, lsk, sizeof(lx));
    mca_mat_mul(clx, c, lx, 3u, 3u, 3u);
    float *h = ins->upd_h, *z = ins->upd_z, *r = ins->upd_r;
    memset(h, 0, sizeof(ins->upd_h));
    memset(r, 0, sizeof(ins->upd_r));
    float var[MCA_MEAS_MAX];
    size_t m = 0u;
    float skew_cl[9], skew_cwl[9];
    const float scl[9] = {0.0f, -cl[2], cl[1], cl[2], 0.0f, -cl[0], -cl[1], cl[0], 0.0f};
    const float scw[9] = {0.0f, -cwl[2], cwl[1], cwl[2], 0.0f, -cwl[0], -cwl[1], cwl[0], 0.0f};
    memcpy(skew_cl, scl, sizeof(skew_cl));
    memcpy(skew_cwl, scw, sizeof(skew_cwl));
    for (size_t i = 0; i < 3u; ++i) {
        if (i == 2u && !(has_alt && fix->fix_type >= 3u)) {
            continue;
        }
        float *row = &h[m * NX];
        row[MCA_INS_DR + i] = 1.0f;
        ins->upd_idx[m] = (uint8_t)(MCA_INS_DR + i);
        for (size_t j = 0; j < 3u; ++j) {
            row[MCA_INS_PHI + j] = -skew_cl[i * 3u + j];
        }
        z[m] = ned[i] - s->r[i] - cl[i];
        var[m] = r_pos[i < 2u ? 0u : 1u];
        ++m;
    }
    const size_t mp = m;
    for (size_t i = 0; i < 3u; ++i) {
        if ((vmask & (1u << i)) == 0u) {
            continue;
        }
        float *row = &h[m * NX];
        row[MCA_INS_DV + i] = 1.0f;
        ins->upd_idx[m] = (uint8_t)(MCA_INS_DV + i);
        for (size_t j = 0; j < 3u; ++j) {
            row[MCA_INS_PHI + j] = -skew_cwl[i * 3u + j];
            row[MCA_INS_BG + j] = clx[i * 3u + j];
        }
        z[m] = vel[i] - s->v[i] - cwl[i];
        var[m] = s_acc * s_acc;
        ++m;
    }
    const size_t mv = m - mp;
    for (size_t i = 0; i < mp; ++i) {
        r[i * mp + i] = var[i];
    }
    for (size_t i = 0; i < mv; ++i) {
        r[mp * mp + i * mv + i] = var[mp + i];
    }
    *m_pos = mp;
    return m;
}

/* Lock-up guard reset of rows [r0, r0 + mb) (ALGORITHMS.md 10, GNSS update step 5): their states
 * take the fix (dx = the innovation, replacing what the other block put there), their covariance
 * R, uncorrelated with the rest. Not inlined: the guard is rare, the GNSS step's stack is not.
 * Row and column are written in one pass, the diagonal inside it: written as zeroing loops and
 * then the diagonal store, GCC 12.2 at -O3 dropped the call altogether (not at -O0, -O2, -Os;
 * tests/python/test_ins.py against the golden model and tests/c/test_ins.c at Release catch it). */
static MCA_NOINLINE void gnss_reset_block(mca_ins_t *ins, size_t r0, size_t mb, const float *rb)
{
    for (size_t i = 0; i < mb; ++i) {
        const size_t k = ins->upd_idx[r0 + i];
        const float r_kk = rb[i * mb + i];
        ins->dx[k] = ins->upd_z[r0 + i];
        for (size_t j = 0; j < NX; ++j) {
            ins->p[k * NX + j] = j == k ? r_kk : 0.0f;
            ins->p[j * NX + k] = j == k ? r_kk : 0.0f;
        }
    }
}

/* One block of GNSS rows (ALGORITHMS.md 10, GNSS update step 5): rows [r0, r0 + mb) of the
 * scratch with R at rb, applied to the accumulated correction ins->dx in the configured robust
 * mode with the block's own memory; when the mode rejects it and a lock-up guard is due
 * (guard), the rows are reset to the fix instead and the memory cleared. */
static mca_status_t gnss_block(mca_ins_t *ins, size_t r0, size_t mb, const float *rb, mca_robust_state_t *rs,
                               mca_update_report_t *rep, int guard)
{
    const mca_status_t st = mca_kf_update_tested(ins->dx, ins->p, NX, &ins->upd_h[r0 * NX], &ins->upd_z[r0], rb, mb,
                                                 &ins->cfg.robust, rs, NULL, NULL, ins->ws, MCA_INS_WS_LEN, rep);
    if (st == MCA_OK && guard && rep->rejected) {
        gnss_reset_block(ins, r0, mb, rb);
        mca_robust_state_init(rs);
        rep->reset = 1u;
        rep->rejected = 0u;
    }
    return st;
}

/* T of the rows [r0, r0 + mb) alone against the prior (x = 0, P as propagated), R at rb:
 * nu^T (H P H^T + R)^-1 nu, the statistic mca_kf_update takes; +inf when it cannot be formed. */
static float gnss_block_t(mca_ins_t *ins, size_t r0, size_t mb, const float *rb)
{
    /* in the update scratch, free between the two block updates: C, P h^T, the test's scratch */
    float *c = ins->ws, *u = &ins->ws[9], *ws = &ins->ws[9u + NX];
    const float *h = &ins->upd_h[r0 * NX];
    for (size_t j = 0; j < mb; ++j) {
        mca_mat_mul(u, ins->p, &h[j * NX], NX, NX, 1u); /* P h_j^T */
        for (size_t i = 0; i <= j; ++i) {
            float a = rb[i * mb + j];
            for (size_t k = 0; k < NX; ++k) {
                a += h[i * NX + k] * u[k];
            }
            c[i * mb + j] = a;
            c[j * mb + i] = a;
        }
    }
    float t_stat = INFINITY;
    if (mca_kf_test_stat(&ins->upd_z[r0], c, mb, ws, &t_stat) != MCA_OK || !isfinite(t_stat)) {
        t_stat = INFINITY;
    }
    return t_stat;
}

/* Output flags of one block's report. */
static uint32_t gnss_block_flags(const mca_update_report_t *rep)
{
    return (rep->rejected ? (uint32_t)MCA_INS_FLAG_REJECTED : 0u) |
           (rep->detected ? (uint32_t)MCA_INS_FLAG_DETECTED : 0u) | (rep->reset ? (uint32_t)MCA_INS_FLAG_RESET : 0u);
}

/* What one block did: its T into the sum, its flags, its fuse time when applied. */
static void gnss_block_done(const mca_update_report_t *rep, uint64_t t, uint64_t *t_fuse, float *t_sum,
                            uint32_t *fl, int *applied)
{
    *t_sum += rep->t_stat;
    *fl |= gnss_block_flags(rep);
    if (!rep->rejected) {
        *applied = 1;
        *t_fuse = t;
    }
}

/* A block held out (ALGORITHMS.md 10, GNSS update step 5): rejected without being offered to its
 * mode, whose memory stays; its report's T is the block's own against the prior. */
static void gnss_hold_out(mca_ins_t *ins, mca_update_report_t *rep, size_t r0, size_t mb, const float *rb,
                          uint8_t detected)
{
    const float t_stat = gnss_block_t(ins, r0, mb, rb);
    memset(rep, 0, sizeof(*rep));
    rep->m = (uint8_t)mb;
    rep->mode = ins->cfg.robust.mode;
    rep->t_stat = t_stat;
    rep->rejected = 1u;
    rep->detected = detected;
}

/* GNSS update steps 3-7 (ALGORITHMS.md 10): the velocity block, then the position block on the
 * correction the first left, each in the robust mode with its own memory. A velocity block after
 * a rejected one waits for the position: it is held out while the position block alone is not
 * consistent (T >= chi2_m(0.025)). While the velocity is rejected, the position block is held out
 * unless it was applied on the fix before. A block its mode rejects after the lock-up guards' time
 * is reset to the fix; one correction of the state with what both applied. */
static mca_status_t gnss_update(mca_ins_t *ins, const mca_gps_fix_t *fix, const ins_sol_t *s, const float vel[3],
                                uint8_t vmask, const float r_pos[2], float s_acc)
{
    size_t mp = 0u;
    const size_t m = gnss_rows(ins, fix, s, vel, vmask, r_pos, s_acc, &mp);
    const size_t mv = m - mp;
    memset(ins->dx, 0, sizeof(ins->dx));
    const uint64_t t = fix->t_us;
    const uint64_t t_any = ins->t_fuse_pos_us > ins->t_fuse_vel_us ? ins->t_fuse_pos_us : ins->t_fuse_vel_us;
    const uint32_t lim_any = us(ins->cfg.gnss_reset_s), lim_blk = us(ins->cfg.gnss_block_reset_s);
    const int stale_any = lim_any > 0u && t - t_any > lim_any;
    int applied = 0;
    float t_sum = 0.0f;
    uint32_t fl = 0u;
    mca_status_t st = MCA_OK;
    int vel_rejected = 0;
    if (mv > 0u) {
        const int guard = stale_any || (lim_blk > 0u && t - ins->t_fuse_vel_us > lim_blk);
        const float *rv = &ins->upd_r[mp * mp];
        if (ins->vel_out && !guard && mp > 0u &&
            !(gnss_block_t(ins, 0u, mp, ins->upd_r) < mca_chi2_quantile(mp, MCA_CHI2_2P5E2))) {
            /* after a rejected velocity, the position alone disagrees: the INS has no way yet to
             * tell a velocity fault that its own coast has grown to cover from a clean velocity */
            gnss_hold_out(ins, &ins->rep_v, mp, mv, rv, 1u);
        } else {
            st = gnss_block(ins, mp, mv, rv, &ins->rs_v, &ins->rep_v, guard);
        }
        if (st == MCA_OK) {
            vel_rejected = ins->rep_v.rejected != 0u;
            ins->vel_out = (uint8_t)vel_rejected;
            gnss_block_done(&ins->rep_v, t, &ins->t_fuse_vel_us, &t_sum, &fl, &applied);
        }
    }
    if (st == MCA_OK && mp > 0u) {
        const int guard = stale_any || (lim_blk > 0u && t - ins->t_fuse_pos_us > lim_blk);
        if (vel_rejected && !guard && ins->pos_out) {
            /* held out with the velocity: a fault of both takes the position out at its start */
            gnss_hold_out(ins, &ins->rep, 0u, mp, ins->upd_r, 0u);
        } else {
            st = gnss_block(ins, 0u, mp, ins->upd_r, &ins->rs, &ins->rep, guard);
        }
        if (st == MCA_OK) {
            ins->pos_out = ins->rep.rejected;
            gnss_block_done(&ins->rep, t, &ins->t_fuse_pos_us, &t_sum, &fl, &applied);
        }
    }
    if (applied) {
        /* a position block that failed leaves the velocity block's P and dx, which stand */
        correct(ins, ins->dx);
        ins->n_gps_upd++;
    }
    if (st != MCA_OK || (fl & MCA_INS_FLAG_REJECTED) != 0u) {
        ins->n_gps_rej++;
    }
    if (st == MCA_OK || applied) {
        const uint32_t mask = MCA_INS_FLAG_REJECTED | MCA_INS_FLAG_DETECTED | MCA_INS_FLAG_RESET;
        ins->flags = (ins->flags & ~mask) | fl;
    }
    if (st == MCA_OK) {
        ins->last_gps_t = t_sum;
        ins->last_gps_m = (uint32_t)m;
    }
    return st;
}

mca_status_t mca_ins_gps(mca_ins_t *ins, const mca_gps_fix_t *fix)
{
    if (ins == NULL || fix == NULL) {
        return MCA_ERR_NULL;
    }
    mca_fix_view_t fv; /* the same checks and defaults as the navigation filter */
    const mca_status_t sf =
        mca_gps_fix_read(fix, ins->cfg.gps_pos_sigma_m, ins->cfg.gps_alt_sigma_m, ins->cfg.gps_vel_sigma_mps, &fv);
    if (sf != MCA_OK) {
        return sf;
    }
    if (ins->have_fix && fix->t_us <= ins->t_lastfix_us) {
        return MCA_ERR_TIME_BACKWARDS;
    }
    const int has_alt = fv.has_alt != 0u;
    const int has_vne = (fv.vel_mask & 3u) == 3u;
    const float *vel = fv.vel_ned_mps;
    const uint8_t vmask = fv.vel_mask;
    /* the receiver's own accuracies, floored (ALGORITHMS.md 10, GNSS update step 3) */
    const float p_min = ins->cfg.gps_pos_noise_min_m, v_min = ins->cfg.gps_vel_noise_min_mps;
    /* (mca_gps_fix_read gives finite accuracies > 0; no libm fmaxf in the core) */
    const float h_acc = fv.h_acc_m > p_min ? fv.h_acc_m : p_min, v_acc = fv.v_acc_m > p_min ? fv.v_acc_m : p_min;
    const float s_acc = fv.s_acc_mps > v_min ? fv.s_acc_mps : v_min;
    float r_pos[2], rx_q[2];
    receiver_error(&ins->cfg, h_acc, v_acc, r_pos, rx_q);
    if (!ins->home_set) {
        (void)mca_geo_set_home(&ins->home, fix->lat_e7, fix->lon_e7, has_alt ? fix->alt_mm : 0);
        ins->home_set = 1u;
        const float lat = (float)fix->lat_e7 * E7_TO_RAD;
        ins->g_align_mps2 = mca_geo_gravity(lat, (float)ins->home.alt_mm * 1e-3f);
    }
    mca_status_t st = MCA_OK;
    if (!ins->aligned) {
        ins->n_gps_skip++;
    } else if (!ins->nav) {
        /* navigation starts with the heading known (ALGORITHMS.md 10, Start of navigation) */
        float q_now[4];
        memcpy(q_now, ins->q_nb, sizeof(q_now));
        cog_align(ins, vel, has_vne, s_acc, q_now);
        if (ins->yaw_aligned) {
            start_nav(ins, fix, vel, vmask, h_acc, v_acc, s_acc);
        } else {
            ins->n_gps_skip++;
        }
    } else {
        ins_sol_t s;
        if (!solution_at(ins, fix->t_us, &s)) {
            ins->flags |= MCA_INS_FLAG_HIST_MISS;
            ins->n_gps_skip++;
        } else {
            ins->flags &= ~(uint32_t)MCA_INS_FLAG_HIST_MISS;
            st = gnss_update(ins, fix, &s, vel, vmask, r_pos, s_acc);
            if (st != MCA_OK) {
                return st; /* the failed block changed nothing (ALGORITHMS.md 10, GNSS update step 5) */
            }
        }
    }
    ins->have_fix = 1u;
    ins->t_lastfix_us = fix->t_us;
    ins->rx_q[0] = rx_q[0];
    ins->rx_q[1] = rx_q[1];
    ins->fix_speed_mps = has_vne ? sqrtf(vel[0] * vel[0] + vel[1] * vel[1]) : -1.0f;
    return st;
}

/* ------------------------------------------------------------------------ magnetometer */

mca_status_t mca_ins_mag(mca_ins_t *ins, uint64_t t_us, const float mag_b[3])
{
    if (ins == NULL || mag_b == NULL) {
        return MCA_ERR_NULL;
    }
    if (!mca_all_finite(mag_b, 3u)) {
        return MCA_ERR_NONFINITE;
    }
    if (ins->cfg.yaw_source != MCA_YAW_MAG || !ins->aligned) {
        return MCA_OK;
    }
    if (ins->have_mag && (t_us < ins->t_lastmag_us || t_us - ins->t_lastmag_us < us(ins->cfg.mag_period_s))) {
        return MCA_OK;
    }
    if (ins->yaw_aligned && !ins->nav) {
        return MCA_OK; /* updates only while navigating */
    }
    float e[3];
    mca_quat_to_euler(e, ins->q_nb);
    if (!(norm3(mag_b) > 0.0f) || fabsf(e[1]) > MAG_MAX_TILT) {
        return MCA_OK; /* gate: skipped */
    }
    /* tilt-compensated heading (ALGORITHMS.md 7): m_l = R_y(theta) R_x(phi) m_b */
    float sp, cp, st, ct;
    mca_sincosf(e[0], &sp, &cp);
    mca_sincosf(e[1], &st, &ct);
    const float mlx = ct * mag_b[0] + st * sp * mag_b[1] + st * cp * mag_b[2];
    const float mly = cp * mag_b[1] - sp * mag_b[2];
    const float psi_m = mca_atan2f(-mly, mlx) + ins->cfg.mag_declination_rad;
    const float sig2 = ins->cfg.mag_yaw_sigma_rad * ins->cfg.mag_yaw_sigma_rad;
    if (!ins->yaw_aligned) {
        yaw_turn(ins, mca_wrap_pi(psi_m - e[2]), sig2);
    } else {
        float c[9];
        mca_quat_to_dcm(c, ins->q_nb);
        const float d = c[0] * c[0] + c[3] * c[3];
        float *h = ins->upd_h;
        memset(h, 0, NX * sizeof(float));
        h[MCA_INS_PHI] = -c[0] * c[6] / d;
        h[MCA_INS_PHI + 1u] = -c[3] * c[6] / d;
        h[MCA_INS_PHI + 2u] = 1.0f;
        ins->upd_z[0] = mca_wrap_pi(psi_m - e[2]);
        ins->upd_r[0] = sig2;
        memset(ins->dx, 0, sizeof(ins->dx));
        const mca_status_t s = mca_kf_update_tested(ins->dx, ins->p, NX, h, ins->upd_z, ins->upd_r, 1u, NULL, NULL,
                                                    NULL, NULL, ins->ws, MCA_INS_WS_LEN, NULL);
        if (s != MCA_OK) {
            return s;
        }
        correct(ins, ins->dx);
    }
    ins->have_mag = 1u;
    ins->t_lastmag_us = t_us;
    return MCA_OK;
}

/* ------------------------------------------------------------------------ output, replay */

void mca_ins_output(const mca_ins_t *ins, mca_ins_output_t *out)
{
    if (ins == NULL || out == NULL) {
        return;
    }
    memset(out, 0, sizeof(*out));
    out->t_us = ins->t_imu_us;
    memcpy(out->q_nb, ins->q_nb, sizeof(out->q_nb));
    mca_quat_to_euler(out->euler_rad, ins->q_nb);
    if (ins->nav) {
        pos_home_ned(ins, out->pos_ned_m);
    }
    memcpy(out->vel_ned_mps, ins->vel_ned_mps, sizeof(out->vel_ned_mps));
    out->lat_e7 = ins->lat_e7;
    out->lon_e7 = ins->lon_e7;
    out->alt_mm = ins->alt_mm;
    memcpy(out->gyro_bias_rps, ins->bg_rps, sizeof(out->gyro_bias_rps));
    memcpy(out->accel_bias_mps2, ins->ba_mps2, sizeof(out->accel_bias_mps2));
    for (size_t i = 0; i < NX; ++i) {
        out->p_diag[i] = ins->p[i * (NX + 1u)];
    }
    out->gps_t = ins->last_gps_t;
    out->gps_m = ins->last_gps_m;
    uint32_t f = ins->flags;
    f |= ins->aligned ? (uint32_t)MCA_INS_FLAG_ALIGNED : 0u;
    f |= ins->home_set ? (uint32_t)MCA_INS_FLAG_HOME_SET : 0u;
    f |= ins->nav ? (uint32_t)MCA_INS_FLAG_NAV : 0u;
    f |= ins->yaw_aligned ? (uint32_t)MCA_INS_FLAG_YAW_ALIGNED : 0u;
    const int lost = !ins->have_fix ||
                     (ins->t_imu_us > ins->t_lastfix_us && ins->t_imu_us - ins->t_lastfix_us > us(ins->cfg.gps_timeout_s));
    f |= lost ? (uint32_t)MCA_INS_FLAG_GPS_LOST : 0u;
    out->flags = f;
    out->n_gps_upd = ins->n_gps_upd;
    out->n_gps_rej = ins->n_gps_rej;
    out->n_gps_skip = ins->n_gps_skip;
}

mca_status_t mca_ins_replay(mca_ins_t *ins, const mca_imu_sample_t *imu, size_t n_imu, const mca_gps_event_t *gps,
                            size_t n_gps, const mca_mag_sample_t *mag, size_t n_mag, mca_ins_output_t *out,
                            uint8_t *imu_status, uint8_t *gps_status, uint8_t *mag_status)
{
    if (ins == NULL || (n_imu > 0u && (imu == NULL || out == NULL)) || (n_gps > 0u && gps == NULL) ||
        (n_mag > 0u && mag == NULL)) {
        return MCA_ERR_NULL;
    }
    mca_replay_cursor_t c = {0u, 0u, 0u};
    int ev;
    /* bounded: each pass consumes one event; the order of ALGORITHMS.md 9 (mca_replay_next) */
    while ((ev = mca_replay_next(&c, imu, n_imu, gps, n_gps, mag, n_mag)) != MCA_EVENT_NONE) {
        if (ev == MCA_EVENT_IMU) {
            const mca_status_t st = mca_ins_imu(ins, imu[c.i].t_us, imu[c.i].gyro_b_rps, imu[c.i].accel_b_mps2);
            if (imu_status != NULL) {
                imu_status[c.i] = (uint8_t)st;
            }
            mca_ins_output(ins, &out[c.i]);
            ++c.i;
        } else if (ev == MCA_EVENT_GPS) {
            const mca_status_t st = mca_ins_gps(ins, &gps[c.j].fix);
            if (gps_status != NULL) {
                gps_status[c.j] = (uint8_t)st;
            }
            ++c.j;
        } else {
            const mca_status_t st = mca_ins_mag(ins, mag[c.k].t_us, mag[c.k].mag_b);
            if (mag_status != NULL) {
                mag_status[c.k] = (uint8_t)st;
            }
            ++c.k;
        }
    }
    return MCA_OK;
}

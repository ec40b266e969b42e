/* Navigation top level (DESIGN.md 4, docs/ALGORITHMS.md 8). See mca_nav.h. */
#include "mcahrs/mca_nav.h"
#include "mca_att_nocheck.h"
#include "mca_cold.h"
#include "mca_cs_nocheck.h"
#include "mca_defaults.h"
#include "mca_geo_nocheck.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

#define DEG 0.0174532925199433f
#define G0 9.80665f
#define YAW_STALE_US 10000000u
#define COG_GATE_N 10u          /* the course gate's guard: refusals in a row, */
#define COG_GATE_US 30000000u   /* and no yaw observation for this long (GPS step 6), */
#define COG_GATE_ARMED_US 120000000u /* or this long while the step test is armed */
#define STEP_HOLD_US 20000000u /* the velocity step test's hold in the whole-update modes (GPS step 3) */

/* compile-time check: the shared scratch fits both updates */
typedef char mca_nav_ws_fits_cs[(MCA_NAV_WS_LEN >= MCA_CS_WS_LEN) ? 1 : -1];
/* the ring's head and count are uint8_t */
typedef char mca_nav_hist_fits_u8[(MCA_HIST_LEN <= 255) ? 1 : -1];

MCA_COLD void mca_nav_config_default(mca_nav_config_t *c)
{
    static const mca_nav_config_t d = {
        .cs_h = MCA_CS_CONFIG_H_INIT(1.0f), /* ALGORITHMS.md 8: the presets' CS tuning (tau_a 2 s) */
        .cs_v = MCA_CS_CONFIG_V_INIT,
        .att = MCA_ATT_CONFIG_INIT((30.0f * DEG) * (30.0f * DEG)),
        .comp_mode = MCA_COMP_CS,
        .yaw_source = MCA_YAW_COG, /* a ground vehicle moves along its nose */
        .cs_lag_s = 0.2f,
        .gps_timeout_s = 1.5f,
        .grav_period_s = 0.1f,
        .nogps_rp_var_rad2 = 0.05f * 0.05f,
        .nogps_centripetal = 1u,
        .gravity_mps2 = 0.0f,
        .imu_dt_max_s = 0.1f,
        .init_still_s = 1.0f,
        .init_gyro_still_rps = 0.05f,
        .init_acc_still_mps2 = 0.5f,
        .init_timeout_s = 5.0f,
        .accel_sat_mps2 = 156.9f,
        .gps_pos_sigma_m = 2.5f,
        .gps_alt_sigma_m = 5.0f,
        .gps_vel_sigma_mps = 0.2f,
        .mag_declination_rad = 0.0f,
        .mag_yaw_sigma_rad = 0.05f,
        .cog_min_speed_mps = 3.0f,
        .cog_sigma0_rad = 0.05f,
        .gps_test_imu = 1u,
        .imu_acc_sigma_mps2 = 0.3f,
        .coast_acc_sigma_mps2 = 0.15f,
        .gps_pos_white_m = 0.0f, /* receiver model off: the reported accuracies are R */
        .gps_alt_white_m = 0.0f,
    };
    mca_copy_bytes(c, &d, sizeof d);
}

/* The presets change only what differs from the defaults (course-over-ground yaw and the 30 deg
 * initial yaw std are the defaults' too). */
MCA_COLD void mca_nav_config_fixedwing(mca_nav_config_t *c)
{
    mca_nav_config_default(c);
    c->cog_min_speed_mps = 5.0f;
    c->cs_h.a_max_mps2 = 8.0f;
}

MCA_COLD void mca_nav_config_multirotor(mca_nav_config_t *c)
{
    mca_nav_config_default(c);
    c->yaw_source = MCA_YAW_MAG;
    c->nogps_centripetal = 0u; /* a multirotor does not move along its nose */
    c->cs_h.a_max_mps2 = 5.0f;
    c->cs_lag_s = 0.3f;
}

/* A configured duration in integer microseconds (ALGORITHMS.md 8, Times). Durations are
 * checked to be far below 71 minutes, so uint32: one vcvt on the M4F, where float <-> 64-bit
 * integer conversions are library calls through soft double. Not inlined: its constants and
 * conversion at each of its nine call sites cost 108 B of flash more than the calls. */
MCA_NOINLINE static uint32_t us(float s)
{
    return (uint32_t)(s * 1e6f + 0.5f);
}

/* Seconds from a to b (b >= a) on the IMU clock, saturating at 71 minutes (uint32 us). Not
 * inlined: the 64-bit difference and saturation at its five call sites cost 80 B more. */
MCA_NOINLINE static float span_s(uint64_t a, uint64_t b)
{
    const uint64_t d = b - a;
    return (float)(d > (uint64_t)UINT32_MAX ? UINT32_MAX : (uint32_t)d) * 1e-6f;
}

MCA_COLD mca_status_t mca_nav_config_check(const mca_nav_config_t *c)
{
    if (c == NULL) {
        return MCA_ERR_NULL;
    }
    if (mca_cs_config_check(&c->cs_h) != MCA_OK || mca_cs_config_check(&c->cs_v) != MCA_OK ||
        mca_att_config_check(&c->att) != MCA_OK) {
        return MCA_ERR_BAD_CONFIG;
    }
    /* the pairing delay plus one entry must fit in the history ring */
    const float hist_s = (float)(MCA_HIST_LEN - 1) * (float)MCA_HIST_DT_US * 1e-6f;
    /* the float fields: bit k of nonneg set, field k >= 0; else > 0; all finite */
    static const uint16_t off[] = {
        offsetof(mca_nav_config_t, cs_lag_s),          offsetof(mca_nav_config_t, gps_timeout_s),
        offsetof(mca_nav_config_t, grav_period_s),     offsetof(mca_nav_config_t, nogps_rp_var_rad2),
        offsetof(mca_nav_config_t, gravity_mps2),      offsetof(mca_nav_config_t, imu_dt_max_s),
        offsetof(mca_nav_config_t, init_still_s),      offsetof(mca_nav_config_t, init_gyro_still_rps),
        offsetof(mca_nav_config_t, init_acc_still_mps2), offsetof(mca_nav_config_t, init_timeout_s),
        offsetof(mca_nav_config_t, accel_sat_mps2),    offsetof(mca_nav_config_t, gps_pos_sigma_m),
        offsetof(mca_nav_config_t, gps_alt_sigma_m),   offsetof(mca_nav_config_t, gps_vel_sigma_mps),
        offsetof(mca_nav_config_t, mag_yaw_sigma_rad), offsetof(mca_nav_config_t, cog_min_speed_mps),
        offsetof(mca_nav_config_t, cog_sigma0_rad),    offsetof(mca_nav_config_t, imu_acc_sigma_mps2),
        offsetof(mca_nav_config_t, coast_acc_sigma_mps2),
        offsetof(mca_nav_config_t, gps_pos_white_m),   offsetof(mca_nav_config_t, gps_alt_white_m)};
    const uint32_t nonneg = 0x1u | 0x8u | 0x10u | 0x80u | 0x100u | 0x8000u | 0x20000u | 0x40000u | 0x80000u | 0x100000u;
    if (c->comp_mode > MCA_COMP_VELDIFF || c->yaw_source > MCA_YAW_COG || c->cs_lag_s > hist_s ||
        !mca_fields_ok(c, off, sizeof off / sizeof off[0], nonneg) || c->nogps_centripetal > 1u ||
        !isfinite(c->mag_declination_rad) || c->gps_test_imu > 1u) {
        return MCA_ERR_BAD_CONFIG;
    }
    return MCA_OK;
}

MCA_COLD mca_status_t mca_nav_init(mca_nav_t *nav, const mca_nav_config_t *cfg)
{
    if (nav == NULL || cfg == NULL) {
        return MCA_ERR_NULL;
    }
    const mca_status_t st = mca_nav_config_check(cfg);
    if (st != MCA_OK) {
        return st;
    }
    mca_zero_bytes(nav, sizeof(*nav));
    mca_copy_bytes(&nav->cfg, cfg, sizeof(nav->cfg));
    nav->g_mps2 = cfg->gravity_mps2 > 0.0f ? cfg->gravity_mps2 : G0;
    nav->hist_dt_q = MCA_HIST_DT_US / 250u;
    nav->att.q_nb[0] = 1.0f;
    for (size_t i = 0; i < 3u; ++i) {
        nav->last_gps_t[i] = NAN;
    }
    return MCA_OK;
}

/* Not inlined into its two calls (the alignment's still test): 16 B of flash less. */
MCA_NOINLINE static float norm3(const float v[3])
{
    return sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

static void align(mca_nav_t *nav, const float f_mean[3], const float bias[3], float att_var_rad2)
{
    const float eul[3] = {mca_atan2f(-f_mean[1], -f_mean[2]),
                          mca_atan2f(f_mean[0], sqrtf(f_mean[1] * f_mean[1] + f_mean[2] * f_mean[2])), 0.0f};
    float q[4];
    mca_quat_from_euler(q, eul);
    mca_att_init_nocheck(&nav->att, &nav->cfg.att, q, bias); /* config checked at init; means of finite samples */
    nav->att.p[0] = att_var_rad2; /* roll and pitch: this alignment's variance, not att0_var */
    nav->att.p[7] = att_var_rad2;
    nav->aligned = 1u;
    nav->t_lastgrav_us = nav->t_imu_us;
}

/* ALGORITHMS.md 8, IMU step 4: block means, and the all-time mean at the timeout. */
static void accumulate_alignment(mca_nav_t *nav, const float w[3], const float f[3], uint32_t dt_us)
{
    for (size_t i = 0; i < 3u; ++i) {
        nav->u.init.f_sum[i] += f[i];
        nav->u.init.w_sum[i] += w[i];
        nav->u.init.f_all[i] += f[i];
    }
    nav->u.init.n++;
    nav->u.init.n_all++;
    nav->u.init.win_us += dt_us;
    const float zero[3] = {0.0f, 0.0f, 0.0f};
    if (nav->u.init.win_us >= us(nav->cfg.init_still_s)) {
        const float inv = 1.0f / (float)nav->u.init.n;
        float fm[3], wm[3];
        for (size_t i = 0; i < 3u; ++i) {
            fm[i] = nav->u.init.f_sum[i] * inv;
            wm[i] = nav->u.init.w_sum[i] * inv;
        }
        /* moving by GPS: the newest fix's horizontal speed (ALGORITHMS.md 8, IMU step 4) */
        const int moving = nav->have_fix && (nav->prev_vel_mask & 3u) == 3u &&
                           nav->vel_prev[0] * nav->vel_prev[0] + nav->vel_prev[1] * nav->vel_prev[1] > 0.25f;
        if (!moving && norm3(wm) <= nav->cfg.init_gyro_still_rps &&
            fabsf(norm3(fm) - nav->g_mps2) <= nav->cfg.init_acc_still_mps2) {
            align(nav, fm, wm, nav->cfg.att.att0_var_rad2);
            return;
        }
        for (size_t i = 0; i < 3u; ++i) { /* not still: the next block */
            nav->u.init.f_sum[i] = 0.0f;
            nav->u.init.w_sum[i] = 0.0f;
        }
        nav->u.init.n = 0u;
        nav->u.init.win_us = 0u;
    }
    if (nav->t_imu_us - nav->t_first_us >= us(nav->cfg.init_timeout_s)) {
        const float inv = 1.0f / (float)nav->u.init.n_all;
        const float fa[3] = {nav->u.init.f_all[0] * inv, nav->u.init.f_all[1] * inv, nav->u.init.f_all[2] * inv};
        align(nav, fa, zero, 25.0f * nav->cfg.att.att0_var_rad2);
    }
}

static void hist_accumulate(mca_nav_t *nav, const float f[3], uint32_t dt_us, int sat)
{
    for (size_t i = 0; i < 3u; ++i) {
        nav->hist_f_sum[i] += f[i];
    }
    nav->hist_n++;
    nav->hist_acc_us += dt_us;
    nav->hist_sat = (uint8_t)(nav->hist_sat | (sat ? 1u : 0u));
    if (nav->hist_acc_us >= (uint32_t)nav->hist_dt_q * 250u) {
        mca_hist_entry_t *e = &nav->hist[nav->hist_head];
        const float inv = 1.0f / (float)nav->hist_n;
        e->t_us = (uint32_t)nav->t_imu_us;
        for (size_t i = 0; i < 3u; ++i) {
            e->f_b_mps2[i] = nav->hist_f_sum[i] * inv;
            nav->hist_f_sum[i] = 0.0f;
        }
        memcpy(e->q_nb, nav->att.q_nb, sizeof(e->q_nb));
        e->saturated = nav->hist_sat;
        nav->hist_head = (uint8_t)((nav->hist_head + 1u) % MCA_HIST_LEN);
        if (nav->hist_count < MCA_HIST_LEN) {
            nav->hist_count++;
        }
        nav->hist_n = 0u;
        nav->hist_acc_us = 0u;
        nav->hist_sat = 0u;
    }
}

static uint16_t hist_oldest(const mca_nav_t *nav)
{
    return (uint16_t)((nav->hist_head + MCA_HIST_LEN - nav->hist_count) % MCA_HIST_LEN);
}

static const mca_hist_entry_t *hist_at(const mca_nav_t *nav, uint16_t oldest, uint16_t k)
{
    return &nav->hist[(oldest + k) % MCA_HIST_LEN];
}

/* Position k (0 = oldest) of the first entry whose time is >= t32, hist_count if none. Entry
 * times increase strictly (one push per >= MCA_HIST_DT_US), so a binary search on the
 * wrap-safe signed differences of the low 32 bits (the ring spans < 2.4 s) does it. Not inlined
 * into its two callers (24 B); hist_at stays inlined in its loop (as a call it cost ~220
 * instructions on the longest GPS step). */
MCA_NOINLINE static uint16_t hist_lower_bound(const mca_nav_t *nav, uint16_t oldest, uint32_t t32)
{
    uint16_t lo = 0u, hi = nav->hist_count;
    while (lo < hi) {
        const uint16_t mid = (uint16_t)((lo + hi) / 2u);
        if ((int32_t)(hist_at(nav, oldest, mid)->t_us - t32) < 0) {
            lo = (uint16_t)(mid + 1u);
        } else {
            hi = mid;
        }
    }
    return lo;
}

/* Entry nearest t (ties: the older); NULL when empty or t older than the oldest entry. */
static const mca_hist_entry_t *hist_find(const mca_nav_t *nav, int64_t t)
{
    if (nav->hist_count == 0u) {
        return NULL;
    }
    const uint16_t oldest = hist_oldest(nav);
    const uint32_t t32 = (uint32_t)t;
    if ((int32_t)(t32 - nav->hist[oldest].t_us) < 0) {
        return NULL;
    }
    /* the nearest is the first entry at or after t, or the one before it (older on ties) */
    const uint16_t k = hist_lower_bound(nav, oldest, t32);
    const mca_hist_entry_t *before = hist_at(nav, oldest, (uint16_t)(k != 0u ? k - 1u : 0u));
    if (k == 0u || k == nav->hist_count) {
        return before; /* k 0: t is the oldest entry's time */
    }
    const mca_hist_entry_t *after = hist_at(nav, oldest, k);
    return (after->t_us - t32) < (t32 - before->t_us) ? after : before;
}

/* Newest entry; NULL when empty. Not inlined into its three callers (20 B). */
MCA_NOINLINE static const mca_hist_entry_t *hist_newest(const mca_nav_t *nav)
{
    if (nav->hist_count == 0u) {
        return NULL;
    }
    return &nav->hist[(nav->hist_head + MCA_HIST_LEN - 1u) % MCA_HIST_LEN];
}

/* mca_nav_t.grav_pending */
enum { GRAV_NONE = 0, GRAV_UPDATE = 1, GRAV_SKIP = 2, GRAV_NO_HIST = 3 };

/* A skipped observation attempt (no usable input). Not inlined into its three callers: 12 B of
 * flash less. */
MCA_NOINLINE static void gravity_skip(mca_nav_t *nav)
{
    nav->flags |= MCA_FLAG_GRAV_SKIPPED;
    nav->n_grav_skip++;
}

/* The counters and flags of a roll/pitch observation attempt: no history entry (hist_miss), or
 * the status of its update (a saturated entry, a gate or a failed update: skipped, not an error
 * of the caller, ALGORITHMS.md 8). */
static void gravity_done(mca_nav_t *nav, int hist_miss, mca_status_t st)
{
    const uint32_t f = nav->flags & ~(uint32_t)MCA_FLAG_HIST_MISS;
    nav->flags = hist_miss ? f | MCA_FLAG_HIST_MISS : f;
    if (hist_miss || st != MCA_OK) {
        gravity_skip(nav);
        return;
    }
    nav->flags &= ~(uint32_t)MCA_FLAG_GRAV_SKIPPED;
    nav->n_grav_obs++;
}

/* One roll/pitch observation from a history entry, at its attitude; counts and flags. */
/* No report: its 212 B would sit on the deepest stack chain; T is read from the attitude
 * filter's robust memory instead. */
static void gravity_obs(mca_nav_t *nav, const mca_hist_entry_t *e, const float acc_n[3], float r_acc)
{
    const mca_status_t st =
        e == NULL || e->saturated
            ? MCA_ERR_BAD_ARG
            : mca_att_gravity_nocheck(&nav->att, e->f_b_mps2, acc_n, e->q_nb, nav->g_mps2, r_acc, nav->ws);
    gravity_done(nav, e == NULL, st);
}

/* Yaw observation, or the alignment when yaw was never observed (ALGORITHMS.md 7). */
static mca_status_t yaw_obs(mca_nav_t *nav, float psi_m, float r, const float q_d[4], float gate)
{
    /* psi_m finite and r finite, > 0: as the yaw update, the alignment takes them unchecked */
    mca_status_t st = MCA_OK;
    if (nav->have_yaw_obs) {
        st = mca_att_yaw_nocheck(&nav->att, psi_m, r, q_d, nav->ws, gate);
    } else {
        mca_att_align_yaw_nocheck(&nav->att, psi_m, r);
    }
    if (st == MCA_OK) {
        nav->t_lastyaw_us = nav->t_imu_us;
        nav->have_yaw_obs = 1u;
    }
    return st;
}

/* No yaw observation in the last 10 s of IMU time (always so with no yaw source): the output
 * flag, its one caller since N and E are aided once yaw was observed (GPS step 3). */
static int yaw_unobserved(const mca_nav_t *nav)
{
    return nav->cfg.yaw_source == MCA_YAW_NONE || !nav->have_yaw_obs ||
           nav->t_imu_us - nav->t_lastyaw_us > (uint64_t)YAW_STALE_US;
}

/* One ring interval of o_us microseconds at the NED acceleration of history entry e,
 * a = C_nb(q) f + [0, 0, g] (DESIGN.md 2): dp += v o + a o^2 / 2 with v the running dv, then
 * dv += a o. One function for the entries and the hold past the newest (60 B less flash than
 * the rotation inlined at both). */
static void integrate(const mca_nav_t *nav, const mca_hist_entry_t *e, int32_t o_us, mca_cs_inc_t inc[3])
{
    float a[3];
    mca_quat_rotate(a, e->q_nb, e->f_b_mps2);
    a[2] += nav->g_mps2;
    const float o = (float)o_us * 1e-6f;
    for (size_t i = 0; i < 3u; ++i) {
        inc[i].dp_m += inc[i].dv_mps * o + 0.5f * a[i] * o * o;
        inc[i].dv_mps += a[i] * o;
    }
}

/* IMU velocity and position increments over (t0, t1] from the history ring into inc[i].dv_mps
 * and dp_m (ALGORITHMS.md 8, GPS step 3): entry k covers (t_k-1, t_k] with its mean f and its
 * q; past the newest entry its acceleration is held for at most two spacings (an entry pushed
 * once its samples reach one, and a fix up to a sample past the newest: session 33). 1 when the
 * ring covers the interval (the oldest entry ends at or before t0) and no entry used is
 * saturated; 0 otherwise. */
static int hist_increments(const mca_nav_t *nav, uint64_t t0, uint64_t t1, mca_cs_inc_t inc[3])
{
    if (nav->hist_count < 2u || t1 - t0 > (uint64_t)INT32_MAX) {
        return 0;
    }
    const uint32_t t1_32 = (uint32_t)t1;
    const int32_t r0 = -(int32_t)(uint32_t)(t1 - t0); /* times relative to t1, wrap-safe */
    const uint16_t oldest = hist_oldest(nav);
    if ((int32_t)(nav->hist[oldest].t_us - t1_32) > r0) {
        return 0;
    }
    for (size_t i = 0; i < 3u; ++i) { /* (acc_var is the caller's) */
        inc[i].dp_m = 0.0f;
        inc[i].dv_mps = 0.0f;
    }
    /* from the entry before the first one ending after t0 (k0 >= 1: the oldest ends at or before t0) */
    const uint16_t k0 = hist_lower_bound(nav, oldest, (uint32_t)t0 + 1u);
    int32_t prev = (int32_t)(hist_at(nav, oldest, (uint16_t)(k0 - 1u))->t_us - t1_32);
    for (uint16_t k = k0; k < nav->hist_count && prev < 0; ++k) {
        const mca_hist_entry_t *e = hist_at(nav, oldest, k);
        const int32_t end = (int32_t)(e->t_us - t1_32);
        const int32_t lo = prev > r0 ? prev : r0;
        const int32_t hi = end < 0 ? end : 0;
        prev = end;
        if (hi <= lo) {
            continue;
        }
        if (e->saturated) {
            return 0;
        }
        integrate(nav, e, hi - lo, inc);
    }
    if (prev < 0) {
        const mca_hist_entry_t *e = hist_newest(nav);
        if (-prev > (int32_t)nav->hist_dt_q * 500 || e->saturated) {
            return 0;
        }
        integrate(nav, e, -prev, inc);
    }
    return 1;
}

/* GPS step 4, the receiver model: the part of a position std that is white, R's; the CS
 * GPS-error state carries the rest. white 0: all of it. */
MCA_NOINLINE static float white_part(float acc, float white)
{
    return (white > 0.0f && white < acc) ? white : acc;
}

/* The fuzzy-rows profile (ALGORITHMS.md 5: fuzzy, fuzzy_reject 2): the step test's hold leaves its
 * velocity rows out, and the position return rule does not run for it (GPS steps 3, 4).
 * fix_flagged spells it out with IGG-III: through this helper there it cost 8 B of flash and 8
 * instructions a GPS step. */
static inline int fuzzy_rows(const mca_robust_config_t *rc)
{
    return rc->mode == (uint8_t)MCA_ROBUST_FUZZY && rc->fuzzy_reject == 2u;
}

/* mca_nav_t.step_flags; PRE: the step test ran on the last fix (so u.step.pre is its); RET: this
 * fix restarts the CS, the end of a fault it took in (set by gps_cs: GPS steps 3 and 4); REF:
 * u.step.ref holds the position reference, in fuzzy rows the position hold's anchor (aligned only,
 * set by gps_cs: GPS step 4); PHOLD: fuzzy rows' position hold holds, PIN: and the whole-update
 * guard took its step in (GPS step 4) */
enum {
    STEP_ANCHOR = 1u,
    STEP_ARMED = 2u,
    STEP_TESTED = 4u,
    STEP_PRE = 8u,
    STEP_RET = 16u,
    STEP_REF = 32u,
    STEP_PHOLD = 64u,
    STEP_PIN = 128u
};

/* The fuzzy memories of N and E: a hold of the rows held (MCA_CS_POS or MCA_CS_VEL) leaves them out
 * of both updates with the alarm (the pair rows, started; D raised to at least 2); held 0, the end
 * of a hold, lowers D to at most 1. */
MCA_NOINLINE static void step_dk(mca_nav_t *nav, uint8_t held)
{
    const float v = held != 0u ? 2.0f : 1.0f;
    for (size_t i = 0; i < 2u; ++i) {
        mca_robust_state_t *rs = &nav->cs.axis[i].rs;
        rs->started |= held;
        rs->d_k = (held != 0u ? rs->d_k < v : rs->d_k > v) ? v : rs->d_k;
    }
}

/* The receiver's position error over t (ALGORITHMS.md 8, GPS steps 3 and 4): the white part w at
 * both ends and the Gauss-Markov part's wander, 2 (w^2 + sigma_p^2 t / tau_p), cs_h's. */
MCA_NOINLINE static float hold_var(const mca_nav_t *nav, float w, float t)
{
    const mca_cs_config_t *c = &nav->cs.axis[0].cfg;
    return 2.0f * (w * w + c->sigma_p_m * c->sigma_p_m * t / c->tau_p_s);
}

/* The velocity step test (ALGORITHMS.md 8, GPS step 3): the fix's N/E velocity against the
 * anchor carried on by the IMU increments. A step holds the anchor until the fix passes again
 * (and is nearer the anchor than the held step), steps back, or the guard has passed: in fuzzy
 * rows the whole-update guard's count of fixes, and the hold leaves both velocity rows out (the
 * N/E pair's rows, with the alarm); in the other modes STEP_HOLD_US of fixes, and a held fix
 * gives no course observation (GPS step 6). t_us: this fix's interval. */
MCA_NOINLINE static void step_test(mca_nav_t *nav, const mca_fix_view_t *fv, const mca_cs_inc_t inc[3], float var_h,
                                   float coast_h, float t, uint8_t hold, uint64_t t_us)
{
    const float *v = fv->vel_ned_mps;
    float pred[2], s[2], e2 = 0.0f, r2 = 0.0f, dot = 0.0f, n0 = 0.0f, ds = 0.0f, pp = 0.0f, pv = 0.0f;
    for (size_t i = 0; i < 2u; ++i) {
        pv += nav->u.step.pv[i] * nav->u.step.s0[i];
        const float ep = v[i] - nav->u.step.pre[i] - inc[i].dv_mps;
        pp += ep * ep;
        pred[i] = nav->u.step.v[i] + inc[i].dv_mps;
        s[i] = v[i] - pred[i];
        const float r = v[i] - nav->vel_prev[i] - inc[i].dv_mps; /* the raw step from the last fix */
        e2 += s[i] * s[i];
        r2 += r * r;
        dot += (hold != 0u ? r : s[i]) * nav->u.step.s0[i];
        ds += s[i] * nav->u.step.s0[i];
        n0 += nav->u.step.s0[i] * nav->u.step.s0[i];
    }
    const float g4 = mca_chi2_quantile(2u, MCA_CHI2_1E4);
    const float g = hold != 0u ? mca_chi2_quantile(2u, MCA_CHI2_5E3) : g4;
    /* lambda, the variance scale (GPS step 3): C_u is configured for real sensors and receivers */
    const float lam = 1.0f - nav->step_dlam;
    const float c_raw = lam * (2.0f * fv->s_acc_mps * fv->s_acc_mps + var_h * t * t);
    const float c_u = fv->s_acc_mps * fv->s_acc_mps + nav->u.step.var + var_h * t * t;
    const float c = lam * c_u;
    /* No fix held: a step from an anchor that the anchor before it (carried on) agrees with is
     * the anchor's, a spike that passed its own test, not this fix's. Holding: a fix nearer the
     * held step than the anchor (s . s0 >= |s0|^2 / 2) still carries the fault, however the
     * anchor's variance has grown; in fuzzy rows so does one whose held fixes' velocities, less
     * their positions' change, still say the step (nearer it than 0, beyond the receiver's
     * position error over the hold), however far the anchor has drifted, and one they say is
     * clean (within that error of 0, beyond it of the step: the anchor had the step) is released,
     * whatever the anchor says. */
    const int rows = fuzzy_rows(&nav->cs.axis[0].cfg.robust);
    const float var_p = hold_var(nav, white_part(fv->h_acc_m, nav->cfg.gps_pos_white_m), nav->u.step.pv[2]);
    const float te = n0 * nav->u.step.pv[2];
    const float kv = n0 * var_p;
    const int held_rows = rows && hold != 0u;
    const int by_pos = held_rows && 2.0f * pv >= te && pv * pv > g * kv;
    const int no_step = held_rows && pv * pv <= g * kv && (te - pv) * (te - pv) > g4 * kv;
    const int fail = !no_step && (e2 > g * c ? hold != 0u || (nav->step_flags & STEP_PRE) == 0u || pp > g * c
                                             : hold != 0u && (2.0f * ds >= n0 || by_pos));
    /* the return: the reverse of the step that started the hold, within it the raw step, after a
     * release with the fault still in the anchor's; at least 0.71 of the held step, and at most
     * 1.5 times it unless the positions say the step (s0 is one fix against the anchor) */
    const float q = hold != 0u ? r2 : e2;
    const int ret = fail && dot < 0.0f && dot * dot >= 0.5f * q * n0 && q >= 0.5f * n0 && (by_pos || q <= 2.25f * n0) &&
                    (hold != 0u ? r2 > g4 * c_raw : (nav->step_flags & STEP_ARMED) != 0u);
    nav->step_flags |= STEP_TESTED;
    if (hold == 0u && e2 <= g * c) { /* lambda: the mean of |s|^2 / 2 C_u of fixes that pass on their own */
        const float l = lam * (31.0f / 32.0f) + e2 / (64.0f * c_u);
        nav->step_dlam = 1.0f - (l < 0.25f ? 0.25f : (l > 1.0f ? 1.0f : l));
    }
    const int guard = rows ? hold < nav->cs.axis[0].cfg.robust.reject_reset_n : hold * t_us < STEP_HOLD_US;
    if (fail && !ret && guard) {
        if (hold == 0u) {
            mca_copyf(nav->u.step.s0, s, 2u);
            nav->step_flags &= (uint8_t)~STEP_ARMED;
        }
        mca_copyf(nav->u.step.v, pred, 2u);
        nav->u.step.var += coast_h * t * t;
        nav->step_hold = (uint8_t)(hold + 1u);
        if (rows) {
            step_dk(nav, MCA_CS_VEL);
        }
    } else {
        if (ret || hold != 0u) {
            /* a release with the fault still in (no raw step) arms the return; else the fault ended,
             * one the CS took in unless the positions released it (the anchor had the step) */
            const int armed = !ret && !no_step && r2 <= g * c_raw;
            nav->step_flags = (uint8_t)(armed ? nav->step_flags | STEP_ARMED : nav->step_flags & ~STEP_ARMED);
            if (!armed) {
                if (rows) {
                    step_dk(nav, 0u);
                }
                nav->step_flags = (uint8_t)(no_step ? nav->step_flags : nav->step_flags | STEP_RET);
            }
        }
        mca_copyf(nav->u.step.pre, pred, 2u);
    }
}

/* CS predict over t to the fix at t_fix, IMU-aided on the axes where that is possible
 * (ALGORITHMS.md 8, GPS step 3). */
MCA_NOINLINE static void cs_predict(mca_nav_t *nav, uint64_t t_fix, float t, const mca_fix_view_t *fv)
{
    const uint8_t hold = nav->step_hold;
    nav->step_hold = 0u;
    nav->step_flags &= (uint8_t)~(STEP_TESTED | STEP_RET); /* this fix's, set by step_test */
    mca_cs_inc_t inc[3];
    const mca_cs_inc_t *use[3] = {NULL, NULL, NULL};
    if (nav->cfg.gps_test_imu && nav->aligned && hist_increments(nav, nav->t_lastfix_us, t_fix, inc)) {
        const float *pa = nav->att.p;
        const float g2 = nav->g_mps2 * nav->g_mps2;
        const float s2 = nav->cfg.imu_acc_sigma_mps2 * nav->cfg.imu_acc_sigma_mps2;
        const float c2 = nav->cfg.coast_acc_sigma_mps2 * nav->cfg.coast_acc_sigma_mps2;
        /* tilt error: g d theta horizontally; yaw error turns the mean horizontal acceleration */
        const float ah2 = (inc[0].dv_mps * inc[0].dv_mps + inc[1].dv_mps * inc[1].dv_mps) / (t * t);
        const float var_h = s2 + g2 * (pa[0] + pa[7]) + ah2 * pa[14];
        const float coast_h = c2 + g2 * (pa[0] + pa[7]) + ah2 * pa[14];
        /* N and E are aided once yaw was observed: a yaw gone stale (a car's stop) is in var_h
         * (P_att[2][2]). The increments of finite history entries are finite; a variance that
         * overflowed (P_att huge) leaves the fix with the CS filter's own test. */
        const int aid_h = nav->have_yaw_obs != 0u && isfinite(var_h + coast_h);
        for (size_t i = 0; i < 3u; ++i) {
            inc[i].acc_var_m2ps4 = i < 2u ? var_h : s2;
            inc[i].coast_var_m2ps4 = i < 2u ? coast_h : c2;
            use[i] = (i == 2u || aid_h) ? &inc[i] : NULL;
        }
        if (aid_h && nav->cs.axis[0].cfg.robust.mode != (uint8_t)MCA_ROBUST_PLAIN && (fv->vel_mask & 3u) == 3u &&
            (nav->step_flags & STEP_ANCHOR) != 0u) {
            step_test(nav, fv, inc, var_h, coast_h, t, hold, t_fix - nav->t_lastfix_us);
        }
    }
    /* 0 < t <= dt_max (mca_nav_gps); the increments of finite history entries are finite and
     * the variances used finite (aid_h) and >= the configured ones */
    mca_cs3_predict_aided_nocheck(&nav->cs, t, use);
}

static int gps_lost(const mca_nav_t *nav, uint64_t t)
{
    return !nav->have_fix || (t > nav->t_lastfix_us && t - nav->t_lastfix_us > us(nav->cfg.gps_timeout_s));
}

/* Roll/pitch observation while GPS is lost (ALGORITHMS.md 8, IMU step 6). */
static void nav_nogps_observation(mca_nav_t *nav, const float gyro[3])
{
    const uint64_t t_us = nav->t_imu_us;
    nav->t_lastgrav_us = t_us;
    float acc[3] = {0.0f, 0.0f, 0.0f};
    const uint8_t mode = nav->cfg.comp_mode;
    if (mode == MCA_COMP_CS && nav->have_fix) {
        const float age = span_s(nav->t_lastfix_us, t_us);
        /* the decay exp(-age / tau_a) of each axis, computed again only when tau_a changes (N
         * and E share cs_h's; the presets give D the same) */
        float tau_prev = 0.0f, d = 0.0f;
        for (size_t i = 0; i < 3u; ++i) {
            const float tau = i < 2u ? nav->cfg.cs_h.tau_a_s : nav->cfg.cs_v.tau_a_s;
            if (tau < tau_prev || tau > tau_prev) {
                d = age <= 4.0f * tau ? mca_expf(-age / tau) : 0.0f;
                tau_prev = tau;
            }
            acc[i] = d > 0.0f ? nav->acc_comp_n[i] * d : 0.0f;
        }
    }
    if (mode != MCA_COMP_OFF && nav->cfg.nogps_centripetal && nav->have_fix && (nav->prev_vel_mask & 3u) == 3u) {
        /* a vehicle moving along its nose at V, turning at w: a_b = w x [V, 0, 0] = [0, w_z V, -w_y V] */
        const float v = sqrtf(nav->vel_prev[0] * nav->vel_prev[0] + nav->vel_prev[1] * nav->vel_prev[1]);
        const float wy = gyro[1] - nav->att.bias_rps[1], wz = gyro[2] - nav->att.bias_rps[2];
        const float ab[3] = {0.0f, wz * v, -wy * v};
        float an[3];
        mca_quat_rotate(an, nav->att.q_nb, ab);
        for (size_t i = 0; i < 3u; ++i) {
            acc[i] += an[i];
        }
    }
    const float g = nav->g_mps2, sa = nav->cfg.cs_h.sigma_a0_mps2;
    const float r_acc = nav->cfg.nogps_rp_var_rad2 + sa * sa * nav->cfg.cs_h.tau_a_s / (g * g * nav->cfg.grav_period_s);
    /* the measurement now, the update at the start of the next call (grav_complete): the two
     * halves of the observation in two IMU steps */
    const mca_hist_entry_t *e = hist_newest(nav);
    if (e == NULL) {
        nav->grav_pending = GRAV_NO_HIST;
    } else if (e->saturated || mca_att_gravity_measure_nocheck(&nav->att, e->f_b_mps2, acc, g, r_acc, nav->grav_nu,
                                                               nav->grav_rows, &nav->grav_r) != MCA_OK) {
        nav->grav_pending = GRAV_SKIP;
    } else {
        nav->grav_pending = GRAV_UPDATE;
    }
}

/* The no-GPS observation the last IMU step made (ALGORITHMS.md 8, IMU step 6), completed before
 * this call changes anything: the attitude is still the one it was measured at. Nothing when none
 * is pending (the test here, not at its three callers: 8 B of flash less). */
MCA_NOINLINE static void grav_complete(mca_nav_t *nav)
{
    const uint8_t pending = nav->grav_pending;
    if (pending == GRAV_NONE) {
        return;
    }
    nav->grav_pending = GRAV_NONE;
    const mca_status_t st = pending == GRAV_UPDATE ? mca_att_gravity_apply_nocheck(&nav->att, nav->grav_nu,
                                                                                   nav->grav_rows, nav->grav_r, nav->ws)
                                                   : MCA_ERR_BAD_ARG; /* a gate or a saturated entry */
    gravity_done(nav, pending == GRAV_NO_HIST, st);
}

mca_status_t mca_imu_clock_step(uint64_t *t_last_us, uint64_t *t_first_us, uint8_t *have, uint64_t t_us,
                                const float gyro[3], const float accel[3], uint32_t dt_max_us, uint32_t *dt_us)
{
    if (t_last_us == NULL || t_first_us == NULL || have == NULL || gyro == NULL || accel == NULL || dt_us == NULL) {
        return MCA_ERR_NULL;
    }
    *dt_us = 0u;
    if (!mca_all_finite(gyro, 3u) || !mca_all_finite(accel, 3u)) {
        return MCA_ERR_NONFINITE;
    }
    if (!*have) {
        *have = 1u;
        *t_last_us = t_us;
        *t_first_us = t_us;
        return MCA_OK;
    }
    if (t_us <= *t_last_us) {
        return MCA_ERR_TIME_BACKWARDS;
    }
    const uint64_t dt64 = t_us - *t_last_us;
    *t_last_us = t_us;
    if (dt64 > dt_max_us) {
        return MCA_ERR_BAD_DT; /* re-anchored */
    }
    *dt_us = (uint32_t)dt64;
    return MCA_OK;
}

mca_status_t mca_nav_imu(mca_nav_t *nav, uint64_t t_us, const float gyro[3], const float accel[3])
{
    if (nav == NULL || gyro == NULL || accel == NULL) {
        return MCA_ERR_NULL;
    }
    grav_complete(nav); /* the last IMU step's observation, whatever this call's inputs */
    uint32_t dt_us;
    const mca_status_t sc = mca_imu_clock_step(&nav->t_imu_us, &nav->t_first_us, &nav->have_imu, t_us, gyro, accel,
                                               us(nav->cfg.imu_dt_max_s), &dt_us);
    if (sc != MCA_OK || dt_us == 0u) {
        return sc; /* an error, or the first sample (clock anchored only) */
    }
    const float dt = (float)dt_us * 1e-6f;
    const float sat = nav->cfg.accel_sat_mps2;
    int saturated = 0;
    for (size_t i = 0; i < 3u; ++i) {
        saturated |= fabsf(accel[i]) >= sat;
    }
    if (saturated) {
        nav->flags |= MCA_FLAG_SATURATED;
    }
    if (!nav->aligned) {
        accumulate_alignment(nav, gyro, accel, dt_us);
        return MCA_OK;
    }
    mca_att_propagate_nocheck(&nav->att, gyro, dt); /* inputs checked above */
    hist_accumulate(nav, accel, dt_us, saturated);
    if (gps_lost(nav, t_us) && t_us - nav->t_lastgrav_us >= us(nav->cfg.grav_period_s)) {
        nav_nogps_observation(nav, gyro);
    }
    return MCA_OK;
}

static float sigma_or(float s, float dflt)
{
    return mca_positive(s) ? s : dflt;
}

mca_status_t mca_gps_fix_read(const mca_gps_fix_t *fix, float pos_sigma_m, float alt_sigma_m, float vel_sigma_mps,
                              mca_fix_view_t *view)
{
    if (fix == NULL || view == NULL) {
        return MCA_ERR_NULL;
    }
    if (fix->fix_type < 2u) {
        return MCA_ERR_BAD_ARG;
    }
    const int has_alt = (fix->flags & MCA_FIX_ALT) != 0u;
    const int has_vne = (fix->flags & MCA_FIX_VEL_NE) != 0u;
    const int has_vd = (fix->flags & MCA_FIX_VEL_D) != 0u;
    if (mca_geo_check(fix->lat_e7, fix->lon_e7, has_alt ? fix->alt_mm : 0) != MCA_OK) {
        return MCA_ERR_RANGE;
    }
    /* a velocity present: finite (NONFINITE wins), then within MCA_FIX_VEL_MAX_MPS (RANGE) */
    const uint8_t vmask = (uint8_t)((has_vne ? 3u : 0u) | (has_vd ? 4u : 0u));
    mca_status_t sv = MCA_OK;
    for (size_t i = 0; i < 3u; ++i) {
        const float v = ((vmask >> i) & 1u) != 0u ? fix->vel_ned_mps[i] : 0.0f;
        sv = !isfinite(v) ? MCA_ERR_NONFINITE : (fabsf(v) > MCA_FIX_VEL_MAX_MPS && sv == MCA_OK ? MCA_ERR_RANGE : sv);
        view->vel_ned_mps[i] = v;
    }
    if (sv != MCA_OK) {
        return sv;
    }
    view->vel_mask = vmask;
    view->has_alt = has_alt ? 1u : 0u;
    view->h_acc_m = sigma_or(fix->h_acc_m, pos_sigma_m);
    view->v_acc_m = sigma_or(fix->v_acc_m, alt_sigma_m);
    view->s_acc_mps = sigma_or(fix->s_acc_mps, vel_sigma_mps);
    return (mca_positive(view->h_acc_m * view->h_acc_m) && mca_positive(view->v_acc_m * view->v_acc_m) &&
            mca_positive(view->s_acc_mps * view->s_acc_mps))
               ? MCA_OK
               : MCA_ERR_BAD_ARG;
}

/* The end of a position fault the CS took in (ALGORITHMS.md 8, GPS step 4), axis i (N, E),
 * after the predict and before the update; d the position change the fixes' velocities say (or,
 * without them or on a fix the step test holds after its first, the CS's prediction). A jump of the
 * fix (its position change less d) beyond chi2_1(1e-4) of two fixes' R, or beyond a quarter of
 * the material bound, is summed, and the sum forgets over 5 tau_p. POS_RETURN when the fix is
 * material, beyond the receiver error's wandering from the CS (nu^2 > chi2_1(1e-4) (sigma_p^2 +
 * R)), and the jumps summed are within half of nu: the fixes just jumped back where they were, or
 * never left, and the CS is not (a CS that drifted from a position fault's fixes is no return);
 * gps_cs asks for this fix's jump (POS_JUMPED) too while a fault is pending on N or E
 * (POS_PENDING: the sum beyond half the material bound). The position reference, when there is
 * one, is carried on by d, and POS_NEAR when the fix is within the material bound of it. */
enum { POS_RETURN = 1, POS_NEAR = 2, POS_JUMPED = 4, POS_PENDING = 8 };
MCA_NOINLINE static int pos_return(mca_nav_t *nav, size_t i, float z, float r, float d, float t)
{
    const mca_cs_axis_t *ax = &nav->cs.axis[i];
    const float g = mca_chi2_quantile(1u, MCA_CHI2_1E4);
    const float sp = ax->cfg.sigma_p_m;
    const float b = g * (sp * sp + r);
    const float jump = z - nav->pos_prev[i] - d; /* NaN after a start: no jump */
    float e = nav->pos_jump[i];
    /* a jump is beyond two fixes' white error, and every quarter of the material bound is one:
     * R taken as all white (no receiver model) would otherwise hide a material fault */
    const int jumped = jump * jump > (2.0f * g * r < 0.25f * b ? 2.0f * g * r : 0.25f * b);
    if (jumped) {
        e += jump;
    }
    e -= e * (t / (5.0f * ax->cfg.tau_p_s));
    nav->pos_jump[i] = e;
    nav->pos_prev[i] = z;
    const float nu = z - ax->x[0] - ax->x[3];
    int near = 0;
    if ((nav->step_flags & STEP_REF) != 0u) {
        float *ref = &nav->u.step.ref[i];
        *ref += d;
        near = (z - *ref) * (z - *ref) <= b;
    }
    return (nu * nu > b && 4.0f * e * e <= nu * nu ? POS_RETURN : 0) | (near ? POS_NEAR : 0) | (jumped ? POS_JUMPED : 0) |
           (4.0f * e * e > b ? POS_PENDING : 0);
}

/* 1 when the robust mode of the N or E update of this fix flagged it (ALGORITHMS.md 8, GPS
 * step 6): FTA, AKF and fuzzy when the mode detected it or its (tested) T exceeds chi2_m(0.01);
 * IGG-III, which weighs rows, and fuzzy rows (fuzzy_reject 2) when the update left the velocity
 * row out or was rejected (the axis' aid.out, which mca_cs keeps for coasting; a position left
 * out while the velocity is applied keeps the CS acceleration). Plain mode never flags. */
static int fix_flagged(const mca_nav_t *nav, uint8_t vmask)
{
    const size_t m = (vmask & 3u) == 3u ? 2u : 1u;
    for (size_t i = 0; i < 2u; ++i) {
        const mca_cs_axis_t *ax = &nav->cs.axis[i];
        const uint8_t mode = ax->cfg.robust.mode;
        const int by_rows = mode == (uint8_t)MCA_ROBUST_IGG3 ||
                            (mode == (uint8_t)MCA_ROBUST_FUZZY && ax->cfg.robust.fuzzy_reject == 2u);
        const int flagged = by_rows ? ax->aid.out != 0u
                                    : mode != (uint8_t)MCA_ROBUST_PLAIN &&
                                          (ax->rs.detected != 0u || ax->rs.t_stat > mca_chi2_quantile(m, MCA_CHI2_1E2));
        if (flagged) {
            return 1;
        }
    }
    return 0;
}

/* CS filter (re)started at ned (a fix, or N and E at the position reference: GPS steps 2-4), no
 * compensation acceleration. Its memories' T start NaN, "no update yet": gps_cs reports an axis'
 * memory T, which only a successful update writes (a numerically failed one leaves the axis, and
 * so its T, unchanged). */
static void cs_start(mca_nav_t *nav, const float ned[3], const float vel[3])
{
    mca_cs3_init_nocheck(&nav->cs, &nav->cfg.cs_h, &nav->cfg.cs_v, ned, vel); /* checked at init and entry */
    for (size_t i = 0; i < 3u; ++i) {
        nav->acc_comp_n[i] = 0.0f;
        nav->cs.axis[i].rs.t_stat = NAN;
    }
    for (size_t i = 0; i < 2u; ++i) { /* the position return rule's memory (GPS step 4) */
        nav->pos_prev[i] = NAN;
        nav->pos_jump[i] = 0.0f;
    }
    nav->step_flags &= (uint8_t)~(STEP_REF | STEP_PHOLD | STEP_PIN); /* and its reference: the next quiet fix's */
}

/* The position hold before the update (fuzzy rows; ALGORITHMS.md 8, GPS step 4): the anchor
 * carried on by d, a fix that steps back (the reverse of the held step) disarms, and a hold is kept
 * (the N/E pair's position rows out, with the alarm) or ended. Returns PH_RESTART for a fix that
 * steps back with no hold at its start (restarted when its update leaves a position row out) and
 * PH_START for one that starts a hold when its update leaves a position row out (with no hold at
 * its start, beyond the receiver's error from the anchor). Sets pos_prev (z_prev) to the fix. w:
 * the white part of h_acc. */
enum { PH_RESTART = 1, PH_START = 2 };
MCA_NOINLINE static int pos_hold(mca_nav_t *nav, const float ned[3], const float d[2], float t, float w)
{
    const int pref = nav->aligned && (nav->step_flags & STEP_REF) != 0u;
    const int holding = (nav->step_flags & STEP_PHOLD) != 0u;
    const int pin = (nav->step_flags & STEP_PIN) != 0u;
    const float hs = (holding ? nav->pos_hold_s : 0.0f) + t;
    const float v = hold_var(nav, w, hs);
    float es = 0.0f, ss = 0.0f, rs = 0.0f, rr = 0.0f, ee = 0.0f, jj = 0.0f;
    for (size_t i = 0; i < 2u; ++i) {
        const float s0 = nav->pos_jump[i];
        const float r = ned[i] - nav->pos_prev[i] - d[i]; /* this fix's jump (NaN after a start) */
        nav->pos_prev[i] = ned[i];
        if (pref) { /* (aligned: before alignment, nav->u is the alignment's) */
            nav->u.step.ref[i] += d[i];
            const float e = ned[i] - nav->u.step.ref[i];
            es += e * s0;
            ee += (e - s0) * (e - s0);
            jj += e * e;
            rs += r * s0;
            rr += r * r;
            ss += s0 * s0;
        }
    }
    const float g4 = mca_chi2_quantile(2u, MCA_CHI2_1E4);
    const int back = rs < 0.0f && rs * rs >= 0.5f * rr * ss && fabsf(rr - 1.25f * ss) <= ss;
    if (back) {
        nav->pos_jump[0] = nav->pos_jump[1] = 0.0f;
    }
    if (pref && holding) {
        nav->pos_hold_s = hs;
        /* kept: not the step back, nearer the held step than the anchor, still the held step within
         * the receiver's wander, and within the guard or the step beyond the wander */
        if (!back && 2.0f * es >= ss && ee <= g4 * v &&
            (nav->cs.axis[0].rs.n_removed[0] < nav->cs.axis[0].cfg.robust.reject_reset_n ||
             es * es > mca_chi2_quantile(2u, MCA_CHI2_5E3) * ss * v)) {
            step_dk(nav, MCA_CS_POS);
        } else {
            nav->step_flags &= (uint8_t)~(STEP_PHOLD | STEP_REF | STEP_PIN);
            if (nav->step_hold == 0u) {
                step_dk(nav, 0u);
            }
        }
    }
    /* while holding, the step back restarts only a CS that the guard took the step into */
    return !pref ? 0 : back && (!holding || pin) ? PH_RESTART : !holding && jj > g4 * v ? PH_START : 0;
}

/* GPS steps 2-4 of a fix within dt_max of the last one (ALGORITHMS.md 8): the CS predict to
 * the fix and the three axis updates. Its own frame, so the attitude observations after it do
 * not carry its arrays on their (deeper) call chain. */
MCA_NOINLINE static mca_status_t gps_cs(mca_nav_t *nav, const mca_gps_fix_t *fix, const mca_fix_view_t *fv,
                                        const float ned[3], float t)
{
    const int has_vne = (fv->vel_mask & 3u) == 3u;
    const int has_vd = (fv->vel_mask & 4u) != 0u;
    const float s_acc = fv->s_acc_mps;
    const float h_acc = white_part(fv->h_acc_m, nav->cfg.gps_pos_white_m);
    const float v_acc = white_part(fv->v_acc_m, nav->cfg.gps_alt_white_m);
    const uint8_t mask[3] = {(uint8_t)(MCA_CS_POS | (has_vne ? MCA_CS_VEL : 0u)),
                             (uint8_t)(MCA_CS_POS | (has_vne ? MCA_CS_VEL : 0u)),
                             (uint8_t)(((fv->has_alt != 0u && fix->fix_type >= 3u) ? MCA_CS_POS : 0u) |
                                       (has_vd ? MCA_CS_VEL : 0u))};
    const float rp[3] = {h_acc * h_acc, h_acc * h_acc, v_acc * v_acc};
    const float rv[3] = {s_acc * s_acc, s_acc * s_acc, s_acc * s_acc};
    /* The values were checked where the fix entered (mca_gps_fix_read: the accuracies' squares
     * finite floats > 0; a white part in use is below its accuracy, so its square is finite, and
     * at worst 0, which the update takes: H P H^T > 0) and the masks are well formed: nothing of
     * mca_cs3_update's checks is left to make. */
    const float x0[2] = {nav->cs.axis[0].x[0], nav->cs.axis[1].x[0]};
    const uint8_t held0 = nav->step_hold; /* fixes held before this one's test */
    cs_predict(nav, fix->t_us, t, fv);
    const uint8_t held = nav->step_hold;
    const int rows = fuzzy_rows(&nav->cs.axis[0].cfg.robust);
    if (held != 0u && rows) {
        /* the step test's position check (GPS step 3): a held fix after the first adds its
         * velocity less its position change since the last fix, held too */
        for (size_t i = 0; i < 3u; ++i) {
            const float d =
                i < 2u ? 0.5f * t * (fv->vel_ned_mps[i] + nav->vel_prev[i]) - (ned[i] - nav->pos_prev[i]) : t;
            nav->u.step.pv[i] = held > 1u ? nav->u.step.pv[i] + d : 0.0f;
        }
    }
    /* the end of a position fault the CS took in (GPS step 4): the modes that take a long fault
     * in (not plain, which handles none, nor fuzzy rows, which holds the position row out); the
     * fixes' motion from their velocities (the trapezoid): a fault the CS takes in through its
     * velocity moves the CS prediction, not them; in fuzzy rows the position hold */
    int pos = 0, near = POS_NEAR, ran = 0, ax_bits[2] = {0, 0};
    const int vv = has_vne && (nav->prev_vel_mask & 3u) == 3u;
    float d[2];
    /* on a fix the step test holds after its first the fixes' velocity has the fault: the CS's
     * predicted change, as without velocities; for fuzzy rows' position hold also on the hold's
     * first fix and the fix after a held one (the trapezoid would carry a held velocity) */
    const int trapezoid = vv && (rows ? (held | held0) == 0u : held < 2u);
    for (size_t i = 0; i < 2u; ++i) {
        const mca_robust_config_t *rc = &nav->cs.axis[i].cfg.robust;
        d[i] = trapezoid ? 0.5f * t * (fv->vel_ned_mps[i] + nav->vel_prev[i]) : nav->cs.axis[i].x[0] - x0[i];
        if (rc->mode != (uint8_t)MCA_ROBUST_PLAIN && !rows) {
            const int b = pos_return(nav, i, ned[i], rp[i], d[i], t);
            pos |= b;
            near &= b;
            ax_bits[i] = b;
            ran = 1;
        }
    }
    const int ph = rows ? pos_hold(nav, ned, d, t, h_acc) : 0;
    /* an axis returns on its jump, or with no fault pending on either axis: the restart takes both
     * (GPS step 4); the bits an axis needs for it */
    const int need = (pos & POS_PENDING) != 0 ? POS_RETURN | POS_JUMPED : POS_RETURN;
    const int ret_pos = (ax_bits[0] & need) == need || (ax_bits[1] & need) == need;
    /* No report (T is read from the axis memory; N and E can then share one covariance
     * update). An axis can fail only numerically, and then it is left unchanged
     * (mca_cs_axis_update is atomic) and keeps its T. */
    const mca_status_t st = mca_cs3_update_nocheck(&nav->cs, ned, fv->vel_ned_mps, rp, rv, mask, nav->ws);
    for (size_t i = 0; i < 3u; ++i) {
        if (mask[i] != 0u) {
            nav->last_gps_t[i] = nav->cs.axis[i].rs.t_stat; /* NaN until an update succeeds */
        }
    }
    /* the end of a velocity fault the CS took in (GPS step 3): the step test's end of a fault, which
     * the CS then flags (in fuzzy rows and IGG-III: N or E left the velocity out) */
    const int flagged = fix_flagged(nav, fv->vel_mask);
    const int out = nav->cs.axis[0].rs.n_removed[0] > 0u || nav->cs.axis[1].rs.n_removed[0] > 0u;
    const int ret = ((nav->step_flags & STEP_RET) != 0u && flagged) || ret_pos || (ph == PH_RESTART && out);
    if (ret) {
        /* the restart (GPS steps 3 and 4): N and E at the position reference when the fix is
         * within the material bound of it on both, with variance sigma_p^2 (the next fix splits
         * its innovation between p and eps_p); else at the fix */
        const int at_ref = ran && near != 0 && (nav->step_flags & STEP_REF) != 0u;
        float start[3] = {ned[0], ned[1], ned[2]};
        if (at_ref) {
            mca_copyf(start, nav->u.step.ref, 2u);
        }
        cs_start(nav, start, fv->vel_ned_mps);
        for (size_t i = 0; at_ref && i < 2u; ++i) {
            nav->cs.axis[i].p[0] = nav->cs.axis[i].cfg.sigma_p_m * nav->cs.axis[i].cfg.sigma_p_m;
        }
        nav->step_flags |= STEP_RET;
    } else {
        nav->step_flags &= (uint8_t)~STEP_RET;
        /* the position hold's start (GPS step 4), or the anchor at this fix */
        if (ph == PH_START && out) {
            nav->step_flags |= STEP_PHOLD;
            nav->pos_hold_s = 0.0f;
            for (size_t i = 0; i < 2u; ++i) {
                nav->pos_jump[i] = ned[i] - nav->u.step.ref[i];
            }
        } else if (rows && nav->aligned && (nav->step_flags & STEP_PHOLD) == 0u) {
            mca_copyf(nav->u.step.ref, ned, 2u);
            nav->step_flags |= STEP_REF;
        } else if (!out && (nav->step_flags & STEP_PHOLD) != 0u) {
            nav->step_flags |= STEP_PIN; /* held, and the position rows went in: the guard's plain update */
        }
        /* the position reference: the CS position of a fix nothing was suspect in (no jump, no
         * fault pending, not flagged, not held), carried on by the fixes' motion (pos_return) */
        if (ran && nav->aligned && (pos & (POS_JUMPED | POS_PENDING)) == 0 && !flagged && nav->step_hold == 0u) {
            for (size_t i = 0; i < 2u; ++i) {
                nav->u.step.ref[i] = nav->cs.axis[i].x[0];
            }
            nav->step_flags |= STEP_REF;
        }
    }
    return st;
}

/* GPS steps 5-6 after the CS updates: the compensation acceleration, the roll/pitch
 * observation and the course-over-ground yaw observation (failures are counted skips or
 * gates, not errors). */
MCA_NOINLINE static void gps_attitude(mca_nav_t *nav, const mca_gps_fix_t *fix, const mca_fix_view_t *fv)
{
    const float *vel = fv->vel_ned_mps;
    const uint8_t vmask = fv->vel_mask;
    const float s_acc = fv->s_acc_mps;
    const float g2 = nav->g_mps2 * nav->g_mps2;
    float *const acc = nav->acc_comp_n; /* built in place: no copy on the deepest stack path */
    acc[0] = acc[1] = acc[2] = 0.0f;
    float r_acc = 0.0f;
    const int flagged = fix_flagged(nav, vmask);
    if (flagged) { /* the CS acceleration carries a fault it let in for about tau_a (GPS step 6) */
        nav->t_flag_end_us = fix->t_us + us(nav->cfg.cs_h.tau_a_s);
    }
    const int excluded = fix->t_us < nav->t_flag_end_us;
    int observe = nav->aligned;
    const mca_hist_entry_t *e = NULL;
    if (nav->cfg.comp_mode == MCA_COMP_CS) {
        for (size_t i = 0; i < 3u; ++i) {
            acc[i] = nav->cs.axis[i].x[2];
        }
        r_acc = (nav->cs.axis[0].p[12] + nav->cs.axis[1].p[12]) / (2.0f * g2);
        e = hist_find(nav, (int64_t)fix->t_us - (int64_t)us(nav->cfg.cs_lag_s));
    } else if (nav->cfg.comp_mode == MCA_COMP_VELDIFF) {
        const float dtf = span_s(nav->t_lastfix_us, fix->t_us);
        if (fix->t_us - nav->t_lastfix_us > us(nav->cfg.gps_timeout_s)) {
            observe = 0;
            if (nav->aligned) {
                gravity_skip(nav); /* no usable previous fix */
            }
        }
        for (size_t i = 0; i < 3u; ++i) {
            const uint8_t bit = (uint8_t)(1u << i);
            if ((vmask & bit) != 0u && (nav->prev_vel_mask & bit) != 0u) {
                acc[i] = (vel[i] - nav->vel_prev[i]) / dtf;
            }
        }
        r_acc = 2.0f * s_acc * s_acc / (dtf * dtf * g2);
        e = hist_find(nav, (int64_t)fix->t_us);
    } else {
        e = hist_newest(nav);
    }
    if (nav->cfg.comp_mode != MCA_COMP_OFF) {
        /* a yaw error turns the horizontal compensation (ALGORITHMS.md 8, GPS step 5) */
        r_acc += (acc[0] * acc[0] + acc[1] * acc[1]) * nav->att.p[14] / g2;
    }
    if (observe && excluded) {
        gravity_skip(nav);
    } else if (observe) {
        gravity_obs(nav, e, acc, r_acc); /* failures are counted skips */
    }
    /* the course observation does not depend on the roll/pitch attempt; a fix the step test held
     * has the suspect velocity too (GPS step 6) */
    if (nav->aligned && !flagged && nav->step_hold == 0u) {
        const float speed = sqrtf(vel[0] * vel[0] + vel[1] * vel[1]);
        if (nav->cfg.yaw_source == MCA_YAW_COG && (vmask & 3u) == 3u && speed >= nav->cfg.cog_min_speed_mps &&
            speed > 0.0f) {
            const mca_hist_entry_t *ec = hist_find(nav, (int64_t)fix->t_us);
            if (ec != NULL) {
                const float r = nav->cfg.cog_sigma0_rad * nav->cfg.cog_sigma0_rad + (s_acc / speed) * (s_acc / speed);
                /* the gate in the robust modes; refused COG_GATE_N times in a row with no yaw
                 * observation for COG_GATE_US and the step test not armed (or none for
                 * COG_GATE_ARMED_US, armed or not), the course re-aligns yaw (GPS step 6) */
                const uint64_t since = nav->t_imu_us - nav->t_lastyaw_us;
                if (nav->cog_gated >= COG_GATE_N && since > (uint64_t)COG_GATE_US &&
                    ((nav->step_flags & STEP_ARMED) == 0u || since > (uint64_t)COG_GATE_ARMED_US)) {
                    nav->have_yaw_obs = 0u;
                }
                const float gate = nav->cfg.att.robust.mode != (uint8_t)MCA_ROBUST_PLAIN
                                       ? mca_chi2_quantile(1u, MCA_CHI2_1E4)
                                       : INFINITY;
                if (yaw_obs(nav, mca_atan2f(vel[1], vel[0]), r, ec->q_nb, gate) == MCA_OK) { /* gates are not errors */
                    nav->cog_gated = 0u;
                } else if (nav->cog_gated < COG_GATE_N) {
                    nav->cog_gated++;
                }
            }
        }
    }
}

mca_status_t mca_nav_gps(mca_nav_t *nav, const mca_gps_fix_t *fix)
{
    if (nav == NULL || fix == NULL) {
        return MCA_ERR_NULL;
    }
    grav_complete(nav); /* the last IMU step's observation, whatever this call's inputs */
    mca_fix_view_t fv;
    const mca_status_t sf =
        mca_gps_fix_read(fix, nav->cfg.gps_pos_sigma_m, nav->cfg.gps_alt_sigma_m, nav->cfg.gps_vel_sigma_mps, &fv);
    if (sf != MCA_OK) {
        return sf;
    }
    if (nav->have_fix && fix->t_us <= nav->t_lastfix_us) {
        return MCA_ERR_TIME_BACKWARDS;
    }
    const int has_alt = fv.has_alt != 0u;
    mca_status_t st = MCA_OK;
    if ((nav->flags & MCA_FLAG_HOME_SET) == 0u) { /* (a sticky bit of flags) */
        mca_geo_set_home_nocheck(&nav->home, fix->lat_e7, fix->lon_e7, has_alt ? fix->alt_mm : 0);
        nav->flags |= MCA_FLAG_HOME_SET;
        if (!(nav->cfg.gravity_mps2 > 0.0f)) {
            const float lat = (float)fix->lat_e7 * 1.74532925199433e-9f;
            nav->g_mps2 = mca_geo_gravity(lat, (float)nav->home.alt_mm * 1e-3f);
        }
        cs_start(nav, NULL, fv.vel_ned_mps);
    } else {
        float ned[3];
        /* the fix was range-checked by mca_gps_fix_read, the home altitude by mca_geo_set_home */
        mca_geo_to_ned_nocheck(&nav->home, fix->lat_e7, fix->lon_e7, has_alt ? fix->alt_mm : nav->home.alt_mm, ned);
        const float t = span_s(nav->t_lastfix_us, fix->t_us);
        if (t > nav->cfg.cs_h.dt_max_s || t > nav->cfg.cs_v.dt_max_s) {
            nav->step_hold = 0u; /* no increments carry the anchor over the gap */
            cs_start(nav, ned, fv.vel_ned_mps);
        } else {
            st = gps_cs(nav, fix, &fv, ned, t);
            /* an axis update that failed numerically (SINGULAR, NONFINITE) left that axis as
             * predicted: the CS is at the fix time all the same (GPS step 4), but the fix makes
             * no attitude observation. A fix the step test found the fault's end, which the CS
             * then flags (GPS step 6), restarts the CS: the CS has the fault in (GPS step 3);
             * so does a fix back where the fixes were before a position fault the CS took in
             * (GPS step 4; gps_cs restarts it for both, at the position reference when the fix
             * is near it, and sets STEP_RET). The step test's hold goes on: the first is
             * released, and a position return in a burst of both is no velocity end */
            if ((nav->step_flags & STEP_RET) == 0u && st == MCA_OK) {
                gps_attitude(nav, fix, &fv);
            }
            /* the ring's spacing for the next fix (ALGORITHMS.md 8, history ring): 1/40 of the span
             * this fix's increments needed, so that the 47 intervals span 1.175 times it */
            const uint64_t need = nav->t_imu_us - nav->t_lastfix_us; /* (IMU behind the last fix: long) */
            const uint32_t q = need >= 2000000u ? MCA_HIST_DT_MAX_US / 250u : (uint32_t)need / 10000u;
            nav->hist_dt_q = (uint8_t)(q < MCA_HIST_DT_US / 250u ? MCA_HIST_DT_US / 250u : q);
        }
    }
    nav->have_fix = 1u;
    nav->t_lastfix_us = fix->t_us;
    memcpy(nav->vel_prev, fv.vel_ned_mps, sizeof(nav->vel_prev));
    if (nav->step_hold == 0u && nav->aligned) { /* (before alignment, nav->u is the alignment's) */
        /* the next anchor: this fix's N/E velocity, when the step test passed it or the CS
         * applied it (GPS step 3) */
        const int ok = (fv.vel_mask & 3u) == 3u && ((nav->step_flags & STEP_TESTED) != 0u ||
                                                     (nav->cs.axis[0].aid.out | nav->cs.axis[1].aid.out) == 0u);
        mca_copyf(nav->u.step.v, fv.vel_ned_mps, 2u);
        nav->u.step.var = fv.s_acc_mps * fv.s_acc_mps;
        nav->step_flags = (uint8_t)((nav->step_flags & (STEP_ARMED | STEP_REF | STEP_PHOLD | STEP_PIN)) |
                                    (ok ? STEP_ANCHOR : 0u) | ((nav->step_flags & STEP_TESTED) != 0u ? STEP_PRE : 0u));
    }
    nav->prev_vel_mask = fv.vel_mask;
    return st;
}

mca_status_t mca_nav_mag(mca_nav_t *nav, uint64_t t_us, const float mag_b[3])
{
    if (nav == NULL || mag_b == NULL) {
        return MCA_ERR_NULL;
    }
    grav_complete(nav); /* the last IMU step's observation, whatever this call's inputs */
    if (!mca_all_finite(mag_b, 3u)) {
        return MCA_ERR_NONFINITE;
    }
    if (nav->cfg.yaw_source != MCA_YAW_MAG || !nav->aligned) {
        return MCA_OK;
    }
    if (nav->have_mag_obs && (t_us < nav->t_lastmag_us || t_us - nav->t_lastmag_us < us(nav->cfg.grav_period_s))) {
        return MCA_OK;
    }
    float psi;
    mca_status_t st = mca_att_mag_heading_nocheck(&nav->att, mag_b, nav->cfg.mag_declination_rad, &psi);
    if (st != MCA_OK) {
        return MCA_OK; /* zero vector: skipped (ALGORITHMS.md 8) */
    }
    st = yaw_obs(nav, psi, nav->cfg.mag_yaw_sigma_rad * nav->cfg.mag_yaw_sigma_rad, nav->att.q_nb, INFINITY);
    if (st == MCA_OK) {
        nav->t_lastmag_us = t_us;
        nav->have_mag_obs = 1u;
        return MCA_OK;
    }
    return st == MCA_ERR_BAD_ARG ? MCA_OK : st;
}

void mca_nav_output(const mca_nav_t *nav, mca_nav_output_t *out)
{
    if (nav == NULL || out == NULL) {
        return;
    }
    out->t_us = nav->t_imu_us; /* every field is written below: no zeroing pass */
    memcpy(out->q_nb, nav->att.q_nb, sizeof(out->q_nb));
    mca_quat_to_euler(out->euler_rad, nav->att.q_nb);
    memcpy(out->gyro_bias_rps, nav->att.bias_rps, sizeof(out->gyro_bias_rps));
    float tau = 0.0f; /* extrapolation time of the CS state, negative when the fix is newer */
    if (nav->have_fix) {
        tau = nav->t_imu_us >= nav->t_lastfix_us ? span_s(nav->t_lastfix_us, nav->t_imu_us)
                                                  : -span_s(nav->t_imu_us, nav->t_lastfix_us);
    }
    uint32_t f = nav->flags;
    for (size_t i = 0; i < 3u; ++i) {
        const mca_cs_axis_t *ax = &nav->cs.axis[i];
        out->pos_ned_m[i] = ax->x[0] + ax->x[1] * tau + 0.5f * ax->x[2] * tau * tau;
        out->vel_ned_mps[i] = ax->x[1] + ax->x[2] * tau;
        out->acc_ned_mps2[i] = ax->x[2];
        out->cs_var[i * 3u] = ax->p[0];
        out->cs_var[i * 3u + 1u] = ax->p[6];
        out->cs_var[i * 3u + 2u] = ax->p[12];
        out->gps_t[i] = nav->last_gps_t[i];
        f |= ax->rs.alarm != 0u ? (uint32_t)MCA_FLAG_ALARM_N << i : 0u;
    }
    for (size_t i = 0; i < 6u; ++i) {
        out->att_var[i] = nav->att.p[i * 7u];
    }
    out->rp_t = nav->n_grav_obs != 0u ? nav->att.rs.t_stat : NAN; /* its memory's T, the last observation's */
    f |= nav->aligned ? (uint32_t)MCA_FLAG_ALIGNED : 0u;
    f |= gps_lost(nav, nav->t_imu_us) ? (uint32_t)MCA_FLAG_GPS_LOST : 0u;
    if (yaw_unobserved(nav)) {
        f |= MCA_FLAG_YAW_UNOBSERVED;
    }
    out->flags = f;
    out->n_grav_obs = nav->n_grav_obs;
    out->n_grav_skip = nav->n_grav_skip;
}

/**
 * @file mca_nav.h
 * @brief The navigation top level a flight controller calls: IMU step, GPS step,
 *        magnetometer step, one output struct (DESIGN.md 4, docs/ALGORITHMS.md 8).
 *
 * Time is uint64 microseconds on the IMU clock. GPS fixes carry their validity time on
 * that clock (arrival minus receiver latency). No function allocates; every one returns a
 * status and leaves the state finite and unchanged on error (exceptions documented).
 */
#ifndef MCA_NAV_H
#define MCA_NAV_H

#include "mca_att.h"
#include "mca_cs.h"
#include "mca_geo.h"

/** History ring: entries and their spacing (ALGORITHMS.md 8). The spacing is MCA_HIST_DT_US, and
 * longer, up to MCA_HIST_DT_MAX_US, while the fixes need it: a fix's IMU increments (GPS step 3)
 * reach back to the last fix, which 47 intervals of 20 ms (0.94 s) do not at 1 Hz. */
#define MCA_HIST_LEN 48
#define MCA_HIST_DT_US 20000
#define MCA_HIST_DT_MAX_US 50000

/** comp_mode */
#define MCA_COMP_OFF 0
#define MCA_COMP_CS 1
#define MCA_COMP_VELDIFF 2
/** yaw_source */
#define MCA_YAW_NONE 0
#define MCA_YAW_MAG 1
#define MCA_YAW_COG 2

/** Fix flags */
#define MCA_FIX_VEL_NE 1
#define MCA_FIX_VEL_D 2
#define MCA_FIX_ALT 4
/** Largest velocity component a fix may carry (m/s): above any receiver's limit (COCOM 515 m/s).
 *  A larger one is MCA_ERR_RANGE: taken in, it would run the CS state out to float32's range. */
#define MCA_FIX_VEL_MAX_MPS 1000.0f

/** Output flag bits (mca_nav_output_t.flags) */
#define MCA_FLAG_ALIGNED 1
#define MCA_FLAG_HOME_SET 2
#define MCA_FLAG_GPS_LOST 4
#define MCA_FLAG_YAW_UNOBSERVED 8
#define MCA_FLAG_GRAV_SKIPPED 16
#define MCA_FLAG_SATURATED 32
#define MCA_FLAG_HIST_MISS 64
#define MCA_FLAG_ALARM_N 128 /**< the N CS axis' fuzzy detector is alarmed (fuzzy modes); E, D: << 1, << 2 */

typedef struct {
    mca_cs_config_t cs_h;       /**< CS configuration, N and E */
    mca_cs_config_t cs_v;       /**< CS configuration, D */
    mca_att_config_t att;       /**< attitude filter */
    uint8_t comp_mode;          /**< MCA_COMP_* */
    uint8_t yaw_source;         /**< MCA_YAW_* */
    uint8_t nogps_centripetal;  /**< without GPS remove w x [V,0,0] (vehicle moves along its nose) */
    uint8_t gps_test_imu;       /**< 1: robust modes test each CS update against the IMU-aided
                                     prediction (ALGORITHMS.md 8, GPS step 3); 0: the CS's own */
    float cs_lag_s;             /**< pairing delay of the CS acceleration, [0, 0.94] (history span) */
    float gps_timeout_s;        /**< no fix this long: GPS lost, > 0 */
    float grav_period_s;        /**< observation period without GPS, > 0 */
    float nogps_rp_var_rad2;    /**< roll/pitch variance added without GPS (base), >= 0 */
    float gravity_mps2;         /**< > 0 constant; 0 normal gravity at home */
    float imu_dt_max_s;         /**< longest accepted IMU step, > 0 */
    float init_still_s;         /**< alignment averaging window, > 0 */
    float init_gyro_still_rps;  /**< still: |gyro| <= this */
    float init_acc_still_mps2;  /**< still: | |f| - g | <= this */
    float init_timeout_s;       /**< align from what was averaged after this long */
    float accel_sat_mps2;       /**< saturation level of any accel axis */
    float gps_pos_sigma_m;      /**< horizontal position std when the fix gives none */
    float gps_alt_sigma_m;      /**< vertical position std when the fix gives none */
    float gps_vel_sigma_mps;    /**< velocity std when the fix gives none */
    float mag_declination_rad;  /**< added to the magnetic heading */
    float mag_yaw_sigma_rad;    /**< magnetometer heading std */
    float cog_min_speed_mps;    /**< course over ground used above this speed */
    float cog_sigma0_rad;       /**< base course-over-ground std */
    float imu_acc_sigma_mps2;   /**< IMU acceleration error std of the IMU-aided prediction (bias, vibration,
                                     ring approximation; tilt and yaw errors are added), >= 0 */
    float coast_acc_sigma_mps2; /**< the part of it that persists over a coast (its bias-like part, without
                                     a maneuver onset's transients), >= 0 (ALGORITHMS.md 2, coasting) */
    float gps_pos_white_m;      /**< receiver model (ALGORITHMS.md 8, GPS step 4): > 0, the white part of
                                     the horizontal position error, R = min(h_acc, this)^2, the rest
                                     in the CS GPS-error state (cs_h sigma_p_m, tau_p_s); 0: R = h_acc^2 */
    float gps_alt_white_m;      /**< the same for the vertical position (v_acc, cs_v), >= 0 */
} mca_nav_config_t;

/** One GPS fix. Absent accuracy: not a finite number > 0 (NaN, 0, negative, infinite). */
typedef struct {
    uint64_t t_us;           /**< validity time, IMU clock */
    int32_t lat_e7;          /**< 1e-7 deg */
    int32_t lon_e7;          /**< 1e-7 deg */
    int32_t alt_mm;          /**< mm */
    float vel_ned_mps[3];    /**< where flagged */
    float h_acc_m;           /**< 1-sigma horizontal */
    float v_acc_m;           /**< 1-sigma vertical */
    float s_acc_mps;         /**< 1-sigma speed */
    uint8_t flags;           /**< MCA_FIX_* */
    uint8_t fix_type;        /**< 0 none, 1 DR, 2 2D, 3 3D, 4+ better */
} mca_gps_fix_t;

/** Scratch the nav shares between its CS and attitude updates (never used at once). */
#define MCA_NAV_WS_LEN MCA_ATT_WS_LEN /* >= MCA_CS_WS_LEN, checked in mca_nav.c */

typedef struct {
    uint32_t t_us;         /**< low 32 bits of the IMU time (wraps every 71 min; compared wrap-safe) */
    float f_b_mps2[3];
    float q_nb[4];
    uint8_t saturated;
} mca_hist_entry_t;

/** Everything the filter owns (under 4 KiB; fw_report prints the figure). */
typedef struct {
    mca_nav_config_t cfg;
    mca_att_t att;
    mca_cs3_t cs;
    mca_geo_home_t home;
    mca_hist_entry_t hist[MCA_HIST_LEN];
    float ws[MCA_NAV_WS_LEN];
    uint64_t t_imu_us;       /**< newest IMU time */
    uint64_t t_first_us;     /**< first IMU time */
    uint64_t t_lastfix_us;   /**< validity time of the last fix used (= CS time) */
    uint64_t t_lastgrav_us;  /**< last no-GPS observation */
    uint64_t t_lastmag_us;   /**< last magnetometer observation */
    uint64_t t_lastyaw_us;   /**< IMU time of the last yaw observation of any source */
    uint64_t t_flag_end_us;  /**< last flagged fix + tau_a: no roll/pitch observation before (0: none) */
    float hist_f_sum[3];     /**< accumulator of the entry being built */
    uint32_t hist_acc_us;    /**< time accumulated in it */
    uint16_t hist_n;         /**< samples in it */
    uint8_t hist_head;       /**< next slot to write */
    uint8_t hist_count;      /**< entries written, up to MCA_HIST_LEN */
    uint8_t hist_sat;        /**< saturated sample in the entry being built */
    uint8_t hist_dt_q;       /**< the ring's spacing in 250 us units, MCA_HIST_DT_US to
                                  MCA_HIST_DT_MAX_US (ALGORITHMS.md 8) */
    uint8_t step_hold;       /**< velocity step test: fixes the anchor has been held for (0: the last fix is it) */
    uint8_t step_flags;      /**< velocity step test: anchor, armed, tested, pre (mca_nav.c) */
    /** Before alignment the alignment's sums; after it the velocity step test's state (the test
     *  runs aligned only, ALGORITHMS.md 8, GPS step 3): one memory for both. */
    union {
        struct {
            float f_sum[3];
            float w_sum[3];
            uint32_t win_us; /**< alignment block time, integer sum of dt_us */
            float f_all[3];  /**< sum of f since the first sample (alignment by timeout) */
            uint32_t n_all;
            uint32_t n;
        } init;
        struct {
            float v[2];   /**< the N/E anchor */
            float s0[2];  /**< the step that started the last hold */
            float var;    /**< the anchor's variance an axis: its fix's s_acc^2, plus coast_h t^2 a fix held */
            float pre[2]; /**< the anchor before the last, carried on to the last fix */
            float ref[2]; /**< N, E: the position reference of a restart (ALGORITHMS.md 8, GPS step 4); in
                               fuzzy rows the position hold's anchor */
            float pv[3];  /**< fuzzy rows: the held fixes' N, E velocity less their position change,
                               summed, and the time it spans (ALGORITHMS.md 8, GPS step 3) */
        } step;
    } u;
    float step_dlam;         /**< velocity step test: 1 - lambda, its variance scale (ALGORITHMS.md 8,
                                  GPS step 3; 0 at init: lambda 1) */
    float g_mps2;
    float acc_comp_n[3];     /**< compensation acceleration of the last fix */
    float vel_prev[3];       /**< velocity of the last fix (at t_lastfix_us; differencing) */
    uint8_t prev_vel_mask;   /**< bit i: vel_prev[i] valid */
    uint8_t have_imu;
    uint8_t aligned;
    uint8_t have_fix;
    uint8_t have_mag_obs;
    uint8_t have_yaw_obs;
    uint8_t cog_gated;       /**< course observations not taken in a row, up to 10 (ALGORITHMS.md 7) */
    uint8_t grav_pending;    /**< no-GPS observation made by the last IMU step, completed at the
                                  start of the next call (ALGORITHMS.md 8, IMU step 6): 0 none,
                                  1 update with grav_nu/rows/r, 2 skipped, 3 skipped (no history) */
    uint32_t flags;          /**< sticky/last-event bits, MCA_FLAG_* */
    float grav_nu[2];        /**< the pending observation's residuals, rows (at q_nb) and R */
    float grav_rows[6];
    float grav_r;
    float last_gps_t[3];
    float pos_prev[2];       /**< N, E: the last fix's position (NaN: none; mca_nav.c, GPS step 4) */
    float pos_jump[2];       /**< N, E: the fixes' position jumps summed since the CS started,
                                  less what 5 tau_p forgot (GPS step 4); in fuzzy rows the position
                                  hold's held step */
    uint32_t n_grav_obs;
    uint32_t n_grav_skip;
    float pos_hold_s;        /**< fuzzy rows: how long the position hold has held (GPS step 4); in the
                                  struct's tail padding, sizeof unchanged */
} mca_nav_t;

typedef struct {
    uint64_t t_us;
    float q_nb[4];
    float euler_rad[3];      /**< roll, pitch, yaw */
    float gyro_bias_rps[3];
    float pos_ned_m[3];
    float vel_ned_mps[3];
    float acc_ned_mps2[3];
    float att_var[6];        /**< diag of the attitude P: dtheta (3), bias (3) */
    float cs_var[9];         /**< per axis N, E, D: var p, v, a */
    float rp_t;              /**< last roll/pitch T */
    float gps_t[3];          /**< last GPS T per axis */
    uint32_t flags;          /**< MCA_FLAG_* */
    uint32_t n_grav_obs;
    uint32_t n_grav_skip;
} mca_nav_output_t;

/** A checked fix: velocity with 0 where absent, what is present, accuracies with defaults. */
typedef struct {
    float vel_ned_mps[3];
    float h_acc_m;
    float v_acc_m;
    float s_acc_mps;
    uint8_t vel_mask;  /**< bit i: velocity component i present (N and E come together) */
    uint8_t has_alt;
} mca_fix_view_t;

/**
 * Check a fix's own content (ALGORITHMS.md 8, GPS step 1 without the time test) and read it,
 * missing or non-positive accuracies replaced by the given defaults. Shared by every filter
 * that takes fixes (navigation, INS). Cost: a few compares.
 * @return MCA_ERR_NULL, MCA_ERR_BAD_ARG (fix_type < 2, or an accuracy after the defaults whose
 *         square is no finite float > 0, in use or not), MCA_ERR_RANGE (lat/lon/altitude, or a
 *         velocity component flagged present over MCA_FIX_VEL_MAX_MPS), MCA_ERR_NONFINITE (a
 *         velocity flagged present but not finite), MCA_OK (view filled).
 */
mca_status_t mca_gps_fix_read(const mca_gps_fix_t *fix, float pos_sigma_m, float alt_sigma_m, float vel_sigma_mps,
                              mca_fix_view_t *view);

/**
 * IMU time bookkeeping every filter does first (ALGORITHMS.md 8, IMU step 1-3): finite
 * inputs, the first sample only anchors the clock (*dt_us = 0), no time going backwards, a
 * gap longer than dt_max_us re-anchors the clock and is BAD_DT. Cost: a few compares.
 * @param[in,out] t_last_us, t_first_us, have  the filter's clock
 * @return MCA_ERR_NONFINITE, MCA_ERR_TIME_BACKWARDS (clock unchanged), MCA_ERR_BAD_DT (clock
 *         re-anchored at t_us), MCA_OK with *dt_us the step (0 for the first sample).
 */
mca_status_t mca_imu_clock_step(uint64_t *t_last_us, uint64_t *t_first_us, uint8_t *have, uint64_t t_us,
                                const float gyro[3], const float accel[3], uint32_t dt_max_us, uint32_t *dt_us);

/** Ground vehicle defaults (ALGORITHMS.md 8). */
void mca_nav_config_default(mca_nav_config_t *cfg);
/** Small fixed-wing preset. */
void mca_nav_config_fixedwing(mca_nav_config_t *cfg);
/** Multirotor preset. */
void mca_nav_config_multirotor(mca_nav_config_t *cfg);
mca_status_t mca_nav_config_check(const mca_nav_config_t *cfg);

/** Start a filter (not aligned, no home). @return MCA_ERR_BAD_CONFIG, MCA_ERR_NULL, MCA_OK. */
mca_status_t mca_nav_init(mca_nav_t *nav, const mca_nav_config_t *cfg);

/**
 * IMU step (ALGORITHMS.md 8). Cost: one attitude propagation plus, every history interval, an
 * entry push; without GPS, a gravity observation every grav_period, made in one step and
 * completed (its update, counters and flags) at the start of the next IMU, GPS or magnetometer
 * call, whatever that call's inputs (IMU step 6: the same filter; the output read right after
 * the first half does not show the update yet). On the Cortex-M4F (-Os with LTO,
 * scripts/fw_report.py): 849 instructions mean, 1.4k max without an observation, 1.6k and 2.3k
 * for its two halves (2342 the longest).
 * @return MCA_ERR_NONFINITE, MCA_ERR_TIME_BACKWARDS (unchanged but for the completed pending
 *         observation), MCA_ERR_BAD_DT (time re-anchored, nothing else changed), else MCA_OK
 *         (a no-GPS observation that fails counts as skipped).
 */
mca_status_t mca_nav_imu(mca_nav_t *nav, uint64_t t_us, const float gyro_b_rps[3], const float accel_b_mps2[3]);

/**
 * GPS step (ALGORITHMS.md 8): CS predict + update, then the gravity observation. A fix the
 * CS robust mode flags (GPS step 6) gives no course observation, and no roll/pitch observation
 * is made from it or for tau_a after it (counted as skipped).
 * Cost on the Cortex-M4F (-Os with LTO, scripts/fw_report.py): 9.9k instructions mean, 11.8k
 * max (10.4k / 12.4k at -O2): about two thirds the CS predict with the IMU-aided test prior and the
 * three axis updates (N and E sharing one covariance update, mca_cs3_update), a fifth the
 * roll/pitch update, the rest the course update, geodesy and history look-ups
 * (scripts/fw_profile.py); stack 928 B worst case (the steps keep no update report on the
 * stack).
 * @return MCA_ERR_BAD_ARG (fix_type < 2), MCA_ERR_RANGE, MCA_ERR_NONFINITE,
 *         MCA_ERR_TIME_BACKWARDS (all unchanged), CS update errors, else MCA_OK.
 */
mca_status_t mca_nav_gps(mca_nav_t *nav, const mca_gps_fix_t *fix);

/** Magnetometer step (ALGORITHMS.md 8). */
mca_status_t mca_nav_mag(mca_nav_t *nav, uint64_t t_us, const float mag_b[3]);

/** Fill the output struct. Cannot fail. */
void mca_nav_output(const mca_nav_t *nav, mca_nav_output_t *out);

#endif /* MCA_NAV_H */

/**
 * @file mca_ins.h
 * @brief Loosely-coupled INS: strapdown NED mechanization with a 15-state error-state EKF
 *        [dr, dv, phi, b_g, b_a] aided by GNSS position and velocity (DESIGN.md 6,
 *        docs/ALGORITHMS.md 10). The reference the CS + gravity filter is measured against.
 *
 * Time is uint64 microseconds on the IMU clock; fixes carry their validity time on it. The
 * position is integer (1e-7 deg, mm) plus float32 metre offsets folded after every change.
 * No function allocates or recurses; every loop is bounded by a compile-time size. Every
 * function that can fail returns a status and, on error, leaves the state unchanged (the one
 * exception, the time re-anchoring and navigation stop on BAD_DT, is documented at the function).
 */
#ifndef MCA_INS_H
#define MCA_INS_H

#include "mca_replay.h"

/** Error-state size and the first index of each block. */
#define MCA_INS_NX 15
#define MCA_INS_DR 0
#define MCA_INS_DV 3
#define MCA_INS_PHI 6
#define MCA_INS_BG 9
#define MCA_INS_BA 12

/** History of the INS solution (ALGORITHMS.md 10, History and latency): entries, spacing. */
#define MCA_INS_HIST_LEN 50
#define MCA_INS_HIST_DT_US 20000

/** Scratch floats: one GNSS update (n = 15, m <= 6), also used by the covariance propagation
 *  (three 15 x 15 matrices; mca_ins.c checks at compile time that they fit). */
#define MCA_INS_WS_LEN MCA_KF_WS_LEN(MCA_INS_NX, MCA_MEAS_MAX)

/** Output flag bits (mca_ins_output_t.flags). */
#define MCA_INS_FLAG_ALIGNED 1      /**< roll/pitch aligned */
#define MCA_INS_FLAG_HOME_SET 2     /**< home fix received */
#define MCA_INS_FLAG_NAV 4          /**< navigating (position and velocity initialised) */
#define MCA_INS_FLAG_YAW_ALIGNED 8  /**< yaw known (yaw source none, or first yaw observation made) */
#define MCA_INS_FLAG_GPS_LOST 16    /**< no fix yet, or none for gps_timeout_s */
#define MCA_INS_FLAG_HIST_MISS 32   /**< last fix older than the history: skipped */
#define MCA_INS_FLAG_REJECTED 64    /**< last GNSS update: a block (position or velocity) rejected */
#define MCA_INS_FLAG_SATURATED 128  /**< a saturated accelerometer sample was seen (sticky) */
#define MCA_INS_FLAG_DETECTED 256   /**< last GNSS update: the robust mode detected an outlier in a block */
#define MCA_INS_FLAG_RESET 512      /**< last GNSS update: a lock-up guard reset a block to the fix */

/** INS configuration (ALGORITHMS.md 10 table). mca_ins_config_default fills it. */
typedef struct {
    float gyro_noise_rps;       /**< gyro white noise density (ARW), rad/s/sqrt(Hz), >= 0 */
    float accel_noise_mps2;     /**< accel white noise density (VRW), m/s^2/sqrt(Hz), >= 0 */
    float gyro_bias_rw_rps2;    /**< gyro bias driving noise density, rad/s^2/sqrt(Hz), >= 0 */
    float accel_bias_rw_mps3;   /**< accel bias driving noise density, m/s^3/sqrt(Hz), >= 0 */
    float gyro_bias_tau_s;      /**< gyro bias Gauss-Markov time, 0 random walk, else >= 1 */
    float accel_bias_tau_s;     /**< accel bias Gauss-Markov time, 0 random walk, else >= 1 */
    float att0_var_rad2;        /**< initial roll/pitch variance (timeout alignment), > 0 */
    float att_still_var_rad2;   /**< roll/pitch variance beyond the accel bias after a still levelling, > 0 */
    float yaw0_var_rad2;        /**< variance of yaw0_rad (yaw source none), > 0 */
    float yaw0_rad;             /**< initial yaw, finite */
    float gyro_bias0_var_rps2;  /**< initial gyro bias variance (timeout alignment), > 0 */
    float gyro_bias_still_var_rps2; /**< initial gyro bias variance after a still-window alignment, > 0 */
    float accel_bias0_var_mps4; /**< initial accel bias variance, > 0 */
    float vel0_var_m2ps2;       /**< initial velocity variance where the first fix has none, > 0 */
    float lever_arm_b_m[3];     /**< GNSS antenna in body FRD from the IMU, |each| <= 10 m */
    float cov_dt_s;             /**< covariance propagation period, [0, 0.1]; 0 every sample */
    uint8_t earth_rate;         /**< 1: earth rotation (attitude and Coriolis), 0: none */
    uint8_t transport_rate;     /**< 1: frame rotation over the ellipsoid, 0: none */
    uint8_t yaw_source;         /**< MCA_YAW_NONE, MCA_YAW_MAG, MCA_YAW_COG */
    float gravity_mps2;         /**< > 0 constant; 0 normal gravity at the current position */
    float imu_dt_max_s;         /**< longest accepted IMU step, > 0 */
    float init_still_s;         /**< alignment averaging window, > 0 */
    float init_gyro_still_rps;  /**< still: |gyro| <= this, >= 0 */
    float init_acc_still_mps2;  /**< still: | |f| - g | <= this, >= 0 */
    float init_timeout_s;       /**< align from what was averaged after this long, > 0 */
    float accel_sat_mps2;       /**< saturation level of any accel axis, > 0 */
    float gps_timeout_s;        /**< flag gps_lost after this long without a fix, > 0 */
    float gps_pos_sigma_m;      /**< horizontal position std when the fix gives none, > 0 */
    float gps_alt_sigma_m;      /**< vertical position std when the fix gives none, > 0 */
    float gps_vel_sigma_mps;    /**< velocity std when the fix gives none, > 0 */
    float mag_declination_rad;  /**< added to the magnetic heading, finite */
    float mag_yaw_sigma_rad;    /**< magnetometer heading std, > 0 */
    float mag_period_s;         /**< at most one magnetometer observation per this, >= 0 */
    float cog_min_speed_mps;    /**< course alignment at or above this ground speed, >= 0 */
    float cog_sigma0_rad;       /**< base course std, > 0 */
    float gps_pos_noise_min_m;  /**< floor of the fix's h_acc and v_acc (EKF2_GPS_P_NOISE), >= 0, 0 none */
    float gps_vel_noise_min_mps; /**< floor of the fix's s_acc (EKF2_GPS_V_NOISE), >= 0, 0 none */
    float gnss_reset_s;         /**< lock-up guard: no GNSS block fused for this long, a block the mode
                                     rejects is reset to the fix, [0, 600], 0 off */
    float gnss_block_reset_s;   /**< lock-up guard: a block not fused for this long (the other fused),
                                     the same, [0, 600], 0 off */
    float gps_pos_tau_s;        /**< receiver position error model (ALGORITHMS.md 10, GNSS update step 3):
                                     correlation time of its slow part, 0 off (h_acc, v_acc white),
                                     else [1, 3600] */
    float gps_pos_white_m;      /**< its white part, N and E each (the rows' R), > 0 */
    float gps_alt_white_m;      /**< its white part, D, > 0 */
    mca_robust_config_t robust; /**< robust/adaptive mode of both GNSS blocks (each its own memory) */
} mca_ins_config_t;

/** One history entry (56 bytes): the INS solution at the end of a 20 ms interval. */
typedef struct {
    uint32_t t_us;          /**< low 32 bits of the IMU time (compared wrap-safe) */
    float pos_ned_m[3];     /**< home NED */
    float vel_ned_mps[3];
    float q_nb[4];
    float w_b_rps[3];       /**< bias-corrected body rate of the sample that closed the entry */
} mca_ins_hist_t;

/** Everything the INS owns. sizeof is printed by tests/c/test_ins.c. */
typedef struct {
    mca_ins_config_t cfg;
    /* nominal state */
    float q_nb[4];
    float vel_ned_mps[3];
    int32_t lat_e7;
    int32_t lon_e7;
    int32_t alt_mm;
    float off_ned_m[3];           /**< position remainder below one integer count, NED metres */
    float bg_rps[3];
    float ba_mps2[3];
    float p[MCA_INS_NX * MCA_INS_NX];
    mca_robust_state_t rs;        /**< robust memory of the GNSS position block */
    mca_robust_state_t rs_v;      /**< robust memory of the GNSS velocity block */
    mca_geo_home_t home;
    mca_ins_hist_t hist[MCA_INS_HIST_LEN];
    float ws[MCA_INS_WS_LEN];
    /* update scratch, kept here rather than on the stack (STYLE.md) */
    float upd_h[MCA_MEAS_MAX * MCA_INS_NX];
    float upd_z[MCA_MEAS_MAX];
    float upd_r[MCA_MEAS_MAX * MCA_MEAS_MAX];
    float dx[MCA_INS_NX];
    uint8_t upd_idx[MCA_MEAS_MAX];  /**< state index (dr or dv component) of each update row */
    mca_update_report_t rep;      /**< report of the last GNSS position block */
    mca_update_report_t rep_v;    /**< report of the last GNSS velocity block */
    /* time */
    uint64_t t_imu_us;
    uint64_t t_first_us;
    uint64_t t_lastfix_us;
    uint64_t t_lastmag_us;
    uint64_t t_fuse_pos_us;       /**< fix time of the last position block applied (or of the start) */
    uint64_t t_fuse_vel_us;       /**< the same for the velocity block */
    uint64_t t_hist_newest_us;    /**< full IMU time of the newest history entry */
    /* accumulators */
    float cov_dv_n[3];            /**< sum of dv_f since the last covariance propagation */
    uint32_t cov_acc_us;
    uint32_t hist_acc_us;
    uint16_t hist_head;
    uint16_t hist_count;
    float init_f_sum[3];
    float init_w_sum[3];
    uint32_t init_win_us;
    uint32_t init_n;
    float init_all_f_sum[3];      /**< specific force of every sample before alignment */
    uint32_t init_all_n;
    float w_last_rps[3];          /**< bias-corrected rate of the newest sample */
    float f_last_mps2[3];         /**< bias-corrected specific force of the newest sample */
    float yaw_var_align;          /**< variance of the aligning yaw observation */
    float bg0_var;                /**< initial gyro bias variance chosen by the alignment */
    uint8_t level_still;          /**< the last levelling was from a still window */
    float rx_q[2];                /**< receiver slow-error growth 2 c^2 / tau of the last fix, N/E and D */
    uint8_t pos_out;              /**< the last fix's position block was rejected or held out */
    uint8_t vel_out;              /**< the same for the velocity block (fixes without velocity leave it) */
    float fix_speed_mps;          /**< ground speed of the last fix (-1: it had no NE velocity) */
    float g_align_mps2;           /**< gravity used by the still test */
    uint8_t have_imu;
    uint8_t aligned;
    uint8_t home_set;
    uint8_t nav;
    uint8_t yaw_aligned;
    uint8_t have_fix;
    uint8_t have_mag;
    uint32_t flags;               /**< event bits (HIST_MISS, REJECTED, SATURATED) */
    float last_gps_t;
    uint32_t last_gps_m;
    uint32_t n_gps_upd;
    uint32_t n_gps_rej;
    uint32_t n_gps_skip;
} mca_ins_t;

/** What the INS reports after a step. */
typedef struct {
    uint64_t t_us;
    float q_nb[4];
    float euler_rad[3];         /**< roll, pitch, yaw */
    float pos_ned_m[3];         /**< home NED (0 before navigation) */
    float vel_ned_mps[3];
    int32_t lat_e7;             /**< integer position (offsets below one count not included) */
    int32_t lon_e7;
    int32_t alt_mm;
    float gyro_bias_rps[3];
    float accel_bias_mps2[3];
    float p_diag[MCA_INS_NX];   /**< diagonal of P: dr, dv, phi, b_g, b_a */
    float gps_t;                /**< last GNSS update T, sum over its blocks (NaN before the first) */
    uint32_t gps_m;             /**< its rows */
    uint32_t flags;             /**< MCA_INS_FLAG_* */
    uint32_t n_gps_upd;         /**< fixes whose GNSS update applied a block */
    uint32_t n_gps_rej;         /**< fixes with a block rejected by the robust mode or failed numerically */
    uint32_t n_gps_skip;        /**< fixes skipped (before alignment, history miss) */
} mca_ins_output_t;

/** Ground-vehicle defaults (ALGORITHMS.md 10). Cannot fail (cfg must not be NULL). */
void mca_ins_config_default(mca_ins_config_t *cfg);
/** Fixed-wing preset: defaults with cog_min_speed_mps 5. */
void mca_ins_config_fixedwing(mca_ins_config_t *cfg);
/** Multirotor preset: defaults with the magnetometer as yaw source. */
void mca_ins_config_multirotor(mca_ins_config_t *cfg);

/**
 * Range check of every field (table of ALGORITHMS.md 10). Cost: ~60 compares. Reads only cfg.
 * @return MCA_ERR_NULL, MCA_ERR_BAD_CONFIG, MCA_OK.
 */
mca_status_t mca_ins_config_check(const mca_ins_config_t *cfg);

/**
 * Start an INS: not aligned, no home. Cost: a memset of sizeof(mca_ins_t).
 * @return MCA_ERR_NULL, MCA_ERR_BAD_CONFIG (ins untouched), MCA_OK.
 */
mca_status_t mca_ins_init(mca_ins_t *ins, const mca_ins_config_t *cfg);

/**
 * IMU step with rates (ALGORITHMS.md 10): alignment (and re-levelling while stopped), attitude-
 * only propagation until navigation starts, or mechanization plus, once per cov_dt_s, the
 * covariance propagation and, once per 20 ms, a history entry (one geodetic conversion): on the
 * Cortex-M4F (-Os) 14.0k instructions mean, 55.0k on the steps that propagate the covariance.
 * @param[in] t_us         sample time, IMU clock
 * @param[in] gyro_b_rps   body rate
 * @param[in] accel_b_mps2 specific force
 * @return MCA_ERR_NULL, MCA_ERR_NONFINITE, MCA_ERR_TIME_BACKWARDS (unchanged), MCA_ERR_BAD_DT (the
 *         time is re-anchored and navigation stops until the next fix; attitude and biases kept),
 *         MCA_OK.
 */
mca_status_t mca_ins_imu(mca_ins_t *ins, uint64_t t_us, const float gyro_b_rps[3], const float accel_b_mps2[3]);

/**
 * IMU step with increments over (previous t_us, t_us]: dtheta_b_rad and dv_b_mps are divided by
 * the interval and passed to the rate step. The first sample only anchors the time (its
 * increments are discarded). Errors as mca_ins_imu.
 */
mca_status_t mca_ins_imu_delta(mca_ins_t *ins, uint64_t t_us, const float dtheta_b_rad[3], const float dv_b_mps[3]);

/**
 * GNSS step (ALGORITHMS.md 10): home, navigation start (with the heading known; course over
 * ground sets it here), or the update against the INS solution at the fix's validity time in two
 * blocks, velocity rows then position rows, each in the configured robust mode with its own
 * memory; a velocity block after a rejected one is offered only when the position block alone is
 * consistent (T < chi2_m(0.025)), and while the velocity is rejected the position block only when
 * it was applied on the fix before; a block left out longer than the lock-up guards
 * (gnss_reset_s, gnss_block_reset_s) is reset to the fix. Cost: the history search (<= 51
 * points), two geodetic conversions, two mca_kf_update (n = 15, m <= 3 each), the correction of
 * the state and of the 50 history entries (scripts/fw_report.py section 4b).
 * @return MCA_ERR_NULL; MCA_ERR_BAD_ARG (fix_type < 2), MCA_ERR_RANGE, MCA_ERR_NONFINITE,
 *         MCA_ERR_TIME_BACKWARDS: nothing changed; MCA_ERR_SINGULAR / MCA_ERR_NONFINITE from a
 *         block: that block not applied (a velocity block applied before a failing position
 *         block stands, and is counted), n_gps_rej counted; else MCA_OK (also for a fix skipped
 *         before alignment, before the heading is known or on a history miss, and a rejected block).
 */
mca_status_t mca_ins_gps(mca_ins_t *ins, const mca_gps_fix_t *fix);

/**
 * Magnetometer step (ALGORITHMS.md 10): with yaw source magnetometer, the first sample after
 * alignment sets yaw, later ones (one per mag_period_s) are yaw updates.
 * @return MCA_ERR_NULL, MCA_ERR_NONFINITE (unchanged), the update's MCA_ERR_SINGULAR (unchanged),
 *         else MCA_OK (also when not used, rate-limited, or skipped by a gate).
 */
mca_status_t mca_ins_mag(mca_ins_t *ins, uint64_t t_us, const float mag_b[3]);

/** Fill the output. Cost: one geodetic conversion. Does nothing when a pointer is NULL. */
void mca_ins_output(const mca_ins_t *ins, mca_ins_output_t *out);

/**
 * Continuous error-state matrix F (15 x 15, row-major) of the current state with the NED specific
 * force f_n_mps2 (ALGORITHMS.md 10 table). For tests and analysis. Cost: ~250 stores.
 * @return MCA_ERR_NULL, MCA_ERR_NONFINITE (f_n), MCA_OK.
 */
mca_status_t mca_ins_error_model(const mca_ins_t *ins, const float f_n_mps2[3], float *f_out);

/**
 * Run every event of a recording through ins (initialised by mca_ins_init) in the order of
 * ALGORITHMS.md 9; one output after each IMU sample. Arrays sorted by time. Cost: the steps.
 * @param[out] out        n_imu outputs
 * @param[out] imu_status n_imu statuses (may be NULL); likewise gps_status, mag_status
 * @return MCA_ERR_NULL when a needed pointer is NULL, else MCA_OK (per-event statuses).
 */
mca_status_t mca_ins_replay(mca_ins_t *ins, const mca_imu_sample_t *imu, size_t n_imu, const mca_gps_event_t *gps,
                            size_t n_gps, const mca_mag_sample_t *mag, size_t n_mag, mca_ins_output_t *out,
                            uint8_t *imu_status, uint8_t *gps_status, uint8_t *mag_status);

#endif /* MCA_INS_H */

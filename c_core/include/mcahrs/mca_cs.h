/**
 * @file mca_cs.h
 * @brief Current-statistical (CS) maneuver-acceleration filter: one 5-state Kalman
 *        filter per NED axis (DESIGN.md section 3, docs/ALGORITHMS.md sections 2-3).
 *
 * Axis state x = [p, v, a, eps_p, eps_v]: position (m), velocity (m/s), acceleration
 * (m/s^2), GPS position error (m) and GPS velocity error (m/s), both first-order
 * Gauss-Markov. Mean propagation is the constant-acceleration step (eq. 17), covariance
 * the exact CS transition with the exact Singer Q, evaluated by a Taylor series below
 * alpha*T = MCA_CS_SERIES_X so float32 does not cancel.
 */
#ifndef MCA_CS_H
#define MCA_CS_H

#include "mca_robust.h"

/** alpha*T below which the Singer Q and Phi13 use their Taylor series. */
#define MCA_CS_SERIES_X 2.0f

/** Mask bits of a CS update. */
#define MCA_CS_POS 1
#define MCA_CS_VEL 2

/** Scratch floats one CS axis update needs. */
/** Scratch of a CS update: the measurement update's, then N's row gains for E (mca_cs3_update). */
#define MCA_CS_WS_LEN (MCA_KF_WS_LEN(MCA_CS_NX, MCA_CS_NZ) + MCA_CS_NZ * (MCA_CS_NX + 1))

/** Configuration of one axis. Defaults from mca_cs_config_default_h/_v. */
typedef struct {
    float tau_a_s;          /**< maneuver correlation time, alpha = 1/tau_a, > 0 */
    float tau_p_s;          /**< GPS position error correlation time, beta = 1/tau_p, > 0 */
    float tau_v_s;          /**< GPS velocity error correlation time, gamma = 1/tau_v, > 0 */
    float sigma_p_m;        /**< GPS position Gauss-Markov error std, >= 0 */
    float sigma_v_mps;      /**< GPS velocity Gauss-Markov error std, >= 0 */
    float sigma_a0_mps2;    /**< fixed maneuver std (and adaptive when abar == 0), > 0 */
    float a_max_mps2;       /**< maximum maneuver acceleration (adaptive), > 0 */
    float sigma_a_min_mps2; /**< floor of the adaptive maneuver std, > 0 */
    float p0_var_m2;        /**< initial position variance, > 0 */
    float v0_var_m2ps2;     /**< initial velocity variance, > 0 */
    float a0_var_m2ps4;     /**< initial acceleration variance, > 0 */
    float dt_max_s;         /**< longest accepted predict step, > 0 */
    uint8_t adaptive;       /**< 0 fixed sigma_a0, 1 current-statistical adaptive */
    uint8_t coast;          /**< 1: after an update that left the velocity row out or was rejected
                                 (robust modes), an IMU-aided predict moves p and v with the IMU
                                 increments (coasting), from the aided prediction (the update
                                 that starts the coast moves p and v by it, ALGORITHMS.md 2) */
    mca_robust_config_t robust; /**< robust/adaptive mode of the GPS updates */
} mca_cs_config_t;

/**
 * IMU-aided prediction of one axis' GPS measurement [p + eps_p, v + eps_v] at the end of a
 * predict (docs/ALGORITHMS.md 2, "IMU-aided test prior"): the posterior before the predict
 * moved with the IMU's velocity and position increments instead of the constant-acceleration
 * step. The robust mode of the next update tests the GPS against it.
 */
typedef struct {
    float y[MCA_CS_NZ];              /**< predicted position (m) and velocity (m/s) measurement */
    float s[MCA_CS_NZ * MCA_CS_NZ];  /**< its covariance without R, row-major */
    uint8_t valid;                   /**< set by an aided predict, cleared by any other predict and by
                                          the update that uses it */
    uint8_t out;                     /**< the last update left the velocity row out (rejected, or
                                          the row removed); with cfg.coast the next aided predict
                                          coasts */
} mca_cs_aid_t;

/** IMU increments over one predict interval, for mca_cs_axis_predict_aided. */
typedef struct {
    float dp_m;          /**< position increment minus the initial velocity's share, int int a dt dt */
    float dv_mps;        /**< velocity increment, int a dt */
    float acc_var_m2ps4; /**< variance of the IMU acceleration error over the interval (the test
                              prior's: with the transients of a maneuver onset), >= 0 */
    float coast_var_m2ps4; /**< the part of it that persists interval after interval, which a
                                coast accumulates (ALGORITHMS.md 2, coasting), >= 0 */
} mca_cs_inc_t;

/** One axis. Owns its state; scratch is passed in by the caller (see mca_cs3_t). */
typedef struct {
    float x[MCA_CS_NX];             /**< [p, v, a, eps_p, eps_v] */
    float p[MCA_CS_NX * MCA_CS_NX]; /**< covariance, row-major, symmetric */
    float s2_m2ps4;                 /**< maneuver variance used by the last predict */
    mca_robust_state_t rs;          /**< robust-mode memory; rs.q_scale scales Q at predict */
    mca_cs_aid_t aid;               /**< IMU-aided test prior of the next update */
    mca_cs_config_t cfg;
} mca_cs_axis_t;

/** Three axes N, E, D. Scratch for updates is passed in (see mca_cs3_update). */
typedef struct {
    mca_cs_axis_t axis[3];
} mca_cs3_t;

/** Horizontal (N, E) defaults of docs/ALGORITHMS.md section 2. */
void mca_cs_config_default_h(mca_cs_config_t *cfg);
/** Vertical (D) defaults of docs/ALGORITHMS.md section 2. */
void mca_cs_config_default_v(mca_cs_config_t *cfg);

/** @return MCA_OK or MCA_ERR_BAD_CONFIG when a field is out of its range. */
mca_status_t mca_cs_config_check(const mca_cs_config_t *cfg);

/**
 * Initialise one axis at position p0_m and velocity v0_mps (0 when unknown).
 * @return MCA_ERR_BAD_CONFIG, MCA_ERR_NONFINITE, MCA_ERR_NULL, or MCA_OK.
 */
mca_status_t mca_cs_axis_init(mca_cs_axis_t *ax, const mca_cs_config_t *cfg, float p0_m, float v0_mps);

/** Maneuver variance for acceleration mean abar (docs/ALGORITHMS.md 2, step 3). */
float mca_cs_maneuver_var(const mca_cs_config_t *cfg, float abar_mps2);

/**
 * Exact CS transition Phi (5 x 5) and process noise Q (5 x 5) over t_s for maneuver
 * variance s2 (DESIGN.md 3). Cost: ~200 flops, two mca_expf, two mca_expm1f (~40 instructions
 * each on the M4F).
 */
void mca_cs_transition(const mca_cs_config_t *cfg, float t_s, float s2_m2ps4, float phi[25], float q[25]);

/** Singer 3 x 3 process noise block for alpha, t_s, and q = 2 alpha s2 (row-major). */
void mca_cs_singer_q(float alpha_ps, float t_s, float s2_m2ps4, float q33[9]);

/** Predict one axis over t_s (clears the aid). @return MCA_ERR_BAD_DT (state unchanged) or MCA_OK. */
mca_status_t mca_cs_axis_predict(mca_cs_axis_t *ax, float t_s);

/**
 * Predict one axis over t_s and, with inc non-NULL, first set its IMU-aided test prior from
 * the posterior being predicted (docs/ALGORITHMS.md 2): y = [p + v t + dp + e_b eps_p,
 * v + dv + e_g eps_v], s = G P G^T + diag(sigma_p^2 (1 - e_b^2), sigma_v^2 (1 - e_g^2)) +
 * acc_var [[t^4/4, t^3/2], [t^3/2, t^2]], G = [[1, t, 0, e_b, 0], [0, 1, 0, 0, e_g]],
 * e_b = exp(-beta t), e_g = exp(-gamma t). inc NULL: mca_cs_axis_predict.
 * With cfg.coast and aid.out set (the last update left the velocity row out) the predict coasts
 * (docs/ALGORITHMS.md 2, coasting): p += v t + dp, v += dv, a kept, the covariance without the
 * p-a and v-a couplings plus acc_var [[t^4/4, t^3/2], [t^3/2, t^2]] on (p, v).
 * Cost: the predict plus ~40 multiply-adds (e_b, e_g and the Gauss-Markov Q come from the
 * predict's own transition).
 * @return MCA_ERR_BAD_DT, MCA_ERR_NONFINITE (inc not finite), MCA_ERR_BAD_ARG (acc_var < 0), MCA_OK;
 *         the axis is unchanged on error.
 */
mca_status_t mca_cs_axis_predict_aided(mca_cs_axis_t *ax, float t_s, const mca_cs_inc_t *inc);

/**
 * Update one axis with position z_p_m (variance r_p) and/or velocity z_v_mps (variance r_v)
 * as selected by mask (MCA_CS_POS | MCA_CS_VEL). Unused values are ignored. When the last
 * predict was aided (ax->aid.valid), the robust mode tests z minus the aid's prediction with
 * covariance s + R (mca_kf_update_tested) and the aid is consumed; else mca_kf_update.
 * @param[out] ws  MCA_CS_WS_LEN floats of scratch
 * @return MCA_ERR_BAD_MASK, MCA_ERR_NONFINITE, MCA_ERR_BAD_ARG (variance <= 0),
 *         MCA_ERR_SINGULAR, or MCA_OK. On error the axis is unchanged.
 */
mca_status_t mca_cs_axis_update(mca_cs_axis_t *ax, float z_p_m, float z_v_mps, float r_p_m2,
                                float r_v_m2ps2, uint8_t mask, float *ws, mca_update_report_t *rep);

/** Initialise N, E with cfg_h and D with cfg_v at pos_ned_m, vel_ned_mps (may be NULL: 0). */
mca_status_t mca_cs3_init(mca_cs3_t *cs, const mca_cs_config_t *cfg_h, const mca_cs_config_t *cfg_v,
                          const float pos_ned_m[3], const float vel_ned_mps[3]);

/**
 * Predict all three axes over t_s; a bad t_s changes none. An axis whose model (the fields
 * mca_cs_transition reads) equals the previous axis' reuses its Phi and unit-variance Q (the
 * maneuver variance s2 scales the Singer block per axis): N and E always, D too when its
 * time constants and sigmas are the horizontal ones. Cost: ~2.2k instructions on the
 * Cortex-M4F (-Os with LTO; 2.2k at -O2), mean over the vectors (scripts/fw_report.py): three expm1 per
 * distinct model, the covariance on its upper triangle.
 */
mca_status_t mca_cs3_predict(mca_cs3_t *cs, float t_s);

/**
 * mca_cs3_predict with an IMU-aided test prior on the axes whose inc[i] is given (inc may be
 * NULL, or hold NULL entries: those axes predict plainly). Everything is checked first; on
 * error no axis changes. Cost: mca_cs3_predict plus ~60 multiply-adds an aided axis.
 */
mca_status_t mca_cs3_predict_aided(mca_cs3_t *cs, float t_s, const mca_cs_inc_t *const inc[3]);

/**
 * Update the three axes; per-axis masks, an axis with mask 0 is skipped, all-zero is
 * MCA_ERR_BAD_MASK. Every axis is validated before any changes. rep (3 entries) may be NULL.
 * Without reports, N and E share one covariance update when their covariances have the same
 * bits, with the same mask and variances, both plain (docs/ALGORITHMS.md 3): E applies N's
 * gains to its own state and takes N's new P, the same bits as its own update.
 * With fuzzy rows on N and E, both tested on position and velocity against their IMU-aided
 * predictions, the rows an alarmed axis leaves out for failing go out of the other's update too
 * (docs/ALGORITHMS.md 5, the N/E pair): each axis' plan is made first, read only (a test
 * statistic and a detector step more per axis; the golden vectors run plain mode, so the
 * instruction figures below do not include it).
 * Cost: one mca_kf_update per axis with a mask, ~2.5k instructions each on the Cortex-M4F
 * (-Os with LTO, mean of the three-axis call with reports 7.4k, max 10.0k; 6.9k mean at -O2); a
 * shared E ~0.5k.
 * @param[out] ws MCA_CS_WS_LEN floats of scratch (shared with other filters by the caller)
 */
mca_status_t mca_cs3_update(mca_cs3_t *cs, const float pos_ned_m[3], const float vel_ned_mps[3],
                            const float r_pos_m2[3], const float r_vel_m2ps2[3], const uint8_t mask[3],
                            float *ws, mca_update_report_t rep[3]);

#endif /* MCA_CS_H */

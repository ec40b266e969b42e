/**
 * @file mca_att.h
 * @brief Maneuver-compensated gravity attitude EKF: quaternion nominal state plus error
 *        state [dtheta (body axes), gyro bias] (DESIGN.md 4, docs/ALGORITHMS.md 7).
 */
#ifndef MCA_ATT_H
#define MCA_ATT_H

#include "mca_robust.h"

#define MCA_ATT_NX 6
/** Scratch floats one attitude update needs (m <= 2). */
#define MCA_ATT_WS_LEN MCA_KF_WS_LEN(MCA_ATT_NX, 2)

/** Attitude filter configuration (ALGORITHMS.md 7 table). */
typedef struct {
    float gyro_noise_rps;    /**< gyro white noise density, rad/s/sqrt(Hz), >= 0 */
    float gyro_bias_rw_rps2; /**< gyro bias random walk density, rad/s^2/sqrt(Hz), >= 0 */
    float att0_var_rad2;     /**< initial roll/pitch variance, > 0 */
    float yaw0_var_rad2;     /**< initial yaw variance, > 0 */
    float bias0_var_rps2;    /**< initial gyro bias variance, > 0 */
    float rp_sigma0_rad;     /**< base std of the roll/pitch observation, > 0 */
    float rp_k_dev;          /**< std per unit of | |g_b| - g | / g, >= 0 */
    float max_tilt_obs_rad;  /**< no roll/pitch or yaw observation beyond this pitch, (0, pi/2) */
    mca_robust_config_t robust; /**< robust/adaptive mode of the roll/pitch observation */
} mca_att_config_t;

typedef struct {
    float q_nb[4];                     /**< body FRD to NED, [w, x, y, z] */
    float bias_rps[3];                 /**< gyro bias estimate */
    float p[MCA_ATT_NX * MCA_ATT_NX];  /**< error-state covariance [dtheta, db] */
    mca_robust_state_t rs;             /**< robust memory of the roll/pitch observation */
    mca_att_config_t cfg;
    float sin_max_tilt;                /**< sin(cfg.max_tilt_obs_rad), set by mca_att_init: the
                                            tilt gates compare sin(pitch), which the rows need
                                            anyway, instead of taking the pitch */
} mca_att_t;

/** Defaults of ALGORITHMS.md 7 (yaw0 for a filter without a yaw source). */
void mca_att_config_default(mca_att_config_t *cfg);
mca_status_t mca_att_config_check(const mca_att_config_t *cfg);

/** Initialise from q_nb and bias. @return MCA_ERR_BAD_CONFIG/NONFINITE/NULL or MCA_OK. */
mca_status_t mca_att_init(mca_att_t *att, const mca_att_config_t *cfg, const float q_nb[4],
                          const float bias_rps[3]);

/**
 * Gyro propagation over dt_s (ALGORITHMS.md 7). Cost: ~90 multiply-adds (F P F^T by F's blocks,
 * the products by A = I - [w x] dt written out), ~600 instructions on the Cortex-M4F.
 * @return MCA_ERR_NONFINITE (gyro), MCA_ERR_BAD_DT (dt not finite or <= 0), MCA_OK.
 */
mca_status_t mca_att_propagate(mca_att_t *att, const float gyro_b_rps[3], float dt_s);

/**
 * Roll/pitch observation from compensated gravity (ALGORITHMS.md 7).
 * @param[in] f_b_mps2   mean specific force at t_d, body
 * @param[in] acc_n_mps2 maneuver acceleration to remove, NED
 * @param[in] q_d        attitude at t_d (q_nb)
 * @param[in] g_mps2     gravity magnitude
 * @param[in] r_acc_rad2 added variance from the acceleration's uncertainty
 * @param[out] ws        MCA_ATT_WS_LEN floats of scratch
 * @param[out] rep       report (may be NULL)
 * @return MCA_OK when applied; MCA_ERR_BAD_ARG when skipped by the |g_b| or tilt gate
 *         (state unchanged); MCA_ERR_NONFINITE; MCA_ERR_SINGULAR.
 */
mca_status_t mca_att_update_gravity(mca_att_t *att, const float f_b_mps2[3], const float acc_n_mps2[3],
                                    const float q_d[4], float g_mps2, float r_acc_rad2, float *ws,
                                    mca_update_report_t *rep);

/**
 * Yaw observation psi_m (rad) with variance r_rad2, made at attitude q_d (pass the current
 * q_nb for an undelayed one). @return as mca_att_update_gravity.
 */
mca_status_t mca_att_update_yaw(mca_att_t *att, float psi_m_rad, float r_rad2, const float q_d[4], float *ws,
                                mca_update_report_t *rep);

/**
 * Yaw alignment (ALGORITHMS.md 7): set yaw to psi_m keeping roll and pitch, P row/column 2
 * zeroed and P[2][2] = r_rad2. For the first yaw observation, instead of an update.
 * @return MCA_ERR_NONFINITE, MCA_ERR_BAD_ARG (r <= 0), MCA_OK.
 */
mca_status_t mca_att_align_yaw(mca_att_t *att, float psi_m_rad, float r_rad2);

/** Tilt-compensated magnetic heading of m_b at the current roll/pitch, plus declination. */
mca_status_t mca_att_mag_heading(const mca_att_t *att, const float mag_b[3], float declination_rad,
                                 float *psi_m_rad);

#endif /* MCA_ATT_H */

/* Private to the core sources: the attitude filter's steps without their argument checks, for
 * the navigation filter (mca_nav.c). Its inputs are checked once where they enter (an IMU
 * sample, a fix, a magnetometer sample) or are its own finite state, so checking them again
 * in every step would only cost instructions. For valid arguments each gives the public
 * function's result (report NULL); the public function is the check, then this. */
#ifndef MCA_ATT_NOCHECK_H
#define MCA_ATT_NOCHECK_H

#include "mcahrs/mca_att.h"

/* mca_att_init with every pointer non-NULL, cfg valid (mca_att_config_check), q_nb and bias finite */
void mca_att_init_nocheck(mca_att_t *att, const mca_att_config_t *cfg, const float q_nb[4], const float bias[3]);

/* mca_att_propagate with gyro finite and dt finite, > 0 */
void mca_att_propagate_nocheck(mca_att_t *att, const float gyro_b_rps[3], float dt_s);

/* mca_att_update_gravity with every argument non-NULL and finite, g > 0, r_acc >= 0, no report.
 * A non-finite f, acc_n or q_d that reached it anyway is still refused (the |g_b| gate refuses a
 * NaN; the update's own check refuses a non-finite result) and changes nothing. */
mca_status_t mca_att_gravity_nocheck(mca_att_t *att, const float f_b_mps2[3], const float acc_n_mps2[3],
                                     const float q_d[4], float g_mps2, float r_acc_rad2, float *ws);

/* The same observation at the current attitude (q_d = att's q_nb) in two parts, so a caller can
 * spread its cost over two calls: the measurement (residuals nu, rows e_rows at q_nb, R = r I;
 * MCA_ERR_BAD_ARG from a gate, nothing written to att), then the update. Together they equal
 * mca_att_gravity_nocheck when att does not change between them. */
mca_status_t mca_att_gravity_measure_nocheck(const mca_att_t *att, const float f_b_mps2[3], const float acc_n_mps2[3],
                                             float g_mps2, float r_acc_rad2, float nu[2], float e_rows[6], float *r);
mca_status_t mca_att_gravity_apply_nocheck(mca_att_t *att, const float nu[2], const float e_rows[6], float r,
                                           float *ws);

/* mca_att_update_yaw with every argument non-NULL and finite, r > 0, no report (a non-finite
 * q_d is still refused through the update's check; a non-finite psi_m would be a zero residual,
 * mca_wrap_pi, so the caller keeps it out), and an innovation gate: MCA_ERR_BAD_ARG, nothing
 * changed, when nu^2 > gate (P[2][2] + r) (gate INFINITY: none; ALGORITHMS.md 7, the course gate) */
mca_status_t mca_att_yaw_nocheck(mca_att_t *att, float psi_m, float r_rad2, const float q_d[4], float *ws,
                                 float gate);

/* mca_att_align_yaw with att non-NULL, psi_m finite and r finite, > 0 */
void mca_att_align_yaw_nocheck(mca_att_t *att, float psi_m, float r);

/* mca_att_mag_heading with every pointer non-NULL, m and decl finite (a zero m is still
 * MCA_ERR_BAD_ARG) */
mca_status_t mca_att_mag_heading_nocheck(const mca_att_t *att, const float m[3], float decl, float *psi_m);

#endif /* MCA_ATT_NOCHECK_H */

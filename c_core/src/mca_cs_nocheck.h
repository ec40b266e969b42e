/* Private to the core sources: the CS filter's three-axis update without its argument checks,
 * for the navigation filter (mca_nav.c), as mca_att_nocheck.h is for the attitude filter. The
 * navigation filter builds the update from a fix it has checked where it entered, so checking
 * it again would only cost flash and instructions. For valid arguments it gives the public
 * function's result; the public function is the check, then this. */
#ifndef MCA_CS_NOCHECK_H
#define MCA_CS_NOCHECK_H

#include "mcahrs/mca_cs.h"

/* mca_cs3_update without reports (rep NULL), every pointer non-NULL, at least one mask non-zero
 * and each non-zero mask of MCA_CS_POS | MCA_CS_VEL only, the measured values finite and their
 * variances finite and > 0 */
mca_status_t mca_cs3_update_nocheck(mca_cs3_t *cs, const float pos[3], const float vel[3], const float r_pos[3],
                                    const float r_vel[3], const uint8_t mask[3], float *ws);

/* mca_cs3_init with every pointer but pos_ned_m / vel_ned_mps non-NULL, both configurations
 * valid (mca_cs_config_check) and the given position and velocity finite */
void mca_cs3_init_nocheck(mca_cs3_t *cs, const mca_cs_config_t *cfg_h, const mca_cs_config_t *cfg_v,
                          const float pos_ned_m[3], const float vel_ned_mps[3]);

/* mca_cs3_predict_aided with cs non-NULL, 0 < t <= dt_max_s of every axis' configuration, and
 * each increment given finite with variances >= 0 */
void mca_cs3_predict_aided_nocheck(mca_cs3_t *cs, float t, const mca_cs_inc_t *const inc[3]);

#endif /* MCA_CS_NOCHECK_H */

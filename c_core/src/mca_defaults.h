/* Private to the core sources: the default configurations as initialisers. One source for the
 * config_default functions (mca_robust.c, mca_cs.c, mca_att.c) and for the navigation
 * defaults (mca_nav.c), which are one constant copied in: the same values as the field by
 * field stores they replace, in a third of the flash. */
#ifndef MCA_DEFAULTS_H
#define MCA_DEFAULTS_H

#include "mcahrs/mca_att.h"
#include "mcahrs/mca_cs.h"
#include "mcahrs/mca_robust.h"

#define MCA_DEFAULTS_DEG 0.0174532925199433f

/* docs/ALGORITHMS.md 5: plain mode, the papers' parameters for the others */
#define MCA_ROBUST_CONFIG_INIT                                                                             \
    {.mode = (uint8_t)MCA_ROBUST_PLAIN, .fuzzy_reject = 1u, .akf_window = MCA_AKF_WINDOW,                  \
     .reject_reset_n = (uint8_t)MCA_ROBUST_RESET_N_DEFAULT, .row_reset_n = 50u, .akf_forget = 0.2f,      \
     .akf_q_min = 0.5f, .akf_q_max = 10.0f, .igg_k0 = 1.5f, .igg_k1 = 3.0f}

/* docs/ALGORITHMS.md 2: a CS axis; the horizontal and vertical defaults differ in the GPS
 * error and maneuver parameters (adaptive 0: the note on the default there) */
#define MCA_CS_CONFIG_INIT(sigma_p, sigma_v, sigma_a0, a_max)                                            \
    {.tau_a_s = 2.0f, .tau_p_s = 60.0f, .tau_v_s = 5.0f, .sigma_p_m = (sigma_p), .sigma_v_mps = (sigma_v), \
     .sigma_a0_mps2 = (sigma_a0), .a_max_mps2 = (a_max), .sigma_a_min_mps2 = 0.05f, .p0_var_m2 = 25.0f,   \
     .v0_var_m2ps2 = 1.0f, .a0_var_m2ps4 = 1.0f, .dt_max_s = 10.0f, .adaptive = 0u, .coast = 0u,         \
     .robust = MCA_ROBUST_CONFIG_INIT}
#define MCA_CS_CONFIG_H_INIT(sigma_a0) MCA_CS_CONFIG_INIT(1.5f, 0.05f, (sigma_a0), 6.0f)
#define MCA_CS_CONFIG_V_INIT MCA_CS_CONFIG_INIT(3.0f, 0.08f, 0.3f, 3.0f)
#define MCA_CS_SIGMA_A0_H 0.5f /* the CS filter's own horizontal default (the presets: 1) */

/* docs/ALGORITHMS.md 7: the attitude filter */
#define MCA_ATT_CONFIG_INIT(yaw0_var)                                                                     \
    {.gyro_noise_rps = 3e-3f, .gyro_bias_rw_rps2 = 1e-4f,                                                 \
     .att0_var_rad2 = (2.0f * MCA_DEFAULTS_DEG) * (2.0f * MCA_DEFAULTS_DEG), .yaw0_var_rad2 = (yaw0_var),  \
     .bias0_var_rps2 = (0.5f * MCA_DEFAULTS_DEG) * (0.5f * MCA_DEFAULTS_DEG), .rp_sigma0_rad = 0.03f,      \
     .rp_k_dev = 1.0f, .max_tilt_obs_rad = 80.0f * MCA_DEFAULTS_DEG, .robust = MCA_ROBUST_CONFIG_INIT}

#endif /* MCA_DEFAULTS_H */

/**
 * @file mca_profile.h
 * @brief The robust profiles of the navigation filter (docs/ALGORITHMS.md 5) as one call an
 *        autopilot makes at start-up, after its preset. A set-up helper outside mca_nav.h: an
 *        autopilot that sets the fields itself does not link it (scripts/fw_report.py gives its
 *        flash apart from the core's).
 */
#ifndef MCA_PROFILE_H
#define MCA_PROFILE_H

#include "mca_nav.h"

/** The robust set-ups benchmarks/bench_outliers.py measures (docs/ALGORITHMS.md 5; python
 * mcahrs.core.robust_profile names them "plain" ... "fuzzy-rows"): the first five are the
 * mca_robust_mode_t of the same number on the CS axes and the attitude filter. */
typedef enum {
    MCA_PROFILE_PLAIN = 0,
    MCA_PROFILE_FTA = 1,
    MCA_PROFILE_AKF = 2,
    MCA_PROFILE_FUZZY = 3,         /**< the fuzzy detector rejecting whole updates while alarmed */
    MCA_PROFILE_IGG3 = 4,
    MCA_PROFILE_FUZZY_INFLATE = 5, /**< the fuzzy detector inflating them (fuzzy_reject 0) */
    MCA_PROFILE_FUZZY_ROWS = 6     /**< the CS axes leave out the failing rows and coast on the IMU */
} mca_robust_profile_t;

/** fuzzy-rows' whole-update guard as a time (mca_robust_config_t.reject_reset_n at the fix rate) */
#define MCA_ROWS_GUARD_S 20.0f

/**
 * Set robust profile `profile` (mca_robust_profile_t) on a configuration, after its preset: the
 * robust mode of the CS axes and the attitude filter; fuzzy inflate also their fuzzy_reject 0;
 * fuzzy rows the CS axes' fuzzy_reject 2, coast 1, no row guard and the whole-update guard
 * MCA_ROWS_GUARD_S of fixes at gps_rate_hz (rounded, 1..254). Other fields are left as they are.
 * @return MCA_ERR_NULL; MCA_ERR_BAD_ARG (cfg unchanged) for an unknown profile or a rate that is
 *         not a finite number > 0; MCA_OK.
 */
mca_status_t mca_nav_config_robust_profile(mca_nav_config_t *cfg, uint8_t profile, float gps_rate_hz);

#endif /* MCA_PROFILE_H */

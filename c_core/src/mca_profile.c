/* Robust profiles of the navigation filter (docs/ALGORITHMS.md 5). See mca_profile.h. */
#include "mcahrs/mca_profile.h"
#include "mca_cold.h"

#include <math.h>
#include <stddef.h>

MCA_COLD mca_status_t mca_nav_config_robust_profile(mca_nav_config_t *cfg, uint8_t profile, float gps_rate_hz)
{
    if (cfg == NULL) {
        return MCA_ERR_NULL;
    }
    if (profile > (uint8_t)MCA_PROFILE_FUZZY_ROWS || !(gps_rate_hz > 0.0f && gps_rate_hz < INFINITY)) {
        return MCA_ERR_BAD_ARG;
    }
    const uint8_t mode = profile <= (uint8_t)MCA_PROFILE_IGG3 ? profile : (uint8_t)MCA_ROBUST_FUZZY;
    const float g = MCA_ROWS_GUARD_S * gps_rate_hz + 0.5f; /* round half up */
    mca_robust_config_t *const rc[3] = {&cfg->cs_h.robust, &cfg->cs_v.robust, &cfg->att.robust};
    for (size_t i = 0; i < 3u; ++i) {
        rc[i]->mode = mode;
        if (profile == (uint8_t)MCA_PROFILE_FUZZY_INFLATE) {
            rc[i]->fuzzy_reject = 0u;
        } else if (profile == (uint8_t)MCA_PROFILE_FUZZY_ROWS && i < 2u) {
            rc[i]->fuzzy_reject = 2u;
            rc[i]->reject_reset_n = (uint8_t)(g < 1.0f ? 1.0f : (g > 254.0f ? 254.0f : g));
            rc[i]->row_reset_n = 0u;
        }
    }
    if (profile == (uint8_t)MCA_PROFILE_FUZZY_ROWS) {
        cfg->cs_h.coast = 1u;
        cfg->cs_v.coast = 1u;
    }
    return MCA_OK;
}

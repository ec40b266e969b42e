/* Batch replay in the event order of docs/ALGORITHMS.md 9. See mca_replay.h. */
#include "mcahrs/mca_replay.h"

mca_status_t mca_nav_replay(mca_nav_t *nav, const mca_imu_sample_t *imu, size_t n_imu, const mca_gps_event_t *gps,
                            size_t n_gps, const mca_mag_sample_t *mag, size_t n_mag, mca_nav_output_t *out,
                            uint8_t *imu_status, uint8_t *gps_status, uint8_t *mag_status)
{
    if (nav == NULL || (n_imu > 0u && (imu == NULL || out == NULL)) || (n_gps > 0u && gps == NULL) ||
        (n_mag > 0u && mag == NULL)) {
        return MCA_ERR_NULL;
    }
    size_t i = 0u, j = 0u, k = 0u;
    /* bounded: each pass consumes one event */
    while (i < n_imu || j < n_gps || k < n_mag) {
        const uint64_t ti = i < n_imu ? imu[i].t_us : UINT64_MAX;
        const uint64_t tg = j < n_gps ? gps[j].t_rx_us : UINT64_MAX;
        const uint64_t tm = k < n_mag ? mag[k].t_us : UINT64_MAX;
        if (i < n_imu && ti <= tg && ti <= tm) {
            const mca_status_t st = mca_nav_imu(nav, ti, imu[i].gyro_b_rps, imu[i].accel_b_mps2);
            if (imu_status != NULL) {
                imu_status[i] = (uint8_t)st;
            }
            mca_nav_output(nav, &out[i]);
            ++i;
        } else if (j < n_gps && tg <= tm) {
            const mca_status_t st = mca_nav_gps(nav, &gps[j].fix);
            if (gps_status != NULL) {
                gps_status[j] = (uint8_t)st;
            }
            ++j;
        } else {
            const mca_status_t st = mca_nav_mag(nav, tm, mag[k].mag_b);
            if (mag_status != NULL) {
                mag_status[k] = (uint8_t)st;
            }
            ++k;
        }
    }
    return MCA_OK;
}

/* Batch replay in the event order of docs/ALGORITHMS.md 9. See mca_replay.h. */
#include "mcahrs/mca_replay.h"

#include <math.h>
#include <string.h>

int mca_replay_next(const mca_replay_cursor_t *c, const mca_imu_sample_t *imu, size_t n_imu,
                    const mca_gps_event_t *gps, size_t n_gps, const mca_mag_sample_t *mag, size_t n_mag)
{
    const uint64_t ti = c->i < n_imu ? imu[c->i].t_us : UINT64_MAX;
    const uint64_t tg = c->j < n_gps ? gps[c->j].t_rx_us : UINT64_MAX;
    const uint64_t tm = c->k < n_mag ? mag[c->k].t_us : UINT64_MAX;
    if (c->i < n_imu && ti <= tg && ti <= tm) {
        return MCA_EVENT_IMU;
    }
    if (c->j < n_gps && tg <= tm) {
        return MCA_EVENT_GPS;
    }
    return c->k < n_mag ? MCA_EVENT_MAG : MCA_EVENT_NONE;
}

mca_status_t mca_nav_replay(mca_nav_t *nav, const mca_imu_sample_t *imu, size_t n_imu, const mca_gps_event_t *gps,
                            size_t n_gps, const mca_mag_sample_t *mag, size_t n_mag, mca_nav_output_t *out,
                            uint8_t *imu_status, uint8_t *gps_status, uint8_t *mag_status)
{
    if (nav == NULL || (n_imu > 0u && (imu == NULL || out == NULL)) || (n_gps > 0u && gps == NULL) ||
        (n_mag > 0u && mag == NULL)) {
        return MCA_ERR_NULL;
    }
    mca_replay_cursor_t c = {0u, 0u, 0u};
    int ev;
    /* bounded: each pass consumes one event */
    while ((ev = mca_replay_next(&c, imu, n_imu, gps, n_gps, mag, n_mag)) != MCA_EVENT_NONE) {
        if (ev == MCA_EVENT_IMU) {
            const mca_status_t st = mca_nav_imu(nav, imu[c.i].t_us, imu[c.i].gyro_b_rps, imu[c.i].accel_b_mps2);
            if (imu_status != NULL) {
                imu_status[c.i] = (uint8_t)st;
            }
            mca_nav_output(nav, &out[c.i]);
            ++c.i;
        } else if (ev == MCA_EVENT_GPS) {
            const mca_status_t st = mca_nav_gps(nav, &gps[c.j].fix);
            if (gps_status != NULL) {
                gps_status[c.j] = (uint8_t)st;
            }
            ++c.j;
        } else {
            const mca_status_t st = mca_nav_mag(nav, mag[c.k].t_us, mag[c.k].mag_b);
            if (mag_status != NULL) {
                mag_status[c.k] = (uint8_t)st;
            }
            ++c.k;
        }
    }
    return MCA_OK;
}

mca_status_t mca_cs3_run(mca_cs3_t *cs, size_t n, const float *dt_s, const float *pos, const float *vel,
                         const float *r_pos, const float *r_vel, const uint8_t *mask, float *ws, float *x_out,
                         float *p_out, float *t_out, uint8_t *status)
{
    if (cs == NULL || ws == NULL || (n > 0u && (dt_s == NULL || pos == NULL || vel == NULL || r_pos == NULL ||
                                                r_vel == NULL || mask == NULL))) {
        return MCA_ERR_NULL;
    }
    for (size_t k = 0; k < n; ++k) {
        mca_status_t st = mca_cs3_predict(cs, dt_s[k]);
        /* no reports (3 x 212 B of stack): T is left in each axis' robust memory */
        const uint8_t *mk = &mask[3u * k];
        int updated = 0;
        if ((mk[0] | mk[1] | mk[2]) != 0u) {
            const mca_status_t su = mca_cs3_update(cs, &pos[3u * k], &vel[3u * k], &r_pos[3u * k], &r_vel[3u * k],
                                                   mk, ws, NULL);
            st = st != MCA_OK ? st : su;
            updated = su == MCA_OK;
        }
        if (status != NULL) {
            status[k] = (uint8_t)st;
        }
        for (size_t i = 0; i < 3u; ++i) {
            if (x_out != NULL) {
                memcpy(&x_out[15u * k + 5u * i], cs->axis[i].x, 5u * sizeof(float));
            }
            if (p_out != NULL) {
                memcpy(&p_out[75u * k + 25u * i], cs->axis[i].p, 25u * sizeof(float));
            }
            if (t_out != NULL) {
                t_out[3u * k + i] = (updated && mk[i] != 0u) ? cs->axis[i].rs.t_stat : NAN;
            }
        }
    }
    return MCA_OK;
}

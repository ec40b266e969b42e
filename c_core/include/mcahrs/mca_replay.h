/**
 * @file mca_replay.h
 * @brief Batch replay of a whole recording through the navigation top level, in the event
 *        order of docs/ALGORITHMS.md 9, so hosts (Python, benches) make one call per
 *        recording instead of one per sample. Not needed on a flight controller; the
 *        firmware link drops it (--gc-sections) unless used.
 */
#ifndef MCA_REPLAY_H
#define MCA_REPLAY_H

#include "mca_nav.h"

typedef struct {
    uint64_t t_us;
    float gyro_b_rps[3];
    float accel_b_mps2[3];
} mca_imu_sample_t;

typedef struct {
    uint64_t t_us;
    float mag_b[3];
} mca_mag_sample_t;

typedef struct {
    uint64_t t_rx_us;      /**< arrival time on the IMU clock: when the step is called */
    mca_gps_fix_t fix;
} mca_gps_event_t;

/** Where a batch replay is in its three event arrays. */
typedef struct {
    size_t i; /**< next IMU sample */
    size_t j; /**< next fix */
    size_t k; /**< next magnetometer sample */
} mca_replay_cursor_t;

/** The kinds mca_replay_next returns. */
#define MCA_EVENT_NONE 0
#define MCA_EVENT_IMU 1
#define MCA_EVENT_GPS 2
#define MCA_EVENT_MAG 3

/**
 * The kind of the next event in the order of ALGORITHMS.md 9 (by time; at equal times IMU,
 * then GPS, then magnetometer), MCA_EVENT_NONE when all are consumed. The caller handles
 * the event at c->i, c->j or c->k and advances that index. Every batch replay (navigation,
 * INS) walks its recording with this, so the order rule lives here only.
 */
int mca_replay_next(const mca_replay_cursor_t *c, const mca_imu_sample_t *imu, size_t n_imu,
                    const mca_gps_event_t *gps, size_t n_gps, const mca_mag_sample_t *mag, size_t n_mag);

/**
 * Run every event through nav (already initialised by mca_nav_init) in time order.
 * Each array must be sorted by its time. Cost: the sum of the steps.
 * @param[out] out        n_imu outputs, one after each IMU sample
 * @param[out] imu_status n_imu statuses (may be NULL); likewise gps_status, mag_status
 * @return MCA_ERR_NULL when a needed pointer is NULL, else MCA_OK (per-event statuses in
 *         the status arrays).
 */
mca_status_t mca_nav_replay(mca_nav_t *nav, const mca_imu_sample_t *imu, size_t n_imu,
                            const mca_gps_event_t *gps, size_t n_gps, const mca_mag_sample_t *mag,
                            size_t n_mag, mca_nav_output_t *out, uint8_t *imu_status,
                            uint8_t *gps_status, uint8_t *mag_status);

/**
 * Run a CS filter over n steps in one call: step k predicts over dt_s[k] and then, for the
 * axes whose mask_k[i] is set, updates with pos_ned_m[k], vel_ned_mps[k] and the variances.
 * Arrays of 3-vectors are n x 3 row-major. Outputs (each may be NULL): x_out (n x 15, the
 * three axes' states after the step), p_out (n x 75, their covariances), t_out (n x 3, the
 * update T, NaN where not updated), status (n, the first non-OK status of the step).
 * @param[out] ws MCA_CS_WS_LEN floats of scratch
 * @return MCA_ERR_NULL, else MCA_OK (per-step statuses in status).
 */
mca_status_t mca_cs3_run(mca_cs3_t *cs, size_t n, const float *dt_s, const float *pos_ned_m,
                         const float *vel_ned_mps, const float *r_pos_m2, const float *r_vel_m2ps2,
                         const uint8_t *mask, float *ws, float *x_out, float *p_out, float *t_out,
                         uint8_t *status);

#endif /* MCA_REPLAY_H */

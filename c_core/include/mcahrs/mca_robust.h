/**
 * @file mca_robust.h
 * @brief The one Kalman measurement update every filter uses, and its robust and adaptive
 *        modes (DESIGN.md section 5, docs/ALGORITHMS.md sections 1 and 5).
 */
#ifndef MCA_ROBUST_H
#define MCA_ROBUST_H

#include "mca_math.h"

/** Which update the caller wants. Selectable at run time. */
typedef enum {
    MCA_ROBUST_PLAIN = 0 /**< textbook update, docs/ALGORITHMS.md section 1 */
} mca_robust_mode_t;

/** What one update did. Sizes fixed; only the first m entries are meaningful. */
typedef struct {
    uint8_t m;                                  /**< measurement rows used */
    uint8_t mode;                               /**< mca_robust_mode_t applied */
    float nu[MCA_MEAS_MAX];                     /**< innovation z - H x- */
    float c[MCA_MEAS_MAX * MCA_MEAS_MAX];       /**< innovation covariance, m x m, row stride m */
    float t_stat;                               /**< nu^T C^-1 nu */
    float factor;                               /**< covariance inflation applied (1 = none) */
} mca_update_report_t;

/**
 * Kalman measurement update with Joseph-form covariance (docs/ALGORITHMS.md section 1).
 *
 * Cost: O(n^3 + n^2 m + m^3) flops (three n x n products). Touches only its arguments.
 * On any error x and p are unchanged.
 *
 * @param[in,out] x      state, n values
 * @param[in,out] p      covariance, n x n, symmetric
 * @param[in]     n      state size
 * @param[in]     h      measurement matrix, m x n
 * @param[in]     z      measurement, m values
 * @param[in]     r      measurement covariance, m x m, symmetric positive definite
 * @param[in]     m      measurement size, 1..MCA_MEAS_MAX
 * @param[out]    ws     scratch, at least MCA_KF_WS_LEN(n, m) floats, not aliasing x, p, h, z, r
 * @param[in]     ws_len floats available in ws
 * @param[out]    rep    report (may be NULL)
 * @return MCA_OK; MCA_ERR_NULL; MCA_ERR_BAD_ARG (m or ws_len); MCA_ERR_NONFINITE (z, r, or
 *         a non-finite result); MCA_ERR_SINGULAR (H P H^T + R not positive definite).
 */
mca_status_t mca_kf_update(float *x, float *p, size_t n, const float *h, const float *z,
                           const float *r, size_t m, float *ws, size_t ws_len,
                           mca_update_report_t *rep);

#endif /* MCA_ROBUST_H */

/**
 * @file mca_robust.h
 * @brief The one Kalman measurement update every filter uses, and its robust and adaptive
 *        modes (DESIGN.md section 5, docs/ALGORITHMS.md sections 1 and 5).
 */
#ifndef MCA_ROBUST_H
#define MCA_ROBUST_H

#include "mca_math.h"

/** Which update the caller wants. Selectable at run time (docs/ALGORITHMS.md 5). */
typedef enum {
    MCA_ROBUST_PLAIN = 0, /**< textbook update, docs/ALGORITHMS.md section 1 */
    MCA_ROBUST_FTA = 1,   /**< chi-square test, gain inflation gamma = T / chi2 (paper 000) */
    MCA_ROBUST_AKF = 2,   /**< R from innovation statistics on detection, Q scaled (paper 004) */
    MCA_ROBUST_FUZZY = 3, /**< fuzzy three-threshold detector, reject or inflate (paper 001) */
    MCA_ROBUST_IGG3 = 4   /**< IGG-III per-component weights (paper 003) */
} mca_robust_mode_t;

/** Longest innovation window any mode keeps (AKF). */
#define MCA_AKF_WINDOW 8

/** Robust-mode configuration of one filter's updates. mca_robust_config_default fills it. */
typedef struct {
    uint8_t mode;          /**< mca_robust_mode_t */
    uint8_t fuzzy_reject;  /**< fuzzy alarm: 1 reject the update, 0 inflate it */
    uint8_t akf_window;    /**< AKF window length, 1..MCA_AKF_WINDOW */
    float akf_forget;      /**< AKF recursive R-estimate weight, (0, 1] */
    float akf_q_min;       /**< AKF Q factor clamp, > 0 */
    float akf_q_max;       /**< AKF Q factor clamp, >= akf_q_min */
    float igg_k0;          /**< IGG-III k0, > 0 */
    float igg_k1;          /**< IGG-III k1, > k0 */
} mca_robust_config_t;

/** Memory a stateful mode keeps between updates of one filter (fixed size). */
typedef struct {
    float win[MCA_AKF_WINDOW];     /**< AKF: last values of nu^T nu - tr(R) */
    float nu_mean[MCA_MEAS_MAX];   /**< AKF: running innovation mean per row */
    float nu_var[MCA_MEAS_MAX];    /**< AKF: running innovation variance per row */
    float q_scale;                 /**< factor the owner applies to its Q at the next predict */
    float d_k;                     /**< fuzzy: exponentially weighted membership D_k */
    uint8_t win_n;                 /**< AKF: entries in win */
    uint8_t win_head;              /**< AKF: next slot */
    uint8_t alarm;                 /**< fuzzy: alarm raised */
    uint8_t started;               /**< AKF: row statistics initialised */
} mca_robust_state_t;

/** What one update did. Sizes fixed; only the first m entries are meaningful. */
typedef struct {
    uint8_t m;                                  /**< measurement rows used */
    uint8_t mode;                               /**< mca_robust_mode_t applied */
    float nu[MCA_MEAS_MAX];                     /**< innovation z - H x- */
    float c[MCA_MEAS_MAX * MCA_MEAS_MAX];       /**< innovation covariance, m x m, row stride m */
    float t_stat;                               /**< nu^T C^-1 nu */
    float factor;                               /**< covariance inflation applied (1 = none) */
    float w[MCA_MEAS_MAX];                      /**< IGG-III weights per row (1 = full) */
    float q_scale;                              /**< AKF Q factor after this update */
    uint8_t detected;                           /**< the mode's test flagged an outlier */
    uint8_t rejected;                           /**< the update was not applied (x, P unchanged) */
    uint8_t alarm;                              /**< fuzzy detector alarm state after this update */
} mca_update_report_t;

/** Defaults: plain mode, and the papers' parameters for the others (ALGORITHMS.md 5). */
void mca_robust_config_default(mca_robust_config_t *cfg);
/** @return MCA_ERR_BAD_CONFIG when a field is out of range, else MCA_OK. */
mca_status_t mca_robust_config_check(const mca_robust_config_t *cfg);
/** Empty memory (q_scale 1, no alarm). */
void mca_robust_state_init(mca_robust_state_t *st);

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
 * @param[in]     rc     robust configuration (NULL: plain)
 * @param[in,out] rs     robust memory (may be NULL for the stateless modes plain, FTA, IGG-III)
 * @param[out]    ws     scratch, at least MCA_KF_WS_LEN(n, m) floats, not aliasing x, p, h, z, r
 * @param[in]     ws_len floats available in ws
 * @param[out]    rep    report (may be NULL)
 * @return MCA_OK; MCA_ERR_NULL; MCA_ERR_BAD_ARG (m or ws_len); MCA_ERR_NONFINITE (z, r, or
 *         a non-finite result); MCA_ERR_SINGULAR (H P H^T + R not positive definite).
 */
mca_status_t mca_kf_update(float *x, float *p, size_t n, const float *h, const float *z,
                           const float *r, size_t m, const mca_robust_config_t *rc,
                           mca_robust_state_t *rs, float *ws, size_t ws_len,
                           mca_update_report_t *rep);

#endif /* MCA_ROBUST_H */

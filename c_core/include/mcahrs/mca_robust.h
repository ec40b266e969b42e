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

/**
 * Upper-tail levels a of the chi-square quantile table chi2_m(a) (docs/ALGORITHMS.md 5),
 * in the table's column order.
 */
typedef enum {
    MCA_CHI2_1E4 = 0,   /**< a = 1e-4: FTA threshold */
    MCA_CHI2_1E2 = 1,   /**< a = 1e-2: AKF detection */
    MCA_CHI2_5E3 = 2,   /**< a = 5e-3: fuzzy TD2 */
    MCA_CHI2_2P5E2 = 3, /**< a = 2.5e-2: fuzzy TD1 */
    MCA_CHI2_LEVELS = 4 /**< number of levels (not a level) */
} mca_chi2_level_t;

/** Longest innovation window any mode keeps (AKF). */
#define MCA_AKF_WINDOW 8

/** Default lock-up guard (mca_robust_config_t.reject_reset_n), also the guard of a fuzzy-rows update
 * that has no test innovation (ALGORITHMS.md 5). */
#define MCA_ROBUST_RESET_N_DEFAULT 5u

/** Robust-mode configuration of one filter's updates. mca_robust_config_default fills it. */
typedef struct {
    uint8_t mode;          /**< mca_robust_mode_t */
    uint8_t fuzzy_reject;  /**< fuzzy alarm: 1 reject the update, 0 inflate it, 2 leave out the failing rows */
    uint8_t akf_window;    /**< AKF window length, 1..MCA_AKF_WINDOW */
    uint8_t reject_reset_n; /**< lock-up guard: the n-th rejection in a row updates plain instead (0: off;
                                 fuzzy rows without a test innovation: at most MCA_ROBUST_RESET_N_DEFAULT) */
    uint8_t row_reset_n;    /**< row lock-up guard: a row removed n times in a row, the same (0: off) */
    float akf_forget;      /**< AKF recursive R-estimate weight, (0, 1] */
    float akf_q_min;       /**< AKF Q factor clamp, > 0 */
    float akf_q_max;       /**< AKF Q factor clamp, >= akf_q_min */
    float igg_k0;          /**< IGG-III k0, > 0 */
    float igg_k1;          /**< IGG-III k1, > k0 */
} mca_robust_config_t;

/** Memory a stateful mode keeps between updates of one filter (fixed size). */
typedef struct {
    float win[MCA_AKF_WINDOW];     /**< AKF: ring of the last values of nu^T nu - tr(R) (always
                                        MCA_AKF_WINDOW slots; the mean reads the last akf_window) */
    float nu_mean[MCA_MEAS_MAX];   /**< AKF: running innovation mean per row; fuzzy: the last tested
                                        innovation per row (read by fuzzy rows' return rule) */
    float nu_var[MCA_MEAS_MAX];    /**< AKF: running innovation variance per row */
    float q_scale;                 /**< factor the owner applies to its Q at the next predict */
    float d_k;                     /**< fuzzy: exponentially weighted membership D_k */
    float t_stat;                  /**< T of the last successful update made with this memory (the
                                        report's t_stat), for callers that pass no report; read by
                                        no mode */
    uint8_t win_n;                 /**< AKF: entries in win, saturating at MCA_AKF_WINDOW */
    uint8_t win_head;              /**< AKF: next slot */
    uint8_t alarm;                 /**< fuzzy: alarm raised */
    uint8_t started;               /**< AKF: row statistics initialised; fuzzy rows: rows the
                                        next update leaves out whatever its alarm (bit j: row j),
                                        set by the caller (mca_cs3_update: the paired horizontal
                                        axis' failing rows), cleared by that update */
    uint8_t n_reject;              /**< rejected updates in a row (lock-up guard) */
    uint8_t detected;              /**< the last successful update's detected flag (the report's),
                                        for callers that pass no report; read by no mode */
    uint8_t n_removed[MCA_MEAS_MAX]; /**< per row index: updates in a row that removed it (IGG-III
                                          weight 0; row lock-up guard) */
} mca_robust_state_t;

/** What one update did. Sizes fixed; only the first m entries are meaningful. */
typedef struct {
    uint8_t m;                                  /**< measurement rows used */
    uint8_t mode;                               /**< mca_robust_mode_t applied */
    float nu[MCA_MEAS_MAX];                     /**< innovation z - H x- */
    float c[MCA_MEAS_MAX * MCA_MEAS_MAX];       /**< innovation covariance, m x m, row stride m */
    float t_stat;                               /**< nu^T C^-1 nu */
    float factor;                               /**< covariance inflation applied (1 = none) */
    float w[MCA_MEAS_MAX];                      /**< IGG-III weights per row (1 = full; fuzzy rows
                                                     report 1: the memory's n_removed says which
                                                     rows were left out) */
    float q_scale;                              /**< AKF Q factor after this update */
    uint8_t detected;                           /**< the mode's test flagged an outlier */
    uint8_t rejected;                           /**< the update was not applied (x, P unchanged) */
    uint8_t alarm;                              /**< fuzzy detector alarm state after this update */
    uint8_t reset;                              /**< lock-up guard fired: memory cleared, plain update */
    uint8_t tested;                             /**< t_stat (and the mode's decisions) came from a test
                                                     innovation (mca_kf_update_tested), not from nu, c */
} mca_update_report_t;



/**
 * Defaults: plain mode, and the papers' parameters for the others (ALGORITHMS.md 5).
 * Cost: a memset and 8 stores. Cannot fail (cfg must not be NULL).
 */
void mca_robust_config_default(mca_robust_config_t *cfg);

/**
 * Range check of every field (mode known, fuzzy_reject 0..2, akf_window 1..MCA_AKF_WINDOW,
 * akf_forget in (0, 1], 0 < akf_q_min <= akf_q_max finite, 0 < igg_k0 < igg_k1 finite).
 * Cost: ~15 compares. Reads only cfg.
 * @return MCA_ERR_NULL (cfg NULL), MCA_ERR_BAD_CONFIG when a field is out of range, else MCA_OK.
 */
mca_status_t mca_robust_config_check(const mca_robust_config_t *cfg);

/**
 * Empty memory: q_scale 1, D_k 0, no alarm, empty AKF window, zero row statistics.
 * Cost: a memset. Cannot fail (st must not be NULL). A filter that switches its mode at run
 * time should call it: a mode only reads and writes the fields it owns (AKF: win, nu_mean,
 * nu_var, q_scale, win_n, win_head, started; fuzzy: d_k, alarm, nu_mean, started), so a q_scale left by
 * AKF would otherwise keep scaling Q after a switch to another mode.
 */
void mca_robust_state_init(mca_robust_state_t *st);

/**
 * 1 when the last update made with this memory left a row out: it was rejected, or one of its
 * m rows was removed (IGG-III weight 0, fuzzy rows). A lock-up guard's plain update leaves none
 * out. Cost: m + 1 compares. Reads only st (not NULL).
 */
int mca_robust_left_out(const mca_robust_state_t *st, size_t m);

/**
 * Upper-a quantile of chi-square with m degrees of freedom, chi2_m(a) =
 * scipy.stats.chi2.ppf(1 - a, m), from the compiled table (scripts/gen_chi2_table.py).
 * Cost: one table read. Cannot fail.
 * @param[in] m     degrees of freedom, 1..MCA_MEAS_MAX
 * @param[in] level upper-tail level
 * @return the quantile (> 0); 0.0f when m or level is out of range (never a valid quantile).
 */
float mca_chi2_quantile(size_t m, mca_chi2_level_t level);

/**
 * Scratch floats mca_kf_update needs for n states and m rows: MCA_KF_WS_LEN(n, m), as a
 * function for bindings that cannot expand the macro. Cost: a few multiplies. Cannot fail.
 */
size_t mca_kf_ws_len(size_t n, size_t m);

/**
 * Kalman measurement update, Joseph-form covariance (docs/ALGORITHMS.md section 1) in
 * the robust/adaptive mode rc->mode (section 5): plain, FTA, AKF, fuzzy, IGG-III.
 *
 * Two paths (docs/ALGORITHMS.md 1, "Sequential form"), the same update in exact arithmetic:
 * - Row by row, when R (with the mode's increments) is diagonal and the gain is not inflated
 *   (every mode but FTA / fuzzy inflation on a detection): each kept row is a scalar update,
 *   u = P h^T, s = h u + r, k = u / s, x += k nu, P -= k u^T on the upper triangle (for this
 *   gain Joseph's form gives the same matrix), T = sum nu_i^2 / s_i. Cost per row: nz n
 *   multiply-adds for u (nz the row's non-zero entries: rows of P, as P is symmetric),
 *   n(n+1)/2 for P, mirrored as it is written, one division; P is written whole. In plain mode
 *   without a report nothing else runs: no m x m matrix is formed or factored.
 * - Joint, otherwise: nu, P H^T, C = H P H^T + R over H's non-zero entries, C's Cholesky
 *   factor, the gain by n solves of size m, expanded Joseph P + A K^T + K A^T (n^2 m + 2 n m^2
 *   multiply-adds).
 * Robust modes and a report form nu and C first (O(nz (n + m))), factor C (m^3 / 6, m sqrtf)
 * for T; AKF adds O(m n + MCA_AKF_WINDOW) and one log2 (the core's own, ~15 flops, no libm);
 * IGG-III m^2 sqrtf; fuzzy O(1). A test innovation adds one m x m factor and solve (for
 * m <= 2, T in closed form from C_t's determinant). On the
 * Cortex-M4F (-Os, scripts/fw_report.py) a plain CS axis update (n = 5, m <= 2) is ~2.5k
 * instructions (mca_cs3_update mean / 3), the roll/pitch update
 * (n = 6, m = 2) ~2k; scripts/fw_profile.py splits them by function. Stack: scalars and pointers
 * only, no arrays (72 bytes for the checks, then 264 for the general path or 88 for the row
 * path, each with 88 + 32 for the row kernel, in the Cortex-M4F firmware build).
 * Touches only its arguments: x, p, rs (AKF and fuzzy only) and rep are written, ws is
 * scratch, everything else is read only.
 *
 * Errors are checked before anything is written; on any error x, p and rs are unchanged
 * (rep is meaningful only on MCA_OK: after an error it may hold nu, C, T and IGG-III weights
 * of the failed update). A rejected update (fuzzy alarm with fuzzy_reject, or IGG-III
 * removing every row) returns MCA_OK with rep->rejected = 1 and x, p unchanged; the fuzzy
 * detector's memory still advances.
 *
 * @param[in,out] x      state, n values (finite)
 * @param[in,out] p      covariance, n x n, symmetric (finite; the row path reads its upper
 *                       triangle and the rows H uses, and writes P+ whole)
 * @param[in]     n      state size, >= 1
 * @param[in]     h      measurement matrix, m x n (finite)
 * @param[in]     z      measurement, m values
 * @param[in]     r      measurement covariance, m x m, symmetric positive definite
 * @param[in]     m      measurement size, 1..MCA_MEAS_MAX
 * @param[in]     rc     robust configuration (NULL: plain); checked with mca_robust_config_check
 *                       unless its mode is plain, which reads no other field
 * @param[in,out] rs     robust memory; required (non-NULL) by AKF and fuzzy, ignored (may be
 *                       NULL) by plain, FTA and IGG-III
 * @param[out]    ws     scratch, at least MCA_KF_WS_LEN(n, m) floats, not aliasing x, p, h, z, r
 * @param[in]     ws_len floats available in ws
 * @param[out]    rep    report (may be NULL)
 * @return MCA_OK; MCA_ERR_NULL (x, p, h, z, r, ws, or rs when the mode needs it);
 *         MCA_ERR_BAD_ARG (n, m or ws_len out of range, or an rs that mca_robust_state_init and
 *         this function cannot have produced: counters out of range, non-finite or negative
 *         statistics); MCA_ERR_BAD_CONFIG (rc out of range, a mode other than plain); MCA_ERR_NONFINITE (x, p, h, z or
 *         r not finite, a non-finite T in a robust mode, or a non-finite result);
 *         MCA_ERR_SINGULAR (H P H^T + R, or the mode's modified gain covariance, not
 *         positive definite).
 */
mca_status_t mca_kf_update(float *x, float *p, size_t n, const float *h, const float *z,
                           const float *r, size_t m, const mca_robust_config_t *rc,
                           mca_robust_state_t *rs, float *ws, size_t ws_len,
                           mca_update_report_t *rep);

/**
 * mca_kf_update whose robust mode tests a given innovation instead of its own
 * (docs/ALGORITHMS.md 5, "Test innovation"): T = nu_t^T C_t^-1 nu_t decides FTA, AKF detection
 * and fuzzy; IGG-III weights rows by |nu_t,i| / sqrt(C_t,ii); AKF's row statistics (R*) follow
 * nu_t. The gain, the state correction, Joseph and AKF's Q window use the nominal nu and C as
 * in mca_kf_update, which is this function with test NULL. rep->t_stat is the tested T and
 * rep->tested is 1; rep->nu and rep->c stay the nominal ones.
 * Cost: mca_kf_update plus one m x m Cholesky and solve (m^3/6 + m^2 multiply-adds, m sqrtf).
 * The navigation filter predicts the GPS measurement with the IMU for the test, so a maneuver,
 * which the accelerometer sees, is not taken for an outlier while the CS filter's own
 * constant-acceleration prediction lags it.
 * @param[in] nu_t test innovation, m values (NULL: test the update's own; then c_t is ignored)
 * @param[in] c_t  its covariance including R, m x m, row stride m, positive definite
 *                 (MCA_ERR_SINGULAR); both finite (MCA_ERR_NONFINITE); read only.
 * Every other parameter, error and guarantee as mca_kf_update.
 */
mca_status_t mca_kf_update_tested(float *x, float *p, size_t n, const float *h, const float *z,
                                  const float *r, size_t m, const mca_robust_config_t *rc,
                                  mca_robust_state_t *rs, const float *nu_t, const float *c_t,
                                  float *ws, size_t ws_len, mca_update_report_t *rep);

/**
 * T = nu_t^T C_t^-1 nu_t of a test innovation, bit for bit as mca_kf_update_tested takes it:
 * C_t symmetrised, closed form for m <= 2 (when C_t's determinant is positive and finite),
 * else from its Cholesky factor. For a caller that applies an update's result itself
 * (mca_cs3_update's shared N/E covariance) and reports the same T.
 * @param[in]  nu_t, c_t m and m x m values (not checked for finiteness: T is then not finite)
 * @param[out] ws 2 m^2 + m floats of scratch; t_stat the statistic
 * @return MCA_ERR_NULL, MCA_ERR_BAD_ARG (m 0 or > MCA_MEAS_MAX), MCA_ERR_SINGULAR (C_t not
 *         positive definite), or MCA_OK.
 */
mca_status_t mca_kf_test_stat(const float *nu_t, const float *c_t, size_t m, float *ws, float *t_stat);

/**
 * mca_kf_update_tested in plain mode with no report and a diagonal R (its row-by-row form), which
 * also returns what each row did: for row i (in order, all rows) gains[i (n + 1) + j] = k_j, the
 * gain applied to x_j, and gains[i (n + 1) + n] = 1 / s_i. A state whose covariance has the same
 * bits as p had, updated with the same h and r, gets the same P+ and these gains
 * (mca_cs3_update: the N and E axes).
 * @param[out] gains m (n + 1) floats
 * @return MCA_ERR_BAD_ARG also for an R with an off-diagonal entry; else as mca_kf_update_tested.
 */
mca_status_t mca_kf_update_plain(float *x, float *p, size_t n, const float *h, const float *z, const float *r,
                                 size_t m, mca_robust_state_t *rs, const float *nu_t, const float *c_t, float *ws,
                                 size_t ws_len, float *gains);

#endif /* MCA_ROBUST_H */

/* Private to the core sources: the one-row step of the sequential measurement update
 * (ALGORITHMS.md 1) and the memory a plain update leaves, shared by mca_kf_update's row path
 * and the attitude filter's plain update (mca_att.c). */
#ifndef MCA_KF_ROWS_H
#define MCA_KF_ROWS_H

#include "mcahrs/mca_robust.h"

#include <stddef.h>

/* x+ = x + k nu and P+ = P - k u^T for k = u inv (n states): the upper triangle computed, each
 * value written twice (mirrored), from xs, ps into xn, pn (in place allowed: xn = xs,
 * pn = ps). Returns the sum of v * 0 over the values written: +-0 while all are finite, NaN
 * after one that is not. */
float mca_kf_row_apply(const float *xs, const float *ps, float *xn, float *pn, const float *u, size_t n, float inv,
                       float nu);

/* A successful plain update's memory (rs NULL: none): no rejection or removed row in a row, T,
 * not detected. */
void mca_kf_plain_memory(mca_robust_state_t *rs, size_t m, float t_stat);

/* Fuzzy rows (rc: mode fuzzy, fuzzy_reject 2; not checked): the rows an update tested on nu_t,
 * c_t (m x m, 1 <= m <= MCA_MEAS_MAX) would leave out while alarmed for failing their own test,
 * and the rows it keeps out that went out no later than the longest-out failing one (a fault of
 * both; docs/ALGORITHMS.md 5, the N/E pair), bit j for row j. 0 when it would not alarm, when no
 * row fails (a whole rejection), and when C_t is refused or T is not finite (the update reports
 * those). Reads rc and rs; ws: 3 m^2 floats of scratch. */
unsigned mca_kf_fuzzy_failed(const mca_robust_config_t *rc, const mca_robust_state_t *rs, const float *nu_t,
                             const float *c_t, size_t m, float *ws);

/* The robust inputs an update of rc's mode reads: MCA_OK for plain (rc NULL or mode plain);
 * else MCA_ERR_BAD_CONFIG for a configuration mca_robust_config_check refuses, and for AKF and
 * fuzzy MCA_ERR_NULL without a memory, MCA_ERR_BAD_ARG for a memory that mca_robust_state_init
 * and the updates cannot have produced. The public updates check it; the filters' own paths
 * check it where their configuration and memory enter (init, their public updates). */
mca_status_t mca_robust_inputs_check(const mca_robust_config_t *rc, const mca_robust_state_t *rs);

/* mca_kf_update_tested past its pointer, size and robust-input checks (ws at least
 * MCA_KF_WS_LEN(n, m) floats); the finite checks of z, R, H and the test stay: they are what
 * refuses an overflowed covariance. gains NULL, or (plain mode, a diagonal R, rep NULL: the
 * row-by-row form, which writes them) the rows' gains as mca_kf_update_plain gives them. */
mca_status_t mca_kf_update_tested_nocheck(float *x, float *p, size_t n, const float *h, const float *z,
                                          const float *r, size_t m, const mca_robust_config_t *rc,
                                          mca_robust_state_t *rs, const float *nu_t, const float *c_t, float *ws,
                                          mca_update_report_t *rep, float *gains);

#endif /* MCA_KF_ROWS_H */

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

#endif /* MCA_KF_ROWS_H */

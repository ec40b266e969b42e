/**
 * @file mca_math.h
 * @brief Status codes and the small float32 linear algebra the filters share.
 *
 * Matrices are row-major float arrays with their dimensions passed explicitly; every loop
 * is bounded by those dimensions, which callers take from mca_config.h. No function here
 * allocates memory or touches memory other than its arguments. Output arguments may not
 * alias inputs unless said.
 */
#ifndef MCA_MATH_H
#define MCA_MATH_H

#include <stddef.h>
#include <stdint.h>

#include "mca_config.h"

/** Result of every public function that can fail. docs/ALGORITHMS.md section 4. */
typedef enum {
    MCA_OK = 0,
    MCA_ERR_NULL = 1,           /**< a required pointer is NULL */
    MCA_ERR_BAD_DT = 2,         /**< step length not finite, <= 0 or above the configured maximum */
    MCA_ERR_NONFINITE = 3,      /**< an input value is NaN or infinite */
    MCA_ERR_SINGULAR = 4,       /**< innovation covariance not positive definite */
    MCA_ERR_BAD_MASK = 5,       /**< measurement mask empty or with unknown bits */
    MCA_ERR_BAD_ARG = 6,        /**< an argument outside its documented range */
    MCA_ERR_BAD_CONFIG = 7,     /**< a configuration value outside its documented range */
    MCA_ERR_TIME_BACKWARDS = 8, /**< a time stamp earlier than the last one accepted */
    MCA_ERR_RANGE = 9,          /**< latitude/longitude/altitude out of range */
    MCA_ERR_NOT_INIT = 10       /**< the filter has not been initialised */
} mca_status_t;

/** 1 when x is neither NaN nor infinite. Cost: a compare. */
int mca_finite(float x);

/** 1 when x is finite and > 0 (NaN and infinities fail). Cost: two compares. */
int mca_positive(float x);

/** 1 when x is finite and >= 0. Cost: two compares. */
int mca_nonneg(float x);

/**
 * Range check of the float fields of a configuration struct s at the byte offsets off[0..n)
 * (n <= 32): field k must be finite and >= 0 when bit k of nonneg is set, finite and > 0
 * otherwise. 1 when every field passes. Cost: n loads and integer compares.
 */
int mca_fields_ok(const void *s, const uint16_t *off, size_t n, uint32_t nonneg);

/** 1 when all n values are finite. Cost: 2n float operations and one compare (~4n instructions on the M4F). */
int mca_all_finite(const float *v, size_t n);

/**
 * dst[0..n) = src[0..n), not overlapping. The core's copies use these two loops, not libc's
 * memcpy: newlib-nano's is 308 B of flash on the Cortex-M4F (speed-unrolled), a loop ~20 B.
 * Cost: mca_copyf ~2n + 15 instructions (four floats a load-multiple and store-multiple on the
 * M4F, ~48 B of flash); mca_copy_bytes ~4 a byte (cold paths: configuration copies).
 */
void mca_copyf(float *dst, const float *src, size_t n);
/** Byte copy of n bytes, not overlapping (struct copies). */
void mca_copy_bytes(void *dst, const void *src, size_t n);
/**
 * dst[0..n) = 0, any object: the zeroing of the navigation core (initialisation, restarts, the
 * reports), in place of libc's memset, newlib-nano's being 164 B of flash on the Cortex-M4F. A
 * word a turn (a 4-byte memcpy, one store on the M4F), then the bytes left.
 * Cost: ~7 instructions a word (cold paths; an update's plan is set field by field).
 */
void mca_zero_bytes(void *dst, size_t n);

/** c (r x k) = a (r x n) * b (n x k). c must not alias a or b. */
void mca_mat_mul(float *c, const float *a, const float *b, size_t r, size_t n, size_t k);

/** c (r x k) = a (r x n) * b^T, b being (k x n). c must not alias a or b. */
void mca_mat_mul_bt(float *c, const float *a, const float *b, size_t r, size_t n, size_t k);

/** a (n x n) = (a + a^T) / 2, in place. */
void mca_mat_symmetrize(float *a, size_t n);

/**
 * Cholesky factor of a symmetric positive definite n x n matrix: a = l l^T, l lower
 * triangular (upper part set to zero). Cost O(n^3/6). n <= MCA_MEAS_MAX.
 * @return MCA_ERR_SINGULAR when a is not positive definite (or not finite); l is then
 *         unspecified but finite.
 */
mca_status_t mca_cholesky(float *l, const float *a, size_t n);

/** Solve l l^T x = b in place in b (n values), l from mca_cholesky. */
void mca_cholesky_solve(const float *l, float *b, size_t n);

/* ---- Quaternions [w, x, y, z], Hamilton, q_nb rotates body FRD to NED (DESIGN.md 2). ---- */

/** r = p (x) q. r may not alias p or q. */
void mca_quat_mul(float r[4], const float p[4], const float q[4]);

/** Normalise in place; a zero or non-finite quaternion becomes identity. Returns the old norm. */
float mca_quat_normalize(float q[4]);

/** Unit quaternion of rotation vector rv (rad), exact (sin/cos), small-angle safe. */
void mca_quat_from_rotvec(float q[4], const float rv_rad[3]);

/** v_n = C_nb v_b without forming the matrix (two cross products). v_n may alias v_b. */
void mca_quat_rotate(float v_n[3], const float q_nb[4], const float v_b[3]);

/** Direction cosine matrix C_nb (row-major 3 x 3) of unit quaternion q_nb: v_n = C_nb v_b. */
void mca_quat_to_dcm(float c_nb[9], const float q_nb[4]);

/**
 * ZYX Euler angles of q_nb: roll phi in [-pi, pi], pitch theta in [-pi/2, pi/2],
 * yaw psi in [-pi, pi]. euler_rad = {phi, theta, psi}.
 */
void mca_quat_to_euler(float euler_rad[3], const float q_nb[4]);
/** mca_quat_to_euler of the angles whose bit is set in axes (1 roll, 2 pitch, 4 yaw; the same
 *  bits), the others 0: one atan2 an angle, for callers that need two of the three. */
void mca_quat_to_euler_part(float euler_rad[3], const float q_nb[4], unsigned axes);

/** q_nb from ZYX Euler angles {phi, theta, psi} (rad). */
void mca_quat_from_euler(float q_nb[4], const float euler_rad[3]);

/**
 * sin and cos of x (rad), |x| < 1e4: Cody-Waite reduction by pi/2 and minimax polynomials
 * on [-pi/4, pi/4] (Cephes), ~1 ulp. The core's own, so host and target compute the same
 * bits and the firmware does not link newlib's 3 KiB large-argument reduction.
 */
void mca_sincosf(float x, float *s, float *c);
float mca_sinf(float x);
float mca_cosf(float x);

/*
 * exp, expm1 and atan2: the core's own, in float32 +, -, *, / and bit operations (no libm,
 * no double, no table), so host and target compute the same bits and the firmware links
 * nothing from libm (newlib's exp, expm1, atan, atan2, floor and errno wrappers were 2.4 KiB).
 * Errors measured against float64 NumPy on dense grids of float32 (every 16th to 128th bit
 * pattern) and seeded random samples of the whole domain, in ulp of float32 at the float64
 * value: tests/python/test_math.py, which asserts these figures. Polynomial coefficients:
 * scripts/gen_libm_poly.py (Remez). Costs: static path lengths of the -O2 M4F code.
 */

/**
 * e^x. Max error 0.80 ulp for normal results; a subnormal result (x < -87.3) is within
 * 1 ulp (2^-149). NaN gives NaN, x > 88.72 +inf, x < -103.97 +0.
 * Cost: ~40 instructions, one float-int conversion, no division (368 B of flash).
 */
float mca_expf(float x);

/**
 * e^x - 1, cancellation-free for small |x|. Max error 0.83 ulp for |x| <= ln(2)/2, where
 * there is no argument reduction at all (the CS filter's expm1f(-alpha T), alpha T down to
 * 1e-7 and below; below 2^-24 the result is x exactly), 0.91 ulp elsewhere. NaN gives NaN,
 * x > 88.72 +inf, x < -18 exactly -1; -0 stays -0.
 * Cost: ~35 instructions for |x| <= ln(2)/2, ~50 beyond, no division (576 B of flash).
 */
float mca_expm1f(float x);

/**
 * atan2(y, x) in [-pi, pi] with C's conventions for zeros and infinities (atan2(+-0, -0) =
 * +-pi, atan2(+-inf, +-inf) = +-pi/4 or +-3pi/4); NaN in either gives NaN. Max error
 * 1.49 ulp (measured 1.484, where y/x lies just above 1/4: its rounding is a whole ulp of
 * the angle one binade lower). Reduction as fdlibm's atanf (bands 7/16, 11/16).
 * Cost: one division and ~60 other instructions (512 B of flash).
 */
float mca_atan2f(float y, float x);

/**
 * Wrap an angle to [-pi, pi): fmodf(a + pi, 2 pi) (+ 2 pi when negative) - pi, bit for bit
 * for |a + pi| < 4 pi, within a few ulp of a beyond. Non-finite a gives 0.
 * Cost: ~10 instructions, no libm.
 */
float mca_wrap_pi(float a_rad);

#endif /* MCA_MATH_H */

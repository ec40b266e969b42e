/* Small float32 linear algebra and quaternions. See mca_math.h. */
#include "mcahrs/mca_math.h"
#include "mca_cold.h"

#include <math.h>
#include <string.h>

#define MCA_PI_F 3.14159265358979f

int mca_finite(float x)
{
    return isfinite(x) ? 1 : 0;
}

/* On the bits (one integer compare each, no FPU flags): a positive finite float is 0x00000001
 * (the smallest denormal) to 0x7f7fffff (FLT_MAX); -0 (0x80000000) is >= 0 as well. */
int mca_positive(float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    return u - 1u < 0x7f7fffffu;
}

int mca_nonneg(float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    return u <= 0x7f7fffffu || u == 0x80000000u;
}

int mca_fields_ok(const void *s, const uint16_t *off, size_t n, uint32_t nonneg)
{
    const unsigned char *b = (const unsigned char *)s;
    for (size_t k = 0; k < n; ++k) {
        float v;
        memcpy(&v, b + off[k], sizeof v);
        if (!(((nonneg >> k) & 1u) != 0u ? mca_nonneg(v) : mca_positive(v))) {
            return 0;
        }
    }
    return 1;
}

int mca_all_finite(const float *v, size_t n)
{
    /* v - v is +0 for a finite v and NaN for an infinite or NaN one, so the sums stay +0
     * exactly when every element is finite: two float operations per element and no
     * compare-and-branch (8 instructions per element on the M4F before, ~4 now; it runs on
     * every measurement update's inputs). Two sums halve the loop overhead. */
    float s0 = 0.0f, s1 = 0.0f;
    size_t i = 0;
    for (; i + 1u < n; i += 2u) {
        s0 += v[i] - v[i];
        s1 += v[i + 1u] - v[i + 1u];
    }
    if (i < n) {
        s0 += v[i] - v[i];
    }
    return isfinite(s0 + s1) ? 1 : 0;
}

void mca_mat_mul(float *c, const float *a, const float *b, size_t r, size_t n, size_t k)
{
    for (size_t i = 0; i < r; ++i) {
        for (size_t j = 0; j < k; ++j) {
            float s = 0.0f;
            for (size_t l = 0; l < n; ++l) {
                s += a[i * n + l] * b[l * k + j];
            }
            c[i * k + j] = s;
        }
    }
}

void mca_mat_mul_bt(float *c, const float *a, const float *b, size_t r, size_t n, size_t k)
{
    for (size_t i = 0; i < r; ++i) {
        for (size_t j = 0; j < k; ++j) {
            float s = 0.0f;
            for (size_t l = 0; l < n; ++l) {
                s += a[i * n + l] * b[j * n + l];
            }
            c[i * k + j] = s;
        }
    }
}

void mca_mat_symmetrize(float *a, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        for (size_t j = i + 1; j < n; ++j) {
            const float s = 0.5f * (a[i * n + j] + a[j * n + i]);
            a[i * n + j] = s;
            a[j * n + i] = s;
        }
    }
}

/* Four floats as one object: a struct copy of it is one load-multiple and one store-multiple on
 * the M4F. Reading floats through it is allowed (an aggregate with float members, C99 6.5p7). */
typedef struct {
    float v[4];
} mca_f4_t;

void mca_copyf(float *dst, const float *src, size_t n)
{
    const float *const end4 = src + (n & ~(size_t)3u), *const end = src + n;
    while (src != end4) {
        *(mca_f4_t *)dst = *(const mca_f4_t *)src;
        dst += 4;
        src += 4;
    }
    while (src != end) {
        *dst++ = *src++;
    }
}

/* Not inlined into the configuration defaults (cold code): 12 B of flash less. */
MCA_NOINLINE void mca_copy_bytes(void *dst, const void *src, size_t n)
{
    unsigned char *d = (unsigned char *)dst;
    const unsigned char *s = (const unsigned char *)src;
    for (size_t i = 0; i < n; ++i) {
        d[i] = s[i];
    }
}

void mca_zero_bytes(void *dst, size_t n)
{
    unsigned char *d = (unsigned char *)dst;
    const uint32_t zero = 0u;
    size_t i = 0;
    for (; i + 4u <= n; i += 4u) { /* a word a turn: a 4-byte memcpy is one store, no call */
        memcpy(d + i, &zero, sizeof zero);
    }
    for (; i < n; ++i) {
        d[i] = 0u;
    }
}

mca_status_t mca_cholesky(float *l, const float *a, size_t n)
{
    /* Column by column; row j's upper part is zeroed with column j's lower part, so no
     * separate zero pass (a memset call on the deepest stack path of every update). */
    for (size_t j = 0; j < n; ++j) {
        float d = a[j * n + j];
        for (size_t k = 0; k < j; ++k) {
            d -= l[j * n + k] * l[j * n + k];
        }
        /* !(d > 0) also catches NaN; sqrtf(+inf) would not be a usable factor. */
        if (!(d > 0.0f) || !isfinite(d)) {
            /* unspecified but finite: all zero, column by column (a strided loop, which the
             * compiler does not turn into a memset call either) */
            for (size_t k = 0; k < n; ++k) {
                for (size_t i = 0; i < n; ++i) {
                    l[i * n + k] = 0.0f;
                }
            }
            return MCA_ERR_SINGULAR;
        }
        const float ljj = sqrtf(d);
        l[j * n + j] = ljj;
        for (size_t i = j + 1; i < n; ++i) {
            float s = a[i * n + j];
            for (size_t k = 0; k < j; ++k) {
                s -= l[i * n + k] * l[j * n + k];
            }
            l[i * n + j] = s / ljj;
            l[j * n + i] = 0.0f;
        }
    }
    return MCA_OK;
}

void mca_cholesky_solve(const float *l, float *b, size_t n)
{
    /* forward: l y = b */
    for (size_t i = 0; i < n; ++i) {
        float s = b[i];
        for (size_t k = 0; k < i; ++k) {
            s -= l[i * n + k] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
    /* backward: l^T x = y */
    for (size_t ii = n; ii-- > 0;) {
        float s = b[ii];
        for (size_t k = ii + 1; k < n; ++k) {
            s -= l[k * n + ii] * b[k];
        }
        b[ii] = s / l[ii * n + ii];
    }
}

void mca_sincosf(float x, float *s, float *c)
{
    /* k = nearest integer to x / (pi/2); r = x - k pi/2 in three parts (exact products) */
    /* floor(v) without libm's floorf: truncation toward zero, one down for a negative
     * fraction; exact for every float (|v| >= 2^23 is already an integer). */
    const float v = x * 0.636619772367581f + 0.5f;
    float kf = v;
    int32_t ki = 0;
    if (fabsf(v) < 8388608.0f) {
        ki = (int32_t)v;
        kf = (float)ki;
        if (kf > v) {
            kf -= 1.0f;
            --ki;
        }
    }
    const float r = ((x - kf * 1.5703125f) - kf * 4.837512969970703125e-4f) - kf * 7.54978995489188e-8f;
    const float z = r * r;
    const float sr = r + r * z * (-1.6666654611e-1f + z * (8.3321608736e-3f + z * -1.9515295891e-4f));
    const float cr = 1.0f - 0.5f * z + z * z * (4.166664568298827e-2f + z * (-1.388731625493765e-3f +
                                                                              z * 2.443315711809948e-5f));
    const int32_t q = ki & 3; /* (ki 0 beyond 2^23, far outside the documented domain) */
    *s = q == 0 ? sr : q == 1 ? cr : q == 2 ? -sr : -cr;
    *c = q == 0 ? cr : q == 1 ? -sr : q == 2 ? -cr : sr;
}

float mca_sinf(float x)
{
    float s, c;
    mca_sincosf(x, &s, &c);
    return s;
}

float mca_cosf(float x)
{
    float s, c;
    mca_sincosf(x, &s, &c);
    return c;
}

/* ---- exp, expm1, atan2: the core's own (see mca_math.h for the measured errors) ---- */

/* 2^k, -126 <= k <= 127, exactly: the exponent field written directly. */
static float pow2i(int32_t k)
{
    const uint32_t bits = (uint32_t)(k + 127) << 23;
    float f;
    memcpy(&f, &bits, sizeof(f));
    return f;
}

/* p 2^k for -151 <= k <= 128 with one rounding (two in the subnormal range, so within an
 * ulp of the subnormal result there); overflows to inf. */
static float scale2(float p, int32_t k)
{
    const int32_t kk = k > 127 ? k - 1 : k < -126 ? k + 64 : k;
    p *= pow2i(kk); /* exact, normal */
    return k > 127 ? p * 2.0f : k < -126 ? p * 0x1p-64f : p;
}

/* e^x - 1 = 2^k (1 + r + corr) - 1 for |x| <= 104 (|k| <= 150), |r| <= ln(2)/2, corr the
 * part of expm1(r) after the exact r (|corr| <= 0.07): the one reduction and polynomial of
 * mca_expf and mca_expm1f. |x| <= ln(2)/2 is not reduced (k = 0, r = x exactly): the
 * small-argument region where the CS filter needs expm1f(-x), x -> 0, has no reduction error.
 * Otherwise ln 2 in two parts (Cephes): the high part has 9 significant bits, so k C1 and
 * x - k C1 are exact (Sterbenz) and r = (x - k C1) + k C2 rounds once; that rounding, c, is
 * recovered (Fast2Sum) and folded into corr (worth up to 0.7 ulp of expm1f otherwise).
 * corr = r^2/2 + r^3 Q(r) + c (1 + r), Q the degree-4 minimax fit of
 * scripts/gen_libm_poly.py (1.1e-9 relative to expm1(r)). */
static float exp_parts(float x, int32_t *k, float *corr)
{
    int32_t ki = 0;
    float r = x, c = 0.0f;
    if (!(fabsf(x) <= 0.34657359f)) {
        const float t = x * 1.44269504f; /* 1 / ln 2 */
        ki = (int32_t)(t < 0.0f ? t - 0.5f : t + 0.5f);
        const float kf = (float)ki;
        const float a = x - kf * 0.693359375f;
        const float b = kf * 2.12194440e-4f; /* -C2: C1 + C2 = ln 2 to 6e-14 */
        r = a + b;
        c = (a - r) + b;
    }
    const float q = 1.666666567e-01f +
                    r * (4.166648164e-02f + r * (8.333419450e-03f + r * (1.393324463e-03f + r * 1.982412941e-04f)));
    *k = ki;
    *corr = (r * r) * (0.5f + r * q) + (c + c * r);
    return r;
}

float mca_expf(float x)
{
    if (isnan(x)) {
        return x + x;
    }
    if (x > 88.8f) {
        return INFINITY; /* above ln(FLT_MAX) = 88.72 (88.72 .. 88.8 overflows in scale2) */
    }
    if (x < -104.0f) {
        return 0.0f; /* below ln(2^-150) = -103.97: rounds to zero */
    }
    int32_t k;
    float corr;
    const float r = exp_parts(x, &k, &corr);
    return scale2(1.0f + (r + corr), k);
}

float mca_expm1f(float x)
{
    if (isnan(x)) {
        return x + x;
    }
    if (x > 88.8f) {
        return INFINITY;
    }
    if (x < -18.0f) {
        return -1.0f; /* e^x < 2^-25.9: -1 + e^x rounds to -1 */
    }
    if (fabsf(x) < 5.9604645e-08f) {
        return x; /* 2^-24: x + x^2/2 rounds to x; -0 stays -0 */
    }
    int32_t k;
    float corr;
    const float r = exp_parts(x, &k, &corr);
    if (k == 0) {
        return r + corr; /* |x| <= ln(2)/2, r = x */
    }
    const float t = pow2i(k < 127 ? k : 127);
    if (k < 0) {
        /* 2^k em + (2^k - 1): 2^k em exact, 2^k - 1 exact or (k = -25) within a quarter ulp
         * of the result: em's rounding and one more */
        return t * (r + corr) + (t - 1.0f);
    }
    if (k == 1) {
        /* 2r + 1 exact (Sterbenz) where the result is small (r < -1/4), then the correction:
         * 2 em + 1 would double em's rounding */
        return ((t - 1.0f) + t * r) + t * corr;
    }
    /* 2^k ((1 - 2^-k) + em), 1 - 2^-k exact up to k = 24; beyond, the -1 goes in as a
     * 2^-k below em's last bit, not as a second rounding after the scaling */
    const float m = k < 100 ? pow2i(-k) : 0.0f;
    return k <= 24 ? t * ((1.0f - m) + (r + corr)) : scale2(1.0f + (r + (corr - m)), k);
}

float mca_atan2f(float y, float x)
{
    if (isnan(x) || isnan(y)) {
        return x + y;
    }
    float ax = fabsf(x), ay = fabsf(y);
    const int inf_x = !(ax <= 3.4028235e38f), inf_y = !(ay <= 3.4028235e38f);
    if (inf_x || inf_y) {
        /* both infinite: the diagonal, as C's atan2; one: the axis it points along */
        ax = inf_x ? 1.0f : 0.0f;
        ay = inf_y ? 1.0f : 0.0f;
    }
    const int swap = ay > ax;
    float n = swap ? ax : ay; /* n <= d */
    float d = swap ? ay : ax;
    /* exact rescaling: a subnormal d would round 0.4375 d and 2n - d below; 2d + n must
     * stay finite (n loses bits only where n / d rounds to 0 anyway) */
    const float f = d < 0x1p-100f ? 0x1p64f : d > 0x1p124f ? 0.25f : 1.0f;
    n *= f;
    d *= f;
    if (!(d > 0.0f)) {
        d = 1.0f; /* both zero: u = 0, and the quadrant below gives C's +-0 / +-pi */
    }
    /* atan(n / d) = hi + atan(u) + lo in [0, pi/4], reduced as fdlibm's atanf, with u
     * formed from n and d directly (2n - d and n - d are exact by Sterbenz), |u| <= 7/16 */
    float num = n, den = d, hi = 0.0f, lo = 0.0f;
    if (n >= 0.6875f * d) {
        num = n - d;
        den = n + d;
        hi = 7.8539818525e-01f; /* pi/4 */
        lo = -2.1855694143e-08f;
    } else if (n >= 0.4375f * d) {
        num = 2.0f * n - d;
        den = 2.0f * d + n;
        hi = 4.6364760399e-01f; /* atan(1/2) */
        lo = 5.0121586881e-09f;
    }
    const float u = num / den;
    /* atan(u) = u + u^3 A(u^2), A the degree-4 minimax fit of scripts/gen_libm_poly.py
     * (3.3e-9 relative to atan(u)); lo goes in before u */
    const float z = u * u;
    const float p = -3.333330452e-01f +
                    z * (1.999773830e-01f + z * (-1.422958225e-01f + z * (1.049080789e-01f + z * -5.819103122e-02f)));
    const float t = hi + (u + (lo + u * z * p));
    /* quadrant: t, pi - t, pi/2 - t or pi/2 + t, each c_hi + (+-t + c_lo): one rounding */
    const int neg_x = signbit(x) != 0;
    const float s = swap == neg_x ? t : -t;
    const float c_hi = swap ? 1.5707963705e+00f : neg_x ? 3.1415927410e+00f : 0.0f;
    const float c_lo = swap ? -4.3711388287e-08f : neg_x ? -8.7422776573e-08f : 0.0f;
    const float r = c_hi + (s + c_lo);
    return signbit(y) ? -r : r;
}

void mca_quat_mul(float r[4], const float p[4], const float q[4])
{
    r[0] = p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3];
    r[1] = p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2];
    r[2] = p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1];
    r[3] = p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0];
}

float mca_quat_normalize(float q[4])
{
    const float n = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(n > 1e-12f) || !isfinite(n)) {
        q[0] = 1.0f;
        q[1] = 0.0f;
        q[2] = 0.0f;
        q[3] = 0.0f;
        return n;
    }
    const float inv = 1.0f / n;
    for (int i = 0; i < 4; ++i) {
        q[i] *= inv;
    }
    return n;
}

void mca_quat_from_rotvec(float q[4], const float rv_rad[3])
{
    const float a2 = rv_rad[0] * rv_rad[0] + rv_rad[1] * rv_rad[1] + rv_rad[2] * rv_rad[2];
    const float a = sqrtf(a2);
    float k; /* sin(a/2)/a */
    if (a < 0.2f) {
        /* Taylor: sin(a/2)/a = 1/2 - a^2/48 + a^4/3840, cos(a/2) = 1 - a^2/8 + a^4/384; the first
         * terms left out, a^6/645120 and a^6/46080, stay below 1.4e-9 here (float32's ulp at 1 is
         * 1.2e-7), so every attitude correction and gyro step takes no sincos. */
        k = 0.5f - a2 * (1.0f / 48.0f) + a2 * a2 * (1.0f / 3840.0f);
        q[0] = 1.0f - a2 * (1.0f / 8.0f) + a2 * a2 * (1.0f / 384.0f);
    } else {
        float sh, ch;
        mca_sincosf(0.5f * a, &sh, &ch);
        k = sh / a;
        q[0] = ch;
    }
    q[1] = k * rv_rad[0];
    q[2] = k * rv_rad[1];
    q[3] = k * rv_rad[2];
}

void mca_quat_rotate(float v_n[3], const float q[4], const float v_b[3])
{
    /* v' = v + 2 w (u x v) + 2 u x (u x v), u = q.xyz */
    const float ux = q[1], uy = q[2], uz = q[3];
    const float tx = 2.0f * (uy * v_b[2] - uz * v_b[1]);
    const float ty = 2.0f * (uz * v_b[0] - ux * v_b[2]);
    const float tz = 2.0f * (ux * v_b[1] - uy * v_b[0]);
    const float rx = v_b[0] + q[0] * tx + (uy * tz - uz * ty);
    const float ry = v_b[1] + q[0] * ty + (uz * tx - ux * tz);
    const float rz = v_b[2] + q[0] * tz + (ux * ty - uy * tx);
    v_n[0] = rx;
    v_n[1] = ry;
    v_n[2] = rz;
}

void mca_quat_to_dcm(float c[9], const float q[4])
{
    const float w = q[0], x = q[1], y = q[2], z = q[3];
    c[0] = 1.0f - 2.0f * (y * y + z * z);
    c[1] = 2.0f * (x * y - w * z);
    c[2] = 2.0f * (x * z + w * y);
    c[3] = 2.0f * (x * y + w * z);
    c[4] = 1.0f - 2.0f * (x * x + z * z);
    c[5] = 2.0f * (y * z - w * x);
    c[6] = 2.0f * (x * z - w * y);
    c[7] = 2.0f * (y * z + w * x);
    c[8] = 1.0f - 2.0f * (x * x + y * y);
}

void mca_quat_to_euler_part(float e[3], const float q[4], unsigned axes)
{
    const float w = q[0], x = q[1], y = q[2], z = q[3];
    e[0] = e[1] = e[2] = 0.0f;
    if ((axes & 1u) != 0u) {
        e[0] = mca_atan2f(2.0f * (w * x + y * z), 1.0f - 2.0f * (x * x + y * y));
    }
    if ((axes & 2u) != 0u) {
        float s = 2.0f * (w * y - z * x);
        s = s > 1.0f ? 1.0f : (s < -1.0f ? -1.0f : s);
        e[1] = mca_atan2f(s, sqrtf(1.0f - s * s)); /* asin without another libm routine */
    }
    if ((axes & 4u) != 0u) {
        e[2] = mca_atan2f(2.0f * (w * z + x * y), 1.0f - 2.0f * (y * y + z * z));
    }
}

void mca_quat_to_euler(float e[3], const float q[4])
{
    mca_quat_to_euler_part(e, q, 7u);
}

void mca_quat_from_euler(float q[4], const float e[3])
{
    float cr, sr, cp, sp, cy, sy;
    mca_sincosf(0.5f * e[0], &sr, &cr);
    mca_sincosf(0.5f * e[1], &sp, &cp);
    mca_sincosf(0.5f * e[2], &sy, &cy);
    q[0] = cr * cp * cy + sr * sp * sy;
    q[1] = sr * cp * cy - cr * sp * sy;
    q[2] = cr * sp * cy + sr * cp * sy;
    q[3] = cr * cp * sy - sr * sp * cy;
}

float mca_wrap_pi(float a)
{
    if (!isfinite(a)) {
        return 0.0f;
    }
    /* w = fmodf(a + pi, 2 pi), then + 2 pi when negative, without libm's fmodf (364 B of
     * flash). For -4 pi < a + pi < 4 pi, every angle difference the filters wrap, the one
     * subtraction or addition of 2 pi is exact (Sterbenz), i.e. the bits of fmodf's exact
     * remainder. Farther out the multiple of 2 pi is taken off in float arithmetic (rounded,
     * so a few ulp of the input off fmodf), and the result is kept inside [-pi, pi). */
    const float two_pi = 2.0f * MCA_PI_F;
    float w = a + MCA_PI_F;
    if (w >= 2.0f * two_pi || w <= -2.0f * two_pi) {
        float k = w / two_pi;
        if (fabsf(k) < 8388608.0f) { /* 2^23: below it a float may have a fraction */
            k = (float)(int32_t)k;   /* toward zero, as fmodf */
        }
        w -= k * two_pi;
        if (!(fabsf(w) < two_pi)) {
            w = 0.0f; /* |a| beyond ~1e7 rad: nothing of the angle is left in a float */
        }
    } else if (w >= two_pi) {
        w -= two_pi;
    } else if (w <= -two_pi) {
        w += two_pi;
    }
    if (w < 0.0f) {
        w += two_pi;
    }
    if (w >= two_pi) {
        w = 0.0f; /* w + 2 pi rounded up from a tiny negative w */
    }
    return w - MCA_PI_F;
}

/*
 * Pinned float math for the diagnostic "pinned" replay builds (fw_pinned.elf, replay_pinned).
 *
 * Host (glibc) and target (newlib) libm round some results differently by an ulp; that is
 * the only source of difference allowed between the two builds of the core. To check that
 * nothing else differs (code generation, float operations, FPU modes, struct layout, 64-bit
 * conversions), these builds link the core's libm calls to the functions below instead
 * (-Wl,--wrap=expf,... : a call to expf lands in __wrap_expf). They use only IEEE-754
 * double +, -, *, / and sqrt (correctly rounded on both platforms, in hardware on the host,
 * in libgcc/newlib software on the M4F) and exact conversions, so both compute the same
 * bits; host and QEMU outputs must then be identical. Accuracy: ~1e-15 relative in double
 * before the final rounding to float, for the argument ranges a filter sees; huge arguments
 * of sin/cos/tan (|x| > 1e9) give deterministic but meaningless values. Not for flight.
 *
 * fmodf and sqrtf are not wrapped: both are exactly rounded by definition on both sides.
 */
#include <math.h>

/* One declaration each, to satisfy -Wmissing-prototypes. */
float __wrap_expf(float x);
float __wrap_expm1f(float x);
float __wrap_sinf(float x);
float __wrap_cosf(float x);
float __wrap_tanf(float x);
void __wrap_sincosf(float x, float *s, float *c);
float __wrap_asinf(float x);
float __wrap_atan2f(float y, float x);

#define LN2_HI 6.93147180369123816490e-01 /* high bits of ln 2: k * LN2_HI is exact */
#define LN2_LO 1.90821492927058770002e-10
#define INV_LN2 1.44269504088896338700e+00
#define PIO2_1 1.57079632673412561417e+00 /* pi/2 in three parts (fdlibm's split) */
#define PIO2_2 6.07710050650619224932e-11
#define PIO2_3 2.02226624879595063154e-21
#define TWO_OVER_PI 6.36619772367581382433e-01
#define PI_D 3.14159265358979311600e+00
#define PI_2_D 1.57079632679489655800e+00
#define PI_4_D 7.85398163397448278999e-01
#define ROUND_MAGIC 6755399441055744.0 /* 1.5 * 2^52: (v + M) - M rounds v to an integer */

/* v rounded to the nearest integer (ties to even), |v| < 2^51. */
static double round_int(double v)
{
    volatile double t = v + ROUND_MAGIC; /* volatile: keep the rounding step */
    return t - ROUND_MAGIC;
}

/* x * 2^k, exact while the result stays normal. */
static double scale2(double x, int k)
{
    double b = k < 0 ? 0.5 : 2.0;
    unsigned e = (unsigned)(k < 0 ? -k : k);
    while (e != 0u) {
        if ((e & 1u) != 0u) {
            x *= b;
        }
        b *= b;
        e >>= 1u;
    }
    return x;
}

/* e^x for |x| <= 110. */
static double exp_d(double x)
{
    const double k = round_int(x * INV_LN2);
    const double r = (x - k * LN2_HI) - k * LN2_LO; /* |r| <= 0.35 */
    double p = 1.0, term = 1.0;
    for (int n = 1; n <= 16; ++n) {
        term = term * r / (double)n;
        p += term;
    }
    return scale2(p, (int)k);
}

float __wrap_expf(float x)
{
    if (isnan(x)) {
        return x;
    }
    if (x > 89.0f) {
        return HUGE_VALF;
    }
    if (x < -110.0f) {
        return 0.0f;
    }
    return (float)exp_d((double)x);
}

float __wrap_expm1f(float x)
{
    if (isnan(x)) {
        return x;
    }
    if (x > 89.0f) {
        return HUGE_VALF;
    }
    if (x < -40.0f) {
        return -1.0f;
    }
    const double xd = (double)x;
    if (xd > -0.5 && xd < 0.5) {
        /* no cancellation: the series without its constant term */
        double s = 0.0, term = 1.0;
        for (int n = 1; n <= 20; ++n) {
            term = term * xd / (double)n;
            s += term;
        }
        return (float)s;
    }
    return (float)(exp_d(xd) - 1.0);
}

/* sin and cos of r, |r| <= pi/4 (Taylor to r^19, error < 1e-19). */
static void sincos_poly(double r, double *s, double *c)
{
    const double r2 = r * r;
    double ts = r, tc = 1.0, ss = r, cc = 1.0;
    for (int n = 1; n <= 9; ++n) {
        ts = -ts * r2 / (double)((2 * n) * (2 * n + 1));
        tc = -tc * r2 / (double)((2 * n - 1) * (2 * n));
        ss += ts;
        cc += tc;
    }
    *s = ss;
    *c = cc;
}

static void sincos_d(double x, double *s, double *c)
{
    if (!(x > -1e9 && x < 1e9)) {
        *s = x - x; /* NaN for inf/NaN, 0 for huge finite: deterministic */
        *c = *s + 1.0;
        return;
    }
    const double k = round_int(x * TWO_OVER_PI);
    const double r = ((x - k * PIO2_1) - k * PIO2_2) - k * PIO2_3;
    double sr, cr;
    sincos_poly(r, &sr, &cr);
    const long q = ((long)k) & 3L;
    if (q == 0) {
        *s = sr;
        *c = cr;
    } else if (q == 1) {
        *s = cr;
        *c = -sr;
    } else if (q == 2) {
        *s = -sr;
        *c = -cr;
    } else {
        *s = -cr;
        *c = sr;
    }
}

float __wrap_sinf(float x)
{
    double s, c;
    sincos_d((double)x, &s, &c);
    return (float)s;
}

float __wrap_cosf(float x)
{
    double s, c;
    sincos_d((double)x, &s, &c);
    return (float)c;
}

void __wrap_sincosf(float x, float *s, float *c)
{
    double sd, cd;
    sincos_d((double)x, &sd, &cd);
    *s = (float)sd;
    *c = (float)cd;
}

float __wrap_tanf(float x)
{
    double s, c;
    sincos_d((double)x, &s, &c);
    return (float)(s / c);
}

/* atan(y), y >= 0 finite. */
static double atan_pos(double y)
{
    double base = 0.0, sign = 1.0;
    if (y > 1.0) { /* atan(y) = pi/2 - atan(1/y) */
        base = PI_2_D;
        sign = -1.0;
        y = 1.0 / y;
    }
    if (y > 0.41421356237309503) { /* above tan(pi/8): atan(y) = pi/4 + atan((y-1)/(y+1)) */
        base += sign * PI_4_D;
        y = (y - 1.0) / (y + 1.0);
    }
    /* |y| <= tan(pi/8): series to y^61, error < 1e-24 */
    const double y2 = y * y;
    double term = y, sum = y;
    for (int n = 1; n <= 30; ++n) {
        term = -term * y2;
        sum += term / (double)(2 * n + 1);
    }
    return base + sign * sum;
}

static double atan2_d(double y, double x)
{
    const int y_neg = signbit(y) != 0, x_neg = signbit(x) != 0;
    const double ay = y_neg ? -y : y, ax = x_neg ? -x : x;
    double a;
    if (!(ay > 0.0)) { /* y is +-0 (NaN handled by the caller) */
        a = x_neg ? PI_D : 0.0;
    } else if (!(ax > 0.0)) {
        a = PI_2_D;
    } else if (isinf(ay) && isinf(ax)) {
        a = x_neg ? 3.0 * PI_4_D : PI_4_D;
    } else if (isinf(ay)) {
        a = PI_2_D;
    } else if (isinf(ax)) {
        a = x_neg ? PI_D : 0.0;
    } else {
        const double t = atan_pos(ay / ax);
        a = x_neg ? PI_D - t : t;
    }
    return y_neg ? -a : a;
}

float __wrap_atan2f(float y, float x)
{
    if (isnan(x) || isnan(y)) {
        return x + y;
    }
    return (float)atan2_d((double)y, (double)x);
}

float __wrap_asinf(float x)
{
    if (isnan(x) || x > 1.0f || x < -1.0f) {
        return (x - x) / (x - x); /* NaN */
    }
    const double xd = (double)x;
    return (float)atan2_d(xd, sqrt((1.0 - xd) * (1.0 + xd)));
}

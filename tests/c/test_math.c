/* Host tests of mca_math: Cholesky, quaternions, Euler round trips, the float copy, range checks. */
#include <string.h>

#include "mca_test.h"
#include "mcahrs/mca_math.h"

#include <stddef.h>
#include <stdint.h>

static void test_cholesky(void)
{
    const float a[9] = {4.0f, 2.0f, 0.4f, 2.0f, 5.0f, 1.0f, 0.4f, 1.0f, 3.0f};
    float l[9];
    CHECK_EQ_INT(mca_cholesky(l, a, 3), MCA_OK);
    /* l l^T reproduces a */
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            float s = 0.0f;
            for (int k = 0; k < 3; ++k) {
                s += l[i * 3 + k] * l[j * 3 + k];
            }
            CHECK_CLOSE(s, a[i * 3 + j], 1e-5);
        }
    }
    /* solve: a x = b with known x */
    const float x_true[3] = {1.0f, -2.0f, 0.5f};
    float b[3];
    for (int i = 0; i < 3; ++i) {
        b[i] = a[i * 3] * x_true[0] + a[i * 3 + 1] * x_true[1] + a[i * 3 + 2] * x_true[2];
    }
    mca_cholesky_solve(l, b, 3);
    for (int i = 0; i < 3; ++i) {
        CHECK_CLOSE(b[i], x_true[i], 1e-5);
    }
    const float bad[4] = {1.0f, 2.0f, 2.0f, 1.0f}; /* indefinite */
    CHECK_EQ_INT(mca_cholesky(l, bad, 2), MCA_ERR_SINGULAR);
    const float nan_m[1] = {NAN};
    CHECK_EQ_INT(mca_cholesky(l, nan_m, 1), MCA_ERR_SINGULAR);
}

static void test_quat(void)
{
    const float e[3] = {0.3f, -0.2f, 1.1f};
    float q[4], e2[3], c[9];
    mca_quat_from_euler(q, e);
    mca_quat_to_euler(e2, q);
    for (int i = 0; i < 3; ++i) {
        CHECK_CLOSE(e2[i], e[i], 1e-6);
    }
    /* C_nb third row = [-sin(theta), sin(phi)cos(theta), cos(phi)cos(theta)] */
    mca_quat_to_dcm(c, q);
    CHECK_CLOSE(c[6], -sinf(e[1]), 1e-6);
    CHECK_CLOSE(c[7], sinf(e[0]) * cosf(e[1]), 1e-6);
    CHECK_CLOSE(c[8], cosf(e[0]) * cosf(e[1]), 1e-6);
    /* rotation vector about z by yaw equals Euler (0, 0, yaw) */
    const float rv[3] = {0.0f, 0.0f, 0.7f}, ez[3] = {0.0f, 0.0f, 0.7f};
    float qa[4], qb[4];
    mca_quat_from_rotvec(qa, rv);
    mca_quat_from_euler(qb, ez);
    for (int i = 0; i < 4; ++i) {
        CHECK_CLOSE(qa[i], qb[i], 1e-6);
    }
    /* both branches (series below 0.2 rad, sincos above) against the exact quaternion, in double,
     * to float32 rounding, on both sides of the switch */
    const float angles[] = {1e-6f, 1e-3f, 0.01f, 0.05f, 0.1f, 0.1999f, 0.2f, 0.2001f, 0.5f, 2.0f};
    for (size_t k = 0; k < sizeof(angles) / sizeof(angles[0]); ++k) {
        const float rk[3] = {0.6f * angles[k], -0.8f * angles[k], 0.0f};
        mca_quat_from_rotvec(qa, rk);
        const double ha = 0.5 * (double)angles[k];
        CHECK_CLOSE(qa[0], cos(ha), 1.2e-7);
        CHECK_CLOSE(qa[1], 0.6 * sin(ha), 1.2e-7 * sin(ha) + 1e-12);
        CHECK_CLOSE(qa[2], -0.8 * sin(ha), 1.2e-7 * sin(ha) + 1e-12);
        CHECK_CLOSE(qa[3], 0.0, 0.0);
    }
    /* product: two half turns about z make a full turn (q = -1) */
    const float h[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    float r[4];
    mca_quat_mul(r, h, h);
    CHECK_CLOSE(r[0], -1.0f, 0.0);
    float z[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    mca_quat_normalize(z);
    CHECK_CLOSE(z[0], 1.0f, 0.0);
    CHECK_CLOSE(mca_wrap_pi(3.0f * 3.14159265f), -3.14159265f, 1e-5);
    CHECK_CLOSE(mca_wrap_pi(-0.5f), -0.5f, 1e-7);
}

/* mca_copyf moves four floats a step, then the rest: every length 0..13 copies exactly n
 * values (bit patterns, NaN included) and writes nothing past them. */
static void test_copyf(void)
{
    float src[16], dst[16];
    for (size_t i = 0; i < 16u; ++i) {
        src[i] = (float)i - 3.5f;
    }
    src[5] = NAN;
    for (size_t n = 0; n < 14u; ++n) {
        for (size_t i = 0; i < 16u; ++i) {
            dst[i] = 1000.0f;
        }
        mca_copyf(dst, src, n);
        CHECK(memcmp(dst, src, n * sizeof(float)) == 0);
        for (size_t i = n; i < 16u; ++i) {
            CHECK(dst[i] == 1000.0f);
        }
    }
}

/* mca_quat_to_euler_part: the selected angles, bit for bit those of mca_quat_to_euler, 0 for
 * the others, over attitudes that include the pitch clamp near +-90 deg. */
static void test_euler_part(void)
{
    const float eul[5][3] = {
        {0.3f, -0.2f, 2.5f}, {-2.9f, 1.2f, -0.4f}, {0.0f, 1.5707963f, 1.0f}, {1.0f, -1.5707963f, -3.1f}, {0.0f, 0.0f, 0.0f}};
    for (int k = 0; k < 5; ++k) {
        float q[4], full[3];
        mca_quat_from_euler(q, eul[k]);
        mca_quat_to_euler(full, q);
        for (unsigned axes = 0; axes < 8u; ++axes) {
            float part[3];
            mca_quat_to_euler_part(part, q, axes);
            for (unsigned i = 0; i < 3u; ++i) {
                const float want = ((axes >> i) & 1u) != 0u ? full[i] : 0.0f;
                CHECK(memcmp(&part[i], &want, sizeof(float)) == 0);
            }
        }
    }
}

/* mca_positive / mca_nonneg on the bits against the compares they replace (finite and > 0 /
 * >= 0), over the edge values; mca_fields_ok reads the offsets it is given, with the nonneg
 * mask bit by bit. */
typedef struct {
    uint8_t pad;
    float a, b, c;
} range_fields_t;

static void test_range_checks(void)
{
    const float inf = INFINITY, nan = NAN;
    const float v[] = {0.0f, -0.0f, 1e-45f, -1e-45f, 1.17549435e-38f, 1.0f, -1.0f, 3.40282347e38f,
                       -3.40282347e38f, inf, -inf, nan, -nan};
    for (size_t i = 0; i < sizeof v / sizeof v[0]; ++i) {
        CHECK_EQ_INT(mca_positive(v[i]), isfinite(v[i]) && v[i] > 0.0f);
        CHECK_EQ_INT(mca_nonneg(v[i]), isfinite(v[i]) && v[i] >= 0.0f);
    }
    const range_fields_t ok = {0u, 1.0f, 0.0f, 2.0f};
    range_fields_t r = ok;
    const uint16_t off[] = {(uint16_t)offsetof(range_fields_t, a), (uint16_t)offsetof(range_fields_t, b),
                            (uint16_t)offsetof(range_fields_t, c)};
    CHECK(!mca_fields_ok(&r, off, 3u, 0x0u)); /* b = 0 is not > 0 */
    CHECK(!mca_fields_ok(&r, off, 3u, 0x5u)); /* a, c may be 0, b still not */
    CHECK(mca_fields_ok(&r, off, 3u, 0x2u));
    CHECK(mca_fields_ok(&r, off, 3u, 0x7u));
    r.c = NAN;
    CHECK(!mca_fields_ok(&r, off, 3u, 0x7u));
    CHECK(mca_fields_ok(&r, off, 2u, 0x2u)); /* c is not read */
    r = ok;
    r.c = -0.0f; /* >= 0, not > 0 */
    CHECK(mca_fields_ok(&r, off, 3u, 0x6u));
    CHECK(!mca_fields_ok(&r, off, 3u, 0x2u));
}

int main(void)
{
    test_range_checks();
    test_cholesky();
    test_quat();
    test_copyf();
    test_euler_part();
    TEST_MAIN_END();
}

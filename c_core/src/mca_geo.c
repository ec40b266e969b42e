/* Geodetic to NED and normal gravity (docs/ALGORITHMS.md 6). See mca_geo.h. */
#include "mcahrs/mca_geo.h"
#include "mca_geo_nocheck.h"
#include "mca_cold.h"

#include <math.h>

#include "mca_geo_table.inc"

#define WGS84_A 6378137.0f
#define WGS84_E2 6.69437999014e-3f
#define E7_TO_RAD 1.74532925199433e-9f /* 1e-7 deg in rad */

mca_status_t mca_geo_check(int32_t lat_e7, int32_t lon_e7, int32_t alt_mm)
{
    if (lat_e7 < -900000000 || lat_e7 > 900000000 || lon_e7 < -1800000000 || lon_e7 > 1800000000 ||
        alt_mm < -1000000 || alt_mm > 100000000) {
        return MCA_ERR_RANGE;
    }
    return MCA_OK;
}

/* Latitude in rad from 1e-7 deg: split so the float product keeps its precision. */
static float lat_rad(int32_t e7)
{
    const int32_t whole = e7 / 10000000; /* whole degrees */
    const int32_t frac = e7 - whole * 10000000;
    return (float)whole * 0.0174532925199433f + (float)frac * E7_TO_RAD;
}

/* sin and cos of a latitude (|lat| <= 90e7) to ~1e-8 rad: multiples of 10 degrees from the
 * table, the remainder (< 10 deg) by sincosf, which is accurate for a small argument. */
static void lat_sincos(int32_t e7, float *s, float *c)
{
    const int32_t a = e7 < 0 ? -e7 : e7;
    const int32_t k = a / 100000000;
    const float f = (float)(a - k * 100000000) * E7_TO_RAD;
    float sf, cf;
    mca_sincosf(f, &sf, &cf);
    const float sk = mca_sin_10deg[k], ck = mca_sin_10deg[9 - k];
    const float sv = sk * cf + ck * sf;
    *c = ck * cf - sk * sf;
    *s = e7 < 0 ? -sv : sv;
}

MCA_COLD mca_status_t mca_geo_set_home(mca_geo_home_t *home, int32_t lat_e7, int32_t lon_e7, int32_t alt_mm)
{
    if (home == NULL) {
        return MCA_ERR_NULL;
    }
    const mca_status_t st = mca_geo_check(lat_e7, lon_e7, alt_mm);
    if (st != MCA_OK) {
        return st;
    }
    mca_geo_set_home_nocheck(home, lat_e7, lon_e7, alt_mm);
    return MCA_OK;
}

MCA_COLD void mca_geo_set_home_nocheck(mca_geo_home_t *home, int32_t lat_e7, int32_t lon_e7, int32_t alt_mm)
{
    home->lat_e7 = lat_e7;
    home->lon_e7 = lon_e7;
    home->alt_mm = alt_mm;
    lat_sincos(lat_e7, &home->sin_lat, &home->cos_lat);
    home->root = sqrtf(1.0f - WGS84_E2 * home->sin_lat * home->sin_lat);
    home->n_m = WGS84_A / home->root;
}

mca_status_t mca_geo_to_ned(const mca_geo_home_t *home, int32_t lat_e7, int32_t lon_e7, int32_t alt_mm,
                            float ned_m[3])
{
    if (home == NULL || ned_m == NULL) {
        return MCA_ERR_NULL;
    }
    const mca_status_t st = mca_geo_check(lat_e7, lon_e7, alt_mm);
    if (st != MCA_OK) {
        return st;
    }
    mca_geo_to_ned_nocheck(home, lat_e7, lon_e7, alt_mm, ned_m);
    return MCA_OK;
}

void mca_geo_to_ned_nocheck(const mca_geo_home_t *home, int32_t lat_e7, int32_t lon_e7, int32_t alt_mm,
                            float ned_m[3])
{
    /* integer differences; longitude wrapped across the antimeridian */
    const int64_t dlat_e7 = (int64_t)lat_e7 - (int64_t)home->lat_e7;
    int64_t dlon_e7 = (int64_t)lon_e7 - (int64_t)home->lon_e7;
    if (dlon_e7 > 1800000000) {
        dlon_e7 -= 3600000000LL;
    } else if (dlon_e7 < -1800000000) {
        dlon_e7 += 3600000000LL;
    }
    /* all three fit in int32 (|dlat| <= 1.8e9, |dlon| <= 1.8e9 after the wrap, |dalt| < 1.1e8):
     * int32 -> float is one instruction on the M4F, int64 -> float a library call */
    const float dphi = (float)(int32_t)dlat_e7 * E7_TO_RAD;
    const float dlam = (float)(int32_t)dlon_e7 * E7_TO_RAD;
    const float dh = (float)(alt_mm - home->alt_mm) * 1e-3f;
    const float h0 = (float)home->alt_mm * 1e-3f;
    const float s0 = home->sin_lat, c0 = home->cos_lat;
    float s1, c1;
    lat_sincos(lat_e7, &s1, &c1);
    /* s1 - s0 = 2 cos(mean) sin(dphi/2), without cancellation */
    const float phim = lat_rad(home->lat_e7) + 0.5f * dphi;
    const float ds = 2.0f * mca_cosf(phim) * mca_sinf(0.5f * dphi);
    const float root1 = sqrtf(1.0f - WGS84_E2 * s1 * s1);
    const float n0 = home->n_m, n1 = WGS84_A / root1;
    const float dn = n0 * n1 * WGS84_E2 * ds * (s1 + s0) / (WGS84_A * (root1 + home->root));
    const float nh1 = n1 + h0 + dh;
    const float sdl2 = mca_sinf(0.5f * dlam), sdp2 = mca_sinf(0.5f * dphi);
    const float ecc = WGS84_E2 * (n1 * ds + dn * s0); /* e2 (N1 s1 - N0 s0) */
    ned_m[1] = nh1 * c1 * mca_sinf(dlam);
    ned_m[0] = nh1 * (mca_sinf(dphi) + 2.0f * s0 * c1 * sdl2 * sdl2) - c0 * ecc;
    const float up = dn + dh - nh1 * (2.0f * sdp2 * sdp2 + 2.0f * c0 * c1 * sdl2 * sdl2) - s0 * ecc;
    ned_m[2] = -up;
}

float mca_geo_gravity(float lat, float h)
{
    const float sl = mca_sinf(lat);
    const float s2 = sl * sl;
    return 9.7803253359f * (1.0f + 0.00193185265241f * s2) / sqrtf(1.0f - WGS84_E2 * s2) - 3.086e-6f * h;
}

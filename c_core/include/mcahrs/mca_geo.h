/**
 * @file mca_geo.h
 * @brief Integer geodetic position to local NED float32 metres, and normal gravity
 *        (DESIGN.md 2, docs/ALGORITHMS.md 6).
 *
 * Lat/lon are int32 in 1e-7 deg, altitude int32 in mm. Differences to home are taken in
 * integers, then every term of the exact ECEF-difference-in-NED formula is of the size of
 * the displacement, so float32 keeps the result to a few ulp (about 2 mm at 20 km).
 */
#ifndef MCA_GEO_H
#define MCA_GEO_H

#include "mca_math.h"

/** Home point with its trigonometry cached. */
typedef struct {
    int32_t lat_e7;
    int32_t lon_e7;
    int32_t alt_mm;
    float sin_lat;
    float cos_lat;
    float n_m;     /**< prime vertical radius N(lat) */
    float root;    /**< sqrt(1 - e2 sin^2 lat) */
} mca_geo_home_t;

/** @return MCA_ERR_RANGE when lat/lon/alt out of range (ALGORITHMS.md 6), else MCA_OK. */
mca_status_t mca_geo_check(int32_t lat_e7, int32_t lon_e7, int32_t alt_mm);

/** Set home. @return MCA_ERR_RANGE or MCA_OK (home untouched on error). */
mca_status_t mca_geo_set_home(mca_geo_home_t *home, int32_t lat_e7, int32_t lon_e7, int32_t alt_mm);

/** NED of a point relative to home. @return MCA_ERR_RANGE or MCA_OK (ned untouched on error). */
mca_status_t mca_geo_to_ned(const mca_geo_home_t *home, int32_t lat_e7, int32_t lon_e7, int32_t alt_mm,
                            float ned_m[3]);

/** WGS84 normal gravity (Somigliana + free-air) at latitude lat_rad and height h_m. */
float mca_geo_gravity(float lat_rad, float h_m);

#endif /* MCA_GEO_H */

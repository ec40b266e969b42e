/* Private to the core sources: the geodetic conversions without their argument checks, for the
 * navigation filter (mca_nav.c), which range-checks a fix where it enters (mca_gps_fix_read).
 * For valid arguments each gives the public function's result; the public function is the
 * check, then this. */
#ifndef MCA_GEO_NOCHECK_H
#define MCA_GEO_NOCHECK_H

#include "mcahrs/mca_geo.h"

/* mca_geo_set_home with home non-NULL and a position mca_geo_check accepts */
void mca_geo_set_home_nocheck(mca_geo_home_t *home, int32_t lat_e7, int32_t lon_e7, int32_t alt_mm);

/* mca_geo_to_ned with home set, ned_m non-NULL and a position mca_geo_check accepts */
void mca_geo_to_ned_nocheck(const mca_geo_home_t *home, int32_t lat_e7, int32_t lon_e7, int32_t alt_mm,
                            float ned_m[3]);

#endif /* MCA_GEO_NOCHECK_H */

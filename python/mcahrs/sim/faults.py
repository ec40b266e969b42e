"""GNSS faults at fixed times, added to a recording's fixes: the golden-vs-C cases
(``tests/python/test_nav_golden_vs_c.py``) and the firmware vectors of the same faults
(``scripts/gen_vectors.py``) take their faults from here. ``benchmarks/bench_outliers.py``
draws its own per fix.
"""

from __future__ import annotations

import math

import numpy as np

from mcahrs.samples import Recording

# A fault: (t0_s, t1_s, position offset m, velocity offset m/s, azimuth deg[, down position m,
# down velocity m/s]), added to the fixes valid in [t0, t1).
Fault = tuple[float, ...]


def with_gnss_faults(rec: Recording, faults: tuple[Fault, ...]) -> Recording:
    """A copy with position and velocity offsets added to the fixes valid in each fault window (the
    position moved on a sphere: both sides of a comparison read the same integers, so exactness does
    not matter), speed and course recomputed."""
    gn = rec.gnss.copy()
    t = gn["t_us"].astype(np.int64) * 1e-6
    for t0, t1, p_m, v_mps, az_deg, *down in faults:
        sel = (t >= t0) & (t < t1)
        if down:  # (position, velocity) offsets along NED down
            gn["alt_mm"][sel] -= np.round(down[0] * 1e3).astype(gn["alt_mm"].dtype)
            gn["vel_ned_mps"][sel, 2] += down[1]
        u = np.array([math.cos(math.radians(az_deg)), math.sin(math.radians(az_deg))])
        lat = gn["lat_e7"][sel] * 1e-7
        dlat = np.degrees(p_m * u[0] / 6378137.0)
        dlon = np.degrees(p_m * u[1] / (6378137.0 * np.cos(np.radians(lat))))
        gn["lat_e7"][sel] = np.round((lat + dlat) * 1e7).astype(gn["lat_e7"].dtype)
        gn["lon_e7"][sel] = np.round((gn["lon_e7"][sel] * 1e-7 + dlon) * 1e7).astype(gn["lon_e7"].dtype)
        gn["vel_ned_mps"][sel, 0] += v_mps * u[0]
        gn["vel_ned_mps"][sel, 1] += v_mps * u[1]
    v = gn["vel_ned_mps"]
    gn["speed_mps"] = np.hypot(v[:, 0], v[:, 1])
    gn["course_rad"] = np.mod(np.arctan2(v[:, 1], v[:, 0]), 2.0 * np.pi)
    return Recording(rec.name + "+gnss_faults", rec.imu, gn, rec.mag, rec.ref, rec.meta)

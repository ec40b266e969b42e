"""Geodetic position to local NED, and normal gravity: float64 golden model of ALGORITHMS.md 6.

Positions come in as integers (DESIGN.md 2): latitude/longitude in 1e-7 deg, height in mm.
:func:`ned_from_home` is the reference: the exact NED vector of the ECEF difference rotated
into the NED frame of home, computed by ``pymap3d.geodetic2ned`` (WGS84) in float64, where
the ECEF difference of two ~6.4e6 m vectors is still good to ~1e-9 m.

:func:`ned_from_home_closed_form` is the cancellation-free closed form the spec gives for
float32 (every term of the size of the displacement). It is here so that the formula itself
is checked against pymap3d (tests/python/test_golden_nav.py); the navigation golden model
uses :func:`ned_from_home`.
"""

from __future__ import annotations

import math
import operator

import numpy as np
import pymap3d

from mcahrs.errors import BadArgError, RangeError

__all__ = [
    "ALT_MAX_MM",
    "ALT_MIN_MM",
    "LAT_MAX_E7",
    "LON_MAX_E7",
    "WGS84_A",
    "WGS84_E2",
    "WGS84_F",
    "check_geodetic",
    "ned_from_home",
    "ned_from_home_closed_form",
    "normal_gravity",
    "normal_gravity_e7",
]

WGS84_A = 6378137.0  # semi-major axis, m
WGS84_F = 1.0 / 298.257223563  # flattening
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared

LAT_MAX_E7 = 900_000_000  # |lat| <= 90 deg
LON_MAX_E7 = 1_800_000_000  # |lon| <= 180 deg
ALT_MIN_MM = -1_000_000  # -1 km
ALT_MAX_MM = 100_000_000  # 100 km

_E7_TO_RAD = 1e-7 * math.pi / 180.0


def _as_int(name: str, v: object) -> int:
    try:
        return operator.index(v)  # type: ignore[arg-type]
    except TypeError as exc:
        raise BadArgError(f"{name} must be an integer, got {v!r}") from exc


def check_geodetic(lat_e7: int, lon_e7: int, alt_mm: int | None = 0) -> tuple[int, int, int | None]:
    """Range check of ALGORITHMS.md 6; returns the values as Python ints.

    ``alt_mm=None`` skips the altitude check (a fix without altitude). Raises RangeError.
    """
    lat, lon = _as_int("lat_e7", lat_e7), _as_int("lon_e7", lon_e7)
    alt = None if alt_mm is None else _as_int("alt_mm", alt_mm)
    if abs(lat) > LAT_MAX_E7:
        raise RangeError(f"latitude {lat} e-7 deg out of range")
    if abs(lon) > LON_MAX_E7:
        raise RangeError(f"longitude {lon} e-7 deg out of range")
    if alt is not None and not (ALT_MIN_MM <= alt <= ALT_MAX_MM):
        raise RangeError(f"altitude {alt} mm out of range")
    return lat, lon, alt


def ned_from_home(
    lat_e7: int, lon_e7: int, alt_mm: int, home_lat_e7: int, home_lon_e7: int, home_alt_mm: int
) -> np.ndarray:
    """NED offset (m, shape (3,)) of a fix from home, WGS84, via ``pymap3d.geodetic2ned``.

    Raises RangeError when either point is out of range (ALGORITHMS.md 6).
    """
    lat, lon, alt = check_geodetic(lat_e7, lon_e7, alt_mm)
    lat0, lon0, alt0 = check_geodetic(home_lat_e7, home_lon_e7, home_alt_mm)
    n, e, d = pymap3d.geodetic2ned(
        lat * 1e-7, lon * 1e-7, alt * 1e-3, lat0 * 1e-7, lon0 * 1e-7, alt0 * 1e-3, deg=True
    )
    return np.array([float(n), float(e), float(d)])


def ned_from_home_closed_form(
    lat_e7: int, lon_e7: int, alt_mm: int, home_lat_e7: int, home_lon_e7: int, home_alt_mm: int
) -> np.ndarray:
    """The closed form of ALGORITHMS.md 6 (differences from integer differences), float64.

    Same result as :func:`ned_from_home` to rounding; kept to check the spec's formula.
    """
    lat, lon, alt = check_geodetic(lat_e7, lon_e7, alt_mm)
    lat0, lon0, alt0 = check_geodetic(home_lat_e7, home_lon_e7, home_alt_mm)
    a, e2 = WGS84_A, WGS84_E2
    phi0, phi1 = lat0 * _E7_TO_RAD, lat * _E7_TO_RAD
    dphi = (lat - lat0) * _E7_TO_RAD
    dlam = (lon - lon0) * _E7_TO_RAD
    h1 = alt * 1e-3
    dh = (alt - alt0) * 1e-3
    s0, c0, s1, c1 = math.sin(phi0), math.cos(phi0), math.sin(phi1), math.cos(phi1)
    w0, w1 = math.sqrt(1.0 - e2 * s0 * s0), math.sqrt(1.0 - e2 * s1 * s1)
    n0, n1 = a / w0, a / w1
    ds = 2.0 * math.cos(0.5 * (phi0 + phi1)) * math.sin(0.5 * dphi)  # s phi1 - s phi0
    dn = n0 * n1 * e2 * ds * (s1 + s0) / (a * (w1 + w0))  # N1 - N0 without cancellation
    sdl2 = math.sin(0.5 * dlam) ** 2
    sdp2 = math.sin(0.5 * dphi) ** 2
    common = n1 * ds + dn * s0
    east = (n1 + h1) * c1 * math.sin(dlam)
    north = (n1 + h1) * (math.sin(dphi) + 2.0 * s0 * c1 * sdl2) - e2 * c0 * common
    up = dn + dh - (n1 + h1) * (2.0 * sdp2 + 2.0 * c0 * c1 * sdl2) - e2 * s0 * common
    return np.array([north, east, -up])


def normal_gravity(lat_rad: float, h_m: float) -> float:
    """WGS84 Somigliana normal gravity with the free-air term (ALGORITHMS.md 6), m/s^2."""
    s2 = math.sin(lat_rad) ** 2
    return 9.7803253359 * (1.0 + 0.00193185265241 * s2) / math.sqrt(1.0 - WGS84_E2 * s2) - 3.086e-6 * h_m


def normal_gravity_e7(lat_e7: int, alt_mm: int) -> float:
    """:func:`normal_gravity` of an integer position (1e-7 deg, mm)."""
    lat, _, alt = check_geodetic(lat_e7, 0, alt_mm)
    assert alt is not None
    return normal_gravity(lat * _E7_TO_RAD, alt * 1e-3)

"""Typed samples: the one vocabulary between readers, loaders, the simulator and the core.

Two forms of the same thing:

* small frozen dataclasses (:class:`ImuSample`, :class:`GnssFix`, :class:`MagSample`) that
  stream readers yield one at a time;
* NumPy structured arrays (``IMU_DTYPE``, ``GNSS_DTYPE``, ``MAG_DTYPE``, ``REF_DTYPE``) that
  loaders, the simulator and the batch replay use, collected in a :class:`Recording`.

Conventions (DESIGN.md section 2): body frame FRD, navigation frame NED, SI units,
time as integer microseconds on the **IMU clock**. Geodetic position is integer
(1e-7 deg, mm). A quantity the source does not give is NaN (floats) or the flag bit is
clear, never a made-up value.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

IMU_DTYPE = np.dtype(
    [
        ("t_us", np.int64),  # sample time, IMU clock
        ("gyro_rps", np.float64, (3,)),  # body FRD angular rate
        ("accel_mps2", np.float64, (3,)),  # body FRD specific force (level at rest: [0, 0, -g])
    ]
)

MAG_DTYPE = np.dtype(
    [
        ("t_us", np.int64),
        ("mag_b", np.float64, (3,)),  # body FRD magnetic field, any consistent unit (gauss, uT)
    ]
)

# Flag bits of GnssFix.flags / GNSS_DTYPE["flags"].
GNSS_HAS_VEL_NE = 0x01  # north/east velocity present
GNSS_HAS_VEL_D = 0x02  # down velocity present
GNSS_HAS_ALT = 0x04  # altitude present
GNSS_HAS_COURSE = 0x08  # speed over ground + course over ground present

GNSS_DTYPE = np.dtype(
    [
        ("t_us", np.int64),  # validity (epoch) time of the fix, IMU clock
        ("t_rx_us", np.int64),  # when it reached the host, IMU clock (>= t_us); replay order
        ("lat_e7", np.int32),  # latitude, 1e-7 deg
        ("lon_e7", np.int32),  # longitude, 1e-7 deg
        ("alt_mm", np.int32),  # height (ellipsoidal if known, else MSL), mm
        ("vel_ned_mps", np.float64, (3,)),  # NaN where not given
        ("speed_mps", np.float64),  # speed over ground, NaN if not given
        ("course_rad", np.float64),  # course over ground, [0, 2 pi), NaN if not given
        ("h_acc_m", np.float64),  # 1-sigma horizontal position accuracy, NaN if unknown
        ("v_acc_m", np.float64),  # 1-sigma vertical position accuracy, NaN if unknown
        ("s_acc_mps", np.float64),  # 1-sigma speed accuracy, NaN if unknown
        ("fix_type", np.uint8),  # 0 none, 1 dead reckoning, 2 2D, 3 3D, 4 DGPS, 5 RTK float, 6 RTK fixed
        ("num_sv", np.uint8),
        ("flags", np.uint8),  # GNSS_HAS_* bits
    ]
)

REF_DTYPE = np.dtype(
    [
        ("t_us", np.int64),
        ("q_nb", np.float64, (4,)),  # reference attitude, Hamilton [w, x, y, z], body FRD -> NED
    ]
)


@dataclass(frozen=True, slots=True)
class ImuSample:
    t_us: int
    gyro_rps: tuple[float, float, float]
    accel_mps2: tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class MagSample:
    t_us: int
    mag_b: tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class GnssFix:
    t_us: int
    t_rx_us: int
    lat_e7: int
    lon_e7: int
    alt_mm: int
    vel_ned_mps: tuple[float, float, float] = (float("nan"),) * 3
    speed_mps: float = float("nan")
    course_rad: float = float("nan")
    h_acc_m: float = float("nan")
    v_acc_m: float = float("nan")
    s_acc_mps: float = float("nan")
    fix_type: int = 3
    num_sv: int = 0
    flags: int = GNSS_HAS_ALT


Sample = ImuSample | MagSample | GnssFix


@dataclass
class Recording:
    """A whole recording as arrays, sorted by time. ``ref`` is None when there is no reference."""

    name: str
    imu: np.ndarray  # IMU_DTYPE
    gnss: np.ndarray  # GNSS_DTYPE
    mag: np.ndarray = field(default_factory=lambda: np.zeros(0, MAG_DTYPE))
    ref: np.ndarray | None = None  # REF_DTYPE
    meta: dict = field(default_factory=dict)


def imu_array(samples: Iterable[ImuSample]) -> np.ndarray:
    """Collect IMU samples into an ``IMU_DTYPE`` array."""
    s = list(samples)
    out = np.zeros(len(s), IMU_DTYPE)
    if s:
        out["t_us"] = [x.t_us for x in s]
        out["gyro_rps"] = [x.gyro_rps for x in s]
        out["accel_mps2"] = [x.accel_mps2 for x in s]
    return out


def mag_array(samples: Iterable[MagSample]) -> np.ndarray:
    """Collect magnetometer samples into a ``MAG_DTYPE`` array."""
    s = list(samples)
    out = np.zeros(len(s), MAG_DTYPE)
    if s:
        out["t_us"] = [x.t_us for x in s]
        out["mag_b"] = [x.mag_b for x in s]
    return out


def gnss_array(fixes: Iterable[GnssFix]) -> np.ndarray:
    """Collect fixes into a ``GNSS_DTYPE`` array."""
    s = list(fixes)
    out = np.zeros(len(s), GNSS_DTYPE)
    for i, f in enumerate(s):
        out[i] = (
            f.t_us,
            f.t_rx_us,
            f.lat_e7,
            f.lon_e7,
            f.alt_mm,
            f.vel_ned_mps,
            f.speed_mps,
            f.course_rad,
            f.h_acc_m,
            f.v_acc_m,
            f.s_acc_mps,
            f.fix_type,
            f.num_sv,
            f.flags,
        )
    return out


def recording_from_samples(name: str, samples: Iterable[Sample]) -> Recording:
    """Split a mixed stream of typed samples into a :class:`Recording`."""
    imu: list[ImuSample] = []
    mag: list[MagSample] = []
    gnss: list[GnssFix] = []
    for s in samples:
        if isinstance(s, ImuSample):
            imu.append(s)
        elif isinstance(s, GnssFix):
            gnss.append(s)
        elif isinstance(s, MagSample):
            mag.append(s)
    return Recording(name, imu_array(imu), gnss_array(gnss), mag_array(mag))

"""MCAHRS serial wire format, and the encoder that writes it.

Wire format
===========

One ASCII sentence per line, NMEA 0183 framing::

    $<address>,<field>,<field>,...*<hh><CR><LF>

``hh`` is the XOR of every byte between ``$`` and ``*``, as two hex digits (written upper
case; the reader accepts either case). A line whose checksum is missing or wrong is
rejected and counted, never used. An empty field means "not given". The reader accepts
lines up to 512 bytes (NMEA's own limit is 82 characters including CR LF; MCAHRS's
proprietary sentences may exceed it, standard ones written here do not).

Numbers are decimal ASCII with ``.`` as separator, an optional sign and an optional
exponent (``-9.80665``, ``1.5e-05``). ``nan``/``inf`` are rejected (reason ``nonfinite``).
``t_us`` is an unsigned decimal integer.

Sensor sentences (proprietary, manufacturer code ``MCA``)
---------------------------------------------------------

IMU sample, all seven fields required::

    $PMCAI,<t_us>,<gx>,<gy>,<gz>,<ax>,<ay>,<az>*hh

* ``t_us``: the sensor's own sample time, integer microseconds. This **IMU clock** is the
  time base of every sample a reader yields.
* ``gx gy gz``: angular rate, rad/s, body FRD.
* ``ax ay az``: specific force, m/s^2, body FRD (a level vehicle at rest reads 0, 0, -g).

Magnetometer sample, all four fields required::

    $PMCAM,<t_us>,<mx>,<my>,<mz>*hh

* ``t_us`` on the IMU clock; ``mx my mz`` body FRD, any consistent unit (gauss or uT).

GNSS extension, optional, one per epoch::

    $PMCAV,<hhmmss.sss>,<t_us>,<vn>,<ve>,<vd>,<s_acc>*hh

* ``hhmmss.sss``: UTC time of the epoch; it must equal the time field of the epoch's
  GGA/RMC, which is how the reader groups it with them.
* ``t_us``: validity time of the fix on the IMU clock, when the sender knows it (e.g. from
  PPS); if given it replaces the reader's arrival-based estimate (see ``timebase.py``).
* ``vn ve vd``: velocity NED, m/s (NMEA itself has no vertical velocity).
* ``s_acc``: 1-sigma speed accuracy, m/s. Every field but the time may be empty.

Standard GNSS sentences
-----------------------

The reader takes GGA, RMC, VTG, GSA, GST and GNS from any talker (GP, GN, GL, GA, GB, BD,
QZ, ...) and counts all other sentences as ignored. The encoder writes, per fix, with
talker ``GN``::

    $GNGGA,<hhmmss.sss>,<ddmm.mmmmmm>,<N|S>,<dddmm.mmmmmm>,<E|W>,<q>,<nn>,,<alt>,M,<sep>,M,,*hh
    $GNRMC,<hhmmss.sss>,A,<ddmm.mmmmmm>,<N|S>,<dddmm.mmmmmm>,<E|W>,<sog_kn>,<cog_deg>,<ddmmyy>,,,<mode>*hh
    $GNGSA,A,<2|3>,,,,,,,,,,,,,,,*hh
    $GNGST,<hhmmss.sss>,,,,,<std_lat>,<std_lon>,<std_alt>*hh      (only if an accuracy is known)
    $PMCAV,...                                                     (optional, see above)

* Latitude/longitude: degrees and **6 decimal minutes**; 1e-7 deg is exactly 6e-6 min, so
  ``lat_e7``/``lon_e7`` survive the round trip exactly.
* ``alt``: metres with 3 decimals (exact mm). The encoder writes the fix's height with
  ``sep`` = ``0.000`` (so MSL + sep = the ellipsoidal height the fix holds); when the fix is
  flagged :data:`GNSS_ALT_MSL` it leaves ``sep`` empty. The reader's height is MSL + sep
  (ellipsoidal) when sep is given, MSL otherwise (then it sets :data:`GNSS_ALT_MSL`).
* ``q``/``mode``/GSA navigation mode carry ``fix_type``: 1 DR = q 6/E, 2 2D = q 1 with GSA
  2, 3 3D = q 1/A, 4 DGPS = q 2/D, 5 RTK float = q 5/F, 6 RTK fixed = q 4/R.
* ``sog_kn``, ``cog_deg`` with 4 decimals (half-LSB: 2.6e-5 m/s, 8.7e-7 rad), so that RMC
  stays within 82 characters up to 999 kn; ``PMCAV`` carries the velocity more finely.
* GST ``std_lat = std_lon = h_acc_m`` and ``std_alt = v_acc_m`` (4 decimals). The reader's
  ``h_acc_m`` is the per-axis 1-sigma ``sqrt((std_lat^2 + std_lon^2)/2)`` (as PX4 uses
  u-blox hAcc per horizontal axis; the 2-D DRMS is sqrt(2) times it).
* ``PMCAV`` velocities and ``s_acc`` with 6 decimals.

Round-trip precision (:func:`encode_recording` then ``read_bytes``): IMU and magnetometer
values bit-exact (``repr`` of the float64, unless ``float_digits`` is given), ``t_us``
exact; ``lat_e7``/``lon_e7``/``alt_mm``/``fix_type``/``num_sv`` exact; ``flags`` exact
when the ``GNSS_HAS_*`` bits mark exactly the values given (without ``PMCAV`` there is no
``GNSS_HAS_VEL_D``); ``vel_ned_mps``/``s_acc_mps`` to 5e-7 m/s (from ``PMCAV``; from RMC
speed and course otherwise); ``speed_mps`` to 2.6e-5 m/s; ``course_rad`` to 8.7e-7 rad;
``h_acc_m``/``v_acc_m`` to 5e-5 m. A fix's ``t_us`` is exact with ``PMCAV`` (otherwise the
reader makes it ``t_rx_us - latency_us``); its ``t_rx_us`` is exact when it equals the time
of an IMU sample (the reader takes the last IMU sample before the fix's sentences; on the
UTC clock, without IMU, ``t_us`` comes from the UTC field, 3 decimals by default). Fixes
with ``fix_type == 0`` are not written (a reader drops epochs without a fix).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from datetime import date, timedelta
from typing import Protocol

import numpy as np

from ..samples import (
    GNSS_HAS_ALT,
    GNSS_HAS_COURSE,
    GNSS_HAS_VEL_D,
    GNSS_HAS_VEL_NE,
    GnssFix,
    ImuSample,
    MagSample,
    Recording,
)
from .framing import xor_checksum

# Extra GnssFix.flags bit: the height is above mean sea level (no geoid separation was
# given), not above the WGS84 ellipsoid. Not in samples.py's GNSS_HAS_* set yet.
GNSS_ALT_MSL = 0x10

DAY_US = 86_400_000_000
KNOT_MPS = 1852.0 / 3600.0  # exact definition of the knot

# pynmeagps payload definitions (NMEAReader.parse(..., userdefined=USERDEFINED)).
# Talker "P" + msgID, so the keys are the address without the leading "P".
_IN, _DE, _TM = "IN", "DE", "TM"  # pynmeagps attribute types (nmeatypes_core)
USERDEFINED: dict[str, dict[str, str]] = {
    "MCAI": {"t_us": _IN, "gx": _DE, "gy": _DE, "gz": _DE, "ax": _DE, "ay": _DE, "az": _DE},
    "MCAM": {"t_us": _IN, "mx": _DE, "my": _DE, "mz": _DE},
    "MCAV": {"time": _TM, "t_us": _IN, "vn": _DE, "ve": _DE, "vd": _DE, "s_acc": _DE},
}

_FIX_TO_GGA_Q = {1: 6, 2: 1, 3: 1, 4: 2, 5: 5, 6: 4}
_FIX_TO_RMC_MODE = {1: "E", 2: "A", 3: "A", 4: "D", 5: "F", 6: "R"}


def sentence(body: str) -> bytes:
    """``body`` (text between ``$`` and ``*``) as a complete line with checksum and CR LF."""
    if "*" in body or "$" in body or "\r" in body or "\n" in body:
        raise ValueError(f"reserved character in sentence body {body!r}")
    return f"${body}*{xor_checksum(body):02X}\r\n".encode("ascii")


def _num(x: float, float_digits: int | None, what: str) -> str:
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"{what}: non-finite value {x!r} cannot be written on the wire")
    return repr(x) if float_digits is None else format(x, f".{float_digits}g")


def _fixed(x: float, decimals: int, what: str) -> str:
    """Fixed-point text, or empty for NaN (the wire's "not given")."""
    x = float(x)
    if math.isnan(x):
        return ""
    if not math.isfinite(x):
        raise ValueError(f"{what}: non-finite value {x!r} cannot be written on the wire")
    s = f"{x:.{decimals}f}"
    return "0." + "0" * decimals if s.lstrip("-").strip("0.") == "" else s


def encode_imu(s: ImuSample, float_digits: int | None = None) -> bytes:
    """One ``$PMCAI`` line. ``float_digits=None`` writes each float64 exactly (``repr``)."""
    if s.t_us < 0:
        raise ValueError(f"IMU t_us={s.t_us} is negative; the wire carries unsigned time")
    names = ("gyro_rps[0]", "gyro_rps[1]", "gyro_rps[2]", "accel_mps2[0]", "accel_mps2[1]", "accel_mps2[2]")
    vals = ",".join(
        _num(v, float_digits, f"IMU sample t_us={s.t_us} {n}")
        for v, n in zip((*s.gyro_rps, *s.accel_mps2), names, strict=True)
    )
    return sentence(f"PMCAI,{int(s.t_us)},{vals}")


def encode_mag(s: MagSample, float_digits: int | None = None) -> bytes:
    """One ``$PMCAM`` line."""
    if s.t_us < 0:
        raise ValueError(f"magnetometer t_us={s.t_us} is negative; the wire carries unsigned time")
    vals = ",".join(
        _num(v, float_digits, f"magnetometer sample t_us={s.t_us} mag_b[{i}]") for i, v in enumerate(s.mag_b)
    )
    return sentence(f"PMCAM,{int(s.t_us)},{vals}")


def _latlon(v_e7: int, deg_digits: int, pos: str, neg: str) -> tuple[str, str]:
    a = abs(int(v_e7))
    deg, rem = divmod(a, 10_000_000)
    minutes_e6 = rem * 6  # rem * 60 / 1e7 minutes, in units of 1e-6 minute: exact
    mm, frac = divmod(minutes_e6, 1_000_000)
    return f"{deg:0{deg_digits}d}{mm:02d}.{frac:06d}", (neg if v_e7 < 0 else pos)


def _mm_text(mm: int) -> str:
    sign = "-" if mm < 0 else ""
    m, r = divmod(abs(int(mm)), 1000)
    return f"{sign}{m}.{r:03d}"


def _utc_text(tod_us: int, decimals: int) -> str:
    q = 10 ** (6 - decimals)
    tod_us = (tod_us + q // 2) // q * q  # round to the written resolution
    tod_us %= DAY_US
    s, us = divmod(tod_us, 1_000_000)
    h, s = divmod(s, 3600)
    m, s = divmod(s, 60)
    frac = f".{us // q:0{decimals}d}" if decimals > 0 else ""
    return f"{h:02d}{m:02d}{s:02d}{frac}"


def encode_fix(
    fix: GnssFix,
    utc_offset_us: int = 0,
    talker: str = "GN",
    date0: date = date(2000, 1, 1),
    pmcav: bool = True,
    utc_decimals: int = 3,
) -> bytes:
    """GGA + RMC + GSA (+ GST) (+ PMCAV) lines for one fix.

    The UTC of the fix is ``fix.t_us + utc_offset_us`` microseconds after midnight of
    ``date0`` (the wire has UTC, the fix has IMU-clock time). Raises ``ValueError`` for
    ``fix_type`` 0 (nothing to write) or a value the wire cannot carry.
    """
    what = f"GNSS fix t_us={fix.t_us}"
    ft = int(fix.fix_type)
    if ft not in _FIX_TO_GGA_Q:
        raise ValueError(f"{what}: fix_type={ft} cannot be written (1..6 only; 0 means no fix)")
    if not 0 <= utc_decimals <= 6:
        raise ValueError(f"utc_decimals={utc_decimals} must be 0..6")
    utc_abs = int(fix.t_us) + int(utc_offset_us)
    day, tod = divmod(utc_abs, DAY_US)
    t = _utc_text(tod, utc_decimals)
    d = date0 + timedelta(days=day)
    lat, ns = _latlon(fix.lat_e7, 2, "N", "S")
    lon, ew = _latlon(fix.lon_e7, 3, "E", "W")
    flags = int(fix.flags)
    if flags & GNSS_HAS_ALT:
        alt = _mm_text(fix.alt_mm)
        sep = "" if flags & GNSS_ALT_MSL else "0.000"
    else:
        alt = sep = ""
    nsv = int(fix.num_sv)
    out = [
        sentence(f"{talker}GGA,{t},{lat},{ns},{lon},{ew},{_FIX_TO_GGA_Q[ft]},{nsv:02d},,{alt},M,{sep},M,,")
    ]
    if flags & GNSS_HAS_COURSE:
        sog = _fixed(fix.speed_mps / KNOT_MPS, 4, f"{what} speed_mps")
        cog_deg = math.degrees(float(fix.course_rad)) % 360.0
        cog = _fixed(cog_deg, 4, f"{what} course_rad")
        if cog == "360.0000":
            cog = "0.0000"
    else:
        sog = _fixed(fix.speed_mps / KNOT_MPS, 4, f"{what} speed_mps")  # speed without course, or empty
        cog = ""
    out.append(
        sentence(
            f"{talker}RMC,{t},A,{lat},{ns},{lon},{ew},{sog},{cog},"
            f"{d.day:02d}{d.month:02d}{d.year % 100:02d},,,{_FIX_TO_RMC_MODE[ft]}"
        )
    )
    out.append(sentence(f"{talker}GSA,A,{2 if ft == 2 else 3}" + "," * 15))
    h, v = float(fix.h_acc_m), float(fix.v_acc_m)
    if not (math.isnan(h) and math.isnan(v)):
        hs, vs = _fixed(h, 4, f"{what} h_acc_m"), _fixed(v, 4, f"{what} v_acc_m")
        out.append(sentence(f"{talker}GST,{t},,,,,{hs},{hs},{vs}"))
    if pmcav:
        vel = fix.vel_ned_mps
        vn = _fixed(vel[0], 6, f"{what} vel_ned_mps[0]") if flags & GNSS_HAS_VEL_NE else ""
        ve = _fixed(vel[1], 6, f"{what} vel_ned_mps[1]") if flags & GNSS_HAS_VEL_NE else ""
        vd = _fixed(vel[2], 6, f"{what} vel_ned_mps[2]") if flags & GNSS_HAS_VEL_D else ""
        sa = _fixed(fix.s_acc_mps, 6, f"{what} s_acc_mps")
        out.append(sentence(f"PMCAV,{t},{int(fix.t_us)},{vn},{ve},{vd},{sa}"))
    return b"".join(out)


def _fixes_of(arr: np.ndarray) -> list[GnssFix]:
    return [
        GnssFix(
            int(r["t_us"]),
            int(r["t_rx_us"]),
            int(r["lat_e7"]),
            int(r["lon_e7"]),
            int(r["alt_mm"]),
            tuple(float(v) for v in r["vel_ned_mps"]),
            float(r["speed_mps"]),
            float(r["course_rad"]),
            float(r["h_acc_m"]),
            float(r["v_acc_m"]),
            float(r["s_acc_mps"]),
            int(r["fix_type"]),
            int(r["num_sv"]),
            int(r["flags"]),
        )
        for r in arr
    ]


def encode_samples(
    samples: Iterable[ImuSample | MagSample | GnssFix],
    float_digits: int | None = None,
    **fix_kw,
) -> bytes:
    """Encode samples in the order given (``fix_kw`` goes to :func:`encode_fix`)."""
    out = []
    for s in samples:
        if isinstance(s, ImuSample):
            out.append(encode_imu(s, float_digits))
        elif isinstance(s, MagSample):
            out.append(encode_mag(s, float_digits))
        elif isinstance(s, GnssFix):
            out.append(encode_fix(s, **fix_kw))
        else:
            raise TypeError(f"cannot encode {type(s).__name__}")
    return b"".join(out)


def recording_samples(rec: Recording) -> list[ImuSample | MagSample | GnssFix]:
    """The samples of ``rec`` in the order a live stream would carry them.

    IMU and magnetometer samples by ``t_us``, fixes by ``t_rx_us``; a fix comes after the
    sensor samples of the same time (so the reader's "last IMU sample before the fix" is the
    one at ``t_rx_us``). Fixes with ``fix_type == 0`` are left out.
    """
    items: list[tuple[int, int, int, ImuSample | MagSample | GnssFix]] = []
    for i, r in enumerate(rec.imu):
        s = ImuSample(int(r["t_us"]), tuple(map(float, r["gyro_rps"])), tuple(map(float, r["accel_mps2"])))
        items.append((s.t_us, 0, i, s))
    for i, r in enumerate(rec.mag):
        m = MagSample(int(r["t_us"]), tuple(map(float, r["mag_b"])))
        items.append((m.t_us, 1, i, m))
    for i, f in enumerate(_fixes_of(rec.gnss)):
        if f.fix_type != 0:
            items.append((f.t_rx_us, 2, i, f))
    items.sort(key=lambda x: x[:3])
    return [x[3] for x in items]


def encode_recording(rec: Recording, float_digits: int | None = None, **fix_kw) -> bytes:
    """A whole :class:`Recording` as a wire byte stream (see :func:`recording_samples`)."""
    return encode_samples(recording_samples(rec), float_digits, **fix_kw)


class ByteSink(Protocol):
    """Anything with ``write(bytes)``: a binary file, a pyserial port, a socket wrapper."""

    def write(self, data: bytes, /) -> int | None: ...


def write_recording(rec: Recording, stream: ByteSink, float_digits: int | None = None, **fix_kw) -> int:
    """Write ``rec`` to a binary stream (file, serial port); return the number of bytes."""
    data = encode_recording(rec, float_digits, **fix_kw)
    stream.write(data)
    return len(data)

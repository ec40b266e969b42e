"""Decode framed sentences (through pynmeagps) and assemble GNSS sentences into epochs.

Decoding
--------
Every used sentence goes through ``pynmeagps.NMEAReader.parse`` (checksum validated again),
with the MCAHRS sentences declared as pynmeagps user-defined messages
(:data:`mcahrs.io.wire.USERDEFINED`). Used types: GGA, RMC, VTG, GSA, GST, GNS from any
talker, and ``$PMCAI``/``$PMCAM``/``$PMCAV``. Any other valid sentence is counted in
``stats.ignored`` by type. A talker pynmeagps does not know (``QZ`` in 1.1.8) is replaced by
``GN`` for parsing only (event ``talker_normalised``); ``stats.sentences`` keeps the original.

Values whose precision matters are taken from the raw field text, not from pynmeagps's
floats: latitude/longitude go from ``(d)ddmm.mmmm`` to integer 1e-7 deg with exact rational
arithmetic (round half away from zero), altitude and geoid separation to integer mm, UTC
time of day to integer microseconds. pynmeagps's own lat/lon is used as a cross-check.
Before pynmeagps sees a number, its text must look like a decimal number (Python's
``int``/``float`` would also take ``1_000`` or ``nan``): ``nan``/``inf`` -> ``nonfinite``,
anything else odd -> ``bad_fields``. A field count outside the standard range for the type
-> ``bad_fields``. A required field left empty -> ``empty_fields``. A sentence that validly
says "no fix" (GGA quality 0, RMC status V, VTG/GNS mode N, empty time) is not a rejection:
event ``no_fix``.

Epochs (one GnssFix per UTC time of fix)
----------------------------------------
* A sentence with a time field (GGA, RMC, GNS, GST, PMCAV) belongs to the epoch of that
  time of day. A different time closes the open epoch and opens a new one.
* A sentence without time (VTG, GSA) joins the open epoch, except a VTG when that epoch
  already has one: then it is held for the next epoch (u-blox receivers with RMC off send
  VTG before the epoch's GGA). Untimed sentences seen while no epoch is open are held too,
  and dropped (event ``orphan_sentence``) when a GGA/RMC/GNS without time (a receiver still
  searching) shows that their cycle had no time.
* An epoch is complete, and its fix is emitted at once, when it has a position and it has
  seen every sentence kind that the epochs with a position of the 3 s of UTC before it had
  between them (the "expected set", learnt from the stream; 3 s so that a 1 Hz RMC among
  10 Hz GGA is still expected). Otherwise it is complete when a sentence with
  another time arrives, when ``epoch_timeout_us`` of IMU time has passed since its first
  sentence, or at the end of the stream. Sentences for an already emitted epoch are
  counted as event ``late_sentence`` and not used.
* Position: GGA with quality 1-6, else GNS with a fix mode, else RMC with status A. Height
  (GGA/GNS): MSL + geoid separation (ellipsoidal) when the separation is given, else MSL
  with flag :data:`~mcahrs.io.wire.GNSS_ALT_MSL`. Speed and course: RMC, else VTG (knots,
  else km/h); velocity N/E = speed * (cos, sin)(course) (NMEA has no vertical velocity),
  unless ``$PMCAV`` gives NED velocity. ``h_acc_m`` = sqrt((std_lat^2 + std_lon^2)/2) and
  ``v_acc_m`` = std_alt from GST. ``num_sv`` from the position sentence.
* ``fix_type``: GGA quality 1 -> 3 (2 when GSA says 2D), 2 -> 4, 3 (PPS) -> 3, 4 -> 6,
  5 -> 5, 6 -> 1; qualities 7 (manual) and 8 (simulation) are not fixes. From GNS/RMC mode
  letters: R -> 6, F -> 5, D/P -> 4, A -> 3 (or 2), E -> 1.
* An epoch without a position gives no fix (event ``epoch_no_fix``).
"""

from __future__ import annotations

import math
import re
from collections import deque
from dataclasses import dataclass, field
from fractions import Fraction

from pynmeagps import NMEAReader
from pynmeagps.exceptions import NMEAMessageError, NMEAParseError, NMEATypeError
from pynmeagps.nmeatypes_core import NMEA_TALKERS, VALCKSUM

from ..samples import (
    GNSS_HAS_ALT,
    GNSS_HAS_COURSE,
    GNSS_HAS_VEL_D,
    GNSS_HAS_VEL_NE,
    ImuSample,
    MagSample,
)
from .framing import Sentence, xor_checksum
from .stats import StreamStats
from .timebase import wrap_day
from .wire import GNSS_ALT_MSL, KNOT_MPS, USERDEFINED

GNSS_KINDS = ("GGA", "RMC", "VTG", "GSA", "GST", "GNS")
# Accepted payload field counts per type (min, max) over NMEA 2.x .. 4.11.
_FIELD_COUNTS = {
    "GGA": (14, 14),
    "RMC": (11, 13),
    "VTG": (8, 9),
    "GSA": (17, 18),
    "GST": (8, 8),
    "GNS": (12, 13),
    "MCAI": (7, 7),
    "MCAM": (4, 4),
    "MCAV": (6, 6),
}
_NUM = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_UINT = re.compile(r"\d+")
_NONFINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)
_TIME = re.compile(r"(\d\d)(\d\d)(\d\d)(?:\.(\d{0,9}))?")
_LATLON = re.compile(r"(\d+)(\d\d(?:\.\d*)?)")

_GGA_FIX = {1: 3, 2: 4, 3: 3, 4: 6, 5: 5, 6: 1}
_MODE_FIX = {"R": 6, "F": 5, "D": 4, "P": 4, "A": 3, "E": 1}
_UNIQUE_UNTIMED = frozenset({"VTG"})
_POSITION_KINDS = frozenset({"GGA", "GNS", "RMC"})


class _Reject(Exception):
    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class _NoFix(Exception):
    pass


@dataclass
class GnssPart:
    """What one GNSS sentence contributes to an epoch."""

    kind: str  # "GGA", "RMC", ..., "MCAV"
    tod_us: int | None  # UTC time of day of the fix, None for VTG/GSA
    values: dict
    imu_t_us: int | None = None  # IMU time of the last IMU sample before this sentence arrived


# -- field helpers ---------------------------------------------------------------------------
def _field(p: list[str], i: int) -> str:
    return p[i] if i < len(p) else ""


def _num(text: str, required: bool = False) -> float | None:
    """Validate numeric text; None if empty and not required."""
    if text == "":
        if required:
            raise _Reject("empty_fields")
        return None
    if _NONFINITE.fullmatch(text):
        raise _Reject("nonfinite")
    if not _NUM.fullmatch(text):
        raise _Reject("bad_fields")
    v = float(text)
    if not math.isfinite(v):  # e.g. 1e999
        raise _Reject("nonfinite")
    return v


def _frac(text: str) -> Fraction:
    return Fraction(text)  # text already matched _NUM; Fraction parses decimals exactly


def _round_half_away(x: Fraction) -> int:
    n = math.floor(abs(x) + Fraction(1, 2))
    return -n if x < 0 else n


def parse_time_us(text: str) -> int:
    """``hhmmss[.s...]`` -> microseconds since midnight (``_Reject('bad_fields')`` if malformed)."""
    m = _TIME.fullmatch(text)
    if not m:
        raise _Reject("bad_fields")
    h, mi, s = int(m.group(1)), int(m.group(2)), int(m.group(3))
    if h > 23 or mi > 59 or s > 60:
        raise _Reject("bad_fields")
    frac = m.group(4) or ""
    us = _round_half_away(Fraction(int(frac), 10 ** len(frac)) * 1_000_000) if frac else 0
    return ((h * 60 + mi) * 60 + s) * 1_000_000 + us


def parse_latlon_e7(text: str, hemi: str, is_lat: bool) -> int:
    """``(d)ddmm.mmmm`` + hemisphere -> integer 1e-7 degrees, exactly rounded."""
    m = _LATLON.fullmatch(text)
    if not m:
        raise _Reject("nonfinite" if _NONFINITE.fullmatch(text) else "bad_fields")
    deg = int(m.group(1))
    minutes = Fraction(m.group(2))
    if minutes >= 60:
        raise _Reject("bad_fields")
    v = _round_half_away((deg + minutes / 60) * 10_000_000)
    limit = 900_000_000 if is_lat else 1_800_000_000
    if v > limit:
        raise _Reject("bad_fields")
    if hemi not in (("N", "S") if is_lat else ("E", "W")):
        raise _Reject("empty_fields" if hemi == "" else "bad_fields")
    return -v if hemi in ("S", "W") else v


def _mm(text: str, required: bool = False) -> int | None:
    if _num(text, required) is None:
        return None
    return _round_half_away(_frac(text) * 1000)


# -- sentence decoding -----------------------------------------------------------------------
def _parse(sent: Sentence, stats: StreamStats):
    """pynmeagps parse of one framed sentence (talker normalised if pynmeagps does not know it)."""
    body = sent.body
    if not sent.address.startswith("P") and sent.talker not in NMEA_TALKERS:
        body = "GN" + body[2:]
        stats.events["talker_normalised"] += 1
    line = f"${body}*{xor_checksum(body):02X}\r\n".encode("ascii")
    try:
        msg = NMEAReader.parse(line, validate=VALCKSUM, userdefined=USERDEFINED)
    except (NMEAParseError, NMEATypeError, NMEAMessageError, ValueError) as err:
        raise _Reject("bad_fields") from err
    if msg is None:
        raise _Reject("bad_fields")
    return msg


def _attr(msg, name: str):
    v = getattr(msg, name, "")
    return None if v == "" else v


def _check_latlon(msg, lat_e7: int, lon_e7: int) -> None:
    """pynmeagps's float decode must agree with the exact one (guards the raw-text parser)."""
    for name, v in (("lat", lat_e7), ("lon", lon_e7)):
        f = getattr(msg, name, "")
        if not isinstance(f, float) or abs(f - v * 1e-7) > 1e-6:
            raise _Reject("bad_fields")


def _position(p: list[str], i: int, msg, required: bool) -> tuple[int, int] | None:
    lat_t, ns, lon_t, ew = p[i], p[i + 1], p[i + 2], p[i + 3]
    if lat_t == "" or lon_t == "":
        if required:
            raise _Reject("empty_fields")
        return None
    lat = parse_latlon_e7(lat_t, ns, True)
    lon = parse_latlon_e7(lon_t, ew, False)
    _check_latlon(msg, lat, lon)
    return lat, lon


def _no_fix(kind: str, tod: int) -> GnssPart:
    """A timed sentence that says "no fix": it still marks its epoch."""
    return GnssPart(kind, tod, {"pos": None})


def _decode_gga(p: list[str], msg) -> GnssPart:
    q_t = p[5]
    if p[0] == "":
        raise _NoFix
    tod = parse_time_us(p[0])
    if q_t != "" and not _UINT.fullmatch(q_t):
        raise _Reject("bad_fields")
    if q_t == "" or int(q_t) not in _GGA_FIX:  # 0 no fix, 7 manual, 8 simulation, others unknown
        return _no_fix("GGA", tod)
    q = int(q_t)
    pos = _position(p, 1, msg, True)
    nsv = p[6]
    if nsv != "" and not _UINT.fullmatch(nsv):
        raise _Reject("bad_fields")
    alt = _mm(p[8])
    sep = _mm(p[10])
    return GnssPart(
        "GGA", tod, {"pos": pos, "quality": q, "num_sv": int(nsv) if nsv else 0, "alt_mm": alt, "sep_mm": sep}
    )


def _decode_gns(p: list[str], msg) -> GnssPart:
    mode = p[5]
    if p[0] == "":
        raise _NoFix
    tod = parse_time_us(p[0])
    fix = max((_MODE_FIX.get(c, 0) for c in mode), default=0)
    if fix == 0:
        return _no_fix("GNS", tod)
    pos = _position(p, 1, msg, True)
    nsv = p[6]
    if nsv != "" and not _UINT.fullmatch(nsv):
        raise _Reject("bad_fields")
    return GnssPart(
        "GNS",
        tod,
        {"pos": pos, "fix": fix, "num_sv": int(nsv) if nsv else 0, "alt_mm": _mm(p[8]), "sep_mm": _mm(p[9])},
    )


def _decode_rmc(p: list[str], msg) -> GnssPart:
    mode = _field(p, 11)[:1]
    if p[0] == "":
        raise _NoFix
    tod = parse_time_us(p[0])
    if p[1] != "A" or mode in ("N", "M", "S"):  # mode: not valid, manual input, simulator
        return _no_fix("RMC", tod)
    pos = _position(p, 2, msg, True)
    spd = _num(p[6])
    cog = _num(p[7])
    return GnssPart("RMC", tod, {"pos": pos, "spd_kn": spd, "cog_deg": cog, "fix": _MODE_FIX.get(mode, 3)})


def _decode_vtg(p: list[str], msg) -> GnssPart:
    mode = _field(p, 8)
    if mode == "N":
        raise _NoFix
    cog = _num(p[0])
    kn = _num(p[4])
    kmh = _num(p[6])
    if kn is None and kmh is not None:
        kn = kmh / 3.6 / KNOT_MPS
    if cog is None and kn is None:
        raise _NoFix
    return GnssPart("VTG", None, {"spd_kn": kn, "cog_deg": cog})


def _decode_gsa(p: list[str], msg) -> GnssPart:
    nav = p[1]
    if not _UINT.fullmatch(nav) or int(nav) not in (1, 2, 3):
        raise _Reject("empty_fields" if nav == "" else "bad_fields")
    return GnssPart("GSA", None, {"nav_mode": int(nav)})


def _decode_gst(p: list[str], msg) -> GnssPart:
    if p[0] == "":
        raise _NoFix
    tod = parse_time_us(p[0])
    return GnssPart("GST", tod, {"std_lat": _num(p[5]), "std_lon": _num(p[6]), "std_alt": _num(p[7])})


def _decode_mcav(p: list[str], msg) -> GnssPart:
    tod = parse_time_us(p[0]) if p[0] else None
    if tod is None:
        raise _Reject("empty_fields")
    t = p[1]
    if t != "" and not _UINT.fullmatch(t):
        raise _Reject("nonfinite" if _NONFINITE.fullmatch(t) else "bad_fields")
    return GnssPart(
        "MCAV",
        tod,
        {
            "t_us": int(t) if t else None,
            "vn": _num(p[2]),
            "ve": _num(p[3]),
            "vd": _num(p[4]),
            "s_acc": _num(p[5]),
        },
    )


_GNSS_DECODERS = {
    "GGA": _decode_gga,
    "GNS": _decode_gns,
    "RMC": _decode_rmc,
    "VTG": _decode_vtg,
    "GSA": _decode_gsa,
    "GST": _decode_gst,
}


def _sensor_values(p: list[str], n: int) -> tuple[int, tuple[float, ...]]:
    t = p[0]
    if t == "":
        raise _Reject("empty_fields")
    if not _UINT.fullmatch(t):
        raise _Reject("nonfinite" if _NONFINITE.fullmatch(t) else "bad_fields")
    vals = tuple(_num(x, required=True) for x in p[1 : 1 + n])
    return int(t), vals  # type: ignore[return-value]


def decode_sentence(sent: Sentence, stats: StreamStats) -> ImuSample | MagSample | GnssPart | None:
    """Decode one framed sentence; None if ignored, rejected (counted) or a valid "no fix"."""
    if sent.address.startswith("P"):
        kind = sent.address[1:]
        if kind not in ("MCAI", "MCAM", "MCAV"):
            if kind.startswith("MCA"):
                stats.reject("unknown_sentence", sent.raw)
            else:
                stats.ignored[sent.address] += 1
            return None
    else:
        kind = sent.address[2:]
        if kind not in _GNSS_DECODERS:
            stats.ignored[kind] += 1
            return None
    payload = sent.body.split(",")[1:]
    lo, hi = _FIELD_COUNTS[kind]
    try:
        if not lo <= len(payload) <= hi:
            raise _Reject("bad_fields")
        # Validate the text of the sensor numbers before pynmeagps's int()/float() see it.
        if kind == "MCAI":
            t, v = _sensor_values(payload, 6)
        elif kind == "MCAM":
            t, v = _sensor_values(payload, 3)
        msg = _parse(sent, stats)
        if kind == "MCAI":
            # decoded by pynmeagps through the user-defined payload definition
            out: ImuSample | MagSample | GnssPart = ImuSample(
                msg.t_us, (msg.gx, msg.gy, msg.gz), (msg.ax, msg.ay, msg.az)
            )
            if (out.t_us, out.gyro_rps + out.accel_mps2) != (t, v):
                raise _Reject("bad_fields")
        elif kind == "MCAM":
            out = MagSample(msg.t_us, (msg.mx, msg.my, msg.mz))
            if (out.t_us, out.mag_b) != (t, v):
                raise _Reject("bad_fields")
        elif kind == "MCAV":
            out = _decode_mcav(payload, msg)
        else:
            out = _GNSS_DECODERS[kind](payload, msg)
    except _Reject as r:
        stats.reject(r.reason, sent.raw)
        return None
    except _NoFix:
        stats.used[kind] += 1
        stats.events["no_fix"] += 1
        if kind in _POSITION_KINDS:  # a cycle without time: marks the end of held sentences
            return GnssPart(kind, None, {"pos": None})
        return None
    stats.used[kind] += 1
    if isinstance(out, GnssPart) and out.values.get("pos", True) is None:
        stats.events["no_fix"] += 1
    return out


# -- epochs ----------------------------------------------------------------------------------
@dataclass
class Epoch:
    """The GNSS sentences of one UTC time of fix."""

    tod_us: int
    parts: list[GnssPart] = field(default_factory=list)
    closed: bool = False

    @property
    def kinds(self) -> set[str]:
        return {p.kind for p in self.parts}

    @property
    def imu_t_us(self) -> int | None:
        """IMU time of the last IMU sample before the epoch's first sentence arrived."""
        return self.parts[0].imu_t_us if self.parts else None

    def first(self, kind: str) -> GnssPart | None:
        """The first part of ``kind`` that carries data (not a "no fix" marker)."""
        for p in self.parts:
            if p.kind == kind and p.values.get("pos", True) is not None:
                return p
        return None

    @property
    def has_position(self) -> bool:
        return any(p.kind in _POSITION_KINDS and p.values["pos"] is not None for p in self.parts)


class EpochAssembler:
    """Groups :class:`GnssPart` into :class:`Epoch` (rules in the module docstring)."""

    def __init__(self, stats: StreamStats, learn_us: int = 3_000_000, max_pending: int = 16) -> None:
        self.stats = stats
        self.current: Epoch | None = None
        self.pending: list[GnssPart] = []
        self.history: deque[tuple[int, frozenset[str]]] = deque(maxlen=64)  # (tod, kinds)
        self.learn_us = learn_us
        self.max_pending = max_pending
        self._recent: deque[int] = deque(maxlen=4)  # times of recently closed epochs

    def expected(self, tod_us: int) -> frozenset[str]:
        """Kinds seen in the epochs with a position of the ``learn_us`` before ``tod_us``."""
        kinds: frozenset[str] = frozenset()
        for t, k in self.history:
            if 0 < wrap_day(tod_us - t) <= self.learn_us:
                kinds |= k
        return kinds

    def _close(self, out: list[Epoch]) -> None:
        ep = self.current
        if ep is None or ep.closed:
            return
        ep.closed = True
        self._recent.append(ep.tod_us)
        if ep.has_position:
            self.history.append((ep.tod_us, frozenset(ep.kinds)))
        out.append(ep)

    def add(self, part: GnssPart) -> list[Epoch]:
        """Add one part; return the epochs that became complete (in order)."""
        out: list[Epoch] = []
        cur = self.current
        if part.tod_us is None and part.values.get("pos", True) is None:
            # GGA/RMC/GNS without time or fix (receiver still searching): sentences held for
            # the next epoch belong to this timeless cycle, not to the next fix
            if (cur is None or cur.closed) and self.pending:
                self.stats.events["orphan_sentence"] += len(self.pending)
                self.pending = []
            return out
        if part.tod_us is not None:
            if cur is not None and part.tod_us == cur.tod_us:
                if cur.closed:
                    self.stats.events["late_sentence"] += 1
                    return out
                cur.parts.append(part)
            elif part.tod_us in self._recent:
                self.stats.events["late_sentence"] += 1
                return out
            else:
                self._close(out)
                self.current = Epoch(part.tod_us, self.pending + [part])
                self.pending = []
        else:
            if cur is not None and not (part.kind in _UNIQUE_UNTIMED and part.kind in cur.kinds):
                if cur.closed:  # GSA comes once per constellation: late ones are normal
                    self.stats.events["late_gsa" if part.kind == "GSA" else "late_sentence"] += 1
                    return out
                cur.parts.append(part)
            else:
                self.pending.append(part)
                if len(self.pending) > self.max_pending:
                    self.pending.pop(0)
                    self.stats.events["orphan_sentence"] += 1
                return out
        cur = self.current
        if cur is None or not cur.has_position:
            return out
        exp = self.expected(cur.tod_us)
        if exp and cur.kinds >= exp:
            self._close(out)
        return out

    def timeout(self, imu_t_us: int, timeout_us: int) -> list[Epoch]:
        """Close the open epoch if ``timeout_us`` of IMU time passed since its first sentence."""
        out: list[Epoch] = []
        cur = self.current
        if cur is not None and not cur.closed and cur.imu_t_us is not None:
            if imu_t_us - cur.imu_t_us > timeout_us:
                self._close(out)
        return out

    def flush(self) -> list[Epoch]:
        """End of stream: close the open epoch; held untimed sentences are orphans."""
        out: list[Epoch] = []
        self._close(out)
        if self.pending:
            self.stats.events["orphan_sentence"] += len(self.pending)
            self.pending = []
        return out


def _speed_course(ep: Epoch) -> tuple[float, float]:
    """Speed (m/s) and course (rad in [0, 2 pi)) from RMC, else VTG; NaN if not given."""
    for kind in ("RMC", "VTG"):
        p = ep.first(kind)
        if p is not None and (p.values["spd_kn"] is not None or p.values["cog_deg"] is not None):
            kn, cog = p.values["spd_kn"], p.values["cog_deg"]
            spd = math.nan if kn is None else kn * KNOT_MPS
            crs = math.nan if cog is None else math.radians(cog % 360.0) % (2 * math.pi)
            return spd, crs
    return math.nan, math.nan


def fix_fields(ep: Epoch) -> dict | None:
    """GnssFix fields of an epoch except the times; None if it has no position."""
    src = None
    for kind in ("GGA", "GNS", "RMC"):
        src = ep.first(kind)
        if src is not None:
            break
    if src is None:
        return None
    v = src.values
    lat, lon = v["pos"]
    flags = 0
    alt_mm = 0
    if src.kind in ("GGA", "GNS") and v["alt_mm"] is not None:
        flags |= GNSS_HAS_ALT
        if v["sep_mm"] is not None:
            alt_mm = v["alt_mm"] + v["sep_mm"]
        else:
            alt_mm = v["alt_mm"]
            flags |= GNSS_ALT_MSL
    fix = _GGA_FIX[v["quality"]] if src.kind == "GGA" else v["fix"]
    gsa = ep.first("GSA")
    if gsa is not None and fix == 3 and gsa.values["nav_mode"] == 2:
        fix = 2
    num_sv = v.get("num_sv", 0)
    spd, crs = _speed_course(ep)
    vel = [math.nan, math.nan, math.nan]
    if not math.isnan(spd) and not math.isnan(crs):
        flags |= GNSS_HAS_COURSE | GNSS_HAS_VEL_NE
        vel[0], vel[1] = spd * math.cos(crs), spd * math.sin(crs)
    elif spd == 0.0:
        flags |= GNSS_HAS_VEL_NE
        vel[0] = vel[1] = 0.0
    s_acc = math.nan
    t_us = None
    mcav = ep.first("MCAV")
    if mcav is not None:
        m = mcav.values
        if m["vn"] is not None and m["ve"] is not None:
            vel[0], vel[1] = m["vn"], m["ve"]
            flags |= GNSS_HAS_VEL_NE
        if m["vd"] is not None:
            vel[2] = m["vd"]
            flags |= GNSS_HAS_VEL_D
        if m["s_acc"] is not None:
            s_acc = m["s_acc"]
        t_us = m["t_us"]
    h_acc = v_acc = math.nan
    gst = ep.first("GST")
    if gst is not None:
        g = gst.values
        if g["std_lat"] is not None and g["std_lon"] is not None:
            h_acc = math.sqrt((g["std_lat"] ** 2 + g["std_lon"] ** 2) / 2.0)
        if g["std_alt"] is not None:
            v_acc = g["std_alt"]
    return {
        "lat_e7": lat,
        "lon_e7": lon,
        "alt_mm": int(alt_mm),
        "vel_ned_mps": (vel[0], vel[1], vel[2]),
        "speed_mps": spd,
        "course_rad": crs,
        "h_acc_m": h_acc,
        "v_acc_m": v_acc,
        "s_acc_mps": s_acc,
        "fix_type": fix,
        "num_sv": min(int(num_sv), 255),
        "flags": flags,
        "pmcav_t_us": t_us,
        "source": src.kind,
    }

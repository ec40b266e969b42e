"""Real receiver captures (gpsd regression logs in data/nmea) against an independent count and
against gpsd's own decode in the ``.chk`` files. Exceptions come from data/nmea/README.md and
are listed below with the reason.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections import Counter, defaultdict
from functools import reduce
from pathlib import Path

import numpy as np
import pytest

from mcahrs.io import read_file
from mcahrs.io.wire import GNSS_ALT_MSL
from mcahrs.samples import GNSS_HAS_ALT

DATA = Path(os.environ.get("MCAHRS_NMEA_DATA", Path(__file__).resolve().parents[3] / "shared/data/nmea"))
LOGS = sorted(DATA.glob("*.log")) if DATA.is_dir() else []
pytestmark = pytest.mark.skipif(
    not LOGS, reason=f"no NMEA captures in {DATA} (set MCAHRS_NMEA_DATA to the data/nmea folder)"
)
IDS = [p.name for p in LOGS]

# Rejections the README documents, per file (reason -> count). Files not listed: none.
EXPECTED_REJECTS = {
    "firefly-II.log": {"bad_checksum": 23},  # every GPGGA has a checksum off by XOR 0x02
    "sl869.log": {"no_checksum": 1},  # first line "$GPTXT,TELIT SW Version..." has no *hh
    "st-teseo-liv4f.log": {"bad_checksum": 1},  # one GPGSV with a bad checksum (per its header)
    "isync.log": {"truncated": 1},  # a GPGSV cut off by a $PTNTA injected into it by hand
}
# Files whose garbage is counted but not reproducible by a plain line regex: only framing
# reasons are allowed, and every started line must be either accepted or rejected.
FRAMING_REASONS = {
    "bad_checksum",
    "no_checksum",
    "truncated",
    "binary",
    "too_long",
    "malformed",
    "bad_address",
}
GARBAGE_FILES = {
    "gp-320fw-2019-04-07-coldboot.log",  # broken/missing checksums, NULs, merged lines
    "ublox8-uniqid-monhw.log",  # '$'/'!' bytes inside interleaved UBX binary frames
}
# Fixes without any gpsd TPV at the same time of day (README, cross-check section).
NO_TPV = {
    "bt451.log": {"15:25:08.50", "14:33:08.50"},  # last fix of each excerpt (cycle left open)
    "bundg_zeus_9.log": {"09:47:36.00", "09:48:16.00"},  # first fix; start of its timing glitch
    "gp-320fw-2019-04-07-coldboot.log": {"00:03:43.03"},  # first fix of the file
    "haicom-305N.log": {"09:53:04.802"},  # first fix of the file
    "isync.log": {"13:15:30.00"},  # last fix of the file
    "rst39.log": {"20:41:32.10"},  # the 10 Hz GGA right after the first RMC
}
# bundg_zeus_9: a chartplotter re-emitting sentences whose positions lag by one epoch; gpsd's
# TPV for a time carries sometimes the RMC/GLL and sometimes the GGA position (up to ~3.5 m
# apart), and from 09:48:16 on its TPV speed is computed by gpsd (0.0-0.3 m/s), not RMC's.
BUNDG = "bundg_zeus_9.log"
BUNDG_POS_TOL_M = 4.0
BUNDG_SPEED_UNTIL = "09:48:16.00"

# gpsd prints lat/lon with 9 decimals; our integers are 1e-7 deg (rounding <= 0.5e-7)
LATLON_TOL_DEG = 0.6e-7
# ublox8-uniqid-monhw: once the receiver talks UBX, gpsd's TPVs carry the UBX NAV position
# (1e-7 deg), not the NMEA one (5 decimal minutes = 1.7e-7 deg): e.g. at 20:42:25 no TPV holds
# the RMC position. Allow the NMEA resolution plus the UBX rounding.
LATLON_TOL_DEG_FILE = {"ublox8-uniqid-monhw.log": 1.67e-7 + 0.5e-7 + 0.1e-7}
SPEED_TOL_MPS = 0.001  # gpsd prints speed with 3 decimals
ALT_TOL_M = 0.0006  # gpsd prints altitude with 4 decimals, our alt is integer mm
GST_TOL_M = 0.0006  # gpsd prints GST sigmas with 3 decimals

_SENTENCE = re.compile(rb"[$!]([\x20-\x23\x25-\x29\x2b-\x7e]+)\*([0-9A-Fa-f]{2})(?=[\r\n$]|\Z)")


def strip_comments(raw: bytes) -> bytes:
    return b"\n".join(ln for ln in raw.split(b"\n") if not ln.startswith(b"#"))


def independent_counts(path: Path) -> tuple[Counter, int, int]:
    """(checksum-valid sentences by address, sentences with a bad checksum, line starts)."""
    data = strip_comments(path.read_bytes())
    good: Counter = Counter()
    bad = 0
    for m in _SENTENCE.finditer(data):
        if reduce(lambda a, b: a ^ b, m.group(1), 0) == int(m.group(2), 16):
            good[m.group(1).split(b",")[0].decode()] += 1
        else:
            bad += 1
    starts = len(re.findall(rb"(?<!\$)[$!]", data))  # '$$' is one start
    return good, bad, starts


def tod_text(us: int) -> str:
    s, frac = divmod(int(us), 1_000_000)
    h, s = divmod(s, 3600)
    m, s = divmod(s, 60)
    ms = frac // 1000
    return f"{h:02d}:{m:02d}:{s:02d}." + (f"{ms:03d}" if ms % 10 else f"{ms // 10:02d}")


def tpv_by_time(path: Path) -> dict[int, list[dict]]:
    out: dict[int, list[dict]] = defaultdict(list)
    for ln in Path(str(path) + ".chk").read_bytes().splitlines():
        if ln.startswith(b"{"):
            o = json.loads(ln)
            if o.get("class") == "TPV" and "time" in o:
                h, m, s = re.search(r"T(\d\d):(\d\d):([\d.]+)Z", o["time"]).groups()
                out[round(((int(h) * 60 + int(m)) * 60 + float(s)) * 1000)].append(o)
    return out


def gst_by_time(path: Path) -> dict[int, dict]:
    out = {}
    for ln in Path(str(path) + ".chk").read_bytes().splitlines():
        if ln.startswith(b"{"):
            o = json.loads(ln)
            if o.get("class") == "GST" and "time" in o:
                h, m, s = re.search(r"T(\d\d):(\d\d):([\d.]+)Z", o["time"]).groups()
                out[round(((int(h) * 60 + int(m)) * 60 + float(s)) * 1000)] = o
    return out


_CACHE: dict[Path, object] = {}


def rec_of(path: Path):
    if path not in _CACHE:
        _CACHE[path] = read_file(path)
    return _CACHE[path]


@pytest.mark.parametrize("path", LOGS, ids=IDS)
def test_sentence_counts_match_independent_count(path):
    good, _, _ = independent_counts(path)
    st = rec_of(path).meta["stats_obj"]
    assert dict(st.sentences) == dict(good)
    # every accepted sentence is used, ignored, or rejected by the decoder
    decode_rejects = sum(v for k, v in st.rejected.items() if k not in FRAMING_REASONS)
    assert sum(st.used.values()) + sum(st.ignored.values()) + decode_rejects == sum(good.values())


@pytest.mark.parametrize("path", LOGS, ids=IDS)
def test_rejections_are_only_the_documented_ones(path):
    st = rec_of(path).meta["stats_obj"]
    if path.name in GARBAGE_FILES:
        good, bad, starts = independent_counts(path)
        assert set(st.rejected) <= FRAMING_REASONS
        assert st.rejected["bad_checksum"] >= bad
        if path.name == "gp-320fw-2019-04-07-coldboot.log":
            # text only (no binary frames): every started line is accepted or rejected
            assert sum(good.values()) + st.total_rejected == starts
    else:
        assert dict(st.rejected) == EXPECTED_REJECTS.get(path.name, {})


@pytest.mark.parametrize("path", LOGS, ids=IDS)
def test_fixes_match_gpsd_epoch_by_epoch(path):
    rec = rec_of(path)
    tpv = tpv_by_time(path)
    tods = rec.meta["gnss_utc_tod_us"]
    assert len(rec.gnss) > 0
    missing, n_alt = set(), 0
    for fix, tod in zip(rec.gnss, tods, strict=True):
        key, name = round(int(tod) / 1000), tod_text(tod)
        ts = tpv.get(key, [])
        if not ts:
            missing.add(name)
            continue
        lat, lon = int(fix["lat_e7"]) * 1e-7, int(fix["lon_e7"]) * 1e-7
        with_pos = [t for t in ts if "lat" in t]
        if path.name == BUNDG:
            d = [
                math.hypot(
                    (t["lat"] - lat) * 111_320, (t["lon"] - lon) * 111_320 * math.cos(math.radians(lat))
                )
                for t in with_pos
            ]
            assert min(d) <= BUNDG_POS_TOL_M, name
        else:
            tol = LATLON_TOL_DEG_FILE.get(path.name, LATLON_TOL_DEG)
            assert any(abs(t["lat"] - lat) <= tol and abs(t["lon"] - lon) <= tol for t in with_pos), name
        speeds = [t["speed"] for t in ts if "speed" in t]
        if (
            not math.isnan(fix["speed_mps"])
            and speeds
            and not (path.name == BUNDG and name >= BUNDG_SPEED_UNTIL)
        ):
            assert abs(speeds[-1] - fix["speed_mps"]) <= SPEED_TOL_MPS, name  # last TPV of the epoch
        key_alt = "altMSL" if fix["flags"] & GNSS_ALT_MSL else "altHAE"
        alts = [t[key_alt] for t in ts if key_alt in t]
        if fix["flags"] & GNSS_HAS_ALT and alts:
            n_alt += 1
            assert any(abs(a - int(fix["alt_mm"]) / 1000) <= ALT_TOL_M for a in alts), name
    assert missing == NO_TPV.get(path.name, set())
    if any(fix["flags"] & GNSS_HAS_ALT for fix in rec.gnss):
        assert n_alt > 0


@pytest.mark.parametrize("path", [p for p in LOGS if b"GST," in p.read_bytes()], ids=lambda p: p.name)
def test_gst_accuracies_match_gpsd_gst(path):
    rec = rec_of(path)
    gst = gst_by_time(path)
    n = 0
    for fix, tod in zip(rec.gnss, rec.meta["gnss_utc_tod_us"], strict=True):
        g = gst.get(round(int(tod) / 1000))
        if g is None:
            continue
        n += 1
        assert fix["h_acc_m"] == pytest.approx(math.sqrt((g["lat"] ** 2 + g["lon"] ** 2) / 2), abs=GST_TOL_M)
        assert fix["v_acc_m"] == pytest.approx(g["alt"], abs=GST_TOL_M)
    assert n > 0


def test_doubled_dollar_capture_is_fully_read():
    # pynmeagps's stream reader returns nothing for this file (README)
    path = DATA / "st-teseo-liv4f.log"
    st = rec_of(path).meta["stats_obj"]
    assert st.events["doubled_start"] == sum(independent_counts(path)[0].values()) + st.total_rejected
    assert len(rec_of(path).gnss) == 12


def test_qzss_talker_counted_not_dropped():
    st = rec_of(DATA / "sl869.log").meta["stats_obj"]
    assert st.sentences["QZGSV"] == 15 and st.ignored["GSV"] == 90


def test_gnss_only_captures_use_utc_clock_and_stay_monotonic():
    for path in LOGS:
        rec = rec_of(path)
        assert rec.meta["clock"] == "utc"
        t = rec.gnss["t_us"]
        assert np.all(np.diff(t) > 0), path.name
        st = rec.meta["stats_obj"]
        if path.name == "bt451.log":
            assert st.events["utc_backwards"] == 1  # 15:25 -> 14:33 between two excerpts
        elif path.name != "gp-320fw-2019-04-07-coldboot.log":
            np.testing.assert_array_equal(t, rec.meta["gnss_utc_tod_us"])

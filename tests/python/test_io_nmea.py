"""Decoding of GNSS and MCAHRS sentences, and epoch assembly (mcahrs.io.nmea via StreamReader)."""

from __future__ import annotations

import math
from fractions import Fraction
from functools import reduce

import pytest
from pynmeagps.nmeatypes_core import NMEA_TALKERS

from mcahrs.io import GNSS_ALT_MSL, StreamReader
from mcahrs.samples import GNSS_HAS_ALT, GNSS_HAS_COURSE, GNSS_HAS_VEL_D, GNSS_HAS_VEL_NE, GnssFix, ImuSample

KNOT = 1852 / 3600


def s(body: str) -> bytes:
    c = reduce(lambda a, b: a ^ b, body.encode(), 0)
    return f"${body}*{c:02X}\r\n".encode()


def read(data: bytes, **kw) -> tuple[list, StreamReader]:
    r = StreamReader(None, **kw)
    out = r.feed(data) + r.finish()
    return out, r


def fixes(out: list) -> list[GnssFix]:
    return [x for x in out if isinstance(x, GnssFix)]


def exact_e7(text: str, hemi: str) -> int:
    """Reference conversion written for the test: (d)ddmm.mmmm -> 1e-7 deg, half away from 0."""
    dp = text.index(".") if "." in text else len(text)
    x = (int(text[: dp - 2]) + Fraction(text[dp - 2 :]) / 60) * 10**7
    n = math.floor(x + Fraction(1, 2))
    return -n if hemi in "SW" else n


GGA = "{t}GGA,123519.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"
RMC = "{t}RMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W"


@pytest.mark.parametrize("talker", ["GP", "GN", "GL", "GA", "GB", "BD", "QZ", "GQ", "GI"])
def test_gga_rmc_from_any_talker_give_a_fix(talker):
    out, r = read(s(GGA.format(t=talker)) + s(RMC.format(t=talker)))
    (f,) = fixes(out)
    assert (f.lat_e7, f.lon_e7) == (exact_e7("4807.038", "N"), exact_e7("01131.000", "E"))
    assert r.stats.sentences == {f"{talker}GGA": 1, f"{talker}RMC": 1}  # original talker kept
    assert r.stats.total_rejected == 0
    if talker not in NMEA_TALKERS:  # e.g. QZ in pynmeagps 1.1.8
        assert r.stats.events["talker_normalised"] == 2


def test_gga_values_height_speed_and_course():
    out, _ = read(s(GGA.format(t="GP")) + s(RMC.format(t="GP")))
    (f,) = fixes(out)
    assert f.alt_mm == 545400 + 46900  # MSL + geoid separation = ellipsoidal
    assert f.flags & GNSS_HAS_ALT and not f.flags & GNSS_ALT_MSL
    assert f.fix_type == 3 and f.num_sv == 8
    assert f.speed_mps == pytest.approx(22.4 * KNOT, abs=1e-12)
    assert f.course_rad == pytest.approx(math.radians(84.4), abs=1e-12)
    assert f.vel_ned_mps[0] == pytest.approx(22.4 * KNOT * math.cos(math.radians(84.4)), abs=1e-12)
    assert f.vel_ned_mps[1] == pytest.approx(22.4 * KNOT * math.sin(math.radians(84.4)), abs=1e-12)
    assert math.isnan(f.vel_ned_mps[2]) and not f.flags & GNSS_HAS_VEL_D
    assert f.flags & GNSS_HAS_VEL_NE and f.flags & GNSS_HAS_COURSE


def test_height_without_geoid_separation_is_flagged_msl():
    out, r = read(s("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,,M,,"))
    (f,) = fixes(out)
    assert f.alt_mm == 545400 and f.flags & GNSS_ALT_MSL
    assert r.meta()["alt_ref"] == "msl"


@pytest.mark.parametrize(
    "lat, ns, lon, ew",
    [
        ("4830.000003", "N", "01130.000003", "E"),  # exact x.5e-7 ties: float rounding gets these wrong
        ("4830.000003", "S", "01130.000003", "W"),
        ("0000.0000006", "S", "00000.0000006", "W"),
        ("8959.9999999", "N", "17959.9999999", "W"),
        ("3645.861835", "N", "03124.651134", "E"),
    ],
)
def test_latlon_converted_exactly_from_text(lat, ns, lon, ew):
    out, _ = read(s(f"GPGGA,000001,{lat},{ns},{lon},{ew},1,05,1.0,1.0,M,0.0,M,,"))
    (f,) = fixes(out)
    assert (f.lat_e7, f.lon_e7) == (exact_e7(lat, ns), exact_e7(lon, ew))


@pytest.mark.parametrize("q, ft", [(1, 3), (2, 4), (3, 3), (4, 6), (5, 5), (6, 1)])
def test_gga_quality_maps_to_fix_type(q, ft):
    out, _ = read(s(f"GPGGA,000001,4807.038,N,01131.000,E,{q},08,0.9,545.4,M,46.9,M,,"))
    assert fixes(out)[0].fix_type == ft


@pytest.mark.parametrize("q", [0, 7, 8])
def test_gga_without_a_real_fix_gives_no_fix(q):
    out, r = read(s(f"GPGGA,000001,4807.038,N,01131.000,E,{q},08,0.9,545.4,M,46.9,M,,"))
    assert fixes(out) == [] and r.stats.total_rejected == 0
    assert r.stats.events["no_fix"] == 1 and r.stats.events["epoch_no_fix"] == 1


def test_gsa_2d_makes_fix_type_2_and_gst_gives_accuracies():
    data = (
        s("GNGGA,000001,4807.038,N,01131.000,E,1,04,0.9,545.4,M,46.9,M,,")
        + s("GNGSA,A,2,01,02,03,,,,,,,,,,2.0,1.0,1.7")
        + s("GNGST,000001,40.1,,,,2.3,3.5,4.1")
    )
    (f,) = fixes(read(data)[0])
    assert f.fix_type == 2
    assert f.h_acc_m == pytest.approx(math.sqrt((2.3**2 + 3.5**2) / 2))
    assert f.v_acc_m == pytest.approx(4.1)


def test_vtg_speed_used_when_no_rmc_knots_else_kmh():
    base = s("GPGGA,000001,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")
    (f,) = fixes(read(base + s("GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,A"))[0])
    assert f.speed_mps == pytest.approx(5.5 * KNOT) and f.course_rad == pytest.approx(math.radians(54.7))
    (g,) = fixes(read(base + s("GPVTG,054.7,T,034.4,M,,N,010.2,K,A"))[0])
    assert g.speed_mps == pytest.approx(10.2 / 3.6)


def test_gns_position_used_when_no_gga():
    out, _ = read(s("GNGNS,191509.98,3645.868327,N,03124.656607,E,AAN,09,1.2,42.2,32.0,,,V"))
    (f,) = fixes(out)
    assert (f.lat_e7, f.lon_e7, f.alt_mm) == (
        exact_e7("3645.868327", "N"),
        exact_e7("03124.656607", "E"),
        74200,
    )
    assert f.num_sv == 9 and f.fix_type == 3


def test_rmc_only_fix_has_no_height():
    (f,) = fixes(read(s(RMC.format(t="GP")))[0])
    assert not f.flags & GNSS_HAS_ALT and f.fix_type == 3


@pytest.mark.parametrize(
    "bad, reason",
    [
        ("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,nan,M,46.9,M,,", "nonfinite"),
        ("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M", "bad_fields"),
        ("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,,,", "bad_fields"),
        ("GPGGA,123519,,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,", "empty_fields"),
        ("GPGGA,123519,48x7.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,", "bad_fields"),
        ("GPGGA,123519,4867.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,", "bad_fields"),
        ("GPGGA,253519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,", "bad_fields"),
        ("GPRMC,123519,A,4807.038,N,01131.000,E,inf,084.4,230394,003.1,W", "nonfinite"),
        ("GPGSA,A,,,,,,,,,,,,,,,,", "empty_fields"),
    ],
)
def test_bad_gnss_fields_rejected_and_rest_of_epoch_used(bad, reason):
    good_rmc = s("GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W")
    out, r = read(s(bad) + good_rmc)
    assert r.stats.rejected == {reason: 1}
    assert len(fixes(out)) == 1  # the RMC still gives the epoch's fix


@pytest.mark.parametrize(
    "bad, reason",
    [
        ("PMCAI,1000,0.1,0.2,nan,0,0,-9.8", "nonfinite"),
        ("PMCAI,1000,0.1,0.2,INF,0,0,-9.8", "nonfinite"),
        ("PMCAI,1000,0.1,0.2,,0,0,-9.8", "empty_fields"),
        ("PMCAI,,0.1,0.2,0.3,0,0,-9.8", "empty_fields"),
        ("PMCAI,1000,0.1,0.2,0.3,0,0", "bad_fields"),
        ("PMCAI,1000,0.1,0.2,0.3,0,0,-9.8,7", "bad_fields"),
        ("PMCAI,1_000,0.1,0.2,0.3,0,0,-9.8", "bad_fields"),
        ("PMCAI,-1000,0.1,0.2,0.3,0,0,-9.8", "bad_fields"),
        ("PMCAI,1000,0.1,0x2,0.3,0,0,-9.8", "bad_fields"),
        ("PMCAM,1000,0.1,0.2", "bad_fields"),
        ("PMCAX,1000,0.1,0.2", "unknown_sentence"),
    ],
)
def test_bad_sensor_sentences_rejected_by_reason(bad, reason):
    good = s("PMCAI,2000,0.1,0.2,0.3,0,0,-9.8")
    out, r = read(s(bad) + good)
    assert r.stats.rejected == {reason: 1}
    assert out == [ImuSample(2000, (0.1, 0.2, 0.3), (0.0, 0.0, -9.8))]


def test_sensor_sentences_decode_with_exponents_and_signs():
    out, r = read(s("PMCAI,7,1e-05,-2.5E+1,+.5,0,0,-9.80665") + s("PMCAM,8,0.21,-0.05,0.43"))
    assert out[0] == ImuSample(7, (1e-05, -25.0, 0.5), (0.0, 0.0, -9.80665))
    assert out[1].mag_b == (0.21, -0.05, 0.43)
    assert r.stats.used == {"MCAI": 1, "MCAM": 1}


def test_other_sentences_are_ignored_not_rejected():
    out, r = read(
        s("GPGSV,1,1,01,20,76,058,40") + s("PSTMVER,GNSSLIB_8.4.18.25_ARM") + s("GPTXT,01,01,02,hello")
    )
    assert out == [] and r.stats.total_rejected == 0
    assert r.stats.ignored == {"GSV": 1, "PSTMVER": 1, "TXT": 1}


# -- epochs ----------------------------------------------------------------------------------
def test_vtg_before_gga_belongs_to_the_next_epoch():
    # u-blox order with RMC off: VTG(k) GGA(k) GSA GLL(k)
    data = b""
    for k in range(1, 5):
        data += s(f"GNVTG,,T,,M,{k}.0,N,,K,A")
        data += s(f"GNGGA,00000{k}.00,4624.27601,N,11700.00000,W,1,12,0.6,100.0,M,-20.0,M,,")
        data += s("GNGSA,A,3,01,02,03,04,,,,,,,,,1.2,0.6,1.0")
        data += s(f"GNGLL,4624.27601,N,11700.00000,W,00000{k}.00,A,A")
    out, r = read(data)
    assert [round(f.speed_mps / KNOT, 9) for f in fixes(out)] == [1.0, 2.0, 3.0, 4.0]


def test_ten_hz_gga_with_one_hz_rmc_keeps_rmc_speed_in_whole_seconds():
    data = b""
    for sec in range(3):
        for tenth in range(10):
            t = f"00000{sec}.{tenth}0"
            data += s(f"GPGGA,{t},4807.038,N,01131.000,E,2,08,0.9,545.4,M,46.9,M,,")
            if tenth == 0:
                data += s(f"GPRMC,{t},A,4807.038,N,01131.000,E,00{sec + 1}.0,084.4,230394,003.1,W")
    out, r = read(data)
    fs = fixes(out)
    assert len(fs) == 30 and r.stats.events["late_sentence"] == 0
    whole = [f for i, f in enumerate(fs) if i % 10 == 0]
    assert [round(f.speed_mps / KNOT, 9) for f in whole] == [1.0, 2.0, 3.0]


def test_epoch_emitted_as_soon_as_its_expected_sentences_arrived():
    r = StreamReader(None)
    epoch = [
        "GNRMC,00000{k}.00,A,4807.038,N,01131.000,E,1.0,084.4,230394,,,A",
        "GNVTG,084.4,T,,M,1.0,N,1.9,K,A",
        "GNGGA,00000{k}.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
        "GNGSA,A,3,01,02,03,04,,,,,,,,,1.2,0.6,1.0",
        "GNGST,00000{k}.00,40,,,,2.3,3.5,4.1",
    ]
    got = []
    for k in range(1, 6):
        got.append(len(fixes(r.feed(b"".join(s(x.format(k=k)) for x in epoch)))))
    # epoch 1 closes when epoch 2's first sentence arrives; from epoch 2 on the expected set
    # is known and each epoch is emitted by its own last sentence
    assert got == [0, 2, 1, 1, 1]
    assert fixes(r.finish()) == [] and r.stats.events["late_sentence"] == 0

"""The MCAHRS wire format: exact sentence layouts and Recording -> bytes -> reader round trips."""

from __future__ import annotations

import math
from functools import reduce

import numpy as np
import pytest
from pynmeagps import NMEAReader
from pynmeagps.nmeatypes_core import VALCKSUM

from mcahrs.io import GNSS_ALT_MSL, encode_fix, encode_imu, encode_mag, encode_recording, read_bytes
from mcahrs.io.wire import recording_samples
from mcahrs.samples import (
    GNSS_DTYPE,
    GNSS_HAS_ALT,
    GNSS_HAS_COURSE,
    GNSS_HAS_VEL_D,
    GNSS_HAS_VEL_NE,
    GnssFix,
    ImuSample,
    MagSample,
    Recording,
    gnss_array,
    imu_array,
    mag_array,
)

ALL = GNSS_HAS_ALT | GNSS_HAS_VEL_NE | GNSS_HAS_VEL_D | GNSS_HAS_COURSE


def cs(body: str) -> str:
    return f"{reduce(lambda a, b: a ^ b, body.encode(), 0):02X}"


def test_imu_and_mag_sentence_layout():
    assert (
        encode_imu(ImuSample(123456, (0.01, -0.02, 0.5), (0.1, 0.0, -9.80665)))
        == (
            f"$PMCAI,123456,0.01,-0.02,0.5,0.1,0.0,-9.80665*{cs('PMCAI,123456,0.01,-0.02,0.5,0.1,0.0,-9.80665')}\r\n"
        ).encode()
    )
    assert (
        encode_mag(MagSample(7, (0.25, -0.125, 0.5)))
        == (f"$PMCAM,7,0.25,-0.125,0.5*{cs('PMCAM,7,0.25,-0.125,0.5')}\r\n").encode()
    )
    assert encode_imu(ImuSample(1, (1 / 3, 0, 0), (0, 0, 0)), float_digits=9).startswith(
        b"$PMCAI,1,0.333333333,"
    )


def test_fix_sentence_layout():
    fix = GnssFix(
        t_us=45_296_789_000,
        t_rx_us=45_296_800_000,
        lat_e7=-337_654_321,
        lon_e7=1_512_900_001,
        alt_mm=-12_345,
        vel_ned_mps=(1.5, -2.25, 0.125),
        speed_mps=2.704163456597992,
        course_rad=math.atan2(-2.25, 1.5) % (2 * math.pi),
        h_acc_m=1.25,
        v_acc_m=2.5,
        s_acc_mps=0.3,
        fix_type=4,
        num_sv=9,
        flags=ALL,
    )
    lines = encode_fix(fix).decode().split("\r\n")[:-1]
    bodies = [ln[1:-3] for ln in lines]
    assert all(ln[-3:] == "*" + cs(b) for ln, b in zip(lines, bodies, strict=True))
    # 33 deg 45.925926 min S (0.7654321 deg = 45.925926 min), 151 deg 17.400006 min E
    assert bodies[0] == "GNGGA,123456.789,3345.925926,S,15117.400006,E,2,09,,-12.345,M,0.000,M,,"
    sog, cog = f"{fix.speed_mps * 3600 / 1852:.4f}", f"{math.degrees(fix.course_rad):.4f}"
    assert (sog, cog) == ("5.2565", "303.6901")
    assert bodies[1] == f"GNRMC,123456.789,A,3345.925926,S,15117.400006,E,{sog},{cog},010100,,,D"
    assert bodies[2] == "GNGSA,A,3,,,,,,,,,,,,,,,"
    assert bodies[3] == "GNGST,123456.789,,,,,1.2500,1.2500,2.5000"
    assert bodies[4] == "PMCAV,123456.789,45296789000,1.500000,-2.250000,0.125000,0.300000"
    # the standard sentences are plain NMEA: pynmeagps parses them and they fit in 82 characters
    for ln in lines[:4]:
        assert NMEAReader.parse((ln + "\r\n").encode(), validate=VALCKSUM) is not None
        assert len(ln) + 2 <= 82


def test_encoder_refuses_what_the_wire_cannot_carry():
    fix = GnssFix(0, 0, 0, 0, 0, fix_type=0)
    with pytest.raises(ValueError, match="fix_type"):
        encode_fix(fix)
    with pytest.raises(ValueError, match="non-finite"):
        encode_imu(ImuSample(0, (math.nan, 0, 0), (0, 0, 0)))
    with pytest.raises(ValueError, match="negative"):
        encode_mag(MagSample(-1, (0, 0, 0)))


def random_recording(seed: int, with_imu: bool = True, n_fix: int = 20) -> Recording:
    rng = np.random.default_rng(seed)
    imu_t = 1_000_000 + np.arange(n_fix * 100) * 10_000  # 100 Hz
    imu = [
        ImuSample(int(t), tuple(rng.normal(0, 0.2, 3)), tuple(rng.normal(0, 1, 3) + [0, 0, -9.81]))
        for t in imu_t
    ]
    mag = [MagSample(int(t) + 3_000, tuple(rng.normal(0, 0.3, 3))) for t in imu_t[::4]]
    fixes = []
    for k in range(n_fix):
        t_rx = int(imu_t[k * 100 + int(rng.integers(0, 50))])
        vn, ve, vd = rng.normal(0, 8, 3)
        speed = math.hypot(vn, ve)
        ft = int(rng.integers(1, 7))
        flags = ALL | (GNSS_ALT_MSL if k % 3 == 0 else 0)
        fixes.append(
            GnssFix(
                t_us=t_rx - int(rng.integers(0, 200_000)),
                t_rx_us=t_rx,
                lat_e7=int(rng.integers(-900_000_000, 900_000_001)),
                lon_e7=int(rng.integers(-1_800_000_000, 1_800_000_001)),
                alt_mm=int(rng.integers(-500_000, 9_000_000)),
                vel_ned_mps=(vn, ve, vd),
                speed_mps=speed,
                course_rad=math.atan2(ve, vn) % (2 * math.pi),
                h_acc_m=float(rng.uniform(0.01, 30)),
                v_acc_m=float(rng.uniform(0.01, 50)),
                s_acc_mps=float(rng.uniform(0.01, 2)),
                fix_type=ft,
                num_sv=int(rng.integers(4, 40)),
                flags=flags,
            )
        )
    if not with_imu:
        return Recording("gnss-only", imu_array([]), gnss_array(fixes))
    return Recording("rt", imu_array(imu), gnss_array(fixes), mag_array(mag))


def assert_gnss_equal(a: np.ndarray, b: np.ndarray, exact_times: bool = True) -> None:
    assert len(a) == len(b)
    for name in ("lat_e7", "lon_e7", "alt_mm", "fix_type", "num_sv", "flags"):
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)  # exact on the wire
    if exact_times:
        np.testing.assert_array_equal(a["t_us"], b["t_us"])
        np.testing.assert_array_equal(a["t_rx_us"], b["t_rx_us"])
    # tolerances: the half-LSB of the wire's decimals (see wire.py), plus float noise
    np.testing.assert_allclose(a["vel_ned_mps"], b["vel_ned_mps"], atol=5.1e-7, rtol=0)
    np.testing.assert_allclose(a["s_acc_mps"], b["s_acc_mps"], atol=5.1e-7, rtol=0)
    np.testing.assert_allclose(a["speed_mps"], b["speed_mps"], atol=2.6e-5, rtol=0)
    np.testing.assert_allclose(a["course_rad"], b["course_rad"], atol=8.8e-7, rtol=0)
    np.testing.assert_allclose(a["h_acc_m"], b["h_acc_m"], atol=5.1e-5, rtol=0)
    np.testing.assert_allclose(a["v_acc_m"], b["v_acc_m"], atol=5.1e-5, rtol=0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_recording_round_trip_with_imu(seed):
    rec = random_recording(seed)
    back = read_bytes(encode_recording(rec))
    np.testing.assert_array_equal(back.imu, rec.imu)  # float64 bit-exact (repr on the wire)
    np.testing.assert_array_equal(back.mag, rec.mag)
    assert_gnss_equal(rec.gnss, back.gnss)
    st = back.meta["stats_obj"]
    assert st.total_rejected == 0 and back.meta["clock"] == "imu"


def test_round_trip_without_pmcav_uses_latency_and_rmc_velocity():
    rec = random_recording(5)
    g = rec.gnss.copy()
    g["t_us"] = g["t_rx_us"] - 65_000
    g["flags"] &= np.uint8(0xFF & ~GNSS_HAS_VEL_D)
    g["vel_ned_mps"][:, 2] = np.nan
    g["s_acc_mps"] = np.nan
    rec.gnss = g
    back = read_bytes(encode_recording(rec, pmcav=False), latency_us=65_000)
    # velocity now comes from RMC speed (4 decimal knots: 2.6e-5 m/s) and course (4 decimal
    # degrees: 8.7e-7 rad, times a speed up to ~40 m/s here)
    np.testing.assert_allclose(back.gnss["vel_ned_mps"][:, :2], g["vel_ned_mps"][:, :2], atol=8e-5, rtol=0)
    g["vel_ned_mps"][:, :2] = back.gnss["vel_ned_mps"][:, :2]
    assert_gnss_equal(g, back.gnss)


def test_gnss_only_round_trip_on_utc_clock():
    rec = random_recording(7, with_imu=False)
    g = rec.gnss.copy()
    g["t_us"] = 3_600_000_000 + np.arange(len(g)) * 200_000  # 5 Hz, ms-aligned (UTC has 3 decimals)
    g["t_rx_us"] = g["t_us"] + 40_000
    rec.gnss = g
    back = read_bytes(encode_recording(rec, pmcav=False, utc_offset_us=0), latency_us=40_000)
    assert back.meta["clock"] == "utc"
    g2 = g.copy()
    g2["flags"] &= np.uint8(0xFF & ~GNSS_HAS_VEL_D)
    g2["vel_ned_mps"][:, 2] = np.nan
    g2["s_acc_mps"] = np.nan
    g2["vel_ned_mps"][:, :2] = back.gnss["vel_ned_mps"][:, :2]
    assert_gnss_equal(g2, back.gnss)
    np.testing.assert_array_equal(back.meta["gnss_utc_tod_us"], g["t_us"])


def test_extreme_coordinates_round_trip_exactly():
    fixes = [
        GnssFix(
            t_us=1_000_000 * (k + 1), t_rx_us=1_000_000 * (k + 1), lat_e7=lat, lon_e7=lon, alt_mm=0, flags=0
        )
        for k, (lat, lon) in enumerate(
            [
                (900_000_000, 1_800_000_000),
                (-900_000_000, -1_800_000_000),
                (-1, 1),
                (1, -1),
                (0, 0),
                (123_456_789, -987_654_321),
            ]
        )
    ]
    rec = Recording("x", imu_array([]), gnss_array(fixes))
    back = read_bytes(encode_recording(rec))
    np.testing.assert_array_equal(back.gnss[["lat_e7", "lon_e7"]], rec.gnss[["lat_e7", "lon_e7"]])


def test_stream_order_puts_fix_after_imu_sample_of_its_t_rx():
    rec = random_recording(3, n_fix=3)
    order = recording_samples(rec)
    for i, x in enumerate(order):
        if isinstance(x, GnssFix):
            prev_imu = [y for y in order[:i] if isinstance(y, ImuSample)][-1]
            assert prev_imu.t_us == x.t_rx_us


def test_gnss_dtype_unchanged_by_reader():
    back = read_bytes(encode_recording(random_recording(4, n_fix=2)))
    assert back.gnss.dtype == GNSS_DTYPE

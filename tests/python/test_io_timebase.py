"""GNSS fixes on the IMU clock, UTC continuity checks, GNSS-only UTC time (mcahrs.io.timebase)."""

from __future__ import annotations

from functools import reduce

import pytest

from mcahrs.io import StreamReader
from mcahrs.io.stats import StreamStats
from mcahrs.io.timebase import TimeBase, wrap_day
from mcahrs.samples import GnssFix, ImuSample

DAY = 86_400_000_000


def s(body: str) -> bytes:
    c = reduce(lambda a, b: a ^ b, body.encode(), 0)
    return f"${body}*{c:02X}\r\n".encode()


def imu(t: int) -> bytes:
    return s(f"PMCAI,{t},0,0,0,0,0,-9.81")


def gga(hhmmss: str) -> bytes:
    return s(f"GPGGA,{hhmmss},4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")


def run(data: bytes, **kw) -> tuple[list, StreamReader]:
    r = StreamReader(None, **kw)
    return r.feed(data) + r.finish(), r


def fixes(out):
    return [x for x in out if isinstance(x, GnssFix)]


def hms(us: int) -> str:
    sec, frac = divmod(us % DAY, 1_000_000)
    h, sec = divmod(sec, 3600)
    m, sec = divmod(sec, 60)
    return f"{h:02d}{m:02d}{sec:02d}.{frac // 10_000:02d}"


def stream_1hz(n: int, utc0_us: int, imu_dt: int = 10_000, t0: int = 5_000_000, utc_steps=None) -> bytes:
    """IMU at 100 Hz; a GGA burst every second, sent right after the IMU sample at the second."""
    data = b""
    utc = utc0_us
    for k in range(n):
        for i in range(100):
            data += imu(t0 + (k * 100 + i) * imu_dt)
            if i == 0:
                data += gga(hms(utc))
        utc += utc_steps[k] if utc_steps else 1_000_000
    return data


def test_fix_time_is_last_imu_sample_before_burst_minus_latency():
    data = (
        imu(1000)
        + imu(2000)
        + gga("120000.00")
        + imu(3000)
        + s("GPRMC,120000.00,A,4807.038,N,01131.000,E,1.0,10.0,010120,,,A")
    )
    (f,) = fixes(run(data, latency_us=700)[0])
    assert (f.t_rx_us, f.t_us) == (2000, 1300)


def test_pmcav_time_replaces_latency_estimate():
    data = imu(1000) + gga("120000.00") + s("PMCAV,120000.00,950,1.0,2.0,0.5,0.2") + imu(2000)
    (f,) = fixes(run(data, latency_us=300)[0])
    assert (f.t_us, f.t_rx_us) == (950, 1000)
    assert f.vel_ned_mps == (1.0, 2.0, 0.5) and f.s_acc_mps == 0.2


def test_consistent_utc_and_imu_steps_raise_no_events():
    out, r = run(stream_1hz(5, 12 * 3600 * 1_000_000), latency_us=50_000)
    fs = fixes(out)
    assert [f.t_rx_us for f in fs] == [5_000_000 + k * 1_000_000 for k in range(5)]
    assert [f.t_rx_us - f.t_us for f in fs] == [50_000] * 5
    assert r.timebase.mode == "imu"
    assert not {"utc_backwards", "utc_step_mismatch", "utc_repeat"} & set(r.stats.events)


def test_utc_jumps_are_counted_and_fixes_still_use_imu_time():
    # steps after fixes 0..4: +1 s, +3 s (gap of 2 s of UTC in 1 s of IMU), -10 s (backwards), +1 s
    out, r = run(
        stream_1hz(5, 12 * 3600 * 1_000_000, utc_steps=[1_000_000, 3_000_000, -10_000_000, 1_000_000, 0])
    )
    fs = fixes(out)
    assert len(fs) == 5
    assert [f.t_us for f in fs] == [5_000_000 + k * 1_000_000 for k in range(5)]
    assert r.stats.events["utc_step_mismatch"] == 1
    assert r.stats.events["utc_backwards"] == 1
    # re-anchored: the step after the backwards jump is consistent again, so no more events
    assert sum(r.stats.events[k] for k in ("utc_backwards", "utc_step_mismatch")) == 2


def test_midnight_is_not_a_utc_jump_with_imu():
    out, r = run(stream_1hz(4, DAY - 2_000_000))
    assert len(fixes(out)) == 4
    assert not {"utc_backwards", "utc_step_mismatch"} & set(r.stats.events)


def test_gnss_only_time_is_microseconds_since_first_midnight_across_rollover():
    tods = ["235958.50", "235959.50", "000000.50", "000001.50"]
    out, r = run(b"".join(gga(t) for t in tods), latency_us=20_000)
    fs = fixes(out)
    t0 = (23 * 3600 + 59 * 60 + 58) * 1_000_000 + 500_000
    assert [f.t_us for f in fs] == [t0 + k * 1_000_000 for k in range(4)]
    assert [f.t_rx_us - f.t_us for f in fs] == [20_000] * 4
    assert r.timebase.mode == "utc" and "utc_backwards" not in r.stats.events


def test_gnss_only_utc_going_backwards_is_reanchored_monotonic():
    # bt451.log style: two excerpts, the second one earlier in the day
    tods = ["152507.00", "152507.50", "152508.00", "143306.00", "143306.50"]
    fs = fixes(run(b"".join(gga(t) for t in tods))[0])
    t = [f.t_us for f in fs]
    assert t[:3] == [55_507_000_000, 55_507_500_000, 55_508_000_000]
    assert t[3] == t[2] + 500_000  # previous t_us + last good step
    assert t[4] == t[3] + 500_000  # then UTC steps again from the new anchor
    assert all(b > a for a, b in zip(t[:-1], t[1:], strict=True))


def test_fix_begun_before_any_imu_sample_has_no_time_base():
    data = gga("120000.00") + imu(1000) + imu(2000) + gga("120001.00") + imu(3000)
    out, r = run(data)
    assert [f.t_rx_us for f in fixes(out)] == [2000]
    assert r.stats.rejected == {"no_time_base": 1}


def test_gnss_only_start_then_imu_switches_clock():
    data = gga("120000.00") + gga("120001.00") + imu(1000) + gga("120002.00") + imu(2000)
    out, r = run(data)
    fs = fixes(out)
    assert r.stats.events["clock_switch"] == 1
    assert fs[-1].t_rx_us == 1000 and fs[0].t_us == 12 * 3600 * 1_000_000


def test_imu_samples_backwards_rejected_but_clock_reset_accepted():
    data = imu(5_000_000) + imu(5_001_000) + imu(5_000_500) + imu(5_001_000) + imu(10) + imu(20)
    out, r = run(data)
    assert [x.t_us for x in out if isinstance(x, ImuSample)] == [5_000_000, 5_001_000, 10, 20]
    assert r.stats.rejected == {"time_backwards": 2}
    assert r.stats.events["imu_clock_reset"] == 1


def test_open_epoch_emitted_after_timeout_of_imu_time():
    r = StreamReader(None, epoch_timeout_us=300_000)
    out = r.feed(imu(1_000_000) + gga("120000.00") + imu(1_200_000))
    assert fixes(out) == []
    out = r.feed(imu(1_400_000))
    assert len(fixes(out)) == 1  # no next epoch needed: 400 ms of IMU time passed


def test_wrap_day_and_argument_checks():
    assert wrap_day(-DAY + 1_000_000) == 1_000_000
    assert wrap_day(DAY - 1_000_000) == -1_000_000
    with pytest.raises(ValueError, match="clock"):
        TimeBase(StreamStats(), clock="gps")
    with pytest.raises(ValueError, match="latency_us"):
        TimeBase(StreamStats(), latency_us=-1)

"""Seeded garbage between good sentences: no crash, every good sentence used, garbage counted."""

from __future__ import annotations

import io
import math
from functools import reduce

import numpy as np
import pytest

from mcahrs.io import StreamReader, encode_fix, encode_imu, encode_mag
from mcahrs.samples import (
    GNSS_HAS_ALT,
    GNSS_HAS_COURSE,
    GNSS_HAS_VEL_NE,
    GnssFix,
    ImuSample,
    MagSample,
    recording_from_samples,
)


def s(body: str) -> bytes:
    c = reduce(lambda a, b: a ^ b, body.encode(), 0)
    return f"${body}*{c:02X}\r\n".encode()


class ChunkedStream(io.RawIOBase):
    """A stream that hands out random-sized chunks, like a serial port does."""

    def __init__(self, data: bytes, rng: np.random.Generator) -> None:
        self.data, self.pos, self.rng = data, 0, rng

    def readable(self) -> bool:
        return True

    def read(self, n: int = -1) -> bytes:
        k = int(self.rng.integers(1, 300))
        out = self.data[self.pos : self.pos + min(k, n if n > 0 else k)]
        self.pos += len(out)
        return out


def good_lines(rng: np.random.Generator, seconds: int = 6) -> list[bytes]:
    """100 Hz IMU, 25 Hz magnetometer, 1 Hz GNSS; each item is one or more complete lines."""
    out = []
    for k in range(seconds * 100):
        t = 2_000_000 + k * 10_000
        out.append(encode_imu(ImuSample(t, tuple(rng.normal(0, 0.1, 3)), tuple(rng.normal(0, 1, 3)))))
        if k % 4 == 1:
            out.append(encode_mag(MagSample(t + 500, tuple(rng.normal(0, 0.3, 3)))))
        if k % 100 == 3:
            fix = GnssFix(
                t_us=t,
                t_rx_us=t,
                lat_e7=int(rng.integers(-9e8, 9e8)),
                lon_e7=int(rng.integers(-18e8, 18e8)),
                alt_mm=int(rng.integers(0, 10**6)),
                vel_ned_mps=(1.0, 2.0, math.nan),
                speed_mps=math.hypot(1, 2),
                course_rad=math.atan2(2, 1),
                h_acc_m=1.5,
                v_acc_m=3.0,
                fix_type=3,
                num_sv=10,
                flags=GNSS_HAS_ALT | GNSS_HAS_VEL_NE | GNSS_HAS_COURSE,
            )
            out.extend(
                ln + b"\r\n" for ln in encode_fix(fix, utc_offset_us=43_200_000_000).split(b"\r\n")[:-1]
            )
    return out


def printable_junk(rng, n: int) -> bytes:
    return bytes(rng.integers(0x20, 0x7F, n).astype(np.uint8)).replace(b"$", b"%").replace(b"!", b"%")


def binary_junk(rng, n: int) -> bytes:
    # any byte but '#': a '#' right after a line end would start a comment line (a file-format
    # rule: skip_comments=True is the default); the comment-vs-binary rule has its own test
    return bytes(rng.integers(0, 256, n).astype(np.uint8)).replace(b"#", b"\x00")


GARBAGE_KINDS = (
    "binary",
    "truncated",
    "bad_checksum",
    "no_checksum",
    "field_count",
    "empty",
    "nan",
    "long",
    "doubled",
)


def garbage(rng, kind: str, good: bytes) -> tuple[bytes, str | None]:
    """(bytes to insert before ``good``, reject reason they must produce or None if not exact)."""
    if kind == "binary":
        return binary_junk(rng, int(rng.integers(1, 400))), None
    if kind == "truncated":  # a prefix of a good sentence, cut off by the next '$'
        return good[: int(rng.integers(2, len(good) - 5))], "truncated"
    if kind == "bad_checksum":
        body = good[1 : good.index(b"*")]
        c = reduce(lambda a, b: a ^ b, body, 0) ^ int(rng.integers(1, 256))
        return b"$" + body + b"*%02X\r\n" % c, "bad_checksum"
    if kind == "no_checksum":
        return good[: good.index(b"*")] + b"\r\n", "no_checksum"
    if kind == "field_count":
        return s("PMCAI,5,0.1,0.2,0.3,0.4"), "bad_fields"
    if kind == "empty":
        return s("PMCAI,5,0.1,,0.3,0.4,0.5,0.6"), "empty_fields"
    if kind == "nan":
        return s("PMCAI,5,0.1,nan,0.3,0.4,0.5,0.6"), "nonfinite"
    if kind == "long":  # a 10 kB line
        return b"$GPGGA," + printable_junk(rng, 10_000) + b"\r\n", "too_long"
    return b"$", None  # "doubled": '$$' before a good sentence, not a rejection


@pytest.mark.parametrize("seed", range(6))
def test_garbage_is_counted_and_every_good_sentence_used(seed):
    rng = np.random.default_rng(seed)
    lines = good_lines(rng)
    clean = b"".join(lines)
    dirty, injected, n_garbage = [], {}, 0
    for ln in lines:
        if rng.random() < 0.3:
            kind = GARBAGE_KINDS[int(rng.integers(0, len(GARBAGE_KINDS)))]
            g, reason = garbage(rng, kind, ln)
            dirty.append(g)
            n_garbage += 1
            if reason:
                injected[reason] = injected.get(reason, 0) + 1
        dirty.append(ln)
    dirty_bytes = b"".join(dirty)

    ref = StreamReader(io.BytesIO(clean), latency_us=20_000)
    ref_rec = recording_from_samples("clean", ref)
    got = StreamReader(ChunkedStream(dirty_bytes, rng), latency_us=20_000)
    rec = recording_from_samples("dirty", got)

    assert ref.stats.total_rejected == 0
    n_good = sum(ln.count(b"\r\n") for ln in lines)
    assert sum(got.stats.sentences.values()) >= n_good
    # every good sentence came out: same samples as without garbage
    assert len(rec.imu) == len(ref_rec.imu) == 600 and len(rec.gnss) == len(ref_rec.gnss) == 6
    np.testing.assert_array_equal(rec.imu, ref_rec.imu)
    np.testing.assert_array_equal(rec.mag, ref_rec.mag)
    for name in rec.gnss.dtype.names:  # field by field: NaN == NaN for plain float arrays
        np.testing.assert_array_equal(rec.gnss[name], ref_rec.gnss[name], err_msg=name)
    # every injected bad line was counted under its reason ('binary' junk may add to any of them)
    for reason, n in injected.items():
        assert got.stats.rejected[reason] >= n, reason
    for reason in ("bad_fields", "empty_fields", "nonfinite"):
        assert got.stats.rejected[reason] == injected.get(reason, 0)  # these cannot come from junk
    assert got.stats.garbage_bytes > 0 and n_garbage > 50


def test_garbage_only_stream_yields_nothing_and_does_not_crash():
    rng = np.random.default_rng(99)
    data = binary_junk(rng, 200_000) + b"$" * 50 + printable_junk(rng, 50_000)
    r = StreamReader(io.BytesIO(data))
    assert list(r) == []
    assert r.stats.bytes_read == len(data)


def test_imu_sentence_with_garbage_value_does_not_stop_the_stream():
    data = b"".join(
        s(f"PMCAI,{t},0,0,0,0,0,{v}") for t, v in [(1, "-9.8"), (2, "1e999"), (3, "x"), (4, "-9.8")]
    )
    r = StreamReader(io.BytesIO(data))
    assert [x.t_us for x in r] == [1, 4]
    assert r.stats.rejected == {"nonfinite": 1, "bad_fields": 1}

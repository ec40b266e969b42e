"""The core's own float32 exp, expm1 and atan2 (mca_math.h) against float64 NumPy: error in
ulp over dense grids and random samples of the whole float32 domain, and C's special values.

ulp = the spacing of float32 at the float64 reference value (2^-149 below the normal range).
The grids are fixed and the samples seeded, so each figure below is a measurement, repeated
exactly by every run; the bounds asserted are those figures rounded up to 0.01 ulp, so a
change that costs accuracy anywhere shows up here. Coefficients: scripts/gen_libm_poly.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mcahrs._mcahrs_cffi import lib

# Measured max |error| in ulp (the figures of mca_math.h), per function and region.
MAX_ULP = {
    "expm1 |x| <= ln2/2": 0.83,  # 0.826: the CS filter's expm1f(-alpha T), alpha T down to 1e-7
    "expm1 elsewhere": 0.91,  # 0.907
    "exp": 0.80,  # 0.7999 (normal results)
    "atan2": 1.49,  # 1.484: n/d rounding just above a power of two, where atan(n/d) is one binade lower
}

F32_MAX = float(np.finfo(np.float32).max)


def ulp(v: np.ndarray) -> np.ndarray:
    _, e = np.frexp(np.abs(v))
    return np.maximum(np.ldexp(1.0, e - 24), 2.0**-149)


def ulp_err(c: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.abs(c - ref) / ulp(ref)


def call(f, *args: np.ndarray) -> np.ndarray:
    return np.array([f(*a) for a in zip(*(x.astype(np.float64).tolist() for x in args), strict=True)])


def floats_between(lo: float, hi: float, step: int = 1) -> np.ndarray:
    """Every step-th positive float32 in [lo, hi] (by bit pattern: dense in every binade)."""
    a, b = np.array([lo, hi], np.float32).view(np.int32)
    return np.arange(a, b + 1, step, dtype=np.int32).view(np.float32)


def random_floats(rng: np.random.Generator, n: int, lo: float, hi: float) -> np.ndarray:
    """n positive float32 uniform in bit pattern over [lo, hi]: every binade equally."""
    a, b = np.array([lo, hi], np.float32).view(np.int32)
    return rng.integers(a, b, n, endpoint=True, dtype=np.int32).view(np.float32)


def test_expm1f_small_arguments_to_0_83_ulp():
    # every 16th float of +-[1e-10, ln2/2] (about 1.2 M values, so every ~1.6e-6 relative step),
    # and all floats of +-[1e-7, 1.2e-7] (the CS filter's smallest alpha T)
    x = np.concatenate([floats_between(1e-10, 0.34657359, 16), floats_between(1e-7, 1.2e-7)])
    x = np.concatenate([x, -x])
    e = ulp_err(call(lib.mca_expm1f, x), np.expm1(x.astype(np.float64)))
    assert e.max() <= MAX_ULP["expm1 |x| <= ln2/2"], (e.max(), x[np.argmax(e)])
    # below 2^-24 the result is x itself: exact
    tiny = random_floats(np.random.default_rng(1), 20000, 1e-45, 5.9e-8)
    np.testing.assert_array_equal(call(lib.mca_expm1f, tiny), tiny.astype(np.float64))


def test_expm1f_whole_domain_to_0_91_ulp():
    rng = np.random.default_rng(2)
    pos = np.concatenate([floats_between(0.34657359, 88.72, 64), random_floats(rng, 200000, 0.3465, 88.72)])
    neg = np.concatenate([floats_between(0.34657359, 18.0, 64), random_floats(rng, 200000, 0.3465, 30.0)])
    x = np.concatenate([pos, -neg])
    e = ulp_err(call(lib.mca_expm1f, x), np.expm1(x.astype(np.float64)))
    assert e.max() <= MAX_ULP["expm1 elsewhere"], (e.max(), x[np.argmax(e)])


def test_expf_whole_domain_to_0_80_ulp():
    rng = np.random.default_rng(3)
    mag = np.concatenate([floats_between(1e-10, 88.72, 128), random_floats(rng, 300000, 1e-30, 88.72)])
    x = np.concatenate([mag, -mag[mag < 87.33]])  # normal results; subnormal ones below
    e = ulp_err(call(lib.mca_expf, x), np.exp(x.astype(np.float64)))
    assert e.max() <= MAX_ULP["exp"], (e.max(), x[np.argmax(e)])
    # subnormal results (x in [-103.97, -87.34]): within an ulp of the subnormal value (2^-149)
    x = -random_floats(rng, 50000, 87.34, 103.9)
    e = ulp_err(call(lib.mca_expf, x), np.exp(x.astype(np.float64)))
    assert e.max() <= 1.0, (e.max(), x[np.argmax(e)])


def test_atan2f_whole_plane_to_1_49_ulp():
    rng = np.random.default_rng(4)
    n = 150000
    sign = lambda: np.where(rng.random(n) < 0.5, -1.0, 1.0).astype(np.float32)  # noqa: E731
    # any two finite floats (bit patterns: all magnitudes, including subnormals)
    y = [random_floats(rng, n, 1e-45, F32_MAX) * sign()]
    x = [random_floats(rng, n, 1e-45, F32_MAX) * sign()]
    # every direction at unit-ish length: a dense grid of angles, and each reduction band
    th = np.linspace(-np.pi, np.pi, 400001)
    y.append(np.sin(th).astype(np.float32))
    x.append(np.cos(th).astype(np.float32))
    ratio, d = rng.uniform(0.0, 1.0, n), rng.uniform(0.1, 10.0, n)
    # just above n/d = 1/4: n/d rounded in its binade, atan(n/d) < 1/4 one binade below
    ratio_q = np.linspace(0.25, 0.2555, n)
    y.append((ratio_q * d).astype(np.float32))
    x.append(d.astype(np.float32))
    for sy, sx in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        y += [(sy * ratio * d).astype(np.float32), (sy * d).astype(np.float32)]
        x += [(sx * d).astype(np.float32), (sx * ratio * d).astype(np.float32)]
    y, x = np.concatenate(y), np.concatenate(x)
    e = ulp_err(call(lib.mca_atan2f, y, x), np.arctan2(y.astype(np.float64), x.astype(np.float64)))
    assert e.max() <= MAX_ULP["atan2"], (e.max(), y[np.argmax(e)], x[np.argmax(e)])


def same(a: float, b: float) -> bool:
    """Equal as floats, NaN equal to NaN, zeros by sign."""
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)


@pytest.mark.parametrize(
    ("x", "expm1", "exp"),
    [
        (math.nan, math.nan, math.nan),
        (math.inf, math.inf, math.inf),
        (-math.inf, -1.0, 0.0),
        (88.8, math.inf, math.inf),  # overflow
        (F32_MAX, math.inf, math.inf),
        (-18.0, -1.0, float(np.float32(math.exp(-18.0)))),
        (-30.0, -1.0, float(np.float32(math.exp(-30.0)))),  # expm1f(-large) is exactly -1
        (-104.0, -1.0, 0.0),  # underflow
        (-F32_MAX, -1.0, 0.0),
        (0.0, 0.0, 1.0),
        (-0.0, -0.0, 1.0),
        (1e-45, 1e-45, 1.0),
        (-1e-45, -1e-45, 1.0),
    ],
)
def test_exp_special_values(x, expm1, exp):
    assert same(lib.mca_expm1f(x), float(np.float32(expm1)))
    assert same(lib.mca_expf(x), float(np.float32(exp)))


SPECIAL = [0.0, -0.0, 1e-45, -1e-45, 1.0, -1.0, 3e38, -3e38, math.inf, -math.inf, math.nan]


@pytest.mark.parametrize("y", SPECIAL)
def test_atan2f_special_values_as_c(y):
    # C99 F.9.1.4 for zeros and infinities (math.atan2 follows it), NaN in gives NaN out
    for x in SPECIAL:
        ref = float(np.float32(math.atan2(y, x))) if not (math.isnan(x) or math.isnan(y)) else math.nan
        got = lib.mca_atan2f(y, x)
        ok = same(got, ref) or abs(got - math.atan2(y, x)) <= ulp(np.array(math.atan2(y, x)))
        assert ok, (y, x, got, ref)

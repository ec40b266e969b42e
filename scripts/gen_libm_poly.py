"""Fit the minimax polynomials of the core's own expf/expm1f and atan2f (c_core/src/mca_math.c).

Run: python scripts/gen_libm_poly.py   (prints the float32 coefficients and their error)

Both functions are split into an exact leading part and a small correction, so the
polynomial only has to be accurate relative to the whole result:

* expm1(r) = r + r^2/2 + r^3 Q(r),      |r| <= ln(2)/2 (after r = x - k ln 2)
* atan(u)  = u + u^3 A(u^2),            |u| <= 7/16 (after the reduction of atan2)

Q and A are fitted by the Remez exchange with the weight that turns their error into the
relative error of expm1(r) and atan(u); the references are the Taylor series, summed in
float64 far past their float64 precision. The coefficients are then rounded to float32
(what the C uses) and the relative error of the rounded polynomial is printed: that is the
approximation error alone (degree 3 for comparison; the C uses degree 4 of both), well below
the float32 rounding the C adds on top (the measured end-to-end ulp figures are in
tests/python/test_math.py).
"""

from __future__ import annotations

import math

import numpy as np

R_EXP = 0.5 * math.log(2.0) * (1.0 + 1e-6)  # |r| after rounding k to the nearest integer
U_ATAN = 7.0 / 16.0


def q_exact(r: np.ndarray) -> np.ndarray:
    """(expm1(r) - r - r^2/2) / r^3 = sum_j r^j / (j+3)!"""
    return sum(r**j / math.factorial(j + 3) for j in range(25))


def w_exp(r: np.ndarray) -> np.ndarray:
    """|r^3 / expm1(r)|: error in Q times this = relative error of expm1."""
    with np.errstate(invalid="ignore"):
        return np.abs(r**3 / (r + r * r * (0.5 + r * q_exact(r))))


def a_exact(z: np.ndarray) -> np.ndarray:
    """(atan(u) - u) / u^3 = sum_j (-1)^(j+1) z^j / (2j+3), z = u^2."""
    return sum((-1.0) ** (j + 1) * z**j / (2 * j + 3) for j in range(60))


def w_atan(z: np.ndarray) -> np.ndarray:
    """u^3 / atan(u) = z / (1 + z A(z)): error in A times this = relative error of atan."""
    return z / (1.0 + z * a_exact(z))


def remez(f, w, lo: float, hi: float, deg: int, iters: int = 30) -> np.ndarray:
    """Coefficients (ascending) of the degree-deg polynomial p minimising max |w (p - f)|."""
    grid = np.linspace(lo, hi, 200001)
    grid = grid[w(grid) > 0.0]  # a zero weight (expm1 at r = 0, atan at z = 0) constrains nothing
    fg, wg = f(grid), w(grid)
    n = deg + 2
    ref = grid[np.linspace(0, len(grid) - 1, n).astype(int)]
    c = np.zeros(deg + 1)
    for _ in range(iters):
        a = np.vander(ref, deg + 1, increasing=True)
        sgn = (-1.0) ** np.arange(n) / w(ref)
        sol = np.linalg.solve(np.column_stack([a, sgn]), f(ref))
        c = sol[:-1]
        err = wg * (np.polynomial.polynomial.polyval(grid, c) - fg)
        # one extremum per run of equal sign, then the n largest consecutive alternating ones
        starts = np.concatenate([[0], np.flatnonzero(np.diff(np.sign(err)) != 0) + 1, [len(grid)]])
        runs = zip(starts[:-1], starts[1:], strict=True)
        idx = np.array([a0 + int(np.argmax(np.abs(err[a0:b0]))) for a0, b0 in runs])
        while len(idx) > n:  # drop the smaller end
            idx = idx[1:] if abs(err[idx[0]]) < abs(err[idx[-1]]) else idx[:-1]
        if len(idx) < n:
            break
        ref = grid[idx]
    return c


def report(name: str, c32: np.ndarray, f, w, lo: float, hi: float) -> None:
    grid = np.linspace(lo, hi, 400001)
    grid = grid[w(grid) > 0.0]
    c = c32.astype(np.float64)
    rel = np.max(np.abs(w(grid) * (np.polynomial.polynomial.polyval(grid, c) - f(grid))))
    print(f"{name}: degree {len(c) - 1}, max relative error {rel:.2e} = {rel / 2.0**-24:.3f} ulp(2^-24)")
    for k, v in enumerate(c32):
        print(f"    c{k} = {float(v):.9e}f  /* {float(v).hex()} */")


def main() -> None:
    for deg in (3, 4):
        c = remez(q_exact, w_exp, -R_EXP, R_EXP, deg).astype(np.float32)
        report("expm1 Q(r)", c, q_exact, w_exp, -R_EXP, R_EXP)
    for deg in (3, 4):
        c = remez(a_exact, w_atan, 0.0, U_ATAN**2, deg).astype(np.float32)
        report("atan A(z)", c, a_exact, w_atan, 0.0, U_ATAN**2)


if __name__ == "__main__":
    main()

"""Smooth scalar profiles of time with exact derivatives and integrals.

Every truth trajectory of :mod:`mcahrs.sim` is built from :class:`Channel` objects. A channel
is a constant plus a sum of smooth steps, integrated ``order`` times (0 or 1)::

    f(t) = c0 + sum_i A_i * I^order S((t - t0_i) / T_i)

``S`` is the septic "smootherstep" ``s(x) = 35 x^4 - 84 x^5 + 70 x^6 - 20 x^7`` on
``[0, 1]`` (0 before, 1 after): its first three derivatives vanish at both ends, so a
channel is C3 in its top quantity. An order-1 channel whose steps are acceleration (or
turn-rate) pulses therefore has continuous acceleration, jerk and jerk rate: a multirotor
tilt follows acceleration and its body rate follows jerk, so both stay continuous.

Value and derivatives are exact polynomials (no numerical differentiation), evaluated with
NumPy over whole time arrays. Cost: O(N) for the steps already finished (cumulative sums)
plus the samples inside each step's ramp (one vectorised slice per step).
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import Polynomial

__all__ = ["Channel", "smoothstep"]

_S = Polynomial([0.0, 0.0, 0.0, 0.0, 35.0, -84.0, 70.0, -20.0])
_DERIV = [_S]  # _DERIV[k] = k-th derivative of s(x)
for _ in range(4):
    _DERIV.append(_DERIV[-1].deriv())
_INTEG = [_S]  # _INTEG[k] = k-fold integral of s(x) from 0
for _ in range(2):
    _INTEG.append(_INTEG[-1].integ(lbnd=0.0))
_INTEG_AT_1 = [float(p(1.0)) for p in _INTEG]  # [1, 1/2, ...]


def smoothstep(x: np.ndarray | float) -> np.ndarray:
    """The septic smoothstep: 0 for x <= 0, 1 for x >= 1, C3 in between."""
    x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
    return _S(x)


class Channel:
    """A smooth scalar profile (see the module docstring).

    ``order`` 0: the value is a sum of smooth steps (e.g. a flight-path angle).
    ``order`` 1: the value is the integral of a sum of smooth steps (e.g. a speed whose
    derivative, the acceleration, is made of smooth trapezoid pulses).
    """

    def __init__(self, order: int, c0: float = 0.0) -> None:
        if order not in (0, 1):
            raise ValueError(f"Channel order must be 0 or 1, got {order}")
        self.order = order
        self.c0 = float(c0)
        self._terms: list[tuple[float, float, float]] = []

    def add_step(self, t0_s: float, ramp_s: float, amp: float) -> None:
        """Add ``amp`` times a smooth step rising over ``[t0_s, t0_s + ramp_s]``."""
        if not ramp_s > 0.0:
            raise ValueError(f"ramp_s must be > 0, got {ramp_s}")
        if amp != 0.0:
            self._terms.append((float(t0_s), float(ramp_s), float(amp)))

    def add_pulse(self, t_on_s: float, t_off_s: float, ramp_s: float, amp: float) -> None:
        """Add a smooth trapezoid of height ``amp``: rises from ``t_on_s``, falls from ``t_off_s``.

        Both ramps last ``ramp_s``; the pulse's integral is exactly ``amp * (t_off_s - t_on_s)``
        (each ramp is point-symmetric about its middle).
        """
        if t_off_s < t_on_s:
            raise ValueError(f"pulse falls ({t_off_s}) before it rises ({t_on_s})")
        self.add_step(t_on_s, ramp_s, amp)
        self.add_step(t_off_s, ramp_s, -amp)

    @property
    def last_change_s(self) -> float:
        """Time after which the top quantity (the steps' sum) no longer changes."""
        return max((t0 + tr for t0, tr, _ in self._terms), default=0.0)

    def eval(self, t_s: np.ndarray, deriv: int = 0) -> np.ndarray:
        """``deriv``-th time derivative (0..4) of the profile at sorted times ``t_s`` (s)."""
        t = np.asarray(t_s, np.float64)
        if t.ndim != 1:
            raise ValueError("t_s must be 1-D")
        if t.size > 1 and t[-1] < t[0]:  # full check too costly at millions of samples: callers sort
            raise ValueError("t_s must be sorted")
        if not 0 <= deriv <= 4:
            raise ValueError(f"deriv must be 0..4, got {deriv}")
        out = np.full(t.shape, self.c0 if deriv == 0 else 0.0)
        if not self._terms:
            return out
        terms = np.asarray(self._terms)
        t0, tr, amp = terms[:, 0], terms[:, 1], terms[:, 2]
        end = t0 + tr
        m = self.order - deriv  # integral level of s(x) seen by this derivative (< 0: derivative)
        poly = _INTEG[m] if m >= 0 else _DERIV[-m]
        scale = tr**m  # d/dt = (1/T) d/dx, integral dt = T integral dx
        lo = np.searchsorted(t, t0, side="left")
        hi = np.searchsorted(t, end, side="left")
        for i in np.flatnonzero(hi > lo):
            x = (t[lo[i] : hi[i]] - t0[i]) / tr[i]
            out[lo[i] : hi[i]] += amp[i] * scale[i] * poly(x)
        if m >= 0:
            # After a step's ramp (x >= 1): m = 0 -> 1;  m = 1 -> T * P1(1) + (t - end).
            # Accumulated as coefficients of a polynomial in absolute t (degree m <= 1).
            n = t.size
            c0 = amp if m == 0 else amp * (tr * _INTEG_AT_1[1] - end)
            out += np.cumsum(np.bincount(hi, weights=c0, minlength=n + 1))[:n]
            if m == 1:
                out += np.cumsum(np.bincount(hi, weights=amp, minlength=n + 1))[:n] * t
        return out

    def at(self, t_s: float, deriv: int = 0) -> float:
        """Scalar convenience wrapper of :meth:`eval`."""
        return float(self.eval(np.array([t_s]), deriv)[0])

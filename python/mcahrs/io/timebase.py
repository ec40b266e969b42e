"""Put GNSS fixes on the IMU clock.

NMEA gives a fix's UTC time of day only; everything MCAHRS computes runs on the IMU clock
(integer microseconds, the ``t_us`` of ``$PMCAI``). The rule:

IMU clock (the stream carries IMU samples)
    * ``t_rx_us`` = ``t_us`` of the last IMU sample that arrived before the **first**
      sentence of the fix's epoch (arrival order in the stream). The first sentence is used,
      not the last, because the length of a receiver's burst varies with the sentences and
      the baud rate, while the start of the burst follows the fix at a steady delay.
    * ``t_us`` = ``t_rx_us - latency_us`` (``latency_us``: the receiver's output latency,
      configured, default 0), unless the epoch has a ``$PMCAV`` with a ``t_us`` field:
      then that value (the sender knew the validity time, e.g. from PPS) is ``t_us``.
    * A fix whose epoch began before any IMU sample has no time base: it is rejected as
      ``no_time_base``.
    * UTC continuity check against the previous fix: ``d_utc`` (wrapped into +-12 h, so
      midnight is no jump) is compared with ``d_imu`` = the difference of the ``t_rx_us``.
      ``d_utc < 0`` -> event ``utc_backwards``, ``d_utc == 0`` -> ``utc_repeat``,
      ``|d_utc - d_imu| > utc_tol_us`` (default 200 ms: arrival jitter of a burst at low
      baud) -> ``utc_step_mismatch``. Re-anchoring: each fix is the reference for the next
      check, so one glitch is counted once, and a receiver clock step or a gap does not make
      every later fix fail. The fix is still emitted (its time comes from the IMU clock,
      which the glitch did not affect).

UTC clock (GNSS-only capture, no IMU sentences)
    * ``t_us`` = microseconds since midnight (UTC) of the first fix's day: the first fix gets
      its time of day; each later fix gets the previous ``t_us`` plus ``d_utc`` (wrapped into
      +-12 h, so 23:59:59 -> 00:00:00 is +1 s and time runs on past 86 400 s).
    * Re-anchoring: when UTC goes backwards or repeats (``utc_backwards``/``utc_repeat``, e.g.
      excerpts joined in one file), the fix gets the previous ``t_us`` plus the last good
      step (1 s if none yet) and becomes the new anchor, so ``t_us`` stays increasing.
    * ``t_rx_us`` = ``t_us + latency_us``. A ``$PMCAV`` ``t_us`` replaces ``t_us`` here too.

Choice of clock (``clock="auto"``, the default): decided at the first complete fix, IMU if
an IMU sample has been seen by then, UTC otherwise. If IMU samples show up later in a UTC
stream, the clock switches to IMU from the next fix on (event ``clock_switch``).
``clock="imu"`` or ``"utc"`` forces one.

IMU samples themselves keep their own ``t_us``. One that is not newer than the previous
one is rejected as ``time_backwards``, unless it is more than ``imu_reset_us`` (default 1 s)
older: then the sensor clock was reset (event ``imu_clock_reset``) and it is accepted.
Magnetometer samples are checked the same way against the previous magnetometer sample.
"""

from __future__ import annotations

from .stats import StreamStats

DAY_US = 86_400_000_000
HALF_DAY_US = DAY_US // 2


def wrap_day(d_us: int) -> int:
    """A time-of-day difference wrapped into [-12 h, +12 h)."""
    return (d_us + HALF_DAY_US) % DAY_US - HALF_DAY_US


class SensorClock:
    """Monotonicity check of one sensor's timestamps (IMU or magnetometer)."""

    def __init__(self, stats: StreamStats, reset_us: int) -> None:
        self.stats = stats
        self.reset_us = reset_us
        self.last: int | None = None

    def accept(self, t_us: int) -> bool:
        """True if the sample is to be used; counts the reason otherwise."""
        if self.last is not None and t_us <= self.last:
            if self.last - t_us > self.reset_us:
                self.stats.events["imu_clock_reset"] += 1
            else:
                return False
        self.last = t_us
        return True


class TimeBase:
    """Maps GNSS epochs onto the IMU clock (rules in the module docstring)."""

    def __init__(
        self,
        stats: StreamStats,
        latency_us: int = 0,
        clock: str = "auto",
        utc_tol_us: int = 200_000,
        imu_reset_us: int = 1_000_000,
    ) -> None:
        if clock not in ("auto", "imu", "utc"):
            raise ValueError(f"clock={clock!r}: expected 'auto', 'imu' or 'utc'")
        if latency_us < 0:
            raise ValueError(f"latency_us={latency_us} must be >= 0")
        self.stats = stats
        self.latency_us = int(latency_us)
        self.mode: str | None = None if clock == "auto" else clock
        self.utc_tol_us = int(utc_tol_us)
        self.imu = SensorClock(stats, imu_reset_us)
        self.mag = SensorClock(stats, imu_reset_us)
        self._prev_tod: int | None = None
        self._prev_t_rx: int | None = None
        self._prev_t_utc: int | None = None  # UTC-clock t_us of the previous fix
        self._step_us = 1_000_000

    @property
    def last_imu_t_us(self) -> int | None:
        return self.imu.last

    def _check_utc_step(self, tod_us: int) -> int | None:
        """Count UTC continuity events against the previous fix; return wrapped d_utc."""
        if self._prev_tod is None:
            return None
        d = wrap_day(tod_us - self._prev_tod)
        if d < 0:
            self.stats.events["utc_backwards"] += 1
        elif d == 0:
            self.stats.events["utc_repeat"] += 1
        return d

    def fix_times(self, tod_us: int, imu_t_us: int | None, pmcav_t_us: int | None) -> tuple[int, int] | None:
        """(t_us, t_rx_us) for an epoch, or None if it cannot be timed (caller counts it).

        ``imu_t_us``: IMU time of the last IMU sample before the epoch's first sentence.
        """
        if self.mode is None:
            self.mode = "imu" if self.imu.last is not None else "utc"
        elif self.mode == "utc" and self.imu.last is not None and imu_t_us is not None:
            self.stats.events["clock_switch"] += 1
            self.mode = "imu"
            self._prev_tod = self._prev_t_rx = None
        if self.mode == "imu":
            if imu_t_us is None:
                return None
            d = self._check_utc_step(tod_us)
            if d is not None and d > 0 and self._prev_t_rx is not None:
                if abs(d - (imu_t_us - self._prev_t_rx)) > self.utc_tol_us:
                    self.stats.events["utc_step_mismatch"] += 1
            self._prev_tod, self._prev_t_rx = tod_us, imu_t_us
            t_us = pmcav_t_us if pmcav_t_us is not None else imu_t_us - self.latency_us
            return t_us, imu_t_us
        # UTC clock
        d = self._check_utc_step(tod_us)
        if d is None or self._prev_t_utc is None:
            t_utc = tod_us
        elif d > 0:
            t_utc = self._prev_t_utc + d
            self._step_us = d
        else:
            t_utc = self._prev_t_utc + self._step_us  # re-anchor after UTC went back or repeated
        self._prev_tod, self._prev_t_utc = tod_us, t_utc
        t_us = pmcav_t_us if pmcav_t_us is not None else t_utc
        return t_us, t_us + self.latency_us

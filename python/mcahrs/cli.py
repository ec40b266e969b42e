"""The ``mcahrs`` command line: demo, simulate, replay, bench (and evaluate/convert).

    mcahrs demo [--out DIR]                         simulate, stream, replay, compare, plot
    mcahrs simulate --scenario car_accel_brake --out car.nmea
    mcahrs replay car.nmea --preset ground --plot car.png --csv car.csv
    mcahrs bench --port /dev/ttyUSB0 --baud 115200 --log bench.nmea
    mcahrs evaluate ... / mcahrs convert ...        (mcahrs.evaluate)

Every subcommand is a thin wrapper over a function of this module that the tests call too:
:func:`run_demo`, :func:`simulate_stream`, :func:`replay_file`, :func:`run_bench`; the
summary text comes from :func:`format_report`, shared by ``replay`` and ``bench`` so that a
bench log replayed later prints the same final state.

Replay order. ``replay`` runs the C core's batch replay (``core.replay``, docs/ALGORITHMS.md
9: events merged by time, IMU before GPS before magnetometer at equal times). ``bench``
steps the C core one sample at a time as bytes arrive, and releases samples in that same
order (:class:`EventMerger`): the stream reader yields a fix when its epoch is complete, a
few IMU samples after the fix's arrival time, so the bench holds back the samples a fix
still to come could precede. That makes ``bench`` and ``replay`` of its ``--log`` agree
exactly, provided the sensor samples arrive in time order (as the wire encoder writes
them); a sample that arrives too late to keep the order is counted (``late samples``).
"""

from __future__ import annotations

import argparse
import ast
import heapq
import importlib
import math
import os
import select
import signal
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np
import serial

from mcahrs import core, errors
from mcahrs.io import StreamReader, StreamStats, read_bytes, read_stream, write_recording
from mcahrs.samples import (
    GNSS_HAS_ALT,
    GNSS_HAS_VEL_D,
    GNSS_HAS_VEL_NE,
    GnssFix,
    ImuSample,
    MagSample,
    Recording,
    Sample,
    gnss_array,
)

if TYPE_CHECKING:
    from mcahrs.plots import RunPlotData
    from mcahrs.sim import SimResult

PRESETS = tuple(core.PRESETS)
SCENARIO_PRESET = {  # simulator scenario -> vehicle-class preset
    "car_accel_brake": "ground",
    "fixedwing_turns": "fixedwing",
    "multirotor_aggressive": "multirotor",
    "gps_outage": "fixedwing",
    "static": "ground",
    "steady": "fixedwing",
}
# The demo's flights: (scenario, overrides, one-line description). The fixed-wing pattern is
# shortened to one right and one left circle so that the whole demo runs in seconds.
DEMO_FLIGHTS: tuple[tuple[str, dict[str, Any], str], ...] = (
    ("car_accel_brake", {}, "car: 0 -> 60 km/h in 5 s, 20 s cruise, braking at 8 m/s^2"),
    ("fixedwing_turns", {"circles": (1.0, -1.0), "lead_s": 6.0, "leg_s": 6.0},
     "fixed-wing: 20 m/s, coordinated 30 deg-bank turns, one right and one left circle"),
)
OUTLIER_LEVELS = (1e-2, 1e-4)  # upper-tail levels of the chi2 tests the summary counts
OUTLIER_LEVEL_PLOT = 1e-4  # the one the plot flags (FTA's level, docs/ALGORITHMS.md 5)
PROGRESS_MIN_BYTES = 2_000_000  # progress bar for files larger than this
_AXES = "NED"


class CliError(Exception):
    """A user error the command line reports in one line and exits with status 2."""


# =============================================================================== helpers

def parse_overrides(items: Iterable[str] | None) -> dict[str, Any]:
    """``["cs_h.tau_a_s=3", "comp_mode=0"]`` -> ``{"cs_h.tau_a_s": 3, "comp_mode": 0}``.

    Values are Python literals (numbers, tuples); anything else stays a string.
    """
    out: dict[str, Any] = {}
    for item in items or ():
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise CliError(f"--set {item!r}: expected NAME=VALUE (e.g. cs_h.tau_a_s=3)")
        try:
            out[key.strip()] = ast.literal_eval(text.strip())
        except (ValueError, SyntaxError):
            out[key.strip()] = text.strip()
    return out


def nav_config(preset: str, overrides: Mapping[str, Any] | None = None) -> Any:
    """The C navigation configuration of a preset with overrides; CliError naming the bad one."""
    ov = dict(overrides or {})
    try:
        return core.nav_config(preset, **ov)
    except errors.BadConfigError as exc:
        raise CliError(f"configuration (preset {preset}, overrides {ov}): {exc}") from exc
    except (TypeError, OverflowError) as exc:  # cffi: a value of the wrong type or range for the field
        for key, value in ov.items():
            try:
                core.nav_config(preset, **{key: value})
            except (TypeError, OverflowError, errors.BadConfigError) as one:
                raise CliError(f"configuration: {key}={value!r}: {one}") from exc
        raise CliError(f"configuration (preset {preset}, overrides {ov}): {exc}") from exc


LIVE_GPS_RATE_HZ = 5.0  # the fix rate a live bench's robust profile assumes (fuzzy-rows' guard)


def with_robust_profile(profile: str | None, gps_rate_hz: float,
                        overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """``--robust``: the profile's overrides (``core.robust_profile``), then ``overrides`` over them."""
    ov = dict(overrides or {})
    if profile is None:
        return ov
    try:
        return {**core.robust_profile(profile, gps_rate_hz), **ov}
    except errors.BadConfigError as exc:
        raise CliError(f"--robust {profile}: {exc}") from exc


def latency_us_of(latency_ms: float) -> int:
    """Receiver latency in integer microseconds (>= 0)."""
    if not math.isfinite(latency_ms) or latency_ms < 0:
        raise CliError(f"--latency-ms {latency_ms}: must be a finite number >= 0")
    return int(round(latency_ms * 1000.0))


def _deg(x: Any) -> np.ndarray:
    return np.degrees(np.asarray(x, np.float64))


def _rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def fix_measurements(gnss: np.ndarray) -> np.ndarray:
    """Measurements per N/E/D axis of each fix in the GPS step (docs/ALGORITHMS.md 8, step 4):
    N, E: position + velocity when present; D: position when the fix has altitude and is 3D,
    + velocity when present. Shape (n, 3), values 0..2."""
    fl = gnss["flags"].astype(np.int64)
    vel_ne = (fl & GNSS_HAS_VEL_NE) != 0
    m = np.zeros((len(gnss), 3), np.int64)
    m[:, 0] = m[:, 1] = 1 + vel_ne
    pos_d = ((fl & GNSS_HAS_ALT) != 0) & (gnss["fix_type"] >= 3)
    m[:, 2] = pos_d.astype(np.int64) + ((fl & GNSS_HAS_VEL_D) != 0)
    return m


def gps_t_limits(meas: np.ndarray, level: float) -> np.ndarray:
    """chi2_m(level) of the C core's table for each entry of ``meas`` (NaN where m = 0)."""
    table = {m: core.chi2_quantile(m, level) for m in (1, 2)}
    out = np.full(meas.shape, np.nan)
    for m, v in table.items():
        out[meas == m] = v
    return out


def _fix_statistic(before: np.ndarray, after: np.ndarray, meas: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """GPS innovation statistic of each fix from the output rows around it.

    ``before``/``after``: ``gps_t`` of the output row before and after the fix was processed
    (the rows of the IMU samples around its arrival); an axis whose value did not change, was
    not measured, or a fix whose step failed, gets NaN (the output keeps the last value).
    """
    t = np.array(after, np.float64, copy=True)
    same = (before == after) | (np.isnan(before) & np.isnan(after))
    t[same | (meas == 0) | ~ok[:, None]] = np.nan
    return t


def _fixes_ned(gnss: np.ndarray) -> tuple[tuple[int, int, int] | None, np.ndarray]:
    """Home (latitude/longitude of the first fix with fix_type >= 2, height of the first fix that has
    one, else 0) and the NED of every fix from it (C core geodesy; a fix without altitude is put at
    the home height; NaN if unusable). The navigation filter's own home takes the first fix's
    height, 0 if it has none (docs/ALGORITHMS.md 8)."""
    ned = np.full((len(gnss), 3), np.nan)
    usable = np.flatnonzero(gnss["fix_type"] >= 2)
    if usable.size == 0:
        return None, ned
    h = gnss[usable[0]]
    with_alt = usable[(gnss["flags"][usable] & GNSS_HAS_ALT) != 0]
    home_alt = int(gnss["alt_mm"][with_alt[0]]) if with_alt.size else 0
    home = (int(h["lat_e7"]), int(h["lon_e7"]), home_alt)
    for i in usable:
        g = gnss[i]
        alt = int(g["alt_mm"]) if g["flags"] & GNSS_HAS_ALT else home_alt
        try:
            ned[i] = core.geo_to_ned(home, int(g["lat_e7"]), int(g["lon_e7"]), alt)[0]
        except errors.McaError:
            pass  # out of range: stays NaN (the nav rejects it too)
    return home, ned


# =============================================================================== GNSS only

@dataclass
class GnssOnlyRun:
    """The C core's CS filter (``core.Cs3``) run on the fixes alone, one row per fix."""

    t_s: np.ndarray  # validity time from the first usable fix
    ned_m: np.ndarray  # fix position, NED from the first fix
    vel_ned_mps: np.ndarray  # CS velocity after the fix (NaN where not used)
    acc_ned_mps2: np.ndarray  # CS acceleration after the fix
    gps_t: np.ndarray  # innovation statistic per axis
    meas: np.ndarray  # measurements per axis
    used: np.ndarray  # bool: the fix went into the filter
    home: tuple[int, int, int] | None
    skipped: Counter = field(default_factory=Counter)  # reason -> fixes


def gnss_only_cs(gnss: np.ndarray, cfg: Any) -> GnssOnlyRun:
    """Run the three-axis CS filter over the fixes as the navigation GPS step does
    (docs/ALGORITHMS.md 8, steps 1-4): home and CS start at the first fix (``fix_type`` >= 2),
    then per fix predict over the validity-time step and update N, E with position (and
    velocity), D with altitude (3D fixes) and vertical velocity when present. Accuracies come
    from the fix, else from the configuration; a step longer than ``dt_max_s`` restarts the
    filter at the fix. ``cfg`` is a navigation configuration (its ``cs_h``/``cs_v`` are used).
    """
    n = len(gnss)
    cd = core.config_dict(cfg)
    cfg_h, cfg_v = core.cs_config(False, **cd["cs_h"]), core.cs_config(True, **cd["cs_v"])
    dt_max = min(cd["cs_h"]["dt_max_s"], cd["cs_v"]["dt_max_s"])
    home, ned = _fixes_ned(gnss)
    meas = fix_measurements(gnss)
    vel = np.full((n, 3), np.nan)
    acc = np.full((n, 3), np.nan)
    tstat = np.full((n, 3), np.nan)
    used = np.zeros(n, bool)
    skipped: Counter = Counter()
    t0 = None
    cs: core.Cs3 | None = None
    t_prev = 0

    def fix_vel(g: np.void) -> np.ndarray:
        v = np.nan_to_num(np.asarray(g["vel_ned_mps"], np.float64), nan=0.0)
        if not g["flags"] & GNSS_HAS_VEL_NE:
            v[:2] = 0.0
        if not g["flags"] & GNSS_HAS_VEL_D:
            v[2] = 0.0
        return v

    def sigma(x: float, default: float) -> float:
        return float(x) if math.isfinite(x) and x > 0 else default

    for i, g in enumerate(gnss):
        if g["fix_type"] < 2:
            skipped["no 2D/3D fix"] += 1
            continue
        if not np.isfinite(ned[i]).all():
            skipped["out of range"] += 1
            continue
        t_us = int(g["t_us"])
        if cs is None or t_us <= t_prev or (t_us - t_prev) * 1e-6 > dt_max:
            if cs is not None and t_us <= t_prev:
                skipped["time not increasing"] += 1
                continue
            if cs is not None:
                skipped["restart after a gap > dt_max_s"] += 1
            cs = core.Cs3(cfg_h, cfg_v, ned[i], fix_vel(g))
        else:
            cs.predict((t_us - t_prev) * 1e-6)
            fl = int(g["flags"])
            pos_d = bool(fl & GNSS_HAS_ALT) and g["fix_type"] >= 3
            mask = np.zeros(3, np.uint8)
            mask[:2] = core.lib.MCA_CS_POS | (core.lib.MCA_CS_VEL if fl & GNSS_HAS_VEL_NE else 0)
            mask[2] = ((core.lib.MCA_CS_POS if pos_d else 0)
                       | (core.lib.MCA_CS_VEL if fl & GNSS_HAS_VEL_D else 0))
            h = sigma(g["h_acc_m"], cd["gps_pos_sigma_m"])
            v = sigma(g["v_acc_m"], cd["gps_alt_sigma_m"])
            s = sigma(g["s_acc_mps"], cd["gps_vel_sigma_mps"])
            try:
                rep = cs.update(ned[i], fix_vel(g), [h * h, h * h, v * v], [s * s] * 3, mask)
            except errors.McaError as exc:
                skipped[f"update failed ({type(exc).__name__})"] += 1
                continue
            tstat[i] = np.where(mask > 0, rep["t_stat"], np.nan)
        if t0 is None:
            t0 = t_us
        t_prev = t_us
        x = cs.x
        vel[i], acc[i] = x[:, 1], x[:, 2]
        used[i] = True
    t_s = (gnss["t_us"].astype(np.int64) - (t0 if t0 is not None else 0)) * 1e-6
    return GnssOnlyRun(t_s, ned, vel, acc, tstat, meas, used, home, skipped)


# =============================================================================== report

@dataclass
class RunReport:
    """What ``replay`` and ``bench`` say about one stream and the filter run on it.

    ``final``: the output row after the last IMU sample (``mca_nav_output_t`` fields as NumPy
    values), None without IMU samples; ``fix_gps_t``/``fix_meas``: innovation statistic and
    measurement count per fix and axis; ``step_errors``: C statuses other than OK by step kind.
    """

    preset: str
    latency_us: int
    overrides: dict[str, Any]
    stats: StreamStats
    clock: str | None
    alt_ref: str
    n_imu: int
    n_mag: int
    n_fix: int
    final: dict[str, np.ndarray] | None
    step_errors: dict[str, dict[str, int]]
    fix_gps_t: np.ndarray
    fix_meas: np.ndarray
    gnss_only: GnssOnlyRun | None = None


def _row_values(row: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """An output row (structured-array row or ``Nav.output()`` dict) as NumPy values."""
    return {name: np.array(row[name], dtype=core.OUT_C_DTYPE[name].base) for name in core.OUT_C_DTYPE.names}


def finals_equal(a: Mapping[str, np.ndarray] | None, b: Mapping[str, np.ndarray] | None) -> bool:
    """Bit-for-bit equality of two final rows (NaN equals NaN)."""
    if a is None or b is None:
        return a is b
    return all(np.array_equal(a[k], b[k], equal_nan=np.issubdtype(a[k].dtype, np.floating)) for k in a)


def _status_counts(st: np.ndarray) -> dict[str, int]:
    c = Counter(core.STATUS_NAMES.get(int(s), f"status {int(s)}") for s in st if s != 0)
    return dict(sorted(c.items()))


def report_from_replay(rec: Recording, out: dict[str, np.ndarray] | None, preset: str, latency_us: int,
                       overrides: Mapping[str, Any], gnss_only: GnssOnlyRun | None = None) -> RunReport:
    """The report of a batch replay (``core.replay`` output ``out``, None for GNSS only)."""
    meas = fix_measurements(rec.gnss)
    stats = rec.meta.get("stats_obj") or StreamStats()
    nfix = len(rec.gnss)
    if out is not None and len(out["t_us"]):
        t = out["t_us"].astype(np.int64)
        idx = np.searchsorted(t, rec.gnss["t_rx_us"].astype(np.int64), side="right")
        nan3 = np.full((nfix, 3), np.nan)
        gt = out["gps_t"].astype(np.float64)
        before = np.where((idx > 0)[:, None], gt[np.maximum(idx - 1, 0)], nan3) if nfix else nan3
        after = np.where((idx < len(t))[:, None], gt[np.minimum(idx, len(t) - 1)], nan3) if nfix else nan3
        fix_t = _fix_statistic(before, after, meas, out["gps_status"] == 0)
        final = _row_values({k: out[k][-1] for k in core.OUT_C_DTYPE.names})
        steps = {k: _status_counts(out[f"{k}_status"]) for k in ("imu", "gps", "mag")}
    else:
        fix_t = gnss_only.gps_t if gnss_only is not None else np.full((nfix, 3), np.nan)
        final = None
        steps = {"imu": {}, "gps": {}, "mag": {}}
    return RunReport(preset, latency_us, dict(overrides), stats, rec.meta.get("clock"),
                     rec.meta.get("alt_ref", "none"), len(rec.imu), len(rec.mag), nfix, final, steps, fix_t,
                     meas, gnss_only)


def _flag_names(flags: int) -> str:
    names = [k for k, bit in core.FLAG_BITS.items() if flags & bit]
    return ", ".join(names) if names else "none"


def _vec(v: Sequence[float], fmt: str = "{:+9.3f}", labels: str = _AXES) -> str:
    return "  ".join(f"{a} {fmt.format(float(x))}" for a, x in zip(labels, v, strict=True))


def _outlier_lines(gps_t: np.ndarray, meas: np.ndarray, source: str) -> list[str]:
    n_stat = int(np.isfinite(gps_t).any(axis=1).sum())
    head = (f"GPS outliers: innovation statistic T = nu' C^-1 nu of each fix and axis ({source})\n"
            "  against chi2_m, m = measurements on that axis (the filter output has no outlier flag):")
    if n_stat == 0:
        return [head, "  no fix with an innovation statistic (a filter needs two usable fixes)"]
    lines = [head]
    for level in OUTLIER_LEVELS:
        lim = gps_t_limits(meas, level)
        over = np.isfinite(gps_t) & np.isfinite(lim) & (gps_t > lim)
        per_axis = ", ".join(f"{a} {int(over[:, k].sum())}" for k, a in enumerate(_AXES))
        lines.append(f"  T > chi2_m({level:g}): {int(over.any(axis=1).sum())} of {n_stat} fixes ({per_axis})")
    finite = gps_t[np.isfinite(gps_t)]
    lines.append(f"  T median {np.median(finite):.2f}, max {np.max(finite):.1f}")
    return lines


def format_stream(rep: RunReport) -> list[str]:
    """Lines about what was read: samples, fixes, rejected lines by reason, events."""
    s = rep.stats
    lines = [
        f"stream: {s.bytes_read} bytes, {rep.n_imu} IMU samples, {rep.n_mag} magnetometer samples, "
        f"{rep.n_fix} GNSS fixes (clock {rep.clock or 'none'}, height {rep.alt_ref}, "
        f"latency {rep.latency_us / 1000:g} ms)",
    ]
    if s.total_rejected:
        lines.append(f"rejected lines: {s.total_rejected}")
        for reason, count in sorted(s.rejected.items(), key=lambda kv: (-kv[1], kv[0])):
            ex = s.examples.get(reason, [b""])
            example = ex[0].decode("ascii", "backslashreplace")[:60] if ex else ""
            lines.append(f"  {reason:16s} {count:6d}   e.g. {example!r}")
    else:
        lines.append("rejected lines: none")
    if s.garbage_bytes:
        lines.append(f"garbage bytes outside any line: {s.garbage_bytes}")
    if s.events:
        lines.append("events: " + ", ".join(f"{k} {v}" for k, v in sorted(s.events.items())))
    return lines


def format_report(rep: RunReport) -> str:
    """The summary ``replay`` and ``bench`` print (same text for the same bytes and options)."""
    lines = [f"preset {rep.preset}" + (f", overrides {rep.overrides}" if rep.overrides else "")]
    lines += format_stream(rep)
    if rep.final is None:
        lines += _format_gnss_only(rep)
        return "\n".join(lines)
    lines += _outlier_lines(rep.fix_gps_t, rep.fix_meas, "the output's gps_t after each fix")
    errs = [f"{k} {', '.join(f'{n} {c}' for n, c in v.items())}" for k, v in rep.step_errors.items() if v]
    lines.append("filter step errors: " + ("; ".join(errs) if errs else "none"))
    f = rep.final
    e = _deg(f["euler_rad"])
    sd = np.degrees(np.sqrt(np.maximum(f["att_var"][:3].astype(np.float64), 0.0)))
    t_us = int(f["t_us"])
    flags = int(f["flags"])
    lines += [
        f"final state at t_us {t_us} ({t_us * 1e-6:.3f} s on the IMU clock), after the last IMU sample:",
        f"  attitude  roll {e[0]:+8.3f}  pitch {e[1]:+8.3f}  yaw {e[2]:+8.3f} deg"
        f"   (1-sigma {sd[0]:.3f}, {sd[1]:.3f}, {sd[2]:.3f} deg)",
        (f"  position  {_vec(f['pos_ned_m'])} m (NED from home = first fix)"
         if flags & core.FLAG_BITS["home_set"] else "  position  none: no GPS fix yet (no home)"),
        f"  velocity  {_vec(f['vel_ned_mps'])} m/s",
        f"  accel.    {_vec(f['acc_ned_mps2'])} m/s^2 (CS maneuver acceleration)",
        f"  gyro bias {_vec(_deg(f['gyro_bias_rps']), '{:+9.4f}', 'xyz')} deg/s",
        f"  flags     0x{flags:08x}: {_flag_names(flags)}",
        f"  gravity observations: {int(f['n_grav_obs'])} made, {int(f['n_grav_skip'])} skipped",
    ]
    if not flags & core.FLAG_BITS["aligned"]:
        lines.append("  NOT ALIGNED: the filter needs about 1 s of still IMU samples (or 5 s of any) first")
    return "\n".join(lines)


def _format_gnss_only(rep: RunReport) -> list[str]:
    g = rep.gnss_only
    lines = [
        "NO IMU SAMPLES in this stream: attitude (roll, pitch, yaw) needs IMU samples ($PMCAI sentences,",
        "docs/WIRE_FORMAT.md). Shown instead: the fixes and the C core's CS maneuver filter run on them",
        "alone (velocity and maneuver acceleration).",
    ]
    if g is None or not g.used.any():
        lines.append("no usable GNSS fix (2D/3D) either: nothing to estimate")
        return lines
    u = np.flatnonzero(g.used)
    span = g.t_s[u[-1]] - g.t_s[u[0]]
    lat, lon, _ = g.home if g.home else (0, 0, 0)
    skipped = ", ".join(f"{k} {v}" for k, v in sorted(g.skipped.items()))
    lines.append(f"fixes used: {u.size} of {len(g.used)} over {span:.1f} s; home {abs(lat) * 1e-7:.7f} "
                 f"{'N' if lat >= 0 else 'S'} {abs(lon) * 1e-7:.7f} {'E' if lon >= 0 else 'W'}"
                 + (f"; skipped: {skipped}" if skipped else ""))
    i = u[-1]
    v, a = g.vel_ned_mps[i], g.acc_ned_mps2[i]
    sp = np.hypot(g.vel_ned_mps[u, 0], g.vel_ned_mps[u, 1])
    ah = np.hypot(g.acc_ned_mps2[u, 0], g.acc_ned_mps2[u, 1])
    lines += [
        f"CS filter (preset {rep.preset} cs_h/cs_v, core.Cs3 on NED from the first fix), "
        f"last fix t = {g.t_s[i]:.2f} s:",
        f"  position  {_vec(g.ned_m[i])} m",
        f"  velocity  {_vec(v)} m/s (horizontal speed {math.hypot(v[0], v[1]):.3f} m/s)",
        f"  accel.    {_vec(a)} m/s^2 (maneuver acceleration)",
        f"  over the capture: horizontal speed max {np.max(sp):.2f} m/s; horizontal acceleration "
        f"RMS {_rms(ah):.3f}, max {np.max(ah):.3f} m/s^2",
    ]
    lines += _outlier_lines(g.gps_t, g.meas, "the CS update's report")
    return lines


# =============================================================================== replay

@dataclass
class ReplayResult:
    """A file read by the stream reader and run through the C core (``core.replay``)."""

    path: Path
    rec: Recording
    cfg: Any
    out: dict[str, np.ndarray] | None  # None for a GNSS-only stream
    report: RunReport


class _ProgressFile:
    """A binary file whose reads advance a tqdm bar (the stream reader calls ``read1``)."""

    def __init__(self, fh: IO[bytes], bar: Any) -> None:
        self.fh, self.bar = fh, bar

    def read1(self, size: int = -1) -> bytes:
        b = self.fh.read1(size)  # type: ignore[attr-defined]
        self.bar.update(len(b))
        return b

    def read(self, size: int = -1) -> bytes:
        b = self.fh.read(size)
        self.bar.update(len(b))
        return b


def read_capture(path: str | os.PathLike, latency_us: int = 0, clock: str = "auto",
                 progress: bool | None = None) -> Recording:
    """Read a stream file (wire format or plain NMEA) with the stream reader.

    ``progress``: True/False forces the tqdm bar on stderr; None shows it for files over
    ``PROGRESS_MIN_BYTES`` when stderr is a terminal. Raises FileNotFoundError/IsADirectoryError.
    """
    p = Path(path)
    size = p.stat().st_size
    show = progress if progress is not None else (size > PROGRESS_MIN_BYTES and sys.stderr.isatty())
    with open(p, "rb") as fh:
        if show:
            from tqdm import tqdm

            with tqdm(total=size, unit="B", unit_scale=True, desc=f"reading {p.name}", leave=False,
                      file=sys.stderr) as bar:
                rec = read_stream(_ProgressFile(fh, bar), name=p.name, latency_us=latency_us, clock=clock)
        else:
            rec = read_stream(fh, name=p.name, latency_us=latency_us, clock=clock)
    rec.meta["source"] = str(p)
    return rec


def read_capture_bytes(data: bytes, latency_us: int = 0, clock: str = "auto",
                       name: str = "bytes") -> Recording:
    """Read a stream held in memory (see :func:`read_capture`)."""
    return read_bytes(data, name=name, latency_us=latency_us, clock=clock)


def replay_recording(
    rec: Recording, preset: str = "ground", latency_us: int = 0, overrides: Mapping[str, Any] | None = None
) -> tuple[Any, dict[str, np.ndarray] | None, RunReport]:
    """Run a read stream through the C core (or the CS filter alone without IMU samples)."""
    ov = dict(overrides or {})
    cfg = nav_config(preset, ov)
    if len(rec.imu) == 0:
        return cfg, None, report_from_replay(rec, None, preset, latency_us, ov, gnss_only_cs(rec.gnss, cfg))
    try:
        out = core.replay(rec, cfg)
    except errors.BadArgError as exc:
        raise CliError(f"{rec.name}: {exc} (IMU time stamps reset, or fixes timed on two clocks: "
                       "try --clock imu)") from exc
    return cfg, out, report_from_replay(rec, out, preset, latency_us, ov)


def replay_file(path: str | os.PathLike, preset: str = "ground", latency_ms: float = 0.0,
                overrides: Mapping[str, Any] | None = None, clock: str = "auto",
                progress: bool | None = None, robust: str | None = None) -> ReplayResult:
    """``mcahrs replay``: read ``path`` with the stream reader and run the C core over it
    (``robust``: a robust profile, set up for the stream's fix rate, under ``overrides``)."""
    lat = latency_us_of(latency_ms)
    p = Path(path)
    try:
        rec = read_capture(p, lat, clock, progress)
    except (FileNotFoundError, IsADirectoryError, PermissionError) as exc:
        raise CliError(f"cannot read {p}: {exc.strerror or exc}") from exc
    ov = with_robust_profile(robust, core.fix_rate_hz(rec, LIVE_GPS_RATE_HZ), overrides)
    cfg, out, rep = replay_recording(rec, preset, lat, ov)
    return ReplayResult(p, rec, cfg, out, rep)


def write_csv(res: ReplayResult, path: str | os.PathLike) -> Path:
    """Per-IMU-sample filter output (or per-fix CS output for a GNSS-only stream) as CSV."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    if res.out is not None:
        o = res.out
        cols = [o["t_us"].astype(np.float64) * 1e-6, *(_deg(o["euler_rad"]).T), *(_deg(o["gyro_bias_rps"]).T),
                *o["pos_ned_m"].T, *o["vel_ned_mps"].T, *o["acc_ned_mps2"].T, o["rp_t"], *o["gps_t"].T,
                o["flags"]]
        header = ("t_s,roll_deg,pitch_deg,yaw_deg,bias_x_dps,bias_y_dps,bias_z_dps,pos_n_m,pos_e_m,pos_d_m,"
                  "vel_n_mps,vel_e_mps,vel_d_mps,acc_n_mps2,acc_e_mps2,acc_d_mps2,rp_t,gps_t_n,gps_t_e,gps_t_d,flags")
        fmt = ["%.6f"] + ["%.7g"] * 19 + ["%d"]
    else:
        g = res.report.gnss_only
        assert g is not None
        cols = [g.t_s, *g.ned_m.T, *g.vel_ned_mps.T, *g.acc_ned_mps2.T, *g.gps_t.T, g.used.astype(int)]
        header = ("t_s,pos_n_m,pos_e_m,pos_d_m,vel_n_mps,vel_e_mps,vel_d_mps,acc_n_mps2,acc_e_mps2,"
                  "acc_d_mps2,gps_t_n,gps_t_e,gps_t_d,used")
        fmt = ["%.6f"] + ["%.7g"] * 12 + ["%d"]
    np.savetxt(p, np.column_stack(cols), delimiter=",", header=header, comments="", fmt=fmt)
    return p


def plot_data(res: ReplayResult, title: str, truth_euler_rad: np.ndarray | None = None,
              truth_acc_ned: np.ndarray | None = None,
              compare: Mapping[str, Mapping[str, np.ndarray]] | None = None,
              subtitle: str = "") -> RunPlotData:
    """:class:`mcahrs.plots.RunPlotData` of a replay (truth arrays at the output rows, if known)."""
    from mcahrs.plots import RunPlotData

    rep = res.report
    if res.out is None:
        g = rep.gnss_only
        assert g is not None
        return RunPlotData(title=title, subtitle=subtitle, acc_t_s=g.t_s, acc_ned_mps2=g.acc_ned_mps2,
                           vel_ned_mps=g.vel_ned_mps, fix_speed_mps=res.rec.gnss["speed_mps"],
                           fix_t_s=g.t_s, fix_ned_m=g.ned_m, gps_t=g.gps_t,
                           gps_t_limit=gps_t_limits(g.meas, OUTLIER_LEVEL_PLOT),
                           limit_label=f"chi2_m({OUTLIER_LEVEL_PLOT:g})")
    o = res.out
    t0 = int(o["t_us"][0])
    t_s = (o["t_us"].astype(np.int64) - t0) * 1e-6
    def aligned_deg(run: Mapping[str, np.ndarray]) -> np.ndarray:
        e = _deg(run["euler_rad"])
        e[(run["flags"] & core.FLAG_BITS["aligned"]) == 0] = np.nan  # no attitude before alignment
        return e

    eul = {"MCAHRS": aligned_deg(o)}
    for label, other in (compare or {}).items():
        eul[label] = aligned_deg(other)
    _, fix_ned = _fixes_ned(res.rec.gnss)
    return RunPlotData(
        title=title, subtitle=subtitle, t_s=t_s, euler_deg=eul,
        ref_euler_deg=None if truth_euler_rad is None else _deg(truth_euler_rad),
        acc_t_s=t_s, acc_ned_mps2=o["acc_ned_mps2"].astype(np.float64), ref_acc_ned_mps2=truth_acc_ned,
        fix_t_s=(res.rec.gnss["t_us"].astype(np.int64) - t0) * 1e-6, fix_ned_m=fix_ned,
        gps_t=rep.fix_gps_t, gps_t_limit=gps_t_limits(rep.fix_meas, OUTLIER_LEVEL_PLOT),
        limit_label=f"chi2_m({OUTLIER_LEVEL_PLOT:g})", est_ned_m=o["pos_ned_m"].astype(np.float64),
    )


# =============================================================================== simulate

def simulate_stream(
    scenario_name: str, out: str | os.PathLike, seed: int = 1, duration_s: float | None = None,
    params: Mapping[str, Any] | None = None,
) -> tuple[SimResult, int]:
    """``mcahrs simulate``: simulate a scenario and write it as a wire-format stream file.

    Returns (``SimResult``, bytes written). ``params``: simulator overrides (SimParams fields
    or the scenario's own arguments).
    """
    from mcahrs.sim import SCENARIOS, scenario

    if scenario_name not in SCENARIOS:
        raise CliError(f"unknown scenario {scenario_name!r}; known: {', '.join(sorted(SCENARIOS))}")
    kw = dict(params or {})
    if duration_s is not None:
        if not duration_s > 0:
            raise CliError(f"--duration {duration_s}: must be > 0")
        kw["duration_s"] = float(duration_s)
    try:
        sim = scenario(scenario_name, seed=seed, **kw)
    except (TypeError, ValueError) as exc:
        raise CliError(f"scenario {scenario_name}: {exc}") from exc
    p = Path(out)
    p.parent.mkdir(parents=True, exist_ok=True)
    with open(p, "wb") as fh:
        n = write_recording(sim.recording, fh)
    return sim, n


# =============================================================================== demo

@dataclass
class DemoFlight:
    scenario: str
    preset: str
    stream_path: Path
    plot_path: Path
    stream_bytes: int
    replay: ReplayResult
    errors_deg: dict[str, np.ndarray]  # method -> [roll RMS, pitch RMS, roll max, pitch max]


def attitude_errors_deg(out: Mapping[str, np.ndarray], truth: Any) -> np.ndarray:
    """Roll/pitch error (deg) of the aligned output rows against the simulator's truth
    ([roll RMS, pitch RMS, roll max, pitch max]) and the per-row errors (n, 2)."""
    idx = truth.index_of(out["t_us"].astype(np.int64))
    err = np.degrees(out["euler_rad"][:, :2].astype(np.float64) - truth.euler_rad[idx, :2])
    err = (err + 180.0) % 360.0 - 180.0
    err[(out["flags"] & core.FLAG_BITS["aligned"]) == 0] = np.nan
    absmax = np.nanmax(np.abs(err), axis=0)
    return np.array([_rms(err[:, 0]), _rms(err[:, 1]), absmax[0], absmax[1]])


def run_demo(
    out_dir: str | os.PathLike = "out",
    flights: Sequence[tuple[str, dict[str, Any], str]] = DEMO_FLIGHTS,
    seed: int = 1,
    echo: Callable[[str], None] | None = print,
    plot: bool = True,
) -> list[DemoFlight]:
    """``mcahrs demo``: per flight, simulate, write the wire-format stream, read it back with the
    stream reader and run the C core (the user's path: :func:`replay_file`), replay it again
    with the maneuver compensation off, compare roll/pitch with the truth, and plot."""
    say = echo or (lambda _s: None)
    d = Path(out_dir)
    d.mkdir(parents=True, exist_ok=True)
    results = []
    for name, params, desc in flights:
        preset = SCENARIO_PRESET.get(name, "ground")
        stream = d / f"{name}.nmea"
        sim, nbytes = simulate_stream(name, stream, seed=seed, params=params)
        res = replay_file(stream, preset=preset)
        off = core.replay(res.rec, nav_config(preset, {"comp_mode": 0}))
        errs = {"MCAHRS (CS compensation)": attitude_errors_deg(res.out, sim.truth),
                "compensation off": attitude_errors_deg(off, sim.truth)}
        s = res.report.stats
        say(f"{name}: {desc} (preset {preset})")
        say(f"  stream  {stream}: {nbytes / 1e6:.2f} MB, {res.report.n_imu} IMU + {res.report.n_mag} "
            f"magnetometer samples, {res.report.n_fix} GNSS fixes, {s.total_rejected} rejected lines")
        say(f"  roll/pitch error against the truth (deg) {'roll RMS':>8s} {'pitch RMS':>9s} "
            f"{'roll max':>8s} {'pitch max':>9s}")
        for label, e in errs.items():
            say(f"    {label:38s} {e[0]:8.2f} {e[1]:9.2f} {e[2]:8.2f} {e[3]:9.2f}")
        on, of = errs["MCAHRS (CS compensation)"], errs["compensation off"]
        gain = math.hypot(of[0], of[1]) / math.hypot(on[0], on[1])
        say(f"  compensation lowers the roll+pitch RMS {gain:.1f}x")
        png = d / f"{name}.png"
        if plot:
            from mcahrs.plots import plot_run

            idx = sim.truth.index_of(res.out["t_us"].astype(np.int64))
            pd = plot_data(res, f"{name}: MCAHRS on a simulated flight, replayed from {stream.name}",
                           truth_euler_rad=sim.truth.euler_rad[idx],
                           truth_acc_ned=sim.truth.acc_ned_mps2[idx], compare={"compensation off": off},
                           subtitle=f"{desc}; preset {preset}, seed {seed}")
            plot_run(pd, png)
            say(f"  plot    {png}")
        results.append(DemoFlight(name, preset, stream, png, nbytes, res, errs))
    return results


# =============================================================================== bench

_IMU, _GPS, _MAG = 0, 1, 2  # rank at equal times (docs/ALGORITHMS.md 9)
_INF = (math.inf, 0, 0)


class EventMerger:
    """Puts the samples a :class:`StreamReader` yields into the batch replay order.

    Order (docs/ALGORITHMS.md 9): by time (IMU and magnetometer ``t_us``, fix ``t_rx_us``),
    at equal times IMU, then GPS, then magnetometer, within a kind in stream order. The
    reader yields a fix only when its epoch is complete, after IMU samples newer than the
    fix's ``t_rx_us``; a sample is released once nothing still to come can precede it:

    * a fix still to come has ``t_rx_us`` >= the IMU time its epoch started at (the open
      epoch's, the held untimed sentences', or the newest IMU time for epochs not begun);
      on the UTC clock (no IMU), >= the last fix's;
    * a sensor sample still to come is newer than the newest sensor sample (sensor samples
      arrive in time order); before any sensor sample, none is expected.

    A sample that arrives older than one already released cannot be put in order: it is
    released at once and counted in ``late``. A sample is never held back for more than
    ``max_hold_us`` of IMU time (2 s; longer than the reader's 1 s epoch timeout, so complete
    epochs are always waited for).
    """

    def __init__(self, reader: StreamReader, max_hold_us: int = 2_000_000) -> None:
        self.reader = reader
        self._heap: list[tuple[int, int, int, Sample]] = []
        self._seq = 0
        self.last_imu: int | None = None
        self.last_mag: int | None = None
        self.last_sensor: int | None = None
        self.last_fix_rx: int | None = None
        self._released: tuple[float, int, int] = (-math.inf, 0, 0)
        self.late = 0
        self.max_hold_us = max_hold_us

    def push(self, samples: Iterable[Sample]) -> None:
        for s in samples:
            if isinstance(s, ImuSample):
                key = (s.t_us, _IMU)
                self.last_imu = s.t_us
            elif isinstance(s, MagSample):
                key = (s.t_us, _MAG)
                self.last_mag = s.t_us
            else:
                key = (s.t_rx_us, _GPS)
                self.last_fix_rx = s.t_rx_us
            if not isinstance(s, GnssFix):
                self.last_sensor = s.t_us if self.last_sensor is None else max(self.last_sensor, s.t_us)
            item = (key[0], key[1], self._seq, s)
            self._seq += 1
            if item[:3] < self._released:
                self.late += 1
            heapq.heappush(self._heap, item)

    def _floor(self) -> tuple[float, int, int]:
        """The smallest key a sample still to come can have."""
        nxt = self._seq
        bounds = [_INF]
        if self.last_sensor is not None:
            imu_lo = self.last_sensor if self.last_imu is None else max(self.last_imu + 1, self.last_sensor)
            mag_lo = self.last_sensor if self.last_mag is None else max(self.last_mag + 1, self.last_sensor)
            bounds += [(imu_lo, _IMU, nxt), (mag_lo, _MAG, nxt)]
        tb = self.reader.timebase
        if tb.mode == "utc" or tb.last_imu_t_us is None:
            if self.last_fix_rx is not None:
                bounds.append((self.last_fix_rx, _GPS, nxt))
            elif self.last_sensor is not None or self._heap:
                bounds.append((-math.inf, _GPS, nxt))
        else:
            starts = [tb.last_imu_t_us]
            ep = self.reader.epochs.current
            if ep is not None and not ep.closed and ep.imu_t_us is not None:
                starts.append(ep.imu_t_us)
            starts += [p.imu_t_us for p in self.reader.epochs.pending if p.imu_t_us is not None]
            # bounded latency: sentences held longer than max_hold_us of IMU time (a receiver
            # sending untimed sentences and no fix) do not stall the filter
            bounds.append((max(min(starts), tb.last_imu_t_us - self.max_hold_us), _GPS, nxt))
        return min(bounds)

    def release(self) -> list[Sample]:
        """The samples that can be stepped now, in order."""
        floor = self._floor()
        out = []
        while self._heap and self._heap[0][:3] < floor:
            item = heapq.heappop(self._heap)
            self._released = max(self._released, item[:3])
            out.append(item[3])
        return out

    def drain(self) -> list[Sample]:
        """End of stream: everything held, in order."""
        out = []
        while self._heap:
            item = heapq.heappop(self._heap)
            self._released = max(self._released, item[:3])
            out.append(item[3])
        return out


class LiveNav:
    """Bytes in, the C core stepped one sample at a time (``core.Nav``), in replay order.

    ``feed(bytes)`` as bytes arrive; ``finish()`` at the end returns the :class:`RunReport`,
    the same as :func:`replay_file` gives for the same bytes and options.
    """

    def __init__(self, preset: str = "ground", latency_us: int = 0,
                 overrides: Mapping[str, Any] | None = None, clock: str = "auto") -> None:
        self.preset = preset
        self.latency_us = latency_us
        self.overrides = dict(overrides or {})
        self.cfg = nav_config(preset, self.overrides)
        self.nav = core.Nav(self.cfg)
        self.reader = StreamReader(None, latency_us=latency_us, clock=clock)
        self.merger = EventMerger(self.reader)
        self.n_imu = self.n_mag = 0
        self.fixes: list[GnssFix] = []
        self.fix_ok: list[bool] = []
        self.fix_before: list[np.ndarray] = []
        self.fix_after: list[np.ndarray | None] = []
        self._waiting: list[int] = []  # fixes waiting for the next output row
        self.last_row: dict[str, Any] | None = None
        self.step_errors: dict[str, Counter] = {"imu": Counter(), "gps": Counter(), "mag": Counter()}
        self._report: RunReport | None = None

    def feed(self, data: bytes) -> None:
        self.merger.push(self.reader.feed(data))
        self._step(self.merger.release())

    def finish(self) -> RunReport:
        """End of stream (idempotent): emit the open epoch, step everything held, report."""
        if self._report is None:
            self.merger.push(self.reader.finish())
            self._step(self.merger.drain())
            self._report = self._make_report()
        return self._report

    def _gps_t_now(self) -> np.ndarray:
        row = self.last_row
        return np.full(3, np.nan) if row is None else np.array(row["gps_t"], np.float64)

    def _step(self, samples: Iterable[Sample]) -> None:
        nav = self.nav
        for s in samples:
            if isinstance(s, ImuSample):
                self.n_imu += 1
                try:
                    nav.imu(s.t_us, s.gyro_rps, s.accel_mps2)
                except errors.McaError as exc:
                    self.step_errors["imu"][type(exc).__name__] += 1
                self.last_row = nav.output()
                if self._waiting:
                    row_t = np.array(self.last_row["gps_t"], np.float64)
                    for j in self._waiting:
                        self.fix_after[j] = row_t
                    self._waiting.clear()
            elif isinstance(s, GnssFix):
                self.fixes.append(s)
                self.fix_before.append(self._gps_t_now())
                self.fix_after.append(None)
                self._waiting.append(len(self.fixes) - 1)
                ok = True
                try:
                    self._gps(s)
                except errors.McaError as exc:
                    self.step_errors["gps"][type(exc).__name__] += 1
                    ok = False
                self.fix_ok.append(ok)
            else:
                self.n_mag += 1
                try:
                    nav.mag(s.t_us, s.mag_b)
                except errors.McaError as exc:
                    self.step_errors["mag"][type(exc).__name__] += 1

    def _gps(self, f: GnssFix) -> None:
        """One GPS step with the fix converted exactly as the batch replay does (core.gnss_to_c)."""
        vel = None
        if f.flags & GNSS_HAS_VEL_NE:
            vel = [0.0 if math.isnan(v) else v for v in f.vel_ned_mps]
        self.nav.gps(f.t_us, f.lat_e7, f.lon_e7, f.alt_mm if f.flags & GNSS_HAS_ALT else None,
                     vel_ned_mps=vel, h_acc_m=f.h_acc_m, v_acc_m=f.v_acc_m, s_acc_mps=f.s_acc_mps,
                     fix_type=f.fix_type, vel_d=bool(f.flags & GNSS_HAS_VEL_D))

    def _make_report(self) -> RunReport:
        gnss = gnss_array(self.fixes)
        meas = fix_measurements(gnss)
        stats = self.reader.stats
        meta = self.reader.meta()
        if self.n_imu == 0:
            g = gnss_only_cs(gnss, self.cfg)
            no_steps: dict[str, dict[str, int]] = {"imu": {}, "gps": {}, "mag": {}}
            return RunReport(self.preset, self.latency_us, self.overrides, stats, meta["clock"],
                             meta["alt_ref"], 0, self.n_mag, len(gnss), None, no_steps, g.gps_t, meas, g)
        nan3 = np.full(3, np.nan)
        before = np.array(self.fix_before).reshape(-1, 3)
        after = np.array([a if a is not None else nan3 for a in self.fix_after]).reshape(-1, 3)
        fix_t = _fix_statistic(before, after, meas, np.array(self.fix_ok, bool))
        assert self.last_row is not None
        steps = {k: dict(sorted(v.items())) for k, v in self.step_errors.items()}
        return RunReport(self.preset, self.latency_us, self.overrides, stats, meta["clock"], meta["alt_ref"],
                         self.n_imu, self.n_mag, len(gnss), _row_values(self.last_row), steps, fix_t, meas)

    def status_line(self) -> str:
        """One line: IMU time, attitude, fixes, rejects, flags."""
        st = self.reader.stats
        if self.last_row is None:
            return (f"waiting for IMU samples | fixes {st.emitted['gnss']} | bytes {st.bytes_read} | "
                    f"rejects {st.total_rejected}")
        r = self.last_row
        e = _deg(r["euler_rad"])
        return (f"t {r['t_us'] * 1e-6:9.2f} s | roll {e[0]:+7.2f} pitch {e[1]:+7.2f} yaw {e[2]:+7.1f} deg | "
                f"fixes {len(self.fixes)} | IMU {self.n_imu} | rejects {st.total_rejected} | "
                f"flags {_flag_names(int(r['flags']))}")


@dataclass
class BenchResult:
    """What :func:`run_bench` did."""

    report: RunReport
    live: LiveNav
    bytes_read: int
    disconnects: int
    reconnects: int
    wall_s: float
    stop_reason: str  # "interrupted", "stopped", "max_duration", "idle", "port closed"
    log_path: Path | None
    clock: str = "auto"  # the reader's clock option


def _open_port(url: str, baud: int) -> Any:
    # timeout 0: every read returns at once with what is there, so bytes received just before
    # a disconnect are never dropped inside a blocking read; the loop waits with select.
    port = serial.serial_for_url(url, baudrate=baud, timeout=0, do_not_open=True)
    if url.lower().startswith("socket://"):
        # pyserial's socket handler throws away, in open(), whatever the server sent since the
        # connection was made (reset_input_buffer); those bytes are the live stream: keep them.
        port.reset_input_buffer = lambda: None
    port.open()
    return port


def _wait_readable(port: Any, timeout_s: float) -> None:
    try:
        fd = port.fileno()
    except (AttributeError, OSError, ValueError, serial.SerialException):
        time.sleep(min(timeout_s, 0.01))  # loop:// and other handlers without a descriptor
        return
    try:
        select.select([fd], [], [], timeout_s)
    except (OSError, ValueError):
        time.sleep(min(timeout_s, 0.01))


def run_bench(
    port_url: str,
    baud: int = 115200,
    preset: str = "ground",
    log: str | os.PathLike | None = None,
    latency_ms: float = 0.0,
    overrides: Mapping[str, Any] | None = None,
    clock: str = "auto",
    max_duration_s: float | None = None,
    idle_timeout_s: float | None = None,
    stop: threading.Event | None = None,
    status: IO[str] | None = sys.stderr,
    status_period_s: float = 0.5,
    on_event: Callable[[str], None] | None = None,
    backoff_max_s: float = 2.0,
    robust: str | None = None,
) -> BenchResult:
    """``mcahrs bench``: read a live port, step the C core sample by sample, print a status line.

    Opens ``serial.serial_for_url(port_url)`` (a device, a pty path, ``socket://host:port``,
    ``loop://``). A read error (device unplugged, socket closed, pty hung up) counts a
    disconnect; the port is reopened with exponential backoff (0.1 s up to ``backoff_max_s``)
    and the same reader and filter go on. Stops on ``stop`` (set), Ctrl-C
    (KeyboardInterrupt), ``max_duration_s`` of wall time, or ``idle_timeout_s`` without a
    byte (end of data). ``log``: every byte read, in order, so ``replay`` of it reproduces the
    final report. ``on_event``: called with "open", "disconnected", "reconnected", "stop".
    ``robust``: a robust profile (set up for a :data:`LIVE_GPS_RATE_HZ` receiver) under
    ``overrides``. Raises :class:`CliError` if the port cannot be opened the first time.
    """
    lat = latency_us_of(latency_ms)
    live = LiveNav(preset, lat, with_robust_profile(robust, LIVE_GPS_RATE_HZ, overrides), clock)
    say = on_event or (lambda _e: None)
    logf = open(log, "wb") if log is not None else None  # noqa: SIM115 - closed in finally
    t0 = time.monotonic()
    last_data = t0
    next_status = t0
    port = None
    opened = False
    backoff = 0.1
    retry_at = t0
    disconnects = reconnects = nbytes = 0
    tty = bool(status is not None and getattr(status, "isatty", lambda: False)())
    reason = "stopped"
    try:
        while True:
            now = time.monotonic()
            if stop is not None and stop.is_set():
                reason = "stopped"
                break
            if max_duration_s is not None and now - t0 >= max_duration_s:
                reason = "max_duration"
                break
            if idle_timeout_s is not None and now - last_data >= idle_timeout_s:
                reason = "idle" if port is not None or not opened else "port closed"
                break
            if port is None:
                if now < retry_at:
                    time.sleep(min(0.05, retry_at - now))
                    continue
                try:
                    port = _open_port(port_url, baud)
                except (serial.SerialException, OSError, ValueError) as exc:
                    if not opened:
                        raise CliError(f"cannot open {port_url}: {exc}") from exc
                    retry_at = now + backoff
                    backoff = min(backoff * 2.0, backoff_max_s)
                    continue
                backoff = 0.1
                if opened:
                    reconnects += 1
                    say("reconnected")
                else:
                    opened = True
                    say("open")
            try:
                data = port.read(max(65536, getattr(port, "in_waiting", 0) or 0))
            except serial.SerialException:
                disconnects += 1
                say("disconnected")
                try:
                    port.close()
                except Exception:  # noqa: BLE001 - a vanished port may fail to close; it is gone anyway
                    pass
                port = None
                retry_at = time.monotonic() + backoff
                continue
            if data:
                last_data = time.monotonic()
                nbytes += len(data)
                if logf is not None:
                    logf.write(data)
                live.feed(data)
            else:
                _wait_readable(port, 0.05)
            if status is not None and time.monotonic() >= next_status:
                next_status = time.monotonic() + status_period_s
                line = live.status_line() + (f" | disconnects {disconnects}" if disconnects else "")
                status.write(("\r" + line[:150].ljust(150)) if tty else line + "\n")
                status.flush()
    except KeyboardInterrupt:
        reason = "interrupted"
    finally:
        if port is not None:
            try:
                port.close()
            except Exception:  # noqa: BLE001
                pass
        if logf is not None:
            logf.close()
        if status is not None and tty:
            status.write("\n")
    report = live.finish()
    say("stop")
    return BenchResult(report, live, nbytes, disconnects, reconnects, time.monotonic() - t0, reason,
                       Path(log) if log is not None else None, clock)


def format_bench(res: BenchResult, port_url: str) -> str:
    """The bench summary: connection figures, then :func:`format_report`."""
    lines = [
        f"bench on {port_url}: {res.bytes_read} bytes in {res.wall_s:.1f} s, stopped ({res.stop_reason}); "
        f"disconnects {res.disconnects}, reconnects {res.reconnects}",
    ]
    if res.live.merger.late:
        lines.append(f"WARNING: {res.live.merger.late} samples arrived out of time order and were stepped "
                     "late; replay of the log sorts them and may differ")
    lines.append(format_report(res.report))
    if res.log_path is not None:
        cmd = f"mcahrs replay {res.log_path} --preset {res.report.preset}"
        if res.report.latency_us:
            cmd += f" --latency-ms {res.report.latency_us / 1000:g}"
        if res.clock != "auto":
            cmd += f" --clock {res.clock}"
        cmd += "".join(f" --set {k}={v!r}" for k, v in res.report.overrides.items())
        lines.append(f"log: {res.log_path} ({res.bytes_read} bytes); `{cmd}` reproduces the report above")
    return "\n".join(lines)


# =============================================================================== commands

def _add_run_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", choices=PRESETS, default="ground",
                   help="vehicle-class configuration (default ground)")
    p.add_argument("--latency-ms", type=float, default=0.0, metavar="X",
                   help="GNSS receiver output latency: fix time = arrival - X (default 0)")
    p.add_argument("--clock", choices=("auto", "imu", "utc"), default="auto",
                   help="time base of the fixes (docs/WIRE_FORMAT.md; default auto)")
    p.add_argument("--robust", choices=core.ROBUST_PROFILES, default=None, metavar="PROFILE",
                   help="GNSS outlier handling on the CS and attitude filters: "
                        f"{', '.join(core.ROBUST_PROFILES)} (README, GNSS outliers; default: the preset's, "
                        "plain); --set applies after it")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="override a configuration field, e.g. comp_mode=0 or cs_h.robust.mode=1 (repeatable)")


def cmd_demo(args: argparse.Namespace) -> int:
    t0 = time.monotonic()
    print("MCAHRS demo: simulated flight -> wire-format stream file -> StreamReader -> C core, "
          "against the truth")
    flights = run_demo(args.out, seed=args.seed)
    first = flights[0]
    print(f"done in {time.monotonic() - t0:.1f} s. Replay a stream yourself:\n"
          f"  mcahrs replay {first.stream_path} --preset {first.preset} --plot {args.out}/replay.png")
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    params = parse_overrides(args.param)
    sim, n = simulate_stream(args.scenario, args.out, seed=args.seed, duration_s=args.duration, params=params)
    r = sim.recording
    dur = (r.imu["t_us"][-1] - r.imu["t_us"][0]) * 1e-6 if len(r.imu) else 0.0
    preset = SCENARIO_PRESET.get(args.scenario, "ground")
    print(f"wrote {args.out}: {n} bytes, {dur:.1f} s, {len(r.imu)} IMU + {len(r.mag)} magnetometer samples, "
          f"{len(r.gnss)} GNSS fixes (scenario {args.scenario}, seed {args.seed})")
    print(f"replay it: mcahrs replay {args.out} --preset {preset}")
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    res = replay_file(args.file, preset=args.preset, latency_ms=args.latency_ms,
                      overrides=parse_overrides(args.set), clock=args.clock,
                      progress=False if args.no_progress else None, robust=args.robust)
    print(f"replay of {res.path}")
    print(format_report(res.report))
    if args.csv:
        print(f"csv: {write_csv(res, args.csv)}")
    if args.plot:
        from mcahrs.plots import plot_run

        title = f"MCAHRS replay of {res.path.name}" + (" (GNSS only)" if res.out is None else "")
        sub = f"preset {args.preset}; " + ("no reference attitude in the stream" if res.out is not None
                                           else "attitude needs IMU samples")
        print(f"plot: {plot_run(plot_data(res, title, subtitle=sub), args.plot)}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    stop = threading.Event()
    handlers: dict[int, Any] = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            handlers[sig] = signal.signal(sig, lambda _n, _f: stop.set())
    try:
        res = run_bench(args.port, baud=args.baud, preset=args.preset, log=args.log,
                        latency_ms=args.latency_ms, overrides=parse_overrides(args.set), clock=args.clock,
                        max_duration_s=args.max_duration, idle_timeout_s=args.idle_timeout, stop=stop,
                        robust=args.robust,
                        on_event=lambda e: print(f"[bench] {e}", file=sys.stderr, flush=True))
    finally:
        for sig, h in handlers.items():
            signal.signal(sig, h)
    if res.stop_reason == "stopped":
        res.stop_reason = "interrupted"  # the only setter of ``stop`` here is the signal handler
    print(format_bench(res, args.port))
    return 0


def _dispatch_external(name: str, argv: list[str]) -> int:
    """``evaluate``/``convert`` live in mcahrs.evaluate (``main_evaluate``/``main_convert``)."""
    func = f"main_{name}"
    try:
        mod = importlib.import_module("mcahrs.evaluate")
    except ImportError as exc:
        print(f"mcahrs {name}: not available: cannot import mcahrs.evaluate ({exc})", file=sys.stderr)
        return 2
    fn = getattr(mod, func, None)
    if fn is None:
        print(f"mcahrs {name}: not available: mcahrs.evaluate has no {func}()", file=sys.stderr)
        return 2
    rc = fn(argv)
    return int(rc) if rc is not None else 0


def _dispatch_allan(argv: list[str]) -> int:
    """``allan`` lives in mcahrs.allan (``main_allan``), imported only when used."""
    try:
        mod = importlib.import_module("mcahrs.allan")
    except ImportError as exc:
        print(f"mcahrs allan: not available: cannot import mcahrs.allan ({exc})", file=sys.stderr)
        return 2
    rc = mod.main_allan(argv)
    return int(rc) if rc is not None else 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="mcahrs", description="MCAHRS: GPS-aided maneuver-compensated attitude "
                                 "estimator (C core) - simulate, replay, live bench.")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("demo", help="simulate maneuvering flights, stream, replay through the C core, plot")
    p.add_argument("--out", default="out", metavar="DIR", help="output directory (default out/)")
    p.add_argument("--seed", type=int, default=1)
    p.set_defaults(func=cmd_demo)

    from mcahrs.sim import SCENARIOS

    p = sub.add_parser("simulate", help="write a simulated flight as a wire-format stream file")
    p.add_argument("--scenario", required=True, choices=sorted(SCENARIOS))
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--duration", type=float, default=None, metavar="S", help="flight duration, s")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="simulator override (SimParams field or scenario argument), repeatable")
    p.add_argument("--out", required=True, metavar="FILE")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("replay", help="run a stream file (wire format or plain NMEA) through the C core")
    p.add_argument("file")
    _add_run_options(p)
    p.add_argument("--plot", metavar="PNG", help="write a figure")
    p.add_argument("--csv", metavar="OUT",
                   help="write the filter output per IMU sample (per fix without IMU)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("bench", help="live: read a serial port / pty / socket, run the C core, show status")
    p.add_argument("--port", required=True, metavar="URL",
                   help="device, pty path, socket://host:port, loop:// (pyserial serial_for_url)")
    p.add_argument("--baud", type=int, default=115200)
    p.add_argument("--log", metavar="FILE", help="write every byte read (replay it to reproduce the result)")
    _add_run_options(p)
    p.add_argument("--max-duration", type=float, default=None, metavar="S",
                   help="stop after S s of wall time")
    p.add_argument("--idle-timeout", type=float, default=None, metavar="S",
                   help="stop after S s without a byte (end of data)")
    p.set_defaults(func=cmd_bench)

    for name, text in (("evaluate", "accuracy against a reference (mcahrs.evaluate)"),
                       ("convert", "convert a dataset to the wire format (mcahrs.evaluate)")):
        p = sub.add_parser(name, help=text, add_help=False)
        p.add_argument("args", nargs=argparse.REMAINDER)
    p = sub.add_parser("allan", help="IMU noise parameters from a static recording (mcahrs.allan)",
                       add_help=False)
    p.add_argument("args", nargs=argparse.REMAINDER)
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mcahrs`` console script; returns the exit status."""
    args_list = list(sys.argv[1:] if argv is None else argv)
    if args_list and args_list[0] == "allan":
        return _dispatch_allan(args_list[1:])
    if args_list and args_list[0] in ("evaluate", "convert"):
        return _dispatch_external(args_list[0], args_list[1:])
    args = build_parser().parse_args(args_list)
    try:
        return int(args.func(args))
    except CliError as exc:
        print(f"mcahrs {args.command}: {exc}", file=sys.stderr)
        return 2
    except errors.McaError as exc:
        print(f"mcahrs {args.command}: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())

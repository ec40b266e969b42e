"""Figures of one navigation run: attitude against truth or a reference, the maneuver
acceleration the CS filter removes from the accelerometer, the GPS innovation statistic
with its outlier thresholds, and the GPS track.

Used by ``mcahrs demo`` and ``mcahrs replay --plot``. Only the object-oriented matplotlib
API is used with the Agg canvas (no ``pyplot``, no global backend switch), so importing
this module never opens a window or changes the backend of a user's session.

    data = RunPlotData(title="car_accel_brake", t_s=..., euler_deg={"MCAHRS": e}, ...)
    plot_run(data, "out/car.png")
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

# Colours of the estimates in the order they are given (first: the filter under test).
_EST_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd")
_EST_STYLES = ("-", "--", "-.", ":")
_AXIS_COLOURS = {"N": "#1f77b4", "E": "#d62728", "D": "#2ca02c"}
_AXIS_MARKERS = {"N": "o", "E": "s", "D": "^"}
_MANEUVER_MPS2 = 0.5  # shading: horizontal maneuver acceleration above this


@dataclass
class RunPlotData:
    """Everything :func:`plot_run` draws. Arrays are NumPy; times in seconds on one clock.

    ``euler_deg`` maps a label to (n, 3) roll, pitch, yaw in degrees at ``t_s``; the first
    entry is the main estimate. With ``t_s`` None (a GNSS-only capture) the attitude panels
    say so instead. ``gps_t``/``gps_t_limit``: (m, 3) innovation statistic per fix and N/E/D
    axis and the threshold it is flagged against (NaN where the axis was not measured).
    """

    title: str
    t_s: np.ndarray | None = None
    euler_deg: dict[str, np.ndarray] = field(default_factory=dict)
    ref_euler_deg: np.ndarray | None = None
    ref_label: str = "truth"
    acc_t_s: np.ndarray | None = None
    acc_ned_mps2: np.ndarray | None = None
    acc_label: str = "CS filter"
    ref_acc_ned_mps2: np.ndarray | None = None  # at ``t_s`` (truth of the simulator)
    fix_t_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fix_ned_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    gps_t: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    gps_t_limit: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    limit_label: str = "chi2 threshold"
    est_ned_m: np.ndarray | None = None  # filter position at ``t_s``
    vel_ned_mps: np.ndarray | None = None  # filter velocity at ``acc_t_s`` (drawn for GNSS-only runs)
    fix_speed_mps: np.ndarray | None = None  # speed over ground reported by the fixes
    subtitle: str = ""


def _wrap_deg(x: np.ndarray) -> np.ndarray:
    return (x + 180.0) % 360.0 - 180.0


def _rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def _shade_maneuvers(ax: Axes, t: np.ndarray, acc_h: np.ndarray) -> None:
    """Light background where the horizontal maneuver acceleration is large."""
    on = np.abs(acc_h) > _MANEUVER_MPS2
    if not on.any():
        return
    edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        ax.axvspan(t[a], t[b - 1], color="0.92", lw=0, zorder=0)


def _attitude_panel(ax: Axes, d: RunPlotData, k: int, name: str, maneuver: np.ndarray | None) -> None:
    assert d.t_s is not None
    t = d.t_s
    if maneuver is not None:
        _shade_maneuvers(ax, t, maneuver)
    if d.ref_euler_deg is not None:
        ax.plot(t, d.ref_euler_deg[:, k], color="k", lw=2.4, alpha=0.45, label=d.ref_label, zorder=2)
    for i, (label, e) in enumerate(d.euler_deg.items()):
        text = label
        if d.ref_euler_deg is not None:
            err = _wrap_deg(e[:, k] - d.ref_euler_deg[:, k])
            text = f"{label} (error RMS {_rms(err):.2f}, max {np.nanmax(np.abs(err)):.2f} deg)"
        ax.plot(t, e[:, k], color=_EST_COLOURS[i % 4], ls=_EST_STYLES[i % 4], lw=1.3 if i == 0 else 1.0,
                label=text, zorder=3 + (len(d.euler_deg) - i))
    ax.set_ylabel(f"{name} (deg)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8, framealpha=0.85)


def _error_panel(ax: Axes, d: RunPlotData, maneuver: np.ndarray | None) -> None:
    """|roll| and |pitch| error of every estimate against the reference, log scale."""
    assert d.t_s is not None and d.ref_euler_deg is not None
    if maneuver is not None:
        _shade_maneuvers(ax, d.t_s, maneuver)
    floor = 1e-3
    for i, (label, e) in enumerate(d.euler_deg.items()):
        for k, (name, ls) in enumerate((("roll", "-"), ("pitch", ":"))):
            err = np.abs(_wrap_deg(e[:, k] - d.ref_euler_deg[:, k]))
            ax.semilogy(d.t_s, np.maximum(err, floor), color=_EST_COLOURS[i % 4], ls=ls,
                        lw=1.2 if k == 0 else 1.4, alpha=0.9, label=f"{label}: {name}")
    ax.set_ylim(bottom=0.01)
    ax.set_ylabel("|error| vs " + d.ref_label + " (deg)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="best", fontsize=8, ncol=2, framealpha=0.85)


def _acc_panel(ax: Axes, d: RunPlotData, maneuver: np.ndarray | None) -> None:
    if d.acc_ned_mps2 is None or d.acc_t_s is None:
        ax.text(0.5, 0.5, "no maneuver acceleration (no fixes)", transform=ax.transAxes, ha="center")
        return
    if maneuver is not None and d.t_s is not None:
        _shade_maneuvers(ax, d.t_s, maneuver)
    for k, axis in enumerate("NED"):
        c = _AXIS_COLOURS[axis]
        if d.ref_acc_ned_mps2 is not None and d.t_s is not None:
            ax.plot(d.t_s, d.ref_acc_ned_mps2[:, k], color=c, lw=2.4, alpha=0.3)
        ax.plot(d.acc_t_s, d.acc_ned_mps2[:, k], color=c, lw=1.1, label=f"{axis} ({d.acc_label})",
                marker="." if d.t_s is None else None, ms=3)
    if d.ref_acc_ned_mps2 is not None:
        ax.plot([], [], color="0.4", lw=2.4, alpha=0.3, label="truth (wide, pale)")
    ax.set_ylabel("maneuver accel. NED (m/s$^2$)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8, ncol=2, framealpha=0.85)


def _velocity_panel(ax: Axes, d: RunPlotData) -> None:
    """GNSS-only runs: the filter's velocity per axis and the fixes' speed over ground."""
    if d.vel_ned_mps is None or d.acc_t_s is None:
        ax.text(0.5, 0.5, "no velocity (no fixes)", transform=ax.transAxes, ha="center")
        return
    for k, axis in enumerate("NED"):
        ax.plot(d.acc_t_s, d.vel_ned_mps[:, k], color=_AXIS_COLOURS[axis], lw=1.1, marker=".", ms=3,
                label=f"{axis} ({d.acc_label})")
    if d.fix_speed_mps is not None and np.isfinite(d.fix_speed_mps).any():
        ax.plot(d.fix_t_s, d.fix_speed_mps, ls="none", marker="o", ms=3, mfc="none", color="0.3",
                label="speed over ground (fixes)")
    ax.set_ylabel("velocity NED (m/s)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8, ncol=2, framealpha=0.85)
    ax.set_title("no IMU samples: attitude needs IMU samples ($PMCAI); GNSS fixes and the CS filter only",
                 fontsize=10)


def _innovation_panel(ax: Axes, d: RunPlotData) -> np.ndarray:
    """Plot T per axis and fix; return the (m,) mask of fixes flagged on any axis."""
    flagged = np.zeros(len(d.fix_t_s), bool)
    if len(d.fix_t_s) == 0 or not np.isfinite(d.gps_t).any():
        ax.text(0.5, 0.5, "no GPS innovation statistic (fewer than two usable fixes)",
                transform=ax.transAxes, ha="center", va="center", color="0.35")
        ax.set_xlabel("time (s)")
        return flagged
    t = d.fix_t_s
    floor = 1e-3
    for k, axis in enumerate("NED"):
        v = d.gps_t[:, k]
        ok = np.isfinite(v)
        if ok.any():
            ax.semilogy(t[ok], np.maximum(v[ok], floor), ls="none", marker=_AXIS_MARKERS[axis], ms=3.5,
                        color=_AXIS_COLOURS[axis], alpha=0.75, label=f"T {axis}")
        lim = d.gps_t_limit[:, k]
        out = ok & np.isfinite(lim) & (v > lim)
        flagged |= out
        if out.any():
            ax.semilogy(t[out], v[out], ls="none", marker="o", ms=10, mfc="none", mec="red", mew=1.5)
    for i, lim in enumerate(np.unique(d.gps_t_limit[np.isfinite(d.gps_t_limit)])):
        ax.axhline(lim, color="red", ls=("--", ":", "-.")[i % 3], lw=1.0, alpha=0.7,
                   label=f"{d.limit_label} {lim:.1f}")
    ax.plot([], [], ls="none", marker="o", ms=10, mfc="none", mec="red", mew=1.5,
            label=f"flagged fixes: {int(flagged.sum())}")
    shown = np.concatenate([d.gps_t[np.isfinite(d.gps_t)], d.gps_t_limit[np.isfinite(d.gps_t_limit)]])
    top = float(np.max(shown))
    ax.set_ylim(floor * 0.7, top * 40)  # head room for the legend above the points
    ax.set_ylabel("GPS innovation T = $\\nu^T C^{-1} \\nu$")
    ax.set_xlabel("time (s)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="upper left", fontsize=8, ncol=3, framealpha=0.85)
    ax.set_title("GPS innovation statistic per fix and axis (CS filter update)", fontsize=10)
    return flagged


def _track_panel(ax: Axes, d: RunPlotData, flagged: np.ndarray) -> None:
    ned = d.fix_ned_m
    if len(ned) == 0:
        ax.text(0.5, 0.5, "no GPS fixes", transform=ax.transAxes, ha="center")
        return
    ax.plot(ned[:, 1], ned[:, 0], ls="none", marker=".", ms=4, color="0.45", label=f"GPS fixes ({len(ned)})")
    if d.est_ned_m is not None and len(d.est_ned_m):
        ok = np.isfinite(d.est_ned_m).all(axis=1)
        ax.plot(d.est_ned_m[ok, 1], d.est_ned_m[ok, 0], color=_EST_COLOURS[0], lw=1.2,
                label="filter position")
    if flagged.any():
        ax.plot(ned[flagged, 1], ned[flagged, 0], ls="none", marker="x", ms=8, mew=1.8, color="red",
                label="flagged fix")
    first, last = np.flatnonzero(np.isfinite(ned).all(axis=1))[[0, -1]]
    ax.plot(ned[first, 1], ned[first, 0], marker="^", ms=10, color="#2ca02c", ls="none", label="start",
            zorder=5)
    ax.plot(ned[last, 1], ned[last, 0], marker="s", ms=9, color="#d62728", ls="none", label="end", zorder=5)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8, framealpha=0.85)
    ax.set_title("GPS track (NED from the first fix)", fontsize=10)


def plot_run(data: RunPlotData, path: str | os.PathLike) -> Path:
    """Draw the run and write it to ``path`` (PNG, or any format matplotlib knows by suffix).

    Left: roll, pitch (, their error against the reference when there is one), maneuver
    acceleration; right: GPS track and the GPS innovation statistic. Returns the path.
    """
    d = data
    fig = Figure(figsize=(15, 12 if d.ref_euler_deg is not None else 9.5), layout="constrained")
    FigureCanvasAgg(fig)
    if d.t_s is None or not d.euler_deg:  # GNSS only: velocity and acceleration instead of attitude
        gs = fig.add_gridspec(2, 2, width_ratios=(1.6, 1.0))
        ax_vel = fig.add_subplot(gs[0, 0])
        ax_acc = fig.add_subplot(gs[1, 0], sharex=ax_vel)
        ax_innov = fig.add_subplot(gs[1, 1], sharex=ax_vel)
        _velocity_panel(ax_vel, d)
        _acc_panel(ax_acc, d, None)
        ax_acc.set_xlabel("time (s)")
        _track_panel(fig.add_subplot(gs[0, 1]), d, _innovation_panel(ax_innov, d))
        return _save(fig, d, path)
    with_error = d.ref_euler_deg is not None
    rows = 4 if with_error else 3
    gs = fig.add_gridspec(rows, 2, width_ratios=(1.6, 1.0))
    ax_roll = fig.add_subplot(gs[0, 0])
    ax_pitch = fig.add_subplot(gs[1, 0], sharex=ax_roll)
    ax_err = fig.add_subplot(gs[2, 0], sharex=ax_roll) if with_error else None
    ax_acc = fig.add_subplot(gs[rows - 1, 0], sharex=ax_roll)
    ax_track = fig.add_subplot(gs[0:2, 1])
    ax_innov = fig.add_subplot(gs[2:rows, 1], sharex=ax_roll)

    maneuver = None
    if d.ref_acc_ned_mps2 is not None:
        maneuver = np.hypot(d.ref_acc_ned_mps2[:, 0], d.ref_acc_ned_mps2[:, 1])
    elif d.acc_ned_mps2 is not None and d.t_s is not None and len(d.acc_ned_mps2) == len(d.t_s):
        maneuver = np.hypot(d.acc_ned_mps2[:, 0], d.acc_ned_mps2[:, 1])

    _attitude_panel(ax_roll, d, 0, "roll", maneuver)
    _attitude_panel(ax_pitch, d, 1, "pitch", maneuver)
    if ax_err is not None:
        _error_panel(ax_err, d, maneuver)
    _acc_panel(ax_acc, d, maneuver)
    ax_acc.set_xlabel("time (s)")
    if maneuver is not None:
        ax_roll.set_title("attitude (grey background: horizontal maneuver acceleration > "
                          f"{_MANEUVER_MPS2:g} m/s$^2$)", fontsize=10)
    flagged = _innovation_panel(ax_innov, d)
    _track_panel(ax_track, d, flagged)
    return _save(fig, d, path)


def _save(fig: Figure, d: RunPlotData, path: str | os.PathLike) -> Path:
    fig.suptitle(d.title + (f"\n{d.subtitle}" if d.subtitle else ""), fontsize=12)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    return out

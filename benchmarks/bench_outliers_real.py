"""GNSS faults injected into the real recordings of ../shared/data: the robust profiles on real sensors.

Run: PYTHONPATH=python python benchmarks/bench_outliers_real.py [--data DIR] [--seed N] [--fix-rate HZ]

Prints, never asserts. ``benchmarks/bench_outliers.py`` measures the robust set-ups
(``core.robust_profile``) on the simulator, whose receiver and IMU errors are the model's. Here
the same kinds of fault go into real recordings, each fault alone in its own copy, so what a
profile does with it is measured against the same profile's run without it:

* the PX4 multirotor flight ``log_61`` (EKF2 attitude as reference, 2 Hz fixes), the comma2k19
  highway minute (fused reference pose, 10 Hz) and the RTK car drive (no attitude reference,
  4 Hz); the preset of each as ``mcahrs evaluate --preset auto`` picks it;
* faults (horizontal, random azimuth; positions moved on the WGS-84 ellipsoid as in
  bench_outliers, velocities added to the fix velocity, speed and course of those fixes made to
  match): one epoch of 30 m, one of 3 m/s, a 10 s velocity burst of 2 m/s, a 10 s burst of both
  (20 m and 2 m/s), a 30 s position fault of 30 m (the 100 s one of bench_outliers does not fit
  the short recordings); on the short recordings once, 25 s after the start, on the car at six
  places spread over the drive;
* the CS + gravity filter in each robust profile, then the 15-state INS in each robust mode with
  the real-recording set-up of ``mcahrs evaluate`` (``REAL_INS``: EKF2's accuracy floors and IMU
  noise; its flags: the mode's ``detected``, plain T > chi2_m(0.005));
* per fault and profile: roll/pitch off the profile's outlier-free run (RMS over the fault and the
  10 s after it, deg: the damage the fault did to the attitude), where there is a reference the
  attitude error's RMS over the same span with and without the fault, the share of the fault's
  fixes the profile's rule flags (bench_outliers' rules on the GPS T: plain chi2(0.005), FTA
  chi2(1e-4), AKF chi2(1e-2), the fuzzy detector re-run, IGG-III T > 9), and the position's
  worst distance from the outlier-free run's, during the fault and 10 s after it.

``--fix-rate HZ`` keeps one fix in ``round(rate / HZ)`` of each recording (a slower receiver on the
same drive, e.g. 1 Hz: the comma2k19 minute's 1 in 10, the car's 1 in 4, the PX4 log's 1 in 2),
with the profiles set up for the rate that leaves.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
import types
import warnings
from pathlib import Path

import numpy as np
import pymap3d

from mcahrs import core
from mcahrs.evaluate import (
    REAL_INS,
    auto_preset,
    estimate_ref_lag,
    gyro_only_drift,
    imu_is_interval_mean,
    interp_quat,
    quat_roll_pitch,
    wrap_pi,
)
from mcahrs.samples import Recording

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_outliers as bo  # noqa: E402 - the same rules and profiles as the simulator benchmark

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT / ".." / "shared" / "data"
RECORDINGS = ("ulog/log_61_2024-2-6-16-27-02.ulg", "comma2k19/comma2k19_example1", "car")
START_S = 25.0  # a fault's start on the short recordings, s after the first fix
AFTER_S = 10.0  # the span after a fault that its figures include
CAR_PLACES = 6  # faults of each kind on the long drive

# (name, duration s (0: one epoch), position offset m, velocity offset m/s)
FAULTS = (
    ("30 m jump", 0.0, 30.0, 0.0),
    ("3 m/s spike", 0.0, 0.0, 3.0),
    ("2 m/s 10 s", 10.0, 0.0, 2.0),
    ("both 10 s", 10.0, 20.0, 2.0),
    ("30 m 30 s", 30.0, 30.0, 0.0),
)


def inject(rec: Recording, sel: np.ndarray, pos_m: float, vel_mps: float, az: float) -> Recording:
    """A copy of ``rec`` with a horizontal offset on the fixes ``sel`` (and only there)."""
    g = rec.gnss.copy()
    u = np.array([math.cos(az), math.sin(az), 0.0])
    idx = np.flatnonzero(sel)
    if pos_m:
        off = np.tile(pos_m * u, (idx.size, 1))
        lat0, lon0, h0 = g["lat_e7"][idx] * 1e-7, g["lon_e7"][idx] * 1e-7, g["alt_mm"][idx] * 1e-3
        lat, lon, h = pymap3d.ned2geodetic(off[:, 0], off[:, 1], off[:, 2], lat0, lon0, h0, deg=True)
        g["lat_e7"][idx] = np.round(np.asarray(lat) * 1e7).astype(np.int32)
        g["lon_e7"][idx] = np.round(np.asarray(lon) * 1e7).astype(np.int32)
        g["alt_mm"][idx] = np.round(np.asarray(h) * 1e3).astype(np.int32)
    if vel_mps:
        v = g["vel_ned_mps"].copy()
        v[idx] += vel_mps * u
        g["vel_ned_mps"] = v
        g["speed_mps"][idx] = np.hypot(v[idx, 0], v[idx, 1])
        g["course_rad"][idx] = np.mod(np.arctan2(v[idx, 1], v[idx, 0]), 2.0 * np.pi)
    return dataclasses.replace(rec, name=rec.name + "+fault", gnss=g)


@dataclasses.dataclass
class Replay:
    out: dict[str, np.ndarray]
    rows: np.ndarray  # output row of each fix
    T: np.ndarray  # (n_fix, 3) GPS T per axis
    m: np.ndarray  # (n_fix, 3) rows of each axis' update
    valid: np.ndarray  # fix made a CS update


def replay(rec: Recording, cfg: object) -> Replay:
    out = core.replay(rec, cfg)
    rows = bo.fix_rows(out, rec)
    valid = out["gps_status"] == 0
    valid[int(np.flatnonzero(valid)[0])] = False  # the home fix
    return Replay(out, rows, out["gps_t"][rows].astype(np.float64), bo.measurement_rows(rec.gnss), valid)


def reference_rp(rec: Recording) -> np.ndarray | None:
    """(n_imu, 2) reference roll, pitch at the IMU times (time offset measured as evaluate does)."""
    if rec.ref is None or len(rec.ref) == 0:
        return None
    lag, _ = estimate_ref_lag(rec.imu, rec.ref, interval_mean=imu_is_interval_mean(rec))
    lag = lag if math.isfinite(lag) else 0.0
    t = rec.imu["t_us"].astype(np.int64)
    q = interp_quat(rec.ref["t_us"].astype(np.int64) - int(round(lag * 1e6)), rec.ref["q_nb"], t)
    return np.stack(quat_roll_pitch(q), axis=1)


def rp_rms_deg(d: np.ndarray) -> float:
    d = d[np.all(np.isfinite(d), axis=1)]
    return float(np.degrees(np.sqrt(np.mean(wrap_pi(d) ** 2)))) if d.size else float("nan")


def fault_starts(rec: Recording) -> list[float]:
    """Fault start times (s after the first fix): 25 s on a short recording; CAR_PLACES spread
    over a long one, each with its fault and AFTER_S clear of the next and of the end."""
    t = rec.gnss["t_us"] * 1e-6
    span = float(t[-1] - t[0])
    longest = max(d for _, d, _, _ in FAULTS) + AFTER_S
    if span < 3.0 * START_S + longest:
        return [START_S]
    step = (span - START_S - longest) / (CAR_PLACES - 1)
    return [START_S + k * step for k in range(CAR_PLACES)]


def bench_recording(path: Path, seed: int, fix_rate_hz: float | None = None) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the loaders' notes on the logs' own quirks
        from mcahrs.io.loaders import load

        rec = load(path)
    if fix_rate_hz:
        step = max(1, round(core.fix_rate_hz(rec) / fix_rate_hz))
        rec = dataclasses.replace(rec, gnss=rec.gnss[::step])
    preset, why = auto_preset(rec, path)
    t_fix = rec.gnss["t_us"] * 1e-6
    t0_fix = float(t_fix[0])
    rate_hz = core.fix_rate_hz(rec)
    ref = reference_rp(rec)
    starts = fault_starts(rec)
    print(
        f"\n=== {path.name} (preset {preset}: {why}; {len(rec.gnss)} fixes at {rate_hz:.1f} Hz, "
        f"{t_fix[-1] - t0_fix:.0f} s; {'a' if ref is not None else 'no'} reference attitude; "
        f"faults at {', '.join(f'{s:.0f}' for s in starts)} s) ==="
    )
    filled = int(rec.meta.get("imu_filled_samples", 0))
    if filled:
        print(f"IMU: {filled} samples missing from the log put back by the loader (mcahrs.io.loaders.ulog)")
    rng = np.random.default_rng(seed)
    plans = []
    for name, dur, pos, vel in FAULTS:
        for s in starts:
            a = t0_fix + s
            if dur:
                sel = (t_fix >= a) & (t_fix < a + dur)
            else:
                sel = np.zeros(t_fix.size, bool)
                sel[int(np.argmin(np.abs(t_fix - a)))] = True
            plans.append((name, sel, inject(rec, sel, pos, vel, rng.uniform(0.0, 2.0 * math.pi))))
    cs_runs = []
    for label, mode, profile in bo.MODES:
        cfg = core.nav_config(preset, **core.robust_profile(profile, rate_hz))
        rule = bo.profile_rule(mode, profile)
        cs_runs.append((label, lambda r, cfg=cfg, rule=rule: cs_run(r, cfg, rule)))
    ins_runs = []
    for label, mode, extra in bo.INS_MODES:
        cfg = core.ins_config(preset, robust=mode, **{**REAL_INS, **extra})
        ins_runs.append((label, lambda r, cfg=cfg, mode=mode: ins_run(r, cfg, mode)))
    for what, runs in (
        ("CS + gravity filter, robust profiles", cs_runs),
        ("15-state INS (evaluate's REAL_INS)", ins_runs),
    ):
        results = measure(runs, rec, plans, ref)
        print(f"-- {what}")
        print_tables(results, ref is not None, len(starts) > 1)
    drift = gyro_only_text(rec, preset, starts)
    print(
        "gyro alone from the CS + gravity filter's attitude and bias at each fault start, off its roll/pitch "
        f"after 2 / 5 / 10 s (deg, worst axis; what leaving gravity out costs): {drift}"
    )


def cs_run(rec: Recording, cfg: object, rule: str) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The CS + gravity filter's output, and per fix whether its profile flagged it (the fuzzy
    modes: the C's own alarm; the others: their rule on T; ``bench_outliers.mode_flags``)."""
    r = replay(rec, cfg)
    return r.out, bo.mode_flags(rule, r) & r.valid


def ins_run(rec: Recording, cfg: object, mode: str) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The INS's output, and per fix its ``detected`` flag (plain: T > chi2_m(0.005))."""
    out = core.ins_replay(rec, cfg)
    rows = bo.fix_rows(out, rec)
    valid = out["gps_status"] == 0
    T = out["gps_t"][rows].astype(np.float64)[:, None]
    m = out["gps_m"][rows].astype(int)[:, None]
    ns = types.SimpleNamespace(out=out, rows=rows, valid=valid, T=T, m=m)
    return out, bo.ins_flags(ns, mode)


def measure(
    runs: list, rec: Recording, plans: list, ref: np.ndarray | None
) -> dict[str, dict[str, np.ndarray]]:
    """Per run (label, function of a recording -> output, per-fix flags) and fault: roll/pitch RMS
    off its outlier-free run, share of the fault's fixes flagged, worst position off, and with a
    reference the attitude error's RMS without and with the fault; means over the places."""
    t_fix = rec.gnss["t_us"] * 1e-6
    t_imu = rec.imu["t_us"] * 1e-6
    results: dict[str, dict[str, np.ndarray]] = {}
    for label, run_fn in runs:
        clean, _ = run_fn(rec)
        per: dict[str, list[list[float]]] = {name: [] for name, *_ in FAULTS}
        for name, sel, bad in plans:
            out, flags = run_fn(bad)
            win = (t_imu >= t_fix[sel][0]) & (t_imu < t_fix[sel][-1] + AFTER_S)
            e_run = out["euler_rad"][win, :2].astype(np.float64)
            e_clean = clean["euler_rad"][win, :2].astype(np.float64)
            share = float(np.mean(flags[sel])) if np.any(sel) else float("nan")
            dp = out["pos_ned_m"][win, :2].astype(np.float64) - clean["pos_ned_m"][win, :2]
            row = [rp_rms_deg(e_run - e_clean), share, float(np.hypot(dp[:, 0], dp[:, 1]).max())]
            if ref is not None:
                row += [rp_rms_deg(e_clean - ref[win]), rp_rms_deg(e_run - ref[win])]
            per[name].append(row)
        results[label] = {name: np.mean(np.array(v), axis=0) for name, v in per.items()}
    return results


def print_tables(results: dict[str, dict[str, np.ndarray]], with_ref: bool, places: bool) -> None:
    head = f"{'profile':12s}" + "".join(f"{name:>13s}" for name, *_ in FAULTS)
    tables = [
        ("roll/pitch RMS off the outlier-free run, deg (fault + 10 s)", lambda v: f"{v[0]:13.2f}"),
        ("share of the fault's fixes flagged", lambda v: f"{100.0 * v[1]:12.0f}%"),
        ("worst horizontal position off the outlier-free run, m", lambda v: f"{v[2]:13.1f}"),
    ]
    if with_ref:
        tables.append(
            (
                "roll/pitch RMS error against the reference, deg: outlier-free -> with the fault",
                lambda v: f"{v[3]:7.2f}>{v[4]:5.2f}",
            )
        )
    for title, cell in tables:
        print(f"{title}{', mean of the places' if places else ''}:")
        print(head)
        for label, res in results.items():
            print(f"{label:12s}" + "".join(cell(res[name]) for name, *_ in FAULTS))


def gyro_only_text(rec: Recording, preset: str, starts: list[float]) -> str:
    """The worst, over the fault starts, of ``evaluate.gyro_only_drift`` from the plain filter."""
    out = core.replay(rec, core.nav_config(preset))
    t0_us = int(rec.gnss["t_us"][0])
    drift = gyro_only_drift(rec, out, [t0_us + round(s * 1e6) for s in starts])
    return " / ".join(f"{v:.2f}" for v in np.nanmax(drift, axis=0))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the shared data folder")
    ap.add_argument("--seed", type=int, default=1, help="fault azimuths")
    ap.add_argument(
        "--fix-rate", type=float, metavar="HZ", help="keep one fix in round(rate / HZ): a slower receiver"
    )
    args = ap.parse_args()
    t_start = time.perf_counter()
    data = args.data.resolve()
    print(
        "GNSS faults injected into real recordings, each alone; the robust profiles of core.robust_profile."
        + (f" Fixes thinned to about {args.fix_rate:g} Hz." if args.fix_rate else "")
    )
    for rel in RECORDINGS:
        path = data / rel
        if not path.exists():
            print(f"\n{path}: not present, skipped")
            continue
        bench_recording(path, args.seed, args.fix_rate)
    print(f"\nrun time {time.perf_counter() - t_start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())

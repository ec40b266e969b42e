"""The loosely-coupled INS (DESIGN.md 6, docs/ALGORITHMS.md 10) against the CS + gravity filter.

Run: PYTHONPATH=python python benchmarks/bench_ins.py [--seeds 1 2] [--no-real]

Prints, never asserts:

1. simulator scenarios: INS position / velocity / attitude RMS against the truth, beside the
   CS + gravity navigation filter's (``core.replay``) roll/pitch RMS on the same data, and the
   host time per IMU sample of both;
2. GPS outages of 10, 30 and 60 s (``gps_outage`` scenario, fixed-wing, car, multirotor): INS
   position drift at the end of the outage, roll/pitch of both filters during and after it;
3. GNSS outliers: measured by benchmarks/bench_outliers.py, which runs its fault set through the
   INS too (``--ins-only``), per robust mode, with detections and false alarms;
4. real recordings from ../shared/data when present (loaders of mcahrs.io.loaders; the INS with
   EKF2's accuracy floors and IMU noise, mcahrs.evaluate.REAL_INS): the car
   (RTK fixes, no attitude reference: INS drift against the withheld RTK fixes in outages, the
   two filters' roll/pitch against each other and against the levelled static start),
   comma2k19 (reference pose) and the PX4 ULog (EKF2 attitude as reference);
5. Cortex-M4F instruction counts: measured by scripts/fw_report.py (section 4b, INS beside CS + gravity).

Simulator runs use ``earth_rate=True`` (the gyros sense the earth's rotation, which the INS
removes; the simulator's accelerometers have no Coriolis term, <= 4 mm/s^2 at 25 m/s, which the
INS cannot tell from an accelerometer bias).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np
import pymap3d

from mcahrs import core
from mcahrs.evaluate import REAL_INS
from mcahrs.samples import Recording
from mcahrs.sim import quat_to_euler, scenario

sys.path.insert(0, str(Path(__file__).resolve().parent))
DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
SIM = {"car_accel_brake": "ground", "fixedwing_turns": "fixedwing", "multirotor_aggressive": "multirotor"}
OUTAGE_VEHICLES = {"fixedwing": "fixedwing", "car": "ground", "multirotor": "multirotor"}


def rms(x: np.ndarray) -> float:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def wrap_deg(a: np.ndarray) -> np.ndarray:
    return (a + 180.0) % 360.0 - 180.0


def home_offset(rec: Recording, home_deg: tuple[float, float, float]) -> np.ndarray:
    """NED (in the frame of ``home_deg``) of the INS home, its first fix with fix_type >= 2."""
    g = rec.gnss[np.flatnonzero(rec.gnss["fix_type"] >= 2)[0]]
    return np.array(
        pymap3d.geodetic2ned(g["lat_e7"] * 1e-7, g["lon_e7"] * 1e-7, g["alt_mm"] * 1e-3, *home_deg)
    )


def sim_home(res) -> tuple[float, float, float]:
    p = res.params
    return p.home_lat_deg, p.home_lon_deg, p.home_alt_m


def euler_err_deg(euler_rad: np.ndarray, ref_euler_rad: np.ndarray) -> np.ndarray:
    return wrap_deg(np.degrees(np.asarray(euler_rad, float) - ref_euler_rad))


def ins_valid(out: dict) -> np.ndarray:
    want = core.INS_FLAG_BITS["nav"] | core.INS_FLAG_BITS["yaw_aligned"]
    return (out["flags"] & want) == want


def nav_valid(out: dict) -> np.ndarray:
    return (out["flags"] & core.FLAG_BITS["aligned"]) != 0


def timed(fn, *a):
    t0 = time.perf_counter()
    out = fn(*a)
    return out, time.perf_counter() - t0


def without_fixes(rec: Recording, windows: list[tuple[float, float]]) -> Recording:
    """A copy without the fixes valid in the windows (s from the first IMU sample)."""
    t = (rec.gnss["t_us"].astype(np.int64) - int(rec.imu["t_us"][0])) * 1e-6
    keep = np.ones(len(t), bool)
    for a, b in windows:
        keep &= ~((t >= a) & (t < b))
    return dataclasses.replace(rec, gnss=rec.gnss[keep])


# ------------------------------------------------------------------------------ 1. simulator


def bench_sim(seeds: list[int]) -> None:
    print(
        "\n1. Simulator scenarios (errors against the truth, mean over seeds "
        f"{seeds}; INS from navigation start + yaw alignment, CS+gravity from its alignment)"
    )
    print(
        f"{'scenario':24s} {'INS pos':>8s} {'INS vel':>8s} {'INS roll':>8s} {'pitch':>6s} {'yaw':>6s}  "
        f"{'CS+g roll':>9s} {'pitch':>6s}  {'us/IMU INS':>10s} {'CS+g':>6s}"
    )
    for name, preset in SIM.items():
        rows = []
        for seed in seeds:
            res = scenario(name, seed=seed, earth_rate=True)
            rec, tr = res.recording, res.truth
            ins, t_ins = timed(core.ins_replay, rec, core.ins_config(preset))
            nav, t_nav = timed(core.replay, rec, core.nav_config(preset))
            m = ins_valid(ins)
            pe = np.linalg.norm(ins["pos_ned_m"] + home_offset(rec, sim_home(res)) - tr.pos_ned_m, axis=1)[m]
            ve = np.linalg.norm(ins["vel_ned_mps"] - tr.vel_ned_mps, axis=1)[m]
            ei = euler_err_deg(ins["euler_rad"], tr.euler_rad)[m]
            en = euler_err_deg(nav["euler_rad"], tr.euler_rad)[nav_valid(nav)]
            n = len(rec.imu)
            rows.append(
                [
                    rms(pe),
                    rms(ve),
                    rms(ei[:, 0]),
                    rms(ei[:, 1]),
                    rms(ei[:, 2]),
                    rms(en[:, 0]),
                    rms(en[:, 1]),
                    1e6 * t_ins / n,
                    1e6 * t_nav / n,
                ]
            )
        r = np.mean(rows, axis=0)
        print(
            f"{name:24s} {r[0]:7.2f}m {r[1]:6.3f}/s {r[2]:7.3f}d {r[3]:6.3f} {r[4]:6.3f}  {r[5]:8.3f}d "
            f"{r[6]:6.3f}  {r[7]:10.2f} {r[8]:6.2f}"
        )
    print("(position: the GNSS error is a 2.5 m / 5 m Gauss-Markov process the INS follows; deg RMS)")


# ------------------------------------------------------------------------------ 2. outages


def bench_outages(seeds: list[int]) -> None:
    print(
        "\n2. GPS outages (gps_outage scenario, 180 s, outage centred; mean over seeds "
        f"{seeds}). Drift = INS position error at the outage end minus at its start."
    )
    print(
        f"{'vehicle':10s} {'outage':>6s} {'drift':>7s} {'err end':>8s}  {'INS r/p max in':>14s} "
        f"{'10 s after':>10s}  {'CS+g r/p max in':>15s} {'10 s after':>10s}"
    )
    for vehicle, preset in OUTAGE_VEHICLES.items():
        for length in (10, 30, 60):
            rows = []
            for seed in seeds:
                res = scenario(
                    "gps_outage",
                    seed=seed,
                    vehicle=vehicle,
                    outage_s=length,
                    duration_s=180.0,
                    earth_rate=True,
                )
                rec, tr = res.recording, res.truth
                ins = core.ins_replay(rec, core.ins_config(preset))
                nav = core.replay(rec, core.nav_config(preset))
                t = (rec.imu["t_us"] - rec.imu["t_us"][0]) * 1e-6
                a, b = 90.0 - length / 2, 90.0 + length / 2
                k0, k1 = np.searchsorted(t, a), np.searchsorted(t, b)
                during, after = slice(k0, k1), (t >= b) & (t < b + 10.0)
                err = np.linalg.norm(
                    ins["pos_ned_m"] + home_offset(rec, sim_home(res)) - tr.pos_ned_m, axis=1
                )
                ei = np.abs(euler_err_deg(ins["euler_rad"], tr.euler_rad)[:, :2])
                en = np.abs(euler_err_deg(nav["euler_rad"], tr.euler_rad)[:, :2])
                rows.append(
                    [
                        err[k1] - err[k0],
                        err[k1],
                        ei[during].max(),
                        rms(ei[after]),
                        en[during].max(),
                        rms(en[after]),
                    ]
                )
            r = np.mean(rows, axis=0)
            print(
                f"{vehicle:10s} {length:5d}s {r[0]:6.1f}m {r[1]:7.1f}m  {r[2]:13.2f}d {r[3]:9.2f}d  "
                f"{r[4]:14.2f}d {r[5]:9.2f}d"
            )
    print("(roll/pitch 'max in' = largest |error| during the outage; '10 s after' = RMS over 10 s after)")


# ------------------------------------------------------------------------------ 4. real data


def _nearest(t_from: np.ndarray, t_to: np.ndarray) -> np.ndarray:
    i = np.clip(np.searchsorted(t_from, t_to), 1, len(t_from) - 1)
    return np.where(np.abs(t_from[i - 1] - t_to) <= np.abs(t_from[i] - t_to), i - 1, i)


def _fix_ned(rec: Recording, home: tuple[float, float, float]) -> np.ndarray:
    g = rec.gnss
    return np.stack(
        pymap3d.geodetic2ned(g["lat_e7"] * 1e-7, g["lon_e7"] * 1e-7, g["alt_mm"] * 1e-3, *home), axis=1
    )


def bench_real_one(label: str, rec: Recording, preset: str, ins_over: dict, outages: tuple[int, ...]) -> None:
    t = (rec.imu["t_us"].astype(np.int64) - int(rec.imu["t_us"][0])) * 1e-6
    dur = t[-1]
    ins = core.ins_replay(rec, core.ins_config(preset, **ins_over, **REAL_INS))
    nav = core.replay(rec, core.nav_config(preset))
    mi, mn = ins_valid(ins), nav_valid(nav)
    print(
        f"\n  {label}: {dur:.0f} s, {len(rec.imu)} IMU, {len(rec.gnss)} fixes, {len(rec.mag)} mag; INS "
        f"statuses imu {np.bincount(ins['imu_status'], minlength=1)[0]}/{len(rec.imu)} OK, gps "
        f"{np.count_nonzero(ins['gps_status'] == 0)}/{len(rec.gnss)} OK; updates {ins['n_gps_upd'][-1]}, "
        f"rejected {ins['n_gps_rej'][-1]}, skipped {ins['n_gps_skip'][-1]}; "
        f"navigating {mi.mean():.0%} of samples"
    )
    g0 = rec.gnss[np.flatnonzero(rec.gnss["fix_type"] >= 2)[0]]
    home = (g0["lat_e7"] * 1e-7, g0["lon_e7"] * 1e-7, g0["alt_mm"] * 1e-3)
    fix = _fix_ned(rec, home)
    k = _nearest(rec.imu["t_us"].astype(np.int64), rec.gnss["t_us"].astype(np.int64))
    ok = mi[k]
    res_h = np.linalg.norm((ins["pos_ned_m"][k] - fix)[ok, :2], axis=1)
    res_v = np.linalg.norm((ins["vel_ned_mps"][k] - np.nan_to_num(rec.gnss["vel_ned_mps"]))[ok], axis=1)
    print(
        f"    INS vs its fixes at their validity time: horizontal position RMS {rms(res_h):.2f} m, "
        f"velocity RMS {rms(res_v):.3f} m/s"
    )
    both = mi & mn
    d = euler_err_deg(ins["euler_rad"], nav["euler_rad"].astype(float))[both]
    print(
        f"    INS minus CS+gravity roll/pitch: RMS {rms(d[:, 0]):.2f} / {rms(d[:, 1]):.2f} deg, "
        f"max {np.abs(d[:, 0]).max():.2f} / {np.abs(d[:, 1]).max():.2f} deg"
    )
    if rec.ref is not None and len(rec.ref):
        j = _nearest(rec.ref["t_us"].astype(np.int64), rec.imu["t_us"].astype(np.int64))
        ref_e = quat_to_euler(rec.ref["q_nb"][j])
        for nm, out, m in (("INS", ins, mi), ("CS+gravity", nav, mn)):
            e = euler_err_deg(out["euler_rad"], ref_e)[m]
            print(
                f"    {nm:10s} vs reference: roll RMS {rms(e[:, 0]):.2f} deg, "
                f"pitch RMS {rms(e[:, 1]):.2f} deg "
                f"(max {np.abs(e[:, 0]).max():.2f} / {np.abs(e[:, 1]).max():.2f})"
            )
    for length in outages:
        a = 0.5 * dur - 0.5 * length
        if a < 10.0:
            continue
        b = a + length
        cut = without_fixes(rec, [(a, b)])
        o_ins = core.ins_replay(cut, core.ins_config(preset, **ins_over, **REAL_INS))
        o_nav = core.replay(cut, core.nav_config(preset))
        tf = (rec.gnss["t_us"].astype(np.int64) - int(rec.imu["t_us"][0])) * 1e-6
        inside = (tf >= a) & (tf < b)
        kk = k[inside]
        drift = np.linalg.norm((o_ins["pos_ned_m"][kk] - fix[inside])[:, :2], axis=1)
        w = (t >= a) & (t < b)
        after = (t >= b) & (t < b + 10.0)
        line = (
            f"    outage {length:2d} s ({a:.0f}-{b:.0f} s): INS horizontal error vs withheld fixes at end "
            f"{drift[-1]:.2f} m (max {drift.max():.2f} m)"
        )
        if rec.ref is not None and len(rec.ref):
            j = _nearest(rec.ref["t_us"].astype(np.int64), rec.imu["t_us"].astype(np.int64))
            ref_e = quat_to_euler(rec.ref["q_nb"][j])
            ei = np.abs(euler_err_deg(o_ins["euler_rad"], ref_e)[:, :2])
            en = np.abs(euler_err_deg(o_nav["euler_rad"], ref_e)[:, :2])
            line += (
                f"; r/p vs reference max during INS {ei[w].max():.2f} / CS+g {en[w].max():.2f} deg, "
                f"10 s after RMS {rms(ei[after]):.2f} / {rms(en[after]):.2f} deg"
            )
        else:
            dd = np.abs(euler_err_deg(o_ins["euler_rad"], ins["euler_rad"].astype(float))[:, :2])
            line += f"; INS r/p change from the GNSS-aided run max during {dd[w].max():.2f} deg"
        print(line)


def bench_real() -> None:
    from mcahrs.io.loaders import LoaderError, load

    print("\n4. Real recordings (../shared/data)")
    if not DATA.exists():
        print(f"  {DATA} not present: skipped")
        return
    sets = (
        (
            "car (RTK, roof IMU, no attitude reference)",
            DATA / "car",
            "ground",
            {"lever_arm_b_m": [0.0, -0.05, 0.0]},
            (10, 30, 60),
        ),
        (
            "comma2k19 highway (reference pose)",
            DATA / "comma2k19" / "comma2k19_example1",
            "ground",
            {},
            (10, 30),
        ),
        (
            "PX4 ULog multirotor (EKF2 as reference)",
            DATA / "ulog" / "log_61_2024-2-6-16-27-02.ulg",
            "multirotor",
            {},
            (10, 30),
        ),
    )
    for label, path, preset, over, outages in sets:
        if not path.exists():
            print(f"  {label}: {path} not present, skipped")
            continue
        try:
            rec = load(path)
        except LoaderError as exc:
            print(f"  {label}: cannot load ({exc})")
            continue
        bench_real_one(label, rec, preset, over, outages)
    car = DATA / "car"
    if car.exists():
        rec = load(car)
        t = (rec.imu["t_us"] - rec.imu["t_us"][0]) * 1e-6
        still = t < 20.0
        f = rec.imu["accel_mps2"][still].mean(axis=0)
        lev = np.degrees([math.atan2(-f[1], -f[2]), math.atan2(f[0], math.hypot(f[1], f[2]))])
        ins = core.ins_replay(
            rec, core.ins_config("ground", lever_arm_b_m=[0.0, -0.05, 0.0], **REAL_INS)
        )
        nav = core.replay(rec, core.nav_config("ground"))
        k = np.searchsorted(t, 15.0)
        print(
            f"  car static start: levelled accelerometer roll/pitch {lev[0]:.2f} / {lev[1]:.2f} deg; "
            f"at 15 s INS {np.degrees(ins['euler_rad'][k, 0]):.2f} / "
            f"{np.degrees(ins['euler_rad'][k, 1]):.2f}, CS+gravity "
            f"{np.degrees(nav['euler_rad'][k, 0]):.2f} / {np.degrees(nav['euler_rad'][k, 1]):.2f} deg"
        )


# ------------------------------------------------------------------------------ main


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--no-real", action="store_true")
    args = ap.parse_args()
    t0 = time.perf_counter()
    print(
        "INS benchmark: C loosely-coupled INS (core.ins_replay) and C CS+gravity filter (core.replay), "
        "default configurations of each vehicle preset."
    )
    bench_sim(args.seeds)
    bench_outages(args.seeds)
    print("\n3. GNSS outliers on the INS, per robust mode, with detections and false alarms:")
    print("   python benchmarks/bench_outliers.py --ins-only (the faults the CS + gravity filter gets)")
    if not args.no_real:
        bench_real()
    print("\n5. Cortex-M4F instruction counts of the INS and of the CS + gravity filter, side by side:")
    print("   python scripts/fw_report.py (section 4b; QEMU -icount, exact counts per step and update)")
    print(f"\nrun time {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()

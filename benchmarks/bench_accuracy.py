"""Roll/pitch accuracy of the C navigation filter on the simulator's scenarios, with
maneuver compensation by the CS filter (MCAHRS), with compensation off (plain gravity),
and with GPS velocity differencing (what common autopilots do); and during a 60 s GPS
outage, against gyro-only integration. Prints figures and the goals beside them.

Run: python benchmarks/bench_accuracy.py [--seeds 1 2 3]
"""

from __future__ import annotations

import argparse

import numpy as np

from mcahrs import core
from mcahrs.sim import scenario
from mcahrs.sim.truth import quat_mul, quat_to_euler

SCENARIOS = {  # scenario -> vehicle-class preset
    "car_accel_brake": "ground",
    "fixedwing_turns": "fixedwing",
    "multirotor_aggressive": "multirotor",
    "gps_outage": "fixedwing",
}
MODES = {"MCAHRS (CS)": 1, "compensation off": 0, "velocity differencing": 2}


def rp_errors_deg(out: dict, truth_euler: np.ndarray) -> np.ndarray:
    """Roll/pitch error (deg) of every aligned output row; NaN before alignment."""
    err = np.degrees(out["euler_rad"][:, :2].astype(np.float64) - truth_euler[:, :2])
    err[:, 0] = (err[:, 0] + 180.0) % 360.0 - 180.0
    err[(out["flags"] & core.FLAG_BITS["aligned"]) == 0] = np.nan
    return err


def gyro_only(q0: np.ndarray, bias: np.ndarray, gyro: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Integrate body rates (minus a constant bias) from q0: exact rotation per step."""
    q = np.empty((len(gyro), 4))
    cur = q0 / np.linalg.norm(q0)
    for k in range(len(gyro)):
        rv = (gyro[k] - bias) * dt[k]
        a = np.linalg.norm(rv)
        dq = (
            np.array([1.0, 0, 0, 0])
            if a < 1e-12
            else np.concatenate([[np.cos(a / 2)], np.sin(a / 2) * rv / a])
        )
        cur = quat_mul(cur, dq)
        q[k] = cur
    return q


def rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    args = ap.parse_args()
    print("Roll/pitch error (deg) against simulated truth; mean over seeds", args.seeds)
    print(
        f"{'scenario':24s} {'method':22s} {'roll RMS':>8s} {'pitch RMS':>9s} "
        f"{'roll max':>8s} {'pitch max':>9s}"
    )
    table: dict[tuple[str, str], np.ndarray] = {}
    for name, preset in SCENARIOS.items():
        for label, mode in MODES.items():
            figs = []
            for seed in args.seeds:
                s = scenario(name, seed=seed)
                out = core.replay(s.recording, core.nav_config(preset, comp_mode=mode))
                e = rp_errors_deg(out, s.truth.euler_rad)
                figs.append(
                    [rms(e[:, 0]), rms(e[:, 1]), np.nanmax(np.abs(e[:, 0])), np.nanmax(np.abs(e[:, 1]))]
                )
            f = np.mean(figs, axis=0)
            table[(name, label)] = f
            print(f"{name:24s} {label:22s} {f[0]:8.2f} {f[1]:9.2f} {f[2]:8.2f} {f[3]:9.2f}")
    car_on, car_off = (
        table[("car_accel_brake", "MCAHRS (CS)")],
        table[("car_accel_brake", "compensation off")],
    )
    print(
        f"\nGoal: car 0->60 km/h pitch RMS >= 5x lower than compensation off: "
        f"{car_off[1]:.2f} / {car_on[1]:.2f} = {car_off[1] / car_on[1]:.1f}x (paper ~11x)"
    )
    print("Goal: MCAHRS below velocity differencing in every maneuver scenario (roll+pitch RMS):")
    for name in SCENARIOS:
        a, b = table[(name, "MCAHRS (CS)")], table[(name, "velocity differencing")]
        print(
            f"  {name:24s} MCAHRS {np.hypot(a[0], a[1]):.2f}  differencing {np.hypot(b[0], b[1]):.2f}  "
            f"{'met' if np.hypot(a[0], a[1]) < np.hypot(b[0], b[1]) else 'MISSED'}"
        )

    print("\nGPS outage (60 s without fixes in the middle of maneuvers), fixed-wing preset:")
    rows = []
    for seed in args.seeds:
        s = scenario("gps_outage", seed=seed)
        t0, t1 = s.params.gps_outages[0]
        t = (s.recording.imu["t_us"] - s.recording.imu["t_us"][0]) * 1e-6
        during = (t >= t0) & (t < t1)
        after = (t >= t1) & (t < t1 + 30.0)
        out = core.replay(s.recording, core.nav_config("fixedwing"))
        e = rp_errors_deg(out, s.truth.euler_rad)
        k0 = int(np.argmax(t >= t0))
        gyro, dt = (
            s.recording.imu["gyro_rps"],
            np.diff(s.recording.imu["t_us"], prepend=s.recording.imu["t_us"][0]) * 1e-6,
        )
        # gyro only from the outage start, with the filter's own attitude and bias estimate there
        q_go = gyro_only(
            out["q_nb"][k0].astype(np.float64),
            out["gyro_bias_rps"][k0].astype(np.float64),
            gyro[k0:],
            dt[k0:],
        )
        e_go = np.degrees(quat_to_euler(q_go)[:, :2] - s.truth.euler_rad[k0:, :2])
        # gyro only over the whole flight from the true initial attitude, no bias estimate
        q_raw = gyro_only(s.truth.q_nb[0], np.zeros(3), gyro, dt)
        e_raw = np.degrees(quat_to_euler(q_raw)[:, :2] - s.truth.euler_rad[:, :2])
        sel = during[k0:]
        rows.append(
            [
                rms(e[during]),
                np.nanmax(np.abs(e[during])),
                rms(e[after]),
                rms(e_go[sel]),
                np.max(np.abs(e_go[sel])),
                rms(e_raw[during]),
                np.max(np.abs(e_raw[during])),
            ]
        )
    r = np.mean(rows, axis=0)
    print(
        f"  MCAHRS during outage:            RMS {r[0]:.2f} deg, max {r[1]:.2f} deg; "
        f"30 s after: RMS {r[2]:.2f} deg"
    )
    print(
        f"  gyro only from outage start:     RMS {r[3]:.2f} deg, max {r[4]:.2f} deg "
        "(starting from the filter's attitude and bias estimate)"
    )
    print(f"  gyro only from take-off:         RMS {r[5]:.2f} deg, max {r[6]:.2f} deg (no bias estimate)")
    print("  Goal: error bounded during the outage and far below gyro-only integration")


if __name__ == "__main__":
    main()

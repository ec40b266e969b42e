"""GNSS outlier benchmark of the C navigation filter, once per robust update mode (DESIGN.md 5).

Run: PYTHONPATH=python python benchmarks/bench_outliers.py [--seed N] [--duration S]
     [--scenario NAME ...] [--cs-only] [--own-test] [--cs-white] [--no-ins | --ins-only]
     [--cs-seeds 1-4] [--ins-seeds 1-8]   (several seeds: the summaries only, every goal a seed,
                                           and how many seeds meet each goal)
     [--modes fuzzy-rows,...]   (CS + gravity: these robust profiles only, beside plain)
     [--sim NAME=VALUE ...]   (simulator parameters, e.g. a gyro scale-factor error)
     [--set NAME=VALUE ...]   (navigation configuration of the CS + gravity runs, e.g.
                               imu_acc_sigma_mps2=0.15)

Prints, never asserts. For each simulator scenario it injects GNSS faults the way the detection
paper (001, section 3.2) tests them, and replays the clean and the faulty recording through the C
filter (``core.replay``) in every mode: 0 plain, 1 FTA, 2 AKF, 3 fuzzy (reject, inflate, and
rows: the CS axes coasting on the IMU while a row is out, see ``MODES``), 4 IGG-III, set on the
three CS axes (``cs_h``, ``cs_v``) and on the attitude filter (``att``; ``--cs-only`` leaves the
attitude filter plain), with the simulator's receiver modelled (``cs_receiver_model``,
ALGORITHMS.md 8, GPS step 4: the white 0.3 / 0.5 m of its position error as R, its 2.5 / 5 m,
60 s Gauss-Markov part in the CS GPS-error state, as the INS below models it; ``--cs-white`` takes
the reported accuracies as white instead, as before session 16). The CS updates' robust decisions
test the GPS against the IMU-aided prediction (ALGORITHMS.md 8, GPS step 3, the default
``gps_test_imu = 1``); ``--own-test`` runs
them on the CS filter's own constant-acceleration prediction instead, for comparison. A fix the
CS robust mode flags feeds no attitude observation (ALGORITHMS.md 8, GPS step 6), so the roll/pitch
figures measure the detector as much as the attitude filter's own robust mode.

Faults (horizontal, random azimuth; lat/lon moved with the exact geodetic conversion,
``pymap3d.ned2geodetic``; velocity added to ``vel_ned_mps``), nothing in the first 60 s:

* 20 single-epoch faults, 60-300 s, alternating position jumps 5-50 m and velocity spikes 1-5 m/s;
* 12 bursts of 10-20 s, from 300 s, 10-15 s apart; a constant offset each, cycling position,
  velocity, both (same ranges);
* one 100 s long fault from 680 s: a 30 m position offset (a positioning fault, as in paper 001;
  the velocity stays good, so a mode that keeps the velocity row can ride it out).

Per mode it prints roll/pitch RMS error against the truth (clean run, faulty run, ratio), position
and velocity RMS (3-D), and per-fix detections, misses and false alarms, per axis; a fix counts as
flagged when any axis is. The replay output carries each CS axis' fuzzy alarm (flags
``alarm_n/e/d``) and ``gps_t`` (the last GPS T per axis), so detection is:

* plain: the usual single threshold T > chi2_m(0.005) (the plain filter itself detects nothing);
* FTA: T > chi2_m(1e-4) (gamma > 1); AKF: T > chi2_m(1e-2);
* fuzzy, fuzzy-inflate, fuzzy-rows: the C's own alarm after each fix. (Until session 15 the
  three-threshold rule was re-run on the printed T with the golden model: the same figures on
  seeds 9-40; on 73-104 seeds 73, 79 and 97 differ by a point, not traced. The table of
  detectors on the plain filter's T still re-runs it.);
* IGG-III: T > k1^2 (per-row weights are not in the output; a row can only be removed when its
  standardised residual exceeds k1, which needs T > k1^2).

The same faults then go through the loosely-coupled INS (``core.ins_replay``, ALGORITHMS.md 10;
the simulator with earth rate, which the INS removes), the kind of filter paper 001 tests, once per
robust mode on its GNSS update (position and velocity blocks, each with its own memory). Its output
carries per-fix flags, so there detection is the mode's own ``detected`` flag (fuzzy: its alarm;
plain: T > chi2_m(0.005) on the update's T, the sum over its blocks); the same scores and goals.

Baseline for false alarms: the 4-epoch sliding-window chi-square detector on the same T (sum of the
last 4 epochs' T of an axis > chi2 with the summed m, at 0.005), as in paper 001.
False alarms are counted twice: on the clean fixes of the run with outliers (nearly all of them
come within 10 s after a fault ends, while the filter sheds what it let in: the fix is clean, the
state is not; the benchmark prints how many) and on the outlier-free run (alarms with nothing
wrong). Per fault it also prints whether each mode's rule flagged it at all, and after how many
fixes, and per fault class (``FAULT_CLASSES``: single, burst or the 100 s fault; position,
velocity or both; small or large) the share of its fixes each mode flagged, per scenario and, with
``--cs-seeds`` / ``--ins-seeds``, over the seeds.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import dataclasses
import io
import math
import time
from collections.abc import Sequence

import numpy as np
import pymap3d

from mcahrs import core
from mcahrs.cli import parse_overrides
from mcahrs.golden.robust import chi2_quantile, fuzzy_detector_step
from mcahrs.samples import GNSS_HAS_ALT, GNSS_HAS_VEL_D, GNSS_HAS_VEL_NE, Recording
from mcahrs.sim import scenario

# scenario -> nav preset
SCENARIOS = {
    "fixedwing_turns": "fixedwing",
    "multirotor_aggressive": "multirotor",
    "car_accel_brake": "ground",
}
# (label, mca_robust_config_t.mode, robust profile: core.robust_profile, the set-ups a user selects
# with `mcahrs replay --robust`). fuzzy-rows: the rows that fail their own test are left out
# (ALGORITHMS.md 5) with the CS filters coasting on the IMU while the velocity row is out
# (ALGORITHMS.md 2); its
# lock-up guard 20 s of whole rejections in a row (100 at 5 Hz: how long the CS filter coasts on an
# IMU it has no bias estimate for), no row guard (a position left out while the velocity is
# applied does not run open loop; the row guard would let the 100 s fault in after 10 s).
MODES = (
    ("plain", 0, "plain"),
    ("FTA", 1, "fta"),
    ("AKF", 2, "akf"),
    ("fuzzy", 3, "fuzzy"),
    ("fuzzy-infl", 3, "fuzzy-inflate"),
    ("IGG-III", 4, "igg3"),
    ("fuzzy-rows", 3, "fuzzy-rows"),
)
IGG_K1 = 3.0  # mca_robust_config_t default igg_k1; the IGG-III detection proxy is T > k1^2

CLEAN_UNTIL_S = 60.0
SINGLES = dict(start_s=60.0, period_s=12.0, count=20)
BURSTS = dict(start_s=300.0, count=12, length_s=(10.0, 20.0), gap_s=(10.0, 15.0))
LONG = dict(start_s=680.0, length_s=100.0, pos_m=30.0, vel_mps=0.0)
POS_JUMP_M = (5.0, 50.0)
VEL_SPIKE_MPS = (1.0, 5.0)
SETTLE_S = 30.0  # errors are averaged from the first fix + this (alignment and CS convergence)
SW_LEN = 4  # sliding-window length (paper 001: 4)
SW_ALPHA = 0.005
AFTER_FAULT_S = 10.0  # false alarms this soon after a fault ends are counted apart

KIND_NAMES = {1: "single", 2: "burst", 3: "long"}

# Goals (from the brief and papers 000/001), printed beside the figures.
GOAL_ROBUST_RP_RATIO = 1.20
GOAL_PLAIN_RP_RATIO = 2.0
GOAL_FUZZY_DETECTION = 0.98
GOAL_FUZZY_FA_CUT = 0.80
GOAL_RECOVERY_FIXES = 5
DIVERGED_M = 100.0  # horizontal error that counts as divergence under the long fault


# --------------------------------------------------------------------------------------
# Faults
# --------------------------------------------------------------------------------------


@dataclasses.dataclass
class Faults:
    """Per-fix truth of the injected faults."""

    pos_ned_m: np.ndarray  # (n, 3) offset added to the fix position
    vel_ned_mps: np.ndarray  # (n, 3) offset added to the fix velocity
    kind: np.ndarray  # (n,) 0 clean, 1 single, 2 burst, 3 long
    long_window_s: tuple[float, float]

    @property
    def faulty(self) -> np.ndarray:
        return self.kind > 0


def _horizontal(rng: np.random.Generator, lo_hi: tuple[float, float]) -> np.ndarray:
    az = rng.uniform(0.0, 2.0 * math.pi)
    mag = rng.uniform(*lo_hi)
    return np.array([mag * math.cos(az), mag * math.sin(az), 0.0])


def plan_faults(t_fix_s: np.ndarray, duration_s: float, rng: np.random.Generator) -> Faults:
    n = t_fix_s.size
    pos = np.zeros((n, 3))
    vel = np.zeros((n, 3))
    kind = np.zeros(n, np.int8)

    for k in range(SINGLES["count"]):
        t = SINGLES["start_s"] + k * SINGLES["period_s"]
        i = int(np.argmin(np.abs(t_fix_s - t)))
        if k % 2 == 0:
            pos[i] = _horizontal(rng, POS_JUMP_M)
        else:
            vel[i] = _horizontal(rng, VEL_SPIKE_MPS)
        kind[i] = 1

    t = BURSTS["start_s"]
    for k in range(BURSTS["count"]):
        length = rng.uniform(*BURSTS["length_s"])
        sel = (t_fix_s >= t) & (t_fix_s < t + length)
        p = _horizontal(rng, POS_JUMP_M) if k % 3 in (0, 2) else np.zeros(3)
        v = _horizontal(rng, VEL_SPIKE_MPS) if k % 3 in (1, 2) else np.zeros(3)
        pos[sel], vel[sel], kind[sel] = p, v, 2
        t += length + rng.uniform(*BURSTS["gap_s"])
    if t > LONG["start_s"] - 10.0:
        raise ValueError("bursts overlap the long fault; shorten BURSTS")

    t0, t1 = LONG["start_s"], LONG["start_s"] + LONG["length_s"]
    if t1 + 30.0 > duration_s:
        raise ValueError(f"duration {duration_s} s leaves no recovery time after the long fault")
    az = rng.uniform(0.0, 2.0 * math.pi)
    u = np.array([math.cos(az), math.sin(az), 0.0])
    sel = (t_fix_s >= t0) & (t_fix_s < t1)
    pos[sel], vel[sel], kind[sel] = LONG["pos_m"] * u, LONG["vel_mps"] * u, 3
    assert not np.any(kind[t_fix_s < CLEAN_UNTIL_S])
    return Faults(pos, vel, kind, (t0, t1))


def inject(rec: Recording, faults: Faults) -> Recording:
    """A copy of ``rec`` with the faults added to its GNSS fixes (exact geodetic move)."""
    g = rec.gnss.copy()
    idx = np.flatnonzero(np.any(faults.pos_ned_m != 0.0, axis=1))
    lat0, lon0, h0 = g["lat_e7"][idx] * 1e-7, g["lon_e7"][idx] * 1e-7, g["alt_mm"][idx] * 1e-3
    off = faults.pos_ned_m[idx]
    lat, lon, h = pymap3d.ned2geodetic(off[:, 0], off[:, 1], off[:, 2], lat0, lon0, h0, deg=True)
    g["lat_e7"][idx] = np.round(np.asarray(lat) * 1e7).astype(np.int32)
    g["lon_e7"][idx] = np.round(np.asarray(lon) * 1e7).astype(np.int32)
    g["alt_mm"][idx] = np.round(np.asarray(h) * 1e3).astype(np.int32)
    g["vel_ned_mps"] = g["vel_ned_mps"] + faults.vel_ned_mps
    v = g["vel_ned_mps"]
    g["speed_mps"] = np.hypot(v[:, 0], v[:, 1])
    g["course_rad"] = np.mod(np.arctan2(v[:, 1], v[:, 0]), 2.0 * np.pi)
    return dataclasses.replace(rec, name=rec.name + "+outliers", gnss=g)


# --------------------------------------------------------------------------------------
# Runs and their errors against the truth
# --------------------------------------------------------------------------------------


OWN_TEST = False  # --own-test: gps_test_imu = 0
CS_WHITE = False  # --cs-white: the CS + gravity runs without the receiver model
SIM_OVERRIDES: dict = {}  # --sim NAME=VALUE: simulator parameters (SimParams fields)
NAV_OVERRIDES: dict = {}  # --set NAME=VALUE: navigation configuration, every CS + gravity run


def cs_receiver_model(res: object) -> dict:
    """The navigation filter's receiver model (ALGORITHMS.md 8, GPS step 4) set to the simulator's
    receiver: white parts as R, its Gauss-Markov part in the CS GPS-error state. Empty with
    --cs-white (the reported accuracies taken as white, on top of the CS state's defaults)."""
    p = res.params
    if CS_WHITE:
        return {}
    return core.receiver_model(
        p.gps_pos_white_h_m, p.gps_pos_white_v_m, p.gps_pos_sigma_h_m, p.gps_pos_sigma_v_m, p.gps_pos_tau_s
    )


def nav_cfg(preset: str, profile: str, cs_only: bool, res: object) -> object:
    """The C navigation configuration of a robust profile (``cs_only``: the attitude filter plain)
    with the simulator's receiver model (``cs_receiver_model``), then ``--set``."""
    over = {
        k: v
        for k, v in core.robust_profile(profile, res.params.gps_rate_hz).items()
        if not (cs_only and k.startswith("att."))
    }
    over |= cs_receiver_model(res) | {"gps_test_imu": 0 if OWN_TEST else 1}
    return core.nav_config(preset, **(over | NAV_OVERRIDES))


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@dataclasses.dataclass
class Run:
    out: dict[str, np.ndarray]
    rows: np.ndarray  # output row of each fix (the first row after the fix is processed)
    valid: np.ndarray  # fix made a CS update (status OK and not the home fix)
    T: np.ndarray  # (n_fix, 3) GPS T per axis after each fix
    m: np.ndarray  # (n_fix, 3) rows of each axis' update
    rp_err: np.ndarray  # (n_imu, 2) roll, pitch error (rad)
    pos_err: np.ndarray  # (n_imu, 3) m, truth frame
    vel_err: np.ndarray  # (n_imu, 3)
    window: np.ndarray  # rows used for the RMS figures


def measurement_rows(gnss: np.ndarray) -> np.ndarray:
    """m of each axis' update (ALGORITHMS.md 8, GPS step 4)."""
    fl = gnss["flags"]
    vel_ne = (fl & GNSS_HAS_VEL_NE) != 0
    vel_d = (fl & GNSS_HAS_VEL_D) != 0
    alt = ((fl & GNSS_HAS_ALT) != 0) & (gnss["fix_type"] >= 3)
    m_h = 1 + vel_ne.astype(int)
    return np.stack([m_h, m_h, alt.astype(int) + vel_d.astype(int)], axis=1)


def fix_rows(out: dict[str, np.ndarray], rec: Recording) -> np.ndarray:
    """Output row of each fix. Replay order (ALGORITHMS.md 9): at equal times IMU first, then GPS;
    a row is recorded after each IMU sample, so a fix shows in the first row after its arrival."""
    t_imu = out["t_us"].astype(np.int64)
    return np.minimum(np.searchsorted(t_imu, rec.gnss["t_rx_us"], side="right"), t_imu.size - 1)


def replay(rec: Recording, res: object, cfg: object) -> Run:
    out = core.replay(rec, cfg)
    rows = fix_rows(out, rec)
    ok = out["gps_status"] == 0
    valid = ok.copy()
    home = int(np.flatnonzero(ok)[0])
    valid[home] = False
    T = out["gps_t"][rows].astype(np.float64)
    return _run(out, rec, res, rows, valid, home, T, measurement_rows(rec.gnss))


def _run(
    out: dict[str, np.ndarray],
    rec: Recording,
    res: object,
    rows: np.ndarray,
    valid: np.ndarray,
    home: int,
    T: np.ndarray,
    m: np.ndarray,
) -> Run:
    t_imu = out["t_us"].astype(np.int64)
    gnss = rec.gnss

    truth = res.truth
    rp_err = _wrap(out["euler_rad"][:, :2].astype(np.float64) - truth.euler_rad[:, :2])
    # The C home is the home fix; move its NED output to the simulator's NED frame exactly.
    lat_h, lon_h, h_h = gnss["lat_e7"][home] * 1e-7, gnss["lon_e7"][home] * 1e-7, gnss["alt_mm"][home] * 1e-3
    p = out["pos_ned_m"].astype(np.float64)
    lat, lon, h = pymap3d.ned2geodetic(p[:, 0], p[:, 1], p[:, 2], lat_h, lon_h, h_h, deg=True)
    hp = res.params
    n, e, d = pymap3d.geodetic2ned(lat, lon, h, hp.home_lat_deg, hp.home_lon_deg, hp.home_alt_m, deg=True)
    pos_err = np.stack([n, e, d], axis=1) - truth.pos_ned_m
    vel_err = out["vel_ned_mps"].astype(np.float64) - truth.vel_ned_mps
    window = t_imu >= gnss["t_us"][home] + round(SETTLE_S * 1e6)
    return Run(out, rows, valid, T, m, rp_err, pos_err, vel_err, window)


def rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(a * a, axis=1) / a.shape[1])))


def rms3(a: np.ndarray) -> float:
    """3-D RMS (root of the mean squared vector norm)."""
    return float(np.sqrt(np.mean(np.sum(a * a, axis=1))))


# --------------------------------------------------------------------------------------
# Detection
# --------------------------------------------------------------------------------------

RULES = ("chi2(0.005)", "FTA", "AKF", "fuzzy", "IGG-III")
MODE_RULE = {0: "chi2(0.005)", 1: "FTA", 2: "AKF", 3: "fuzzy", 4: "IGG-III"}


def profile_rule(mode: int, profile: str) -> str:
    """The detection rule of a robust profile: its mode's, the fuzzy rows variant's for fuzzy-rows
    (alarm at D >= 1, ALGORITHMS.md 5)."""
    return "fuzzy rows" if profile == "fuzzy-rows" else MODE_RULE[mode]


def rule_flags(rule: str, run: Run) -> np.ndarray:
    """Per-fix flag of a detection rule applied to a run's T (see the module docstring)."""
    T, m, valid = run.T, run.m, run.valid
    flags = np.zeros(T.shape, dtype=bool)
    for axis in range(3):
        d_k, alarm = 0.0, False
        for i in np.flatnonzero(valid):
            mi, t = int(m[i, axis]), float(T[i, axis])
            if mi == 0 or not math.isfinite(t):
                continue
            if rule == "chi2(0.005)":
                flags[i, axis] = t > chi2_quantile(0.005, mi)
            elif rule == "FTA":
                flags[i, axis] = t > chi2_quantile(1e-4, mi)
            elif rule == "AKF":
                flags[i, axis] = t > chi2_quantile(1e-2, mi)
            elif rule in ("fuzzy", "fuzzy rows"):
                d_k, alarm, _ = fuzzy_detector_step(d_k, alarm, t, mi, rule == "fuzzy rows")
                flags[i, axis] = alarm
            else:
                flags[i, axis] = t > IGG_K1**2
    return flags.any(axis=1)


ALARM_BITS = core.FLAG_BITS["alarm_n"] | core.FLAG_BITS["alarm_e"] | core.FLAG_BITS["alarm_d"]


def mode_flags(rule: str, run: Run) -> np.ndarray:
    """Per-fix flag of a mode on its own run: the fuzzy detector's own alarm (the output's per-axis
    alarm bits after each fix), the rule applied to T for the others (``rule_flags``)."""
    if rule in ("fuzzy", "fuzzy rows"):
        return run.valid & ((run.out["flags"][run.rows] & ALARM_BITS) != 0)
    return rule_flags(rule, run)


def sliding_window_flags(run: Run) -> np.ndarray:
    """Sum of the last SW_LEN epochs' T per axis against chi2(sum of m) at SW_ALPHA."""
    flags = np.zeros(run.T.shape, dtype=bool)
    idx = np.flatnonzero(run.valid)
    for axis in range(run.T.shape[1]):
        for j, i in enumerate(idx):
            last = idx[max(0, j - SW_LEN + 1) : j + 1]
            dof = int(run.m[last, axis].sum())
            if dof == 0:
                continue
            flags[i, axis] = float(run.T[last, axis].sum()) > chi2_quantile(SW_ALPHA, dof)
    return flags.any(axis=1)


# Detection by what a fault is and how large: the velocity faults below 2 m/s are the ones a
# filter that coasts on its IMU without an accelerometer-bias estimate cannot tell from its own
# coasting error over a 10-20 s burst (docs/OUTLIERS.md, session 17).
FAULT_CLASSES = (
    "single, position 5-50 m",
    "single, velocity 1-2 m/s",
    "single, velocity 2-5 m/s",
    "burst, position 5-20 m",
    "burst, position 20-50 m",
    "burst, velocity 1-2 m/s",
    "burst, velocity 2-5 m/s",
    "burst, both, velocity 1-2 m/s",
    "burst, both, velocity 2-5 m/s",
    "100 s, position 30 m",
)
SMALL_VEL_MPS = 2.0
SMALL_POS_M = 20.0


def fault_classes(faults: Faults) -> np.ndarray:
    """Per fix its index in :data:`FAULT_CLASSES` (-1: clean)."""
    v = np.hypot(faults.vel_ned_mps[:, 0], faults.vel_ned_mps[:, 1])
    p = np.hypot(faults.pos_ned_m[:, 0], faults.pos_ned_m[:, 1])
    big_v, big_p = (v >= SMALL_VEL_MPS).astype(int), (p >= SMALL_POS_M).astype(int)
    has_v, has_p = v > 0.0, p > 0.0
    out = np.full(faults.kind.shape, -1)
    single, burst = faults.kind == 1, faults.kind == 2
    out[single & has_p] = 0
    out[single & has_v] = (1 + big_v)[single & has_v]
    out[burst & has_p & ~has_v] = (3 + big_p)[burst & has_p & ~has_v]
    out[burst & has_v & ~has_p] = (5 + big_v)[burst & has_v & ~has_p]
    out[burst & has_v & has_p] = (7 + big_v)[burst & has_v & has_p]
    out[faults.kind == 3] = 9
    return out


@dataclasses.dataclass
class Detection:
    detected: int
    missed: int
    false_alarms: int
    clean: int
    by_kind: dict[str, tuple[int, int]]  # kind -> (detected, faulty)
    by_class: tuple[tuple[int, int], ...]  # FAULT_CLASSES -> (detected, faulty)

    @property
    def rate(self) -> float:
        n = self.detected + self.missed
        return self.detected / n if n else float("nan")

    def row(self) -> str:
        pairs = (self.by_kind[k] for k in KIND_NAMES.values())
        kinds = "  ".join(f"{100.0 * a / b if b else float('nan'):5.1f}%" for a, b in pairs)
        return (
            f"{self.detected:8d} {self.missed:6d} {self.false_alarms:5d} "
            f"{100.0 * self.false_alarms / max(self.clean, 1):5.1f}%  {kinds}"
        )


DETECTION_HEADER = (
    f"{'detected':>8s} {'missed':>6s} {'FA':>5s} {'FA %':>6s}  {'single':>6s} {'burst':>7s} {'long':>7s}"
)


def score(flags: np.ndarray, faults: Faults, valid: np.ndarray) -> Detection:
    f, ok = faults.faulty, valid
    by_kind = {
        name: (int(np.sum(flags & ok & (faults.kind == k))), int(np.sum(ok & (faults.kind == k))))
        for k, name in KIND_NAMES.items()
    }
    cls = fault_classes(faults)
    in_class = [ok & (cls == c) for c in range(len(FAULT_CLASSES))]
    by_class = tuple((int(np.sum(flags & sel)), int(np.sum(sel))) for sel in in_class)
    return Detection(
        detected=int(np.sum(flags & f & ok)),
        missed=int(np.sum(~flags & f & ok)),
        false_alarms=int(np.sum(flags & ~f & ok)),
        clean=int(np.sum(~f & ok)),
        by_kind=by_kind,
        by_class=by_class,
    )


def class_table(columns: list[tuple[str, Sequence[tuple[int, int]]]]) -> None:
    """Detection per fault class (:data:`FAULT_CLASSES`), one column a detector: the faulty fixes it
    flagged, of how many."""
    print(f"{'fault':30s} " + " ".join(f"{name:>22s}" for name, _ in columns))
    for c, cname in enumerate(FAULT_CLASSES):
        cells = []
        for _, by_class in columns:
            a, b = by_class[c]
            cells.append(f"{100.0 * a / b:6.1f}% of {b:6d}" if b else f"{'-':>16s}")
        print(f"{cname:30s} " + " ".join(f"{x:>22s}" for x in cells))


def sum_classes(counts: Sequence[Sequence[tuple[int, int]]]) -> list[tuple[int, int]]:
    """Per-class counts (each a sequence of (flagged, faulty) per :data:`FAULT_CLASSES`) summed."""
    return [(sum(c[k][0] for c in counts), sum(c[k][1] for c in counts)) for k in range(len(FAULT_CLASSES))]


def fault_events(faults: Faults) -> list[tuple[int, np.ndarray]]:
    """Each injected fault as (kind, its fix indices): a single epoch, a burst, the long fault."""
    events = []
    k = faults.kind
    i = 0
    while i < k.size:
        if k[i] == 0:
            i += 1
            continue
        j = i
        while j + 1 < k.size and k[j + 1] == k[i] and (k[i] != 1):
            j += 1
        events.append((int(k[i]), np.arange(i, j + 1)))
        i = j + 1
    return events


def event_detection(flags: np.ndarray, faults: Faults, valid: np.ndarray) -> str:
    """Faults flagged at least once (per kind) and the fixes from a fault's start to its first
    flag (median, max over the detected ones)."""
    hit = {name: [0, 0] for name in KIND_NAMES.values()}
    delays = []
    for kind, idx in fault_events(faults):
        idx = idx[valid[idx]]
        if idx.size == 0:
            continue
        name = KIND_NAMES[kind]
        hit[name][1] += 1
        first = np.flatnonzero(flags[idx])
        if first.size:
            hit[name][0] += 1
            delays.append(int(first[0]))
    cells = " ".join(f"{a:3d}/{b:<3d}" for a, b in hit.values())
    delay = f"{int(np.median(delays)):3d} {max(delays):4d}" if delays else "  -    -"
    return f"{cells} {delay}"


EVENT_HEADER = f"{'single':>7s} {'burst':>7s} {'long':>7s} {'delay med/max':>13s}"


def post_fault(faults: Faults, t_fix_s: np.ndarray, span_s: float) -> np.ndarray:
    """Clean fixes less than span_s after the end of a fault."""
    out = np.zeros(t_fix_s.size, dtype=bool)
    for _, idx in fault_events(faults):
        t_end = t_fix_s[idx[-1]]
        out |= (t_fix_s > t_end) & (t_fix_s <= t_end + span_s)
    return out & ~faults.faulty


def fuzzy_fa_clean_goal(fa: int, sw_fa: int) -> str:
    cut = 1.0 - fa / sw_fa if sw_fa else float("nan")
    return (
        f"FA {fa} vs SW4 {sw_fa}, {100.0 * cut:.0f}% fewer (>= {100.0 * GOAL_FUZZY_FA_CUT:.0f}%: "
        f"{_goal(cut >= GOAL_FUZZY_FA_CUT)})"
    )


def fuzzy_goal(det: Detection, sw: Detection) -> str:
    cut = 1.0 - det.false_alarms / sw.false_alarms if sw.false_alarms else float("nan")
    return (
        f"detection {100.0 * det.rate:.1f}% (>= {100.0 * GOAL_FUZZY_DETECTION:.0f}%: "
        f"{_goal(det.rate >= GOAL_FUZZY_DETECTION)}), FA {100.0 * cut:.0f}% fewer than SW4 "
        f"(>= {100.0 * GOAL_FUZZY_FA_CUT:.0f}%: {_goal(cut >= GOAL_FUZZY_FA_CUT)})"
    )


# --------------------------------------------------------------------------------------
# The long fault
# --------------------------------------------------------------------------------------


@dataclasses.dataclass
class LongFault:
    max_err_during_m: float
    max_err_after_m: float
    recovery_fixes: int | None  # fixes after the fault until the error stays small; None: never
    recovery_10m_fixes: int | None  # the same with a 10 m bound
    flagged_after: int  # fixes in the 30 s after the fault still flagged by the mode's detector

    @property
    def diverged(self) -> bool:
        return max(self.max_err_during_m, self.max_err_after_m) > DIVERGED_M


def long_fault(run: Run, bound_m: float, faults: Faults, flags: np.ndarray, t_fix_s: np.ndarray) -> LongFault:
    """Errors under and after the 100 s fault. Recovered: from that fix on, the horizontal error
    at each of the next 10 fixes is within ``bound_m``."""
    t0, t1 = faults.long_window_s
    t_imu = run.out["t_us"] * 1e-6
    herr = np.hypot(run.pos_err[:, 0], run.pos_err[:, 1])
    after_fix = np.flatnonzero((t_fix_s >= t1) & run.valid)

    def recovery(bound: float) -> int | None:
        good = herr[run.rows[after_fix]] <= bound
        return next((j for j in range(max(0, good.size - 10)) if good[j : j + 10].all()), None)

    soon = after_fix[t_fix_s[after_fix] < t1 + 30.0]
    return LongFault(
        float(herr[(t_imu >= t0) & (t_imu < t1)].max()),
        float(herr[t_imu >= t1].max()),
        recovery(bound_m),
        recovery(10.0),
        int(np.sum(flags[soon])),
    )


# --------------------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------------------


def _goal(ok: bool) -> str:
    return "met" if ok else "NOT met"


def segments(faults: Faults, t_fix_s: np.ndarray, duration_s: float) -> list[tuple[str, float, float]]:
    t_single_end = SINGLES["start_s"] + SINGLES["count"] * SINGLES["period_s"]
    t_burst_end = float(t_fix_s[faults.kind == 2].max()) + 1.0
    t0, t1 = faults.long_window_s
    return [
        ("warm-up", SETTLE_S, CLEAN_UNTIL_S),
        ("singles", SINGLES["start_s"], t_single_end),
        ("bursts", BURSTS["start_s"], t_burst_end),
        ("quiet", t_burst_end, t0),
        ("100s fault", t0, t1),
        ("after", t1, duration_s),
    ]


def scores(clean: Run, run: Run, flags: np.ndarray, clean_flags: np.ndarray, faults: Faults) -> dict:
    """Errors of the outlier-free and the faulty run, and the detection scores of a mode's flags
    on the faulty run (``flags``) and on the outlier-free one (``clean_flags``), with SW4 beside."""
    return dict(
        rp_clean=rms(clean.rp_err[clean.window]),
        rp_bad=rms(run.rp_err[run.window]),
        pos=(rms3(clean.pos_err[clean.window]), rms3(run.pos_err[run.window])),
        vel=(rms3(clean.vel_err[clean.window]), rms3(run.vel_err[run.window])),
        det=score(flags, faults, run.valid),
        sw=score(sliding_window_flags(run), faults, run.valid),
        clean_fa=score(clean_flags, faults, clean.valid).false_alarms,
        sw_clean_fa=score(sliding_window_flags(clean), faults, clean.valid).false_alarms,
        events=event_detection(flags, faults, run.valid),
    )


def bench_scenario(name: str, preset: str, seed: int, duration_s: float, cs_only: bool) -> list[dict]:
    res = scenario(name, seed=seed, duration_s=duration_s, **SIM_OVERRIDES)
    rec = res.recording
    t_fix_s = rec.gnss["t_us"] * 1e-6
    faults = plan_faults(t_fix_s, duration_s, np.random.default_rng(seed + 1000))
    bad = inject(rec, faults)
    n_kind = {k: int(np.sum(faults.kind == i)) for i, k in KIND_NAMES.items()}
    print(
        f"\n=== {name} (preset {preset}, seed {seed}, {duration_s:.0f} s, {len(rec.gnss)} fixes at "
        f"{res.params.gps_rate_hz:g} Hz; faulty: {n_kind['single']} single, {n_kind['burst']} in bursts, "
        f"{n_kind['long']} in the 100 s fault) ==="
    )
    rows = []
    for label, mode, profile in MODES:
        cfg = nav_cfg(preset, profile, cs_only, res)
        clean = replay(rec, res, cfg)
        run = replay(bad, res, cfg)
        rows.append(dict(label=label, mode=mode, rule=profile_rule(mode, profile), clean=clean, run=run))
    plain_clean = rows[0]["clean"]
    e_plain = plain_clean.pos_err[plain_clean.window]
    herr_plain = np.hypot(e_plain[:, 0], e_plain[:, 1])
    bound_m = float(np.percentile(herr_plain, 99)) + 1.0
    pos_plain = rms3(plain_clean.pos_err[plain_clean.window])
    for r in rows:
        clean, run = r["clean"], r["run"]
        flags = mode_flags(r["rule"], run)
        r.update(
            **scores(clean, run, flags, mode_flags(r["rule"], clean), faults),
            fa_flags=flags & ~faults.faulty & run.valid,
            long=long_fault(run, bound_m, faults, flags, t_fix_s),
            refused=int(np.sum(run.out["gps_status"] != 0)),
        )
        r["clean_diverged"] = r["pos"][0] > 10.0 * pos_plain

    deg = 180.0 / math.pi
    print("Errors against the truth (outlier-free run / run with outliers):")
    print(
        f"{'mode':10s} {'roll/pitch RMS (deg)':>21s} {'ratio':>6s}  {'pos RMS (m)':>19s}  "
        f"{'vel RMS (m/s)':>17s}   goal (roll/pitch ratio)"
    )
    for r in rows:
        ratio = r["rp_bad"] / r["rp_clean"]
        if r["mode"] == 0:
            goal = f">= {GOAL_PLAIN_RP_RATIO:.1f}x: {_goal(ratio >= GOAL_PLAIN_RP_RATIO)}"
        else:
            goal = f"<= {GOAL_ROBUST_RP_RATIO:.2f}x: {_goal(ratio <= GOAL_ROBUST_RP_RATIO)}"
        if r["clean_diverged"]:
            goal += "; DIVERGES on the outlier-free run"
        print(
            f"{r['label']:10s} {r['rp_clean'] * deg:8.3f} / {r['rp_bad'] * deg:8.3f} {ratio:6.2f}  "
            f"{_num(r['pos'][0])} / {_num(r['pos'][1])}  {_num(r['vel'][0])} / {_num(r['vel'][1])}   {goal}"
        )

    segs = segments(faults, t_fix_s, duration_s)
    print("\nRoll/pitch RMS (deg) of the run with outliers, by segment (outlier-free run in brackets):")
    print(f"{'mode':10s} " + " ".join(f"{f'{s} {a:.0f}-{b:.0f} s':>20s}" for s, a, b in segs))
    for r in rows:
        cells = []
        for _, a, b in segs:
            bad_rp = rms(r["run"].rp_err[_between(r["run"], a, b)]) * deg
            clean_rp = rms(r["clean"].rp_err[_between(r["clean"], a, b)]) * deg
            cells.append(f"{bad_rp:9.2f} ({clean_rp:6.2f})")
        print(f"{r['label']:10s} " + " ".join(f"{c:>20s}" for c in cells))

    print(
        "\nDetection per fix, each mode on its own run (fuzzy: its alarm; the others: their rule on T;"
        " closed loop):"
    )
    print(f"{'mode':10s} {DETECTION_HEADER}  {'SW4 FA':>6s} {'FA clean run':>12s} {'SW4':>5s}   goal")
    for r in rows:
        goal = fuzzy_goal(r["det"], r["sw"]) if r["mode"] == 3 else ""
        print(
            f"{r['label']:10s} {r['det'].row()}  {r['sw'].false_alarms:6d} {r['clean_fa']:12d} "
            f"{r['sw_clean_fa']:5d}   {goal}"
        )
    after = post_fault(faults, t_fix_s, AFTER_FAULT_S)
    shares = ", ".join(
        f"{r['label']} {int(np.sum(r['fa_flags'] & after))}/{r['det'].false_alarms}" for r in rows
    )
    n_clean = int(np.sum(~faults.faulty & rows[0]["run"].valid))
    n_after = int(np.sum(after & rows[0]["run"].valid))
    print(
        "(SW4 FA: the 4-epoch sliding window on the same run's T; FA clean run: the rule, and SW4, on the\n"
        f" outlier-free run. False alarms of the run with outliers less than {AFTER_FAULT_S:.0f} s after a\n"
        f" fault ends ({n_after} of the {n_clean} clean fixes), while the filter sheds what it let in (the\n"
        f" fix is clean, the state is not): {shares})"
    )
    for r in rows:
        if r["mode"] == 3:
            goal = fuzzy_fa_clean_goal(r["clean_fa"], r["sw_clean_fa"])
            print(f"{r['label']:10s} on the outlier-free run: {goal}")
    print("\nFaults flagged at least once, each mode's rule (fixes from a fault's start to its first flag):")
    print(f"{'mode':10s} {EVENT_HEADER}")
    for r in rows:
        print(f"{r['label']:10s} {r['events']}")
    print("\nFixes flagged by fault class (fuzzy: its alarm; the others: their rule on T):")
    class_table([(r["label"], r["det"].by_class) for r in rows])

    plain_run = rows[0]["run"]
    sw = score(sliding_window_flags(plain_run), faults, plain_run.valid)
    print("\nDetectors on one T stream, the plain filter's (open loop, as paper 001 compares them):")
    print(f"{'rule':12s} {DETECTION_HEADER}   goal")
    for rule in RULES:
        det = score(rule_flags(rule, plain_run), faults, plain_run.valid)
        goal = fuzzy_goal(det, sw) if rule == "fuzzy" else ""
        print(f"{rule:12s} {det.row()}   {goal}")
    print(f"{'SW4 (0.005)':12s} {sw.row()}   baseline")

    print(f"\n100 s fault (recovered: 10 fixes in a row within {bound_m:.1f} m, plain clean p99 + 1 m;")
    print(" roll/pitch RMS in deg over the 10 s after it, the outlier-free run's in brackets):")
    print(
        f"{'mode':10s} {'max herr during':>15s} {'after':>10s} {'recovery':>10s} {'to 10 m':>9s} "
        f"{'flagged in 30 s after':>22s} {'roll/pitch 10 s after':>22s}   goal"
    )
    t_end = faults.long_window_s[1]
    for r in rows:
        rp_after = rms(r["run"].rp_err[_between(r["run"], t_end, t_end + 10.0)]) * deg
        rp_after_clean = rms(r["clean"].rp_err[_between(r["clean"], t_end, t_end + 10.0)]) * deg
        lf = r["long"]
        rec_txt = f"{lf.recovery_fixes:d} fixes" if lf.recovery_fixes is not None else "never"
        rec10 = f"{lf.recovery_10m_fixes:d} fixes" if lf.recovery_10m_fixes is not None else "never"
        ok = not lf.diverged and lf.recovery_fixes is not None and lf.recovery_fixes <= GOAL_RECOVERY_FIXES
        goal = f"no divergence (< {DIVERGED_M:.0f} m), recovery <= {GOAL_RECOVERY_FIXES} fixes: {_goal(ok)}"
        print(
            f"{r['label']:10s} {_num(lf.max_err_during_m)} m {_num(lf.max_err_after_m)} m "
            f"{rec_txt:>10s} {rec10:>9s} {lf.flagged_after:22d} "
            f"{f'{rp_after:.2f} ({rp_after_clean:.2f})':>22s}   {goal}"
        )
    refused = [f"{r['label']} {r['refused']}" for r in rows if r["refused"]]
    if refused:
        print("fixes refused by the C filter (status != OK): " + ", ".join(refused))
    return rows


# --------------------------------------------------------------------------------------
# The same faults on the loosely-coupled INS (ALGORITHMS.md 10), the filter paper 001 tests
# --------------------------------------------------------------------------------------

# (label, robust mode name, other mca_ins_config_t fields)
INS_MODES = (
    ("plain", "plain", {}),
    ("FTA", "fta", {}),
    ("AKF", "akf", {}),
    ("fuzzy", "fuzzy", {}),
    ("fuzzy-infl", "fuzzy", {"robust.fuzzy_reject": 0}),
    ("IGG-III", "igg3", {}),
)
INS_PRESETS = {
    "fixedwing_turns": "fixedwing",
    "multirotor_aggressive": "multirotor",
    "car_accel_brake": "ground",
}


def ins_replay(rec: Recording, res: object, preset: str, mode: str, extra: dict) -> Run:
    """The INS on a recording, as a Run: T and m are the GNSS update's (the sum over its position
    and velocity blocks, m all rows); a fix counts when it made an update (applied or rejected)."""
    out = core.ins_replay(rec, core.ins_config(preset, robust=mode, **extra))
    rows = fix_rows(out, rec)
    made = np.diff(out["n_gps_upd"][rows] + out["n_gps_rej"][rows], prepend=0) > 0
    valid = (out["gps_status"] == 0) & made
    home = int(np.flatnonzero(out["gps_status"] == 0)[0])
    T = out["gps_t"][rows].astype(np.float64)[:, None]
    run = _run(out, rec, res, rows, valid, home, T, out["gps_m"][rows].astype(int)[:, None])
    run.window &= (out["flags"] & core.INS_FLAG_BITS["nav"]) != 0
    return run


def ins_flags(run: Run, mode: str) -> np.ndarray:
    """Per-fix detection: the robust mode's own (output flag ``detected``: a block's test flagged
    it; fuzzy: its alarm); plain detects nothing, so the single threshold T > chi2_m(0.005)."""
    if mode == "plain":
        t, m = run.T[:, 0], run.m[:, 0]
        q = np.array([chi2_quantile(0.005, int(k)) if k > 0 else np.inf for k in m])
        return run.valid & (t > q)
    return run.valid & ((run.out["flags"][run.rows] & core.INS_FLAG_BITS["detected"]) != 0)


def ins_receiver_model(res: object) -> dict:
    """The INS's receiver position error model (ALGORITHMS.md 10, GNSS update step 3) set to the
    simulator's receiver: its Gauss-Markov correlation time and its white parts."""
    p = res.params
    return {
        "gps_pos_tau_s": p.gps_pos_tau_s,
        "gps_pos_white_m": p.gps_pos_white_h_m,
        "gps_alt_white_m": p.gps_pos_white_v_m,
    }


def bench_ins_scenario(name: str, seed: int, duration_s: float, white: bool = False) -> list[dict]:
    preset = INS_PRESETS[name]
    res = scenario(
        name, seed=seed, duration_s=duration_s, earth_rate=True, **SIM_OVERRIDES
    )  # the INS removes it
    rec = res.recording
    t_fix_s = rec.gnss["t_us"] * 1e-6
    faults = plan_faults(t_fix_s, duration_s, np.random.default_rng(seed + 1000))
    bad = inject(rec, faults)
    receiver = {} if white else ins_receiver_model(res)
    how = "accuracies taken as white"
    if not white:
        r = receiver
        how = f"receiver error model: tau {r['gps_pos_tau_s']:.0f} s, white {r['gps_pos_white_m']} / "
        how += f"{r['gps_alt_white_m']} m"
    print(f"\n=== INS, {name} (preset {preset}, seed {seed}, the same faults; GNSS {how}) ===")
    rows = []
    for label, mode, base in INS_MODES:
        extra = base | receiver
        clean, run = ins_replay(rec, res, preset, mode, extra), ins_replay(bad, res, preset, mode, extra)
        flags = ins_flags(run, mode)
        rows.append(
            dict(label=label, mode=mode, clean=clean, run=run)
            | scores(clean, run, flags, ins_flags(clean, mode), faults)
        )
    e_plain = rows[0]["clean"].pos_err[rows[0]["clean"].window]
    bound_m = float(np.percentile(np.hypot(e_plain[:, 0], e_plain[:, 1]), 99)) + 1.0
    for r in rows:
        r["long"] = long_fault(r["run"], bound_m, faults, ins_flags(r["run"], r["mode"]), t_fix_s)
    deg = 180.0 / math.pi
    print(
        f"{'mode':10s} {'roll/pitch RMS (deg)':>21s} {'ratio':>6s}  {'pos RMS (m)':>19s}  "
        f"{'vel RMS (m/s)':>17s}  {DETECTION_HEADER}  {'SW4 FA':>6s} {'clean FA':>8s} {'SW4':>4s}  "
        f"{'100 s: max herr':>15s} {'recovery':>9s}"
    )
    for r in rows:
        lf = r["long"]
        rec_txt = f"{lf.recovery_fixes:d}" if lf.recovery_fixes is not None else "never"
        print(
            f"{r['label']:10s} {r['rp_clean'] * deg:8.3f} / {r['rp_bad'] * deg:8.3f} "
            f"{r['rp_bad'] / r['rp_clean']:6.2f}  {_num(r['pos'][0])} / {_num(r['pos'][1])}  "
            f"{_num(r['vel'][0])} / {_num(r['vel'][1])}  {r['det'].row()}  "
            f"{r['sw'].false_alarms:6d} {r['clean_fa']:8d} {r['sw_clean_fa']:4d}  "
            f"{_num(max(lf.max_err_during_m, lf.max_err_after_m))} m {rec_txt:>9s}"
        )
    print(
        "(recovery: fixes after the 100 s fault until 10 in a row are within "
        f"{bound_m:.1f} m, plain clean p99 + 1 m)"
    )
    print(f"{'mode':10s} faults flagged at least once: {EVENT_HEADER}")
    for r in rows:
        print(f"{r['label']:10s} {'':30s}{r['events']}")
    return rows


def mode_summary(rs: list[dict], label: str, plain: bool, fuzzy: bool) -> dict:
    """One mode over the scenarios' results ``rs`` (CS + gravity or INS): its figures, and whether
    it meets each goal that applies to it (``plain``: the plain filter's; ``fuzzy``: the fuzzy
    detector's, for every mode that runs it)."""
    ratios = [r["rp_bad"] / r["rp_clean"] for r in rs]
    det = sum(r["det"].detected for r in rs)
    miss = sum(r["det"].missed for r in rs)
    fa = sum(r["det"].false_alarms for r in rs)
    swfa = sum(r["sw"].false_alarms for r in rs)
    recs = [r["long"].recovery_fixes for r in rs]
    diverged = any(r["long"].diverged for r in rs)
    out = dict(
        label=label,
        ratios=ratios,
        rate=det / max(det + miss, 1),
        fa=fa,
        swfa=swfa,
        cut=1.0 - fa / swfa if swfa else float("nan"),
        fa0=sum(r["clean_fa"] for r in rs),
        swfa0=sum(r["sw_clean_fa"] for r in rs),
        recs=recs,
        rec_ok=not diverged and all(x is not None and x <= GOAL_RECOVERY_FIXES for x in recs),
        by_class=sum_classes([r["det"].by_class for r in rs]),
        during=[r["long"].max_err_during_m for r in rs],
    )
    if plain:
        out["ratio_ok"] = min(ratios) >= GOAL_PLAIN_RP_RATIO
    else:
        out["ratio_ok"] = max(ratios) <= GOAL_ROBUST_RP_RATIO
    out["all_ok"] = out["ratio_ok"] and (plain or out["rec_ok"])
    out["fuzzy_ok"] = None
    if fuzzy:
        out["fuzzy_ok"] = out["rate"] >= GOAL_FUZZY_DETECTION and out["cut"] >= GOAL_FUZZY_FA_CUT
        out["all_ok"] = out["all_ok"] and out["fuzzy_ok"]
    return out


def ins_mode_summary(results: dict[str, list[dict]], k: int) -> dict:
    """INS mode ``k`` of :data:`INS_MODES` over the scenarios of ``results``."""
    label, mode, _ = INS_MODES[k]
    return mode_summary([results[n][k] for n in results], label, mode == "plain", mode == "fuzzy")


def cs_mode_summary(results: dict[str, list[dict]], k: int) -> dict:
    """CS + gravity mode ``k`` of :data:`MODES` over the scenarios of ``results``."""
    label, mode, _ = MODES[k]
    return mode_summary([results[n][k] for n in results], label, mode == 0, mode == 3)


def goal_text(sm: dict, plain: bool) -> str:
    """The goals of a mode summary, met or not."""
    if plain:
        return f"ratio >= {GOAL_PLAIN_RP_RATIO:.1f}x: {_goal(sm['ratio_ok'])}"
    goal = f"ratio <= {GOAL_ROBUST_RP_RATIO:.2f}x: {_goal(sm['ratio_ok'])}"
    if sm["fuzzy_ok"] is not None:
        rate, cut = sm["rate"], sm["cut"]
        goal += (
            f"; detection {100.0 * rate:.1f}% (>= {100.0 * GOAL_FUZZY_DETECTION:.0f}%: "
            f"{_goal(rate >= GOAL_FUZZY_DETECTION)}), FA {100.0 * cut:.0f}% fewer than SW4 "
            f"(>= {100.0 * GOAL_FUZZY_FA_CUT:.0f}%: {_goal(cut >= GOAL_FUZZY_FA_CUT)})"
        )
    return goal + f"; no divergence, recovery <= {GOAL_RECOVERY_FIXES} fixes: {_goal(sm['rec_ok'])}"


def _during(sm: dict) -> str:
    """The largest horizontal error under the 100 s fault of each vehicle of a mode summary (m)."""
    return " ".join(f"{x:.0f}" for x in sm["during"])


def _recs(recs: list[int | None]) -> str:
    return " ".join("-" if x is None else str(x) for x in recs)


def seed_counts(sms: list[dict], plain: bool) -> str:
    """How many of the seeds' mode summaries ``sms`` meet each goal, and the means over them: a
    few seeds say little about a closed loop in which one let-in fault decides the next."""
    n = len(sms)
    if plain:
        return f"over {n} seeds: ratio >= {GOAL_PLAIN_RP_RATIO:.1f}x on {sum(sm['ratio_ok'] for sm in sms)}"
    fuzzy = sms[0]["fuzzy_ok"] is not None  # the mode runs the fuzzy detector
    worst = sum(max(sm["ratios"]) for sm in sms) / n
    det = sum(sm["rate"] >= GOAL_FUZZY_DETECTION for sm in sms)
    cut = sum(sm["cut"] >= GOAL_FUZZY_FA_CUT for sm in sms)
    rec, every = sum(sm["rec_ok"] for sm in sms), sum(sm["all_ok"] for sm in sms)
    text = f"over {n} seeds: ratio on {sum(sm['ratio_ok'] for sm in sms)}"
    text += f", detection on {det}, false alarms on {cut}" if fuzzy else ""
    text += f", recovery on {rec}, every goal on {every}; mean worst ratio {worst:.2f}"
    if fuzzy:
        rate = 100.0 * sum(sm["rate"] for sm in sms) / n
        below = 100.0 * sum(sm["cut"] for sm in sms) / n
        text += f", detection {rate:.1f}%, below SW4 {below:.0f}%"
    return text


def summary_table(title: str, results: dict[str, list[dict]], modes: tuple, summarize, plain_mode) -> None:
    """Every mode of ``modes`` over the scenarios of ``results`` against the goals (``summarize``:
    :func:`cs_mode_summary` or :func:`ins_mode_summary`; ``plain_mode``: the plain filter's mode)."""
    names = list(results)
    print(f"\n=== {title} ===")
    print(
        f"{'mode':10s} {'roll/pitch ratio (' + ', '.join(n.split('_')[0] for n in names) + ')':>34s} "
        f"{'detection':>10s} {'FA':>6s} {'SW4 FA':>7s} {'FA / SW4 FA, outlier-free':>26s} "
        f"{'100 s: recovery':>16s}   diverges on clean data; goal"
    )
    for k, (label, mode, _) in enumerate(modes):
        sm = summarize(results, k)
        div = "-"  # not measured (the INS runs)
        if all("clean_diverged" in results[n][k] for n in names):
            div = ", ".join(n for n in names if results[n][k]["clean_diverged"]) or "no"
        clean_fa = f"{sm['fa0']} / {sm['swfa0']}"
        print(
            f"{label:10s} {' '.join(f'{x:6.2f}' for x in sm['ratios']):>34s} {100.0 * sm['rate']:9.1f}% "
            f"{sm['fa']:6d} {sm['swfa']:7d} {clean_fa:>26s} {_recs(sm['recs']):>16s}   {div}; "
            f"{goal_text(sm, mode == plain_mode)}"
        )


def ins_summary(results: dict[str, list[dict]]) -> None:
    summary_table(
        "INS, all scenarios (goals as for the CS + gravity filter)",
        results,
        INS_MODES,
        ins_mode_summary,
        "plain",
    )


def ins_seeds(seeds: list[int], names: list[str], duration_s: float, white: bool) -> None:
    """The INS runs of each seed (their per-scenario tables left out), then one line a seed for
    the fuzzy detector and the plain filter against every goal. Only the summaries are kept: a
    seed's runs are ~2 GB of outputs."""
    k_plain = next(k for k, m in enumerate(INS_MODES) if m[0] == "plain")
    k_fuzzy = next(k for k, m in enumerate(INS_MODES) if m[0] == "fuzzy")
    lines = []
    sms_fuzzy: list[dict] = []
    sms_plain: list[dict] = []
    for seed in seeds:
        with contextlib.redirect_stdout(io.StringIO()):
            results = {n: bench_ins_scenario(n, seed, duration_s, white) for n in names}
        print(f"\n--- seed {seed}")
        ins_summary(results)
        fz, pl = ins_mode_summary(results, k_fuzzy), ins_mode_summary(results, k_plain)
        sms_fuzzy.append(fz)
        sms_plain.append(pl)
        del results
        lines.append(
            f"{seed:4d} {max(fz['ratios']):11.2f} {100.0 * fz['rate']:9.1f}% {fz['fa']:5d} {fz['swfa']:7d} "
            f"{100.0 * fz['cut']:8.0f}% {_recs(fz['recs']):>10s} {_during(fz):>10s} "
            f"{min(pl['ratios']):18.2f}   "
            f"fuzzy {_goal(fz['all_ok'])}, plain >= {GOAL_PLAIN_RP_RATIO:.1f}x {_goal(pl['ratio_ok'])}"
        )
    print(f"\n=== INS, fuzzy detector, seeds {', '.join(map(str, seeds))} ===")
    print(
        f"{'seed':>4s} {'worst ratio':>11s} {'detection':>10s} {'FA':>5s} {'SW4 FA':>7s} {'below SW4':>9s} "
        f"{'recovery':>10s} {'max err':>10s} {'plain, least ratio':>18s}   every goal"
    )
    print("\n".join(lines))
    print(f"fuzzy {seed_counts(sms_fuzzy, False)}")
    print(f"plain {seed_counts(sms_plain, True)}")
    print(f"\nINS, faulty fixes flagged by fault class over the {len(seeds)} seeds and every scenario:")
    cols = [(ss[0]["label"], sum_classes([sm["by_class"] for sm in ss])) for ss in (sms_fuzzy, sms_plain)]
    class_table(cols)


def cs_summary(results: dict[str, list[dict]], classes: bool = False) -> None:
    """The CS + gravity filter's modes over every scenario of ``results``, against the goals
    (``classes``: with the detection per fault class)."""
    summary_table("all scenarios", results, MODES, cs_mode_summary, 0)
    if classes:
        print("\nFaulty fixes flagged by fault class, every scenario:")
        by_mode = [cs_mode_summary(results, k)["by_class"] for k in range(len(MODES))]
        class_table([(m[0], b) for m, b in zip(MODES, by_mode, strict=True)])


def cs_seeds(seeds: list[int], names: list[str], duration_s: float, cs_only: bool) -> None:
    """The CS + gravity runs of each seed (their per-scenario tables left out, its all-scenario
    summary printed), then every mode over the seeds against every goal. Only the summaries are
    kept: a seed's runs are ~2 GB of outputs."""
    by_mode: dict[int, list[str]] = {k: [] for k in range(len(MODES))}
    sms: dict[int, list[dict]] = {k: [] for k in range(len(MODES))}
    met: dict[int, bool] = {k: True for k in range(len(MODES))}
    for seed in seeds:
        with contextlib.redirect_stdout(io.StringIO()):
            results = {n: bench_scenario(n, SCENARIOS[n], seed, duration_s, cs_only) for n in names}
        print(f"\n--- seed {seed}")
        cs_summary(results)
        for k, (_, mode, _) in enumerate(MODES):
            sm = cs_mode_summary(results, k)
            ratio = min(sm["ratios"]) if mode == 0 else max(sm["ratios"])
            fuzzy = f"{100.0 * sm['rate']:9.1f}% {100.0 * sm['cut']:8.0f}%" if mode == 3 else f"{'':19s}"
            by_mode[k].append(
                f"{seed:4d} {ratio:11.2f} {fuzzy} {_recs(sm['recs']):>16s} {_during(sm):>14s}   "
                f"{_goal(sm['all_ok'])}"
            )
            met[k] = met[k] and sm["all_ok"]
            sms[k].append(sm)
        del results
    print(f"\n=== CS + gravity filter, seeds {', '.join(map(str, seeds))} ===")
    print(
        "ratio: the worst robust one over the vehicles (plain: the least); fuzzy detector: detection,\n"
        "false alarms below SW4 on the same T; recovery: fixes after the 100 s fault (- never);\n"
        "max err: the largest horizontal error during the 100 s fault (m), per vehicle"
    )
    print(
        f"{'mode':10s} {'seed':>4s} {'ratio':>11s} {'detection':>10s} {'below SW4':>9s} "
        f"{'recovery':>16s} {'max err':>14s}   every goal"
    )
    for k, (label, mode, _) in enumerate(MODES):
        for j, line in enumerate(by_mode[k]):
            print(f"{label if j == 0 else '':10s} {line}")
        print(f"{'':10s} every goal on every seed: {_goal(met[k])}")
        print(f"{'':10s} {seed_counts(sms[k], mode == 0)}")
    print(f"\nFaulty fixes flagged by fault class over the {len(seeds)} seeds and every scenario:")
    class_table([(m[0], sum_classes([sm["by_class"] for sm in sms[k]])) for k, m in enumerate(MODES)])


def _between(run: Run, a: float, b: float) -> np.ndarray:
    t = run.out["t_us"] * 1e-6
    return (t >= a) & (t < b)


def _num(v: float) -> str:
    """Fixed width; huge values (divergence) in exponent form."""
    return f"{v:8.2f}" if abs(v) < 1e5 else f"{v:8.1e}"


def _seed_list(spec: str) -> list[int]:
    """Seeds from "1-8" or "1,3"."""
    lo, _, hi = spec.partition("-")
    return list(range(int(lo), int(hi) + 1)) if hi else [int(x) for x in spec.split(",")]


def main() -> None:
    global OWN_TEST, CS_WHITE, MODES
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--duration", type=float, default=900.0, help="seconds per scenario (>= 810)")
    ap.add_argument("--scenario", action="append", choices=sorted(SCENARIOS), help="repeatable; default all")
    ap.add_argument("--cs-only", action="store_true", help="robust mode on the CS filters only")
    ap.add_argument("--own-test", action="store_true", help="test the CS prediction, not the IMU-aided one")
    ap.add_argument("--no-ins", action="store_true", help="leave out the INS runs")
    ap.add_argument("--ins-only", action="store_true", help="only the INS runs")
    ap.add_argument(
        "--ins-white", action="store_true", help="INS without the receiver error model (accuracies as white)"
    )
    ap.add_argument(
        "--cs-white",
        action="store_true",
        help="CS + gravity without the receiver model (accuracies as white)",
    )
    ap.add_argument("--ins-seeds", help="INS only, these seeds (e.g. 1-8 or 1,3): a summary line a seed")
    ap.add_argument("--cs-seeds", help="CS + gravity only, these seeds (e.g. 1-4): every mode a seed")
    ap.add_argument(
        "--modes",
        help="CS + gravity robust profiles to run, comma-separated (e.g. fuzzy-rows; plain always runs: "
        f"the baseline of the goals); default all: {', '.join(m[2] for m in MODES)}",
    )
    ap.add_argument(
        "--sim",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="simulator parameter (SimParams field), e.g. 'gyro_scale_ppm=(5000,-5000,5000)'; repeatable",
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="navigation configuration field of every CS + gravity run, after the profile's (as "
        "mcahrs replay --set), e.g. imu_acc_sigma_mps2=0.15; repeatable",
    )
    args = ap.parse_args()
    NAV_OVERRIDES.update(parse_overrides(args.set))
    if args.modes:
        known = {m[2]: m for m in MODES}
        wanted = [w.strip() for w in args.modes.split(",") if w.strip()]
        bad = [w for w in wanted if w not in known]
        if bad:
            ap.error(f"--modes: unknown profile(s) {', '.join(bad)}; known: {', '.join(known)}")
        MODES = tuple(m for m in MODES if m[2] == "plain" or m[2] in wanted)
    OWN_TEST = args.own_test
    CS_WHITE = args.cs_white
    for item in args.sim:
        key, _, text = item.partition("=")
        SIM_OVERRIDES[key.strip()] = ast.literal_eval(text.strip())
    t_start = time.perf_counter()
    names = args.scenario or list(SCENARIOS)
    where = "CS N/E/D filters only" if args.cs_only else "CS N/E/D and attitude filters"
    rx = "accuracies as white" if CS_WHITE else "the simulator's receiver modelled (white R, GM in the CS)"
    rx += "".join(f"; {k} = {v!r}" for k, v in NAV_OVERRIDES.items())
    print(f"GNSS outlier benchmark: C navigation filter (core.replay), robust mode on the {where}; {rx}.")
    print(
        "Detection per axis: the fuzzy modes' own alarm (the replay output's alarm flags); the others'\n"
        "rule on the axis' GPS T (plain: single threshold T > chi2_m(0.005); FTA T > chi2_m(1e-4);\n"
        "AKF T > chi2_m(1e-2); IGG-III: T > k1^2, necessary for a removed row). A fix is flagged when\n"
        "any axis is.\n"
        "SW4: 4-epoch sliding-window chi-square at 0.005.\n"
        f"Errors from the first fix + {SETTLE_S:.0f} s; roll/pitch RMS over both angles; pos/vel RMS 3-D."
    )
    if args.ins_seeds or args.cs_seeds:
        if args.ins_seeds:
            ins_seeds(_seed_list(args.ins_seeds), names, args.duration, args.ins_white)
        if args.cs_seeds:
            cs_seeds(_seed_list(args.cs_seeds), names, args.duration, args.cs_only)
        print(f"\nrun time {time.perf_counter() - t_start:.1f} s")
        return
    if not args.no_ins:
        ins = {n: bench_ins_scenario(n, args.seed, args.duration, args.ins_white) for n in names}
        ins_summary(ins)
    if args.ins_only:
        print(f"\nrun time {time.perf_counter() - t_start:.1f} s")
        return
    results = {n: bench_scenario(n, SCENARIOS[n], args.seed, args.duration, args.cs_only) for n in names}
    cs_summary(results, classes=True)
    print(f"\nrun time {time.perf_counter() - t_start:.1f} s")


if __name__ == "__main__":
    main()

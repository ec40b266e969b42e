"""The C navigation filter (float32, ``core.replay``) against the float64 golden model
(``golden.nav.run``), step by step: every IMU output row of every simulator scenario
(docs/ALGORITHMS.md 7-9, DESIGN.md 8 "Golden model vs C").

Both sides are built from the same preset name and the same overrides, and their
configurations are first asserted equal field by field (this catches drift between the C
preset table and the golden one). Recordings are shortened (60-120 s) to keep the file fast.

Tolerances. Continuous quantities: the C core is float32 (eps 6e-8) in a stable filter, so
its gap to float64 stays small and does not grow; each bound below is a few times the
largest gap measured over the cases here (the numbers are in the comments of ``TOL``).
Discrete events (an observation gate or threshold) can flip on a float32 rounding: they are
counted, the count is bounded (see ``MAX_DISCRETE``), and the continuous comparison stops at
the first one rather than hiding it behind a loose tolerance.

Robust modes (ALGORITHMS.md 2, 5, 8): the cases with a ``profile`` run ``core.robust_profile`` on
both sides (the golden configuration built from the same dotted overrides, robust configurations
included in the field-by-field check) over recordings with injected GNSS faults. Their discrete
decisions are compared through what the C output exposes: the CS axes' alarms (flags
``alarm_n``/``alarm_e``/``alarm_d``, in the flag comparison), and the roll/pitch observations made
and skipped (a flagged fix and the ``tau_a`` after it skip them, GPS step 6); a velocity step test
hold shows as both horizontal alarms and skipped observations. A case whose own tolerances differ
(``Case.tol``) says why next to them (``TOL_COAST``, ``TOL_COAST_GUARD``, ``TOL_GUARD_BOTH``, ``TOL_IGG``,
``TOL_IGG_STOP``, ``TOL_AKF``, ``TOL_FTA_INTAKE``, ``TOL_REF_FAR``);
a case where the C differs from the spec is an ``xfail(strict=True)`` with the diagnosis
(``XFAIL``).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mcahrs import core, errors, sim
from mcahrs.golden import attitude as gatt
from mcahrs.golden import cs as gcs
from mcahrs.golden import geo as ggeo
from mcahrs.golden import nav as gnav
from mcahrs.golden import robust as grobust
from mcahrs.samples import GNSS_HAS_ALT, GNSS_HAS_VEL_D, GNSS_HAS_VEL_NE, Recording

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
import gen_vectors as gv  # noqa: E402  (the firmware vectors of three cases' faults: ROWS_VECTORS)

# --------------------------------------------------------------------------------------
# Cases
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One comparison: a simulator scenario, a preset, and overrides applied to both sides."""

    scenario: str
    preset: str
    duration_s: float
    sim_kw: dict[str, Any] = field(default_factory=dict)
    overrides: dict[str, Any] = field(default_factory=dict)  # top-level config fields
    seed: int = 1
    faults: bool = False  # inject bad and edge-case samples (_with_faults)
    nan_velocity: bool = False  # one fix with a NaN east velocity flagged present
    profile: str | None = None  # robust profile on both sides (core.robust_profile)
    receiver_model: bool = False  # the simulator's receiver model (core.receiver_model)
    gnss_faults: tuple[tuple[float, ...], ...] = ()  # GNSS faults (sim.with_gnss_faults)
    cs_only: bool = False  # the profile on the CS axes only (the attitude filter plain)
    tol: dict[str, float] = field(default_factory=dict)  # TOL entries of this case (see TOL_COAST, TOL_IGG)
    tilt_blips: tuple[float, ...] = ()  # start times of 0.8 s specific-force tilts (_with_tilt_blips)
    s_acc_mps: float | None = None  # every fix's reported speed accuracy set to this (_with_fix_edits)
    # (t_s, k, dN m/s, dE m/s): added to the velocity of the k-th fix after the first one valid at or
    # after t_s (k = 0: that one; _with_fix_edits)
    vel_offsets: tuple[tuple[float, int, float, float], ...] = ()


# GNSS faults (t0_s, t1_s, position offset m, velocity offset m/s, azimuth deg[, down position m,
# down velocity m/s]) added to the fixes valid in [t0, t1): the kinds of benchmarks/bench_outliers.py
# (position jumps 5-50 m, velocity spikes 1-5 m/s, bursts of either or both, one long position fault)
# at fixed times.
CAR_FAULTS = (
    (12.0, 12.1, 15.0, 0.0, 30.0),  # single position jump (one fix at 5 Hz)
    (14.0, 14.1, 0.0, 3.0, 200.0),  # single velocity spike
    (16.0, 19.0, 0.0, 1.5, 70.0),  # 1-2 m/s velocity bursts: the step test's (GPS step 3)
    (22.0, 24.0, 0.0, 1.2, 300.0),
    (26.0, 29.0, 10.0, 2.0, 120.0),  # a burst of both
    (35.0, 35.1, 0.0, 5.0, 10.0),  # spike at a stop
    (48.0, 66.0, 25.0, 0.0, 250.0),  # long position fault (18 s of cruise)
    (72.0, 72.1, 0.0, 2.0, 90.0),  # spike at a stop
    (85.0, 88.0, 0.0, 1.8, 150.0),  # velocity burst while pulling away
)
FIXEDWING_FAULTS = (
    (15.0, 15.1, 20.0, 0.0, 20.0),
    (18.0, 18.1, 0.0, 4.0, 100.0),
    (21.0, 24.0, 0.0, 1.5, 0.0),
    (27.0, 29.0, 0.0, 1.1, 230.0),
    (32.0, 35.0, 15.0, 1.5, 120.0),
    (40.0, 60.0, 30.0, 0.0, 300.0),  # long position fault, through turns
    (44.0, 46.0, 0.0, 0.0, 0.0, 25.0, 0.0),  # vertical: a 25 m altitude burst (the D axis alone)
    (50.0, 52.0, 0.0, 0.0, 0.0, 0.0, 2.0),  # and a 2 m/s vertical velocity burst
    (63.0, 87.0, 0.0, 1.0, 160.0),  # 24 s velocity burst: held to the guard (20 s), released armed,
    (80.0, 80.1, 40.0, 0.0, 200.0),  # its end the armed return (GPS step 3)
    (88.0, 88.1, 0.0, 2.5, 45.0),
)

# A car that stops for 25 s (yaw unobserved from ~10 s into the stop): faults before the first
# course-over-ground yaw (no IMU-aided test: fuzzy rows' own test, guard 5), and a long position
# fault through the stop and the pull-away (N and E leave a row out: the aided test's exception,
# ALGORITHMS.md 8 GPS step 3), with velocity faults inside it.
CAR_STOP_FAULTS = (
    (3.0, 3.1, 0.0, 2.5, 60.0),  # at rest, before the first yaw observation
    (4.0, 4.1, 12.0, 0.0, 200.0),
    (40.0, 64.0, 20.0, 0.0, 330.0),  # long position fault from 8 s into the stop to the cruise
    (47.0, 47.1, 0.0, 3.0, 150.0),  # yaw unobserved by now
    (50.0, 53.0, 0.0, 1.5, 250.0),
    (60.0, 62.0, 0.0, 1.4, 80.0),  # pulling away
)

# A 30 s GNSS outage (25-55 s, longer than the CS dt_max: the CS restarts at the first fix after it)
# entered with a fault of both and a velocity burst held, and faults right after it (the step
# test's anchor and the detectors' memories after the restart).
OUTAGE_FAULTS = (
    (15.0, 25.0, 15.0, 0.0, 45.0),
    (20.0, 25.0, 0.0, 1.6, 300.0),
    (56.0, 59.0, 0.0, 1.5, 120.0),
    (62.0, 62.1, 25.0, 0.0, 10.0),
    (64.0, 66.0, 0.0, 3.0, 200.0),
)

# Tolerances of the robust cases where they differ from TOL (measured: the largest of their cases).
# Coasting (fuzzy rows, ALGORITHMS.md 2): p and v move with the IMU increments, which the C forms
# from its float32 attitude; the attitude gap (<= 4.4e-5 rad, within TOL) tilts g by 4e-4 m/s^2,
# which a 2-3 s coast integrates into the velocity (measured 8.3e-4 m/s on rows_fixedwing_rx, the
# 3 s 1.5 m/s burst from 21 s; back to 2e-5 at the first fix that applies the velocity); that fix's
# gain puts it on the acceleration (measured 1.1e-3 m/s^2) and on the test's T (3.5e-3 relative).
# (Over the 810 s runs of benchmarks/bench_outliers.py's fault plan, not run here, the fixed-wing's
# 10-20 s coasts reach 7e-3 m/s and 7e-2 m with every decision the same.)
TOL_COAST: dict[str, float] = {"vel_mps": 3e-3, "acc_mps2": 5e-3, "gps_T_rel": 1e-2}
# A coast to the guard (the fixed-wing's 24 s, 1 m/s burst from 63 s, held 20 s since the step test
# holds a fix nearer the held step than the anchor, ALGORITHMS.md 8 GPS step 3): the same velocity
# gap (measured 1.25e-3 m/s, rx 2.2e-3, within TOL_COAST) integrates into the position for 20 s,
# smoothly from 2e-4 m to 1.16e-2 m (rx 2.95e-2 m at 82 s), back to 1e-3 m at the first fix after the
# hold; every decision equal. The bound is TOL_COAST's velocity bound over the 20 s guard.
TOL_COAST_GUARD: dict[str, float] = {**TOL_COAST, "pos_m": 3e-3 * 20.0}
# A fault of both that lasts the guard (CAR_GUARD_BOTH_FAULTS): every burst fix is flagged (GPS step 6),
# so for 20 s no roll/pitch or course observation is made and the attitude P only propagates. Each
# step's P + Q is rounded to float32 the same way (the x/y gyro-bias variances grow 2.6e-6 relative a
# step at 400 Hz, half an ulp is 6e-8): TOL att_var_rel's static drift, measured 3.8e-5 -> 3.65e-4
# relative on those variances from 12 s to the burst's end at 30 s. The observations after it shrink
# them 16x (9.8e-6 -> 6.0e-7 rad^2/s^2) but not the absolute gap, so the relative one reaches 3.18e-3
# at 37.9 s (2.9-3.1e-3 with the burst at azimuths 20 and 250 deg or on seed 2), over TOL's 3e-3; every
# decision equal. The coast through the burst is TOL_COAST's (measured 1.8e-4 m/s, 1.0e-3 m).
TOL_GUARD_BOTH: dict[str, float] = {**TOL_COAST, "att_var_rel": 1e-2}
# IGG-III: a weight near k1 is steep, w = (k0/s)((k1 - s)/(k1 - k0))^2, so a row at s = 2.95
# (w = 0.002) takes R / w with the float32 rounding of s amplified ~40x: measured on igg3_car 1e-4
# m/s, 3e-4 m/s^2, 3e-4 relative on P (70 s; 6.3e-4 m/s, 7e-4 on P at 82.8 s of a 90 s run), and
# through the long position fault, whose N rows take w = 0.001-0.02 fix after fix, 2.1e-3 on the T
# of 63.5 s (2.2730 vs 2.2683); each back to the plain cases' level a few fixes later.
TOL_IGG: dict[str, float] = {"vel_mps": 3e-3, "acc_mps2": 2e-3, "cs_var_rel": 3e-3, "gps_T_rel": 6e-3}
# IGG-III on the car since N and E are aided through its stops (session 26, GPS step 3): the test prior
# then carries the IMU through the stops, and N's T is 8-15 through the braking of 68-70 s, just after
# the long position fault's end (CAR_FAULTS, igg3_car): its rows sit on the steep part of the weight fix
# after fix, and the C-vs-golden gap, 2e-5 m/s until 66 s, grows to 8.0e-3 m/s, 5.5e-3 m, 4.3e-3 m/s^2
# and 5.2e-3 relative on the CS P at 69.9 s (every decision equal). The golden model against itself with
# +-1e-6 m/s (a float32 rounding at 16 m/s) on the fix velocities: 3.6e-4 m/s, 2.4e-4 relative on the P,
# the same few-hundredfold growth. igg3_car_pos_fault_rx: 3.3e-3 relative on N's velocity variance at
# 45-50 s, the pull-away from a stop, back to 6e-6 by 50 s.
TOL_IGG_STOP: dict[str, float] = {
    **TOL_IGG,
    "pos_m": 1e-2,
    "vel_mps": 1.2e-2,
    "acc_mps2": 6e-3,
    "cs_var_rel": 8e-3,
}
# AKF: Q scaled by q_scale = clamp(log2(alpha + 1)), alpha = mean(window of nu^T nu - tr(R)) /
# tr(H P H^T): a difference of two terms of the size of R, which float32 cancels; the scaled Q moves
# P and the gains (measured on akf_car_cs 1.1e-4 relative on the CS P and 4.5e-5 m/s^2; over 90 s,
# at the braking at 66-69 s, 2.1e-4 and 1.75e-4 m/s^2, 5e-6 m/s^2 away from it; no decision differs).
TOL_AKF: dict[str, float] = {"acc_mps2": 1e-3, "cs_var_rel": 1e-3}
# FTA taking a 30 m position fault in at 2 Hz (fta_fixedwing_pos_fault_2hz_rx, FIXEDWING_POS_FAULT_2HZ): E's
# gain shrunk by gamma = T / chi2_2(1e-4) (15 at 24.0 s, 1.3 at 27.0 s) fix after fix, whose T differs by
# 1-4e-5 relative, then the fixes of 26.5-27.0 s shrink E's velocity variance 11.5x and 3.9x (4.8 -> 0.012
# m^2/s^2): the C's expanded Joseph cancels there as after an outage (TOL cs_var_rel). Measured: the CS P
# 3.8e-6 relative at 23.5 s, doubling a fix to 3.0e-4 (E_vv) at 26.5 s, 2.2e-6 at the next fix; the
# acceleration 7.2e-5 m/s^2 at 27.1 s, back to 6e-6 after 28 s (seeds 2 and 3: 6.7e-4 / 1.4e-4 and 4.0e-4 /
# 1.7e-4, seed 2's velocity 3.2e-4 m/s). No decision differs.
TOL_FTA_INTAKE: dict[str, float] = {"acc_mps2": 3e-4, "cs_var_rel": 1e-3}
# The same fault at 1 Hz (fta_fixedwing_pos_fault_1hz_rx, FIXEDWING_POS_FAULT_1HZ) since session 29, with the
# IMU-aided test (the history ring's spacing follows the fixes: 27.5 ms, 1.29 s): the aided T differs by
# 1.4-5.5e-4 relative from 10 s on (the float32 positions of the 1 s prediction), gamma with it, and E's
# velocity variance, grown to 2.39 m^2/s^2 while the fault goes in (22-24 s), shrinks 24x to 0.10 at 24-26 s:
# 2.14e-3 relative there, 1.3e-4 at 26-28 s, under 1e-5 from 28 s; E's velocity 8.6e-4 m/s and acceleration
# 6.2e-4 m/s^2 at 24-28 s, back to 5e-5 and 1e-5 after 28 s. No decision differs.
TOL_FTA_INTAKE_1HZ: dict[str, float] = {"vel_mps": 1.2e-3, "acc_mps2": 8e-4, "cs_var_rel": 3e-3}
# A restart from the position reference far from home (fta_car_pos_fault_rx, CAR_POS_FAULT; GPS step 4,
# session 25): the N and E fixes' float32 positions, 2 km from home, move the aided T by up to 4.4e-4
# relative a rounding, and the case's largest gps_T gap a 10 s grows with the distance, 4e-4 at 50 s to
# 1.19e-3 at 110 s, before the reference changes anything. The restart at 120.0 s starts N and E at the
# reference with P_NN = sigma_p^2 = 6.25 m^2 (p0_var 25 at the fix), so the position rows weigh more in T
# for the fixes after it: measured 1.52e-3 relative at 123.3 s (C 0.903605, golden 0.905121), 1.08e-3 at
# 130 s; every decision equal, the restart's position within 3e-4 m on both sides.
TOL_REF_FAR: dict[str, float] = {"gps_T_rel": 2e-3}
# Fuzzy inflate's inflated updates (gamma > 1) solve the gain with mca_cholesky_solve since session 28 (a
# division per pivot, where a copy of it multiplied by the reciprocals before): the same gain to rounding.
# In fuzzy_inflate_car_pos_fault_ref_rx, while the 40 s fault goes in (24.5-25.5 s), the acceleration gap
# grew from 3.3e-5 to 9.6e-5 m/s^2 at 24.7 s (velocity 2.1e-5 -> 5.1e-5 m/s, CS P 3.7e-5 -> 8.2e-5
# relative), and it is under 2e-5 again from 25.5 s; no decision differs.
TOL_INFLATE_GAIN: dict[str, float] = {"acc_mps2": 2e-4}

# The velocity step test's rules of ALGORITHMS.md 8, GPS step 3 (fuzzy rows, the receiver model, the
# simulated car; tests/python/test_nav.py's last two tests at short, fast recordings). An 18 s, 1.0 m/s
# velocity-only burst from 2 s before the end of a stop through the pull-away into the cruise: while
# holding, every fix nearer the held step than the anchor (2 s.s0 >= |s0|^2) stays held, so the hold
# lasts the burst although the anchor's variance has grown past the step by then.
CAR_BURST_FAULTS = ((40.0, 58.0, 0.0, 1.0, 306.87),)  # (0.6, -0.8) m/s
# A velocity spike that passes its own test and the clean fix after it (with no fix held, a fix that
# agrees with the anchor before, v_pre + dv, is no step): 0.5 m/s on one fix, 0.2 m/s the other way on
# the next, at the end of a stop and in the cruise; the simulator's velocity noise lowered to 0.01 m/s
# and every fix's s_acc set to 0.1 m/s so that the offsets are what the test sees.
CAR_SPIKE_OFFSETS = ((40.0, 0, -0.5, 0.0), (40.0, 1, 0.2, 0.0), (55.0, 0, 0.3, -0.4), (55.0, 1, -0.12, 0.16))
# The end of a fault the CS took in (GPS step 3): a burst of both, 38 m and 4.7 m/s (bench_outliers.py
# seed 18's), on exactly fuzzy rows' guard of fixes (reject_reset_n, 100 at 5 Hz: 10.2-30.0 s, the
# cruise). The step test holds every burst fix (the velocity rows out). Until session 28 the CS rejected
# them and its guard took the fault in plainly at the last one. Now the position hold (GPS step 4) holds
# the positions from 10.4 s until the anchor, carried on by the CS's coast, is 6.2 m off the held step
# (19.4 s: |e - s_p|^2 > chi2_2(1e-4) V), the per-row test keeps them out after it, and at 26.6 s the
# position passes as the last row standing (30.3 C_t) and is applied beside the step test's velocity rows
# (section 5, session 28: before, no row failing rejected the update): the CS takes 22 m of the fault in.
# The clean fix of 30.2 s is then the first after the step test's hold, disarmed, which the CS leaves its
# velocity out of, and it steps back against the position hold's step while not holding, its position left
# out: the CS restarts from it by either rule (no alarm after it, and no roll/pitch attempt at it). The
# golden model with neither restart alarms on the clean fixes to 43.2 s (with one of them, as the C).
CAR_GUARD_BOTH_FAULTS = ((10.1, 30.1, 38.0, 4.7, 120.0),)
# The held fixes' positions (GPS step 3, fuzzy rows, session 27: while holding, a fix also fails when the held
# fixes' velocities less their positions' change, summed as e over t_e, still say the held step). An 18 s, 1.1
# m/s velocity-only burst (east) over 20-38 s of the multirotor's maneuvers (seed 3), with the receiver model.
# The held step s0 is 0.93 m/s (0.21, 0.91); the anchor, carried on by the IMU increments, drifts toward the
# burst and past it (|s|^2 under k C from 23.6 s; s . s0 / |s0|^2 from 1.2 at the onset to 0.49 at 26.8 s and
# -0.62 at 37.6 s), while the positions' mean e . s0 / (t_e |s0|^2) stays 0.96-1.22: from 26.8 s they alone
# keep 47 of the burst's fixes failing, the hold lasts the burst (20.0-37.8 s), and its first clean fix (38.0
# s) is the return, on both sides. That fix steps back 1.56 |s0| (q = 2.44 |s0|^2), outside the return's size
# window, which is not asked while the positions say the held step. The golden model without the rule released
# the hold at 26.8 s, the CS took the burst in, and its end was held as a step of its own to the guard
# (38.0-57.8 s): it parts from the C at 26.9 s (146 / 146 roll/pitch decisions, 6 flag events); with the size
# window asked there it holds the end 2 s more (to 39.8 s) and parts from the C at 38.1 s (10 / 10, 3).
MULTIROTOR_DRIFT_BURST = ((20.0, 38.0, 0.0, 1.1, 90.0),)
# The return's size window and the positions (GPS step 3, fuzzy rows: 0.25 |s0|^2 <= q <= 2.25 |s0|^2 is not
# asked while the positions say the held step): a 15 s velocity-only burst in the car's cruise (seed 1) whose
# first fix (15.0 s) is half of the rest, 1.0 then 2.0 m/s at azimuth 306.87 deg ((0.6, -0.8) m/s, then twice
# that; tests/python/test_nav.py's burst), with the receiver model. The held step s0 is 1.26 m/s (the first
# fix against the anchor), the positions measure 1.59 |s0| (2.0 m/s) over the hold, and the first clean fix
# (30.0 s) steps back 1.54 |s0| (q = 2.36 |s0|^2): the return, the alarm on the burst's fixes (15.0-29.8 s)
# and none after, on both sides. The golden model with the window asked holds that end as a fix the positions
# still say failing for 25 clean fixes (to 34.8 s) and parts from the C at 30.1 s (25 / 25 roll/pitch
# decisions, 4 flag events). Without the positions' rule it releases at 30.0 s too (the end passes the anchor
# test there).
CAR_HALF_ONSET_BURST = ((15.0, 15.2, 0.0, 1.0, 306.87), (15.2, 30.0, 0.0, 2.0, 306.87))
# The sum's start (GPS step 3, fuzzy rows: the hold's first fix sets e = 0, t_e = 0 and adds nothing, each
# held fix after it adds T (v_fix + v_last) / 2 - (p_fix - p_last)): an 18 s, 1.1 m/s velocity-only burst
# (azimuth 120 deg) over 20-38 s of the fixed-wing's turns (seed 1), with the receiver model. The held step s0
# is 1.14 m/s; the anchor test keeps the hold to 23.4 s (s . s0 / |s0|^2 0.47, |s|^2 0.84 k C at 23.6 s), and
# the positions, summed from the hold's second fix, do not say the held step yet: at 23.6 s e . s0 / (t_e
# |s0|^2) is 0.75 and (e . s0)^2 0.90 k |s0|^2 V_e, so the hold releases there, on both sides (the CS then
# takes the burst in, and neither side alarms again). The golden model with the hold's first fix's term summed
# too (T (v_1 + v_0) / 2 - (p_1 - p_0), v_0 and p_0 the fault-free fix before the hold: half the held step
# over that interval; the reading before the spec's revision) has the positions say the held step from 23.0 s
# (0.96 and 1.57 at 23.6 s), holds the burst to its end and parts from the C at 23.7 s (71 / 72 roll/pitch
# decisions, 4 flag events); so does the one with the sums made before the test, this fix's interval in them
# (tried in session 32 and withdrawn: 0.84 and 1.19 at 23.6 s).
FIXEDWING_FIRST_HELD_BURST = ((20.0, 38.0, 0.0, 1.1, 120.0),)
# The release by the positions (GPS step 3, fuzzy rows, session 32: a held fix does not fail when the held
# fixes' positions agree with their velocities, (e . s0)^2 <= k |s0|^2 V_e, and not with the held step, (t_e
# |s0|^2 - e . s0)^2 > chi2_2(1e-4) |s0|^2 V_e; such a release is not armed and no fault's end) at 2 Hz over
# the car's cruise, braking (30.2-32.3 s) and stop (seed 1), with the receiver model. A velocity-only burst at
# azimuth 120 deg ramps up 0.2 m/s a fix (15.0-17.5 s) to 1.2 m/s (to 25.0 s): the step test passes it fix by
# fix (the anchor follows it, no alarm), so its end (25.0 s) steps back 1.13 m/s from the anchor and is held,
# and the clean fixes after it with it (the anchor keeps them failing: |s|^2 2.8 k C, s . s0 / |s0|^2 1.9 at
# 29.0 s). A 15 m position fault (azimuth 30 deg, 27.0-31.0 s) is held by the position hold (onset 27.0 s,
# released 31.0 s). At 29.0 s (t_e 3.5 s, the held fixes of 25.5-28.5 s) the positions release the velocity
# hold (e . s0 / (t_e |s0|^2) -0.24, (e . s0)^2 0.09 k |s0|^2 V_e, (t_e |s0|^2 - e . s0)^2 1.44 chi2_2(1e-4)
# |s0|^2 V_e; 0.96 at 28.5 s), disarmed; step 6 flags that fix (the position hold), and no restart follows. A
# second 1.2 m/s burst at 120 deg (32.0-36.0 s) is then held from its first fix (to 34.0 s; released by the
# anchor at 34.5 s, armed, its end at 36.0 s the return). Both sides alarm on 25.0-30.5 s and 32.0-34.0 s and
# restart the CS at home only. The golden model without the release holds the clean fixes to the second burst,
# takes its first fix for the fault's end (a restart there) and parts from the C at 31.1 s (12 / 13 roll/pitch
# decisions, 4 flag events); with the release armed it takes the second burst's first fix for the return and
# parts at 32.1 s (14 / 14, 5); with a restart at the release (as a fault's end step 6 flags), at 29.1 s (5 /
# 6, 4). With the sums made before the test (this fix's interval in them, withdrawn) the release comes one fix
# earlier, 28.5 s, and the outputs stay within the tolerances: rows_fixedwing_first_held_rx separates that
# reading.
# (the faults are also the firmware vector nav_rows_release_2hz's, scripts/gen_vectors.py ROWS_VECTORS)
CAR_MISSED_BURST_2HZ = gv.ROWS_VECTORS["nav_rows_release_2hz"][3]
# The end of a position fault the CS took in (GPS step 4): a 100 s, 30 m horizontal position fault (N 18,
# E -24 m, velocity clean; bench_outliers.py's long fault) over 20-120 s of the car's cruise, braking,
# stop and pull-away, with the receiver model. FTA and IGG-III take it in within a few fixes (the GPS-error
# state holds it); the fixes' jump at its start stays ~70 % in J, so at the first clean fix (120.0 s)
# the jump back leaves J within half of the innovation on N and E, and the CS restarts at that fix
# (its position moves 26 m there; measured on seeds 1-3, and with AKF and fuzzy reject or inflate too).
# In both cases of it N and E restart at the position reference, near the fix (see CAR_POS_FAULT_40S).
CAR_POS_FAULT = ((20.0, 120.0, 30.0, 0.0, 306.87),)
# The same rule on a turning vehicle, where its jump definition matters (GPS step 4: j = (z - z_prev) - d,
# d the trapezoid T (v + v_prev) / 2 of the fixes' N (E) velocities): a 25 s, 30 m position fault (N 15,
# E -26 m) over 20-45 s of the fixed-wing's first turn (30 deg of bank, 5.7 m/s^2, to ~33 s) and the leg
# after it, fixes at 2 Hz (T = 0.5 s), FTA with the receiver model (jump bound 1.65 m). The onset's jump
# stays 92 % in J (13.6 / -24.3 m at 44.5 s), the end's (-15.5 / +24.8 m) leaves J at -1.8 / +0.5 against
# nu -15.2 / +24.8: N and E return and the CS restarts at the first clean fix (45.0 s, fix 90; N and E from
# the position reference), on both sides. With the predicted change p - p_0 as d (until session 24) FTA's
# gamma of 3-6 on N (nu 15-20 m) leaves N on its own prediction through the turn, 2-5 m a fix behind the
# fixes, and those were summed as jumps: J of N grew 15 -> 74 m, the end left J at +55 / -23 m, no return,
# no restart to the end (55 s).
# At the simulator's 5 Hz both definitions restart at the end (the lag a fix stays under the bound).
FIXEDWING_POS_FAULT_2HZ = ((20.0, 45.0, 30.0, 0.0, 300.0),)
# Only a fix that jumped returns while a fault is pending (GPS step 4: the axis returns when this fix's j was
# a jump or 4 J^2 <= B, nothing pending, and nu^2 > B and 4 J^2 <= nu^2): the same fault (N 26, E 15 m) at
# 1 Hz fixes (T = 1 s), FTA with the receiver model (jump bound 1.65 m, material bound 9.8 m). The onset jumps
# into J; FTA's shrunk gain then leaves N off the fixes through the turn, the fixes moving on with their
# velocities, while N's fix less the CS grows from 27 m (20 s) to 45 m (25 s) and 147 m (34 s). (Since session
# 29 the history ring's spacing follows the fixes, here 27.5 ms and 1.29 s, which covers a 1 Hz fix and its
# 0.1 s latency: the IMU-aided test and the velocity step test run. Before, on the CS's own prediction, 26, 51
# and 235 m; the figures below are from then.)
# Without the rule's first condition (the jump, J being pending: 4 J^2 > B) N returned at 25.0 s, nu 51.0 m
# past twice J (25.2 m) with a j of -0.5 m: the CS restarted from a faulty fix, took the end's jump (-26.2 /
# -15.1 m) for a jump away (J -26.1 / -15.0 m against nu -26.2 / -15.5 m: no return) and stayed 26 m off after
# it. With it only the end's fix (45.0 s, fix 45) jumped: N and E return and the CS restarts there, on both
# sides (still so with the IMU aid: test_long_position_fault_ends_with_a_cs_restart_at_the_same_fix_...).
FIXEDWING_POS_FAULT_1HZ = ((20.0, 45.0, 30.0, 0.0, 30.0),)
# The predicted change on a fix the velocity step test holds after the hold's first (GPS step 4, n > 1
# after step 3: d = p - p_0): a receiver reporting centimetres (the simulator's position error 1 cm white
# and 1 cm Gauss-Markov, 2 cm vertically; no receiver model, so R is the whole 1.4 cm accuracy and any j
# beyond 7.8 cm is a jump, as on the RTK car drive of bench_outliers_real.py) and a 10 s burst of both,
# 20 m and 2 m/s (N 17.3 m, 1.73 m/s), in the car's cruise under IGG-III. The step test holds every burst
# fix (20.0-29.8 s); the onset jumps +17.1 / +9.9 m into J. IGG-III takes N's position in within a second
# and the fault's velocity with it, which then runs the CS past the fixes (nu of N +17.3 m at 20.2 s,
# -0.4 m at 21 s, -11.0 m at 26.6 s): from 21 s the predicted change carries the burst's 1.73 m/s as the
# fixes' velocities do, j = -0.35 to -0.49 m on N a held fix, counted, and J of N falls from +16.5 m to
# +5.4 m by 26.6 s (fix 133, the hold's 34th), where nu passed twice J: N returns on that held fix and the
# CS restarts from it (a fix 20 m off; n kept, the hold goes on). J then sums the held fixes again (-5.3 /
# -2.9 m at 29.8 s), the first clean fix (30.0 s, fix 150) jumps back -17.4 / -10.1 m (J -22.7 / -13.0 m
# against nu -22.8 / -10.2 m: no return) and the step test's end of a fault the CS took in (GPS step 3)
# restarts the CS there: restarts at 26.6 and 30.0 s on both sides. The rule before (no jump counted on
# such a fix) restarted at 30.0 s only (J of N +16.7 m to the burst's end). The trapezoid of the held
# fixes' velocities (no special case) restarts at the same fixes with the same decisions (j -0.33 to
# -0.39 m on N from 20.2 s), and so do FTA, AKF and fuzzy reject or inflate here with either d (at 30.0 s
# only; their J differ, FTA's N +10.1 m against +2.8 m at 28 s, but none returns): this recording does
# not separate the predicted change from the trapezoid.
CAR_RTK_SIM = {
    "gps_pos_sigma_h_m": 0.01,
    "gps_pos_white_h_m": 0.01,
    "gps_pos_sigma_v_m": 0.02,
    "gps_pos_white_v_m": 0.02,
}
CAR_RTK_BURST_BOTH = ((20.0, 30.0, 20.0, 2.0, 30.0),)
# A position fault's end inside a hold (GPS step 4, the predicted change on a fix held after the hold's
# first): the car with a 10 s cruise (accelerating 5-10 s, braking at 8 m/s^2 from 20.0 s), an 11 s, 30 m
# position fault (N 18, E -24 m, velocity clean) over 10-21 s, and a 0.8 s tilt of the specific force from
# 20.0 s (_with_tilt_blips: the IMU-aided increments 4.7 m/s^2 off) under AKF with the receiver model.
# The onset jumps +17.6 / -24.6 m into J; AKF takes the fault in (nu -0.1 / -0.5 m at 19.8 s). The tilt
# makes the step test hold from 20.4 s to the end of the recording (n 48 at 29.8 s, within the n T < 20 s
# guard), so the fault's end (21.0 s, fix 105) is the hold's 4th fix: its d is the predicted change,
# j = -17.7 / +23.7 m leaves J at -0.8 / -0.1 m against nu -17.7 / +23.8 m, N and E return and the CS
# restarts there, on both sides (N and E from the position reference; its position moves 4.1 m: AKF held
# the fault in eps_p). With the rule before (no jump counted on such a fix) J stayed +16.9 / -23.7 m, no
# return and no restart to the end (30 s): the golden model then parts from the C at 21.1 s (13 / 14
# roll/pitch decisions, a flag event).
# The fixes' velocities are clean here, so their trapezoid gives the same j within 0.2 m (the seed 15 car
# of bench_outliers.py held for a wrong yaw, not a velocity fault).
CAR_POS_FAULT_END_HELD = ((10.0, 21.0, 30.0, 0.0, 306.87),)
# The position reference (GPS step 4, session 25): a restart at a fault's end starts N and E at p_ref (the CS
# position of the last quiet fix, carried on by the fixes' d) with position variance sigma_p^2, when both are
# within the material bound of it. A 40 s, 30 m position fault (N 18, E -24 m, velocity clean) over 20-60 s
# of the car's cruise, braking, 10 s stop and pull-away, fuzzy inflate with the receiver model (material
# bound 9.8 m). The last quiet fix is 19.8 s; the onset jumps +17.6 / -24.0 m into J (no quiet fix after it:
# a fault pending), and fuzzy inflate takes the fault in (|nu| under 0.9 m over 59-60 s). At the first clean
# fix (60.0 s, fix 300) the jump back leaves J at -2.5 / +2.8 m against nu -18.0 / +23.8 m: N and E return,
# and the fix is -2.2 / -3.8 m from p_ref (carried 40 s, 200 fixes): both near, so the CS restarts at p_ref
# with P_NN = sigma_p^2 = 6.25 m^2, 4.41 m from the fix, on both sides. The golden model without the reference
# (the restart at the fix, P_NN = p0_var 25 m^2) parts from the C at 60.1 s: 4.41 m of horizontal position
# (3.84 m on E), the CS P 0.75 relative, gps_T 1.06 relative; no decision differs. With it every gap is
# within TOL (measured 5.3e-6 rad of attitude, 3.2e-4 m, 3.7e-5 relative on the CS P, 6.5e-4 on gps_T).
CAR_POS_FAULT_40S = ((20.0, 60.0, 30.0, 0.0, 306.87),)
# Nothing pending is asked of both N and E (GPS step 4, session 25: an axis returns when its own j was a jump
# or 4 J^2 <= B on N and on E, each its own J and B, and its own nu^2 > B and 4 J^2 <= nu^2): the multirotor
# under IGG-III with the receiver model (material bound 9.8 m), a 30 m position fault mostly along E (azimuth
# 84 deg: N 3.1, E 29.8 m) over 20-50 s, and inside it a velocity fault along N ramped in 0.5 m/s steps a
# second to 2 m/s and back over 25-37 s (steps small enough that the velocity step test's end of a fault the
# CS took in restarts nothing; 1 m/s steps restarted the CS at the first step down, 34.0 s, clearing J on both
# sides and with either rule). The onset jumps +3.7 / +30.0 m into J (N within half the material bound, E
# pending); IGG-III takes E's fault in (nu of E 0.9 m by 30 s, J of E +28.6 m at 34.4 s, +27.2 m at the end)
# and follows the faulty N velocity past N's fixes: nu of N +3.1 m at 28 s, -10.4 m at 34.4 s, -13.3 m at 37.8
# s, back to -0.3 m at 40 s, every j of N within the bound (J of N +3.5 m). With the rule before (4 J^2 <= B
# of the axis itself) N returned at 34.4 s with E's fault pending: the CS restarted into it from that fix
# (10.2 m N, 15.8 m E off the C's at 34.6 s), J went to 0, the fault's end (50.0 s, fix 250) jumped E back
# -29.7 m for J -29.7 against nu -29.8 m (no return), and no restart followed to the end (60 s). With it N's
# return waits on E (N materially off on the fixes of 34.4-37.8 s), and at the fault's end E returns (J -2.5
# against nu -29.7 m) and the CS restarts there, on both sides (at the fix, moving 18.4 m: N's p_ref, carried
# by the fixes' faulty velocities, is far). The benchmark's case (seed 33's 900 s multirotor) has no velocity
# fault: IGG-III's N drifted 12 m from its fixes 28 s into the fault. In the 90 s runs tried here (seeds 1-6,
# the E fault alone over 20-80 or 30-85 s) |nu| of N stayed under 0.8 sqrt(B), so no return; FTA, AKF, fuzzy
# reject and fuzzy inflate on this recording restart at the same fixes with either rule (seeds 1-4).
MULTIROTOR_POS_FAULT_E_VEL_N = ((20.0, 50.0, 30.0, 0.0, 84.0),) + tuple(
    (25.0 + k, 37.0 - k, 0.0, 0.5, 0.0) for k in range(4)
)
# The position hold (GPS step 4, session 28; fuzzy rows, the receiver model, the simulated car of seed 1
# unless said). The hold's numbers depend on the fixes alone (their positions, velocities and the receiver
# model's V), so the same faults on the fixed-wing and the multirotor of seed 1 take the same decisions; each
# recording is the simulator's at its own duration (another duration is another recording).
# A small position-only burst held to its end: 6 m (N 3.6, E -4.8 m) over 20-35 s of the cruise. The burst's
# first fix (20.0 s) is out by the per-row test, and the hold starts after its update (s_p = 3.42 / -5.02 m
# against the anchor carried on by the fixes' velocities); every fix after it stays held (N and E position
# rows out, D >= 2: N and E alarm) while the anchor wanders 2.6 m toward the fault with the receiver's
# Gauss-Markov error (e . s_p / |s_p|^2 from 1.0 to 0.57 at 34.8 s), and the first clean fix (35.0 s) steps
# back and ends it: no alarm after it, on both sides. The golden model without the hold (never anchored) lets
# the burst in at 28.8 s, 9 s in, as the per-row test did before session 28 (the position's variance grown
# back), and alarms on the clean fixes of 35.0-41.8 s: it parts from the C at 23.1 s (5 flag events).
CAR_POS_BURST = ((20.0, 35.0, 6.0, 0.0, 306.87),)
# A position fault longer than fuzzy rows' whole-update guard (reject_reset_n, 100 fixes at 5 Hz: 20 s), held
# past it by the significance: 12 m (N 7.4, E -10.0 m) over 15-43 s (28 s). N's position row is out 100
# updates in a row at 35.0 s, and from there the hold lasts only while (e . s_p)^2 > chi2_2(0.005) |s_p|^2 V:
# 1.25-1.71 times that to the fault's last fix (42.8 s); its first clean fix steps back and ends the hold. The
# golden model with the guard alone releases the hold at 35.0 s, the per-row test (the velocity applied, the
# position's own level chi2_1(0.005)) takes the 12 m in at once there, and it parts from the C at 35.1 s (a
# flag event, a roll/pitch decision); without the hold it lets the fault in after 34.8 s and alarms on the
# clean fixes of 43.0-54.8 s. At 30 m the per-row test alone holds the fault out for its 28 s (the position's
# variance does not grow to 30 m in that time): with the guard alone the golden model then parts from the C
# only at the fault's first clean fix (43.1 s, one roll/pitch decision), which the alarms do not show.
CAR_POS_FAULT_28S = ((15.0, 43.0, 12.0, 0.0, 306.87),)
# A burst of both whose end the step back finds (seed 4): 8 m and 1.5 m/s east (azimuth 90 deg) over 20-35 s,
# through the car's braking to a stop. The velocity step test holds every burst fix (the velocity rows out),
# the hold the positions (s_p = -0.39 / +8.26 m), so the CS coasts on the IMU through the braking, and the
# anchor, carried on by the CS's predicted change on the fixes the step test holds after its first, drifts
# with that coast: 7.5 m west by 34.8 s (e 15.7 m east; the coast reaches the stop 1 m/s off). The first clean
# fix (35.0 s, e = -2.12 / +7.44 m) is then nearer the held step than the anchor (2 e . s_p = 1.82 |s_p|^2),
# within g4 V of it and under the guard: only its step back (r against s_p) ends the hold, on both sides, and
# the CS, its position variance grown to 42 m^2, takes the fix in whole (no alarm, no restart). The golden
# model without the step back in the hold's rule keeps the clean fixes held to 46.0 s and parts from the C at
# 35.1 s (a flag event).
CAR_BURST_BOTH_BACK = ((20.0, 35.0, 8.0, 1.5, 90.0),)
# The hold's restart (a fix that steps back while not holding, its N or E update leaving the position row
# out): the burst of CAR_POS_BURST 2 s longer (20-37 s). The anchor's wander with the receiver's error (e .
# s_p / |s_p|^2 0.45 at 35.4 s: nearer the anchor than the held step) releases the hold 1.6 s before the
# burst's end; the anchor restarts at the faulty fixes, and the CS, its alarm released, takes part of the
# fault in. The first clean fix (37.0 s) steps back against the held step kept, its update leaves the position
# out, and the CS restarts from it on both sides (no alarm after 35.2 s). The golden model without the restart
# alarms on the clean fixes of 37.0-45.6 s and parts from the C at 37.1 s (3 flag events, a roll/pitch
# decision).
CAR_POS_BURST_RESTART = ((20.0, 37.0, 6.0, 0.0, 306.87),)
# A fix that steps back while holding ends the hold and restarts nothing ("while not holding": holding at the
# fix's start): the burst of CAR_POS_BURST with a 0.4 m/s velocity fault the other way (azimuth 126.87 deg),
# small enough for the velocity step test and the CS to let in. The anchor, carried on by the faulty
# velocities, runs from the fixes along s_p (e . s_p / |s_p|^2 1.0 -> 1.7), the CS (velocity in, position held
# out) the same way, and the first clean fix (35.0 s) is still nearer the held step than the anchor (2 e . s_p
# = 1.08 |s_p|^2): its step back ends the hold, while E's update, the CS off by the velocity it took in,
# leaves the position (and the velocity) out. No restart on either side; E alarms after 35.0 and 35.2 s. The
# golden model reading *holding* after the release restarts the CS there and parts from the C at 35.1 s (10 /
# 11 roll/pitch decisions, 2 flag events); without the step back the first clean fix stays held, and it parts
# there too.
CAR_POS_VEL_DRIFT = ((20.0, 35.0, 6.0, 0.0, 306.87), (20.0, 35.0, 0.0, 0.4, 126.87))
# The hold's restart on a fix the velocity step test holds, and p_last NaN (GPS step 3: every CS
# (re-)initialisation makes z_prev NaN): CAR_POS_BURST_RESTART with an 18 s, 1.1 m/s east velocity burst from
# 36.0 s. The step test holds from 36.0 s; the position hold restarts the CS at 37.0 s (n = 6 kept), so the
# next held fix sums T (v_fix + v_last) / 2 - (p_fix - NaN) and the held fixes' positions say nothing for the
# rest of the hold: the anchor test alone releases it at 50.0 s, 4 s before the burst's end (no alarm after
# 49.8 s; the CS takes the rest of the burst in and restarts at its end, 54.0 s, GPS step 3), on both sides.
# The golden model that adds nothing for the NaN term (or restarts the sum there) keeps the positions' rule
# and the hold to the burst's end, and parts from the C at 50.1 s (19 / 20 roll/pitch decisions, 3 flag
# events); without the restart it alarms from 20.0 s to 53.8 s and parts at 37.1 s.
CAR_POS_BURST_RESTART_HELD = CAR_POS_BURST_RESTART + ((36.0, 54.0, 0.0, 1.1, 90.0),)
# The position hold's d on the fixes the step test holds, its first included, and on the fix after a held one
# (GPS step 4, fuzzy rows: the CS's predicted change, where the trapezoid T (v + v_prev) / 2 would carry the
# held velocity into the anchor): a 4 m/s east velocity spike on one fix of the car's cruise at 2 Hz (seed 1,
# 45 s, T 0.5 s), with the receiver model, on the fix of 22.0 s (CAR_SPIKE_HELD_2HZ) or of 21.5 s
# (CAR_SPIKE_BEFORE_2HZ). The step test holds the spike's fix (n = 1) and releases at the next. The fix of
# 22.0 s is one whose N and E updates leave the position row out (either rule; its jump against the predicted
# change -0.45 / -1.38 m), so the hold's onset there reads |j|^2 > g4 V (g4 V 5.23 m^2, V 0.284 m^2): with the
# predicted change |j|^2 is 2.11 (2.07) m^2, no hold, and both sides alarm on the spike's fix (22.0 s; 21.5 s,
# and by E's per-row test 22.0-22.5 s). With the trapezoid there (the rule before: the hold's first fix and
# the fix after a hold took it) d carries 1.04 m of the spike east, j = -0.43 / -2.42 m (6.05 m^2): the hold
# starts at 22.0 s, the anchor (carried another 1.04 m at 22.5 s when the spike is on 22.0 s) holds the clean
# fixes until the fix of 29.0 s steps back, and that golden model alarms on 22.0-28.5 s (21.5-28.5 s) and
# parts from the C at 22.6 s: 1 flag event (within MAX_DISCRETE; the alarms' test catches it), 2 with the
# spike on 21.5 s. Each case parts so with only its own half of the revision missing (CAR_SPIKE_HELD_2HZ the
# hold's first fix, CAR_SPIKE_BEFORE_2HZ the fix after a hold).
CAR_SPIKE_HELD_2HZ = ((22.0, 22.5, 0.0, 4.0, 90.0),)
CAR_SPIKE_BEFORE_2HZ = ((21.5, 22.0, 0.0, 4.0, 90.0),)
# The lock-up guard inside a position hold (GPS step 4, session 33): a 20 s burst of both, 23.9 m and 1.4 m/s
# at azimuth 30 deg, on the car of seed 1 at 2 Hz (the size of bench_outliers.py --sim gps_rate_hz=2, seed
# 29's car). The step test holds its velocity and the position hold its position, so each update is rejected
# and the 40th, the burst's last fix (39.5 s), is the whole-update guard's: done plain, the CS takes the burst
# in, which sets *taken*; the hold goes on, and the first clean fix (40.0 s) steps back while holding with
# *taken* set: the CS restarts. With the step back only ending the hold (the C before; at azimuths 0, 79 and
# 200 deg the step test's return restarts it there anyway) the clean fixes stood the held step from a CS
# inside the burst and a new hold started on them: alarmed from 40.0 s to the end, no restart.
# (the firmware vector nav_rows_taken_2hz's too)
CAR_GUARD_BOTH_2HZ = gv.ROWS_VECTORS["nav_rows_taken_2hz"][3]
# Fixes without latency and an IMU whose times jitter (GPS step 3's increments past the newest history entry,
# session 33): the simulator's car at 400 Hz, its IMU times off by up to 0.6 ms (imu_time_jitter_us) and
# the fixes' latency 0, as on the real car drive. An entry is pushed once its samples reach the 20 ms spacing,
# so it often takes a ninth, and at a fix just before such a push the newest entry ends up to 23 ms before it:
# 19 of the 276 fixes (measured in the C). The increments hold the newest entry for up to twice the spacing.
# Held for one (the C before), those fixes had none, so no IMU-aided test and no step test; the burst of both
# (32-42 s) has four (35.2, 36.4, 38.0 and 41.4 s), and the C before let its 35.2 s fix in, alarmed on 42.2
# and 42.4 s after it, and ran 22 m from the C of now. Held for two: alarmed on the bursts' fixes, nowhere
# after. (The firmware vector nav_rows_jitter's too.)
CAR_JITTER_FAULTS = gv.ROWS_VECTORS["nav_rows_jitter"][3]

CASES: dict[str, Case] = {
    # Ground vehicle, yaw from course over ground, each compensation mode.
    "car_cs": Case("car_accel_brake", "ground", 60.0),
    "car_plain": Case("car_accel_brake", "ground", 60.0, overrides={"comp_mode": 0}),
    "car_gpsdiff": Case("car_accel_brake", "ground", 60.0, overrides={"comp_mode": 2}),
    # Fixed wing in coordinated turns (aligned in the 10 s of steady straight flight first).
    "fixedwing_turns": Case("fixedwing_turns", "fixedwing", 90.0),
    # Multirotor, yaw from the magnetometer, no centripetal term.
    "multirotor_mag": Case("multirotor_aggressive", "multirotor", 60.0),
    # GPS outages of 30 s (> CS dt_max 10 s: re-initialisation at the first fix after it):
    # lost-GPS observations with the decaying CS acceleration and the centripetal term.
    "outage_fixedwing": Case("gps_outage", "fixedwing", 100.0, {"vehicle": "fixedwing", "outage_s": 30.0}),
    "outage_car_gpsdiff": Case(
        "gps_outage", "ground", 100.0, {"vehicle": "car", "outage_s": 30.0}, {"comp_mode": 2}
    ),
    "outage_multirotor": Case("gps_outage", "multirotor", 100.0, {"vehicle": "multirotor", "outage_s": 30.0}),
    # Short outages (longer than gps_timeout, shorter than the CS dt_max) in turns: the CS
    # predicts across them; in mode 2 the first fix after one has no usable previous fix.
    "short_outages_cs": Case(
        "fixedwing_turns", "fixedwing", 80.0, {"gps_outages": ((25.0, 31.0), (50.0, 53.0))}
    ),
    "short_outages_gpsdiff": Case(
        "fixedwing_turns", "fixedwing", 80.0, {"gps_outages": ((25.0, 31.0), (50.0, 53.0))}, {"comp_mode": 2}
    ),
    # Bad and edge-case inputs injected (statuses, re-anchoring, saturation, defaults, zero mag).
    "faults_car": Case("car_accel_brake", "ground", 60.0, faults=True),
    "faults_multirotor": Case("multirotor_aggressive", "multirotor", 60.0, faults=True),
    "nan_velocity_fix": Case("car_accel_brake", "ground", 40.0, nan_velocity=True),
    # The receiver model (ALGORITHMS.md 8, GPS step 4): R from the white parts, below the
    # simulator's reported 2.52 / 5.02 m.
    "car_receiver_model": Case(
        "car_accel_brake", "ground", 60.0, overrides={"gps_pos_white_m": 0.3, "gps_alt_white_m": 0.5}
    ),
    # At rest: no course over ground (speed 0), yaw unobserved, roll/pitch only.
    "static": Case("static", "ground", 60.0, {"roll_deg": 5.0, "pitch_deg": -3.0, "yaw_deg": 40.0}),
    # Constant velocity from t = 0 (a car never at rest, aligned while moving straight).
    "steady_car": Case("steady", "ground", 60.0, {"vehicle": "car", "speed_mps": 15.0}),
    # Robust modes (ALGORITHMS.md 5) at the navigation level under GNSS faults: fuzzy rows (the N/E
    # pair, coasting, the IMU-aided test and its exception, flagged fixes, the velocity step test)
    # on the car and the fixed-wing, with and without the receiver model; each other mode once.
    "rows_car": Case(
        "car_accel_brake", "ground", 90.0, profile="fuzzy-rows", gnss_faults=CAR_FAULTS, tol=TOL_COAST
    ),
    "rows_car_rx": Case(
        "car_accel_brake",
        "ground",
        90.0,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_FAULTS,
        tol=TOL_COAST,
    ),
    "rows_fixedwing": Case(
        "fixedwing_turns",
        "fixedwing",
        90.0,
        profile="fuzzy-rows",
        gnss_faults=FIXEDWING_FAULTS,
        tol=TOL_COAST_GUARD,
    ),
    "rows_fixedwing_rx": Case(
        "fixedwing_turns",
        "fixedwing",
        90.0,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=FIXEDWING_FAULTS,
        tol=TOL_COAST_GUARD,
    ),
    "rows_car_stop": Case(
        "car_accel_brake",
        "ground",
        68.0,
        {"stop_s": 25.0},
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_STOP_FAULTS,
        tol=TOL_COAST,
    ),
    "rows_outage_fixedwing": Case(
        "gps_outage",
        "fixedwing",
        70.0,
        {"vehicle": "fixedwing", "gps_outages": ((25.0, 55.0),)},
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=OUTAGE_FAULTS,
        tol=TOL_COAST,
    ),
    "fta_car": Case("car_accel_brake", "ground", 70.0, profile="fta", gnss_faults=CAR_FAULTS),
    # TOL_AKF's cancellation, here on the innovations: with the CS restarted at the bursts' ends (19.0,
    # 24.0 s) but not at the unflagged spike's (14.2 s), the burst of both (26-29 s) meets N at ~290 m,
    # where a float32 position step is 3e-5 m, with 5-12 m innovations, just as the AKF Q scale leaves
    # its clamp: N's acceleration variance 3.1e-4 relative at 28.0 s (1e-6 before 26 s; no decision
    # differs). The golden model alone, with 3e-5 / 1e-4 m added to its innovations there, moves the same
    # variance 9.7e-5 / 3.2e-4 at the same fix.
    "akf_car": Case("car_accel_brake", "ground", 30.0, profile="akf", gnss_faults=CAR_FAULTS, tol=TOL_AKF),
    # AKF on the CS axes alone (the attitude filter plain)
    "akf_car_cs": Case(
        "car_accel_brake", "ground", 70.0, profile="akf", gnss_faults=CAR_FAULTS, cs_only=True, tol=TOL_AKF
    ),
    "fuzzy_car": Case("car_accel_brake", "ground", 70.0, profile="fuzzy", gnss_faults=CAR_FAULTS),
    "fuzzy_inflate_car": Case(
        "car_accel_brake", "ground", 70.0, profile="fuzzy-inflate", gnss_faults=CAR_FAULTS
    ),
    # The attitude filter's fuzzy detector rejecting roll/pitch observations (tilted specific force;
    # the CS axes on their own test, gps_test_imu 0, so that the IMU fault flags no fix): a rejected
    # observation is made, not skipped (golden/nav.py, choice 13).
    "fuzzy_car_tilt_blips": Case(
        "car_accel_brake",
        "ground",
        40.0,
        overrides={"gps_test_imu": 0},
        profile="fuzzy",
        tilt_blips=(15.0, 22.0, 35.0),
    ),
    # IGG-III also reaches GPS step 4's return with nothing pending (J 0 since the step test's restart at
    # the burst of both's end, 29.0 s): the CS drifts from the clean fixes after it and N returns at 32.4 s
    # (nu -11.7 m; N and E near the position reference, from which the CS restarts: its position moves
    # 12.3 m), on both sides (test below). Requiring this fix's jump always, the golden model parts from the
    # C there (3 / 4 roll/pitch decisions).
    "igg3_car": Case(
        "car_accel_brake", "ground", 70.0, profile="igg3", gnss_faults=CAR_FAULTS, tol=TOL_IGG_STOP
    ),
    # The velocity step test (ALGORITHMS.md 8, GPS step 3): a burst held to its end, a spike that
    # passed blamed instead of the clean fix after it, and the end of a fault of both the CS took in at
    # its guard (CAR_BURST_FAULTS, CAR_SPIKE_OFFSETS, CAR_GUARD_BOTH_FAULTS).
    "rows_car_burst18_rx": Case(
        "car_accel_brake",
        "ground",
        66.0,
        seed=2,  # every burst fix held (seed 1: released 0.8 s before the end, on both sides)
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_BURST_FAULTS,
        tol=TOL_COAST,
    ),
    "rows_car_spike_rx": Case(
        "car_accel_brake",
        "ground",
        62.0,
        {"gps_vel_sigma_h_mps": 0.01},
        profile="fuzzy-rows",
        receiver_model=True,
        s_acc_mps=0.1,
        vel_offsets=CAR_SPIKE_OFFSETS,
        tol=TOL_COAST,
    ),
    "rows_car_guard_both_rx": Case(
        "car_accel_brake",
        "ground",
        45.0,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_GUARD_BOTH_FAULTS,
        tol=TOL_GUARD_BOTH,
    ),
    # The held fixes' positions keep a burst held that the anchor drifted toward, and the return's size window
    # is not asked while they say the held step (MULTIROTOR_DRIFT_BURST, CAR_HALF_ONSET_BURST); within TOL
    # (measured 4.0e-5 m/s, 3.6e-4 m, 4.9e-5 m/s^2 on the multirotor; 2.1e-5 m/s, 1.2e-4 m on the car).
    "rows_multirotor_drift_burst_rx": Case(
        "multirotor_aggressive",
        "multirotor",
        60.0,
        seed=3,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=MULTIROTOR_DRIFT_BURST,
        tol=TOL_COAST,
    ),
    "rows_car_half_onset_burst_rx": Case(
        "car_accel_brake",
        "ground",
        45.0,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_HALF_ONSET_BURST,
        tol=TOL_COAST,
    ),
    # The sum's start (FIXEDWING_FIRST_HELD_BURST): the hold releases 3.6 s into the burst (14 s before its
    # end), on both sides; the coast to it within TOL_COAST (measured 2.4e-4 m/s, 4.9e-4 m/s^2).
    "rows_fixedwing_first_held_rx": Case(
        "fixedwing_turns",
        "fixedwing",
        60.0,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=FIXEDWING_FIRST_HELD_BURST,
        tol=TOL_COAST,
    ),
    # The release by the positions (CAR_MISSED_BURST_2HZ), at 2 Hz; within the default tolerances (measured
    # 4.4e-5 m/s, 2.8e-5 m/s^2).
    "rows_car_missed_burst_2hz_rx": Case(
        "car_accel_brake",
        "ground",
        40.0,
        {"gps_rate_hz": 2.0},
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_MISSED_BURST_2HZ,
    ),
    # The velocity step test in a whole-update mode (ALGORITHMS.md 8, GPS step 3, and step 6): FTA on the
    # burst of rows_car_burst18_rx (same seed; course over ground the car's yaw source). The test holds
    # every burst fix (90, 40.0-57.8 s: 18 s, under the other modes' n T < 20 s guard) and releases at the
    # first clean one, disarmed; the hold changes no update and raises no alarm, but the held fixes give
    # no course observation: the C's yaw_unobserved flag (set at 41.9 s, 10 s after the braking's last
    # course) clears at 58.3 s, at 43.7 s without the burst (its yaw variance grows 3.4e-4 -> 1.3e-3 rad^2
    # over the burst, shrinks to 8.9e-5 without it; golden yaw observations 165, 235 with the test not run
    # in FTA). The held fixes from 42 s are aided by step 3's exception alone (n > 0). The golden model
    # without the course rule, without that exception, or with the test in fuzzy rows only parts from the
    # C at 43.5 s (11 observation decisions; gps_T 0.97 relative; both). The first clean fix (58.0 s, fix
    # 290) is the fault's end, and step 6 flags it (N's tested T 11.4 over chi2_2(0.01) = 9.21, E detected,
    # T 38.3; neither left its velocity out), so the CS restarts from it (GPS step 3, the end of a fault the
    # CS took in): FTA had taken the burst in, and the restart moves the CS 11.9 m and 0.94 m/s (the same
    # on both sides). The CAR_FAULTS cases restart at their bursts' ends (19.0, 24.0, 29.0 s: flagged) in
    # FTA, AKF, fuzzy reject / inflate and IGG-III, at the spikes' ends (14.2, 35.2 s) in fuzzy reject /
    # inflate only (E's T over chi2_2(0.01); FTA, AKF and IGG-III do not flag them), in fuzzy rows at none.
    "fta_car_burst_rx": Case(
        "car_accel_brake",
        "ground",
        66.0,
        seed=2,
        profile="fta",
        receiver_model=True,
        gnss_faults=CAR_BURST_FAULTS,
    ),
    # The end of a position fault the CS took in (ALGORITHMS.md 8, GPS step 4; CAR_POS_FAULT). IGG-III's
    # steep weights through the fault reach 2.2e-3 m/s, 1.2e-3 m/s^2, 2.6e-3 relative on the CS P at the
    # pull-away of 82 s (within TOL_IGG; 1e-5 after the restart); FTA within TOL but its T after the
    # restart from the position reference (TOL_REF_FAR).
    "fta_car_pos_fault_rx": Case(
        "car_accel_brake",
        "ground",
        140.0,
        profile="fta",
        receiver_model=True,
        gnss_faults=CAR_POS_FAULT,
        tol=TOL_REF_FAR,
    ),
    "igg3_car_pos_fault_rx": Case(
        "car_accel_brake",
        "ground",
        140.0,
        profile="igg3",
        receiver_model=True,
        gnss_faults=CAR_POS_FAULT,
        tol=TOL_IGG_STOP,
    ),
    # The jumps against the fixes' velocities in a turn (FIXEDWING_POS_FAULT_2HZ): the golden model with the
    # predicted change as d parts from the C at 45.1 s (no restart; 15 roll/pitch decisions, 24 m).
    "fta_fixedwing_pos_fault_2hz_rx": Case(
        "fixedwing_turns",
        "fixedwing",
        55.0,
        {"gps_rate_hz": 2.0},
        profile="fta",
        receiver_model=True,
        gnss_faults=FIXEDWING_POS_FAULT_2HZ,
        tol=TOL_FTA_INTAKE,
    ),
    # Only a fix that jumped returns while a fault is pending (FIXEDWING_POS_FAULT_1HZ): the golden model
    # without that condition
    # parts from the C at 25.1 s (a restart inside the fault; 21 / 23 roll/pitch decisions, 6 flag events).
    # FTA's gain shrinks here too, but its gaps stay within TOL (measured: attitude 5.7e-5 rad, att_var_rel
    # 1.5e-3, CS P 1.4e-5 relative, acceleration 8.1e-6 m/s^2, gps_T 2.0e-4 relative).
    "fta_fixedwing_pos_fault_1hz_rx": Case(
        "fixedwing_turns",
        "fixedwing",
        60.0,
        {"gps_rate_hz": 1.0},
        profile="fta",
        receiver_model=True,
        gnss_faults=FIXEDWING_POS_FAULT_1HZ,
        tol=TOL_FTA_INTAKE_1HZ,
    ),
    # The predicted change on a held fix after the hold's first (CAR_RTK_BURST_BOTH): a return on a held
    # fix inside the burst (26.6 s, fix 133), then the step test's restart at its end (30.0 s). The golden
    # model with the rule before (no jump on such a fix) restarts at 30.0 s only and parts from the C at
    # 26.7 s, which the step-by-step comparison alone lets through (the rows from the first differing
    # decision on are not compared, and that decision is a single roll/pitch event, within MAX_DISCRETE):
    # test_long_position_fault_ends_with_a_cs_restart_at_the_same_fix_on_both_sides catches it. It does not
    # separate the predicted change from the held fixes' trapezoid (see CAR_RTK_BURST_BOTH). IGG-III's steep
    # weights: TOL_IGG (measured 1.1e-4 m/s^2, 2.5e-4 relative on the CS P, 3.9e-4 on gps_T, 1.4e-4 m/s).
    # CAR_POS_FAULT_END_HELD; within TOL (measured 2.3e-5 rad of attitude, 3.6e-4 relative on the
    # attitude P, 7.3e-5 on the CS P, 1.5e-5 m/s^2, 1.1e-4 on gps_T).
    "akf_car_pos_fault_end_held_rx": Case(
        "car_accel_brake",
        "ground",
        30.0,
        {"cruise_s": 10.0},
        profile="akf",
        receiver_model=True,
        gnss_faults=CAR_POS_FAULT_END_HELD,
        tilt_blips=(20.0,),
    ),
    "igg3_car_rtk_burst_both": Case(
        "car_accel_brake",
        "ground",
        40.0,
        CAR_RTK_SIM,
        profile="igg3",
        gnss_faults=CAR_RTK_BURST_BOTH,
        tol=TOL_IGG,
    ),
    # The restart from the position reference (CAR_POS_FAULT_40S): the golden model restarting at the fix
    # instead parts from the C at 60.1 s (4.41 m, CS P 0.75 relative; no decision differs).
    "fuzzy_inflate_car_pos_fault_ref_rx": Case(
        "car_accel_brake",
        "ground",
        75.0,
        profile="fuzzy-inflate",
        receiver_model=True,
        gnss_faults=CAR_POS_FAULT_40S,
        tol=TOL_INFLATE_GAIN,
    ),
    # Nothing pending on N and on E (MULTIROTOR_POS_FAULT_E_VEL_N): the golden model with the rule before
    # (4 J^2 <= B of the axis itself) parts from the C at 34.5 s (N's return into E's fault: 4 / 2
    # roll/pitch decisions, a flag event; 10.2 / 15.8 m N / E at once, 29.8 m on E after the fault's end,
    # 0.74 deg of roll/pitch). IGG-III's steep weights: TOL_IGG (measured 8.7e-5 m/s^2 at 28.1 s, 3.0e-4 m/s,
    # 4.9e-4 m, 8.7e-5 relative on the CS P, 1.0e-4 on gps_T).
    # The position hold (GPS step 4, session 28): CAR_POS_BURST, CAR_POS_FAULT_28S, CAR_BURST_BOTH_BACK,
    # CAR_POS_BURST_RESTART, CAR_POS_VEL_DRIFT, CAR_POS_BURST_RESTART_HELD. Every decision equal; within TOL
    # (measured at most 1.8e-5 rad of attitude, 4.9e-4 m, 1.2e-4 m/s, 1.7e-4 relative on the attitude P,
    # 1.9e-5 on the CS P, 5.1e-4 on gps_T) but the acceleration of CAR_POS_BURST_RESTART_HELD's coast through
    # its velocity hold, 3.5e-4 m/s^2 (TOL_COAST; 2.9e-5 on CAR_BURST_BOTH_BACK's, 5.6e-6 on the others).
    "rows_car_pos_burst_rx": Case(
        "car_accel_brake",
        "ground",
        50.0,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_POS_BURST,
        tol=TOL_COAST,
    ),
    "rows_car_pos_fault_28s_rx": Case(
        "car_accel_brake",
        "ground",
        55.0,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_POS_FAULT_28S,
        tol=TOL_COAST,
    ),
    "rows_car_burst_both_back_rx": Case(
        "car_accel_brake",
        "ground",
        47.0,
        seed=4,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_BURST_BOTH_BACK,
        tol=TOL_COAST,
    ),
    "rows_car_pos_burst_restart_rx": Case(
        "car_accel_brake",
        "ground",
        50.0,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_POS_BURST_RESTART,
        tol=TOL_COAST,
    ),
    "rows_car_pos_vel_drift_rx": Case(
        "car_accel_brake",
        "ground",
        47.0,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_POS_VEL_DRIFT,
        tol=TOL_COAST,
    ),
    "rows_car_pos_restart_held_rx": Case(
        "car_accel_brake",
        "ground",
        62.0,
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_POS_BURST_RESTART_HELD,
        tol=TOL_COAST,
    ),
    # The position hold's d on a held fix and the fix after it (CAR_SPIKE_HELD_2HZ, CAR_SPIKE_BEFORE_2HZ);
    # within TOL (measured 1.0e-5 rad of attitude, 9.4e-5 m, 6.1e-6 m/s^2, 1.8e-4 relative on gps_T).
    "rows_car_spike_held_2hz_rx": Case(
        "car_accel_brake",
        "ground",
        45.0,
        {"gps_rate_hz": 2.0},
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_SPIKE_HELD_2HZ,
    ),
    "rows_car_spike_before_2hz_rx": Case(
        "car_accel_brake",
        "ground",
        45.0,
        {"gps_rate_hz": 2.0},
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_SPIKE_BEFORE_2HZ,
    ),
    "rows_car_guard_both_2hz_rx": Case(
        "car_accel_brake",
        "ground",
        52.0,
        {"gps_rate_hz": 2.0},
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_GUARD_BOTH_2HZ,
        tol=TOL_GUARD_BOTH,
    ),
    "rows_car_imu_jitter_rx": Case(
        "car_accel_brake",
        "ground",
        55.0,
        {"gps_latency_us": 0, "imu_time_jitter_us": 600},
        profile="fuzzy-rows",
        receiver_model=True,
        gnss_faults=CAR_JITTER_FAULTS,
        tol=TOL_COAST,
    ),
    "igg3_multirotor_pos_fault_e_rx": Case(
        "multirotor_aggressive",
        "multirotor",
        60.0,
        seed=2,  # seed 1 parts the same way (32.8 s), but IGG-III's steep weights reach 1.6e-2 on gps_T
        profile="igg3",
        receiver_model=True,
        gnss_faults=MULTIROTOR_POS_FAULT_E_VEL_N,
        tol=TOL_IGG,
    ),
}


def _with_tilt_blips(rec: Recording, starts: tuple[float, ...]) -> Recording:
    """A copy whose specific force is turned by 0.5 rad about body x for 0.8 s from each start: a
    gravity observation 0.5 rad off in roll with |f| unchanged (no extra R from |g_b| - g), which
    the attitude filter's robust mode rejects."""
    imu = rec.imu.copy()
    t = imu["t_us"].astype(np.int64) * 1e-6
    c, s = math.cos(0.5), math.sin(0.5)
    rot = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    for t0 in starts:
        sel = (t >= t0) & (t < t0 + 0.8)
        imu["accel_mps2"][sel] = imu["accel_mps2"][sel] @ rot.T
    return Recording(rec.name + "+tilt_blips", imu, rec.gnss, rec.mag, rec.ref, rec.meta)


def _with_fix_edits(
    rec: Recording, s_acc_mps: float | None, offsets: tuple[tuple[float, int, float, float], ...]
) -> Recording:
    """A copy with every fix's s_acc set to ``s_acc_mps`` (None: kept) and the velocity offsets of
    ``Case.vel_offsets`` added (N, E; speed and course recomputed)."""
    gn = rec.gnss.copy()
    if s_acc_mps is not None:
        gn["s_acc_mps"] = s_acc_mps
    t = gn["t_us"].astype(np.int64)
    for t_s, k, dn, de in offsets:
        j = int(np.searchsorted(t, round(t_s * 1e6))) + k
        gn["vel_ned_mps"][j, 0] += dn
        gn["vel_ned_mps"][j, 1] += de
    v = gn["vel_ned_mps"]
    gn["speed_mps"] = np.hypot(v[:, 0], v[:, 1])
    gn["course_rad"] = np.mod(np.arctan2(v[:, 1], v[:, 0]), 2.0 * np.pi)
    return Recording(rec.name + "+fix_edits", rec.imu, gn, rec.mag, rec.ref, rec.meta)


def _with_nan_velocity(rec: Recording) -> Recording:
    """A copy with one fix whose east velocity is NaN although flagged present (NONFINITE)."""
    gn = rec.gnss.copy()
    gn["vel_ned_mps"][len(gn) // 4 + 6, 1] = math.nan
    return Recording(rec.name + "+nan_velocity", rec.imu, gn, rec.mag, rec.ref, rec.meta)


def _with_faults(rec: Recording) -> Recording:
    """A copy of a recording with bad and edge-case samples injected at fixed places."""
    imu, gn, mag = rec.imu.copy(), rec.gnss.copy(), rec.mag.copy()
    n = len(imu)
    imu["gyro_rps"][n // 3, 0] = math.nan  # NONFINITE, nothing changes
    imu["accel_mps2"][n // 3 + 50, 1] = math.inf  # NONFINITE
    imu["accel_mps2"][n // 2, 2] = -200.0  # saturated (>= 156.9): sticky flag, its entry skipped
    imu["t_us"][n // 2 + 400] = imu["t_us"][n // 2 + 399]  # repeated time: TIME_BACKWARDS
    gap = slice(2 * n // 3, 2 * n // 3 + 60)  # 150 ms without IMU: BAD_DT and re-anchor
    imu = np.delete(imu, np.arange(n)[gap])
    k = len(gn)
    gn["fix_type"][k // 4] = 1  # BAD_ARG
    gn["lat_e7"][k // 4 + 3] = 900_000_001  # RANGE
    gn["t_us"][k // 4 + 9] = gn["t_us"][k // 4 + 8]  # same validity time: TIME_BACKWARDS
    gn["h_acc_m"][k // 3 : k // 3 + 10] = math.nan  # defaults used
    gn["s_acc_mps"][k // 3 + 5 : k // 3 + 15] = -1.0  # <= 0: default (COG sigma too)
    gn["v_acc_m"][k // 3 + 10 : k // 3 + 20] = 0.0
    gn["flags"][k // 2 : k // 2 + 5] &= ~np.uint8(GNSS_HAS_ALT)  # home altitude used, D axis skipped
    gn["flags"][k // 2 + 10 : k // 2 + 15] &= ~np.uint8(GNSS_HAS_VEL_D)
    gn["flags"][k // 2 + 20 : k // 2 + 25] &= ~np.uint8(GNSS_HAS_VEL_NE | GNSS_HAS_VEL_D)  # no COG
    gn["fix_type"][k // 2 + 30 : k // 2 + 35] = 2  # 2D: no D position row
    if len(mag):
        m = len(mag)
        mag["mag_b"][m // 3] = 0.0  # zero vector: skipped, OK
        mag["mag_b"][m // 3 + 7 : m // 3 + 9] = 0.0
        mag["mag_b"][m // 2, 2] = math.nan  # NONFINITE
    return Recording(rec.name + "+faults", imu, gn, mag, rec.ref, rec.meta)


# --------------------------------------------------------------------------------------
# Configurations: the same preset on both sides, asserted equal
# --------------------------------------------------------------------------------------

# Golden CsAxisConfig field -> C mca_cs_config_t field where the names differ.
_CS_NAMES = {"v0_var_m2s2": "v0_var_m2ps2", "a0_var_m2s4": "a0_var_m2ps4"}
# C robust mode numbers of the golden mode names (mca_robust_config_t.mode).
_MODE_NUMBERS = {name: int(core.ROBUST_MODES[name]) for name in grobust.MODES}
# Float32 config values vs float64 ones: a constant such as radians(2)^2 computed in float32
# may differ from the float64 value rounded to float32 by an ulp or two (eps 6e-8).
_CFG_RTOL = 3e-7


def _config_mismatches(golden: Any, c: dict[str, Any], path: str, names: dict[str, str]) -> list[str]:
    """Field-by-field differences between a golden config dataclass and a C config dict."""
    bad: list[str] = []
    g_names = {names.get(f.name, f.name): f.name for f in fields(golden)}
    c_names = set(c)
    for extra in sorted(c_names - set(g_names)):
        bad.append(f"{path}.{extra}: in the C config only")
    for extra in sorted(set(g_names) - c_names):
        bad.append(f"{path}.{extra}: in the golden config only")
    for c_name in sorted(c_names & set(g_names)):
        gv, cv = getattr(golden, g_names[c_name]), c[c_name]
        if isinstance(gv, (gcs.CsAxisConfig, gatt.AttConfig, grobust.RobustConfig)):
            bad += _config_mismatches(gv, cv, f"{path}.{c_name}", _CS_NAMES)
        elif isinstance(gv, str):  # the robust mode: a name in the golden model, a number in C
            if _MODE_NUMBERS.get(gv) != int(cv):
                bad.append(f"{path}.{c_name}: golden {gv!r} != C {cv!r}")
        elif not math.isclose(float(gv), float(cv), rel_tol=_CFG_RTOL, abs_tol=0.0):
            bad.append(f"{path}.{c_name}: golden {gv!r} != C {cv!r}")
    return bad


@pytest.mark.parametrize("preset", ["ground", "fixedwing", "multirotor"])
def test_golden_and_c_presets_are_equal_field_by_field(preset: str) -> None:
    bad = _config_mismatches(
        gnav.NavConfig.preset(preset), core.config_dict(core.nav_config(preset)), preset, {}
    )
    assert not bad, "\n".join(bad)


def _golden_override(cfg: Any, name: str, value: Any) -> Any:
    """``cfg`` with one (dotted) field replaced, as ``core.nav_config`` takes it: nested configs
    by ``cs_h.robust.mode`` and the robust mode by its C number."""
    head, _, rest = name.partition(".")
    if rest:
        return replace(cfg, **{head: _golden_override(getattr(cfg, head), rest, value)})
    if isinstance(cfg, grobust.RobustConfig) and head == "mode":
        value = grobust.MODES[[_MODE_NUMBERS[m] for m in grobust.MODES].index(int(value))]
    elif isinstance(cfg, gcs.CsAxisConfig) and head in ("coast", "adaptive"):
        value = bool(value)
    return replace(cfg, **{head: value})


def _case_overrides(case: Case, rec: Recording | None = None) -> dict[str, Any]:
    """The dotted overrides of a case: its robust profile (at the recording's fix rate), the
    simulator's receiver model when asked, then its own."""
    over: dict[str, Any] = {}
    if case.profile is not None:
        rate = core.fix_rate_hz(rec) if rec is not None else 5.0
        over |= {
            k: v
            for k, v in core.robust_profile(case.profile, rate).items()
            if not (case.cs_only and k.startswith("att."))
        }
    if case.receiver_model:
        sp = sim.SimParams()
        over |= core.receiver_model(
            sp.gps_pos_white_h_m,
            sp.gps_pos_white_v_m,
            sp.gps_pos_sigma_h_m,
            sp.gps_pos_sigma_v_m,
            sp.gps_pos_tau_s,
        )
    return over | case.overrides


def _configs(case: Case, rec: Recording | None = None) -> tuple[Any, gnav.NavConfig]:
    over = _case_overrides(case, rec)
    c_cfg = core.nav_config(case.preset, **over)
    g_cfg = gnav.NavConfig.preset(case.preset)
    for name, value in over.items():
        g_cfg = _golden_override(g_cfg, name, value)
    bad = _config_mismatches(g_cfg, core.config_dict(c_cfg), case.preset, {})
    assert not bad, "\n".join(bad)
    return c_cfg, g_cfg


# --------------------------------------------------------------------------------------
# Runs and gaps
# --------------------------------------------------------------------------------------

_RUNS: dict[str, tuple[dict[str, np.ndarray], dict[str, np.ndarray]]] = {}


def _runs(name: str) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """(C output, golden output) of a case, computed once per session."""
    if name not in _RUNS:
        case = CASES[name]
        rec = sim.scenario(case.scenario, seed=case.seed, duration_s=case.duration_s, **case.sim_kw).recording
        if case.faults:
            rec = _with_faults(rec)
        if case.nan_velocity:
            rec = _with_nan_velocity(rec)
        if case.gnss_faults:
            rec = sim.with_gnss_faults(rec, case.gnss_faults)
        if case.tilt_blips:
            rec = _with_tilt_blips(rec, case.tilt_blips)
        if case.s_acc_mps is not None or case.vel_offsets:
            rec = _with_fix_edits(rec, case.s_acc_mps, case.vel_offsets)
        c_cfg, g_cfg = _configs(case, rec)
        _RUNS[name] = (core.replay(rec, c_cfg), gnav.run(rec, g_cfg))
    return _RUNS[name]


def _attitude_gap_rad(q_c: np.ndarray, q_g: np.ndarray) -> np.ndarray:
    """Rotation angle of q_c^-1 (x) q_g per row (q_c renormalised in float64)."""
    qc = q_c.astype(np.float64)
    qc /= np.linalg.norm(qc, axis=1, keepdims=True)
    w1, v1 = qc[:, 0], -qc[:, 1:]  # conjugate of q_c
    w2, v2 = q_g[:, 0], q_g[:, 1:]
    w = w1 * w2 - np.sum(v1 * v2, axis=1)
    v = w1[:, None] * v2 + w2[:, None] * v1 + np.cross(v1, v2)
    return 2.0 * np.arctan2(np.linalg.norm(v, axis=1), np.abs(w))


def _rel(c: np.ndarray, g: np.ndarray, floor: float) -> float:
    """max |c - g| / max(|g|, floor) over the entries finite on both sides."""
    c = c.astype(np.float64)
    ok = np.isfinite(c) & np.isfinite(g)
    if not np.any(ok):
        return 0.0
    return float(np.max(np.abs(c[ok] - g[ok]) / np.maximum(np.abs(g[ok]), floor)))


# Per-IMU-row outputs of core.replay (the statuses of fixes and magnetometer samples are not rows).
_ROW_KEYS_C = set(core.OUT_C_DTYPE.names) | {"imu_status"}


def _gaps(c: dict[str, np.ndarray], g: dict[str, np.ndarray]) -> dict[str, float]:
    """Every measured gap between the C and golden outputs (one row per IMU sample)."""
    f64 = {k: v.astype(np.float64) for k, v in c.items() if v.dtype.kind == "f"}
    d_euler = f64["euler_rad"] - g["euler"]
    d_euler[:, 2] = np.angle(np.exp(1j * d_euler[:, 2]))  # yaw wraps at +-pi
    return {
        "attitude_rad": float(np.max(_attitude_gap_rad(c["q_nb"], g["q"]))),
        "euler_rad": float(np.max(np.abs(d_euler))),
        "gyro_bias_rps": float(np.max(np.abs(f64["gyro_bias_rps"] - g["gyro_bias"]))),
        "pos_m": float(np.max(np.abs(f64["pos_ned_m"] - g["pos_ned"]))),
        "vel_mps": float(np.max(np.abs(f64["vel_ned_mps"] - g["vel_ned"]))),
        "acc_mps2": float(np.max(np.abs(f64["acc_ned_mps2"] - g["acc_ned"]))),
        "att_var_rel": _rel(c["att_var"], g["att_P_diag"], 1e-12),
        "cs_var_rel": _rel(c["cs_var"], g["cs_P_diag"], 1e-12),
        "rp_T_rel": _rel(c["rp_t"], g["rp_T"], 1.0),
        "gps_T_rel": _rel(c["gps_t"], g["gps_T"], 1.0),
    }


def _events(diff: np.ndarray) -> np.ndarray:
    """Rows where a per-row difference (counter offset, flag XOR) takes a new nonzero value."""
    prev = np.concatenate([[0], diff[:-1]])
    return np.flatnonzero((diff != 0) & (diff != prev))


def _discrete(c: dict[str, np.ndarray], g: dict[str, np.ndarray]) -> tuple[dict[str, int], int]:
    """Discrete differences, counted as events (a flip that persists is one event), and the
    first row at which any observation decision differs (len(rows) when none does)."""
    n = len(g["t_us"])
    made = _events(c["n_grav_obs"].astype(np.int64) - g["n_grav_made"])
    skipped = _events(c["n_grav_skip"].astype(np.int64) - g["n_grav_skipped"])
    flags = _events(c["flags"].astype(np.int64) ^ g["flags"].astype(np.int64))
    first = min([n] + [int(e[0]) for e in (made, skipped, flags) if len(e)])
    counts = {
        "t_us": int(np.count_nonzero(c["t_us"].astype(np.int64) != g["t_us"])),
        "grav_made_events": len(made),
        "grav_skipped_events": len(skipped),
        "flag_events": len(flags),
        "nan_pattern_T": int(
            np.count_nonzero(np.isnan(c["rp_t"]) != np.isnan(g["rp_T"]))
            + np.count_nonzero(np.isnan(c["gps_t"]) != np.isnan(g["gps_T"]))
        ),
        "imu_status": int(np.count_nonzero(c["imu_status"].astype(np.int64) != g["imu_status"])),
        "gps_status": int(np.count_nonzero(c["gps_status"].astype(np.int64) != g["gps_status"])),
        "mag_status": int(np.count_nonzero(c["mag_status"].astype(np.int64) != g["mag_status"])),
    }
    return counts, first


# Largest gap allowed on any row of any case, with the reason. "measured": the largest over the
# passing cases above (seed 1). A spec change that either side misses shows up orders of
# magnitude above these (checked by hand: dropping the level-only roll/pitch correction gives
# 0.08 rad of attitude, dropping the lost-GPS centripetal term 0.06 rad, a 1.5x yaw-alignment
# variance 0.33 relative on the attitude P).
TOL: dict[str, float] = {
    # float32 quaternion in a stable filter: ~1e-7 per step, corrected by every observation;
    # measured 3.2e-5 rad (7.7e-5 before the structured attitude covariance predict).
    "attitude_rad": 3e-4,
    "euler_rad": 3e-4,  # the same error seen as roll, pitch, yaw (measured 2.8e-5)
    # bias = sum of float32 corrections of the gain; measured 2.2e-6 rad/s.
    "gyro_bias_rps": 1e-5,
    # float32 NED position: ulp 6e-5 m at 1 km, plus the CS state carried in float32 and the
    # constant-acceleration extrapolation to IMU time; measured 2.0e-3 m (2 km from home).
    "pos_m": 5e-3,
    "vel_mps": 3e-4,  # measured 1.3e-4 m/s (extrapolated after a 30 s outage re-initialisation)
    "acc_mps2": 5e-5,  # measured 1.0e-5 m/s^2
    # Attitude P diagonal, relative: the per-step process noise of an unobserved state (z gyro
    # bias at rest: +3e-7 relative per step at 400 Hz) is rounded to a few float32 ulps each
    # step, a systematic drift over 24 000 steps; measured 9.8e-4 (static), <= 3.1e-4 elsewhere.
    "att_var_rel": 3e-3,
    # CS P in float32. The C evaluates Joseph expanded, P - K U' - U K' + K S K' (O(n^2 m)); when a
    # fix after an outage shrinks P by ~1e3 that sum cancels to eps * P / P+ ~ 1e-4 (measured 5.8e-5)
    "cs_var_rel": 2e-4,
    # NIS = nu^T C^-1 nu with nu a small difference of float32 angles (relative to max(T, 1));
    # measured 7.5e-4 (fixedwing_turns).
    "rp_T_rel": 5e-3,
    # GPS NIS, since the IMU-aided test (ALGORITHMS.md 8, GPS step 3) the aided one: its velocity
    # variance (~0.012 m^2/s^2) is ~5x below the CS's own, so float32 velocity rounding (3e-5 m/s
    # at 30 m/s) moves T by ~2 nu dnu / C = 5e-4; measured 5.8e-4 (6.4e-5 on the CS's own T)
    "gps_T_rel": 1.5e-3,
}

# Discrete differences allowed per case, as events.
MAX_DISCRETE: dict[str, int] = {
    "t_us": 0,  # integer time, copied: must be identical
    # Observation decisions that read a float: the gravity gate (|g_b| in [0.5 g, 1.5 g]), the
    # tilt limit, the course-over-ground speed threshold, the alignment stillness test. One can
    # flip when its value lands within a float32 rounding (~1e-7 relative) of the threshold:
    # allow one such event per case (measured: 0 in every case). The history-entry choice, the
    # timers and the mode-2 usability test are integer-microsecond decisions and cannot flip.
    "grav_made_events": 1,
    "grav_skipped_events": 1,
    "flag_events": 1,
    "nan_pattern_T": 0,  # NaN until first set (ALGORITHMS.md 8, output): same rows on both sides
    "imu_status": 0,  # statuses are decided on integer times and finiteness: never a rounding
    "gps_status": 0,
    "mag_status": 0,
}


# Comparisons where the C path disagrees with the spec (reported to the lead; the golden follows
# ALGORITHMS.md). The C side was not read: each diagnosis is from the outputs and the public API.
#
# akf_car once was one: the C scaled only the angle block of the attitude filter's Qd by the AKF
# q_scale, the spec (then) said its process noise, and the golden model scaled the whole Qd (4.7e-3
# relative off in att_var by 12 s, a robust decision flipped at the braking). The spec now says the
# angle block (ALGORITHMS.md 7, with why), and the golden model follows it.
XFAIL: dict[str, str] = {}


def _case_params() -> list:
    # Two cases once found C-side deviations (course observation skipped after a skipped
    # differencing observation; a flagged NaN velocity passed to the C as 0 by core.gnss_to_c);
    # both are fixed and the cases are plain comparisons now.
    return [
        pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=XFAIL[n])) if n in XFAIL else n
        for n in CASES
    ]


@pytest.mark.parametrize("name", _case_params())
def test_c_matches_golden_step_by_step(name: str) -> None:
    c, g = _runs(name)
    disc, first = _discrete(c, g)
    # After a flipped observation decision the two filters legitimately part (by the size of one
    # observation): the continuous comparison covers the rows before it (all rows when none).
    rows = slice(0, first)
    gaps = _gaps({k: v[rows] for k, v in c.items() if k in _ROW_KEYS_C}, {k: v[rows] for k, v in g.items()})
    print(f"\n{name}: " + ", ".join(f"{k} {v:.3g}" for k, v in gaps.items()))
    print(
        f"{name}: first differing decision at row {first} of {len(g['t_us'])}; "
        + ", ".join(f"{k} {v}" for k, v in disc.items())
    )
    over_d = {k: v for k, v in disc.items() if v > MAX_DISCRETE[k]}
    assert not over_d, f"{name}: discrete differences {over_d} (allowed {MAX_DISCRETE})"
    tol = TOL | CASES[name].tol
    over = {k: v for k, v in gaps.items() if not v <= tol[k]}
    assert not over, f"{name}: continuous gaps over tolerance {over} (tolerances {tol})"


def test_guard_burst_of_both_ends_with_a_cs_restart_on_both_sides() -> None:
    """rows_car_guard_both_rx reaches the rule it is for (ALGORITHMS.md 8, GPS step 3, the end of a
    fault the CS took in): its burst lasts exactly fuzzy rows' whole-update guard of fixes, both sides
    alarm on N and E through it, and neither after its first clean fix, from which the CS restarts (a
    restart at the fix: the N position variance ``p0_var_m2`` after it; without the restarts it alarmed
    to 43.2 s). The alarm set by the burst's last fix lasts until that clean fix is received."""
    case = CASES["rows_car_guard_both_rx"]
    rec = sim.scenario(case.scenario, seed=case.seed, duration_s=case.duration_s, **case.sim_kw).recording
    t0, t1 = case.gnss_faults[0][:2]
    t_fix = rec.gnss["t_us"].astype(np.int64) * 1e-6
    guard = core.robust_profile("fuzzy-rows", core.fix_rate_hz(rec))["cs_h.robust.reject_reset_n"]
    assert np.count_nonzero((t_fix >= t0) & (t_fix < t1)) == guard
    c, g = _runs("rows_car_guard_both_rx")
    alarm = core.FLAG_BITS["alarm_n"] | core.FLAG_BITS["alarm_e"]
    t_last = t_fix[t_fix < t1][-1]
    first_clean = int(np.flatnonzero(t_fix >= t1)[0])
    t_clean_rx = rec.gnss["t_rx_us"][first_clean] * 1e-6  # its GPS step (after the IMU sample of that time)
    for flags in (c["flags"], g["flags"]):
        on = (flags.astype(np.int64) & alarm) == alarm
        t = g["t_us"] * 1e-6
        assert np.all(on[(t > t0 + 0.5) & (t < t_last)])
        assert not np.any(on[t > t_clean_rx])  # at equal times the IMU sample comes first
    restarts = _restarts("rows_car_guard_both_rx")[1]
    assert restarts[0] == restarts[1] == [0, first_clean]


# The fixes (times in [t0, t1), s, one or more spans) after which N or E alarms in the cases of the test
# below, and no others.
ALARMED_FIXES: dict[str, tuple[tuple[float, float], ...]] = {
    "rows_multirotor_drift_burst_rx": ((20.0, 38.0),),  # the burst's fixes
    "rows_car_half_onset_burst_rx": ((15.0, 30.0),),  # the burst's fixes
    # released 14 s before the burst's end; the alarm with it since session 28 (the position applied beside
    # the held velocity keeps the CS on the fixes: before, the CS coasted and the release fix's position
    # failed, so the alarm lasted one fix more, 23.6 s)
    "rows_fixedwing_first_held_rx": ((20.0, 23.6),),
    # a missed burst's end held, released by the positions at 29.0 s (the position fault's alarm to 30.5 s),
    # and a second burst held from its first fix (not taken for an armed return)
    "rows_car_missed_burst_2hz_rx": ((25.0, 31.0), (32.0, 34.5)),
    # the position hold (GPS step 4, session 28)
    "rows_car_pos_burst_rx": ((20.0, 35.0),),  # the burst's fixes, held to its end (no hold: 20.0-28.8 s)
    "rows_car_pos_fault_28s_rx": ((15.0, 43.0),),  # the fault's fixes, past the guard (guard alone: 34.8 s)
    "rows_car_burst_both_back_rx": ((20.0, 35.0),),  # the burst's fixes (without the step back: to 46.0 s)
    "rows_car_pos_burst_restart_rx": ((20.0, 35.4),),  # released at 35.4 s, restarted at 37.0 s
    "rows_car_pos_vel_drift_rx": ((20.0, 35.4),),  # E's position out at 35.0 and 35.2 s, no restart
    "rows_car_pos_restart_held_rx": ((20.0, 37.0), (37.2, 50.0)),  # the restart at 37.0 s; released at 50.0 s
    # a velocity spike held one fix, no position hold after it (the trapezoid as d: held to 28.5 s)
    "rows_car_spike_held_2hz_rx": ((22.0, 22.5),),
    "rows_car_spike_before_2hz_rx": ((21.5, 23.0),),  # and E's per-row test at 22.0-22.5 s
    # the burst's fixes but its last, which the whole-update guard takes in (restarted at 40.0 s)
    "rows_car_guard_both_2hz_rx": ((20.0, 39.5),),
    # the bursts' fixes, with two fixes of the second that had no increments until session 33
    "rows_car_imu_jitter_rx": ((20.0, 26.0), (32.0, 42.0)),
}


@pytest.mark.parametrize("name", list(ALARMED_FIXES))
def test_burst_held_by_the_positions_alarms_on_the_same_fixes_on_both_sides(name: str) -> None:
    """The MULTIROTOR_DRIFT_BURST, CAR_HALF_ONSET_BURST and FIXEDWING_FIRST_HELD_BURST cases reach the rules
    they are for (ALGORITHMS.md 8, GPS step 3, fuzzy rows: the held fixes' positions, the return's size window
    not asked while they say the held step, and their sum from the hold's second fix): on both sides N or E
    alarms after every fix of ``ALARMED_FIXES`` and neither after any other fix of the recording. The
    multirotor's hold lasts the burst although the anchor drifted past it, and releases at its first clean
    fix, 1.56 times the held step back (without the positions' rule it released 11 s before the burst's end,
    and its end was held 20 s); the car's releases at its first clean fix, 1.54 times the held step back
    (with the size window asked there, 5 s later); the fixed-wing's releases 3.6 s into the burst (with the
    hold's first fix's term summed, or the sums made before the test, at its end).
    So do the cases of GPS step 4's position hold (session 28): CAR_POS_BURST held to its end,
    CAR_POS_FAULT_28S past the whole-update guard by the significance, CAR_BURST_BOTH_BACK's end found by
    its step back (the anchor carried off on the CS's coast), CAR_POS_BURST_RESTART released before its end
    by the anchor's wander, CAR_POS_VEL_DRIFT's end a step back while holding, and
    CAR_POS_BURST_RESTART_HELD's velocity hold released before the burst's end once the restart made
    ``p_last`` NaN (their golden models without the rule alarm on other fixes: see each fault plan's
    comment). CAR_MISSED_BURST_2HZ's end of a missed burst, held, is released by the positions (session 32;
    without that release the clean fixes are held to the next burst, 32.0 s), and that burst held from its
    first fix (the release not armed). CAR_SPIKE_HELD_2HZ's and CAR_SPIKE_BEFORE_2HZ's spike, held one fix,
    starts no position hold (the predicted change as its ``d`` on that fix and the next; with the trapezoid
    the clean fixes are held to 28.5 s). Their restarts:
    test_position_hold_restarts_the_cs_at_the_same_fixes_on_both_sides."""
    case = CASES[name]
    rec = sim.scenario(case.scenario, seed=case.seed, duration_s=case.duration_s, **case.sim_kw).recording
    t_fix = rec.gnss["t_us"].astype(np.int64) * 1e-6
    c, g = _runs(name)
    row = np.searchsorted(g["t_us"], rec.gnss["t_rx_us"].astype(np.int64), side="right")  # after each fix
    ok = row < len(g["t_us"])
    spans = [(t_fix >= t0 - 1e-3) & (t_fix < t1 - 1e-3) for t0, t1 in ALARMED_FIXES[name]]
    alarmed = np.any(spans, axis=0)[ok]
    alarm = core.FLAG_BITS["alarm_n"] | core.FLAG_BITS["alarm_e"]
    for flags in (c["flags"], g["flags"]):
        at_fix = flags[row[ok]].astype(np.int64) & alarm
        assert np.all(at_fix[alarmed] != 0)
        assert not np.any(at_fix[~alarmed])


# The CS restarts of the position hold's cases (fix times, s, home excluded): the hold's restart at a fault's
# end that steps back while not holding (CAR_POS_BURST_RESTART; CAR_POS_BURST_RESTART_HELD's on a fix the step
# test holds, and then at 54.0 s GPS step 3's end of the velocity burst, which the CS took in after the
# velocity hold's release at 50.0 s), and none at a fault's end that steps back while holding
# (CAR_POS_VEL_DRIFT) or ends a hold that kept the fault out (CAR_BURST_BOTH_BACK's CS, coasted 7.5 m off,
# takes its first clean fix in whole); and none at GPS step 3's release by the positions, flagged inside a
# position hold (CAR_MISSED_BURST_2HZ: no fault's end).
HOLD_RESTARTS: dict[str, tuple[float, ...]] = {
    "rows_car_pos_burst_rx": (),
    "rows_car_pos_fault_28s_rx": (),
    "rows_car_burst_both_back_rx": (),
    "rows_car_pos_burst_restart_rx": (37.0,),
    "rows_car_pos_vel_drift_rx": (),
    "rows_car_pos_restart_held_rx": (37.0, 54.0),
    "rows_car_missed_burst_2hz_rx": (),  # the release by the positions (29.0 s, flagged) restarts nothing
    "rows_car_guard_both_2hz_rx": (40.0,),  # the step back after the guard's fix
}


@pytest.mark.parametrize("name", list(HOLD_RESTARTS))
def test_position_hold_restarts_the_cs_at_the_same_fixes_on_both_sides(name: str) -> None:
    """ALGORITHMS.md 8, GPS step 4, the position hold's restart: a fix that steps back while not holding,
    whose N or E update left its position row out, restarts the CS (as the end of a position fault the CS
    took in, at the fix: the N position variance ``p0_var_m2`` after it). In the cases of
    ``HOLD_RESTARTS`` the CS restarts at home and at those fixes only, on both sides (without the hold's
    restart, the golden model of CAR_POS_BURST_RESTART and CAR_POS_BURST_RESTART_HELD restarts at home
    only and parts from the C there)."""
    rec, restarts, _ = _restarts(name)
    t_fix_us = rec.gnss["t_us"].astype(np.int64)
    expected = [0] + [int(np.flatnonzero(t_fix_us == round(t * 1e6))[0]) for t in HOLD_RESTARTS[name]]
    assert restarts[1] == expected
    assert restarts[0] == restarts[1]


# Restarts other than home and the fault's end (fix times, s) and the least move of the CS horizontal
# position at the end's restart (m) of the cases of the test below.
RESTARTS_INSIDE: dict[str, tuple[float, ...]] = {"igg3_car_rtk_burst_both": (26.6,)}
RESTART_MOVE_M: dict[str, float] = {"akf_car_pos_fault_end_held_rx": 3.0}


def _restarts(name: str, from_ref: bool = False) -> tuple[Recording, list[list[int]], np.ndarray]:
    """The case's recording, the fixes (indices) after which the CS N position variance is
    ``p0_var_m2`` (section 2: a CS (re-)initialisation at the fix; no update lands on it) or
    ``sigma_p_m^2`` of ``cs_h`` (ALGORITHMS.md 8, GPS step 4, the position reference: a restart at the
    end of a fault that starts N and E at ``p_ref`` takes that variance in place of ``p0_var_m2``; no
    update lands on it either) in the C and the golden output, and each fix's output row after it.
    With ``from_ref`` only the restarts from the reference (``sigma_p_m^2``)."""
    case = CASES[name]
    rec = sim.scenario(case.scenario, seed=case.seed, duration_s=case.duration_s, **case.sim_kw).recording
    c, g = _runs(name)
    cs_h = _configs(case, rec)[1].cs_h
    starts = (cs_h.sigma_p_m**2,) if from_ref else (cs_h.p0_var_m2, cs_h.sigma_p_m**2)
    row = np.searchsorted(g["t_us"], rec.gnss["t_rx_us"].astype(np.int64), side="right")  # after each fix
    ok = row < len(g["t_us"])
    restarts = []
    for p in (c["cs_var"], g["cs_P_diag"]):
        # the variance is set, not computed: equal in float32 on both sides (within 1e-6 relative, a P
        # decaying through sigma_p^2 counted as a restart: igg3_car's N at 12.2 s with a fixed 30 ms
        # history spacing, tried in session 29, 2.2499981 in the golden model)
        p_nn = p[row[ok], 0].astype(np.float32)
        hit = np.any([p_nn == np.float32(v) for v in starts], axis=0)
        restarts.append(np.flatnonzero(ok)[hit].tolist())
    return rec, restarts, row


def test_cs_drifted_from_clean_fixes_with_no_position_fault_pending_returns_on_both_sides() -> None:
    """ALGORITHMS.md 8, GPS step 4, the return's first condition: this fix's ``j`` a jump *or* ``4 J^2 <=
    B`` (no position fault pending). In igg3_car (CAR_FAULTS) the CS restarts at home, at the step test's
    ends of the velocity bursts (19.0, 24.0 s) and of the burst of both (29.0 s), and at 32.4 s, where no
    fix jumped but J is 0 (cleared at 29.0 s) and the CS drifted from the clean fixes (N: nu -11.7 m):
    the same fixes on both sides. Every restart but home starts N and E at the position reference (N and
    E near it; ``_restarts`` counts both kinds). Requiring the jump always there is no restart at 32.4 s."""
    rec, restarts, _ = _restarts("igg3_car")
    t_fix_us = rec.gnss["t_us"].astype(np.int64)
    expected = [int(np.flatnonzero(t_fix_us == round(t * 1e6))[0]) for t in (0.0, 19.0, 24.0, 29.0, 32.4)]
    assert restarts[1] == expected
    assert restarts[0] == restarts[1]


@pytest.mark.parametrize(
    "name",
    [
        "fta_car_pos_fault_rx",
        "igg3_car_pos_fault_rx",
        "fta_fixedwing_pos_fault_2hz_rx",
        "fta_fixedwing_pos_fault_1hz_rx",
        "akf_car_pos_fault_end_held_rx",
        "igg3_car_rtk_burst_both",
        "igg3_multirotor_pos_fault_e_rx",
    ],
)
def test_long_position_fault_ends_with_a_cs_restart_at_the_same_fix_on_both_sides(name: str) -> None:
    """The CAR_POS_FAULT, FIXEDWING_POS_FAULT_2HZ / _1HZ, CAR_POS_FAULT_END_HELD, CAR_RTK_BURST_BOTH and
    MULTIROTOR_POS_FAULT_E_VEL_N cases reach the rule they are for (ALGORITHMS.md 8, GPS step 4, the end of
    a position fault the CS took in): the CS, which took the fault in, restarts at the first clean fix after
    it, on both sides, and at no other fix but home (in the 1 Hz case, not inside the fault: with the onset's
    jump pending only a fix that jumped returns; in the multirotor's, not at N's return while E's fault is
    pending)
    and those of ``RESTARTS_INSIDE`` (in the burst of both, the return on a held fix at 26.6 s: its jump
    against the predicted change). The end of CAR_POS_FAULT_END_HELD is a fix the step test holds after
    the hold's first: its jump against the predicted change is counted, so it returns. The ends' restarts
    of the receiver-model cases start N and E at the position reference (the fix near it; CAR_RTK_BURST_BOTH's
    centimetre bound leaves its fixes far from it, and MULTIROTOR_POS_FAULT_E_VEL_N's reference is carried
    by the faulty N velocities: their restarts at the fix). A CS (re-)initialisation sets
    the N position variance to ``p0_var_m2`` (section 2), or ``sigma_p_m^2`` when it starts from the position
    reference, which no update lands on: the fixes whose step leaves either there are the restarts."""
    case = CASES[name]
    rec, restarts, row = _restarts(name)
    g = _runs(name)[1]
    t1 = case.gnss_faults[0][1]
    t_fix_us = rec.gnss["t_us"].astype(np.int64)
    first_clean = int(np.flatnonzero(t_fix_us >= round(t1 * 1e6))[0])
    inside = [int(np.flatnonzero(t_fix_us == round(t * 1e6))[0]) for t in RESTARTS_INSIDE.get(name, ())]
    assert restarts[1] == sorted([0, first_clean, *inside])  # home, (inside,) then the end of the fault
    assert restarts[0] == restarts[1]
    # the CS had the fault in: the restart moves its horizontal position by most of the 30 m (AKF holds a
    # short fault in eps_p, whose move the output does not show)
    r = row[first_clean]
    assert np.hypot(*(g["pos_ned"][r, :2] - g["pos_ned"][r - 1, :2])) > RESTART_MOVE_M.get(name, 15.0)


# The least horizontal distance of the CS position from the fix's at the restart from the position reference
# of fuzzy_inflate_car_pos_fault_ref_rx (m; measured 4.41 m on both sides; a restart at the fix: 0).
REF_OFFSET_M = 4.0


def test_position_fault_end_restarts_from_the_position_reference_on_both_sides() -> None:
    """ALGORITHMS.md 8, GPS step 4, the position reference: in fuzzy_inflate_car_pos_fault_ref_rx
    (CAR_POS_FAULT_40S) the CS restarts at home and at the fault's first clean fix (60.0 s) only, on both
    sides, and that restart starts N and E at ``p_ref``: the N position variance right after it is
    ``sigma_p_m^2`` of ``cs_h`` (``p0_var_m2`` at the fix), and the CS horizontal position at the fix's
    time is more than ``REF_OFFSET_M`` from the fix's position (a restart at the fix puts it there). The
    output is the CS carried to the IMU time with ``a = 0`` after a restart: at the fix's time it is
    ``pos - vel tau``."""
    name = "fuzzy_inflate_car_pos_fault_ref_rx"
    case = CASES[name]
    rec, restarts, row = _restarts(name)
    from_ref = _restarts(name, from_ref=True)[1]
    c, g = _runs(name)
    t_fix_us = rec.gnss["t_us"].astype(np.int64)
    first_clean = int(np.flatnonzero(t_fix_us >= round(case.gnss_faults[0][1] * 1e6))[0])
    assert restarts[0] == restarts[1] == [0, first_clean]
    assert from_ref[0] == from_ref[1] == [first_clean]
    fix, home = rec.gnss[first_clean], rec.gnss[0]  # both outside the fault
    z = ggeo.ned_from_home(
        int(fix["lat_e7"]),
        int(fix["lon_e7"]),
        int(fix["alt_mm"]),
        int(home["lat_e7"]),
        int(home["lon_e7"]),
        int(home["alt_mm"]),
    )
    r = row[first_clean]
    tau = (int(g["t_us"][r]) - int(t_fix_us[first_clean])) * 1e-6
    for pos, vel in ((c["pos_ned_m"], c["vel_ned_mps"]), (g["pos_ned"], g["vel_ned"])):
        p = pos[r, :2].astype(np.float64) - vel[r, :2].astype(np.float64) * tau
        assert math.hypot(p[0] - z[0], p[1] - z[1]) > REF_OFFSET_M


@pytest.mark.parametrize("axis", [0, 2])
def test_c_matches_golden_through_a_numerically_failed_cs_update(axis: int) -> None:
    """ALGORITHMS.md 8, GPS step 4: one CS axis' position variance corrupted (negative: SINGULAR) on
    both sides at the fix of 30 s (the car braking), repaired after it, then 2.5 s without fixes (GPS
    lost: the lost-GPS observations decay ``a_last`` from the failed fix's time). Both return the
    status; the other axes update, the CS time moves to the fix, no observation is made (golden
    choice 22), and the runs agree step by step within the file's tolerances."""
    case = CASES["car_cs"]
    rec = sim.scenario(case.scenario, seed=case.seed, duration_s=40.0).recording
    t_fix = rec.gnss["t_us"].astype(np.int64)
    gap = (t_fix > 30_000_000) & (t_fix < 32_500_000)
    rec = Recording(rec.name, rec.imu, rec.gnss[~gap], rec.mag, rec.ref, rec.meta)
    c_cfg, g_cfg = _configs(case, rec)
    cn, gv = core.Nav(c_cfg), gnav.Nav(g_cfg)
    fixes = core.gnss_to_c(rec.gnss)
    i_fail = int(np.searchsorted(rec.gnss["t_us"], 30_000_000))
    n = len(rec.imu)
    c_rows = np.zeros(n, core.OUT_C_DTYPE)
    g_keys = ("q", "euler", "gyro_bias", "pos_ned", "vel_ned", "acc_ned", "att_P_diag", "cs_P_diag", "rp_T")
    g: dict[str, Any] = {k: [] for k in (*g_keys, "t_us", "gps_T", "flags", "n_grav_made", "n_grav_skipped")}
    status: list[tuple[int, int]] = []
    kinds, idxs = gnav.replay_order(rec)
    for kind, i in zip(kinds.tolist(), idxs.tolist(), strict=True):
        if kind == 0:
            im = rec.imu[i]
            cn.imu(int(im["t_us"]), im["gyro_rps"], im["accel_mps2"])
            gv.imu(int(im["t_us"]), im["gyro_rps"], im["accel_mps2"])
            for k, v in cn.output().items():
                c_rows[k][i] = v
            o = gv.output()
            for k in g_keys:
                g[k].append(getattr(o, k))
            g["t_us"].append(o.t_us)
            g["gps_T"].append(o.gps_T)
            g["flags"].append(o.flags)
            g["n_grav_made"].append(o.n_grav_made)
            g["n_grav_skipped"].append(o.n_grav_skipped)
        elif kind == 1:
            if i == i_fail:
                p_c, p_g = cn._nav.cs.axis[axis].p[0], float(gv.cs.axes[axis].P[0, 0])
                cn._nav.cs.axis[axis].p[0] = -100.0  # the axis' position variance (packed P's first element)
                gv.cs.axes[axis].P[0, 0] = -100.0
            codes = []
            c_fix = core.ffi.cast("mca_gps_fix_t *", core.ffi.from_buffer(fixes[i : i + 1]["fix"]))
            codes.append(int(core.lib.mca_nav_gps(cn._nav, c_fix)))
            try:
                gv.gps(rec.gnss[i])
                codes.append(0)
            except errors.McaError as exc:
                codes.append(gnav.status_code(exc))
            status.append((codes[0], codes[1]))
            if i == i_fail:
                assert codes == [gnav.STATUS_CODES[errors.SingularError]] * 2
                assert gv.t_lastfix_us == 30_000_000
                cn._nav.cs.axis[axis].p[0], gv.cs.axes[axis].P[0, 0] = p_c, p_g
    assert all(c == gg for c, gg in status)
    c = {k: c_rows[k] for k in c_rows.dtype.names} | {
        "imu_status": np.zeros(n, np.int32),
        "gps_status": np.zeros(len(status), np.int32),
        "mag_status": np.zeros(0, np.int32),
    }
    gg = {k: np.array(v) for k, v in g.items()} | {
        "imu_status": np.zeros(n, np.int32),
        "gps_status": np.zeros(len(status), np.int32),
        "mag_status": np.zeros(0, np.int32),
    }
    disc, first = _discrete(c, gg)
    rows = slice(0, first)
    gaps = _gaps({k: v[rows] for k, v in c.items() if k in _ROW_KEYS_C}, {k: v[rows] for k, v in gg.items()})
    print(f"\nfailed axis {axis}: " + ", ".join(f"{k} {v:.3g}" for k, v in gaps.items()) + f"; {disc}")
    assert not {k: v for k, v in disc.items() if v > MAX_DISCRETE[k]}
    assert not {k: v for k, v in gaps.items() if not v <= TOL[k]}
    # Tighter than TOL on purpose: the lost-GPS observations after the failed fix decay a_last, which
    # the golden model takes from the last fix whose step 5 ran (choice 22); the failed fix's own CS
    # a instead measures 8.8e-5 / 7.6e-5 rad of attitude (axis 0 / 2) and 1.8e-2 / 1.1e-2 on rp_T here
    # (9.7e-6 / 9.9e-6 and 3e-5 as it is).
    assert gaps["attitude_rad"] < 4e-5


def test_firmware_vectors_of_the_fuzzy_rows_rules_are_their_golden_cases() -> None:
    """scripts/gen_vectors.py's nav_rows_* vectors carry the rules of GPS steps 3-4 that the golden cases
    below trace to the M4F (tests/python/test_vectors.py): the same scenario, preset, profile, seed,
    simulator overrides and length as their case (the faults are shared; the vectors run the IMU at
    100 Hz to fit the file size)."""
    for name, (case_name, sim_kw, duration_s, faults) in gv.ROWS_VECTORS.items():
        case = CASES[case_name]
        expected = ("car_accel_brake", "ground", "fuzzy-rows", 1)
        assert (case.scenario, case.preset, case.profile, case.seed) == expected, name
        assert case.receiver_model and not case.overrides, name
        assert (sim_kw, duration_s, faults) == (case.sim_kw, case.duration_s, case.gnss_faults), name

"""Real-data evaluation (python/mcahrs/evaluate.py): ``mcahrs convert`` round trip, ``mcahrs
evaluate`` on short cuts of the shared logs, and the measuring tools on synthetic cases with a
known answer (reference time offset, stop tilt, stop detection, quaternion interpolation).

Tests on real data skip, naming the missing path, when ``../shared/data`` (relative to the
repository root) is absent. No timing assertions.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from mcahrs import core
from mcahrs.evaluate import (
    MethodRun,
    cut_recording,
    detect_stops,
    estimate_ref_lag,
    gyro_only_drift,
    interp_quat,
    main_convert,
    main_evaluate,
    quat_from_rotvec,
    quat_mul,
    quat_roll_pitch,
    stop_tilt,
)
from mcahrs.io import read_file
from mcahrs.io.loaders import load
from mcahrs.io.loaders._common import euler_zyx_to_quat
from mcahrs.samples import GNSS_DTYPE, GNSS_HAS_VEL_NE, IMU_DTYPE, REF_DTYPE, Recording

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / ".." / "shared" / "data"
ULOG61 = DATA / "ulog" / "log_61_2024-2-6-16-27-02.ulg"
COMMA = DATA / "comma2k19"
CAR = DATA / "car"


def _need(path: Path) -> None:
    if not path.exists():
        pytest.skip(f"shared data not present: {path} (expected ../shared/data beside the repository)")


# --------------------------------------------------------------------------------------
# Synthetic: tools with a known answer
# --------------------------------------------------------------------------------------


def _synthetic_imu(
    seconds: float = 40.0, rate_hz: float = 200.0, seed: int = 3
) -> tuple[np.ndarray, np.ndarray]:
    """IMU samples with rich motion (sums of sines on every axis) and the attitude they integrate to.

    Each gyro value is the rate over the interval it ends; the attitude is propagated exactly
    with it, so the truth matches the interval-mean reading of the samples."""
    rng = np.random.default_rng(seed)
    n = int(seconds * rate_hz)
    t_us = np.round(np.arange(n) * 1e6 / rate_hz).astype(np.int64) + 7_000_000
    t = t_us * 1e-6
    w = np.zeros((n, 3))
    for k in range(3):
        for f, a in zip(rng.uniform(0.1, 1.5, 4), rng.uniform(0.05, 0.4, 4), strict=True):
            w[:, k] += a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    q = np.zeros((n, 4))
    q[0] = [1.0, 0.0, 0.0, 0.0]
    dt = np.diff(t)
    dq = quat_from_rotvec(w[1:] * dt[:, None])
    for i in range(1, n):
        q[i] = quat_mul(q[i - 1], dq[i - 1])
    imu = np.zeros(n, IMU_DTYPE)
    imu["t_us"] = t_us
    imu["gyro_rps"] = w
    imu["accel_mps2"] = [0.0, 0.0, -9.8]
    return imu, q


@pytest.mark.parametrize("lag_s", [0.137, -0.083, 0.0])
def test_reference_time_offset_is_recovered(lag_s: float) -> None:
    imu, q = _synthetic_imu()
    t_true = np.arange(imu["t_us"][0] + 500_000, imu["t_us"][-1] - 500_000, 50_000)  # 20 Hz reference
    ref = np.zeros(len(t_true), REF_DTYPE)
    ref["t_us"] = t_true + int(round(lag_s * 1e6))  # stamped late by lag_s
    ref["q_nb"] = interp_quat(imu["t_us"], q, t_true)
    est, info = estimate_ref_lag(imu, ref, interval_mean=True)
    # 1 ms search step refined by a parabola; the synthetic data are exact up to the slerp
    # between 5 ms IMU attitudes, so well under a millisecond is expected.
    assert abs(est - lag_s) < 1e-3, (est, info)


def test_reference_time_offset_point_samples_within_half_interval() -> None:
    """Read as point samples (the comma2k19 phone IMU), an interval-mean stream is off by half
    an IMU interval at most: the model difference the docstring states."""
    imu, q = _synthetic_imu()
    t_ref = np.arange(imu["t_us"][0] + 500_000, imu["t_us"][-1] - 500_000, 50_000)
    ref = np.zeros(len(t_ref), REF_DTYPE)
    ref["t_us"] = t_ref
    ref["q_nb"] = interp_quat(imu["t_us"], q, t_ref)
    est, _ = estimate_ref_lag(imu, ref, interval_mean=False)
    assert abs(est) <= 0.5 * 0.005 + 1e-3


def test_interp_quat_slerps_and_marks_outside_nan() -> None:
    t = np.array([0, 1_000_000], np.int64)
    q = np.array([[1.0, 0, 0, 0], quat_from_rotvec(np.array([[0.4, 0, 0]]))[0]])
    out = interp_quat(t, q, np.array([-1, 250_000, 1_000_000, 1_000_001]))
    assert np.isnan(out[0]).all() and np.isnan(out[3]).all()
    roll, _ = quat_roll_pitch(out[1:3])
    assert roll[0] == pytest.approx(0.1, abs=1e-12)  # a quarter of the 0.4 rad rotation
    assert roll[1] == pytest.approx(0.4, abs=1e-12)


def _synthetic_stop_case() -> tuple[Recording, list[MethodRun], dict[str, tuple[float, float]]]:
    """A vehicle drives 10 s, stops 6 s on a slope (roll +2 deg, pitch -3 deg), drives 10 s.

    GNSS at 4 Hz; the accelerometer at rest reads the specific force of that tilt plus noise;
    two fake methods report the tilt plus a known error during the first 0.5 s of the stop."""
    rate = 100.0
    n = int(26 * rate)
    t_us = np.arange(n, dtype=np.int64) * 10_000 + 1_000_000
    ts = (t_us - t_us[0]) * 1e-6
    roll0, pitch0 = math.radians(2.0), math.radians(-3.0)
    stopped = (ts >= 10.0) & (ts < 16.0)
    c = euler_zyx_to_quat(np.array([roll0]), np.array([pitch0]), np.array([0.7]))
    from mcahrs.evaluate import down_in_body

    f_rest = -9.80665 * down_in_body(c)[0]
    rng = np.random.default_rng(1)
    imu = np.zeros(n, IMU_DTYPE)
    imu["t_us"] = t_us
    imu["accel_mps2"] = np.where(stopped[:, None], f_rest, [1.0, 0.3, -9.7]) + rng.normal(0, 0.3, (n, 3))
    tf = np.arange(0, 26, 0.25)
    gn = np.zeros(len(tf), GNSS_DTYPE)
    gn["t_us"] = gn["t_rx_us"] = t_us[0] + np.round(tf * 1e6).astype(np.int64)
    speed = np.where((tf >= 10.0) & (tf < 16.0), 0.02, 5.0)
    gn["vel_ned_mps"] = np.stack([speed, np.zeros_like(speed), np.zeros_like(speed)], axis=1)
    gn["flags"] = GNSS_HAS_VEL_NE
    gn["fix_type"] = 3
    rec = Recording("synthetic_stop", imu, gn)
    known = {"A": (0.3, -0.2), "B": (-1.0, 2.5)}
    runs = []
    for name, (er, ep) in known.items():
        roll = np.full(n, roll0 + 0.5)  # wrong outside the first 0.5 s: must not count
        pitch = np.full(n, pitch0 - 0.5)
        early = (ts >= 10.0) & (ts <= 10.5)
        roll[early] = roll0 + math.radians(er)
        pitch[early] = pitch0 + math.radians(ep)
        runs.append(MethodRun(name, roll, pitch))
    return rec, runs, known


def test_gyro_only_drift_is_the_gyros_own_error() -> None:
    """Started from the true attitude with no bias, an ideal simulated gyro integrated alone stays
    on the true roll/pitch through the fixed-wing's turns (integration error only), and a 1 %
    scale-factor error takes it off by about 1 % of the roll the turns put in (30 deg: 0.3 deg)."""
    from mcahrs.sim import scenario

    drift = {}
    for label, kw in (("ideal", {}), ("scale 1 %", {"gyro_scale_ppm": (1e4, 1e4, 1e4)})):
        res = scenario("fixedwing_turns", seed=2, duration_s=60.0, ideal=True, **kw)
        tr = res.truth
        truth = {"q_nb": tr.q_nb, "gyro_bias_rps": np.zeros((len(tr.q_nb), 3))}
        t0 = int(res.recording.imu["t_us"][0])
        drift[label] = gyro_only_drift(res.recording, truth, [t0 + k * 5_000_000 for k in (2, 4, 6, 8)])
    print({k: np.round(v, 3).tolist() for k, v in drift.items()})
    assert drift["ideal"].shape == (4, 3) and np.nanmax(drift["ideal"]) < 0.02
    assert 0.2 < np.nanmax(drift["scale 1 %"]) < 0.4


def test_stop_detection_finds_the_stop() -> None:
    rec, _, _ = _synthetic_stop_case()
    stops = detect_stops(rec.gnss)
    assert len(stops) == 1
    a, b = stops[0]
    assert (a - rec.imu["t_us"][0]) * 1e-6 == pytest.approx(10.0)
    assert (b - rec.imu["t_us"][0]) * 1e-6 == pytest.approx(15.75)


def test_stop_tilt_known_answer() -> None:
    rec, runs, known = _synthetic_stop_case()
    rows = stop_tilt(rec, runs, detect_stops(rec.gnss))
    assert len(rows) == 1
    row = rows[0]
    # accelerometer noise 0.3 m/s^2 averaged over ~575 samples: tilt within 0.1 deg
    assert row["acc_roll_deg"] == pytest.approx(2.0, abs=0.1)
    assert row["acc_pitch_deg"] == pytest.approx(-3.0, abs=0.1)
    for name, (er, ep) in known.items():
        got = row["err"][name]
        assert got[0] == pytest.approx(er, abs=0.1)
        assert got[1] == pytest.approx(ep, abs=0.1)


# --------------------------------------------------------------------------------------
# Real data: convert round trip
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(("path", "preset", "start"), [(ULOG61, "multirotor", 20.0), (COMMA, "ground", 0.0)])
def test_convert_then_read_replays_like_the_loader(
    tmp_path: Path, path: Path, preset: str, start: float
) -> None:
    _need(path)
    out = tmp_path / "stream.nmea"
    assert main_convert([str(path), "--out", str(out), "--start", str(start), "--duration", "25"]) == 0
    rec = cut_recording(load(path), start, 25.0)
    back = read_file(out)
    assert not back.meta["stats"].get("rejected"), back.meta["stats"]
    # IMU and magnetometer: bit-exact (repr of the float64) and the same times.
    for f in ("t_us", "gyro_rps", "accel_mps2"):
        assert np.array_equal(back.imu[f], rec.imu[f]), f
    assert np.array_equal(back.mag["t_us"], rec.mag["t_us"])
    assert np.array_equal(back.mag["mag_b"], rec.mag["mag_b"])
    g, h = rec.gnss, back.gnss
    assert len(h) == len(g)
    for f in ("t_us", "lat_e7", "lon_e7", "alt_mm", "fix_type", "flags"):
        assert np.array_equal(h[f], g[f]), f
    # arrival: the last IMU sample at or before the original arrival (the wire's precision)
    last_imu = rec.imu["t_us"][np.searchsorted(rec.imu["t_us"], g["t_rx_us"], side="right") - 1]
    assert np.array_equal(h["t_rx_us"], last_imu)
    ok = np.isfinite(g["vel_ned_mps"])
    assert np.array_equal(ok, np.isfinite(h["vel_ned_mps"]))
    dv = np.abs(h["vel_ned_mps"][ok] - g["vel_ned_mps"][ok])
    assert np.max(dv, initial=0.0) <= 5e-7 + 1e-12  # PMCAV: 6 decimals
    for f, tol in (("s_acc_mps", 5e-7), ("h_acc_m", 5e-5), ("v_acc_m", 5e-5)):
        fin = np.isfinite(g[f])
        assert np.array_equal(fin, np.isfinite(h[f])), f
        assert np.max(np.abs(h[f][fin] - g[f][fin]), initial=0.0) <= tol + 1e-12, f
    a = core.replay(rec, core.nav_config(preset))
    b = core.replay(back, core.nav_config(preset))
    assert np.array_equal(a["flags"], b["flags"])
    assert np.array_equal(a["n_grav_obs"], b["n_grav_obs"])
    d = np.degrees(np.abs(a["euler_rad"][:, :2].astype(np.float64) - b["euler_rad"][:, :2]))
    # The rounding above changes what the float32 core sees by at most one ulp; the stable filter
    # keeps the difference at float32 noise level (measured <= 3e-5 deg on the full shared logs).
    assert d.max() < 1e-3, d.max()
    assert np.max(np.abs(a["pos_ned_m"] - b["pos_ned_m"])) < 1e-3


def test_convert_leaves_out_fixes_before_the_first_imu_sample(tmp_path: Path) -> None:
    _need(COMMA)
    rec = cut_recording(load(COMMA), 0.0, 5.0)
    early = rec.gnss[:1].copy()
    early["t_us"] = early["t_rx_us"] = rec.imu["t_us"][0] - 300_000
    rec = Recording(rec.name, rec.imu, np.concatenate([early, rec.gnss]), rec.mag, None, rec.meta)
    from mcahrs.evaluate import convert

    info = convert(rec, tmp_path / "s.nmea")
    assert info["fixes_before_first_imu"] == 1
    assert len(read_file(tmp_path / "s.nmea").gnss) == len(rec.gnss) - 1


# --------------------------------------------------------------------------------------
# Real data: evaluate on short cuts
# --------------------------------------------------------------------------------------


def test_evaluate_short_cut_prints_table_and_writes_plots(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    _need(COMMA)
    plots, table = tmp_path / "plots", tmp_path / "rp.csv"
    rc = main_evaluate(
        [str(COMMA), "--start", "0", "--duration", "25", "--plot", str(plots), "--csv", str(table)]
    )
    assert rc == 0
    out = capsys.readouterr().out
    assert "roll/pitch error vs reference [deg]" in out
    for name in ("MCAHRS (CS)", "compensation off", "velocity differencing", "VQF", "Fusion"):
        assert name in out
    assert "C core vs golden model" in out and "Goals (printed, not asserted)" in out
    assert "Reference time offset" in out
    pngs = sorted(p.name for p in plots.glob("*.png"))
    assert len(pngs) == 3, pngs
    with open(table) as fh:
        rows = list(csv.reader(fh))
    assert rows[0][:3] == ["t_s", "in_window", "man_acc_mps2"] and "ref_pitch_deg" in rows[0]
    assert len(rows) - 1 == len(cut_recording(load(COMMA), 0.0, 25.0).imu)


def test_evaluate_robust_profile_runs_mcahrs_in_it() -> None:
    """``evaluate(..., robust=P)`` (``mcahrs evaluate --robust P``): the MCAHRS runs are the C core
    in profile P for the recording's fix rate, the report says so, and the golden comparison is
    left out with a note (the golden model has no robust modes)."""
    from mcahrs.evaluate import MCAHRS, evaluate, format_report

    _need(COMMA)
    rec = cut_recording(load(COMMA), 0.0, 25.0)
    ev = evaluate(rec, "ground", robust="igg3", baselines=False)
    assert ev.robust == "igg3" and ev.golden is None
    assert any("no golden-model comparison" in n for n in ev.notes)
    rate_hz = 1.0 / float(np.median(np.diff(rec.gnss["t_us"]) * 1e-6))
    cfg = core.nav_config("ground", comp_mode=1, **core.robust_profile("igg3", rate_hz))
    mc = ev.run(MCAHRS).out
    assert mc is not None
    np.testing.assert_array_equal(mc["euler_rad"], core.replay(rec, cfg)["euler_rad"])
    assert "robust profile igg3" in format_report(ev)


def test_evaluate_without_reference_reports_stop_tilt(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    _need(CAR)
    rc = main_evaluate(
        [str(CAR), "--start", "180", "--duration", "30", "--no-golden", "--plot", str(tmp_path)]
    )
    assert rc == 0
    out = capsys.readouterr().out
    assert "Stop tilt" in out and "no stops" not in out
    assert "tilt error at stops" in out
    assert "gyro alone from MCAHRS's attitude and bias" in out
    assert len(list(tmp_path.glob("*.png"))) == 3


def test_imu_as_logged_keeps_the_logs_samples_and_is_ulog_only(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """``--imu-as-logged``: the ULog's IMU samples as logged, without the missing ones the loader
    puts back (evaluate and convert); any other recording is a usage error."""
    ulog = ULOG61
    _need(ulog)
    _need(COMMA)
    args = ["--start", "10", "--duration", "10", "--no-golden"]
    assert main_evaluate([str(ulog), *args]) == 0
    filled = capsys.readouterr().out
    assert main_evaluate([str(ulog), *args, "--imu-as-logged"]) == 0
    logged = capsys.readouterr().out
    n_filled, n_logged = (int(o.split("\nIMU ")[1].split(" samples")[0]) for o in (filled, logged))
    assert "samples missing from the log put back" in filled and "put back" not in logged
    assert n_logged < n_filled < 1.1 * n_logged  # 10 s at 200 Hz: about 150 of 2000 missing
    out = tmp_path / "s.txt"
    assert main_convert([str(ulog), "--out", str(out), "--duration", "5", "--imu-as-logged"]) == 0
    capsys.readouterr()
    assert main_evaluate([str(COMMA), "--imu-as-logged"]) == 2
    assert main_convert([str(COMMA), "--out", str(out), "--imu-as-logged"]) == 2
    assert "applies to ULog files only" in capsys.readouterr().err


def test_evaluate_bad_path_is_a_usage_error(capsys: pytest.CaptureFixture) -> None:
    assert main_evaluate([str(ROOT / "no_such_recording.ulg")]) == 2
    assert "no such file" in capsys.readouterr().err

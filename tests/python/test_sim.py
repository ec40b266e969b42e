"""Tests of mcahrs.sim: truth self-consistency, vehicle physics, sensor statistics, GNSS geodesy, timing.

Expected values come from the configured parameters and from independent constructions in
this file (Euler-angle DCMs, pymap3d, textbook formulas), never from numbers the simulator
printed. Statistical tolerances are ~5 standard deviations of the estimator, derived where used.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcahrs.samples import (
    GNSS_DTYPE,
    GNSS_HAS_ALT,
    GNSS_HAS_COURSE,
    GNSS_HAS_VEL_D,
    GNSS_HAS_VEL_NE,
    IMU_DTYPE,
    MAG_DTYPE,
    REF_DTYPE,
)
from mcahrs.sim import (
    SCENARIOS,
    Channel,
    SimParams,
    ned_to_geodetic_wgs84,
    normal_gravity,
    scenario,
)

try:  # pymap3d (test extra) is the independent geodetic path; tests that need it skip without it
    import pymap3d
except ImportError:  # pragma: no cover
    pymap3d = None
needs_pymap3d = pytest.mark.skipif(pymap3d is None, reason="pymap3d not installed")

DEG = math.pi / 180.0


# --------------------------------------------------------------------------- independent helpers
def dcm_nb_from_euler(roll, pitch, yaw) -> np.ndarray:
    """C_nb = Rz(yaw) Ry(pitch) Rx(roll), built from elementary rotation matrices; shape (..., 3, 3)."""
    roll, pitch, yaw = np.broadcast_arrays(*(np.asarray(a, np.float64) for a in (roll, pitch, yaw)))
    one, zero = np.ones_like(roll), np.zeros_like(roll)
    cr, sr, cp, sp, cy, sy = (
        np.cos(roll),
        np.sin(roll),
        np.cos(pitch),
        np.sin(pitch),
        np.cos(yaw),
        np.sin(yaw),
    )
    rx = np.stack([one, zero, zero, zero, cr, -sr, zero, sr, cr], -1).reshape(roll.shape + (3, 3))
    ry = np.stack([cp, zero, sp, zero, one, zero, -sp, zero, cp], -1).reshape(roll.shape + (3, 3))
    rz = np.stack([cy, -sy, zero, sy, cy, zero, zero, zero, one], -1).reshape(roll.shape + (3, 3))
    return rz @ ry @ rx


def dcm_from_quat(q: np.ndarray) -> np.ndarray:
    """Hamilton [w, x, y, z] to the DCM it rotates with (textbook formula)."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        -1,
    ).reshape(q.shape[:-1] + (3, 3))  # fmt: skip


def rotvec_between(q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Rotation vector of C0^T C1 (body-frame rotation from q0 to q1), via DCMs (sign-free)."""
    r = np.swapaxes(dcm_from_quat(q0), -1, -2) @ dcm_from_quat(q1)
    ang = np.arccos(np.clip((np.trace(r, axis1=-2, axis2=-1) - 1) / 2, -1, 1))
    v = np.stack([r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]], -1)
    k = np.where(ang > 1e-12, ang / (2 * np.sin(np.maximum(ang, 1e-300))), 0.5)
    return v * k[:, None]


def d5(x: np.ndarray, h: float) -> np.ndarray:
    """5-point central difference (error h^4 f^(5) / 30), for samples 2..N-3."""
    return (x[:-4] - 8 * x[1:-3] + 8 * x[3:-1] - x[4:]) / (12 * h)


def fix_ned(res) -> np.ndarray:
    """GNSS fixes back to NED metres via pymap3d (the independent path)."""
    g, p = res.recording.gnss, res.params
    n, e, d = pymap3d.geodetic2ned(
        g["lat_e7"] * 1e-7,
        g["lon_e7"] * 1e-7,
        g["alt_mm"] * 1e-3,
        p.home_lat_deg,
        p.home_lon_deg,
        p.home_alt_m,
    )
    return np.stack([n, e, d], -1)


def allan_var(y: np.ndarray, m: int) -> np.ndarray:
    """Non-overlapping Allan variance of rate samples y (n, k) at cluster size m, per column."""
    nc = y.shape[0] // m
    means = y[: nc * m].reshape(nc, m, -1).mean(axis=1)
    return 0.5 * np.mean(np.diff(means, axis=0) ** 2, axis=0)


# --------------------------------------------------------------------------- truth consistency
CONSISTENCY_CASES = [
    ("car_accel_brake", {"grade_deg": 3.0, "turn_deg": 90.0, "k_pitch": 0.01, "k_roll": 0.02}),
    ("fixedwing_turns", {}),
    ("multirotor_aggressive", {}),
    ("gps_outage", {}),
    ("gps_outage", {"vehicle": "car"}),
    ("steady", {"vehicle": "multirotor", "climb_deg": 10.0}),
]


@pytest.mark.parametrize("name,kw", CONSISTENCY_CASES)
def test_truth_derivatives_match_velocity_acceleration_and_body_rate(name, kw):
    # 800 Hz: the 5-point stencil's h^4 error (and Richardson's h^4 for the rate) is then ~1e-8 relative,
    # so the 1e-6 bound tests the truth, not the differencing.
    res = scenario(name, seed=5, ideal=True, imu_rate_hz=800.0, **kw)
    tr = res.truth
    h = 1.0 / 800.0
    assert np.all(np.diff(tr.t_us) == 1250)
    vel_scale = np.abs(tr.vel_ned_mps).max()
    acc_scale = max(np.abs(tr.acc_ned_mps2).max(), 1.0)
    assert np.abs(d5(tr.pos_ned_m, h) - tr.vel_ned_mps[2:-2]).max() < 1e-6 * vel_scale
    assert np.abs(d5(tr.vel_ned_mps, h) - tr.acc_ned_mps2[2:-2]).max() < 1e-6 * acc_scale
    # position is the integral of velocity: composite Simpson (error ~h^4, < 1e-12 m here) on sample pairs;
    # 1e-8 m is ~100x below what a midpoint-rule integration would leave
    v = tr.vel_ned_mps
    simpson = np.cumsum((h / 3) * (v[0:-2:2] + 4 * v[1:-1:2] + v[2::2]), axis=0)
    assert np.abs(tr.pos_ned_m[2::2] - tr.pos_ned_m[0] - simpson).max() < 1e-8
    # body rate: rotation over +-h and +-2h, Richardson-extrapolated (the error is even in h)
    q = tr.q_nb
    w1 = rotvec_between(q[1:-3], q[3:-1]) / (2 * h)
    w2 = rotvec_between(q[:-4], q[4:]) / (4 * h)
    w_num = (4 * w1 - w2) / 3
    rate_scale = max(np.abs(tr.omega_b_rps).max(), 0.1)
    assert np.abs(w_num - tr.omega_b_rps[2:-2]).max() < 1e-6 * rate_scale
    # Euler angles, quaternion and specific force agree with independent constructions
    c_nb = dcm_nb_from_euler(*tr.euler_rad.T)
    assert np.abs(c_nb - dcm_from_quat(q)).max() < 1e-12
    f_n = tr.acc_ned_mps2 - np.array([0.0, 0.0, res.g_mps2])
    f_b = np.einsum("nji,nj->ni", c_nb, f_n)
    assert np.abs(f_b - res.recording.imu["accel_mps2"]).max() < 1e-9
    assert np.abs(tr.omega_b_rps - res.recording.imu["gyro_rps"]).max() == 0.0
    assert np.all(q[:, 0] >= 0.0)
    assert np.all(np.abs(tr.euler_rad[:, 2]) <= math.pi)


def test_channel_pulse_integral_is_exact_and_smooth():
    ch = Channel(1, c0=2.0)
    ch.add_pulse(1.0, 3.0, 0.5, 1.5)  # integral 1.5 * (3 - 1) = 3
    t = np.linspace(0.0, 6.0, 60001)
    v, a = ch.eval(t), ch.eval(t, 1)
    assert v[0] == 2.0 and abs(v[-1] - 5.0) < 1e-12
    assert abs(a.max() - 1.5) < 1e-12 and a[0] == 0.0 and a[-1] == 0.0
    h = t[1] - t[0]
    for k in range(1, 4):  # each derivative is the derivative of the previous one
        lo, hi = ch.eval(t, k - 1), ch.eval(t, k)
        assert np.abs(d5(lo, h) - hi[2:-2]).max() < 1e-6 * max(np.abs(hi).max(), 1.0)
    with pytest.raises(ValueError):
        Channel(2)


# --------------------------------------------------------------------------- vehicle physics
@pytest.mark.parametrize("level", [True, False])
def test_static_noise_free_accelerometer_reads_rotated_gravity(level):
    euler_deg = (0.0, 0.0, 0.0) if level else (20.0, -35.0, 120.0)
    res = scenario(
        "static", ideal=True, duration_s=5.0,
        roll_deg=euler_deg[0], pitch_deg=euler_deg[1], yaw_deg=euler_deg[2],
    )  # fmt: skip
    g = res.g_mps2
    c_nb = dcm_nb_from_euler(*(np.array(euler_deg) * DEG))
    expect = c_nb.T @ np.array([0.0, 0.0, -g])
    if level:
        np.testing.assert_allclose(expect, [0.0, 0.0, -g], atol=0)
    phi, theta = (
        euler_deg[0] * DEG,
        euler_deg[1] * DEG,
    )  # closed form f_b = -g [-s_theta, s_phi c_theta, c_phi c_theta]
    np.testing.assert_allclose(
        expect,
        -g * np.array([-math.sin(theta), math.sin(phi) * math.cos(theta), math.cos(phi) * math.cos(theta)]),
        atol=1e-12,
    )
    imu = res.recording.imu
    assert np.abs(imu["accel_mps2"] - expect).max() < 1e-12
    assert np.abs(imu["gyro_rps"]).max() < 1e-15
    assert np.abs(dcm_from_quat(res.recording.ref["q_nb"]) - c_nb).max() < 1e-12
    mag_n = res.params.mag_ned
    assert abs(mag_n[2] / np.linalg.norm(mag_n) - math.sin(res.params.mag_inclination_deg * DEG)) < 1e-12
    assert np.abs(res.recording.mag["mag_b"] - c_nb.T @ mag_n).max() < 1e-12


def test_coordinated_turn_bank_matches_turn_rate_and_no_side_force():
    res = scenario("fixedwing_turns", ideal=True)
    tr, g = res.truth, res.g_mps2
    h = 1.0 / res.params.imu_rate_hz
    course = np.unwrap(np.arctan2(tr.vel_ned_mps[:, 1], tr.vel_ned_mps[:, 0]))
    omega = d5(course, h)
    speed = np.linalg.norm(tr.vel_ned_mps, axis=1)[2:-2]
    bank = tr.euler_rad[2:-2, 0]
    assert np.abs(bank - np.arctan(speed * omega / g)).max() < 1e-6  # 5-point difference error ~1e-9
    assert abs(np.abs(bank).max() - res.scenario_params["bank_deg"] * DEG) < 1e-9  # the turns reach the bank
    assert np.count_nonzero(bank > 29.9 * DEG) and np.count_nonzero(bank < -29.9 * DEG)  # right and left
    # heading changes by whole circles; nose along velocity (yaw = course, pitch = 0 in level flight)
    assert abs((course[-1] - course[0]) / (2 * math.pi) - sum(res.scenario_params["circles"])) < 1e-6
    yaw_err = np.angle(np.exp(1j * (tr.euler_rad[:, 2] - course)))
    assert np.abs(yaw_err).max() < 1e-9 and np.abs(tr.euler_rad[:, 1]).max() < 1e-12
    f_b = res.recording.imu["accel_mps2"]
    assert np.abs(f_b[:, 1]).max() < 1e-9  # coordinated: no body-y specific force
    assert np.abs(tr.pos_ned_m[:, 2] + res.scenario_params["altitude_m"]).max() < 1e-9  # level
    assert abs(speed.max() - 20.0) < 1e-9 and abs(speed.min() - 20.0) < 1e-9


def test_car_reaches_60_kmh_in_5_s_then_brakes_to_rest():
    res = scenario("car_accel_brake", ideal=True)
    tr, sp = res.truth, res.scenario_params
    speed = np.linalg.norm(tr.vel_ned_mps, axis=1)
    t = tr.t_s
    k0 = np.flatnonzero(speed > 0.0)[0]  # first sample moving
    assert abs(t[k0 - 1] - sp["rest_s"]) < 1.0 / res.params.imu_rate_hz + 1e-12  # >= 2 s at rest first
    assert sp["rest_s"] >= 2.0
    k5 = np.searchsorted(tr.t_us, tr.t_us[k0 - 1] + 5_000_000)
    assert abs(speed[k5] - 60.0 / 3.6) < 1e-9
    assert np.all(speed[:k5] < 60.0 / 3.6)
    assert abs(speed.max() - 60.0 / 3.6) < 1e-9
    decel = -np.einsum("ni,ni->n", tr.acc_ned_mps2, tr.vel_ned_mps) / np.maximum(speed, 1e-9)
    assert abs(decel.max() - sp["brake_mps2"]) < 1e-6  # hard braking reaches the commanded deceleration
    assert speed[-1] < 1e-9 and np.abs(tr.acc_ned_mps2[-1]).max() < 1e-12  # at rest at the end
    # attitude follows the heading of travel; level road, no suspension: pitch = roll = 0
    moving = speed > 0.1
    course = np.arctan2(tr.vel_ned_mps[moving, 1], tr.vel_ned_mps[moving, 0])
    assert np.abs(np.angle(np.exp(1j * (tr.euler_rad[moving, 2] - course)))).max() < 1e-9
    assert np.abs(tr.euler_rad[:, :2]).max() == 0.0


def test_car_road_grade_pitches_the_nose_along_velocity():
    res = scenario("car_accel_brake", ideal=True, grade_deg=4.0)
    tr = res.truth
    speed_h = np.hypot(tr.vel_ned_mps[:, 0], tr.vel_ned_mps[:, 1])
    moving = speed_h > 1.0
    gamma = np.arctan2(-tr.vel_ned_mps[moving, 2], speed_h[moving])
    assert np.abs(tr.euler_rad[moving, 1] - gamma).max() < 1e-12
    assert abs(tr.euler_rad[:, 1].max() - 4.0 * DEG) < 1e-12


def test_multirotor_thrust_along_body_minus_z_and_aggressive_accelerations():
    res = scenario("multirotor_aggressive", ideal=True, seed=2, duration_s=300.0)
    tr, sp = res.truth, res.scenario_params
    f_b = res.recording.imu["accel_mps2"]
    assert np.abs(f_b[:, :2]).max() < 1e-9  # thrust only: no body x/y specific force
    assert np.all(f_b[:, 2] < 0.0)
    a_lo, a_hi = sp["accel_mps2"]
    a_norm = np.linalg.norm(tr.acc_ned_mps2, axis=1)
    assert a_norm.max() <= a_hi + 1e-9 and a_norm.max() > a_lo
    # manoeuvres in various directions: horizontal accelerations above a_lo in every quadrant
    big = np.hypot(tr.acc_ned_mps2[:, 0], tr.acc_ned_mps2[:, 1]) > 0.9 * a_lo
    az = np.arctan2(tr.acc_ned_mps2[big, 1], tr.acc_ned_mps2[big, 0])
    assert len(np.unique(np.floor(az / (math.pi / 2)))) == 4
    # stops: zero velocity again several times after take-off
    speed = np.linalg.norm(tr.vel_ned_mps, axis=1)
    stopped = speed < 1e-9
    assert np.count_nonzero(np.diff(stopped.astype(int)) == 1) >= 5
    assert np.all(speed[tr.t_s < sp["rest_s"]] == 0.0) and sp["rest_s"] >= 2.0
    assert np.all(-tr.pos_ned_m[tr.t_s > 20.0, 2] > 1.0)  # airborne after take-off


# --------------------------------------------------------------------------- IMU error models
def test_gyro_and_accel_white_noise_density():
    p = {"gyro_noise_rps_rthz": 1e-3, "accel_noise_mps2_rthz": 4e-3, "imu_rate_hz": 200.0}
    res = scenario("static", seed=7, ideal=True, duration_s=600.0, **p)
    n = res.recording.imu.size * 3
    for field, truth_f, dens in (
        ("gyro_rps", np.zeros(3), p["gyro_noise_rps_rthz"]),
        ("accel_mps2", res.truth.specific_force_b_mps2[0], p["accel_noise_mps2_rthz"]),
    ):
        e = res.recording.imu[field] - truth_f
        s = e.std()
        # per-sample sigma = density * sqrt(f_s); rel. std of a sample std is 1/sqrt(2n) ~ 0.1%: 1% ~ 10 sigma
        assert abs(s / (dens * math.sqrt(p["imu_rate_hz"])) - 1.0) < 0.01
        assert abs(e.mean()) < 5 * s / math.sqrt(n)


def test_allan_variance_white_noise_and_rate_random_walk():
    fs = 20.0
    n_dens, k_rw = 2e-3, 2e-4
    white = scenario(
        "static", seed=3, ideal=True, imu_rate_hz=fs, duration_s=20000.0, gyro_noise_rps_rthz=n_dens
    )
    m = int(fs * 1.0)  # tau = 1 s: 20000 clusters per axis, AVAR rel. std ~ sqrt(2/20000) = 1%; pooled 3 axes
    av = allan_var(white.recording.imu["gyro_rps"], m).mean()
    assert abs(av / (n_dens**2 / 1.0) - 1.0) < 0.05
    rw = scenario("static", seed=3, ideal=True, imu_rate_hz=fs, duration_s=20000.0, gyro_bias_rw_rps_rts=k_rw)
    tau = 10.0  # 2000 clusters per axis: rel. std ~ 2.5-3% per axis, ~1.7% pooled; 10% is ~6 sigma
    av = allan_var(rw.recording.imu["gyro_rps"], int(fs * tau)).mean()
    assert abs(av / (k_rw**2 * tau / 3.0) - 1.0) < 0.10
    # the truth bias is what the sensor adds
    assert np.abs(rw.recording.imu["gyro_rps"] - rw.truth.gyro_bias_rps).max() < 1e-15


def test_constant_bias_scale_factor_quantization_and_saturation():
    res = scenario(
        "static", seed=1, duration_s=2.0, roll_deg=30.0,
        gyro_noise_rps_rthz=0.0, accel_noise_mps2_rthz=0.0,
        gyro_bias_rw_rps_rts=0.0, accel_bias_rw_mps2_rts=0.0,
        gyro_bias_rps=(0.01, -0.02, 0.03), accel_bias_mps2=(0.1, 0.2, -0.3),
        accel_scale_ppm=(0.0, 1000.0, -2000.0),
    )  # fmt: skip
    p, imu = res.params, res.recording.imu
    f_true = dcm_nb_from_euler(30 * DEG, 0.0, 0.0).T @ np.array([0.0, 0.0, -res.g_mps2])
    expect = f_true * (1 + 1e-6 * np.array(p.accel_scale_ppm)) + np.array(p.accel_bias_mps2)
    assert np.abs(imu["accel_mps2"] - expect).max() <= 0.5 * p.accel_lsb_mps2 + 1e-12
    assert np.abs(imu["gyro_rps"] - np.array(p.gyro_bias_rps)).max() <= 0.5 * p.gyro_lsb_rps + 1e-12
    for field, lsb in (("accel_mps2", p.accel_lsb_mps2), ("gyro_rps", p.gyro_lsb_rps)):
        k = imu[field] / lsb
        assert np.abs(k - np.round(k)).max() < 1e-6  # integer counts
    sat = scenario("static", seed=1, duration_s=1.0, accel_range_mps2=5.0)
    assert np.all(sat.recording.imu["accel_mps2"][:, 2] == -5.0)
    # drawn turn-on biases are seeded, per axis, and recorded in the truth
    a, b = scenario("static", seed=11, duration_s=1.0), scenario("static", seed=12, duration_s=1.0)
    assert not np.allclose(a.truth.gyro_bias_rps[0], b.truth.gyro_bias_rps[0])


def test_vibration_hard_and_soft_iron():
    soft = ((1.1, 0.05, 0.0), (0.05, 0.9, 0.0), (0.0, 0.0, 1.0))
    res = scenario(
        "static", ideal=True, duration_s=10.0, pitch_deg=10.0, accel_vibration_mps2=2.0,
        accel_vibration_hz=50.0, mag_hard_iron_ut=(5.0, -3.0, 1.0), mag_soft_iron=soft,
    )  # fmt: skip
    vib = res.recording.imu["accel_mps2"] - res.truth.specific_force_b_mps2
    t = res.truth.t_s
    basis = np.stack([np.sin(2 * math.pi * 50.0 * t), np.cos(2 * math.pi * 50.0 * t)], -1)
    coef = np.linalg.lstsq(basis, vib, rcond=None)[0]  # (2, 3): sin/cos weights per axis
    np.testing.assert_allclose(np.hypot(coef[0], coef[1]), 2.0, rtol=1e-9)  # amplitude on every axis
    assert np.abs(vib - basis @ coef).max() < 1e-9  # a pure 50 Hz sinusoid
    c_nb = dcm_nb_from_euler(0.0, 10.0 * DEG, 0.0)
    expect = np.array(soft) @ (c_nb.T @ res.params.mag_ned) + np.array([5.0, -3.0, 1.0])
    assert np.abs(res.recording.mag["mag_b"] - expect).max() < 1e-12
    assert np.all(np.diff(res.recording.mag["t_us"]) == round(1e6 / res.params.mag_rate_hz))


def test_earth_rate_option():
    res = scenario("static", ideal=True, duration_s=1.0, earth_rate=True)
    lat = res.params.home_lat_deg * DEG
    omega_e = 7.292115e-5
    expect = omega_e * np.array([math.cos(lat), 0.0, -math.sin(lat)])  # level, yaw 0: body = NED
    np.testing.assert_allclose(res.recording.imu["gyro_rps"][0], expect, atol=1e-15)


# --------------------------------------------------------------------------- GNSS
@needs_pymap3d
def test_gps_gauss_markov_sigma_and_autocorrelation():
    tau, rate = 5.0, 5.0
    res = scenario(
        "static", seed=4, duration_s=20000.0, imu_rate_hz=10.0, gps_rate_hz=rate, mag_rate_hz=0.0,
        gps_pos_tau_s=tau, gps_pos_white_h_m=0.0, gps_pos_white_v_m=0.0,
    )  # fmt: skip
    p = res.params
    err = fix_ned(res) - res.truth.pos_ned_m[res.truth.index_of(res.recording.gnss["t_us"])]
    n = err.shape[0]
    phi = math.exp(-1.0 / (rate * tau))
    # AR(1): var(s^2)/sigma^4 ~ (2/n)(1+phi^2)/(1-phi^2) -> rel. std of s ~ 1.1% per axis; 5 sigma
    rel_sd = 0.5 * math.sqrt(2.0 / n * (1 + phi**2) / (1 - phi**2))
    s_h = np.sqrt(np.mean(err[:, :2] ** 2))
    s_v = np.sqrt(np.mean(err[:, 2] ** 2))
    assert abs(s_h / p.gps_pos_sigma_h_m - 1.0) < 5 * rel_sd / math.sqrt(2)
    assert abs(s_v / p.gps_pos_sigma_v_m - 1.0) < 5 * rel_sd
    lag = int(round(tau * rate))  # one correlation time: expected rho = exp(-lag dt / tau) = e^-1
    for lg in (1, lag, 3 * lag):
        rho_expect = phi**lg
        # Bartlett: var(r_L) ~ [(1+phi^2)(1-phi^2L)/(1-phi^2) - 2 L phi^2L] / n, two pooled axes
        var_r = ((1 + phi**2) * (1 - phi ** (2 * lg)) / (1 - phi**2) - 2 * lg * phi ** (2 * lg)) / n / 2
        e = err[:, :2] - err[:, :2].mean(axis=0)
        rho = np.sum(e[lg:] * e[:-lg]) / np.sum(e * e)
        assert abs(rho - rho_expect) < 5 * math.sqrt(var_r)


def test_gps_velocity_noise_and_reported_accuracies():
    res = scenario("static", seed=9, duration_s=4000.0, imu_rate_hz=20.0, gps_rate_hz=10.0, mag_rate_hz=0.0)
    p, g = res.params, res.recording.gnss
    v = g["vel_ned_mps"]
    n = v.shape[0]
    # white: rel. std of a sample std is 1/sqrt(2n) (0.5% per axis); 3% is > 5 sigma
    assert abs(v[:, :2].std() / p.gps_vel_sigma_h_mps - 1) < 0.03
    assert abs(v[:, 2].std() / p.gps_vel_sigma_v_mps - 1) < 0.03
    assert abs(np.corrcoef(v[1:, 0], v[:-1, 0])[0, 1]) < 5 / math.sqrt(n)  # white: uncorrelated
    np.testing.assert_allclose(g["h_acc_m"], math.hypot(p.gps_pos_sigma_h_m, p.gps_pos_white_h_m))
    np.testing.assert_allclose(g["v_acc_m"], math.hypot(p.gps_pos_sigma_v_m, p.gps_pos_white_v_m))
    np.testing.assert_allclose(g["s_acc_mps"], p.gps_vel_sigma_h_mps)
    np.testing.assert_allclose(g["speed_mps"], np.hypot(v[:, 0], v[:, 1]))
    c = g["course_rad"]
    assert np.all((c >= 0) & (c < 2 * math.pi))
    np.testing.assert_allclose(np.cos(c) * g["speed_mps"], v[:, 0], atol=1e-12)
    np.testing.assert_allclose(np.sin(c) * g["speed_mps"], v[:, 1], atol=1e-12)
    assert np.all(g["flags"] == GNSS_HAS_VEL_NE | GNSS_HAS_VEL_D | GNSS_HAS_ALT | GNSS_HAS_COURSE)
    assert np.all(g["fix_type"] == 3)


@pytest.mark.parametrize("latency_us,jitter_us", [(None, 0), (250_000, 0), (80_000, 20_000)])
def test_gps_latency(latency_us, jitter_us):
    kw = {} if latency_us is None else {"gps_latency_us": latency_us}
    res = scenario("steady", seed=1, duration_s=30.0, gps_latency_jitter_us=jitter_us, **kw)
    g, p = res.recording.gnss, res.params
    lat = g["t_rx_us"] - g["t_us"]
    if latency_us is None:
        latency_us = SimParams().gps_latency_us
    assert p.gps_latency_us == latency_us
    if jitter_us == 0:
        assert np.all(lat == latency_us)
    else:
        assert lat.min() >= latency_us and lat.max() <= latency_us + jitter_us and lat.std() > 0
    assert g["t_rx_us"].max() <= res.truth.t_us[-1]
    # epochs at the configured rate on the IMU clock
    assert np.all(np.diff(g["t_us"]) == round(1e6 / p.gps_rate_hz))


def test_imu_time_jitter_moves_the_reported_times_only():
    """imu_time_jitter_us: each IMU sample's reported time is off its sampling instant by a uniform
    integer in [-j, j] us (clipped at 0), still increasing; the samples, the fixes, the magnetometer and
    the reference are those of the run without it (a generator of its own), and ideal() turns it off."""
    a = scenario("car_accel_brake", seed=3, duration_s=20.0)
    b = scenario("car_accel_brake", seed=3, duration_s=20.0, imu_time_jitter_us=600)
    d = b.recording.imu["t_us"] - a.recording.imu["t_us"]
    assert d.min() >= -600 and d.max() <= 600 and np.unique(d).size > 1000
    assert np.all(b.recording.imu["t_us"] >= 0) and np.all(np.diff(b.recording.imu["t_us"]) > 0)
    # the intervals sum to under the history's 20 ms span as often as over it (what the option is for)
    span = b.recording.imu["t_us"][8:] - b.recording.imu["t_us"][:-8]
    assert 0.3 < np.mean(span < 20_000) < 0.7
    for field in ("gyro_rps", "accel_mps2"):
        np.testing.assert_array_equal(a.recording.imu[field], b.recording.imu[field])
    np.testing.assert_array_equal(a.recording.gnss, b.recording.gnss)
    np.testing.assert_array_equal(a.recording.mag, b.recording.mag)
    np.testing.assert_array_equal(a.recording.ref, b.recording.ref)
    assert SimParams(imu_time_jitter_us=600).ideal().imu_time_jitter_us == 0
    with pytest.raises(ValueError, match="imu_time_jitter_us"):
        scenario("steady", seed=1, duration_s=5.0, imu_time_jitter_us=1250)  # half of a 400 Hz sample


@needs_pymap3d
def test_gps_lat_lon_round_trip_to_ned_within_quantization():
    res = scenario("fixedwing_turns", ideal=True)
    g, p = res.recording.gnss, res.params
    idx = res.truth.index_of(g["t_us"])
    d = fix_ned(res) - res.truth.pos_ned_m[idx]
    # half an LSB: 0.5e-7 deg on the meridian (~5.5 mm) and the parallel (~4.8 mm at 30.5 deg), 0.5 mm height
    a, e2 = 6378137.0, 6.69437999014e-3
    s2 = math.sin(p.home_lat_deg * DEG) ** 2
    r_m = a * (1 - e2) / (1 - e2 * s2) ** 1.5 + 1000.0
    r_n = a / math.sqrt(1 - e2 * s2) + 1000.0
    half = 0.5e-7 * DEG
    assert np.abs(d[:, 0]).max() <= half * r_m * 1.001
    assert np.abs(d[:, 1]).max() <= half * r_n * math.cos(p.home_lat_deg * DEG) * 1.01
    assert np.abs(d[:, 2]).max() <= 0.5e-3 + 1e-6
    assert np.abs(d).max() > 1e-4  # really quantized (not float pass-through)
    np.testing.assert_allclose(g["vel_ned_mps"], res.truth.vel_ned_mps[idx], atol=1e-12)


@needs_pymap3d
def test_own_wgs84_conversion_matches_pymap3d():
    rng = np.random.default_rng(0)
    n, e = rng.uniform(-100e3, 100e3, (2, 2000))
    d = rng.uniform(-10e3, 1e3, 2000)
    for lat0, lon0, h0 in (
        (30.5, 114.3, 50.0),
        (-60.0, -170.0, 2000.0),
        (0.0, 0.0, 0.0),
        (85.0, 10.0, -30.0),
    ):
        mine = ned_to_geodetic_wgs84(n, e, d, lat0, lon0, h0)
        ref = pymap3d.ned2geodetic(n, e, d, lat0, lon0, h0)
        assert np.abs(mine[0] - ref[0]).max() < 1e-10  # deg (~1e-5 m)
        assert np.abs(np.angle(np.exp(1j * np.radians(mine[1] - ref[1])))).max() < 1e-12  # rad
        assert np.abs(mine[2] - ref[2]).max() < 1e-5  # m


@needs_pymap3d
def test_fallback_conversion_gives_the_same_fixes(monkeypatch):
    import sys

    a = scenario("fixedwing_turns", seed=3, duration_s=60.0)
    monkeypatch.setitem(sys.modules, "pymap3d", None)  # import pymap3d now raises ImportError
    b = scenario("fixedwing_turns", seed=3, duration_s=60.0)
    for f in ("lat_e7", "lon_e7", "alt_mm"):  # the two paths agree to well below one LSB
        assert np.abs(a.recording.gnss[f].astype(np.int64) - b.recording.gnss[f]).max() <= 1


@needs_pymap3d
def test_gps_lever_arm():
    res = scenario("static", ideal=True, duration_s=2.0, yaw_deg=90.0, gps_lever_arm_b_m=(1.0, 0.0, -0.5))
    d = fix_ned(res)
    np.testing.assert_allclose(
        d, np.broadcast_to([0.0, 1.0, -0.5], d.shape), atol=6e-3
    )  # 1e-7 deg quantization


def test_gps_outage_window_has_no_fixes():
    res = scenario("gps_outage", seed=2)
    g, p = res.recording.gnss, res.params
    ((start, end),) = p.gps_outages
    assert end - start == pytest.approx(res.scenario_params["outage_s"])
    assert 0.0 < start and end < res.truth.t_s[-1]  # in the middle of the run
    t = g["t_us"] * 1e-6
    assert not np.any((t >= start) & (t < end))
    dt = 1.0 / p.gps_rate_hz
    assert t[t < start].max() > start - 2 * dt and t[t >= end].min() < end + dt  # fixes right up to/after it
    gap = np.diff(t)
    assert np.count_nonzero(gap > 1.5 * dt) == 1
    # manoeuvring during the outage
    inside = (res.truth.t_s >= start) & (res.truth.t_s < end)
    assert np.linalg.norm(res.truth.acc_ned_mps2[inside], axis=1).max() > 2.0
    # explicit window override
    res2 = scenario("static", duration_s=30.0, gps_outages=((5.0, 7.0), (10.0, 12.5)))
    t2 = res2.recording.gnss["t_us"] * 1e-6
    assert not np.any(((t2 >= 5) & (t2 < 7)) | ((t2 >= 10) & (t2 < 12.5)))
    assert np.any(t2 == 7.0) and np.any(t2 == 12.6)


# --------------------------------------------------------------------------- structure, seeds, gravity
@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_every_scenario_yields_a_consistent_recording(name):
    res = scenario(name, seed=1, duration_s=30.0)
    rec = res.recording
    assert rec.imu.dtype == IMU_DTYPE and rec.gnss.dtype == GNSS_DTYPE and rec.mag.dtype == MAG_DTYPE
    assert rec.ref.dtype == REF_DTYPE
    assert np.all(np.diff(rec.imu["t_us"]) == round(1e6 / res.params.imu_rate_hz))
    assert rec.imu["t_us"][0] == 0 and rec.imu.size == 30 * 400 + 1
    np.testing.assert_array_equal(rec.ref["t_us"], rec.imu["t_us"])
    np.testing.assert_array_equal(rec.ref["q_nb"], res.truth.q_nb)
    assert np.all(np.diff(rec.gnss["t_rx_us"]) > 0) and np.all(rec.gnss["t_rx_us"] >= rec.gnss["t_us"])
    assert np.all(np.isfinite(rec.imu["gyro_rps"])) and np.all(np.isfinite(rec.imu["accel_mps2"]))
    assert np.all(np.isin(rec.mag["t_us"], rec.imu["t_us"])) and np.all(
        np.isin(rec.gnss["t_us"], rec.imu["t_us"])
    )
    assert rec.meta["g_mps2"] == res.params.g_mps2 and rec.name == f"sim/{name}"
    tr = res.truth
    for arr in (
        tr.pos_ned_m,
        tr.vel_ned_mps,
        tr.acc_ned_mps2,
        tr.omega_b_rps,
        tr.gyro_bias_rps,
        tr.accel_bias_mps2,
    ):
        assert arr.shape == (rec.imu.size, 3)
    assert tr.q_nb.shape == (rec.imu.size, 4) and tr.euler_rad.shape == (rec.imu.size, 3)
    np.testing.assert_allclose(np.linalg.norm(tr.q_nb, axis=1), 1.0, atol=1e-14)
    # at rest (or in steady level flight) for the first 2 s
    first = tr.t_s <= 2.0
    assert np.abs(tr.acc_ned_mps2[first]).max() < 1e-12 and np.abs(tr.omega_b_rps[first]).max() < 1e-12


def test_seeds_make_runs_reproducible_and_streams_independent():
    a = scenario("multirotor_aggressive", seed=42, duration_s=40.0)
    b = scenario("multirotor_aggressive", seed=42, duration_s=40.0)
    c = scenario("multirotor_aggressive", seed=43, duration_s=40.0)
    for f in ("imu", "gnss", "mag", "ref"):
        np.testing.assert_array_equal(getattr(a.recording, f), getattr(b.recording, f))
    assert not np.array_equal(a.recording.imu["gyro_rps"], c.recording.imu["gyro_rps"])
    assert not np.array_equal(a.truth.pos_ned_m, c.truth.pos_ned_m)  # the manoeuvre sequence is seeded too
    # changing the GNSS model leaves the IMU noise and the trajectory untouched
    d = scenario("multirotor_aggressive", seed=42, duration_s=40.0, gps_pos_sigma_h_m=10.0, gps_rate_hz=10.0)
    np.testing.assert_array_equal(a.recording.imu, d.recording.imu)


def test_normal_gravity_somigliana_published_values():
    # WGS84 (NIMA TR8350.2) equatorial and polar normal gravity
    assert normal_gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert normal_gravity(90.0, 0.0) == pytest.approx(9.8321849378, abs=1e-9)
    # Somigliana's original form, (a ge cos^2 L + b gp sin^2 L) / sqrt(a^2 cos^2 L + b^2 sin^2 L)
    a, b = 6378137.0, 6356752.314245
    for lat in (10.0, 30.5, 45.0, 77.0):
        c2, s2 = math.cos(lat * DEG) ** 2, math.sin(lat * DEG) ** 2
        expect = (a * 9.7803253359 * c2 + b * 9.8321849378 * s2) / math.sqrt(a * a * c2 + b * b * s2)
        assert normal_gravity(lat, 0.0) == pytest.approx(expect, abs=1e-12)
    assert 9.8061 < normal_gravity(45.0, 0.0) < 9.8063  # the familiar 9.806 at 45 deg
    # normal free-air gradient ~ -0.3086 mGal/m = -3.086e-6 s^-2
    assert (normal_gravity(45.0, 100.0) - normal_gravity(45.0, 0.0)) / 100.0 == pytest.approx(
        -3.086e-6, abs=3e-9
    )
    res = scenario("static", duration_s=1.0, home_lat_deg=60.0, home_alt_m=1000.0)
    assert res.params.g_mps2 == normal_gravity(60.0, 1000.0)
    res = scenario("static", duration_s=1.0, ideal=True, g_mps2=9.81)
    assert res.params.g_mps2 == 9.81 and res.recording.imu["accel_mps2"][0, 2] == -9.81


def test_unknown_override_is_rejected():
    with pytest.raises(TypeError, match="bank_deg"):
        scenario("car_accel_brake", bank_deg=30.0)
    with pytest.raises(ValueError):
        scenario("no_such_scenario")


def test_long_400hz_generation_sizes():
    # Sizes of a long run at 400 Hz. Speed is a benchmark figure, never a test assertion; the
    # full 2 h at 400 Hz runs in tests/python/test_nav.py, through the filter.
    res = scenario("fixedwing_turns", seed=1, duration_s=600.0)
    p = res.params
    assert res.recording.imu.size == int(600 * p.imu_rate_hz) + 1
    epochs = np.arange(0.0, 600.0 + 1e-9, 1.0 / p.gps_rate_hz)
    assert res.recording.gnss.size == np.count_nonzero(epochs * 1e6 + p.gps_latency_us <= 600e6)

"""Named scenarios and the simulation driver.

``scenario(name, seed=0, **overrides)`` builds a truth trajectory, runs the sensor models
and returns a :class:`SimResult`. Overrides are either :class:`~mcahrs.sim.sensors.SimParams`
fields (rates, home, noise levels, ``gps_outages``, ...) or the scenario's own keyword
arguments (listed in each builder's docstring; ``duration_s``, alias ``duration``, for all).
``ideal=True`` first switches every sensor error off (then explicit overrides apply).

Every scenario starts with at least 2 s at rest, except the fixed-wing ones, which start with
``lead_s`` (default 10 s) of steady, straight, level flight (an aircraft cannot be at rest in
the air; a filter initialises in steady flight as it would on the ground), and ``steady``,
which is constant velocity throughout by definition (zero acceleration and rate from t = 0).

Random manoeuvre sequences (``multirotor_aggressive``, ``gps_outage``) draw from the trajectory
generator of the seed, independent of the sensor-noise generators.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace

import numpy as np

from mcahrs.samples import REF_DTYPE, Recording
from mcahrs.sim.profiles import Channel
from mcahrs.sim.sensors import SimParams, gnss_model, imu_model, mag_model, normal_gravity
from mcahrs.sim.truth import AxisMotion, PathMotion, Truth, build_truth

__all__ = ["SCENARIOS", "Plan", "SimResult", "scenario", "simulate"]

_DEG = math.pi / 180.0


@dataclass
class Plan:
    """A truth trajectory to simulate: a motion, the vehicle attitude rule and where it starts."""

    motion: PathMotion | AxisMotion
    rule: str  # "car" | "fixedwing" | "multirotor" | "fixed" (see mcahrs.sim.truth)
    duration_s: float
    pos0_ned_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rule_kw: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)  # SimParams defaults this scenario sets
    info: dict = field(default_factory=dict)  # the scenario arguments used


@dataclass
class SimResult:
    """Output of a simulation run."""

    recording: Recording  # imu, gnss, mag, ref (truth q_nb at IMU rate), meta
    truth: Truth
    params: SimParams  # with g_mps2 resolved
    scenario: str
    scenario_params: dict
    seed: int

    @property
    def g_mps2(self) -> float:
        return float(self.params.g_mps2)


@dataclass
class _Ctx:
    g: float
    rng: np.random.Generator


# --------------------------------------------------------------------------- manoeuvre helpers
def _speed_change(ch: Channel, t: float, dv: float, accel: float, ramp: float) -> float:
    """Change an order-1 channel by ``dv`` with a smooth trapezoid of height ``accel``; returns its end."""
    if dv == 0.0:
        return t
    dur = abs(dv) / accel
    ch.add_pulse(t, t + dur, ramp, math.copysign(accel, dv))
    return t + dur + ramp


def _turn(ch: Channel, t: float, dpsi: float, rate: float, ramp: float) -> float:
    """Turn by ``dpsi`` (rad, signed) at ``rate`` (rad/s, > 0); returns the time the turn ends."""
    dur = abs(dpsi) / rate
    ch.add_pulse(t, t + dur, ramp, math.copysign(rate, dpsi))
    return t + dur + ramp


def _fw_random(ctx: _Ctx, m: PathMotion, t: float, t_end: float, speed: float, alt: float) -> None:
    """Random coordinated turns (15-35 deg bank), speed changes (16-26 m/s) and climbs/descents."""
    rng = ctx.rng
    while t < t_end:
        r = rng.random()
        if r < 0.55:
            bank = rng.uniform(15.0, 35.0) * _DEG
            dpsi = rng.uniform(45.0, 300.0) * _DEG * rng.choice([-1.0, 1.0])
            t = _turn(m.course, t, dpsi, ctx.g * math.tan(bank) / speed, 1.5)
        elif r < 0.75:
            target = rng.uniform(16.0, 26.0)
            t = _speed_change(m.speed, t, target - speed, 1.0, 1.0)
            speed = target
        else:
            gam = rng.uniform(3.0, 8.0) * _DEG
            if alt > 130.0 or (alt > 70.0 and rng.random() < 0.5):
                gam = -gam
            hold = rng.uniform(4.0, 10.0)
            m.gamma.add_step(t, 2.0, gam)
            m.gamma.add_step(t + 2.0 + hold, 2.0, -gam)
            alt += speed * math.sin(gam) * (hold + 2.0)
            t += hold + 4.0
        t += rng.uniform(2.0, 8.0)  # straight leg


def _car_random(ctx: _Ctx, m: PathMotion, t: float, t_end: float) -> None:
    """Random drive: accelerate from rest, turns at 1.5-3.5 m/s^2 lateral, speed changes, stops."""
    rng = ctx.rng
    speed = 0.0
    while t < t_end:
        if speed == 0.0:
            target = rng.uniform(8.0, 20.0)
            t = _speed_change(m.speed, t, target, rng.uniform(1.5, 3.5), 0.5)
            speed = target
        else:
            r = rng.random()
            if r < 0.5:
                dpsi = rng.uniform(30.0, 120.0) * _DEG * rng.choice([-1.0, 1.0])
                t = _turn(m.course, t, dpsi, rng.uniform(1.5, 3.5) / speed, 1.0)
            elif r < 0.75:
                target = rng.uniform(8.0, 20.0)
                t = _speed_change(m.speed, t, target - speed, rng.uniform(1.0, 3.0), 0.5)
                speed = target
            else:
                t = _speed_change(m.speed, t, -speed, rng.uniform(2.0, 6.0), 0.3)
                speed = 0.0
        t += rng.uniform(2.0, 8.0)


def _mr_move(
    m: AxisMotion, t: float, d: np.ndarray, accel: float, speed: float, hold: float, decel: float, ramp: float
) -> tuple[float, np.ndarray]:
    """Move along unit vector ``d``: accelerate to ``speed``, hold, stop; return (end time, displacement).

    A velocity change made of one symmetric pulse covers exactly ``dv * (its duration) / 2``.
    """
    t1 = t + speed / accel + ramp
    t2 = t1 + hold
    t3 = t2 + speed / decel + ramp
    for i in range(3):
        if d[i] != 0.0:
            m.vel[i].add_pulse(t, t1 - ramp, ramp, accel * d[i])
            m.vel[i].add_pulse(t2, t3 - ramp, ramp, -decel * d[i])
    return t3, d * speed * (0.5 * (t1 - t) + hold + 0.5 * (t3 - t2))


def _mr_random(ctx: _Ctx, m: AxisMotion, t: float, t_end: float, pos: np.ndarray, kw: dict) -> None:
    """Aggressive translations (accelerations ``accel_mps2`` range in random directions), stops, yaw turns."""
    rng = ctx.rng
    a_lo, a_hi = kw["accel_mps2"]
    v_lo, v_hi = kw["speed_mps"]
    while t < t_end:
        if kw["yaw_turns"] and rng.random() < 0.3:
            dpsi = rng.uniform(45.0, 180.0) * _DEG * rng.choice([-1.0, 1.0])
            t = _turn(m.yaw, t, dpsi, rng.uniform(30.0, 90.0) * _DEG, 0.5)
        r_h = math.hypot(pos[0], pos[1])
        az = (
            math.atan2(-pos[1], -pos[0]) + rng.uniform(-1.0, 1.0)
            if r_h > 40.0
            else rng.uniform(0.0, 2 * math.pi)
        )
        dz = rng.uniform(-0.3, 0.3)
        d = np.array([math.sqrt(1 - dz * dz) * math.cos(az), math.sqrt(1 - dz * dz) * math.sin(az), dz])
        accel, decel, speed = rng.uniform(a_lo, a_hi), rng.uniform(a_lo, a_hi), rng.uniform(v_lo, v_hi)
        hold = rng.uniform(0.5, 3.0)
        probe = AxisMotion()
        _, disp = _mr_move(probe, 0.0, d, accel, speed, hold, decel, kw["ramp_s"])
        if not -40.0 <= pos[2] + disp[2] <= -3.0:  # keep 3-40 m above home
            d[2] = -d[2]
            if not -40.0 <= pos[2] - disp[2] <= -3.0:
                d[2] = 0.0
                d /= np.linalg.norm(d)
        t, disp = _mr_move(m, t, d, accel, speed, hold, decel, kw["ramp_s"])
        pos = pos + disp
        t += rng.uniform(0.5, 2.0)  # hover


# --------------------------------------------------------------------------- scenarios
def _car_accel_brake(
    ctx: _Ctx, rest_s: float = 5.0, speed_kmh: float = 60.0, accel_s: float = 5.0, cruise_s: float = 20.0,
    brake_mps2: float = 8.0, stop_s: float = 10.0, heading_deg: float = 20.0, grade_deg: float = 0.0,
    turn_deg: float = 0.0, k_pitch: float = 0.0, k_roll: float = 0.0, duration_s: float | None = None,
) -> Plan:  # fmt: skip
    """Car at rest, 0 -> ``speed_kmh`` in exactly ``accel_s`` (0.5 s jerk ramps), cruise (optionally a hill of
    ``grade_deg`` and a turn of ``turn_deg`` at 2 m/s^2 lateral), brake at ``brake_mps2`` to standstill, rest.
    With ``duration_s`` longer than one cycle the cycle repeats. ``k_pitch``/``k_roll`` (rad per m/s^2):
    suspension pitch and roll (default 0)."""
    m = PathMotion()
    m.course.c0 = heading_deg * _DEG
    v = speed_kmh / 3.6
    t = rest_s
    while True:
        ramp = 0.5
        m.speed.add_pulse(t, t + accel_s - ramp, ramp, v / (accel_s - ramp))  # integral = v exactly
        t += accel_s
        if grade_deg:
            m.gamma.add_step(t + 1.0, 2.0, grade_deg * _DEG)
            m.gamma.add_step(t + cruise_s - 3.0, 2.0, -grade_deg * _DEG)
        if turn_deg:
            rate = 2.0 / v
            dur = abs(turn_deg) * _DEG / rate + 1.0
            _turn(m.course, t + 0.5 * (cruise_s - dur), turn_deg * _DEG, rate, 1.0)
        t += cruise_s
        t = _speed_change(m.speed, t, -v, brake_mps2, 0.3) + stop_s
        if duration_s is None or t >= duration_s:
            break
    return Plan(
        m, "car", duration_s if duration_s is not None else t, rule_kw={"k_pitch": k_pitch, "k_roll": k_roll}
    )


def _fixedwing_turns(
    ctx: _Ctx, speed_mps: float = 20.0, bank_deg: float = 30.0, altitude_m: float = 100.0,
    heading_deg: float = 0.0, lead_s: float = 10.0, leg_s: float = 15.0,
    circles: tuple[float, ...] = (1.0, -2.0, 1.0), roll_in_s: float = 1.5, duration_s: float | None = None,
) -> Plan:  # fmt: skip
    """Steady level flight at ``speed_mps``, then coordinated level turns at ``bank_deg`` (turn rate
    ``g tan(bank) / V``) of ``circles`` full circles each (sign: + right, - left), each followed by a
    straight leg of ``leg_s``. With ``duration_s`` the circle pattern repeats until then."""
    m = PathMotion()
    m.speed.c0 = speed_mps
    m.course.c0 = heading_deg * _DEG
    rate = ctx.g * math.tan(bank_deg * _DEG) / speed_mps
    t = lead_s
    while True:
        for n in circles:
            t = _turn(m.course, t, 2.0 * math.pi * n, rate, roll_in_s) + leg_s
        if duration_s is None or t >= duration_s or not circles:
            break
    return Plan(m, "fixedwing", duration_s if duration_s is not None else t, (0.0, 0.0, -altitude_m))


def _multirotor_aggressive(
    ctx: _Ctx, rest_s: float = 3.0, takeoff_alt_m: float = 10.0, accel_mps2: tuple[float, float] = (3.0, 5.0),
    speed_mps: tuple[float, float] = (3.0, 8.0), ramp_s: float = 0.5, yaw_turns: bool = True,
    heading_deg: float = 0.0, duration_s: float = 120.0,
) -> Plan:  # fmt: skip
    """Multirotor on the ground, vertical take-off to ``takeoff_alt_m`` (2 m/s^2, 2 m/s), then random
    translations: accelerate at ``accel_mps2`` (uniform range) along a random direction (up to +-17 deg
    from horizontal) to ``speed_mps``, hold 0.5-3 s, stop at ``accel_mps2``, hover 0.5-2 s; random yaw
    turns (45-180 deg at 30-90 deg/s). Jerk ramps ``ramp_s``. Stays within ~40 m of home, 3-40 m up."""
    m = AxisMotion()
    m.yaw.c0 = heading_deg * _DEG
    # take-off: up at 2 m/s; the hold is chosen so the climb totals takeoff_alt_m
    ramp, a, v = 0.5, 2.0, 2.0
    hold = max(0.0, takeoff_alt_m / v - (v / a + ramp))
    t, disp = _mr_move(m, rest_s, np.array([0.0, 0.0, -1.0]), a, v, hold, a, ramp)
    kw = {"accel_mps2": accel_mps2, "speed_mps": speed_mps, "ramp_s": ramp_s, "yaw_turns": yaw_turns}
    _mr_random(ctx, m, t + 1.0, duration_s, disp, kw)
    return Plan(m, "multirotor", duration_s)


def _gps_outage(
    ctx: _Ctx, vehicle: str = "fixedwing", outage_s: float = 60.0, duration_s: float = 180.0,
    lead_s: float = 10.0, speed_mps: float = 20.0, altitude_m: float = 100.0,
) -> Plan:  # fmt: skip
    """Random manoeuvres of ``vehicle`` ("fixedwing", "car" or "multirotor") from ``lead_s`` on (rest or
    steady level flight before), with a GNSS outage of ``outage_s`` centred in ``duration_s`` (default
    60-120 s; override the window with ``gps_outages=((start, end),)``)."""
    mid = 0.5 * duration_s
    params = {"gps_outages": ((mid - 0.5 * outage_s, mid + 0.5 * outage_s),)}
    if vehicle == "fixedwing":
        m = PathMotion()
        m.speed.c0 = speed_mps
        _fw_random(ctx, m, lead_s, duration_s, speed_mps, altitude_m)
        return Plan(m, "fixedwing", duration_s, (0.0, 0.0, -altitude_m), params=params)
    if vehicle == "car":
        m = PathMotion()
        _car_random(ctx, m, lead_s, duration_s)
        return Plan(m, "car", duration_s, params=params)
    if vehicle == "multirotor":
        plan = _multirotor_aggressive(ctx, rest_s=lead_s, duration_s=duration_s)
        plan.params = params
        return plan
    raise ValueError(f"vehicle must be 'fixedwing', 'car' or 'multirotor', got {vehicle!r}")


def _static(
    ctx: _Ctx, roll_deg: float = 0.0, pitch_deg: float = 0.0, yaw_deg: float = 0.0, duration_s: float = 300.0
) -> Plan:
    """At rest for ``duration_s`` at a fixed attitude (level by default; tilt it for Allan or
    accelerometer-calibration tests)."""
    euler = (roll_deg * _DEG, pitch_deg * _DEG, yaw_deg * _DEG)
    return Plan(AxisMotion(), "fixed", duration_s, rule_kw={"euler_rad": euler})


def _steady(
    ctx: _Ctx, vehicle: str = "fixedwing", speed_mps: float = 20.0, heading_deg: float = 45.0,
    climb_deg: float = 0.0, altitude_m: float | None = None, duration_s: float = 60.0,
) -> Plan:  # fmt: skip
    """Constant velocity for the whole run (speed, course, flight-path angle ``climb_deg``). A car or
    multirotor here is never at rest: use it where a filter is initialised moving."""
    psi, gam = heading_deg * _DEG, climb_deg * _DEG
    alt = altitude_m if altitude_m is not None else (100.0 if vehicle == "fixedwing" else 0.0)
    if vehicle in ("fixedwing", "car"):
        m = PathMotion()
        m.speed.c0, m.course.c0, m.gamma.c0 = speed_mps, psi, gam
        return Plan(m, vehicle, duration_s, (0.0, 0.0, -alt))
    if vehicle == "multirotor":
        a = AxisMotion()
        v = speed_mps * np.array(
            [math.cos(gam) * math.cos(psi), math.cos(gam) * math.sin(psi), -math.sin(gam)]
        )
        for ch, vi in zip(a.vel, v, strict=True):
            ch.c0 = float(vi)
        a.yaw.c0 = psi
        return Plan(a, "multirotor", duration_s, (0.0, 0.0, -alt))
    raise ValueError(f"vehicle must be 'fixedwing', 'car' or 'multirotor', got {vehicle!r}")


SCENARIOS: dict[str, Callable[..., Plan]] = {
    "car_accel_brake": _car_accel_brake,
    "fixedwing_turns": _fixedwing_turns,
    "multirotor_aggressive": _multirotor_aggressive,
    "gps_outage": _gps_outage,
    "static": _static,
    "steady": _steady,
}


# --------------------------------------------------------------------------- driver
def _generators(seed: int) -> list[np.random.Generator]:
    """Independent generators: trajectory, gyro, accel, gnss, mag, IMU time jitter (a child's draws do
    not depend on how many there are: adding one left the others' as they were)."""
    return [np.random.Generator(np.random.PCG64(s)) for s in np.random.SeedSequence(seed).spawn(6)]


def simulate(plan: Plan, params: SimParams | None = None, seed: int = 0, name: str = "custom") -> SimResult:
    """Run the truth and sensor models for a :class:`Plan` (use this for a custom trajectory).

    ``params.g_mps2`` None: WGS84 normal gravity at home. IMU samples at ``t_us = round(k 1e6 / rate)``.
    """
    p = params if params is not None else SimParams()
    if p.g_mps2 is None:
        p = replace(p, g_mps2=normal_gravity(p.home_lat_deg, p.home_alt_m))
    if not (p.imu_rate_hz > 0 and plan.duration_s > 0):
        raise ValueError("imu_rate_hz and duration_s must be > 0")
    if not 0 <= p.imu_time_jitter_us < 0.5e6 / p.imu_rate_hz:
        raise ValueError(f"imu_time_jitter_us must be in [0, half a sample) us, got {p.imu_time_jitter_us}")
    _, rng_gyro, rng_accel, rng_gps, rng_mag, rng_time = _generators(seed)
    n = int(math.floor(plan.duration_s * p.imu_rate_hz + 1e-9)) + 1
    t_us = np.rint(np.arange(n) * (1e6 / p.imu_rate_hz)).astype(np.int64)
    truth = build_truth(plan.motion, plan.rule, t_us, p.g_mps2, plan.pos0_ned_m, plan.rule_kw)
    imu = imu_model(truth, p, rng_gyro, rng_accel)
    if p.imu_time_jitter_us:  # the reported times only: the samples are of the true instants
        j = int(p.imu_time_jitter_us)
        imu["t_us"] = np.maximum(imu["t_us"] + rng_time.integers(-j, j + 1, len(imu)), 0)  # (times >= 0)
    gnss = gnss_model(truth, p, rng_gps)
    mag = mag_model(truth, p, rng_mag)
    ref = np.zeros(n, REF_DTYPE)
    ref["t_us"] = t_us
    ref["q_nb"] = truth.q_nb
    meta = {
        "source": "mcahrs.sim",
        "scenario": name,
        "seed": seed,
        "vehicle": plan.rule,
        "home": {"lat_deg": p.home_lat_deg, "lon_deg": p.home_lon_deg, "alt_m": p.home_alt_m},
        "g_mps2": p.g_mps2,
        "params": p.to_dict(),
        "scenario_params": dict(plan.info),
    }
    rec = Recording(f"sim/{name}", imu, gnss, mag, ref, meta)
    return SimResult(rec, truth, p, name, dict(plan.info), seed)


def scenario(name: str, seed: int = 0, **overrides) -> SimResult:
    """Simulate a named scenario (``SCENARIOS``); see the module docstring for ``overrides``."""
    if name not in SCENARIOS:
        raise ValueError(f"unknown scenario {name!r}; known: {sorted(SCENARIOS)}")
    builder = SCENARIOS[name]
    if "duration" in overrides:
        overrides["duration_s"] = overrides.pop("duration")
    ideal = bool(overrides.pop("ideal", False))
    sim_names = {f.name for f in fields(SimParams)}
    own = inspect.signature(builder).parameters
    p_over = {k: v for k, v in overrides.items() if k in sim_names}
    s_over = {k: v for k, v in overrides.items() if k in own and k != "ctx"}
    unknown = set(overrides) - set(p_over) - set(s_over)
    if unknown:
        valid = sorted(set(own) - {"ctx"}) + ["ideal", "<SimParams fields>"]
        raise TypeError(f"scenario {name!r}: unknown overrides {sorted(unknown)}; valid: {valid}")
    base = SimParams().ideal() if ideal else SimParams()
    base = replace(base, **{k: v for k, v in p_over.items() if k.startswith("home_")})
    g = p_over.get("g_mps2") or normal_gravity(base.home_lat_deg, base.home_alt_m)
    plan = builder(_Ctx(g, _generators(seed)[0]), **s_over)
    plan.info = {
        k: v.default for k, v in own.items() if k != "ctx" and v.default is not inspect.Parameter.empty
    } | s_over
    plan.info["duration_s"] = plan.duration_s
    params = replace(base, **{**plan.params, **p_over, "g_mps2": g})
    return simulate(plan, params, seed, name)

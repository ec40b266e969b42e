"""Simulator: truth trajectories and realistic sensor streams for MCAHRS.

Usage::

    from mcahrs.sim import scenario
    res = scenario("fixedwing_turns", seed=1, gps_rate_hz=10, bank_deg=25)
    res.recording            # mcahrs.samples.Recording: imu, gnss, mag, ref (truth q_nb at IMU rate)
    res.truth.euler_rad      # truth arrays at IMU rate (see Truth)
    res.params.g_mps2        # every sensor parameter used, gravity included

Scenarios (``SCENARIOS``): ``car_accel_brake``, ``fixedwing_turns``, ``multirotor_aggressive``,
``gps_outage``, ``static``, ``steady``. Overrides: any :class:`SimParams` field, the scenario's
own arguments (see its builder in :mod:`mcahrs.sim.scenarios`), ``duration_s`` (alias
``duration``) and ``ideal=True`` (all sensor errors off).

Modules: :mod:`~mcahrs.sim.profiles` (smooth profiles with exact derivatives),
:mod:`~mcahrs.sim.truth` (motions, vehicle attitude rules, truth arrays),
:mod:`~mcahrs.sim.sensors` (IMU / GNSS / magnetometer models, gravity, geodesy),
:mod:`~mcahrs.sim.scenarios` (named scenarios and the driver), :mod:`~mcahrs.sim.faults` (GNSS
faults at fixed times).
"""

from mcahrs.sim.faults import with_gnss_faults
from mcahrs.sim.profiles import Channel
from mcahrs.sim.scenarios import SCENARIOS, Plan, SimResult, scenario, simulate
from mcahrs.sim.sensors import (
    SimParams,
    gauss_markov,
    ned_to_geodetic,
    ned_to_geodetic_wgs84,
    normal_gravity,
)
from mcahrs.sim.truth import AxisMotion, PathMotion, Truth, euler_to_quat, quat_to_euler

__all__ = [
    "SCENARIOS",
    "AxisMotion",
    "Channel",
    "PathMotion",
    "Plan",
    "SimParams",
    "SimResult",
    "Truth",
    "euler_to_quat",
    "gauss_markov",
    "ned_to_geodetic",
    "ned_to_geodetic_wgs84",
    "normal_gravity",
    "quat_to_euler",
    "scenario",
    "simulate",
    "with_gnss_faults",
]

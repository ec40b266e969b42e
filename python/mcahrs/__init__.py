"""MCAHRS: GPS-aided maneuver-compensated attitude estimation for small-UAV autopilots.

The flight code is the float32 C core (c_core/); :mod:`mcahrs.core` drives that exact code
through cffi. :mod:`mcahrs.golden` is an independent float64 NumPy model of the same
equations, :mod:`mcahrs.io` reads streams, files and recorded logs, :mod:`mcahrs.sim`
simulates vehicles and sensors with truth.
"""

__version__ = "0.1.0"

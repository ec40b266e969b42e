"""Recording loaders: turn a recorded log into a :class:`mcahrs.samples.Recording`.

``load(path)`` picks the loader from the path:

* a ``.ulg`` file -> :func:`load_ulog` (PX4 ULog, via pyulog);
* a folder with ``processed_log/IMU`` (or holding exactly one such segment) -> :func:`load_comma2k19`;
* an ``imu_<id>.csv`` with ``imu_<id>.csv.tag`` beside it, that ``.tag``, a ``gnss_<id>*.pos``, or a
  folder holding them -> :func:`load_rtklib_car`.

Every loader returns IMU in body FRD and SI units, GNSS as ``GNSS_DTYPE`` (validity time ``t_us``,
arrival ``t_rx_us``, both on the IMU clock), magnetometer and reference attitude where the
recording has them, and a ``meta`` dict saying what was assumed. Malformed or incomplete input
raises :class:`LoaderError` (a ``ValueError``) naming the file and the field.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mcahrs.samples import Recording

from ._common import LoaderError
from .comma2k19 import find_segment, load_comma2k19
from .rtklib_car import find_car_files, load_rtklib_car
from .ulog import load_ulog

__all__ = ["LoaderError", "load", "load_comma2k19", "load_rtklib_car", "load_ulog"]


def _is_car(path: Path) -> bool:
    try:
        find_car_files(path)
    except LoaderError:
        return False
    return True


def _is_comma(path: Path) -> bool:
    try:
        find_segment(path)
    except LoaderError:
        return False
    return True


def load(path: str | Path, **kwargs: Any) -> Recording:
    """Load a recording, choosing the loader from the file type or folder layout.

    Keyword arguments go to the chosen loader. Raises :class:`LoaderError` if nothing matches.
    """
    p = Path(path)
    if not p.exists():
        raise LoaderError(f"{p}: no such file or folder")
    if p.is_file() and p.suffix.lower() in (".ulg", ".ulog"):
        return load_ulog(p, **kwargs)
    if p.is_file() and (p.suffix.lower() in (".csv", ".pos") or p.name.endswith(".csv.tag")):
        return load_rtklib_car(p, **kwargs)
    if p.is_dir():
        if _is_comma(p):
            return load_comma2k19(p, **kwargs)
        if _is_car(p):
            return load_rtklib_car(p, **kwargs)
        ulgs = sorted(p.glob("*.ulg"))
        if len(ulgs) == 1:
            return load_ulog(ulgs[0], **kwargs)
    raise LoaderError(
        f"{p}: not a recognised recording "
        "(.ulg file, comma2k19 segment folder, or imu_*.csv + .tag + gnss_*.pos)"
    )

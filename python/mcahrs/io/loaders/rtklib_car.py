"""RTKLIB-logged IMU CSV + str2str time tags + RTKLIB .pos solution -> :class:`~mcahrs.samples.Recording`.

The layout of ``data/car/`` (rtklibexplorer GNSS_IMU drive): ``imu_<id>.csv``, ``imu_<id>.csv.tag``
and ``gnss_<id>*.pos``. See ``data/car/README.md``.

**IMU CSV**: rows ``acc_x, acc_y, acc_z [g], gyro_x, gyro_y, gyro_z [deg/s], tick [ms]`` in the
sensor frame. Body FRD = ``C_sb @ sensor`` with ``C_sb = R1(roll) R2(pitch) R3(yaw)`` (the ZYX
Euler direction-cosine matrix of ``mounting_rpy_deg``; upstream's ``Euler_to_CTM(imu_misalign)``),
default ``(180, 0, 180) + (0, -6.79, 5.35)`` deg from the README. Accelerations are scaled by
standard gravity (the sensor's "g").

**Time**: the ``.tag`` file (RTKLIB str2str) is a 60-byte text header, ``uint32 tick_f``,
``uint32 time`` + ``double sec`` (GPST at file open, RTKLIB counts GPST as Unix-like seconds), then
``(uint32 tick_ms_since_open, uint32 file_pos)`` records: at ``tick`` the CSV had grown to
``file_pos`` bytes. Each CSV row's arrival time is the first record whose ``file_pos`` covers the
row's last byte. A straight line fitted (least squares, outliers > 4 sigma dropped) to arrival time
against device tick gives GPST for every row; ``imu_time_offset_s`` (default -0.125 s, upstream's
logging-delay correction) is added. If the CSV lost its CR bytes (a CRLF file checked out with LF
line ends), positions are corrected by one byte per line; this is detected from the file size.

**Clock**: ``t_us`` is GPST in microseconds since the start of the GPS week of the tag file's
open time (so ``t_us / 1e6`` is GPS time of week), for IMU and GNSS alike.

**GNSS (.pos)**: columns by header name. Calendar (``yyyy/mm/dd hh:mm:ss.sss``) or week/TOW time in
GPST (UTC converted with leap seconds); lat/lon/height (deg, ellipsoidal m) or ECEF x/y/z.
``vd = -vu``; ``h_acc = hypot(sdn, sde)``, ``v_acc = sdu``, ``s_acc = hypot(sdvn, sdve)``.
Q: 1 fix -> 6, 2 float -> 5, 3 SBAS -> 4, 4 DGPS -> 4, 5 single -> 3, 6 PPP -> 3, 7 DR -> 1.
``t_rx_us = t_us`` (a post-processed solution has no arrival time).
"""

from __future__ import annotations

import datetime as _dt
import struct
from pathlib import Path

import numpy as np

from mcahrs.samples import GNSS_DTYPE, GNSS_HAS_ALT, GNSS_HAS_VEL_D, GNSS_HAS_VEL_NE, Recording

from ._common import (
    GPS_EPOCH_UNIX_S,
    SECONDS_PER_WEEK,
    LoaderError,
    deg_to_e7,
    gps_minus_utc_s,
    imu_array_from,
    m_to_mm,
    need,
    rate_stats,
)

#: Mounting (roll, pitch, yaw) in degrees from data/car/README.md: [180, 0, 180] + [0, -6.79, 5.35].
README_MOUNTING_RPY_DEG = (180.0, -6.79, 185.35)
#: Upstream's logging-delay correction added to the IMU time (s).
README_IMU_TIME_OFFSET_S = -0.125
STANDARD_GRAVITY = 9.80665

_TAG_HEADER_LEN = 60
_TAG_RECORD = np.dtype([("tick_ms", "<u4"), ("fpos", "<u4")])
_Q_TO_FIX = {1: 6, 2: 5, 3: 4, 4: 4, 5: 3, 6: 3, 7: 1}


def euler_to_ctm(rpy_deg: tuple[float, float, float]) -> np.ndarray:
    """ZYX Euler DCM ``R1(roll) R2(pitch) R3(yaw)``: maps original-frame vectors into the rotated frame."""
    r, p, y = np.deg2rad(rpy_deg)
    sr, cr, sp, cp, sy, cy = np.sin(r), np.cos(r), np.sin(p), np.cos(p), np.sin(y), np.cos(y)
    return np.array(
        [
            [cp * cy, cp * sy, -sp],
            [-cr * sy + sr * sp * cy, cr * cy + sr * sp * sy, sr * cp],
            [sr * sy + cr * sp * cy, -sr * cy + cr * sp * sy, cr * cp],
        ]
    )


def find_car_files(path: str | Path) -> tuple[Path, Path, Path]:
    """(imu csv, tag, pos) for a folder, an ``imu_<id>.csv``, its ``.tag`` or a ``gnss_<id>*.pos`` path."""
    path = Path(path)
    if path.is_dir():
        csvs = sorted(path.glob("imu_*.csv"))
        csvs = [c for c in csvs if c.with_name(c.name + ".tag").is_file()]
        need(len(csvs) == 1, path, f"expected one imu_*.csv with a .tag beside it, found {len(csvs)}")
        csv = csvs[0]
    elif path.name.endswith(".csv.tag"):
        csv = path.with_name(path.name[: -len(".tag")])
    elif path.suffix == ".pos":
        ident = path.stem.split("_")[1] if path.stem.startswith("gnss_") and "_" in path.stem else ""
        csv = path.with_name(f"imu_{ident}.csv")
    else:
        csv = path
    tag = csv.with_name(csv.name + ".tag")
    need(csv.is_file(), csv, "IMU CSV file not found")
    need(tag.is_file(), tag, "time-tag file not found (expected beside the IMU CSV)")
    if path.suffix == ".pos":
        pos = path
    else:
        ident = csv.stem[len("imu_") :] if csv.stem.startswith("imu_") else csv.stem
        poss = sorted(csv.parent.glob(f"gnss_{ident}*.pos"))
        need(len(poss) >= 1, csv.parent, f"no gnss_{ident}*.pos solution file beside {csv.name}")
        pos = poss[0]
    return csv, tag, pos


def read_tag(tag: Path) -> tuple[float, np.ndarray]:
    """Parse a str2str time-tag file: (GPST Unix-like seconds at file open, records array)."""
    raw = tag.read_bytes()
    hdr_len = _TAG_HEADER_LEN + 16
    need(len(raw) >= hdr_len, tag, f"too short for the {hdr_len}-byte header ({len(raw)} bytes)")
    need(raw.startswith(b"TIMETAG RTKLIB"), tag, "header does not start with 'TIMETAG RTKLIB'")
    need(
        (len(raw) - hdr_len) % _TAG_RECORD.itemsize == 0,
        tag,
        f"record area of {len(raw) - hdr_len} bytes is not a multiple of {_TAG_RECORD.itemsize}",
    )
    (time_time,) = struct.unpack_from("<I", raw, _TAG_HEADER_LEN + 4)
    (time_sec,) = struct.unpack_from("<d", raw, _TAG_HEADER_LEN + 8)
    need(0.0 <= time_sec < 1.0, tag, f"header field 'sec' = {time_sec} is not a fraction of a second")
    rec = np.frombuffer(raw, _TAG_RECORD, offset=hdr_len)
    need(rec.size > 0, tag, "no time-tag records")
    need(bool(np.all(np.diff(rec["tick_ms"].astype(np.int64)) >= 0)), tag, "tick field goes backwards")
    need(bool(np.all(np.diff(rec["fpos"].astype(np.int64)) >= 0)), tag, "file-position field goes backwards")
    return float(time_time) + time_sec, rec


def _read_imu_csv(csv: Path) -> tuple[np.ndarray, np.ndarray, int]:
    """(values (N,7), end byte offset of each row in the file as stored, number of LF-only line ends)."""
    raw = csv.read_bytes()
    lines = raw.split(b"\n")
    ends = np.cumsum([len(x) + 1 for x in lines]) - 1  # offset of each '\n' (last piece: past EOF)
    ends[-1] = len(raw) - 1
    rows, row_ends = [], []
    bad_mid = []
    for i, line in enumerate(lines):
        s = line.strip()
        if not s:
            continue
        parts = s.split(b",")
        try:
            vals = [float(p) for p in parts] if len(parts) == 7 else None
        except ValueError:
            vals = None
        if vals is None:
            if 0 < i < len(lines) - 2:
                bad_mid.append(i + 1)
            continue  # a partial first/last line of a captured stream is expected
        rows.append(vals)
        row_ends.append(ends[i] + 1)
    need(not bad_mid, csv, f"malformed rows (need 7 numeric fields) at lines {bad_mid[:5]}")
    need(len(rows) >= 2, csv, "fewer than 2 IMU rows")
    n_lf_only = raw.count(b"\n") - raw.count(b"\r\n")
    return np.asarray(rows, np.float64), np.asarray(row_ends, np.int64), n_lf_only


def _fit_clock(tick_ms: np.ndarray, arrival_s: np.ndarray) -> tuple[np.ndarray, dict]:
    """Least-squares line arrival = a + b (tick - tick0), refitted once without > 4 sigma outliers."""
    x = (tick_ms - tick_ms[0]) * 1e-3
    use = np.isfinite(arrival_s)
    coef = np.zeros(2)
    for _ in range(2):
        a = np.stack([np.ones(use.sum()), x[use]], axis=1)
        coef = np.linalg.lstsq(a, arrival_s[use], rcond=None)[0]
        res = arrival_s - (coef[0] + coef[1] * x)
        sig = np.std(res[use])
        use &= np.abs(res) <= 4 * sig + 1e-9
    res = arrival_s[use] - (coef[0] + coef[1] * x[use])
    info = {
        "offset_s": float(coef[0]),
        "rate": float(coef[1]),
        "rate_error_ppm": float((coef[1] - 1.0) * 1e6),
        "residual_std_ms": float(np.std(res) * 1e3),
        "residual_max_ms": float(np.abs(res).max() * 1e3),
        "rows_used": int(use.sum()),
    }
    return coef[0] + coef[1] * x, info


def _parse_pos(pos: Path, week: int) -> tuple[np.ndarray, dict]:
    header: list[str] | None = None
    data_lines: list[tuple[int, list[str]]] = []
    with pos.open("r", encoding="ascii", errors="replace") as fh:
        for lineno, line in enumerate(fh, 1):
            if line.startswith("%"):
                toks = line[1:].split()
                if toks and any(t.startswith(("latitude", "x-ecef")) for t in toks):
                    header = toks
                continue
            if line.strip():
                data_lines.append((lineno, line.split()))
    need(header is not None, pos, "no '%' column header naming latitude(...) or x-ecef(...)")
    assert header is not None
    timesys = header[0]
    need(timesys in ("GPST", "UTC"), pos, f"time system {timesys!r} not supported (GPST or UTC)")
    names = [h.split("(")[0] for h in header[1:]]
    need(bool(data_lines), pos, "no solution rows")
    ncol = 2 + len(names)
    col = {nm: 2 + i for i, nm in enumerate(names)}
    rows = []
    for lineno, toks in data_lines:
        need(
            len(toks) == ncol,
            pos,
            f"line {lineno}: {len(toks)} fields, header says {ncol} "
            "(degree-minute-second output is not supported)",
        )
        rows.append(toks)
    calendar = "/" in rows[0][0]
    try:
        vals = np.array([[float(t) for t in r[2:]] for r in rows])
        if calendar:
            secs = np.array(
                [
                    _dt.datetime.strptime(f"{r[0]} {r[1]}", "%Y/%m/%d %H:%M:%S.%f")
                    .replace(tzinfo=_dt.timezone.utc)
                    .timestamp()
                    for r in rows
                ]
            )
        else:
            secs = np.array([GPS_EPOCH_UNIX_S + int(r[0]) * SECONDS_PER_WEEK + float(r[1]) for r in rows])
    except ValueError as exc:
        raise LoaderError(f"{pos}: unparsable number or time ({exc})") from exc
    info: dict = {"pos_time_system": timesys}
    if timesys == "UTC":
        leap = gps_minus_utc_s(float(secs[0]), str(pos))
        secs = secs + leap
        info["pos_leap_s_added"] = leap
    tow = secs - GPS_EPOCH_UNIX_S - week * SECONDS_PER_WEEK

    def get(name: str) -> np.ndarray | None:
        return vals[:, col[name] - 2] if name in col else None

    if "latitude" in col:
        lat, lon, hgt = get("latitude"), get("longitude"), get("height")
        need(lon is not None and hgt is not None, pos, "header has latitude but no longitude/height")
    elif "x-ecef" in col:
        import pymap3d

        x, y, z = get("x-ecef"), get("y-ecef"), get("z-ecef")
        need(y is not None and z is not None, pos, "header has x-ecef but no y-ecef/z-ecef")
        lat, lon, hgt = pymap3d.ecef2geodetic(x, y, z)
    else:  # pragma: no cover - excluded by the header search above
        raise LoaderError(f"{pos}: no position columns")
    need("Q" in col, pos, "no Q (solution quality) column")
    n = vals.shape[0]
    out = np.zeros(n, GNSS_DTYPE)
    out["t_us"] = np.round(tow * 1e6).astype(np.int64)
    out["t_rx_us"] = out["t_us"]
    out["lat_e7"] = deg_to_e7(np.asarray(lat), str(pos), "latitude", 90.0)
    out["lon_e7"] = deg_to_e7(np.asarray(lon), str(pos), "longitude", 180.0)
    out["alt_mm"] = m_to_mm(np.asarray(hgt), str(pos), "height")
    flags = np.full(n, GNSS_HAS_ALT, np.uint8)
    vel = np.full((n, 3), np.nan)
    vn, ve, vu = get("vn"), get("ve"), get("vu")
    if vn is not None and ve is not None:
        vel[:, 0], vel[:, 1] = vn, ve
        flags |= GNSS_HAS_VEL_NE
    if vu is not None:
        vel[:, 2] = -vu  # NED down = -up
        flags |= GNSS_HAS_VEL_D
    out["vel_ned_mps"] = vel
    out["flags"] = flags
    out["speed_mps"] = out["course_rad"] = np.nan
    sdn, sde, sdu, sdvn, sdve = get("sdn"), get("sde"), get("sdu"), get("sdvn"), get("sdve")
    out["h_acc_m"] = np.hypot(sdn, sde) if sdn is not None and sde is not None else np.nan
    out["v_acc_m"] = sdu if sdu is not None else np.nan
    out["s_acc_mps"] = np.hypot(sdvn, sdve) if sdvn is not None and sdve is not None else np.nan
    q = get("Q")
    assert q is not None
    out["fix_type"] = [_Q_TO_FIX.get(int(v), 0) for v in q]
    ns = get("ns")
    out["num_sv"] = np.clip(ns, 0, 255).astype(np.uint8) if ns is not None else 0
    good = out["fix_type"] > 0
    info["pos_dropped_no_solution"] = int((~good).sum())
    out = out[good]
    order = np.argsort(out["t_us"], kind="stable")
    out = out[order]
    need(bool(np.all(np.diff(out["t_us"]) > 0)), pos, "duplicate epochs")
    info["pos_q_counts"] = {int(k): int(v) for k, v in zip(*np.unique(q, return_counts=True), strict=True)}
    return out, info


def load_rtklib_car(
    path: str | Path,
    *,
    mounting_rpy_deg: tuple[float, float, float] = README_MOUNTING_RPY_DEG,
    imu_time_offset_s: float = README_IMU_TIME_OFFSET_S,
    g_unit_mps2: float = STANDARD_GRAVITY,
) -> Recording:
    """Load an RTKLIB-logged IMU CSV with its ``.tag`` and the matching ``gnss_*.pos`` solution.

    ``path`` is the folder, the CSV, its ``.tag`` or the ``.pos`` file (see :func:`find_car_files`).
    """
    csv, tag, pos = find_car_files(path)
    t_open_gpst, rec = read_tag(tag)
    vals, row_end, n_lf_only = _read_imu_csv(csv)
    size = csv.stat().st_size
    last = int(rec["fpos"][-1])
    if last == size:
        crlf_fix = False
    elif last == size + n_lf_only:
        crlf_fix = True  # the tags count the CR bytes the checked-out file no longer has
    elif last < size:
        crlf_fix = False  # tags stop early (stream closed before the last write was tagged)
    else:
        raise LoaderError(
            f"{tag}: last file position {last} fits neither {csv.name} ({size} bytes) nor its CRLF form "
            f"({size + n_lf_only} bytes)"
        )
    if crlf_fix:
        raw = csv.read_bytes()
        lf = np.frombuffer(raw, np.uint8) == 10
        cr_before = np.zeros_like(lf)
        cr_before[1:] = np.frombuffer(raw, np.uint8)[:-1] == 13
        lf_only_cum = np.cumsum(lf & ~cr_before)
        row_end = row_end + lf_only_cum[np.minimum(row_end - 1, len(raw) - 1)]
    k = np.searchsorted(rec["fpos"].astype(np.int64), row_end, side="left")
    arrival = np.full(row_end.size, np.nan)
    ok = k < rec.size
    arrival[ok] = rec["tick_ms"][k[ok]] * 1e-3
    need(int(ok.sum()) >= 2, tag, f"file positions cover fewer than 2 rows of {csv.name}")

    tick = vals[:, 6]
    need(bool(np.all(np.diff(tick) > 0)), csv, "device tick (column 6) is not strictly increasing")
    since_open, clock = _fit_clock(tick, arrival)
    week = int((t_open_gpst - GPS_EPOCH_UNIX_S) // SECONDS_PER_WEEK)
    tow_open = t_open_gpst - GPS_EPOCH_UNIX_S - week * SECONDS_PER_WEEK
    t_us = np.round((tow_open + since_open + imu_time_offset_s) * 1e6).astype(np.int64)
    need(bool(np.all(np.diff(t_us) > 0)), csv, "mapped IMU times are not strictly increasing")

    c_sb = euler_to_ctm(mounting_rpy_deg)
    acc_b = (vals[:, 0:3] * g_unit_mps2) @ c_sb.T
    gyr_b = np.deg2rad(vals[:, 3:6]) @ c_sb.T
    imu = imu_array_from(t_us, gyr_b, acc_b, str(csv))

    gnss, pos_info = _parse_pos(pos, week)
    week_start = _dt.datetime(1980, 1, 6, tzinfo=_dt.timezone.utc) + _dt.timedelta(weeks=week)
    # Static start (the README: the car stands still at the start): levelled-accelerometer tilt.
    t0 = imu["t_us"][0]
    first = imu["accel_mps2"][imu["t_us"] < t0 + 5_000_000].mean(axis=0)
    meta: dict = {
        "source": "rtklib_car",
        "files": {"imu": csv.name, "tag": tag.name, "pos": pos.name},
        "time_base": f"GPST microseconds since the start of GPS week {week} "
        f"({week_start:%Y-%m-%d} 00:00:00 GPST); t_us / 1e6 is GPS time of week",
        "gps_week": week,
        "tag_open_gpst": _dt.datetime.fromtimestamp(t_open_gpst, _dt.timezone.utc).strftime(
            "%Y-%m-%d %H:%M:%S.%f"
        ),
        "tag_tick_f_ms": int(struct.unpack_from("<I", tag.read_bytes(), _TAG_HEADER_LEN)[0]),
        "tag_crlf_corrected": crlf_fix,
        "imu_clock_fit": clock,
        "imu_time_offset_s": imu_time_offset_s,
        "imu_time_model": "t = GPST(tag open) + fitted arrival(device tick) + imu_time_offset_s",
        "mounting_rpy_deg": tuple(float(a) for a in mounting_rpy_deg),
        "C_sensor_to_body": c_sb.round(9).tolist(),
        "imu_units_in": "accel g (x g_unit_mps2), gyro deg/s, sensor frame",
        "g_unit_mps2": g_unit_mps2,
        "imu_frame": "body FRD after the mounting rotation",
        "lever_arm_m_frd": {"imu": (0.0, 0.0, -0.65), "gnss_antenna": (0.0, -0.05, -0.65)},
        "static_start_5s": {
            "mean_accel_mps2": first.tolist(),
            "norm_mps2": float(np.linalg.norm(first)),
            "roll_deg": float(np.degrees(np.arctan2(-first[1], -first[2]))),
            "pitch_deg": float(np.degrees(np.arctan2(first[0], np.hypot(first[1], first[2])))),
        },
        "gnss_notes": "post-processed RTKLIB solution: t_rx_us = t_us; vd = -vu; h_acc = hypot(sdn, sde); "
        "s_acc = hypot(sdvn, sdve); speed/course not given (NaN)",
        "reference": "none: this recording has no reference attitude",
        **pos_info,
    }
    meta["imu"] = rate_stats(imu["t_us"])
    meta["gnss"] = rate_stats(gnss["t_us"])
    return Recording(f"car/{csv.stem}", imu, gnss, meta=meta)

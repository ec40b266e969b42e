"""Python face of the C core: the exact float32 code that flies, through cffi (API mode).

The cffi module is private; this module checks dtypes and shapes, maps status codes to
:mod:`mcahrs.errors` exceptions, and owns the C state. Sizes and struct layouts are read
from the compiled C (``ffi.sizeof``, ``ffi.typeof(...).fields``), never repeated here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from mcahrs import errors
from mcahrs._mcahrs_cffi import ffi, lib
from mcahrs.samples import GNSS_HAS_ALT, GNSS_HAS_VEL_D, GNSS_HAS_VEL_NE, Recording

_STATUS_ERRORS: dict[int, type[errors.McaError]] = {
    lib.MCA_ERR_NULL: errors.NullError,
    lib.MCA_ERR_BAD_DT: errors.BadDtError,
    lib.MCA_ERR_NONFINITE: errors.NonFiniteError,
    lib.MCA_ERR_SINGULAR: errors.SingularError,
    lib.MCA_ERR_BAD_MASK: errors.BadMaskError,
    lib.MCA_ERR_BAD_ARG: errors.BadArgError,
    lib.MCA_ERR_BAD_CONFIG: errors.BadConfigError,
    lib.MCA_ERR_TIME_BACKWARDS: errors.TimeBackwardsError,
    lib.MCA_ERR_RANGE: errors.RangeError,
    lib.MCA_ERR_NOT_INIT: errors.NotInitError,
}

STATUS_NAMES: dict[int, str] = {0: "OK", **{k: v.__name__ for k, v in _STATUS_ERRORS.items()}}


def check(status: int, what: str) -> None:
    """Raise the exception of a C status code (no-op for MCA_OK)."""
    if status != lib.MCA_OK:
        exc = _STATUS_ERRORS.get(status, errors.McaError)
        raise exc(f"{what}: status {status} ({exc.__name__})")


# ---------------------------------------------------------------- struct <-> NumPy

_PRIMS = {
    "float": np.float32,
    "double": np.float64,
    "uint8_t": np.uint8,
    "int8_t": np.int8,
    "uint16_t": np.uint16,
    "int16_t": np.int16,
    "uint32_t": np.uint32,
    "int32_t": np.int32,
    "uint64_t": np.uint64,
    "int64_t": np.int64,
    "int": np.intc,
    "size_t": np.uintp,
}


def _ctype_dtype(t: Any) -> np.dtype:
    if t.kind == "primitive":
        return np.dtype(_PRIMS[t.cname])
    if t.kind == "enum":
        return np.dtype(np.intc)
    if t.kind == "array":
        return np.dtype((_ctype_dtype(t.item), (t.length,)))
    if t.kind == "struct":
        return struct_dtype(t.cname)
    raise TypeError(f"no NumPy dtype for C type {t.cname}")


def struct_dtype(cname: str) -> np.dtype:
    """NumPy structured dtype with the exact layout (offsets, size) of a C struct."""
    t = ffi.typeof(cname)
    names, formats, offsets = [], [], []
    for name, field in t.fields:
        names.append(name)
        formats.append(_ctype_dtype(field.type))
        offsets.append(field.offset)
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": ffi.sizeof(t)})


def _as_f32(x: Any, shape: tuple[int, ...], name: str) -> np.ndarray:
    a = np.ascontiguousarray(x, dtype=np.float32)
    if a.shape != shape:
        raise errors.BadArgError(f"{name}: expected shape {shape}, got {a.shape}")
    return a


def _fptr(a: np.ndarray) -> Any:
    return ffi.cast("float *", ffi.from_buffer(a))


def _struct_type(obj: Any) -> Any:
    t = ffi.typeof(obj)
    return t.item if t.kind == "pointer" else t


def _struct_to_dict(obj: Any) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name, field in _struct_type(obj).fields:
        v = getattr(obj, name)
        if field.type.kind == "struct":
            out[name] = _struct_to_dict(v)
        elif field.type.kind == "array":
            out[name] = list(v)
        else:
            out[name] = v
    return out


def _apply(obj: Any, overrides: Mapping[str, Any], where: str) -> None:
    """Set struct fields from a mapping; nested structs by dict or dotted names."""
    fields = dict(_struct_type(obj).fields)
    for key, value in overrides.items():
        head, _, rest = key.partition(".")
        if head not in fields:
            raise errors.BadConfigError(f"{where}: no field {head!r} (known: {', '.join(fields)})")
        if rest:
            _apply(getattr(obj, head), {rest: value}, f"{where}.{head}")
        elif isinstance(value, Mapping):
            _apply(getattr(obj, head), value, f"{where}.{head}")
        else:
            setattr(obj, head, value)


# ---------------------------------------------------------------- CS filter


def cs_config(vertical: bool = False, **overrides: Any) -> Any:
    """A ``mca_cs_config_t`` with the documented defaults (horizontal or vertical) and overrides."""
    cfg = ffi.new("mca_cs_config_t *")
    (lib.mca_cs_config_default_v if vertical else lib.mca_cs_config_default_h)(cfg)
    _apply(cfg, overrides, "mca_cs_config_t")
    check(lib.mca_cs_config_check(cfg), "mca_cs_config_t")
    return cfg


def cs_transition(cfg: Any, t_s: float, s2: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact CS transition Phi and process noise Q (5 x 5, float32) of the C core."""
    phi = np.zeros(25, np.float32)
    q = np.zeros(25, np.float32)
    lib.mca_cs_transition(cfg, t_s, s2, _fptr(phi), _fptr(q))
    return phi.reshape(5, 5), q.reshape(5, 5)


def singer_q(alpha: float, t_s: float, s2: float) -> np.ndarray:
    """The C core's Singer 3 x 3 process noise (float32)."""
    q = np.zeros(9, np.float32)
    lib.mca_cs_singer_q(alpha, t_s, s2, _fptr(q))
    return q.reshape(3, 3)


class Cs3:
    """Three-axis (N, E, D) CS maneuver filter of the C core."""

    def __init__(
        self, cfg_h: Any = None, cfg_v: Any = None, pos_ned_m: Any = None, vel_ned_mps: Any = None
    ) -> None:
        self._cs = ffi.new("mca_cs3_t *")
        self._ws = ffi.new("float[]", lib.MCA_CS_WS_LEN)
        self._rep = ffi.new("mca_update_report_t[3]")
        cfg_h = cfg_h if cfg_h is not None else cs_config(False)
        cfg_v = cfg_v if cfg_v is not None else cs_config(True)
        # the arrays stay referenced until the call returns (a pointer alone does not keep them)
        pa = None if pos_ned_m is None else _as_f32(pos_ned_m, (3,), "pos_ned_m")
        va = None if vel_ned_mps is None else _as_f32(vel_ned_mps, (3,), "vel_ned_mps")
        p = ffi.NULL if pa is None else _fptr(pa)
        v = ffi.NULL if va is None else _fptr(va)
        check(lib.mca_cs3_init(self._cs, cfg_h, cfg_v, p, v), "mca_cs3_init")

    def predict(self, t_s: float) -> None:
        check(lib.mca_cs3_predict(self._cs, t_s), f"mca_cs3_predict(t_s={t_s!r})")

    def predict_aided(
        self, t_s: float, dp_m: Any, dv_mps: Any, acc_var_m2ps4: Any, coast_var_m2ps4: Any = None
    ) -> dict[str, np.ndarray]:
        """Predict with the IMU increments per axis (``mca_cs3_predict_aided``, docs/ALGORITHMS.md 2);
        NaN in ``acc_var`` leaves that axis unaided. ``coast_var``: the part of ``acc_var`` a coast
        accumulates (None: all of it). Returns the test priors ``y`` (3 x 2) and ``S`` (3 x 2 x 2),
        NaN on unaided axes; the next :meth:`update` tests against them."""
        dp, dv, qa = (np.asarray(a, np.float64).reshape(3) for a in (dp_m, dv_mps, acc_var_m2ps4))
        qc = qa if coast_var_m2ps4 is None else np.asarray(coast_var_m2ps4, np.float64).reshape(3)
        incs = [
            ffi.new("mca_cs_inc_t *", {"dp_m": p, "dv_mps": v, "acc_var_m2ps4": q, "coast_var_m2ps4": c})
            for p, v, q, c in zip(dp, dv, qa, qc, strict=True)
        ]
        ptrs = ffi.new("mca_cs_inc_t *[3]", [incs[i] if np.isfinite(qa[i]) else ffi.NULL for i in range(3)])
        check(lib.mca_cs3_predict_aided(self._cs, t_s, ptrs), f"mca_cs3_predict_aided(t_s={t_s!r})")
        y, s = np.full((3, 2), np.nan), np.full((3, 2, 2), np.nan)
        for i in range(3):
            aid = self._cs.axis[i].aid
            if aid.valid:
                y[i] = list(aid.y)
                s[i] = np.array(list(aid.s)).reshape(2, 2)
        return {"y": y, "S": s}

    def update(
        self, pos_ned_m: Any, vel_ned_mps: Any, r_pos_m2: Any, r_vel_m2ps2: Any, mask: Any
    ) -> dict[str, np.ndarray]:
        """Update; returns per-axis ``m``, ``nu`` (3 x 2), ``c`` (3 x 2 x 2), ``t_stat`` (3), and
        the robust outcome ``rejected``, ``alarm``, ``reset`` and ``coasting`` (the update left the
        velocity row out or was rejected: with ``coast`` set the next aided predict coasts,
        ALGORITHMS.md 2) (3, bool)."""
        arrs = [
            _as_f32(a, (3,), n)
            for a, n in (
                (pos_ned_m, "pos_ned_m"),
                (vel_ned_mps, "vel_ned_mps"),
                (r_pos_m2, "r_pos_m2"),
                (r_vel_m2ps2, "r_vel_m2ps2"),
            )
        ]
        m = np.ascontiguousarray(mask, dtype=np.uint8)
        if m.shape != (3,):
            raise errors.BadArgError(f"mask: expected shape (3,), got {m.shape}")
        st = lib.mca_cs3_update(
            self._cs,
            *(_fptr(a) for a in arrs),
            ffi.cast("uint8_t *", ffi.from_buffer(m)),
            self._ws,
            self._rep,
        )
        check(st, "mca_cs3_update")
        out = {
            "m": np.zeros(3, np.int64),
            "nu": np.full((3, 2), np.nan),
            "c": np.full((3, 2, 2), np.nan),
            "t_stat": np.full(3, np.nan),
            **{k: np.zeros(3, bool) for k in ("rejected", "alarm", "reset", "coasting")},
        }
        for i in range(3):
            r = self._rep[i]
            k = r.m
            out["m"][i] = k
            out["rejected"][i], out["alarm"][i], out["reset"][i] = r.rejected != 0, r.alarm != 0, r.reset != 0
            out["coasting"][i] = bool(self._cs.axis[i].aid.out)
            if k:
                out["nu"][i, :k] = list(r.nu)[:k]
                out["c"][i, :k, :k] = np.array(list(r.c)[: k * k]).reshape(k, k)
                out["t_stat"][i] = r.t_stat
        return out

    def run(
        self,
        dt_s: Any,
        pos_ned_m: Any,
        vel_ned_mps: Any,
        r_pos_m2: Any,
        r_vel_m2ps2: Any,
        mask: Any,
        want_p: bool = True,
    ) -> dict[str, np.ndarray]:
        """Many predict(+update) steps in one C call (``mca_cs3_run``).

        ``dt_s`` (n,); the others (n, 3); ``mask`` 0 on every axis means predict only.
        Returns ``x`` (n, 3, 5), ``P`` (n, 3, 5, 5) when ``want_p``, ``T`` (n, 3, NaN where not
        updated) and ``status`` (n,) per step; statuses are not raised.
        """
        dt = np.ascontiguousarray(dt_s, np.float32).reshape(-1)
        n = len(dt)
        arrs = [
            _as_f32(a, (n, 3), name)
            for a, name in (
                (pos_ned_m, "pos_ned_m"),
                (vel_ned_mps, "vel_ned_mps"),
                (r_pos_m2, "r_pos_m2"),
                (r_vel_m2ps2, "r_vel_m2ps2"),
            )
        ]
        m = np.ascontiguousarray(mask, np.uint8)
        if m.shape != (n, 3):
            raise errors.BadArgError(f"mask: expected shape {(n, 3)}, got {m.shape}")
        x = np.zeros((n, 3, 5), np.float32)
        p = np.zeros((n, 3, 5, 5), np.float32) if want_p else None
        t = np.zeros((n, 3), np.float32)
        st = np.zeros(n, np.uint8)
        check(
            lib.mca_cs3_run(
                self._cs,
                n,
                _fptr(dt),
                *(_fptr(a) for a in arrs),
                ffi.cast("uint8_t *", ffi.from_buffer(m)),
                self._ws,
                _fptr(x),
                _fptr(p) if p is not None else ffi.NULL,
                _fptr(t),
                ffi.cast("uint8_t *", ffi.from_buffer(st)),
            ),
            "mca_cs3_run",
        )
        out = {"x": x, "T": t, "status": st}
        if p is not None:
            out["P"] = p
        return out

    @property
    def x(self) -> np.ndarray:
        """States (3 x 5): rows N, E, D; columns p, v, a, eps_p, eps_v."""
        return np.array([list(self._cs.axis[i].x) for i in range(3)], dtype=np.float32)

    @property
    def P(self) -> np.ndarray:  # noqa: N802 - the covariance is P in every text
        """Covariances (3 x 5 x 5)."""
        return np.array([list(self._cs.axis[i].p) for i in range(3)], dtype=np.float32).reshape(3, 5, 5)

    @property
    def s2(self) -> np.ndarray:
        """Maneuver variance used by the last predict, per axis."""
        return np.array([self._cs.axis[i].s2_m2ps4 for i in range(3)], dtype=np.float32)


# ---------------------------------------------------------------- geodesy


def geo_to_ned(home: tuple[int, int, int], lat_e7: Any, lon_e7: Any, alt_mm: Any) -> np.ndarray:
    """NED (float32 m) of integer geodetic points relative to an integer home (C core, ALGORITHMS.md 6)."""
    h = ffi.new("mca_geo_home_t *")
    check(lib.mca_geo_set_home(h, *(int(v) for v in home)), f"mca_geo_set_home{tuple(home)}")
    lat, lon, alt = (np.atleast_1d(np.asarray(v, np.int64)) for v in (lat_e7, lon_e7, alt_mm))
    out = np.zeros((len(lat), 3), np.float32)
    ned = ffi.new("float[3]")
    for k in range(len(lat)):
        check(
            lib.mca_geo_to_ned(h, int(lat[k]), int(lon[k]), int(alt[k]), ned),
            f"mca_geo_to_ned({lat[k]}, {lon[k]}, {alt[k]})",
        )
        out[k] = list(ned)
    return out


def normal_gravity(lat_rad: float, h_m: float) -> float:
    """WGS84 normal gravity of the C core (float32)."""
    return float(lib.mca_geo_gravity(lat_rad, h_m))


# ---------------------------------------------------------------- navigation top level

PRESETS = {
    "ground": lib.mca_nav_config_default,
    "fixedwing": lib.mca_nav_config_fixedwing,
    "multirotor": lib.mca_nav_config_multirotor,
}

FLAG_BITS = {
    "aligned": lib.MCA_FLAG_ALIGNED,
    "home_set": lib.MCA_FLAG_HOME_SET,
    "gps_lost": lib.MCA_FLAG_GPS_LOST,
    "yaw_unobserved": lib.MCA_FLAG_YAW_UNOBSERVED,
    "grav_skipped": lib.MCA_FLAG_GRAV_SKIPPED,
    "saturated": lib.MCA_FLAG_SATURATED,
    "hist_miss": lib.MCA_FLAG_HIST_MISS,
    "alarm_n": lib.MCA_FLAG_ALARM_N,
    "alarm_e": lib.MCA_FLAG_ALARM_N << 1,
    "alarm_d": lib.MCA_FLAG_ALARM_N << 2,
}

IMU_C_DTYPE = struct_dtype("mca_imu_sample_t")
MAG_C_DTYPE = struct_dtype("mca_mag_sample_t")
GPS_C_DTYPE = struct_dtype("mca_gps_event_t")
OUT_C_DTYPE = struct_dtype("mca_nav_output_t")


def nav_config(preset: str = "ground", **overrides: Any) -> Any:
    """A ``mca_nav_config_t`` from a preset and overrides (``cs_h={'tau_a_s': 3}`` or ``'cs_h.tau_a_s'``)."""
    if preset not in PRESETS:
        raise errors.BadConfigError(f"unknown preset {preset!r}; known: {', '.join(PRESETS)}")
    cfg = ffi.new("mca_nav_config_t *")
    PRESETS[preset](cfg)
    _apply(cfg, overrides, "mca_nav_config_t")
    check(lib.mca_nav_config_check(cfg), "mca_nav_config_t")
    return cfg


def config_dict(cfg: Any) -> dict[str, Any]:
    """A configuration struct as a nested dict (for logs and comparison with the golden model)."""
    return _struct_to_dict(cfg)


def gnss_to_c(gnss: np.ndarray) -> np.ndarray:
    """GNSS_DTYPE fixes to ``mca_gps_event_t`` records."""
    ev = np.zeros(len(gnss), GPS_C_DTYPE)
    ev["t_rx_us"] = gnss["t_rx_us"]
    fix = ev["fix"]
    fix["t_us"] = gnss["t_us"]
    fix["lat_e7"] = gnss["lat_e7"]
    fix["lon_e7"] = gnss["lon_e7"]
    fix["alt_mm"] = gnss["alt_mm"]
    # NaN where absent: the C reads a velocity only where flagged, and rejects a flagged NaN
    fix["vel_ned_mps"] = gnss["vel_ned_mps"]
    fix["h_acc_m"] = gnss["h_acc_m"]
    fix["v_acc_m"] = gnss["v_acc_m"]
    fix["s_acc_mps"] = gnss["s_acc_mps"]
    fl = gnss["flags"]
    fix["flags"] = (
        np.where(fl & GNSS_HAS_VEL_NE, lib.MCA_FIX_VEL_NE, 0)
        | np.where(fl & GNSS_HAS_VEL_D, lib.MCA_FIX_VEL_D, 0)
        | np.where(fl & GNSS_HAS_ALT, lib.MCA_FIX_ALT, 0)
    )
    fix["fix_type"] = gnss["fix_type"]
    ev["fix"] = fix
    return ev


def _fill_fix(
    f: Any,
    t_us: int,
    lat_e7: int,
    lon_e7: int,
    alt_mm: int | None,
    vel_ned_mps: Any,
    h_acc_m: float,
    v_acc_m: float,
    s_acc_mps: float,
    fix_type: int,
    vel_d: bool,
) -> None:
    """Fill a ``mca_gps_fix_t`` from keyword values (what ``Nav.gps`` and ``Ins.gps`` take)."""
    f.t_us, f.lat_e7, f.lon_e7 = int(t_us), int(lat_e7), int(lon_e7)
    f.alt_mm = 0 if alt_mm is None else int(alt_mm)
    flags = 0 if alt_mm is None else lib.MCA_FIX_ALT
    if vel_ned_mps is not None:
        f.vel_ned_mps = [float(v) for v in vel_ned_mps]
        flags |= lib.MCA_FIX_VEL_NE | (lib.MCA_FIX_VEL_D if vel_d else 0)
    f.h_acc_m, f.v_acc_m, f.s_acc_mps = h_acc_m, v_acc_m, s_acc_mps
    f.flags, f.fix_type = flags, fix_type


def _run_batch(
    c_replay: Any, state: Any, rec: Recording, out_dtype: np.dtype, what: str
) -> dict[str, np.ndarray]:
    """A recording through a C batch replay (``mca_nav_replay``, ``mca_ins_replay``): the arrays in
    the C layouts, one call, every output field and the per-event statuses as arrays."""
    imu = np.zeros(len(rec.imu), IMU_C_DTYPE)
    imu["t_us"] = rec.imu["t_us"]
    imu["gyro_b_rps"] = rec.imu["gyro_rps"]
    imu["accel_b_mps2"] = rec.imu["accel_mps2"]
    gps = gnss_to_c(rec.gnss)
    mag = np.zeros(len(rec.mag), MAG_C_DTYPE)
    mag["t_us"] = rec.mag["t_us"]
    mag["mag_b"] = rec.mag["mag_b"]
    for name, t in (("imu", imu["t_us"]), ("gnss", gps["t_rx_us"]), ("mag", mag["t_us"])):
        if np.any(np.diff(t.astype(np.int64)) < 0):
            raise errors.BadArgError(f"{rec.name}: {name} samples must be sorted by time")
    out = np.zeros(len(imu), out_dtype)
    st_i = np.zeros(len(imu), np.uint8)
    st_g = np.zeros(len(gps), np.uint8)
    st_m = np.zeros(len(mag), np.uint8)

    def ptr(a: np.ndarray) -> Any:
        return ffi.cast("void *", ffi.from_buffer(a)) if len(a) else ffi.NULL

    check(
        c_replay(
            state,
            ptr(imu),
            len(imu),
            ptr(gps),
            len(gps),
            ptr(mag),
            len(mag),
            ptr(out),
            ptr(st_i),
            ptr(st_g),
            ptr(st_m),
        ),
        what,
    )
    res = {name: out[name] for name in out_dtype.names}
    res.update(imu_status=st_i, gps_status=st_g, mag_status=st_m)
    return res


class Nav:
    """The navigation top level of the C core, one sample at a time or a whole recording."""

    def __init__(self, cfg: Any = None) -> None:
        self.cfg = cfg if cfg is not None else nav_config()
        self._nav = ffi.new("mca_nav_t *")
        self._out = ffi.new("mca_nav_output_t *")
        self._fix = ffi.new("mca_gps_fix_t *")
        self._f3 = [np.zeros(3, np.float32) for _ in range(2)]
        check(lib.mca_nav_init(self._nav, self.cfg), "mca_nav_init")

    def imu(self, t_us: int, gyro_b_rps: Any, accel_b_mps2: Any) -> None:
        g = _as_f32(gyro_b_rps, (3,), "gyro_b_rps")
        a = _as_f32(accel_b_mps2, (3,), "accel_b_mps2")
        check(lib.mca_nav_imu(self._nav, int(t_us), _fptr(g), _fptr(a)), f"mca_nav_imu(t_us={t_us})")

    def gps(
        self,
        t_us: int,
        lat_e7: int,
        lon_e7: int,
        alt_mm: int | None = None,
        vel_ned_mps: Any = None,
        h_acc_m: float = float("nan"),
        v_acc_m: float = float("nan"),
        s_acc_mps: float = float("nan"),
        fix_type: int = 3,
        vel_d: bool = True,
    ) -> None:
        f = self._fix
        _fill_fix(f, t_us, lat_e7, lon_e7, alt_mm, vel_ned_mps, h_acc_m, v_acc_m, s_acc_mps, fix_type, vel_d)
        check(lib.mca_nav_gps(self._nav, f), f"mca_nav_gps(t_us={t_us}, lat_e7={lat_e7}, lon_e7={lon_e7})")

    def mag(self, t_us: int, mag_b: Any) -> None:
        m = _as_f32(mag_b, (3,), "mag_b")
        check(lib.mca_nav_mag(self._nav, int(t_us), _fptr(m)), f"mca_nav_mag(t_us={t_us})")

    def output(self) -> dict[str, Any]:
        lib.mca_nav_output(self._nav, self._out)
        return _struct_to_dict(self._out[0])

    def replay(self, rec: Recording) -> dict[str, np.ndarray]:
        """Run a whole recording (ALGORITHMS.md 9) in one C call; one output row per IMU sample."""
        return _run_batch(lib.mca_nav_replay, self._nav, rec, OUT_C_DTYPE, "mca_nav_replay")


def replay(rec: Recording, cfg: Any = None) -> dict[str, np.ndarray]:
    """Run a recording through a fresh C navigation filter."""
    return Nav(cfg).replay(rec)


# ================================================================ robust and adaptive updates
# (docs/ALGORITHMS.md 5; the C's mca_kf_update). Section owned by the robust-modes work; the
# rest of this module is unchanged by it.

ROBUST_MODES: dict[str, int] = {
    "plain": lib.MCA_ROBUST_PLAIN,
    "fta": lib.MCA_ROBUST_FTA,
    "akf": lib.MCA_ROBUST_AKF,
    "fuzzy": lib.MCA_ROBUST_FUZZY,
    "igg3": lib.MCA_ROBUST_IGG3,
}
"""Mode names of ``robust_config`` and the golden model, with their C values."""

CHI2_LEVELS: dict[float, int] = {
    1e-4: lib.MCA_CHI2_1E4,
    1e-2: lib.MCA_CHI2_1E2,
    5e-3: lib.MCA_CHI2_5E3,
    2.5e-2: lib.MCA_CHI2_2P5E2,
}
"""Upper-tail levels a of the C chi-square table, with their ``mca_chi2_level_t`` values."""

_MODES_WITH_MEMORY = (lib.MCA_ROBUST_AKF, lib.MCA_ROBUST_FUZZY)


def _robust_mode(mode: str | int) -> int:
    if isinstance(mode, str):
        if mode not in ROBUST_MODES:
            raise errors.BadConfigError(f"unknown robust mode {mode!r}; known: {', '.join(ROBUST_MODES)}")
        return ROBUST_MODES[mode]
    if int(mode) not in ROBUST_MODES.values():
        raise errors.BadConfigError(f"unknown robust mode {mode!r}")
    return int(mode)


def robust_config(mode: str | int = "plain", **overrides: Any) -> Any:
    """A checked ``mca_robust_config_t *``: the C defaults, ``mode`` ('plain', 'fta', 'akf', 'fuzzy',
    'igg3' or its number) and field overrides (``akf_window=4``, ``igg_k0=2.0``...)."""
    cfg = ffi.new("mca_robust_config_t *")
    lib.mca_robust_config_default(cfg)
    cfg.mode = _robust_mode(mode)
    _apply(cfg, overrides, "mca_robust_config_t")
    check(lib.mca_robust_config_check(cfg), "mca_robust_config_t")
    return cfg


ROBUST_PROFILES = ("plain", "fta", "akf", "fuzzy", "fuzzy-inflate", "igg3", "fuzzy-rows")
"""The navigation filter's robust set-ups that ``benchmarks/bench_outliers.py`` measures (README,
GNSS outliers): one robust mode on the CS axes (``cs_h``, ``cs_v``) and the attitude filter."""

PROFILE_NUMBERS: dict[str, int] = {
    "plain": lib.MCA_PROFILE_PLAIN,
    "fta": lib.MCA_PROFILE_FTA,
    "akf": lib.MCA_PROFILE_AKF,
    "fuzzy": lib.MCA_PROFILE_FUZZY,
    "fuzzy-inflate": lib.MCA_PROFILE_FUZZY_INFLATE,
    "igg3": lib.MCA_PROFILE_IGG3,
    "fuzzy-rows": lib.MCA_PROFILE_FUZZY_ROWS,
}
"""The C core's ``mca_robust_profile_t`` of each of :data:`ROBUST_PROFILES`."""

ROWS_GUARD_S = 20.0
"""fuzzy-rows' lock-up guard as a time: about as long as a CS axis without an accelerometer-bias
estimate coasts through a fault of both before its variance lets the fault back in."""


def fix_rate_hz(rec: Recording, default: float = 5.0) -> float:
    """The median fix rate of a recording, the rate :func:`robust_profile` takes (``default`` with
    fewer than two fixes at distinct times)."""
    dt = np.diff(rec.gnss["t_us"].astype(np.int64)) * 1e-6
    dt = dt[dt > 0]
    return float(1.0 / np.median(dt)) if dt.size else default


def receiver_model(
    white_h_m: float, white_v_m: float, sigma_h_m: float, sigma_v_m: float, tau_s: float
) -> dict[str, float]:
    """The overrides of :func:`nav_config` (dotted names) that model a receiver's position error
    as white noise plus a Gauss-Markov error (``docs/ALGORITHMS.md`` 8, GPS step 4): the white
    stds ``white_h_m`` / ``white_v_m`` are the position rows' R (below a fix's reported accuracy),
    and the CS axes' GPS-error state carries the correlated part, std ``sigma_h_m`` / ``sigma_v_m``
    with correlation time ``tau_s``. Without it the reported accuracy is taken as white, on top of
    the CS GPS-error state's own default: the correlated part is counted twice and a position jump
    of a few accuracies passes the test. Values are checked by :func:`nav_config`."""
    return {
        "gps_pos_white_m": white_h_m,
        "gps_alt_white_m": white_v_m,
        "cs_h.sigma_p_m": sigma_h_m,
        "cs_v.sigma_p_m": sigma_v_m,
        "cs_h.tau_p_s": tau_s,
        "cs_v.tau_p_s": tau_s,
    }


def robust_profile(name: str, gps_rate_hz: float = 5.0) -> dict[str, int]:
    """The overrides of :func:`nav_config` (dotted names) that set up robust profile ``name``.

    * ``plain``, ``fta``, ``akf``, ``fuzzy``, ``igg3``: that mode, with its defaults
      (``docs/ALGORITHMS.md`` 5), on the CS axes and the attitude filter.
    * ``fuzzy-inflate``: the fuzzy detector inflating instead of rejecting (``fuzzy_reject`` 0).
    * ``fuzzy-rows``: the CS axes leave out only the rows that fail their own test and coast on the
      IMU while the velocity row is out (``fuzzy_reject`` 2, ``coast`` 1), with the whole-update guard at
      :data:`ROWS_GUARD_S` of fixes at ``gps_rate_hz`` (at most 254) and no row guard; the attitude
      filter's one gravity observation takes the fuzzy default, reject.

    Apply other overrides after these: ``nav_config(preset, **{**robust_profile(p), **mine})``.
    Raises BadConfigError for an unknown name or a rate that is not a finite number > 0. The C core
    sets the same fields with ``mca_nav_config_robust_profile`` (the names' numbers:
    :data:`PROFILE_NUMBERS`).
    """
    if name not in ROBUST_PROFILES:
        raise errors.BadConfigError(f"unknown robust profile {name!r}; known: {', '.join(ROBUST_PROFILES)}")
    if not (math.isfinite(gps_rate_hz) and gps_rate_hz > 0.0):
        raise errors.BadConfigError(f"robust profile {name!r}: GNSS rate {gps_rate_hz!r} Hz is not > 0")
    mode = ROBUST_MODES[name.split("-")[0]]
    cs: dict[str, int] = {"robust.mode": mode}
    att: dict[str, int] = {"robust.mode": mode}
    if name == "fuzzy-inflate":
        cs["robust.fuzzy_reject"] = att["robust.fuzzy_reject"] = 0
    elif name == "fuzzy-rows":
        guard = min(254, max(1, math.floor(ROWS_GUARD_S * gps_rate_hz + 0.5)))  # half up, as the C
        cs |= {"robust.fuzzy_reject": 2, "robust.reject_reset_n": guard, "robust.row_reset_n": 0, "coast": 1}
    out = {f"{f}.{k}": v for f in ("cs_h", "cs_v") for k, v in cs.items()}
    return out | {f"att.{k}": v for k, v in att.items()}


class RobustFilterState:
    """Owns one ``mca_robust_state_t`` (the memory AKF and the fuzzy detector keep between the
    updates of one filter), initialised empty by ``mca_robust_state_init``."""

    def __init__(self) -> None:
        self.c = ffi.new("mca_robust_state_t *")
        self.reset()

    def reset(self) -> None:
        lib.mca_robust_state_init(self.c)

    def copy(self) -> RobustFilterState:
        other = RobustFilterState()
        ffi.memmove(other.c, self.c, ffi.sizeof("mca_robust_state_t"))
        return other

    def as_dict(self) -> dict[str, Any]:
        return _struct_to_dict(self.c[0])

    @property
    def q_scale(self) -> float:
        """Factor the owning filter applies to its Q at its next predict (AKF; 1 otherwise)."""
        return float(self.c.q_scale)

    @property
    def d_k(self) -> float:
        return float(self.c.d_k)

    @property
    def alarm(self) -> bool:
        return bool(self.c.alarm)


def _report_dict(rep: Any) -> dict[str, Any]:
    m = int(rep.m)
    return {
        "m": m,
        "mode": int(rep.mode),
        "nu": np.array(list(rep.nu)[:m], np.float32),
        "C": np.array(list(rep.c)[: m * m], np.float32).reshape(m, m),
        "T": float(rep.t_stat),
        "factor": float(rep.factor),
        "w": np.array(list(rep.w)[:m], np.float32),
        "q_scale": float(rep.q_scale),
        "detected": bool(rep.detected),
        "rejected": bool(rep.rejected),
        "reset": bool(rep.reset),
        "tested": bool(rep.tested),
        "alarm": bool(rep.alarm),
    }


def kf_update(
    x: Any,
    P: Any,
    H: Any,
    z: Any,
    R: Any,
    cfg: Any = None,  # noqa: N803 - P, H, R as in the text
    state: RobustFilterState | None = None,
    test: tuple[Any, Any] | None = None,
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """One ``mca_kf_update`` (``mca_kf_update_tested`` with ``test = (nu_t, C_t)``: the robust
    mode tests that innovation, m and m x m, instead of the update's own) on float32 copies:
    ``x`` (n), ``P`` (n x n), ``H`` (m x n, or (n,) for
    m = 1), ``z`` (m), ``R`` (m x m, or (m,) for a diagonal). ``cfg`` from :func:`robust_config`
    (None: plain); ``state`` a :class:`RobustFilterState`, required by 'akf' and 'fuzzy', updated
    in place. Returns ``(x_new, P_new, report)``; the inputs are not modified. Errors raise the
    :mod:`mcahrs.errors` exception of the C status (x, P, state then unchanged)."""
    xa = np.array(x, dtype=np.float32).reshape(-1)
    n = xa.size
    ha = np.atleast_2d(np.asarray(H, dtype=np.float32))
    m = ha.shape[0]
    ha = _as_f32(ha, (m, n), "H")
    za = _as_f32(np.asarray(z, dtype=np.float32).reshape(-1), (m,), "z")
    ra = np.asarray(R, dtype=np.float32)
    if ra.ndim <= 1 and ra.size == m:
        ra = np.diag(ra.reshape(m))
    ra = _as_f32(ra, (m, m), "R")
    pa = np.array(_as_f32(P, (n, n), "P"), dtype=np.float32, copy=True)
    mode = int(cfg.mode) if cfg is not None else lib.MCA_ROBUST_PLAIN
    if state is None and mode in _MODES_WITH_MEMORY:
        raise errors.NullError(f"kf_update: robust mode {mode} needs a RobustFilterState")
    ws_len = int(lib.mca_kf_ws_len(n, m))
    ws = np.empty(max(ws_len, 1), np.float32)
    rep = ffi.new("mca_update_report_t *")
    nu_p = c_p = ffi.NULL
    if test is not None:
        nu_t = _as_f32(np.asarray(test[0], dtype=np.float32).reshape(-1), (m,), "test nu")
        c_t = _as_f32(np.asarray(test[1], dtype=np.float32), (m, m), "test C")
        nu_c, c_c = np.ascontiguousarray(nu_t), np.ascontiguousarray(c_t)
        nu_p, c_p = _fptr(nu_c), _fptr(c_c)
    st = lib.mca_kf_update_tested(
        _fptr(xa),
        _fptr(pa),
        n,
        _fptr(ha),
        _fptr(za),
        _fptr(ra),
        m,
        cfg if cfg is not None else ffi.NULL,
        state.c if state is not None else ffi.NULL,
        nu_p,
        c_p,
        _fptr(ws),
        ws_len,
        rep,
    )
    check(st, f"mca_kf_update(n={n}, m={m}, mode={mode})")
    return xa, pa.reshape(n, n), _report_dict(rep)


def chi2_quantile(m: int, level: float) -> float:
    """The C core's chi2_m(a) (``mca_chi2_quantile``) for m = 1..MCA_MEAS_MAX and a in
    :data:`CHI2_LEVELS` (1e-4, 1e-2, 5e-3, 2.5e-2)."""
    if level not in CHI2_LEVELS:
        known = ", ".join(map(str, CHI2_LEVELS))
        raise errors.BadArgError(f"chi2 level {level!r} not in the table ({known})")
    if not 1 <= int(m) <= lib.MCA_MEAS_MAX:
        raise errors.BadArgError(f"chi2 degrees of freedom {m!r} not in 1..{lib.MCA_MEAS_MAX}")
    return float(lib.mca_chi2_quantile(int(m), CHI2_LEVELS[level]))


# ================================================================ loosely-coupled INS
# (docs/ALGORITHMS.md 10; the C's mca_ins.h). Section owned by the INS work; the rest of this
# module is unchanged by it.

INS_PRESETS = {
    "ground": lib.mca_ins_config_default,
    "fixedwing": lib.mca_ins_config_fixedwing,
    "multirotor": lib.mca_ins_config_multirotor,
}

INS_FLAG_BITS = {
    "aligned": lib.MCA_INS_FLAG_ALIGNED,
    "home_set": lib.MCA_INS_FLAG_HOME_SET,
    "nav": lib.MCA_INS_FLAG_NAV,
    "yaw_aligned": lib.MCA_INS_FLAG_YAW_ALIGNED,
    "gps_lost": lib.MCA_INS_FLAG_GPS_LOST,
    "hist_miss": lib.MCA_INS_FLAG_HIST_MISS,
    "rejected": lib.MCA_INS_FLAG_REJECTED,
    "saturated": lib.MCA_INS_FLAG_SATURATED,
    "detected": lib.MCA_INS_FLAG_DETECTED,
    "reset": lib.MCA_INS_FLAG_RESET,
}

INS_OUT_C_DTYPE = struct_dtype("mca_ins_output_t")


def ins_config(preset: str = "ground", **overrides: Any) -> Any:
    """A checked ``mca_ins_config_t *`` from a preset ('ground', 'fixedwing', 'multirotor') and field
    overrides (``gyro_noise_rps=1e-3``, ``robust={'mode': 1}`` or ``'robust.mode'``; the robust mode may
    also be given by name, ``robust='fta'``)."""
    if preset not in INS_PRESETS:
        raise errors.BadConfigError(f"unknown INS preset {preset!r}; known: {', '.join(INS_PRESETS)}")
    cfg = ffi.new("mca_ins_config_t *")
    INS_PRESETS[preset](cfg)
    over = dict(overrides)
    if isinstance(over.get("robust"), (str, int)):
        over["robust.mode"] = _robust_mode(over.pop("robust"))
    _apply(cfg, over, "mca_ins_config_t")
    check(lib.mca_ins_config_check(cfg), "mca_ins_config_t")
    return cfg


class Ins:
    """The C loosely-coupled INS, one sample at a time or a whole recording."""

    def __init__(self, cfg: Any = None) -> None:
        self.cfg = cfg if cfg is not None else ins_config()
        self._ins = ffi.new("mca_ins_t *")
        self._out = ffi.new("mca_ins_output_t *")
        self._fix = ffi.new("mca_gps_fix_t *")
        check(lib.mca_ins_init(self._ins, self.cfg), "mca_ins_init")

    def imu(self, t_us: int, gyro_b_rps: Any, accel_b_mps2: Any) -> None:
        g = _as_f32(gyro_b_rps, (3,), "gyro_b_rps")
        a = _as_f32(accel_b_mps2, (3,), "accel_b_mps2")
        check(lib.mca_ins_imu(self._ins, int(t_us), _fptr(g), _fptr(a)), f"mca_ins_imu(t_us={t_us})")

    def imu_delta(self, t_us: int, dtheta_b_rad: Any, dv_b_mps: Any) -> None:
        g = _as_f32(dtheta_b_rad, (3,), "dtheta_b_rad")
        a = _as_f32(dv_b_mps, (3,), "dv_b_mps")
        check(
            lib.mca_ins_imu_delta(self._ins, int(t_us), _fptr(g), _fptr(a)), f"mca_ins_imu_delta(t_us={t_us})"
        )

    def gps(
        self,
        t_us: int,
        lat_e7: int,
        lon_e7: int,
        alt_mm: int | None = None,
        vel_ned_mps: Any = None,
        h_acc_m: float = float("nan"),
        v_acc_m: float = float("nan"),
        s_acc_mps: float = float("nan"),
        fix_type: int = 3,
        vel_d: bool = True,
    ) -> None:
        f = self._fix
        _fill_fix(f, t_us, lat_e7, lon_e7, alt_mm, vel_ned_mps, h_acc_m, v_acc_m, s_acc_mps, fix_type, vel_d)
        check(lib.mca_ins_gps(self._ins, f), f"mca_ins_gps(t_us={t_us}, lat_e7={lat_e7}, lon_e7={lon_e7})")

    def mag(self, t_us: int, mag_b: Any) -> None:
        m = _as_f32(mag_b, (3,), "mag_b")
        check(lib.mca_ins_mag(self._ins, int(t_us), _fptr(m)), f"mca_ins_mag(t_us={t_us})")

    def output(self) -> dict[str, Any]:
        lib.mca_ins_output(self._ins, self._out)
        return _struct_to_dict(self._out[0])

    @property
    def P(self) -> np.ndarray:  # noqa: N802 - the covariance is P in every text
        """Error-state covariance (15 x 15): dr, dv, phi, b_g, b_a."""
        return np.array(list(self._ins.p), np.float32).reshape(15, 15)

    def error_model(self, f_n_mps2: Any) -> np.ndarray:
        """The continuous error-state matrix F (15 x 15) of the current state (ALGORITHMS.md 10)."""
        fn = _as_f32(f_n_mps2, (3,), "f_n_mps2")
        out = np.zeros(225, np.float32)
        check(lib.mca_ins_error_model(self._ins, _fptr(fn), _fptr(out)), "mca_ins_error_model")
        return out.reshape(15, 15)

    def replay(self, rec: Recording) -> dict[str, np.ndarray]:
        """Run a whole recording (ALGORITHMS.md 9) in one C call; one output row per IMU sample.

        Returns every ``mca_ins_output_t`` field as an array (``t_us``, ``q_nb``, ``euler_rad``,
        ``pos_ned_m``, ``vel_ned_mps``, ``gyro_bias_rps``, ``accel_bias_mps2``, ``p_diag``, ``gps_t``,
        ``flags``, counters...), ``biases`` (n, 6: gyro then accel) and the per-event statuses
        ``imu_status``, ``gps_status``, ``mag_status`` (not raised)."""
        res = _run_batch(lib.mca_ins_replay, self._ins, rec, INS_OUT_C_DTYPE, "mca_ins_replay")
        res["biases"] = np.concatenate([res["gyro_bias_rps"], res["accel_bias_mps2"]], axis=1)
        return res


def ins_replay(recording: Recording, cfg: Any = None) -> dict[str, np.ndarray]:
    """Run a recording through a fresh C INS (``cfg`` from :func:`ins_config`; None: ground defaults)."""
    return Ins(cfg).replay(recording)

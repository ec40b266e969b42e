"""The command line (mcahrs.cli): demo, simulate + replay, GNSS-only and garbage-laden
replays, and the live bench end to end through a pseudo-terminal and a socket that
vanishes and comes back. No timing assertions: the waits below only bound a test that hangs.
"""

from __future__ import annotations

import io
import os
import pty
import signal
import socket
import subprocess
import sys
import threading
import time
import tty
import types
from pathlib import Path

import numpy as np
import pytest

from mcahrs import cli
from mcahrs.io import encode_recording, xor_checksum
from mcahrs.sim import scenario

REPO = Path(__file__).resolve().parents[2]
NMEA_DIR = (REPO / ".." / "shared" / "data" / "nmea").resolve()
SHORT_CAR = {"rest_s": 3.0, "accel_s": 3.0, "cruise_s": 3.0, "stop_s": 2.0}  # ~13 s: quick, still maneuvers
WAIT_S = 120.0  # upper bound on any wait below (a hang fails instead of blocking the run)


@pytest.fixture(scope="module")
def car_stream() -> tuple[bytes, float]:
    """A short simulated car flight as wire bytes, and its duration (s)."""
    s = scenario("car_accel_brake", seed=3, **SHORT_CAR)
    t = s.recording.imu["t_us"]
    return encode_recording(s.recording), (t[-1] - t[0]) * 1e-6


def _sent(out: str, *needles: str) -> None:
    for n in needles:
        assert n in out, f"{n!r} not in output:\n{out}"


def _paced_write(write, data: bytes, duration_s: float, speed: float, seed: int = 0) -> None:
    """Write ``data`` in random chunks (cut mid-line) at ``speed`` times the real-time rate."""
    rng = np.random.default_rng(seed)
    rate = len(data) / duration_s * speed  # bytes per second
    i = 0
    while i < len(data):
        n = int(rng.integers(100, 3000))
        write(data[i:i + n])
        i += n
        time.sleep(n / rate)


# ------------------------------------------------------------------------------ demo

def test_demo_prints_errors_and_writes_streams_and_plots(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture) -> None:
    assert cli.main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    _sent(out, "car_accel_brake", "fixedwing_turns", "MCAHRS (CS compensation)", "compensation off",
          "roll RMS", "pitch RMS", "0 rejected lines")
    for name, _, _ in cli.DEMO_FLIGHTS:
        png = tmp_path / f"{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert (tmp_path / f"{name}.nmea").stat().st_size > 100_000


def test_demo_compensation_beats_plain_gravity_on_the_car(tmp_path: Path) -> None:
    flights = cli.run_demo(tmp_path, flights=[("car_accel_brake", SHORT_CAR, "short car")], echo=None,
                           plot=False)
    e = flights[0].errors_deg
    # pitch during acceleration is the paper's headline: compensation must be clearly better
    assert e["MCAHRS (CS compensation)"][1] < 0.5 * e["compensation off"][1]


# ------------------------------------------------------------------------------ simulate + replay

def test_simulate_then_replay_round_trip(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    stream, csv, png = tmp_path / "car.nmea", tmp_path / "car.csv", tmp_path / "car.png"
    assert cli.main(["simulate", "--scenario", "car_accel_brake", "--seed", "4", "--duration", "12",
                     "--out", str(stream)]) == 0
    sim = scenario("car_accel_brake", seed=4, duration_s=12.0)
    assert cli.main(["replay", str(stream), "--preset", "ground", "--csv", str(csv), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    r = sim.recording
    _sent(out, f"{len(r.imu)} IMU samples", f"{len(r.mag)} magnetometer samples", f"{len(r.gnss)} GNSS fixes",
          "rejected lines: none", "final state", "attitude", "position", "velocity", "gyro bias", "flags",
          "aligned", "GPS outliers")
    res = cli.replay_file(stream)
    assert np.array_equal(res.rec.imu, r.imu)  # the wire carries IMU samples bit-exactly
    assert np.array_equal(res.rec.gnss["t_us"], r.gnss["t_us"])
    rows = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert rows.shape == (len(r.imu), 21)
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_replay_robust_profile_under_set_overrides(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """``--robust`` sets up a robust profile (``core.robust_profile``, its guard for the stream's
    fix rate) and ``--set`` applies after it. A 3 s, 2.5 m/s velocity fault on the fixes of a
    simulated car cruising (the filter settled) moves the plain filter's roll/pitch off its
    outlier-free run by ~1 deg; fuzzy-rows leaves the velocity out and moves it ~0.2 deg; the
    replay is the C core's run of that configuration."""
    import dataclasses

    from mcahrs import core

    rec = scenario("car_accel_brake", seed=3, rest_s=20.0, accel_s=8.0, cruise_s=20.0, stop_s=8.0).recording
    g = rec.gnss.copy()
    t_s = g["t_us"] * 1e-6
    v = g["vel_ned_mps"].copy()
    v[(t_s >= 33.0) & (t_s < 36.0), 1] += 2.5
    g["vel_ned_mps"] = v
    g["speed_mps"] = np.hypot(v[:, 0], v[:, 1])
    g["course_rad"] = np.mod(np.arctan2(v[:, 1], v[:, 0]), 2.0 * np.pi)
    streams = {}
    for name, r in (("clean", rec), ("fault", dataclasses.replace(rec, gnss=g))):
        streams[name] = tmp_path / f"{name}.bin"
        streams[name].write_bytes(encode_recording(r))
    assert cli.main(["replay", str(streams["fault"]), "--robust", "fuzzy-rows",
                     "--set", "cs_v.robust.reject_reset_n=7", "--no-progress"]) == 0
    _sent(capsys.readouterr().out, "'cs_h.coast': 1", "'cs_h.robust.reject_reset_n': 100",
          "'cs_v.robust.reject_reset_n': 7", "'att.robust.mode': 3")
    mine = {"cs_v.robust.reject_reset_n": 7}
    dev = {}
    for profile in ("plain", "fuzzy-rows"):
        clean = cli.replay_file(streams["clean"], robust=profile, overrides=mine)
        fault = cli.replay_file(streams["fault"], robust=profile, overrides=mine)
        assert clean.out is not None and fault.out is not None
        cfg = core.nav_config("ground", **{**core.robust_profile(profile, 5.0), **mine})
        np.testing.assert_array_equal(fault.out["euler_rad"], core.replay(fault.rec, cfg)["euler_rad"])
        d = fault.out["euler_rad"][:, :2].astype(np.float64) - clean.out["euler_rad"][:, :2]
        dev[profile] = float(np.degrees(np.abs(d)).max())
    print(f"roll/pitch off the outlier-free run, max (deg): {dev}")
    assert dev["plain"] > 3.0 * dev["fuzzy-rows"]
    with pytest.raises(cli.CliError, match="rate"):
        cli.with_robust_profile("fuzzy-rows", 0.0)


def test_replay_missing_file_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert cli.main(["replay", str(tmp_path / "nope.nmea")]) == 2
    assert "cannot read" in capsys.readouterr().err


def test_replay_gnss_only_capture_reports_cs_velocity_and_attitude_notice(
        capsys: pytest.CaptureFixture) -> None:
    path = NMEA_DIR / "haicom-305N.log"
    if not path.exists():
        pytest.skip(f"GNSS capture {path} not present (shared data folder ../shared/data/nmea)")
    assert cli.main(["replay", str(path)]) == 0
    out = capsys.readouterr().out
    _sent(out, "0 IMU samples", "68 GNSS fixes", "NO IMU SAMPLES",
          "attitude (roll, pitch, yaw) needs IMU samples", "CS filter", "velocity", "accel.", "m/s^2")
    res = cli.replay_file(path)
    g = res.report.gnss_only
    assert res.out is None and g is not None
    assert g.used.sum() == len(res.rec.gnss)
    last = np.flatnonzero(g.used)[-1]
    assert np.isfinite(g.vel_ned_mps[last]).all() and np.isfinite(g.acc_ned_mps2[last]).all()
    # a walking capture: the CS velocity stays a walking speed
    assert np.nanmax(np.hypot(g.vel_ned_mps[:, 0], g.vel_ned_mps[:, 1])) < 5.0


def _garbage(rng: np.random.Generator) -> tuple[bytes, str | None]:
    """One bad line (or bytes outside any line) and the reject reason it must be counted under."""
    def good(body: str) -> bytes:
        return f"${body}*{xor_checksum(body.encode()):02X}\r\n".encode()

    kinds = [
        (b"$GNGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*00\r\n", "bad_checksum"),
        (b"$PMCAI,1,2,3\r\n", "no_checksum"),
        (b"$GNRMC,12\xff\xfe\x00junk\r\n", "binary"),
        (b"$PMCAI,100,0.1,0.2", "truncated"),  # cut off by the next line's '$'
        (good("PMCAX,1,2,3"), "unknown_sentence"),
        (good("PMCAI,100,nan,0,0,0,0,-9.8"), "nonfinite"),
        (b"\xb5\x62\x01\x07\x5c\x00\x00\x01\x02", None),  # UBX-like bytes between lines
    ]
    return kinds[int(rng.integers(len(kinds)))]


def test_replay_of_garbage_laden_stream_counts_rejects_and_uses_every_good_sentence(
        tmp_path: Path, car_stream: tuple[bytes, float], capsys: pytest.CaptureFixture) -> None:
    clean, _ = car_stream
    lines = clean.split(b"\r\n")[:-1]
    rng = np.random.default_rng(7)
    expected: dict[str, int] = {}
    dirty = []
    for ln in lines:
        if rng.random() < 0.03:
            g, reason = _garbage(rng)
            dirty.append(g)
            if reason:
                expected[reason] = expected.get(reason, 0) + 1
        dirty.append(ln + b"\r\n")
    (tmp_path / "clean.nmea").write_bytes(clean)
    (tmp_path / "dirty.nmea").write_bytes(b"".join(dirty))
    a = cli.replay_file(tmp_path / "clean.nmea")
    b = cli.replay_file(tmp_path / "dirty.nmea")
    assert dict(b.report.stats.rejected) == expected
    assert b.report.stats.garbage_bytes > 0
    counts = (a.report.n_imu, a.report.n_mag, a.report.n_fix)
    assert (b.report.n_imu, b.report.n_mag, b.report.n_fix) == counts
    assert np.array_equal(a.rec.imu, b.rec.imu) and np.array_equal(a.rec.gnss, b.rec.gnss)
    assert cli.finals_equal(a.report.final, b.report.final)
    assert cli.main(["replay", str(tmp_path / "dirty.nmea")]) == 0
    out = capsys.readouterr().out
    _sent(out, f"rejected lines: {sum(expected.values())}", *(f"{r} " for r in expected))


# ------------------------------------------------------------------------------ bench without a port

# multirotor: yaw from the magnetometer, so the place of every mag sample in the order matters
@pytest.mark.parametrize("preset", ["ground", "multirotor"])
def test_live_nav_in_random_chunks_equals_batch_replay(preset: str, car_stream: tuple[bytes, float]) -> None:
    data, _ = car_stream
    rec_res = cli.replay_recording(cli.read_capture_bytes(data), preset)
    live = cli.LiveNav(preset)
    rng = np.random.default_rng(1)
    i = 0
    while i < len(data):
        n = int(rng.integers(1, 5000))
        live.feed(data[i:i + n])
        i += n
    rep = live.finish()
    assert live.merger.late == 0
    assert cli.finals_equal(rep.final, rec_res[2].final)
    assert cli.format_report(rep) == cli.format_report(rec_res[2])


def test_live_nav_on_gnss_only_capture_equals_replay() -> None:
    path = NMEA_DIR / "rst39.log"
    if not path.exists():
        pytest.skip(f"GNSS capture {path} not present")
    data = path.read_bytes()
    live = cli.LiveNav()
    for k in range(0, len(data), 333):
        live.feed(data[k:k + 333])
    assert cli.format_report(live.finish()) == cli.format_report(cli.replay_file(path).report)


# ------------------------------------------------------------------------------ bench through a pty

def test_bench_through_pty_equals_replay_of_the_bytes_and_of_its_log(
        tmp_path: Path, car_stream: tuple[bytes, float]) -> None:
    data, duration = car_stream
    master, slave = pty.openpty()
    tty.setraw(slave)  # no echo, no CR/LF translation before the bench configures the port
    path = os.ttyname(slave)
    opened = threading.Event()
    errors: list[BaseException] = []

    def writer() -> None:
        try:
            assert opened.wait(WAIT_S)
            os.close(slave)  # the bench holds its own descriptor now

            def write_all(chunk: bytes) -> None:
                while chunk:
                    chunk = chunk[os.write(master, chunk):]

            _paced_write(write_all, data, duration, speed=8.0)
        except BaseException as exc:  # noqa: BLE001 - reported by the test below
            errors.append(exc)

    th = threading.Thread(target=writer, daemon=True)
    th.start()
    status = io.StringIO()
    log = tmp_path / "bench.nmea"
    try:
        res = cli.run_bench(path, log=log, idle_timeout_s=3.0, max_duration_s=WAIT_S, status=status,
                            status_period_s=0.2, on_event=lambda e: opened.set() if e == "open" else None)
    finally:
        th.join(WAIT_S)
        os.close(master)
    assert not errors, errors
    assert res.stop_reason == "idle"
    assert res.disconnects == 0
    assert log.read_bytes() == data  # every byte, in order
    assert res.live.merger.late == 0
    assert "roll" in status.getvalue() and "fixes" in status.getvalue()  # the rolling status line ran
    (tmp_path / "sent.nmea").write_bytes(data)
    for f in (tmp_path / "sent.nmea", log):
        rep = cli.replay_file(f).report
        assert cli.finals_equal(res.report.final, rep.final)
        assert cli.format_report(res.report) == cli.format_report(rep)
    assert res.report.final is not None and res.report.final["flags"] & cli.core.FLAG_BITS["aligned"]
    text = cli.format_bench(res, path)
    assert "reproduces the report above" in text


# ------------------------------------------------------------------------------ bench, socket vanishes

def test_bench_survives_socket_server_vanishing_and_keeps_filter_state(
        tmp_path: Path, car_stream: tuple[bytes, float]) -> None:
    data, duration = car_stream
    cut = len(data) // 2 + 17  # mid-line
    resume = cut + len(data) // 40  # bytes sent while nobody listened are lost (about 0.3 s of data)
    srv = socket.create_server(("127.0.0.1", 0))
    port = srv.getsockname()[1]
    done = threading.Event()
    errors: list[BaseException] = []

    def server() -> None:
        try:
            conn, _ = srv.accept()
            # pyserial's socket open() ends with reset_input_buffer(), which drops what has arrived
            # by then; the bench cannot tell us it is open, so the server waits a moment
            time.sleep(0.3)
            _paced_write(conn.sendall, data[:cut], duration, speed=10.0)
            conn.close()
            srv.close()  # the port vanishes
            time.sleep(0.6)
            srv2 = socket.create_server(("127.0.0.1", port))  # and comes back
            conn2, _ = srv2.accept()
            time.sleep(0.3)  # as above, for the reconnection's open()
            _paced_write(conn2.sendall, data[resume:], duration, speed=10.0)
            assert done.wait(WAIT_S)
            conn2.close()
            srv2.close()
        except BaseException as exc:  # noqa: BLE001
            errors.append(exc)

    th = threading.Thread(target=server, daemon=True)
    th.start()
    events: list[str] = []
    log = tmp_path / "bench.nmea"
    try:
        res = cli.run_bench(f"socket://127.0.0.1:{port}", log=log, idle_timeout_s=3.0, max_duration_s=WAIT_S,
                            status=None, on_event=events.append, backoff_max_s=0.4)
    finally:
        done.set()
        th.join(WAIT_S)
    assert not errors, errors
    assert res.disconnects == 1 and res.reconnects == 1
    assert events[:3] == ["open", "disconnected", "reconnected"]
    received = data[:cut] + data[resume:]
    assert log.read_bytes() == received
    rep = cli.replay_file(log).report
    assert cli.finals_equal(res.report.final, rep.final)  # one filter over the whole stream, as replay
    assert cli.format_report(res.report) == cli.format_report(rep)
    # the state was kept: a filter restarted at the reconnection ends elsewhere
    restarted = cli.replay_recording(cli.read_capture_bytes(data[resume:]))[2]
    assert not cli.finals_equal(res.report.final, restarted.final)
    assert res.report.stats.total_rejected >= 1  # the line cut by the outage


# ------------------------------------------------------------------------------ bench, Ctrl-C

def test_bench_command_stops_cleanly_on_sigint(tmp_path: Path, car_stream: tuple[bytes, float]) -> None:
    data, duration = car_stream
    srv = socket.create_server(("127.0.0.1", 0))
    port = srv.getsockname()[1]
    stop = threading.Event()

    def server() -> None:
        conn, _ = srv.accept()
        try:
            _paced_write(conn.sendall, data[: len(data) // 3], duration, speed=4.0)
            stop.wait(WAIT_S)
        except OSError:
            pass
        finally:
            conn.close()
            srv.close()

    th = threading.Thread(target=server, daemon=True)
    th.start()
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    cmd = [sys.executable, "-m", "mcahrs.cli", "bench", "--port", f"socket://127.0.0.1:{port}",
           "--log", str(tmp_path / "b.nmea")]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stderr is not None
        t0 = time.monotonic()
        line = ""
        while "[bench] open" not in line and time.monotonic() - t0 < WAIT_S:
            line = proc.stderr.readline()
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=WAIT_S)
    finally:
        stop.set()
        if proc.poll() is None:
            proc.kill()
        th.join(WAIT_S)
    assert proc.returncode == 0, err
    _sent(out, "stopped (interrupted)", "final state", "reproduces the report above")


def test_bench_unopenable_port_is_a_clear_error(capsys: pytest.CaptureFixture) -> None:
    assert cli.main(["bench", "--port", "/dev/does-not-exist-mcahrs", "--max-duration", "5"]) == 2
    assert "cannot open /dev/does-not-exist-mcahrs" in capsys.readouterr().err


# ------------------------------------------------------------------------------ evaluate / convert

def test_evaluate_and_convert_dispatch_to_mcahrs_evaluate(monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture) -> None:
    seen: list[list[str]] = []
    fake = types.ModuleType("mcahrs.evaluate")
    fake.main_evaluate = lambda argv: seen.append(list(argv)) or 0  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "mcahrs.evaluate", fake)
    assert cli.main(["evaluate", "log.ulg", "--plot", "d"]) == 0
    assert seen == [["log.ulg", "--plot", "d"]]
    assert cli.main(["convert", "x"]) == 2  # the fake module has no main_convert
    assert "main_convert" in capsys.readouterr().err

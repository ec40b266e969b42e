"""The public entry of the stream input layer: bytes in, typed samples out.

    with serial.serial_for_url("/dev/ttyUSB0", 115200, timeout=None) as port:
        reader = StreamReader(port, latency_us=80_000)
        for sample in reader:          # ImuSample | MagSample | GnssFix, in stream order
            ...
        print(reader.stats.summary())

    rec = read_file("flight.nmea")     # -> Recording (meta["stats"] holds the counters)

Layers: :mod:`~mcahrs.io.framing` (bytes -> checked sentences), :mod:`~mcahrs.io.nmea`
(sentences -> samples and GNSS epochs, through pynmeagps), :mod:`~mcahrs.io.timebase`
(epochs -> IMU-clock times). The wire format is in :mod:`~mcahrs.io.wire`.

The reader never raises on bad input; it counts (``reader.stats``) and goes on. Iteration
reads until the stream returns no bytes: end of file, or a serial read timeout with nothing
received (open the port with ``timeout=None`` to read until it is closed). A
``serial.SerialException`` while reading (socket closed, device unplugged) also ends it:
event ``disconnected``, the exception kept in ``reader.error``; ``PortNotOpenError`` is
raised. Samples are
yielded in the order their last sentence arrived; a fix is yielded when its epoch is
complete (see :mod:`~mcahrs.io.nmea`), so a few IMU samples newer than its ``t_rx_us`` may
come before it.
"""

from __future__ import annotations

import io
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Protocol

import numpy as np
import serial

from ..samples import GNSS_HAS_ALT, GnssFix, ImuSample, MagSample, Recording, Sample, recording_from_samples
from .framing import DEFAULT_MAX_LINE, NmeaFramer
from .nmea import Epoch, EpochAssembler, GnssPart, decode_sentence, fix_fields
from .stats import StreamStats
from .timebase import TimeBase
from .wire import GNSS_ALT_MSL

DEFAULT_CHUNK = 4096


class ByteSource(Protocol):
    """What the reader needs from a stream: a binary file, ``io.BytesIO``, a pyserial port."""

    def read(self, size: int = ..., /) -> bytes: ...


class StreamReader:
    """Typed samples from a byte stream of NMEA sentences and MCAHRS sensor sentences.

    Parameters
    ----------
    stream:
        Anything with ``read(n)``: a binary file, ``io.BytesIO``, or a pyserial port from
        ``serial.serial_for_url`` (real port, ``loop://``, ``socket://``, a pty). Pass None
        to use the push interface (:meth:`feed` / :meth:`finish`) only.
    latency_us:
        Receiver output latency: fix ``t_us = t_rx_us - latency_us`` (see timebase.py).
    clock:
        "auto" (IMU clock if the stream has IMU samples, else UTC), "imu" or "utc".
    max_line:
        Longest line accepted, bytes (NMEA's own limit is 82).
    skip_comments:
        Skip lines starting with ``#`` (gpsd capture headers).
    utc_tol_us:
        Tolerance of the UTC-step versus IMU-step check.
    epoch_timeout_us:
        Emit an open epoch after this much IMU time since its first sentence.
    """

    def __init__(
        self,
        stream: ByteSource | None,
        latency_us: int = 0,
        clock: str = "auto",
        max_line: int = DEFAULT_MAX_LINE,
        skip_comments: bool = True,
        utc_tol_us: int = 200_000,
        epoch_timeout_us: int = 1_000_000,
        chunk_size: int = DEFAULT_CHUNK,
    ) -> None:
        self.stream = stream
        self.stats = StreamStats()
        self.framer = NmeaFramer(self.stats, max_line=max_line, skip_comments=skip_comments)
        self.epochs = EpochAssembler(self.stats)
        self.timebase = TimeBase(self.stats, latency_us=latency_us, clock=clock, utc_tol_us=utc_tol_us)
        self.epoch_timeout_us = int(epoch_timeout_us)
        self.chunk_size = int(chunk_size)
        self.alt_refs: set[str] = set()  # "ellipsoid" / "msl" of the fixes emitted
        self.fix_utc_tod_us: list[int] = []  # UTC time of day of each emitted fix, in order
        self._finished = False
        self.error: Exception | None = None  # the SerialException that ended the stream, if any

    # -- push interface --------------------------------------------------------------------
    def feed(self, data: bytes) -> list[Sample]:
        """Consume bytes; return the samples they completed, in stream order."""
        out: list[Sample] = []
        for sent in self.framer.feed(data):
            item = decode_sentence(sent, self.stats)
            if item is None:
                continue
            if isinstance(item, ImuSample):
                if not self.timebase.imu.accept(item.t_us):
                    self.stats.reject("time_backwards", sent.raw)
                    continue
                for ep in self.epochs.timeout(item.t_us, self.epoch_timeout_us):
                    self._emit_fix(ep, out)
                out.append(item)
                self.stats.emitted["imu"] += 1
            elif isinstance(item, MagSample):
                if not self.timebase.mag.accept(item.t_us):
                    self.stats.reject("time_backwards", sent.raw)
                    continue
                out.append(item)
                self.stats.emitted["mag"] += 1
            else:
                assert isinstance(item, GnssPart)
                item.imu_t_us = self.timebase.last_imu_t_us
                for ep in self.epochs.add(item):
                    self._emit_fix(ep, out)
        return out

    def finish(self) -> list[Sample]:
        """End of stream: a cut-off line is counted, the open epoch is emitted."""
        if self._finished:
            return []
        self._finished = True
        self.framer.flush()
        out: list[Sample] = []
        for ep in self.epochs.flush():
            self._emit_fix(ep, out)
        return out

    # -- pull interface --------------------------------------------------------------------
    def _read(self) -> bytes:
        s = self.stream
        if s is None:
            return b""
        waiting = getattr(s, "in_waiting", None)  # pyserial: do not block for a full chunk
        if waiting is not None:
            return s.read(max(1, min(int(waiting), self.chunk_size)))
        read1 = getattr(s, "read1", None)
        if read1 is not None:
            return read1(self.chunk_size)
        return s.read(self.chunk_size)

    def __iter__(self) -> Iterator[Sample]:
        while True:
            try:
                data = self._read()
            except serial.PortNotOpenError:
                raise
            except serial.SerialException as exc:  # socket closed, device unplugged, pty hung up
                self.stats.events["disconnected"] += 1
                self.error = exc
                break
            if not data:
                break
            yield from self.feed(data)
        yield from self.finish()

    # -- internals -------------------------------------------------------------------------
    def _emit_fix(self, ep: Epoch, out: list[Sample]) -> None:
        f = fix_fields(ep)
        if f is None:
            self.stats.events["epoch_no_fix"] += 1
            return
        times = self.timebase.fix_times(ep.tod_us, ep.imu_t_us, f.pop("pmcav_t_us"))
        if times is None:
            self.stats.reject("no_time_base", f"epoch {ep.tod_us} us of day".encode())
            return
        f.pop("source")
        t_us, t_rx_us = times
        out.append(GnssFix(t_us=t_us, t_rx_us=t_rx_us, **f))
        self.fix_utc_tod_us.append(ep.tod_us)
        if f["flags"] & GNSS_HAS_ALT:
            self.alt_refs.add("msl" if f["flags"] & GNSS_ALT_MSL else "ellipsoid")
        self.stats.emitted["gnss"] += 1

    def meta(self) -> dict:
        """What a Recording made from this reader should carry in ``meta``."""
        alt = self.alt_refs
        return {
            "reader": "mcahrs.io.StreamReader",
            "clock": self.timebase.mode,
            "latency_us": self.timebase.latency_us,
            # height reference of the fixes: "ellipsoid", "msl" (flag GNSS_ALT_MSL), "mixed", "none"
            "alt_ref": "none" if not alt else next(iter(alt)) if len(alt) == 1 else "mixed",
            "stats": self.stats.as_dict(),
            # UTC time of day (us) of each fix, aligned with Recording.gnss
            "gnss_utc_tod_us": np.array(self.fix_utc_tod_us, dtype=np.int64),
        }


def read_stream(stream: ByteSource, name: str = "stream", **kw) -> Recording:
    """Read a whole stream into a :class:`Recording` (``kw`` go to :class:`StreamReader`).

    Arrays are in stream order: IMU and magnetometer samples in time order (backward steps
    are rejected), fixes in order of arrival. ``meta`` holds ``clock``, ``latency_us``,
    ``alt_ref``, ``gnss_utc_tod_us`` (UTC time of day of each fix), ``stats`` (plain dict)
    and ``stats_obj`` (the :class:`StreamStats`).
    """
    reader = StreamReader(stream, **kw)
    rec = recording_from_samples(name, reader)
    rec.meta.update(reader.meta())
    rec.meta["stats_obj"] = reader.stats
    return rec


def read_bytes(data: bytes, name: str = "bytes", **kw) -> Recording:
    """Read a byte string (see :func:`read_stream`)."""
    return read_stream(io.BytesIO(data), name=name, **kw)


def read_file(path: str | os.PathLike, **kw) -> Recording:
    """Read a capture file into a :class:`Recording` named after the file.

    Raises ``FileNotFoundError`` / ``IsADirectoryError`` for a bad path; bad content is
    counted in ``rec.meta["stats"]``, never raised.
    """
    p = Path(path)
    with open(p, "rb") as fh:
        rec = read_stream(fh, name=p.name, **kw)
    rec.meta["source"] = str(p)
    return rec


def iter_file(path: str | os.PathLike, **kw) -> Iterator[GnssFix | ImuSample | MagSample]:
    """Yield the samples of a file one by one (for large captures)."""
    with open(path, "rb") as fh:
        yield from StreamReader(fh, **kw)

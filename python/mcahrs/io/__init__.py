"""Stream input layer: bytes (file, serial port, socket, pty) -> typed samples.

Public entry points: :class:`StreamReader`, :func:`read_file`, :func:`read_bytes`,
:func:`read_stream`; the wire format and its encoder are in :mod:`mcahrs.io.wire`.
"""

from .framing import NmeaFramer, Sentence, xor_checksum
from .stats import REJECT_REASONS, StreamStats
from .stream import StreamReader, iter_file, read_bytes, read_file, read_stream
from .wire import (
    GNSS_ALT_MSL,
    encode_fix,
    encode_imu,
    encode_mag,
    encode_recording,
    encode_samples,
    recording_samples,
    write_recording,
)

__all__ = [
    "GNSS_ALT_MSL",
    "NmeaFramer",
    "REJECT_REASONS",
    "Sentence",
    "StreamReader",
    "StreamStats",
    "encode_fix",
    "encode_imu",
    "encode_mag",
    "encode_recording",
    "encode_samples",
    "iter_file",
    "read_bytes",
    "read_file",
    "read_stream",
    "recording_samples",
    "write_recording",
    "xor_checksum",
]

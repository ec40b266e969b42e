"""Counters kept by the stream input layer: what was read, used, ignored and rejected.

A stream reader never raises on bad input: every line it gives up on is counted here under a
named reason, and reading goes on. Reasons (``StreamStats.rejected``):

========================  =============================================================
``bad_checksum``          ``*hh`` present but wrong, or not two hex digits
``no_checksum``           a line with no ``*hh`` at all (checksums are enforced)
``too_long``              more than ``max_line`` bytes before a terminator (not buffered)
``binary``                a started line ran into a byte outside printable ASCII
``truncated``             a line cut off by the next ``$`` or by the end of the stream
``malformed``             empty address, or a reserved ``*`` inside the sentence body
``bad_address``           address field is not ``ttsss`` (talker + type) or ``P...``
``unknown_sentence``      a ``$PMCA..`` sentence of our own namespace that is not defined
``bad_fields``            wrong field count, unparsable number, time or lat/lon text
``empty_fields``          a field the sentence cannot do without is empty
``nonfinite``             ``nan``/``inf`` text in a numeric field
``time_backwards``        a sensor sample (IMU/mag) not newer than the previous one
``no_time_base``          a GNSS fix that cannot be put on the IMU clock (no IMU sample yet)
========================  =============================================================

Events that are not rejections (``StreamStats.events``) are counted too:
framing: ``doubled_start`` (``$$GPGGA``), ``no_terminator`` (``*hh`` followed directly by
``$``), ``long_line`` (accepted, over NMEA's 82 characters), ``start_in_comment`` (a ``$`` or
``!`` inside a skipped ``#`` line); decoding: ``no_fix`` (a valid sentence saying there is no
fix), ``talker_normalised``; epochs: ``epoch_no_fix``, ``late_sentence``, ``late_gsa``,
``orphan_sentence``; time base: ``utc_backwards``, ``utc_repeat``, ``utc_step_mismatch``,
``clock_switch``, ``imu_clock_reset``; transport: ``disconnected``.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

REJECT_REASONS = (
    "bad_checksum",
    "no_checksum",
    "too_long",
    "binary",
    "truncated",
    "malformed",
    "bad_address",
    "unknown_sentence",
    "bad_fields",
    "empty_fields",
    "nonfinite",
    "time_backwards",
    "no_time_base",
)

_EXAMPLES_PER_REASON = 3
_EXAMPLE_BYTES = 120


@dataclass
class StreamStats:
    """What a :class:`~mcahrs.io.stream.StreamReader` saw.

    ``stats["bad_checksum"]`` is a shortcut for ``stats.rejected["bad_checksum"]``.
    """

    bytes_read: int = 0
    garbage_bytes: int = 0  # bytes outside any accepted or rejected line (binary frames, orphan text)
    comment_lines: int = 0  # '#' lines skipped (gpsd capture headers)
    sentences: Counter = field(default_factory=Counter)  # checksum-valid sentences by address ("GPGGA")
    used: Counter = field(default_factory=Counter)  # decoded and used, by kind ("GGA", "PMCAI")
    ignored: Counter = field(default_factory=Counter)  # valid, but of a type this layer does not use
    rejected: Counter = field(default_factory=Counter)  # reason -> count (see module docstring)
    events: Counter = field(default_factory=Counter)  # non-reject happenings
    emitted: Counter = field(default_factory=Counter)  # samples yielded: "imu", "mag", "gnss"
    examples: dict = field(default_factory=dict)  # reason -> first few offending lines (bytes)

    def reject(self, reason: str, line: bytes | bytearray = b"") -> None:
        """Count one rejected line under ``reason`` and keep a short example of it."""
        if reason not in REJECT_REASONS:
            raise ValueError(f"unknown reject reason {reason!r}")
        self.rejected[reason] += 1
        ex = self.examples.setdefault(reason, [])
        if len(ex) < _EXAMPLES_PER_REASON:
            ex.append(bytes(line[:_EXAMPLE_BYTES]))

    def __getitem__(self, reason: str) -> int:
        return self.rejected[reason]

    @property
    def total_rejected(self) -> int:
        return sum(self.rejected.values())

    def as_dict(self) -> dict:
        """Plain-dict form (JSON-friendly apart from the example bytes, which are decoded)."""
        return {
            "bytes_read": self.bytes_read,
            "garbage_bytes": self.garbage_bytes,
            "comment_lines": self.comment_lines,
            "sentences": dict(self.sentences),
            "used": dict(self.used),
            "ignored": dict(self.ignored),
            "rejected": dict(self.rejected),
            "events": dict(self.events),
            "emitted": dict(self.emitted),
            "examples": {
                k: [e.decode("ascii", "backslashreplace") for e in v] for k, v in self.examples.items()
            },
        }

    def summary(self) -> str:
        """A few human-readable lines for logs and the CLI."""
        out = [
            f"bytes {self.bytes_read}, garbage {self.garbage_bytes}, comment lines {self.comment_lines}",
            f"sentences {sum(self.sentences.values())}: "
            + ", ".join(f"{k} {v}" for k, v in sorted(self.sentences.items())),
            "emitted: " + ", ".join(f"{k} {v}" for k, v in sorted(self.emitted.items())),
            "rejected: " + (", ".join(f"{k} {v}" for k, v in sorted(self.rejected.items())) or "none"),
            "events: " + (", ".join(f"{k} {v}" for k, v in sorted(self.events.items())) or "none"),
        ]
        return "\n".join(out)

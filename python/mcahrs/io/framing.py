"""Split any byte stream into NMEA 0183 sentences, counting everything it cannot use.

The framer does its own framing instead of pynmeagps's stream reader, because that reader
silently drops ``$$``-prefixed lines and talkers it does not know (see
``data/nmea/README.md``). Here no started line is ever lost without being counted in
:class:`~mcahrs.io.stats.StreamStats`.

Rules (bytes in, :class:`Sentence` out):

* A line starts at ``$`` or ``!`` and ends at CR or LF. A second start character right
  after the first (``$$GPGGA``) is taken as one start (event ``doubled_start``).
* Inside a line only printable ASCII (0x20-0x7E) may occur. Any other byte rejects the
  line as ``binary``; the bytes after it are skipped up to the next ``$``/``!`` or line end
  (resynchronisation). UBX or other binary frames between sentences are skipped the same
  way and counted in ``garbage_bytes``.
* A ``$`` inside a line starts a new line. The old one is accepted if it already ends in
  ``*hh`` (event ``no_terminator``), otherwise it is rejected as ``truncated``. A ``!``
  inside a line is ordinary text.
* A line longer than ``max_line`` bytes (default 512; NMEA allows 82 including CR LF) is
  rejected as ``too_long`` as soon as the cap is passed; nothing beyond the cap is
  buffered. Accepted lines over 82 characters are counted as event ``long_line``.
* The checksum is enforced: no ``*`` -> ``no_checksum``; ``*`` not followed by exactly two
  hex digits up to the line end, or an XOR mismatch -> ``bad_checksum`` (hex digits of
  either case are accepted).
* The address (text before the first comma) must be ``TTSSS`` (2-character talker, 3-letter
  type) or a proprietary ``P...``, otherwise ``bad_address``.
* With ``skip_comments`` (default), a line whose first byte is ``#`` (gpsd capture headers)
  is skipped up to LF and counted in ``comment_lines``; a ``$``/``!`` inside it is counted
  as event ``start_in_comment`` (gpsd headers quote sentences). A control byte (other than
  TAB/CR) inside such a line ends it early, so binary data that happens to hold ``LF #``
  does not hide the sentences after it in a "comment".
* End of stream inside a line -> ``truncated``.

Cost: one regex scan per run of ordinary bytes, one XOR pass per candidate line; memory is
bounded by ``max_line``.
"""

from __future__ import annotations

import re
from typing import NamedTuple

from .stats import StreamStats

DEFAULT_MAX_LINE = 512
NMEA_MAX_CHARS = 82  # NMEA 0183 maximum sentence length including CR LF

_OUTSIDE = re.compile(rb"[$!\r\n#]")
_IN_LINE = re.compile(rb"[^\x20-\x23\x25-\x7e]")  # not printable ASCII, or '$'
_COMMENT_END = re.compile(rb"[\x00-\x08\x0a-\x0c\x0e-\x1f\x7f$!]")
_DISCARD_END = re.compile(rb"[$!\r\n]")
_ENDS_WITH_CHECKSUM = re.compile(rb"\*[0-9A-Fa-f]{2}\Z")
_HEX2 = re.compile(rb"[0-9A-Fa-f]{2}\Z")
_ADDRESS = re.compile(rb"P[A-Z0-9]{2,}|[A-Z][A-Z0-9][A-Z][A-Z0-9]{2}")

_OUT, _LINE, _COMMENT, _DISCARD = range(4)


class Sentence(NamedTuple):
    """One framed sentence whose checksum is good."""

    start: str  # "$" or "!"
    address: str  # e.g. "GPGGA", "PMCAI"
    body: str  # text between the start character and '*', ASCII
    raw: bytes  # the line as received, without terminator (may start with "$$")

    @property
    def talker(self) -> str:
        return "P" if self.address.startswith("P") else self.address[:2]

    @property
    def sentence_type(self) -> str:
        return self.address[1:] if self.address.startswith("P") else self.address[2:]

    def to_bytes(self) -> bytes:
        """The sentence as a clean ``$...*hh\\r\\n`` line (single start character)."""
        return f"{self.start}{self.body}*{xor_checksum(self.body):02X}\r\n".encode("ascii")


def xor_checksum(body: str | bytes) -> int:
    """NMEA checksum: XOR of all bytes between the start character and ``*``."""
    data = body.encode("ascii") if isinstance(body, str) else body
    c = 0
    for b in data:
        c ^= b
    return c


class NmeaFramer:
    """Incremental framer: ``feed(bytes)`` returns the complete sentences found so far.

    ``stats`` is updated in place (rejections, garbage, comments, sentence counts).
    """

    def __init__(
        self,
        stats: StreamStats | None = None,
        max_line: int = DEFAULT_MAX_LINE,
        skip_comments: bool = True,
    ) -> None:
        if max_line < NMEA_MAX_CHARS:
            raise ValueError(f"max_line={max_line} is below NMEA's {NMEA_MAX_CHARS} characters")
        self.stats = stats if stats is not None else StreamStats()
        self.max_line = max_line
        self.skip_comments = skip_comments
        self._state = _OUT
        self._line_start = True  # at the start of a physical line (for '#' comments)
        self._buf = bytearray()
        self._doubled = False

    # -- public --------------------------------------------------------------------------
    def feed(self, data: bytes) -> list[Sentence]:
        """Consume ``data``; return the sentences completed by it, in stream order."""
        out: list[Sentence] = []
        self.stats.bytes_read += len(data)
        i, n = 0, len(data)
        while i < n:
            if self._state == _OUT:
                i = self._scan_outside(data, i, n)
            elif self._state == _LINE:
                i = self._scan_line(data, i, n, out)
            elif self._state == _COMMENT:
                i = self._scan_comment(data, i, n)
            else:
                i = self._scan_discard(data, i, n)
        return out

    def flush(self) -> list[Sentence]:
        """End of stream: a line still open is ``truncated``."""
        if self._state == _LINE:
            self.stats.reject("truncated", self._buf)
        elif self._state == _COMMENT:
            self.stats.comment_lines += 1
        self._buf = bytearray()
        self._state = _OUT
        self._line_start = True
        return []

    # -- states --------------------------------------------------------------------------
    def _scan_outside(self, data: bytes, i: int, n: int) -> int:
        m = _OUTSIDE.search(data, i)
        j = m.start() if m else n
        if j > i:
            self.stats.garbage_bytes += j - i
            self._line_start = False
        if m is None:
            return n
        c = data[j]
        if c in (0x0D, 0x0A):
            self._line_start = True
        elif c == 0x23:  # '#'
            if self._line_start and self.skip_comments:
                self._state = _COMMENT
            else:
                self.stats.garbage_bytes += 1
                self._line_start = False
        else:  # '$' or '!'
            self._begin(c)
        return j + 1

    def _scan_comment(self, data: bytes, i: int, n: int) -> int:
        m = _COMMENT_END.search(data, i)
        if m is None:
            return n
        j = m.start()
        if data[j] in (0x24, 0x21):  # '$'/'!' in a comment: skipped, but counted
            self.stats.events["start_in_comment"] += 1
            return j + 1
        if data[j] == 0x0A:
            self.stats.comment_lines += 1
            self._state = _OUT
            self._line_start = True
            return j + 1
        # A control byte: this was binary data, not a comment. Re-read the byte outside.
        self._state = _OUT
        self._line_start = False
        return j

    def _scan_discard(self, data: bytes, i: int, n: int) -> int:
        m = _DISCARD_END.search(data, i)
        j = m.start() if m else n
        self.stats.garbage_bytes += j - i
        if m is None:
            return n
        c = data[j]
        if c in (0x0D, 0x0A):
            self._state = _OUT
            self._line_start = True
        else:
            self._begin(c)
        return j + 1

    def _scan_line(self, data: bytes, i: int, n: int, out: list[Sentence]) -> int:
        m = _IN_LINE.search(data, i)
        j = m.start() if m else n
        room = self.max_line - len(self._buf)
        if j - i > room:  # cap passed: reject now, buffer nothing more
            self._buf += data[i : i + room]
            self.stats.reject("too_long", self._buf)
            self._buf = bytearray()
            self._state = _DISCARD
            return i + room
        self._buf += data[i:j]
        if m is None:
            return n
        c = data[j]
        if c == 0x24:  # '$' inside a line
            if len(self._buf) == 1:
                self.stats.events["doubled_start"] += 1
                self._buf = bytearray(b"$")
                self._doubled = True
            else:
                if _ENDS_WITH_CHECKSUM.search(self._buf):
                    self.stats.events["no_terminator"] += 1
                    self._finish(out)
                else:
                    self.stats.reject("truncated", self._buf)
                self._begin(c)
            return j + 1
        if c in (0x0D, 0x0A):
            self._finish(out)
            self._state = _OUT
            self._line_start = True
            return j + 1
        # any other non-printable byte
        self.stats.reject("binary", self._buf + data[j : j + 1])
        self._buf = bytearray()
        self._state = _DISCARD
        return j + 1

    # -- helpers -------------------------------------------------------------------------
    def _begin(self, c: int) -> None:
        self._buf = bytearray((c,))
        self._doubled = False
        self._state = _LINE
        self._line_start = False

    def _finish(self, out: list[Sentence]) -> None:
        buf = bytes(self._buf)
        raw = b"$" + buf if self._doubled else buf
        self._buf = bytearray()
        self._doubled = False
        if len(buf) == 1:
            self.stats.reject("truncated", raw)
            return
        star = buf.rfind(b"*")
        if star < 0:
            self.stats.reject("no_checksum", raw)
            return
        tail = buf[star + 1 :]
        body = buf[1:star]
        if not _HEX2.match(tail) or xor_checksum(body) != int(tail, 16):
            self.stats.reject("bad_checksum", raw)
            return
        if not body or b"*" in body:
            self.stats.reject("malformed", raw)
            return
        comma = body.find(b",")
        address = body if comma < 0 else body[:comma]
        if not _ADDRESS.fullmatch(address):
            self.stats.reject("bad_address", raw)
            return
        if len(buf) + 2 > NMEA_MAX_CHARS:
            self.stats.events["long_line"] += 1
        addr = address.decode("ascii")
        self.stats.sentences[addr] += 1
        out.append(Sentence(chr(buf[0]), addr, body.decode("ascii"), raw))

"""Framing of raw bytes into NMEA sentences (mcahrs.io.framing): every line used or counted."""

from __future__ import annotations

from functools import reduce

import pytest

from mcahrs.io.framing import NmeaFramer, xor_checksum
from mcahrs.io.stats import StreamStats


def cs(body: bytes) -> bytes:
    """Checksum computed here, independently of the code under test."""
    return b"%02X" % reduce(lambda a, b: a ^ b, body, 0)


def line(body: bytes, end: bytes = b"\r\n") -> bytes:
    return b"$" + body + b"*" + cs(body) + end


def frame(data: bytes, **kw) -> tuple[list, StreamStats]:
    fr = NmeaFramer(**kw)
    out = fr.feed(data) + fr.flush()
    return out, fr.stats


def test_xor_checksum_matches_nmea_reference_example():
    # The classic GGA example from NMEA references, checksum *47.
    assert xor_checksum("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,") == 0x47


def test_framer_accepts_crlf_lf_cr_and_bang_starts():
    body = b"GPGLL,4916.45,N,12311.12,W,225444,A,"
    data = (
        line(body)
        + line(body, b"\n")
        + line(body, b"\r")
        + b"!"
        + b"AIVDM,1,1,,A,15M67N0000G?Uf6E`FepT@3n00Sa,0"
        + b"*"
        + cs(b"AIVDM,1,1,,A,15M67N0000G?Uf6E`FepT@3n00Sa,0")
        + b"\r\n"
    )
    out, st = frame(data)
    assert [s.address for s in out] == ["GPGLL"] * 3 + ["AIVDM"]
    assert out[3].start == "!"
    assert st.total_rejected == 0 and st.garbage_bytes == 0


def test_doubled_dollar_start_is_one_sentence():
    body = b"GNGGA,135806.000,4723.7000,N,00048.1000,E,1,08,1.0,60.0,M,50.0,M,,"
    out, st = frame(b"$" + line(body) + b"$" + line(body))
    assert len(out) == 2 and out[0].body == body.decode()
    assert st.events["doubled_start"] == 2 and st.total_rejected == 0


def test_lowercase_checksum_hex_is_accepted():
    body = b"GPZDA,201530.00,04,07,2002,00,00"
    out, st = frame(b"$" + body + b"*" + cs(body).lower() + b"\r\n")
    assert len(out) == 1 and st.total_rejected == 0


@pytest.mark.parametrize(
    "bad, reason",
    [
        (b"$GPZDA,201530.00,04,07,2002,00,00*00\r\n", "bad_checksum"),
        (b"$GPZDA,201530.00,04,07,2002,00,00\r\n", "no_checksum"),
        (b"$GPZDA,201530.00,04,07,2002,00,00*6\r\n", "bad_checksum"),
        (b"$GPZDA,201530.00,04,07,2002,00,00*6G\r\n", "bad_checksum"),
        (b"$\r\n", "truncated"),
        (b"$GPZDA,2015\x00\x00\x00   \r\n", "binary"),
        (line(b"GPN,00000.0000,E,0,00,0.0,,M,,M,,"), "bad_address"),
        (line(b""), "malformed"),
    ],
)
def test_bad_line_is_counted_and_next_good_line_is_kept(bad, reason):
    good = line(b"GPZDA,201530.00,04,07,2002,00,00")
    out, st = frame(good + bad + good)
    assert len(out) == 2
    assert st.rejected == {reason: 1}
    assert st.examples[reason]


def test_line_cut_by_next_dollar_is_truncated_and_next_sentence_kept():
    # isync.log style: a GSV cut off by a $PTNTA injected into its middle
    tail = line(b"PTNTA,20160203131539,2,T4,000000066,+107,3,0,3")
    out, st = frame(b"$GPGSV,4,1,15,02,11,115,36,0" + tail)
    assert [s.address for s in out] == ["PTNTA"]
    assert st.rejected == {"truncated": 1}


def test_checksum_followed_directly_by_dollar_is_accepted():
    # gp-320fw style: "*1E$GPRMC..." without a line terminator in between
    a, b = line(b"GPGSA,A,1,,,,,,,,,,,,,,,", b""), line(b"GPZDA,201530.00,04,07,2002,00,00")
    out, st = frame(a + b)
    assert [s.address for s in out] == ["GPGSA", "GPZDA"]
    assert st.events["no_terminator"] == 1 and st.total_rejected == 0


def test_end_of_stream_inside_line_is_truncated():
    out, st = frame(line(b"GPZDA,201530.00,04,07,2002,00,00") + b"$GPGGA,1234")
    assert len(out) == 1 and st.rejected == {"truncated": 1}


def test_ten_kilobyte_line_is_rejected_once_and_not_buffered():
    fr = NmeaFramer(max_line=512)
    junk = b"$GPGGA," + b"1," * 5000  # 10 kB without terminator
    fr.feed(junk)
    assert len(fr._buf) <= 512  # bounded memory while the line is still going
    out = fr.feed(b"\r\n" + line(b"GPZDA,201530.00,04,07,2002,00,00")) + fr.flush()
    assert len(out) == 1
    assert fr.stats.rejected == {"too_long": 1}


def test_lines_up_to_the_cap_are_accepted_and_counted_long():
    body = b"PXYZ," + b"9" * 300
    out, st = frame(line(body), max_line=512)
    assert len(out) == 1 and st.events["long_line"] == 1


def test_binary_between_sentences_is_skipped_and_counted():
    ubx = bytes([0xB5, 0x62, 0x01, 0x07, 0x5C, 0x00]) + bytes(range(256)) * 2  # contains '$' and '!'
    good = line(b"GPZDA,201530.00,04,07,2002,00,00")
    out, st = frame(good + ubx + good + ubx + good)
    assert len(out) == 3
    assert st.garbage_bytes > 0
    assert set(st.rejected) <= {"binary", "truncated"}


def test_comment_lines_are_skipped_and_quoted_sentences_counted():
    quoted = line(b"GPGSV,3,3,12,2,40,16,00,090,", b"")
    data = b"# header\n# quoting " + quoted + b"\n" + line(b"GPZDA,201530.00,04,07,2002,00,00")
    out, st = frame(data)
    assert [s.address for s in out] == ["GPZDA"]
    assert st.comment_lines == 2 and st.events["start_in_comment"] == 1
    out2, st2 = frame(data, skip_comments=False)
    assert [s.address for s in out2] == ["GPGSV", "GPZDA"]


def test_comment_ended_by_control_byte_does_not_hide_sentence():
    # binary data that happens to contain LF '#' followed by a NUL, then a sentence
    data = b"\x01\n#\x00\x05" + line(b"GPZDA,201530.00,04,07,2002,00,00")
    out, _ = frame(data)
    assert len(out) == 1


def test_result_does_not_depend_on_chunk_boundaries():
    good = line(b"GPZDA,201530.00,04,07,2002,00,00")
    data = b"$$" + good[1:] + b"\x00\xff$GPG" + good + b"$GPZDA,1*00\r\n" + good + b"xx" * 300 + good
    ref, ref_st = frame(data)
    fr = NmeaFramer()
    got = []
    for i in range(len(data)):
        got += fr.feed(data[i : i + 1])
    got += fr.flush()
    assert got == ref
    assert fr.stats.rejected == ref_st.rejected and fr.stats.garbage_bytes == ref_st.garbage_bytes


def test_max_line_below_nmea_limit_is_refused():
    with pytest.raises(ValueError, match="max_line"):
        NmeaFramer(max_line=40)

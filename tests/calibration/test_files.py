"""calibration.files: atomic writes (an interrupted write leaves the old file whole) and
the checks every reader makes on its input path."""

from __future__ import annotations

import os
import stat

import pytest

from calibration.files import TextLines, atomic_output, read_text, write_atomic


class Refused(ValueError):
    pass


def test_write_replaces_atomically_and_keeps_the_mode(tmp_path):
    p = tmp_path / "params.json"
    write_atomic(p, "one\n")
    assert p.read_text() == "one\n"
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~umask
    p.chmod(0o640)
    write_atomic(p, "two\n")
    assert p.read_text() == "two\n" and stat.S_IMODE(p.stat().st_mode) == 0o640
    assert sorted(f.name for f in tmp_path.iterdir()) == ["params.json"]


def test_an_interrupted_write_leaves_the_old_file_whole(tmp_path):
    p = tmp_path / "report.html"
    p.write_text("the old report")
    with pytest.raises(OSError, match="No space left"), atomic_output(p) as tmp:
        tmp.write_text("half a new rep")
        raise OSError(28, "No space left on device")
    assert p.read_text() == "the old report"
    assert sorted(f.name for f in tmp_path.iterdir()) == ["report.html"]


def test_the_temporary_file_keeps_the_suffix_and_a_symlink_is_kept(tmp_path):
    target = tmp_path / "real.png"
    target.write_bytes(b"old")
    link = tmp_path / "plot.png"
    link.symlink_to(target)
    with atomic_output(link) as tmp:
        assert tmp.suffix == ".png" and tmp.parent == tmp_path
        tmp.write_bytes(b"new")
    assert link.is_symlink() and target.read_bytes() == b"new"


def test_a_device_is_written_directly(tmp_path):
    write_atomic(os.devnull, "discarded")
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode)


@pytest.mark.parametrize("make, message", [
    (lambda p: None, "no such file"),
    (lambda p: p.mkdir(), "is a directory"),
    (lambda p: os.mkfifo(p), "FIFO"),
    (lambda p: p.write_bytes("a,b\nc,\xe9\n".encode("latin-1")), "line 2: byte 0xe9"),
    (lambda p: p.write_bytes("x".encode("utf-16")), "UTF-16"),
    (lambda p: p.write_bytes(b"a\x00b"), "NUL byte"),
    (lambda p: p.write_bytes(b"x" * 2000), "too large"),
])
def test_reading_refuses_what_is_not_a_text_file(tmp_path, make, message):
    p = tmp_path / "in.csv"
    make(p)
    with pytest.raises(Refused, match=message) as e:
        read_text(p, Refused, "CSV file", max_bytes=1000)
    assert str(p) in str(e.value) and "\n" not in str(e.value)


def test_special_files_and_missing_folders(tmp_path):
    with pytest.raises(Refused, match="not a regular file"):
        read_text("/dev/zero", Refused)
    with pytest.raises(Refused, match="folder .*nofolder does not exist"):
        read_text(tmp_path / "nofolder" / "x.csv", Refused)
    p = tmp_path / "bom.csv"
    p.write_bytes(b"\xef\xbb\xbfq1,q2\r\n")
    assert read_text(p, Refused) == "q1,q2\r\n"


@pytest.mark.parametrize("raw", [
    b"", b"a", b"a\n", b"\n\n", b"\xef\xbb\xbfq1,q2\r\nx\ry\x0bz\x0c\n",
    "é,ü\u2028x\x85y\r\n\r\n".encode(), b"a\r\nb\r\n" * 50 + b"c",
])
@pytest.mark.parametrize("block", [1, 3, 7, 1 << 20])
def test_lines_read_a_block_at_a_time_are_the_lines_of_the_text(tmp_path, raw, block,
                                                                 monkeypatch):
    p = tmp_path / "in.csv"
    p.write_bytes(raw)
    monkeypatch.setattr(TextLines, "BLOCK", block)
    want = list(enumerate(read_text(p, Refused).splitlines(), start=1))
    assert list(TextLines(p, Refused)) == want


@pytest.mark.parametrize("raw", [
    b"a,b\nc,\xe9\n", b"\xef\xbb\xbfa\nb,\xff,c\n", b"a\x00b\n" + b"x\n" * 30 + b"\xfe\n",
    b"a\n" * 30 + b"b\x00\n" + b"c\n" * 30, b"\x00" + b"a\n" * 30 + b"\xfe",
    "x".encode("utf-16"),
])
@pytest.mark.parametrize("block", [1, 5, 1 << 20])
def test_lines_read_a_block_at_a_time_say_the_error_reading_the_text_says(
        tmp_path, raw, block, monkeypatch):
    p = tmp_path / "in.csv"
    p.write_bytes(raw)
    monkeypatch.setattr(TextLines, "BLOCK", block)
    with pytest.raises(Refused) as want:
        read_text(p, Refused, "CSV file")
    with pytest.raises(Refused) as got:
        list(TextLines(p, Refused, "CSV file"))
    assert str(got.value) == str(want.value)
    lines = TextLines(p, Refused, "CSV file")  # a caller that stops at its own error
    with pytest.raises(Refused) as got:
        next(iter(lines), None)
        lines.check_rest()
    assert str(got.value) == str(want.value)


def test_a_byte_order_mark_does_not_shift_the_bad_byte_named(tmp_path):
    p = tmp_path / "in.csv"
    p.write_bytes(b"\xef\xbb\xbfab,c\nd,\xe9\n")
    with pytest.raises(Refused, match="line 2: byte 0xe9"):
        read_text(p, Refused)

"""Tests of acquire/atomic_file.py: files written whole or not at all, with a plain file's permissions."""

import os
import stat

import pytest

from livedic.acquire.atomic_file import TEMP_PREFIX, AtomicFile, OutputError, atomic_files, current_umask


def _names(folder):
    return sorted(os.listdir(folder))


def test_commit_puts_the_whole_file_in_place_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "out.csv"
    path.write_text("yesterday")
    with AtomicFile(path) as out:
        out.write("a,b\r\n")
        out.write("1,2\n")
        assert path.read_text() == "yesterday"              # the old file stays until the commit
        assert out.tmp.startswith(str(tmp_path / TEMP_PREFIX)) and out.tmp.endswith(".partial")
        out.commit()
    assert path.read_bytes() == b"a,b\r\n1,2\n"              # no newline translation
    assert _names(tmp_path) == ["out.csv"]


def test_an_error_or_no_commit_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "out.bin"
    path.write_bytes(b"old")
    with pytest.raises(RuntimeError):
        with AtomicFile(path, binary=True) as out:
            out.write(b"half")
            raise RuntimeError("writer failed")
    with AtomicFile(path, binary=True) as out:
        out.write(b"never committed")
    assert path.read_bytes() == b"old" and _names(tmp_path) == ["out.bin"]


def test_the_file_gets_the_permissions_of_a_plain_open(tmp_path):
    previous = os.umask(0o027)
    try:
        assert current_umask() == 0o027
        with AtomicFile(tmp_path / "atomic.txt") as out:
            out.write("x")
            out.commit(sync=True)
        with open(tmp_path / "plain.txt", "w") as plain:
            plain.write("x")
    finally:
        os.umask(previous)
    modes = [stat.S_IMODE(os.stat(tmp_path / name).st_mode) for name in ("atomic.txt", "plain.txt")]
    assert modes == [0o640, 0o640]


def test_a_suffix_keeps_the_extension_for_writers_that_choose_by_it(tmp_path):
    out = AtomicFile(tmp_path / "movie.mp4", binary=True, suffix=".mp4")
    assert out.tmp.endswith(".partial.mp4")
    out.discard()
    out.discard()                                          # twice is harmless
    assert _names(tmp_path) == []


def test_a_folder_or_a_missing_folder_is_one_output_error(tmp_path):
    with pytest.raises(OutputError, match="is a folder: give a file name"):
        AtomicFile(tmp_path)
    with pytest.raises(OutputError, match="folder .*missing.* does not exist"):
        AtomicFile(tmp_path / "missing" / "out.csv")
    assert issubclass(OutputError, ValueError)


def test_a_folder_that_appears_before_the_commit_is_an_output_error(tmp_path):
    path = tmp_path / "out.csv"
    out = AtomicFile(path)
    out.write("x")
    (path / "inner").mkdir(parents=True)
    with pytest.raises(OutputError, match="is a folder"):
        out.commit()
    assert _names(tmp_path) == ["out.csv"] and os.path.isdir(path)


def test_several_files_are_written_all_or_none(tmp_path):
    folder = tmp_path / "new" / "deeper"
    with atomic_files({"csv": folder / "a.csv", "bin": folder / "b.bin"}, binary={"bin"}) as files:
        files["csv"].write("text")
        files["bin"].write(b"\x00\x01")
    assert (folder / "a.csv").read_text() == "text" and (folder / "b.bin").read_bytes() == b"\x00\x01"
    failed = tmp_path / "failed"
    with pytest.raises(KeyError):
        with atomic_files({"one": failed / "1.csv", "two": failed / "2.csv"}) as files:
            files["one"].write("x")
            raise KeyError("second writer")
    assert not failed.exists()                             # the folder it created is removed again
    with pytest.raises(OutputError):
        with atomic_files({"good": tmp_path / "good.csv", "bad": folder}):
            pass
    assert not (tmp_path / "good.csv").exists() and not any(n.startswith(TEMP_PREFIX) for n in _names(tmp_path))

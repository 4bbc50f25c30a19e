import os
import time
import stat

import pytest

from quadnodes.errors import ExportError
from quadnodes.io import _atomic
from quadnodes.io._atomic import write_atomic, write_bytes_atomic, write_text_atomic


def test_writes_and_returns_the_path(tmp_path):
    p = write_text_atomic(str(tmp_path / "a.txt"), "hello\n")
    assert p == tmp_path / "a.txt"
    assert p.read_text() == "hello\n"
    assert write_bytes_atomic(tmp_path / "b.bin", b"\x00\x01").read_bytes() == b"\x00\x01"
    assert sorted(os.listdir(tmp_path)) == ["a.txt", "b.bin"]


def test_replaces_an_existing_file(tmp_path):
    p = tmp_path / "a.txt"
    p.write_text("old")
    write_text_atomic(p, "new")
    assert p.read_text() == "new"
    assert os.listdir(tmp_path) == ["a.txt"]


def test_file_mode_follows_the_umask(tmp_path):
    old = os.umask(0o022)
    try:
        _atomic._MODE = None
        p = write_text_atomic(tmp_path / "a.txt", "x")
    finally:
        os.umask(old)
        _atomic._MODE = None
    assert stat.S_IMODE(p.stat().st_mode) == 0o644


def test_failure_mid_write_keeps_the_original_and_removes_the_temp_file(tmp_path):
    p = tmp_path / "a.txt"
    p.write_text("original")

    def half(tmp):
        with open(tmp, "w") as f:
            f.write("partial")
        raise OSError(28, "No space left on device")

    with pytest.raises(ExportError, match=r"a\.txt.*No space left") as info:
        write_atomic(p, half)
    assert isinstance(info.value.__cause__, OSError)
    assert p.read_text() == "original"
    assert os.listdir(tmp_path) == ["a.txt"]


def test_failed_rename_removes_the_temp_file(tmp_path, monkeypatch):
    p = tmp_path / "a.txt"
    p.write_text("original")

    def broken_replace(src, dst):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(_atomic.os, "replace", broken_replace)
    with pytest.raises(ExportError, match="Permission denied"):
        write_text_atomic(p, "new")
    assert p.read_text() == "original"
    assert os.listdir(tmp_path) == ["a.txt"]


def test_interrupt_is_not_converted_but_still_cleans_up(tmp_path):
    def interrupted(tmp):
        with open(tmp, "w") as f:
            f.write("partial")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomic(tmp_path / "a.txt", interrupted)
    assert os.listdir(tmp_path) == []


def test_export_error_from_the_writer_passes_through(tmp_path):
    def fails(tmp):
        raise ExportError("panel 3 (P_0_3): cannot build")

    with pytest.raises(ExportError, match=r"^panel 3 \(P_0_3\): cannot build$"):
        write_atomic(tmp_path / "a.step", fails)
    assert os.listdir(tmp_path) == []


def test_missing_folder_raises_export_error(tmp_path):
    with pytest.raises(ExportError, match="nope"):
        write_text_atomic(tmp_path / "nope" / "a.txt", "x")
    assert os.listdir(tmp_path) == []


def test_unwritable_folder_raises_export_error(tmp_path, monkeypatch):
    # simulated so that the test also means something when run as root
    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(tmp_path))

    monkeypatch.setattr(_atomic.tempfile, "mkstemp", denied)
    with pytest.raises(ExportError, match="cannot write.*Permission denied"):
        write_text_atomic(tmp_path / "a.txt", "x")
    assert os.listdir(tmp_path) == []


def test_read_only_folder_raises_export_error(read_only_folder):
    # (root ignores permission bits: the fixture injects the refusal where the OS gives it, creating the file)
    ro = read_only_folder
    with pytest.raises(ExportError, match="Permission denied"):
        write_text_atomic(ro / "a.txt", "x")
    assert os.listdir(ro) == []


def test_failed_rename_leaves_nothing_and_keeps_the_old_file(tmp_path, monkeypatch):
    (tmp_path / "a.txt").write_text("old")

    def denied(src, dst):
        raise PermissionError(13, "Permission denied", os.fspath(dst))

    monkeypatch.setattr(os, "replace", denied)
    with pytest.raises(ExportError, match="Permission denied"):
        write_text_atomic(tmp_path / "a.txt", "new")
    assert os.listdir(tmp_path) == ["a.txt"] and (tmp_path / "a.txt").read_text() == "old"


def test_a_250_character_name_is_writable(tmp_path):
    name = "p" * 246 + ".obj"
    assert len(name) == 250
    p = write_text_atomic(tmp_path / name, "v 0 0 0\n")
    assert p.read_text() == "v 0 0 0\n" and os.listdir(tmp_path) == [name]


def test_stale_temporary_files_are_removed_by_the_next_write(tmp_path, monkeypatch):
    monkeypatch.setattr(_atomic, "_SWEPT", set())
    stale = tmp_path / ".qn-k1ll3d00.tmp"
    fresh = tmp_path / ".qn-inflight.tmp"            # another process writing right now
    other = tmp_path / ".notes.tmp"                  # not ours
    for p in (stale, fresh, other):
        p.write_text("half")
    old = time.time() - 2 * _atomic.STALE_SECONDS
    os.utime(stale, (old, old))
    os.utime(other, (old, old))
    write_text_atomic(tmp_path / "a.txt", "x")
    assert sorted(os.listdir(tmp_path)) == sorted([fresh.name, other.name, "a.txt"])


def test_directory_in_the_way_raises_export_error(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(ExportError):
        write_text_atomic(tmp_path / "d", "x")
    assert os.listdir(tmp_path) == ["d"]


def test_a_folder_refusal_names_the_folder_not_the_temporary_file(tmp_path, read_only_folder):
    # the message was "cannot write 'sub/a.txt': [Errno 2] No such file or directory: '.../sub/.qn-bztvgrt2.tmp'",
    # naming a file the user never asked for
    with pytest.raises(ExportError, match=r"^cannot write '.*a\.txt': the folder '.*nope' does not exist$"):
        write_text_atomic(tmp_path / "nope" / "a.txt", "x")
    (tmp_path / "file").write_text("")
    with pytest.raises(ExportError, match=r"^cannot write '.*a\.txt': '.*file' is not a folder$"):
        write_text_atomic(tmp_path / "file" / "a.txt", "x")
    ro = read_only_folder
    with pytest.raises(ExportError, match=r"^cannot write '.*a\.txt': cannot create a file in the folder '.*ro' "
                                         r"\(Permission denied\)$"):
        write_text_atomic(ro / "a.txt", "x")

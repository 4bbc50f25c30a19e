"""Cutting a count into per-thread ranges (``split_ranges``)."""

from __future__ import annotations

from unittest import mock

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.linalg import threads as linalg_threads
from quadnodes.linalg.threads import split_ranges


@settings(max_examples=300, deadline=None)
@given(count=st.integers(0, 10**7), parts=st.integers(1, 9), align=st.integers(1, 64))
def test_split_ranges_cover_the_count_in_aligned_ranges(count, parts, align):
    ranges = split_ranges(count, parts=parts, align=align)
    # contiguous from 0 to count, none empty unless count is 0
    assert ranges[0][0] == 0 and ranges[-1][1] == count
    assert all(a[1] == b[0] for a, b in zip(ranges, ranges[1:]))
    assert all(hi > lo for lo, hi in ranges) or ranges == [(0, 0)]
    # every cut but the end aligned, and at most parts ranges; exactly min(parts, count) unaligned
    assert all(lo % align == 0 for lo, _ in ranges)
    assert 1 <= len(ranges) <= parts
    if align == 1:
        assert len(ranges) == max(1, min(parts, count))
    # the cuts are count * i // parts rounded down to the alignment
    p = max(1, min(parts, count))
    assert {lo for lo, _ in ranges} == {count * i // p // align * align for i in range(p)}


@settings(max_examples=200, deadline=None)
@given(count=st.integers(0, 10**6), min_size=st.integers(1, 10**5), threads=st.integers(1, 4))
def test_split_ranges_default_parts_follow_threads_and_min_size(count, min_size, threads):
    with mock.patch.object(linalg_threads, "thread_count", lambda: threads):
        ranges = split_ranges(count, min_size=min_size)
    assert len(ranges) == max(1, min(threads, count // min_size))
    assert ranges[0][0] == 0 and ranges[-1][1] == count
    sizes = [hi - lo for lo, hi in ranges]
    assert max(sizes) - min(sizes) <= 1  # about equal
    if len(ranges) > 1:
        assert min(sizes) >= min_size


def test_split_ranges_refuses_bad_arguments():
    for kwargs in ({"count": -1}, {"count": 5, "parts": 0}, {"count": 5, "min_size": 0}, {"count": 5, "align": 0}):
        with pytest.raises(ValueError, match="split_ranges"):
            split_ranges(**kwargs)


def test_the_blas_scan_cue_cannot_deadlock_a_thread_loading_shared_objects(tmp_path):
    """One thread asks for the shared-object count (as the kernel loader's BLAS scan does) while another loads new
    shared objects with the GIL held (as an extension module's import does; here ``ctypes.CDLL`` of 120 fresh copies
    of a small one). Counted by ``dl_iterate_phdr`` with a callback into Python, this deadlocked every time (the
    callback waits for the GIL under glibc's loader lock, ``dlopen`` waits for that lock holding the GIL); ``quadnodes
    watch`` hung so in CI. In a child process, with a timeout."""
    import importlib.util
    import subprocess
    import sys
    import textwrap

    small = next((spec.origin for spec in map(importlib.util.find_spec, ("_bisect", "_heapq", "_json", "_csv", "_lsprof"))
                  if spec is not None and str(spec.origin).endswith(".so")), None)
    if small is None:
        pytest.skip("no small extension module in a shared object to copy")
    code = textwrap.dedent(
        f"""
        import ctypes, shutil, threading
        from quadnodes.linalg import threads
        paths = [shutil.copy({small!r}, {str(tmp_path)!r} + f"/lib{{i}}.so") for i in range(120)]
        stop = []
        def count():
            while not stop:
                threads._library_count()
        t = threading.Thread(target=count, daemon=True)
        t.start()
        for p in paths:
            ctypes.CDLL(p)
        stop.append(True)
        t.join(10)
        print("ok")
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"

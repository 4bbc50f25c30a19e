"""quadnodes.linalg.heap: scoped heap reuse for big temporaries."""

import threading

import numpy as np

from quadnodes.linalg import heap


def test_nested_and_concurrent_uses_restore_once_and_results_are_unchanged(monkeypatch):
    calls = []

    class FakeLibc:
        def mallopt(self, param, value):
            calls.append(("mallopt", param, value))
            return 1

        def malloc_trim(self, pad):
            calls.append(("trim", pad))
            return 1

    monkeypatch.setattr(heap, "_LIBC", FakeLibc())
    a = np.arange(1000.0)
    with heap.reused_heap():
        with heap.reused_heap():
            inner = float((a * 2).sum())
        assert ("trim", 0) not in calls  # the outer use still runs
    assert inner == float((a * 2).sum())
    assert calls[:2] == [("mallopt", heap._M_TRIM_THRESHOLD, 2**31 - 1), ("mallopt", heap._M_MMAP_MAX, 0)]
    assert calls[-1] == ("trim", 0) and ("mallopt", heap._M_MMAP_MAX, heap._DEFAULT_MMAP_MAX) in calls
    assert heap._DEPTH == 0

    calls.clear()
    barrier = threading.Barrier(2)

    def worker():
        with heap.reused_heap():
            barrier.wait()

    threads = [threading.Thread(target=worker) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sum(c[0] == "trim" for c in calls) == 1 and heap._DEPTH == 0


def test_an_exception_inside_still_restores(monkeypatch):
    seen = []

    class FakeLibc:
        def mallopt(self, param, value):
            seen.append(param)
            return 1

        def malloc_trim(self, pad):
            seen.append("trim")
            return 1

    monkeypatch.setattr(heap, "_LIBC", FakeLibc())
    try:
        with heap.reused_heap():
            raise ValueError("inside")
    except ValueError:
        pass
    assert seen[-1] == "trim" and heap._DEPTH == 0


def test_the_real_libc_takes_the_settings():
    if heap._LIBC is None:
        return  # not glibc: reused_heap does nothing (tested above with a stand-in)
    with heap.reused_heap():
        big = np.ones(5_000_000)  # 40 MB: from the heap here
        assert float(big.sum()) == 5e6


def test_numpy_huge_pages_are_off_inside_and_restored_by_the_last_to_leave(monkeypatch):
    state = {"on": True}
    seen = []

    def switch(enabled):
        seen.append(enabled)
        previous, state["on"] = state["on"], bool(enabled)
        return previous

    monkeypatch.setattr(heap, "_NUMPY_HUGE_PAGES", switch)
    with heap.reused_heap():
        assert state["on"] is False
        with heap.reused_heap():
            assert state["on"] is False
        assert state["on"] is False  # the outer use still runs
    assert state["on"] is True and seen == [False, True] and heap._DEPTH == 0
    state["on"] = False  # a process that had switched them off itself keeps them off
    with heap.reused_heap():
        pass
    assert state["on"] is False and heap._DEPTH == 0


def test_the_users_numpy_huge_page_setting_is_left_alone(monkeypatch):
    monkeypatch.setenv("NUMPY_MADVISE_HUGEPAGE", "1")
    assert heap._numpy_huge_pages() is None
    monkeypatch.delenv("NUMPY_MADVISE_HUGEPAGE")
    switch = heap._numpy_huge_pages()
    assert switch is not None  # NumPy ≥ 1.26 has it (numpy._core or numpy.core)
    monkeypatch.setattr(heap, "_NUMPY_HUGE_PAGES", switch)  # (whatever this process's environment said)
    previous = switch(True)
    try:
        with heap.reused_heap():
            assert switch(False) is False  # (it was off inside)
        assert switch(True) is True  # and restored on leaving
    finally:
        switch(previous)


def test_a_setting_refused_on_entry_leaves_no_use_behind(monkeypatch):
    state = {"on": True}

    def switch(enabled):
        previous, state["on"] = state["on"], bool(enabled)
        return previous

    class RefusingLibc:
        def mallopt(self, param, value):
            raise OSError("mallopt refused")

        def malloc_trim(self, pad):
            return 1

    monkeypatch.setattr(heap, "_NUMPY_HUGE_PAGES", switch)
    monkeypatch.setattr(heap, "_LIBC", RefusingLibc())
    try:
        with heap.reused_heap():
            raise AssertionError("not entered")
    except OSError:
        pass
    assert heap._DEPTH == 0 and state["on"] is True and not heap._HUGE_PAGES

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

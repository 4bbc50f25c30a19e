"""NumPy's ``np.unique`` against sorting, on mesh-sized integer arrays.

Backs the session-8 entry "``np.unique`` in NumPy 2.3+ hashes integer keys" in docs/design-notes.md and the
choice of ``quadnodes._arrays`` (``unique_values``, ``unique_rows``) for the package's calls on mesh-sized
arrays. Inputs (seeded): ``n`` distinct int64 keys in random order (as vertex-pair keys are), and ``n`` index
pairs below ``n`` with repeats (as a mesh's sorted edges are: each interior edge twice). Prints the best of
``--repeat`` wall times of each and checks that the results are equal.

Run:  python benchmarks/studies/unique_sort.py [--sizes 100000 1000000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from quadnodes._arrays import unique_rows, unique_values


def _best(fn, repeat: int) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print(f"NumPy {np.__version__}")
    print("| input | n | np.unique (s) | sort-based, quadnodes._arrays (s) | equal |")
    print("|---|---:|---:|---:|---|")
    for n in args.sizes:
        rng = np.random.default_rng(0)
        keys = rng.permutation(n).astype(np.int64) * 7919
        pairs = rng.integers(0, n, size=(n // 2, 2))
        pairs = np.sort(np.concatenate([pairs, pairs[::-1]]), axis=1)
        for name, ref, ours, data in (("int64 keys", np.unique, unique_values, keys),
                                      ("index pairs (axis=0)", lambda a: np.unique(a, axis=0), unique_rows, pairs)):
            t_ref, r = _best(lambda: ref(data), args.repeat)
            t_ours, o = _best(lambda: ours(data), args.repeat)
            print(f"| {name} | {n:,} | {t_ref:.3f} | {t_ours:.3f} | {np.array_equal(r, o)} |", flush=True)


if __name__ == "__main__":
    main()

"""When does local/global stagnate? The rule behind ``planarize(method="auto")``'s early Gauss–Newton.

Backs "When auto hands over early" in docs/planarize.md (``STALL_DOUBLINGS``, ``STALL_PROGRESS``).
For every benchmark case of ``benchmarks/perf/bench_planarize.py`` (E1–E4 and F100, built by the
same recipe: seeded noise, then ``fair(noisy, iterations=3)``) and each reference (clean mesh,
build123d face, none), runs ``planarize(method="local-global")`` with its defaults and replays the
adaptive weight's rule on the history (a doubling where the planarity gained < 1 % over 10
iterations). Columns: iterations and whether local/global met the tolerance; the least gain of any
3 consecutive doublings (1 − planarity after / planarity before: the stagnation test fires when it
is below 5 %), up to the first firing; the iteration where the test first fires (— if never).

Run:  python benchmarks/studies/planarize_stall.py [--quick]   (--quick: E1–E4 only; F100 adds ~2 min)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402


def doublings(history: list[float]) -> list[int]:
    """Iterations (1-based) where the adaptive planarity weight doubled, replayed from the history."""
    out, last = [], 0
    for it in range(10, len(history) + 1):
        if it - last >= 10 and history[it - 1] > 0.99 * history[it - 10]:
            out.append(it)
            last = it
    return out


def main() -> None:
    from quadnodes.planarization import STALL_DOUBLINGS, STALL_PROGRESS, planarize

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="E1–E4 only")
    args = ap.parse_args()
    k = STALL_DOUBLINGS
    print(f"| mesh | reference | iterations | met | least gain over {k} doublings | stagnation test fires at |")
    print("|---|---|---:|---|---:|---:|")
    for name in ("E1", "E2", "E3", "E4") + (() if args.quick else ("F100",)):
        face, clean, faired = _common.planarize_case(name)
        _ = faired.topology.windows
        for label, ref in (("clean mesh", clean), ("face", face), ("none", None)):
            _, rep = planarize(faired, reference=ref, method="local-global")
            h = rep.history
            at = doublings(h)
            gains = [1 - h[at[j] - 1] / h[at[j - k] - 1] for j in range(k, len(at))]
            fires = [at[j] for j, g in zip(range(k, len(at)), gains) if g < STALL_PROGRESS]
            if fires:  # up to the first firing (later, at the weight cap, the planarity may jump back up)
                gains = gains[: at.index(fires[0]) - k + 1]
            print(f"| {name} | {label} | {rep.iterations} | {'yes' if rep.converged else 'no'} "
                  f"| {min(gains):.1%} | {fires[0] if fires else '—'} |" if gains else
                  f"| {name} | {label} | {rep.iterations} | {'yes' if rep.converged else 'no'} | — | — |", flush=True)


if __name__ == "__main__":
    main()

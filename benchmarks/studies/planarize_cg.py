"""The local/global global step at 300² and 1000²: which CG set-up pays (storage × preconditioner).

Backs the choice in docs/planarize.md ("After issue 15, item 3") of plain CG in diagonal storage for
planarize's global step above 20,000 free vertices. The system is the one ``planarize`` solves in its
first iteration on the F100 recipe at ``size × size`` (``benchmarks/perf/bench_planarize.py``'s
``--iteration`` input, reference = clean mesh, corners held, ``w_p = 1``), from the current positions,
to its relative residual 1e-8 (``LARGE_RTOL``). Rows: ``QuadraticProblem`` with ``storage`` "csr" or
"diagonal" and ``preconditioner`` "none", "jacobi", "block-jacobi"; and the line preconditioner
(``linalg.cg.PathLinePreconditioner`` along the grid's rows and columns, half-bandwidth 2) on CSR.
Columns: set-up CPU, CG steps, solve wall and CPU, largest difference from the first row.

``--peers`` adds issue 15's peers on the same system (the unknowns' block ``Q_uu`` and its right-hand side, all
coordinates): SciPy's SuperLU (COLAMD; at 1000² only with ``--slow``: minutes and gigabytes, as in
``bench_core.py``), CG preconditioned by pyamg's smoothed aggregation from the same guess to the same rtol, and
CHOLMOD's supernodal Cholesky where scikit-sparse is installed (``pip install -e .[bench]``); their set-up
(factorization, hierarchy) and solve in one, as "solve".

Run:  python benchmarks/studies/planarize_cg.py [--size 300|1000] [--cache] [--peers [--slow]]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402  (bench_planarize.py's --iteration input, optionally cached)


def captured_system(size: int, cache: bool):
    """(Q, keyword arguments, B, Y, guess) of planarize's first global step on the recipe at ``size``."""
    import quadnodes.linalg.quadratic as Qm
    import quadnodes.planarization as P

    clean, faired = _common.planarize_big_case(size, cache)
    _ = faired.topology.windows
    got: dict = {}
    init, solve = Qm.QuadraticProblem.__init__, Qm.QuadraticProblem.solve

    def spy_init(self, Q, **kw):
        got.setdefault("init", (Q, kw))
        init(self, Q, **kw)

    def spy_solve(self, B, *, Y=None, Beq=None, guess=None):
        got.setdefault("solve", (B, Y, guess))
        return solve(self, B, Y=Y, Beq=Beq, guess=guess)

    Qm.QuadraticProblem.__init__, Qm.QuadraticProblem.solve = spy_init, spy_solve
    limit = P.DIRECT_LIMIT
    P.DIRECT_LIMIT = 10  # (the CG global step at every size)
    try:
        P.planarize(faired, reference=clean, method="local-global", adapt=False, max_iterations=1)
    finally:
        Qm.QuadraticProblem.__init__, Qm.QuadraticProblem.solve = init, solve
        P.DIRECT_LIMIT = limit
    return (*got["init"], *got["solve"])


def main() -> None:
    from quadnodes.linalg import QuadraticProblem, compiled
    from quadnodes.linalg.cg import PathLinePreconditioner, block_cg
    from quadnodes.linalg.threads import RowBlocks

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=300)
    ap.add_argument("--cache", action="store_true", help="reuse out/bench-cache/ (see bench_planarize.py)")
    ap.add_argument("--peers", action="store_true", help="also SuperLU, pyamg-preconditioned CG and CHOLMOD")
    ap.add_argument("--slow", action="store_true", help="with --peers: SuperLU above 300² too")
    args = ap.parse_args()
    Q, kw, B, Y, guess = captured_system(args.size, args.cache)
    compiled.wait()  # (loaded before timing: its one-off cost is not the solve's)
    print(f"F100 recipe at {args.size}×{args.size}, {Q.shape[0] - len(kw.get('known', []))} unknowns, "
          f"rtol {kw['rtol']:g}\n")
    print("| storage | preconditioner | set-up CPU (s) | CG steps | solve wall (s) | solve CPU (s) | max difference |")
    print("|---|---|---:|---:|---:|---:|---:|")
    first = None
    for storage in ("csr", "diagonal"):
        for pre in ("none", "jacobi", "block-jacobi"):
            c = time.process_time()
            qp = QuadraticProblem(Q, **{**kw, "storage": storage, "preconditioner": pre})
            setup = time.process_time() - c
            t, c = time.perf_counter(), time.process_time()
            z = qp.solve(B, Y=Y, guess=guess)
            wall, cpu = time.perf_counter() - t, time.process_time() - c
            first = z if first is None else first
            print(f"| {qp.storage} | {pre} | {setup:.2f} | {qp.iterations} | {wall:.2f} | {cpu:.2f} "
                  f"| {np.abs(z - first).max():.1e} |", flush=True)
    # the line preconditioner along the grid's rows and columns (paths broken at the held corners)
    qp = QuadraticProblem(Q, **{**kw, "storage": "csr"})
    n = args.size
    rank = -np.ones(n * n, dtype=np.int64)
    rank[qp.unknown] = np.arange(qp.unknown.size)
    paths, starts = [], []
    for lines in (rank.reshape(n, n), rank.reshape(n, n).T):
        flat = lines.reshape(-1)
        ok = flat >= 0
        st = np.zeros(flat.size, dtype=bool)
        st[::n] = True
        st |= np.r_[True, ~ok[:-1]]
        paths.append(flat[ok])
        starts.append(st[ok])
    c = time.process_time()
    pc = PathLinePreconditioner(qp._Quu, np.concatenate(paths), np.concatenate(starts), kd=2)
    setup = time.process_time() - c
    rhs = -B[qp.unknown] - qp._Quk @ Y
    t, c = time.perf_counter(), time.process_time()
    zu, its, _ = block_cg(RowBlocks(qp._Quu), rhs, guess, rtol=kw["rtol"], maxiter=20000, precond=pc)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    print(f"| csr | lines (rows and columns) | {setup:.2f} | {its} | {wall:.2f} | {cpu:.2f} "
          f"| {np.abs(zu - first[qp.unknown]).max():.1e} |", flush=True)
    if args.peers:
        _peers(qp._Quu.tocsr(), rhs, guess, kw["rtol"], first[qp.unknown], superlu=args.size <= 300 or args.slow)


def _peers(M, rhs: np.ndarray, guess: np.ndarray, rtol: float, reference: np.ndarray, superlu: bool) -> None:
    """Rows of the peers on ``M x = rhs`` (every column, ``_common.peer_solve``), against ``reference``."""
    import importlib.util

    peers = [("superlu", "scipy", "SciPy SuperLU (COLAMD), factorized and solved")] if superlu else []
    peers += [("pyamg", "pyamg", "CG + pyamg smoothed aggregation (hierarchy included)"),
              ("cholmod", "sksparse", "CHOLMOD supernodal Cholesky, factorized and solved")]
    for kind, module, name in peers:
        if importlib.util.find_spec(module) is None:
            print(f"| peer | {kind}: {module} not installed | | | | | |")
            continue
        t, c = time.perf_counter(), time.process_time()
        x = _common.peer_solve(kind, M, rhs, guess, rtol)
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        print(f"| peer | {name} | — | — | {wall:.2f} | {cpu:.2f} | {np.abs(x - reference).max():.1e} |", flush=True)


if __name__ == "__main__":
    main()

"""Gauss–Seidel sweeps around the spectral preconditioner: half the steps, and what a step then costs.

Backs docs/fairing.md "Tried: Gauss–Seidel around the transforms" (issue 15: coefficients that vary at random, the
torus's 41 steps) and the session-21 entry of docs/design-notes.md.

The spectral preconditioner (:class:`quadnodes.linalg.spectral.SpectralPreconditioner`) inverts a model with one
coefficient per family (or a profile along an axis); where the windows' coefficients vary at random — broadband
noise as large as a short edge, the bench torus's tube edges — CG needs the steps that the model's spread costs.
The symmetric cycle

    ``x = (D + L)⁻¹ r``,  ``x += K⁻¹ (r − M x)``,  ``x += (D + U)⁻¹ (r − M x)``

(a forward Gauss–Seidel sweep, the spectral inverse ``K⁻¹``, a backward sweep: the two-grid cycle of
:mod:`quadnodes.linalg.multigrid` with the transforms in place of the coarse grid) damps what the model misses
locally. For every ``--meshes`` (``sheet``: the bench sheet; ``graded``: its columns' spacing growing tenfold;
``torus``: the bench torus; all with broadband noise of 0.2 edge lengths, ``benchmarks/_common.py``) and weight it
builds fair()'s first-iteration system (every window middle free, ``line_spacing="fair"``, the compiled kernels
loaded), and solves it to fair's rtol with CG preconditioned by the spectral preconditioner alone
(``preconditioner="spectral"``: exact lines) and by the cycle around the same object. Prints steps, solve
seconds (set-up excluded, one run), the largest difference between the two results over the mesh's extent, and
the parts of a step measured alone (median of 20): the spectral application, a matrix product, a forward and a
backward sweep. "fused" is what a step of the cycle would cost at best — the application, the two sweeps and
one product, the residuals folded as in Eisenstat's form — times the cycle's steps.

Run:  python benchmarks/studies/spectral_smoothing.py [--size 300] [--meshes sheet graded torus]
            [--weights 0.3 0.0001]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402


def _system(kind: str, n: int, weight: float):
    """``(mesh, free, make)``: ``make(preconditioner)`` builds fair()'s first-iteration system."""
    from quadnodes.fairing import FairingSystem, even_lengths
    from quadnodes.mesh import QuadMesh
    from quadnodes.zigzag import detect, line_gaps, window_edges

    noisy = {"torus": lambda: _common.noisy_torus(n, n), "sheet": lambda: _common.noisy_grid(n, "broadband"),
             "graded": lambda: _common.noisy_graded(n, 10.0)}[kind]()
    m = QuadMesh(noisy.vertices, noisy.faces)
    found = detect(m, 0.0)
    free = line_gaps(found.free, m.topology.windows, found.fixed)  # (fair()'s: gaps="auto" fills them)
    inverse = even_lengths(1.0 / np.sqrt(np.stack(
        [np.einsum("ij,ij->i", d, d) for d in window_edges(m.vertices, m.topology.windows)], axis=1)))

    def make(preconditioner: str) -> FairingSystem:
        return FairingSystem(m.vertices, m.topology.windows, free, weight / m.mean_edge_length**2, solver="cg",
                             preconditioner=preconditioner, _topology=m.topology, _inverse_lengths=inverse)

    return m, free, make


def _cycle(blocks, spectral):
    """The symmetric cycle around ``spectral`` on ``blocks``' sweeps (block_cg's ``precond``)."""
    from quadnodes.linalg.gauss_seidel import CsrGaussSeidel, SymmetricGaussSeidel
    from quadnodes.linalg.multigrid import _Cycle

    class Inverse:  # (the cycle's "coarse solve": K⁻¹ on (n, c) vectors)
        def __init__(self, n: int) -> None:
            self.n = n

        def solve(self, Y: np.ndarray) -> np.ndarray:
            R = np.ascontiguousarray(Y.T)
            Z = np.empty_like(R)
            spectral.apply(R, Z, 0, self.n, True)
            return Z.T

    class Cycle(_Cycle):
        def __init__(self) -> None:
            self.sweeps = SymmetricGaussSeidel(blocks) if hasattr(blocks, "upper") else CsrGaussSeidel(blocks)
            self._n = blocks.M.shape[0]
            self.coarse = Inverse(self._n)
            self._buffers = {}

        def restrict(self, Y: np.ndarray) -> np.ndarray:
            return Y[:, : self._n].T

        def prolong(self, E: np.ndarray, X: np.ndarray) -> None:
            X[:, : self._n] += E.T

    return Cycle()


def _parts(blocks, spectral, sweeps) -> dict[str, float]:
    """Milliseconds of one spectral application, product, forward and backward sweep on (3, n) vectors."""
    from quadnodes.linalg.gauss_seidel import backward_solve, forward_solve, sweep_scratch
    from quadnodes.linalg.threads import run_tasks

    n = blocks.M.shape[0]
    rng = np.random.default_rng(0)
    R = rng.random((3, n)) if sweeps.columns else rng.random((n, 3))
    Rc = np.ascontiguousarray(R if sweeps.columns else R.T)
    Zc, W, T, P, zero = (np.empty_like(Rc), np.empty_like(R), np.zeros_like(R), np.empty_like(R), np.zeros_like(R))
    scratch = sweep_scratch(sweeps, 3)

    def ms(f) -> float:
        f()
        times = []
        for _ in range(20):
            t = time.perf_counter()
            f()
            times.append(time.perf_counter() - t)
        return 1e3 * float(np.median(times))

    return {"apply": ms(lambda: spectral.apply(Rc, Zc, 0, n, True)),
            "product": ms(lambda: run_tasks(lambda lo, hi: blocks.matvec(Rc, Zc, lo, hi), blocks.ranges)),
            "forward": ms(lambda: forward_solve(sweeps, R, zero, W, scratch)),
            "backward": ms(lambda: backward_solve(sweeps, R, P, T, scratch))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=300)
    ap.add_argument("--meshes", nargs="+", choices=["sheet", "graded", "torus"], default=["sheet", "graded", "torus"])
    ap.add_argument("--weights", type=float, nargs="+", default=[0.3, 0.0001])
    args = ap.parse_args()
    import _fused_cycle
    from quadnodes.linalg import compiled
    from quadnodes.linalg.cg import DiagonalBlocks, SymmetricDiagonalBlocks

    compiled.wait()
    _fused_cycle.compile_kernels()
    for kind in args.meshes:  # (the fused cycle's kernels compile on first use, SciPy's transforms load: not timed)
        m, free, make = _system(kind, 24, 0.3)
        warm = make("spectral")
        blocks, spectral, _ = warm._cg_setup()
        _routed_solve(warm, _fused_cycle.SmoothedInverse(blocks, spectral), m.vertices[free])
        make("spectral").solve(m.vertices[free])
    print(f"{args.size}², broadband noise, fair()'s first-iteration system; steps · solve seconds (one run)\n")
    print("| mesh | ω | spectral | GS–spectral–GS | fused cycle (its set-up) | difference / extent "
          "| apply, product, sweeps (ms) |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for kind in args.meshes:
        for weight in args.weights:
            m, free, make = _system(kind, args.size, weight)
            alone = make("spectral")
            blocks, spectral, _ = alone._cg_setup()
            t = time.perf_counter()
            x = alone.solve(m.vertices[free])
            t_alone = time.perf_counter() - t
            open_grid = blocks.offsets.size == 13
            fine = (SymmetricDiagonalBlocks if open_grid else DiagonalBlocks)(blocks.offsets, blocks.data)
            cycled = make("spectral")
            inverse = cycled._cg_setup()[1]
            cycle = _cycle(fine, inverse)
            cycled._cg = (fine, cycle, None)
            t = time.perf_counter()
            y = cycled.solve(m.vertices[free])
            t_cycle = time.perf_counter() - t
            # the fused cycle on the spectral path's own product (its blocks), the sweeps in compressed rows
            t = time.perf_counter()
            smoothed = _fused_cycle.SmoothedInverse(blocks, spectral)
            t_setup = time.perf_counter() - t
            fused = make("spectral")
            t = time.perf_counter()
            f = _routed_solve(fused, smoothed, m.vertices[free])
            t_fused = time.perf_counter() - t
            extent = float(np.ptp(m.vertices, axis=0).max())
            p = _parts(blocks, inverse, cycle.sweeps)  # (the product the transforms' path and the fused cycle use)
            worst = max(np.abs(x - y).max(), np.abs(x - f).max()) / extent
            print(f"| {kind} | {weight:g} | {alone.iterations} · {t_alone:.3f} | {cycled.iterations} · {t_cycle:.3f} "
                  f"| {fused.iterations} · {t_fused:.3f} ({t_setup:.3f}) | {worst:.1e} "
                  f"| {p['apply']:.2f}, {p['product']:.2f}, {p['forward']:.2f} + {p['backward']:.2f} |", flush=True)


def _routed_solve(system, smoothed, anchor: np.ndarray) -> np.ndarray:
    """``system.solve(anchor)`` with ``smoothed`` as its preconditioner (on the blocks it was made for), fair's CG
    call routed to :func:`_fused_cycle.smoothed_cg`."""
    import _fused_cycle
    import quadnodes.fairing as fairing

    system._cg = (smoothed.blocks, smoothed, None)

    plain = fairing.block_cg

    def routed(blocks, B, X0, *, rtol, maxiter, precond=None):  # type: ignore[no-untyped-def]
        if precond is smoothed:
            return _fused_cycle.smoothed_cg(blocks, B, X0, rtol=rtol, maxiter=maxiter, cycle=smoothed)
        return plain(blocks, B, X0, rtol=rtol, maxiter=maxiter, precond=precond)

    fairing.block_cg = routed
    try:
        return system.solve(anchor)
    finally:
        fairing.block_cg = plain


if __name__ == "__main__":
    main()

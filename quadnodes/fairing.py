"""The thesis's structure-line fairing (chapter 4, eq. 32–34).

For every window ``p0..p3`` of every structure line, the deviation of three
consecutive unit directions is linearized by freezing the edge lengths
``l0, l1, l2`` at the current iterate::

    f = -p0/(2 l0) + (1/(2 l0) + 1/l1) p1 - (1/l1 + 1/(2 l2)) p2 + p3/(2 l2)

and the energy ``Σ_windows ||f||² + ω Σ_free ||p − anchor||²`` is minimized over
the free (zigzag) vertices, fixed vertices moving to the right-hand side. The
matrix ``AᵀA + ω I`` is the same for x, y and z: it is factorized once and solved
for three right-hand sides.

The weight is dimensionless by default: ``ω_eff = ω / h²`` with ``h`` the mean edge
length of the input, so the result does not depend on the unit of the model.
"""

from __future__ import annotations

import warnings
import weakref
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from . import _validate
from ._arrays import unique_rows
from .errors import InputError
from .linalg import factorize
from .linalg.cg import (HAS_DIAGONAL_KERNEL, BlockJacobi, DiagonalBlocks, LinePreconditioner,
                        PathLinePreconditioner, SymmetricDiagonalBlocks, block_cg, permuted,
                        strongest_lines)
from .linalg import compiled as kernels
from .linalg import spectral
from .linalg.gauss_seidel import CsrGaussSeidel, SymmetricGaussSeidel, gauss_seidel_cg
from .linalg.grid import GridPattern
from .linalg.heap import reused_heap
from .linalg.multigrid import TWO_GRID_STRIDE, LineTwoGrid, TwoGrid, coarse_nodes, line_interpolation
from .linalg.threads import RowBlocks
from .progress import report_progress
from .mesh import QuadMesh
from .topology import fixed_vertices
from .line_ends import line_end_arms, line_end_free, line_end_rows
from .zigzag import (DEFAULT_DETECTION, DEFAULT_GAPS, DETECTIONS, GAPS_MODES, _detect, _threshold, _walk_edges,
                     _window_geometry, line_gaps, window_edges)

__all__ = [
    "DEFAULT_WEIGHT",
    "window_coefficients",
    "extraordinary_windows",
    "EXTRAORDINARY_MODES",
    "LINE_SPACING_MODES",
    "DEFAULT_LINE_SPACING",
    "LINE_CURVATURE_MODES",
    "DEFAULT_LINE_CURVATURE",
    "CURVATURE_CHANGE",
    "CURVATURE_CONTRAST",
    "CURVATURE_NOISE_SHARE",
    "CURVATURE_MIN_SHARE",
    "curvature_windows",
    "fairing_matrix",
    "fairing_energy",
    "FairingSystem",
    "grid_pattern",
    "IterationReport",
    "FairingReport",
    "fair",
]

#: Systems with at most this many unknown vertices are solved directly by default.
DIRECT_LIMIT = 2000
#: :class:`FairingSystem` keeps every window's four slots in ``A`` (a fixed vertex's as an explicit zero, the
#: coefficients not copied) where at most one window in this many has a fixed vertex; else it compresses them.
PARTIAL_IN_PLACE = 8
#: Cap on conjugate-gradient steps before falling back to the direct solver.
MAX_CG_ITERATIONS = 20000
#: Unknowns per block of the block-Jacobi preconditioner (a patch of about 4 × 4 vertices).
BLOCK_SIZE = 16
#: Precondition when the mean diagonal of AᵀA exceeds this many times ω (else plain CG wins);
#: about ω < 0.2 (normalized) — or ω < 0.02 where the grid's faster diagonal storage applies
#: (``benchmarks/studies/cg_weights.py``).
BLOCK_JACOBI_RATIO = 50.0
GRID_BLOCK_JACOBI_RATIO = 500.0
#: Symmetric Gauss–Seidel leaves its last residual in smooth modes, where a residual means a larger
#: error than plain CG's (which ends on the oscillating ones): stopping at fair's rtol of 1e-9 its
#: solution was up to 1.4e-8 (300² sheet, broadband noise, eq. 32's own lengths, ω = 0.003) and 1.8e-8
#: (cube-sphere) of the extent from the exact one, beyond the 1e-8 the solver keeps to. It stops at this
#: fraction of ``rtol`` instead: at most 1.9e-9 over both noises, both spacings, both meshes and
#: ω = 0.003–3, for 13–18 % more steps (``python benchmarks/studies/gauss_seidel.py --accuracy``).
GAUSS_SEIDEL_RTOL = 0.1
#: Below the weights measured there a residual within rtol may leave an error beyond the solver's 1e-8 of the
#: extent: at a small ω (κ ≈ 64/ω) the residual's smooth part is amplified up to 1/ω, the more so where fixed
#: vertices' couplings make the right-hand side large. Above a Gershgorin bound of this many times ω (a weight
#: below about 10⁻³) every CG path also stops no earlier than ``‖r‖₂ ≤ ERROR_RMS · extent · ω · √k`` per
#: coordinate, which bounds the root-mean-square error by ERROR_RMS of the extent (``‖e‖₂ ≤ ‖r‖₂ / ω``, as
#: ``λ_min ≥ ω``). Without it Gauss–Seidel ended 2.0e-7 of the extent from the direct solve on the 120² bench
#: sheet at ω = 10⁻⁶ (``tests/test_fairing.py::test_gauss_seidel_at_tiny_weights_keeps_to_the_direct_solve``), and
#: 7.8e-8 and 4.7e-8 with 10 % of the vertices fixed on 200² at 10⁻⁴ and 10⁻⁶ (4.2e-10 and 2.8e-12 with it:
#: ``python benchmarks/studies/multigrid.py --solver --size 200 --weights 0.0001 0.000001 --fixed 0.1``, and the
#: same with ``--no-guard``).
ERROR_GUARD_CONTRAST = 5e4
ERROR_RMS = 1e-8
#: With the compiled kernels at hand, "auto" takes symmetric Gauss–Seidel where the largest Gershgorin
#: bound of ``AᵀA + ωI`` exceeds this many times ω (plain CG's steps grow with its square root): at the
#: default weight (about 170 ω on broadband noise) it solves a 1000² grid in 38 steps and half the time of
#: plain CG's 84; at ω = 3 (about 17 ω) the two tie on the grid, at ω = 10 plain CG is 10 % faster
#: (``python benchmarks/studies/gauss_seidel.py``, also ``--mesh cube-sphere`` and ``--mesh torus``).
GAUSS_SEIDEL_CONTRAST = 30.0
#: Below a weight of about 10⁻⁴ Gauss–Seidel's steps (growing as 1/√ω) cost more than the two-grid cycle's
#: (77–107 from 10⁻³ to 10⁻⁶, each some ten Gauss–Seidel steps' time, plus a coarse factorization once):
#: "auto" may take :class:`~quadnodes.linalg.multigrid.TwoGrid` on a grid (open, a cylinder, or a torus that the
#: spectral preconditioner does not take: see :data:`SPECTRAL_MIN_WORK`), and
#: :class:`~quadnodes.linalg.multigrid.LineTwoGrid` on any other mesh, where the Gershgorin bound exceeds this
#: many times ω (about ω = 2.5·10⁻⁴ on the bench sheet, 10⁻³ on a cylinder or torus),
#: where Gauss–Seidel's rate says it pays (:data:`TWO_GRID_AFTER`, :data:`TWO_GRID_REMAINING`). On the 300² sheet
#: (2026-12-02 15:09 UTC): 1.74 s Gauss–Seidel against 1.71 s two-grid at 3·10⁻⁴, 3.06 against 1.88 s at 10⁻⁴,
#: 7.47 against 1.73 s at 10⁻⁵; 12:20 UTC the same day, 1.31 against 1.88 s, 1.60 against 1.70 s and 9.38
#: against 2.24 s (``python benchmarks/studies/multigrid.py --solver --size 300``).
TWO_GRID_CONTRAST = 2e5
#: "auto" takes the two-grid path only where its coarse space has at most this many nodes (a square grid up to
#: about 1,100 × 1,100 at strides (4, 4), about 780² where an axis takes stride 2; on any other mesh every 4th
#: structure line makes about one coarse node in 16 unknowns, so up to some 1.2 million unknowns, and its coarse
#: space is checked before Gauss–Seidel starts). The coarse matrix (cubic interpolation's Galerkin
#: product, up to 81 couplings a row) is factorized, and its fill grows faster than its size: at 1000² (63,001
#: coarse vertices) the factor holds 51 million entries and a solve of the three coordinates costs some nine
#: Gauss–Seidel steps. There the two-grid path took 80–101 steps and 25–32 s from ω = 10⁻⁴ to 10⁻⁶, where
#: Gauss–Seidel took 1,075 steps (14.8 s) at 10⁻⁴ and 3,582 (47.4 s) at 10⁻⁵ (``python
#: benchmarks/studies/multigrid.py --solver --size 1000 --weights 0.0001 0.00001 --columns gauss-seidel two-grid
#: auto``; ``docs/fairing.md``, "The two-grid path"). Beyond this size Gauss–Seidel stays (its steps grow as 1/√ω).
TWO_GRID_COARSE_MAX = 80_000
#: ... and only where the grid has more than this many rows and columns (four coarse intervals each way).
TWO_GRID_MIN_SIDE = 16
#: The two-grid path stops at this fraction of ``rtol`` (its residual, like Gauss–Seidel's, leaves smooth error).
TWO_GRID_RTOL = 0.1
#: Where "auto" may take the two-grid path it runs Gauss–Seidel first and switches (from Gauss–Seidel's iterate)
#: no earlier than after this many steps. The Gershgorin bound does not see fixed vertices, and fixed
#: vertices scattered over the free ones hold the smooth modes as ω would: on a 200² sheet at ω = 10⁻⁶ with 10 %
#: of the vertices fixed at random Gauss–Seidel converges in 467 steps (0.42 s), with 30 % in 106 (0.10 s), where
#: the two-grid path takes 0.71 and 0.55 s; all free it needs 14,083 (9.08 s against 0.81 s; "auto" 0.84 s)
#: (``python benchmarks/studies/multigrid.py --solver --size 200 --weights 0.0001 0.000001 --fixed 0 0.1 0.3``).
TWO_GRID_AFTER = 300
#: ... except on a mesh that is no grid, where the Gershgorin bound exceeds this many ω and at most
#: TWO_GRID_AT_ONCE_HELD of the vertices are held: there the lines' cycle starts at once. From this contrast on,
#: Gauss–Seidel took 2,192 steps or more in every case of a throwaway calibration (150² sheet, 120² cylinder and
#: torus, 15k cube-sphere, 44k random quads; 0 or 2 % held; ω from 10⁻² to 10⁻⁵), so its first TWO_GRID_AFTER
#: steps are spent before a switch that comes anyway.
TWO_GRID_AT_ONCE_CONTRAST = 5e6
TWO_GRID_AT_ONCE_HELD = 0.02
#: ... and then only where Gauss–Seidel's own rate says it needs more than this many steps still (the
#: residual's decay over its last 100 steps, extrapolated to the target; checked every :data:`TWO_GRID_AFTER`
#: steps). What the switch costs — the coarse factorization and 50–150 steps of the cycle, each about ten
#: Gauss–Seidel steps — matched 600–1,400 steps of Gauss–Seidel on the 300² sheet, cylinder and torus, as the
#: machine's speed and the mesh went; with a count of steps alone "auto" switched and lost where Gauss–Seidel
#: needed 380–650 steps in all, 200–350 after the first check (``python benchmarks/studies/multigrid.py
#: --solver --size 300``, ``--mesh torus``, ``--mesh cylinder``; ``docs/fairing.md``, "The two-grid path").
#: This many for a coarse space of up to :data:`TWO_GRID_REMAINING_COARSE` nodes; a larger one costs more per
#: node (the coarse factor's fill grows faster than its size), so the count grows with the square root of its
#: size (:func:`_switch_remaining`).
TWO_GRID_REMAINING = 700
#: ... the coarse space's size up to which :data:`TWO_GRID_REMAINING` holds as it is (the 300² sheet's 5,776
#: coarse vertices). At 1000² (63,001) the two-grid path's 25–27 s matched some 1,800–2,000 Gauss–Seidel steps of
#: 13.5 ms (the command at :data:`TWO_GRID_COARSE_MAX`): the square root's 2,268 there errs a little towards
#: Gauss–Seidel (some 5 s at most). At 600² (22,801 nodes; 1,365) the switch cost what some 1,800 steps did: at
#: ω = 3·10⁻⁵, where Gauss–Seidel had 1,826 to go, it won 7.99 against 8.36 s (``--size 600``). A step of the
#: cycle cost about ten Gauss–Seidel steps at 300² and about 16 at 1000², and the factorization grows faster still.
TWO_GRID_REMAINING_COARSE = 6_000
#: ... and on the structure lines (:class:`~quadnodes.linalg.multigrid.LineTwoGrid`: a mesh that is no grid, or a
#: grid under 60 % free) the square root stops at this many coarse nodes; measured on that cycle only. On the
#: 998,786-vertex cube-sphere (62,426 coarse nodes, every 4th line) at ω = 10⁻⁴ the grids' price (2,258 steps) kept
#: Gauss–Seidel for all its 2,222 steps: 50.7 s, against 35.4 s and 375 steps priced at 1,278 (``python
#: benchmarks/perf/bench_core.py --sizes 1000 --cube-sphere --noise broadband --only fair --weight 0.0001 --repeat 1
#: --against``, one run each; a throwaway pair gave 63.1 against 40.0 s). From those runs the switch, set-up
#: included, cost what some 1,050–1,200 Gauss–Seidel steps did. On the 399,386-vertex one (every 3rd line) 21.5
#: against 12.1 s (``--sizes 632``); on 303,689 random quads (42,739 coarse nodes, tangled lines) at 2·10⁻⁴ the
#: capped price switched after 300 steps where the grids' (1,868) switched after 600: 42.1 against 46.3 s (a
#: throwaway pair). Below the cap nothing changes: the 101k cube-sphere's 11,618 coarse nodes are priced 974, as
#: before (session 15 put its break-even near 1,100, on that session's engine). A fit to these points, not a model.
TWO_GRID_LINE_REMAINING_COARSE = 20_000
#: On a mesh that is no grid the two-grid path keeps every this many structure lines (not
#: :data:`~quadnodes.linalg.multigrid.TWO_GRID_STRIDE`, the grids' 4) up to :data:`TWO_GRID_LINE_STRIDE_MAX`
#: unknowns. Its compressed-row sweeps, residuals and transfers cost more per step than a grid's, so halving
#: the steps pays for the larger coarse space there: on cube-spheres at ω = 10⁻⁵ 46 steps against 91–92, 3.31
#: against 4.09 s at 101k vertices and 17.8 against 19.3 s at 399k; at 15k 0.27 and 0.32 s against 0.37 and
#: 0.42 s at 10⁻⁴ and 10⁻⁶ (``python benchmarks/studies/multigrid.py --solver --mesh cube-sphere --size 130``,
#: ``--size 258 --weights 0.00001 --columns lines``, ``--size 50``: the column "two-grid, structure lines, stride
#: 4" beside the solver's). On the 300² grid the stride of 3 halves the steps too but gains no time (1.38 against
#: 1.48 s, 1.68 against 1.64 s at 10⁻⁴ and 10⁻⁶; ``--size 300 --strides 3 4 --columns two-grid``), so grids keep
#: 4 (a grid off the grid path, under 60 % free, takes the lines and so 3).
TWO_GRID_LINE_STRIDE = 3
#: ... and above this many unknowns every 4th line: the gain shrinks with the size (21–28 %, 13–20 % and 8 % at 15k,
#: 101k and 399k), and at 10⁶ a stride of 3 would make some 111,000 coarse nodes, above
#: :data:`TWO_GRID_COARSE_MAX`.
TWO_GRID_LINE_STRIDE_MAX = 450_000
#: The two-grid path coarsens by 2 instead of :data:`TWO_GRID_STRIDE` along an axis whose nearest couplings (the
#: matrix's ±1 or ±cols diagonals, mean magnitude over the free vertices) are this many times weaker than the
#: other axis's: there the point sweeps leave the error rough. On 200² cylinders at ω = 10⁻⁵ whose edges around
#: are 2 and 6 times those along the steps fell from 117 and 221 to 74 and 78 (1.90 to 1.60 s, 3.09 to
#: 1.66 s); at 1.5 times it keeps 4 (101 steps)
#: (``python benchmarks/studies/multigrid.py --solver --mesh cylinder --size 200 --aspect 2 --weights 0.00001
#: --strides 4``, and ``--aspect 6``, ``--aspect 1.5``; on 300² cylinders and tori, ``docs/fairing.md``).
TWO_GRID_ANISOTROPY = 2.5
#: The structure lines' two-grid cycle adds a damped line step (:class:`~quadnodes.linalg.multigrid.LineTwoGrid`'s
#: ``lines``, :meth:`FairingSystem._line_smoothing`) where more than LINE_SMOOTHING_SHARE of the unknowns are tied
#: over LINE_SMOOTHING_RATIO times more strongly along one line than along the other
#: (:func:`~quadnodes.linalg.cg.strongest_lines`): long, thin faces, where the point sweeps leave error that
#: is smooth along the strong line and rough across it.
LINE_SMOOTHING_RATIO = 10.0
LINE_SMOOTHING_SHARE = 0.01
#: Where the lines' cycle takes that line step, the switch is worth this share of :func:`_switch_remaining`: the
#: cycle needs about a quarter of the steps (38 against 140 on the 111,873 random quads at ω = 10⁻⁴) at about 1.5
#: times the price a step, so the switch costs some 0.55 of what it did. On those quads at ω = 10⁻³ "auto" kept
#: Gauss–Seidel for all its 1,100 steps (7.70–7.93 s) under the whole price and switches after 300 under half of it
#: (4.67–5.59 s); at 3·10⁻³ both keep Gauss–Seidel (751 steps) (``python benchmarks/studies/multigrid.py --solver
#: --free fair --weights 0.003 0.001 --columns auto --mesh random --size 300``, two rounds; ``docs/fairing.md``).
LINE_STEP_PRICE = 0.5
#: ``FairingSystem(preconditioner=...)``'s choices.
PRECONDITIONERS = ("auto", "gauss-seidel", "two-grid", "lines", "spectral", "none")
#: The grid path uses the compiled kernels (:mod:`quadnodes.linalg._kernels`: symmetric storage,
#: fused CG passes and the line preconditioner) from this many unknowns on. Below, SciPy's
#: diagonal kernel and NumPy: loading Numba and its cached kernels costs about a second per
#: process, more than the whole solve of a 300² grid (0.6 s zigzag, 1.2 s broadband) and far
#: less than what the kernels save at 1000² (36 s -> 10 s broadband, ``benchmarks/perf/bench_core.py``).
COMPILED_MIN_UNKNOWNS = 250_000
#: From this many vertices on, fair() serves its large temporaries from the heap instead of fresh
#: pages (:func:`quadnodes.linalg.heap.reused_heap`): at a million vertices a (3, 2·10⁶) temporary
#: costs a page fault per 4 KB otherwise; at 300² (2 MB temporaries, above glibc's first mmap
#: threshold) the whole fair() is about 12 % faster with it (median of 9 fresh processes each, a throwaway A/B).
HEAP_MIN_VERTICES = 10_000
#: On a complete vertex grid, solve in the grid's own numbering with diagonal storage
#: (13 diagonals, 1.3-1.7x faster products than CSR) when at least this share of the
#: vertices is free (fixed vertices become identity rows there, so their rows cost too).
GRID_MIN_FREE = 0.6

#: "auto" preconditions CG on a mostly free vertex grid without the compiled kernels by
#: :class:`~quadnodes.linalg.spectral.SpectralPreconditioner` where the Gershgorin bound exceeds
#: :data:`GAUSS_SEIDEL_CONTRAST` ω (below, plain CG's few steps cost less: at ω = 3 on the 300² sheet 28 plain steps
#: took 0.085 s against 13 preconditioned ones' 0.092 s, ``benchmarks/studies/cg_weights.py --size 300 --noise
#: broadband``) and plain CG's work, unknowns × √(Gershgorin bound / ω), is at least this (or at any size once SciPy's
#: transforms are imported): importing ``scipy.fft`` costs about 40 ms, which the fewer steps repay from here on (in
#: fresh processes 0.274 against 0.276 s at 300² and the default weight, work 1.2·10⁶;
#: ``benchmarks/perf/bench_core.py --sizes 300 --only fair --noise broadband --against``).
SPECTRAL_MIN_WORK = 6e5
#: "auto" takes the spectral preconditioner (its exact lines) on a grid that it fits (below) in place of Gauss–Seidel
#: and the two-grid switch where the Gershgorin bound exceeds this many times ω on a grid whose longest open side has
#: :data:`SPECTRAL_CONTRAST_SIDE` nodes (a weight below about 5·10⁻³ on the bench sheet with broadband noise; the
#: rule at other sides: :func:`_spectral_contrast`): its steps do not grow as the weight falls, Gauss–Seidel's do as
#: 1/√ω. Fair's first-iteration system on the 1000² sheet, kernels loaded: at 0.003 20 · 3.41 s against 268 · 5.10 s
#: (``python benchmarks/studies/multigrid.py --solver --free fair --size 1000 --columns gauss-seidel spectral auto``,
#: session 18), at 0.01 19 · 2.40 s against 153 · 2.11 s (``--weights 0.03 0.01 0.003 --columns spectral auto``,
#: session 28).
SPECTRAL_CONTRAST = 1e4
#: ... times (longest open side / this)²: an exact line costs ``O(side)`` a node a step, so the Gauss–Seidel steps it
#: must save grow with the side (on 1500², whose rule says 2.25·10⁴ ω, the two tied at ω = 0.003, a bound of
#: 1.7·10⁴ ω: first-iteration system 19 steps 10.9 s against 261 steps 11.2 s, and at 0.001 7.7 s against 15.2 s,
#: set-up and solve, a throwaway script), and only up to :data:`~quadnodes.linalg.spectral.EXACT_MAX_SIDE` nodes an
#: open side.
SPECTRAL_CONTRAST_SIDE = 1000
#: ... but on an open grid never below this many times ω (a weight of about 0.025 on the bench sheet; a cylinder keeps
#: :data:`SPECTRAL_CONTRAST` up to that side, :func:`_spectral_contrast`): under about 450 nodes a side the
#: exact lines' steps cost less than that square says, and the two tie at a bound of about 1.7·10³ ω (ω = 0.03)
#: on the 100², 200², 300² and 450² sheets alike. Fair's first-iteration system with broadband noise, kernels
#: loaded, spectral against "auto"'s Gauss–Seidel, set-up and solve (``python benchmarks/studies/multigrid.py
#: --solver --free fair --size 300 --weights 0.1 0.03 0.01 0.005 --columns gauss-seidel spectral auto``,
#: ``--size 100``, ``200``, ``450``, ``700``, ``1000``; session 28): on 300² 0.12 against 0.08 s at ω = 0.1,
#: 0.12 against 0.14 s at 0.03, **0.11 against 0.19 s** at 0.01 (18 steps against 163); on 700² a tie at 0.01
#: (0.96 against 1.02 s, a bound of about 5·10³ ω, which the square gives: 4.9·10³); on 1000² at 0.01 Gauss–Seidel
#: still wins (2.11 against 2.40 s), at 0.003 the two take the same path.
SPECTRAL_CONTRAST_MIN = 2e3
#: ... and only where at most this many fixed vertices lie inside the unknowns' box (the exact lines invert around each,
#: at a set-up that grows with their square; a zigzag detection leaves fixed vertices scattered): on the 300² sheet at
#: ω = 0.01–0.02, with the kernels loaded, the spectral lines took 0.16–0.18 s with about 27 of them (its spectral
#: and "auto" columns), 0.20–0.23 s with 54, 0.22–0.26 s with 90 and 0.25–0.33 s with 144, where Gauss–Seidel takes
#: 0.20–0.28 s, fewer steps as more are held (``python benchmarks/studies/multigrid.py --solver --free fair --size
#: 300 --fixed 0.0003 0.0006 0.001 0.0016 --weights 0.02 0.01 --columns gauss-seidel spectral auto``, session 28;
#: its Gauss–Seidel column, run first, pays some 0.04 s of warm-up, which makes 54 a tie). Above it the floor does
#: not apply (the bound is ``SPECTRAL_CONTRAST · max(1, side / SPECTRAL_CONTRAST_SIDE)²``).
SPECTRAL_FLOOR_MAX_INSIDE = 50
#: The spectral preconditioner takes its exact lines where the Gershgorin bound exceeds this many times ω, and cosine
#: lines (``open_lines="cosine"``) below where SciPy's transforms are imported already (or an axis closes around):
#: their steps cost less, and where few are needed the exact lines' fewer steps do not repay that and their
#: set-up. An open grid's exact lines need no transforms, and in a fresh process they save the transforms' import
#: (about 40 ms), which repays their dearer steps up to a side of :data:`SPECTRAL_EXACT_FRESH_SIDE`. On the 300²
#: sheet with broadband noise (in-process, transforms imported; ``python benchmarks/studies/cg_weights.py --size 300
#: --noise broadband``), since session 20's cheaper application: 15 exact steps 0.168 s against 24 cosine ones
#: 0.197 s at the default weight (a bound of 168 ω), 13 against 18, 0.153 against 0.139 s at ω = 1 (about 50 ω),
#: 11 against 13, 0.141 against 0.142 s at 3 (session 19: 300, when the default weight's were 0.206 against 0.171 s).
SPECTRAL_EXACT_CONTRAST = 1e2
#: ... and at any bound on an open grid up to this many nodes a side where SciPy's transforms are not imported (a
#: fresh process): whole fair() at the default weight, medians of five fresh processes, exact against cosine lines
#: (the import inside), 0.203 against 0.239 s on the 250² sheet, 0.499 against 0.407 s on 350², 0.499 against
#: 0.522 s on 400² (a throwaway script); on 300² ``benchmarks/perf/bench_core.py --sizes 300 --only fair --noise
#: broadband --repeat 9 --against`` gave 0.245 s, 15 steps, against the session-start engine's cosine lines' 0.255 s,
#: 28 steps.
SPECTRAL_EXACT_FRESH_SIDE = 320
#: ... and only where no unknown's fairing diagonal exceeds this many times the median one's: a stiff spot (a
#: collapsed stretch of a line) is an outlier that the constant coefficients miss. The sampled design surfaces
#: with broadband noise are at 1.9–2.6, a torus at 6.1 (a throwaway script's figures; the study prints its
#: sheet's: ``cg_weights.py``).
SPECTRAL_MAX_STIFFNESS = 12.0
#: The spectral preconditioner follows the coefficients' variation along an open axis (a grid sampled with uneven
#: spacing, lines that shrink toward one side) where their medians along it spread by this factor or more
#: (:func:`_coefficient_profile`). Even sheets and a cylinder spread 1.1–1.4, the sampled saddle, S-shape and dome
#: 1.6–1.8, where exact lines with constant coefficients take 16–19 steps and the profile saves 1–3 more at dearer
#: steps. From 2.1 (spacing growing 1.5-fold across a 300² sheet: 20 → 15 steps) it pays, and more the more they
#: vary (tenfold: 111 → 17 steps, 1.25 → 0.40 s; both ways tenfold 188 → 30, 1.87 → 0.59 s;
#: ``benchmarks/studies/coefficient_profile.py``).
PROFILE_MIN_SPREAD = 2.0
#: On an open grid the exact lines invert around the fixed vertices inside the unknowns' box in the lines'
#: coordinates, at a set-up of ``p² N`` multiply-adds for ``p`` of them: the spectral preconditioner is taken only
#: where ``p²`` is at most this many times the square root of the Gershgorin bound over ω (plain CG's steps grow
#: with that root). On 300² at the default weight (a bound of about 170 ω: up to 80 fixed vertices) the set-up took
#: 29 ms for 61 of them, 164 ms for 143 and 1.08 s for 457, where plain CG's whole solve takes about 0.3 s (a
#: throwaway timing); at ω = 10⁻⁵ (about 5·10⁶ ω) the cap is :data:`~quadnodes.linalg.spectral.MAX_CORRECTED_EXACT`.
CORRECTION_PAYS = 500.0
#: ... and only along an axis of at most this many nodes: the varying axis's basis is one dense eigendecomposition
#: of its whole span, not cached (n = 2000 took 1.55 s on one BLAS thread, 4000 took 16.1 s against 2.7 s for the
#: constant lines' two halves, a reviewer's timing).
PROFILE_MAX_SIDE = 2048
#: "auto" preconditions a grid's CG by the line preconditioner (banded solves along every row and column line,
#: :class:`~quadnodes.linalg.cg.LinePreconditioner`, loading the compiled kernels at any size) in place of
#: Gauss–Seidel, block Jacobi or plain CG where some unknown's fairing diagonal is at least this many times the
#: median one's (:func:`_stiffness`) — stiff spots, from eq. 32's own lengths on a nearly collapsed stretch of a line:
#: point sweeps relax such a stretch slowly, the lines solve it whole. Not where the two-grid switch may be
#: wanted (the Gershgorin bound over the stiffness still above :data:`TWO_GRID_CONTRAST` ω: a tiny weight) nor
#: where the spectral preconditioner takes the grid. Fair's first-iteration system at the default weight under
#: ``line_spacing="hold"``, kernels loaded (``python benchmarks/studies/stiff_lines.py``; docs/fairing.md, "The line
#: preconditioner"): at a stiffness of 3–13 Gauss–Seidel takes about half the lines' time; at 177–366 on 300² the
#: two are within the runs' spread (0.31–0.65 s against 0.39–0.69 s), at 202–335 on 600² the lines take 1.10–1.82 s
#: against 1.35–2.10 s, on the 1000² sheet at 1,822 2.61 s against 5.68 s, on the bench torus (1,002 and 837)
#: 1.03 s against 2.00 s at 300² and 10.86 s against 20.19 s at 1000².
LINES_MIN_STIFFNESS = 100.0
#: ... where the compiled kernels are wanted anyway (:data:`COMPILED_MIN_UNKNOWNS`, or loaded already) or plain CG's
#: work, unknowns × √(Gershgorin bound / ω), is at least this: loading the kernels costs about a second in a fresh
#: process. The bench torus under ``line_spacing="hold"`` in fresh processes, the lines forced at every size (a
#: throwaway script, two runs each): 100² (work 2·10⁶) 0.55–1.18 s against plain CG's 0.20 s, 150² (4.7·10⁶)
#: 0.71–0.85 against 0.48–0.54 s, 200² (1.5·10⁷) 1.16–1.60 against 1.51–1.54 s, 300² (3.7·10⁷) 1.95 against 5.46 s.
#: The rule's outcome, ``python benchmarks/perf/bench_core.py --sizes 100 150 200 300 --only fair_hold --noise
#: broadband --torus --repeat 3 --against /tmp/base`` (base 38f704b): 100²–200² the same path as before (0.20, 0.53,
#: 1.36 s against 0.19, 0.53, 1.20 s), 300² 2.22 s against 5.48 s.
LINES_MIN_WORK = 2e7
#: Default dimensionless penalty weight (in units of the mean edge length).
#: Chosen from ``benchmarks/studies/weight_sweep.py``; see ``docs/fairing.md``.
DEFAULT_WEIGHT = 0.3


def window_coefficients(vertices: np.ndarray, windows: np.ndarray, *, line_spacing: str = "hold") -> np.ndarray:
    """Coefficients ``(a0, a1, a2, a3)`` of eq. 32 for every window.

    Lengths are taken from ``vertices`` (frozen). Each row sums to zero, so the
    term is invariant under translation.

    Parameters
    ----------
    vertices : (n, 3) float64
    windows : (w, 4) int64
    line_spacing : {"hold", "fair"}
        ``"hold"`` (default here: eq. 32 exactly): every edge's own length;
        ``"fair"``: the window's mean edge length for all three (:func:`even_lengths`).

    Returns
    -------
    (w, 4) float64

    Examples
    --------
    >>> v = np.array([[0., 0, 0], [1, 0, 0], [3, 0, 0], [4, 0, 0]])
    >>> window_coefficients(v, np.array([[0, 1, 2, 3]])).tolist()
    [[-0.5, 1.0, -1.0, 0.5]]
    >>> window_coefficients(v, np.array([[0, 1, 2, 3]]), line_spacing="fair").tolist()  # mean length 4/3
    [[-0.375, 1.125, -1.125, 0.375]]
    """
    line_spacing = _validate.choice(line_spacing, LINE_SPACING_MODES, "line_spacing")
    inv = np.stack([1.0 / np.sqrt(np.einsum("ij,ij->i", d, d)) for d in window_edges(vertices, windows)], axis=1)
    if line_spacing == "fair":
        inv = even_lengths(inv)
    return _coefficients(inv[:, 0], inv[:, 1], inv[:, 2])


#: Scale of the pseudo-windows' rows (:func:`extraordinary_windows`) relative to a window's (energy: its square);
#: 0.25 measured best of 1, 0.5, 0.25, 0.1 on seeded noise (docs/fairing.md).
EXTRAORDINARY_SCALE = 0.25
#: The values of ``extraordinary`` in :func:`fair`: ``"fair"`` the line-end term of :mod:`quadnodes.line_ends`,
#: ``"lines"`` the pseudo-windows of :func:`extraordinary_windows`, ``"hold"`` the thesis (neither).
EXTRAORDINARY_MODES: tuple[str, ...] = ("fair", "lines", "hold")
#: The values of ``line_spacing`` in :func:`fair` and :func:`window_coefficients`: ``"hold"`` freezes every edge's
#: length (eq. 32 exactly), ``"fair"`` gives a window's three edges their mean length (:func:`even_lengths`).
LINE_SPACING_MODES: tuple[str, ...] = ("fair", "hold")
#: Measured on the real meshes and on E1–E4 (docs/fairing.md, "Spacing along the lines").
DEFAULT_LINE_SPACING = "fair"
#: The values of ``line_curvature`` in :func:`fair`: ``"fair"`` fairs every curvature change along the lines
#: (eq. 34, the thesis), ``"hold"`` gives back the smooth part of what one solve removed (Tukey's twicing at
#: half the weight), so the design's own curvature changes are held (docs/fairing.md, "The design's curvature"),
#: ``"auto"`` holds them only in the windows where the faired lines change curvature (:func:`curvature_windows`).
LINE_CURVATURE_MODES: tuple[str, ...] = ("fair", "hold", "auto")
#: ``"auto"``: measured on the real meshes and E1–E4 (docs/fairing.md, "The design's curvature"); ``"hold"``
#: gains on curved designs and loses 1–5 % on nearly flat ones, ``"auto"`` corrects only the former.
DEFAULT_LINE_CURVATURE = "auto"
#: ``line_curvature="auto"`` holds a window's line term at the faired value x₁ where it is above all three
#: levels (:func:`curvature_windows`): this change of turning per window (in the line's unit directions: about
#: 3°), so evenly curved and finely sampled designs are left to the single solve, ...
CURVATURE_CHANGE = 0.055
#: ... this multiple of the median of the windows' terms on x₁ (a curvature change stands out of the design's
#: own lines; residual noise and even curvature do not), ...
CURVATURE_CONTRAST = 2.0
#: ... and this share of the median of their terms on the input (what one solve leaves of the noise scales with
#: it). Measured on the real meshes and E1–E4 (docs/fairing.md, "The design's curvature").
CURVATURE_NOISE_SHARE = 0.08
#: Fewer held windows than this share of the inner windows are not worth a second solve of the whole mesh (its
#: cost is global, its effect local): on the broadband benchmark sheets about 0.1 % pass, residual noise all; the
#: curved meshes of docs/real-meshes.md hold 1.6–28 %.
CURVATURE_MIN_SHARE = 0.005


def curvature_windows(faired: np.ndarray, noisy: np.ndarray | None, windows: np.ndarray, inner: np.ndarray, *,
                      noisy_norms: np.ndarray | None = None) -> np.ndarray:
    """The windows whose line term ``line_curvature="auto"`` holds: the design's curvature changes.

    One solve suppresses the noise's line terms (high frequencies, by about ``ω/λ``)
    and keeps most of a design's curvature change; so a window whose term on the
    faired result ``x₁`` is still large marks where the design's lines change their
    curvature (a rounded edge's start and end), which the solve begins to fair away.
    A window is held when its term on ``x₁`` is above :data:`CURVATURE_CHANGE`,
    :data:`CURVATURE_CONTRAST` times the median over the inner windows on ``x₁`` and
    :data:`CURVATURE_NOISE_SHARE` times their median on the input; when it is an
    inner window (its four vertices free: a held or unfound vertex's noise is not
    design); and when the window before or after it along its line is held by the
    same rules (a design's curvature change spans consecutive windows, the largest
    terms residual noise leaves are isolated). When fewer than :data:`CURVATURE_MIN_SHARE`
    of the inner windows qualify, none is held (a second solve of the whole mesh for
    a few windows is not worth its cost).

    Parameters
    ----------
    faired : (r, 3) float64
        The rows' line terms at ``x₁`` (``A x₁ + b``); the first ``w`` rows are ``windows``,
        any later rows (the line-end term's) are never held.
    noisy : (r, 3) float64, or None with ``noisy_norms``
        The same rows at the input (the anchor).
    noisy_norms : (w,) float64, optional
        Their norms for the ``w`` windows, when known (fair has their squares from its detection pass).
    windows : (w, 4) int
        The windows of the first ``w`` rows, consecutive windows of a line next to each other.
    inner : (r,) bool
        Rows whose vertices are all free.

    Returns
    -------
    (r,) bool

    Raises
    ------
    InputError
        When the shapes do not fit together (the argument is named).

    Examples
    --------
    One line of 11 vertices (8 windows), the faired terms large at windows 3 and 4:

    >>> win = np.arange(8)[:, None] + np.arange(4)
    >>> f1 = np.zeros((8, 3)); f1[3:5, 2] = 0.1
    >>> np.flatnonzero(curvature_windows(f1, np.full((8, 3), 0.3), win, np.ones(8, bool))).tolist()
    [3, 4]
    >>> f1[4] = 0.0  # an isolated large term is residual noise
    >>> curvature_windows(f1, np.full((8, 3), 0.3), win, np.ones(8, bool)).any()
    np.False_
    """
    faired, windows, inner = (np.asarray(a) for a in (faired, windows, inner))
    if faired.ndim != 2 or faired.shape[1:] != (3,):
        raise InputError(f"faired: expected shape (r, 3), got {faired.shape}")
    r = faired.shape[0]
    if noisy_norms is None:
        noisy = np.asarray(noisy)
        if noisy.shape != faired.shape:
            raise InputError(f"noisy: expected the shape of faired {faired.shape}, got {noisy.shape}")
    elif np.shape(noisy_norms) != (len(windows),):
        raise InputError(f"noisy_norms: expected shape ({len(windows)},), got {np.shape(noisy_norms)}")
    if windows.ndim != 2 or windows.shape[1:] != (4,) or windows.shape[0] > r:
        raise InputError(f"windows: expected shape (w, 4) with w <= {r}, got {windows.shape}")
    if inner.shape != (r,) or inner.dtype != bool:
        raise InputError(f"inner: expected a bool array of shape ({r},), got {inner.dtype} {inner.shape}")
    w = len(windows)
    s1 = np.sqrt(np.einsum("ij,ij->i", faired[:w], faired[:w]))
    inside = inner[:w]
    held = np.zeros(len(faired), dtype=bool)
    if w < 2 or not inside.any():
        return held
    s0 = np.sqrt(np.einsum("ij,ij->i", noisy[:w], noisy[:w])) if noisy_norms is None else np.asarray(noisy_norms)
    every = bool(inside.all())  # (no copies for the medians then)
    level = max(CURVATURE_CHANGE, CURVATURE_CONTRAST * float(np.median(s1 if every else s1[inside])))
    # the input's median matters only where its share is above the other levels: a count tells
    if np.count_nonzero(s0[inside] > level / CURVATURE_NOISE_SHARE) * 2 >= np.count_nonzero(inside):
        level = max(level, CURVATURE_NOISE_SHARE * float(np.median(s0 if every else s0[inside])))
    above = inside & (s1 > level)
    i = np.flatnonzero(above[:-1] & above[1:])
    i = i[(windows[i + 1, :3] == windows[i, 1:]).all(axis=1)]  # window i+1 continues window i's line
    held[i] = True
    held[i + 1] = True
    if np.count_nonzero(held) < CURVATURE_MIN_SHARE * np.count_nonzero(inside):
        held[:] = False
    return held


def even_lengths(inverse: np.ndarray) -> np.ndarray:
    """Inverse lengths ``(w, 3)`` with each window's three edges given their mean length.

    With ``line_spacing="fair"`` the window term ``((d0 + d2)/2 − d1) / l̄`` is a third
    difference along the line: it vanishes on a straight line whose vertices are
    evenly spaced or whose spacing grows linearly, and sees a vertex slid along
    the line (which frozen per-edge lengths hold, because ``d/l`` keeps its
    direction). On a window with equal edges both rules are eq. 32.

    Examples
    --------
    >>> even_lengths(np.array([[1.0, 0.5, 1.0]])).tolist()  # lengths 1, 2, 1: mean 4/3
    [[0.75, 0.75, 0.75]]
    """
    m = 3.0 / (1.0 / inverse).sum(axis=1)
    return np.repeat(m[:, None], 3, axis=1)


def extraordinary_windows(vertices: np.ndarray, topology: object) -> np.ndarray:
    """Pseudo-windows through the vertices where structure lines end inside the mesh.

    At an interior vertex ``v`` of valence ``k ≠ 4`` (an extraordinary vertex) ``k``
    lines end; no window has ``v`` as a middle point, so the thesis never moves it.
    Each line ending at ``v`` (its last vertices ``… a2, a1, v``) is paired with the
    line leaving ``v`` that is *most opposite* to it — the arm ``v → b1`` whose unit
    direction has the smallest dot product with ``v → a1`` — as if the line went on
    through ``v``: the pair gives the windows ``(a2, a1, v, b1)`` and
    ``(a1, v, b1, b2)`` (those whose four vertices exist). Each unordered pair counts
    once. The eq. 32 term of these windows is the structure-line energy of the
    continued line; on a valence-6 vertex the pairs are the three straight lines.

    Parameters
    ----------
    vertices : (n, 3) float64
        Positions that decide the pairing (the input of :func:`fair`).
    topology : quadnodes.topology.Topology

    Returns
    -------
    (w, 4) int64
        Empty ``(0, 4)`` when the mesh has no extraordinary vertex.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> extraordinary_windows(grid(4, 4).vertices, grid(4, 4).topology).shape
    (0, 4)
    """
    ext = topology.extraordinary
    if not ext.any():
        return np.empty((0, 4), dtype=np.int64)
    lines = topology.structure_lines
    ln = lines.lengths
    first = lines.offsets[:-1]
    last = lines.offsets[1:] - 1
    idx = lines.indices
    open_ = ~lines.closed & (ln >= 2)
    arms = []  # (v, a1, a2) with a2 = -1 when the line has two vertices
    for at_end, step in ((first, 1), (last, -1)):
        sel = open_ & ext[idx[at_end]]
        e = at_end[sel]
        a2 = np.where(ln[sel] >= 3, idx[np.clip(e + 2 * step, 0, idx.size - 1)], -1)
        arms.append(np.stack([idx[e], idx[e + step], a2], axis=1))
    arm = np.concatenate(arms)
    if len(arm) == 0:  # no line ends at these vertices
        return np.empty((0, 4), dtype=np.int64)
    arm = arm[np.lexsort((arm[:, 1], arm[:, 0]))]
    v = arm[:, 0]
    d = vertices[arm[:, 1]] - vertices[v]
    d /= np.linalg.norm(d, axis=1)[:, None]
    # every arm against every other arm of the same vertex (valence is small)
    starts = np.flatnonzero(np.r_[True, v[1:] != v[:-1]])
    group = np.repeat(np.arange(starts.size), np.diff(np.r_[starts, v.size]))
    kmax = int(np.diff(np.r_[starts, v.size]).max())
    cand = starts[group][:, None] + np.arange(kmax)
    valid = (cand < v.size)
    cand = np.minimum(cand, v.size - 1)
    valid &= (v[cand] == v[:, None]) & (cand != np.arange(v.size)[:, None])
    dots = np.where(valid, np.einsum("ij,ikj->ik", d, d[cand]), np.inf)
    has = valid.any(axis=1)
    partner = cand[np.arange(v.size), np.argmin(dots, axis=1)]
    i = np.flatnonzero(has)
    j = partner[i]
    pairs = unique_rows(np.sort(np.stack([i, j], axis=1), axis=1))
    i, j = pairs[:, 0], pairs[:, 1]
    w1 = np.stack([arm[i, 2], arm[i, 1], arm[i, 0], arm[j, 1]], axis=1)
    w2 = np.stack([arm[i, 1], arm[i, 0], arm[j, 1], arm[j, 2]], axis=1)
    out = np.concatenate([w1[arm[i, 2] >= 0], w2[arm[j, 2] >= 0]])
    return out.astype(np.int64)


def _line_end_pairs(topology: object) -> np.ndarray:
    """The arms that get the line-end term (:mod:`quadnodes.line_ends`): those of every vertex that is
    no window's middle (extraordinary vertices, middles of lines too short for a window, line ends on
    the boundary)."""
    return line_end_arms(topology, ~topology.window_middle)  # type: ignore[attr-defined]


def _window_energy(vertices: np.ndarray, windows: np.ndarray, inverse: np.ndarray,
                   walk: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """``||f_i||²`` of every window at ``vertices`` with the inverse lengths ``inverse`` ``(w, 3)``.

    With the topology's ``walk`` (whose windows are ``windows``) the edges are taken along it.
    """
    if walk is not None:
        ext, start = walk
        e, _ = _walk_edges(vertices, ext)
        d0, d1, d2 = (np.take(e, start + k, axis=1).T for k in range(3))
    else:
        d0, d1, d2 = window_edges(vertices, windows)
    f = d0 * (0.5 * inverse[:, :1])
    f += d2 * (0.5 * inverse[:, 2:])
    f -= d1 * inverse[:, 1:2]
    return np.einsum("ij,ij->i", f, f)


def _coefficients(i0: np.ndarray, i1: np.ndarray, i2: np.ndarray) -> np.ndarray:
    """Eq. 32 coefficients from the inverse lengths of the windows' three edges."""
    c = np.empty((len(i0), 4))
    if kernels.ready():  # row by row (the same numbers): NumPy writes the columns with a stride
        from ._window_kernels import window_coefficients

        window_coefficients(*(np.asarray(i, dtype=np.float64) for i in (i0, i1, i2)), c, 0, len(c))
        return c
    c[:, 0] = -0.5 * i0
    c[:, 1] = 0.5 * i0 + i1
    c[:, 2] = -i1 - 0.5 * i2
    c[:, 3] = 0.5 * i2
    return c


def fairing_matrix(vertices: np.ndarray, windows: np.ndarray) -> sp.csr_matrix:
    """The ``(w, n)`` matrix ``A`` with ``(A @ P)[i]`` = the linearized term of window ``i``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(2, 5)
    >>> A = fairing_matrix(m.vertices, m.topology.windows)
    >>> A.shape, float(abs(A @ m.vertices).max())
    ((4, 10), 0.0)
    """
    n = vertices.shape[0]
    c = window_coefficients(vertices, windows)
    rows = np.repeat(np.arange(len(windows)), 4)
    return sp.csr_matrix((c.reshape(-1), (rows, windows.reshape(-1))), shape=(len(windows), n))


def fairing_energy(
    vertices: np.ndarray, windows: np.ndarray, *, lengths_from: np.ndarray | None = None, line_spacing: str = "hold"
) -> float:
    """Linearized fairness energy ``Σ ||f_i||²`` with lengths frozen at ``lengths_from``.

    ``lengths_from`` defaults to ``vertices``; then, with ``line_spacing="hold"``,
    ``||f_i||²`` equals the window's deviation (eq. 30) exactly. ``line_spacing="fair"``
    is the energy :func:`fair` minimizes by default (see :func:`window_coefficients`).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(3, 5)
    >>> fairing_energy(m.vertices, m.topology.windows)
    0.0
    """
    ref = vertices if lengths_from is None else lengths_from
    c = window_coefficients(ref, windows, line_spacing=line_spacing)
    f = np.einsum("wk,wkj->wj", c, vertices[windows])
    return float(np.einsum("ij,ij->", f, f))


_GRID_PATTERNS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def grid_pattern(topology: object) -> GridPattern | None:
    """The diagonal-storage pattern of a complete vertex grid's fairing matrix, or None.

    Made from the topology alone (its :attr:`~quadnodes.topology.Topology.grid_shape`,
    or :attr:`~quadnodes.topology.Topology.closed_grid` for a cylinder or torus grid
    with at least 7 vertices around every closed direction, whose windows across
    the seam get periodic diagonals) and kept in a declared
    cache keyed weakly by the topology, so every iteration and weight on the same
    mesh reuses it and it goes with the mesh.

    Examples
    --------
    >>> from quadnodes.mesh import cylinder, grid
    >>> t = grid(6, 7).topology
    >>> p = grid_pattern(t)
    >>> p.offsets.tolist(), grid_pattern(t) is p
    ([-21, -14, -7, -3, -2, -1, 0, 1, 2, 3, 7, 14, 21], True)
    >>> grid_pattern(cylinder(5, 8).topology).offsets[13:].tolist()  # rings of 8: across the seam
    [-7, 7, -6, 6, -5, 5]
    """
    try:
        return _GRID_PATTERNS[topology]
    except KeyError:
        pass
    shape = topology.grid_shape  # type: ignore[attr-defined]
    pattern = None
    if shape is not None and shape[1] >= 4:  # narrower: no row windows, offsets would collide
        # the windows of topology.structure_lines' order for a grid: row 0, every column, rows 1 …
        pattern = GridPattern.open_grid(shape[0], shape[1], [(0, 0, 1), (1, 0, shape[1]), (0, 1, shape[0] - 1)])
    closed = topology.closed_grid if shape is None else None  # type: ignore[attr-defined]
    if closed is not None and closed[1] >= (7 if closed[3] else 4) and (closed[0] >= 7 or not closed[2]):
        # a cylinder or torus grid: periodic diagonals for the windows across the seam (at least 7 vertices
        # around, so that no two diagonals share an offset); its windows come in the open grid's order of lines
        pattern = GridPattern.closed_grid(closed[0], closed[1], [(0, 0, 1), (1, 0, closed[1]), (0, 1, closed[0] - 1)],
                                          wrap_rows=closed[2], wrap_cols=closed[3])
    if pattern is not None and not pattern.valid:
        pattern = None
    _GRID_PATTERNS[topology] = pattern
    return pattern


def _two_grid_strides(data: np.ndarray, free: np.ndarray) -> tuple[int, int]:
    """The two-grid cycle's ``(rows', cols')`` strides for a grid's diagonal storage (:data:`TWO_GRID_ANISOTROPY`).

    The grid's first 13 offsets are ``-3c, -2c, -c, -3 … 3, c, 2c, 3c``: the mean magnitude of the ``+c`` (slot 10)
    and ``+1`` (slot 7) diagonals over the free vertices measures the couplings along the rows' and the
    columns' axis.
    """
    along = [float(np.abs(data[slot][free]).mean()) for slot in (10, 7)]
    half = TWO_GRID_STRIDE // 2
    return (half if along[0] * TWO_GRID_ANISOTROPY < along[1] else TWO_GRID_STRIDE,
            half if along[1] * TWO_GRID_ANISOTROPY < along[0] else TWO_GRID_STRIDE)


def _spectral_contrast(open_side: int, *, floored: bool) -> float:
    """The Gershgorin bound over ω above which "auto" takes the spectral preconditioner on a grid that it fits, in
    place of Gauss–Seidel and the two-grid switch.

    Parameters
    ----------
    open_side : int
        Nodes along the grid's longest open side (0 where both axes close around).
    floored : bool
        Whether the floor under small grids applies: an open grid (no axis closed around) with at most
        :data:`SPECTRAL_FLOOR_MAX_INSIDE` fixed vertices inside the unknowns' box.

    Returns
    -------
    float
        :data:`SPECTRAL_CONTRAST` at a longest open side of :data:`SPECTRAL_CONTRAST_SIDE` nodes, growing with the
        square of that side (an exact line costs ``O(side)`` a node a step); ``floored`` never below
        :data:`SPECTRAL_CONTRAST_MIN`, else never below :data:`SPECTRAL_CONTRAST`. A cylinder's bound is some 3–5
        times a sheet's at the same ω and its spectral steps twice as many, so there Gauss–Seidel still wins at
        bounds the floor would give away (the 300² cylinder at ω = 0.03, about 8·10³ ω: 153 steps 0.26 s against
        35 steps 0.28 s); and with many fixed vertices inside the box the exact lines' correction costs more than
        Gauss–Seidel's solve (docs/fairing.md, "Session 28: the floor under small grids").

    Examples
    --------
    >>> [_spectral_contrast(side, floored=True) for side in (300, 1000, 1500)]
    [2000.0, 10000.0, 22500.0]
    >>> [_spectral_contrast(side, floored=False) for side in (0, 300, 1500)]  # (0: a torus)
    [10000.0, 10000.0, 22500.0]
    """
    if not floored:
        return SPECTRAL_CONTRAST * max(1.0, open_side / SPECTRAL_CONTRAST_SIDE) ** 2
    return max(SPECTRAL_CONTRAST_MIN, SPECTRAL_CONTRAST * (open_side / SPECTRAL_CONTRAST_SIDE) ** 2)


def _spectral_pays(unknowns: int, contrast: float) -> bool:
    """Whether the spectral preconditioner pays for a grid's CG (the other conditions in ``_cg_setup``): where the
    Gershgorin bound exceeds :data:`GAUSS_SEIDEL_CONTRAST` ω and plain CG's work, ``unknowns · √contrast`` (its
    steps grow with the square root of the bound over ω), is at least :data:`SPECTRAL_MIN_WORK` — or, that
    bound exceeded, at any size once SciPy's transforms are imported."""
    if contrast <= GAUSS_SEIDEL_CONTRAST:
        return False
    return spectral.loaded() or unknowns * np.sqrt(contrast) >= SPECTRAL_MIN_WORK


def _stiffness(offsets: np.ndarray, data: np.ndarray, free: np.ndarray, weight: float,
               model: np.ndarray | None = None) -> float:
    """The stiffest unknown's fairing diagonal (``AᵀA``'s, without ω) over the median unknown's, from a grid's
    diagonal storage; with ``model`` (a diagonal over all nodes, e.g. :func:`_profile_diagonal`'s) each unknown's
    ratio to it instead (the stiff spots that the model misses)."""
    d = data[int(np.flatnonzero(offsets == 0)[0])][free] - weight
    if model is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            d = d / model[free]
        d = d[np.isfinite(d)]
    median = float(np.median(d)) if d.size else 0.0
    return float(d.max()) / median if median > 0 else np.inf


def _coefficient_profile(offsets: np.ndarray, data: np.ndarray, shape: tuple[int, int],
                         wrap: tuple[bool, bool]) -> tuple[int, np.ndarray, np.ndarray, np.ndarray | None] | None:
    """The coefficients' variation along an open axis of a grid's ``AᵀA + ωI`` in diagonal storage, where it is
    large enough to pay (a spread of :data:`PROFILE_MIN_SPREAD` or more):
    :class:`~quadnodes.linalg.spectral.SpectralPreconditioner`'s ``profile``, else None.

    A window's coefficient is the magnitude of its ends' coupling (the ``+3`` diagonal for the rows' windows, the
    ``+3·cols`` one for the columns'); where an end is fixed (or no window is) that coupling is absent from the
    storage, not zero in the window, so only positive ones count. Along axis 1: the rows' window coefficients'
    median over the rows at each window position, and each column's median; along axis 0 the same with rows and
    columns swapped (the seams' windows of a closed axis are left out). Where the other family's windows vary
    along their own (open) axis too, by :data:`PROFILE_MIN_SPREAD` or more (a sheet graded both ways), their
    medians over its lines relative to each line's, ``across``. A position or line with no coefficient takes its
    neighbours' (linear interpolation). The axis whose own medians spread more (largest over smallest) is taken, up
    to :data:`PROFILE_MAX_SIDE` nodes along it (and along the other for ``across``): where one axis's profile takes
    the whole variation, the other axis keeps its halves.
    """
    rows, cols = shape
    found = {int(o): d for d, o in enumerate(offsets)}
    if rows < 4 or cols < 4 or 3 not in found or 3 * cols not in found:
        return None
    along_rows = -data[found[3]].reshape(rows, cols)[:, 3:]  # (rows, cols − 3): row i's window k on nodes k … k+3
    along_cols = -data[found[3 * cols]].reshape(rows, cols)[3:, :]  # (rows − 3, cols)
    best: tuple[float, int, np.ndarray, np.ndarray, np.ndarray] | None = None
    for axis, (windows, lines) in enumerate(((along_cols, along_rows), (along_rows, along_cols))):
        if wrap[axis] or shape[axis] > PROFILE_MAX_SIDE:
            continue
        w = _positive_medians(windows, 1 - axis)  # (the family along the axis: its windows' medians by position)
        s = _positive_medians(lines, 1 - axis)  # (the other family: each line's median)
        if w is None or s is None:
            continue
        spread = max(float(w.max() / w.min()), float(s.max() / s.min()))
        if best is None or spread > best[0]:
            best = (spread, axis, w, s, lines)
    if best is None:
        return None
    spread, axis, w, s, lines = best
    across = None  # (the other family's windows along their own axis, relative to their line's median)
    if not wrap[1 - axis] and shape[1 - axis] <= PROFILE_MAX_SIDE:
        o = _positive_medians(lines / (s[None, :] if axis == 1 else s[:, None]), axis)
        if o is not None and o.max() / o.min() >= PROFILE_MIN_SPREAD:
            across, spread = o, max(spread, float(o.max() / o.min()))
    if spread < PROFILE_MIN_SPREAD:
        return None
    return axis, w, s, across


def _positive_medians(values: np.ndarray, axis: int) -> np.ndarray | None:
    """Medians of the positive entries of a 2-d array along ``axis``; where there are none, interpolated from the
    neighbouring medians (None where no entry at all is positive)."""
    positive = values > 0
    if positive.all():  # (the common case, every window free: NumPy's median, 4× faster than its NaN-aware one)
        return np.median(values, axis=axis)
    with warnings.catch_warnings():  # (all-NaN slices: filled below)
        warnings.simplefilter("ignore", RuntimeWarning)
        m = np.nanmedian(np.where(positive, values, np.nan), axis=axis)
    known = np.flatnonzero(np.isfinite(m))
    if not known.size:
        return None
    if known.size < m.size:
        m = np.interp(np.arange(m.size), known, m[known])
    return m


def _profile_diagonal(shape: tuple[int, int], wrap: tuple[bool, bool],
                      profile: tuple[int, np.ndarray, np.ndarray, np.ndarray | None]) -> np.ndarray:
    """The diagonal ``(rows · cols,)`` of a coefficient profile's operator (:func:`_coefficient_profile`), without
    ``ω``: for :func:`_stiffness`'s ``model``."""
    axis, windows, lines, relative = profile
    stencil = [1.0, 9.0, 9.0, 1.0]  # (Dᵀ C D's diagonal: a window's squared stencil)
    along = np.convolve(windows, stencil)
    other = shape[1 - axis]
    if relative is not None:
        across = np.convolve(relative, stencil)
    else:
        across = np.full(other, 20.0) if wrap[1 - axis] else np.convolve(np.ones(max(other - 3, 0)), stencil)
    if axis == 1:
        return (along[None, :] + across[:, None] * lines[None, :]).reshape(-1)
    return (along[:, None] + lines[:, None] * across[None, :]).reshape(-1)


def _spectral_preconditioner(offsets: np.ndarray, data: np.ndarray, shape: tuple[int, int], wrap: tuple[bool, bool],
                             weight: float, free: np.ndarray, exact: bool = True,
                             profile: tuple[int, np.ndarray, np.ndarray, np.ndarray | None] | None = None,
                             ) -> "spectral.SpectralPreconditioner":
    """:class:`~quadnodes.linalg.spectral.SpectralPreconditioner` of a grid's ``AᵀA + ωI`` in diagonal storage:
    each family's coefficient the median magnitude of its ``±3`` diagonal (the product of a window's end
    coefficients) over the windows that have one; a family without windows of four nodes gets 0. Where the
    coefficients vary along an open axis (``profile``, :func:`_coefficient_profile`'s) their profile along it
    instead. Exact lines (``exact``; the caller keeps open sides within
    :data:`~quadnodes.linalg.spectral.EXACT_MAX_SIDE`) or cosine ones."""
    rows, cols = shape
    if profile is not None:
        return spectral.SpectralPreconditioner(shape, wrap, 1.0, 1.0, weight, free,
                                               open_lines="exact" if exact else "cosine", profile=profile)
    found = {int(o): d for d, o in enumerate(offsets)}

    def coefficient(offset: int, side: int) -> float:
        if side < 4 or offset not in found:
            return 0.0
        ends = -data[found[offset]]
        ends = ends[ends > 0]
        return float(np.median(ends)) if ends.size else 0.0

    return spectral.SpectralPreconditioner(shape, wrap, coefficient(3, cols), coefficient(3 * cols, rows), weight,
                                           free, open_lines="exact" if exact else "cosine")


def _gershgorin(data: np.ndarray, rows: np.ndarray) -> float:
    """Largest Gershgorin bound (absolute row sum) over ``rows`` (a mask) of a symmetric matrix
    in diagonal storage (a column sum there: ``data[d, j] = M[j - offset_d, j]``)."""
    total = np.abs(data[0])
    for row in data[1:]:  # row by row: no (d, n) temporary
        total += np.abs(row)
    return float(total[rows].max())


def _csr_gershgorin(M: sp.csr_matrix) -> float:
    """Largest Gershgorin bound (absolute row sum) of a CSR matrix."""
    return float(np.add.reduceat(np.abs(M.data), M.indptr[:-1]).max()) if M.nnz else 0.0


def _line_paths(lines: object, free_index: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The free unknowns along every structure line: ``(path, starts, closed)`` for
    :class:`~quadnodes.linalg.cg.PathLinePreconditioner`.

    A new path starts at each line's start and after every vertex that is not free; a closed
    line with such a vertex is first turned to start there (so no path runs across its seam),
    a closed line whose vertices are all free is one closed path.
    """
    col = np.full(n, -1, dtype=np.int64)
    col[free_index] = np.arange(free_index.size)
    flat = lines.indices  # type: ignore[attr-defined]
    lengths = lines.lengths  # type: ignore[attr-defined]
    offsets = lines.offsets[:-1]  # type: ignore[attr-defined]
    line = np.repeat(np.arange(len(lengths)), lengths)
    c = col[flat]
    held = c < 0
    ring = lines.closed  # type: ignore[attr-defined]
    # a closed line with a held vertex: rotate it to begin at its first held vertex
    pos = np.arange(flat.size) - offsets[line]
    first_held = np.full(len(lengths), -1, dtype=np.int64)
    hv = np.flatnonzero(held[::-1])  # the last write wins: scan backwards for the first
    first_held[line[::-1][hv]] = pos[::-1][hv]
    turn = ring & (first_held > 0)
    if turn.any():
        shift = np.where(turn, first_held, 0)[line]
        src = offsets[line] + (pos + shift) % lengths[line]
        c = c[src]
        held = c < 0
    keep = ~held
    starts = np.ones(flat.size, dtype=bool)
    starts[1:] = (line[1:] != line[:-1]) | held[:-1]
    all_free = ring & (np.bincount(line, weights=held, minlength=len(lengths)) == 0)
    closed = starts & all_free[line]
    return c[keep], starts[keep], closed[keep]


def _line_preconditioner(data: np.ndarray, offsets: np.ndarray, cols: int) -> LinePreconditioner:
    """Row-line and column-line bands of a grid's diagonals (offsets ±1..3 come only from row
    windows, ±cols.. only from column windows), each with the whole diagonal, in the nodes' order.

    On a grid closed around (a cylinder or torus: periodic diagonals after the first 13) the
    couplings across the seam are left out of the bands and their absolute values added to
    the diagonal of the lines they belong to (rows for offsets below ``cols``, else columns):
    ``D_|E| − E`` is diagonally dominant, so each band stays at least its family's ``AᵀA``
    plus the rest of the diagonal — positive definite — and a closed line costs one banded
    solve like an open one.
    """
    n = data.shape[1]
    rows = np.zeros((4, n))
    cols_ = np.zeros((4, n))
    rows[3] = cols_[3] = data[6]
    rows[:3] = data[9:6:-1]  # data[6 + k, j] = M[j - k, j] -> row 3 - k
    cols_[:3] = data[12:9:-1]  # data[9 + k, j] = M[j - k·cols, j]
    for slot in range(13, len(offsets)):  # data[slot, j] = M[j - o, j]: column j's entry, = row j's
        (rows if abs(int(offsets[slot])) < cols else cols_)[3] += np.abs(data[slot])
    return LinePreconditioner(rows, cols_, cols)


def _with_rows(rows: sp.spmatrix, vertices: np.ndarray, free: np.ndarray, free_index: np.ndarray, A: sp.csr_matrix,
               b: np.ndarray, rhs: np.ndarray, active: np.ndarray) -> tuple:
    """The system with the rows ``rows`` ``(r, n)`` appended: those holding a free vertex, their fixed part
    moved to ``b`` and ``rhs`` (as for a window with a fixed vertex); ``active`` grows by one flag per row."""
    R = rows.tocsr()
    touch = np.asarray(abs(R) @ free.astype(np.float64)).reshape(-1) > 0
    R = R[touch]
    Rf = R[:, free_index]
    Rb = np.asarray(R[:, ~free] @ vertices[~free]).reshape(-1, 3)
    A = sp.vstack([A, Rf], format="csr")
    return A, np.vstack([b, Rb]), rhs - Rf.T @ Rb, np.concatenate([active, touch])


def _with_weight(AtA: sp.csr_matrix, weight: float) -> sp.csr_matrix:
    """``AᵀA + ω I``, adding ω on the stored diagonal in place (every free vertex is in a
    window, so AᵀA stores each diagonal entry; SciPy would insert a missing one)."""
    M = AtA.tocsr()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sp.SparseEfficiencyWarning)
        M.setdiag(M.diagonal() + weight)
    return M


def _patch_order(windows: np.ndarray, free_index: np.ndarray, side: int = 4) -> np.ndarray:
    """Order of the free vertices that groups them in patches of about ``side × side``.

    Every vertex gets its position along (up to) two structure lines through it,
    read off the windows (consecutive windows of a line share three vertices):
    ``a`` along the line with the smaller number, ``b`` along another. Sorting by
    ``(a // side, b // side, a % side, b % side)`` puts a regular grid's
    ``side × side`` patches one after the other; elsewhere the groups are
    merely less compact.
    """
    n = int(max(windows.max(initial=0), free_index.max(initial=0))) + 1
    brk = np.r_[True, (windows[1:, :3] != windows[:-1, 1:]).any(axis=1)]
    line = np.cumsum(brk) - 1
    first = np.flatnonzero(brk)
    pos = np.arange(len(windows)) - first[line] + 1  # position of p1 along its line
    v = np.concatenate([windows[:, 1], windows[:, 2]])
    ln = np.concatenate([line, line])
    ps = np.concatenate([pos, pos + 1])
    la = np.full(n, np.iinfo(np.int64).max)
    np.minimum.at(la, v, ln)
    a = np.zeros(n, dtype=np.int64)
    b = np.zeros(n, dtype=np.int64)
    on_a = ln == la[v]
    a[v[on_a]] = ps[on_a]
    b[v[~on_a]] = ps[~on_a]
    a, b = a[free_index], b[free_index]
    span = int(b.max(initial=0)) // side + 1
    key = ((a // side) * span + b // side) * (side * side) + (a % side) * side + b % side
    return np.argsort(key, kind="stable")


def _switch_remaining(coarse: int, lines: bool = False) -> float:
    """How many more Gauss–Seidel steps the two-grid path with ``coarse`` coarse nodes is worth:
    :data:`TWO_GRID_REMAINING`, times √(``coarse`` / :data:`TWO_GRID_REMAINING_COARSE`) above that size; on the
    structure lines (``lines``) with ``coarse`` taken at most :data:`TWO_GRID_LINE_REMAINING_COARSE`.

    Examples
    --------
    >>> _switch_remaining(5_776), round(_switch_remaining(63_001)), round(_switch_remaining(62_426, lines=True))
    (700.0, 2268, 1278)
    """
    if lines:
        coarse = min(coarse, TWO_GRID_LINE_REMAINING_COARSE)
    return TWO_GRID_REMAINING * max(1.0, float(np.sqrt(coarse / TWO_GRID_REMAINING_COARSE)))


class _SwitchCheck:
    """Gauss–Seidel's monitor where "auto" may switch to the two-grid cycle (:func:`_switch_remaining`).

    Every :data:`TWO_GRID_AFTER` steps it extrapolates the residual's decay over the last 100 steps (means of
    its logarithm over 10 steps at each end) to the target ``rtol``; it stops the solve (``switch`` True)
    where that needs more than ``remaining`` steps more, or the residual no longer falls. With ``cheaper`` (asked
    only where the steps still needed lie between :data:`LINE_STEP_PRICE` ``· remaining`` and ``remaining``): where
    it returns True the cycle is that much cheaper, and the check switches from the lower price on.
    """

    def __init__(self, rtol: float, remaining: float, cheaper: Callable[[], bool] | None = None) -> None:
        self.target = float(np.log(rtol))
        self.remaining = remaining
        self.cheaper = cheaper
        self.logs: list[float] = []
        self.switch = False

    def __call__(self, step: int, residual: float) -> bool:
        self.logs.append(float(np.log(max(residual, 1e-300))))
        if step < TWO_GRID_AFTER or step % TWO_GRID_AFTER:  # (one log a step: step ≥ 300 of them, 110 needed)
            return False
        now, before = np.mean(self.logs[-10:]), np.mean(self.logs[-110:-100])
        rate = (now - before) / 100.0  # (log of the residual per step: negative while it falls)
        if rate >= 0.0:
            self.switch = True
            return True
        needed = (self.target - now) / rate
        self.switch = bool(needed > self.remaining
                           or (needed > LINE_STEP_PRICE * self.remaining and self.cheaper is not None
                               and self.cheaper()))
        return self.switch


class FairingSystem:
    """One fairing iteration's least-squares system.

    Unknowns are the free vertices only; every window with at least one free
    vertex contributes a row; fixed vertices move to the right-hand side. The
    normal matrix ``AᵀA + ω I`` is the same for x, y and z. It is solved by
    conjugate gradients on all three coordinates at once (one sparse product per
    step for x, y and z together), started from the anchor (or a given start), or — for small systems, on
    request, or if CG does not converge — by a sparse factorization made once
    and reused for every anchor. The condition number is about
    ``(32 + ω h²) / (ω h²)`` on a regular grid with edge length ``h``, so CG needs
    a few dozen steps at the default weight.

    Parameters
    ----------
    vertices : (n, 3) float64
        Current positions; lengths are frozen from them, fixed vertices stay here.
    windows : (w, 4) int64
        Windows of the mesh's structure lines.
    free : (n,) bool
        Vertices to move; must contain at least one vertex.
    weight : float
        Effective penalty weight ``ω`` (> 0), in the model's units (``1/length²``).
    solver : {"auto", "direct", "cg"}
        ``"auto"``: direct up to :data:`DIRECT_LIMIT` unknowns, CG above.
    rtol : float
        CG stops when every coordinate's residual is below ``rtol`` times its
        right-hand side (the solution's relative error is then of the same order).
    preconditioner : {"auto", "gauss-seidel", "two-grid", "lines", "spectral", "none"}
        ``"auto"``: from :data:`COMPILED_MIN_UNKNOWNS` unknowns on (or wherever the compiled
        kernels are loaded), where the Gershgorin bound exceeds :data:`GAUSS_SEIDEL_CONTRAST` ω,
        symmetric Gauss–Seidel in Eisenstat's form: 2.2–6.2× fewer steps than plain CG on two
        threads, each step two sweeps and no product. An open grid takes the grid's fast sweeps
        (:class:`~quadnodes.linalg.gauss_seidel.SymmetricGaussSeidel`), and so does a cylinder grid of at
        least 49 vertices around (its seam's few couplings kept out of the sweeps); tori, smaller cylinders
        and any other mesh sweep compressed rows
        (:class:`~quadnodes.linalg.gauss_seidel.CsrGaussSeidel`). Where the bound exceeds
        :data:`TWO_GRID_CONTRAST` ω (a weight below about 2.5·10⁻⁴) and Gauss–Seidel's rate after
        :data:`TWO_GRID_AFTER` steps says it needs more than :func:`_switch_remaining` more, the
        two-grid cycle around those sweeps, whose steps do not grow as the weight falls: on a grid (open,
        a cylinder or a torus) its coarse grid (:class:`~quadnodes.linalg.multigrid.TwoGrid`), on any
        other mesh (``_lines`` given) coarse nodes along its structure lines
        (:class:`~quadnodes.linalg.multigrid.LineTwoGrid`); either with at most
        :data:`TWO_GRID_COARSE_MAX` coarse nodes. Without the compiled kernels (not loaded, or Numba
        missing), on a mostly free vertex grid (``_topology`` given) whose windows are scaled third
        differences (fair's even spacing): the line operator with constant coefficients inverted by its
        lines' eigenvectors and transforms (:class:`~quadnodes.linalg.spectral.SpectralPreconditioner`,
        on the 300² sheet 4–6× fewer steps than plain CG at the default weight and 74× at 10⁻³, each three to
        six times as dear) where
        :func:`_spectral_pays`, every fixed vertex inside the unknowns' box is inverted around exactly
        (:func:`~quadnodes.linalg.spectral.inverts_exactly`) and no stiff spot exceeds
        :data:`SPECTRAL_MAX_STIFFNESS`. Its steps do not grow as the weight falls (15–25 from the default
        weight to 10⁻⁶), so on such a grid it also takes a torus at every weight and any grid where the bound
        exceeds :func:`_spectral_contrast` ω (on the bench sheet a weight below about 0.025 up to some 450 nodes a
        side with at most :data:`SPECTRAL_FLOOR_MAX_INSIDE` fixed vertices inside, else 5·10⁻³ up to 1000, and
        on cylinders, growing with the side's square), with or without the kernels, in
        place of Gauss–Seidel and the two-grid switch; cosine lines where the bound is at most
        :data:`SPECTRAL_EXACT_CONTRAST` ω and SciPy's transforms are imported (or an axis closes around).
        On a grid (open or closed around) with stiff spots — some unknown's fairing diagonal at least
        :data:`LINES_MIN_STIFFNESS` times the median one's, as eq. 32's own lengths give a nearly collapsed
        stretch of a line — and no tiny weight (the bound over that stiffness within :data:`TWO_GRID_CONTRAST`
        ω): the line preconditioner in place of all the above but the spectral one, the kernels loaded for it
        where they are wanted anyway or plain CG's work reaches :data:`LINES_MIN_WORK`.
        Elsewhere: block Jacobi at small weights, else none.
        ``"gauss-seidel"``: that preconditioner at any size (needs the compiled kernels).
        ``"two-grid"``: the two-grid cycle at any weight (a mostly free vertex grid's, else the structure
        lines'; needs ``_topology`` or ``_lines``).
        ``"lines"``:
        the line preconditioner at any size — on a grid's diagonal storage the additive
        row-line + column-line blocks (:class:`~quadnodes.linalg.cg.LinePreconditioner`),
        on any other mesh (``_lines`` given) the same along its structure lines
        (:class:`~quadnodes.linalg.cg.PathLinePreconditioner`); its step count barely
        depends on the noise or the size (59–60 steps on 300² and 1000² broadband
        noise against 222 and 473). ``"spectral"``: the transforms' preconditioner at any size and
        weight (a mostly free vertex grid, ``_topology`` given). ``"none"``: plain CG.

    Attributes
    ----------
    A : (w, k) scipy.sparse.csr_matrix
        The active windows' rows over the free vertices (a row may hold a column twice, or an explicit zero where a
        window's vertex is fixed). Its data is read-only — on the grid path it is the memory the diagonal storage
        is built from — so SciPy's methods that tidy a matrix in place (``abs``, ``max``, ``sort_indices`` …) raise
        on it; use ``A.copy()`` for those.
    iterations : int
        CG steps of the last :meth:`solve` (0 for the direct solver).
    residual : float
        Relative residual of the last :meth:`solve`.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(3, 5, height=[[0] * 5, [0, 0, 1, 0, 0], [0] * 5])
    >>> free = np.zeros(15, bool); free[7] = True
    >>> s = FairingSystem(m.vertices, m.topology.windows, free, weight=1.0)
    >>> s.solve(m.vertices[free]).round(3).tolist()
    [[2.0, 1.0, 0.308]]
    """

    def __init__(
        self,
        vertices: np.ndarray,
        windows: np.ndarray,
        free: np.ndarray,
        weight: float,
        *,
        solver: Literal["auto", "direct", "cg"] = "auto",
        rtol: float = 1e-9,
        preconditioner: Literal["auto", "gauss-seidel", "two-grid", "lines", "spectral", "none"] = "auto",
        _inverse_lengths: np.ndarray | None = None,
        _topology: object | None = None,
        _lines: object | None = None,
        _extra_rows: sp.spmatrix | None = None,
    ) -> None:
        weight = _validate.positive_number(weight, "weight")
        free = np.asarray(free, dtype=bool)
        n = vertices.shape[0]
        self.free_index = np.flatnonzero(free)
        k = self.free_index.size
        if k == 0:
            raise InputError("free: no vertex is free; nothing to solve")
        is_free = free[windows]
        # a window's four flags as one 32-bit word (NumPy reduces over an axis of 4 slowly)
        word = is_free.view(np.uint32).reshape(-1)
        active = word != 0
        win = windows if active.all() else windows[active]
        if win is not windows:
            is_free, word = is_free[active], word[active]
        # whether every window's row is a scaled third difference (its three edges at one length: fair's even
        # spacing, line_spacing="fair"): the spectral preconditioner's model, which eq. 32's own lengths leave
        self._third_differences = False
        if _inverse_lengths is not None:  # (w, 3) for all windows, from fair()'s detection pass
            coef_all = _coefficients(_inverse_lengths[:, 0], _inverse_lengths[:, 1], _inverse_lengths[:, 2])
            self._third_differences = bool(np.array_equal(_inverse_lengths[:, 0], _inverse_lengths[:, 1])
                                           and np.array_equal(_inverse_lengths[:, 1], _inverse_lengths[:, 2]))
        elif _topology is not None:  # the grid path needs every window's coefficients
            coef_all = window_coefficients(vertices, windows)
        else:
            coef_all = None
        if coef_all is None:
            coef = window_coefficients(vertices, win)
        else:
            coef = coef_all if win is windows else coef_all[active]
        # ``_topology``: the mesh's, whose windows ``windows`` are (fair() passes it): see _cg_setup
        pattern = None if _topology is None else grid_pattern(_topology)
        self._grid = None if pattern is None else (pattern, coef_all, free)
        idx = np.int32 if max(n, 4 * len(win)) < 2**31 - 1 else np.int64
        col = np.full(n, -1, dtype=idx)
        col[self.free_index] = np.arange(k, dtype=idx)
        cols = col[win]
        # rows are the windows in order, so the CSR arrays come straight out of the
        # row-major masks: no COO sort (a row may hold one column twice on a 3-ring;
        # sparse products add such duplicates, as the sum of squares requires)
        partial = np.flatnonzero(word != np.frombuffer(b"\x01" * 4, np.uint32)[0])  # windows with a fixed vertex
        # fixed vertices' contribution to every active row (zero where all four are free)
        b = np.zeros((len(win), 3))
        wp = win[partial]
        b[partial] = np.einsum("wk,wkj->wj", np.where(is_free[partial], 0.0, coef[partial]),
                               np.take(vertices, wp.reshape(-1), axis=0).reshape(wp.shape + (3,)))
        pf = is_free[partial]
        at, w_coef = cols[partial][pf], coef[partial][pf]  # (the partial windows' free slots, for -Aᵀb below)
        if partial.size <= len(win) // PARTIAL_IN_PLACE:
            # none or a few windows with a fixed vertex (a fixed boundary, a few fixed corners): every row keeps its
            # four slots, a fixed vertex's slot turned into an explicit zero at a free vertex of its window (no new
            # coupling; products add it as nothing), so the coefficients go into A as they are, not copied. (The
            # grid's storage drops fixed slots by ``free`` itself.)
            first = cols[partial, np.argmax(pf, axis=1)]
            cols[partial] = np.where(pf, cols[partial], first[:, None])
            coef[partial] = np.where(pf, coef[partial], 0.0)
            indptr = np.arange(0, 4 * len(win) + 1, 4, dtype=idx)
            # A's data is a read-only view of the coefficients — on the grid path the same memory the grid's storage
            # is made from at the first solve: SciPy's tidying methods (abs, max, sort_indices … sort and sum a
            # row's slots in place) then raise instead of rewriting them. (The array itself stays writable: the
            # compiled kernels are loaded for writable arrays.)
            data = coef.reshape(-1)
            data.flags.writeable = False
            A = sp.csr_matrix((data, cols.reshape(-1), indptr), shape=(len(win), k))
        else:
            count = np.full(len(win), 4, dtype=idx)
            count[partial] = pf.sum(axis=1)
            indptr = np.zeros(len(win) + 1, dtype=idx)
            np.cumsum(count, out=indptr[1:])
            A = sp.csr_matrix((coef[is_free], cols[is_free], indptr), shape=(len(win), k))
        self.weight = weight
        self._lines = _lines  # the mesh's structure lines (StructureLines): paths for the line preconditioner
        self._n_vertices = n
        # (the error guard's; column by column: NumPy reduces an (n, 3) array over its rows 10× slower)
        self._extent = max(float(vertices[:, j].max() - vertices[:, j].min()) for j in range(3))
        self._windows = win
        self.active = active
        self.A = A
        self.b = b
        # -Aᵀb: only the windows with a fixed vertex have b ≠ 0
        rhs = np.zeros((k, 3))
        if partial.size:
            wb = np.repeat(b[partial], pf.sum(axis=1), axis=0)
            if at.size <= k // 8:  # (a few: in place, in the same order, the same sums; no three k-long counts)
                np.subtract.at(rhs, at, w_coef[:, None] * wb)
            else:
                for j in range(3):
                    rhs[:, j] = -np.bincount(at, weights=w_coef * wb[:, j], minlength=k)
        if _extra_rows is not None:  # more rows of any width (quadnodes.line_ends), after the windows'
            A, b, rhs, active = _with_rows(_extra_rows, vertices, free, self.free_index, A, b, rhs, active)
            self.A, self.b, self.active = A, b, active
        self._rhs = rhs
        if solver not in ("auto", "direct", "cg"):
            raise InputError(f"solver: expected 'auto', 'direct' or 'cg', got {solver!r}")
        self.solver = "direct" if solver == "direct" or (solver == "auto" and k <= DIRECT_LIMIT) else "cg"
        self.preconditioner = _validate.choice(preconditioner, PRECONDITIONERS, "preconditioner")
        self._grid_cols = None if _topology is None or _topology.grid_shape is None else _topology.grid_shape[1]
        self.rtol = _validate.positive_number(rtol, "rtol")
        self.iterations = 0
        self.residual = 0.0
        self._lu: object | None = None

    @property
    def matrix(self) -> sp.csr_matrix:
        """The normal matrix ``AᵀA + ω I`` (assembled on first use)."""
        if self._matrix is None:
            self._matrix = _with_weight(self.A.T.tocsr() @ self.A, self.weight)
        return self._matrix

    _matrix: sp.csr_matrix | None = None

    def _apply(self, X: np.ndarray) -> np.ndarray:
        """``(AᵀA + ω I) X`` with the assembled matrix (one sparse pass per product)."""
        return self.matrix @ X

    def _factor(self) -> object:
        """Factorize ``AᵀA + ωI`` once.

        The matrix is symmetric positive definite as long as ``ω`` is not lost
        next to ``AᵀA`` in floating point; then a factorization without pivoting
        in a symmetric fill-reducing order is a Cholesky factorization and cannot
        meet a zero pivot (:func:`quadnodes.linalg.factorize`). Where ``ω`` is negligible (below 1e-10 of the largest
        diagonal entry) the system is refused instead of handed to SuperLU.
        """
        if self._lu is None:
            M = self.matrix
            top = float(M.diagonal().max())
            if not self.weight > 1e-10 * top:
                raise InputError(
                    f"weight: the effective weight {self.weight:.3g} is negligible next to the fairing term "
                    f"({top:.3g}); the system is numerically singular — raise the weight, or check for very "
                    "short edges"
                )
            self._lu = factorize(M, kind="spd", what="fairing")
        return self._lu

    def _cg_setup(self) -> tuple[RowBlocks, BlockJacobi | None, np.ndarray | None]:
        """The CG operator (row ranges), its preconditioner and the unknowns' order, made once.

        With the compiled kernels at hand and a Gershgorin bound above :data:`GAUSS_SEIDEL_CONTRAST` ω:
        symmetric Gauss–Seidel, the fast sweeps on a mostly free open vertex grid and on a cylinder grid
        whose periodic pairs the storage reads as entries
        (:class:`~quadnodes.linalg.gauss_seidel.SymmetricGaussSeidel`), compressed rows on a torus, a smaller
        cylinder and any other mesh (:class:`~quadnodes.linalg.gauss_seidel.CsrGaussSeidel`).
        Where the bound exceeds :data:`TWO_GRID_CONTRAST` ω — on such a grid (open or closed around) with more
        than :data:`TWO_GRID_MIN_SIDE` rows and columns and a coarse grid of at most :data:`TWO_GRID_COARSE_MAX`
        vertices, on any other mesh with its structure lines (``_lines``) from :data:`TWO_GRID_MIN_SIDE`² to
        :data:`TWO_GRID_COARSE_MAX` · :data:`~quadnodes.linalg.multigrid.TWO_GRID_STRIDE`² unknowns — Gauss–Seidel
        is marked to switch to the two-grid cycle (:class:`~quadnodes.linalg.multigrid.TwoGrid`, or on the lines
        :class:`~quadnodes.linalg.multigrid.LineTwoGrid`) in :meth:`solve` where its rate after
        :data:`TWO_GRID_AFTER` steps says it needs more than :func:`_switch_remaining` more (on a mesh that is no
        grid the cycle starts at once above :data:`TWO_GRID_AT_ONCE_CONTRAST` ω with at most
        :data:`TWO_GRID_AT_ONCE_HELD` of the vertices held; its line step where faces are long and thin,
        :meth:`_line_smoothing`); there the
        kernels are loaded at any size — except where the spectral preconditioner takes the grid (see
        ``preconditioner`` in the class: a torus, or a grid above :func:`_spectral_contrast` ω). Otherwise, on a
        mostly free vertex grid whose windows are scaled third differences, the spectral preconditioner
        (:class:`~quadnodes.linalg.spectral.SpectralPreconditioner`; with the coefficients' profile where they vary
        along an open axis, :func:`_coefficient_profile`) where :func:`_spectral_pays`, every fixed vertex inside
        the unknowns' box inverted around exactly and no stiff spot above :data:`SPECTRAL_MAX_STIFFNESS` (against
        the profile where there is one); else
        when the weight is small next to the fairing term (mean diagonal of AᵀA
        above :data:`BLOCK_JACOBI_RATIO` ω, or :data:`GRID_BLOCK_JACOBI_RATIO` ω on a
        grid), the unknowns are renumbered in patches (:func:`_patch_order`) and
        preconditioned by :class:`BlockJacobi`; otherwise CG on ``AᵀA + ωI``:
        on a mostly free complete vertex grid (``_topology`` given) in the grid's
        numbering with diagonal storage (:class:`~quadnodes.linalg.grid.GridPattern`; compiled
        from :data:`COMPILED_MIN_UNKNOWNS` unknowns on), else plain in ``free_index`` order. The
        line preconditioner on request (``preconditioner="lines"``), or on a grid with stiff spots (see
        ``preconditioner`` in the class: :data:`LINES_MIN_STIFFNESS`).
        """
        if self._cg is None:
            A, k = self.A, self.n_free
            mean_diag = float(np.einsum("i,i->", A.data, A.data)) / k
            grid = self._grid is not None and HAS_DIAGONAL_KERNEL and k >= GRID_MIN_FREE * self._grid[2].size
            ratio = GRID_BLOCK_JACOBI_RATIO if grid else BLOCK_JACOBI_RATIO
            # the compiled kernels from COMPILED_MIN_UNKNOWNS on (fair() started loading them), or
            # wherever they are loaded already (a server, a second run): then they cost nothing
            wanted = (k >= COMPILED_MIN_UNKNOWNS or self.preconditioner in ("lines", "gauss-seidel", "two-grid")
                      or kernels.ready())
            storage: list = []  # the grid's diagonal storage, built once where a path uses it

            def grid_storage() -> tuple[np.ndarray, np.ndarray]:
                if not storage:
                    pattern, coef, free = self._grid
                    storage.extend(pattern.normal_matrix(coef, free, self.weight))
                return storage[0], storage[1]

            # the largest Gershgorin bound against ω: how many steps plain CG would need (and the error guard's cue)
            bound = _gershgorin(grid_storage()[1], self._grid[2]) if grid else _csr_gershgorin(self.matrix)
            contrast = self._contrast = bound / self.weight
            open_grid = grid and self._grid[0].offsets.size == 13
            shape = wrap = strides = None  # a grid's (rows, cols), whether they close around, the two-grid strides
            if grid:
                offsets, data = grid_storage()
                cols = int(offsets[10])  # (offsets: -3c, -2c, -c, -3 … 3, c, 2c, 3c[, across the seams])
                shape, wrap = (data.shape[1] // cols, cols), self._grid[0].wrap
                if self.preconditioner == "two-grid" or contrast > TWO_GRID_CONTRAST:  # (only where it may be used)
                    strides = _two_grid_strides(data, self._grid[2])
            # on a grid whose windows are scaled third differences (fair's even spacing), with no stiff spot and
            # every fixed vertex inside the unknowns' box inverted around exactly: the line operator with constant
            # coefficients by the lines' eigenvectors and transforms. Its steps do not grow as the weight falls, so
            # it takes a torus at every weight and any grid at small weights (above _spectral_contrast) in place of
            # everything else; at larger weights, where the compiled sweeps are not used (not loaded, or Numba
            # missing) and it pays (_spectral_pays), in place of plain CG and of block Jacobi
            fits: list[bool] = []  # (the checks once)
            open_side = max([side for side, closed in zip(shape, wrap) if not closed], default=0) if grid else 0
            # exact lines where the bound exceeds SPECTRAL_EXACT_CONTRAST ω (or on request), or on an open grid where
            # SciPy's transforms are not imported (exact lines need none); cosine ones below
            exact_lines = (contrast > SPECTRAL_EXACT_CONTRAST or self.preconditioner == "spectral"
                           or (grid and not any(wrap) and not spectral.loaded()
                               and open_side <= SPECTRAL_EXACT_FRESH_SIDE)) \
                and open_side <= spectral.EXACT_MAX_SIDE

            stiff: list[float] = []  # (_stiffness once)

            def stiffness() -> float:
                if not stiff:
                    stiff.append(_stiffness(*grid_storage(), self._grid[2], self.weight))
                return stiff[0]

            profile: list = []  # (the coefficients' profile along an open axis, or None: once)

            def coefficient_profile() -> tuple[int, np.ndarray, np.ndarray, np.ndarray | None] | None:
                if not profile:
                    profile.append(_coefficient_profile(*grid_storage(), shape, wrap))
                return profile[0]

            inside: list[int] = []  # (the fixed vertices inside the unknowns' box: counted once)

            def fixed_inside() -> int:
                if not inside:
                    inside.append(spectral.fixed_inside(self._grid[2].reshape(shape), wrap))
                return inside[0]

            def correction_pays() -> bool:  # (the exact lines' correction's set-up against plain CG's steps)
                if not exact_lines or any(wrap):
                    return True
                p = fixed_inside()
                return p * p <= CORRECTION_PAYS * np.sqrt(contrast)

            def spectral_fits() -> bool:
                # (a stiff spot: an outlier that the coefficients miss, constant or their profile)
                if not fits:
                    fits.append(self.preconditioner == "auto" and self._third_differences
                                and spectral.inverts_exactly(self._grid[2].reshape(shape), wrap,
                                                             "exact" if exact_lines else "cosine")
                                and correction_pays()
                                and (stiffness() if coefficient_profile() is None else
                                     _stiffness(*grid_storage(), self._grid[2], self.weight,
                                                _profile_diagonal(shape, wrap, coefficient_profile()))
                                     ) <= SPECTRAL_MAX_STIFFNESS)
                return fits[0]

            # (each fixed vertex left out of the correction costs many steps at tiny weights: a 150² torus with 16 of
            # them, only zeroed, took 1,341 at ω = 10⁻⁸ against the two-grid cycle's 381, a reviewer's script)
            # (above the floor under small grids only on an open grid with few fixed vertices inside the box to
            # invert around: counted only there)
            tiny = exact_lines and (
                contrast > _spectral_contrast(open_side, floored=False)
                or (contrast > _spectral_contrast(open_side, floored=True) and grid and not any(wrap)
                    and self.preconditioner == "auto" and fixed_inside() <= SPECTRAL_FLOOR_MAX_INSIDE))
            spectral_only = grid and (wrap == (True, True) or tiny) and _spectral_pays(k, contrast) and spectral_fits()
            # a grid with stiff spots (a stretch of a line nearly collapsed, under eq. 32's own lengths): the lines'
            # banded solves take what the point sweeps cannot — not at a weight where the two-grid switch may be
            # wanted (the bound over ω without the stiff spots' excess, the bound over the stiffness, above
            # TWO_GRID_CONTRAST)
            # (the kernels loaded for it where plain CG's work, unknowns × √(bound / ω), repays loading them)
            stiff_lines = (grid and self.preconditioner == "auto" and not spectral_only
                           and contrast > GAUSS_SEIDEL_CONTRAST and stiffness() >= LINES_MIN_STIFFNESS
                           and contrast / stiffness() <= TWO_GRID_CONTRAST
                           and (wanted or k * np.sqrt(contrast) >= LINES_MIN_WORK))
            may_switch = (self.preconditioner == "auto" and contrast > TWO_GRID_CONTRAST and not spectral_only
                          and not stiff_lines)
            if may_switch and shape is not None:
                self._coarse = int(np.prod([coarse_nodes(side, st, c).size
                                            for side, st, c in zip(shape, strides, wrap)]))
                may_switch = min(shape) > TWO_GRID_MIN_SIDE and self._coarse <= TWO_GRID_COARSE_MAX
            elif may_switch:  # any other mesh: coarse nodes along its structure lines (every 4th: one in about 16)
                may_switch = (self._lines is not None
                              and TWO_GRID_MIN_SIDE**2 < k <= TWO_GRID_COARSE_MAX * TWO_GRID_STRIDE**2)
            wanted = wanted or may_switch or stiff_lines
            chosen = self.preconditioner in ("gauss-seidel", "two-grid")
            if (chosen or (self.preconditioner == "auto" and wanted and contrast > GAUSS_SEIDEL_CONTRAST
                           and not spectral_only and not stiff_lines)) \
                    and kernels.wait():
                # symmetric Gauss–Seidel in Eisenstat's form: an open grid's fast sweeps, and a cylinder's with
                # its seam's couplings kept out of them; a torus and any other mesh in compressed rows,
                # in their own order. At tiny weights, the two-grid cycle around those sweeps.
                if not grid:  # any other mesh: the cycle's coarse nodes along its structure lines
                    if self.preconditioner == "two-grid" and self._lines is None:
                        raise InputError("preconditioner='two-grid' needs the mesh's structure lines; use 'auto'")
                    rows = RowBlocks(self.matrix)
                    if self.preconditioner == "two-grid":
                        return self._two_grid(rows, self._line_prolongation())
                    if may_switch:  # (the coarse space made now: where it is too large, no switch and no restart)
                        try:
                            self._switch_to = self._line_prolongation()
                            self._coarse = self._switch_to.shape[1]
                        except InputError:
                            pass
                    if (self._switch_to is not None and contrast > TWO_GRID_AT_ONCE_CONTRAST
                            and k >= (1.0 - TWO_GRID_AT_ONCE_HELD) * self._n_vertices):
                        try:
                            return self._two_grid(rows, self._switch_to)
                        except InputError:  # (the coarse matrix is made definite: not expected)
                            pass  # Gauss–Seidel, ready to switch, as below
                    return self._gauss_seidel(rows, CsrGaussSeidel)
                offsets, data = grid_storage()
                if self.preconditioner == "two-grid":
                    blocks = SymmetricDiagonalBlocks(offsets, data) if open_grid else DiagonalBlocks(offsets, data)
                    return self._two_grid(blocks, (shape, wrap, strides))
                if may_switch:
                    self._switch_to = (shape, wrap, strides)
                # a cylinder too: the open grid's sweeps, its seam's few couplings kept out of them (on a torus
                # leaving both seams out cost more steps than the fast sweeps save: a 51,200-vertex torus 603
                # against 467 steps at ω = 0.3, a reviewer's throwaway timing)
                if all(wrap):
                    return self._gauss_seidel(DiagonalBlocks(offsets, data), CsrGaussSeidel)
                blocks = SymmetricDiagonalBlocks(offsets, data)
                return self._gauss_seidel(blocks, SymmetricGaussSeidel if SymmetricGaussSeidel.fits(blocks)
                                          else CsrGaussSeidel)
            if self.preconditioner in ("gauss-seidel", "two-grid"):
                raise InputError(f"preconditioner={self.preconditioner!r} needs the compiled kernels (Numba); use 'auto'")
            if self.preconditioner == "spectral" and not grid:
                raise InputError("preconditioner='spectral' needs the grid path: a complete vertex grid (rows and "
                                 f"columns of at least 4 vertices) with at least {GRID_MIN_FREE:.0%} of its vertices "
                                 "free; use 'auto'")
            use_spectral = grid and (self.preconditioner == "spectral" or spectral_only
                                     or (not (wanted and kernels.wait()) and _spectral_pays(k, contrast)
                                         and spectral_fits()))
            stiff_lines = stiff_lines and kernels.wait()
            if k >= BLOCK_SIZE and mean_diag > ratio * self.weight and self.preconditioner == "auto" \
                    and not use_spectral and not stiff_lines:
                order = _patch_order(self._windows, self.free_index, 4)
                M = permuted(self.matrix, order)
                self._cg = (RowBlocks(M), BlockJacobi(M, BLOCK_SIZE), order)
            elif grid:  # a mostly free vertex grid: diagonal storage in the grid's numbering
                offsets, data = grid_storage()
                compiled = wanted and kernels.wait()
                precond = None
                if self.preconditioner == "lines" or stiff_lines:  # (on request, or a grid with stiff spots)
                    try:
                        precond = _line_preconditioner(data, offsets, cols)
                    except np.linalg.LinAlgError as exc:  # a line block not positive definite
                        if not stiff_lines:
                            raise InputError(f"preconditioner='lines': {exc}; use 'auto'") from exc
                        precond = None  # ("auto"'s choice: rounding lost a band's definiteness; plain CG then)
                elif use_spectral:  # (cosine lines where the exact ones' dearer steps do not pay: exact_lines)
                    precond = _spectral_preconditioner(offsets, data, shape, wrap, self.weight, self._grid[2],
                                                       exact=exact_lines, profile=coefficient_profile())
                blocks = SymmetricDiagonalBlocks(offsets, data) if compiled else DiagonalBlocks(offsets, data)
                self._cg = (blocks, precond, None)
            else:
                M = self.matrix
                precond = None
                if self._lines is not None and self.preconditioner == "lines" and kernels.wait():  # (on request)
                    try:
                        precond = PathLinePreconditioner(M, *_line_paths(self._lines, self.free_index,
                                                                         self._n_vertices))
                    except np.linalg.LinAlgError as exc:  # a band not positive definite
                        raise InputError(f"preconditioner='lines': {exc}; use 'auto'") from exc
                self._cg = (RowBlocks(M), precond, None)
        return self._cg

    _cg: tuple | None = None
    _contrast = 0.0  # (set by _cg_setup: the Gershgorin bound over ω where a preconditioner was chosen by it)
    _coarse = 0  # (set by _cg_setup where "auto" may switch: the two-grid path's coarse nodes)
    #: (set by _cg_setup where "auto" may switch to the two-grid cycle: the grid's (rows, cols), its wrap and
    #: the cycle's strides; on any other mesh the structure lines' prolongation, :meth:`_line_prolongation`)
    _switch_to: tuple[tuple[int, int], tuple[bool, bool], tuple[int, int]] | sp.csr_matrix | None = None

    def _two_grid(self, blocks: RowBlocks,
                  target: tuple[tuple[int, int], tuple[bool, bool], tuple[int, int]] | sp.csr_matrix) -> tuple:
        """``self._cg`` with the two-grid cycle on ``blocks`` (a grid's diagonal storage, or compressed rows):
        for ``target = ((rows, cols), (wrap_rows, wrap_cols), (rows' stride, cols' stride))`` the grid's
        (:class:`~quadnodes.linalg.multigrid.TwoGrid`), for a prolongation (:meth:`_line_prolongation`) the
        structure lines' (:class:`~quadnodes.linalg.multigrid.LineTwoGrid`)."""
        try:
            if sp.issparse(target):
                self._cg = (blocks, LineTwoGrid(blocks, target, lines=self._line_step(blocks.M)), None)
            else:
                shape, wrap, strides = target
                self._cg = (blocks, TwoGrid(blocks, shape, self._grid[2], stride=strides, wrap=wrap), None)
        except InputError:  # (the line coarse space too large, or the coarse matrix not factorized: named already)
            raise
        except ValueError as exc:  # a grid too small for a coarse grid
            raise InputError(f"preconditioner='two-grid': {exc}") from exc
        except np.linalg.LinAlgError as exc:  # pragma: no cover - ω > 0 keeps the diagonal positive
            raise InputError(f"preconditioner='two-grid': {exc}") from exc
        self._switch_to = None
        return self._cg

    def _line_step(self, M: sp.csr_matrix) -> PathLinePreconditioner | None:
        """:meth:`_line_smoothing` of ``M``, made once for it (the switch's monitor may ask before the cycle is
        made; both pass the same matrix)."""
        if self._line_step_of is not M:
            self._line_step_solves = self._line_smoothing(M)
            self._line_step_of = M
        return self._line_step_solves

    _line_step_of: sp.csr_matrix | None = None
    _line_step_solves: PathLinePreconditioner | None = None

    def _line_smoothing(self, M: sp.csr_matrix) -> PathLinePreconditioner | None:
        """The structure lines' cycle's line solves, where faces are long and thin: each unknown's most strongly
        tied line (:func:`~quadnodes.linalg.cg.strongest_lines`), in stretches of consecutive unknowns, solved
        along (:class:`~quadnodes.linalg.cg.PathLinePreconditioner`). None where at most
        :data:`LINE_SMOOTHING_SHARE` of the unknowns are tied :data:`LINE_SMOOTHING_RATIO` times more strongly one way
        than the other (the point sweeps do there), or where a band is not positive definite."""
        path, starts, _ = _line_paths(self._lines, self.free_index, self._n_vertices)
        if path.size == 0:
            return None
        ratio, strongest = strongest_lines(M, path, starts)
        if np.count_nonzero(ratio > LINE_SMOOTHING_RATIO) <= LINE_SMOOTHING_SHARE * ratio.size:
            return None
        kept = np.flatnonzero(strongest)
        stretch = starts[kept]
        stretch[1:] |= kept[1:] != kept[:-1] + 1
        stretch[0] = True
        try:  # (the stretches open: a closed line kept whole leaves its seam's couplings to the sweeps)
            return PathLinePreconditioner(M, path[kept], stretch)
        except np.linalg.LinAlgError:  # pragma: no cover - a band of a definite M with its whole diagonal
            return None

    def _line_prolongation(self) -> sp.csr_matrix:
        """The unknowns' rows of :func:`~quadnodes.linalg.multigrid.line_interpolation` on the structure lines
        (coarse nodes that reach no unknown dropped): every :data:`TWO_GRID_LINE_STRIDE`-th line up to
        :data:`TWO_GRID_LINE_STRIDE_MAX` unknowns (unless that makes more than :data:`TWO_GRID_COARSE_MAX`
        coarse nodes), every :data:`~quadnodes.linalg.multigrid.TWO_GRID_STRIDE`-th otherwise.

        Raises
        ------
        InputError
            When the coarse nodes exceed :data:`TWO_GRID_COARSE_MAX` (lines too tangled for a coarse space).
        """
        lines = self._lines
        # (every 3rd line makes one coarse node in 9 to 4 unknowns, as densely as the extraordinary vertices lie;
        # where that exceeds the cap, every 4th line, one in about 16)
        strides = ((TWO_GRID_LINE_STRIDE, TWO_GRID_STRIDE) if self.n_free <= TWO_GRID_LINE_STRIDE_MAX
                   else (TWO_GRID_STRIDE,))
        for stride in strides:
            P = line_interpolation(lines.indices, lines.offsets, lines.closed,  # type: ignore[union-attr]
                                   self._n_vertices, stride=stride)[0][self.free_index]
            P = P[:, np.flatnonzero(P.getnnz(axis=0))].tocsr()
            if P.shape[1] <= TWO_GRID_COARSE_MAX:
                return P
        raise InputError(f"preconditioner='two-grid': {P.shape[1]} coarse nodes along the structure lines, more "
                         f"than {TWO_GRID_COARSE_MAX}; use 'auto' (Gauss–Seidel)")

    def _gauss_seidel(self, blocks: RowBlocks, kind: type) -> tuple:
        """``self._cg`` with symmetric Gauss–Seidel of ``kind`` on ``blocks``."""
        try:
            self._cg = (blocks, kind(blocks), None)
        except np.linalg.LinAlgError as exc:  # pragma: no cover - ω > 0 keeps the diagonal positive
            raise InputError(f"preconditioner: {exc}") from exc
        return self._cg

    @property
    def n_free(self) -> int:
        """Number of unknown vertices."""
        return int(self.free_index.size)

    def solve(self, anchor: ArrayLike, start: ArrayLike | None = None) -> np.ndarray:
        """Minimize ``||A x + b||² + ω ||x − anchor||²``.

        Parameters
        ----------
        anchor : (k, 3) float64
            Penalty targets of the free vertices, in ``free_index`` order.
        start : (k, 3) float64, optional
            CG's starting guess (default: the anchor). An anchor far off the mesh (fair's second solves
            at tiny weights put it at ``a + AᵀHf/ω``) wants a start near the answer: CG's updated residual
            drifts from the true one by rounding in proportion to the first residual.

        Returns
        -------
        (k, 3) float64
            New positions of the free vertices.
        """
        a = np.asarray(anchor, dtype=np.float64)
        if a.shape != (self.n_free, 3):
            raise InputError(f"anchor: expected shape ({self.n_free}, 3), got {a.shape}")
        s0 = a if start is None else np.asarray(start, dtype=np.float64)
        if s0.shape != a.shape:
            raise InputError(f"start: expected shape ({self.n_free}, 3), got {s0.shape}")
        rhs = self._rhs + self.weight * a
        if self.solver == "cg":
            # translation equivariance: solve about the start's centroid, so the stopping
            # rule is relative to the mesh's extent, not to its distance from the origin
            c = np.ones(len(s0)) @ s0 / len(s0)  # (NumPy's mean over axis 0 of (k, 3) is ~15x slower)
            blocks, precond, order = self._cg_setup()
            if isinstance(blocks, DiagonalBlocks):  # the grid's numbering: fixed rows are identity
                fi = self.free_index
                shifted = np.zeros((blocks.M.shape[0], 3))
                ones = np.ones((1, shifted.shape[0]))
                row_sums = np.empty_like(ones)
                blocks.matvec(ones, row_sums, 0, shifted.shape[0])
                shifted[fi] = rhs - np.take(row_sums[0], fi)[:, None] * c  # M c = (M 1) c: one scatter
                x0 = np.zeros_like(shifted)
                x0[fi] = s0 - c
            else:
                rhs_cg, s_cg = rhs, s0
                if order is not None:  # unknowns along the Morton curve
                    rhs_cg, s_cg = np.take(rhs, order, axis=0), np.take(s0, order, axis=0)
                shifted = rhs_cg - blocks.M @ np.broadcast_to(c, a.shape)
                x0 = s_cg - c
            rtol = self.rtol * (GAUSS_SEIDEL_RTOL if getattr(precond, "eisenstat", False)
                                else TWO_GRID_RTOL if isinstance(precond, (TwoGrid, LineTwoGrid)) else 1.0)
            guard = np.inf  # ‖e‖₂ ≤ ‖r‖₂ / ω: at tiny weights keep the RMS error within ERROR_RMS of the extent
            if self._contrast > ERROR_GUARD_CONTRAST:
                extent = self._extent  # (the mesh's, not the anchor's: fair's second solves move it far off the mesh)
                worst = float(np.sqrt(np.einsum("ij,ij->j", shifted, shifted).max()))
                if worst > 0 and extent > 0:
                    guard = ERROR_RMS * extent * self.weight * np.sqrt(len(a)) / worst
                    rtol = min(rtol, guard)
            on_lines = sp.issparse(self._switch_to)
            check = None if self._switch_to is None else _SwitchCheck(
                rtol, _switch_remaining(self._coarse, lines=on_lines),
                cheaper=(lambda: self._line_step(blocks.M) is not None) if on_lines else None)
            if check is not None:  # Gauss–Seidel, watched: it stops where the two-grid cycle would be faster
                y, its, res = gauss_seidel_cg(blocks, shifted, x0, rtol=rtol, maxiter=MAX_CG_ITERATIONS,
                                              sweeps=precond, monitor=check)
            else:
                y, its, res = block_cg(blocks, shifted, x0, rtol=rtol, maxiter=MAX_CG_ITERATIONS, precond=precond)
            if check is not None and check.switch:  # slow: smooth modes that only ω holds
                # (on from Gauss–Seidel's iterate, which has not met the error guard: the guard is what keeps the
                # residual it leaves in the smooth modes from meaning a large error)
                try:
                    blocks, precond, _ = self._two_grid(blocks, self._switch_to)
                    rtol = min(self.rtol * TWO_GRID_RTOL, guard)
                except InputError:  # pragma: no cover - (the coarse matrix is made definite, the line coarse space
                    # checked in _cg_setup) Gauss–Seidel goes on
                    self._switch_to = None
                y, more, res = block_cg(blocks, shifted, y, rtol=rtol, maxiter=MAX_CG_ITERATIONS - its,
                                        precond=precond)
                its += more
            # (at the cap a residual within rtol is not enough: at tiny weights the smooth error it leaves may be
            # far beyond rtol, see ERROR_GUARD_CONTRAST)
            if res <= self.rtol and its < MAX_CG_ITERATIONS:
                self.iterations, self.residual = its, res
                if isinstance(blocks, DiagonalBlocks):
                    y = np.take(y, self.free_index, axis=0)
                y += c
                if order is not None:
                    out = np.empty_like(y)
                    out[order] = y
                    y = out
                return y
            warnings.warn(
                f"fairing: conjugate gradients reached a relative residual of {res:.1e} after {its} iterations"
                f"{f' (the cap: {MAX_CG_ITERATIONS})' if its >= MAX_CG_ITERATIONS else ''}; falling back to the "
                f"direct solver",
                UserWarning,
                stacklevel=2,
            )
        x = self._factor().solve(rhs)
        r = rhs - self._apply(x)
        self.iterations = 0
        self.residual = float(np.linalg.norm(r) / max(np.linalg.norm(rhs), 1e-300))
        return x

    def energy_after(self, x: np.ndarray, energy_before: float, window_deviation: np.ndarray) -> float:
        """Whole-mesh linearized energy at free positions ``x``, lengths frozen as built.

        Only the active windows (those with a free vertex) change; the others keep
        their ``window_deviation`` (the energy at the build positions).
        """
        r = self.A @ x + self.b
        return float(energy_before - window_deviation[self.active].sum() + np.einsum("ij,ij->", r, r))

    def objective(self, x: np.ndarray, anchor: np.ndarray) -> float:
        """Value of ``||A x + b||² + ω ||x − anchor||²`` for free positions ``x``."""
        r = self.A @ x + self.b
        d = x - anchor
        return float(np.einsum("ij,ij->", r, r) + self.weight * np.einsum("ij,ij->", d, d))


@dataclass(frozen=True)
class IterationReport:
    """What one fairing iteration did.

    ``energy_before``/``energy_after`` are the linearized energy (eq. 32) of the
    whole mesh with lengths frozen at the iterate's start (each window's mean
    length with ``line_spacing="fair"``); ``deviation_*`` the exact eq. 30 sums.
    ``n_curvature_held``: windows whose line term ``line_curvature="auto"`` held
    (:func:`curvature_windows`; 0: the iteration solved once).
    """

    iteration: int
    threshold: float
    weight: float
    weight_effective: float
    n_free: int
    energy_before: float
    energy_after: float
    deviation_before: float
    deviation_after: float
    max_displacement: float
    solver: str = "none"
    cg_iterations: int = 0
    residual: float = 0.0
    n_curvature_held: int = 0


@dataclass(frozen=True)
class FairingReport:
    """Per-iteration reports of :func:`fair`, the length scale used, and what the user should know.

    ``iterations_asked`` is the requested count; ``iterations`` holds one entry per
    iteration actually run (fewer when fairing stopped early because no vertex was
    free and no later threshold was lower). ``held_off_reference`` is the largest
    distance of a held vertex from the reference surface (0 without a reference).
    """

    iterations: list[IterationReport] = field(default_factory=list)
    length_scale: float = 1.0
    weight_scale: str = "normalized"
    iterations_asked: int = 0
    fix: str = "corners"
    n_fixed: int = 0
    held_off_reference: float = 0.0
    unit: str = "mm"

    @property
    def effective_iterations(self) -> int:
        """Iterations that freed at least one vertex."""
        return sum(1 for r in self.iterations if r.n_free > 0)

    def notes(self) -> list[str]:
        """Short sentences for the user: early stops, idle iterations, held vertices off the surface.

        Examples
        --------
        >>> from quadnodes.mesh import grid
        >>> _, rep = fair(grid(4, 4), iterations=3)
        >>> rep.notes()
        ['no vertex was above the threshold: nothing was faired (stopped after iteration 1 of 3)']
        """
        out: list[str] = []
        asked = self.iterations_asked or len(self.iterations)
        idle = [r.iteration + 1 for r in self.iterations if r.n_free == 0]
        if self.iterations and self.effective_iterations == 0:
            out.append(f"no vertex was above the threshold: nothing was faired (stopped after iteration "
                       f"{len(self.iterations)} of {asked})")
            return out
        if idle:
            out.append(f"iteration{'s' if len(idle) > 1 else ''} {_ranges(idle)} freed no vertex")
        if len(self.iterations) < asked:
            out.append(f"stopped after iteration {len(self.iterations)} of {asked}: no vertex above the "
                       "threshold, and no later threshold is lower")
        if self.held_off_reference > 0.1 * self.length_scale:
            out.append(f"held vertices (fix={self.fix!r} or fixed) lie up to {self.held_off_reference:.3g} "
                       f"{self.unit} ({self.held_off_reference / self.length_scale:.2g} edge lengths) off the "
                       "reference surface; they were not moved")
        return out

    def to_dict(self) -> dict:
        """Plain-Python form (JSON-ready)."""
        return {
            "length_scale": self.length_scale,
            "weight_scale": self.weight_scale,
            "iterations_asked": self.iterations_asked,
            "effective_iterations": self.effective_iterations,
            "fix": self.fix,
            "n_fixed": self.n_fixed,
            "held_off_reference": self.held_off_reference,
            "unit": self.unit,
            "notes": self.notes(),
            "iterations": [asdict(r) for r in self.iterations],
        }


def _ranges(values: list[int]) -> str:
    """``[2, 3, 4, 7]`` as ``"2–4, 7"``."""
    parts: list[str] = []
    start = prev = values[0]
    for v in values[1:] + [None]:  # type: ignore[list-item]
        if v is not None and v == prev + 1:
            prev = v
            continue
        parts.append(f"{start}" if start == prev else f"{start}–{prev}")
        if v is not None:
            start = prev = v
    return ", ".join(parts)


@_validate.renamed(deviation="threshold", deviation_decay="threshold_decay", fix_boundary="fix='boundary'")
def fair(
    mesh: QuadMesh,
    *,
    iterations: int = 1,
    threshold: float | Sequence[float] | None = None,
    threshold_decay: float = 1.0,
    weight: float | Sequence[float] = DEFAULT_WEIGHT,
    weight_decay: float = 1.0,
    weight_scale: Literal["normalized", "raw"] = "normalized",
    anchor: Literal["current", "input"] = "current",
    reference: object | None = None,
    fix: Literal["none", "corners", "boundary"] = "corners",
    fixed: ArrayLike | None = None,
    solver: Literal["auto", "direct", "cg"] = "auto",
    extraordinary: Literal["fair", "lines", "hold"] = "fair",
    detection: Literal["alternating", "thesis"] = DEFAULT_DETECTION,
    line_spacing: Literal["fair", "hold"] = DEFAULT_LINE_SPACING,
    gaps: Literal["auto", "fair", "hold"] = "auto",
    line_curvature: Literal["fair", "hold", "auto"] = DEFAULT_LINE_CURVATURE,
) -> tuple[QuadMesh, FairingReport]:
    """Fair the zigzag structure lines of a quad mesh (thesis chapter 4).

    Each iteration detects the free vertices (deviation above the iteration's
    threshold, see :func:`quadnodes.zigzag.detect`), freezes edge lengths, and
    solves one sparse least-squares problem for the free vertices.

    Parameters
    ----------
    mesh : QuadMesh
    iterations : int
        Number of iterations (1 … 100,000). Fairing stops early when no vertex is
        free and no later threshold is lower (nothing could change any more); the
        report says so.
    threshold : float or sequence of float, optional
        Zigzag threshold (eq. 30) per iteration: one number, or one value per
        iteration (the same name as in :func:`quadnodes.zigzag.detect`). Default:
        the ``detection``'s (:data:`quadnodes.zigzag.DEFAULT_THRESHOLDS`: 0.03 for
        ``"alternating"``, the thesis's 0.1 for ``"thesis"``).
    threshold_decay : float
        Factor applied to a single ``threshold`` each iteration (the thesis's
        example 3 uses ``threshold=1, threshold_decay=0.5``).
    weight : float or sequence of float
        Penalty weight ω (> 0) per iteration, like ``deviation``.
    weight_decay : float
        Factor applied to a single ``weight`` each iteration.
    weight_scale : {"normalized", "raw"}
        ``"normalized"`` (default): ``ω_eff = ω / h²`` with ``h`` the input's mean
        edge length, so ``fair(s·P) == s·fair(P)``. ``"raw"``: the thesis's ω as is
        (its effect then depends on the model's unit).
    anchor : {"current", "input"}
        Penalize the distance to the current iterate (default) or to the input.
    reference : build123d Face, QuadMesh or :class:`quadnodes.reference.Reference`, optional
        Design surface: the penalty then pulls every free vertex to the closest
        point of the current iterate on it (instead of the iterate itself), so
        faired lines slide along the surface and normal noise is removed; a
        face is sampled 4 times as finely as the mesh (``anchor`` is ignored).
    fix : {"none", "corners", "boundary"}
        Vertices held in place (:func:`quadnodes.topology.fixed_vertices`). Corners
        lie in no window's middle and never move whatever ``fix`` says.
    fixed : (n,) bool or int indices, optional
        More vertices that never move.
    solver : {"auto", "direct", "cg"}
        Linear solver, see :class:`FairingSystem`; results agree to about 1e-10.
    extraordinary : {"fair", "lines", "hold"}
        ``"hold"``: the thesis exactly — vertices where lines end inside the mesh
        (extraordinary vertices) and the middles of lines too short for a window
        are no window's middle and never move.
        ``"fair"`` (default): on a mesh with extraordinary vertices, every vertex
        that is no window's middle gets the 1-ring term of :mod:`quadnodes.line_ends`
        (the change of mean turning along each of its arms, eq. 30 carried to the
        ring) and is freed by the same ``detection`` and ``threshold``.
        ``"lines"``: the pseudo-windows of :func:`extraordinary_windows` (lines
        continued through the vertex; an extraordinary vertex is freed when a
        vertex next to it is free). See ``docs/fairing.md``. Meshes without
        extraordinary vertices give the same result with every setting.
    detection : {"alternating", "thesis"}
        How zigzag vertices are found each iteration (:func:`quadnodes.zigzag.detect`):
        ``"thesis"`` is eq. 30; ``"alternating"`` (default) leaves steady bends alone.
    line_spacing : {"fair", "hold"}
        How edge lengths are frozen in eq. 32. ``"hold"``: the thesis exactly —
        every edge keeps its own length, so a vertex slid along its line (the
        along-line part of noise) costs nothing and stays. ``"fair"`` (default):
        a window's three edges get their mean length (:func:`even_lengths`), so
        uneven spacing along a line is faired too, while evenly or linearly graded
        spacing costs nothing. Which vertices are free does not change.
    gaps : {"auto", "fair", "hold"}
        ``"hold"``: only the vertices the detection finds move (the thesis).
        ``"fair"``: a vertex between two found vertices of a line moves too
        (:func:`quadnodes.zigzag.line_gaps`), so broadband noise whose turning
        happens not to alternate at a vertex is faired with the rest; found
        regions are filled, not grown (a lone spike is faired as with ``"hold"``).
        ``"auto"`` (default): the detection's (:data:`quadnodes.zigzag.DEFAULT_GAPS`:
        ``"fair"`` with ``"alternating"``, ``"hold"`` with ``"thesis"``).
    line_curvature : {"fair", "hold", "auto"}
        ``"fair"`` (the thesis): each iteration's solve fairs every change
        of curvature along the lines, the design's own too — a clean mesh whose
        lines change curvature (rounded edges and corners) drifts where every
        vertex is free. ``"hold"``: bias correction (Tukey's twicing) — the
        iteration solves once more at the same free vertices and lengths and gives
        back the faired part of what the first solve removed:
        ``x₂ = S(2a − x₁)`` with ``x₁ = S a`` (``a`` the anchor), both at half the
        weight. The drift of a clean mesh is never larger (on every eigenmode of
        the system, ``λ(λ + ω)/(λ + ω/2)²`` of it), the high-frequency noise
        response is the same (``≈ ω/λ``), middle frequencies pass somewhat more.
        Better on curved designs under noise that frees every vertex, 1–5 % worse
        on nearly flat ones (``docs/fairing.md``); each iteration costs two solves.
        ``"auto"`` (default): the correction only where the design's lines change curvature —
        the windows whose line term is still large on the faired result ``x₁``
        (:func:`curvature_windows`) keep that term in a second solve of the same
        system at the same weight, ``min ‖A x + b − H(A x₁ + b)‖² + ω‖x − a‖²``
        (``H`` those windows; all of them would be twicing at ``ω``); where no
        window qualifies (nearly flat, evenly curved or finely sampled designs)
        the result is ``"fair"``'s, bit for bit, after one solve. The report's
        ``n_curvature_held`` counts the held windows. Only with
        ``line_spacing="fair"``: with ``"hold"`` the terms are measured with the
        frozen noisy edge lengths, so on ``x₁`` they show the lengths' noise, not
        the design's curvature, and ``"auto"`` solves once, as ``"fair"`` (so
        ``extraordinary="hold", detection="thesis", line_spacing="hold"`` is the
        thesis exactly with the default).

    Returns
    -------
    mesh : QuadMesh
        The faired mesh (the input itself when no vertex was free).
    report : FairingReport

    Raises
    ------
    InputError
        On something other than a mesh, a non-positive or NaN weight, a negative
        threshold, a schedule shorter than ``iterations``, an unknown option, or
        when the fixing leaves no vertex that could move.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> z = np.zeros((5, 7)); z[2, 3] = 0.5
    >>> out, rep = fair(grid(5, 7, height=z), iterations=3, threshold=0.01)
    >>> [r.n_free for r in rep.iterations], round(float(out.vertices[17, 2]), 3)
    ([5, 0], 0.03)
    >>> [r.n_free for r in fair(grid(5, 7, height=z), iterations=3, threshold=0.01, detection="thesis")[1].iterations]
    [7, 0]
    >>> rep.notes()
    ['iteration 2 freed no vertex', 'stopped after iteration 2 of 3: no vertex above the threshold, and no later threshold is lower']
    """
    _validate.quad_mesh(mesh)
    settings = dict(iterations=iterations, threshold=threshold, threshold_decay=threshold_decay, weight=weight,
                    weight_decay=weight_decay, weight_scale=weight_scale, anchor=anchor, reference=reference,
                    fix=fix, fixed=fixed, solver=solver, extraordinary=extraordinary, detection=detection,
                    line_spacing=line_spacing, gaps=gaps, line_curvature=line_curvature)
    if mesh.n_vertices < HEAP_MIN_VERTICES:
        return _fair(mesh, **settings)  # type: ignore[arg-type]
    with reused_heap():  # a big mesh's temporaries: reused heap blocks, not fresh pages each time
        return _fair(mesh, **settings)  # type: ignore[arg-type]


def _fair(
    mesh: QuadMesh,
    *,
    iterations: int,
    threshold: float | Sequence[float] | None,
    threshold_decay: float,
    weight: float | Sequence[float],
    weight_decay: float,
    weight_scale: Literal["normalized", "raw"],
    anchor: Literal["current", "input"],
    reference: object | None,
    fix: Literal["none", "corners", "boundary"],
    fixed: ArrayLike | None,
    solver: Literal["auto", "direct", "cg"],
    extraordinary: Literal["fair", "lines", "hold"],
    detection: Literal["alternating", "thesis"],
    line_spacing: Literal["fair", "hold"],
    gaps: Literal["auto", "fair", "hold"],
    line_curvature: Literal["fair", "hold", "auto"] = DEFAULT_LINE_CURVATURE,
) -> tuple[QuadMesh, FairingReport]:
    """:func:`fair` on a validated mesh."""
    iterations = _validate.iteration_count(iterations, "iterations")
    detection = _validate.choice(detection, DETECTIONS, "detection")  # type: ignore[assignment]
    thresholds = _validate.schedule(_threshold(threshold, detection), iterations, "threshold", decay=threshold_decay)
    weights = _validate.schedule(weight, iterations, "weight", decay=weight_decay, positive=True)
    weight_scale = _validate.choice(weight_scale, ("normalized", "raw"), "weight_scale")  # type: ignore[assignment]
    anchor = _validate.choice(anchor, ("current", "input"), "anchor")  # type: ignore[assignment]
    solver = _validate.choice(solver, ("auto", "direct", "cg"), "solver")  # type: ignore[assignment]
    extraordinary = _validate.choice(extraordinary, EXTRAORDINARY_MODES, "extraordinary")  # type: ignore[assignment]
    detection = _validate.choice(detection, DETECTIONS, "detection")  # type: ignore[assignment]
    line_spacing = _validate.choice(line_spacing, LINE_SPACING_MODES, "line_spacing")  # type: ignore[assignment]
    gaps = _validate.choice(gaps, ("auto",) + GAPS_MODES, "gaps")  # type: ignore[assignment]
    line_curvature = _validate.choice(line_curvature, LINE_CURVATURE_MODES, "line_curvature")  # type: ignore[assignment]
    if gaps == "auto":
        gaps = DEFAULT_GAPS[detection]  # type: ignore[assignment]
    topo = mesh.topology
    if mesh.n_vertices >= COMPILED_MIN_UNKNOWNS:
        kernels.warm_up()  # the solve will want the compiled kernels (any mesh): load them while we set up
    held = fixed_vertices(mesh, fix, fixed)
    xw = extraordinary_windows(mesh.vertices, topo) if extraordinary == "lines" else np.empty((0, 4), np.int64)
    if xw.size:
        # an extraordinary vertex may move when a vertex of its ring is free: arms' first vertices
        xv = xw[:, 1:3].reshape(-1)
        mids = xw[:, 1:3][:, ::-1].reshape(-1)
        ext_mask = topo.extraordinary[xv]
        xv, xn = xv[ext_mask], mids[ext_mask]
    # line ends and short lines: the vertices that are no window's middle get the 1-ring term of
    # quadnodes.line_ends along their arms (only where extraordinary vertices are, like the pseudo-windows)
    ends = _line_end_pairs(topo) if extraordinary == "fair" and topo.extraordinary.any() else np.empty((0, 2), np.int64)
    movable = topo.window_middle & ~held
    if topo.window_middle.any() and not movable.any():
        raise InputError(
            f"fix={fix!r}, fixed: every vertex that lies inside a structure line is held; nothing can be faired"
        )
    ref = None
    h = mesh.mean_edge_length
    off_reference = 0.0
    if reference is not None:
        from .reference import as_reference

        ref = as_reference(reference, mesh)
        still = held | ~topo.window_middle  # vertices fairing never moves
        if ends.size:
            still[ends.reshape(-1)] = held[ends.reshape(-1)]
        if still.any():
            _, dist = ref.closest(mesh.vertices[still])
            off_reference = float(np.max(dist))
    # no vertex free and no lower threshold to come: nothing can change any more
    later_min = np.minimum.accumulate(thresholds[::-1])[::-1]
    scale = 1.0 / h**2 if weight_scale == "normalized" else 1.0
    w = topo.windows
    walk = topo.window_walk
    x0 = mesh.vertices
    x = x0
    reports: list[IterationReport] = []
    geometry = None  # windows' deviation and inverse edge lengths at x, shared by every use
    for it in range(iterations):
        current = mesh if x is x0 else mesh.with_vertices(x)
        if geometry is None:
            geometry = _window_geometry(x, w, walk, alternation=detection == "alternating",
                                        even=line_spacing == "fair" and walk is not None)
        alt = geometry[2] if detection == "alternating" else None
        zz = _detect(current, float(thresholds[it]), held, geometry[0], fix, alt)
        dev_before = float(zz.window_deviation.sum())
        if line_spacing == "hold":
            inverse = geometry[1]
            w_energy = zz.window_deviation  # lengths frozen at x: each window's term is its eq. 30 deviation
        elif walk is not None:  # the window walk's pass measured them (as even_lengths, _window_energy)
            inverse, w_energy = geometry[-2], geometry[-1]
        else:
            inverse = even_lengths(geometry[1])
            w_energy = _window_energy(x, w, inverse, walk)
        e_before = float(w_energy.sum())
        free = zz.free if gaps == "hold" else line_gaps(zz.free, w, zz.fixed)
        if xw.size:
            # the ring of an extraordinary vertex: the middle vertices of its pseudo-windows
            ring_free = np.zeros(x.shape[0], dtype=bool)
            ring_free[xv[free[xn]]] = True
            free = free | (ring_free & ~held)
            x_geom = _window_geometry(x, xw)
            e_before += EXTRAORDINARY_SCALE**2 * float(x_geom[0].sum())  # the rows are scaled by s
        if ends.size:
            free = line_end_free(x, topo, ends, free, held, float(thresholds[it]), detection=detection,
                                 line_spacing=line_spacing)
            end_rows = line_end_rows(x, topo, ends, line_spacing=line_spacing)
            f_end = end_rows @ x
            end_energy = np.einsum("ij,ij->i", f_end, f_end)
            e_before += float(end_energy.sum())
        if not free.any():
            reports.append(
                IterationReport(it, float(thresholds[it]), float(weights[it]), float(weights[it] * scale),
                                0, e_before, e_before, dev_before, dev_before, 0.0)
            )
            report_progress((it + 1) / iterations, f"iteration {it + 1}/{iterations}: no zigzag above {thresholds[it]:g}")
            if it + 1 < iterations and later_min[it + 1] >= thresholds[it]:
                break
            continue
        w_eff = float(weights[it] * scale)
        if line_curvature == "hold":
            w_eff *= 0.5  # two solves: the same high-frequency noise response as one at ω
        if xw.size or ends.size:
            xs = [w, xw] if xw.size else [w]
            inv_all = [inverse, EXTRAORDINARY_SCALE * x_geom[1]] if xw.size else [inverse]
            dev_all = [w_energy, EXTRAORDINARY_SCALE**2 * x_geom[0]] if xw.size else [w_energy]
            system = FairingSystem(x, np.concatenate(xs), free, w_eff, solver=solver,
                                   _inverse_lengths=np.concatenate(inv_all), _lines=topo.structure_lines,
                                   _extra_rows=end_rows if ends.size else None)
            all_dev = np.concatenate(dev_all + ([end_energy] if ends.size else []))
        else:
            system = FairingSystem(x, w, free, w_eff, solver=solver, _inverse_lengths=inverse,
                                   _topology=topo, _lines=topo.structure_lines)
            all_dev = w_energy
        if ref is not None:
            target, _ = ref.closest(x[system.free_index])
        else:
            target = np.take(x if anchor == "current" else x0, system.free_index, axis=0)
        new_free = system.solve(target)
        n_held = 0
        if line_curvature == "auto" and line_spacing == "fair":
            # the design's curvature changes: their line terms at x₁ are held by a second solve of the same
            # system, min ‖A x + b − H(A x₁ + b)‖² + ω‖x − a‖² (H: the held rows), i.e. the anchor a + AᵀH(A x₁ + b)/ω
            f1 = system.A @ new_free + system.b
            inner = np.zeros(system.A.shape[0], dtype=bool)
            # a window's four flags as one 32-bit word: all free when every byte is 1
            inner[:len(system._windows)] = (np.ascontiguousarray(free[system._windows]).view(np.uint32).reshape(-1)
                                            == np.frombuffer(b"\x01" * 4, np.uint32)[0])
            if ref is None and anchor == "current" and not (xw.size or ends.size):
                # the input's window terms are the detection pass's energies (A a + b with a = x)
                e0 = w_energy if system.active.all() else w_energy[system.active]
                rows = curvature_windows(f1, None, system._windows, inner, noisy_norms=np.sqrt(e0))
            else:
                rows = curvature_windows(f1, system.A @ target + system.b, system._windows, inner)
            n_held = int(np.count_nonzero(rows))
            if n_held:
                first = system.iterations
                f1[~rows] = 0.0
                new_free = system.solve(target + (system.A.T @ f1) * (1.0 / system.weight), start=new_free)
                system.iterations += first  # the report counts the CG steps of both solves
        if line_curvature == "hold":
            # twicing: x₁ + S(a − x₁) = S(2a − x₁) (the fixed vertices' part enters once), the same system
            first = system.iterations
            new_free = system.solve(2.0 * target - new_free, start=new_free)
            system.iterations += first  # the report counts the CG steps of both solves
        x_new = x.copy()
        x_new[system.free_index] = new_free
        moved = new_free - np.take(x, system.free_index, axis=0)
        disp = np.sqrt(np.einsum("ij,ij->i", moved, moved))
        last = it + 1 == iterations  # then only the deviation is wanted, for the report
        geometry = _window_geometry(x_new, w, walk, alternation=detection == "alternating" and not last,
                                    even=line_spacing == "fair" and walk is not None and not last)
        reports.append(
            IterationReport(
                iteration=it,
                threshold=float(thresholds[it]),
                weight=float(weights[it]),
                weight_effective=w_eff,
                n_free=system.n_free,
                energy_before=e_before,
                energy_after=system.energy_after(new_free, e_before, all_dev),
                deviation_before=dev_before,
                deviation_after=float(geometry[0].sum()),
                max_displacement=float(disp.max()),
                solver=system.solver,
                cg_iterations=system.iterations,
                residual=system.residual,
                n_curvature_held=n_held,
            )
        )
        x = x_new
        report_progress((it + 1) / iterations, f"iteration {it + 1}/{iterations}: {system.n_free} free vertices")
    out = mesh if x is x0 else mesh.with_vertices(x)
    return out, FairingReport(reports, length_scale=h, weight_scale=weight_scale, iterations_asked=iterations,
                              fix=fix, n_fixed=int(held.sum()), held_off_reference=off_reference, unit=mesh.unit)

"""Real meshes: recover each mesh of ``tests/data`` from seeded noise with fair and the smoothing peers.

Backs docs/real-meshes.md "Recovering from noise" (and the defaults it justifies in docs/fairing.md).

For every mesh (``tests/data/README.md``) and three noise kinds —

- ``zigzag``: ``perturb(tangential=0.25)`` (vertices slide along the lines, the thesis's zigzag),
- ``normal``: ``perturb(normal=0.2)`` (normal-only),
- ``jitter``: ``perturb(jitter=0.2)`` (isotropic),

amplitudes in local edge lengths, corners held (``fix="corners"``), seeds 0..``--seeds``-1 — the error
is the mean distance of every vertex from its clean position, in mean edge lengths ``h`` (the noise
moves vertices, not the correspondence), averaged over the seeds. Methods, each **tuned**: the
best of its settings on that mesh and noise is shown (the setting beside it):

- ``fair``: ``quadnodes.fair`` with its defaults (``detection="alternating"``, ``gaps="fair"``,
  ``extraordinary="fair"``, ``line_spacing="fair"``), iterations 1, 3, 5;
- ``fair (curvature fair)``: fair with its defaults and ``line_curvature="fair"`` (the thesis's single solve, the
  default before ``"auto"``), iterations 1, 3, 5;
- ``fair (curvature hold)``: fair with its defaults and ``line_curvature="hold"`` (bias correction by twicing),
  iterations 1, 3, 5;
- ``fair (before)``: fair's defaults before issue 16 item 6: ``line_spacing="hold", threshold=0.1,
  extraordinary="lines", gaps="hold", line_curvature="fair"``, iterations 1, 3, 5;
- ``fair (thesis)``: ``extraordinary="hold", detection="thesis", line_spacing="hold", line_curvature="fair"`` — the
  thesis's method,
  iterations 1, 3, 5;
- ``laplacian``: ``quadnodes.laplacian`` (λ = 0.5, corners held), iterations 1, 2, 4, 8;
- ``taubin``: ``quadnodes.taubin`` (corners held), iterations 1, 2, 5, 10, 20;
- ``trimesh taubin``: ``trimesh.smoothing.filter_taubin`` on the triangulated mesh, iterations
  2, 5, 10, 20, 50 (single steps), corners put back afterwards.

The last columns say whether fair (its defaults; then with ``line_curvature="fair"``; with ``"hold"``) is the best
(``zigzag`` on an open mesh) or within 20 % of the best peer.

``--studies`` prints instead the measurements behind the defaults (``docs/fairing.md``): detection on the
clean meshes and on E1–E4 (``quadnodes.report``'s noise and parameters, seed 7), and the pseudo-window
scale ``EXTRAORDINARY_SCALE`` on ``tests/meshes.extraordinary_mesh(3)``, and the line-end term
(``extraordinary="hold"|"lines"|"fair"``, its scale ``quadnodes.line_ends.RING_SCALE``) on ``polygon_quads``,
``rounded_box`` and ``extraordinary_mesh(3)``. ``--gaps`` prints E1–E4 with ``gaps="hold"`` against
``"fair"`` as ``--spacing`` does for ``line_spacing``. ``--curvature`` prints E1–E4 with ``line_curvature="fair"`` (the thesis) against ``"hold"`` and ``"auto"`` (the
default); ``--paired`` the real meshes with ``"auto"`` against ``"fair"`` seed by seed (6 seeds).
``--spacing`` prints the study behind
``line_spacing="fair"``: E1–E4 as in ``quadnodes compare`` (seeds 7 and 1–5, noise on the corners-held and on the
interior-only variant), the thesis's parameters and the default weight, ``line_spacing="hold"`` against ``"fair"``.

The studies (``--studies``, ``--spacing``, ``--gaps``) run fair with ``line_curvature="fair"``, the single solve
they were measured with before ``"auto"`` became the default.

Run:  python benchmarks/studies/bench_real_meshes.py [--seeds 3] [--markdown] [--meshes NAME ...]
      [--noises zigzag normal jitter] [--studies | --spacing | --gaps | --curvature | --paired]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from quadnodes.fairing import fair
from quadnodes.io import load
from quadnodes.noise import perturb
from quadnodes.smoothing import laplacian, taubin
from quadnodes.topology import fixed_vertices

DATA = Path(__file__).resolve().parents[2] / "tests" / "data"
MESHES = ["compas/quadmesh.obj", "compas/tubemesh.obj", "compas/hypar.obj", "quadmesh_hole.obj",
          "staircase_saddle.obj", "polygon_quads.obj", "rounded_box.obj"]
NOISE = {"zigzag": {"tangential": 0.25}, "normal": {"normal": 0.2}, "jitter": {"jitter": 0.2}}


def _fair_single(mesh, **settings):
    """fair as the studies behind its other defaults measured it (``--studies``, ``--spacing``, ``--gaps``): one
    solve per iteration, ``line_curvature="fair"``, unless the study sets ``line_curvature`` itself."""
    settings.setdefault("line_curvature", "fair")
    return fair(mesh, **settings)


def _trimesh_taubin(mesh, iterations):
    import trimesh
    from trimesh.smoothing import filter_taubin

    f = mesh.faces
    tri = np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]])
    t = trimesh.Trimesh(mesh.vertices.copy(), tri, process=False)
    filter_taubin(t, iterations=iterations)
    v = np.asarray(t.vertices).copy()
    held = fixed_vertices(mesh, "corners")
    v[held] = mesh.vertices[held]
    return mesh.with_vertices(v)


METHODS = {
    "fair": [(f"{k} it", lambda m, k=k: fair(m, iterations=k)[0]) for k in (1, 3, 5)],
    "fair (curvature fair)": [(f"{k} it", lambda m, k=k: fair(m, iterations=k, line_curvature="fair")[0])
                              for k in (1, 3, 5)],
    "fair (curvature hold)": [(f"{k} it", lambda m, k=k: fair(m, iterations=k, line_curvature="hold")[0])
                              for k in (1, 3, 5)],
    "fair (before)": [(f"{k} it", lambda m, k=k: fair(m, iterations=k, line_spacing="hold", threshold=0.1,
                                                       extraordinary="lines", gaps="hold", line_curvature="fair")[0])
                      for k in (1, 3, 5)],
    "fair (thesis)": [(f"{k} it", lambda m, k=k: fair(m, iterations=k, extraordinary="hold", detection="thesis",
                                                       line_spacing="hold", threshold=0.1, line_curvature="fair")[0])
                      for k in (1, 3, 5)],
    "laplacian": [(f"{k} it", lambda m, k=k: laplacian(m, iterations=k, fix="corners")[0]) for k in (1, 2, 4, 8)],
    "taubin": [(f"{k} it", lambda m, k=k: taubin(m, iterations=k, fix="corners")[0]) for k in (1, 2, 5, 10, 20)],
    "trimesh taubin": [(f"{k} it", lambda m, k=k: _trimesh_taubin(m, k)) for k in (2, 5, 10, 20, 50)],
}


def studies() -> None:
    import sys

    import quadnodes.fairing as F
    from quadnodes.report import THESIS_EXAMPLES, _geometry
    from quadnodes.zigzag import _walk_alternation, detect

    print("clean meshes: vertices freed by detect() at the detection's default threshold (thesis 0.1, alternating "
          "0.03) / largest move of fair(iterations=3) in h / largest alternating turning")
    for name in MESHES:
        m = load(DATA / name)
        h = m.mean_edge_length
        cells = []
        for det in ("thesis", "alternating"):
            out, _ = _fair_single(m, iterations=3, detection=det, gaps="hold")
            cells.append(f"{det} {detect(m, detection=det).n_free} / "
                         f"{np.linalg.norm(out.vertices - m.vertices, axis=1).max() / h:.3f}")
        alt = float(_walk_alternation(m.vertices, m.topology.window_walk).max())
        print(f"  {name:22s} " + " | ".join(cells) + f" | {alt:.2g}")
    print("E1-E4 (seed 7): clean vertices freed, and mean vertex error / h after fair on the noisy model")
    for name in ("E1", "E2", "E3", "E4"):
        ex = THESIS_EXAMPLES[name]
        clean, _ = _geometry(name)
        h = clean.mean_edge_length
        noisy, _ = perturb(clean, tangential=ex.noise[0], normal=ex.noise[1], seed=7, fix="corners")
        cells = []
        for det in ("thesis", "alternating"):
            out, _ = _fair_single(noisy, **ex.fair, detection=det, gaps="hold")
            _, crep = _fair_single(clean, **ex.fair, detection=det, gaps="hold")
            cells.append(f"{det} {sum(r.n_free for r in crep.iterations)} / "
                         f"{np.linalg.norm(out.vertices - clean.vertices, axis=1).mean() / h:.3f}")
        print(f"  {name} " + " | ".join(cells))
    sys.path.insert(0, str(DATA.parent))
    from meshes import extraordinary_mesh

    m = extraordinary_mesh(3)
    e = m.topology.extraordinary
    h = m.mean_edge_length
    print("pseudo-window scale s on extraordinary_mesh(3), 4 seeds, boundary held: mean error / largest at "
          "extraordinary vertices, in h")
    for s in (None, 1.0, 0.5, 0.25, 0.1):
        cells = []
        for kind, amp in (("tangential", 0.25), ("normal", 0.2), ("jitter", 0.2)):
            res = []
            for seed in range(4):
                noisy, _ = perturb(m, seed=seed, fix="boundary", **{kind: amp})
                old = F.EXTRAORDINARY_SCALE
                F.EXTRAORDINARY_SCALE = 1.0 if s is None else s
                try:
                    out, _ = _fair_single(noisy, iterations=5, extraordinary="hold" if s is None else "lines",
                                  gaps="hold")
                finally:
                    F.EXTRAORDINARY_SCALE = old
                err = np.linalg.norm(out.vertices - m.vertices, axis=1) / h
                res.append((err.mean(), err[e].max()))
            r = np.mean(res, axis=0)
            cells.append(f"{kind} {r[0]:.4f} / {r[1]:.3f}")
        print(f"  {'hold' if s is None else s!s:5s} " + " | ".join(cells))


def line_end_study() -> None:
    """``extraordinary="hold"|"lines"|"fair"`` and the line-end scale ``RING_SCALE`` (``--studies``)."""
    import sys

    import quadnodes.line_ends as LE

    sys.path.insert(0, str(DATA.parent))
    from meshes import extraordinary_mesh

    cases = {"polygon_quads.obj": (load(DATA / "polygon_quads.obj"), "corners"),
             "rounded_box.obj": (load(DATA / "rounded_box.obj"), "corners"),
             "extraordinary_mesh(3)": (extraordinary_mesh(3), "boundary")}
    print("extraordinary= and the line-end scale s: mean vertex error / h after fair (1 iteration, seeds 0 and 1) "
          "for zigzag / normal / jitter noise; vertices that are no window's middle")
    for name, (m, fix) in cases.items():
        t = m.topology
        print(f"  {name}: {m.n_vertices} vertices, {int(t.extraordinary.sum())} extraordinary, "
              f"{int(t.window_middle.sum())} a window's middle, lines of 3 vertices: "
              f"{int((t.structure_lines.lengths == 3).sum())} of {len(t.structure_lines.lengths)}")
    old = LE.RING_SCALE
    for mode, s in (("hold", None), ("lines", None), ("fair", 0.25), ("fair", 0.5), ("fair", 1.0)):
        cells = []
        for name, (m, fix) in cases.items():
            h = m.mean_edge_length
            res = []
            for kind, amp in NOISE.items():
                errs = []
                for seed in (0, 1):
                    noisy, _ = perturb(m, seed=seed, fix=fix, **amp)
                    LE.RING_SCALE = old if s is None else s
                    try:
                        out, _ = _fair_single(noisy, fix=fix, extraordinary=mode)
                    finally:
                        LE.RING_SCALE = old
                    errs.append(np.linalg.norm(out.vertices - m.vertices, axis=1).mean() / h)
                res.append(f"{np.mean(errs):.3f}")
            cells.append(f"{name} {'/'.join(res)}")
        print(f"  {mode:5s} {'' if s is None else s!s:4s} " + " | ".join(cells), flush=True)


def spacing_study(setting: str = "line_spacing", modes: tuple[str, ...] = ("hold", "fair")) -> None:
    """E1–E4 with ``setting`` at ``modes[0]`` (the thesis) and ``modes[1]``: the numbers of ``quadnodes compare``
    (``line_spacing``: ``--spacing``; ``gaps``: ``--gaps``; ``line_curvature``, thesis ``"fair"`` -> ``"hold"``:
    ``--curvature``)."""
    from quadnodes.report import THESIS_EXAMPLES, _boundary_frame, _noisy_example, measure

    keys = [("vertex_distance_mean_h", "to clean vertex"), ("surface_distance_mean_h", "to clean surface"),
            ("zigzag_max", "zigzag max"), ("boundary_displacement_max_h", "boundary moved max"),
            ("relief_change_pct", "relief %")]
    print(f"E1-E4, mean over seeds 7, 1-5 (worst seed in brackets); {setting}: {modes[0]} -> {' / '.join(modes[1:])}")
    for name in ("E1", "E2", "E3", "E4"):
        ex = THESIS_EXAMPLES[name]
        for fix in ("corners", "boundary"):
            for label, params in (("thesis weights", dict(ex.fair)), ("default weight", {**ex.fair, "weight": 0.3})):
                vals: dict[str, list] = {m: [] for m in modes}
                for seed in (7, 1, 2, 3, 4, 5):
                    _, clean, fine, noisy, _, _ = _noisy_example(name, seed, fix)
                    frame = _boundary_frame(clean)
                    for mode in vals:
                        # (the line_spacing study as documented: found vertices only)
                        pin = {"gaps": "hold"} if setting == "line_spacing" else {}
                        out, _ = _fair_single(noisy, **params, **{setting: mode}, **pin)
                        row = measure(noisy, out, clean, fine, boundary_frame=frame)
                        vals[mode].append([row[k] for k, _ in keys])
                h = np.array(vals[modes[0]])
                fs = [np.array(vals[m]) for m in modes[1:]]
                worse = [(f - h).max(axis=0) for f in fs]  # the worst seed's change (larger = worse; relief: signed)
                cells = [f"{lab} {h[:, j].mean():.3g} -> " + " / ".join(f"{f[:, j].mean():.3g}" for f in fs)
                         + " (" + " / ".join(f"{wf[j]:+.2g}" for wf in worse) + ")"
                         for j, (_, lab) in enumerate(keys)]
                print(f"  {name} noise on {fix:8s} {label:15s} " + " | ".join(cells), flush=True)


def curvature_pairs(meshes: list[str], noises: list[str], seeds: int = 6) -> None:
    """``--paired``: fair's default ``line_curvature="auto"`` against ``"fair"`` on the same noisy meshes, seed by
    seed (seeds 0..``seeds``-1, 1 and 3 iterations): the mean change, its standard deviation over the seeds (the
    seed-to-seed noise of the difference) and on how many seeds auto was worse; the windows held."""
    print(f"auto - fair, mean vertex error / h over seeds 0-{seeds - 1}; sd: over the seeds")
    for name in meshes:
        clean = load(DATA / name)
        h = clean.mean_edge_length
        for kind in noises:
            noisy = [perturb(clean, seed=s, fix="corners", **NOISE[kind])[0] for s in range(seeds)]
            for its in (1, 3):
                errs, held = [], []
                for m in noisy:
                    e = []
                    for mode in ("fair", "auto"):
                        out, rep = fair(m, iterations=its, line_curvature=mode)
                        e.append(np.linalg.norm(out.vertices - clean.vertices, axis=1).mean() / h)
                    errs.append(e)
                    held.append(sum(r.n_curvature_held for r in rep.iterations))
                e = np.array(errs)
                d = e[:, 1] - e[:, 0]
                print(f"  {name:22s} {kind:7s} {its} it: fair {e[:, 0].mean():.4f} (sd {e[:, 0].std(ddof=1):.4f}) "
                      f"auto {e[:, 1].mean():.4f}: {d.mean():+.5f} ({100 * d.mean() / e[:, 0].mean():+.1f} %, "
                      f"sd {d.std(ddof=1):.5f}, worse on {int((d > 0).sum())}/{seeds}), windows held "
                      f"{min(held)}-{max(held)}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--markdown", action="store_true", help="print a Markdown table")
    ap.add_argument("--studies", action="store_true", help="the measurements behind the defaults instead")
    ap.add_argument("--spacing", action="store_true", help="the study behind line_spacing='fair' instead")
    ap.add_argument("--gaps", action="store_true", help="the E1-E4 study behind gaps='fair' instead")
    ap.add_argument("--curvature", action="store_true",
                    help="the E1-E4 study of line_curvature 'fair' / 'hold' / 'auto' instead")
    ap.add_argument("--paired", action="store_true",
                    help="line_curvature 'auto' against 'fair', seed by seed (6 seeds), instead")
    ap.add_argument("--meshes", nargs="+", default=MESHES, choices=MESHES, metavar="NAME",
                    help="only these meshes of tests/data (default: all)")
    ap.add_argument("--noises", nargs="+", default=list(NOISE), choices=list(NOISE), help="only these noises")
    args = ap.parse_args()
    if args.studies:
        studies()
        line_end_study()
        return
    if args.paired:
        curvature_pairs(args.meshes, args.noises)
        return
    if args.curvature:
        spacing_study("line_curvature", ("fair", "hold", "auto"))
        return
    if args.spacing or args.gaps:
        spacing_study("gaps" if args.gaps else "line_spacing")
        return
    head = ["mesh", "noise", "noisy"] + list(METHODS) + ["fair vs best peer", "curvature fair vs best peer",
                                                        "curvature hold vs best peer"]
    rows = []
    for name in args.meshes:
        clean = load(DATA / name)
        h = clean.mean_edge_length
        closed = not clean.topology.boundary_vertices.any()
        for kind in args.noises:
            amp = NOISE[kind]
            noisy_list = [perturb(clean, seed=s, fix="corners", **amp)[0] for s in range(args.seeds)]

            def err(meshes):
                return float(np.mean([np.linalg.norm(m.vertices - clean.vertices, axis=1).mean() / h for m in meshes]))

            best = {}
            for method, settings in METHODS.items():
                scores = [(err([fn(m) for m in noisy_list]), label) for label, fn in settings]
                best[method] = min(scores)
            peers = min(v[0] for k, v in best.items() if not k.startswith("fair"))
            verdicts = []
            for variant in ("fair", "fair (curvature fair)", "fair (curvature hold)"):
                f = best[variant][0]
                if kind == "zigzag" and not closed:
                    verdicts.append("best" if f <= peers else f"NOT best (+{100 * (f / peers - 1):.0f} %)")
                else:
                    verdicts.append(f"{100 * (f / peers - 1):+.0f} %" + ("" if f <= 1.2 * peers else " (beyond 20 %)"))
            rows.append([name, kind, f"{err(noisy_list):.3f}"]
                        + [f"{best[k][0]:.3f} ({best[k][1]})" for k in METHODS] + verdicts)
    print(f"mean vertex error / h, mean of {args.seeds} seeds; best setting of each method in brackets")
    if args.markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for r in rows:
            print("| " + " | ".join(r) + " |")
    else:
        w = [max(len(str(x)) for x in col) for col in zip(head, *rows)]
        for r in [head] + rows:
            print("  ".join(str(x).ljust(k) for x, k in zip(r, w)))


if __name__ == "__main__":
    main()

"""Write the graph files of the thesis's four examples (examples/e1_saddle.toml ... e4_dome.toml).

Each graph: the clean example surface -> seeded zigzag noise -> Laplacian, Taubin and
the new method with the thesis's parameters -> metrics of each (against the noisy
input, with the clean mesh as reference) -> STEP/OBJ/CSV of the faired panels and a
four-panel PNG. The thesis's weights are used as normalized weights (the thesis's
meshes are taken to have unit edge length; see docs/fairing.md).

Run:  python examples/make_thesis_graphs.py   (rewrites the four files)
"""

from __future__ import annotations

from pathlib import Path

import quadnodes.nodes  # noqa: F401  (registers the built-in nodes)
from quadnodes.graph import Graph, dumps
from quadnodes.io._atomic import write_text_atomic

HERE = Path(__file__).parent

ADVICE = ("with the thesis's weight ω = {fair.weight} the freed vertices, boundary included, drift off the "
          "design; run with --set fair.weight=0.3 (the default weight) or --set fair.fix=boundary")

# What each file's header says about the result, measured with
#   quadnodes run examples/<file>.toml            (metrics.json: fair / laplace, boundary_displacement_max,
#   quadnodes run examples/<file>.toml --set fair.weight=0.3      reference_mean = mean distance to the clean surface)
MEASURED = {
    "E1": ("583 mm", "26 mm", "467 mm", "12 mm", "161 mm", "9.6 mm"),
    "E2": ("370 mm", "127 mm", "250 mm", "12 mm", "170 mm", "18 mm"),
    "E3": ("322 mm", "25 mm", "184 mm", "6.8 mm", "83 mm", "4.3 mm"),
    "E4": ("752 mm", "89 mm", "306 mm", "11 mm", "136 mm", "2.2 mm"),
}


def header(name: str, stem: str) -> str:
    """The comment block at the top of an example file: what it shows, and why the new method looks bad."""
    b, d, lb, ld, fb, fd = MEASURED[name]
    return f"""# Thesis example {name}: Laplacian, Taubin and the new method with the thesis's parameters.
#   quadnodes run examples/{stem}.toml          (outputs in out/{stem}/)
#
# Why the new method looks bad here: the thesis's weights (ω = 0.001 and alike) are tiny, so the
# vertices it frees, boundary included, are barely held: the boundary moves up to {b} and the
# surface ends {d} off the design on average (Laplacian: {lb}, {ld}). The run summary says so
# (node 'advice'). The setting to change is the weight:
#   quadnodes run examples/{stem}.toml --set fair.weight=0.3     (the default weight: {fb}, {fd})
# or --set fair.fix=boundary to hold the boundary. Numbers from metrics.json of those two commands.
"""

# name, file, laplace steps, taubin iterations, fair settings, noise
EXAMPLES = [
    ("E1", "e1_saddle", 3, 40, dict(iterations=3, threshold=0.1, weight=0.001), (0.25, 0.1)),
    ("E2", "e2_s_shape", 1, 20, dict(iterations=3, threshold=0.1, weight=0.005), (0.25, 0.1)),
    ("E3", "e3_wavy", 4, 50, dict(iterations=10, threshold=1.0, threshold_decay=0.5, weight=0.001), (0.25, 0.1)),
    ("E4", "e4_dome", 4, 30, dict(iterations=5, threshold=1.0, weight=0.0005), (0.6, 0.2)),
]


def thesis_graph(name: str, laplace: int, taubin: int, fair: dict, noise: tuple[float, float]) -> Graph:
    """The comparison pipeline of one thesis example."""
    g = Graph()
    clean = g.add("thesis_example", id="clean", name=name)
    noisy = g.add("perturb", clean.mesh, id="noisy", tangential=noise[0], normal=noise[1], seed=7, fix="corners")
    lap = g.add("laplacian", noisy.mesh, id="laplace", iterations=laplace)
    tau = g.add("taubin", noisy.mesh, id="taubin", iterations=taubin)
    new = g.add("fair", noisy.mesh, id="fair", **fair)
    reports = [g.add("compare", noisy.mesh, m.mesh, clean.mesh, id=f"metrics_{k}")
               for k, m in (("laplace", lap), ("taubin", tau), ("fair", new))]
    g.add("export_report", *(r.metrics for r in reports), new.report, id="report", path="metrics.json",
          names=["laplace", "taubin", "fair", "fair_log"])
    g.add("export_step", new.mesh, id="step", path="faired.step")
    g.add("export_obj", new.mesh, id="obj", path="faired.obj")
    g.add("export_csv", new.mesh, id="csv", path="faired_panels.csv")
    g.add("render_png", noisy.mesh, lap.mesh, tau.mesh, new.mesh, id="png", path="comparison.png",
          titles=["original (noisy)", "Laplacian, {laplace.iterations} steps", "Taubin, {taubin.iterations} iterations",
                  "new method, {fair.iterations} iterations"])  # filled in from the settings when the graph runs
    g.add("advise", reports[2].metrics, reports[0].metrics, id="advice", key="boundary_displacement_max",
          message=ADVICE)
    return g


def main() -> None:
    for name, stem, laplace, taubin, fair, noise in EXAMPLES:
        g = thesis_graph(name, laplace, taubin, fair, noise)
        path = write_text_atomic(HERE / f"{stem}.toml", header(name, stem) + dumps(g, base_dir=HERE))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()

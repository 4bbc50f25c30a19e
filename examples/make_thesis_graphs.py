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
from quadnodes.graph import Graph

HERE = Path(__file__).parent

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
          titles=["original (noisy)", f"Laplacian, {laplace} steps", f"Taubin, {taubin} iterations",
                  f"new method, {fair['iterations']} iterations"])
    return g


def main() -> None:
    for name, stem, laplace, taubin, fair, noise in EXAMPLES:
        path = thesis_graph(name, laplace, taubin, fair, noise).save(HERE / f"{stem}.toml")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()

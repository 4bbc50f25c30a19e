"""The example graphs' CAD outputs at the sizes that used to abort the STEP export (issue 13).

Only the nodes the STEP and CSV outputs need are run; benchmarks/perf/bench_cad.py runs 40, 45, 60 and 120 per
side.
"""

import csv
import tomllib
from pathlib import Path

import pytest

from quadnodes.graph.files import from_dict

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
KEEP = {"surface", "clean", "noisy", "fair", "flat", "step", "csv"}


def cad_outputs(name: str, n: int, out: Path):
    """Run ``examples/<name>`` at ``n × n`` keeping the STEP and CSV nodes: (STEP text, CSV rows, step report)."""
    import quadnodes.nodes  # noqa: F401  (registers the node types)

    data = tomllib.loads((EXAMPLES / name).read_text())
    data["nodes"] = {k: v for k, v in data["nodes"].items() if k in KEEP}
    data["nodes"]["clean"]["params"].update(nu=n, nv=n)
    graph = from_dict(data, base_dir=out)
    result = graph.run()
    report = result[graph["step"].report]
    rows = list(csv.DictReader((out / data["nodes"]["csv"]["params"]["path"]).open()))
    return (out / data["nodes"]["step"]["params"]["path"]).read_text(), rows, report


@pytest.mark.parametrize(("name", "n"), [("quickstart.toml", 45), ("planar_panels.toml", 60)])
def test_examples_write_step_at_sizes_that_used_to_fail(tmp_path, name, n):
    text, rows, report = cad_outputs(name, n, tmp_path)
    panels = (n - 1) ** 2
    assert len(rows) == panels and report.n_panels == panels and report.fallback == ()
    assert text.count("ADVANCED_FACE(") == panels
    # the schedule and the STEP file agree on the planar panels
    assert sum(r["kind"] == "planar" for r in rows) == report.n_planar
    assert text.count("ADVANCED_FACE('P_") == panels  # every face named
    interior = 2 * (n - 1) * (n - 2)
    assert report.n_shared_edges == interior and report.n_free_edges == 4 * (n - 1)
    assert max(float(r["corner_move_mm"]) for r in rows) == pytest.approx(report.max_corner_move, abs=5e-4)

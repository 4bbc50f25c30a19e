"""The thesis comparison report: files, columns, parameters, measures, errors and the CLI."""

import csv
import importlib.util
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

import quadnodes as qn
from quadnodes import report
from quadnodes.cli import main
from quadnodes.errors import InputError
from quadnodes.mesh import grid

ROOT = Path(__file__).resolve().parents[1]


PROGRESS: list[tuple[float, str]] = []


@pytest.fixture(scope="module")
def e1(tmp_path_factory):
    from quadnodes.progress import reporting

    out = tmp_path_factory.mktemp("compare")
    with reporting(lambda f, m: PROGRESS.append((f, m))):
        return report.thesis_comparison(out, examples=["e1"], spread_seeds=(1,), size_px=500,
                                        variants_figure=True)


def test_progress_for_every_step_of_every_example(e1):
    messages = [m for _, m in PROGRESS]
    for step in ("E1 (1/1): seed 7", "E1 (1/1): figure", "E1 (1/1): variants figure",
                 "E1 (1/1): seed 1 (1 of 1 for the spread)", "E1 (1/1): interior noise"):
        assert step in messages, step
    assert any(m.startswith("E1 (1/1): figure: drawing mesh") for m in messages)   # the PNG's own progress
    fractions = [f for f, _ in PROGRESS]
    assert fractions == sorted(fractions) and 0 <= fractions[0] and fractions[-1] <= 1


def test_writes_figures_and_tables_with_all_columns(e1):
    fig = e1.figures["E1"]
    assert fig.name == "E1.png" and e1.variant_figures["E1"].name == "E1_variants.png"
    for p in (fig, e1.variant_figures["E1"]):
        px = imread(p)[..., :3]
        assert px.shape[1] == 500 and px.std() > 0.05
    md = e1.markdown.read_text()
    assert "## E1: saddle 10×10" in md and "![E1](E1.png)" in md
    for _, header, _ in report.COLUMNS:
        assert f"| {header} " in md
    assert "Range (min – max) over seeds 1:" in md
    assert "noise on interior vertices only" in md
    rows = list(csv.DictReader(e1.csv.read_text().splitlines()))
    keys = ["example", "seed", "fix", "method", "label", "edge_length_mm"] + [c[0] for c in report.COLUMNS]
    assert list(rows[0]) == keys
    assert [r["method"] for r in rows] == list(report.METHODS) * 2
    assert {r["fix"] for r in rows} == {"corners", "boundary"}
    for r in rows:
        for k in keys[5:]:
            assert np.isfinite(float(r[k])), (r["method"], k)
    seeds = list(csv.DictReader(e1.seeds_csv.read_text().splitlines()))
    assert {r["seed"] for r in seeds} == {"1"} and len(seeds) == len(report.METHODS)


def test_numbers_make_sense(e1):
    rows = {r["method"]: r for r in e1.results[0].rows}
    orig = rows["original"]
    assert orig["displacement_max_h"] == 0.0 and orig["zigzag_max"] > 0.5
    for key in ("laplacian", "taubin", "new", "new_default_weight"):
        assert rows[key]["zigzag_max"] < 0.1, key  # every method removes the zigzag above 0.1
    for key in ("laplacian_fixed_boundary", "taubin_fixed_boundary", "new_fixed_boundary"):
        assert rows[key]["boundary_displacement_max_h"] == 0.0, key
    assert rows["laplacian"]["bbox_change_pct"] < 0  # Laplacian shrinks
    assert rows["new_default_weight"]["vertex_distance_mean_h"] < rows["laplacian"]["vertex_distance_mean_h"]
    res = e1.results[0]
    assert res.free["original"].sum() == orig["vertices_above_0.1"]
    assert not res.free["new"][res.fixed["new"]].any()


def test_parameters_match_the_example_graphs():
    spec = importlib.util.spec_from_file_location("make_thesis_graphs", ROOT / "examples" / "make_thesis_graphs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert len(mod.EXAMPLES) == len(report.THESIS_EXAMPLES)
    for name, _stem, laplace, taubin, fair, noise in mod.EXAMPLES:
        ex = report.THESIS_EXAMPLES[name]
        assert (ex.laplace, ex.taubin, dict(ex.fair), ex.noise) == (laplace, taubin, fair, noise)
        assert qn.surfaces.EXAMPLES[name] == (ex.surface, ex.rows, ex.cols)


def test_measure_identity_and_boundary_directions():
    m = grid(6, 7)
    row = report.measure(m, m, m, m)
    for k, _, _ in report.COLUMNS:
        assert row[k] == 0.0, k
    c = m.vertices.mean(axis=0)
    bigger = m.with_vertices(c + 1.1 * (m.vertices - c))
    row = report.measure(m, bigger, m, m)
    assert row["boundary_outward_max_h"] > 0.2 and row["boundary_inward_max_h"] == 0.0
    assert row["bbox_change_pct"] == pytest.approx(10.0)
    smaller = m.with_vertices(c + 0.9 * (m.vertices - c))
    row = report.measure(m, smaller, m, m)
    assert row["boundary_inward_max_h"] > 0.2 and row["boundary_outward_max_h"] == 0.0
    lifted = m.with_vertices(m.vertices + [0.0, 0.0, 0.5])
    assert report.measure(m, lifted, m, m)["normal_offset_mean_h"] == pytest.approx(0.5)
    with pytest.raises(InputError, match="result: must have the same faces"):
        report.measure(m, grid(3, 3), m, m)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(examples=["E5"]), "examples: unknown example 'E5'"),
        (dict(examples=[]), "examples: expected a non-empty list"),
        (dict(examples="E1"), "examples: expected a non-empty list"),
        (dict(examples=["E1", "e1"]), "examples: listed twice"),
        (dict(seed=1.5), "seed: expected an integer"),
        (dict(spread_seeds=[1, "2"]), r"spread_seeds\[1\]: expected an integer"),
        (dict(size_px=10), "size_px: must be >= 200"),
    ],
)
def test_errors_name_the_parameter(tmp_path, kwargs, match):
    with pytest.raises(InputError, match=match):
        report.thesis_comparison(tmp_path / "out", **kwargs)
    assert not (tmp_path / "out").exists()


def test_run_example_errors():
    with pytest.raises(InputError, match="fix"):
        report.run_example("E1", fix="all")
    with pytest.raises(InputError, match="examples: unknown example 'X'"):
        report.run_example("X")


def test_cli_compare(tmp_path, capsys):
    out = tmp_path / "cmp"
    rc = main(["compare", "--out", str(out), "--examples", "E1", "--spread-seeds", "0", "--no-variants",
               "--no-interior-noise", "--size", "400", "--no-chapter3"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "E1" in text and "wrote" in text
    assert sorted(p.name for p in out.iterdir()) == ["E1.png", "comparison.csv", "comparison.md"]
    assert main(["compare", "--out", str(tmp_path / "bad"), "--examples", "E7"]) == 1
    assert "unknown example 'E7'" in capsys.readouterr().err


def test_chapter3_methods_in_the_comparison(e1):
    assert set(e1.chapter3) == {"E1", "C1"} and e1.chapter3_figures["E1"].name == "E1_chapter3.png"
    px = imread(e1.chapter3_figures["C1"])[..., :3]
    assert px.shape[1] == 500 and px.std() > 0.05
    md = e1.chapter3_markdown.read_text()
    assert "## E1: saddle 10×10" in md and "![E1](E1_chapter3.png)" in md and "## Closed lines" in md
    rows = {r["method"]: r for r in e1.chapter3["E1"].rows}
    assert list(rows) == list(report.CHAPTER3_METHODS)
    assert rows["fair_web_cylinders"]["zigzag_max"] < 0.1  # the cylinders let it remove the zigzag
    for key in ("fair_web", "spring", "schneider_kobbelt", "laplacian_fixed_boundary"):
        assert rows[key]["boundary_displacement_max_h"] == 0.0, key
    assert rows["new"]["seconds"] > 0 and rows["fair_web_cylinders"]["iterations"] > 0
    closed = {r["method"]: r for r in e1.chapter3["C1"].rows}
    assert list(closed) == list(report.CLOSED_METHODS)
    # Fourier descriptors remove the normal noise of the rings: much closer to the clean cylinder
    assert closed["fourier"]["surface_distance_mean_h"] < 0.2 * closed["original"]["surface_distance_mean_h"]
    table = list(csv.DictReader(e1.chapter3_csv.read_text().splitlines()))
    assert {r["fix"] for r in table} == {"corners", "boundary"}
    assert all(np.isfinite(float(r["zigzag_max"])) for r in table)

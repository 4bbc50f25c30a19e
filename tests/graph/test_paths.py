"""Output confinement and the files a run reports (issue 12, item 2), through the Python API."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadnodes.errors import GraphError
from quadnodes.graph import Graph, Registry, node
from quadnodes.graph.paths import check_paths, output_path_errors


@pytest.fixture()
def wreg():
    reg = Registry()

    @node("num", registry=reg)
    def num(*, value: float = 1.0) -> float:
        return value

    @node("save", registry=reg, writes=("path",))
    def save(x: float, *, path: Path, skip: bool = False) -> float:
        if not skip:
            path.write_text(repr(x))
        return x

    return reg


@pytest.mark.parametrize("text, words", [
    ("../x.txt", "leads out of the output folder"),
    ("a/../../x.txt", "leads out of the output folder"),
    ("/etc/x.txt", "is an absolute path"),
    (".", "leads out of the output folder"),
])
def test_lexical_errors_name_node_and_setting(wreg, text, words):
    g = Graph(registry=wreg)
    n = g.add("num", id="n")
    g.add("save", n, id="w", path=text)
    errs = output_path_errors(g)
    assert len(errs) == 1 and str(errs[0]).startswith("node 'w' (save@1): setting 'path': ") and words in str(errs[0])


def test_run_refuses_before_anything_runs(wreg, tmp_path):
    calls = []
    g = Graph(registry=wreg)
    n = g.add("num", id="n")
    g.add("save", n, id="w", path=str(tmp_path / "outside.txt"))
    (tmp_path / "out").mkdir()
    with pytest.raises(GraphError, match="outside the output folder"):
        g.run(out=tmp_path / "out", progress=calls.append)
    assert calls == [] and not (tmp_path / "outside.txt").exists()


def test_two_names_of_one_file_through_a_symlink_are_refused(wreg, tmp_path):
    out = tmp_path / "out"
    (out / "real").mkdir(parents=True)
    (out / "alias").symlink_to(out / "real", target_is_directory=True)
    g = Graph(registry=wreg)
    n = g.add("num", id="n")
    g.add("save", n, id="a", path="real/x.txt")
    g.add("save", n, id="b", path="alias/x.txt")
    assert output_path_errors(g) == []                   # different text ...
    with pytest.raises(GraphError, match=r"node 'b' \(save@1\).*same file as the one node 'a' \(save@1\) writes"):
        check_paths(g, out=out)                          # ... one file


def test_a_run_reports_only_files_it_wrote(wreg, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("from an earlier run")
    g = Graph(registry=wreg)
    n = g.add("num", id="n")
    g.add("save", n, id="w", path="new.txt")
    g.add("save", n, id="lazy", path="old.txt", skip=True)   # runs, but leaves its file alone
    r = g.run(out=out)
    assert r.record("w").files == (out / "new.txt",) and r.record("lazy").files == ()


def test_a_writer_path_with_another_format_s_extension_is_refused(tmp_path):
    # export_step with path = "panels.stl" wrote a STEP file named .stl, and `quadnodes check` said ok
    import quadnodes.nodes  # noqa: F401  (the built-in writers declare their file suffixes)

    g = Graph()
    m = g.add("grid", id="m", rows=3, cols=3)
    g.add("export_step", m.mesh, id="step", path="panels.stl")
    g.add("export_obj", m.mesh, id="obj", path="sub/panels.OBJ")  # any case
    g.add("render_png", m.mesh, id="png", path="view.jpg")
    g.add("render_html", m.mesh, id="html", path="view.htm")
    g.add("export_csv", m.mesh, id="csv", path="schedule")
    want = [
        "node 'step' (export_step@1): setting 'path': 'panels.stl' does not end in .step or .stp, the kind of "
        "file export_step writes; name it e.g. 'panels.step'",
        "node 'png' (render_png@1): setting 'path': 'view.jpg' does not end in .png, the kind of file "
        "render_png writes; name it e.g. 'view.png'",
        "node 'csv' (export_csv@1): setting 'path': 'schedule' does not end in .csv, the kind of file "
        "export_csv writes; name it e.g. 'schedule.csv'",
    ]
    assert [str(e) for e in output_path_errors(g)] == want
    with pytest.raises(GraphError) as err:  # the Python API's run checks the same
        check_paths(g, out=tmp_path)
    assert str(err.value).splitlines() == want
    assert not list(tmp_path.iterdir())


def test_a_writer_without_declared_suffixes_takes_any_name(wreg, tmp_path):
    g = Graph(registry=wreg)
    g.add("save", g.add("num", id="n").out, id="s", path="x.anything")
    assert output_path_errors(g) == []
    check_paths(g, out=tmp_path)

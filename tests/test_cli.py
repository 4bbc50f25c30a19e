import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from quadnodes.cli import main
from processes import ctrl_c_able

SMALL = '''format = "quadnodes-graph"
version = 1

[nodes.mesh]
op = "grid@1"
params = {{ rows = 8, cols = 9 }}

[nodes.noisy]
op = "perturb@1"
inputs = {{ mesh = "mesh.mesh" }}
params = {{ tangential = 0.2, seed = {seed}, fix = "corners" }}

[nodes.fair]
op = "fair@1"
inputs = {{ mesh = "noisy.mesh" }}
params = {{ iterations = 2 }}

[nodes.obj]
op = "export_obj@1"
inputs = {{ mesh = "fair.mesh" }}
params = {{ path = "faired.obj" }}
'''


def _graph(tmp_path, seed=1, name="g.toml"):
    p = tmp_path / name
    p.write_text(SMALL.format(seed=seed))
    return p


def _statuses(text):
    out = {}
    for line in text.splitlines():
        parts = line.split()
        if line.strip().startswith("[") and len(parts) >= 3:
            out[parts[2]] = parts[1]
    return out


def test_run_then_cached_then_set(tmp_path, capsys):
    g = _graph(tmp_path)
    out = tmp_path / "out"
    assert main(["run", str(g), "--out", str(out)]) == 0
    first = capsys.readouterr().out
    assert set(_statuses(first).values()) == {"ran"} and (out / "faired.obj").exists()
    assert "wrote" in first
    assert main(["run", str(g), "--out", str(out)]) == 0
    assert set(_statuses(capsys.readouterr().out).values()) == {"cached"}
    assert main(["run", str(g), "--out", str(out), "--set", "fair.iterations=3"]) == 0
    st = _statuses(capsys.readouterr().out)
    assert st == {"mesh": "cached", "noisy": "cached", "fair": "ran", "obj": "ran"}
    (out / "faired.obj").unlink()
    assert main(["run", str(g), "--out", str(out), "--set", "fair.iterations=3"]) == 0
    assert _statuses(capsys.readouterr().out)["obj"] == "ran"


@pytest.mark.parametrize("text, message", [
    ('format = "quadnodes-graph"\nversion = 1\n[nodes.a]\nop = "nope@1"\n', "node 'a'"),
    ('format = "quadnodes-graph"\nversion = 1\n[nodes.a]\nop = "grid@1"\nparams = { rowz = 3 }\n', "rowz"),
    ('format = "quadnodes-graph"\nversion = 1\n[nodes.a\nop = "grid@1"\n', "line 3"),
])
def test_errors_exit_nonzero_with_one_line(tmp_path, capsys, text, message):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and err.count("\n") == 1
    assert main(["check", str(p)]) == 1


def test_check_nodes_new(tmp_path, capsys, monkeypatch):
    assert main(["check", str(_graph(tmp_path))]) == 0
    assert "ok, 4 nodes" in capsys.readouterr().out
    assert main(["nodes"]) == 0
    listing = capsys.readouterr().out
    assert "fair@1" in listing and "export_step@1" in listing
    assert main(["nodes", "fair"]) == 0
    detail = capsys.readouterr().out
    assert "threshold_decay" in detail and "default 0.3" in detail
    monkeypatch.chdir(tmp_path)
    assert main(["new", "starter"]) == 0
    assert main(["new", "starter"]) == 1
    capsys.readouterr()
    assert main(["check", "starter.toml"]) == 0


def test_bad_set_syntax(tmp_path, capsys):
    assert main(["run", str(_graph(tmp_path)), "--out", str(tmp_path / "o"), "--set", "fairiterations"]) == 1
    assert "node.setting=value" in capsys.readouterr().err


def test_watch_reruns_after_edit_and_survives_a_broken_edit(tmp_path, capsys):
    g = _graph(tmp_path, seed=1)
    out = tmp_path / "out"

    def save(text: str) -> None:  # as an editor saves by rename: never read half-written (write_text truncates
        # first; on a loaded machine — the compiled kernels loading beside a cold start — the watcher once read the
        # emptied file between the truncation and the write, and that error run used up --max-runs)
        tmp = g.with_suffix(".tmp")
        tmp.write_text(text)
        os.replace(tmp, g)

    def edit():
        time.sleep(1.5)
        save("this is not toml [")          # a broken edit: error, keep watching
        time.sleep(1.0)
        save(SMALL.format(seed=2))          # fixed: re-run, only from 'noisy' on

    t = threading.Thread(target=edit)
    t.start()
    rc = main(["watch", str(g), "--out", str(out), "--interval", "0.1", "--max-runs", "3", "--timeout", "20"])
    t.join()
    cap = capsys.readouterr()
    assert rc == 0
    runs = cap.out.split("running ")[1:]
    assert len(runs) == 2, cap.out
    assert _statuses(runs[1]) == {"mesh": "cached", "noisy": "ran", "fair": "ran", "obj": "ran"}
    assert "error:" in cap.err


def test_watch_reruns_readers_when_input_file_changes(tmp_path, capsys):
    from quadnodes.io import save_obj
    from quadnodes.mesh import grid

    save_obj(grid(5, 6), tmp_path / "in.obj")
    g = tmp_path / "r.toml"
    g.write_text('format = "quadnodes-graph"\nversion = 1\n[nodes.read]\nop = "read_mesh@1"\n'
                 'params = { path = "in.obj" }\n[nodes.fair]\nop = "fair@1"\ninputs = { mesh = "read.mesh" }\n')

    def edit():
        time.sleep(1.5)
        save_obj(grid(5, 7), tmp_path / "in.obj")

    t = threading.Thread(target=edit)
    t.start()
    main(["watch", str(g), "--out", str(tmp_path / "o"), "--interval", "0.1", "--max-runs", "2", "--timeout", "20"])
    t.join()
    runs = capsys.readouterr().out.split("running ")[1:]
    assert len(runs) == 2 and _statuses(runs[1]) == {"read": "ran", "fair": "ran"}


@pytest.mark.skipif(shutil.which("quadnodes") is None and not (Path(sys.executable).parent / "quadnodes").exists(),
                    reason="console script not installed")
def test_ctrl_c_stops_watch_cleanly(tmp_path):
    exe = shutil.which("quadnodes") or str(Path(sys.executable).parent / "quadnodes")
    g = _graph(tmp_path)
    p = subprocess.Popen([exe, "watch", str(g), "--out", str(tmp_path / "o")], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, preexec_fn=ctrl_c_able)
    deadline = time.time() + 60
    while time.time() < deadline and not (tmp_path / "o" / "faired.obj").exists():
        time.sleep(0.2)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=30)
    assert p.returncode == 0, err
    assert "stopped" in out and "Traceback" not in err


# ----------------------------------------------------------------- output confinement (issue 12, item 2)
def _with_obj_path(tmp_path, path_text, name="g.toml"):
    p = tmp_path / name
    p.write_text(SMALL.format(seed=1).replace('path = "faired.obj"', f"path = {path_text}"))
    return p


@pytest.mark.parametrize("path_text, words", [
    ('"../escape.obj"', "leads out of the output folder"),
    ('"sub/../../escape.obj"', "leads out of the output folder"),
    ("'{abs}'", "is an absolute path"),
])
def test_a_graph_file_cannot_write_outside_out(tmp_path, capsys, path_text, words):
    target = tmp_path / "escape.obj"
    g = _with_obj_path(tmp_path, path_text.format(abs=target))
    out = tmp_path / "work" / "out"
    assert main(["run", str(g), "--out", str(out)]) == 1
    cap = capsys.readouterr()
    assert "node 'obj' (export_obj@1): setting 'path'" in cap.err and words in cap.err
    assert not target.exists() and "[1/" not in cap.out          # refused before anything ran
    assert main(["check", str(g)]) == 1
    assert "node 'obj'" in capsys.readouterr().err


def test_set_cannot_send_an_output_elsewhere(tmp_path, capsys):
    g = _graph(tmp_path)
    target = tmp_path / "elsewhere" / "x.obj"
    target.parent.mkdir()
    rc = main(["run", str(g), "--out", str(tmp_path / "out"), "--set", f"obj.path={target}"])
    cap = capsys.readouterr()
    assert rc == 1 and "node 'obj' (export_obj@1): setting 'path'" in cap.err and "absolute" in cap.err
    assert not target.exists() and "wrote" not in cap.out.replace(str(tmp_path), "")


def test_a_symlink_leading_out_is_refused_before_anything_runs(tmp_path, capsys):
    outside = tmp_path / "outside"
    outside.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    (out / "link").symlink_to(outside, target_is_directory=True)
    g = _with_obj_path(tmp_path, '"link/faired.obj"')
    assert main(["run", str(g), "--out", str(out)]) == 1
    cap = capsys.readouterr()
    assert "node 'obj' (export_obj@1): setting 'path'" in cap.err and "symbolic link" in cap.err
    assert os.listdir(outside) == [] and "[1/" not in cap.out
    assert main(["check", str(g), "--out", str(out)]) == 1
    assert "symbolic link" in capsys.readouterr().err


def test_two_writers_of_one_file_are_an_error_naming_both(tmp_path, capsys):
    g = tmp_path / "two.toml"
    g.write_text(SMALL.format(seed=1) + '\n[nodes.obj2]\nop = "export_obj@1"\ninputs = { mesh = "noisy.mesh" }\n'
                 'params = { path = "./faired.obj" }\n')
    assert main(["check", str(g)]) == 1
    err = capsys.readouterr().err
    assert "node 'obj2'" in err and "node 'obj'" in err and "also written by" in err


def test_reads_stay_in_the_graph_folder_unless_allowed(tmp_path, capsys):
    from quadnodes.io import save_obj
    from quadnodes.mesh import grid

    data = tmp_path / "data"
    data.mkdir()
    save_obj(grid(4, 5), data / "in.obj")
    gdir = tmp_path / "graphs"
    gdir.mkdir()
    g = gdir / "r.toml"
    g.write_text('format = "quadnodes-graph"\nversion = 1\n[nodes.read]\nop = "read_mesh@1"\n'
                 'params = { path = "../data/in.obj" }\n')
    assert main(["run", str(g), "--out", str(tmp_path / "o"), "--no-cache"]) == 1
    err = capsys.readouterr().err
    assert "node 'read' (read_mesh@1): setting 'path'" in err and "--allow-read" in err
    assert main(["check", str(g)]) == 1                                   # check says it too, before any run
    assert "node 'read' (read_mesh@1): setting 'path'" in capsys.readouterr().err
    assert main(["check", str(g), "--allow-read", str(data)]) == 0
    capsys.readouterr()
    assert main(["run", str(g), "--out", str(tmp_path / "o"), "--no-cache", "--allow-read", str(data)]) == 0
    assert _statuses(capsys.readouterr().out) == {"read": "ran"}


def test_python_api_outputs_stay_in_the_run_folder(tmp_path):
    import quadnodes.nodes  # noqa: F401
    from quadnodes.errors import GraphError
    from quadnodes.graph import Graph

    g = Graph()
    m = g.add("grid", id="m", rows=3, cols=3)
    g.add("export_obj", m.mesh, id="obj", path=str(tmp_path / "elsewhere.obj"))
    with pytest.raises(GraphError, match=r"node 'obj' \(export_obj@1\): setting 'path'.*outside the output folder"):
        g.run(out=tmp_path / "out")
    assert not (tmp_path / "elsewhere.obj").exists()
    g.set("obj", path="inside.obj")
    (tmp_path / "out").mkdir()
    r = g.run(out=tmp_path / "out")
    assert r.record("obj").files == ((tmp_path / "out" / "inside.obj"),) and (tmp_path / "out" / "inside.obj").exists()


# --------------------------------------------------------------- wrote / unchanged (issue 12, item 8)
def test_run_reports_wrote_only_for_files_written_this_run(tmp_path, capsys):
    from quadnodes.cli import _shown

    g = _graph(tmp_path)
    out = tmp_path / "out"
    assert main(["run", str(g), "--out", str(out)]) == 0
    first = capsys.readouterr().out
    assert "wrote" in first and _shown(out / "faired.obj") in first
    assert main(["run", str(g), "--out", str(out)]) == 0
    second = capsys.readouterr().out
    assert not any(line.split()[:1] == ["wrote"] for line in second.splitlines())
    assert f"unchanged {_shown(out / 'faired.obj')}" in second
    (out / "faired.obj").write_text("edited by hand\n")
    assert main(["run", str(g), "--out", str(out)]) == 0
    third = capsys.readouterr().out
    assert f"wrote     {_shown(out / 'faired.obj')}" in third
    assert not any(line.split()[:1] == ["unchanged"] for line in third.splitlines())


# --------------------------------------------------------------- the output folder (issue 12, item 4)
def test_out_onto_a_file_is_one_clear_line(tmp_path, capsys):
    g = _graph(tmp_path)
    (tmp_path / "afile").write_text("x")
    assert main(["run", str(g), "--no-cache", "--out", str(tmp_path / "afile")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: --out") and "a file is in the way" in err and err.count("\n") == 1
    assert main(["run", str(g), "--no-cache", "--out", str(tmp_path / "afile" / "sub")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: --out") and "Traceback" not in err and err.count("\n") == 1
    assert main(["run", str(g), "--out", str(tmp_path / "afile")]) == 1          # with the disk cache in --out
    err = capsys.readouterr().err
    assert err.startswith("error: --out") and "a file is in the way" in err and err.count("\n") == 1


def test_out_onto_a_read_only_folder_is_one_clear_line(tmp_path, capsys, read_only_folder):
    # (root ignores permission bits: the fixture injects the refusal where the OS gives it, creating a file)
    g = _graph(tmp_path)
    ro = read_only_folder
    assert main(["run", str(g), "--no-cache", "--out", str(ro)]) == 1
    err = capsys.readouterr().err
    assert err == f"error: --out {str(ro)!r}: cannot write into the folder: Permission denied\n"
    assert os.listdir(ro) == []


# --------------------------------------------------------------- check lists every problem (issue 12, item 7)
MANY_ERRORS = '''format = "quadnodes-graph"
version = 1

[nodes.mesh]
op = "grid@1"
params = { rows = 8, colz = 9 }

[nodes.noisy]
op = "perturbb@1"
inputs = { mesh = "mesh.mesh" }

[nodes.fair]
op = "fair@1"
inputs = { mesh = "noisy.mesh", fixd = "mesh.mesh" }
params = { iterations = -1, weight = [0.3, -0.1], solver = "fast" }

[nodes.png]
op = "render_png@1"
inputs = { mesh = "fair.mesh", mesh2 = "mesh.nope" }
params = { path = "../f.png", titles = ["a", "faired {fair.iteratons} times"] }

[nodes.loop_a]
op = "laplacian@1"
inputs = { mesh = "loop_b.mesh" }

[nodes.loop_b]
op = "laplacian@1"
inputs = { mesh = "loop_a.mesh" }
'''


def test_check_reports_every_error_of_a_file(tmp_path, capsys):
    p = tmp_path / "many.toml"
    p.write_text(MANY_ERRORS)
    assert main(["check", str(p)]) == 1
    err = capsys.readouterr().err
    expected = [
        "line 4: node 'mesh' (grid@1): unknown setting 'colz'; did you mean 'cols'?",
        "line 8: node 'noisy': unknown op 'perturbb@1'; did you mean 'perturb'?",
        "line 12: node 'fair' (fair@1): setting 'iterations': -1 is out of range (must be >= 1)",
        "line 12: node 'fair' (fair@1): setting 'weight'[1]: -0.1 is out of range (must be > 0)",
        "line 12: node 'fair' (fair@1): setting 'solver'",
        "line 12: node 'fair' (fair@1): unknown input port 'fixd'; did you mean 'fixed'?",
        "line 17: node 'png' (render_png@1): input 'mesh2' refers to 'mesh.nope'",
        "line 17: node 'png' (render_png@1): setting 'path': '../f.png' leads out of the output folder",
        "line 17: node 'png' (render_png@1): setting 'titles'[1]: '{fair.iteratons}' names no setting 'iteratons'"
        " of node 'fair' (fair@1); did you mean 'iterations'?",
        "cycle: loop_",
    ]
    for e in expected:
        assert e in err, e
    assert "refers to 'noisy.mesh'" not in err           # the unknown op is reported once, not again downstream
    assert err.strip().endswith("10 problems")
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 1   # run stops at the first, before running
    assert "[1/" not in capsys.readouterr().out


def test_value_ranges_are_checked_when_the_file_is_loaded(tmp_path, capsys):
    from quadnodes.errors import GraphError
    from quadnodes.graph import load

    p = tmp_path / "neg.toml"
    p.write_text(SMALL.format(seed=1).replace("iterations = 2", "iterations = -1"))
    with pytest.raises(GraphError, match=r"line \d+: node 'fair' \(fair@1\): setting 'iterations': -1 is out of range"):
        load(p)
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 1
    cap = capsys.readouterr()
    assert "-1 is out of range (must be >= 1)" in cap.err and "[1/" not in cap.out
    assert main(["run", str(_graph(tmp_path)), "--out", str(tmp_path / "o"), "--set", "noisy.tangential=-0.5"]) == 1
    assert "setting 'tangential': -0.5 is out of range (must be >= 0)" in capsys.readouterr().err


# --------------------------------------------------------------- nodes shows every setting (issue 12, item 9)
def test_nodes_op_shows_type_default_range_and_meaning_of_every_setting(capsys):
    import quadnodes.nodes  # noqa: F401
    from quadnodes.graph import REGISTRY, describe

    assert main(["nodes", "fair"]) == 0
    out = capsys.readouterr().out
    assert "iterations: int  (default 1, range >= 1)\n      Rounds of detect-then-solve" in out
    assert "Parameters\n----------" not in out                       # the section is shown setting by setting
    for nt in REGISTRY.latest():
        d = describe(nt.op)
        for s in d["settings"]:
            assert s["doc"], f"{nt.op}: setting {s['name']!r} has no line of meaning in the docstring"


def test_nodes_list_shows_whole_first_sentences(capsys):
    import quadnodes.nodes  # noqa: F401
    from quadnodes.graph import REGISTRY, describe

    assert main(["nodes"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    for nt in REGISTRY.latest():
        summary = describe(nt.op)["summary"]
        assert " ".join(summary.split()) in out, nt.op
        assert summary.rstrip().endswith((".", ")")) or ";" in summary or summary == "", (nt.op, summary)


# --------------------------------------------------------------- progress on a terminal (issue 12, item 12)
class _Terminal:
    """A stdout stand-in that says it is a terminal."""

    def __init__(self):
        self.text = ""

    def write(self, s):
        self.text += s

    def flush(self):
        pass

    def isatty(self):
        return True


PNG_STEP = SMALL + '''
[nodes.step]
op = "export_step@1"
inputs = {{ mesh = "fair.mesh" }}
params = {{ path = "faired.step" }}

[nodes.png]
op = "render_png@1"
inputs = {{ mesh = "noisy.mesh", mesh2 = "fair.mesh" }}
params = {{ path = "f.png", size_px = 300, titles = ["noisy", "faired, {{fair.iterations}} iterations"] }}
'''


def test_progress_of_step_and_png_on_a_terminal_and_none_in_a_log(tmp_path, monkeypatch):
    import argparse
    import io

    from quadnodes import cli
    from quadnodes.graph import Cache

    g = tmp_path / "g.toml"
    g.write_text(PNG_STEP.format(seed=1))
    args = argparse.Namespace(graph=str(g), out=str(tmp_path / "o"), set=None, allow_read=None)
    ticks = iter(range(10**6))                     # a clock that advances 1 s per look: no update is throttled
    monkeypatch.setattr(cli._ProgressLine, "clock", staticmethod(lambda: float(next(ticks))))
    tty = _Terminal()
    cli._run(args, Cache(), tty)
    assert "step: " in tty.text and "building panel" in tty.text     # STEP writing, in place ...
    assert "png: " in tty.text and "drawing mesh 1/2" in tty.text     # ... and PNG rendering
    assert "\r\033[K" in tty.text
    plain = io.StringIO()                                              # a log file: no progress, plain lines
    cli._run(args, Cache(), plain)
    text = plain.getvalue()
    assert "\r" not in text and "\033" not in text and "building panel" not in text
    assert "[6/6] ran" in text


# --------------------------------------------------------------- notes in the summary (issue 12, items 10-11)
def test_notes_of_any_output_are_printed_in_the_summary(tmp_path, capsys):
    from dataclasses import dataclass

    from quadnodes.graph import REGISTRY, node

    @dataclass
    class Rep:
        n_free: tuple

        def notes(self):
            idle = [i + 1 for i, n in enumerate(self.n_free) if n == 0]
            return [f"{len(self.n_free)} iterations asked, iterations {idle} freed no vertex"] if idle else []

    @node("test_noted", outputs=("report",))
    def test_noted(*, n_free: list[int] = [3, 0, 0]) -> Rep:  # noqa: B006
        """A report with notes (test only)."""
        return Rep(tuple(n_free))

    try:
        g = tmp_path / "n.toml"
        g.write_text('format = "quadnodes-graph"\nversion = 1\n[nodes.fair]\nop = "test_noted@1"\n')
        assert main(["run", str(g), "--out", str(tmp_path / "o"), "--no-cache"]) == 0
        assert "  note: fair: 3 iterations asked, iterations [2, 3] freed no vertex" in capsys.readouterr().out
        assert main(["run", str(g), "--out", str(tmp_path / "o"), "--no-cache", "--set", "fair.n_free=[1, 2]"]) == 0
        assert "note:" not in capsys.readouterr().out
    finally:
        REGISTRY.unregister("test_noted@1")


def test_e3_says_why_the_boundary_moves_and_what_fixes_it(tmp_path, capsys):
    from pathlib import Path

    e3 = Path(__file__).resolve().parent.parent / "examples" / "e3_wavy.toml"
    text = e3.read_text()
    assert "fair.weight=0.3" in text and "boundary" in text.split("format =")[0]      # the file's comments say it
    out = tmp_path / "e3"
    assert main(["run", str(e3), "--out", str(out)]) == 0
    summary = capsys.readouterr().out
    note = [line for line in summary.splitlines() if line.startswith("  note: advice:")]
    assert note and "boundary_displacement_max" in note[0] and "fair.weight=0.3" in note[0]
    assert main(["run", str(e3), "--out", str(out), "--set", "fair.weight=0.3"]) == 0
    assert "note: advice:" not in capsys.readouterr().out       # fixed: no note


def test_check_keeps_the_loaders_own_error_next_to_the_others(tmp_path, capsys):
    p = tmp_path / "dup.json"
    p.write_text('{"format": "quadnodes-graph", "version": 1, "nodes": {"m": {"op": "grid@1", '
                 '"params": {"rows": 0, "rows": 3}}, "f": {"op": "fair@1", "inputs": {"mesh": "m.mesh"}, '
                 '"params": {"iterations": 0}}}}')
    assert main(["check", str(p)]) == 1
    err = capsys.readouterr().err
    assert "'rows' appears twice" in err and "setting 'iterations': 0 is out of range" in err


def test_check_refuses_a_surface_wired_into_a_mesh_input_and_the_reverse(tmp_path, capsys):
    # face ports were typed Any: `check` said ok, and `run` failed inside fair/sample
    p = tmp_path / "wired.toml"
    p.write_text('format = "quadnodes-graph"\nversion = 1\n\n[nodes.surface]\nop = "saddle@1"\n\n'
                 '[nodes.plane]\nop = "grid@1"\n\n[nodes.fair]\nop = "fair@1"\ninputs = { mesh = "surface.face" }\n\n'
                 '[nodes.clean]\nop = "sample@1"\ninputs = { face = "plane.mesh" }\n')
    assert main(["check", str(p)]) == 1
    cap = capsys.readouterr()
    assert cap.out == "" and cap.err.splitlines() == [
        f"error: {p} line 10: node 'fair' (fair@1): input 'mesh' expects QuadMesh, but 'surface.face' gives Face",
        f"error: {p} line 14: node 'clean' (sample@1): input 'face' expects Face, but 'plane.mesh' gives QuadMesh",
        f"{p}: 2 problems",
    ]
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 1
    cap = capsys.readouterr()
    assert "input 'mesh' expects QuadMesh, but 'surface.face' gives Face" in cap.err and "[1/" not in cap.out


@pytest.mark.parametrize("command", ["run", "check"])
def test_ctrl_c_during_a_run_is_one_clear_line_and_leaves_no_half_file(tmp_path, capsys, monkeypatch, command):
    # Ctrl-C printed a 30-line traceback ending in OCCT's or NumPy's internals
    import quadnodes.io._atomic as atomic

    g = _graph(tmp_path)
    out = tmp_path / "out"
    real = atomic.write_atomic

    def interrupted(path, write):
        def half(tmp):
            with open(tmp, "w") as fh:
                fh.write("v 0 0 0\n")
            raise KeyboardInterrupt

        return real(path, half)

    monkeypatch.setattr(atomic, "write_atomic", interrupted)
    if command == "check":  # interrupted while loading the graph (the parser)
        import quadnodes.graph.diagnostics as diagnostics

        def stop(*args, **kwargs):
            raise KeyboardInterrupt

        monkeypatch.setattr(diagnostics, "file_problems", stop)
    assert main([command, str(g)] + (["--out", str(out)] if command == "run" else [])) == 130
    err = capsys.readouterr().err
    assert err.splitlines()[-1].startswith("interrupted (Ctrl-C)"), err
    assert "Traceback" not in err
    assert not (out / "faired.obj").exists() and not [p for p in tmp_path.rglob("*") if ".tmp" in p.name]


@pytest.mark.parametrize("name", ["", "sub/", ".toml", "sub/.toml"])
def test_new_without_a_file_name_is_refused(tmp_path, capsys, monkeypatch, name):
    # `quadnodes new ""` wrote a hidden file '.toml' and told the user to run it
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sub").mkdir()
    assert main(["new", name]) == 1
    assert capsys.readouterr().err == (f"error: new: {name!r} has no file name; give one such as my_design "
                                       "(writes my_design.toml)\n")
    assert not list(tmp_path.rglob("*.toml"))


def test_new_into_a_missing_folder_names_the_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["new", "sub/dir/y"]) == 1
    assert capsys.readouterr().err == "error: cannot write 'sub/dir/y.toml': the folder 'sub/dir' does not exist\n"


def test_every_argument_of_every_command_has_help(capsys):
    # check's graph, nodes' op, new's name and --force showed no help at all
    from quadnodes.cli import build_parser

    ap = build_parser()
    sub = next(a for a in ap._actions if a.__class__.__name__ == "_SubParsersAction")
    for name, parser in sub.choices.items():
        for action in parser._actions:
            assert action.help, f"quadnodes {name}: argument {action.dest!r} has no help"


def test_output_into_a_closed_pipe_ends_quietly(capsys, monkeypatch):
    # `quadnodes nodes | head` printed "error: cannot use: Broken pipe"
    class Closed:
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            raise BrokenPipeError(32, "Broken pipe")

        def fileno(self):
            raise OSError("no file")

    monkeypatch.setattr(sys, "stdout", Closed())
    assert main(["nodes"]) == 141
    assert capsys.readouterr().err == ""

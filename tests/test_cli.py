import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from quadnodes.cli import main

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

    def edit():
        time.sleep(1.5)
        g.write_text("this is not toml [")          # a broken edit: error, keep watching
        time.sleep(1.0)
        g.write_text(SMALL.format(seed=2))          # fixed: re-run, only from 'noisy' on

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
                         stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline and not (tmp_path / "o" / "faired.obj").exists():
        time.sleep(0.2)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=30)
    assert p.returncode == 0, err
    assert "stopped" in out and "Traceback" not in err

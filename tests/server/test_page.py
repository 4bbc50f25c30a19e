"""The page in headless Chromium (driven over the DevTools protocol; skipped without Chromium).

Loads the quick-start in a real `quadnodes serve`, changes a setting through the form, sees the 3-D view
update and the file change on disk, sees an invalid edit's message on the node, and reloads the page.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

import chromium as cdp

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(not cdp.available(), reason="Chromium is not installed")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    d = tmp_path_factory.mktemp("page")
    graph = d / "quickstart.toml"
    shutil.copy(ROOT / "examples" / "quickstart.toml", graph)
    port = _free_port()
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
           "PYTHONUNBUFFERED": "1"}
    # the server's output goes to files, not pipes: a pipe that nobody reads after the first lines fills with the
    # runs' progress and the requests' log, and then blocks the server
    out, err = open(d / "serve.out", "w"), open(d / "serve.err", "w")
    proc = subprocess.Popen([sys.executable, "-m", "quadnodes", "serve", str(graph), "--no-browser",
                             "--port", str(port), "--out", str(d / "out")],
                            cwd=d, env=env, stdout=out, stderr=err, text=True)
    browser = None
    try:
        deadline = time.monotonic() + 60
        while len(lines := (d / "serve.out").read_text().splitlines()) < 2:  # (the second line is the address)
            assert time.monotonic() < deadline and proc.poll() is None, (d / "serve.err").read_text()[-3000:]
            time.sleep(0.05)
        url = lines[1].strip()
        assert url.startswith(f"http://127.0.0.1:{port}/?token="), url
        browser = cdp.Browser(width=1600, height=900)
        yield {"url": url, "graph": graph, "browser": browser, "dir": d}
    finally:
        if browser is not None:
            browser.close()
        proc.terminate()
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        out.close()
        err.close()


VIEW_KEY = "(document.querySelector('.view[data-view=\"fair.mesh\"]') || {dataset: {}}).dataset.key"


def _open(b: cdp.Browser, url: str, logs: Path) -> None:
    try:
        b.goto(url)
        b.wait_for("document.body && document.body.dataset.ready === '1'", timeout=120)
    except TimeoutError as exc:  # (say what the server and the browser logged)
        tails = {name: (logs / name).read_text(errors="replace")[-2000:] for name in ("serve.out", "serve.err")}
        tails["chromium"] = b.log.read_text(errors="replace")[-2000:]
        raise TimeoutError(f"{exc}; logs: {tails}") from exc


def test_the_page_edits_the_quickstart_live(served):
    b, graph = served["browser"], served["graph"]
    _open(b, served["url"], served["dir"])
    assert b.evaluate("[...document.querySelectorAll('.node')].length") == 16
    # the first visit opens a 3-D view of the faired mesh; wait until the first run has drawn it
    key0 = b.wait_for(VIEW_KEY, timeout=300)
    assert b.evaluate("document.querySelector('.view[data-view=\"fair.mesh\"] .view-plot').data.length") == 2
    assert b.evaluate("document.querySelectorAll('#wires path.wire').length") >= 20
    comment = "# threshold 0.03 (alternating detection) and weight 0.3 by default"
    assert comment in graph.read_text()

    # change fair.iterations through the form
    b.evaluate("""(() => {
        const i = document.querySelector('.node[data-node="fair"] [data-setting="iterations"]');
        i.value = '1'; i.dispatchEvent(new Event('change', {bubbles: true})); })()""")
    deadline = time.monotonic() + 60
    while "iterations = 1" not in graph.read_text():
        assert time.monotonic() < deadline, graph.read_text()
        time.sleep(0.1)
    assert comment in graph.read_text()  # the user's comment survives the edit
    key1 = b.wait_for(f"(() => {{ const k = {VIEW_KEY}; return k && k !== {json.dumps(key0)} ? k : null; }})()",
                      timeout=120)
    assert key1 != key0
    # fair re-ran, the nodes before it came from the cache (both shown at once: under load a status may
    # arrive a moment after another)
    b.wait_for("(() => { const s = n => document.querySelector(`.node[data-node=\"${n}\"] [data-status]`).dataset.status;"
               " return s('fair') === 'ran' && s('noisy') === 'cached'; })()")

    # an invalid edit: refused, the message on the node, the file unchanged
    before = graph.read_bytes()
    b.evaluate("""(() => {
        const i = document.querySelector('.node[data-node="fair"] [data-setting="iterations"]');
        i.value = 'many'; i.dispatchEvent(new Event('change', {bubbles: true})); })()""")
    msg = b.wait_for("(() => { const e = document.querySelector('.node[data-node=\"fair\"] [data-error]');"
                     " return e && !e.hidden ? e.textContent : null; })()")
    assert "node 'fair' (fair@1): setting 'iterations': expected int, got str 'many'" in msg
    assert graph.read_bytes() == before

    shot = b.screenshot(served["dir"] / "page.png")
    assert shot.stat().st_size > 50_000

    # reloading shows the same graph, the edited value and the open view
    _open(b, served["url"], served["dir"])
    assert b.evaluate("[...document.querySelectorAll('.node')].map(n => n.dataset.node).sort().join(' ')") == \
        " ".join(sorted(["surface", "clean", "noisy", "fair", "laplace", "taubin", "metrics_fair", "metrics_laplace",
                         "metrics_taubin", "report", "step", "obj", "csv", "png", "planarity_png", "html"]))
    assert b.evaluate("document.querySelector('.node[data-node=\"fair\"] [data-setting=\"iterations\"]').value") == "1"
    assert b.wait_for(VIEW_KEY, timeout=60) == key1
    assert not b.console, b.console


def test_the_page_needs_the_token(served):
    b = served["browser"]
    b.goto(served["url"].split("?")[0])
    text = b.wait_for("document.body && document.body.innerText")
    assert "token" in text and "quadnodes" not in b.evaluate("document.title")

"""watch: an edit saved while a run is in progress is not lost (issue 12, item 3)."""

from __future__ import annotations

import os
import time

from quadnodes.errors import GraphError
from quadnodes.graph.watch import watch


def test_an_edit_saved_during_a_run_triggers_another_run(tmp_path):
    g = tmp_path / "g.toml"
    g.write_text("version 1\n")
    seen: list[str] = []

    def slow_run():
        seen.append(g.read_text())
        if len(seen) == 1:
            time.sleep(0.05)                 # the run is in progress ...
            g.write_text("version 2, saved during the first run\n")   # ... when the user saves
            time.sleep(0.05)
        return None

    state = watch(g, slow_run, interval=0.02, settle=0.0, max_runs=2, timeout=5)
    assert state.runs == 2 and seen == ["version 1\n", "version 2, saved during the first run\n"]


def test_a_broken_edit_during_a_run_is_also_picked_up(tmp_path):
    g = tmp_path / "g.toml"
    g.write_text("a\n")
    errors: list[GraphError] = []
    calls = 0

    def run_once():
        nonlocal calls
        calls += 1
        if calls == 1:
            g.write_text("broken [\n")
            os.utime(g, ns=(time.time_ns(), time.time_ns() + 10**9))
            return None
        raise GraphError("line 1: broken")

    state = watch(g, run_once, interval=0.02, settle=0.0, max_runs=2, timeout=5, on_error=errors.append)
    assert state.runs == 2 and state.errors == 1 and len(errors) == 1


def test_no_edit_no_rerun(tmp_path):
    g = tmp_path / "g.toml"
    g.write_text("a\n")
    state = watch(g, lambda: None, interval=0.02, settle=0.0, max_runs=5, timeout=0.3)
    assert state.runs == 1

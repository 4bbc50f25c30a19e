"""{node.setting} in template settings: expanded from the resolved settings, checked at load (issue 12, item 10)."""

from __future__ import annotations

import pytest

from quadnodes.errors import GraphError
from quadnodes.graph import Cache, Graph, Registry, loads, node


@pytest.fixture()
def treg():
    reg = Registry()

    @node("smooth", registry=reg)
    def smooth(*, rounds: int = 3, lam: float = 0.5, tags: list[str] | None = None) -> int:
        return rounds

    @node("caption", registry=reg, templates=("titles",))
    def caption(x: int, *, titles: list[str] | None = None, plain: str = "") -> list:
        return [titles, plain]

    return reg


def test_titles_follow_the_settings_and_overrides(treg):
    g = Graph(registry=treg)
    s = g.add("smooth", id="s")
    other = g.add("smooth", id="other", lam=0.25)
    c = g.add("caption", s, id="c", titles=["{s.rounds} rounds, λ {s.lam}", "other λ {other.lam:.1%}"],
              plain="{s.rounds} stays")
    cache = Cache()
    assert g.run(cache=cache)[c] == [["3 rounds, λ 0.5", "other λ 25.0%"], "{s.rounds} stays"]
    r = g.run(cache=cache, overrides={"s.rounds": 5})
    assert r[c][0][0] == "5 rounds, λ 0.5"
    # a setting of a node that is not upstream still changes the title, and so the cache key
    r = g.run(cache=cache, overrides={"other.lam": 0.5})
    assert r[c][0][1] == "other λ 50.0%" and "c" in r.ran


@pytest.mark.parametrize("title, words", [
    ("{x.rounds}", "names no node 'x'"),
    ("{s.roundz}", "names no setting 'roundz' of node 's' (smooth@1); did you mean 'rounds'?"),
    ("{s}", "expected '{node.setting}'"),
    ("{s.rounds", "expected '}'"),
])
def test_unknown_references_are_refused_when_the_file_is_loaded(treg, title, words):
    text = ('format = "quadnodes-graph"\nversion = 1\n[nodes.s]\nop = "smooth"\n[nodes.c]\nop = "caption"\n'
            f'inputs = {{ x = "s.out" }}\nparams = {{ titles = ["ok", {title!r}] }}\n').replace("'", '"')
    with pytest.raises(GraphError) as e:
        loads(text, fmt="toml", registry=treg)
    assert "line 5: node 'c' (caption@1): setting 'titles'[1]" in str(e.value) and words in str(e.value)


def test_the_cli_figure_titles_follow_set(tmp_path, monkeypatch):
    import quadnodes.nodes  # noqa: F401
    from quadnodes import viz
    from quadnodes.cli import main

    seen = []
    real = viz.render_png

    def spy(meshes, path, **kw):
        seen.append(kw["titles"])
        return real(meshes, path, **kw)

    monkeypatch.setattr(viz, "render_png", spy)
    g = tmp_path / "g.toml"
    g.write_text('format = "quadnodes-graph"\nversion = 1\n'
                 '[nodes.mesh]\nop = "grid@1"\nparams = { rows = 6, cols = 6 }\n'
                 '[nodes.noisy]\nop = "perturb@1"\ninputs = { mesh = "mesh.mesh" }\n'
                 'params = { tangential = 0.2, seed = 1, fix = "corners" }\n'
                 '[nodes.fair]\nop = "fair@1"\ninputs = { mesh = "noisy.mesh" }\nparams = { iterations = 3 }\n'
                 '[nodes.png]\nop = "render_png@1"\ninputs = { mesh = "noisy.mesh", mesh2 = "fair.mesh" }\n'
                 'params = { path = "f.png", size_px = 400, titles = ["noisy", "faired, {fair.iterations} iterations"] }\n')
    assert main(["run", str(g), "--out", str(tmp_path / "o"), "--set", "fair.iterations=5"]) == 0
    assert seen == [["noisy", "faired, 5 iterations"]]

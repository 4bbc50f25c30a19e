"""quadnodes.linalg.compiled: loading the kernels in the background (in a child process, so the
test process's own paths stay as they were)."""

import subprocess
import sys
import textwrap


def test_warm_up_loads_in_the_background_and_fair_uses_the_kernels_at_any_size_then():
    code = textwrap.dedent(
        """
        import numpy as np
        from quadnodes.linalg import compiled
        from quadnodes.linalg.cg import SymmetricDiagonalBlocks
        from quadnodes.fairing import FairingSystem
        from quadnodes.mesh import grid
        assert not compiled.ready()
        compiled.warm_up(); compiled.warm_up()  # once per process
        assert compiled.wait() and compiled.ready()
        from quadnodes._window_kernels import window_geometry  # other modules' kernels (also_load) came too
        assert len(window_geometry.signatures) == 1
        m = grid(60, 60)
        m = m.with_vertices(m.vertices + np.random.default_rng(1).normal(scale=0.1, size=m.vertices.shape))
        free = m.topology.window_middle.copy()
        s = FairingSystem(m.vertices, m.topology.windows, free, 0.3, solver="cg", _topology=m.topology)
        x = s.solve(m.vertices[free])
        assert isinstance(s._cg[0], SymmetricDiagonalBlocks)
        d = FairingSystem(m.vertices, m.topology.windows, free, 0.3, solver="direct").solve(m.vertices[free])
        assert abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
        print("ok")
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"

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
        assert len(window_geometry.signatures) == 3  # (read-only and writable arrays are typed apart)
        m = grid(60, 60)
        m = m.with_vertices(m.vertices + np.random.default_rng(1).normal(scale=0.1, size=m.vertices.shape))
        free = m.topology.window_middle.copy()
        s = FairingSystem(m.vertices, m.topology.windows, free, 0.3, solver="cg", _topology=m.topology)
        x = s.solve(m.vertices[free])
        assert isinstance(s._cg[0], SymmetricDiagonalBlocks)
        d = FairingSystem(m.vertices, m.topology.windows, free, 0.3, solver="direct").solve(m.vertices[free])
        assert abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
        # fair compiles nothing more once the load is done: every signature it uses was loaded (Numba types
        # read-only and writable arrays, strided and contiguous ones apart; a new one costs ~10 ms in the call)
        import quadnodes._window_kernels as wk
        from quadnodes import fair
        from quadnodes.linalg import _kernels
        from quadnodes.mesh import cylinder
        from quadnodes.noise import perturb
        kernels = [wk.window_geometry, wk.window_coefficients, _kernels.symmetric_diagonal_product,
                   _kernels.cg_update, _kernels.cg_direction, _kernels.row_dots, _kernels.grid_family,
                   _kernels.unit_backward_sweep, _kernels.unit_forward_sweep, _kernels.unit_cg_update,
                   _kernels.unit_scaled, _kernels.csr_backward_sweep, _kernels.csr_forward_sweep,
                   _kernels.rows_cg_update, _kernels.csr_separators]
        counts = [len(k.signatures) for k in kernels]
        noisy = perturb(m, jitter=0.2, seed=2)[0]
        for spacing in ("fair", "hold"):
            fair(noisy, iterations=2, threshold=0.0, line_spacing=spacing)
        fair(perturb(cylinder(12, 30), jitter=0.2, seed=2)[0], iterations=2)
        from quadnodes.mesh import QuadMesh  # no grid: Gauss–Seidel row by row
        p = np.random.default_rng(3).permutation(noisy.n_vertices)
        _, rep = fair(QuadMesh(noisy.vertices[p], np.argsort(p)[noisy.faces]), iterations=1, threshold=0.0)
        assert rep.iterations[0].solver == "cg"
        assert [len(k.signatures) for k in kernels] == counts, ([len(k.signatures) for k in kernels], counts)
        print("ok")
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_a_forked_child_loads_the_kernels_itself(monkeypatch):
    # after a fork the parent's loading thread does not exist in the child: _forget_thread (registered with
    # os.register_at_fork) drops it unless the kernels were loaded, so the child loads its own when asked
    import threading

    from quadnodes.linalg import compiled

    dead = threading.Thread(target=lambda: None)
    monkeypatch.setattr(compiled, "_THREAD", dead)
    monkeypatch.setattr(compiled, "_STATE", {"ready": False, "error": None})
    compiled._forget_thread()
    assert compiled._THREAD is None
    monkeypatch.setattr(compiled, "_THREAD", dead)
    monkeypatch.setattr(compiled, "_STATE", {"ready": True, "error": None})
    compiled._forget_thread()
    assert compiled._THREAD is dead  # loaded before the fork: kept


def test_other_modules_kernels_load_with_these_and_a_failing_one_leaves_the_numpy_paths():
    code = textwrap.dedent(
        """
        from quadnodes.linalg import compiled
        import quadnodes.reference, quadnodes.zigzag  # (register their kernels at import)
        calls = []
        compiled.also_load(lambda: calls.append(compiled.ready()))
        assert compiled.wait() and calls == [False]  # called before "ready"
        from quadnodes._reference_kernels import closest_on_candidates
        from quadnodes._window_kernels import window_coefficients, window_geometry
        # every signature fair and planarize use: read-only and writable arrays, strided and contiguous columns
        assert [len(k.signatures) for k in (closest_on_candidates, window_coefficients, window_geometry)] == [1, 2, 3]
        assert quadnodes.reference._compiled_kernel(1) is closest_on_candidates
        print("ok")
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
    code = textwrap.dedent(
        """
        from quadnodes.linalg import compiled
        import quadnodes.reference
        def broken():
            raise RuntimeError("no machine code")
        compiled.also_load(broken)
        assert not compiled.wait() and not compiled.ready()
        assert quadnodes.reference._compiled_kernel(10**7) is None  # the NumPy path
        print("ok")
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.errors import InputError
from quadnodes.fourier_descriptors import fourier, low_pass
from quadnodes.mesh import cylinder, grid, torus


def test_a_circle_stays_a_circle():
    c = cylinder(4, 24, radius=3.0)
    out, rep = fourier(c, keep=1)
    np.testing.assert_allclose(out.vertices, c.vertices, atol=1e-12)
    assert rep.closed_lines == 4 and rep.open_lines_untouched == 24 and "open" in rep.note


@settings(max_examples=25)
@given(st.integers(1, 5), st.integers(0, 2**31 - 1))
def test_noise_above_the_cut_is_removed_exactly(keep, seed):
    rng = np.random.default_rng(seed)
    L = 20
    c = cylinder(3, L)
    v = c.vertices.copy()
    for f in range(keep + 1, L // 2 + 1):  # every harmonic above the cut, random amplitude and phase
        amp, phase = rng.normal(size=3) * 0.05, rng.uniform(0, 2 * np.pi, 3)
        v += amp * np.cos(2 * np.pi * f * (np.arange(3 * L) % L)[:, None] / L + phase)
    out, rep = fourier(c.with_vertices(v), keep=keep)
    np.testing.assert_allclose(out.vertices, c.vertices, atol=1e-12)
    assert rep.removed_energy > 0


def test_low_harmonics_are_kept():
    L = 16
    t = 2 * np.pi * np.arange(L) / L
    s = np.stack([np.cos(t) + 0.1 * np.cos(2 * t), np.sin(t), 0.3 * np.sin(3 * t)], axis=1)[None]
    np.testing.assert_allclose(low_pass(s, 3), s, atol=1e-12)
    np.testing.assert_allclose(low_pass(s, 2)[0, :, 2], 0, atol=1e-12)


def test_torus_is_the_two_dimensional_low_pass():
    T = torus(12, 16)
    rng = np.random.default_rng(1)
    noisy = T.with_vertices(T.vertices + 0.02 * rng.normal(size=T.vertices.shape))
    out, rep = fourier(noisy, keep=2)
    assert rep.rounds == 2 and rep.closed_lines == 28 and rep.open_lines_untouched == 0
    grid_xyz = noisy.vertices.reshape(12, 16, 3)
    f = np.fft.fft2(grid_xyz, axes=(0, 1))
    fr = np.abs(np.fft.fftfreq(12, 1 / 12))
    fc = np.abs(np.fft.fftfreq(16, 1 / 16))
    f[(fr[:, None] > 2) | (fc[None, :] > 2)] = 0
    np.testing.assert_allclose(out.vertices, np.fft.ifft2(f, axes=(0, 1)).real.reshape(-1, 3), atol=1e-12)


def test_open_mesh_untouched_and_fixing():
    g = grid(4, 5)
    out, rep = fourier(g)
    assert np.array_equal(out.vertices, g.vertices) and rep.closed_lines == 0 and "no closed" in rep.note
    c = cylinder(3, 10)
    v = c.vertices.copy()
    v[:, 0] += 0.1 * (-1) ** np.arange(30)
    out, rep = fourier(c.with_vertices(v), keep=1, fixed=[0])
    assert np.array_equal(out.vertices[0], v[0]) and rep.n_fixed == 1
    with pytest.raises(InputError, match="keep"):
        fourier(c, keep=0)

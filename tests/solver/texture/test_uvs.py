"""Texture coordinates (solver/texture/uvs.py): per-vertex UVs into a photo (thesis §5) and
the UV raster kept with the model."""

import gc
import weakref
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from solver import OrthographicCamera, bake_texture
from solver.texture.uvs import clear_raster_cache, orthographic_uvs, uv_raster
from tests.solver.texture.support import H, W, coded_photo, uv_sphere


def test_orthographic_uvs_match_thesis_formula():
    w, h = 768, 1024
    cam = OrthographicCamera.nominal("orthographic-front", (w, h))
    pts = np.array([[0.0, 0.0, 0.0], [0.1, -0.05, 0.05], [-0.02, 0.3, -0.1]])
    uv = orthographic_uvs(pts, cam)
    np.testing.assert_allclose(uv[0], [0.5, 0.5])
    # eq. 48-49 with the nose-tip origin at pixel (U_n, V_n) = (w/2, h/2) and model
    # coordinates in image heights: Y = transverse (world x), X = up (world z).
    un, vn = w / 2, h / 2
    y_t = pts[:, 0] * cam.scale / h
    x_t = pts[:, 2] * cam.scale / h
    np.testing.assert_allclose(uv[:, 0], (un + y_t * h) / w)
    np.testing.assert_allclose(uv[:, 1], 1 - vn / h + x_t)
    # depth (world y) does not matter in a parallel projection
    assert uv[2, 0] == pytest.approx(0.5 - 0.02 * cam.scale / w)


def test_orthographic_uvs_rejects_bad_vertices():
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    with pytest.raises(ValueError, match="vertices"):
        orthographic_uvs(np.array([[0.0, np.nan, 0.0]]), cam)
    with pytest.raises(ValueError, match="vertices"):
        orthographic_uvs(np.zeros((3, 2)), cam)


def test_raster_is_cached_and_reusable():
    m = uv_sphere()
    r1 = uv_raster(m, 64)
    assert uv_raster(m, 64) is r1
    assert uv_raster(m, 32) is not r1
    # the sphere's UVs cover the unit square except half of each pole band
    assert abs(len(r1.texel) / 64**2 - (1 - 1 / 24)) < 0.02
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    a = bake_texture(m, m.vertices, [(coded_photo(), cam)], 64, raster=r1)
    b = bake_texture(m, m.vertices, [(coded_photo(), cam)], 64)
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="raster"):
        bake_texture(m, m.vertices, [(coded_photo(), cam)], 32, raster=r1)


def test_raster_is_kept_with_its_model_and_freed_with_it():
    m = uv_sphere()
    first = uv_raster(m, 32)
    clear_raster_cache(m)
    again = uv_raster(m, 32)
    assert again is not first
    np.testing.assert_array_equal(again.texel, first.texel)
    assert uv_raster(uv_sphere(), 32) is not again  # another model has rasters of its own
    gone = weakref.ref(again)
    del m, first, again
    gc.collect()
    assert gone() is None


def test_threads_share_one_raster():
    m = uv_sphere()
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda _: uv_raster(m, 48), range(8)))
    assert all(r is got[0] for r in got)


def test_gather_is_interp_transposed_without_a_copy():
    """``gather`` sums texel values onto the vertices through ``interp``'s own arrays (a
    stored transpose was 39 MB of a worker's rasters); ``cover`` is its row sums."""
    m = uv_sphere()
    r = uv_raster(m, 64)
    x = np.random.default_rng(0).random((len(r.texel), 3)).astype(np.float32)
    np.testing.assert_allclose(r.gather @ x, r.interp.toarray().T @ x, rtol=1e-5, atol=1e-6)
    assert r.gather.shape == (len(m.vertices), len(r.texel))
    assert np.shares_memory(r.gather.data, r.interp.data)
    np.testing.assert_allclose(r.cover, r.interp.toarray().sum(axis=0)[r.vertices], rtol=1e-5)
    assert r.texel.dtype == np.int32


def test_raster_is_stored_beside_the_model_file_and_loaded_bit_for_bit(tmp_path,
                                                                        monkeypatch):
    """The next process loads the raster its model's file has beside it instead of
    rasterising, and bakes the same texture bit for bit; a damaged file is built again."""
    from solver.texture import uvs

    m = uv_sphere()
    (tmp_path / "model").mkdir()
    m.path = str(tmp_path / "model" / "sphere.npz")
    (tmp_path / "model" / "sphere.npz").write_bytes(b"the model")
    built = uv_raster(m, 64)
    stored = list((tmp_path / "model-cache").glob("sphere-uv-raster-64-*.npz"))
    assert len(stored) == 1
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    want = bake_texture(m, m.vertices, [(coded_photo(), cam)], 64, raster=built)

    builds = []
    build = uvs._build_raster
    monkeypatch.setattr(uvs, "_build_raster", lambda *a: builds.append(a) or build(*a))
    clear_raster_cache(m)  # a new process: nothing in memory
    loaded = uv_raster(m, 64)
    assert not builds and loaded is not built
    for name in ("texel", "vertices", "cover", "triangles", "bleed_to", "bleed_from"):
        got, ref = getattr(loaded, name), getattr(built, name)
        assert got.dtype == ref.dtype
        np.testing.assert_array_equal(got, ref)
    assert (loaded.interp != built.interp).nnz == 0 and loaded.parts == built.parts
    np.testing.assert_array_equal(
        bake_texture(m, m.vertices, [(coded_photo(), cam)], 64, raster=loaded), want)

    clear_raster_cache(m)
    stored[0].write_bytes(stored[0].read_bytes()[:1000])
    np.testing.assert_array_equal(uv_raster(m, 64).texel, built.texel)
    assert len(builds) == 1
    clear_raster_cache(m, stored=True)
    assert not list((tmp_path / "model-cache").glob("*.npz"))

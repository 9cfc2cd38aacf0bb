"""Benchmark the head model: build time, file size, load time.

    python -m bench.bench_model

Builds the model from ICT-FaceKit into a temporary folder (the project's own model file
is left alone), then loads that file several times without the loader's cache. Targets:
build <= 2 min, file <= 30 MB, load <= 0.3 s.
"""

import tempfile
import time
from pathlib import Path

from bench.common import machine_description, median_time
from solver.model import head_model as model_module
from tools import build_model


def _load_uncached(path):
    model_module._cache.clear()  # the loader caches per path; time the real read
    m = model_module.load_model(path)
    # Expressions are decoded on first use: count them, every fitted head needs them.
    if m.expressions.shape[1] != m.n_vertices:
        raise RuntimeError("expressions do not match the mesh")
    return m


def main():
    print("bench_model: head model build, size and load")
    print(f"machine: {machine_description()}")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "head_model.npz"
        t0 = time.perf_counter()
        build_model.build(out_path=out, log=lambda *a, **k: None)
        build_s = time.perf_counter() - t0
        size_mb = out.stat().st_size / 1e6
        t = median_time(lambda: _load_uncached(out), repeats=7, warmup=1)
        m = t.result
        print(f"build: {build_s:.2f} s (target <= 120 s)")
        print(f"file: {size_mb:.1f} MB (target <= 30 MB)")
        print(f"load (with the expressions decoded): median {t.median:.3f} s, "
              f"min {t.min:.3f}, max {t.max:.3f} (target <= 0.3 s); {m.n_vertices} vertices, "
              f"{m.identity.n_coeffs} identity modes, {len(m.region_names)} regions")
    model_module._cache.clear()


if __name__ == "__main__":
    main()

"""What the benchmarks share: a line describing the machine, timing and memory (the
accuracy of a fitted head is ``solver.synthetic.skin_error_mm``, which the tests use too).

    from bench.common import machine_description, max_rss_mb, median_time, peak_memory

    print(f"machine: {machine_description()}")  # load_average() alone after a long run
    t = median_time(lambda: work(case), repeats=7, warmup=1)
    print(f"work: median {t.median:.3f} s (min {t.min:.3f}, max {t.max:.3f}; "
          f"CPU {t.cpu_median:.3f} s)")           # t.result: the last run's return value
    result, peak = peak_memory(lambda: work(case))  # bytes allocated at the peak
    print(f"peak {peak / 2**20:.0f} MiB, process {max_rss_mb():.0f} MB")

Benchmarks print numbers and assert nothing: wall times on a shared machine vary with its
load, which ``machine_description`` reports with the core count and library versions.
"""

import dataclasses
import json
import os
import platform
import resource
import statistics
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np


def cpu_model():
    """The CPU's model name (from /proc/cpuinfo on Linux)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def load_average():
    """The 1, 5 and 15 minute load averages as text ("n/a" where unknown)."""
    if not hasattr(os, "getloadavg"):
        return "n/a"
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


def machine_description():
    """One line: CPU, cores (logical and usable by this process), load average, Python,
    numpy and scipy versions, BLAS threads, and Blender's version when bpy is imported."""

    parts = [cpu_model()]
    cores = f"{os.cpu_count()} logical cores"
    if hasattr(os, "sched_getaffinity"):
        cores += f" ({len(os.sched_getaffinity(0))} usable)"
    parts.append(cores)
    parts.append(f"load average {load_average()}")
    libs = f"Python {platform.python_version()}, numpy {np.__version__}"
    try:
        import scipy

        libs += f", scipy {scipy.__version__}"
    except ImportError:
        pass
    parts.append(libs)
    parts.append(f"BLAS threads {os.environ.get('OPENBLAS_NUM_THREADS', 'library default')}")
    if "bpy" in sys.modules:
        parts.append(f"Blender {sys.modules['bpy'].app.version_string}")
    return "; ".join(parts)


@dataclasses.dataclass(frozen=True)
class Timing:
    """Timed runs of one function: wall and process CPU seconds (all threads) per run."""

    wall: tuple
    cpu: tuple
    result: object  # what the last run returned

    @property
    def median(self):
        return statistics.median(self.wall)

    @property
    def min(self):
        return min(self.wall)

    @property
    def max(self):
        return max(self.wall)

    @property
    def cpu_median(self):
        return statistics.median(self.cpu)


def median_time(fn, repeats=5, warmup=1):
    """Call ``fn()`` ``warmup`` times untimed (caches, lazy imports), then ``repeats`` times
    timed. Returns a :class:`Timing` (``.median``, ``.min``, ``.max`` seconds)."""
    if repeats < 1:
        raise ValueError(f"repeats: at least 1 timed run, got {repeats}")
    for _ in range(warmup):
        fn()
    wall, cpu = [], []
    result = None
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        result = fn()
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    return Timing(tuple(wall), tuple(cpu), result)


def peak_memory(fn):
    """Call ``fn()`` under ``tracemalloc``: returns (its result, the peak bytes of Python
    and numpy allocations made during the call; memory held before it is not counted)."""
    tracemalloc.start()
    try:
        result = fn()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return result, peak


def max_rss_mb():
    """Peak resident memory of this process so far (everything it loaded), MB."""
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / (2**20 if sys.platform == "darwin" else 1024.0)  # bytes on macOS, else KiB


def option_values(pairs):
    """FitOptions fields from ``--set NAME=VALUE`` strings (the value read as JSON, else
    kept as a string); an unknown name stops the benchmark, naming it."""
    from solver import FitOptions

    out = {}
    for pair in pairs:
        name, _, text = pair.partition("=")
        if name not in FitOptions.__dataclass_fields__:
            raise SystemExit(f"--set {pair}: FitOptions has no field {name!r}")
        try:
            out[name] = json.loads(text)
        except json.JSONDecodeError:
            out[name] = text
    return out

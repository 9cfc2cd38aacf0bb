"""The C heap's free memory goes back to the system (glibc)."""

import sys
from pathlib import Path

import numpy as np
import pytest

from headrecon_addon import heap


def _resident_mb():
    line = next(x for x in Path("/proc/self/status").read_text().splitlines()
                if x.startswith("VmRSS"))
    return int(line.split()[1]) / 1024


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim")
def test_freed_heap_memory_is_given_back():
    # 200 MB in heap-sized pieces (64 kB, below glibc's mmap threshold), every other one
    # freed: the holes stay resident, glibc cannot shrink a heap whose top is in use
    pieces = [np.ones(8192) for _ in range(3200)]
    del pieces[::2]
    before = _resident_mb()
    assert heap.release_free_memory()
    assert _resident_mb() < before - 50

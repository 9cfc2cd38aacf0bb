"""How many cores this process may use: its CPU affinity where the system keeps one (a
container or ``taskset`` may allow fewer than the machine has), else the machine's count.
Threads and worker processes are sized by it."""

import os


def usable_cores():
    """The number of cores this process may run on (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1

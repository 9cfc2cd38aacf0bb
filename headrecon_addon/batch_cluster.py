"""A batch on a Dask distributed cluster (``--cluster ADDRESS``, or ``local`` for a
one-machine cluster of ``--jobs`` worker processes started here and shut down at the end).

Dask is an optional extra, never bundled with the extension: it is imported only when
``--cluster`` is given (``pip install "dask[distributed]==2024.8.2"`` next to the bpy
module). The cluster runs the very tasks the local workers run: each is a task dict of
``headless._tasks`` handed to :func:`run_head`, which calls ``batch_head.run_task`` (fit,
outputs written atomically through a hidden staging folder, the record last) and returns
the summary row; the client streams the rows as they finish, into the same summaries,
progress line and resume records as a local batch.

The model is loaded once per Dask worker process, not sent per task: bpy must run on a
process's main thread and a Dask task runs on a thread of the worker's pool, so each Dask
worker keeps one HeadRecon worker process (``batch_workers``, the one ``--jobs`` starts:
``headless --worker``, or Blender running ``headless.py`` when the client is Blender),
started at its first head; it loads the model from the file once and fits every head the
Dask worker is given (a cache in this module keyed by the model file's path and that
command). The Dask worker itself never imports bpy (this module and the ones it uses do
not): only the process it drives does. Every worker therefore needs the repository (on
``PYTHONPATH``), the client's worker command (the bpy module's Python, or Blender) and
the model file at the client's paths (or ``HEADRECON_MODEL``), and the inputs and ``OUT``
at the same paths as the client (a shared file system): the tasks carry paths, not data.
"""

import atexit
import logging
import subprocess
import sys
import threading
from contextlib import contextmanager

INSTALL = 'pip install "dask[distributed]==2024.8.2"'

#: Dask's nanny gives its worker processes ``MALLOC_TRIM_THRESHOLD_=65536`` (its config
#: ``distributed.nanny.pre-spawn-environ``); inherited by the fitting process, glibc hands
#: every freed block back and faults it in again: 6.0-6.4 CPU s a head instead of 3.6-3.9
#: (``bench_batch_stages``). The fitting process trims its heap itself (``heap.py``).
DASK_MALLOC_VARIABLE = "MALLOC_TRIM_THRESHOLD_"

_fitters = {}  # (model path, command) -> this process's HeadRecon worker (batch_workers)
_loads = {}  # model path -> HeadRecon workers started (each loads the model once)
_lock = threading.Lock()


def distributed():
    """The ``dask.distributed`` module, or ``ValueError`` in one line saying how to install
    it."""
    try:
        import dask.distributed as dd
    except ImportError as e:
        raise ValueError(f"--cluster needs Dask distributed, which is not installed ({e}); "
                         f"install it with: {INSTALL}") from None
    return dd


def model_path():
    """The model file this process would load (``HEADRECON_MODEL`` or the default)."""
    from .solver_link import solver_module

    return str(solver_module("paths").model_path().resolve())


def _fitter(path, command):
    """This Dask worker's HeadRecon worker process for the model ``path``, started with
    ``command`` (and the model loaded in it) on first use only."""
    from . import batch_workers

    fitter = _fitters.get((path, tuple(command)))
    if fitter is None:
        env = batch_workers.worker_env(HEADRECON_MODEL=path)
        env.pop(DASK_MALLOC_VARIABLE, None)
        fitter = _fitters[path, tuple(command)] = batch_workers._Worker(list(command), env)
        _loads[path] = _loads.get(path, 0) + 1
    return fitter


@atexit.register
def _close_fitters():
    """End this worker's HeadRecon worker with it (its input closed: it stops)."""
    for fitter in list(_fitters.values()):
        fitter.close()
    _fitters.clear()


def model_loads():
    """How many times this process had the model of each file loaded (``client.run`` asks
    the workers; the tests count them)."""
    return dict(_loads)


def run_head(task, path, command):
    """A cluster task: one head of the batch on this worker's HeadRecon worker (the summary
    row). bpy must run on a process's main thread, and a Dask task runs on a thread of the
    worker's pool, so the head goes to the very worker process a local ``--jobs`` batch
    uses (``command``, the client's ``batch_workers.worker_command()``: ``batch_head.run_task``, the
    same code), kept for the worker's life. A head that kills it fails alone; the next
    head starts a new one."""
    from . import batch_summary

    with _lock:
        fitter = _fitter(path, command)
        answer = fitter.ask(task) if fitter.ready else None
        if answer is None:
            _fitters.pop((path, tuple(command)), None)
            return batch_summary.worker_died_row(task, fitter.close())
        return answer


#: Seconds a worker of the local cluster waits for the scheduler to come back before it ends
#: (so a killed batch leaves no worker behind for long).
DEATH_TIMEOUT = 60


def worker_command(address, name):
    """The ``dask worker`` command of one worker process (one thread) for ``address``."""
    return [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
            "--nworkers", "1", "--name", name, "--no-dashboard",
            "--death-timeout", str(DEATH_TIMEOUT)]


@contextmanager
def local_cluster(jobs, timeout=300):
    """A scheduler in this process and ``jobs`` ``dask worker`` processes (one thread
    each) of this Python, the repository on their path: the same as a real cluster's
    commands, on one machine. The workers are separate processes, not forks or
    multiprocessing children of this one (whose ``sys.path`` holds Blender's script
    folders once bpy is imported, which breaks ``import bpy`` in a spawned child). Yields
    the scheduler's address; the workers are stopped on leaving."""
    from . import batch_workers

    dd = distributed()
    env = batch_workers.worker_env()
    env.setdefault("DASK_LOGGING__DISTRIBUTED", "error")
    with dd.LocalCluster(n_workers=0, processes=False, protocol="tcp://", host="127.0.0.1",
                         dashboard_address=None,
                         silence_logs=logging.ERROR) as cluster:
        procs = []
        try:
            for i in range(int(jobs)):
                procs.append(subprocess.Popen(
                    worker_command(cluster.scheduler_address, f"headrecon-{i}"), env=env,
                    stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL))
            yield cluster.scheduler_address, procs
        finally:
            stop_processes(procs)


def stop_processes(procs, timeout=30):
    """Ask the processes to end, then wait for each, killing any that takes longer than
    ``timeout`` seconds."""
    for proc in procs:
        proc.terminate()
    for proc in procs:
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@contextmanager
def client_for(address, jobs, timeout=300):
    """A Dask client of the cluster at ``address`` (``tcp://host:8786``, or a scheduler
    file ``*.json``), or of a local cluster of ``jobs`` worker processes when ``address``
    is "local" (started here, waited for, and shut down on leaving)."""
    dd = distributed()
    if address == "local":
        with local_cluster(jobs) as (scheduler, _), dd.Client(scheduler) as client:
            client.wait_for_workers(int(jobs), timeout=timeout)
            yield client
    elif address.endswith(".json"):
        with dd.Client(scheduler_file=address, timeout="30s") as client:
            yield client
    else:
        with dd.Client(address, timeout="30s") as client:
            yield client


def run_cluster(tasks, client, died):
    """Run ``tasks`` on the cluster of ``client``; yield (task, summary row) as each
    finishes. ``died(task, message)``: the row of a task the cluster could not run (its
    worker died more than the scheduler allows, or the task could not be sent)."""
    from . import batch_workers

    dd = distributed()
    path, command = model_path(), batch_workers.worker_command()
    futures = {client.submit(run_head, task, path, command,
                             key=f"head-{task['index']}-{task['name']}", pure=False): task
               for task in tasks}
    for future in dd.as_completed(futures):
        task = futures.pop(future)
        try:
            row = future.result()
        except Exception as e:  # KilledWorker and the like: this head only
            row = died(task, f"{type(e).__name__}: {e}")
        yield task, row


def loads_per_worker(client):
    """Worker address -> {model path: times loaded} of every worker of ``client``."""
    return client.run(model_loads)

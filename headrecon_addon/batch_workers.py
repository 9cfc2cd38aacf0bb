"""Worker processes of a batch: each one a Python (or Blender) process that loads the model
once and then fits heads sent to it, one at a time, until its input ends.

The parent sends a task as one JSON line on the worker's stdin and reads the worker's
answer, one JSON line, on its stdout. The worker keeps the original stdout for answers
only and points its file descriptor 1 at stderr, so whatever Blender prints goes to the
log, never into the answers. Each worker gets one BLAS thread (``blas_threads``) unless
the environment sets its thread count. A thread per worker takes the next task as soon as its worker
answers, so results stream in the order they finish. A worker that dies (killed, out of
memory) fails the head it had; the next task starts a new worker.
"""

import json
import os
import queue
import subprocess
import sys
import threading
from pathlib import Path

from . import blas_threads

PACKAGE_ROOT = Path(__file__).resolve().parent.parent


def worker_env(**extra):
    """The environment of a worker process (this one's, plus ``extra``): the repository
    on its path, one BLAS thread unless this environment sets the count."""
    env = dict(os.environ, **extra)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(PACKAGE_ROOT)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    return blas_threads.environment(env)


def worker_command():
    """The command that starts a worker: Blender running ``headless.py`` when this is the
    Blender binary, else this Python with ``-m headrecon_addon.headless`` (the bpy
    module, which this process need not have imported)."""
    bpy = sys.modules.get("bpy")  # always there in Blender
    if bpy is not None and bpy.app.binary_path:  # empty for the bpy module
        script = Path(__file__).resolve().with_name("headless.py")
        return [bpy.app.binary_path, "-b", "--factory-startup", "-P", str(script), "--",
                "--worker"]
    return [sys.executable, "-m", f"{__package__}.headless", "--worker"]


def serve(handle):
    """The worker's loop: read a task a line from stdin, answer ``handle(task)`` as one
    JSON line; stop at the end of the input."""
    answers = os.fdopen(os.dup(1), "w", encoding="utf-8", buffering=1)
    sys.stdout.flush()
    os.dup2(2, 1)  # Blender's own prints go to stderr from here on
    print(json.dumps({"ready": True}), file=answers, flush=True)
    for line in sys.stdin:
        if line.strip():
            print(json.dumps(handle(json.loads(line))), file=answers, flush=True)


class _Worker:
    def __init__(self, command, env):
        self.proc = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     env=env, text=True, encoding="utf-8", bufsize=1)
        self.ready = self._read()

    def _read(self):
        line = self.proc.stdout.readline()
        return json.loads(line) if line else None

    def ask(self, task):
        """The worker's answer to ``task``, or None when it died."""
        try:
            self.proc.stdin.write(json.dumps(task) + "\n")
            self.proc.stdin.flush()
        except OSError:
            return None
        return self._read()

    def close(self):
        try:
            self.proc.stdin.close()
        except OSError:
            pass
        return self.proc.wait()


def run_pool(tasks, jobs, died, command=None):
    """Run ``tasks`` on ``jobs`` worker processes; yield (task, answer) as each finishes.

    Parameters
    ----------
    tasks : list of dict
        JSON-able tasks.
    jobs : int
        Worker processes (at most one per task).
    died : callable (task, exit code) -> answer
        The answer for a task whose worker ended before answering.
    command : list of str, optional
        The worker command (default ``worker_command()``).
    """
    command = command or worker_command()
    env = worker_env()
    todo, done = queue.Queue(), queue.Queue()
    for t in tasks:
        todo.put(t)

    def drive():
        worker = None
        try:
            while True:
                try:
                    task = todo.get_nowait()
                except queue.Empty:
                    break
                if worker is None:
                    worker = _Worker(command, env)
                answer = worker.ask(task) if worker.ready else None
                if answer is None:
                    done.put((task, died(task, worker.close())))
                    worker = None
                else:
                    done.put((task, answer))
        finally:
            if worker is not None:
                worker.close()
            done.put(None)

    threads = [threading.Thread(target=drive, daemon=True)
               for _ in range(max(1, min(int(jobs), len(tasks))))]
    for t in threads:
        t.start()
    running = len(threads)
    while running:
        item = done.get()
        if item is None:
            running -= 1
        else:
            yield item

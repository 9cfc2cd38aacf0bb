"""What a batch tells about its heads: one summary row per head (``summary.csv`` and
``summary.jsonl`` in the output folder, rewritten atomically as heads finish) and the
progress line (done, failed, rate, time left)."""

import csv
import io
import json
import time

FIELDS = ("name", "status", "error", "method", "rms_px", "noise_px", "plausibility",
          "warnings", "seconds", "outputs", "input")
STATUSES = ("done", "skipped", "failed")  # skipped: unchanged since a previous batch


def failed_row(name, where, message, seconds=0.0):
    """The summary row of a head that could not be written."""
    return {"name": name, "status": "failed", "error": message, "method": None,
            "rms_px": None, "noise_px": None, "plausibility": None, "warnings": [],
            "seconds": round(seconds, 3), "outputs": {}, "input": where}


def worker_died_row(task, code):
    """The summary row of a head whose worker process ended (exit ``code``) before
    answering."""
    return failed_row(task["name"], task["where"],
                      f"{task['where']}: the worker process ended (exit code {code}) while "
                      "fitting it")


def _cell(value):
    if value is None:
        return ""
    if isinstance(value, dict):
        return ";".join(f"{k}={v}" for k, v in value.items())
    if isinstance(value, list):
        return " | ".join(map(str, value))
    return value


def summary_texts(rows):
    """(csv text, jsonl text) of the summary rows, in the order given."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=FIELDS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: _cell(row.get(k)) for k in FIELDS})
    jsonl = "".join(json.dumps({k: row.get(k) for k in FIELDS}) + "\n" for row in rows)
    return buf.getvalue(), jsonl


def write_summaries(folder, rows):
    """Write ``folder/summary.csv`` and ``folder/summary.jsonl`` as one atomic set."""
    from .solver_link import solver_module

    atomic = solver_module("io.atomic")
    text_csv, text_jsonl = summary_texts(rows)
    atomic.write_files_atomic({folder / "summary.csv": text_csv,
                               folder / "summary.jsonl": text_jsonl})


def _clock(seconds):
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    return f"{h}h{rest // 60:02d}m" if h else f"{rest // 60}m{rest % 60:02d}s"


class Progress:
    """Counts of a running batch and the line that reports them: heads finished of the
    total, failed, skipped, the rate of heads fitted per minute (skipped ones left out) and
    the time left at that rate."""

    def __init__(self, total, clock=time.monotonic):
        self.total, self.clock = total, clock
        self.start = clock()
        self.counts = dict.fromkeys(STATUSES, 0)
        self.fitted = 0

    def add(self, status, fitted=True):
        """Count one finished head of ``status`` (one of ``STATUSES``); ``fitted``: it was
        run in this batch (the rate counts those only, not rows refused or skipped)."""
        self.counts[status] += 1
        self.fitted += bool(fitted) and status != "skipped"

    def line(self):
        """E.g. ``12/50 heads, 1 failed, 0 skipped, 9.8 heads/min, 3m53s left``."""
        done = sum(self.counts.values())
        minutes = max(self.clock() - self.start, 1e-9) / 60.0
        rate = self.fitted / minutes
        left = self.total - done
        eta = _clock(60.0 * left / rate) if rate > 0 else "?"
        return (f"{done}/{self.total} heads, {self.counts['failed']} failed, "
                f"{self.counts['skipped']} skipped, {rate:.1f} heads/min, {eta} left")

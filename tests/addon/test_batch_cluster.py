"""The batch on a Dask distributed cluster (``--cluster local``: a scheduler here and two
``dask worker`` processes; a scheduler started apart, reached by its file or its address):
the same outputs and summary rows as ``--jobs 2``, a broken row reported alone, the model
loaded once per worker, a clear line without Dask."""

import json
import subprocess
import sys
import time

import pytest

from tests.addon.support import ROOT, run_python, synthetic_files

pytest.importorskip("distributed", reason="--cluster needs dask[distributed]")


@pytest.fixture(scope="module")
def heads(model, tmp_path_factory):
    folder = tmp_path_factory.mktemp("cluster_heads")
    for i in range(3):
        synthetic_files(model, folder, seed=60 + i, name=f"c{i}")
    manifest = folder / "heads.csv"
    manifest.write_text("name,landmarks,components\nc0,c0.json,10\nc1,c1.json,10\n"
                        "broken,missing.json,10\nc2,c2.json,10\n")
    return manifest


def _rows(out):
    return {r["name"]: r for r in map(json.loads, (out / "summary.jsonl").read_text()
                                      .splitlines())}


def _same(row):
    """A summary row without what differs between runs (time, the output folder)."""
    return {k: v for k, v in row.items() if k not in ("seconds", "outputs")} | {
        "outputs": {k: p.rsplit("/", 1)[-1] for k, p in row["outputs"].items()}}


def test_local_cluster_matches_jobs_2(heads, tmp_path):
    args = [heads, "--no-texture", "--force", "--jobs", "2"]
    local = run_python(["-m", "headrecon_addon.headless", *args, "--out", tmp_path / "jobs"])
    cluster = run_python(["-m", "headrecon_addon.headless", *args, "--out",
                          tmp_path / "cluster", "--cluster", "local"])
    for proc in (local, cluster):
        assert proc.returncode == 1, proc.stderr  # the broken row
        assert "3 of 4 heads written" in proc.stdout
        assert "4/4 heads, 1 failed, 0 skipped" in proc.stderr
    # two workers, each loaded the model once for its heads
    assert "cluster: 2 workers, the model loaded 1/1 times on them" in cluster.stderr
    a, b = _rows(tmp_path / "jobs"), _rows(tmp_path / "cluster")
    assert list(a) == list(b) == ["c0", "c1", "broken", "c2"]  # manifest order
    assert {n: _same(r) for n, r in a.items()} == {n: _same(r) for n, r in b.items()}
    assert b["broken"]["status"] == "failed" and "missing.json" in b["broken"]["error"]
    out = tmp_path / "cluster"
    for name in ("c0", "c1", "c2"):
        assert b[name]["status"] == "done"
        assert (out / f"{name}.blend").is_file() and (out / f"{name}.batch.json").is_file()
    assert not list(out.glob(".*"))  # no staging folder left

    # resuming works the same through the cluster: nothing changed, nothing fitted
    again = run_python(["-m", "headrecon_addon.headless", heads, "--no-texture", "--out",
                        out, "--cluster", "local", "--jobs", "2"])
    assert again.returncode == 1 and "(3 unchanged, skipped)" in again.stdout


def test_cluster_from_the_blender_script_form(heads, tmp_path):
    """``blender -b -P headless.py -- ... --cluster local``: the same path taken with plain
    Python and "--" (as test_headless does for the script form). The Dask workers are
    this Python and import no bpy; the fitting processes are the client's worker command
    (Blender itself under Blender)."""
    out = tmp_path / "script"
    proc = run_python([ROOT / "headrecon_addon" / "headless.py", "--", heads, "--out", out,
                       "--no-texture", "--cluster", "local", "--jobs", "2"], cwd=tmp_path,
                      env={"PYTHONPATH": ""})
    assert proc.returncode == 1, proc.stdout + proc.stderr  # the broken row only
    assert "3 of 4 heads written" in proc.stdout
    assert "cluster: 2 workers, the model loaded 1/1 times on them" in proc.stderr
    assert {r["name"]: r["status"] for r in _rows(out).values()} == {
        "c0": "done", "c1": "done", "broken": "failed", "c2": "done"}


@pytest.fixture
def scheduler(tmp_path):
    """A Dask scheduler started as its own process (``dask scheduler --scheduler-file``,
    as on a cluster's head node) and two ``dask worker`` processes joined to it through
    its file: (scheduler file, its tcp:// address)."""
    from headrecon_addon import batch_cluster, batch_workers

    file = tmp_path / "scheduler.json"
    env = batch_workers.worker_env(DASK_LOGGING__DISTRIBUTED="error")
    quiet = {"env": env, "stdin": subprocess.DEVNULL, "stdout": subprocess.DEVNULL,
             "stderr": subprocess.DEVNULL}
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler",
                               "--scheduler-file", str(file), "--host", "127.0.0.1",
                               "--port", "0", "--dashboard-address", ":0"], **quiet)]
    try:
        deadline = time.monotonic() + 60
        while not (file.is_file() and file.read_text().strip().endswith("}")):
            assert time.monotonic() < deadline and procs[0].poll() is None, \
                "the scheduler did not start"
            time.sleep(0.2)
        address = json.loads(file.read_text())["address"]
        procs += [subprocess.Popen(batch_cluster.worker_command(address, f"remote-{i}"),
                                   **quiet) for i in range(2)]
        yield file, address
    finally:
        batch_cluster.stop_processes(procs)


def test_a_scheduler_of_its_own_by_file_and_by_address(heads, scheduler, tmp_path):
    """``--cluster sched.json`` and ``--cluster tcp://host:port``: a scheduler this batch
    did not start, with the workers a cluster would have; the same heads as ``--jobs 2``,
    and the model loaded once per worker over both batches."""
    file, address = scheduler
    assert address.startswith("tcp://127.0.0.1:")
    local = run_python(["-m", "headrecon_addon.headless", heads, "--no-texture", "--force",
                        "--jobs", "2", "--out", tmp_path / "jobs"])
    assert local.returncode == 1, local.stderr
    for where, out in ((file, "by_file"), (address, "by_address")):
        proc = run_python(["-m", "headrecon_addon.headless", heads, "--no-texture",
                           "--force", "--out", tmp_path / out, "--cluster", where])
        assert proc.returncode == 1, proc.stdout + proc.stderr  # the broken row only
        assert "3 of 4 heads written" in proc.stdout
        assert "cluster: 2 workers, the model loaded 1/1 times on them" in proc.stderr
        rows = _rows(tmp_path / out)
        assert {n: _same(r) for n, r in rows.items()} == \
            {n: _same(r) for n, r in _rows(tmp_path / "jobs").items()}
        assert all((tmp_path / out / f"c{i}.blend").is_file() for i in range(3))


def test_a_dead_worker_process_fails_its_head_only(monkeypatch):
    from headrecon_addon import batch_cluster

    monkeypatch.setattr(batch_cluster, "_fitters", {})
    task = {"name": "x", "where": "heads.csv row 2"}
    row = batch_cluster.run_head(task, "/no/model.npz",
                                 [sys.executable, "-c", "import sys; sys.exit(3)"])
    assert row["status"] == "failed" and "exit code 3" in row["error"]
    assert batch_cluster._fitters == {}  # the next head starts a new one


def test_the_fitting_process_does_not_inherit_dask_s_malloc_setting(monkeypatch):
    """Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers; in the fitting process it
    cost 60 % more CPU a head, so the process a Dask worker drives runs without it."""
    from headrecon_addon import batch_cluster

    monkeypatch.setattr(batch_cluster, "_fitters", {})
    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "65536")
    speaks = ("import json, os; print(json.dumps({'ready': True}), flush=True); input(); "
              "print(json.dumps({'malloc': os.environ.get('MALLOC_TRIM_THRESHOLD_', 'unset')}),"
              " flush=True)")
    got = batch_cluster.run_head({"name": "x", "where": "row 2"}, "/no/model.npz",
                                 [sys.executable, "-c", speaks])
    batch_cluster._close_fitters()
    assert got == {"malloc": "unset"}


def test_a_dask_worker_does_not_import_bpy():
    """What a Dask worker imports to run a head (this module, the worker pool, the summary
    rows) leaves bpy to the fitting process it drives."""
    proc = run_python(["-c", "import sys, headrecon_addon.batch_cluster, "
                       "headrecon_addon.batch_workers, headrecon_addon.batch_summary; "
                       "print('bpy' in sys.modules)"])
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "False"


def test_without_dask_one_line(monkeypatch):
    from headrecon_addon import batch_cluster

    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    with pytest.raises(ValueError, match=r"--cluster needs Dask distributed.*pip install"):
        batch_cluster.distributed()

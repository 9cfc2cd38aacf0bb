"""Where a batch worker's time and memory go: one process runs ``batch_head.write_head`` (the
code a ``--jobs`` worker runs per head) on a few synthetic heads and times each stage.

    python -m bench.bench_batch_stages [--heads 4] [--texture-size 1024] [--outputs blend]
                                       [--blas-threads 1]

Printed: the process's start (importing bpy and the add-on, loading the model), then per
head its wall and CPU seconds by stage (reading the landmarks and photos, the fit, the
texture bake; the scene: a fresh one, the head's mesh, its shape keys, the photo planes,
the rest of the scene; the .blend save, the game export (``--outputs blend,glb``), the
record, the rest of ``write_head``), the resident
memory after the head and the peak so far (Linux: ``/proc/self/status``). The heads are
made in a child process, so this one holds what a worker holds. The first
head also fills the caches a worker keeps (UV rasters, the fit's model copies), so the heads
after it are what a long batch costs per head.
"""

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench.blas_threads import parser, script_args  # noqa: E402


def _parse():
    p = parser("bench_batch_stages", __doc__)
    p.add_argument("--heads", type=int, default=4)
    p.add_argument("--texture-size", type=int, default=1024)
    p.add_argument("--outputs", default="blend",
                   help="the outputs a head writes, as the batch's --outputs (e.g. blend,glb)")
    return p.parse_args()


ARGS = script_args(_parse, __name__)


def memory_mb():
    """(resident, peak resident) MB of this process, (0, 0) where /proc is missing."""
    try:
        fields = dict(line.split(":", 1) for line in
                      Path("/proc/self/status").read_text().splitlines() if ":" in line)
    except OSError:
        return 0, 0
    return (int(fields["VmRSS"].split()[0]) // 1024, int(fields["VmHWM"].split()[0]) // 1024)


class Stages:
    """Wall and CPU seconds per stage of the current head, from wrapped functions; a
    wrapped call inside another is taken out of the outer one's time."""

    def __init__(self):
        self.times, self._stack = {}, []

    def wrap(self, module, name, stage):
        inner = getattr(module, name)

        def timed(*args, **kwargs):
            t, c = time.perf_counter(), time.process_time()
            self._stack.append([0.0, 0.0])
            try:
                return inner(*args, **kwargs)
            finally:
                wall, cpu = time.perf_counter() - t, time.process_time() - c
                nested = self._stack.pop()
                if self._stack:
                    self._stack[-1][0] += wall
                    self._stack[-1][1] += cpu
                got = self.times.setdefault(stage, [0.0, 0.0])
                got[0] += wall - nested[0]
                got[1] += cpu - nested[1]

        setattr(module, name, timed)


def main(args):
    t0, c0 = time.perf_counter(), time.process_time()
    import bpy  # noqa: F401

    t1, c1 = time.perf_counter(), time.process_time()
    from headrecon_addon import (
        batch_head,
        batch_manifest,
        batch_stamp,
        case_to_scene,
        export,
        head_scene,
        headless,
        reference_head,
        result_to_scene,
        shape_keys,
    )

    t2, c2 = time.perf_counter(), time.process_time()
    model = headless.load_model()
    t3, c3 = time.perf_counter(), time.process_time()
    from bench.common import load_average, machine_description

    print(f"machine: {machine_description()}")
    print(f"start: import bpy {t1 - t0:.2f} s (CPU {c1 - c0:.2f}), the add-on {t2 - t1:.2f} "
          f"({c2 - c1:.2f}), the model {t3 - t2:.2f} ({c3 - c2:.2f}); "
          f"{memory_mb()[0]} MB resident")
    stages = Stages()
    for module, name, stage in (
            (batch_head, "load_landmarks", "read"), (head_scene, "images_for", "read"),
            (batch_head, "fit_head", "fit"), (batch_head, "bake_fit_texture", "bake"),
            (head_scene, "reset_scene", "fresh"),
            (head_scene, "build_scene_from_fit", "scene"),
            (case_to_scene, "build_view_planes", "planes"),
            (reference_head, "new_head_object", "mesh"),
            (shape_keys, "write_fit_keys", "keys"),
            (result_to_scene, "write_textures", "scene"),
            (head_scene, "save_blend", "save"),
            (export, "export_head", "export"),
            (batch_stamp, "write_record", "record"),
            (batch_head, "write_head", "other")):
        stages.wrap(module, name, stage)
    settings = {"outputs": args.outputs.split(","), "bake": True, "texture_size": args.texture_size,
                "texture_shading": "keep", "bake_identity": False, "morph_normals": False,
                "method": None, "components": None, "regional": None, "exact": False}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "in").mkdir()
        subprocess.run([sys.executable, "-c", "import sys; from pathlib import Path; "
                        "from bench.bench_batch import make_heads; "
                        "make_heads(Path(sys.argv[1]), int(sys.argv[2]))",
                        str(folder / "in"), str(args.heads)], cwd=ROOT, check=True,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)))
        manifest = folder / "in" / "heads.csv"
        heads = batch_manifest.plan_heads([manifest], folder / "out")
        _, tasks = headless._tasks(heads, settings, True)
        order = ["read", "fit", "bake", "fresh", "mesh", "keys", "planes", "scene", "save",
                 "export", "record", "other"]
        print("head      " + " ".join(f"{s:>6s}" for s in order) + "    all    MB  peak")
        for i, task in enumerate(tasks):
            stages.times.clear()
            t, c = time.perf_counter(), time.process_time()
            row = batch_head.run_task(task, model)
            wall, cpu = time.perf_counter() - t, time.process_time() - c
            if row["status"] != "done":
                raise SystemExit(f"head {i}: {row['error']}")
            rss, peak = memory_mb()
            for k, label in ((0, "wall"), (1, "CPU ")):
                cells = " ".join(f"{stages.times.get(s, (0, 0))[k]:6.2f}" for s in order)
                total = wall if k == 0 else cpu
                mem = f"  {rss:4d}  {peak:4d}" if k == 0 else ""
                print(f"{i:4d} {label} {cells} {total:6.2f}{mem}")
    print(f"load average at the end: {load_average()}")


if __name__ == "__main__":
    main(ARGS)

"""The extension zip: built with Blender's own builder, validated, installed into a
throw-away user folder, enabled, and it fits.

Needs the network the first time (pip downloads the scipy wheels into wheels/, cached
there afterwards). BLENDER_USER_RESOURCES must be set before bpy is imported, so the
install runs in a subprocess.
"""

import json
import zipfile

from tests.addon.support import run_python, synthetic_files

INSTALL_AND_FIT = r"""
import json, sys
import bpy
zip_path, case_path = sys.argv[1], sys.argv[2]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                         enable_on_install=True)
mod = "bl_ext.user_default.headrecon"
assert mod in {a.module for a in bpy.context.preferences.addons}, "not enabled"
scene = bpy.context.scene
scene.headrecon.texture_size = "256"
scene.headrecon.n_identity = 30
assert bpy.ops.headrecon.import_landmarks(filepath=case_path) == {"FINISHED"}
assert bpy.ops.headrecon.fit() == {"FINISHED"}
head = scene.headrecon.head
solver = sys.modules[mod + ".solver.fitting.fit"]
print("RESULT " + json.dumps({
    "keys": len(head.data.shape_keys.key_blocks),
    "solver_file": solver.__file__,
    "top_level_solver": "solver" in sys.modules,
    "status": scene.headrecon.status,
}))
sys.stdout.flush()
if bpy.app.version < (4, 4, 0):  # bpy < 4.4 crashes at interpreter exit (Blender #125376)
    import os
    os._exit(0)
"""


def test_extension_zip_builds_installs_and_fits(model, tmp_path):
    from tools import build_extension as be

    be.download_wheels()
    be.fetch_detector(if_missing=True)
    zips = be.build(tmp_path / "dist", split_platforms=True)
    names = sorted(z.name for z in zips)
    assert names == ["headrecon-0.1.0-linux_x64.zip", "headrecon-0.1.0-macos_arm64.zip",
                     "headrecon-0.1.0-macos_x64.zip", "headrecon-0.1.0-windows_x64.zip"]
    linux = next(z for z in zips if "linux" in z.name)
    with zipfile.ZipFile(linux) as zf:
        files = zf.namelist()
    top = {f.split("/")[0] for f in files}
    assert top == {"__init__.py", "blender_manifest.toml", "headrecon_addon", "solver",
                   "assets", "generated", "wheels", "LICENSE", "README.md"}
    assert "generated/model/head_model.npz" in files
    assert "generated/model/LICENSE-ICT-FaceKit.txt" in files
    # only the head model and the detector's three models, with their notices, from
    # generated/ (no samples, no caches)
    assert sorted(f for f in files if f.startswith("generated/")) == [
        "generated/detector/LICENSE-MediaPipe.txt",
        "generated/detector/face_detection_short_range.tflite",
        "generated/detector/face_landmark.tflite",
        "generated/detector/selfie_segmentation.tflite",
        "generated/model/LICENSE-ICT-FaceKit.txt", "generated/model/head_model.npz"]
    wheels = [f for f in files if f.endswith(".whl")]
    assert len(wheels) == 1 and "manylinux" in wheels[0] and "scipy-1.13.1" in wheels[0]
    assert not any("__pycache__" in f for f in files)

    case_path, _, _ = synthetic_files(model, tmp_path / "case", seed=13)
    user = tmp_path / "user"
    proc = run_python(["-c", INSTALL_AND_FIT, linux, case_path], cwd=tmp_path,
                      env={"BLENDER_USER_RESOURCES": str(user), "PYTHONPATH": ""},
                      timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT "))
    res = json.loads(line[len("RESULT "):])
    assert res["keys"] == 1 + 30 + 1 + 59  # basis, identity, detail, 51 ARKit + 8 extras
    # the installed copy ran, with its own solver (not this checkout's)
    assert res["solver_file"].startswith(str(user))
    assert not res["top_level_solver"]

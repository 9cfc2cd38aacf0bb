"""Build the HeadRecon extension zip with Blender's own extension builder.

    python -m tools.build_extension [--output-dir dist] [--single] [--platform linux-x64 ...]

1. Downloads the scipy wheels the extension bundles (cp311, one per platform) into
   ``wheels/`` with pip (cached: a wheel already there is not fetched again).
2. Writes their paths into ``blender_manifest.toml`` (``wheels = [...]``).
3. Runs ``blender_ext.py build`` from the installed bpy package (plain Python, no Blender
   needed) and ``blender_ext.py validate`` on every zip it made.

By default one zip per platform (``--split-platforms``: each carries only its own scipy
wheel, ~35 MB instead of ~150 MB); ``--single`` makes one zip for all platforms.
The head model must be built first (``./run model``): the zip carries
``generated/model/head_model.npz`` and its MIT notice. The face detector's models are
fetched here (``tools/fetch_detector.py``) and go in with their Apache-2.0 licence.
"""

import argparse
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

from tools.fetch_detector import fetch as fetch_detector

ROOT = Path(__file__).resolve().parent.parent
MANIFEST = ROOT / "blender_manifest.toml"
WHEEL_DIR = ROOT / "wheels"
SCIPY = ("scipy", "1.13.1")
PYTHON_VERSION = "3.11"
# Blender platform -> pip platform tag to ask for (pip picks the matching wheel).
PLATFORMS = {
    "windows-x64": "win_amd64",
    "macos-arm64": "macosx_12_0_arm64",
    "macos-x64": "macosx_10_9_x86_64",
    "linux-x64": "manylinux_2_17_x86_64",
}
MODEL_FILES = ("generated/model/head_model.npz", "generated/model/LICENSE-ICT-FaceKit.txt")


def _wheel_platform_ok(wheel_name, tag):
    # scipy-1.13.1-cp311-cp311-<platform tags, dot-separated>.whl
    return tag in wheel_name[:-len(".whl")].split("-")[-1].split(".")


def find_wheel(wheel_dir, tag):
    """The cached scipy wheel for pip platform ``tag`` in ``wheel_dir``, or None."""
    name, version = SCIPY
    py = "cp" + PYTHON_VERSION.replace(".", "")
    for p in sorted(Path(wheel_dir).glob(f"{name}-{version}-{py}-{py}-*.whl")):
        if _wheel_platform_ok(p.name, tag):
            return p
    return None


def download_wheels(wheel_dir=WHEEL_DIR, platforms=tuple(PLATFORMS)):
    """Make sure the scipy wheel of each Blender platform is in ``wheel_dir``.

    Returns
    -------
    list of Path
        One wheel per platform, in the order of ``platforms``.
    """
    wheel_dir = Path(wheel_dir)
    wheel_dir.mkdir(parents=True, exist_ok=True)
    out = []
    for platform in platforms:
        tag = PLATFORMS[platform]
        wheel = find_wheel(wheel_dir, tag)
        if wheel is None:
            print(f"build_extension: downloading {SCIPY[0]} {SCIPY[1]} for {platform}",
                  flush=True)
            subprocess.run([sys.executable, "-m", "pip", "download",
                            f"{SCIPY[0]}=={SCIPY[1]}", "--only-binary=:all:",
                            "--python-version", PYTHON_VERSION, "--platform", tag,
                            "--no-deps", "--quiet", "-d", str(wheel_dir)], check=True)
            wheel = find_wheel(wheel_dir, tag)
            if wheel is None:
                raise RuntimeError(f"pip downloaded no {SCIPY[0]} wheel for {tag} into "
                                   f"{wheel_dir}")
        out.append(wheel)
    return out


def write_manifest_wheels(wheels, manifest=MANIFEST, root=ROOT):
    """Replace the ``wheels = [...]`` list of the manifest (paths relative to ``root``).
    Returns True if the file changed."""
    text = Path(manifest).read_text(encoding="utf-8")
    rel = [Path(w).resolve().relative_to(Path(root).resolve()).as_posix() for w in wheels]
    block = "wheels = [\n" + "".join(f'  "./{r}",\n' for r in rel) + "]"
    new, n = re.subn(r"(?ms)^wheels = \[.*?^\]", block, text)
    if n != 1:
        raise ValueError(f"{manifest}: expected exactly one 'wheels = [...]' block, found {n}")
    if new != text:
        Path(manifest).write_text(new, encoding="utf-8")
        return True
    return False


def blender_ext_cli():
    """Path of Blender's extension builder inside the installed bpy package."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError("the bpy package is not installed (./run installs it)")
    for base in spec.submodule_search_locations:
        hits = sorted(Path(base).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if hits:
            return hits[-1]
    raise RuntimeError("blender_ext.py not found inside the bpy package")


def _run_cli(args):
    cmd = [sys.executable, str(blender_ext_cli()), *args]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[2:4])} failed ({proc.returncode}):\n"
                           f"{proc.stdout}{proc.stderr}")
    return proc.stdout


def build(output_dir, split_platforms=True, source_dir=ROOT):
    """Run the builder; returns the zips it wrote (validated)."""
    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    before = {p: p.stat().st_mtime_ns for p in output_dir.glob("headrecon-*.zip")}
    args = ["build", "--source-dir", str(source_dir), "--output-dir", str(output_dir)]
    if split_platforms:
        args.append("--split-platforms")
    log = _run_cli(args)
    zips = sorted(p for p in output_dir.glob("headrecon-*.zip")
                  if before.get(p) != p.stat().st_mtime_ns)
    if not zips:
        raise RuntimeError(f"the builder wrote no zip into {output_dir}:\n{log}")
    for z in zips:
        _run_cli(["validate", str(z)])
    return zips


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m tools.build_extension",
                                description="Build the HeadRecon extension zip(s).")
    p.add_argument("--output-dir", default=str(ROOT / "dist"))
    p.add_argument("--single", action="store_true",
                   help="one zip for all platforms instead of one per platform")
    args = p.parse_args(argv)
    missing = [f for f in MODEL_FILES if not (ROOT / f).is_file()]
    if missing:
        print(f"build_extension: missing {', '.join(missing)}: build the head model first "
              "(./run model)", file=sys.stderr)
        return 1
    fetch_detector(if_missing=True)
    wheels = download_wheels()
    if write_manifest_wheels(wheels):
        print("build_extension: updated the wheels list in blender_manifest.toml")
    zips = build(args.output_dir, split_platforms=not args.single)
    for z in zips:
        print(f"{z}  ({z.stat().st_size / 1e6:.1f} MB, validated)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

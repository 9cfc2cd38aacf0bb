"""Take the MediaPipe face models from the ``mediapipe`` wheel on PyPI into
``generated/detector/`` (git-ignored), with their Apache-2.0 licence.

    python -m tools.fetch_detector [--if-missing]

The wheel (pinned version and sha256) is downloaded with pip into ``wheels/`` (cached);
only the ``.tflite`` files ``solver.detect`` runs (face detection, face mesh, selfie
segmentation) and the wheel's LICENSE are extracted, each checked against its sha256, so a
changed upload is refused; a file already there and intact is left alone. The models are
the same bytes in every platform's wheel; the Linux one is asked for on any machine.
"""

import argparse
import hashlib
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
WHEEL_DIR = ROOT / "wheels"
DETECTOR_DIR = ROOT / "generated" / "detector"
WHEEL = ("mediapipe-0.10.14-cp311-cp311-manylinux_2_17_x86_64.manylinux2014_x86_64.whl",
         "a807328339e7356fda0bb14df12fedbf1d33bdf81649c5f8666b0026b1cc30b4")
# member of the wheel -> (file name in DETECTOR_DIR, sha256)
FILES = {
    "mediapipe/modules/face_detection/face_detection_short_range.tflite":
        ("face_detection_short_range.tflite",
         "bbff11cebd1eb27a1e004cae0b0e63ec8c551cbf34a4451148b4908b8db3eca8"),
    "mediapipe/modules/face_landmark/face_landmark.tflite":
        ("face_landmark.tflite",
         "1055cb9d4a9ca8b8c688902a3a5194311138ba256bcc94e336d8373a5f30c814"),
    "mediapipe/modules/selfie_segmentation/selfie_segmentation.tflite":
        ("selfie_segmentation.tflite",
         "9ee168ec7c8f2a16c56fe8e1cfbc514974cbbb7e434051b455635f1bd1462f5c"),
    "mediapipe-0.10.14.dist-info/LICENSE":
        ("LICENSE-MediaPipe.txt",
         "8707eef0533987efc5b155d64761eeb6e20793f50b9bd1a68dad1cf4719d0ed8"),
}


def _sha256(data):
    return hashlib.sha256(data).hexdigest()


def _intact(path, sha):
    return path.is_file() and _sha256(path.read_bytes()) == sha


def _ready(out_dir):
    return all(_intact(out_dir / name, sha) for name, sha in FILES.values())


def download_wheel(wheel_dir=WHEEL_DIR):
    """The pinned mediapipe wheel in ``wheel_dir`` (downloaded once), its sha256 checked."""
    wheel_dir = Path(wheel_dir)
    wheel = wheel_dir / WHEEL[0]
    if not wheel.is_file():
        print("fetch_detector: downloading mediapipe 0.10.14 (36 MB) for its face models",
              flush=True)
        subprocess.run([sys.executable, "-m", "pip", "download", "mediapipe==0.10.14",
                        "--no-deps", "--only-binary=:all:", "--python-version", "3.11",
                        "--platform", "manylinux_2_17_x86_64", "--quiet",
                        "-d", str(wheel_dir)], check=True)
    if _sha256(wheel.read_bytes()) != WHEEL[1]:
        raise ValueError(f"{wheel}: sha256 differs from the pinned one; delete it and "
                         f"run again, or update tools/fetch_detector.py deliberately")
    return wheel


def fetch(out_dir=DETECTOR_DIR, wheel_dir=WHEEL_DIR, if_missing=False):
    """Extract the detector files into ``out_dir``; returns ``out_dir``."""
    out_dir = Path(out_dir)
    if if_missing and _ready(out_dir):
        return out_dir
    wheel = download_wheel(wheel_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(wheel) as z:
        for member, (name, sha) in FILES.items():
            if _intact(out_dir / name, sha):
                continue
            data = z.read(member)
            if _sha256(data) != sha:
                raise ValueError(f"{wheel}: {member} has an unexpected sha256")
            tmp = out_dir / (name + ".tmp")
            tmp.write_bytes(data)
            tmp.replace(out_dir / name)
    return out_dir


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--if-missing", action="store_true",
                    help="do nothing when the files are already there and intact")
    ap.add_argument("--out", type=Path, default=DETECTOR_DIR)
    args = ap.parse_args(argv)
    out = fetch(args.out, if_missing=args.if_missing)
    print(f"fetch_detector: {', '.join(n for n, _ in FILES.values())} in {out}")


if __name__ == "__main__":
    main()

"""Command line: ``python -m solver fit|validate|landmarks|detect ...``.

The same fit the Blender add-on runs, headless: read a landmarks file, fit the head model,
write the head as OBJ (model topology and UVs, metres), optionally bake the photos into a
texture, and write a JSON report. Progress goes to stderr; bad input ends with exit code 1
and one line naming the file, view and key at fault (never a traceback). Only this module
reads images (with Pillow); the solver's texture functions take arrays.
"""

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from .io.camera_json import LENS_MM_RANGE, camera_to_json
from .io.exif import orient, oriented_size, read_photo_exif
from .io.landmark_counts import MIN_LANDMARKS_PER_VIEW, MIN_LANDMARKS_TOTAL
from .io.landmark_set import load_landmark_set
from .io.landmarks_file import LandmarksError, load_landmarks
from .io.photo_lens import orthographic_lenses
from .texture.bake import CLOTHES_MODES

PROG = "python -m solver"
EXIT_OK, EXIT_FAILED, EXIT_INTERRUPTED = 0, 1, 130  # argparse exits 2 on bad usage


class CliError(Exception):
    """A problem with the user's input or environment: printed as one line, exit 1."""


# --------------------------------------------------------------------------------------
# Small helpers


class _Progress:
    """Prints ``[ 42%] message`` lines on stderr (nothing when quiet), with elapsed time."""

    def __init__(self, quiet):
        self.quiet = quiet
        self.t0 = time.perf_counter()
        self._last = None

    def __call__(self, fraction, message):
        if self.quiet:
            return
        line = f"[{100 * min(max(float(fraction), 0.0), 1.0):3.0f}%] {message}"
        if line == self._last:  # a fit may report the same step repeatedly
            return
        self._last = line
        print(f"{line}  ({time.perf_counter() - self.t0:.1f} s)", file=sys.stderr, flush=True)


def _one_line(text):
    return " ".join(str(text).split()) or "failed"


#: Most pixels of a photo read (a 200-megapixel camera's). Larger ones are refused before
#: decoding: Pillow's own limit would end in a DecompressionBombError naming no photo.
MAX_PHOTO_PIXELS = 200_000_000


def _pil_open(path):
    """``Image.open(path)`` with Pillow's own pixel limit lifted: ``MAX_PHOTO_PIXELS`` is
    checked by the callers, with a message naming the photo."""
    import warnings

    from PIL import Image

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)
        limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
        try:
            return Image.open(path)
        finally:
            Image.MAX_IMAGE_PIXELS = limit


#: Pillow's grey modes of more than 8 bits (a 16-bit grey PNG or TIFF), which its own
#: conversion to RGB clips to white.
_WIDE_MODES = ("I;16", "I;16B", "I;16L", "I;16N", "I", "F")


def _photo_mode(im):
    """"RGBA" for a photo with transparency (a cut-out), else "RGB"."""
    alpha = im.mode in ("RGBA", "LA", "PA") or "transparency" in im.info
    return "RGBA" if alpha else "RGB"


def _converted(im, mode):
    """``im`` (a Pillow image) in ``mode`` ("RGB" or "RGBA"); a grey photo of more than 8
    bits (``_WIDE_MODES``) scaled to 8 bits first, where Pillow would clip it white: its
    values taken as 16-bit, or as 8-bit where none passes 255, or (a float one) as in
    [0, 1] where none passes 1."""
    from PIL import Image

    if im.mode == mode:
        return im
    if im.mode in _WIDE_MODES:
        values = np.asarray(im, dtype=np.float32)
        peak = float(values.max(initial=0.0))
        top = 65535.0 if im.mode.startswith("I;16") or peak > 255.0 else \
            1.0 if im.mode == "F" and peak <= 1.0 else 255.0
        scaled = np.clip(values * np.float32(255.0 / top), 0.0, 255.0)
        im = Image.fromarray(np.round(scaled).astype(np.uint8))  # mode "L"
    return im.convert(mode)


def _orientation(path, stored_size=None, size=None):
    """The EXIF Orientation to turn a photo upright by (1: as stored), as Blender's Load
    Photos does; a photo turned by 90° whose stored size is the landmarks file's ``size``
    (a file written before orientation was applied) stays as stored. Unreadable EXIF is
    one warning line naming the file."""
    exif, problem = read_photo_exif(path)
    if problem:
        print(f"warning: {problem}", file=sys.stderr)
    turn = exif.orientation if exif is not None else 1
    if size is not None and tuple(size) == tuple(stored_size) != oriented_size(stored_size,
                                                                               turn):
        return 1
    return turn


def _open_photo(case, view_name):
    """A view's photo opened (not decoded), checked against the pixel limit and the file's
    size once upright; returns (Image, path, EXIF orientation to apply)."""
    from PIL import UnidentifiedImageError

    view = case.views[view_name]
    where = f"{case.source}: views.{view_name}.image"
    path = case.image_path(view_name)
    if not path.is_file():
        raise CliError(f"{where}: photo {view.image!r} not found ({path})")
    try:
        im = _pil_open(path)
    except UnidentifiedImageError:
        raise CliError(f"{where}: {path.name} is not an image Pillow can read") from None
    except OSError as e:
        raise CliError(f"{where}: cannot read {path.name}: {e}") from None
    w, h = im.size
    if w * h > MAX_PHOTO_PIXELS:
        im.close()
        raise CliError(f"{where}: {path.name} is {w}x{h} pixels ({w * h / 1e6:.0f} "
                       f"megapixels); photos up to {MAX_PHOTO_PIXELS / 1e6:.0f} megapixels "
                       "are read")
    turn = _orientation(path, (w, h), view.size)
    uw, uh = oriented_size((w, h), turn)
    if (uw, uh) != tuple(view.size):
        im.close()
        raise CliError(f"{case.source}: views.{view_name}.size: the file says "
                       f"{view.size[0]}x{view.size[1]} but {path.name} is {uw}x{uh} pixels"
                       + (" upright" if turn != 1 else ""))
    return im, path, turn


def _read_photo(case, view_name, texture_size):
    """A view's photo as float32 (H, W, 3|4) in [0, 1], reduced to what a texture of
    ``texture_size`` needs (``bake_photo_size``; the bake samples it where the full photo
    would be), so a huge photo costs neither minutes nor gigabytes."""
    from PIL import Image

    from .texture.bake import bake_photo_size

    im, path, turn = _open_photo(case, view_name)
    where = f"{case.source}: views.{view_name}.image"
    try:
        with im:
            target = bake_photo_size(im.size, texture_size)
            if target != im.size:
                im.draft("RGB", target)  # JPEG: decode at a reduced scale directly
            rgb = _converted(im, _photo_mode(im))
            if rgb.size != target:
                rgb = rgb.resize(target, Image.Resampling.BOX, reducing_gap=2.0)
            arr = np.ascontiguousarray(orient(np.asarray(rgb, dtype=np.float32), turn))
    except OSError as e:
        raise CliError(f"{where}: cannot read {path.name}: {e}") from None
    return arr / np.float32(255.0)


#: The command line's option for each FitOptions field it sets (for messages).
_OPTION_FLAGS = {"method": "--method", "n_identity": "--components", "n_regional": "--regional",
                 "lambda1": "--lambda1", "lambda2": "--lambda2", "prior": "--prior",
                 "max_iterations": "--max-iterations", "noise_px": "--noise-px",
                 "noise": "--noise", "outline_landmarks": "--outline-landmarks",
                 "expressions": "--expressions", "definition_mm": "--definition-mm"}


def _fit_options(args, model, progress):
    """The FitOptions of the arguments, checked (``check_options``) before anything runs;
    a bad value is named by its command-line option, with the range."""
    from .fitting.options import FitOptions, check_options

    kw = {"progress": progress}
    for key, flag in _OPTION_FLAGS.items():
        value = getattr(args, flag[2:].replace("-", "_"))
        if value is not None:
            kw[key] = value
    if args.exact:
        kw["exact_landmarks"] = True
    options = FitOptions(**kw)
    try:
        return check_options(options, model)
    except ValueError as e:
        msg = str(e)
        for key, flag in _OPTION_FLAGS.items():
            if msg.startswith(f"options.{key}:"):
                msg = flag + msg[len(f"options.{key}"):]
        raise CliError(msg) from None


def _fit_failure(case, error):
    """One line for a fit that failed on input the checks let through: the file, and the
    view when the fit names it ("view 'front': ..."), else how to find the view."""
    msg = _one_line(error)
    if msg.startswith("view '") or msg.startswith(case.source):
        return msg if msg.startswith(case.source) else f"{case.source}: {msg}"
    return (f"{case.source}: the fit failed ({type(error).__name__}: {msg}); "
            f"'{PROG} validate {case.source}' checks each view's camera and landmarks")


def _outputs(args):
    """What ``fit`` will write, by option: the OBJ, with a texture its PNG and .mtl, the
    report."""
    from .io.obj import mtl_path

    outputs = {"--out": Path(args.out)}
    if args.texture:
        outputs["--texture"] = Path(args.texture)
        outputs[f"the .mtl of --out ({mtl_path(args.out).name})"] = mtl_path(args.out)
    if args.report:
        outputs["--report"] = Path(args.report)
    return outputs


def _inputs(args, case):
    """What ``fit`` reads: the landmarks file, every view's photo, the head model."""
    inputs = {"the landmarks file": Path(args.landmarks)}
    for name in case.views:
        photo = case.image_path(name)
        if photo is not None:
            inputs[f"the photo of view {name!r}"] = photo
    if args.model:
        inputs["--model"] = Path(args.model)
    return inputs


# --------------------------------------------------------------------------------------
# fit


def _cmd_fit(args):
    from .io.atomic import check_outputs

    progress = _Progress(args.quiet)
    timings = {}
    t_start = time.perf_counter()

    # No progress output until the input is checked: bad input gets exactly one line.
    t = time.perf_counter()
    case = load_landmarks(args.landmarks)
    outputs = _outputs(args)
    check_outputs(outputs, _inputs(args, case))  # before anything is read or written
    photos = {}
    if args.texture:  # read the photos before fitting: a missing photo fails fast
        for name, view in case.views.items():
            if view.image is not None:
                photos[name] = _read_photo(case, name, args.texture_size)
        if not photos:
            raise CliError(f"--texture: {case.source}: no view names a photo ('image')")
    timings["read"] = time.perf_counter() - t

    t = time.perf_counter()
    # Imported here, after the input checks: a bad file fails fast, before numpy-heavy
    # modules load.
    from .fitting.fit import fit_head
    from .io.atomic import write_files_atomic
    from .io.contour import thin_case_contours
    from .io.export import head_obj_files
    from .io.report import fit_report, report_text
    from .model.head_model import load_model

    model = load_model(args.model)
    options = _fit_options(args, model, progress)
    timings["model"] = time.perf_counter() - t
    progress(0.0, f"read {case.source} ({case.n_points} landmarks in {len(case.views)} views) "
                  f"and the head model")
    notes = thin_case_contours(case)
    orthographic_lenses(case)  # the photos' EXIF lenses, for the projection check
    progress(0.0, f"fitting ({options.method})")
    t = time.perf_counter()
    try:
        result = fit_head(model, case, options)
    except (ValueError, ArithmeticError) as e:
        raise CliError(_fit_failure(case, e)) from None
    timings["fit"] = time.perf_counter() - t
    for message in notes:  # after the fit: a failure still gets one line
        print(f"notice: {message}", file=sys.stderr)
    for message in result.info.get("warnings", ()):
        print(f"warning: {message}", file=sys.stderr)

    tiles = iris = None
    if args.texture:
        from .texture.bake import BakeOptions, bake_fit_texture
        from .texture.iris import iris_colour

        progress(1.0, f"baking the texture from {len(photos)} photo(s)")
        t = time.perf_counter()
        tiles = bake_fit_texture(model, result, photos, size=args.texture_size,
                                 options=BakeOptions(shading=args.texture_shading,
                                                     clothes=args.texture_clothes))
        iris = iris_colour(model, result, photos, case)
        timings["texture"] = time.perf_counter() - t

    progress(1.0, f"writing {args.out}")
    t = time.perf_counter()
    vertices = result.world_vertices if args.frame == "world" else result.local_vertices
    names, files = head_obj_files(outputs["--out"], model, vertices, tiles,
                                  outputs.get("--texture"))
    written = {key: names[key] for key in ("texture", "obj", "mtl") if key in names}
    if args.report:
        written["report"] = outputs["--report"]
        timings["write"] = time.perf_counter() - t
        timings["total"] = time.perf_counter() - t_start
        options = {k: v for k, v in vars(args).items() if k not in ("func", "debug")}
        files[outputs["--report"]] = report_text(fit_report(case, model, result, options,
                                                            written, timings, iris))
    for path in files:
        path.parent.mkdir(parents=True, exist_ok=True)
    write_files_atomic(files)  # all or nothing: a failure leaves every old file
    timings["write"] = time.perf_counter() - t

    if not args.quiet:
        for view, r in result.residuals.items():
            px = np.asarray(r.pixels, dtype=np.float64)
            if px.size:
                flag = f"; check {', '.join(r.flagged)}" if r.flagged else ""
                print(f"{view}: landmark residual mean {px.mean():.2f} px, max {px.max():.2f} px"
                      f"{flag}", file=sys.stderr)
        print(f"done in {time.perf_counter() - t_start:.2f} s: "
              + ", ".join(str(p) for p in written.values()), file=sys.stderr)
    return EXIT_OK


# --------------------------------------------------------------------------------------
# validate / landmarks


def _cmd_validate(args):
    status = EXIT_OK
    for path in args.files:
        try:
            case = load_landmarks(path, for_fit=not args.draft)
        except LandmarksError as e:
            for line in e.messages():
                print(_one_line(line), file=sys.stderr)
            status = EXIT_FAILED
            continue
        except (ValueError, OSError) as e:
            print(_one_line(e), file=sys.stderr)
            status = EXIT_FAILED
            continue
        parts = []
        for name, view in case.views.items():
            text = f"{name} {len(view.points)} landmarks"
            if view.contour is not None:
                text += f" + contour of {len(view.contour)} points"
            if case.version >= 2:
                text += _view_v2_summary(view)
            parts.append(text)
            photo = case.image_path(name)
            if photo is not None and not photo.is_file():
                print(f"{path}: views.{name}.image: warning: photo {view.image!r} not found "
                      f"({photo}); a fit works, --texture would not", file=sys.stderr)
        # A version-1 file reads as it always did; version 2 says what its cameras are.
        head = "" if case.version == 1 else f"version {case.version}; "
        tail = f"; {len(case.passpoints)} passpoints defined" if case.passpoints else ""
        print(f"{path}: OK ({head}{'; '.join(parts)}{tail})")
    return status


def _view_v2_summary(view):
    """What version 2 says about a view: its camera (kind, given or to compute, fixed or
    refined), the photo it is the mirror image in, its passpoints."""
    text = ""
    if view.passpoints:
        text += f" + {len(view.passpoints)} passpoints"
    if view.camera is None:
        source = "passpoints" if view.passpoints else "self-calibration"
        text += f", {view.camera_kind} camera from {source}"
    elif not isinstance(camera_to_json(view.camera, view.size), str):
        text += f", {view.camera_kind} camera given"
    else:
        text += f", {view.camera_kind} camera (nominal)"
    text += ", kept fixed" if view.camera_fixed else ", refined"
    if view.mirror_of is not None:
        text += f", mirror image in {view.mirror_of!r}"
    return text


def _cmd_landmarks(args):
    lms = load_landmark_set()
    if args.json:
        print(json.dumps(list(lms.info), indent=1))
        return EXIT_OK
    for entry in lms.info:
        ibug = entry.get("ibug")
        tag = f"ibug{ibug:02d}" if ibug is not None else ""
        views = ",".join(entry.get("views", []))
        print(f"{entry['name']:<28} {tag:<7} {views:<12} {entry.get('description', '')}")
    return EXIT_OK


def load_photo(path):
    """A photo file as uint8 RGB (H, W, 3), or RGBA (H, W, 4) where it has transparency (a
    cut-out: the detector lays it on a grey backdrop), upright as its EXIF says; problems
    name the photo."""
    from PIL import UnidentifiedImageError

    path = Path(path)
    if path.is_dir():
        raise CliError(f"{path}: a folder, not a photo (give its photos; headless --detect "
                       "takes a folder of one head's photos)")
    if not path.is_file():
        raise CliError(f"{path}: photo not found")
    try:
        with _pil_open(path) as im:
            w, h = im.size
            if w * h > MAX_PHOTO_PIXELS:
                raise CliError(f"{path}: {w}x{h} pixels; photos up to "
                               f"{MAX_PHOTO_PIXELS / 1e6:.0f} megapixels are read")
            return np.ascontiguousarray(orient(np.asarray(_converted(im, _photo_mode(im))),
                                               _orientation(path)))
    except UnidentifiedImageError:
        raise CliError(f"{path}: not an image Pillow can read") from None
    except OSError as e:
        raise CliError(f"{path}: cannot read: {e}") from None


def view_entries(photos, views):
    """(given view name or None, photo) of each photo to detect: ``photos`` as they are,
    then each ``NAME=PHOTO`` of ``views`` (a photo given both ways takes the name)."""
    named = []
    for item in views or ():
        name, sep, photo = item.partition("=")
        if not sep or not name.strip() or not photo:
            raise CliError(f"--view {item!r}: expected NAME=PHOTO (e.g. right=side.jpg)")
        named.append((name.strip(), photo))
    given = {Path(p).resolve() for _, p in named}
    names = [n for n, _ in named]
    twice = {n for n in names if names.count(n) > 1}
    if twice:
        raise CliError(f"--view {sorted(twice)[0]}: given to two photos")
    entries = [(None, p) for p in photos or () if Path(p).resolve() not in given] + named
    if not entries:
        raise CliError("give the photos (PHOTO ... or --view NAME=PHOTO)")
    return entries


def detect_landmarks(photos, out, views=(), models=None, quiet=False, outlines="all",
                     exif_lens=True, lens_mm=None, warnings=None):
    """Detect the face in each photo, and the head's outline in those ``outlines`` says
    (``detected_case.wants_outline``), and write the landmarks file ``out`` (a photo whose
    EXIF gives its lens gets a pinhole camera of it unless ``exif_lens`` is False, one
    whose EXIF gives none a pinhole of ``lens_mm`` when given); the
    lines of ``solver.detect.detected_case.detect_photos`` go to stderr ("warning:" and
    "note:" lines even when ``quiet``), and the warnings, without their "warning: ", to the
    list ``warnings`` when given (a batch's summary). Returns the case. ``CliError`` /
    ``ValueError``: one line naming the photo or option."""
    from .detect import Detector
    from .detect.detected_case import detect_photos
    from .io.landmarks_file import save_landmarks

    entries = view_entries(photos, views)
    detector = Detector(models) if models else Detector()
    out = Path(out)
    progress = _Progress(quiet)
    done = []

    def echo(line):
        if line.startswith(("warning:", "note:")):
            print(line, file=sys.stderr, flush=True)
            if warnings is not None and line.startswith("warning: "):
                warnings.append(line[len("warning: "):])
        else:
            done.append(line)
            faces = sum(" -> view " in ln for ln in done)
            progress(min(faces, len(entries)) / len(entries), line)

    case = detect_photos(entries, detector, load_photo, base_dir=out.parent, echo=echo,
                         outlines=outlines, exif_lens=exif_lens, lens_mm=lens_mm)
    save_landmarks(case, out)
    if not quiet:
        print(f"wrote {out}", file=sys.stderr)
    return case


def _cmd_detect(args):
    if args.orthographic and args.lens is not None:
        raise CliError("--lens and --orthographic: give one (--lens makes the photos "
                       "without an EXIF lens perspective, --orthographic every photo parallel)")
    detect_landmarks(args.photos, args.out, args.view, args.models, args.quiet,
                     args.outlines, not args.orthographic, args.lens)
    return EXIT_OK


# --------------------------------------------------------------------------------------
# Parser and entry point


def _parsed(text, convert, what):
    """``convert(text)``, or the argparse error "expected <what>, got '<text>'"."""
    try:
        return convert(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None


def _positive_int(text):
    value = _parsed(text, int, "a whole number")
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected 0 or more, got {value}")
    return value


def lens_mm_arg(text):
    """A lens given on the command line (mm, 36 mm equivalent), one a landmarks file
    accepts (``LENS_MM_RANGE``); else argparse's error naming it."""
    value = _parsed(text, float, "a focal length in mm")
    lo, hi = LENS_MM_RANGE
    if not lo <= value <= hi:  # NaN too
        raise argparse.ArgumentTypeError(
            f"expected {lo:g} to {hi:g} mm (36 mm equivalent), got {text}")
    return value


def _texture_size(text):
    value = _positive_int(text)
    if not 8 <= value <= 16384:
        raise argparse.ArgumentTypeError(f"expected 8 to 16384 pixels, got {value}")
    return value


def _non_negative_float(text):
    value = _parsed(text, float, "a number")
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text}")
    return value


def build_parser():
    parser = argparse.ArgumentParser(
        prog=PROG, description="HeadRecon: fit a 3D head to landmarks placed on a front and "
                               "a profile photo.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    fit = sub.add_parser(
        "fit", help="fit the head to a landmarks file; write OBJ (+ texture, report)",
        description="Fit the head model to the landmarks of LANDMARKS.json and write the "
                    "head as OBJ (metres, Y up, the model's polygons and UVs).")
    fit.add_argument("landmarks", metavar="LANDMARKS.json", help="the landmarks file")
    fit.add_argument("--out", required=True, metavar="HEAD.obj", help="OBJ file to write")
    fit.add_argument("--texture", metavar="HEAD.png",
                     help="bake the photos into this PNG (and write HEAD.mtl using it)")
    fit.add_argument("--texture-size", type=_texture_size, default=1024, metavar="PX",
                     help="texture height in pixels, and width per UV tile (default 1024; "
                          "the skin's two tiles make a 2048x1024 image)")
    fit.add_argument("--texture-shading", choices=("keep", "remove"), default="keep",
                     help="keep the photos' light in the texture, or remove its "
                          "low-frequency part (a smoothed luminance divided out) for a flat, "
                          "albedo-like texture (default keep)")
    fit.add_argument("--texture-clothes", choices=CLOTHES_MODES, default="leave-out",
                     help="leave out what the photos show of clothes below the chin (a "
                          "collar, a shirt) so the neck there gets the smooth fill, or keep "
                          "the photos as they are (default leave-out)")
    fit.add_argument("--report", metavar="REPORT.json",
                     help="write residuals, coefficients, uncertainty and timings as JSON")
    fit.add_argument("--method", choices=("combined", "approach1", "approach2"),
                     help="fitting method (default: the fit's default, combined)")
    fit.add_argument("--components", type=_positive_int, metavar="N",
                     help="global identity components to fit")
    fit.add_argument("--regional", type=_positive_int, metavar="N",
                     help="components per region of the regional model (0: global only)")
    fit.add_argument("--exact", action="store_true",
                     help="add thin-plate-spline detail so the landmarks are hit exactly")
    fit.add_argument("--lambda1", type=_non_negative_float, metavar="W",
                     help="weight of the region-border smoothness rows (Gamma)")
    fit.add_argument("--lambda2", type=_non_negative_float, metavar="W",
                     help="weight of the shape prior (Lambda)")
    fit.add_argument("--prior", choices=("eigen", "identity"), help="shape prior")
    fit.add_argument("--max-iterations", type=_positive_int, metavar="N",
                     help="iteration limit of the fit")
    fit.add_argument("--noise-px", type=_non_negative_float, metavar="PX",
                     help="the least placement noise of a landmark assumed (standard "
                          "deviation, pixels; default 1): the fit estimates each photo's "
                          "noise from its residuals, never below this; pixels of a head "
                          "the size it is in a 1024-px photo (a larger or smaller head's "
                          "are scaled with it, a smaller one's not below half a pixel)")
    fit.add_argument("--noise", choices=("estimate", "fixed"),
                     help="'estimate' (default): placement noise and per-landmark weights "
                          "from the fit itself; 'fixed': every landmark placed with "
                          "--noise-px")
    fit.add_argument("--expressions", choices=("fit", "neutral"),
                     help="'fit' (default): each photo's expression (eyes closed, a smile) "
                          "is estimated and taken out of its landmarks before the identity "
                          "is fitted; 'neutral': the faces are assumed neutral")
    fit.add_argument("--outline-landmarks", choices=("vertex", "slide"),
                     help="the jaw, chin and head-side points of a front photo: 'vertex' "
                          "(default) fitted to their model vertices, 'slide' across the "
                          "head's silhouette and loosely along it")
    fit.add_argument("--definition-mm", type=float, metavar="MM",
                     help="how far, in mm, a landmark group (an eye, a brow, a jaw side) "
                          "may sit off the model's points together as a convention of "
                          "placing them (default 2; 0: every landmark independent)")
    fit.add_argument("--frame", choices=("local", "world"), default="local",
                     help="OBJ coordinates: 'local' the head upright in the model's frame "
                          "(default), 'world' posed as in the photos")
    fit.add_argument("--model", metavar="HEAD_MODEL.npz",
                     help="head model file (default: $HEADRECON_MODEL or generated/model/)")
    fit.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    fit.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    fit.set_defaults(func=_cmd_fit)

    val = sub.add_parser(
        "validate", help="check landmarks files without fitting",
        description="Check landmarks files (format versions 1 and 2): schema, landmark "
                    "names, points inside the images, cameras, mirror views and passpoints, "
                    f"at least {MIN_LANDMARKS_PER_VIEW} landmarks per view (views without "
                    f"passpoints) and {MIN_LANDMARKS_TOTAL} in all. Lists every problem; "
                    "exit code 1 if any file has one.")
    val.add_argument("files", nargs="+", metavar="LANDMARKS.json")
    val.add_argument("--draft", action="store_true",
                     help="work in progress: do not require enough landmarks for a fit")
    val.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    val.set_defaults(func=_cmd_validate)

    lm = sub.add_parser("landmarks", help="list the landmark names a file may use",
                        description="List every landmark (name, iBUG-68 alias, views it is "
                                    "placed in, description) from assets/landmarks.json.")
    lm.add_argument("--json", action="store_true", help="print the entries as JSON")
    lm.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    lm.set_defaults(func=_cmd_landmarks)

    det = sub.add_parser(
        "detect", help="find the face's landmarks in photos; write a landmarks file",
        description="Detect the face in each photo (MediaPipe's face detection and face mesh "
                    "models, run with numpy) and write its iBUG-68 landmarks, under the "
                    "project's names and each with its uncertainty in pixels, as a "
                    "landmarks file: one view per photo, named and its camera guessed from "
                    "which way the face looks: front, right or left (profiles: the few "
                    "points trustworthy there only), three_quarter_right or _left (a "
                    "pinhole camera the fit calibrates), a photo whose EXIF gives its lens a "
                    "pinhole camera of that lens held near its view's direction; and the "
                    "head's outline (the "
                    "person's segmentation, its skin stretch around the face: hair and "
                    "clothes left out) as each view's contour.")
    det.add_argument("photos", nargs="*", metavar="PHOTO")
    det.add_argument("--view", action="append", metavar="NAME=PHOTO",
                     help="name a photo's view yourself (front, right, left, "
                          "three_quarter_right, three_quarter_left also set its camera; a "
                          "profile given the wrong side is corrected and said); repeatable")
    det.add_argument("--out", required=True, metavar="CASE.json",
                     help="landmarks file to write")
    det.add_argument("--outlines", choices=("all", "profile", "none"), default="all",
                     help="photos whose head outline is detected as their contour "
                          "(default: all; on the sample the front's outline took the fit "
                          "from 2.5 to 1.6 mm)")
    det.add_argument("--orthographic", action="store_true",
                     help="front and profile photos as parallel projections whatever lens "
                          "their EXIF gives (e.g. photos cropped after they were taken, "
                          "whose EXIF lens no longer holds)")
    det.add_argument("--lens", type=lens_mm_arg, metavar="MM",
                     help="the lens (mm, 36 mm equivalent) of the photos whose EXIF gives "
                          "none, e.g. 26 for a phone's main camera when a messaging app "
                          "removed the EXIF: they are fitted as perspective photos of it "
                          "(default: such photos are parallel projections)")
    det.add_argument("--models", metavar="FOLDER",
                     help="folder of the .tflite files (default: generated/detector/)")
    det.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    det.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    det.set_defaults(func=_cmd_detect)
    return parser


def main(argv=None):
    """Run the command line; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (CliError, ValueError, OSError, MemoryError) as e:
        # Bad input (a file, a photo, an option): one line, no traceback.
        if args.debug:
            raise
        print(f"{PROG} {args.command}: error: {_one_line(e)}", file=sys.stderr)
        return EXIT_FAILED
    except Exception as e:  # a bug: still one line, and how to see where
        if args.debug:
            raise
        print(f"{PROG} {args.command}: internal error: {type(e).__name__}: {_one_line(e)} "
              "(run with --debug for the traceback, and please report it)", file=sys.stderr)
        return EXIT_FAILED

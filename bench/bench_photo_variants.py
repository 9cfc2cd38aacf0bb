"""Photos as users give them: heads fitted from their photos alone (detected, as Auto Fit
takes them) as rendered and changed as real photos are: with hair, a beard or glasses,
bare shoulders, in a room or before a busy background, black and white, the head small in
a larger photo, JPEG-compressed, darker, turned in their plane, cropped, blurred, noisy,
with a colour cast.

    python -m bench.bench_photo_variants [--variants NAME ...] [--face] [--james DIR]
                                         [--heads DIR ...] [--render SEED ...]
                                         [--profile-line] [--upside-down]

Heads: as ``bench.bench_photo_size`` (the sample and ``generated/bench_heads/seed<N>``).
Variants (``VARIANTS``; all by default), each applied to both photos, written to a
temporary folder: ``hair`` (dark hair painted over the skull above the brows and the back
of the head, within the head's own outline; the rendered heads are bald), ``thick_hair``
(the same grown out past the skull up to 12 mm, as hair is), ``beard`` (a dark full beard
from under the nose to under the chin and the lips' edge, up to 8 mm out past the jaw),
``glasses`` (dark frames: rims round the eyes, arms past the ears; on a profile the rim
ahead of the eye), ``bare`` (the clothes coloured as the face's skin, their shading kept:
bare shoulders or a skin-coloured top), ``room`` (a room behind the person, by the
render's alpha: a lit wall, a painted door, a bookshelf and a window, out of focus; each
photo its own), ``wood`` (the same with a wooden door: a thing of the skin's colour behind
the head), ``blocks`` and ``confetti`` (a busy background: random colours in squares,
16 or 64 down the photo), ``cut_out`` (cut out around the person: a PNG with the
render's alpha, white under its transparency), ``grey`` (black and white),
``grey_hair`` (``hair``, then black and white), ``small`` (the photo in the middle of one
four times its size, its corner's colour around it: the face 10 % of the longer side),
``jpeg50`` (JPEG at quality 50), ``dark`` (half as bright), ``overexposed`` (1.2 times
as bright, clipped: the rendered faces' lit skin white),
``turned10``, ``turned25`` and ``turned45`` (turned by 10, 25 or 45 degrees
counterclockwise, the corners filled with its corner's colour: the profile's face looking
up),
``cropped`` (its top eighth cut off: the skull's top), ``tight`` (cut close around the
detected face: a front's ears and the skull's top and back cut off), ``blurred`` (a 2 px Gaussian),
``noisy`` (Gaussian noise of 8 levels), ``warm`` and ``cool`` (red and blue scaled by
1.15 and 0.8, or 0.85 and 1.15: a white balance off). Scores: skin RMS against the true
head after a similarity (``skin_error_mm``, the whole head: under hair the skull is not
seen), or with ``--face`` over the face region alone
(``realistic_cases.model_face_vertices``, aligned on it), mm, the mean head's beside
them; a variant whose photos ``solver detect`` refuses is said and left out of the mean.
``--james DIR`` adds the scan james' own two photos (real three-quarter photos), as
photographed and through the variants that change a photo alone (``PHOTO_ONLY``), fitted
as ``solver detect`` makes their case and scored against the scan's face as
``bench_realistic`` scores it.

With ``--profile-line`` nothing is fitted: the profile line's points read off each
profile photo's detected outline (as ``solver detect`` reads them) are scored against the
head's own profile landmarks (its ``sample.json``), per point the median, 90th percentile
and largest error in % of the face's size and how many of the heads' profiles gave it.
With ``--turned`` nothing is fitted either: each photo (a head folder's PNG, or the JPEG a
render with a lens writes) is detected as given and turned by one, two and three quarter
turns, and the photos given a turn wrongly, and the turned ones whose points do not come
back to the photo's own, are counted (``turn_table``).
"""

import argparse
import io
import tempfile
import zlib
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFilter
from scipy import ndimage

from bench.bench_detect import PROFILE_LINE, padded, read_profile_line
from bench.bench_photo_size import photos_case
from bench.common import machine_description
from bench.realistic_cases import model_face_vertices, scan_photo_halves
from bench.rendered_heads import add_head_options, chosen_folders
from solver import fit_head, load_landmarks, load_model
from solver.detect import Detector
from solver.detect.photo_turn import to_turned, turned
from solver.procrustes import similarity_procrustes
from solver.synthetic import skin_error_mm


def _jpeg(image, quality=50):
    buffer = io.BytesIO()
    image.save(buffer, "JPEG", quality=quality)
    return Image.open(io.BytesIO(buffer.getvalue())).convert("RGB")


def tight(im, head, face, person, alpha):
    """The photo cut close around its detected face, as people crop a portrait: from a
    quarter of the face's width beside its box and half of it above the eyes, down to the
    bottom edge (a front's ears and the skull's top cut off, a profile's back of the head
    too)."""
    u0, _, u1, _ = face.box
    size = u1 - u0
    top = min(face.keypoints[0][1], face.keypoints[1][1]) - 0.5 * size
    return im.crop((max(0, int(u0 - 0.25 * size)), max(0, int(top)),
                    min(im.width, int(u1 + 0.25 * size)), im.height))


def _noisy(image, sigma=8.0):
    pixels = np.asarray(image, float)
    pixels += np.random.default_rng(0).normal(0, sigma, pixels.shape)
    return Image.fromarray(np.clip(pixels, 0, 255).astype(np.uint8))


def _cast(image, gains):
    return Image.fromarray(np.clip(np.asarray(image, float) * gains, 0, 255).astype(np.uint8))


def _corner(image):
    return tuple(int(c) for c in np.asarray(image)[2, 2])


def hair_region(head, face):
    """Where :func:`hair` paints, (H, W) bool: of ``head`` (H, W) bool (the true head's
    pixels), the skull above the brows and, on a profile, the back of the head down to
    below the ear; on a front photo the sides above the ears. ``face``: the photo's
    detected face (its keypoints place the brows and ears)."""
    h, w = head.shape
    v, u = np.mgrid[0:h, 0:w]
    k, size = np.asarray(face.keypoints, float), float(face.box[2] - face.box[0])
    painted = head & (v < k[:2, 1].mean() - 0.15 * size)
    if face.is_profile:
        painted |= head & (u < k[4, 0] - 0.1 * size) & (v < k[4, 1] + 0.35 * size)
    else:
        sides = (u < k[4:6, 0].min() + 0.05 * size) | (u > k[4:6, 0].max() - 0.05 * size)
        painted |= head & (v < k[4:6, 1].mean() - 0.05 * size) & sides
    return painted


def _paint_hair(image, where, seed=0):
    pixels = np.asarray(image).copy()
    shade = np.random.default_rng(seed).normal(0, 6, pixels.shape[:2] + (1,))
    pixels[where] = np.clip(np.array([40, 28, 20]) + shade[where], 0, 255)
    return Image.fromarray(pixels)


def hair(image, head, face, *_):
    """Dark hair painted on the head over :func:`hair_region`, within the head's own
    outline (a shaved head's hair)."""
    return _paint_hair(image, hair_region(head, face))


def thick_hair(image, head, face, *_, mm=12.0):
    """:func:`hair` grown out past the skull as real hair is: up to ``mm`` thick on the
    crown, thinning toward the brows and, on a profile, down the nape, with a gentle wave
    (the face's box taken as 15 cm); the head's own outline is hidden under it."""
    painted = hair_region(head, face)
    k, size = np.asarray(face.keypoints, float), float(face.box[2] - face.box[0])
    dist, (iv, iu) = ndimage.distance_transform_edt(~head, return_indices=True)
    # full thickness half a face above the brows, less below
    rise = np.clip((k[:2, 1].mean() - iv) / (0.5 * size), 0.15, 1.0)
    wave = 1.0 + 0.25 * np.sin(iu / (0.15 * size) * np.pi)
    grown = ~head & painted[iv, iu] & (dist <= mm * size / 150.0 * rise * wave)
    return _paint_hair(image, painted | grown)


def _lips(shape, face):
    """The lips, (H, W) bool: inside the outer lip line the face mesh draws (iBUG 49-60
    of ``face``, detected on the photo before anything is painted on it)."""
    mask = Image.new("L", (shape[1], shape[0]), 0)
    ImageDraw.Draw(mask).polygon([tuple(p) for p in np.asarray(face.ibug)[48:60]], fill=1)
    return np.asarray(mask, bool)


def beard_region(head, face, mm=8.0):
    """Where :func:`beard` paints, (H, W) bool: of ``head`` (H, W) bool, the face below
    the nose down to under the chin, in front of the ears, up to the lips' edge (the lips
    left bare); and grown out past the head's outline up to ``mm`` below the mouth (the
    face's box taken as 15 cm)."""
    h, w = head.shape
    v, u = np.mgrid[0:h, 0:w]
    k, size = np.asarray(face.keypoints, float), float(face.box[2] - face.box[0])
    nose, mouth = k[2], k[3]
    # from under the nose (a moustache; on a profile the nose keypoint may lie above the
    # tip: not higher than a little over the mouth) to under the chin
    top = max(nose[1] + 0.06 * size, mouth[1] - 0.1 * size)
    band = (v > top) & (v < mouth[1] + 0.45 * size)
    if face.is_profile:   # in front of the ear, toward the nose
        front = np.sign(nose[0] - k[4, 0]) * (u - k[4, 0]) > 0.15 * size
    else:
        front = (u > k[4:6, 0].min() + 0.08 * size) & (u < k[4:6, 0].max() - 0.08 * size)
    painted = head & band & front & ~_lips(head.shape, face)
    dist, (iv, iu) = ndimage.distance_transform_edt(~head, return_indices=True)
    grown = ~head & painted[iv, iu] & (iv > mouth[1]) & (dist <= mm * size / 150.0)
    return painted | grown


def bare(image, head, face, person, *_):
    """The clothes coloured as the face's skin, their shading kept: bare shoulders or a
    skin-coloured top, whose colour does not end the outline. ``person`` (H, W) bool: the
    person's pixels (the head's and the clothes')."""
    pixels = np.asarray(image, float).copy()
    clothes = person & ~head
    k, size = np.asarray(face.keypoints, float), float(face.box[2] - face.box[0])
    v, u = np.mgrid[0:head.shape[0], 0:head.shape[1]]
    cheek = head & (np.hypot(u - k[2, 0], v - k[2, 1]) < 0.3 * size)  # around the nose
    skin = np.median(pixels[cheek], axis=0)
    shade = pixels[clothes].mean(axis=1)
    pixels[clothes] = skin * (shade / np.median(shade))[:, None]
    return Image.fromarray(np.clip(pixels, 0, 255).astype(np.uint8))


def beard(image, head, face, *_):
    """A dark full beard (:func:`beard_region`): the jaw's and chin's outline is the
    beard's, up to 8 mm out from the skin."""
    return _paint_hair(image, beard_region(head, face), seed=2)


#: Paints of a room's wall, RGB 0-255: off-white, grey, beige, blue-grey, sage, taupe.
WALLS = np.array([[236, 232, 222], [205, 205, 200], [222, 210, 188], [190, 200, 205],
                  [200, 210, 190], [180, 170, 160]], float)
#: A door behind the sitter: painted grey-blue, or wood (warm, near the skin's colour).
DOORS = {"painted": (120, 125, 135), "wood": (150, 100, 60)}


def room_behind(shape, rng, door):
    """A room behind the sitter, (H, W, 3) float RGB 0-255: a wall lit from above, a door
    (``DOORS[door]``: wood with a grain, paint evenly shaded), a bookshelf of coloured
    spines and a bright window, out of focus (a Gaussian of 2-5 px) as a portrait's
    background is."""
    h, w = shape
    v, u = np.mgrid[0:h, 0:w]
    v, u = v / h, u / w
    light = 0.85 + 0.25 * (1 - v) + 0.1 * np.cos(3 * u + rng.uniform(0, 6))
    out = WALLS[rng.integers(len(WALLS))] * light[..., None]
    left = rng.uniform(0.0, 0.15) if rng.random() < 0.5 else rng.uniform(0.55, 0.75)
    panel = (u > left) & (u < left + rng.uniform(0.2, 0.35)) & (v > rng.uniform(0.0, 0.2))
    if door == "wood":
        grain = 1 + 0.08 * np.sin(300 * u * w / max(h, w) + 4 * np.sin(20 * v)) \
            + 0.04 * rng.standard_normal((h, w))
    else:
        grain = 0.95 + 0.1 * v
    colour = np.asarray(DOORS[door], float) * rng.uniform(0.8, 1.2)
    out[panel] = colour * grain[panel][:, None]
    shelf = rng.uniform(0.0, 0.6)
    width, top = rng.uniform(0.25, 0.4), rng.uniform(0.05, 0.3)
    for row in range(3):
        bottom = top + 0.16 * row + 0.13
        x = shelf
        while x < shelf + width:
            spine = rng.uniform(0.01, 0.03)
            book = (u >= x) & (u < x + spine) & (v >= bottom - rng.uniform(0.09, 0.13)) \
                & (v < bottom)
            out[book] = rng.uniform(40, 200, 3) * rng.uniform(0.6, 1.0)
            x += spine + 0.002
        board = (u >= shelf - 0.01) & (u < shelf + width + 0.01) & (v >= bottom) \
            & (v < bottom + 0.012)
        out[board] = 0.9 * np.asarray(DOORS["wood"], float)
    wx, wy = rng.uniform(0.0, 0.8), rng.uniform(0.0, 0.3)
    out[(u >= wx) & (u < wx + 0.2) & (v >= wy) & (v < wy + 0.3)] = \
        np.array([245, 248, 252]) * rng.uniform(0.97, 1.0)
    return ndimage.gaussian_filter(np.clip(out, 0, 255), (rng.uniform(2, 5),) * 2 + (0,))


def _behind(image, alpha, background):
    """``image`` with ``background(shape, rng)`` ((H, W, 3) float RGB 0-255) behind the
    person, by their ``alpha`` (H, W) in [0, 1]; its random draw seeded by the photo's
    pixels, so each head and view has its own and a rerun the same."""
    pixels = np.asarray(image, float)
    rng = np.random.default_rng(zlib.crc32(np.ascontiguousarray(pixels[::16, ::16])))
    a = np.asarray(alpha, float)[..., None]
    out = pixels * a + background(a.shape[:2], rng) * (1 - a)
    return Image.fromarray(np.clip(out, 0, 255).astype(np.uint8))


def in_a_room(image, alpha, door):
    """``image`` with a room (:func:`room_behind`) behind the person (``_behind``)."""
    return _behind(image, alpha, lambda shape, rng: room_behind(shape, rng, door))


def colour_blocks(image, alpha, rows):
    """``image`` with a busy background behind the person (``_behind``): square blocks of
    random colours, ``rows`` of them down the photo, blurred by 2 px (a poster wall at 16
    rows; confetti at 64)."""
    def blocks(shape, rng):
        h, w = shape
        b = max(h // rows, 1)
        colours = rng.uniform(0, 255, (-(-h // b), -(-w // b), 3))
        return ndimage.gaussian_filter(np.repeat(np.repeat(colours, b, 0), b, 1)[:h, :w],
                                       (2.0, 2.0, 0))

    return _behind(image, alpha, blocks)


def cut_out(image, alpha, under=255):
    """The person cut out as a background remover gives it: RGBA, the render's alpha,
    ``under`` (white) left under the transparent pixels."""
    rgb = np.asarray(image).copy()
    a = np.round(255 * alpha).astype(np.uint8)
    rgb[a == 0] = under
    return Image.fromarray(np.dstack([rgb, a]))


def glasses(image, head, face, *_):
    """Dark-framed glasses drawn from the detected face's keypoints: on a front photo a
    rim around each eye, the bridge between them and the arms out past the ears; on a
    profile the rim in front of the eye and the arm back to the ear (the face's box taken
    as 15 cm: rims 2 mm thick, 4 cm by 3 cm)."""
    out = image.copy()
    draw = ImageDraw.Draw(out)
    k, size = np.asarray(face.keypoints, float), float(face.box[2] - face.box[0])
    frame, width = (20, 20, 24), max(int(round(0.013 * size)), 1)
    rx, ry = 0.13 * size, 0.1 * size
    if face.is_profile:
        eye, ear = k[:2].mean(0), k[4]
        ahead = np.sign(k[2, 0] - ear[0])
        rim = eye[0] + ahead * 0.09 * size
        draw.line([(rim, eye[1] - ry), (rim, eye[1] + 0.8 * ry)], fill=frame, width=2 * width)
        draw.line([(rim, eye[1] - 0.5 * ry), tuple(ear)], fill=frame, width=width)
        return out
    for e in k[:2]:
        draw.ellipse([e[0] - rx, e[1] - ry, e[0] + rx, e[1] + ry], outline=frame, width=width)
    inner = sorted(k[:2], key=lambda e: e[0])
    draw.line([(inner[0][0] + rx, inner[0][1] - 0.3 * ry),
               (inner[1][0] - rx, inner[1][1] - 0.3 * ry)], fill=frame, width=width)
    for e, ear in ((inner[0], min(k[4:6], key=lambda p: p[0])),
                   (inner[1], max(k[4:6], key=lambda p: p[0]))):
        side = np.sign(ear[0] - e[0])
        draw.line([(e[0] + side * rx, e[1] - 0.3 * ry),
                   (ear[0] + side * 0.08 * size, e[1] - 0.1 * ry)], fill=frame, width=width)
    return out


#: name -> (PIL RGB image, the true head's pixels (H, W) bool, its detected face, the
#: person's pixels (H, W) bool) -> PIL RGB image
VARIANTS = {
    "hair": hair,
    "thick_hair": thick_hair,
    "beard": beard,
    "glasses": glasses,
    "bare": bare,
    "room": lambda im, head, face, person, alpha: in_a_room(im, alpha, "painted"),
    "wood": lambda im, head, face, person, alpha: in_a_room(im, alpha, "wood"),
    "blocks": lambda im, head, face, person, alpha: colour_blocks(im, alpha, 16),
    "confetti": lambda im, head, face, person, alpha: colour_blocks(im, alpha, 64),
    "cut_out": lambda im, head, face, person, alpha: cut_out(im, alpha),
    "grey": lambda im, *_: im.convert("L").convert("RGB"),
    "grey_hair": lambda im, head, face, *_: hair(im, head, face).convert("L").convert("RGB"),
    "small": lambda im, *_: Image.fromarray(padded(np.asarray(im), {}, 4)[0]),
    "jpeg50": lambda im, *_: _jpeg(im),
    "dark": lambda im, *_: Image.fromarray((np.asarray(im) * 0.5).astype(np.uint8)),
    "overexposed": lambda im, *_: Image.fromarray(
        np.clip(np.asarray(im) * 1.2, 0, 255).astype(np.uint8)),
    "turned10": lambda im, *_: im.rotate(10, Image.BICUBIC, expand=True, fillcolor=_corner(im)),
    "turned25": lambda im, *_: im.rotate(25, Image.BICUBIC, expand=True, fillcolor=_corner(im)),
    "turned45": lambda im, *_: im.rotate(45, Image.BICUBIC, expand=True, fillcolor=_corner(im)),
    "cropped": lambda im, *_: im.crop((0, im.height // 8, im.width, im.height)),
    "tight": tight,
    "blurred": lambda im, *_: im.filter(ImageFilter.GaussianBlur(2)),
    "noisy": lambda im, *_: _noisy(im),
    "warm": lambda im, *_: _cast(im, (1.15, 1.0, 0.8)),
    "cool": lambda im, *_: _cast(im, (0.85, 1.0, 1.15)),
}


#: The variants a real photo can be given: they change the photo alone, not the render's
#: head or person (``--james``).
PHOTO_ONLY = ("grey", "small", "jpeg50", "dark", "overexposed", "turned10", "turned25",
              "turned45", "cropped", "blurred", "noisy", "warm", "cool")


def photo_path(folder, view):
    """A rendered head's photo of ``view`` ("front", "side"): its PNG, or the JPEG a render
    with a lens writes."""
    png = Path(folder) / f"{view}.png"
    return png if png.is_file() else Path(folder) / f"{view}.jpg"


def changed(folder, variant, into, detector):
    """The head's two photos changed by ``VARIANTS[variant]``, written into ``into`` (as
    PNG). A variant takes (photo, the head's pixels, the detected face, the person's pixels,
    the person's alpha in [0, 1])."""
    into.mkdir(parents=True, exist_ok=True)
    truth = np.load(folder / "truth.npz", allow_pickle=True)
    for view in ("front", "side"):
        image = Image.open(photo_path(folder, view)).convert("RGB")
        face = detector.detect(np.asarray(image))
        alpha = truth[f"alpha_{view}"]
        VARIANTS[variant](image, truth[f"head_alpha_{view}"] >= 128, face, alpha >= 128,
                          alpha / 255.0).save(into / f"{view}.png")
    return into


def james_errors(folder, variants, detector, model, samples=4000):
    """Face RMS (mm) against the scan james (``bench_realistic``'s scoring) of the fit from
    its own two photos (its texture's halves: real three-quarter photos) through ``solver
    detect``: {"mean head": ..., "as photographed": ..., variant: ...} for each of
    ``variants`` in ``PHOTO_ONLY`` (the others need a render's masks), NaN where the photos
    are refused."""
    from bench.bench_realistic import SCAN_SEED, scan_truth
    from bench.realistic_cases import load_scan
    from solver.detect.detected_case import detect_photos

    truth = scan_truth(model, load_scan(folder), samples, np.random.default_rng(SCAN_SEED))
    halves = {name: Image.fromarray(photo) for name, photo in scan_photo_halves(folder).items()}
    out = {"mean head": truth.score(model.vertices)["face"]}
    for variant in [None] + [v for v in variants if v in PHOTO_ONLY]:
        photos = {name: np.asarray(photo if variant is None else
                                   VARIANTS[variant](photo, None, None, None, None))
                  for name, photo in halves.items()}
        try:
            case = detect_photos([(None, name) for name in photos], detector,
                                 photos.__getitem__)
        except ValueError as err:
            print(f"  james {variant or 'as photographed'}: {err}")
            out[variant or "as photographed"] = float("nan")
            continue
        out[variant or "as photographed"] = truth.score(
            fit_head(model, case).local_vertices)["face"]
    return out


def face_error_mm(model, local, truth_local):
    """RMS vertex distance over the face region (``model_face_vertices``), mm, after a
    similarity laying ``local`` on ``truth_local`` there (V, 3) m."""
    face = model_face_vertices(model)
    a, b = local[face], truth_local[face]
    sim = similarity_procrustes(a, b)
    return 1000.0 * float(np.sqrt(((sim.apply(a) - b) ** 2).sum(axis=1).mean()))


def profile_line_table(folders, variants, detector):
    """Print, per variant (None: as rendered), how far the profile line's points read off
    the heads' detected profile outlines lie from their own profile landmarks; returns
    them: {variant or "as rendered": {point: [error, % of the face's size, per profile
    that gave it]}}."""
    table = {}
    print("profile line read off the detected profile outline vs the head's own landmarks, "
          "% of the face's size: median / p90 / max (profiles that gave it)")
    print(f"  {'variant':<12}" + "".join(f"{n:>18}" for n in PROFILE_LINE))
    with tempfile.TemporaryDirectory() as tmp:
        for variant in [None] + variants:
            errors = {n: [] for n in PROFILE_LINE}
            for folder in folders:
                photos = folder if variant is None else \
                    changed(folder, variant, Path(tmp) / f"{folder.name}_{variant}", detector)
                truth = load_landmarks(folder / "sample.json").views["side"].points
                image = np.asarray(Image.open(photos / "side.png").convert("RGB"))
                err, _, size, _ = read_profile_line(detector, image, truth)
                for n, e in err.items():
                    errors[n].append(100.0 * e / size)
            print(f"  {variant or 'as rendered':<12}" + "".join(
                f"{np.median(e):5.1f}/{np.percentile(e, 90):4.1f}/{max(e):4.1f} {len(e):>2}"
                if e else f"{'-':>18}" for e in errors.values()), flush=True)
            table[variant or "as rendered"] = errors
    return table


#: A turned photo's points (``turn_table``) agree with the photo's own to within this share
#: of the face's size, median: the same pixels detected upright agree exactly, a face left
#: 65 degrees from level (between two quarter turns) came 0.8-1.8 % off.
TURN_AGREE = 0.005


def turn_table(folders, variants, detector, james=None):
    """Print, per variant (None: as rendered), how the detection finds the turn that shows
    a photo's face upright (``DetectedFace.turn``): each head's two photos (and james' two,
    ``james``: the folder of james.obj, as rendered only) detected as given and turned by
    one, two and three quarter turns. Counts: the photos, those read as profiles as given
    (a profile turned is found only where the photo turned back shows a face that is not a
    profile: not counted turned), those given a turn as given (wrongly), and the turned
    photos of the others with no face found, or whose points, given back on the photo as
    it was, lie further than ``TURN_AGREE`` of the face's size (median) from the points
    found as given (missed: a turn not found, or a poor one); and the smallest margin of
    the detector's confidence as given, upright less upside down.
    Returns {variant or "as rendered": counts}."""
    table = {}
    print("photos turned: detected as given and turned by 1, 2 and 3 quarter turns "
          "(no fits)")
    print(f"  {'variant':<12}{'photos':>8}{'profiles':>10}{'wrong':>7}{'missed':>8}"
          f"{'min margin':>12}")
    extra = {}
    if james:
        extra = {f"james {k}": v for k, v in scan_photo_halves(Path(james)).items()}
    with tempfile.TemporaryDirectory() as tmp:
        for variant in [None] + variants:
            photos = [] if variant else list(extra.values())
            for folder in folders:
                where = folder if variant is None else \
                    changed(folder, variant, Path(tmp) / f"{folder.name}_{variant}", detector)
                photos += [np.asarray(Image.open(photo_path(where, v)).convert("RGB"))
                           for v in ("front", "side")]
            n = profiles = wrong = missed = 0
            margins = []
            for image in photos:
                face = detector.detect(image)
                if face is None:
                    continue
                n += 1
                wrong += face.turn != 0
                if face.is_profile:
                    profiles += 1
                    continue
                h, w = image.shape[:2]
                points = face.in_photo(face.ibug)
                for k in (1, 2, 3):
                    seen = detector.detect(turned(image, k))  # None: no face found (missed)
                    if k == 2 and seen is not None:
                        margins.append(face.score - (seen.given_score if seen.turn
                                                     else seen.score))
                    missed += seen is None or np.median(np.linalg.norm(
                        seen.in_photo(seen.ibug) - to_turned(points, k, (w, h)), axis=1)) \
                        > TURN_AGREE * face.face_size
            row = {"photos": n, "profiles": profiles, "wrong": wrong, "missed": missed,
                   "margin": min(margins, default=np.nan)}
            print(f"  {variant or 'as rendered':<12}{n:>8}{profiles:>10}{wrong:>7}{missed:>8}"
                  f"{row['margin']:>12.2f}", flush=True)
            table[variant or "as rendered"] = row
    return table


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", nargs="*", choices=list(VARIANTS), default=list(VARIANTS))
    ap.add_argument("--face", action="store_true",
                    help="score the face region alone, not the whole head")
    ap.add_argument("--profile-line", action="store_true",
                    help="no fits: score the profile line's points read off each profile "
                         "photo's detected outline against the head's own landmarks")
    ap.add_argument("--turned", action="store_true",
                    help="no fits: each photo detected as given and turned by 1-3 quarter "
                         "turns, counting the photos given a turn wrongly and missed")
    ap.add_argument("--james", default=None, metavar="DIR",
                    help="also the scan james' own two photos (the folder of james.obj) "
                         "through the variants a real photo can be given, scored against "
                         "the scan's face")
    add_head_options(ap)
    args = ap.parse_args(argv)
    print(f"machine: {machine_description()}")
    folders = chosen_folders(args)
    detector = Detector()
    if args.profile_line:
        profile_line_table(folders, args.variants, detector)
        return
    if args.turned:
        turn_table(folders, args.variants, detector, args.james)
        return
    model = load_model()
    columns = ["mean head", "as rendered"] + args.variants
    score = face_error_mm if args.face else skin_error_mm
    print(f"{'face region' if args.face else 'skin'} RMS vs the true head, mm, from the "
          "photos alone")
    print(f"  {'head':<10}" + "".join(f"{c:>12}" for c in columns))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for folder in folders:
            truth = np.load(folder / "truth.npz", allow_pickle=True)["local_vertices"]
            row = [score(model, model.vertices, truth)]
            for variant in [None] + args.variants:
                photos = folder if variant is None else \
                    changed(folder, variant, Path(tmp) / f"{folder.name}_{variant}", detector)
                try:
                    case = photos_case(photos, detector)
                except ValueError as err:
                    print(f"  {folder.name} {variant}: {err}")
                    row.append(np.nan)
                    continue
                row.append(score(model, fit_head(model, case).local_vertices, truth))
            rows.append(row)
            print(f"  {folder.name:<10}" + "".join(f"{v:>12.2f}" for v in row), flush=True)
    a = np.array(rows)
    print(f"  {'mean':<10}" + "".join(f"{v:>12.2f}" for v in np.nanmean(a, axis=0)))
    print(f"  {'worst':<10}" + "".join(f"{v:>12.2f}" for v in np.nanmax(a, axis=0)))
    beats = (a[:, 1:] < a[:, :1]).sum(axis=0)
    print(f"  {'beat mean':<10}" + " " * 12 + "".join(f"{f'{b} of {len(a)}':>12}"
                                                     for b in beats))
    if args.james:
        errors = james_errors(Path(args.james), args.variants, detector, model)
        print("james' own photos (real, three-quarter views) through solver detect, face "
              "RMS vs the scan, mm:")
        print("  " + "".join(f"{k:>16}" for k in errors))
        print("  " + "".join(f"{v:>16.2f}" for v in errors.values()))


if __name__ == "__main__":
    main()

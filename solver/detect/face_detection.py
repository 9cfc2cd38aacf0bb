"""Faces in a photo with MediaPipe's short-range BlazeFace model
(``face_detection_short_range.tflite``): the whole photo letterboxed into 128 px (then,
if no face is found, overlapping parts of it), 896 SSD anchors decoded into boxes and six
keypoints, weighted non-maximum suppression.

The settings are those of MediaPipe's ``face_detection_short_range.pbtxt``: anchors of
strides 8, 16, 16, 16 (fixed size), scale 128, score sigmoid clipped at ±100, minimum
score 0.5, suppression at IoU 0.3 with score-weighted averaging.
"""

from dataclasses import dataclass

import numpy as np

from .crop import Square, crop, shrink, shrunk_square, unshrink

INPUT = 128
MIN_SCORE = 0.5
MIN_SUPPRESSION_IOU = 0.3
#: A photo whose whole shows no face is searched in squares of half and a quarter of its
#: longer side, none smaller than ``MIN_TILE`` px: a face down to about 4 % of the
#: photo's longer side is found (docs/DECISIONS.md, "Small faces").
TILE_LEVELS = 2
MIN_TILE = 256
#: A face narrower than this fraction of the square it was found in is found again in a
#: square it fills by ``FACE_FILL`` (the sample's and james' photos: 0.40-0.42 of the
#: photo, left as they are).
SMALL_FACE = 0.3
FACE_FILL = 0.45
#: The detector's keypoints, in its order (sides are the subject's own).
KEYPOINTS = ("eye_right", "eye_left", "nose_tip", "mouth_center", "tragion_right",
             "tragion_left")


@dataclass
class Face:
    """One detected face: ``box`` (u_min, v_min, u_max, v_max) px, ``keypoints`` (6, 2)
    px in ``KEYPOINTS`` order, ``score`` in (0, 1)."""

    box: np.ndarray
    keypoints: np.ndarray
    score: float


def anchors():
    """Anchor centres (896, 2) in the unit square, in the model's output order."""
    out = []
    for stride, per_cell in ((8, 2), (16, 6)):
        m = INPUT // stride
        c = (np.arange(m) + 0.5) / m
        yy, xx = np.meshgrid(c, c, indexing="ij")
        xy = np.stack([xx.ravel(), yy.ravel()], axis=1)
        out.append(np.repeat(xy, per_cell, axis=0))
    return np.concatenate(out)


def decode(regressors, scores):
    """Raw outputs (896, 16) and (896,) -> boxes (N, 4) (x0, y0, x1, y1), keypoints
    (N, 6, 2), both in the unit square, and scores (N,)."""
    a = anchors()
    r = np.asarray(regressors, float) / INPUT
    centre = r[:, :2] + a
    half = r[:, 2:4] / 2
    boxes = np.concatenate([centre - half, centre + half], axis=1)
    keypoints = r[:, 4:16].reshape(-1, 6, 2) + a[:, None, :]
    score = 1 / (1 + np.exp(-np.clip(np.asarray(scores, float).ravel(), -100, 100)))
    return boxes, keypoints, score


def _iou(box, boxes):
    lo = np.maximum(box[:2], boxes[:, :2])
    hi = np.minimum(box[2:], boxes[:, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=1)
    area = lambda b: np.prod(np.clip(b[..., 2:] - b[..., :2], 0, None), axis=-1)  # noqa: E731
    union = area(box) + area(boxes) - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1), 0.0)


def weighted_nms(boxes, keypoints, score, min_score=MIN_SCORE, iou=MIN_SUPPRESSION_IOU):
    """MediaPipe's weighted suppression: the best remaining box takes every box
    overlapping it by more than ``iou``, averaged by score (box and keypoints).

    Returns
    -------
    list of (box (4,), keypoints (6, 2), score)
        Best first.
    """
    keep = np.flatnonzero(score >= min_score)
    keep = keep[np.argsort(-score[keep], kind="stable")]
    out = []
    while keep.size:
        overlap = _iou(boxes[keep[0]], boxes[keep]) > iou
        group = keep[overlap]
        w = score[group][:, None]
        out.append(((boxes[group] * w).sum(0) / w.sum(),
                    (keypoints[group] * w[:, :, None]).sum(0) / w.sum(),
                    float(score[keep[0]])))
        keep = keep[~overlap]
    return out


def _faces_in(network, image, square, min_score):
    """Faces the model finds in one ``square`` of ``image``, in photo pixels, best
    first."""
    x = crop(image, square, INPUT, border="zero") * 2 - 1
    regressors, scores = network(x[None])
    boxes, keypoints, score = decode(regressors[0], scores[0])
    faces = []
    for box, kp, s in weighted_nms(boxes, keypoints, score, min_score):
        corners = square.to_photo(box.reshape(2, 2) * INPUT, INPUT).ravel()
        faces.append(Face(corners, square.to_photo(kp * INPUT, INPUT), s))
    return faces


def _tiles(w, h, side):
    """Squares of ``side`` px covering a (``w``, ``h``) photo, each overlapping the next
    by half, so any face under half a side lies wholly inside one."""
    def centres(length):
        n = max(1, int(np.ceil((length - side) / (side / 2))) + 1)
        return np.linspace(side / 2, max(length - side / 2, side / 2), n)
    return [Square((float(u), float(v)), side) for v in centres(h) for u in centres(w)]


def _faces_in_tiles(network, image, side, min_score):
    """Faces in the overlapping squares of ``side`` px (:func:`_tiles`), best first, one
    each; the photo is shrunk once for all of them (as each square's crop would be)."""
    h, w = image.shape[:2]
    k = max(int(side / INPUT / 1.5), 1)
    small = shrink(image, k) if k > 1 else image
    faces = []
    for square in _tiles(w, h, side):
        faces += [Face(unshrink(f.box.reshape(2, 2), k).ravel(), unshrink(f.keypoints, k),
                       f.score)
                  for f in _faces_in(network, small, shrunk_square(square, k), min_score)]
    return _distinct(faces)


def _distinct(faces):
    """``faces`` best first, without those overlapping a better one (the same face found
    in two tiles)."""
    faces = sorted(faces, key=lambda f: -f.score)
    out = []
    for f in faces:
        if not out or not np.any(_iou(f.box, np.array([g.box for g in out]))
                                 > MIN_SUPPRESSION_IOU):
            out.append(f)
    return out


def detect_faces(network, image, min_score=MIN_SCORE):
    """Faces in ``image`` (H, W, 3) float32 in [0, 1], the widest first: the subject of a
    portrait or profile is the largest face in it. The most confident is not: a profile
    scores lower than a smaller face looking at the camera behind it (docs/DECISIONS.md,
    "Another face in the photo").

    The model sees the whole photo in 128 px, where a face narrower than about a fifth of
    the photo's longer side is not found (docs/DECISIONS.md, "Small faces"); then it sees
    halves and quarters of it in overlapping squares (``TILE_LEVELS``, none under
    ``MIN_TILE`` px). The widest face, if small in the square it was found in
    (``SMALL_FACE``), is found once more in a square around it that it fills as a
    portrait's face fills its photo (``FACE_FILL``): its box and keypoints come out as
    on a portrait.

    Parameters
    ----------
    network : Network
        The short-range face detection model.
    """
    h, w = image.shape[:2]
    side = float(max(h, w))
    faces = _faces_in(network, image, Square((w / 2, h / 2), side), min_score)
    for _ in range(TILE_LEVELS):
        if faces or side / 2 < MIN_TILE:
            break
        side /= 2
        faces = _faces_in_tiles(network, image, side, min_score)
    faces = sorted(faces, key=lambda f: -(f.box[2] - f.box[0]))  # stable: then by score
    if faces and faces[0].box[2] - faces[0].box[0] < SMALL_FACE * side:
        box = faces[0].box
        square = Square(((box[0] + box[2]) / 2, (box[1] + box[3]) / 2),
                        float(box[2] - box[0]) / FACE_FILL)
        again = _faces_in(network, image, square, min_score)
        if again:
            faces = again[:1] + faces[1:]
    return faces

"""Render the sample case: front and side photos of a head drawn from the model, with its
landmarks file and the ground truth.

    python -m tools.make_sample [--out generated/sample] [--seed N] [--size WxH]
                                [--samples N] [--force] [--lens MM] [--yaw DEG]
                                [--pitch DEG] [--side-deg DEG] [--skin TONE]
                                [--expression NAME]

A head is sampled from the identity model (seeded), turned a few degrees like a person who
does not sit perfectly straight, and rendered with Cycles (CPU) through orthographic
cameras from the front and from the subject's right: ``front.png`` and ``side.png``
(with ``--lens``, pinhole cameras of that lens as close as it frames the head alike:
``front.jpg`` and ``side.jpg`` with the lens in their EXIF, as a camera writes them;
with ``--yaw``, the head turned further: three-quarter photos; with ``--pitch``, the head
nodded (the face tipped down, or up when negative) in both photos; with ``--side-deg``, the
side photo taken that many degrees from the front camera's direction, short of a profile;
with ``--expression``, the face in both photos showing one of ``EXPRESSIONS``, the truth
still the neutral head a fit should find).
The person wears a plain shirt whose collar hides the model's neck cut, as in a real
photo. ``sample.json`` is the landmarks file a user would make: every landmark visible in
a view (``assets/landmarks.json`` "views", minus any the shirt covers) projected by the
Blender camera plus ~1 px of placement noise, and the side photo's head outline traced
from the render's alpha of the head alone, from the collar at the front of the neck over
the face and skull to the collar at the back. ``truth.npz`` holds what a test measures
the fit against: the true vertices, coefficients, pose, cameras, exact landmark pixels
and alpha masks. ``overlay_*.png`` show the points on the photos for a visual check.

Outputs are made once and reused: the run is skipped while the files exist and were made
with the same parameters and model (``--force`` redoes them). Everything is written into a
temporary folder that replaces the output folder at the end, so an interrupted run never
leaves a half sample behind.
"""

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from solver import (
    LandmarkCase,
    OrthographicCamera,
    PinholeCamera,
    View,
    load_landmarks,
    load_model,
    save_landmarks,
)
from solver.geometry import distance_to_segments
from solver.synthetic import (
    _longest_cyclic_run,
    _moore_trace,
    resample_polyline,
)

# Bump when the output changes for the same parameters (forces a re-render).
SAMPLE_VERSION = 2

REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUT = REPO_ROOT / "generated" / "sample"
DEFAULT_SEED = 7
DEFAULT_SIZE = (768, 1024)  # the thesis' photo size
DEFAULT_SAMPLES = 16
NOISE_PX = 1.0  # landmark placement noise (standard deviation, pixels at 1024 px height)
CONTOUR_POINTS = 128
MAX_TILT_DEG = 3.0
TOP_MARGIN = (0.04, 0.07)  # space above the head, fraction of the image height
SIDE_SCALE = 0.98  # the side photo is a second shot: slightly different scale
#: Expressions a sample's face can show (``--expression``): model expression weights of the
#: size people show when photographed (the middles of ``bench_realistic``'s ranges).
EXPRESSIONS = {"smile": {"mouthSmile_L": 0.4, "mouthSmile_R": 0.4},
               "eyes_closed": {"eyeBlink_L": 0.9, "eyeBlink_R": 0.9},
               "jaw_open": {"jawOpen": 0.2}}
# view name -> nominal camera (the fit handles orthographic front/right/left views)
VIEWS = {"front": "orthographic-front", "side": "orthographic-right"}
FILES = ("front.png", "side.png", "truth.npz", "sample.json")

# The eyes are the add-on's (headrecon_addon/material.py: eye material, eyeball layout).
# Parts made for Unreal's digital-human eye shaders (wet film, soft shadow) and the
# eyelashes' alpha-textured strips: drawn opaque they would be grey sheets over the eyes.
HIDDEN_PART_WORDS = ("lacrimal", "blend", "occlusion", "eyelash")


# --------------------------------------------------------------------------- head


def rotation_from_euler(yaw, pitch, roll):
    """Rotation matrix (3, 3) of a head turned by ``yaw`` (about Z), nodding by ``pitch``
    (about X) and tilted by ``roll`` (about Y), degrees, applied roll, pitch, then yaw."""
    y, p, r = np.radians([yaw, pitch, roll])
    rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, np.cos(p), -np.sin(p)], [0, np.sin(p), np.cos(p)]])
    ry = np.array([[np.cos(r), 0, np.sin(r)], [0, 1, 0], [-np.sin(r), 0, np.cos(r)]])
    return rz @ rx @ ry


def sample_head(model, seed, yaw_deg=0.0, pitch_deg=0.0):
    """A seeded identity and pose; ``yaw_deg`` turns the head further about the vertical
    (toward the subject's right camera when negative: the front photo then shows a
    three-quarter view, the side photo one nearer the front), ``pitch_deg`` nods it about
    the left-right axis (positive: the face tipped down, the chin toward the chest).

    Returns
    -------
    coeffs : ndarray, shape (K,)
        Identity coefficients (standard deviations), N(0, 1) clipped to +-2.5.
    local : ndarray, shape (V, 3), metres
    rotation : ndarray, shape (3, 3)
    translation : ndarray, shape (3,), metres
    """
    rng = np.random.default_rng(seed)
    coeffs = np.clip(rng.standard_normal(model.identity.n_coeffs), -2.5, 2.5)
    local = model.identity.instance(coeffs)
    yaw, pitch, roll = rng.uniform(-MAX_TILT_DEG, MAX_TILT_DEG, 3)
    rotation = rotation_from_euler(yaw, pitch, roll)
    if yaw_deg or pitch_deg:
        rotation = rotation_from_euler(float(yaw_deg), float(pitch_deg), 0.0) @ rotation
    translation = rng.uniform(-0.01, 0.01, 3)
    return coeffs, local, rotation, translation


def frame_cameras(world, collar_z, size, seed, side_deg=90.0):
    """Orthographic cameras that frame the head like a portrait photo: the top of the head
    a little below the top edge, head and collar as large as the narrower side allows,
    the shoulders below. The front and side photos differ slightly in scale and centring
    (they are two shots).

    Parameters
    ----------
    world : ndarray, shape (V, 3), metres
        The posed head.
    collar_z : float, metres
        Height of the shirt's collar: what lies above it is framed.
    size : (int, int)
    seed : int
    side_deg : float
        The side camera's direction, degrees from the front camera's toward the subject's
        right (90: an exact profile).

    Returns
    -------
    dict of str -> OrthographicCamera
        Keyed by view name (``VIEWS``).
    """
    w, h = size
    rng = np.random.default_rng(seed + 1)
    head = world[world[:, 2] > collar_z]
    top_z = head[:, 2].max()
    rotations = {view: view_camera(view, size, side_deg).rotation for view in VIEWS}
    span_u = max(np.ptp(head @ r[0]) for r in rotations.values())
    scale = min(0.88 * h / (top_z - collar_z + 0.03), 0.86 * w / span_u)
    cams = {}
    for view, kind in VIEWS.items():
        s = scale * (SIDE_SCALE if view == "side" else 1.0)
        u = head @ rotations[view][0]
        du = rng.uniform(-0.02, 0.02) * w
        # v = s * (-z) + offset_v: the top of the head a few per cent below the top edge
        offset = np.array([w / 2.0 + du - s * (u.min() + u.max()) / 2.0,
                           rng.uniform(*TOP_MARGIN) * h + s * top_z])
        cams[view] = OrthographicCamera(rotations[view], s, offset, size, kind)
    return cams


def view_camera(view, size, side_deg=90.0):
    """The orthographic camera ``sample.json`` gives a view: its nominal one, the side's
    turned to ``side_deg`` (degrees from the front camera's direction) when not 90."""
    if view == "side" and float(side_deg) != 90.0:
        return OrthographicCamera.turned(VIEWS[view], size, side_deg)
    return OrthographicCamera.nominal(VIEWS[view], size)


def perspective_cameras(cameras, world, lens_mm):
    """Pinhole cameras of the lens ``lens_mm`` (36 mm equivalent) standing where they see
    the head at the centre of its depth as ``cameras`` (orthographic) frame it: a photo
    taken as close as the lens asks for that framing (50 mm: about half a metre), moved
    back by 5 % at a time while the nearer parts of the head, larger in the photo, would
    leave it.

    Parameters
    ----------
    cameras : dict of str -> OrthographicCamera
    world : ndarray, shape (V, 3), metres
    lens_mm : float

    Returns
    -------
    dict of str -> PinholeCamera
    """
    out = {}
    for view, cam in cameras.items():
        w, h = cam.size
        r = cam.rotation
        depth = float(np.median(world @ r[2]))
        # the world point the orthographic photo shows at its centre, at the head's depth
        target = r.T @ np.array([(w / 2.0 - cam.offset[0]) / cam.scale,
                                 (h / 2.0 - cam.offset[1]) / cam.scale, depth])
        f_px = float(lens_mm) * PinholeCamera.px_per_mm(cam.size)
        distance = f_px / cam.scale
        for _ in range(40):
            pin = PinholeCamera.look_at(target - distance * r[2], target, cam.size,
                                        f_px=f_px, up=-r[1])
            px = pin.project(world)
            if px.min() >= 0 and px[:, 0].max() <= w and px[:, 1].max() <= h:
                break
            distance *= 1.05
        out[view] = pin
    return out


def save_jpeg(path, rgb, lens_mm):
    """A photo as a camera writes it: JPEG (quality 95) whose EXIF gives the lens's 36 mm
    equivalent focal length (``FocalLengthIn35mmFilm``, by the diagonal as cameras state
    it, an integer: within 0.5 mm of ``lens_mm``)."""
    from solver.io import exif as exif_tags

    img = Image.fromarray(np.clip(np.round(np.asarray(rgb) * 255.0), 0, 255).astype(np.uint8))
    w, h = img.size
    diagonal = lens_mm * (exif_tags.FULL_FRAME_DIAGONAL_MM / exif_tags.FULL_FRAME_LONG_MM) \
        * max(w, h) / np.hypot(w, h)  # the inverse of Exif.lens_36mm's rescaling
    data = Image.Exif()
    data.get_ifd(exif_tags.EXIF_IFD)[exif_tags.FOCAL_35MM] = int(round(diagonal))
    img.save(path, "JPEG", quality=95, exif=data)


def _polygon_signed_distance(points, polygon):
    """Distance of 2-D points (n, 2) to a closed polygon's (m, 2) edges, positive inside,
    shape (n,), in the points' unit."""
    a = polygon
    b = np.roll(polygon, -1, axis=0)
    d = distance_to_segments(points, a, b)
    # crossing number: edges straddling the point's horizontal line, crossing to its right
    y0, y1 = a[:, 1][None], b[:, 1][None]
    py, px = points[:, 1:2], points[:, 0:1]
    straddle = (y0 > py) != (y1 > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[:, 0][None] + (py - y0) * (b[:, 0] - a[:, 0])[None] / (y1 - y0)
    inside = ((straddle & (px < xc)).sum(axis=1) % 2) == 1
    return np.where(inside, d, -d)


def _smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def appearance_attributes(model):
    """Per-vertex weights the skin and eye shaders read, from the mean shape.

    Regions are found from landmarks on the mean head seen from the front (x, z), so they
    follow the vertices through any identity.

    Returns
    -------
    dict of str -> ndarray (V,)
        ``lips``, ``brows``, ``blush``, ``lash`` in [0, 1], and the eye material's attribute
        (``material.EYE_ATTRIBUTE``, see ``material.eye_attribute``).
    """
    from headrecon_addon import material

    v = model.vertices
    n = len(v)
    face_part = np.zeros(n, dtype=bool)
    face_part[model.skin] = True
    xz = v[:, [0, 2]]

    def lm(i):
        return v[model.landmark_vertex(f"ibug{i:02d}")]

    out = {}
    # Lips: inside the outer lip line (ibug 49-60), only on the front of the head.
    outer = np.array([lm(i) for i in range(49, 61)])
    front = face_part & (v[:, 1] < outer[:, 1].max() + 0.008)
    sd = _polygon_signed_distance(xz, outer[:, [0, 2]])
    out["lips"] = np.where(front, _smoothstep(-0.0004, 0.0012, sd), 0.0)

    # Brows: a band under each brow line (ibug 18-22 right, 23-27 left), thick at the
    # inner end and tapering outward.
    brows = np.zeros(n)
    for idx in (range(18, 23), range(23, 28)):
        line = np.array([lm(i) for i in idx])
        inner, outer_end = (line[-1], line[0]) if idx.start == 18 else (line[0], line[-1])
        order = np.argsort(line[:, 0])
        zl = np.interp(v[:, 0], line[order, 0], line[order, 2])
        s = (v[:, 0] - inner[0]) / (outer_end[0] - inner[0])  # 0 inner .. 1 outer
        half = 0.0042 * (1.0 - s) + 0.0022 * s
        centre = zl - 0.0018
        across = _smoothstep(half + 0.0012, half - 0.0008, np.abs(v[:, 2] - centre))
        along = _smoothstep(-0.12, 0.05, s) * _smoothstep(1.12, 0.95, s)
        near = face_part & (v[:, 1] < line[:, 1].max() + 0.012)
        brows = np.maximum(brows, np.where(near, across * along, 0.0))
    out["brows"] = brows

    # Blush: warm cheeks and nose tip (soft Gaussian spots on the front).
    spots = [(lm(31), 0.012, 0.5)]
    for nose_side, jaw in ((32, 4), (36, 14)):
        spots.append((0.55 * lm(nose_side) + 0.45 * lm(jaw), 0.02, 0.6))
    blush = np.zeros(n)
    for c, sigma, amp in spots:
        d2 = ((xz - c[[0, 2]]) ** 2).sum(axis=1)
        blush = np.maximum(blush, amp * np.exp(-d2 / (2 * sigma**2)))
    out["blush"] = np.where(face_part & (v[:, 1] < lm(31)[1] + 0.06), blush, 0.0)

    # Lash line: dark upper lid margin (the lashes themselves are left out), faint lower.
    edges, label = skin_border(model)
    on_border = np.unique(edges)
    lash = np.zeros(n)
    for side in ("right", "left"):
        corners = v[[model.landmark_vertex(f"eye_inner_{side}"),
                     model.landmark_vertex(f"eye_outer_{side}")]]
        centre = corners.mean(axis=0)
        nearest = on_border[np.argmin(np.linalg.norm(v[on_border] - centre, axis=1))]
        rim = v[on_border[label[on_border] == label[nearest]]]
        near = np.flatnonzero(face_part & (np.linalg.norm(v - centre, axis=1) < 0.03))
        d = np.linalg.norm(v[near, None, :] - rim[None], axis=2)
        upper = rim[:, 2] >= centre[2]
        w_up = _smoothstep(0.0024, 0.0008, d[:, upper].min(axis=1))
        w_low = 0.4 * _smoothstep(0.0012, 0.0004, d[:, ~upper].min(axis=1))
        lash[near] = np.maximum(w_up, w_low)
    out["lash"] = lash

    out[material.EYE_ATTRIBUTE] = material.eye_attribute(v)
    return out


# --------------------------------------------------------------------------- materials


#: Skin tones (``--skin``): each scales the skin's albedo (its tone, blush and lips) per
#: linear RGB channel. "light" is the sample's own; "medium" a tan brown, "dark" a deep
#: brown (linear albedo about 0.13, 0.07, 0.04), so the outline's and the detector's
#: colour rules are measured on more than one complexion.
SKIN_TONES = {"light": (1.0, 1.0, 1.0), "medium": (0.55, 0.48, 0.42),
              "dark": (0.22, 0.18, 0.15)}
#: Lightings (``--light``), the keys of ``render_util.LIGHTINGS`` (which needs bpy, so it is
#: not imported here): "studio" is the sample's own.
LIGHTS = ("studio", "window")


def _materials(skin_tone="light"):
    """Skin, eye, mouth, teeth, eye socket and shirt materials (procedural; the eye is the
    add-on's); the skin of ``SKIN_TONES[skin_tone]``."""
    import bpy

    from headrecon_addon import material

    # Skin: tone with blotchy variation, warm blush, darker lips, hairy brows, lash line,
    # pores.
    skin = bpy.data.materials.new("Skin")
    b = material.NodeBuilder(skin)
    obj_co = b.coordinates("Object")
    k = SKIN_TONES[skin_tone]

    def toned(rgb):
        return tuple(c * f for c, f in zip(rgb, k, strict=True))

    tone = b.ramp(b.noise(obj_co, 90.0, 4.0),
                  [(0.3, toned((0.56, 0.35, 0.26))), (0.7, toned((0.66, 0.43, 0.33)))])
    col = b.mix(b.math("MULTIPLY", b.attribute("blush"), 0.55), tone,
                toned((0.66, 0.30, 0.24)))
    lip_col = b.ramp(b.noise(obj_co, 600.0),
                     [(0.3, toned((0.38, 0.13, 0.12))), (0.7, toned((0.46, 0.18, 0.16)))])
    col = b.mix(b.attribute("lips"), col, lip_col)
    # brow hairs: streaks from noise stretched across the brow
    stretch = b.new("ShaderNodeMapping", Vector=obj_co, Scale=(0.25, 1.0, 1.0))
    hairs = b.noise(stretch.outputs["Vector"], 1500.0, 1.0)
    strands = b.math("ADD", b.math("MULTIPLY", hairs, 0.7), 0.45)  # 0.45 .. 1.15
    hair_fac = b.math("MINIMUM", b.math("MULTIPLY", b.attribute("brows"), strands), 1.0)
    col = b.mix(b.math("MULTIPLY", hair_fac, 0.95), col, (0.035, 0.02, 0.012))
    col = b.mix(b.math("MULTIPLY", b.attribute("lash"), 0.9), col, (0.02, 0.012, 0.01))
    b.set(b.bsdf.inputs["Base Color"], col)
    # No subsurface scattering: at this photo size it changes little and costs a third of
    # the render time.
    b.bsdf.inputs["Roughness"].default_value = 0.5
    b.bsdf.inputs["Specular IOR Level"].default_value = 0.35
    bump = b.new("ShaderNodeBump", Strength=0.08, Distance=0.0003,
                 Height=b.noise(obj_co, 1200.0, 3.0))
    b.set(b.bsdf.inputs["Normal"], bump.outputs["Normal"])
    b.arrange()

    def plain(name, colour, rough):
        mat = bpy.data.materials.new(name)
        bsdf = material.NodeBuilder(mat).bsdf
        bsdf.inputs["Base Color"].default_value = colour + (1.0,)
        bsdf.inputs["Roughness"].default_value = rough
        return mat

    mouth = plain("Mouth", (0.18, 0.04, 0.04), 0.4)
    teeth = plain("Teeth", (0.75, 0.72, 0.62), 0.3)
    socket = plain("Eye socket", (0.40, 0.16, 0.14), 0.3)
    shirt = bpy.data.materials.new("Shirt")
    b = material.NodeBuilder(shirt)
    weave = b.noise(b.coordinates("Object"), 400.0)
    b.set(b.bsdf.inputs["Base Color"],
          b.ramp(weave, [(0.3, (0.02, 0.03, 0.05)), (0.7, (0.03, 0.045, 0.07))]))
    b.bsdf.inputs["Roughness"].default_value = 0.9
    b.arrange()
    return {"skin": skin, "eye": material.new_part_material("Eyes"), "mouth": mouth,
            "teeth": teeth, "socket": socket, "shirt": shirt}


def face_subset(model, keep):
    """The polygons where ``keep`` (F,) is True as a mesh of their own.

    Returns
    -------
    loops : ndarray, shape (L',)
        The kept polygons' corners (indices into ``model.loop_vertex``/``loop_uv``).
    face_loop_start, face_loop_total : ndarray, shape (F',)
        Their layout in ``loops``.
    """
    start, total = model.face_loop_start[keep], model.face_loop_total[keep]
    new_start = np.concatenate([[0], np.cumsum(total)[:-1]]).astype(np.int64)
    loops = np.repeat(start - new_start, total) + np.arange(total.sum())
    return loops, new_start, total


SLOTS = ("skin", "eye", "mouth", "teeth", "socket")  # the head's material slots


def _face_materials(model):
    """Material slot of each polygon (index into ``SLOTS``), -1 for polygons left out."""
    from headrecon_addon import material

    slot_of_part = []
    for name in model.part_names:
        low = name.lower()
        if any(w in low for w in HIDDEN_PART_WORDS):
            slot_of_part.append(-1)
        elif low in ("face", "head and neck"):
            slot_of_part.append(SLOTS.index("skin"))
        elif "eyeball" in low:
            slot_of_part.append(SLOTS.index("eye"))
        elif "teeth" in low:
            slot_of_part.append(SLOTS.index("teeth"))
        elif "eye socket" in low:
            slot_of_part.append(SLOTS.index("socket"))
        else:  # mouth socket, gums and tongue
            slot_of_part.append(SLOTS.index("mouth"))
    slot = np.asarray(slot_of_part)[model.face_part]
    # leave the eyeballs' inner iris spheres out: the sclera hides them (material.py)
    first = model.loop_vertex[model.face_loop_start]
    for i0, i1 in material.IRIS_RANGES:
        slot[(first >= i0) & (first <= i1)] = -1
    return slot


# --------------------------------------------------------------------------- contour


def side_contour(alpha, cut_pixels, n_points=CONTOUR_POINTS, margin=None):
    """The side photo's head outline in drawing order, from the front of the neck over the
    face and skull to the back of the neck, without the stretch where the collar (or the
    image's border) cuts the neck off.

    Parameters
    ----------
    alpha : ndarray, shape (h, w), float in [0, 1]
        Alpha of the head alone in the side view.
    cut_pixels : ndarray, shape (m, 2)
        The closed line that cuts the neck off (the collar's rim) projected into the side
        view, pixels, in order around the neck.
    n_points : int
        Points returned, evenly spaced along the outline.
    margin : float, optional
        Outline pixels closer than this to the cut are dropped (default 1 % of the
        image height: the collar's cloth is a few pixels thick).

    Returns
    -------
    ndarray, shape (n_points, 2)
        (u, v) pixels, pixel centres (a boundary pixel (r, c) is at (c + 0.5, r + 0.5)).
    """
    margin = 0.01 * alpha.shape[0] if margin is None else margin
    mask = alpha >= 0.5
    rc = _moore_trace(mask)
    pts = rc[:, ::-1].astype(np.float64) + 0.5
    h, w = mask.shape
    on_border = (rc[:, 0] <= 0) | (rc[:, 0] >= h - 1) | (rc[:, 1] <= 0) | (rc[:, 1] >= w - 1)
    near_cut = distance_to_segments(pts, cut_pixels, np.roll(cut_pixels, -1, axis=0)) <= margin
    keep = ~near_cut & ~on_border
    if keep.all() or not keep.any():
        raise ValueError("side contour: the outline neither meets the image's edge nor the "
                         "collar; cannot tell where the neck ends")
    run = pts[_longest_cyclic_run(keep)]
    # the face looks toward +u in the right-side view: start at the front of the neck
    if run[0, 0] < run[-1, 0]:
        run = run[::-1]
    return resample_polyline(run, n_points)


def skin_border(model):
    """The skin's open boundary (ICT face + head and neck are open at the neck, the mouth
    and the eyes).

    Returns
    -------
    edges : ndarray, shape (E, 2)
        Edges used by one skin polygon only.
    label : ndarray, shape (V,)
        Connected component of each vertex over those edges (one per opening).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    skin_parts = [model.part_names.index(p) for p in ("Face", "Head and Neck")]
    start, total = model.face_loop_start, model.face_loop_total
    face_of_loop = np.repeat(np.arange(start.size), total)
    nxt = np.arange(model.loop_vertex.size) + 1
    nxt[start + total - 1] = start  # close each polygon
    on_skin = np.isin(model.face_part[face_of_loop], skin_parts)
    a, b = model.loop_vertex[on_skin], model.loop_vertex[nxt[on_skin]]
    uniq, count = np.unique(np.sort(np.column_stack([a, b]), axis=1), axis=0,
                            return_counts=True)
    edges = uniq[count == 1]
    n = model.n_vertices
    g = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    return edges, connected_components(g, directed=False)[1]


def neck_cut_vertices(model):
    """Vertices of the skin's opening at the bottom of the neck (the one holding the
    lowest border vertex), shape (m,)."""
    edges, label = skin_border(model)
    on_border = np.unique(edges)
    lowest = on_border[np.argmin(model.vertices[on_border, 2])]
    return on_border[label[on_border] == label[lowest]]


# --------------------------------------------------------------------------- torso


def _circular_smooth(values, window):
    """Moving average of a periodic sequence (n,) over ``window`` (odd) samples."""
    k = window // 2
    padded = np.concatenate([values[-k:], values, values[:k]])
    return np.convolve(padded, np.ones(window) / window, mode="valid")


def _skin_radius(points_axis, centre, theta, z, half_angle=0.12, half_height=0.006):
    """Largest distance from the neck's axis of the points in each angular sector and
    height slab: (n,) metres, 0 where the sector is empty.

    Parameters
    ----------
    points_axis : ndarray, shape (S, 3)
        Skin points (local, metres).
    centre : ndarray, shape (2,)
        The neck's axis (x, y).
    theta, z : ndarray, shape (n,)
        Angle (radians, from +X toward +Y) and height of each query.
    """
    d = points_axis[:, :2] - centre
    ang = np.arctan2(d[:, 1], d[:, 0])
    rad = np.hypot(d[:, 0], d[:, 1])
    dang = np.abs((ang[None, :] - theta[:, None] + np.pi) % (2 * np.pi) - np.pi)
    near = (dang < half_angle) & (np.abs(points_axis[None, :, 2] - z[:, None]) < half_height)
    return np.where(near, rad[None, :], 0.0).max(axis=1)


def torso_mesh(local, skin, cut, n_around=72):
    """A shirt over the shoulders whose collar hides the model's neck cut.

    Real photos show shoulders and clothes, not the bust's cut edge. The collar follows
    the cut 1.5 cm above it (a crew neck, lower in front) a few millimetres off the skin;
    below, the cloth widens to the shoulders. Every ring stays outside the skin it
    passes, whatever the identity.

    Parameters
    ----------
    local : ndarray, shape (V, 3)
        Head vertices (local, metres).
    skin : ndarray, shape (S,)
        Skin vertex indices.
    cut : ndarray, shape (m,)
        The neck cut's vertices (``neck_cut_vertices``).
    n_around : int
        Vertices per ring.

    Returns
    -------
    vertices : ndarray, shape (n_around * rows, 3)
    loop_vertex, face_loop_start, face_loop_total : ndarray
        Quads between consecutive rings (``add_mesh`` layout).
    rim : ndarray, shape (n_around, 3)
        The collar's top edge, in order around the neck.
    """
    cut_pts = local[cut]
    centre = cut_pts[:, :2].mean(axis=0)
    theta = np.linspace(-np.pi, np.pi, n_around, endpoint=False)
    d = cut_pts[:, :2] - centre
    cut_ang = np.arctan2(d[:, 1], d[:, 0])
    order = np.argsort(cut_ang)
    # height of the cut at each angle (periodic interpolation), smoothed around the neck;
    # the collar runs 1.5 cm above it but dips at most 3 cm below its highest point
    z_cut = _circular_smooth(np.interp(theta, cut_ang[order], cut_pts[order, 2],
                                       period=2 * np.pi), 9)
    z_rim = np.maximum(z_cut + 0.015, z_cut.max() - 0.03)
    z_rim = np.maximum(_circular_smooth(z_rim, 11), z_cut + 0.008)  # round the corners
    skin_pts = local[skin]
    gap = 0.0025
    r_rim = _circular_smooth(_skin_radius(skin_pts, centre, theta, z_rim), 5)
    # rings: (drop below the rim, share of the way to the shoulder outline)
    rings = ((0.0, 0.0), (0.004, 0.06), (0.008, 0.14), (0.013, 0.24), (0.02, 0.38),
             (0.03, 0.55), (0.045, 0.75), (0.065, 0.92), (0.1, 1.0), (0.3, 1.04))
    direction = np.column_stack([np.cos(theta), np.sin(theta)])
    # shoulders: a superellipse, wide across, chest slightly forward (-Y)
    a, b, e = 0.2, 0.105, 3.0
    shoulder = (direction / (np.abs(direction[:, 0] / a) ** e
                             + np.abs(direction[:, 1] / b) ** e)[:, None] ** (1.0 / e))
    shoulder_r = np.linalg.norm(shoulder, axis=1)
    rows = []
    for drop, t in rings:
        z = z_rim - drop
        ease = t * t * (3.0 - 2.0 * t)
        r = (1.0 - ease) * (r_rim + gap) + ease * shoulder_r
        r = np.maximum(r, _skin_radius(skin_pts, centre, theta, z) + gap)
        xy = centre + direction * r[:, None] + np.array([0.0, -0.01]) * ease
        rows.append(np.column_stack([xy, z]))
    vertices = np.concatenate(rows)
    n_rows = len(rows)
    i = np.arange(n_around)
    quads = []
    for k in range(n_rows - 1):
        a0, a1 = k * n_around + i, k * n_around + (i + 1) % n_around
        quads.append(np.column_stack([a0, a1, a1 + n_around, a0 + n_around]))
    quads = np.concatenate(quads)
    loop_vertex = quads.ravel()
    start = np.arange(len(quads)) * 4
    return vertices, loop_vertex, start, np.full(len(quads), 4), rows[0]


# --------------------------------------------------------------------------- render


def render_views(model, local, pose, torso, cameras, size, samples, seed, log,
                 skin_tone="light", light="studio"):
    """Render each view with Cycles.

    Parameters
    ----------
    model : HeadModel
    local : ndarray, shape (V, 3)
        Head vertices (local, metres).
    pose : (ndarray (3, 3), ndarray (3,))
        Rotation and translation, local -> world.
    torso : tuple
        The shirt (``torso_mesh``), in the head's local space.
    cameras : dict of str -> OrthographicCamera
    size : (int, int)
    samples : int
    seed : int
        Backdrop noise.
    log : callable
    skin_tone : str
        A key of ``SKIN_TONES``.
    light : str
        A key of ``render_util.LIGHTINGS``.

    Returns
    -------
    renders : dict of str -> dict
        ``photo`` (h, w, 3) on the backdrop, ``alpha`` (h, w) of head and shirt,
        ``head_alpha`` (h, w) of the head alone (the shirt held out), in [0, 1].
    cam_objs : dict of str -> bpy camera object
    """
    from tools import render_util as ru

    t0 = time.perf_counter()
    rotation, translation = pose
    ru.new_scene(size, samples)
    mats = _materials(skin_tone)
    slot = _face_materials(model)
    drawn = slot >= 0
    loops, new_start, totals = face_subset(model, drawn)
    head = ru.add_mesh("Head", local, model.loop_vertex[loops], new_start, totals,
                       loop_uv=model.loop_uv[loops], face_material=slot[drawn],
                       materials=[mats[s] for s in SLOTS],
                       point_attributes=appearance_attributes(model))
    shirt = ru.add_mesh("Shirt", *torso[:4], materials=[mats["shirt"]])
    solid = shirt.modifiers.new("Cloth thickness", "SOLIDIFY")
    solid.thickness = 0.002
    solid.offset = 1.0
    for obj in (head, shirt):
        ru.set_pose(obj, 1.0, rotation, translation)
    world = local @ rotation.T + translation
    ru.LIGHTINGS[light](world[model.skin].mean(axis=0))
    out, cam_objs = {}, {}
    for view, cam in cameras.items():
        add = ru.add_pinhole_camera if cam.perspective else ru.add_ortho_camera
        cam_objs[view] = add(cam, name=f"Camera {view}")
    for i, view in enumerate(cameras):
        t = time.perf_counter()
        rgba = ru.render_rgba(cam_objs[view])
        photo = ru.composite(rgba, ru.backdrop(size, seed=seed + 10 + i))
        head_alpha = ru.render_alpha(cam_objs[view], holdout=[shirt])  # the head alone
        out[view] = {"photo": photo, "alpha": rgba[..., 3], "head_alpha": head_alpha}
        log(f"  rendered {view} ({size[0]}x{size[1]}, {samples} samples) in "
            f"{time.perf_counter() - t:.1f} s")
    log(f"  Blender scene and renders: {time.perf_counter() - t0:.1f} s")
    return out, cam_objs


def _visible_names(model, view_kind):
    """Landmarks that assets/landmarks.json marks visible in a view of this kind."""
    side = view_kind.split("-")[-1]  # "front", "right" or "left", as the file names views
    return [e["name"] for e in model.landmark_info if side in (e.get("views") or ())]


def draw_overlay(photo, points, contour=None):
    """Photo with landmarks (green crosses) and the contour (cyan line): a PIL image."""
    im = Image.fromarray(np.clip(photo * 255 + 0.5, 0, 255).astype(np.uint8))
    d = ImageDraw.Draw(im)
    if contour is not None and len(contour) > 1:
        d.line([tuple(p) for p in contour], fill=(0, 200, 255), width=1)
        for u, v in contour:
            d.ellipse([u - 1.5, v - 1.5, u + 1.5, v + 1.5], outline=(0, 200, 255))
    r = max(2.0, photo.shape[0] / 300)
    for u, v in points.values():
        d.line([(u - r, v), (u + r, v)], fill=(0, 255, 0))
        d.line([(u, v - r), (u, v + r)], fill=(0, 255, 0))
    return im


# --------------------------------------------------------------------------- driver


def _params(model, seed, size, samples, lens_mm=None, yaw_deg=0.0, side_deg=90.0,
            skin_tone="light", expression=None, pitch_deg=0.0, light="studio"):
    params = {"version": SAMPLE_VERSION, "seed": int(seed),
              "size": [int(size[0]), int(size[1])], "samples": int(samples),
              "model": getattr(model, "build_hash", "")}
    if lens_mm is not None:
        params["lens_mm"] = float(lens_mm)
    if yaw_deg:
        params["yaw_deg"] = float(yaw_deg)
    if pitch_deg:
        params["pitch_deg"] = float(pitch_deg)
    if float(side_deg) != 90.0:
        params["side_deg"] = float(side_deg)
    if skin_tone != "light":
        params["skin_tone"] = skin_tone
    if expression is not None:
        params["expression"] = expression
    if light != "studio":
        params["light"] = light
    return params


def _files(params):
    """The files a sample made with ``params`` holds: perspective photos are JPEGs, as a
    camera writes them, with the lens in their EXIF."""
    if "lens_mm" not in params:
        return FILES
    return tuple(f.replace(".png", ".jpg") for f in FILES)


def is_up_to_date(out, params):
    """True when every output exists and truth.npz says it was made with ``params``."""
    out = Path(out)
    if not all((out / f).is_file() for f in _files(params)):
        return False
    try:
        with np.load(out / "truth.npz", allow_pickle=False) as t:
            return json.loads(str(t["params"])) == params
    except (OSError, ValueError, KeyError):
        return False


def make_sample(out=DEFAULT_OUT, seed=DEFAULT_SEED, size=DEFAULT_SIZE, samples=DEFAULT_SAMPLES,
                force=False, model=None, log=print, lens_mm=None, yaw_deg=0.0, side_deg=90.0,
                skin_tone="light", expression=None, pitch_deg=0.0, light="studio"):
    """Make the sample case in ``out`` unless it is up to date.

    Parameters
    ----------
    out : str or Path
        Output folder (replaced as a whole when remade).
    seed : int
        Identity, pose, framing and landmark noise.
    size : (int, int)
        Photo width and height in pixels.
    samples : int
        Cycles samples per pixel (denoised with OpenImageDenoise).
    force : bool
        Remake even when up to date.
    model : HeadModel, optional
        Default: ``load_model()``.
    log : callable
    lens_mm : float, optional
        Photograph the head with pinhole cameras of this lens (36 mm equivalent across
        the long side) instead of orthographic ones, standing where they frame the head
        alike (``perspective_cameras``): JPEG photos with the lens in their EXIF, views
        whose cameras the fit calibrates from it (``{"kind": "pinhole", "lens_mm": ...}``).
    yaw_deg : float
        The head turned by this much more (``sample_head``): three-quarter photos.
    pitch_deg : float
        The head nodded by this much more (``sample_head``; positive: the face down), in
        both photos: a sitter who looks a little down or up.
    side_deg : float
        The side camera's direction, degrees from the front camera's (``frame_cameras``):
        under 90, a side photo short of a profile; its view's camera in ``sample.json``
        is turned so (``view_camera``).
    skin_tone : str
        The head's complexion, a key of ``SKIN_TONES``.
    expression : str, optional
        The face in the photos shows this key of ``EXPRESSIONS`` (its landmarks and
        outline with it); ``truth.npz`` keeps the neutral head as ``local_vertices`` and
        the weights as ``expression``.
    light : str
        How the head is lit, a key of ``render_util.LIGHTINGS``: "studio" (soft, from the
        front) or "window" (one side: the other in shade, a band of light along the
        profile).

    Returns
    -------
    Path
        The landmarks file ``out/sample.json``.
    """
    out = Path(out)
    size = (int(size[0]), int(size[1]))
    if int(samples) < 1:
        raise ValueError(f"samples: at least 1 Cycles sample per pixel, got {samples}")
    if min(size) < 64:
        raise ValueError(f"size: photos of at least 64x64 pixels, got {size[0]}x{size[1]}")
    model = load_model() if model is None else model
    if lens_mm is not None and not 5.0 <= float(lens_mm) <= 1000.0:
        raise ValueError(f"lens_mm: a lens of 5-1000 mm, got {lens_mm}")
    if not -90.0 < float(yaw_deg) < 90.0:
        raise ValueError(f"yaw_deg: a turn of under 90 degrees either way, got {yaw_deg}")
    if not -30.0 <= float(pitch_deg) <= 30.0:
        raise ValueError(f"pitch_deg: a nod of at most 30 degrees either way, got {pitch_deg}")
    if not 45.0 <= float(side_deg) <= 90.0:
        raise ValueError(f"side_deg: a side camera 45-90 degrees from the front, got {side_deg}")
    if skin_tone not in SKIN_TONES:
        raise ValueError(f"skin_tone: one of {', '.join(SKIN_TONES)}, got {skin_tone!r}")
    if expression is not None and expression not in EXPRESSIONS:
        raise ValueError(f"expression: one of {', '.join(EXPRESSIONS)}, got {expression!r}")
    if light not in LIGHTS:
        raise ValueError(f"light: one of {', '.join(LIGHTS)}, got {light!r}")
    params = _params(model, seed, size, samples, lens_mm, yaw_deg, side_deg, skin_tone,
                     expression, pitch_deg, light)
    if not force and is_up_to_date(out, params):
        log(f"sample up to date: {out}")
        return out / "sample.json"
    t0 = time.perf_counter()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    try:
        _make_into(tmp, model, seed, size, samples, params, log, lens_mm, yaw_deg, side_deg,
                   skin_tone, expression, pitch_deg, light)
        old = out.parent / f".{out.name}.old-{os.getpid()}"
        if out.exists():
            out.rename(old)
        tmp.rename(out)
        shutil.rmtree(old, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    log(f"sample written to {out} in {time.perf_counter() - t0:.1f} s")
    return out / "sample.json"


def _make_into(folder, model, seed, size, samples, params, log, lens_mm=None, yaw_deg=0.0,
               side_deg=90.0, skin_tone="light", expression=None, pitch_deg=0.0,
               light="studio"):
    from tools import render_util as ru

    coeffs, local, rotation, translation = sample_head(model, seed, yaw_deg, pitch_deg)
    weights = EXPRESSIONS.get(expression, {})
    shown = local + model.expression_offsets(weights)
    world = shown @ rotation.T + translation
    torso = torso_mesh(shown, model.skin, neck_cut_vertices(model))
    rim = torso[4] @ rotation.T + translation  # the collar's top edge, world
    cameras = frame_cameras(world, float(rim[:, 2].mean()), size, seed, side_deg)
    if lens_mm is not None:
        cameras = perspective_cameras(cameras, world, lens_mm)
    renders, cam_objs = render_views(model, shown, (rotation, translation), torso, cameras,
                                     size, samples, seed, log, skin_tone, light)

    rng = np.random.default_rng(seed + 2)
    noise_px = NOISE_PX * size[1] / 1024.0
    views, exact = {}, {}
    for view, cam in cameras.items():
        r = renders[view]
        names = _visible_names(model, VIEWS[view])
        idx = np.array([model.landmark_vertex(n) for n in names])
        px_blender = ru.blender_project(cam_objs[view], world[idx], size)
        px_solver = cam.project(world[idx])
        gap = np.abs(px_blender - px_solver).max()
        if gap > 0.05:  # the camera conversion must be exact, or the truth is wrong
            raise RuntimeError(f"view {view}: Blender and solver projections differ by "
                               f"{gap:.3f} px")
        # a user cannot place what the shirt covers
        col = np.clip(px_blender[:, 0].astype(int), 0, size[0] - 1)
        row = np.clip(px_blender[:, 1].astype(int), 0, size[1] - 1)
        hidden = (r["alpha"][row, col] >= 0.5) & (r["head_alpha"][row, col] < 0.5)
        if hidden.any():
            log(f"  {view}: covered by the shirt: {', '.join(np.array(names)[hidden])}")
        names = [n for n, hid in zip(names, hidden, strict=True) if not hid]
        px_blender = px_blender[~hidden]
        noisy = px_blender + rng.normal(0.0, noise_px, px_blender.shape)
        exact[view] = px_blender
        contour = None
        if view == "side":
            contour = side_contour(r["head_alpha"], cam.project(rim))
        photo = f"{view}.png"
        camera, hints = view_camera(view, size, side_deg), {}
        if lens_mm is None:
            ru.save_png(folder / photo, r["photo"])
        else:
            photo = f"{view}.jpg"
            save_jpeg(folder / photo, r["photo"], lens_mm)
            camera, hints = None, {"kind": "pinhole", "lens_mm": float(lens_mm)}
        points = {n: (float(u), float(v)) for n, (u, v) in zip(names, noisy, strict=True)}
        views[view] = View(name=view, image=photo, size=size, camera=camera, points=points,
                           contour=contour, camera_hints=hints)
        draw_overlay(r["photo"], points, contour).save(folder / f"overlay_{view}.png")

    truth = {
        "params": np.array(json.dumps(params)),
        "identity_coeffs": coeffs,
        "local_vertices": local,
        "world_vertices": world,
        "scale": np.array(1.0),
        "rotation": rotation,
        "translation": translation,
        "skin": np.asarray(model.skin),
        "cameras": np.array(json.dumps({v: c.to_dict() for v, c in cameras.items()})),
        "landmark_names": np.array(json.dumps({v: list(views[v].points) for v in views})),
        "collar_rim": rim,
        "expression": np.array(json.dumps(weights)),
    }
    for view in cameras:
        truth[f"alpha_{view}"] = np.round(renders[view]["alpha"] * 255).astype(np.uint8)
        truth[f"head_alpha_{view}"] = np.round(renders[view]["head_alpha"] * 255) \
            .astype(np.uint8)
        truth[f"exact_{view}"] = exact[view]
    np.savez_compressed(folder / "truth.npz", **truth)
    path = folder / "sample.json"
    save_landmarks(LandmarkCase(views=views, source=str(path)), path)
    # read back what we wrote: the sample must be a valid landmarks file
    load_landmarks(path, known_names=model)


def parse_size(text):
    """'768x1024' -> (768, 1024)."""
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--size: expected WxH like 768x1024, got {text!r}") from None
    if w < 64 or h < 64:
        raise argparse.ArgumentTypeError(f"--size: at least 64x64, got {text!r}")
    return w, h


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m tools.make_sample",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(DEFAULT_OUT),
                        help="output folder (default: generated/sample)")
    parser.add_argument("--seed", type=int, default=DEFAULT_SEED)
    parser.add_argument("--size", type=parse_size, default=DEFAULT_SIZE,
                        help="photo size WxH (default 768x1024)")
    parser.add_argument("--samples", type=int, default=DEFAULT_SAMPLES,
                        help="Cycles samples per pixel (default %(default)s)")
    parser.add_argument("--force", action="store_true", help="remake even when up to date")
    parser.add_argument("--lens", type=float, default=None, metavar="MM",
                        help="perspective photos taken with this lens (36 mm equivalent), "
                             "JPEGs with it in their EXIF (default: orthographic)")
    parser.add_argument("--yaw", type=float, default=0.0, metavar="DEG",
                        help="the head turned by this much more (negative: toward the side "
                             "camera), for three-quarter photos (default 0)")
    parser.add_argument("--pitch", type=float, default=0.0, metavar="DEG",
                        help="the head nodded by this much more in both photos (positive: "
                             "the face down; default 0)")
    parser.add_argument("--side-deg", type=float, default=90.0, metavar="DEG",
                        help="the side camera this many degrees from the front camera "
                             "(default 90: an exact profile)")
    parser.add_argument("--skin", choices=list(SKIN_TONES), default="light",
                        help="the head's skin tone (default light)")
    parser.add_argument("--expression", choices=list(EXPRESSIONS), default=None,
                        help="the face in the photos shows this expression (default: "
                             "neutral); the truth stays the neutral head")
    parser.add_argument("--light", choices=list(LIGHTS), default="studio",
                        help="how the head is lit: studio (soft, from the front; default) or "
                             "window (from the subject's left: the other side in shade)")
    args = parser.parse_args(argv)
    try:
        make_sample(args.out, args.seed, args.size, args.samples, args.force,
                    lens_mm=args.lens, yaw_deg=args.yaw, side_deg=args.side_deg,
                    skin_tone=args.skin, expression=args.expression, pitch_deg=args.pitch,
                    light=args.light)
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())

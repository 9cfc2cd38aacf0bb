"""The irises' colour, read off the photos: the fitted head's irises projected into every
photo that looks into the eyes, sampled where the lids leave them open, so the head's eyes
get the person's colour instead of one colour for everybody.

The iris is the ring of each sclera's front between the pupil and the iris's rim
(``solver.eyes``), kept ``RIM_MARGIN`` inside both; a point counts where no skin lies in
front of it in that photo (the lids: a depth buffer of the skin around the eye) and,
where the photo's eye landmarks are placed or detected, inside the opening they draw (a
fitted lid is a model's, the landmarks are the photo's own), and only in photos whose
camera looks along the eye's axis within ``MAX_ANGLE_DEG``. Of the
colours sampled, the brightest (the light's reflection in the cornea, the white of the
eye at a lid that is a little off) and the darkest (lashes, the pupil's edge) are left
out before the median.
"""

import numpy as np
import scipy.ndimage as ndi

from ..eyes import (
    EYE_OPENINGS,
    IRIS_RADIUS,
    IRIS_RANGES,
    PUPIL_RADIUS,
    sclera_axis_distance,
)
from ..geometry import inside_polygon
from ..photo_colour import sample_photo
from .raster import depth_buffer

#: Kept inside the pupil's and the iris's rims, metres: a fit a little off still samples
#: the iris.
RIM_MARGIN = 0.0008
#: Largest angle between an eye's axis and the direction to a camera that still sees into
#: the eye, degrees (a profile photo sees the iris edge-on).
MAX_ANGLE_DEG = 50.0
#: Skin within this distance of an iris's centre occludes it (the lids, the brow, the
#: nose), metres.
OCCLUDER_REACH = 0.03
#: Share of the samples left out at the dark and the bright end.
TRIM = (0.1, 0.3)
#: Fewest samples (over both eyes and all photos) a colour is read from.
MIN_SAMPLES = 20
#: An opening drawn by the landmarks is shrunk toward its centre by this share: the lashes
#: and the lid's shadow lie along its edge.
OPENING_SHRINK = 0.15


def eye_openings(model, view):
    """The eye openings (k, 6, 2) px that ``view``'s landmarks draw (each eye's six iBUG
    points, under any name the landmark set knows them by; an eye missing any of them left
    out), shrunk by ``OPENING_SHRINK``."""
    lms = model.landmark_set
    given = {lms.canonical(k): p for k, p in view.points.items()}
    out = []
    for numbers in EYE_OPENINGS:
        names = [lms.canonical(f"ibug{n:02d}") for n in numbers]
        if all(n in given for n in names):
            p = np.array([given[n] for n in names], dtype=np.float64)
            centre = p.mean(axis=0)
            out.append(centre + (1.0 - OPENING_SHRINK) * (p - centre))
    return np.array(out).reshape(-1, 6, 2)


def iris_samples(model, local_vertices, world_vertices, camera, image, openings=None):
    """The colours (k, 3) of ``image`` (H, W, 3 or 4; uint8 or float in [0, 1]) at the
    iris points that ``camera`` sees into, in the image's own encoding, in [0, 1].

    ``local_vertices`` (V, 3) m: the head in the model's frame (where the iris ring is
    chosen); ``world_vertices`` (V, 3) m: the same head where ``camera`` sees it;
    ``openings`` (k, n, 2): the eye openings in the camera's pixels (``eye_openings``),
    each iris sampled only inside the one nearest it (None: by the lids alone)."""
    image = np.asarray(image)
    # a few hundred points are sampled: the photo is not converted as a whole
    unit = np.iinfo(image.dtype).max if np.issubdtype(image.dtype, np.integer) else 1.0
    h, w = image.shape[:2]
    size = getattr(camera, "size", None)
    scale = np.ones(2) if size is None else np.array([w / size[0], h / size[1]])
    world = np.asarray(world_vertices, dtype=np.float64)
    skin_tris = model.skin_triangles()
    skin_centres = world[skin_tris].mean(axis=1)
    out = []
    for (idx, r, front), (i0, i1) in zip(sclera_axis_distance(local_vertices), IRIS_RANGES,
                                         strict=True):
        ring = idx[front & (r > PUPIL_RADIUS + RIM_MARGIN) & (r < IRIS_RADIUS - RIM_MARGIN)]
        centre = world[i0:i1 + 1].mean(axis=0)
        axis = world[ring].mean(axis=0) - centre
        axis /= np.linalg.norm(axis)
        toward = np.asarray(camera.toward_camera(centre[None]), float).reshape(-1, 3)[0]
        if axis @ toward < np.cos(np.radians(MAX_ANGLE_DEG)):
            continue
        uv = camera.project(world[ring]) * scale
        depth = camera.to_camera(world[ring])[:, 2]
        near = skin_tris[np.linalg.norm(skin_centres - centre, axis=1) < OCCLUDER_REACH]
        x0, y0 = np.floor(uv.min(axis=0)).astype(int) - 2
        x1, y1 = np.ceil(uv.max(axis=0)).astype(int) + 3
        if x0 < 0 or y0 < 0 or x1 > w or y1 > h:
            continue  # the eye runs off the photo
        tri_uv = camera.project(world[near].reshape(-1, 3)).reshape(-1, 3, 2) * scale
        tri_z = camera.to_camera(world[near].reshape(-1, 3))[:, 2].reshape(-1, 3)
        skin = depth_buffer(tri_uv - (x0, y0), tri_z, x1 - x0, y1 - y0)
        # a point beside a lid's edge counts as covered: the fitted lid may be a pixel off
        skin = ndi.minimum_filter(skin, size=3, mode="nearest")
        px = np.floor(uv - (x0, y0)).astype(int)
        open_ = depth < skin[px[:, 1], px[:, 0]]
        if openings is not None and len(openings):
            at = np.asarray(openings, float) * scale
            own = at[np.argmin(np.linalg.norm(at.mean(axis=1) - uv.mean(axis=0), axis=1))]
            open_ &= inside_polygon(uv, own)
        out.append(sample_photo(image[..., :3], uv[open_]) / unit)
    return np.concatenate(out) if out else np.zeros((0, 3))


def iris_colour(model, result, images, case=None):
    """The irises' colour (3,) in the photos' encoding (sRGB for ordinary photos), in
    [0, 1], or None where the photos show fewer than ``MIN_SAMPLES`` points of an iris
    (closed eyes, only profiles).

    ``result``: the FitResult (its local and world vertices, its cameras); ``images``:
    dict view -> photo (H, W, 3 or 4), keyed like ``result.cameras``; ``case``: the
    LandmarkCase fitted, whose eye landmarks bound each iris by the photo's own lids."""
    samples = [iris_samples(model, result.local_vertices, result.world_vertices,
                            result.cameras[name], image,
                            None if case is None or name not in case.views
                            else eye_openings(model, case.views[name]))
               for name, image in images.items() if name in result.cameras]
    colours = np.concatenate(samples) if samples else np.zeros((0, 3))
    if len(colours) < MIN_SAMPLES:
        return None
    light = colours.mean(axis=1)
    lo, hi = np.quantile(light, [TRIM[0], 1.0 - TRIM[1]])
    return np.median(colours[(light >= lo) & (light <= hi)], axis=0)


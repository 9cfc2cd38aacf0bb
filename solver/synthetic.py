"""Synthetic landmark cases with a known answer, for tests and benchmarks.

A head is drawn from the model (identity coefficients ~ N(0, 1)), posed by a random
similarity and photographed:

- ``make_case``: by orthographic cameras, each with its own scale, offset (and optionally
  in-plane tilt), like two photos taken separately. Its landmarks are the projections of
  the landmark vertices a view can see (``views`` in assets/landmarks.json) plus Gaussian
  noise; a side view also gets the traced head outline: the silhouette of the projected
  skin, rasterised at image resolution, traced along its outer boundary, the bottom cut of
  the neck left out (a person tracing a photo follows the head, not the mesh's end);
- ``make_perspective_case``: by 2-4 pinhole cameras at any angle (35-85 mm equivalent,
  0.5-2 m, yaw up to +-45 degrees), each landmark placed where the photo shows it:
  its vertex faces the camera and nothing nearer covers it (``visible_landmarks``);
- ``make_mirror_case``: by one pinhole camera that sees the face and, in a flat mirror
  beside the head, its mirror image (seed 001 ch. 3): two views of one photo.
"""

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from . import geometry
from .cameras import ORTHO_VIEWS, OrthographicCamera
from .cameras.mirror import MirrorPlane
from .cameras.pinhole import SENSOR_MM, PinholeCamera
from .io.case import LandmarkCase, View
from .procrustes import similarity_procrustes
from .texture.raster import depth_buffer, rasterize

# Moore neighbourhood in clockwise order on screen (rows run down): W, NW, N, NE, E, SE, S, SW.
_MOORE = np.array([(0, -1), (-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1)])


@dataclass
class SyntheticTruth:
    """What the synthetic photos show.

    Attributes
    ----------
    identity_coeffs : ndarray, shape (K,)
        Coefficients of the head (standard deviations; K = all modes of the model).
    local_vertices : ndarray, shape (V, 3), metres
        ``model.identity.instance(identity_coeffs)``.
    scale : float
    rotation : ndarray, shape (3, 3)
        Local -> world.
    translation : ndarray, shape (3,), metres
    cameras : dict of str -> OrthographicCamera
        The cameras that took the photos.
    pixels : dict of str -> dict of str -> ndarray (2,)
        Noise-free projection of every landmark placed in each view.
    contour : dict of str -> ndarray (n, 2)
        Noise-free traced outline of each side view (before subsampling noise).
    planes : dict of str -> MirrorPlane
        The mirror of each mirror view (``make_mirror_case``).
    """

    identity_coeffs: np.ndarray
    local_vertices: np.ndarray
    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    cameras: dict
    pixels: dict = field(default_factory=dict)
    contour: dict = field(default_factory=dict)
    planes: dict = field(default_factory=dict)

    @property
    def world_vertices(self):
        """Posed head, shape (V, 3), metres."""
        return self.scale * self.local_vertices @ self.rotation.T + self.translation


def random_rotation(rng, max_deg):
    """Rotation about a uniformly random axis by an angle uniform in [0, max_deg] degrees."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = np.radians(rng.uniform(0.0, max_deg))
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def _view_camera_name(view):
    name = view if view.startswith("orthographic-") else f"orthographic-{view}"
    if name not in ORTHO_VIEWS:
        raise ValueError(f"views: unknown view {view!r}; use front, right or left")
    return name


def _landmark_side(view):
    """Key of a view in the ``views`` list of assets/landmarks.json."""
    return _view_camera_name(view)[len("orthographic-"):]


def make_case(model, rng=None, *, noise_px=1.0, rotation_deg=5.0, image_height=1024,
              views=("front", "right"), coeffs=None, coeff_scale=1.0, in_plane_deg=0.0,
              contour=True, contour_points=100, contour_noise_px=None, aspect=0.75,
              fill=(0.75, 0.9)):
    """A synthetic case: landmarks (and a profile contour) of a random head.

    Parameters
    ----------
    model : HeadModel
    rng : numpy.random.Generator or int or None
        Random source or seed.
    noise_px : float
        Standard deviation of the Gaussian noise added to each landmark coordinate, pixels.
    rotation_deg : float
        Largest rotation of the head (random axis), degrees.
    image_height : int
        Photo height in pixels; the width is ``aspect * image_height``.
    views : sequence of str
        Views to photograph: "front", "right", "left" (the view's name in the case).
    coeffs : array_like, shape (K,), optional
        The head's identity coefficients (default: standard normal times ``coeff_scale``).
    coeff_scale : float
        Spread of the sampled coefficients (1: the model's distribution).
    in_plane_deg : float
        Largest tilt of each camera about its viewing direction, degrees (0: upright).
    contour : bool
        Trace the outline in side views.
    contour_points : int
        Points of the subsampled outline.
    contour_noise_px : float, optional
        Noise of the outline points (default ``noise_px``).
    aspect : float
        Image width / height.
    fill : (float, float)
        Range of the fraction of the image height the head's projection fills.

    Returns
    -------
    case : LandmarkCase
    truth : SyntheticTruth
    """
    rng = np.random.default_rng(rng)
    if noise_px < 0 or rotation_deg < 0:
        raise ValueError("noise_px and rotation_deg: must be >= 0")
    if not views:
        raise ValueError("views: at least one view is needed")
    c, local, rot, scale, trans = _random_head(model, rng, coeffs, coeff_scale, rotation_deg)
    world = scale * local @ rot.T + trans
    cnoise = noise_px if contour_noise_px is None else contour_noise_px

    h = int(image_height)
    w = int(round(aspect * h))
    skin_tris = model.skin_triangles()
    case_views, cams, clean, outlines = {}, {}, {}, {}
    for view in views:
        cam_name = _view_camera_name(view)
        side = _landmark_side(view)
        cam = _random_camera(rng, cam_name, (w, h), world[model.skin], fill, in_plane_deg)
        cams[view] = cam
        names = [e["name"] for e in model.landmark_info if side in e.get("views", ())]
        verts = np.array([model.landmarks[n] for n in names], dtype=np.int64)
        px = cam.project(world[verts])
        clean[view] = dict(zip(names, px, strict=True))
        noisy = px + noise_px * rng.normal(size=px.shape)
        noisy = np.clip(noisy, 0.0, [w, h])
        outline = None
        if contour and side in ("right", "left"):
            traced = trace_silhouette(model, world, cam, skin_tris)
            outlines[view] = traced
            outline = resample_polyline(traced, contour_points)
            outline = np.clip(outline + cnoise * rng.normal(size=outline.shape), 0.0, [w, h])
        case_views[view] = View(name=view, image=None, size=(w, h),
                                camera=OrthographicCamera.nominal(cam_name, (w, h)),
                                points=dict(zip(names, noisy, strict=True)), contour=outline)
    truth = SyntheticTruth(c, local, scale, rot, trans, cams, clean, outlines)
    return LandmarkCase(case_views, "<synthetic>"), truth


def _random_head(model, rng, coeffs, coeff_scale, rotation_deg):
    """(coefficients, local vertices, rotation, scale, translation) of a random posed
    head (the draws in this order, so seeds reproduce across versions)."""
    ident = model.identity
    k = ident.n_coeffs
    if coeffs is None:
        c = coeff_scale * rng.normal(size=k)
    else:
        c = np.zeros(k)
        given = np.asarray(coeffs, dtype=np.float64).reshape(-1)
        if len(given) > k:
            raise ValueError(f"coeffs: at most {k} values, got {len(given)}")
        c[:len(given)] = given
    local = ident.instance(c)
    rot = random_rotation(rng, rotation_deg)
    scale = float(rng.uniform(0.95, 1.05))
    trans = rng.uniform(-0.01, 0.01, size=3)
    return c, local, rot, scale, trans


def _pinhole_scene(model, rng, coeffs, coeff_scale, rotation_deg):
    """A random posed head as the pinhole photos of ``make_perspective_case`` and
    ``make_mirror_case`` see it (drawn by ``_random_head``: same draws, same seeds).

    Returns
    -------
    head : tuple
        (coefficients, local vertices, scale, rotation, translation): the first fields of
        its SyntheticTruth, in their order.
    world : ndarray, shape (V, 3), metres
        The posed head.
    normals : ndarray, shape (V, 3)
        Its unit vertex normals (which landmarks a camera sees).
    skin_tris : ndarray, shape (T, 3)
        Skin triangles (occlusion, the traced silhouette).
    skin : ndarray, shape (S, 3), metres
        The posed skin (what the frames are fitted to).
    centre : ndarray, shape (3,), metres
        Middle of the skin's bounding box (where the cameras aim).
    """
    c, local, rot, scale, trans = _random_head(model, rng, coeffs, coeff_scale, rotation_deg)
    world = scale * local @ rot.T + trans
    skin = world[model.skin]
    centre = 0.5 * (skin.min(axis=0) + skin.max(axis=0))
    return ((c, local, scale, rot, trans), world, vertex_normals(model, world),
            model.skin_triangles(), skin, centre)


def vertex_normals(model, world):
    """Unit normals of the posed mesh's vertices (area-weighted face normals), (V, 3)."""
    return geometry.vertex_normals(world, model.triangles()[0])


def visible_landmarks(model, world, camera, normals=None, min_cos=0.0, grid=1024,
                      tolerance=0.004, triangles=None):
    """The landmarks a photo shows: those whose vertex faces the camera (the normal's
    cosine with the direction toward the camera above ``min_cos``, i.e. not seen edge-on),
    that nothing nearer covers (a z-buffer of the skin at ``grid`` cells along the image's
    longer side; slack ``tolerance`` metres plus what the surface's slope allows within a
    cell), and that fall inside the image.

    Parameters
    ----------
    model : HeadModel
    world : ndarray, shape (V, 3), metres
        Posed vertices.
    camera : Camera with ``depth`` (pinhole, DLT)
    normals : ndarray, shape (V, 3), optional
        Vertex normals of ``world`` (computed when not given).
    min_cos, grid, tolerance : float
    triangles : ndarray, shape (T, 3), optional
        Occluding triangles (default the skin's).

    Returns
    -------
    list of str
        Landmark names, in the order of ``model.landmark_info``.
    """
    if normals is None:
        normals = vertex_normals(model, world)
    names = [e["name"] for e in model.landmark_info]
    verts = np.array([model.landmarks[n] for n in names], dtype=np.int64)
    x = world[verts]
    toward = camera.toward_camera(x)
    cos = np.einsum("ij,ij->i", normals[verts], toward)
    w, h = camera.size
    px = camera.project(x)
    inside = (px >= 0).all(axis=1) & (px[:, 0] <= w) & (px[:, 1] <= h)
    tris = model.skin_triangles() if triangles is None else triangles
    f = grid / max(w, h)
    gw, gh = int(np.ceil(w * f)), int(np.ceil(h * f))
    corner = world[tris].reshape(-1, 3)
    buf = depth_buffer((camera.project(corner) * f).reshape(-1, 3, 2),
                       camera.depth(corner).reshape(-1, 3), gw, gh)
    g = np.clip(np.floor(px * f).astype(int), 0, [gw - 1, gh - 1])
    near = buf[g[:, 1], g[:, 0]]
    # metres a grid cell spans at the landmark, times the slope there (cos >= min_cos)
    cell = (1.0 / f) / camera.pixels_per_metre(x)
    slope = np.minimum(np.sqrt(np.maximum(1.0 - cos**2, 0.0)) / np.maximum(cos, 1e-3), 5.0)
    uncovered = camera.depth(x) <= near + tolerance + cell * slope
    keep = (cos > min_cos) & inside & uncovered
    return [n for n, k in zip(names, keep, strict=True) if k]


def _look(centre, target, size, f_px, roll):
    """A pinhole camera at ``centre`` looking at ``target``, +Z up, turned by ``roll``
    radians about its viewing direction."""
    cam = PinholeCamera.look_at(centre, target, size, f_px=f_px)
    q = np.array([[np.cos(roll), -np.sin(roll)], [np.sin(roll), np.cos(roll)]])
    rot = cam.rotation.copy()
    rot[:2] = q @ rot[:2]
    return cam.replaced(rotation=rot)


def perspective_yaws(rng, n_views, yaw_deg):
    """Yaw of each photo, degrees: the first near the front (|yaw| <= yaw_deg / 4), then
    alternately to either side at least half of ``yaw_deg`` out, further ones anywhere in
    +-yaw_deg (photos of a person taken from a few places around them)."""
    yaws = [rng.uniform(-0.25, 0.25) * yaw_deg]
    side = rng.choice([-1.0, 1.0])
    for i in range(1, n_views):
        if i <= 2:
            yaws.append(side * rng.uniform(0.5, 1.0) * yaw_deg)
            side = -side
        else:
            yaws.append(rng.uniform(-1.0, 1.0) * yaw_deg)
    return yaws


def make_perspective_case(model, rng=None, *, n_views=2, noise_px=1.0, lens_mm=(35.0, 85.0),
                          distance_m=(0.5, 2.0), yaw_deg=45.0, pitch_deg=10.0,
                          roll_deg=3.0, rotation_deg=5.0, coeffs=None, coeff_scale=1.0,
                          head_px=(768.0, 922.0), calibrated=False, focal_prior=0.05,
                          contour=False, contour_points=100, contour_noise_px=None,
                          min_cos=0.0):
    """A synthetic case photographed by pinhole cameras around the head.

    Each photo: a lens of ``lens_mm`` (35 mm equivalent, uniform in the range), a camera
    ``distance_m`` from the head's centre (uniform, but at least where the head fits in the
    frame), turned by a yaw (see :func:`perspective_yaws`), a pitch within
    +-``pitch_deg`` and a roll within +-``roll_deg``, aimed at the head's centre (plus up
    to 2 cm). The photo is a portrait frame (3:4) whose resolution makes the head's skin
    ``head_px`` pixels tall (uniform in the range; by default what ``make_case`` gives a
    1024-pixel photo), so a pixel of noise means the same as in the orthographic cases.
    The landmarks are those the photo shows (:func:`visible_landmarks`), with Gaussian
    noise.

    Parameters
    ----------
    model : HeadModel
    rng : numpy.random.Generator or int or None
    n_views : int
        Photos, 1 or more.
    noise_px : float
        Landmark noise, pixels (standard deviation per coordinate).
    lens_mm, distance_m : (float, float)
    yaw_deg, pitch_deg, roll_deg, rotation_deg : float
        Largest camera yaw, pitch, roll and head rotation (random axis), degrees.
    coeffs, coeff_scale : see ``make_case``
    head_px : (float, float)
    calibrated : bool
        True: the views carry their true cameras, kept by the fit. False: the cameras are
        to be self-calibrated (``{"kind": "pinhole", "lens_mm": ...}``).
    focal_prior : float or None
        With ``calibrated=False``: the relative error of the ``lens_mm`` the file states
        (drawn from N(0, focal_prior), like EXIF data of uncertain crop factor; the fit's
        prior assumes 5 %). None: no lens_mm (the focal length only walled in to 20-200 mm).
    contour : bool
        Trace the head's outline in every photo.
    contour_points : int
    contour_noise_px : float, optional
    min_cos : float
        Visibility: the smallest cosine between a landmark's normal and the direction to
        the camera.

    Returns
    -------
    case : LandmarkCase
        Views "photo0", "photo1", ...
    truth : SyntheticTruth
        ``cameras`` the true PinholeCameras.
    """
    rng = np.random.default_rng(rng)
    if int(n_views) < 1:
        raise ValueError(f"n_views: at least 1, got {n_views}")
    if noise_px < 0 or rotation_deg < 0:
        raise ValueError("noise_px and rotation_deg: must be >= 0")
    head, world, normals, skin_tris, skin, centre = _pinhole_scene(model, rng, coeffs,
                                                                   coeff_scale, rotation_deg)
    cnoise = noise_px if contour_noise_px is None else contour_noise_px
    views, cams, clean, outlines = {}, {}, {}, {}
    for i, yaw in enumerate(perspective_yaws(rng, int(n_views), yaw_deg)):
        name = f"photo{i}"
        lens = float(rng.uniform(*lens_mm))
        pitch = np.radians(rng.uniform(-pitch_deg, pitch_deg))
        roll = np.radians(rng.uniform(-roll_deg, roll_deg))
        target = centre + rng.uniform(-0.02, 0.02, size=3)
        want = float(rng.uniform(*head_px))
        direction = np.array([np.sin(np.radians(yaw)) * np.cos(pitch),
                              -np.cos(np.radians(yaw)) * np.cos(pitch), np.sin(pitch)])
        lo = max(distance_m[0], 0.0)
        for _ in range(50):
            dist = float(rng.uniform(lo, distance_m[1]))
            probe = _look(centre + dist * direction, target, (3, 4), 1.0, roll)
            ext = np.ptp(probe.project(skin), axis=0)  # metres per unit focal length
            f_px = want / ext[1]
            height = int(round(SENSOR_MM * f_px / lens))
            size = (int(round(0.75 * height)), height)
            cam = _look(centre + dist * direction, target, size, lens * height / SENSOR_MM,
                        roll)
            px = cam.project(skin)
            if px.min() >= 0.02 * height and (px <= np.array(size) * 0.98).all():
                break
            lo = min(0.5 * (dist + distance_m[1]), distance_m[1])  # farther, then retry
        else:
            raise ValueError(f"photo {i}: the head does not fit in the frame at up to "
                             f"{distance_m[1]} m with a {lens:.0f} mm lens")
        cams[name] = cam
        names = visible_landmarks(model, world, cam, normals, min_cos, triangles=skin_tris)
        verts = np.array([model.landmarks[n] for n in names], dtype=np.int64)
        px = cam.project(world[verts])
        clean[name] = dict(zip(names, px, strict=True))
        noisy = np.clip(px + noise_px * rng.normal(size=px.shape), 0.0, size)
        outline = None
        if contour:
            traced = trace_silhouette(model, world, cam, skin_tris)
            outlines[name] = traced
            outline = resample_polyline(traced, contour_points)
            outline = np.clip(outline + cnoise * rng.normal(size=outline.shape), 0.0, size)
        if calibrated:
            view = View(name, None, size, cam, dict(zip(names, noisy, strict=True)), outline,
                        calibrated=True)
        else:
            hints = {"kind": "pinhole"}
            if focal_prior is not None:
                hints["lens_mm"] = float(lens * (1.0 + focal_prior * rng.normal()))
            view = View(name, None, size, None, dict(zip(names, noisy, strict=True)), outline,
                        camera_hints=hints)
        views[name] = view
    truth = SyntheticTruth(*head, cams, clean, outlines)
    return LandmarkCase(views, "<synthetic>"), truth


def make_hand_placed_case(model, rng=None, *, side_deg=90.0, noise_px=1.5,
                          size=(768, 1024), middle_m=0.005):
    """Landmarks of a random model head as an artist places them by hand on a front photo
    and on a side photo whose camera stood ``side_deg`` degrees from the front camera
    (90: an exact right profile), both views given the nominal orthographic cameras a
    hand-placed case has. The front shows every landmark that means something there, the
    side those of the subject's right and the middle (vertex x at most ``middle_m``).

    Returns
    -------
    case : LandmarkCase
        Views "front" and "side"; no image, no contour.
    head : ndarray, shape (V, 3)
        The true head's local vertices.
    """
    rng = np.random.default_rng(rng)
    head = model.identity.instance(rng.normal(size=model.identity.n_coeffs))
    lms = model.landmark_set

    def view(name, kind, yaw, keep):
        names = [n for n in lms.vertices if lms.has_meaning_in(n, kind.split("-")[1])
                 and keep(model.vertices[lms.vertices[n], 0])]
        px = OrthographicCamera.turned(kind, size, yaw).project(
            head[[lms.vertices[n] for n in names]])
        px = px + rng.normal(0.0, noise_px, px.shape)
        return View(name, None, tuple(size), OrthographicCamera.nominal(kind, size),
                    dict(zip(names, map(tuple, px), strict=True)))

    return LandmarkCase({
        "front": view("front", "orthographic-front", 0.0, lambda x: True),
        "side": view("side", "orthographic-right", side_deg, lambda x: x <= middle_m)}), head


def make_mirror_case(model, rng=None, *, noise_px=1.0, distance_m=(0.9, 1.4),
                     mirror_angle_deg=(30.0, 50.0), mirror_gap_m=(0.2, 0.3), yaw_deg=10.0,
                     rotation_deg=5.0, coeffs=None, coeff_scale=1.0, head_px=700.0,
                     calibrated=False, focal_prior=0.05, min_cos=0.0):
    """One photo of a head and its mirror image (seed 001 ch. 3).

    The camera stands ``distance_m`` in front of the head (yaw within +-``yaw_deg``). A
    vertical flat mirror stands beside the head on the subject's left, ``mirror_gap_m``
    from its centre, its normal turned ``mirror_angle_deg`` from the left-right axis
    toward the camera, so the mirror shows the head from its left side. The camera aims
    between the head and its mirror image; the lens is chosen so both fill 85 % of the
    landscape (4:3) frame (its width, or its height), the resolution so the head is
    ``head_px`` tall.

    Returns
    -------
    case : LandmarkCase
        View "front" (the face seen directly) and view "mirror" (``mirror_of="front"``, its
        landmarks named by the subject's true side, camera to be derived by the fit), one
        image and size.
    truth : SyntheticTruth
        ``cameras``: the real camera ("front") and the reflected one ("mirror");
        ``planes["mirror"]``: the mirror.
    """
    rng = np.random.default_rng(rng)
    head, world, normals, skin_tris, skin, centre = _pinhole_scene(model, rng, coeffs,
                                                                   coeff_scale, rotation_deg)
    alpha = np.radians(rng.uniform(*mirror_angle_deg))
    normal = np.array([-np.cos(alpha), -np.sin(alpha), 0.0])
    plane = MirrorPlane.from_point_normal(centre + [rng.uniform(*mirror_gap_m), 0.0, 0.0],
                                          normal)
    mirrored_centre = plane.reflect_points(centre[None])[0]
    yaw = np.radians(rng.uniform(-yaw_deg, yaw_deg))
    dist = float(rng.uniform(*distance_m))
    eye = centre + dist * np.array([np.sin(yaw), -np.cos(yaw), 0.0])
    aim = 0.5 * (centre + mirrored_centre)
    probe = _look(eye, aim, (4, 3), 1.0, 0.0)
    both = np.vstack([probe.project(skin), probe.mirrored(plane).project(skin)])
    ext = np.ptp(both, axis=0)
    lens = 0.85 * SENSOR_MM / max(ext[0], ext[1] / 0.75)
    f_unit = np.ptp(probe.project(skin)[:, 1])
    width = int(round(SENSOR_MM * head_px / (f_unit * lens)))
    size = (width, int(round(0.75 * width)))
    cam = _look(eye, aim, size, lens * width / SENSOR_MM, 0.0)
    mcam = cam.mirrored(plane)
    views, clean = {}, {}
    hints = {"kind": "pinhole"}
    if focal_prior is not None:
        hints["lens_mm"] = float(lens * (1.0 + focal_prior * rng.normal()))
    for name, camera in (("front", cam), ("mirror", mcam)):
        names = visible_landmarks(model, world, camera, normals, min_cos, triangles=skin_tris)
        verts = np.array([model.landmarks[n] for n in names], dtype=np.int64)
        px = camera.project(world[verts])
        clean[name] = dict(zip(names, px, strict=True))
        noisy = dict(zip(names, np.clip(px + noise_px * rng.normal(size=px.shape), 0.0,
                                        size), strict=True))
        if name == "front":
            views[name] = View(name, None, size, cam if calibrated else None, noisy,
                               calibrated=True if calibrated else None,
                               camera_hints={} if calibrated else hints)
        else:
            views[name] = View(name, None, size, None, noisy, mirror_of="front",
                               camera_hints={"kind": "pinhole"})
    truth = SyntheticTruth(*head, {"front": cam, "mirror": mcam}, clean,
                           planes={"mirror": plane})
    return LandmarkCase(views, "<synthetic>"), truth


def _random_camera(rng, cam_name, size, skin_world, fill, in_plane_deg):
    """Orthographic camera with a random scale, offset and tilt that keeps the whole skin
    inside the image."""
    w, h = size
    base = ORTHO_VIEWS[cam_name]
    tilt = np.radians(rng.uniform(-in_plane_deg, in_plane_deg))
    q = np.array([[np.cos(tilt), -np.sin(tilt)], [np.sin(tilt), np.cos(tilt)]])
    rot = base.copy()
    rot[:2] = q @ base[:2]
    a = skin_world @ rot[:2].T  # image-plane metres
    lo, hi = a.min(axis=0), a.max(axis=0)
    scale = rng.uniform(*fill) * h / (hi[1] - lo[1])
    scale = min(scale, 0.95 * w / (hi[0] - lo[0]))
    ext = scale * (hi - lo)
    room = np.array([w, h]) - ext
    corner = rng.uniform(0.2, 0.8, size=2) * room
    offset = corner - scale * lo
    return OrthographicCamera(rot, scale, offset, size, cam_name)


def _neck_cut_vertices(model, triangles):
    """Vertices of the skin's open boundary loop at the bottom of the neck."""
    e = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    e = np.sort(e, axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    # Fan triangulation adds diagonals inside polygons; they are used twice like any inner
    # edge, so edges used once are exactly the boundary.
    border = uniq[count == 1]
    n = model.n_vertices
    g = coo_matrix((np.ones(len(border)), (border[:, 0], border[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    bverts = np.unique(border)
    lowest = bverts[np.argmin(model.vertices[bverts, 2])]
    return bverts[label[bverts] == label[lowest]], border


def trace_silhouette(model, world, camera, triangles=None):
    """Outer outline of the projected skin, neck cut removed, in drawing order.

    Parameters
    ----------
    model : HeadModel
    world : ndarray, shape (V, 3), metres
        Posed vertices.
    camera : OrthographicCamera
    triangles : ndarray, shape (T, 3), optional
        Skin triangles (computed when not given).

    Returns
    -------
    ndarray, shape (n, 2), pixels
        From the front of the neck over the face and skull to the back of the neck, one
        point per boundary pixel, moved half a pixel outward so it sits on the edge of the
        silhouette rather than on the centres of its outermost pixels.
    """
    tris = model.skin_triangles() if triangles is None else triangles
    neck, border = _neck_cut_vertices(model, tris)
    is_neck = np.zeros(model.n_vertices, bool)
    is_neck[neck] = True
    return trace_outline(world, tris, camera, border[is_neck[border[:, 0]] & is_neck[border[:, 1]]])


def trace_outline(world, triangles, camera, cut_edges):
    """Outer outline of a projected mesh without the stretches that are its cut edges.

    The outline a person traces on a photo follows the surface's silhouette, not where a
    mesh (a head model's neck, a scan's edge) happens to end.

    Parameters
    ----------
    world : ndarray, shape (V, 3), metres
    triangles : ndarray, shape (T, 3)
    camera : OrthographicCamera
    cut_edges : ndarray, shape (E, 2)
        Vertex pairs of the mesh's open boundary to leave out (outline pixels within 2 px of
        their projections).

    Returns
    -------
    ndarray, shape (n, 2), pixels
        The longest stretch of the outline away from the cuts, one point per boundary
        pixel, half a pixel outward, starting at its end toward the face (Blender's -Y).
    """
    w, h = camera.size
    px = camera.project(world)
    pixel, _, _ = rasterize(px[triangles], w, h)
    mask = np.zeros(h * w, bool)
    mask[pixel] = True
    mask = mask.reshape(h, w)
    loop = _moore_trace(mask)  # (n, 2) as (row, col)
    pts = loop[:, ::-1] + 0.5  # pixel centres as (u, v)
    # Outward normals from the neighbours along the loop; flip where they point inside.
    tangent = np.roll(pts, -2, axis=0) - np.roll(pts, 2, axis=0)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    probe = np.floor(pts + 1.5 * normal).astype(int)
    probe = np.clip(probe, 0, [w - 1, h - 1])
    normal[mask[probe[:, 1], probe[:, 0]]] *= -1.0
    pts = pts + 0.5 * normal
    cut = np.asarray(cut_edges, dtype=np.int64).reshape(-1, 2)
    near = geometry.distance_to_segments(pts, px[cut[:, 0]], px[cut[:, 1]]) <= 2.0
    keep = _longest_cyclic_run(~near)
    out = pts[keep]
    # Start at the end toward the face (drawing order of the profile chain).
    forward = camera.rotation[:2] @ np.array([0.0, -1.0, 0.0])
    if out[0] @ forward < out[-1] @ forward:
        out = out[::-1]
    return out


def _moore_trace(mask):
    """Outer boundary of the 8-connected component holding the first set pixel (raster
    order) of a boolean image, as (row, col) pixels in order (Moore-neighbour tracing)."""
    h, w = mask.shape
    pad = np.zeros((h + 2, w + 2), bool)
    pad[1:-1, 1:-1] = mask
    flat = np.flatnonzero(pad)
    if flat.size == 0:
        raise ValueError("silhouette: the projected head covers no pixel")
    start = (int(flat[0] // (w + 2)), int(flat[0] % (w + 2)))
    out = [start]
    cur = start
    back = 0  # index into _MOORE of the (empty) neighbour we came from: west of the start
    first_step = None
    for _ in range(8 * pad.size):
        for i in range(1, 9):
            d = (back + i) % 8
            r, c = cur[0] + _MOORE[d][0], cur[1] + _MOORE[d][1]
            if pad[r, c]:
                # The neighbour checked just before d is empty: it becomes the backtrack,
                # expressed relative to the new pixel.
                pr, pc = cur[0] + _MOORE[(d - 1) % 8][0], cur[1] + _MOORE[(d - 1) % 8][1]
                nxt = (r, c)
                back = _direction(nxt, (pr, pc))
                break
        else:  # isolated pixel
            break
        if first_step is None:
            first_step = nxt
        elif cur == start and nxt == first_step:
            break
        cur = nxt
        out.append(cur)
    loop = np.array(out[:-1] if len(out) > 1 and out[-1] == start else out)
    return loop - 1


def _direction(frm, to):
    d = (to[0] - frm[0], to[1] - frm[1])
    for i, m in enumerate(_MOORE):
        if m[0] == d[0] and m[1] == d[1]:
            return i
    raise ValueError("moore trace: pixels are not neighbours")


def _longest_cyclic_run(flags):
    """Indices of the longest run of True in a cyclic boolean array, in order."""
    n = len(flags)
    if flags.all():
        return np.arange(n)
    if not flags.any():
        raise ValueError("silhouette: nothing left once the cut edges are removed")
    shift = int(np.flatnonzero(~flags)[0])
    f = np.roll(flags, -shift)  # starts with False: runs do not wrap
    edges = np.diff(np.concatenate([[0], f.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    i = int(np.argmax(ends - starts))
    return (np.arange(starts[i], ends[i]) + shift) % n


def resample_polyline(points, n):
    """``n`` points evenly spaced by arc length along a polyline (ends kept), (n, 2)."""
    p = np.asarray(points, dtype=np.float64)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    t = np.linspace(0.0, s[-1], int(n))
    return np.stack([np.interp(t, s, p[:, 0]), np.interp(t, s, p[:, 1])], axis=1)


def skin_squared_distances(model, local, truth_local):
    """Squared distance of each skin vertex (``model.skin``), (n,) square metres, between
    ``local`` and ``truth_local`` (V, 3) in metres, after the similarity alignment over the
    skin (photos cannot tell size)."""
    a, b = local[model.skin], truth_local[model.skin]
    sim = similarity_procrustes(a, b)
    return ((sim.apply(a) - b) ** 2).sum(axis=1)


def skin_error_mm(model, local, truth_local):
    """RMS vertex distance over the skin, millimetres, between ``local`` and
    ``truth_local`` (V, 3) in metres, after similarity alignment
    (:func:`skin_squared_distances`): how the tests and the benchmarks measure a fitted
    head."""
    return 1000.0 * float(np.sqrt(skin_squared_distances(model, local, truth_local).mean()))

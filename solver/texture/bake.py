"""The texture bake: a texture in the model's own UV layout (``model.loop_uv``, rasterised
by ``uvs.py``) from all photos at once, which the thesis names as the missing piece (§9).

Each texel's surface point is projected into every photo, sampled where the photo sees it
(depth-buffer occlusion test) and blended by how squarely the surface faces that photo; a
profile photo is also used mirrored across the head's mid-sagittal plane so the far cheek
gets the near cheek's colours; what no photo sees is filled smoothly over the mesh, and the
UV islands get a few texels of bleed so mipmapping shows no seams. Before blending, the
photos are equalised (a gain and an offset per photo, then a smooth levelling of each
photo pass to the reference: ``equalise.py``, ``levelling.py``) and each one's weight fades
in from the edge of what it sees (``seams.py``); the light can be divided out
(``shading.py``, an option).
:func:`bake_tiles` returns one texture per UDIM tile, :func:`bake_texture` one tile;
:func:`bake_samples` the photo passes unblended (to measure them against each other).

Photo convention: pixel (u, v) with the origin at the image's top-left corner and the
image spanning [0, W] x [0, H], so pixel (i, j) is centred on (i + 0.5, j + 0.5) (the
nominal orthographic camera puts the world origin at (W / 2, H / 2)). Colours are blended
in the photos' own encoding (sRGB values in, sRGB values out).

Parts: by default the skin ("Face", "Head and Neck"). Eyes, teeth, mouth interior and the
eye overlay meshes are not baked: they are hidden or transparent on the photos, and the
add-on gives them their own materials (``parts=["Eyeball left"]`` bakes one if wanted; the
skin still occludes it).

Typical use (the UV rasters are kept with the model, so repeated bakes skip the
rasterisation)::

    tiles = bake_fit_texture(model, result, {"front": front_rgb, "right": side_rgb})
"""

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np
import scipy.ndimage as ndi
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..cores import usable_cores
from ..errors import as_points
from ..geometry import vertex_normals
from .clothes import clothes_mask
from .equalise import apply_gains, default_reference, fit_gains
from .levelling import level_field
from .raster import depth_buffer
from .seams import edge_graph, seam_fade
from .shading import mesh_operators, remove_shading, shading_factor
from .uvs import (
    BLEED,
    SKIN_PARTS,
    UVRaster,
    mesh_laplacian,
    resolve_parts,
    selected_triangles,
    uv_raster,
    uv_tiles,
)

#: Longest photo side the bake samples, per texel of the texture's height: a photo larger
#: than this is reduced before the bake (``bake_photo_size``). The skin's face tile spans
#: about a quarter of a portrait photo's height, so 4 photo pixels per texel still give
#: each texel its own pixel on a face a quarter of the photo high.
PHOTO_PIXELS_PER_TEXEL = 4

#: Texels sampled at once (``_sample_tile``): a 1024-texel face tile has about a million,
#: and sampling them all at once held about 200 MB of temporaries.
SAMPLE_BLOCK = 1 << 17

#: ``BakeOptions.shading``: keep the photos' light, or remove its low-frequency part.
SHADING_MODES = ("keep", "remove")
#: ``BakeOptions.clothes``: leave out what the photos show of the clothes, or keep it
#: (spelt as command lines, manifests and the add-on take it: no space to quote).
CLOTHES_MODES = ("leave-out", "keep")

#: Overlap texels the colour equalisation is fitted on at most (every k-th is taken): the
#: twelve numbers per photo are settled long before that.
EQUALISE_TEXELS = 50_000

#: Least blend weight (``cos ** power``, times ``mirror_weight`` for a mirrored pass) of
#: both passes at a texel the levelling matches them on: 0.02 is about 75 degrees off each
#: camera at power 3; grazing samples near a photo's outline are darker and blurred.
LEVEL_WEIGHT = 0.02


def bake_photo_size(photo_size, texture_size):
    """The (width, height) a photo is reduced to for a bake of ``texture_size`` texels: the
    photo's own size when its longer side is at most ``PHOTO_PIXELS_PER_TEXEL`` texels per
    texture row (never below 2048), else scaled down to that, aspect kept. The bake takes
    the reduced photo with the camera of the full one (``bake_tiles``)."""
    w, h = (int(v) for v in photo_size)
    most = max(2048, PHOTO_PIXELS_PER_TEXEL * int(texture_size))
    if max(w, h) <= most:
        return w, h
    f = most / max(w, h)
    return max(1, round(w * f)), max(1, round(h * f))


def _photo_scale(image_size, camera_size):
    """(sx, sy) from the camera's pixels to the image's, or None when the image is neither
    the camera's photo nor that photo reduced with its aspect kept (within a pixel)."""
    (w, h), (cw, ch) = image_size, camera_size
    if (w, h) == (cw, ch):
        return 1.0, 1.0
    if w > cw or h > ch or abs(w - cw * h / ch) > 1 or abs(h - ch * w / cw) > 1:
        return None
    return w / cw, h / ch


@dataclass(frozen=True)
class BakeOptions:
    """Knobs of the texture bake (defaults suit two photos of about 1 megapixel).

    Attributes
    ----------
    power : float
        Blend weight of a view is ``max(0, n . toward_camera) ** power``: larger prefers
        the photo that sees a spot most squarely and fades grazing samples faster.
    mirror_weight : float
        Factor on the weight of a mirrored profile photo, below 1 so a photo that sees a
        spot directly wins over the mirrored guess.
    mirror_min_lateral : float
        A view is used mirrored (with ``mirror=True``) when its direction toward the camera
        has at least this component along the symmetry plane's normal (0.5: 30 degrees or
        more off the front, i.e. side and three-quarter views, never the front photo).
    fill_weight : float
        Texels whose total weight is below this are blended with the smooth fill, fully
        where nothing sees them; keeps grazing, noisy samples from standing out.
    depth_resolution : int
        Longer side, in pixels, of each photo's depth buffer (at most the photo's size).
    depth_tolerance : float
        Slack of the occlusion test as a fraction of the head's size (the baked and
        occluding parts' bounding-box diagonal, 0.48 m for the ICT skin: 0.01 is about
        5 mm, less than an ear stands off the head); the depth a surface spans across a
        buffer pixel at its slope is added on top.
    feather : float
        Width over which a photo's weight fades in from the head's outline in it, as a
        fraction of the head's size (0.02: about 1 cm; 0: no fading).
    bleed : int
        Texels outside the UV islands that copy their nearest island texel, so filtering
        and mipmaps never sample the background colour at a seam.
    equalise : bool
        Fit a gain and an offset per channel to every photo but the reference (the one
        that overlaps the others most, normally the front photo) on the texels two photos
        see directly, and apply them before blending (a profile used mirrored takes its
        photo's; ``fit_view_gains``, ``equalise.fit_gains``), so photos of another exposure
        or white balance meet without a step.
    level : bool
        With ``equalise``: then level every photo pass but the reference to it with a
        smooth additive correction over the surface (``levelling.level_field``), for the
        step a global gain leaves where the light differs from place to place (a profile
        used mirrored carries the other cheek's light).
    level_length : float
        Smoothing length of that correction, as a fraction of the head's size (0.015: about
        7 mm; measured in docs/DECISIONS.md, "Texture seams").
    level_decay : float
        Distance over which that correction fades away from the overlap, as a fraction
        of the head's size (0.1: about 5 cm), so a photo keeps its own colours far from its
        seams.
    seam_feather : float
        Width over which a photo's weight fades in from the edge of what it sees on the
        surface (occlusion edges, where it faces away), as a fraction of the head's size
        (0.03: about 1.5 cm; 0: off; ``seams.seam_fade``). Only the shares of the photos
        change, not the texel's total weight.
    shading : str
        "keep" the photos' light in the texture, or "remove" its low-frequency part (a
        smoothed luminance over the surface, divided out: ``shading.py``) for a flat,
        albedo-like texture.
    shading_length : float
        Smoothing length of the light estimate, as a fraction of the head's size (0.06:
        about 3 cm).
    clothes : str
        ``bake_fit_texture``: "leave-out" what a photo shows below the chin that is not
        skin and reaches its bottom edge (a collar, a shirt: ``clothes.py``), so the neck
        the model has under them gets the smooth fill; or "keep" every pixel.
    threads : int
        Threads the bake works in at once (blocks of texels, each photo's depth buffer,
        each photo's levelling, each tile's blend); 0 (default): as many as the process
        may use cores (``usable_cores``), for one head at a time; 1 where other processes
        share the cores (a batch's workers). The texture is the same for any number.
    """

    power: float = 3.0
    mirror_weight: float = 0.5
    mirror_min_lateral: float = 0.5
    fill_weight: float = 0.05
    depth_resolution: int = 512
    depth_tolerance: float = 0.01
    feather: float = 0.02
    bleed: int = BLEED
    equalise: bool = True
    level: bool = True
    level_length: float = 0.015
    level_decay: float = 0.1
    seam_feather: float = 0.03
    shading: str = "keep"
    shading_length: float = 0.06
    clothes: str = "leave-out"
    threads: int = 0

    def __post_init__(self):
        checks = {"power": self.power > 0, "mirror_weight": self.mirror_weight >= 0,
                  "mirror_min_lateral": 0 <= self.mirror_min_lateral <= 1,
                  "fill_weight": self.fill_weight > 0,
                  "depth_resolution": self.depth_resolution >= 8,
                  "depth_tolerance": self.depth_tolerance >= 0, "feather": self.feather >= 0,
                  "bleed": self.bleed >= 0, "seam_feather": self.seam_feather >= 0,
                  "shading": self.shading in SHADING_MODES,
                  "clothes": self.clothes in CLOTHES_MODES,
                  "shading_length": self.shading_length > 0,
                  "level_length": self.level_length > 0,
                  "level_decay": self.level_decay > self.level_length,
                  "threads": self.threads >= 0}
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"BakeOptions.{name}: out of range ({getattr(self, name)!r})")


def bake_texture(model, world_vertices, views, size=1024, *, parts=None, tile=None,
                 similarity=None, mirror=True, occluders=None, raster=None, options=None):
    """Bake one UV tile's texture from photos.

    Parameters
    ----------
    model : HeadModel
    world_vertices : ndarray, shape (V, 3), metres
        The fitted head in world space (``FitResult.world_vertices``).
    views : list of (image, camera)
        ``image`` ndarray (H, W, 3 or 4) float in [0, 1] (an alpha channel weighs the
        pixel: 0 = background); ``camera`` the photo's fitted Camera. The image may be the
        camera's photo reduced with its aspect kept (``bake_photo_size``): it is sampled
        where the full photo would be.
    size : int
        Texture size in texels.
    parts, tile
        What to bake: see :func:`uv_raster` (default the skin; ``tile`` must be given when
        the parts span several UV tiles, as the ICT skin does: use :func:`bake_tiles`).
    similarity : Similarity or (scale, rotation, translation), optional
        The fit's local -> world map (``FitResult.scale, .rotation, .translation``); the
        mid-sagittal plane is local x = 0. Default: world = local.
    mirror : bool or sequence of bool
        Use side views mirrored across the mid-sagittal plane too: True picks the views
        that look at the head from the side (see ``BakeOptions.mirror_min_lateral``); a
        sequence says it per view.
    occluders : sequence of str or int, optional
        Parts besides the baked ones that can hide a texel from a photo (they go into the
        depth buffers); default the skin, so e.g. eyelids hide the eyeball behind them.
    raster : UVRaster, optional
        A raster from :func:`uv_raster` to reuse (must match model, size, parts, tile).
    options : BakeOptions, optional

    Returns
    -------
    ndarray, shape (size, size, 3), float32
        Row 0 is the top of the texture (v = 1).
    """
    opts = _options(options)
    if raster is None:
        raster = uv_raster(model, size, parts=parts, tile=tile, bleed=opts.bleed)
    else:
        _check_raster(raster, model, size, parts, tile)
    return _bake(model, world_vertices, views, [raster], parts, occluders, similarity,
                 mirror, opts)[raster.tile]


def bake_tiles(model, world_vertices, views, size=1024, *, parts=None, similarity=None,
               mirror=True, occluders=None, rasters=None, options=None, keep=None):
    """Bake every UV tile the chosen parts use (the skin: tiles 1001 and 1002).

    Parameters are those of :func:`bake_texture`; ``rasters`` optionally gives the cached
    rasters (a dict tile -> UVRaster, e.g. from a previous call's :func:`uv_raster`);
    ``keep``, per view, None or an (H, W) bool mask of its image: pixels outside it are
    not baked (as alpha 0).

    Returns
    -------
    dict of int -> ndarray (size, size, 3) float32
        UDIM tile number -> texture.
    """
    opts = _options(options)
    rs = _rasters(model, size, parts, rasters, opts)
    return _bake(model, world_vertices, views, rs, parts, occluders, similarity, mirror, opts,
                 keep)


def bake_fit_texture(model, result, images, size=1024, *, parts=None, mirror=True,
                     occluders=None, options=None):
    """Bake from a FitResult: its world vertices, cameras and similarity.

    Parameters
    ----------
    model : HeadModel
    result : FitResult
    images : dict of str -> ndarray (H, W, 3 or 4)
        Photo of each view to use, keyed like ``result.cameras``.
    size, parts, mirror, occluders, options
        As in :func:`bake_tiles`.

    Returns
    -------
    dict of int -> ndarray (size, size, 3) float32
    """
    opts = _options(options)
    views = []
    for name, image in images.items():
        if name not in result.cameras:
            raise ValueError(f"images: view {name!r} has no camera in the fit result "
                             f"(it has {', '.join(result.cameras)})")
        views.append((image, result.cameras[name]))
    keep = None
    if opts.clothes == "leave-out":
        keep = _map(lambda v: _without_clothes(model, result.world_vertices, v[1], v[0]),
                    views, opts.threads)
    return bake_tiles(model, result.world_vertices, views, size, parts=parts,
                      similarity=(result.scale, result.rotation, result.translation),
                      mirror=mirror, occluders=occluders, options=opts, keep=keep)


def _without_clothes(model, world, camera, image):
    """The pixels of a view's image that are not clothes (``clothes.clothes_mask``), or
    None (every pixel) where that cannot be told: an image of another size than its
    camera's photo and the photo reduced, or too little cheek in it."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] not in (3, 4):
        return None  # the bake names the fault
    scale = _camera_to_image(img, camera)
    if scale is None:
        return None
    clothes = clothes_mask(model, world, camera, _unit_range(img), scale)
    return None if clothes is None else ~clothes


def _unit_range(img):
    """An image's integer values as floats in [0, 1]; float images as they are."""
    if np.issubdtype(img.dtype, np.integer):
        return img.astype(np.float32) / np.iinfo(img.dtype).max
    return img


def _camera_to_image(img, camera):
    """(sx, sy) from the camera's pixels to the image's (``_photo_scale``; 1 for a camera
    without a size), or None when the image is not its photo."""
    size = getattr(camera, "size", None)
    if size is None:
        return 1.0, 1.0
    return _photo_scale((img.shape[1], img.shape[0]), (int(size[0]), int(size[1])))


def _options(options):
    if options is None:
        return BakeOptions()
    if not isinstance(options, BakeOptions):
        raise ValueError(f"options: expected BakeOptions, got {type(options).__name__}")
    return options


def _check_raster(raster, model, size, parts, tile):
    if not isinstance(raster, UVRaster):
        raise ValueError(f"raster: expected a UVRaster, got {type(raster).__name__}")
    _, names = resolve_parts(model, parts)
    n = int(np.asarray(model.vertices).shape[0])
    if raster.size != size or raster.parts != names or raster.n_vertices != n or (
            tile is not None and raster.tile != int(tile)):
        raise ValueError(f"raster: built for size {raster.size}, parts {raster.parts}, tile "
                         f"{raster.tile}, {raster.n_vertices} vertices; asked size {size}, "
                         f"parts {names}, tile {tile}, {n} vertices")


def _check_views(views, keep=None):
    """[(image float32 (H, W, 3|4) premultiplied, camera, (sx, sy))] of the views; a
    ``keep`` mask (H, W) bool of a view (None: all) becomes its image's alpha."""
    if isinstance(views, tuple) and len(views) == 2 and hasattr(views[1], "project"):
        views = [views]  # a single (image, camera) pair
    keep = list(keep) if keep is not None else [None] * len(views)
    if len(keep) != len(views):
        raise ValueError(f"keep: {len(keep)} masks for {len(views)} views")
    out = []
    for i, view in enumerate(views):
        try:
            image, camera = view
        except (TypeError, ValueError):
            raise ValueError(f"views[{i}]: expected an (image, camera) pair") from None
        img = np.asarray(image)
        if img.ndim != 3 or img.shape[2] not in (3, 4) or min(img.shape[:2]) < 1:
            raise ValueError(f"views[{i}]: image must have shape (H, W, 3) or (H, W, 4), "
                             f"got {img.shape}")
        if not (np.issubdtype(img.dtype, np.integer) or np.issubdtype(img.dtype, np.floating)):
            raise ValueError(f"views[{i}]: image dtype {img.dtype} is not numeric")
        img = _unit_range(img)
        if keep[i] is not None and img.shape[2] == 3:  # the mask as alpha, in one copy
            rgba = np.empty(img.shape[:2] + (4,), np.float32)
            rgba[..., :3] = img
            rgba[..., 3] = 1.0
            img = rgba
        else:
            img = np.array(img, dtype=np.float32)
        if not np.isfinite(img).all():
            raise ValueError(f"views[{i}]: image has NaN or infinite values")
        if keep[i] is not None:
            if np.shape(keep[i]) != img.shape[:2]:
                raise ValueError(f"keep[{i}]: mask of shape {np.shape(keep[i])} for an image "
                                 f"of {img.shape[1]}x{img.shape[0]} pixels")
            img[..., 3] *= np.asarray(keep[i], dtype=bool)
        if img.shape[2] == 4:  # premultiply, so bilinear samples never mix in hidden colour
            img[..., 3] = np.clip(img[..., 3], 0.0, 1.0)
            _by_row(img[..., :3], img[..., 3])
        if not hasattr(camera, "project") or not hasattr(camera, "to_camera"):
            raise ValueError(f"views[{i}]: camera must be a Camera, got {type(camera).__name__}")
        scale = _camera_to_image(img, camera)
        if scale is None:
            h, w = img.shape[:2]
            size = camera.size
            raise ValueError(f"views[{i}]: image is {w}x{h} pixels but its camera expects "
                             f"{int(size[0])}x{int(size[1])} (or that photo reduced)")
        out.append((img, camera, scale))
    if not out:
        raise ValueError("views: no photos given")
    return out


def _plane(similarity):
    """Mid-sagittal plane (point, unit normal) in world space from local x = 0."""
    if similarity is None:
        return np.zeros(3), np.array([1.0, 0.0, 0.0])
    if hasattr(similarity, "rotation"):
        scale, rot, trans = similarity.scale, similarity.rotation, similarity.translation
    else:
        try:
            scale, rot, trans = similarity
        except (TypeError, ValueError):
            raise ValueError("similarity: expected (scale, rotation, translation)") from None
    rot = np.asarray(rot, dtype=np.float64)
    trans = np.asarray(trans, dtype=np.float64)
    if rot.shape != (3, 3) or trans.shape != (3,) or not np.isfinite(rot).all() or \
            not np.isfinite(trans).all() or not np.isfinite(float(scale)):
        raise ValueError("similarity: rotation must be a finite (3, 3) and translation a "
                         "finite (3,) array")
    normal = rot[:, 0]
    norm = np.linalg.norm(normal)
    if norm < 1e-12:
        raise ValueError("similarity: rotation has a zero first column")
    return trans, normal / norm


class _ViewSampler:
    """One photo with its camera and a depth buffer of the head, ready to colour texels.

    The camera is evaluated at the vertices only and its pixel position, depth and
    direction interpolated to the texels like any vertex attribute: exact for parallel
    projection, and off by far less than a pixel for a perspective camera over triangles
    of a few millimetres; a million texels then cost sparse products, not camera calls.
    """

    def __init__(self, image, camera, scale, world, occluders, head_size, centre, opts):
        self.h, self.w = image.shape[:2]
        self.scale = np.asarray(scale, dtype=np.float64)  # camera pixels -> image pixels
        self.alpha = image.shape[2] == 4
        # Four float32 channels viewed as one complex128: one 16-byte gather per pixel.
        # A one-pixel edge-replicated border spares clamping the bilinear neighbours.
        rgba = np.zeros((self.h + 2, self.w + 2, 4), np.float32)
        rgba[1:-1, 1:-1, :image.shape[2]] = image
        rgba[0], rgba[-1] = rgba[1], rgba[-2]
        rgba[:, 0], rgba[:, -1] = rgba[:, 1], rgba[:, -2]
        self.texels = rgba.reshape(-1, 4).view(np.complex128).ravel()
        self.camera = camera
        self.power = opts.power
        f = min(1.0, opts.depth_resolution / max(self.w, self.h))
        self.bw, self.bh = max(1, round(self.w * f)), max(1, round(self.h * f))
        self.fx, self.fy = self.bw / self.w, self.bh / self.h
        self.used = np.unique(occluders)
        self.direct = self._vertex_terms(world)
        px = self.direct[0][:, :2] * (self.fx, self.fy)
        depth = depth_buffer(px[occluders], self.direct[0][occluders, 2], self.bw, self.bh)
        # Nearest depth over each pixel's 3x3 neighbourhood: a point just beside a nearer
        # silhouette counts as hidden, so the occluder's blurred edge in the photo (and a
        # slightly-off fit) does not paint a rim of the front surface onto the one behind.
        near = ndi.minimum_filter(depth, size=3, mode="nearest")
        self.depth = near.astype(np.float32).ravel()
        # one buffer pixel in metres at the head, for the slope part of the tolerance
        ppm = camera.pixels_per_metre(centre[None], self.scale)[0]
        self.footprint = np.float32(1.0 / (ppm * min(self.fx, self.fy)))
        self.tol = np.float32(opts.depth_tolerance * head_size)
        self.feather = self._feather(depth, opts.feather * head_size / self.footprint)
        self.mirrored = None

    def _feather(self, depth, feather):
        """Weight factor (bh * bw,) rising from 0 at the head's outline in this photo to 1
        ``feather`` buffer pixels inside, so the blend fades out where a small fit error
        would sample the photo's background; None when feathering is off.

        Only the outline against the background fades: inner occlusion edges (nose over
        cheek) are handled by the depth test, and a steep but continuous surface is no
        edge at all.
        """
        if feather <= 0:
            return None
        outline = np.isinf(ndi.maximum_filter(depth, size=3, mode="nearest"))
        if not outline.any():
            return None
        dist = ndi.distance_transform_edt(~outline)
        return np.clip(dist / feather, 0.0, 1.0).astype(np.float32).ravel()

    def _vertex_terms(self, world):
        """Per vertex: (pixel u, pixel v, depth) (V, 3) and toward-camera (V, 3) or (3,)."""
        pts = world[self.used]
        # float32 per texel: 1e-4 pixel and sub-micrometre depth resolution, half the traffic
        uvz = np.zeros((len(world), 3), np.float32)
        uvz[self.used, :2] = self.camera.project(pts) * self.scale
        uvz[self.used, 2] = self.camera.to_camera(pts)[:, 2]
        toward = np.asarray(self.camera.toward_camera(pts), dtype=np.float64)
        if np.ptp(toward, axis=0).max() < 1e-12:  # parallel projection: one direction
            return uvz, toward[0].astype(np.float32)
        full = np.zeros((len(world), 3), np.float32)
        full[self.used] = toward
        return uvz, full

    def mirror(self, world, plane_point, plane_normal):
        """Use the photo for the head reflected through the mid-sagittal plane."""
        if self.mirrored is None:
            refl = world - 2.0 * ((world - plane_point) @ plane_normal)[:, None] * plane_normal
            uvz, toward = self._vertex_terms(refl)
            # the reflected surface's normal is the reflected normal: n' . t = n . refl(t)
            toward = toward - 2.0 * (toward @ plane_normal)[..., None] * plane_normal
            self.mirrored = (uvz, toward.astype(np.float32))
        return self.mirrored

    def sample(self, normals, cos, uvz, factor=1.0):
        """Texels (k,) the photo sees, their weights (k,) and colours (k, 3).

        ``normals`` (N, 3) are the texels' unit normals, ``cos`` (N,) their cosine with
        the direction toward the camera, ``uvz`` (N, 3) their pixel position and depth
        (all interpolated from the vertex terms of the direct or mirrored head).
        """
        u, v, z = uvz[:, 0], uvz[:, 1], uvz[:, 2]
        idx = np.flatnonzero((cos > 1e-3) & (u >= 0) & (u < self.w) & (v >= 0) & (v < self.h))
        u, v, z, c = u[idx], v[idx], z[idx], cos[idx]
        bx = np.minimum((u * np.float32(self.fx)).astype(np.intp), self.bw - 1)
        by = np.minimum((v * np.float32(self.fy)).astype(np.intp), self.bh - 1)
        slope = np.minimum(np.sqrt(np.maximum(1 - c * c, 0)) / c, np.float32(8))
        reach = self.tol + self.footprint * (1 + 2 * slope)  # own pixel + neighbours
        cell = by * self.bw + bx
        ok = z <= self.depth[cell] + reach
        idx, u, v, c, cell = idx[ok], u[ok], v[ok], c[ok], cell[ok]
        rgba = _bilinear(self.texels, self.w, u, v)
        w = np.float32(factor) * c ** np.float32(self.power)
        if self.feather is not None:
            w *= self.feather[cell]
        rgb = rgba[:, :3]
        if self.alpha:  # premultiplied: un-premultiply, weigh by coverage
            alpha = rgba[:, 3]
            w *= alpha
            rgb = _by_row(rgb, np.maximum(alpha, 1e-6), np.divide)  # rgba is ours
        return idx, w, rgb


def _by_row(a, s, op=np.multiply):
    """``a`` (..., k) combined in place with ``s`` (...) by ``op`` (multiply or divide),
    each of its k columns at a time: numpy broadcasting ``s[..., None]`` over a last axis
    of 3 or 4 runs its inner loop that short, several times slower. Returns ``a``."""
    for c in range(a.shape[-1]):
        op(a[..., c], s, out=a[..., c])
    return a


def _bilinear(texels, w, u, v):
    """Bilinear samples (n, 4) float32 at pixel positions ``u`` in [0, w), ``v`` in [0, h)
    (n,) of an image stored with a one-pixel border, one complex128 (= four float32
    channels) per pixel, row-major ((h + 2) * (w + 2),)."""
    x = u + np.float32(0.5)  # pixel centres at +0.5, shifted by the border
    y = v + np.float32(0.5)
    x0 = np.floor(x)
    y0 = np.floor(y)
    tx = x - x0
    ty = y - y0
    stride = w + 2
    i = y0.astype(np.intp) * stride + x0.astype(np.intp)

    def gather(j):
        return texels.take(j).view(np.float32).reshape(-1, 4)

    def lerp(a, b, t):  # a + (b - a) t, in place in a (b is spent)
        b -= a
        a += _by_row(b, t)
        return a

    top = lerp(gather(i), gather(i + 1), tx)
    bottom = lerp(gather(i + stride), gather(i + stride + 1), tx)
    return lerp(top, bottom, ty)


@dataclass(frozen=True, eq=False)
class TileSamples:
    """What every photo pass says about one UV tile's texels, before they are blended.

    A pass is a photo as seen directly, or a profile photo used mirrored
    (``BakeOptions.mirror_weight``); passes are in the order of the views, each view's
    direct pass before its mirrored one.

    Attributes
    ----------
    raster : UVRaster
    colours : ndarray, shape (P, N, 3), float32
        Each pass's colour at the raster's texels (0 where it does not see them).
    weights : ndarray, shape (P, N), float32
        Each pass's blend weight (after the seam fade; 0 where it does not see them).
    seen : ndarray, shape (P, N), float32
        The weights before the seam fade (what the pass sees, how squarely).
    view : ndarray, shape (P,), int
        The view (index into ``views``) of each pass.
    """

    raster: UVRaster
    colours: np.ndarray
    weights: np.ndarray
    seen: np.ndarray
    view: np.ndarray


@dataclass(frozen=True, eq=False)
class _Context:
    world: np.ndarray
    normals: np.ndarray
    samplers: list
    plane: tuple
    head_size: float
    opts: BakeOptions


def bake_samples(model, world_vertices, views, size=1024, *, parts=None, similarity=None,
                 mirror=True, occluders=None, rasters=None, options=None):
    """Every photo pass's colours and weights on every UV tile, unblended (what
    :func:`bake_tiles` equalises and blends; for measuring the views against each other).

    Parameters are those of :func:`bake_tiles`.

    Returns
    -------
    dict of int -> TileSamples
        UDIM tile number -> the tile's samples.
    """
    opts = _options(options)
    rs = _rasters(model, size, parts, rasters, opts)
    ctx = _context(model, world_vertices, views, rs, parts, occluders, similarity, mirror,
                   opts)
    return _samples(ctx, rs)


def fit_view_gains(samples, options=None):
    """Each pass's gain and offset per channel (``equalise.fit_gains``) from the samples of
    every tile (:func:`bake_samples`): one gain and offset per photo, fitted on the texels
    two photos see directly, the photo that overlaps the others most (normally the front)
    fixed. A profile's mirrored pass takes its photo's: the exposure is the photo's, while
    the other cheek's light it carries is the levelling's to match
    (:func:`equalised_colours`; measured in docs/DECISIONS.md, "Texture seams").

    Returns
    -------
    gain, offset : ndarray, shape (P, 3)
        Identity (ones, zeros) when ``options.equalise`` is off.
    """
    opts = _options(options)
    first = next(iter(samples.values()))
    view = first.view
    p = len(view)
    direct = np.flatnonzero(np.r_[True, view[1:] != view[:-1]])  # each view's first pass
    if not opts.equalise or len(direct) < 2:
        return np.ones((p, 3)), np.zeros((p, 3))
    both = {t: np.flatnonzero(_count_seen(s.seen, direct) >= 2) for t, s in samples.items()}
    step = max(1, sum(len(b) for b in both.values()) // EQUALISE_TEXELS)
    # only the texels used are gathered: a whole tile's passes are tens of MB
    cols = [s.colours[direct[:, None], both[t][::step]] for t, s in samples.items()]
    ws = [s.seen[direct[:, None], both[t][::step]] for t, s in samples.items()]
    row = np.searchsorted(direct, np.arange(p), side="right") - 1  # pass -> its photo's row
    gain, offset = fit_gains(np.concatenate(cols, axis=1), np.concatenate(ws, axis=1),
                             reference=int(row[view_reference(samples)]))
    return gain[row], offset[row]


def _count_seen(seen, passes):
    """How many of the ``passes`` (rows of ``seen`` (P, N)) see each texel, (N,)."""
    count = np.zeros(seen.shape[1], np.int8)
    for k in passes:
        count += seen[k] > 0
    return count


def view_reference(samples):
    """The pass the others are equalised to (``equalise.default_reference`` over every
    tile's weights: the one that overlaps the others most, normally the front photo)."""
    cols = [s.seen[:, ::max(1, s.seen.shape[1] // EQUALISE_TEXELS)]
            for s in samples.values()]
    return default_reference(np.concatenate(cols, axis=1))


def _rasters(model, size, parts, rasters, opts):
    rs = []
    for t in uv_tiles(model, parts):
        r = (rasters or {}).get(t)
        if r is None:
            r = uv_raster(model, size, parts=parts, tile=t, bleed=opts.bleed)
        else:
            _check_raster(r, model, size, parts, t)
        rs.append(r)
    return rs


def _context(model, world_vertices, views, rasters, parts, occluders, similarity, mirror,
             opts, keep=None):
    n_vertices = int(np.asarray(model.vertices).shape[0])
    world = as_points(world_vertices, "world_vertices")
    if len(world) != n_vertices:
        raise ValueError(f"world_vertices: expected {n_vertices} vertices (the model's), "
                         f"got {len(world)}")
    views = _check_views(views, keep)
    point, normal_m = _plane(similarity)
    idx, _ = resolve_parts(model, parts)
    if occluders is None:
        skin = {n.lower() for n in SKIN_PARTS}
        occ_idx = set(idx) | {i for i, n in enumerate(model.part_names) if n.lower() in skin}
    else:
        occ_idx = set(resolve_parts(model, occluders)[0])
    occluders, _, _ = selected_triangles(model, tuple(sorted(occ_idx | set(idx))))

    normals = vertex_normals(world, occluders)
    used = np.unique(occluders)
    lo, hi = world[used].min(axis=0), world[used].max(axis=0)
    head_size = float(np.linalg.norm(hi - lo))
    centre = (lo + hi) / 2.0

    if isinstance(mirror, bool | np.bool_):
        mirror_flags = None if mirror else [False] * len(views)
    else:
        mirror_flags = [bool(m) for m in mirror]
        if len(mirror_flags) != len(views):
            raise ValueError(f"mirror: {len(mirror_flags)} flags for {len(views)} views")
    built = _map(lambda v: _ViewSampler(*v, world, occluders, head_size, centre, opts), views,
                 opts.threads)
    samplers = []
    for i, ((_, cam, _), s) in enumerate(zip(views, built, strict=True)):
        if mirror_flags is None:
            toward = np.asarray(cam.toward_camera(centre[None]), dtype=np.float64)[0]
            use_mirror = abs(float(toward @ normal_m)) >= opts.mirror_min_lateral
        else:
            use_mirror = mirror_flags[i]
        samplers.append((s, use_mirror))
    return _Context(world, normals, samplers, (point, normal_m), head_size, opts)


def _bake(model, world_vertices, views, rasters, parts, occluders, similarity, mirror,
          options, keep=None):
    ctx = _context(model, world_vertices, views, rasters, parts, occluders, similarity,
                   mirror, options, keep)
    samples = _samples(ctx, rasters)
    ctx = replace(ctx, samplers=())  # the photos and their depth buffers: sampled, let go
    colours = equalised_colours(samples, ctx.world, ctx.opts, ctx.head_size, in_place=True)
    sums = dict(zip(samples, _map(lambda sc: _weighted(*sc),
                                  [(s, colours[t]) for t, s in samples.items()],
                                  ctx.opts.threads), strict=True))
    del samples, colours  # every pass of every texel: free them before the textures
    fill = _smooth_fill(model, rasters, sums, ctx.opts.fill_weight)
    blended = {r.tile: _blend(r, *sums[r.tile], fill, ctx.opts) for r in rasters}
    del sums
    if ctx.opts.shading == "remove":
        _remove_shading(blended, rasters, ctx)
    out = {}
    for raster in rasters:
        size = raster.size
        tex = np.empty((size * size, 3), np.float32)
        acc = blended[raster.tile]
        if len(raster.texel) == 0:
            tex[:] = 0.5
        else:
            tex[:] = np.einsum("ij->j", acc) / len(acc)  # outside the islands: the mean
            tex[raster.texel] = acc
            tex[raster.bleed_to] = tex[raster.bleed_from]
        out[raster.tile] = tex.reshape(size, size, 3)
    return out


def _samples(ctx, rasters):
    samples = {r.tile: _sample_tile(r, ctx) for r in rasters}
    if ctx.opts.seam_feather > 0:
        _fade_seams(samples, rasters, ctx)
    return samples


def _sample_tile(raster, ctx):
    """Colours (P, N, 3) and weights (P, N) of every pass at the raster's texels."""
    opts = ctx.opts
    n = len(raster.texel)
    # Every per-vertex quantity the passes need goes through the sparse interpolation in
    # one product: (normal | per pass: pixel u, v, depth [, toward x, y, z]).
    passes, view = [], []
    for i, (sampler, use_mirror) in enumerate(ctx.samplers):
        passes.append((sampler, sampler.direct, 1.0))
        view.append(i)
        if use_mirror and opts.mirror_weight > 0:
            passes.append((sampler, sampler.mirror(ctx.world, *ctx.plane), opts.mirror_weight))
            view.append(i)
    view = np.array(view)
    colours = np.zeros((len(passes), n, 3), np.float32)
    weights = np.zeros((len(passes), n), np.float32)
    if n == 0:
        return TileSamples(raster, colours, weights, weights, view)
    columns = [ctx.normals.astype(np.float32)]
    for _, (uvz, toward), _ in passes:
        columns.append(uvz)
        if toward.ndim == 2:
            columns.append(toward)
    columns = np.hstack(columns)
    # A block of texels at a time: every step is per texel, so the result is the same, and
    # the temporaries (the interpolated columns, a pass's sampling) stay a block's size;
    # blocks write disjoint texels, so threads may take them in any order.
    def block(a):
        b = min(n, a + SAMPLE_BLOCK)
        values = raster.interp[a:b] @ columns
        nrm = values[:, :3]
        _by_row(nrm, np.maximum(np.sqrt(np.einsum("ij,ij->i", nrm, nrm)), 1e-30), np.divide)
        col = 3
        for k, (sampler, (_, toward), factor) in enumerate(passes):
            uvz = values[:, col:col + 3]
            col += 3
            if toward.ndim == 1:
                cos = nrm @ toward
            else:
                cos = np.einsum("ij,ij->i", nrm, values[:, col:col + 3])
                col += 3
            idx, w, rgb = sampler.sample(nrm, cos, uvz, factor)
            colours[k, a + idx] = rgb
            weights[k, a + idx] = w

    _map(block, range(0, n, SAMPLE_BLOCK), opts.threads)
    return TileSamples(raster, colours, weights, weights.copy(), view)


def _map(fn, items, threads):
    """``[fn(item) for item in items]`` on up to ``threads`` threads (0: the usable
    cores; numpy lets go of the interpreter in its array loops); the first error is
    raised."""
    items = list(items)
    threads = threads or usable_cores()
    if threads <= 1 or len(items) <= 1:
        return [fn(item) for item in items]
    with ThreadPoolExecutor(min(threads, len(items))) as pool:
        return [done.result() for done in [pool.submit(fn, item) for item in items]]


def _fade_seams(samples, rasters, ctx):
    """Fade each pass's weights over ``seam_feather`` from the edge of what it sees on the
    surface (``seams.seam_fade``), keeping every texel's total weight."""
    tris = np.concatenate([r.triangles for r in rasters])
    graph = edge_graph(ctx.world, tris)
    seen, cover = _on_vertices(rasters, {r.tile: (samples[r.tile].seen > 0).T.astype(np.float32)
                                         for r in rasters})  # (V, P): every pass at once
    width = ctx.opts.seam_feather * ctx.head_size
    fades = []
    for k in range(seen.shape[1]):
        unseen = (cover > 0) & (seen[:, k] < 0.5 * cover)
        fades.append(seam_fade(unseen, graph, width).astype(np.float32))
    fade = np.stack(fades, axis=1)  # (V, P)
    for r in rasters:
        s = samples[r.tile]
        if not len(r.texel):
            continue
        f = r.interp @ fade  # (N, P)
        np.maximum(f, np.float32(1e-3), out=f)
        w = np.multiply(s.seen, f.T, out=s.weights)  # in place: a tile's passes are large
        del f
        total, faded = s.seen.sum(axis=0), w.sum(axis=0)
        w *= np.where(faded > 0, total / np.maximum(faded, 1e-30), 0.0)[None]


def equalised_colours(samples, world, options=None, head_size=None, in_place=False):
    """Every pass's colours after the equalisation: the gains and offsets of
    :func:`fit_view_gains`, then each pass but the reference levelled to it
    (``levelling.level_field``, with ``BakeOptions.level``).

    Parameters
    ----------
    samples : dict of int -> TileSamples
        From :func:`bake_samples`.
    world : ndarray, shape (V, 3), metres
        The head the samples were taken on.
    options : BakeOptions, optional
    head_size : float, optional
        Metres the options' relative lengths refer to; default the rasters' vertices'
        bounding-box diagonal.
    in_place : bool
        Equalise the samples' own ``colours`` (returned) instead of copies: the bake's
        samples, whose colours it needs no more, without a second 60 MB at 1024 texels.

    Returns
    -------
    dict of int -> ndarray (P, N, 3) float32
    """
    opts = _options(options)
    gain, offset = fit_view_gains(samples, opts)
    out = {t: apply_gains(s.colours, gain, offset, in_place) for t, s in samples.items()}
    p = len(gain)
    if not (opts.equalise and opts.level and p > 1):
        return out
    world = np.asarray(world, dtype=np.float64)
    rasters = [s.raster for s in samples.values()]
    tris = np.concatenate([r.triangles for r in rasters])
    if head_size is None:
        used = np.unique(tris)
        head_size = float(np.linalg.norm(np.ptp(world[used], axis=0)))
    ref = view_reference(samples)
    n_vertices = len(world)
    cover = np.zeros(n_vertices)
    for r in rasters:
        cover[r.vertices] += r.cover
    operators = mesh_operators(world, tris)  # one surface for every pass

    def level(k):  # each pass writes its own colours only, so passes may go at once
        both = np.zeros(n_vertices)
        diff = np.zeros((n_vertices, 3))
        strength = np.zeros(n_vertices)
        for t, s in samples.items():
            r = s.raster
            om = np.minimum(s.seen[ref], s.seen[k])
            om *= om >= np.float32(LEVEL_WEIGHT)  # grazing samples (an outline) say little
            step = out[t][ref] - out[t][k]
            _by_row(step, om)  # in place: a tile's colours are large
            diff += r.gather @ step
            both += r.gather @ om
            strength += r.gather @ (om > 0).astype(np.float32)
        if not (both > 0).any():
            return
        _by_row(diff, np.maximum(both, 1e-30), np.divide)
        share = np.where(cover > 0, strength / np.maximum(cover, 1e-30), 0.0)
        field = level_field(diff, share, world, tris, opts.level_length * head_size,
                            decay=opts.level_decay * head_size, operators=operators)
        for t, s in samples.items():
            add = s.raster.interp @ field.astype(np.float32)
            _by_row(add, s.seen[k] > 0)
            out[t][k] += add

    _map(level, [k for k in range(p) if k != ref], opts.threads)
    return out


def _weighted(samples, colours):
    """A tile's passes' (equalised) ``colours`` (P, N, 3) summed by their weights: (the
    weighted sums (N, 3), the weights' sums (N,))."""
    w = samples.weights
    return np.einsum("pn,pnc->nc", w, colours), w.sum(axis=0)


def _blend(raster, acc, wsum, fill, opts):
    """The tile's texels' colours (N, 3) from their weighted sums ``acc`` (N, 3) and
    ``wsum`` (N,), the smooth ``fill`` (V, 3, vertex colours) where the photos see little."""
    if not len(raster.texel):
        return acc
    filled = raster.interp @ fill
    short = np.maximum(opts.fill_weight - wsum, 0.0)
    _by_row(filled, short)  # in place, as below: a tile's colours are large
    acc += filled
    _by_row(acc, wsum + short, np.divide)
    return np.clip(acc, 0.0, 1.0, out=acc)


def _remove_shading(blended, rasters, ctx):
    """Divide the low-frequency light out of the blended texels of every tile (in place),
    the light estimated on the surface across the tiles (``shading.shading_factor``)."""
    colour, cover = _on_vertices(rasters, blended)
    has = cover > 0
    colour[has] /= cover[has, None]
    tris = np.concatenate([r.triangles for r in rasters])
    factor = shading_factor(colour, ctx.world, tris, ctx.opts.shading_length * ctx.head_size)
    factor[~has] = 1.0
    for r in rasters:
        blended[r.tile] = remove_shading(blended[r.tile], r.interp @ factor).astype(np.float32)


def _smooth_fill(model, rasters, sums, fill_weight):
    """Colour (V, 3) at each vertex, filled harmonically over the mesh of every tile.

    Vertices whose surroundings the photos see well enough keep their seen (averaged)
    colour; the others solve the graph Laplace equation, so a hole gets the smoothest
    blend of its rim, consistently across UV seams and UV tiles (a hole in one tile takes
    the colours another tile sees at their shared vertices), and never leaves the rim's
    range. ``sums``: tile -> (weighted colour sums (N, 3), weight sums (N,)) of its texels.
    """
    on, cover = _on_vertices(rasters, {t: np.column_stack([acc, wsum])
                                       for t, (acc, wsum) in sums.items()})
    verts, lap = mesh_laplacian(model, rasters)
    colsum, seen, cover = on[verts, :3], on[verts, 3], cover[verts]
    known = (cover > 0) & (seen >= fill_weight * cover) & (seen > 0)
    value = np.zeros((len(verts), 3))
    if known.any():
        value[known] = colsum[known] / seen[known, None]
        mean = value[known].mean(axis=0)
    else:
        mean = np.full(3, 0.5)
    unknown = np.flatnonzero(~known)
    if len(unknown):
        k = np.flatnonzero(known)
        # A tiny screening term pulls parts that touch no seen vertex to the mean colour
        # and keeps the system regular; it is far too weak to bend the fill elsewhere.
        eps = 1e-6
        a = lap[unknown][:, unknown] + eps * sp.identity(len(unknown), format="csr")
        rhs = -(lap[unknown][:, k] @ value[k]) + eps * mean
        value[unknown] = spla.spsolve(a.tocsc(), rhs).reshape(len(unknown), 3)
    full = np.zeros((len(model.vertices), 3), np.float32)
    full[verts] = value
    return full


def _on_vertices(rasters, values):
    """Per-tile texel values (tile -> (N, C)) summed onto the mesh's vertices across every
    tile, (V, C) float64 (each tile's product in the texels' precision), and the vertices'
    cover summed likewise (V,): how a tile's texels reach the vertices it shares with
    another tile."""
    n = rasters[0].n_vertices
    total, cover = np.zeros((n, values[rasters[0].tile].shape[1])), np.zeros(n)
    for r in rasters:
        total += r.gather @ values[r.tile]
        cover[r.vertices] += r.cover
    return total, cover


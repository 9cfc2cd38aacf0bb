"""Blender (bpy) helpers shared by the sample renderer and the demo preview.

Everything here runs in background mode with Cycles on the CPU (Eevee needs a GPU
context). Meshes come in as plain arrays (the head model's polygon layout), cameras as
``solver.cameras.base.OrthographicCamera`` so the photos, the landmarks file and the fit agree
on one projection: pixel = scale * R[:2] @ X + offset, origin at the image's top-left
corner, pixel (i, j) covering [i, i+1] x [j, j+1].
"""

import tempfile
from pathlib import Path

import bpy
import numpy as np
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Matrix, Vector
from PIL import Image


def new_scene(size, samples, denoise=True):
    """Empty factory scene set up for Cycles CPU renders of ``size`` (w, h) pixels.

    ``read_factory_settings`` drops every datablock of earlier renders in this process,
    so one render never inherits another's objects, materials or settings.
    """
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return configure_cycles(bpy.context.scene, size, samples, denoise)


def configure_cycles(scene, size, samples, denoise=True):
    """Cycles on the CPU, ``samples`` per pixel (OpenImageDenoise unless ``denoise`` is
    False), a transparent film and 8-bit RGBA PNG output of ``size`` (w, h)."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = int(samples)
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = bool(denoise)
    if denoise:
        scene.cycles.denoiser = "OPENIMAGEDENOISE"
    # Few bounces: skin, eyes and a backdrop-free scene need no more, and it halves time.
    scene.cycles.max_bounces = 4
    scene.cycles.transparent_max_bounces = 8
    scene.cycles.caustics_reflective = False
    scene.cycles.caustics_refractive = False
    scene.render.resolution_x, scene.render.resolution_y = int(size[0]), int(size[1])
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.image_settings.color_depth = "8"
    scene.view_settings.view_transform = "Standard"
    return scene


def add_mesh(name, vertices, loop_vertex, face_loop_start, face_loop_total, loop_uv=None,
             face_material=None, materials=(), point_attributes=None):
    """Create a smooth-shaded polygon mesh object from arrays.

    Parameters
    ----------
    name : str
    vertices : ndarray, shape (V, 3), metres (object space)
    loop_vertex : ndarray, shape (L,)
        Vertex of each face corner.
    face_loop_start, face_loop_total : ndarray, shape (F,)
        First corner and corner count of each face.
    loop_uv : ndarray, shape (L, 2), optional
        Texture coordinates per corner (layer "UVMap").
    face_material : ndarray, shape (F,), optional
        Material slot of each face (index into ``materials``).
    materials : sequence of bpy.types.Material
    point_attributes : dict of str -> ndarray (V,) or (V, 4), optional
        Float (V,) or colour (V, 4) attributes per vertex, readable by Attribute nodes.

    Returns
    -------
    bpy.types.Object
    """
    v = np.asarray(vertices, dtype=np.float32)
    lv = np.asarray(loop_vertex, dtype=np.int32)
    fs = np.asarray(face_loop_start, dtype=np.int32)
    ft = np.asarray(face_loop_total, dtype=np.int32)
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(v))
    me.vertices.foreach_set("co", v.ravel())
    me.loops.add(len(lv))
    me.loops.foreach_set("vertex_index", lv)
    me.polygons.add(len(fs))
    me.polygons.foreach_set("loop_start", fs)
    me.polygons.foreach_set("loop_total", ft)
    me.polygons.foreach_set("use_smooth", np.ones(len(fs), dtype=bool))
    if loop_uv is not None:
        uv = me.uv_layers.new(name="UVMap")
        uv.data.foreach_set("uv", np.asarray(loop_uv, dtype=np.float32).ravel())
    for mat in materials:
        me.materials.append(mat)
    if face_material is not None:
        me.polygons.foreach_set("material_index", np.asarray(face_material, dtype=np.int32))
    for key, values in (point_attributes or {}).items():
        a = np.asarray(values, dtype=np.float32)
        if a.ndim == 1:
            attr = me.attributes.new(key, "FLOAT", "POINT")
            attr.data.foreach_set("value", a)
        else:
            attr = me.attributes.new(key, "FLOAT_COLOR", "POINT")
            attr.data.foreach_set("color", a.ravel())
    me.update(calc_edges=True)
    me.validate(clean_customdata=False)
    obj = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def set_pose(obj, scale, rotation, translation):
    """Object transform world = scale * rotation @ local + translation."""
    m = np.eye(4)
    m[:3, :3] = float(scale) * np.asarray(rotation, dtype=np.float64)
    m[:3, 3] = translation
    obj.matrix_world = Matrix(m.tolist())


def add_ortho_camera(camera, name="Camera", depth=2.0):
    """Blender orthographic camera that renders exactly what ``camera`` projects.

    Parameters
    ----------
    camera : solver.cameras.base.OrthographicCamera
        rotation rows (u, v, viewing direction), scale px/m, offset px, size (w, h).
    depth : float, metres
        Distance of the camera before the world origin along the viewing direction (the
        clip range spans twice that, so anything within ``depth`` of the origin is seen).

    Returns
    -------
    bpy.types.Object
    """
    w, h = camera.size
    r = camera.rotation
    cam = bpy.data.cameras.new(name)
    cam.type = "ORTHO"
    # ortho_scale spans the fitted sensor side: pin it to the longer image side.
    cam.sensor_fit = "VERTICAL" if h >= w else "HORIZONTAL"
    cam.ortho_scale = (h if h >= w else w) / camera.scale
    cam.clip_start = 0.01
    cam.clip_end = 2.0 * depth
    obj = bpy.data.objects.new(name, cam)
    # The image centre (w/2, h/2) sees the line through this point along the view direction.
    cu = (w / 2.0 - camera.offset[0]) / camera.scale
    cv = (h / 2.0 - camera.offset[1]) / camera.scale
    loc = r.T @ np.array([cu, cv, -depth])
    # Blender cameras look down their local -Z with +Y up in the image: columns u, -v, -d.
    basis = np.column_stack([r[0], -r[1], -r[2]])
    m = np.eye(4)
    m[:3, :3] = basis
    m[:3, 3] = loc
    obj.matrix_world = Matrix(m.tolist())
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_pinhole_camera(camera, name="Camera"):
    """Blender perspective camera that renders exactly what ``camera`` projects.

    Parameters
    ----------
    camera : solver.cameras.pinhole.PinholeCamera
        Without lens distortion (``k1`` 0: Blender renders none).

    Returns
    -------
    bpy.types.Object
    """
    from headrecon_addon.photo_cameras import set_lens

    params = camera.to_blender()
    cam = bpy.data.cameras.new(name)
    set_lens(cam, params)
    cam.clip_start = 0.01
    cam.clip_end = 20.0
    obj = bpy.data.objects.new(name, cam)
    obj.matrix_world = Matrix(params["matrix_world"])
    bpy.context.scene.collection.objects.link(obj)
    return obj


def blender_project(cam_obj, points, size):
    """Pixel positions of world points as Blender's camera sees them: (n, 3) -> (n, 2).

    Independent of ``solver.cameras.base`` (it goes through ``world_to_camera_view``), so
    comparing the two checks the camera conversion.
    """
    scene = bpy.context.scene
    bpy.context.view_layer.update()
    w, h = size
    ndc = np.array([tuple(world_to_camera_view(scene, cam_obj, Vector(p)))[:2]
                     for p in np.asarray(points, dtype=np.float64)])
    return np.column_stack([ndc[:, 0] * w, (1.0 - ndc[:, 1]) * h])


def add_light(kind, location, target, energy, size=1.0, color=(1.0, 1.0, 1.0), name=None):
    """An area or sun light at ``location`` aimed at ``target`` (world, metres)."""
    data = bpy.data.lights.new(name or kind, kind)
    data.energy = energy
    data.color = color
    if kind == "AREA":
        data.shape = "DISK"
        data.size = size
    elif kind == "SUN":
        data.angle = 0.3
    obj = bpy.data.objects.new(name or kind, data)
    obj.location = Vector(location)
    direction = Vector(target) - Vector(location)
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.collection.objects.link(obj)
    return obj


def studio_lighting(center, world_strength=0.2, light_scale=1.0,
                    world_color=(0.55, 0.56, 0.58)):
    """Soft portrait lighting around ``center``: a large key from the subject's front right
    (it lights both the front and the right-side photo), a fill from the front left, a
    rim from behind, and a world for ambient light.

    The sample photos use the defaults. A texture baked from photos already holds their
    light, so previews of it use a bright white world and dimmed lights
    (``PREVIEW_LIGHTING``): the texture then shows about as it was photographed.
    """
    c = np.asarray(center, dtype=np.float64)
    add_light("AREA", c + (-1.0, -1.4, 0.7), c, 75.0 * light_scale, size=1.2,
              color=(1.0, 0.96, 0.9), name="Key")
    add_light("AREA", c + (1.4, -1.0, 0.1), c, 30.0 * light_scale, size=1.5,
              color=(0.92, 0.96, 1.0), name="Fill")
    add_light("AREA", c + (0.3, 1.3, 1.0), c, 40.0 * light_scale, size=0.8, name="Rim")
    _world(world_color, world_strength)


def window_lighting(center):
    """A window at the subject's left, level with the head and a little in front of it, as
    the only light but a dim room: the front photo's far side and the whole right profile
    in shade, a band of light along the profile's forehead and nose."""
    c = np.asarray(center, dtype=np.float64)
    add_light("AREA", c + (1.6, -0.6, 0.4), c, 110.0, size=0.9, color=(1.0, 0.98, 0.95),
              name="Window")
    _world((0.55, 0.56, 0.58), 0.12)


#: The sample photos' lightings by name (``tools.make_sample --light``).
LIGHTINGS = {"studio": studio_lighting, "window": window_lighting}


def _world(color, strength):
    world = bpy.data.worlds.new("World")
    if world.node_tree is None:  # Blender 4.x: node trees are switched on by hand
        world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    bg.inputs["Color"].default_value = tuple(color) + (1.0,)
    bg.inputs["Strength"].default_value = strength
    bpy.context.scene.world = world


PREVIEW_LIGHTING = {"world_strength": 0.7, "light_scale": 0.25, "world_color": (1.0, 1.0, 1.0)}


def vertex_color_material(name, attribute):
    """A matte material coloured by a per-vertex colour attribute (e.g. an error map)."""
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # Blender 4.x
        mat.use_nodes = True
    nt = mat.node_tree
    bsdf = nt.nodes.get("Principled BSDF")
    node = nt.nodes.new("ShaderNodeAttribute")
    node.attribute_name = attribute
    nt.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = 0.7
    return mat


def render_alpha(cam_obj, holdout=()):
    """Coverage only, (h, w) float32: what ``render_rgba`` would give as alpha, with the
    objects in ``holdout`` cut out. Shading is replaced by one plain material and two
    samples without bounces, so it costs a fraction of a real render."""
    scene = bpy.context.scene
    layer = bpy.context.view_layer
    saved = (scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.max_bounces,
             layer.material_override)
    plain = bpy.data.materials.new("Alpha only")
    try:
        scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.max_bounces = 2, False, 0
        layer.material_override = plain
        for obj in holdout:
            obj.is_holdout = True
        return render_rgba(cam_obj)[..., 3]
    finally:
        for obj in holdout:
            obj.is_holdout = False
        (scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.max_bounces,
         layer.material_override) = saved
        bpy.data.materials.remove(plain)


def render_rgba(cam_obj):
    """Render the scene through ``cam_obj``: (h, w, 4) float32 in [0, 1], straight alpha,
    display-referred (view transform applied) like a saved photo."""
    scene = bpy.context.scene
    scene.camera = cam_obj
    with tempfile.TemporaryDirectory(prefix="headrecon_render_") as tmp:
        path = Path(tmp) / "render.png"
        scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
        with Image.open(path) as im:
            return np.asarray(im.convert("RGBA"), dtype=np.float32) / 255.0


def backdrop(size, seed=0, top=(0.80, 0.80, 0.78), bottom=(0.66, 0.67, 0.68)):
    """A plain photo-studio wall: vertical gradient, soft vignette and faint sensor noise,
    shape (h, w, 3) float32 in [0, 1]."""
    w, h = size
    t = np.linspace(0.0, 1.0, h, dtype=np.float32)[:, None, None]
    img = (1.0 - t) * np.asarray(top, np.float32) + t * np.asarray(bottom, np.float32)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((x - w / 2) / w) ** 2 + ((y - h / 2) / h) ** 2
    img = img * (1.0 - 0.25 * r2)[..., None]
    noise = np.random.default_rng(seed).normal(0.0, 0.006, (h, w, 1)).astype(np.float32)
    return np.clip(img + noise, 0.0, 1.0)


def composite(rgba, background):
    """Straight-alpha RGBA over an RGB background: (h, w, 3) float32."""
    a = rgba[..., 3:4]
    return rgba[..., :3] * a + background * (1.0 - a)


def save_png(path, rgb):
    """Write float RGB(A) in [0, 1] as an 8-bit PNG via a temporary file and a rename."""
    path = Path(path)
    arr = np.clip(np.round(np.asarray(rgb) * 255.0), 0, 255).astype(np.uint8)
    tmp = path.with_name(f".{path.name}.tmp")
    Image.fromarray(arr).save(tmp, format="PNG")
    tmp.replace(path)

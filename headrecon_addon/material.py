"""Materials of the head, the photo planes and the landmarks, and the uncertainty colour ramp.

The head's eyes and eyelashes are procedural (no image files): an eye with iris, pupil,
limbal ring and a wet coat, painted by the distance from the eye's axis (a per-vertex
attribute, :func:`eye_attribute`); eyelashes as dark strands cut out of ICT's lash strips
by an alpha texture computed from their UV layout (:func:`eyelash_alpha`). The sample
renderer (tools/make_sample.py) uses the same eye material, so the photos and the fitted
head have the same eyes.

Node trees are built by name so they work unchanged on Blender 4.2 and 5.x (the socket
names used here, "Base Color", "Roughness", "Alpha", "Color", "Strength", exist in both;
where 5.0 renamed a socket, e.g. "Fac" -> "Factor", :class:`NodeBuilder` uses the
identifier, which did not change).
"""

import bpy
import numpy as np

from .solver_link import solver_module

# Part groups of the ICT mesh: (material suffix, keywords in the ICT part name, colour RGBA).
# First match wins.
PART_GROUPS = (
    ("Eye Wetness", ("lacrimal", "blend", "occlusion"), (1.0, 1.0, 1.0, 0.0)),
    # ICT's eyelashes are flat strips made for an alpha-mapped texture: the lash shader
    # cuts strands out of them; the viewport colour stays clear (solid mode cannot show
    # the strands, and opaque strips read as grey slabs over the eyes).
    ("Eyelashes", ("eyelash",), (0.02, 0.015, 0.01, 0.0)),
    ("Eyes", ("eyeball",), (0.85, 0.85, 0.82, 1.0)),
    ("Teeth", ("teeth", "tooth"), (0.9, 0.87, 0.78, 1.0)),
    ("Mouth", ("mouth", "gum", "tongue"), (0.45, 0.12, 0.12, 1.0)),
    ("Sockets", ("socket",), (0.05, 0.02, 0.02, 1.0)),
    ("Face", ("face",), (0.8, 0.6, 0.5, 1.0)),
    ("Head", ("head", "neck"), (0.8, 0.6, 0.5, 1.0)),
)
# Material slot order on the head: the skin first.
SLOT_ORDER = ("Face", "Head", "Eyes", "Eye Wetness", "Eyelashes", "Mouth", "Teeth", "Sockets")
# The skin groups: what the photos texture (one UV tile each in the ICT layout).
SKIN_GROUPS = ("Face", "Head")
TEXTURE_NODE = "HeadRecon Texture"
GROUP_KEY = "headrecon_group"  # custom property naming a head material's part group
PHOTO_NODE = "HeadRecon Photo"

# The eyes' geometry (sclera and iris vertices, the iris's and pupil's radii) is the
# model's: ``solver.eyes``.
_EYES = solver_module("eyes")
SCLERA_RANGES, IRIS_RANGES = _EYES.SCLERA_RANGES, _EYES.IRIS_RANGES
IRIS_RADIUS, PUPIL_RADIUS = _EYES.IRIS_RADIUS, _EYES.PUPIL_RADIUS
_SHADING = solver_module("texture.shading")  # the sRGB curves
_RASTER = solver_module("texture.raster")
_FANS = solver_module("model.head_model")  # fan_triangles
# Per-vertex float the eye material reads: 1 on the eye's axis, falling linearly to 0 at
# EYE_RANGE_MM from it, on the front of the sclera; 0 everywhere else. Zero where it is
# missing, so a mesh without it shows plain sclera, not a black pupil.
EYE_ATTRIBUTE = "headrecon_eye"
EYE_RANGE_MM = 20.0

LANDMARK_COLOURS = {
    "PLACED": (0.1, 0.85, 0.2, 1.0),
    "FLAGGED": (1.0, 0.08, 0.05, 1.0),
    "PASSPOINT": (0.1, 0.45, 1.0, 1.0),  # passpoints: blue, red too when flagged
    "DETECTED": (1.0, 0.55, 0.0, 1.0),  # placed by the detector, not checked by hand yet
}


def part_group(part_name):
    """Material group (a PART_GROUPS suffix) of an ICT geometry part name."""
    low = part_name.lower()
    for group, words, _ in PART_GROUPS:
        if any(w in low for w in words):
            return group
    return "Face"


def ensure_nodes(mat):
    """Give ``mat`` its node tree (always there from Blender 5.0, where ``use_nodes`` is
    deprecated; 4.x needs it switched on)."""
    if bpy.app.version < (5, 0, 0) and not mat.use_nodes:
        mat.use_nodes = True
    return mat.node_tree


def _principled(mat):
    ensure_nodes(mat)
    nodes = mat.node_tree.nodes
    bsdf = next((n for n in nodes if n.type == "BSDF_PRINCIPLED"), None)
    if bsdf is None:
        nodes.clear()
        out = nodes.new("ShaderNodeOutputMaterial")
        bsdf = nodes.new("ShaderNodeBsdfPrincipled")
        mat.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return bsdf


def _set_transparent(mat):
    # 4.2+ (EEVEE Next): surface_render_method; blend_method is only kept for old files.
    if hasattr(mat, "surface_render_method"):
        mat.surface_render_method = "DITHERED"
    elif hasattr(mat, "blend_method"):
        mat.blend_method = "HASHED"


def new_part_material(group, name_prefix="HeadRecon"):
    """A new material for one part group of the head (not shared: each head owns its own,
    so a re-fit or a delete of one head never touches another's). Eyes and eyelashes get
    their procedural shaders; every other group a plain colour."""
    colour = next(c for g, _, c in PART_GROUPS if g == group)
    mat = bpy.data.materials.new(f"{name_prefix} {group}")
    mat[GROUP_KEY] = group
    bsdf = _principled(mat)
    # The plain colour stays as the sockets' own values under procedural links too: what
    # an exporter that cannot follow the nodes (glTF) falls back to.
    bsdf.inputs["Base Color"].default_value = colour[:3] + (1.0,)
    bsdf.inputs["Roughness"].default_value = 0.1 if group in ("Eyes", "Eye Wetness") else 0.55
    mat.diffuse_color = colour
    if colour[3] < 1.0:
        bsdf.inputs["Alpha"].default_value = colour[3]
        _set_transparent(mat)
    shader = {"Eyes": eye_shader, "Eyelashes": eyelash_shader}.get(group)
    if shader is not None:
        shader(mat)
    return mat


# --------------------------------------------------------------------------------------
# Procedural shaders


class NodeBuilder:
    """Builds a material's node chain feeding its Principled BSDF (``bsdf``).

    Methods take inputs as sockets (linked) or values (set: a float, or an RGB(A)
    tuple), and return the new node's output socket, so chains read as expressions::

        b = NodeBuilder(mat)
        r = b.math("DIVIDE", b.attribute("eye_radius"), 8.0)
        b.set(b.bsdf.inputs["Base Color"], b.ramp(r, [(0.5, (0, 0, 0)), (0.6, (1, 1, 1))]))
        b.arrange()
    """

    def __init__(self, mat):
        self.bsdf = _principled(mat)
        self.tree = mat.node_tree
        self.nodes, self.links = self.tree.nodes, self.tree.links

    def set(self, socket, value):
        """Link ``value`` into ``socket`` (a socket) or set it (a number, a vector, or a
        colour: RGB gets alpha 1)."""
        if isinstance(value, bpy.types.NodeSocket):
            self.links.new(value, socket)
        elif socket.type == "RGBA" and isinstance(value, tuple | list) and len(value) == 3:
            socket.default_value = tuple(value) + (1.0,)
        else:
            socket.default_value = value
        return socket

    def new(self, kind, **inputs):
        """A node of type ``kind`` with inputs set by name (``Scale=3.0``)."""
        node = self.nodes.new(kind)
        for name, value in inputs.items():
            self.set(node.inputs[name], value)
        return node

    @staticmethod
    def _socket(sockets, identifier):
        return next(s for s in sockets if s.identifier == identifier)

    def coordinates(self, kind="Object"):
        """Texture coordinates: "Object" (metres in the object's space), "UV", ..."""
        node = self.nodes.get("Texture Coordinate") or self.nodes.new("ShaderNodeTexCoord")
        return node.outputs[kind]

    def attribute(self, name):
        """A mesh attribute's value (0 where the mesh has none)."""
        node = self.nodes.new("ShaderNodeAttribute")
        node.attribute_name = name
        return self._socket(node.outputs, "Fac")

    def math(self, op, a, b=0.0):
        """``a op b`` by a Math node ("ADD", "MULTIPLY", "FRACT", "LESS_THAN", ...)."""
        node = self.nodes.new("ShaderNodeMath")
        node.operation = op
        self.set(node.inputs[0], a)
        self.set(node.inputs[1], b)
        return node.outputs["Value"]

    def mix(self, fac, a, b):
        """Colour ``a`` mixed toward ``b`` by ``fac``."""
        node = self.nodes.new("ShaderNodeMix")
        node.data_type = "RGBA"
        for ident, value in (("Factor_Float", fac), ("A_Color", a), ("B_Color", b)):
            self.set(self._socket(node.inputs, ident), value)
        return self._socket(node.outputs, "Result_Color")

    def noise(self, vector, scale, detail=2.0):
        """Perlin noise in [0, 1] (its factor output)."""
        node = self.new("ShaderNodeTexNoise", Vector=vector, Scale=scale, Detail=detail)
        return self._socket(node.outputs, "Fac")

    def ramp(self, fac, stops):
        """A colour ramp over ``fac``: ``stops`` = [(position, RGB), ...], at least two."""
        node = self.nodes.new("ShaderNodeValToRGB")
        elements = node.color_ramp.elements
        for i, (pos, col) in enumerate(stops):
            e = elements[i] if i < 2 else elements.new(pos)
            e.position, e.color = pos, tuple(col) + (1.0,)
        self.set(self._socket(node.inputs, "Fac"), fac)
        return node.outputs["Color"]

    def arrange(self, dx=300.0, dy=220.0):
        """Lay the nodes out in columns by their distance in links from the output, so the
        tree reads left to right in the shader editor."""
        depth = {n.name: 0 for n in self.nodes if n.type == "OUTPUT_MATERIAL"}
        pairs = [(link.from_node.name, link.to_node.name) for link in self.links]
        for _ in range(len(self.nodes)):  # longest path; the trees are small
            changed = False
            for src, dst in pairs:
                d = depth.get(dst)
                if d is not None and depth.get(src, -1) < d + 1:
                    depth[src] = d + 1
                    changed = True
            if not changed:
                break
        columns = {}
        for node in self.nodes:
            columns.setdefault(depth.get(node.name, max(depth.values()) + 1), []).append(node)
        for d, column in columns.items():
            for i, node in enumerate(column):
                node.location = (-dx * d, dy * ((len(column) - 1) / 2.0 - i))


def eye_attribute(vertices):
    """The per-vertex value the eye material reads (``EYE_ATTRIBUTE``).

    Parameters
    ----------
    vertices : ndarray, shape (V, 3), metres
        A head in the ICT vertex order, looking toward -Y (the model's mean shape: the
        value then follows the vertices through every identity).

    Returns
    -------
    ndarray, shape (V,), float32 in [0, 1]
        1 - r / EYE_RANGE_MM on the front half of each sclera, r being the distance from
        the eye's axis (the line through the iris sphere's centre along -Y); 0 elsewhere.
    """
    out = np.zeros(len(vertices), dtype=np.float32)
    for idx, r, front in _EYES.sclera_axis_distance(vertices):
        out[idx] = np.where(front, np.clip(1.0 - r * 1000.0 / EYE_RANGE_MM, 0, 1), 0)
    return out


IRIS_NODE = "HeadRecon Iris"
#: The iris's two colours (linear RGB) when no photo gave one: a blue-grey.
DEFAULT_IRIS = ((0.10, 0.16, 0.22), (0.22, 0.32, 0.36))
#: The iris's darker and lighter streaks around the colour read off the photos (linear).
IRIS_SPREAD = (0.7, 1.3)
# The eye shader's rings, in its units (8 mm from the eye's axis = 1): the pupil's and the
# iris's rims, the iris's light between them and its dark limbal ring (positions, values);
# the iris ends at ``_IRIS_EDGE``; the sclera's colours (linear) from the iris's rim out.
_PUPIL, _IRIS = PUPIL_RADIUS * 1000 / 8.0, IRIS_RADIUS * 1000 / 8.0
_RING = ((_PUPIL - 0.01, _PUPIL + 0.01, _IRIS - 0.08, _IRIS - 0.01, _IRIS + 0.01),
         (0.0, 1.0, 1.0, 0.35, 0.0))
_IRIS_EDGE = _IRIS + 0.005
SCLERA = ((_IRIS, (0.45, 0.42, 0.40)), (1.5, (0.62, 0.55, 0.52)))


def eye_shader(mat):
    """Make ``mat`` an eye: sclera, an iris with radial streaks and a dark limbal ring, a
    pupil, under a clear wet coat; drawn by the distance from the eye's axis
    (``EYE_ATTRIBUTE``, 8 mm = 1 below). The iris is ``DEFAULT_IRIS`` until
    :func:`set_iris_colour` gives it the person's."""
    b = NodeBuilder(mat)
    r = b.math("MULTIPLY", b.math("SUBTRACT", 1.0, b.attribute(EYE_ATTRIBUTE)),
               EYE_RANGE_MM / 8.0)
    iris = b.ramp(b.noise(b.coordinates("Object"), 900.0),
                  [(0.35, DEFAULT_IRIS[0]), (0.65, DEFAULT_IRIS[1])])
    iris.node.name = iris.node.label = IRIS_NODE
    ring = b.ramp(r, [(x, (y,) * 3) for x, y in zip(*_RING, strict=True)])
    sclera = b.ramp(r, list(SCLERA))
    inside = b.math("LESS_THAN", r, _IRIS_EDGE)
    b.set(b.bsdf.inputs["Base Color"], b.mix(inside, sclera, b.mix(ring, (0.005,) * 3, iris)))
    b.bsdf.inputs["Roughness"].default_value = 0.25
    b.bsdf.inputs["Coat Weight"].default_value = 1.0
    b.bsdf.inputs["Coat Roughness"].default_value = 0.03
    b.arrange()
    return mat


def set_iris_colour(mat, srgb):
    """Give an eye material (:func:`eye_shader`) the iris colour read off the photos:
    ``srgb`` (3,) in [0, 1] in the photos' encoding, made linear as the skin texture's
    colours are, its streaks ``IRIS_SPREAD`` darker and lighter. Returns False when
    ``mat`` has no iris (an eye material made elsewhere), leaving it as it is."""
    node = mat.node_tree.nodes.get(IRIS_NODE) if mat.node_tree is not None else None
    if node is None:
        return False
    linear = _SHADING.srgb_to_linear(srgb)
    for element, k in zip(node.color_ramp.elements, IRIS_SPREAD, strict=True):
        element.color = tuple(np.clip(linear * k, 0.0, 1.0)) + (1.0,)
    return True


#: Texels a side of each eye's image for exporters (:func:`eye_image`).
EYE_IMAGE_SIZE = 256


def iris_colours(mat):
    """The two colours (2, 3) linear of an eye material's iris ramp (``IRIS_NODE``: the
    colour read off the photos, or the default, or what the artist set); the default when
    ``mat`` has none."""
    node = mat.node_tree.nodes.get(IRIS_NODE) if mat.node_tree is not None else None
    if node is None:
        return np.array(DEFAULT_IRIS)
    return np.array([tuple(e.color)[:3] for e in node.color_ramp.elements[:2]])


def mesh_corners(mesh):
    """``mesh``'s polygons' first corners and corner counts (P,), and each corner's vertex
    (L,)."""
    starts, totals = np.empty(len(mesh.polygons), np.int64), np.empty(len(mesh.polygons),
                                                                      np.int64)
    mesh.polygons.foreach_get("loop_start", starts)
    mesh.polygons.foreach_get("loop_total", totals)
    loop_vertex = np.empty(len(mesh.loops), np.int64)
    mesh.loops.foreach_get("vertex_index", loop_vertex)
    return starts, totals, loop_vertex


def eye_image(mesh, slot, iris, size=EYE_IMAGE_SIZE):
    """The eyes as an image, for exporters that cannot follow the eye shader's nodes.

    The faces of material ``slot`` of ``mesh`` are painted from their ``EYE_ATTRIBUTE`` as
    the shader paints them (pupil, ``iris`` (2, 3) linear averaged, the limbal ring, the
    sclera), without its noise. The two eyeballs share one UV layout but not to the pixel
    (their axes lie 1.6 mm apart in it), so each eye (``SCLERA_RANGES`` / ``IRIS_RANGES``:
    the head keeps ICT's vertex order) is painted into its own half of the image, and its
    corners' UVs are squeezed into that half.

    Returns
    -------
    pixels : ndarray (size, 2 size, 4) float32
        sRGB-encoded RGBA, row 0 at the bottom (Blender's); texels no face covers are the
        sclera's.
    uv, squeezed : ndarray (L, 2) float32
        The mesh's corner UVs as they are, and with each eye's squeezed into its half.
    """
    starts, totals, loop_vertex = mesh_corners(mesh)
    mats = np.empty(len(mesh.polygons), np.int64)
    mesh.polygons.foreach_get("material_index", mats)
    uv = np.empty((len(mesh.loops), 2), np.float32)
    mesh.uv_layers.active.data.foreach_get("uv", uv.ravel())
    attr = np.zeros(len(mesh.vertices), np.float32)
    if EYE_ATTRIBUTE in mesh.attributes:
        mesh.attributes[EYE_ATTRIBUTE].data.foreach_get("value", attr)
    first = loop_vertex[starts]  # one corner is enough: an eyeball's faces are its own
    iris_rgb = np.asarray(iris, float).mean(axis=0)
    halves, squeezed = [], uv.copy()
    for k, ((s0, s1), (i0, i1)) in enumerate(zip(SCLERA_RANGES, IRIS_RANGES, strict=True)):
        faces = (mats == slot) & (((first >= s0) & (first <= s1))
                                  | ((first >= i0) & (first <= i1)))
        tri_loop, _ = _FANS.fan_triangles(starts[faces], totals[faces])
        halves.append(_painted_eye(np.mod(uv[tri_loop], 1.0) * size,
                                   attr[loop_vertex[tri_loop]], iris_rgb, size))
        count = totals[faces]
        loops = np.repeat(starts[faces] - np.cumsum(count) + count, count) \
            + np.arange(count.sum())
        squeezed[loops, 0] = 0.5 * (k + np.mod(squeezed[loops, 0], 1.0))
    return np.concatenate(halves, axis=1), uv, squeezed


def _painted_eye(tri_xy, tri_value, iris_rgb, size):
    """One eye's image (size, size, 4) from its triangles' corners (T, 3, 2) in texels and
    their ``EYE_ATTRIBUTE`` (T, 3): the eye shader's colours as :func:`eye_image` says."""
    pixel, tri, bary = _RASTER.rasterize(tri_xy, size, size)
    r = (1.0 - np.einsum("nk,nk->n", bary, tri_value[tri])) * EYE_RANGE_MM / 8.0
    ring = np.interp(r, *_RING)
    (a, ca), (b, cb) = SCLERA
    sclera = np.stack([np.interp(r, [a, b], [ca[i], cb[i]]) for i in range(3)], axis=1)
    eye = 0.005 + ring[:, None] * (iris_rgb - 0.005)
    colour = np.where((r < _IRIS_EDGE)[:, None], eye, sclera)
    out = np.empty((size * size, 4), np.float32)
    out[:, :3] = SCLERA[0][1]
    out[pixel, :3] = colour
    out[:, :3] = _SHADING.linear_to_srgb(out[:, :3])
    out[:, 3] = 1.0
    return out.reshape(size, size, 4)


# ICT's eyelash UVs (tile u in [6, 7]): per eye six strips stacked in v, each 1/6 high,
# three for the lower lid, then three for the upper; along a strip u runs along the lid
# (0.48 wide, left eye in [6.5, 7], right in [6, 6.5]) and v from the lash tips (strip
# bottom, 0.084 of the strip) to the roots on the lid (0.924).
LASH_STRIP_TIP, LASH_STRIP_ROOT = 0.084, 0.924
LASH_STRANDS = 45  # strands per strip (x 3 strips: ~135 lashes per lid)
LASH_HALF_WIDTH = 0.14  # at the root, in strand spacings (the tip is a third as thick)
LASH_COLOUR = (0.02, 0.015, 0.01)  # linear RGB
LASH_IMAGE = "HeadRecon Eyelashes"
LASH_TEXTURE_SIZE = 1024
LASH_KEY = "headrecon_lashes"  # custom property on the generated lash image


def _smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def eyelash_alpha(size=LASH_TEXTURE_SIZE):
    """Coverage of ICT's lash strips by lashes, as a texture over one UV tile.

    Thin strands run from the lid (root) to the tip across each strip, each its own
    length, thinning and fading toward the tip and toward the lid's corners; the three
    strips of a lid interleave; the lower lid's lashes are fewer, shorter and lighter.

    Parameters
    ----------
    size : int
        Texels per side.

    Returns
    -------
    ndarray, shape (size, size), float32 in [0, 1]
        Row 0 at the top (v = 1), like an image file; 0 between the strands.
    """
    t = (np.arange(size, dtype=np.float64) + 0.5) / size
    u, v = t[None, :], 1.0 - t[:, None]
    along = np.broadcast_to(np.mod(2.0 * u, 1.0), (size, size))  # 0..1 along the lid
    strip = np.floor(6.0 * v)  # 0-2 lower lid, 3-5 upper
    root = np.clip((np.mod(6.0 * v, 1.0) - LASH_STRIP_TIP)
                   / (LASH_STRIP_ROOT - LASH_STRIP_TIP), 0.0, 1.0)  # 0 tip .. 1 lid
    tipward = 1.0 - root
    # strand coordinate: the three strips' strands interleave; each strand leans a little
    x = along * LASH_STRANDS + 0.37 * strip + 0.3 * tipward
    ids = (np.floor(x) + 101 * strip).astype(np.int64)
    rand = np.random.default_rng(7).random(int(ids.max()) + 1)[ids]
    x = x + (rand - 0.5) * tipward**2  # tips curl apart
    off_centre = np.abs(np.mod(x, 1.0) - 0.5)
    half = LASH_HALF_WIDTH / 3.0 * (1.0 + 2.0 * root)
    strand = 1.0 - _smoothstep(0.5 * half, half, off_centre)
    upper = (strip > 2.5).astype(np.float64)
    strand *= rand > 0.45 * (1.0 - upper)
    # each strand ends somewhere between 55 % and 100 % of the strip (upper lid)
    cut = 1.0 - (0.55 + 0.45 * rand) * (0.7 + 0.3 * upper)
    alpha = strand * _smoothstep(cut, cut + 0.08, root)
    alpha *= 0.35 + 0.65 * _smoothstep(0.0, 0.7, root)
    alpha *= _smoothstep(0.02, 0.14, along) * _smoothstep(0.98, 0.86, along)
    return (alpha * (0.55 + 0.45 * upper)).astype(np.float32)


_LASH_ALPHA = {}  # texture size -> eyelash_alpha(size)


def cached_eyelash_alpha(size=LASH_TEXTURE_SIZE):
    """``eyelash_alpha(size)``, computed once per session (the UI's warm-up thread pays it
    before the first fit)."""
    if size not in _LASH_ALPHA:
        _LASH_ALPHA[size] = eyelash_alpha(size)
    return _LASH_ALPHA[size]


def eyelash_image():
    """The lash texture (``eyelash_alpha`` in alpha, the lash colour in RGB), made once
    per file and shared by every head; packed, so a saved file carries it."""
    img = bpy.data.images.get(LASH_IMAGE)
    if img is not None and img.library is None and img.get(LASH_KEY) \
            and tuple(img.size) == (LASH_TEXTURE_SIZE,) * 2:
        return img
    n = LASH_TEXTURE_SIZE
    rgba = np.empty((n, n, 4), dtype=np.float32)
    rgba[..., :3] = _SHADING.linear_to_srgb(LASH_COLOUR)
    rgba[..., 3] = cached_eyelash_alpha(n)
    img = bpy.data.images.new(LASH_IMAGE, n, n, alpha=True)
    img.pixels.foreach_set(rgba[::-1].ravel())  # Blender's rows run bottom-up
    img[LASH_KEY] = True
    img.pack()
    return img


def eyelash_shader(mat):
    """Make ``mat`` eyelashes: dark strands cut out of ICT's lash strips by the lash
    texture's alpha (an image, so exporters such as glTF carry it too)."""
    b = NodeBuilder(mat)
    tex = b.new("ShaderNodeTexImage")
    tex.image = eyelash_image()
    tex.extension = "REPEAT"  # the lash UVs lie in tile u in [6, 7]
    b.set(b.bsdf.inputs["Base Color"], tex.outputs["Color"])
    b.set(b.bsdf.inputs["Alpha"], tex.outputs["Alpha"])
    b.bsdf.inputs["Roughness"].default_value = 0.45
    _set_transparent(mat)
    b.arrange()
    return mat


def set_skin_texture(mat, image):
    """Use ``image`` as the skin's base colour (adds or reuses the texture node)."""
    bsdf = _principled(mat)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.get(TEXTURE_NODE)
    if tex is None:
        tex = nodes.new("ShaderNodeTexImage")
        tex.name = tex.label = TEXTURE_NODE
        tex.location = (bsdf.location.x - 320, bsdf.location.y)
    tex.image = image
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    mat.diffuse_color = (1.0, 1.0, 1.0, 1.0)
    return tex


def _node_image(mat, node_name):
    """The image of ``mat``'s image node ``node_name``, or None."""
    if mat is None or mat.node_tree is None:
        return None
    tex = mat.node_tree.nodes.get(node_name)
    return tex.image if tex is not None else None


def skin_texture(mat):
    """The image of the skin's texture node, or None."""
    return _node_image(mat, TEXTURE_NODE)


def _emission_material(name, colour):
    """A new material that only emits (unlit: reads the same under any light and in every
    viewport mode). Returns the material and its Emission node."""
    mat = bpy.data.materials.new(name)
    ensure_nodes(mat)
    nodes = mat.node_tree.nodes
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    out.location = (300, 0)
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = colour
    emit.inputs["Strength"].default_value = 1.0
    mat.node_tree.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    mat.diffuse_color = colour
    return mat, emit


def photo_material(image, name):
    """Unlit material showing ``image`` as it is: emission of strength 1, no lighting, so the
    photo's colours stay true and nothing shades or shadows it."""
    mat, emit = _emission_material(name, (1.0, 1.0, 1.0, 1.0))
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new("ShaderNodeTexImage")
    tex.name = tex.label = PHOTO_NODE
    tex.location = (-300, 0)
    tex.image = image
    tex.extension = "CLIP"
    links.new(tex.outputs["Color"], emit.inputs["Color"])
    mat.use_backface_culling = False
    return mat


def photo_image(mat):
    """The photo shown by a photo material, or None."""
    return _node_image(mat, PHOTO_NODE)


def set_photo_image(mat, image):
    mat.node_tree.nodes[PHOTO_NODE].image = image


def landmark_material(state):
    """The shared material of landmarks in ``state`` ("PLACED", "FLAGGED", "PASSPOINT" or
    "DETECTED"), unlit so the state colour reads the same in every viewport mode."""
    name = f"HeadRecon Landmark {state.title()}"
    mat = bpy.data.materials.get(name)
    if mat is not None and mat.library is None:
        return mat
    return _emission_material(name, LANDMARK_COLOURS[state])[0]


# Uncertainty colour ramp: blue (well determined) - cyan - green - yellow - red (uncertain).
_RAMP_POS = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
_RAMP_RGB = np.array([[0.05, 0.1, 0.9], [0.0, 0.8, 0.9], [0.1, 0.85, 0.1],
                      [1.0, 0.85, 0.0], [0.95, 0.05, 0.05]])


def uncertainty_colors(mm, vmax_mm=None):
    """Map per-vertex uncertainty to colours.

    Parameters
    ----------
    mm : ndarray, shape (V,), millimetres
    vmax_mm : float, optional
        The value shown red (default: the 99th percentile, at least 1 mm).

    Returns
    -------
    rgba : ndarray, shape (V, 4), float32 in [0, 1]
    vmax_mm : float
    """
    mm = np.nan_to_num(np.asarray(mm, dtype=np.float64), nan=0.0, posinf=0.0)
    if vmax_mm is None:
        vmax_mm = max(1.0, float(np.percentile(mm, 99))) if mm.size else 1.0
    t = np.clip(mm / vmax_mm, 0.0, 1.0)
    rgba = np.ones((mm.size, 4), dtype=np.float32)
    for c in range(3):
        rgba[:, c] = np.interp(t, _RAMP_POS, _RAMP_RGB[:, c])
    return rgba, float(vmax_mm)

"""Add-on data stored in the .blend: ``Scene.headrecon`` (fit options, result summary,
residual list) and ``Object.headrecon`` (what an object is to HeadRecon: the head, a photo
plane, a landmark, a contour).

The source of truth for landmark positions is the landmark object's location in its photo
plane's local space (see photos.py for the pixel mapping): moving, grabbing, undoing or
parenting a landmark needs nothing else kept in sync.
"""

import dataclasses

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    IntProperty,
    IntVectorProperty,
    PointerProperty,
    StringProperty,
)

from .solver_link import FitOptions


def _fit_default(name):
    """FitOptions' own default for a field, so the panel starts where the solver does."""
    for f in dataclasses.fields(FitOptions):
        if f.name == name:
            if f.default is not dataclasses.MISSING:
                return f.default
            return f.default_factory()
    raise KeyError(f"FitOptions has no field {name!r}")


CAMERA_VIEWS = (
    ("orthographic-front", "Front", "Photo taken from the front"),
    ("orthographic-right", "Right Profile",
     "Profile photo of the subject's right side (the face looks to the image's right)"),
    ("orthographic-left", "Left Profile",
     "Profile photo of the subject's left side (the face looks to the image's left)"),
)

ROLES = (
    ("NONE", "None", "Not made by HeadRecon"),
    ("HEAD", "Head", "The fitted head"),
    ("PHOTO", "Photo", "A photo plane"),
    ("LANDMARK", "Landmark", "A landmark on a photo plane"),
    ("PASSPOINT", "Passpoint",
     "Where a point of a calibration object (known 3-D position) is seen on a photo plane"),
    ("CONTOUR", "Contour", "The traced profile outline of a photo plane"),
    ("CAMERA", "Camera", "The camera of a perspective photo (its plane is its child)"),
)


def _on_camera_view(self, context):
    # A photo's nominal view changed (e.g. right -> left profile): stand it there.
    from . import photos

    if self.role == "PHOTO":
        photos.on_camera_view(self.id_data, context.scene)


NO_MIRROR = "NONE"
_mirror_items_cache = []  # Blender needs a dynamic enum's strings kept alive in Python


def _mirror_items(self, context):
    from . import photos

    scene = getattr(context, "scene", None) or bpy.context.scene
    current = photos.mirror_of(self.id_data) if self.role == "PHOTO" else None
    names = sorted({p.headrecon.view for p in photos.photo_planes(scene)} - {self.view})
    if current and current not in names:  # (its view is gone: shown, flagged on export)
        names.append(current)
    items = [(NO_MIRROR, "None", "Not a mirror image: the photo is seen directly", 0)]
    items += [(n, n, f"The mirror image of the subject inside the photo of view {n!r}", i + 1)
              for i, n in enumerate(names)]
    _mirror_items_cache[:] = items
    return items


def _get_mirror(self):
    from . import photos

    current = photos.mirror_of(self.id_data) if self.role == "PHOTO" else None
    for ident, _, _, value in _mirror_items(self, bpy.context):
        if ident == current:
            return value
    return 0


def _set_mirror(self, value):
    from . import photos

    for ident, _, _, v in _mirror_items(self, bpy.context):
        if v == value and self.role == "PHOTO":
            photos.set_mirror_of(self.id_data, None if ident == NO_MIRROR else ident)
            return


def _get_lens(self):
    from . import photos

    if self.role != "PHOTO" or photos.camera_kind(self.id_data) != "pinhole":
        return 0.0
    return float(photos.lens_hint(self.id_data) or 0.0)


def _set_lens(self, value):
    from . import photos

    if self.role == "PHOTO":
        photos.set_lens_hint(self.id_data, value)


class HEADRECON_PG_object(bpy.types.PropertyGroup):
    role: EnumProperty(name="Role", items=ROLES, default="NONE",
                       description="What the object is to HeadRecon (how the add-on finds "
                                   "it, whichever collection it is in)")
    view: StringProperty(name="View", description="Name of the photo's view, e.g. 'front'")
    landmark: StringProperty(name="Landmark", description="Landmark name")
    camera_view: EnumProperty(name="Camera", items=CAMERA_VIEWS, default="orthographic-front",
                              update=_on_camera_view,
                              description="Which side of the head the photo shows (for a "
                                          "perspective photo: roughly, the fit finds its "
                                          "camera)")
    camera_json: StringProperty(
        name="Camera Parameters",
        description="The view's camera as JSON when it is not the nominal one (from an "
                    "imported file); empty for the nominal orthographic camera")
    view_json: StringProperty(
        name="View Data",
        description="What the landmarks file said about this view that the add-on does not "
                    "edit (calibration flags, mirror, passpoints, camera hints, x- keys), as "
                    "JSON, written back on export")
    mirror_of: EnumProperty(
        name="Mirror Of", items=_mirror_items, get=_get_mirror, set=_set_mirror,
        description="This view is the subject's mirror image inside another view's photo "
                    "(same photo; landmarks named as the subject's true side). Stored in "
                    "the view's data (mirror_of), checked on export and fit")
    image_size: IntVectorProperty(name="Image Size", size=2, min=0,
                                  description="Width and height of the photo in pixels "
                                              "(upright, as the landmarks are placed)")
    pixel_aspect: FloatVectorProperty(
        name="Pixel Aspect", size=2, default=(1.0, 1.0), min=1e-6,
        description="Camera of a perspective photo: its pixel aspect (a render setting in "
                    "Blender, set when looking through it)")
    flip_x: BoolProperty(
        name="Flipped", description="Camera of a perspective photo seen in a mirror: "
                                    "the camera shown sees the photo flipped left-right")
    plane_height: FloatProperty(name="Plane Height", unit="LENGTH", default=0.375, min=1e-6,
                                description="Height of the photo plane (its local units)")
    image: PointerProperty(name="Image", type=bpy.types.Image,
                           description="The photo shown on the plane")
    lens_mm: FloatProperty(
        name="Focal Length", min=0.0, soft_max=300.0, unit="CAMERA", get=_get_lens,
        set=_set_lens,
        description="Perspective photo: the focal length the fit starts its camera from, in "
                    "mm, full-frame (36 mm across the long side) equivalent (0: unknown); "
                    "from the photo's EXIF when it has one, yours to change")
    lens_from_exif: BoolProperty(
        name="Focal Length from EXIF",
        description="The focal length was read from the photo's EXIF data")
    detected: BoolProperty(
        name="Detected",
        description="Placed by Detect Landmarks (or read from a file with its uncertainty), "
                    "shown in its own colour: detecting again may replace it; moved by hand "
                    "it becomes hand-placed")
    uncertainty_px: FloatProperty(
        name="Uncertainty", subtype="PIXEL", default=0.0, min=0.0,
        description="A detected landmark: how far off it may be (standard deviation in "
                    "pixels), which the fit weighs it by; 0: none (placed by hand)")
    depth_px: FloatProperty(
        name="Depth", subtype="PIXEL", default=0.0,
        description="A detected landmark: how far the detector saw it toward the camera "
                    "(pixels, relative to the face), which tells the fit how the head is "
                    "turned; only where Has Depth")
    has_depth: BoolProperty(name="Has Depth", options={"HIDDEN"},
                            description="The detector gave this landmark a depth")
    detected_at: FloatVectorProperty(
        name="Detected At", size=2, options={"HIDDEN"},
        description="Where the detector put the landmark (plane space): moved from there, "
                    "it is hand-placed")
    flagged: BoolProperty(name="Flagged", description="The last fit flagged this landmark")
    residual_px: FloatProperty(name="Residual", subtype="PIXEL", default=-1.0,
                               description="The last fit's distance from this landmark to "
                                           "the head's point in the photo (-1: not fitted)")
    uncertainty_max_mm: FloatProperty(name="Uncertainty Scale", default=0.0,
                                      description="Uncertainty shown red (mm)")
    fit_method: StringProperty(name="Method",
                               description="The approach that made the last fit of the head")
    fit_rms_px: FloatProperty(name="RMS Residual", subtype="PIXEL", default=-1.0,
                              description="Root mean square landmark residual of the last fit "
                                          "(-1: not fitted)")


RESIDUAL_KINDS = (
    ("LANDMARK", "Landmark", "Distance between the landmark and the fitted head's point"),
    ("PASSPOINT", "Passpoint",
     "Reprojection residual of a passpoint in its photo's calibration (seed 000 §5-6)"),
)


class HEADRECON_PG_residual(bpy.types.PropertyGroup):
    view: StringProperty(name="View", description="The photo's view name")
    landmark: StringProperty(name="Name", description="Landmark or passpoint name")
    kind: EnumProperty(name="Kind", items=RESIDUAL_KINDS, default="LANDMARK",
                       description="A landmark of the fit or a passpoint of a calibration")
    pixels: FloatProperty(name="Residual", subtype="PIXEL",
                          description="Distance in the photo in pixels")
    flagged: BoolProperty(name="Flagged",
                          description="Far off the others: probably misplaced")
    message: StringProperty(name="Message", description="Why it is flagged")


def _on_residual_index(self, context):
    from .landmarks import select_landmark

    if 0 <= self.residual_index < len(self.residuals):
        item = self.residuals[self.residual_index]
        select_landmark(context, item.view, item.landmark, item.kind)


def _on_live_refit(self, context):
    from .live_refit import LIVE

    LIVE.reset()


METHODS = (
    ("combined", "Combined", "Both thesis approaches, keeping the better fit"),
    ("approach1", "Landmark ICP", "Thesis approach 1: shape-ICP on landmarks and profile"),
    ("approach2", "TPS-ICP", "Thesis approach 2: thin-plate-spline ICP"),
)
PRIORS = (
    ("eigen", "Eigenvalues", "Shape prior scaled by each component's variance (eq. 42)"),
    ("identity", "Identity", "Equal prior on every coefficient"),
)
TEXTURE_SIZES = (("256", "256", "Preview"), ("512", "512", "Quick to bake"),
                 ("1024", "1024", "The default: the photos' detail for a head of about "
                                  "1000 pixels"),
                 ("2048", "2048", "Slow to bake"))


class HEADRECON_PG_scene(bpy.types.PropertyGroup):
    head: PointerProperty(name="Head", type=bpy.types.Object,
                          poll=lambda self, obj: obj.type == "MESH",
                          description="The head Fit updates (made by Add Reference Head or "
                                      "the first fit)")
    method: EnumProperty(name="Method", items=METHODS, default=_fit_default("method"),
                         description="How the head is fitted to the landmarks")
    n_identity: IntProperty(name="Components", min=1, max=100,
                            default=_fit_default("n_identity"),
                            description="Global identity components the fit uses")
    n_regional: IntProperty(name="Regional Components", min=0, max=10,
                            default=_fit_default("n_regional"),
                            description="Components per region of the regional model "
                                        "(0: global model only)")
    lambda1: FloatProperty(name="λ1 Smoothness", min=0.0, soft_max=100.0,
                           default=_fit_default("lambda1"),
                           description="Weight of Γ: regions agree where they overlap")
    lambda2: FloatProperty(name="λ2 Shape Prior", min=0.0, soft_max=100.0,
                           default=_fit_default("lambda2"),
                           description="Weight of Λ: keep the coefficients plausible")
    prior: EnumProperty(name="Prior", items=PRIORS, default=_fit_default("prior"),
                        description="How the shape prior weighs each component")
    landmark_weight: FloatProperty(name="Landmark Weight", min=0.0, soft_max=100.0,
                                   default=_fit_default("landmark_weight"),
                                   description="Weight of the landmarks against the profile")
    exact_landmarks: BoolProperty(name="Exact Landmarks", default=_fit_default("exact_landmarks"),
                                  description="Add a detail shape so the landmarks hit exactly")
    texture_size: EnumProperty(name="Texture", items=TEXTURE_SIZES, default="1024",
                               description="Size of the baked texture (pixels per side of "
                                           "each tile); larger bakes take longer")
    bake_texture: BoolProperty(name="Bake Texture", default=True,
                               description="Bake the photos into the head's texture")
    texture_shading: EnumProperty(
        name="Shading", default="keep",
        items=(("keep", "Keep", "Keep the photos' light and shadows in the texture"),
               ("remove", "Remove", "Divide out the photos' soft light (a smoothed "
                                    "brightness) for a flat, albedo-like texture to light "
                                    "in Blender; fine shadows stay")),
        description="What the baked texture keeps of the light in the photos")
    texture_clothes: EnumProperty(
        name="Clothes", default="leave-out",
        items=(("leave-out", "Leave Out", "Leave out what the photos show of clothes below "
                                          "the chin (a collar, a shirt): the neck there gets "
                                          "the smooth fill from the skin around it"),
               ("keep", "Keep", "Bake the photos as they are, clothes on the neck too")),
        description="What the baked texture takes of the clothes in the photos")
    replace_hand_placed: BoolProperty(
        name="Replace Hand-Placed", default=False,
        description="Detect Landmarks and Auto Fit replace the landmarks placed or moved by "
                    "hand too (off: they stay, and Auto Fit detects only on photos without "
                    "them)")
    live_refit: BoolProperty(name="Live Refit", default=False, update=_on_live_refit,
                             description="Refit while a landmark is moved, so the head "
                                         "follows (run Fit once first)")
    residuals: CollectionProperty(type=HEADRECON_PG_residual, name="Residuals",
                                  description="Every landmark's residual of the last fit, "
                                              "flagged ones first")
    residual_index: IntProperty(name="Residual", default=-1, update=_on_residual_index,
                                description="The residual chosen in the list (its landmark "
                                            "is selected)")
    status: StringProperty(name="Status", description="What the last fit did")
    case_json: StringProperty(
        name="Case Data",
        description="Top-level keys of the imported landmarks file besides the views "
                    "(passpoints, x- keys), as JSON, written back on export")


# The Fit panel's Advanced settings, in the order shown (Reset to Defaults resets these).
ADVANCED_FIT_SETTINGS = ("n_identity", "n_regional", "lambda1", "lambda2", "prior",
                         "landmark_weight", "exact_landmarks")

CLASSES = (HEADRECON_PG_object, HEADRECON_PG_residual, HEADRECON_PG_scene)


def register_properties():
    bpy.types.Object.headrecon = PointerProperty(type=HEADRECON_PG_object)
    bpy.types.Scene.headrecon = PointerProperty(type=HEADRECON_PG_scene)


def unregister_properties():
    del bpy.types.Scene.headrecon
    del bpy.types.Object.headrecon

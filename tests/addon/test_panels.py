"""The sidebar panels draw in every state of the flow (empty scene, photos with landmarks,
fitted head) with real properties, operators and icons. Background Blender draws no UI,
so each panel's draw() runs against a layout double that checks every name it is given
against Blender's RNA."""

import types

import bpy

from tests.addon.support import addon, empty_scene

ICONS = set(bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items.keys())


class _OpProps:
    def __init__(self, idname):
        cat, name = idname.split(".")
        self.__dict__["_rna"] = getattr(getattr(bpy.ops, cat), name).get_rna_type()

    def __setattr__(self, key, value):
        assert key in self._rna.properties, f"{self._rna.identifier} has no property {key!r}"


class Layout:
    """Records what a panel draws; asserts names exist."""

    def __init__(self, log):
        self.__dict__["log"] = log

    def __setattr__(self, key, value):  # use_property_split, enabled, ...
        assert hasattr(bpy.types.UILayout, key) or key in bpy.types.UILayout.bl_rna.properties

    def _icon(self, kw):
        icon = kw.get("icon", "NONE")
        assert icon in ICONS, f"unknown icon {icon!r}"

    def row(self, **kw):
        return Layout(self.log)

    column = box = split = row

    def label(self, text="", **kw):
        self._icon(kw)
        self.log.append(("label", text))

    def prop(self, data, name, **kw):
        self._icon(kw)
        assert name in data.bl_rna.properties, f"{data!r} has no property {name!r}"
        self.log.append(("prop", name))

    def operator(self, idname, **kw):
        self._icon(kw)
        cat, name = idname.split(".")
        assert hasattr(bpy.types, f"{cat.upper()}_OT_{name}"), f"no operator {idname}"
        self.log.append(("operator", idname))
        self.log.append(("button", kw.get("text", "")))
        return _OpProps(idname)

    def template_list(self, listtype, list_id, data, propname, active_data, active_propname,
                      **kw):
        assert hasattr(bpy.types, listtype)
        assert propname in data.bl_rna.properties
        assert active_propname in active_data.bl_rna.properties
        self.log.append(("list", propname))


def _draw_all():
    import headrecon_addon

    log = []
    for cls in headrecon_addon.panels.CLASSES:
        if issubclass(cls, bpy.types.Panel):
            cls.draw(types.SimpleNamespace(layout=Layout(log)), bpy.context)
    return log


FILES_SEED = 21  # the head of the ``files`` fixture (tests/addon/conftest.py)


def test_panels_draw_through_the_flow(files):
    path, case, _ = files
    empty_scene()
    log = _draw_all()
    assert ("operator", "headrecon.add_head") in log
    assert ("operator", "headrecon.load_photo") in log
    assert ("label", "Load the photos first") in log

    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    log = _draw_all()
    assert ("operator", "headrecon.place_landmarks") in log
    assert ("operator", "headrecon.draw_contour") in log
    # detection: per photo, on all photos, and Auto Fit, with the replace option
    assert log.count(("operator", "headrecon.detect_landmarks")) == len(case.views) + 1
    assert log.count(("operator", "headrecon.detect_outline")) == len(case.views) + 1
    assert ("operator", "headrecon.auto_fit") in log and ("prop", "replace_hand_placed") in log
    assert any(k == "label" and t.startswith("front: ") and "placed" in t for k, t in log)
    assert ("prop", "n_identity") in log and ("prop", "lambda2") in log

    scene = bpy.context.scene
    scene.headrecon.bake_texture = False
    scene.headrecon.n_identity = 10
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    scene.headrecon.live_refit = True
    log = _draw_all()
    assert ("list", "residuals") in log
    assert any(k == "label" and t.startswith("RMS residual: ") for k, t in log)
    for op in ("apply_identity", "import_arkit_animation", "export_head"):
        assert ("operator", f"headrecon.{op}") in log
    fit_again = ("label", "Fit again to take the moved points in")
    assert fit_again not in log
    # a point moved and refitted live: the panel asks for a Fit to take it in fully
    from headrecon_addon import landmarks, photos

    plane = photos.find_plane(scene, next(iter(case.views)))
    next(iter(landmarks.landmark_objects(plane).values())).location.x += 0.002
    scene.headrecon.live_refit = False  # a Quick Refit by hand asks the same
    assert bpy.ops.headrecon.refit_landmarks() == {"FINISHED"}
    assert fit_again in _draw_all()


def test_panels_draw_perspective_photos(model, tmp_path):
    # any number of photos, each with its camera's description; passpoints can be placed;
    # the residual list and the result panel show the passpoint check
    import numpy as np

    from solver import synthetic
    from tests.addon.support import add_passpoints, save_case

    addon()
    case, truth = synthetic.make_perspective_case(model, 0, n_views=3, head_px=(300.0, 320.0))
    add_passpoints(case, truth, "photo0", np.random.default_rng(1), misplace=(3, 12.0))
    path, _ = save_case(case, tmp_path, "persp", photos=False)
    empty_scene()
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    log = _draw_all()
    labels = [t for k, t in log if k == "label"]
    assert sum(t.startswith(("photo0: ", "photo1: ", "photo2: ")) and "(no photo)" not in t
               for t in labels) == 3
    assert "DLT, to compute, calibrated" in labels
    assert sum(t.startswith("Pinhole ") and t.endswith("mm, to compute") for t in labels) == 2
    n = len(case.passpoints)
    # every perspective photo can take the calibration object's passpoints
    assert [t for k, t in log if k == "button" and t.startswith("Passpoints")] == \
        [f"Passpoints ({n} / {n})", f"Passpoints (0 / {n})", f"Passpoints (0 / {n})"]
    assert ("button", "Add Photo (Any Camera)...") in log
    assert log.count(("operator", "headrecon.view_photo")) == 3
    scene = bpy.context.scene
    scene.headrecon.bake_texture = False
    scene.headrecon.n_identity = 10
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    scene.headrecon.residual_index = 0
    log = _draw_all()
    labels = [t for k, t in log if k == "label"]
    assert "Suspect passpoints: 1" in labels
    assert any("misplaced or mislabelled" in t for t in labels)


def _draw(cls):
    log = []
    cls.draw(types.SimpleNamespace(layout=Layout(log)), bpy.context)
    return log


def test_fit_panel_shows_the_defaults_up_front_and_the_rest_under_advanced():
    from headrecon_addon import panels
    from headrecon_addon.properties import ADVANCED_FIT_SETTINGS

    empty_scene()
    shown = [n for k, n in _draw(panels.HEADRECON_PT_fit) if k == "prop"]
    main = set(shown)
    advanced = _draw(panels.HEADRECON_PT_fit_advanced)
    assert {"method", "bake_texture", "texture_size", "live_refit"} <= main
    # the bake's options together: the clothes beside the shading
    assert shown.index("texture_clothes") == shown.index("texture_shading") + 1
    assert not main & set(ADVANCED_FIT_SETTINGS)
    assert [n for k, n in advanced if k == "prop"] == list(ADVANCED_FIT_SETTINGS)
    assert ("operator", "headrecon.reset_fit_settings") in advanced
    assert panels.HEADRECON_PT_fit_advanced.bl_parent_id == "HEADRECON_PT_fit"

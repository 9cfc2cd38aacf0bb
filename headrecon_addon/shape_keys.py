"""The fit's result as shape keys on the head.

Basis is the model's mean; one key per identity component ("identity_000"...) and per
regional component ("<region>_NN") whose value is the fitted coefficient (sliders -3..3,
wider if a coefficient lies outside); "fit_detail" (value 1) carries what the model cannot
express (FitResult.detail); the expression keys (Apple's ARKit names, then the model's
extras: ``arkit.key_plan``) start at 0, and a re-fit keeps the values (and slider ranges,
mutes, vertex groups) the artist gave them, and the artist's own keys with their shapes. With the
values set, the evaluated mesh is exactly FitResult.local_vertices (float32), the terms of
``local = mean + identity + regional + detail``.

Keys are written through ``ShapeKey.points`` (a raw-array view of ``ShapeKey.data``'s
"co": the same memory, but foreach_set there is a memcpy instead of a per-point loop; 4.2
has it too) and the names written are remembered on the Key datablock, so a re-fit
removes exactly those and nothing an artist added.
"""

import numpy as np

from . import arkit

FIT_KEYS = "headrecon_fit_keys"  # ID property on the Key: names of the keys a fit wrote
DETAIL = "fit_detail"
LIVE_MUTED = "headrecon_live_muted"  # ID property on the Key: keys muted while dragging
# ID property on the Key: identity keys Apply Identity kept (muted) after moving them into
# the Basis (apply_identity.py); a re-fit removes them with the other fit keys.
KEPT_APPLIED = "headrecon_identity_applied"
SLIDER = 3.0
SLIDER_LIMIT = 10.0  # Blender's own bound on slider_min / slider_max


def _key_points(kb):
    return kb.points if hasattr(kb, "points") else kb.data


def set_key_co(kb, co):
    """Write key positions (V, 3) in one call."""
    _key_points(kb).foreach_set("co", np.ascontiguousarray(co, dtype=np.float32).ravel())


def get_key_co(kb):
    n = len(kb.data)
    out = np.empty(n * 3, dtype=np.float32)
    _key_points(kb).foreach_get("co", out)
    return out.reshape(n, 3)


def fit_key_names(obj):
    """Names of the keys the last fit wrote on ``obj`` (empty if none)."""
    key = obj.data.shape_keys
    if key is None or FIT_KEYS not in key:
        return []
    return [str(n) for n in key[FIT_KEYS]]


def remove_fit_keys(obj):
    """Remove the keys a previous fit wrote (keys the artist added stay)."""
    key = obj.data.shape_keys
    if key is None:
        return
    names = set(fit_key_names(obj))
    for kb in [kb for kb in key.key_blocks if kb.name in names]:
        obj.shape_key_remove(kb)
    key = obj.data.shape_keys
    for prop in (FIT_KEYS, KEPT_APPLIED):
        if key is not None and prop in key:
            del key[prop]


def _slider(kb, value):
    lo = max(-SLIDER_LIMIT, min(-SLIDER, float(np.floor(value))))
    hi = min(SLIDER_LIMIT, max(SLIDER, float(np.ceil(value))))
    kb.slider_min, kb.slider_max = lo, hi
    kb.value = float(value)


def _set_value(kb, value):
    """A coefficient key's value; the slider range widens only when it must."""
    if kb.slider_min <= value <= kb.slider_max:
        kb.value = float(value)
    else:
        _slider(kb, value)


def regional_model_of(model, result):
    """The regional LinearModel a result's regional coefficients belong to, or None."""
    names = tuple(result.regional_names)
    if not names:
        return None
    n_per = len(names) // max(1, len(model.region_names))
    reg = model.regional(n_per)
    if tuple(reg.names) != names:
        raise ValueError(f"fit result: regional names {names[:3]}... do not match the model's "
                         f"regional model with {n_per} components per region")
    return reg


def write_fit_keys(obj, model, result):
    """Write the result's shape keys on ``obj`` (replacing the previous fit's).

    Parameters
    ----------
    obj : bpy.types.Object
        A head made from ``model`` (same vertex count and order).
    model : HeadModel
    result : FitResult

    Returns
    -------
    list of str
        Names of the keys written, in order (Basis excluded).
    """
    n = model.n_vertices
    if len(obj.data.vertices) != n:
        raise ValueError(f"object {obj.name!r}: has {len(obj.data.vertices)} vertices, the "
                         f"head model {n}; use a head made by HeadRecon")
    mean = model.vertices
    kept = _ArtistKeys(obj, model)
    remove_fit_keys(obj)
    if obj.data.shape_keys is not None and LIVE_MUTED in obj.data.shape_keys:
        del obj.data.shape_keys[LIVE_MUTED]
    if obj.data.shape_keys is None:
        basis = obj.shape_key_add(name="Basis", from_mix=False)
    else:
        basis = obj.data.shape_keys.reference_key
    set_key_co(basis, mean)
    obj.data.vertices.foreach_set("co", mean.astype(np.float32).ravel())

    names = []

    def add(name, co, value, slider=True, lo=0.0, hi=1.0):
        kb = obj.shape_key_add(name=name, from_mix=False)
        if kb.name != name:  # an artist's key already has this name
            raise ValueError(f"object {obj.name!r}: a shape key named {name!r} exists and was "
                             "not made by HeadRecon; rename it and fit again")
        set_key_co(kb, co)
        if slider:
            _slider(kb, value)
        else:
            kb.slider_min, kb.slider_max = lo, hi
            kb.value = float(value)
        names.append(name)
        return kb

    try:
        k = len(result.identity_coeffs)
        # a key's positions at a time: all of them at once were a 64 MB temporary
        for name, c, mode in zip(model.identity.names[:k], result.identity_coeffs,
                                 model.identity.basis[:k], strict=True):
            add(name, mean + mode, c)
        reg = regional_model_of(model, result)
        if reg is not None:
            for name, c, delta in zip(reg.names, result.regional_coeffs, reg.basis, strict=True):
                add(name, mean + delta, c)
        add(DETAIL, mean + np.asarray(result.detail, dtype=np.float64), 1.0, slider=False)
        for name, delta in arkit.expression_keys(model.expression_names, model.expressions):
            add(name, mean + delta, 0.0, slider=False)
    finally:
        obj.data.shape_keys[FIT_KEYS] = names
        kept.restore(obj, mean)
    obj.data.update()
    return names


# What an expression key keeps across fits: the artist's settings, not its shape.
_EXPRESSION_SETTINGS = ("value", "slider_min", "slider_max", "mute", "vertex_group",
                        "interpolation")


class _ArtistKeys:
    """What a re-fit must not lose, read before the previous fit's keys are removed: the
    expression keys' settings (the values the artist posed, slider ranges, mutes, vertex
    groups) and the artist's own keys' offsets from the Basis and their relative keys.

    The artist's keys are stored as positions; a re-fit that changes the Basis (after
    Apply Identity) moves them with it, so each keeps its offset, the shape it adds."""

    def __init__(self, obj, model):
        key = obj.data.shape_keys
        self.expressions, self.own, self.basis = {}, {}, None
        if key is None:
            return
        fit = set(fit_key_names(obj))
        expressions = set(arkit.expression_key_names(model.expression_names))
        ref = key.reference_key
        for kb in key.key_blocks:
            if kb.name in fit and kb.name in expressions:
                self.expressions[kb.name] = {a: getattr(kb, a) for a in _EXPRESSION_SETTINGS}
            elif kb.name not in fit and kb != ref:
                self.own[kb.name] = kb.relative_key.name
        if self.own:
            self.basis = get_key_co(ref)

    def restore(self, obj, mean):
        """Put the settings back on the keys of the new fit (``mean``: its Basis)."""
        blocks = obj.data.shape_keys.key_blocks
        for name, settings in self.expressions.items():
            kb = blocks.get(name)
            if kb is None:
                continue
            kb.slider_min = min(settings["slider_min"], kb.slider_min)
            kb.slider_max = max(settings["slider_max"], kb.slider_max)
            for attr, value in settings.items():
                setattr(kb, attr, value)
        shift = None
        if self.basis is not None:
            shift = np.asarray(mean, dtype=np.float32) - self.basis
            if not np.any(shift):
                shift = None
        for name, relative in self.own.items():
            kb = blocks.get(name)
            if kb is None:
                continue
            if shift is not None:
                set_key_co(kb, get_key_co(kb) + shift)
            if relative in blocks:
                kb.relative_key = blocks[relative]


def update_fit_values(obj, model, result):
    """Live refit: set the coefficient values and the detail key only (no keys added).

    Returns False when the head's keys do not match the result (a full fit is needed).
    """
    settle_live_shape(obj)
    keys = _coefficient_keys(obj, model, result)
    if keys is None:
        return False
    kbs, pairs, detail = keys
    for kb, (_, c) in zip(kbs, pairs, strict=True):
        _set_value(kb, c)
    set_key_co(detail, model.vertices + np.asarray(result.detail, dtype=np.float64))
    detail.value = 1.0
    obj.data.update()
    return True


def _coefficient_keys(obj, model, result):
    """The keys a live refit writes: (coefficient key blocks, their (name, value) pairs,
    the detail key), or None when the head's keys do not match the result."""
    key = obj.data.shape_keys
    if key is None or KEPT_APPLIED in key:  # identity applied: its keys are history
        return None
    k = len(result.identity_coeffs)
    pairs = list(zip(model.identity.names[:k], result.identity_coeffs, strict=True))
    pairs += list(zip(result.regional_names, result.regional_coeffs, strict=True))
    kbs = [key.key_blocks.get(name) for name, _ in pairs]
    detail = key.key_blocks.get(DETAIL)
    if detail is None or any(kb is None for kb in kbs):
        return None
    return kbs, pairs, detail


def show_live_shape(obj, model, result):
    """Drag mode of the live refit: the whole refitted shape goes into the detail key and
    the coefficient keys are muted (their values still follow, so the sliders show them).

    Blender re-evaluates every active shape key whenever one changes, so a drag keeps one
    key active instead of about a hundred. ``settle_live_shape`` turns this back into the
    normal form (coefficients + detail) once the drag ends.

    Returns False when the head's keys do not match the result (a full fit is needed).
    """
    keys = _coefficient_keys(obj, model, result)
    if keys is None:
        return False
    kbs, pairs, detail = keys
    key = obj.data.shape_keys
    muted = set(str(n) for n in key.get(LIVE_MUTED, ()))
    for kb, (name, c) in zip(kbs, pairs, strict=True):
        _set_value(kb, c)
        if not kb.mute:
            kb.mute = True
            muted.add(name)
    key[LIVE_MUTED] = sorted(muted)
    set_key_co(detail, result.local_vertices)
    detail.value = 1.0
    obj.data.update()
    return True


def in_live_shape(obj):
    key = obj.data.shape_keys
    return key is not None and LIVE_MUTED in key


def settle_live_shape(obj):
    """Leave drag mode: detail = (live shape) minus the coefficient keys' part, and the
    keys muted for the drag unmuted. Works from the keys alone (also after a reload)."""
    key = obj.data.shape_keys
    if key is None or LIVE_MUTED not in key:
        return False
    blocks = key.key_blocks
    names = [str(n) for n in key[LIVE_MUTED] if str(n) in blocks]
    basis = get_key_co(key.reference_key).astype(np.float64)
    detail_kb = blocks.get(DETAIL)
    if detail_kb is not None:
        co = get_key_co(detail_kb).astype(np.float64)
        for name in names:
            kb = blocks[name]
            if kb.value != 0.0:
                co -= kb.value * (get_key_co(kb).astype(np.float64) - basis)
        set_key_co(detail_kb, co)
    for name in names:
        blocks[name].mute = False
    del key[LIVE_MUTED]
    obj.data.update()
    return True


def evaluated_vertices(obj, depsgraph):
    """Vertex positions of the evaluated mesh (shape keys applied), local space, (V, 3)."""
    ev = obj.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    try:
        out = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", out)
    finally:
        ev.to_mesh_clear()
    return out.reshape(-1, 3).astype(np.float64)

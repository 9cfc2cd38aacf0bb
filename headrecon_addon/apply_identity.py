"""Apply Identity: the fitted shape becomes the head's base mesh.

After a fit the Basis key is the model's mean head and the person lives in the identity,
regional and ``fit_detail`` key values, which a game engine or any tool that ignores
default key weights does not show. Applying them moves the person into the Basis (and the
mesh itself); the expression keys, and any key of the artist's, are shifted by the same
offset, so each still gives the same deformation on top of the new base. The identity keys
are then removed, or kept muted (their offsets unchanged, for reference: unmuting them
would add the identity a second time).
"""

import numpy as np

from . import arkit, shape_keys


def identity_key_names(obj, model_expression_names):
    """Keys of the last fit that carry the identity (identity, regional, ``fit_detail``):
    the fit's keys minus its expression keys, those present and not kept muted already."""
    key = obj.data.shape_keys
    if key is None:
        return []
    expressions = set(arkit.expression_key_names(model_expression_names))
    muted = {str(n) for n in key.get(shape_keys.KEPT_APPLIED, ())}
    return [n for n in shape_keys.fit_key_names(obj)
            if n not in expressions and n not in muted and n in key.key_blocks]


def identity_problem(obj, model_expression_names):
    """Why Apply Identity cannot run on ``obj`` (a sentence), or None."""
    if obj is None or obj.type != "MESH":
        return "Fit a head first"
    if not identity_key_names(obj, model_expression_names):
        return f"{obj.name} has no identity keys to apply (fit it first, or it is applied)"
    return None


def apply_identity(obj, model_expression_names, keep_muted=False):
    """Make the shape of ``obj``'s identity keys (at their values) its base mesh.

    Parameters
    ----------
    obj : bpy.types.Object
        A fitted head.
    model_expression_names : sequence of str
        ``HeadModel.expression_names`` (tells the expression keys from the identity keys).
    keep_muted : bool
        Keep the identity keys, muted, instead of removing them.

    Returns
    -------
    list of str
        The identity keys applied.

    Raises
    ------
    ValueError
        When there is nothing to apply; ``obj`` is then unchanged, as it is when writing
        the keys fails.
    """
    problem = identity_problem(obj, model_expression_names)
    if problem:
        raise ValueError(problem)
    shape_keys.settle_live_shape(obj)  # the same shape in the normal form of the keys
    key = obj.data.shape_keys
    blocks = key.key_blocks
    basis = key.reference_key
    names = identity_key_names(obj, model_expression_names)
    applied = set(names)
    old = shape_keys.get_key_co(basis).astype(np.float64)
    new = old.copy()
    for name in names:
        kb = blocks[name]
        if not kb.mute and kb.value != 0.0:
            rel = shape_keys.get_key_co(kb.relative_key).astype(np.float64)
            new += kb.value * (shape_keys.get_key_co(kb).astype(np.float64) - rel)
    shift = new - old
    moved = [kb for kb in blocks if kb != basis and (keep_muted or kb.name not in applied)]
    saved = {kb.name: shape_keys.get_key_co(kb) for kb in [basis, *moved]}
    saved_mesh = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", saved_mesh)
    try:
        for kb in moved:
            shape_keys.set_key_co(kb, saved[kb.name] + shift)
        shape_keys.set_key_co(basis, new)
        obj.data.vertices.foreach_set("co", new.astype(np.float32).ravel())
    except Exception:
        for kb in [basis, *moved]:
            shape_keys.set_key_co(kb, saved[kb.name])
        obj.data.vertices.foreach_set("co", saved_mesh)
        raise
    if keep_muted:
        for name in names:
            blocks[name].mute = True
        done = {str(n) for n in key.get(shape_keys.KEPT_APPLIED, ())}
        key[shape_keys.KEPT_APPLIED] = sorted(done | applied)
    else:
        for name in names:
            obj.shape_key_remove(blocks[name])
        key = obj.data.shape_keys
        key[shape_keys.FIT_KEYS] = [n for n in shape_keys.fit_key_names(obj)
                                    if n not in applied]
    obj.data.update()
    return names

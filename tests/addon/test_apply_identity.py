"""Apply Identity: the fitted face becomes the base mesh and the expression keys still give
the same expressions; a failure leaves the head as it was (bpy module, background)."""

import bpy
import numpy as np
import pytest

from tests.addon.support import empty_scene, key_blocks, synthetic_files

EXPRESSION_VALUES = {"jawOpen": 1.0, "eyeBlinkLeft": 0.7, "browInnerUp": 0.5}


@pytest.fixture(scope="module")
def fit(model, tmp_path_factory):
    from solver import FitOptions, fit_head

    _, case, _ = synthetic_files(model, tmp_path_factory.mktemp("apply"), seed=6,
                                 photos=False)
    return case, fit_head(model, case, FitOptions(n_identity=20, n_regional=2))


@pytest.fixture
def head(model, fit):
    """A freshly fitted head (identity, regional and detail keys at their values)."""
    from headrecon_addon import head_scene

    empty_scene()
    case, result = fit
    head = head_scene.build_scene_from_fit(model, case, result, bake=False)
    bpy.context.scene.headrecon.head = head
    return head


def _evaluated(head, values=None):
    from headrecon_addon import shape_keys

    keys = key_blocks(head)
    for name, v in (values or {}).items():
        keys[name].value = v
    out = shape_keys.evaluated_vertices(head, bpy.context.evaluated_depsgraph_get())
    for name in values or {}:
        keys[name].value = 0.0
    return out


def _state(head):
    from headrecon_addon import shape_keys

    return {kb.name: (shape_keys.get_key_co(kb).copy(), kb.value, kb.mute)
            for kb in key_blocks(head)}


def test_the_fitted_face_becomes_the_base_and_expressions_still_work(model, fit, head):
    from headrecon_addon import apply_identity, arkit, shape_keys

    _, result = fit
    neutral = _evaluated(head)
    smiling = _evaluated(head, EXPRESSION_VALUES)
    assert np.abs(neutral - result.local_vertices).max() < 1e-5
    applied = apply_identity.apply_identity(head, model.expression_names)
    assert "identity_000" in applied and "fit_detail" in applied and len(applied) == 1 + 20 + 14
    names = [kb.name for kb in key_blocks(head)]
    assert names == ["Basis"] + arkit.expression_key_names(model.expression_names)
    assert shape_keys.fit_key_names(head) == names[1:]
    assert all(kb.value == 0.0 for kb in key_blocks(head)[1:])
    # the base mesh and the Basis are the fitted face, with every key at 0
    basis = shape_keys.get_key_co(head.data.shape_keys.reference_key)
    mesh = np.empty(len(head.data.vertices) * 3, np.float32)
    head.data.vertices.foreach_get("co", mesh)
    assert np.abs(basis - result.local_vertices).max() < 1e-5
    assert np.abs(mesh.reshape(-1, 3) - basis).max() == 0
    assert np.abs(_evaluated(head) - neutral).max() < 1e-6
    # the same vertex positions with the expression keys dialled in, before and after
    assert np.abs(_evaluated(head, EXPRESSION_VALUES) - smiling).max() < 1e-6
    assert np.abs(smiling - neutral).max() > 5e-3
    with pytest.raises(ValueError, match="no identity keys"):
        apply_identity.apply_identity(head, model.expression_names)


def test_identity_keys_can_stay_muted(model, fit, head):
    from headrecon_addon import apply_identity, shape_keys

    values = {kb.name: kb.value for kb in key_blocks(head)}
    smiling = _evaluated(head, EXPRESSION_VALUES)
    applied = apply_identity.apply_identity(head, model.expression_names, keep_muted=True)
    keys = key_blocks(head)
    assert all(keys[n].mute and keys[n].value == values[n] for n in applied)
    assert np.abs(_evaluated(head, EXPRESSION_VALUES) - smiling).max() < 1e-6
    assert apply_identity.identity_problem(head, model.expression_names) is not None
    _, result = fit
    assert not shape_keys.update_fit_values(head, model, result)  # live refit: fit again
    # a re-fit writes the keys afresh: the kept keys are the fit's and go with the others
    shape_keys.write_fit_keys(head, model, result)
    assert not keys["identity_000"].mute
    assert apply_identity.identity_problem(head, model.expression_names) is None
    assert shape_keys.KEPT_APPLIED not in head.data.shape_keys


def test_an_artists_key_keeps_its_shape(model, head):
    from headrecon_addon import apply_identity, shape_keys

    own = head.shape_key_add(name="my_wrinkle", from_mix=False)
    co = shape_keys.get_key_co(own)
    co[100] += (0.0, 0.0, 0.01)
    shape_keys.set_key_co(own, co)
    before = _evaluated(head, {"my_wrinkle": 1.0})
    apply_identity.apply_identity(head, model.expression_names)
    assert "my_wrinkle" in key_blocks(head)
    assert np.abs(_evaluated(head, {"my_wrinkle": 1.0}) - before).max() < 1e-6


def test_a_failure_leaves_the_head_as_it_was(model, head, monkeypatch):
    from headrecon_addon import apply_identity, shape_keys

    before = _state(head)
    real, calls = shape_keys.set_key_co, []

    def fail_later(kb, co):
        calls.append(kb.name)
        if len(calls) == 30:
            raise RuntimeError("disk full")
        real(kb, co)

    monkeypatch.setattr(shape_keys, "set_key_co", fail_later)
    with pytest.raises(RuntimeError, match="disk full"):
        apply_identity.apply_identity(head, model.expression_names)
    monkeypatch.setattr(shape_keys, "set_key_co", real)
    after = _state(head)
    assert list(after) == list(before)
    for name, (co, value, mute) in before.items():
        assert np.array_equal(after[name][0], co) and after[name][1:] == (value, mute), name


def test_the_operator(model, head):
    assert bpy.ops.headrecon.apply_identity.poll()
    assert bpy.ops.headrecon.apply_identity(keep_muted=False) == {"FINISHED"}
    assert "identity_000" not in key_blocks(head)
    assert not bpy.ops.headrecon.apply_identity.poll()  # nothing left to apply
    with pytest.raises(RuntimeError, match="no identity keys to apply"):
        bpy.ops.headrecon.apply_identity()

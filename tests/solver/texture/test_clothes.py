"""Clothes in a photo (solver/texture/clothes.py): on the rendered sample the shirt is
clothes and the skin is not; only what is not skin, lies below the chin and reaches the
photo's bottom edge counts (skin in a window's light, brighter than the skin's colour
allows, is skin where a cheek shows it) (on a black-and-white photo, all below the chin's line); a
photo that misses the cheeks tells nothing; and the bake
from a fit leaves the clothes out, so the neck under the shirt is not painted blue."""

import numpy as np
import pytest
from PIL import Image

from solver import OrthographicCamera, fit_head, load_landmarks
from solver.texture.bake import BakeOptions, bake_fit_texture
from solver.texture.clothes import BELOW_CHIN_M, RISES_TO, clothes_mask

SKIN = (0.80, 0.56, 0.46)


@pytest.fixture(scope="module")
def sample_fit(model, sample):
    folder, truth = sample
    case = load_landmarks(folder / "sample.json", known_names=model)
    photos = {name: np.asarray(Image.open(folder / view.image).convert("RGB"),
                               np.float32) / 255.0 for name, view in case.views.items()}
    return fit_head(model, case), photos, truth


def test_the_sample_shirt_is_clothes_and_its_skin_is_not(model, sample_fit):
    result, photos, truth = sample_fit
    for name, key in (("front", "front"), ("side", "side")):
        mask = clothes_mask(model, result.world_vertices, result.cameras[name], photos[name])
        head = truth[f"head_alpha_{key}"] > 127
        person = truth[f"alpha_{key}"] > 127
        shirt = person & ~head
        columns = np.zeros_like(head)
        cols = np.flatnonzero(head.any(axis=0))
        columns[:, cols.min():cols.max() + 1] = True  # where the head (and its neck) is
        assert mask[shirt & columns].mean() > 0.99
        img = photos[name]
        warm = person & (img[..., 0] - img[..., 2] > 0.1)  # clearly skin, not the shirt
        assert mask[warm].mean() < 0.015  # the collar's edge, grown by two pixels


def _photo_of_the_mean_head(model, w=300, h=400):
    """(image, camera, chin row, the row clothes may begin at) of the mean head in front
    of a plain skin-coloured photo."""
    cam = OrthographicCamera.nominal("orthographic-front", (w, h))
    chin = cam.project(model.vertices[[model.landmark_vertex("chin_bottom")]])[0, 1]
    top = chin + BELOW_CHIN_M * cam.scale
    return np.tile(np.float32(SKIN), (h, w, 1)), cam, int(chin), int(np.ceil(top))


def test_only_what_reaches_the_bottom_below_the_chin_is_clothes(model):
    img, cam, chin, top = _photo_of_the_mean_head(model)
    img[top + 40:, :] = (0.30, 0.35, 0.45)          # a shirt up from the bottom edge
    img[top + 40:, 200:230] = (1.0, 1.0, 1.0)       # with a white (clipped) stripe
    img[top + 10:top + 20, 140:160] = (0.30, 0.35, 0.45)  # a patch of it, on its own
    img[chin - 30:chin - 20, 140:160] = (0.10, 0.08, 0.06)  # a beard above the chin
    mask = clothes_mask(model, model.vertices, cam, img)
    assert mask[top + 45:, 20:280].all()              # the shirt and its white stripe
    assert not mask[top + 10:top + 20, 140:160].any()  # not connected to the bottom
    assert not mask[:top + 37].any()                   # nothing above the shirt
    # a reduced photo: the same clothes at its own pixels
    half = img[::2, ::2]
    small = clothes_mask(model, model.vertices, cam, half, scale=(0.5, 0.5))
    assert small[(top + 45) // 2 + 1:, 20:140].all() and not small[:(top + 37) // 2].any()


def test_a_light_collar_rising_up_the_neck_is_clothes_a_shade_is_not(model):
    img, cam, chin, top = _photo_of_the_mean_head(model)
    lobes = cam.project(model.vertices[[model.landmark_vertex(n) for n in RISES_TO]])[:, 1]
    lobe = int(np.ceil(lobes.max()))
    img[top + 40:, :] = (0.30, 0.35, 0.45)              # a shirt up from the bottom edge
    img[lobe + 5:, 60:80] = (0.95, 0.97, 0.96)          # its white collar up the neck's side
    img[lobe - 30:, 220:240] = (0.90, 0.92, 0.95)       # another, past the ear lobes
    img[chin - 10:, 120:135] = (0.25, 0.18, 0.15)       # the jaw's shade, down to the shirt
    mask = clothes_mask(model, model.vertices, cam, img)
    assert mask[lobe + 5:, 62:78].all()                 # the collar, from the bottom up
    assert mask[lobe + 2:, 222:238].all() and not mask[:lobe - 2, 220:240].any()
    assert not mask[:top - 2, 122:133].any()            # the shade above the chin's line stays
    assert not mask[:top + 37, 90:110].any()            # and the skin


def test_a_neck_lit_by_a_window_is_skin_and_the_shirt_still_clothes(model):
    img, cam, chin, top = _photo_of_the_mean_head(model)
    edge = 195  # the light's edge through the subject's left cheek: most of that cheek lit,
    # most of both cheeks in shade (the skin's colour comes from the shade)
    img[:] = np.float32(SKIN) * 0.35
    img[:, edge:] = np.minimum(np.float32(SKIN) * 1.6, 1.0)  # 4.6 x brighter, clipped red
    img[top + 40:, :] = (0.30, 0.35, 0.45)              # a grey-blue shirt
    img[top + 40:, 240:260] = (0.95, 0.95, 0.95)        # with a white stripe in the light
    mask = clothes_mask(model, model.vertices, cam, img)
    assert not mask[:top + 37].any()                    # the lit neck, down to the shirt
    assert mask[top + 45:, 20:280].all()                # the shirt and its stripe
    # where no cheek shows the light, nothing tells it is skin: the lit neck is left out
    img[:top + 40, edge:] = np.float32(SKIN) * 0.35
    img[top:top + 40, edge + 20:] = np.minimum(np.float32(SKIN) * 1.6, 1.0)
    assert clothes_mask(model, model.vertices, cam, img)[top:top + 37, edge + 22:edge + 40].all()


def test_below_the_chin_a_black_and_white_photo_is_left_out(model):
    img, cam, chin, top = _photo_of_the_mean_head(model)
    img[top + 40:, :] = (0.30, 0.35, 0.45)              # a shirt up from the bottom edge
    grey = np.repeat(img.mean(2, keepdims=True), 3, axis=2)
    mask = clothes_mask(model, model.vertices, cam, grey)
    u = cam.project(model.vertices[model.skin])[:, 0]
    inside = slice(int(u.min()) + 1, int(u.max()))
    assert mask[top + 1:, inside].all()                 # the neck too: nothing tells skin
    assert not mask[:top - 1].any()                     # the face above the chin's line
    assert not clothes_mask(model, model.vertices, cam, img)[top + 1:top + 37].any()


def test_a_photo_that_misses_the_cheeks_tells_nothing(model):
    img, cam, _, _ = _photo_of_the_mean_head(model)
    away = OrthographicCamera(cam.rotation, cam.scale, cam.offset + [1000.0, 0.0], cam.size,
                              cam.view)
    assert clothes_mask(model, model.vertices, away, img) is None


def test_the_bake_from_a_fit_leaves_the_shirt_off_the_neck(model, sample_fit):
    result, photos, _ = sample_fit
    tiles = {mode: bake_fit_texture(model, result, photos, 256,
                                    options=BakeOptions(clothes=mode, threads=1))
             for mode in ("keep", "leave-out")}

    def cold(tex):  # texels bluer than red: the grey-blue shirt, never skin
        return int((tex[..., 2] > tex[..., 0] + 0.02).sum())

    assert cold(tiles["keep"][1002]) > 500  # the shirt on the neck's sides and back
    assert cold(tiles["leave-out"][1002]) < 0.05 * cold(tiles["keep"][1002])
    # the face, above the collar, is the same but for the photos' equalisation, fitted on
    # fewer texels (about 1e-3)
    np.testing.assert_allclose(tiles["keep"][1001][:128], tiles["leave-out"][1001][:128],
                               atol=0.01)

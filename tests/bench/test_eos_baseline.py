"""The eos baseline (bench/eos_baseline.py): its camera is the scaled orthographic one
that made the pixels, it fits the landmarks eos maps (not the jaw's outline) of the photo
eos takes, and its fit finds a head the model can express from that head's landmarks,
pulled toward the mean head by its regularisation."""

import dataclasses

import numpy as np
import pytest

from bench.eos_baseline import (
    CONTOUR_IBUG,
    eos_fit,
    eos_heads,
    eos_view,
    scaled_orthographic,
    view_landmarks,
)
from solver.geometry import rotation_from_vector
from solver.io.landmark_set import load_landmark_set
from solver.synthetic import make_case, skin_error_mm


def test_the_camera_is_the_scaled_orthographic_one_that_made_the_pixels():
    rng = np.random.default_rng(0)
    points = rng.normal(scale=0.1, size=(30, 3))
    rows = rotation_from_vector(np.array([0.2, -0.4, 0.1]))[:2]
    pixels = 2500.0 * points @ rows.T + [384.0, 512.0]
    scale, found, t = scaled_orthographic(points, pixels)
    assert scale == pytest.approx(2500.0, rel=1e-12)
    np.testing.assert_allclose(found, rows, atol=1e-12)
    np.testing.assert_allclose(t, [384.0, 512.0], atol=1e-9)


def test_it_fits_the_front_without_the_jaws_outline(model):
    case, _ = make_case(model, 5, noise_px=0.0)
    assert eos_view(case) == "front"
    pixels, vertices = view_landmarks(model, case.views["front"])
    lms = model.landmark_set
    jaw = {lms.vertices[load_landmark_set().ibug[i]] for i in CONTOUR_IBUG}
    assert len(vertices) == len(pixels) > 40
    assert not jaw & set(vertices.tolist())
    assert lms.vertices["chin_bottom"] in vertices  # the menton is no contour point
    side = dataclasses.replace(case, views={"right": case.views["right"]})
    assert eos_view(side) == "right"  # no front: the photo with most landmarks


def test_it_finds_a_head_from_its_exact_landmarks_and_lambda_pulls_to_the_mean(model):
    case, truth = make_case(model, 5, noise_px=0.0)
    pixels, vertices = view_landmarks(model, case.views["front"])
    norms = [np.linalg.norm(eos_fit(model, pixels, vertices, lam)) for lam in (1, 10, 100)]
    assert norms[0] > norms[1] > norms[2]
    heads = eos_heads(model, case)
    errors = {lam: skin_error_mm(model, v, truth.local_vertices) for lam, v in heads.items()}
    mean = skin_error_mm(model, model.vertices, truth.local_vertices)
    assert errors[1.0] < 0.5 * mean  # 1.49 against 4.02 mm

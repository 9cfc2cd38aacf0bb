"""bench/head_regions.py: the skin in four regions, each vertex in one, and a head's error
in each, laid on the truth as the whole skin's error is."""

import numpy as np
import pytest

from bench.head_regions import EAR_RADIUS_M, REGIONS, region_errors, skin_regions
from solver.synthetic import skin_error_mm


def test_every_skin_vertex_lies_in_one_region_where_its_name_says(model):
    regions = skin_regions(model)
    assert tuple(regions) == REGIONS
    counts = np.sum([m.astype(int) for m in regions.values()], axis=0)
    assert counts.shape == (len(model.skin),) and (counts == 1).all()
    skin = np.asarray(model.skin)
    at = {v: i for i, v in enumerate(skin)}
    for name in ("ear_lobe_right", "ear_top_left"):
        assert regions["ears"][at[model.landmark_vertex(name)]]
    assert regions["face"][at[model.landmark_vertex("nose_tip")]]
    points = model.vertices[skin]
    ears = model.vertices[[model.landmark_vertex(n) for n in model.landmarks
                           if n.startswith("ear")]]
    # the back lies behind the ears (the face looks toward -Y), the rest anywhere else
    assert points[regions["back"], 1].min() > ears[:, 1].mean()
    near = np.min(np.linalg.norm(points[regions["back"], None] - ears[None], axis=2), axis=1)
    assert near.min() >= EAR_RADIUS_M


def test_a_head_wrong_at_its_ears_only_is_wrong_in_that_region(model):
    regions = skin_regions(model)
    truth = model.vertices
    head = truth.copy()
    ears = np.asarray(model.skin)[regions["ears"]]
    head[ears, 1] += 0.002  # the ears 2 mm further back
    errors = region_errors(model, head, truth, regions)
    # (the similarity over the whole skin takes a little of it: the others move a little)
    assert 1.5 < errors["ears"] < 2.0
    assert max(errors[n] for n in ("face", "back", "rest")) < 0.3 * errors["ears"]
    # the regions' mean squares, weighted by their sizes, make up the whole skin's
    sizes = np.array([regions[n].sum() for n in REGIONS])
    squares = np.array([errors[n] ** 2 for n in REGIONS])
    assert np.sqrt(sizes @ squares / sizes.sum()) == pytest.approx(
        skin_error_mm(model, head, truth), rel=1e-9)

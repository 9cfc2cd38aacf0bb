"""The realistic benchmark's score per part of the face (bench/bench_realistic.py,
``--parts``): the parts' errors make up the face's, and a head is scored where it differs
from the truth."""

from types import SimpleNamespace

import numpy as np
import pytest

from bench.bench_realistic import parts_of, synthetic_truth
from bench.realistic_cases import FACE_PARTS, model_ibug


def test_the_parts_errors_make_up_the_faces_and_show_where_a_head_differs(model):
    rng = np.random.default_rng(5)
    local = model.identity.instance(rng.normal(size=model.identity.n_coeffs))
    truth = synthetic_truth(model, SimpleNamespace(local_vertices=local), 2000, 5, parts=True)
    # the nose pushed 2 mm forward (the model's -Y), nothing else moved
    ibug = model_ibug(model, local)
    near_nose = np.linalg.norm(local - ibug[31], axis=1) < 0.012
    head = local.copy()
    head[near_nose, 1] -= 0.002
    score = truth.score(head)
    parts = {p: score[f"face {p}"] for p in FACE_PARTS}
    n = {p: m.sum() for p, m in truth.parts.items()}
    whole = np.sqrt(sum(n[p] * parts[p] ** 2 for p in parts) / sum(n.values()))
    assert whole == pytest.approx(score["face"], rel=1e-9)
    assert max(parts, key=parts.get) == "nose"
    assert parts["nose"] > 3 * max(parts[p] for p in ("jaw", "brows", "mouth"))
    # a head equal to the truth: nothing anywhere
    assert max(truth.score(local).values()) < 1e-6
    # parts_of regroups the scores by part, as the table prints them
    assert parts_of({"fit": score, "mean": score})["nose"] == {"fit": parts["nose"],
                                                              "mean": parts["nose"]}
    without = synthetic_truth(model, SimpleNamespace(local_vertices=local), 2000, 5)
    assert set(without.score(head)) == {"face", "head"}

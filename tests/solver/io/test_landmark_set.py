"""The landmark set (solver/io/landmark_set.py): names, vertices, ibug aliases, suggestions
for misspelt names, and the sets built from names or a model."""

import copy
import re

import pytest

from solver import MIN_LANDMARKS_TOTAL, parse_landmarks
from solver.io.landmark_set import LandmarkSet, as_landmark_set, load_landmark_set
from tests.solver.io.support import parse_error


def test_landmark_set_has_names_and_ibug_aliases(lms):
    assert len(lms.names) >= MIN_LANDMARKS_TOTAL
    assert lms.ibug, "assets/landmarks.json gives no iBUG numbers"
    for number, name in lms.ibug.items():
        assert 1 <= number <= 68
        assert lms.canonical(f"ibug{number:02d}") == name
        assert lms.vertex(f"ibug{number:02d}") == lms.vertex(name) >= 0
    assert lms.canonical("no_such_landmark") is None
    with pytest.raises(ValueError, match="landmark 'no_such_landmark': unknown"):
        lms.vertex("no_such_landmark")


def test_landmark_set_rejects_bad_entries():
    base = {"format": "headrecon-landmark-set", "version": 1,
            "landmarks": [{"name": "a", "vertex": 1, "ibug": 3}]}
    assert LandmarkSet.from_dict(base).vertex("ibug03") == 1
    bad = copy.deepcopy(base)
    bad["landmarks"].append({"name": "a", "vertex": 2, "ibug": None})
    with pytest.raises(ValueError, match=r"set.json: landmarks\[1\].name: 'a' listed twice"):
        LandmarkSet.from_dict(bad, "set.json")
    bad = copy.deepcopy(base)
    bad["landmarks"].append({"name": "b", "vertex": 2, "ibug": 3})
    with pytest.raises(ValueError, match=r"landmarks\[1\].ibug"):
        LandmarkSet.from_dict(bad, "set.json")
    with pytest.raises(ValueError, match="not a landmark set"):
        LandmarkSet.from_dict({"format": "headrecon-landmarks"}, "set.json")


def test_known_names_from_a_list_or_model_like_object(doc, names):
    case = parse_landmarks(doc, "case.json", known_names=list(names))
    assert case.views["side"].points
    msg = parse_error(doc, known_names=names[1:])
    assert re.search(rf"case.json: views.front.points.{names[0]}: unknown landmark", msg)

    class ModelLike:
        landmark_info = [{"name": n, "vertex": i} for i, n in enumerate(names)]

    case = parse_landmarks(doc, "case.json", known_names=ModelLike())
    assert case.views["front"].arrays(ModelLike())[1].tolist() == list(range(8))


@pytest.mark.parametrize("typo,name", [("nose_tpi", "nose_tip"), ("ibug1", "ibug01"),
                                       ("Nose_Tip", "nose_tip")])
def test_unknown_landmark_suggests_the_closest_name(doc, typo, name):
    doc["views"]["side"]["points"][typo] = [100.0, 100.0]
    msg = parse_error(doc)
    assert re.match(rf"case\.json: views\.side\.points\.{typo}: unknown landmark; "
                    rf"did you mean '{name}'\?", msg), msg


def test_the_model_resolves_names_through_its_landmark_set(model, lms):
    own = model.landmark_set
    assert isinstance(own, LandmarkSet) and as_landmark_set(model) is own
    assert own.names == lms.names and own.ibug == lms.ibug  # the model's copy of the asset
    for number, name in own.ibug.items():
        assert model.landmark_vertex(f"ibug{number:02d}") == own.vertices[name]
    with pytest.raises(ValueError, match=r"landmark 'ibug1': unknown; did you mean 'ibug01'\?"):
        model.landmark_vertex("ibug1")
    assert as_landmark_set(None) is load_landmark_set()
    assert LandmarkSet.from_entries(model.landmark_info).vertices == own.vertices
    assert own.canonical(31) is None
    with pytest.raises(ValueError, match="got a string"):
        as_landmark_set("nose_tip")



def test_outline_points_and_where_a_landmark_has_a_meaning(lms):
    # the jaw is a front photo's outline, with no place in a profile photo
    assert lms.outline_in("jaw_3_right", "front") and not lms.outline_in("nose_tip", "front")
    assert not lms.has_meaning_in("jaw_3_right", "right")
    # the menton: an outline point in front, the chin's lowest point on the profile line
    assert lms.outline_in("chin_bottom", "front") and lms.has_meaning_in("chin_bottom", "right")
    assert lms.has_meaning_in("nose_tip", "right") and lms.has_meaning_in("nose_tip", "front")
    for entry in lms.info:  # every outline view is one of the landmark's views
        assert set(entry.get("outline", ())) <= set(entry["views"]), entry["name"]
    # a set from bare names knows nothing of views: every name means something everywhere
    bare = LandmarkSet.from_names(["a"])
    assert bare.has_meaning_in("a", "right") and not bare.outline_in("a", "front")


def test_every_description_reads_as_sentences(lms):
    # the add-on shows these to the artist: each starts with a capital, and no sentence
    # runs on into the next without its full stop
    for entry in lms.info:
        text = entry["description"]
        assert text[:1].isupper(), entry["name"]
        assert not re.search(r"[a-z,;:] [A-Z][a-z]+ (outline|point|photo)\b", text), \
            (entry["name"], text)

"""The Fit job's report lines (headrecon_addon/fit_job.py): each photo's expression taken
out is named with its weight and how surely the landmarks tell it from neutral."""

from headrecon_addon.fit_job import expression_notes


def test_the_report_names_each_expression_with_its_standard_deviation():
    info = {"expressions": {"front": {"eyeBlink_R": 0.912, "browOuterUp_L": 0.31},
                            "right": {}},
            "expression_sd": {"front": {"eyeBlink_R": 0.2, "browOuterUp_L": 0.254}}}
    assert expression_notes(info) == [
        "photo 'front' showed eyeBlink_R 0.91 \u00b1 0.20, browOuterUp_L 0.31 \u00b1 0.25 "
        "(taken out of its landmarks: the head is neutral)"]
    # a fit whose standard deviations are not known (an older refit state): weights only;
    # a neutral fit: no line
    assert expression_notes({"expressions": {"side": {"jawOpen": 0.25}}}) == [
        "photo 'side' showed jawOpen 0.25 (taken out of its landmarks: the head is neutral)"]
    assert expression_notes({}) == []

"""The add-on's settings offer exactly the values the solver accepts."""

import pytest

from solver import CLOTHES_MODES, FIT_METHODS, SHADING_MODES


@pytest.mark.parametrize("prop, values", [("method", FIT_METHODS),
                                          ("texture_shading", SHADING_MODES),
                                          ("texture_clothes", CLOTHES_MODES)])
def test_a_choice_offers_the_solvers_values(scene, prop, values):
    items = scene.headrecon.bl_rna.properties[prop].enum_items
    assert [i.identifier for i in items] == list(values)

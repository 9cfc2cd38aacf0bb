"""The warm-up (headrecon_addon/warm_up.py): what the first Fit would wait for is made
ahead, and only in the interactive UI in a thread of its own."""

from headrecon_addon import warm_up


def test_prepare_makes_what_the_first_fit_waits_for(model):
    from solver.fitting.engine import FITTED_MODEL
    from solver.memo import memo_items

    seconds = warm_up.prepare(64)
    assert set(seconds) == {"model", "fit", "rasters", "lashes"}
    assert all(s >= 0 for s in seconds.values())
    keys = [k for k, _ in memo_items(model)]
    assert "skin maps" in keys and any(isinstance(k, tuple) and k[:1] == (FITTED_MODEL,)
                                       for k in keys)


def test_no_thread_in_a_background_run():
    assert warm_up.warm_up(64) is None  # bpy.app.background: a batch pays when it fits

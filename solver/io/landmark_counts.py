"""How many landmarks a fit needs, per view and in all: the one rule that the landmarks
file's check, the fit and the add-on's Fit button apply."""

MIN_LANDMARKS_PER_VIEW = 3
MIN_LANDMARKS_TOTAL = 6
#: Different landmarks (a landmark placed in several photos counts once) a case needs: the
#: fit's thin-plate spline takes the landmarks' 3-D targets, and in 3-D it needs four.
MIN_DISTINCT_LANDMARKS = 4


def landmarks_needed(min_refit_points, *, kept=False, passpoints=False, mirror=False,
                     outline=False):
    """Fewest landmarks one view needs.

    Parameters
    ----------
    min_refit_points : int
        ``min_refit_points`` of the view's camera kind (0 for an unknown kind).
    kept : bool
        The camera is kept as given (``calibrated``, or a fixed camera of the fit).
    passpoints : bool
        The view has passpoints, which give its camera.
    mirror : bool
        A mirror view whose camera is the real one reflected: its mirror plane is found
        from landmarks seen both directly and in the mirror.
    outline : bool
        An orthographic profile photo with a traced outline: the outline places its camera
        (``solver.fitting.contour_start``), so landmarks are optional there.

    Returns
    -------
    int
        0 for a camera that is kept, given by passpoints (landmarks refine a passpoint
        camera when there are enough) or placed by a profile's outline;
        ``MIN_LANDMARKS_PER_VIEW`` for a mirror view; else
        what refitting the camera on the head needs, at least ``MIN_LANDMARKS_PER_VIEW``.
    """
    if kept:
        return 0
    if mirror:
        return MIN_LANDMARKS_PER_VIEW
    if passpoints or outline:
        return 0
    return max(MIN_LANDMARKS_PER_VIEW, int(min_refit_points))


def too_few(used, need):
    """The message for a view with ``used`` usable landmarks that needs ``need``, or None."""
    if used >= need:
        return None
    return (f"{used} usable landmark{'s' * (used != 1)}; the fit needs at least {need} in "
            f"this view ({need - used} more)")


def too_few_in_all(total):
    """The message for a case with ``total`` usable landmarks in all, or None."""
    if total >= MIN_LANDMARKS_TOTAL:
        return None
    return (f"{total} usable landmark{'s' * (total != 1)} in all; the fit needs at least "
            f"{MIN_LANDMARKS_TOTAL}")


def too_few_distinct(names, sliding=False):
    """The message for a case whose landmarks are only ``names`` (the different ones, each
    counted once however many photos show it), or None. ``sliding``: a front photo's
    outline points were left out of ``names`` (they slide along the outline)."""
    if len(names) >= MIN_DISTINCT_LANDMARKS:
        return None
    listed = f" ({', '.join(sorted(names))})" if names else ""
    left_out = "; a front photo's outline points slide and do not count" if sliding else ""
    return (f"{len(names)} different landmark{'s' * (len(names) != 1)} in all{listed}; the "
            f"fit needs at least {MIN_DISTINCT_LANDMARKS} different ones (a landmark placed "
            f"in several photos counts once{left_out})")


def count_problems(used, needed):
    """The views with too few landmarks, and a total below ``MIN_LANDMARKS_TOTAL``.

    Parameters
    ----------
    used, needed : dict
        View name -> landmarks usable in it, and -> :func:`landmarks_needed` of it.

    Returns
    -------
    list of (str or None, str)
        (view name, or None for the whole case; message), in view order.
    """
    problems = [(name, too_few(n, needed.get(name, MIN_LANDMARKS_PER_VIEW)))
                for name, n in used.items()]
    problems = [(name, msg) for name, msg in problems if msg is not None]
    total = too_few_in_all(sum(used.values()))
    return problems + ([(None, total)] if total is not None else [])

"""How many landmarks a fit needs, per view and in all: the one rule that the landmarks
file's check, the fit and the add-on's Fit button apply."""

MIN_LANDMARKS_PER_VIEW = 3
MIN_LANDMARKS_TOTAL = 6


def landmarks_needed(min_refit_points, *, kept=False, passpoints=False, mirror=False):
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

    Returns
    -------
    int
        0 for a camera that is kept or given by passpoints (landmarks refine a passpoint
        camera when there are enough); ``MIN_LANDMARKS_PER_VIEW`` for a mirror view; else
        what refitting the camera on the head needs, at least ``MIN_LANDMARKS_PER_VIEW``.
    """
    if kept:
        return 0
    if mirror:
        return MIN_LANDMARKS_PER_VIEW
    if passpoints:
        return 0
    return max(MIN_LANDMARKS_PER_VIEW, int(min_refit_points))


def count_problems(used, needed):
    """The views with too few landmarks and a total below ``MIN_LANDMARKS_TOTAL``.

    Parameters
    ----------
    used, needed : dict
        View name -> landmarks usable in it, and -> :func:`landmarks_needed` of it.

    Returns
    -------
    list of (str or None, str)
        (view name, or None for the whole case; message), in view order.
    """
    problems = []
    for name, n in used.items():
        need = needed.get(name, MIN_LANDMARKS_PER_VIEW)
        if n < need:
            problems.append((name, f"{n} usable landmark{'s' * (n != 1)}; the fit needs at "
                                   f"least {need} in this view ({need - n} more)"))
    total = sum(used.values())
    if total < MIN_LANDMARKS_TOTAL:
        problems.append((None, f"{total} usable landmark{'s' * (total != 1)} in all; the fit "
                               f"needs at least {MIN_LANDMARKS_TOTAL}"))
    return problems

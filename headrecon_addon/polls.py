"""Operator poll helpers: every operator that cannot run says why (``poll_message_set``:
the tooltip of a greyed-out button, the error of a background call), with one wording.

A poll is written as a chain of "problem" checks, each a sentence or None, so the first
problem found is the one shown::

    return poll_result(cls, object_mode_problem(context) or photos_problem(...))
"""

OBJECT_MODE = "Switch to Object Mode first"
VIEW_3D = "Use it in a 3D Viewport"


def poll_result(cls, problem):
    """An operator poll's answer: True when ``problem`` is empty, else False with
    ``problem`` shown as the reason."""
    if problem:
        cls.poll_message_set(problem)
        return False
    return True


def object_mode_problem(context):
    return None if context.mode == "OBJECT" else OBJECT_MODE


def view3d_problem(context):
    return None if context.area is not None and context.area.type == "VIEW_3D" else VIEW_3D


class ObjectModeOperator:
    """Operator mixin: available in Object Mode only."""

    @classmethod
    def poll(cls, context):
        return poll_result(cls, object_mode_problem(context))

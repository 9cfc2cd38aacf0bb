"""The one place the add-on reaches the solver: the solver's public API (``solver.__all__``),
re-exported here by name, and the ``solver`` package itself.

Inside Blender the extension is the package ``bl_ext.<repo>.headrecon`` and the solver is
its sibling subpackage (``from .. import solver``). In a checkout run as plain Python
(tests, ``python -m headrecon_addon.headless``) ``headrecon_addon`` and ``solver`` are both
top-level packages and the relative import fails with "attempted relative import beyond
top-level package"; then the absolute import is the right one. Any other ImportError (a
missing scipy, a broken solver module) is re-raised so it is not mistaken for this case.
"""

import importlib

try:
    from .. import solver
except ImportError as e:  # top-level headrecon_addon (a checkout): the solver is top-level too
    if "beyond top-level package" not in str(e):
        raise
    solver = importlib.import_module("solver")

globals().update({name: getattr(solver, name) for name in solver.__all__})


def solver_module(name):
    """The solver's submodule ``name`` ("io.atomic", "cli", ...), whichever package the
    solver is here."""
    return importlib.import_module(f"{solver.__name__}.{name}")


__all__ = ["solver", "solver_module", *solver.__all__]

"""The heads of a batch: plain landmarks files, or manifests (``.csv`` with a header row,
``.jsonl`` with one JSON object a line) naming one head a row with options of its own.

A manifest row has ``name`` (the outputs' base name), ``landmarks`` (a landmarks file,
relative to the manifest) or ``photos`` (the head's photos separated by ";", relative to
the manifest: the headless script detects the landmarks in them) and optional per-head
options (``OPTION_COLUMNS``); an empty cell means "as on the command line". A problem
with the manifest itself (unreadable, no header, an unknown column) raises ``ValueError``
naming the file and column; a problem with one row (a bad value, a name given twice, a
missing file) becomes that head's ``error``, so the rows around it still run. No bpy here:
the parent of a batch reads the plan without Blender's data.
"""

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path

MANIFEST_SUFFIXES = (".csv", ".jsonl")
TRUE, FALSE = ("1", "true", "yes"), ("0", "false", "no")


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        raise ValueError(f"{text!r} is not a whole number") from None
    if value < 0:
        raise ValueError(f"{text!r} is negative")
    return value


def _solver_choice(name):
    """A parser of a cell that must be one of the solver's values ``solver.<name>``, read
    when a row names the option (the plan of a batch without per-head options does not
    import the solver)."""
    def parse(text):
        from . import solver_link

        choices = getattr(solver_link, name)
        if text not in choices:
            raise ValueError(f"{text!r} is not one of {', '.join(choices)}")
        return text

    return parse


def _flag(text):
    low = str(text).strip().lower()
    if low in TRUE:
        return True
    if low in FALSE:
        return False
    raise ValueError(f"{text!r} is not one of true, false, yes, no, 1, 0")


# column -> (setting it overrides, parser of the cell's text)
OPTION_COLUMNS = {
    "method": ("method", _solver_choice("FIT_METHODS")),
    "components": ("components", _positive_int),
    "regional": ("regional", _positive_int),
    "exact": ("exact", _flag),
    "texture_size": ("texture_size", _positive_int),
    "texture_shading": ("texture_shading", _solver_choice("SHADING_MODES")),
    "texture_clothes": ("texture_clothes", _solver_choice("CLOTHES_MODES")),
    "bake_identity": ("bake_identity", _flag),
}
KNOWN_COLUMNS = ("name", "landmarks", "photos", *OPTION_COLUMNS)


@dataclass(frozen=True)
class Head:
    """One head of a batch.

    ``base`` is the outputs' path without suffix (``OUT/<name>``); ``options`` the row's
    own settings (parsed); ``where`` names the input in messages ("heads.csv row 3");
    ``error`` says why the head cannot be run (it is listed as failed, not fitted);
    ``photos`` (a row's ``photos`` column, when it gives no landmarks file) are the photos
    to detect the landmarks in; ``warnings`` what their detection warned of, for the
    head's summary row.
    """

    name: str
    landmarks: Path | None
    base: Path
    where: str
    options: dict = field(default_factory=dict)
    error: str | None = None
    photos: tuple = ()
    warnings: tuple = ()


def is_manifest(path):
    """Whether ``path`` is read as a manifest (by its suffix) rather than a landmarks file."""
    return Path(path).suffix.lower() in MANIFEST_SUFFIXES


def _column(name):
    return name.strip().lower().replace("-", "_")


def _csv_rows(path):
    with open(path, newline="", encoding="utf-8-sig") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if not header or not any(h.strip() for h in header):
            raise ValueError(f"{path}: no header row (expected columns name, landmarks, ...)")
        columns = [_column(h) for h in header]
        _check_columns(path, columns)
        for number, cells in enumerate(reader, start=2):
            if not any(c.strip() for c in cells):
                continue  # blank line
            if len(cells) > len(columns):
                yield number, None, f"{len(cells)} cells for {len(columns)} columns"
                continue
            yield number, dict(zip(columns, (c.strip() for c in cells), strict=False)), None


def _jsonl_rows(path):
    with open(path, encoding="utf-8-sig") as f:
        for number, line in enumerate(f, start=1):
            if not line.strip():
                continue
            try:
                obj = json.loads(line)
            except json.JSONDecodeError as e:
                yield number, None, f"not JSON ({e.msg} at column {e.colno})"
                continue
            if not isinstance(obj, dict):
                yield number, None, "not a JSON object"
                continue
            row = {_column(k): "" if v is None else str(v) if not isinstance(v, bool)
                   else str(v).lower() for k, v in obj.items()}
            unknown = [k for k in row if k not in KNOWN_COLUMNS]
            if unknown:
                yield number, None, f"unknown key {unknown[0]!r} (known: " \
                                    f"{', '.join(KNOWN_COLUMNS)})"
                continue
            yield number, row, None


def _check_columns(path, columns):
    for c in columns:
        if c not in KNOWN_COLUMNS:
            raise ValueError(f"{path}: column {c!r} is unknown (known: "
                             f"{', '.join(KNOWN_COLUMNS)})")
    for c in ("name", "landmarks"):
        if c not in columns and not (c == "landmarks" and "photos" in columns):
            raise ValueError(f"{path}: no column {c!r}")


def read_manifest(path):
    """The rows of a manifest as (where, row dict | None, problem | None), ``where`` being
    "<file> row N" (the line number; row 1 of a .csv is its header).

    Raises
    ------
    ValueError
        The file cannot be read, or (.csv) has no header or an unknown column.
    """
    path = Path(path)
    rows = _csv_rows if path.suffix.lower() == ".csv" else _jsonl_rows
    try:
        return [(f"{path} row {n}", row, problem) for n, row, problem in rows(path)]
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise ValueError(f"{path}: cannot be read ({e})") from None


def _row_head(where, row, folder, out_dir):
    name = row.get("name", "")
    base = out_dir / (name or "unnamed")
    if not name:
        return Head(name or where, None, base, where, error=f"{where}: column name is empty")
    if Path(name).name != name or name in (".", ".."):
        return Head(name, None, base, where,
                    error=f"{where}: column name {name!r} is not a plain file name")
    options = {}
    for column, (key, parse) in OPTION_COLUMNS.items():
        text = row.get(column, "")
        if text == "":
            continue
        try:
            options[key] = parse(text)
        except ValueError as e:
            return Head(name, None, base, where, error=f"{where}: column {column}: {e}")
    landmarks = row.get("landmarks", "")
    photos = tuple(folder / p.strip() for p in row.get("photos", "").split(";") if p.strip())
    if not landmarks and photos:
        return Head(name, None, base, where, options, photos=photos)
    if not landmarks:
        return Head(name, None, base, where, options,
                    error=f"{where}: column landmarks is empty")
    return Head(name, folder / landmarks, base, where, options)


def plan_heads(inputs, out):
    """The heads of a batch, in input order.

    Parameters
    ----------
    inputs : sequence of path-like
        Landmarks files and manifests (``is_manifest``), mixed as given.
    out : path-like
        A ``.blend`` file (for exactly one head) or a folder (``OUT/<name>.*`` per head).

    Returns
    -------
    list of Head
        A name given twice makes the later head an error (both would write one file).

    Raises
    ------
    ValueError
        One line: a manifest that cannot be read, or a .blend ``out`` for several heads.
    """
    out = Path(out)
    single = out.suffix.lower() == ".blend"
    out_dir = out.parent if single else out
    heads = []
    for item in map(Path, inputs):
        if not is_manifest(item):
            heads.append(Head(item.stem, item, out_dir / item.stem, str(item)))
            continue
        for where, row, problem in read_manifest(item):
            if problem is not None:
                heads.append(Head(where, None, out_dir / "unnamed", where,
                                  error=f"{where}: {problem}"))
            else:
                heads.append(_row_head(where, row, item.parent, out_dir))
    if single:
        if len(heads) != 1:
            raise ValueError(f"--out {out}: one .blend file for {len(heads)} heads; give a "
                             "folder instead")
        h = heads[0]
        heads = [Head(h.name, h.landmarks, out.with_suffix(""), h.where, h.options, h.error,
                      h.photos)]
    seen = {}
    for i, h in enumerate(heads):
        if h.error is None and h.name in seen:
            heads[i] = Head(h.name, h.landmarks, h.base, h.where, h.options,
                            error=f"{h.where}: name {h.name!r} is also {seen[h.name]}; "
                                  "rename one (both would write the same files)",
                            photos=h.photos)
        elif h.error is None:
            seen[h.name] = h.where
    return heads


def fit_options(settings):
    """The solver's ``FitOptions`` of a head's settings (the fit options of ``_settings`` and
    ``OPTION_COLUMNS``); ``ValueError`` naming the option when one is bad."""
    from .solver_link import FitOptions

    kw = {}
    for key, name in (("method", "method"), ("n_identity", "components"),
                      ("n_regional", "regional")):
        if settings.get(name) is not None:
            kw[key] = settings[name]
    if settings.get("exact"):
        kw["exact_landmarks"] = True
    return FitOptions(**kw)

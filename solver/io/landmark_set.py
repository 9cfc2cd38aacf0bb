"""The landmark set (``assets/landmarks.json``): the one source of truth for landmark
names, their model vertices and their iBUG-68 aliases (``ibug01`` ... ``ibug68``).

The landmarks file, the fit and the head model (``HeadModel.landmark_vertex``) all resolve
names through a :class:`LandmarkSet`.
"""

import difflib
import functools
import re
from dataclasses import dataclass
from pathlib import Path

from ..paths import ASSETS_DIR
from .json_file import read_json

LANDMARK_SET_PATH = ASSETS_DIR / "landmarks.json"
SET_FORMAT = "headrecon-landmark-set"

_IBUG = re.compile(r"^ibug(\d\d)$")


@dataclass(frozen=True, eq=False)
class LandmarkSet:
    """Known landmark names, their model vertices and their iBUG-68 numbers.

    Attributes
    ----------
    names : tuple of str
        Canonical names in file order.
    vertices : dict of str -> int
        Canonical name -> model vertex index (-1 when not known, e.g. built from names).
    ibug : dict of int -> str
        iBUG-68 number (1...68) -> canonical name; the alias ``ibugNN`` resolves through it.
    info : tuple of dict
        The entries of ``assets/landmarks.json`` (name, description, vertex, views, ibug,
        thesis), for user interfaces.
    source : str
    """

    names: tuple
    vertices: dict
    ibug: dict
    info: tuple = ()
    source: str = "<names>"

    @classmethod
    def from_dict(cls, data, source="<dict>"):
        """Build from the parsed ``assets/landmarks.json`` document."""
        if not isinstance(data, dict) or data.get("format") != SET_FORMAT:
            raise ValueError(f"{source}: not a landmark set (expected \"format\": "
                             f"\"{SET_FORMAT}\")")
        entries = data.get("landmarks")
        if not isinstance(entries, list) or not entries:
            raise ValueError(f"{source}: landmarks: expected a non-empty list")
        names, vertices, ibug = [], {}, {}
        for i, e in enumerate(entries):
            name = e.get("name") if isinstance(e, dict) else None
            if not isinstance(name, str) or not name or _IBUG.match(name):
                raise ValueError(f"{source}: landmarks[{i}].name: expected a name that is "
                                 f"not an ibug alias, got {name!r}")
            if name in vertices:
                raise ValueError(f"{source}: landmarks[{i}].name: {name!r} listed twice")
            vertex = e.get("vertex")
            if isinstance(vertex, bool) or not isinstance(vertex, int) or vertex < 0:
                raise ValueError(f"{source}: landmarks[{i}].vertex: expected a vertex index, "
                                 f"got {vertex!r}")
            number = e.get("ibug")
            if number is not None:
                if isinstance(number, bool) or not isinstance(number, int) \
                        or not 1 <= number <= 68 or number in ibug:
                    raise ValueError(f"{source}: landmarks[{i}].ibug: expected a free number "
                                     f"1..68 or null, got {number!r}")
                ibug[number] = name
            names.append(name)
            vertices[name] = vertex
        return cls(tuple(names), vertices, ibug, tuple(entries), str(source))

    @classmethod
    def from_entries(cls, entries, source="<entries>"):
        """Build from the entries of a landmark set (e.g. ``HeadModel.landmark_info``)."""
        return cls.from_dict({"format": SET_FORMAT, "landmarks": list(entries)}, source)

    @classmethod
    def from_names(cls, names):
        """A set from bare names (vertices unknown, no ibug aliases beyond names given)."""
        names = tuple(dict.fromkeys(str(n) for n in names))
        return cls(names, dict.fromkeys(names, -1), {}, (), "<names>")

    def canonical(self, name):
        """Canonical name of ``name`` (itself, or the landmark an ``ibugNN`` alias
        stands for), or None if unknown."""
        if name in self.vertices:
            return name
        m = _IBUG.match(name) if isinstance(name, str) else None
        if m:
            return self.ibug.get(int(m.group(1)))
        return None

    def vertex(self, name):
        """Model vertex index of ``name`` (canonical or ``ibugNN``).

        Raises ValueError naming the landmark (and the closest accepted name) when it is
        unknown.
        """
        canon = self.canonical(name)
        if canon is None:
            raise ValueError(f"landmark {name!r}: unknown{self.suggestion(name)}")
        return self.vertices[canon]

    def outline_in(self, name, kind):
        """Whether landmark ``name`` (canonical) is a point of the head's outline in a photo
        of ``kind`` ("front", "right", "left"): matched to the posed model's silhouette
        there, not to its vertex (the entry's "outline")."""
        return kind in self._entry(name).get("outline", ())

    def has_meaning_in(self, name, kind):
        """Whether landmark ``name`` (canonical) means a place in a photo of ``kind`` (the
        entry's "views"; a set without entries, e.g. from names, says yes)."""
        entry = self._entry(name)
        return "views" not in entry or kind in entry["views"]

    def group_of(self, name):
        """The definition group of landmark ``name`` (canonical): the entry's "group", the
        landmarks whose placement shares one convention (an eye, a brow); the name itself
        when the entry gives none."""
        return self._entry(name).get("group", name)

    @functools.cached_property
    def _entries(self):
        return {e.get("name"): e for e in self.info if isinstance(e, dict)}

    def _entry(self, name):
        return self._entries.get(name, {})

    def all_names(self):
        """Every accepted spelling: canonical names, then ``ibugNN`` aliases."""
        return list(self.names) + [f"ibug{n:02d}" for n in sorted(self.ibug)]

    def suggestion(self, name):
        """"; did you mean 'x'?" for the closest accepted name, or ""."""
        if not isinstance(name, str):
            return ""
        accepted = self.all_names()
        lower = {n.lower(): n for n in accepted}
        m = re.match(r"^ibug[ _-]?0*(\d+)$", name.strip(), re.IGNORECASE)
        if m and int(m.group(1)) in self.ibug:  # "ibug1", "iBUG_31": the spelling is fixed
            guess = f"ibug{int(m.group(1)):02d}"
        elif name.strip().lower() in lower:  # "Nose_Tip"
            guess = lower[name.strip().lower()]
        else:
            close = difflib.get_close_matches(name, accepted, n=1, cutoff=0.6)
            guess = close[0] if close else None
        return f"; did you mean {guess!r}?" if guess else ""


@functools.lru_cache(maxsize=8)
def _landmark_set_cached(path, mtime):
    return LandmarkSet.from_dict(read_json(path), str(path))


def load_landmark_set(path=None):
    """The landmark set of ``assets/landmarks.json`` (or ``path``); cached until it changes.

    Raises
    ------
    FileNotFoundError
        The file is missing (the model helper writes ``assets/landmarks.json``).
    ValueError
        The file is not a valid landmark set (message names the file and entry).
    """
    path = Path(path) if path is not None else LANDMARK_SET_PATH
    try:
        mtime = path.stat().st_mtime_ns
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: landmark set not found") from None
    return _landmark_set_cached(str(path), mtime)


def as_landmark_set(known_names):
    """None (the default set), a LandmarkSet, a HeadModel-like object (its
    ``landmark_set``, or a set built from its ``landmark_info``), or an iterable of names
    -> LandmarkSet."""
    if known_names is None:
        return load_landmark_set()
    if isinstance(known_names, LandmarkSet):
        return known_names
    own = getattr(known_names, "landmark_set", None)
    if isinstance(own, LandmarkSet):
        return own
    info = getattr(known_names, "landmark_info", None)
    if info is not None:
        return LandmarkSet.from_entries(info, "<model>")
    if isinstance(known_names, str):
        raise ValueError("known_names: expected a LandmarkSet or names, got a string")
    return LandmarkSet.from_names(known_names)

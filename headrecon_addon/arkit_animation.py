"""Import ARKit Animation: a Live Link Face CSV as an action on the head's expression keys.

Live Link Face (and tools that write its format) records one row per captured frame::

    Timecode,BlendShapeCount,EyeBlinkLeft,EyeLookDownLeft,...,TongueOut,HeadYaw,...
    14:02:31:07.512,61,0.0712,0.1033,...

``Timecode`` is ``HH:MM:SS:FF`` with an optional fraction of a frame (``FF.fff``) at the
capture's timecode rate; the blendshape columns are Apple's 52 names, in any letter case;
the head and eye rotation columns (and any other column) are not blendshapes and are
skipped. Each ARKit column the head has a key for becomes one F-curve on
``key_blocks["<name>"].value``, its keyframes written in one ``foreach_set``, at the
scene's frame rate from the scene's start frame. Columns without a key on the head
(``tongueOut``: the model has none) are reported, not invented.

The file is read and checked completely before the scene is touched: a bad file raises
one ``ValueError`` naming the file, line and column, and the scene stays as it was.
"""

import csv
import re
from dataclasses import dataclass
from pathlib import Path

import bpy
import numpy as np

from . import arkit

TIMECODE_RATES = (24, 25, 30, 50, 60)
DEFAULT_TIMECODE_FPS = 60
HEADER = ("Timecode", "BlendShapeCount")
_TIMECODE = re.compile(r"^(\d+):(\d\d):(\d\d)[:;](\d+(?:\.\d+)?)$")
_LINEAR = 1  # Keyframe.interpolation as an integer: CONSTANT 0, LINEAR 1, BEZIER 2


@dataclass
class Take:
    """A capture read from a CSV.

    Attributes
    ----------
    source : str
        The file.
    names : list of str
        The ARKit names of the blendshape columns, in the file's order.
    times : ndarray, shape (N,)
        Seconds from the first row (increasing).
    values : ndarray, shape (N, len(names))
        The blendshape weights of each row.
    """

    source: str
    names: list
    times: np.ndarray
    values: np.ndarray


def parse_timecode(text, fps):
    """``HH:MM:SS:FF[.fff]`` at ``fps`` frames a second -> seconds (None if malformed)."""
    m = _TIMECODE.match(text.strip())
    if m is None:
        return None
    h, mi, s, f = int(m[1]), int(m[2]), int(m[3]), float(m[4])
    if mi > 59 or s > 59 or f >= fps:
        return None
    return 3600.0 * h + 60.0 * mi + s + f / fps


def read_live_link_csv(path, timecode_fps=DEFAULT_TIMECODE_FPS):
    """Read a Live Link Face CSV.

    Parameters
    ----------
    path : str or Path
    timecode_fps : int
        The frame rate of the file's timecode.

    Returns
    -------
    Take

    Raises
    ------
    ValueError
        The file cannot be read or is not such a CSV: the message names the file, the line
        (1 is the header) and the column.
    """
    name = Path(path).name
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise ValueError(f"{name}: cannot read the file: {e}") from e
    if not rows or [c.strip() for c in rows[0][:2]] != list(HEADER):
        got = ",".join(rows[0][:3]) if rows else ""
        got = f"{got!r}" if got.strip() else "an empty line"
        raise ValueError(f"{name}: line 1: expected a Live Link Face header starting "
                         f"'{','.join(HEADER)}', got {got}")
    header = [c.strip() for c in rows[0]]
    columns, names = [], []
    for i, col in enumerate(header[2:], start=2):
        ak = arkit.arkit_name(col)
        if ak is None:
            continue
        if ak in names:
            raise ValueError(f"{name}: line 1, column {i + 1} ({col}): {ak} appears twice")
        columns.append(i)
        names.append(ak)
    if not names:
        raise ValueError(f"{name}: line 1: no ARKit blendshape columns (eyeBlinkLeft ... "
                         "tongueOut)")
    data = [(n, r) for n, r in enumerate(rows[1:], start=2) if any(c.strip() for c in r)]
    if not data:
        raise ValueError(f"{name}: no data rows after the header")
    times = np.empty(len(data))
    values = np.empty((len(data), len(names)))
    for k, (line, row) in enumerate(data):
        if len(row) != len(header):
            raise ValueError(f"{name}: line {line}: {len(row)} columns, the header has "
                             f"{len(header)}")
        t = parse_timecode(row[0], timecode_fps)
        if t is None:
            raise ValueError(f"{name}: line {line}, column Timecode: {row[0]!r} is not a "
                             f"timecode HH:MM:SS:FF at {timecode_fps} fps")
        if k and t <= times[k - 1]:
            raise ValueError(f"{name}: line {line}, column Timecode: {row[0]} is not after "
                             "the row before it")
        times[k] = t
        for j, c in enumerate(columns):
            try:
                values[k, j] = float(row[c])
            except ValueError:
                values[k, j] = np.nan
            if not np.isfinite(values[k, j]):
                raise ValueError(f"{name}: line {line}, column {header[c]}: {row[c]!r} is not "
                                 "a number")
    return Take(str(path), names, times - times[0], values)


def _fcurves_of(action, key):
    """The F-curve collection to add to and the action slot for ``key`` (None before
    Blender 4.4, whose actions hold F-curves directly)."""
    if hasattr(action, "slots"):  # 4.4+: layered actions
        slot = action.slots.new(id_type="KEY", name=key.name)
        strip = action.layers.new("Capture").strips.new(type="KEYFRAME")
        return strip.channelbag(slot, ensure=True).fcurves, slot
    return action.fcurves, None


def apply_take(head, take, scene=None):
    """Make ``take`` an action on ``head``'s shape keys and assign it.

    Parameters
    ----------
    head : bpy.types.Object
        A head with the expression keys (ARKit names).
    take : Take
    scene : bpy.types.Scene, optional
        Its frame rate and start frame place the keyframes (default: the current scene).

    Returns
    -------
    action : bpy.types.Action
    skipped : list of str
        ARKit names in the take the head has no key for.
    """
    scene = scene or bpy.context.scene
    key = head.data.shape_keys
    if key is None:
        raise ValueError(f"{head.name}: has no shape keys; fit it first")
    present = [(j, n) for j, n in enumerate(take.names) if n in key.key_blocks]
    skipped = [n for n in take.names if n not in key.key_blocks]
    if not present:
        raise ValueError(f"{Path(take.source).name}: none of its columns is a shape key of "
                         f"{head.name}")
    fps = scene.render.fps / scene.render.fps_base
    frames = scene.frame_start + take.times * fps
    ad = key.animation_data
    before = (ad.action, getattr(ad, "action_slot", None)) if ad is not None else None
    action = bpy.data.actions.new(f"{head.name} {Path(take.source).stem}")
    try:
        fcurves, slot = _fcurves_of(action, key)
        co = np.empty((len(frames), 2), dtype=np.float32)
        co[:, 0] = frames
        interp = np.full(len(frames), _LINEAR, dtype=np.int32)
        for j, name in present:
            fc = fcurves.new(f'key_blocks["{name}"].value')
            fc.keyframe_points.add(len(frames))
            co[:, 1] = take.values[:, j]
            fc.keyframe_points.foreach_set("co", co.ravel())
            fc.keyframe_points.foreach_set("interpolation", interp)
            fc.update()
        ad = key.animation_data_create()
        ad.action = action
        if slot is not None:
            ad.action_slot = slot
    except Exception:
        if before is None:
            key.animation_data_clear()
        else:
            key.animation_data.action = before[0]
            if before[1] is not None:
                key.animation_data.action_slot = before[1]
        bpy.data.actions.remove(action)
        raise
    end = int(np.ceil(frames[-1]))
    if end > scene.frame_end:
        scene.frame_end = end
    return action, skipped

"""Detect Landmarks in three steps, as the Fit (fit_job.py): ``prepare_detection`` (main
thread: each photo's pixels and which of its landmarks the artist placed), ``DetectJob.run``
(any thread: the detector only, no bpy), ``apply_detection`` (main thread: the landmarks
placed as detected, and the report's lines). Until the last step the scene is untouched,
so Esc (or an error) leaves it as it was.

What a detection changes on a photo is one rule, ``detection_plan``: every landmark the
detector found is placed as detected, except over one the artist placed or moved by hand
(unless asked to replace those); the photo's earlier detected landmarks the detector no
longer finds go. Auto Fit applies the same plan to the landmarks file it fits.
"""

import dataclasses
import time
from concurrent.futures import ThreadPoolExecutor

from . import landmarks, photo_faces, photos
from .job_progress import Progress
from .solver_link import (
    POINTS_YAW_MIN,
    ViewGuess,
    face_notes,
    is_nominal,
    load_model,
    placed,
    points_yaw_deg,
    usable_cores,
)


def _count(n):
    return f"{n} landmark{'s' * (n != 1)}"


def detection_plan(hand, detected, found, replace):
    """What a detection does to one photo's landmarks.

    Parameters
    ----------
    hand, detected : collection of str
        The photo's landmarks placed by hand, and its detected ones.
    found : collection of str
        The landmarks the detector found.
    replace : bool
        Replace hand-placed landmarks the detector found too.

    Returns
    -------
    place : list of str
        To place (or move) as detected.
    remove : list of str
        Earlier detected landmarks the detector no longer finds.
    kept : list of str
        Found, but kept as placed by hand.
    """
    place = [n for n in found if replace or n not in hand]
    kept = [n for n in found if n in hand and not replace]
    remove = [n for n in detected if n not in found]
    return place, remove, kept


def _turned_camera(guess, size):
    """The orthographic camera ``guess`` turns a photo of ``size`` on the nominal camera to,
    or None where it stays nominal."""
    camera, _ = guess.camera(size)
    return None if camera is None or is_nominal(camera, size) else camera


@dataclasses.dataclass
class PlacedFront:
    """A front photo not detected in this run, on the nominal orthographic camera, whose
    landmarks (placed by hand, or by an earlier detection) show the yaw it was taken from
    (``points_yaw_deg``). The rule places it beside the photos detected now as it would
    place a detected front photo."""

    view: str
    size: tuple  # the photo's (w, h) pixels
    yaw_deg: float

    @property
    def guess(self):
        return ViewGuess("front", self.yaw_deg)

    def turned_camera(self, guess):
        """As ``PhotoTask.turned_camera`` (its camera is the nominal one)."""
        return _turned_camera(guess, self.size)


@dataclasses.dataclass
class PhotoTask:
    """One photo to detect on: read from the scene, then what the detector found."""

    view: str
    photo: str  # the image's name, for messages
    kind: str  # "front", "right", "left"
    perspective: bool
    pixels: object
    hand: set
    detected: set
    face: object = None
    seconds: float = 0.0
    size: tuple = None  # the photo's (w, h) pixels, for a camera of its view
    nominal: bool = False  # its camera the nominal orthographic one (not known, not to compute)
    turned_yaw: float = None  # the yaw its known orthographic camera is turned to, if it is

    def agreeing_guess(self):
        """The face's ViewGuess where it agrees with the view (a front photo's named
        "front", as its plane is, whatever its yaw: a front or three-quarter face; on a
        profile photo a face from the view's side); else None."""
        guess = self.face.guess if self.face is not None else None
        if guess is None:
            return None
        if self.kind == "front":
            return None if guess.profile else dataclasses.replace(guess, name="front")
        return guess if guess.side == self.kind else None

    def turned_camera(self, guess):
        """The orthographic camera ``guess`` (the photo's, as ``DetectJob.placed`` places
        it) turns this photo's to (``ViewGuess.camera``: the camera ``solver detect``
        writes for it), or None: a camera not turned, a photo whose camera is not the
        nominal orthographic one (known, or to compute: it stays)."""
        return _turned_camera(guess, self.size) if self.nominal else None

    def lines(self, replace, turned=None):
        """(level, line) for the report: what was found (or that no face was), the yaw its
        camera is turned to (``turned``, degrees: by this detection, ``DetectJob.placed``,
        or before), and a face that contradicts the view the photo was loaded as (a
        three-quarter face on a front photo does not, once its camera is turned)."""
        where = f"view {self.view!r} ({self.photo})"
        if self.face is None:
            return [("WARNING", f"{where}: no face found")]
        place, _, kept = detection_plan(self.hand, self.detected, self.face.points, replace)
        what = self.face.guess.describe() if self.face.guess else "its direction unknown"
        line = f"{self.view}: {_count(len(place))}, {what}"
        if kept:
            line += f", {len(kept)} kept as placed by hand"
        if self.face.off_outline:
            line += " (a profile: read off its outline)"
        elif self.face.profile:
            line += (" (a profile without an outline found: only the nose tip, subnasale "
                     "and upper lip are detected; trace its outline for the rest)")
        for note in [] if self.face.found is None else face_notes(self.face.found):
            line += f"; {note}"
        if turned is not None:
            line += f"; its camera turned to {turned:+.0f} deg, as the photos show the face"
        out = [("INFO", line)]
        problem = photo_faces.loaded_as_problem(self.kind, self.perspective, self.face.guess)
        if problem and turned is None:
            out.append(("WARNING", f"{where}: {problem}"))
        return out


@dataclasses.dataclass
class PhotosJob(Progress):
    """Photos examined in any thread, several at once (``examine``: the detector only, no
    bpy; each photo its own task), the loop Detect Landmarks and Detect Outline share;
    errors are kept in ``error``, never raised."""

    tasks: list
    replace: bool = False
    error: BaseException = None
    cancelled: bool = False
    fraction: float = 0.0
    message: str = "starting"
    DOING = "examining"  # the progress line before each photo's name
    DONE = "done"  # the progress line after the last photo

    def examine(self, task):
        """Examine one photo's pixels (any thread), setting the task's findings; each
        job gives its own."""
        raise NotImplementedError

    def run(self):
        """Examine every photo, timing each (``task.seconds``): as many at once as the
        process may use cores (the detector's arrays let two photos run 1.5 x as fast as one
        after the other on two cores), the progress moving as each one ends."""
        pool = None
        try:
            photo_faces.detector()  # a missing model: one error before any photo
            n = len(self.tasks)
            self.progress(0.0, f"{self.DOING} {self.tasks[0].photo}" if n else self.DONE)
            pool = ThreadPoolExecutor(max(1, min(n, usable_cores())))
            running = [pool.submit(self._examine_timed, task) for task in self.tasks]
            for i, done in enumerate(running):
                done.result()
                if i + 1 < n:
                    self.progress((i + 1) / n, f"{self.DOING} {self.tasks[i + 1].photo}")
            self.progress(1.0, self.DONE)
        except BaseException as e:  # noqa: B036  (kept for the main thread to report)
            self.error = e
        finally:
            if pool is not None:  # a photo not begun yet is not begun after an error or Esc
                pool.shutdown(wait=True, cancel_futures=True)

    def _examine_timed(self, task):
        t = time.perf_counter()
        self.examine(task)
        task.seconds = time.perf_counter() - t


@dataclasses.dataclass
class DetectJob(PhotosJob):
    """The photos to detect the face on, read from the scene."""

    skipped: list = dataclasses.field(default_factory=list)
    #: A front photo not detected in this run whose camera an earlier detection turned to
    #: its face's yaw: the scene stands in the face's frame already.
    face_frame: bool = False
    #: Else a front photo not detected in this run whose landmarks show its yaw.
    placed_front: PlacedFront = None
    #: The views whose outline is traced with their face (Auto Fit's: a photo's outline
    #: found while the other photos' faces are, not after them all).
    outline_views: frozenset = frozenset()
    DOING = "detecting the face on"
    DONE = "placing the landmarks"

    def examine(self, task):
        task.face = photo_faces.find_face(task.pixels, task.view in self.outline_views)

    @property
    def found_any(self):
        return any(t.face is not None for t in self.tasks)

    def placed(self):
        """({view: ViewGuess}, turn) of the photos whose face agrees with their view, as
        ``solver detect`` places their cameras (the solver's ``placed``: in the face's
        frame, or the orthographic front photo's); ``turn``: whether their orthographic
        cameras may be turned, only with a front photo among them (detected now, or
        ``placed_front``: its guess is placed with theirs) or the scene in the face's
        frame already (``face_frame``: each camera then at its own yaw); else the frame is
        unknown: the yaws as measured, for the cameras to compute held near them."""
        tasks = [t for t in self.tasks if t.agreeing_guess() is not None]
        views = [t.view for t in tasks]
        guesses = [t.agreeing_guess() for t in tasks]
        orthographic = [not t.perspective for t in tasks]
        if not any(t.kind == "front" for t in tasks):
            if self.placed_front is None:
                return dict(zip(views, guesses, strict=True)), self.face_frame
            views.append(self.placed_front.view)
            guesses.append(self.placed_front.guess)
            orthographic.append(True)
        guesses = placed(guesses, orthographic)
        return dict(zip(views, guesses, strict=True)), True

    def camera_changes(self):
        """What the detection does to the cameras, as :meth:`placed` places them: one
        (view, yaw, turned, size) per photo it places, ``yaw`` the degrees a camera to
        compute is held near, ``turned`` the orthographic camera a nominal one turns to
        (or None), ``size`` the photo's pixels. ``apply_detection`` makes them in the
        scene, Auto Fit's merged case in its landmarks file."""
        guesses, turn = self.placed()
        out = [(t.view, guesses[t.view].yaw_deg,
                t.turned_camera(guesses[t.view]) if turn else None, t.size)
               for t in self.tasks if t.view in guesses]
        front = self.placed_front
        if turn and front is not None and front.view in guesses:
            out.append((front.view, guesses[front.view].yaw_deg,
                        front.turned_camera(guesses[front.view]), front.size))
        return out

    def lines(self):
        """(level, line) for the report, photo by photo, then the photos left out."""
        changes = {view: (yaw, turned) for view, yaw, turned, _ in self.camera_changes()}
        out = []
        for t in self.tasks:
            yaw, turned = changes.get(t.view, (None, None))
            out += t.lines(self.replace, yaw if turned is not None else t.turned_yaw)
        front = self.placed_front
        yaw, turned = changes.get(front.view, (None, None)) if front else (None, None)
        if turned is not None:
            out.append(("INFO", f"{front.view}: its camera turned to {yaw:+.0f} deg, as its "
                                "landmarks show the face"))
        return out + [("INFO", line) for line in self.skipped]


def photo_images(scene, view, doing):
    """(plane, view name, image or None when the plane has no readable photo) for one
    view's photo or for every photo, the photos the detection jobs read.

    Raises
    ------
    ValueError
        One line: no photo of that view (or that view's photo is not readable, saying
        it cannot ``doing``), or no photo at all.
    """
    if view:
        plane = photos.find_plane(scene, view)
        if plane is None:
            raise ValueError(f"No photo for view {view!r}")
        planes = [plane]
    else:
        planes = photos.photo_planes(scene)
        if not planes:
            raise ValueError("Load the photos first (Photos panel)")
    for plane in planes:
        img = plane.headrecon.image
        name = plane.headrecon.view
        if img is None or img.get(photos.PLACEHOLDER) or img.size[0] == 0:
            if view:
                raise ValueError(f"view {name!r}: no photo to {doing}")
            img = None
        yield plane, name, img


def prepare_detection(scene, view="", replace=False, skip_hand_placed=False, read=None):
    """Read the photos to detect on (main thread).

    Parameters
    ----------
    view : str
        One photo's view name; empty: every photo.
    replace : bool
        Hand-placed landmarks the detector finds are replaced too.
    skip_hand_placed : bool
        Leave out the photos with a landmark placed by hand (Auto Fit, unless ``replace``).
    read : dict, optional
        The photos' pixels read so far, shared with another job's preparation
        (``photos.detector_pixels``).

    Raises
    ------
    ValueError
        One line: no photo of that view, or the view has no photo to detect on.
    """
    tasks, skipped = [], []
    for plane, name, img in photo_images(scene, view, "detect the face on"):
        if img is None:
            skipped.append(f"{name}: no photo to detect on")
            continue
        hand = set(landmarks.hand_placed_landmarks(plane))
        if skip_hand_placed and hand and not replace:
            skipped.append(f"{name}: kept as placed by hand ({_count(len(hand))})")
            continue
        tasks.append(PhotoTask(name, img.name, photos.view_kind(plane),
                               photos.is_perspective(plane),
                               photos.detector_pixels(img, read), hand,
                               set(landmarks.detected_landmarks(plane)),
                               size=photos.plane_size(plane)[0],
                               nominal=photos.has_nominal_camera(plane),
                               turned_yaw=photos.turned_yaw(plane)))
    detected = {t.view for t in tasks}
    others = [p for p in photos.photo_planes(scene) if p.headrecon.view not in detected]
    face_frame = any(photos.view_kind(p) == "front" and photos.turned_yaw(p) is not None
                     for p in others)
    front = None
    if not face_frame and any(t.kind != "front" for t in tasks):
        front = next(filter(None, map(front_from_landmarks, others)), None)
    return DetectJob(tasks, replace=replace, skipped=skipped, face_frame=face_frame,
                     placed_front=front)


def front_from_landmarks(plane):
    """A ``PlacedFront`` of a front photo on the nominal orthographic camera whose landmarks
    show its yaw, or None (also without the head model: the detection needs none)."""
    if photos.view_kind(plane) != "front" or not photos.has_nominal_camera(plane):
        return None
    points = landmarks.landmark_pixels(plane)
    if len(points) < POINTS_YAW_MIN:
        return None
    try:
        yaw = points_yaw_deg(load_model(), points)
    except FileNotFoundError:
        return None
    return None if yaw is None else PlacedFront(plane.headrecon.view,
                                                photos.plane_size(plane)[0], yaw)


def apply_detection(scene, job):
    """Place what the job found (main thread): each photo's landmarks as
    ``detection_plan`` says; each camera as ``DetectJob.camera_changes`` says (a camera to
    compute held near its yaw, a nominal orthographic one turned where the rule turns
    it). Returns the landmarks placed."""
    n = 0
    for task in job.tasks:
        plane = photos.find_plane(scene, task.view)
        if task.face is None or plane is None:
            continue
        hand = landmarks.hand_placed_landmarks(plane)
        detected = landmarks.detected_landmarks(plane)
        place, remove, _ = detection_plan(hand, detected, task.face.points, job.replace)
        for name in place:
            landmarks.place_detected(plane, name, task.face.points[name],
                                     task.face.uncertainty.get(name),
                                     task.face.depth.get(name))
        photos.remove_objects([detected[name] for name in remove])
        n += len(place)
    for view, yaw, turned, _ in job.camera_changes():
        plane = photos.find_plane(scene, view)
        if plane is None:
            continue
        photos.hold_camera_near(plane, yaw)
        if turned is not None:
            photos.turn_nominal_camera(plane, turned, photos.head_centre(scene))
    return n


def run_detection(scene, view="", replace=False):
    """Detect and place at once (background mode, scripts, tests).

    Returns
    -------
    DetectJob
        Its ``lines()`` are the report.

    Raises
    ------
    ValueError
        As ``prepare_detection``; a missing detector model; no face on any photo (one line
        per photo): the scene is unchanged then.
    """
    job = prepare_detection(scene, view, replace)
    job.run()
    if job.error is not None:
        raise job.error
    if not job.found_any:
        raise ValueError("; ".join(line for _, line in job.lines()))
    apply_detection(scene, job)
    return job

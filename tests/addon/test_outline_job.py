"""Detect Outline on the rendered sample's profile (bpy module, background): the contour
drawn on the true silhouette and marked as detected; a contour traced by hand stays
unless replaced; a photo without a person is one line and changes nothing; Auto Fit
fits with the outlines it found."""

import json
import threading

import bpy
import numpy as np
import pytest
from PIL import Image

from solver import usable_cores
from solver.paths import DETECTOR_DIR
from tests.addon.support import empty_scene


@pytest.fixture(autouse=True)
def _models():
    if not (DETECTOR_DIR / "selfie_segmentation.tflite").is_file():
        pytest.skip(f"detector models missing in {DETECTOR_DIR}: run ./run detector")


def _load(path, view, direction):
    assert bpy.ops.headrecon.load_photo(filepath=str(path), view=view,
                                        camera_view=direction) == {"FINISHED"}
    from headrecon_addon import photos

    return photos.find_plane(bpy.context.scene, view)


def test_detect_outline_draws_the_profile_on_its_silhouette(sample):
    from headrecon_addon import landmarks

    folder, _ = sample
    empty_scene()
    plane = _load(folder / "side.png", "side", "orthographic-right")
    assert bpy.ops.headrecon.detect_outline(view="side") == {"FINISHED"}
    drawn = landmarks.contour_pixels(plane)
    truth = np.asarray(json.loads((folder / "sample.json").read_text())
                       ["views"]["side"]["contour"])
    a, b = truth[:-1], truth[1:]
    t = np.clip(((drawn[:, None] - a) * (b - a)).sum(2) / ((b - a) ** 2).sum(1), 0, 1)
    d = np.linalg.norm(drawn[:, None] - (a + t[..., None] * (b - a)), axis=2).min(1)
    assert len(drawn) > 100 and np.median(d) < 1.0
    assert landmarks.contour_is_detected(plane)
    # detected again: replaced; once edited by hand, kept unless asked
    assert bpy.ops.headrecon.detect_outline(view="side") == {"FINISHED"}
    landmarks.set_contour(plane, drawn[:50])
    assert not landmarks.contour_is_detected(plane)
    assert bpy.ops.headrecon.detect_outline(view="side") == {"FINISHED"}
    assert len(landmarks.contour_pixels(plane)) == 50
    assert bpy.ops.headrecon.detect_outline(view="side", replace_hand_placed=True) \
        == {"FINISHED"}
    assert len(landmarks.contour_pixels(plane)) == len(drawn)


def test_a_photo_without_a_person_is_one_line_and_changes_nothing(tmp_path):
    from headrecon_addon import landmarks

    empty_scene()
    wall = tmp_path / "wall.png"
    Image.new("RGB", (300, 400), (120, 120, 120)).save(wall)
    plane = _load(wall, "side", "orthographic-right")
    with pytest.raises(RuntimeError, match=r"view 'side' \(wall\.png\): no face found"):
        bpy.ops.headrecon.detect_outline(view="side")
    assert landmarks.contour_object(plane) is None


def test_auto_fit_fits_with_the_detected_outlines(sample):
    from headrecon_addon import auto_fit_job, landmarks, photos

    folder, _ = sample
    empty_scene()
    assert bpy.ops.headrecon.add_head() == {"FINISHED"}
    _load(folder / "front.png", "front", "orthographic-front")
    side = _load(folder / "side.png", "side", "orthographic-right")
    scene = bpy.context.scene
    scene.headrecon.bake_texture = False
    job = auto_fit_job.prepare_auto_fit(scene)
    job.run()
    assert job.error is None, job.error
    assert job.fit.case.views["side"].contour is not None
    assert any("side: outline of" in line for _, line in job.lines())
    auto_fit_job.apply_auto_fit(scene, job)
    assert landmarks.contour_is_detected(side)
    assert photos.find_plane(scene, "front") is not None


def test_an_outline_s_warnings_are_lines_of_the_report_naming_the_photo():
    from headrecon_addon.outline_job import OutlineTask

    task = OutlineTask("side", "side.png", None, False, False, points=np.zeros((40, 2)),
                       notes=["starts at the photo's border", "ends at hair"],
                       warnings=["the outline ran along a straight edge beside the face"])
    (level, line), (warn, said) = task.lines(replace=False)
    assert level == "INFO" and "side: outline of 40 points" in line
    assert warn == "WARNING" and said == ("view 'side' (side.png): the outline ran along a "
                                          "straight edge beside the face")
    task.warnings = []
    assert len(task.lines(replace=False)) == 1


def test_the_job_examines_each_photo_and_stops_when_cancelled():
    """The loop Detect Landmarks and Detect Outline share (``detect_job.PhotosJob``): a
    photo without a face is its task's problem, each photo is timed, and a cancelled job
    examines nothing and keeps why it stopped."""
    from headrecon_addon.detect_job import DetectJob, PhotoTask
    from headrecon_addon.job_progress import JobCancelled
    from headrecon_addon.outline_job import OutlineJob, OutlineTask

    blank = np.full((96, 96, 3), 128, np.uint8)
    job = OutlineJob([OutlineTask("front", "blank.png", blank, False, False)])
    job.run()
    task = job.tasks[0]
    assert job.error is None and not job.found_any and task.points is None
    assert task.problem.startswith("no face found") and task.seconds > 0
    assert (job.fraction, job.message) == (1.0, "drawing the outlines")
    stopped = OutlineJob([OutlineTask("front", "blank.png", blank, False, False)],
                         cancelled=True)
    stopped.run()
    assert isinstance(stopped.error, JobCancelled) and stopped.tasks[0].problem is None
    detect = DetectJob([PhotoTask("front", "blank.png", "front", False, blank, set(),
                                  set())])
    detect.run()
    assert detect.error is None and detect.tasks[0].face is None
    assert detect.message == "placing the landmarks" and detect.lines()[0][0] == "WARNING"


@pytest.mark.skipif(usable_cores() < 2, reason="one core: photos examined in turn")
def test_the_job_examines_photos_at_once(monkeypatch):
    """Two photos are examined at the same time (each waits for the other at a barrier,
    which photos examined in turn never pass), each task keeps its own findings, and the
    progress ends as one photo after the other would."""
    from headrecon_addon.outline_job import OutlineJob, OutlineTask

    meet = threading.Barrier(2, timeout=20)

    def examine(self, task):
        meet.wait()
        task.points = np.full((3, 2), float(task.pixels[0, 0, 0]))

    monkeypatch.setattr(OutlineJob, "examine", examine)
    tasks = [OutlineTask(v, f"{v}.png", np.full((4, 4, 3), i, np.uint8), False, False)
             for i, v in enumerate(("front", "side"))]
    job = OutlineJob(tasks)
    job.run()
    assert job.error is None
    assert [float(t.points[0, 0]) for t in job.tasks] == [0.0, 1.0]
    assert all(t.seconds > 0 for t in job.tasks)
    assert (job.fraction, job.message) == (1.0, "drawing the outlines")

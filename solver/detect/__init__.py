"""Automatic landmarks: MediaPipe's face detection and face mesh models (Apache-2.0,
taken from the mediapipe wheel by ``tools/fetch_detector.py``) run by a small numpy
implementation of the TensorFlow Lite operators they use, and the mesh mapped to the
project's iBUG-68 landmark names."""

from .detector import DetectedFace, Detector
from .ibug_map import mesh_to_ibug

__all__ = ["DetectedFace", "Detector", "mesh_to_ibug"]

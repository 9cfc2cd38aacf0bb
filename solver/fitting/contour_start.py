"""Where a photo that carries only a traced outline starts: its orthographic camera found
from the outline alone, the head's profile line laid onto the traced one, so a profile
photo in which nothing but the silhouette was found (or traced) still counts; the fit's
profile stage then refines the camera with the shape."""

import numpy as np
from scipy.spatial import cKDTree

from ..cameras import OrthographicCamera

#: Starts tried: the fraction of the head's profile line (top of the skull to the neck) the
#: traced outline's height spans; the one that lays the line best onto the outline wins.
COVERAGE = (0.35, 0.45, 0.55, 0.65, 0.8, 1.0)
#: ICP steps per start.
ITERATIONS = 25


def camera_from_outline(camera, contour, chain):
    """An orthographic camera with the viewing direction of ``camera`` that lays the head's
    profile line onto a traced outline: 2-D similarity ICP (each outline point to the
    nearest projected line point, pairs farther than three times the median left out), from
    a start per ``COVERAGE`` with the most forward points (the nose) on each other.

    Parameters
    ----------
    camera : OrthographicCamera
        The photo's camera so far (its viewing direction and image size are kept).
    contour : ndarray, shape (k, 2), pixels
    chain : ndarray, shape (m, 3), metres
        The head's profile line in the world (``HeadModel.profile_chain`` of the current
        head).

    Returns
    -------
    camera : OrthographicCamera
    rms_px : float
        RMS distance of the outline's points from the projected line.
    """
    contour = np.asarray(contour, dtype=np.float64).reshape(-1, 2)
    chain = np.asarray(chain, dtype=np.float64).reshape(-1, 3)
    a = chain @ camera.rotation[:2].T  # the line in the image plane, metres
    forward = camera.rotation[:2] @ np.array([0.0, -1.0, 0.0])
    tip_c = contour[np.argmax(contour @ forward)]
    tip_a = a[np.argmax(a @ forward)]
    height = max(float(np.ptp(a[:, 1])), 1e-6)
    best = None
    for f in COVERAGE:
        scale = float(np.ptp(contour[:, 1])) / (f * height)
        if not scale > 0:
            continue
        cam = OrthographicCamera(camera.rotation, scale, tip_c - scale * tip_a, camera.size,
                                 camera.view)
        for _ in range(ITERATIONS):
            d, j = cKDTree(cam.project(chain)).query(contour)
            keep = d <= max(3.0 * float(np.median(d)), 2.0)
            try:
                new = cam.refit(chain[j[keep]], contour[keep])
            except ValueError:
                break
            settled = abs(new.scale / cam.scale - 1.0) < 1e-6 and np.allclose(
                new.offset, cam.offset, atol=1e-3)
            cam = new
            if settled:
                break
        d = cKDTree(cam.project(chain)).query(contour)[0]
        rms = float(np.sqrt(np.mean(d**2)))
        if best is None or rms < best[1]:
            best = (cam, rms)
    if best is None:
        raise ValueError("outline: it has no height to lay the head's profile onto")
    return best

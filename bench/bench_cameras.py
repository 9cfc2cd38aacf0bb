"""Timings of the DLT camera code: calibration, projection + Jacobian over a whole head,
triangulation, passpoint checking, mirror estimation. Prints numbers; asserts nothing.

    python -m bench.bench_cameras
"""

import numpy as np

from bench.common import machine_description, median_time
from solver import DLTCamera, PinholeCamera, check_passpoints, fit_dlt
from solver.cameras.mirror import MirrorPlane, estimate_mirror
from solver.cameras.triangulate import triangulate

SIZE = (1920, 1080)
F_PX = 1500.0  # focal length, pixels (principal point at the image centre)
DIST = np.array([-4e-8, 2e-14, -3e-21, 1.5e-6, -1e-6])


def camera(centre, target=(0.0, 0.0, 0.0)):
    """A full-HD DLT camera at ``centre`` looking at ``target``."""
    return PinholeCamera.look_at(centre, target, SIZE, f_px=F_PX).to_dlt()


def timed(label, fn, repeat=5):
    """Run ``fn`` once untimed, then ``repeat`` times; print the median; return its result."""
    t = median_time(fn, repeat)
    print(f"{label:<58s} {t.median * 1e3:9.2f} ms")
    return t.result


def main():
    rng = np.random.default_rng(0)
    centres = ([0.0, -1.0, 0.05], [0.8, -0.7, 0.1], [-0.7, -0.8, 0.3])
    cams = [camera(c) for c in centres]
    lens = DLTCamera(cams[0].matrix, SIZE, DIST)
    marks = rng.uniform([-0.07, -0.1, -0.11], [0.07, 0.02, 0.11], (68, 3))
    px = cams[0].project(marks) + rng.normal(0, 0.5, (68, 2))
    pxd = lens.project(marks) + rng.normal(0, 0.5, (68, 2))
    head = rng.uniform(-0.12, 0.12, (26719, 3))

    print(f"machine: {machine_description()}")
    print("DLT cameras (numpy/scipy), 1920x1080; median of 5 runs after one warm-up")
    timed("fit_dlt 11 parameters, 68 passpoints", lambda: fit_dlt(marks, px, SIZE))
    f16 = timed("fit_dlt 16 parameters, 68 passpoints",
                lambda: fit_dlt(marks, pxd, SIZE, n_params=16))
    print(f"    DLT-16 on a head-sized patch, 0.5 px noise: {f16.iterations} iterations, "
          f"{f16.n_params} parameters kept, rms {f16.rms:.3f} px, condition "
          f"{f16.condition:.0f} (unscaled {f16.condition_unscaled:.3g})")
    if f16.fell_back:
        print(f"    fell back: {f16.reason}")
    timed("project 26719 points (DLT-11)", lambda: cams[0].project(head))
    timed("jacobian 26719 points (DLT-11)", lambda: cams[0].jacobian(head))
    timed("project 26719 points (DLT-16, Newton)", lambda: lens.project(head))
    timed("jacobian 26719 points (DLT-16)", lambda: lens.jacobian(head))
    pts = rng.uniform(-0.1, 0.1, (10000, 3))
    obs = np.stack([c.project(pts) for c in cams]) + rng.normal(0, 0.5, (3, 10000, 2))
    tri = timed("triangulate 10000 points from 3 views", lambda: triangulate(cams, obs))
    err = np.linalg.norm(tri.points - pts, axis=1)
    print(f"    0.5 px noise: 3-D error rms {np.sqrt((err**2).mean()) * 1e3:.3f} mm, "
          f"median ray gap {np.median(tri.ray_gap) * 1e3:.3f} mm")
    views = {f"v{j}": c.project(marks) + rng.normal(0, 0.5, (68, 2)) for j, c in enumerate(cams)}
    views["v1"][10] += [12.0, 16.0]
    chk = timed("check_passpoints 68 passpoints x 3 views (leave-one-out)",
                lambda: check_passpoints(marks, views), repeat=2)
    print(f"    flagged: {[(s.view, s.name) for s in chk.suspects]}")
    plane = MirrorPlane.from_point_normal([0.35, 0.05, 0.0], [-1.0, -0.6, 0.1])
    cam = camera(centres[0], [0.25, 0.1, 0.0])
    d = cam.project(marks) + rng.normal(0, 0.3, (68, 2))
    m = cam.project(plane.reflect_points(marks)) + rng.normal(0, 0.3, (68, 2))
    fit = timed("estimate_mirror 68 landmark pairs",
                lambda: estimate_mirror(cam, d, m, point_on_mirror=[0.35, 0.05, 0.0]))
    ang = np.degrees(np.arccos(np.clip(fit.plane.normal @ plane.normal, -1, 1)))
    print(f"    0.3 px noise: normal off by {ang:.3f} deg, median gap "
          f"{np.median(fit.gaps) * 1e3:.2f} mm")


if __name__ == "__main__":
    main()

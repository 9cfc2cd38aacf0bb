"""Iso-lines by marching squares: sub-pixel positions, closed and oriented lines."""

import numpy as np

from solver.detect.iso_line import iso_lines, polygon_area


def test_a_disc_gives_one_closed_line_on_its_circle_running_clockwise():
    yy, xx = np.mgrid[0:100, 0:120]
    values = 30 - np.hypot(xx - 50.3, yy - 40.7)
    (line,) = iso_lines(values, 0.0)
    radius = np.hypot(line[:, 0] - 50.3, line[:, 1] - 40.7)
    assert np.abs(radius - 30).max() < 0.01
    assert abs(polygon_area(line) - np.pi * 900) < 0.001 * np.pi * 900
    tangent = np.roll(line, -1, 0) - np.roll(line, 1, 0)
    outward = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    assert (((line - [50.3, 40.7]) * outward).sum(1) > 0).all()


def test_separate_regions_and_the_grid_edge_longest_first():
    m = np.zeros((40, 50))
    m[10:30, 5:45] = 1        # a block
    m[0:4, 0:6] = 1           # a corner block touching the grid's edge: closed outside it
    m[15:20, 20:25] = 0       # a hole: a line of its own
    lines = iso_lines(m)
    assert [len(line) for line in lines] == sorted((len(line) for line in lines), reverse=True)
    assert len(lines) == 3
    block = lines[0]
    assert block[:, 0].min() == 4.5 and block[:, 0].max() == 44.5
    assert block[:, 1].min() == 9.5 and block[:, 1].max() == 29.5
    corner = next(line for line in lines if line[:, 0].min() < 0)
    assert corner[:, 0].min() == -0.5 and corner[:, 1].min() == -0.5
    assert all(polygon_area(line) > 0 for line in lines)
    assert iso_lines(np.zeros((5, 5))) == []

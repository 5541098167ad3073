"""studies/spatial_path_deviation.py's distance to the task's polyline against closed forms."""

import numpy as np

from studies.spatial_path_deviation import distance_to_polyline_m

PTS = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 2.0, 0.0]])


def test_distance_to_the_polyline():
    assert distance_to_polyline_m(np.array([0.5, 0.0, 0.0]), PTS) == 0.0  # on the first segment
    assert np.isclose(distance_to_polyline_m(np.array([0.5, 0.0, 0.3]), PTS), 0.3)  # above it
    assert np.isclose(distance_to_polyline_m(np.array([1.4, 1.0, 0.0]), PTS), 0.4)  # beside the second
    assert np.isclose(distance_to_polyline_m(np.array([-3.0, -4.0, 0.0]), PTS), 5.0)  # past the first end

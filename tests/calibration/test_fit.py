"""stcvision.calibration.fit.fit_profile recovers a known mirror model from exact correspondences."""

import numpy as np

from stcvision.calibration.fit import FitSetup, fit_profile
from stcvision.calibration.profiles import default_profile


def _grid_points(prof):
    """Floor points 0.2-0.8 m around the robot, and where the profile sees them."""
    r, a = np.meshgrid(np.linspace(0.2, 0.8, 7), np.linspace(-np.pi, np.pi, 24, endpoint=False))
    xy = np.column_stack([(r * np.cos(a)).ravel(), (r * np.sin(a)).ravel()])
    return prof.robot_to_image(xy), xy


def test_points_fit_recovers_the_shipped_profile_within_a_millimetre():
    """From the shipped profile's own projections of 168 floor points, a fit started at the
    image centre maps every point back within 1 mm and finds the same flip and forward angle."""
    truth = default_profile()
    uv, xy = _grid_points(truth)
    setup = FitSetup(
        image_size_px=truth.image_size_px,
        rim_radius_px=truth.rim_radius_px,
        viewpoint_height_m=truth.viewpoint_height_m,
    )
    prof, rep = fit_profile(uv, xy, setup)
    assert prof.mirrored == truth.mirrored
    assert abs(np.angle(np.exp(1j * (prof.forward_angle_rad - truth.forward_angle_rad)))) < np.radians(0.1)
    assert rep.n_points == len(xy) and rep.inliers == len(xy)
    assert rep.floor_err_m_max < 1e-3, rep


def test_lines_only_fit_keeps_a_profile_that_already_fits():
    """Points on the floor lines x = 0.32 m and y = -0.16 m, seen through the shipped profile and
    fitted from that profile, stay within 0.5 mm of their lines."""
    truth = default_profile()
    t = np.linspace(-0.6, 0.6, 60)
    line_x = np.column_stack([np.full_like(t, 0.32), t])
    line_y = np.column_stack([t, np.full_like(t, -0.16)])
    uv = truth.robot_to_image(np.vstack([line_x, line_y]))
    axis = np.r_[np.zeros(len(t), int), np.ones(len(t), int)]
    off = np.r_[np.full(len(t), 0.32), np.full(len(t), -0.16)]
    setup = FitSetup(
        image_size_px=truth.image_size_px,
        rim_radius_px=truth.rim_radius_px,
        viewpoint_height_m=truth.viewpoint_height_m,
    )
    empty = np.zeros((0, 2))
    _, rep = fit_profile(empty, empty, setup, lines=(uv, axis, off), base=truth, init=truth)
    assert rep.n_points == 0 and rep.floor_err_m_max < 5e-4, rep

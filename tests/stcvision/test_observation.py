"""The five-box geometry: every mark position maps to the box of the five-box table
(docs/explanation/stc-geometry.md)."""

import numpy as np
import pytest

from stcvision.observation import BOXES, assign_boxes, row_orientation
from stcvision.profile import CORNER_ORDER

INSET = 0.125  # 2 cm of a 16 cm sub-cell
OFFS = np.array([-0.281, -0.094, 0.094, 0.281])  # LED offsets along the edge (D units)
SIGNS = {0: (1, -1), 1: (1, 1), 2: (-1, 1), 3: (-1, -1)}


def _mark(k, edge):
    c = 0.5 * np.array(SIGNS[k], float)
    e = np.array(edge, float)
    t = np.array([-e[1], e[0]])
    return c + e * (0.5 - INSET) + OFFS[:, None] * t


@pytest.mark.parametrize("k", range(4))
@pytest.mark.parametrize("edge", [(1, 0), (0, 1), (-1, 0), (0, -1)])
def test_every_mark_position_gets_its_box(k, edge):
    dots = _mark(k, edge)
    sub, box, _ = assign_boxes(dots)
    assert (sub == k).all()
    want = next((b for b, (kk, e) in BOXES.items() if kk == k and tuple(e) == edge), 0)
    start = {1: (0, 1), 2: (-1, 0), 3: (0, -1)}  # the STC start mark: sub-cell m, exterior edge m
    if start.get(k) == edge:
        want = -k
    assert (box == want).all()


def test_corner_neighbours_keep_their_own_rows():
    """Box 1 and box 5 rows meet at sub-cell 1's lower-right corner: their end dots are
    closer to each other than to their row-mates, yet each keeps its box."""
    dots = np.vstack([_mark(1, (1, 0)), _mark(1, (0, -1))])
    assert row_orientation(dots).tolist() == [1] * 4 + [0] * 4
    _, box, _ = assign_boxes(dots)
    assert box.tolist() == [1] * 4 + [5] * 4
    # shifted by a robot position error of 6 mm in both directions
    _, box, _ = assign_boxes(dots + 0.0375)
    assert box.tolist() == [1] * 4 + [5] * 4


def test_neighbour_marks_outside_the_shared_edge_belong_to_the_neighbour():
    # the forward neighbour's mark along its bottom edge: 2 cm beyond our top edge
    dots = np.array([[x, 1 + INSET] for x in (-0.6, -0.4, -0.2, 0.0)])
    sub, box, nb = assign_boxes(dots)
    assert (sub == -1).all() and (box == 0).all() and (nb == 1).all()


def test_corner_order_is_the_plus_outline_counter_clockwise():
    pts = np.array(CORNER_ORDER, float)
    area = 0.5 * np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
    assert area == pytest.approx(20.0)  # five 2x2 cells, counter-clockwise (positive)


def test_red_lights_give_the_robots_offset_and_residual_heading(default_profile):
    """Red lights stand at cell centres: with two or more well in view the observation says
    where the robot stands off its sub-cell centre and how far the heading fit is still off."""
    from stcvision.observation import ObservationParams
    from stcvision.pipeline import Pipeline, PipelineParams
    from stcvision.sim_camera.camera import SyntheticCamera
    from stcvision.sim_camera.scenarios import cell_scene

    cam = SyntheticCamera()
    rng = np.random.default_rng(5)
    pipe = Pipeline(default_profile, PipelineParams(observation=ObservationParams(pose_estimates=True)))
    pipe.set_dark(cam.median_dark(8, rng=rng))
    checked = 0
    for _ in range(16):
        sc = cell_scene(rng, obstacle_fraction=0.35, position_error_m=0.01, heading_error_deg=(-2, 2))
        res = pipe.process(
            cam.render(sc.pose, rng=rng, t_s=sc.t_s, phosphor=sc.phosphor, red_lights_m=sc.red_lights_m).image
        )
        o = res.observation
        if o.landmark_offset is None:
            assert o.landmark_rotation_rad is None
            continue
        heading = round(sc.pose.heading_rad / (np.pi / 2)) * np.pi / 2
        herr = (sc.pose.heading_rad - heading + np.pi) % (2 * np.pi) - np.pi
        up = np.array([np.cos(heading), np.sin(heading)])
        right = np.array([up[1], -up[0]])
        xy = np.array([sc.pose.x_m, sc.pose.y_m])
        d = (xy - sc.board.subcell_center_m(*sc.board.subcell_at(xy))) / sc.board.subcell_m
        # within 0.04 sub-cell sides (6.4 mm) of the truth
        assert np.allclose(o.landmark_offset, (d @ right, d @ up), atol=0.04), (o.landmark_offset, d)
        # what is left of the heading after the newest row's fit, within 0.25 degrees
        left = res.heading.heading_error_rad - herr
        assert abs(np.degrees(o.landmark_rotation_rad - left)) < 0.25
        checked += 1
    assert checked >= 4


def test_far_red_lights_pin_the_robot_down_in_open_floor(default_profile):
    """On a 10x10 board with few obstacles, lights within 0.4 m are rare; out to 1.25 m (the
    wide red view, refined on the mirror image, each light weighted by its error ellipse) every
    frame has two or more, and the fit stays within a few millimetres of the truth (measured on
    these frames: 24 of 24 with a fix against 2 of 24 with near lights only; median 0.8 mm, max
    2.6 mm; the heading left after the newest row's fit within 0.17 degrees)."""
    from stcvision.observation import ObservationParams
    from stcvision.pipeline import Pipeline, PipelineParams
    from stcvision.sim_camera.camera import SyntheticCamera
    from stcvision.sim_camera.scenarios import cell_scene

    cam = SyntheticCamera()
    rng = np.random.default_rng(5)
    dark = cam.median_dark(8, rng=rng)
    near = Pipeline(
        default_profile, PipelineParams(observation=ObservationParams(pose_estimates=True, landmark_range_m=0))
    )
    far = Pipeline(default_profile, PipelineParams(observation=ObservationParams(pose_estimates=True)), dark=dark)
    near.set_dark(dark)
    n_near = n_far = 0
    errs = []
    for _ in range(24):
        sc = cell_scene(rng, cells=(10, 10), obstacle_fraction=0.1, position_error_m=0.01, heading_error_deg=(-2, 2))
        img = cam.render(sc.pose, rng=rng, t_s=sc.t_s, phosphor=sc.phosphor, red_lights_m=sc.red_lights_m).image
        n_near += near.process(img).observation.landmark_offset is not None
        res = far.process(img)
        o = res.observation
        if o.landmark_offset is None:
            continue
        n_far += 1
        heading = round(sc.pose.heading_rad / (np.pi / 2)) * np.pi / 2
        up = np.array([np.cos(heading), np.sin(heading)])
        right = np.array([up[1], -up[0]])
        xy = np.array([sc.pose.x_m, sc.pose.y_m])
        d = (xy - sc.board.subcell_center_m(*sc.board.subcell_at(xy))) / sc.board.subcell_m
        errs.append(1000 * sc.board.subcell_m * np.hypot(*(np.array(o.landmark_offset) - (d @ right, d @ up))))
        if res.heading.ok:  # what is left of the heading after the newest row's fit
            herr = (sc.pose.heading_rad - heading + np.pi) % (2 * np.pi) - np.pi
            assert abs(np.degrees(o.landmark_rotation_rad - (res.heading.heading_error_rad - herr))) < 0.25
    assert n_far >= 22 and n_far >= 3 * max(n_near, 1), (n_near, n_far)
    assert np.median(errs) < 1.5 and max(errs) < 5.0, errs


def test_homography_kernel_is_numpy_product(default_profile):
    """CellGeometry.to_cell's compiled product (homography, N >= 2) against numpy's
    ``[p, 1] @ H.T`` then division, bit for bit on this machine; N = 1 keeps numpy's own path."""
    from stcvision.observation import CellGeometry, homography

    g = CellGeometry.from_profile(default_profile)
    rng = np.random.default_rng(6)
    for n in (1, 2, 3, 68, 5000):
        p = rng.uniform(-10, 310, (n, 2))
        q = np.column_stack([p, np.ones(n)]) @ g.H.T
        ref = q[:, :2] / q[:, 2:3]
        assert np.array_equal(g.to_cell(p), ref)
        if n >= 2:
            assert np.array_equal(homography(g.H, p), ref)


def test_the_marks_offset_says_which_axes_its_rows_measured():
    """Rows along 'up' only (varying in u) measure the offset to the right and nothing up: the
    observation reads 0 up (the boxes are read unshifted there) and says that axis was not
    measured, so a localisation does not take that 0 for a reading. An offset the caller gives
    is no reading of the marks at all."""
    from types import SimpleNamespace

    from stcvision.observation import MARK_INSET, ObservationParams, _cell_dots

    class Dots(SimpleNamespace):
        def __len__(self):
            return len(self.xy_px)

    flat = SimpleNamespace(to_cell=lambda xy: np.asarray(xy, float))
    d = 0.02  # the robot 0.02 sub-cell left of its centre: the rows lie that much right
    pts = [(1 - MARK_INSET + d, u) for u in (0.2, 0.4, 0.6, 0.8)]
    pts += [(-1 + MARK_INSET + d, -u) for u in (0.2, 0.4, 0.6, 0.8)]
    dots = Dots(xy_px=np.array(pts), lit=np.ones(len(pts), bool))
    _, orient, offset, axes = _cell_dots(dots, flat, 0.0, ObservationParams(), None)
    assert (orient == 1).all() and axes == (True, False)
    assert offset == pytest.approx((-d, 0.0))
    _, _, offset, axes = _cell_dots(dots, flat, 0.0, ObservationParams(), (0.01, 0.02))
    assert offset == (0.01, 0.02) and axes == (False, False)


#: the seven red lights of a short frame (cell units, rotated by the heading fit; the robot at
#: ROBOT_IN_CELL) and the cell centres they were assigned, at spiral_stc_test_2, cooled, seed
#: 918, t = 5,289 s: the light at (6.525, 0.091) lies 8.5 cm off its centre (5.6 sigma along
#: its ray); fitted with it, the robot's offset came out 0.9 cm from the truth
_LIGHTS_918 = [(5.906, -5.837), (5.944, -3.878), (6.005, -1.909), (7.898, -1.894), (6.525, 0.091), (6.002, 2.085),
               (5.956, 4.05)]  # fmt: skip
_CENTRES_918 = [(6, -6), (6, -4), (6, -2), (8, -2), (6, 0), (6, 2), (6, 4)]


def test_a_red_light_far_off_its_cell_centre_is_left_out_of_the_fit():
    """Synthetic lights at their cell centres, seen from a robot turned 0.3 degrees and 0.05 of a
    sub-cell off, one of them moved as the recorded one (0.5 sub-cells along its ray, 0.09
    across): the fit leaves that one out and recovers the pose (0.005 sub-cells, 0.8 mm; 0.05
    degrees); with it, it would be over 0.03 off. On the recorded frame the fit equals the one
    without the far-off light."""
    from scipy import stats

    from stcvision.localisation import LIGHT_OUTLIER_CHI2, landmark_fit, landmark_wls, rotate_about_robot
    from stcvision.profile import ROBOT_IN_CELL

    assert LIGHT_OUTLIER_CHI2 == pytest.approx(stats.chi2.ppf(0.999, 2))
    exp = np.array(_CENTRES_918, float)
    th, off = np.radians(0.3), np.array([0.05, -0.03])
    obs = rotate_about_robot(exp - off, th)  # exp = R(-th) (obs - robot) + robot + off
    rng = np.random.default_rng(5)
    obs = obs + rng.normal(0, 0.003, obs.shape)
    ray = (obs[4] - ROBOT_IN_CELL) / np.hypot(*(obs[4] - ROBOT_IN_CELL))
    bad = obs.copy()
    bad[4] = obs[4] + 0.5 * ray + 0.09 * np.array([-ray[1], ray[0]])  # as recorded: 0.5 along, 0.09 across
    got_th, got_off, _, _ = landmark_fit(bad, exp, 0.16)
    assert np.allclose(got_off, off, atol=0.005) and got_th == pytest.approx(th, abs=np.radians(0.05))
    naive = landmark_wls(bad, exp, 0.16)
    assert np.hypot(*(naive[1] - off)) > 0.03  # what the fit would have been
    # the recorded frame: the same as the fit without the light at (6.525, 0.091)
    rec, cen = np.array(_LIGHTS_918), np.array(_CENTRES_918, float)
    kept = np.arange(len(rec)) != 4
    assert np.allclose(landmark_fit(rec, cen, 0.16)[1], landmark_fit(rec[kept], cen[kept], 0.16)[1])

"""Camera speed without changing a frame: a camera that reuses the last frame's
projection gives exactly the frames and ground truth a fresh camera gives and notices when the
sources move; the fast noise draw is numpy's own."""

import json

import numpy as np

from stcvision.sim_camera.camera import Pose
from stcvision.sim_camera.scene import EXAMPLE_SCENE, Scene


def _render(cam, scene, pose, seed, t_s, **kw):
    return cam.render(
        pose,
        rng=np.random.default_rng(seed),
        t_s=t_s,
        phosphor=scene.phosphor,
        red_lights_m=scene.red_lights_m,
        board=scene.board,
        truth=True,
        **kw,
    )


def _fresh(ref, scene, pose, seed, t_s, **kw):
    """``ref``'s frame as a camera that has not just seen these positions renders it."""
    away = Pose(pose.x_m + 5.0, pose.y_m, pose.heading_rad)
    _render(ref, scene, away, 0, t_s)
    return _render(ref, scene, pose, seed, t_s, **kw)


def test_reused_projection_gives_a_fresh_cameras_frames():
    scene = Scene.from_dict(EXAMPLE_SCENE)
    used, ref = scene.camera(), scene.camera()
    p1 = scene.pose
    p2 = Pose(p1.x_m + 0.02, p1.y_m - 0.01, p1.heading_rad + 0.1)
    s = used.sensor.replace(exposure_s=2.0, gain=4.0)
    # the second of two frames at one pose, at another age, a longer exposure, a stack: the
    # geometry is reused, the brightness and the noise are not
    for pose, seed, t_s, kw in (
        (p1, 1, 0.0, {}),
        (p2, 2, 5.0, {}),
        (p1, 3, 40.0, {}),
        (p1, 5, 60.0, {"sensor": s, "n_avg": 4}),
    ):
        _render(used, scene, pose, 9, 0.0)
        a, b = _render(used, scene, pose, seed, t_s, **kw), _fresh(ref, scene, pose, seed, t_s, **kw)
        assert a.image.tobytes() == b.image.tobytes()
        assert json.dumps(a.truth, sort_keys=True) == json.dumps(b.truth, sort_keys=True)


def test_new_marks_where_the_robot_stands_are_rendered():
    scene = Scene.from_dict(EXAMPLE_SCENE)
    cam = scene.camera()
    before = _render(cam, scene, scene.pose, 1, 0.0)
    n = sum(d["visible"] for d in before.truth["dots"])
    xy = scene.pose.robot_to_world([[0.25, 0.05]])
    scene.phosphor.charge(xy, t_start_s=-3.0, duration_s=3.0)  # a new dot in view, the robot still
    after = _render(cam, scene, scene.pose, 1, 0.0)
    assert sum(d["visible"] for d in after.truth["dots"]) == n + 1
    assert after.image.tobytes() == _fresh(scene.camera(), scene, scene.pose, 1, 0.0).image.tobytes()


def test_the_fast_noise_draw_is_numpys_integers_draw():
    """The noise indices (stcvision.sim_camera.image_sensor._noise_indices) are exactly
    ``rng.integers(0, 65536, dtype=uint16)``, leaving the generator where it leaves it, with a
    32-bit half pending, on another bit generator and for a size not a multiple of 4."""
    from stcvision.sim_camera.image_sensor import _noise_indices

    def pair(make):
        return make(), make()

    cases = [
        (lambda: np.random.default_rng(3), (480, 640, 3)),
        (lambda: np.random.Generator(np.random.MT19937(3)), (40, 64, 3)),
        (lambda: np.random.default_rng(4), (5, 7, 3)),
    ]
    for make, shape in cases:
        for pending in (False, True):
            a, b = pair(make)
            if pending:  # one 32-bit half left in the buffer
                a.integers(0, 2**32, dtype=np.uint32), b.integers(0, 2**32, dtype=np.uint32)
            x, y = _noise_indices(a, shape), b.integers(0, 65536, size=shape, dtype=np.uint16)
            assert x.shape == shape and np.array_equal(x, y)
            assert (
                a.integers(0, 2**32, size=9, dtype=np.uint32).tolist()
                == b.integers(0, 2**32, size=9, dtype=np.uint32).tolist()
            )

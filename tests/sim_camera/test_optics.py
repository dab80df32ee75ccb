"""Catadioptric geometry, checked against independent calculations."""

import cv2
import numpy as np
import pytest

from stcvision.sim_camera.optics import (
    FloorProjector,
    MirrorCameraParams,
    mirror_geometry,
    project_floor_points,
    rim_points_px,
    trace_pixels,
)

PERTURBED = MirrorCameraParams(
    mirror_decentre_m=(0.0012, -0.0007),
    mirror_tilt_rad=np.radians(1.5),
    mirror_tilt_axis_rad=0.8,
    k1=-0.1,
    k2=0.01,
    principal_px=(322.0, 236.5),
)


@pytest.fixture(scope="module", params=["nominal", "perturbed"])
def table(request):
    return trace_pixels(MirrorCameraParams() if request.param == "nominal" else PERTURBED)


def test_pixel_trace_and_reflection_solver_agree(table):
    """pixel -> floor (ray trace) and floor -> pixel (Alhazen's problem) are inverse (sub-pixel)."""
    rng = np.random.default_rng(0)
    idx = np.argwhere(table.ground)
    sel = idx[rng.choice(len(idx), 3000, replace=False)]
    xy = table.floor_xy_m[sel[:, 0], sel[:, 1]]
    uv, ok = project_floor_points(table.params, xy)
    assert ok.mean() > 0.995
    err = np.hypot(uv[ok, 0] - sel[ok, 1], uv[ok, 1] - sel[ok, 0])
    assert err.max() < 1e-3


def test_fast_projector_matches_the_reflection_solver(table):
    fp = FloorProjector(table)
    rng = np.random.default_rng(1)
    r = rng.uniform(0.05, 1.4, 4000)
    a = rng.uniform(-np.pi, np.pi, 4000)
    xy = np.column_stack([r * np.cos(a), r * np.sin(a)])
    uv1, ok1 = fp.project(xy)
    uv2, ok2 = project_floor_points(table.params, xy)
    both = ok1 & ok2
    assert np.abs(uv1[both] - uv2[both]).max() < 0.01
    # visibility differs at most for points straddling the rim or the body outline
    assert (ok1 != ok2).mean() < 0.01


def test_on_axis_trace_matches_a_hand_written_meridional_calculation():
    """Independent 2-D reflection in the meridional plane for the aligned, undistorted mirror."""
    p = MirrorCameraParams(k1=0.0)
    table = trace_pixels(p)
    cx, cy = p.principal_px
    v = int(cy) + 0.5 - 0.5  # the row through the principal point (v = cy exactly)
    v = int(round(cy - 0.5))  # integer pixel row closest to cy
    for u in range(int(cx) + 60, int(cx) + 220, 20):
        if not table.ground[v, u]:
            continue
        # camera x = robot +y; the ray's tilt from the axis in the meridional plane
        ax, ay = (u - cx) / p.focal_px, (v - cy) / p.focal_px
        alpha = np.arctan(np.hypot(ax, ay))
        # sphere centre on the axis at height hc + d + R; ray from (0, hc)
        zc = p.camera_height_m + p.mirror_distance_m + p.mirror_radius_m
        d = np.array([np.sin(alpha), np.cos(alpha)])
        o = np.array([0.0, p.camera_height_m])
        c = np.array([0.0, zc])
        b = d @ (o - c)
        t = -b - np.sqrt(b * b - ((o - c) @ (o - c) - p.mirror_radius_m**2))
        hit = o + t * d
        n = (hit - c) / p.mirror_radius_m
        r = d - 2 * (d @ n) * n
        rho = hit[0] + (-hit[1] / r[1]) * r[0]
        got = np.hypot(*table.floor_xy_m[v, u])
        assert got == pytest.approx(rho, rel=1e-9, abs=1e-12)


def test_image_radius_grows_monotonically_with_floor_distance():
    p = MirrorCameraParams()
    for ang in np.radians([0, 37, 90, 200, 300]):
        rho = np.linspace(0.12, 1.2, 200)
        xy = np.column_stack([rho * np.cos(ang), rho * np.sin(ang)])
        uv, ok = project_floor_points(p, xy)
        assert ok.all()
        rad = np.hypot(uv[:, 0] - p.principal_px[0], uv[:, 1] - p.principal_px[1])
        assert np.all(np.diff(rad) > 0)


def test_forward_is_up_and_left_is_right_in_the_raw_image():
    p = MirrorCameraParams()
    uv, ok = project_floor_points(p, [[0.4, 0.0], [0.0, 0.4]])
    assert ok.all()
    cx, cy = p.principal_px
    assert uv[0, 1] < cy and abs(uv[0, 0] - cx) < 1e-6  # forward: straight up
    assert uv[1, 0] > cx and abs(uv[1, 1] - cy) < 1e-6  # left: to the right (mirror view)


def _fit_circle(pts):
    (x, y), r = cv2.minEnclosingCircle(pts.astype(np.float32))
    A = np.column_stack([2 * pts[:, 0], 2 * pts[:, 1], np.ones(len(pts))])
    b = (pts**2).sum(1)
    cx, cy, c = np.linalg.lstsq(A, b, rcond=None)[0]
    return np.array([cx, cy]), np.sqrt(c + cx * cx + cy * cy)


def test_rim_is_a_circle_where_the_geometry_puts_it():
    p = MirrorCameraParams()
    rim = rim_points_px(p)
    centre, radius = _fit_circle(rim)
    assert centre == pytest.approx(p.principal_px, abs=1e-6)
    assert np.hypot(*(rim - centre).T).std() < 1e-6
    # the mirror mask of the pixel trace ends at that circle (within a pixel)
    table = trace_pixels(p)
    v, u = np.nonzero(table.mirror)
    assert np.hypot(u - centre[0], v - centre[1]).max() == pytest.approx(radius, abs=1.0)
    # closed form on axis: rim at angle atan(a / (d + sagitta)) from the axis
    sag = p.mirror_radius_m - np.sqrt(p.mirror_radius_m**2 - p.mirror_rim_radius_m**2)
    tan_a = p.mirror_rim_radius_m / (p.mirror_distance_m + sag)
    r2 = tan_a**2
    assert radius == pytest.approx(p.focal_px * tan_a * (1 + p.k1 * r2 + p.k2 * r2 * r2), rel=1e-9)


def test_decentre_shifts_the_image_the_way_it_should():
    p0 = MirrorCameraParams(k1=0.0)
    c0, r0 = _fit_circle(rim_points_px(p0))
    dx = 0.001  # 1 mm forward (robot +x) -> image up (v decreases)
    c1, r1 = _fit_circle(rim_points_px(p0.replace(mirror_decentre_m=(dx, 0.0))))
    sag = p0.mirror_radius_m - np.sqrt(p0.mirror_radius_m**2 - p0.mirror_rim_radius_m**2)
    z_rim = p0.mirror_distance_m + sag
    assert c1[1] - c0[1] == pytest.approx(-p0.focal_px * dx / z_rim, rel=1e-6)
    assert c1[0] == pytest.approx(c0[0], abs=1e-9)
    dy = 0.001  # 1 mm left (robot +y) -> image right (u increases)
    c2, _ = _fit_circle(rim_points_px(p0.replace(mirror_decentre_m=(0.0, dy))))
    assert c2[0] - c0[0] == pytest.approx(p0.focal_px * dy / z_rim, rel=1e-6)


def test_tilt_makes_the_rim_an_ellipse_and_moves_the_sphere():
    p = MirrorCameraParams(k1=0.0)
    tilted = p.replace(mirror_tilt_rad=np.radians(2.0), mirror_tilt_axis_rad=0.0)
    (_, _), (a0, b0), _ = cv2.fitEllipse(rim_points_px(p).astype(np.float32))
    (_, _), (a1, b1), _ = cv2.fitEllipse(rim_points_px(tilted).astype(np.float32))
    assert min(a0, b0) / max(a0, b0) == pytest.approx(1.0, abs=1e-4)
    # the rim plane is foreshortened by ~cos(tilt) (perspective changes it slightly)
    squash = 1 - min(a1, b1) / max(a1, b1)
    assert 0.5 * (1 - np.cos(np.radians(2.0))) < squash < 2 * (1 - np.cos(np.radians(2.0)))
    # tilting about the vertex moves the sphere centre sideways by R sin(tilt)
    c0, _, _ = mirror_geometry(p)
    c1, axis, _ = mirror_geometry(tilted)
    assert np.hypot(*(c1 - c0)[:2]) == pytest.approx(p.mirror_radius_m * np.sin(np.radians(2.0)))
    assert axis @ [0, 0, 1] == pytest.approx(np.cos(np.radians(2.0)))


def test_default_view_reaches_the_five_cells():
    """The STC robot must see the 12 corners of its cell and the four neighbours."""
    p = MirrorCameraParams()
    D = 0.16
    # robot in sub-cell 0 (lower right) of its cell, heading up: cell centre at (D/2, D/2)
    # in the robot frame (x forward, y left)
    c = np.array([D / 2, D / 2])
    corners = [
        c + np.array(v) * D
        for v in [
            (1, 1),
            (1, -1),
            (-1, -1),
            (-1, 1),
            (3, 1),
            (3, -1),
            (1, -3),
            (-1, -3),
            (-3, -1),
            (-3, 1),
            (-1, 3),
            (1, 3),
        ]
    ]
    _, ok = project_floor_points(p, np.array(corners))
    assert ok.all()


@pytest.fixture
def geometry_dir(tmp_path, monkeypatch):
    """camera_geometry's files in a folder of the test's own, with an empty memory cache."""
    from stcvision.sim_camera import optics

    monkeypatch.setattr(optics, "GEOMETRY_DIR", tmp_path)
    optics.camera_geometry.cache_clear()
    yield tmp_path
    optics.camera_geometry.cache_clear()


def _same_geometry(a, b):
    (ta, pa), (tb, pb) = a, b
    for name in ("floor_xy_m", "ground", "mirror", "body", "footprint_m2", "vignetting", "jacobian"):
        np.testing.assert_array_equal(getattr(ta, name), getattr(tb, name), err_msg=name)
    np.testing.assert_array_equal(pa.guess, pb.guess)
    np.testing.assert_array_equal(pa.pixels, pb.pixels)
    assert pa.max_radius_m == pb.max_radius_m


def test_camera_geometry_from_its_file_is_the_traced_one_to_the_last_bit(geometry_dir):
    """The second process (here: an emptied memory cache) reads the table and the lookup grid
    from the file the first wrote: the same arrays, bit for bit, as tracing them again, so a
    camera renders the same frames either way; the arrays are shared, so they are read only."""
    from stcvision.sim_camera import optics

    traced = optics.camera_geometry(PERTURBED)
    (file,) = geometry_dir.glob("raytable-*.npz")
    optics.camera_geometry.cache_clear()
    loaded = optics.camera_geometry(PERTURBED)
    assert loaded[0] is not traced[0]
    fresh = trace_pixels(PERTURBED)
    _same_geometry(loaded, (fresh, FloorProjector(fresh)))
    assert not loaded[0].floor_xy_m.flags.writeable and not loaded[0].ground.flags.writeable
    assert optics.camera_geometry(PERTURBED) is loaded  # the memory cache within a process
    assert list(geometry_dir.glob("raytable-*.npz")) == [file]


def test_a_cut_or_foreign_geometry_file_is_traced_again(geometry_dir):
    from stcvision.sim_camera import optics

    traced = optics.camera_geometry(PERTURBED)
    (file,) = geometry_dir.glob("raytable-*.npz")
    whole = file.read_bytes()
    for bad in (whole[: len(whole) // 2], b"", b"not a zip file"):
        file.write_bytes(bad)
        optics.camera_geometry.cache_clear()
        _same_geometry(optics.camera_geometry(PERTURBED), traced)
        assert file.read_bytes() == whole  # written again, whole
    # a file of other shapes under this key (another camera's arrays): traced again
    other = np.load(file)
    np.savez(file, **{k: other[k][:-1] for k in other.files})
    optics.camera_geometry.cache_clear()
    _same_geometry(optics.camera_geometry(PERTURBED), traced)


def test_geometry_files_are_keyed_by_the_optics_and_trimmed(geometry_dir, monkeypatch):
    import dataclasses

    from stcvision.sim_camera import optics

    monkeypatch.setattr(optics, "GEOMETRY_FILES_KEPT", 2)
    small = dataclasses.replace(
        PERTURBED, width_px=160, height_px=120, focal_px=PERTURBED.focal_px / 4, principal_px=(80.5, 59.0)
    )
    for k1 in (-0.10, -0.11, -0.12):
        optics.camera_geometry(dataclasses.replace(small, k1=k1))
    assert len(list(geometry_dir.glob("raytable-*.npz"))) == 2
    a = optics._geometry_path(small)
    assert a == optics._geometry_path(dataclasses.replace(small))
    # the same optics however its numbers were typed (a JSON file's 40 is the 40.0 of Python)
    assert optics._geometry_path(dataclasses.replace(small, focal_px=196)) == optics._geometry_path(
        dataclasses.replace(small, focal_px=np.float64(196.0))
    )
    assert a != optics._geometry_path(dataclasses.replace(small, k2=0.011))
    # the code that traced is the code the process loaded, not the file as it is now
    monkeypatch.setattr(optics, "_SOURCE_DIGEST", "another version of optics.py")
    assert a != optics._geometry_path(small)

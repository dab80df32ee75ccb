"""Ground truth attached to rendered frames.

Cell geometry follows ``docs/explanation/stc-geometry.md``: in the *entry frame* (the robot's
heading rounded to the nearest multiple of 90 degrees points "up"), the sub-cells of the robot's
cell are numbered counter-clockwise from the lower-right one: 0 lower-right, 1 upper-right, 2
upper-left, 3 lower-left. The five mark boxes:

==== ========== ===================
box  sub-cell   edge (entry frame)
==== ========== ===================
1    1          right (exterior)
2    2          top (exterior)
3    2          right (shared with 1)
4    3          top (shared with 2)
5    1          bottom (shared with 0)
==== ========== ===================

A dot belongs to the sub-cell it lies in and to that sub-cell's nearest edge (a mark sits a few
centimetres inside one edge), so the region of a box is the triangle between the sub-cell's
centre and that edge. Neighbour cells are right, forward, left and back of the robot's cell.
"""

from __future__ import annotations

import numpy as np

from stcvision.sim_camera.image_sensor import ROSE_SNR, detection_snr

__all__ = ["BOXES", "NEIGHBOURS", "build_truth", "entry_frame"]

# sub-cell index -> (right, up) sign of its centre relative to the cell centre, entry frame
SUBCELL_SIGNS = {0: (1, -1), 1: (1, 1), 2: (-1, 1), 3: (-1, -1)}
# box -> (sub-cell, edge direction (right, up) in the entry frame)
BOXES = {1: (1, (1, 0)), 2: (2, (0, 1)), 3: (2, (1, 0)), 4: (3, (0, 1)), 5: (1, (0, -1))}
NEIGHBOURS = {"right": (1, 0), "forward": (0, 1), "left": (-1, 0), "back": (0, -1)}


def entry_frame(heading_rad: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Unit vectors (right, up) of the entry frame in world coordinates and its heading."""
    h4 = np.round(heading_rad / (np.pi / 2)) * (np.pi / 2)
    up = np.array([np.cos(h4), np.sin(h4)])
    right = np.array([up[1], -up[0]])
    return right, up, float(h4)


def _square(centre, half, right, up):
    return np.array([centre + half * (sr * right + su * up) for sr, su in ((1, -1), (1, 1), (-1, 1), (-1, -1))])


def _project_polygon(camera, pose, poly_w, per_edge: int = 16):
    """Project a world polygon's densely sampled outline; invisible samples are dropped."""
    pts = []
    for a, b in zip(poly_w, np.roll(poly_w, -1, axis=0), strict=True):
        t = np.linspace(0, 1, per_edge, endpoint=False)[:, None]
        pts.append(a + t * (b - a))
    pts = np.vstack(pts)
    uv, ok = camera.projector.project(pose.world_to_robot(pts))
    return np.round(uv[ok], 2).tolist()


def _dot_box(xy_w, cell_centre, right, up, D):
    """(sub-cell index, box number or None) of each dot relative to the current cell."""
    rel = np.asarray(xy_w) - cell_centre
    r, u = rel @ right, rel @ up
    out = []
    for ri, ui in zip(r, u, strict=True):
        if abs(ri) >= D or abs(ui) >= D:
            out.append((None, None))
            continue
        k = {(1, -1): 0, (1, 1): 1, (-1, 1): 2, (-1, -1): 3}[(1 if ri >= 0 else -1, 1 if ui >= 0 else -1)]
        sr, su = SUBCELL_SIGNS[k]
        lr, lu = ri - sr * D / 2, ui - su * D / 2  # relative to the sub-cell centre
        edge = (int(np.sign(lr)), 0) if abs(lr) > abs(lu) else (0, int(np.sign(lu)))
        box = next((b for b, (kk, e) in BOXES.items() if kk == k and e == edge), None)
        out.append((k, box))
    return out


def build_truth(camera, pose, sensor, info, *, t_s, phosphor=None, red_lights_m=None, board=None) -> dict:
    """Everything a test or an evaluation needs to score a frame (JSON-serialisable)."""
    truth: dict = {
        "t_s": float(t_s),
        "pose": pose.to_dict(),
        "optics": camera.optics.to_dict(),
        "sensor": sensor.to_dict(),
        "dots": [],
        "red_lights": [],
    }
    d = info.get("dots")
    if phosphor is not None and d is not None:
        snr = detection_snr(d["total_e"], d["cov_px"], sensor)
        ages = phosphor.ages_s(t_s)
        xy_w = phosphor.xy_m
        for i in range(len(phosphor)):
            truth["dots"].append(
                {
                    "id": i,
                    "xy_world_m": xy_w[i].round(5).tolist(),
                    "xy_robot_m": d["xy_robot"][i].round(5).tolist(),
                    "uv_px": None if not d["visible"][i] else d["uv"][i].round(3).tolist(),
                    "visible": bool(d["visible"][i]),
                    "age_s": float(ages[i]),
                    "luminance_cd_m2": float(d["lum"][i]),
                    "electrons": float(d["total_e"][i]),
                    "snr": float(snr[i]),
                    "detectable": bool(snr[i] >= ROSE_SNR),
                }
            )
    li = info.get("lights")
    if red_lights_m is not None and li is not None:
        for i, xy in enumerate(np.asarray(red_lights_m)):
            truth["red_lights"].append(
                {
                    "xy_world_m": xy.round(5).tolist(),
                    "uv_px": None if not li["visible"][i] else li["uv"][i].round(3).tolist(),
                    "visible": bool(li["visible"][i]),
                }
            )
    if board is not None:
        truth["cell"] = _cell_truth(camera, pose, board, truth, red_lights_m)
    return truth


def _cell_truth(camera, pose, board, truth, red_lights_m) -> dict:
    D = board.subcell_m
    si, sj = board.subcell_at((pose.x_m, pose.y_m))
    ci, cj = si // 2, sj // 2
    centre = board.cell_center_m(ci, cj)
    right, up, h4 = entry_frame(pose.heading_rad)
    rel = np.array([pose.x_m, pose.y_m]) - centre
    robot_k = {(1, -1): 0, (1, 1): 1, (-1, 1): 2, (-1, -1): 3}[
        (1 if rel @ right >= 0 else -1, 1 if rel @ up >= 0 else -1)
    ]
    lit_dots = [dt for dt in truth["dots"] if dt["luminance_cd_m2"] > 0]
    xy = np.array([dt["xy_world_m"] for dt in lit_dots]).reshape(-1, 2)
    assign = _dot_box(xy, centre, right, up, D)
    for dt, (k, box) in zip(lit_dots, assign, strict=True):
        dt["subcell"], dt["box"] = k, box
    subcells = []
    for k, (sr, su) in SUBCELL_SIGNS.items():
        c = centre + D / 2 * (sr * right + su * up)
        subcells.append(
            {
                "index": k,
                "subcell": list(board.subcell_at(c)),
                "polygon_px": _project_polygon(camera, pose, _square(c, D / 2, right, up)),
                "marked": any(a[0] == k for a in assign),
            }
        )
    boxes = []
    for b, (k, (er, eu)) in BOXES.items():
        sr, su = SUBCELL_SIGNS[k]
        c = centre + D / 2 * (sr * right + su * up)
        e = er * right + eu * up
        t = np.array([e[1], -e[0]])
        tri = np.array([c, c + D / 2 * (e + t), c + D / 2 * (e - t)])
        n = sum(1 for a in assign if a[1] == b)
        boxes.append(
            {
                "box": b,
                "subcell_index": k,
                "lit": n > 0,
                "n_dots": n,
                "polygon_px": _project_polygon(camera, pose, tri),
            }
        )
    lights = np.asarray(red_lights_m).reshape(-1, 2) if red_lights_m is not None else np.zeros((0, 2))
    neighbours = []
    for name, (dr, du) in NEIGHBOURS.items():
        nc = centre + 2 * D * (dr * right + du * up)
        ncell = board.subcell_at(nc)
        ni, nj = ncell[0] // 2, ncell[1] // 2
        inside = lambda pts, c=nc: (  # noqa: E731
            (np.abs((pts - c) @ right) < D) & (np.abs((pts - c) @ up) < D)
        )
        if len(xy):
            for k in np.flatnonzero(inside(xy)):  # which neighbour's marks a dot is, for scoring them
                lit_dots[k]["neighbour"] = name
        neighbours.append(
            {
                "direction": name,
                "cell": [int(ni), int(nj)],
                "free": board.is_cell_free(ni, nj),
                "has_marks": bool(inside(xy).any()) if len(xy) else False,
                "has_red": bool(inside(lights).any()) if len(lights) else False,
                "polygon_px": _project_polygon(camera, pose, _square(nc, D, right, up)),
            }
        )
    return {
        "cell": [int(ci), int(cj)],
        "entry_heading_rad": h4,
        "robot_subcell_index": robot_k,
        "subcells": subcells,
        "boxes": boxes,
        "neighbours": neighbours,
        "visited": {str(k): bool(v) for k, v in _visited(boxes).items()},
    }


def _visited(boxes) -> dict:
    """Sub-cells 1-3 visited according to the five-box rule (docs/explanation/stc-geometry.md)."""
    lit = {b["box"]: b["lit"] for b in boxes}
    return {1: lit[1] or lit[5], 2: lit[2] or lit[3], 3: lit[4]}

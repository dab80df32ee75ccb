"""Rerun recording of a search run (an observer: ``on_move(record, world, robot, fixer)`` after
each move): the obstacles, patch and planned pattern (static), the true and believed poses and paths,
the sensing points and beacon fixes in ``world/``; the phase, tongue, ring and odometry error
as time series; the beacon camera's pipeline stages (``stcvision.rr`` paths) when a frame was
taken. Timelines ``move`` (sequence) and ``sim_time``. World y is flipped for the 2-D view (north
up). The file is streamed as it is logged (:class:`stcvision.rr.RecordingFile`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stcvision.controllers.search.patterns import planned_points
from stcvision.rr import Recorder, RecordingFile
from stcvision.rr import rerun_blueprint as rrb  # rerun, imported when a recording is made
from stcvision.rr import rerun_sdk as rr

__all__ = ["SearchRecorder", "blueprint"]


#: time series (entity under ``series/``, view name)
SERIES = (
    ("phase", "phase (Fig. 5)"),
    ("tongue", "tongue"),
    ("ring", "move blocked (ring or stall)"),
    ("odometry_error_m", "odometry error (m)"),
)


def blueprint() -> rrb.Blueprint:
    """The layout a search run's recording opens with: the floor map with the true and
    believed paths, the time series, the beacon camera's raw frame and ground view, on the
    ``sim_time`` timeline."""
    from stcvision.rr import layout

    world = rrb.Spatial2DView(origin="world", name="world (north up)")
    series = rrb.Vertical(*[rrb.TimeSeriesView(origin=f"series/{k}", name=n) for k, n in SERIES])
    camera = rrb.Vertical(
        rrb.Spatial2DView(origin="raw", name="beacon camera: raw frame"),
        rrb.Spatial2DView(origin="ground", name="beacon camera: ground view"),
    )
    return layout(rrb.Horizontal(world, series, camera, column_shares=[3, 2, 2]), timeline="sim_time")


def _xy(p) -> np.ndarray:
    p = np.asarray(p, float).reshape(-1, 2)
    return np.column_stack([p[:, 0], -p[:, 1]])


class SearchRecorder(Recorder):
    def __init__(self, path: str | Path, scene, pattern) -> None:
        self.path = Path(path)
        self.file = RecordingFile(self.path, app_id="stcvision-search", default_blueprint=blueprint())
        self.rec = self.file.rec
        try:
            self._true = [(0.0, 0.0)]
            self._odo = [(0.0, 0.0)]
            self._fixes: list = []
            self._pipe_logger = None
            self._static(scene, pattern)
        except BaseException as exc:  # stopped before the caller holds it: ended here as the caller would
            self.end(exc)
            raise

    def _static(self, scene, pattern) -> None:
        rec = self.rec
        for k, (x, y, r) in enumerate(scene.obstacles):
            ang = np.linspace(0, 2 * np.pi, 49)
            ring = _xy(np.c_[x + r * np.cos(ang), y + r * np.sin(ang)])
            rec.log(f"world/obstacles/{k}", rr.LineStrips2D([ring], colors=[20, 20, 20], radii=0.004), static=True)
        if scene.patch is not None:
            x, y, r = scene.patch
            rec.log("world/patch", rr.Points2D(_xy([(x, y)]), radii=r, colors=[255, 160, 60, 90]), static=True)
        rec.log(
            "world/planned",
            rr.LineStrips2D([_xy(planned_points(pattern))], colors=[160, 160, 160], radii=0.002),
            static=True,
        )

    def on_move(self, m, world, robot, fixer=None) -> None:
        rec = self.rec
        rec.set_time("move", sequence=m.index)
        rec.set_time("sim_time", duration=float(m.t_s))
        self._true.append(m.true_pose[:2])
        self._odo.append(m.odo_pose[:2])
        true_xy = _xy(self._true)  # the robot senses where it truly stands after each move
        rec.log("world/true_path", rr.LineStrips2D([true_xy], colors=[40, 100, 230], radii=0.003))
        rec.log("world/believed_path", rr.LineStrips2D([_xy(self._odo)], colors=[40, 170, 60], radii=0.002))
        rec.log("world/samples", rr.Points2D(true_xy, radii=0.008, colors=[0, 0, 0]))
        for name, pose, col in (
            ("robot_true", m.true_pose, [40, 100, 230]),
            ("robot_believed", m.odo_pose, [40, 170, 60]),
        ):
            x, y, h = pose
            rec.log(f"world/{name}", rr.Points2D(_xy([(x, y)]), radii=robot.params.radius_m, colors=[*col, 60]))
            tip = (x + 0.2 * np.cos(h), y + 0.2 * np.sin(h))
            rec.log(f"world/{name}_heading", rr.LineStrips2D([_xy([(x, y), tip])], colors=col, radii=0.004))
        if m.fix is not None:
            self._fixes.append(m.fix[:2])
            rec.log("world/beacon_fixes", rr.Points2D(_xy(self._fixes), radii=0.01, colors=[160, 40, 200]))
        rec.log("series/phase", rr.Scalars(float(m.phase)))
        rec.log("series/tongue", rr.Scalars(float(m.tongue)))
        rec.log("series/ring", rr.Scalars(1.0 if m.result == "blocked" else 0.0))
        err = float(np.hypot(m.true_pose[0] - m.odo_pose[0], m.true_pose[1] - m.odo_pose[1]))
        rec.log("series/odometry_error_m", rr.Scalars(err))
        rec.log("move", rr.TextDocument(f"{m.kind} (phase {m.phase}): {m.result}; search steps {m.search_steps}"))
        res = fixer.last_result if fixer is not None else None
        if res is not None and rec.is_enabled():
            from stcvision.rr import PipelineLogger

            if self._pipe_logger is None:
                self._pipe_logger = PipelineLogger(rec, fixer.pipeline, jpeg_quality=70)
            self._pipe_logger.log(res, frame=m.index, sim_time_s=m.t_s)
            fixer.last_result = None

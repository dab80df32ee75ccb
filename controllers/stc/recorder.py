"""Rerun recording of a coverage run: the world (board, obstacle cells, robot pose, marks with
their current luminance, covered sub-cells, the true and believed paths), the camera's
pipeline stages at every decision (``stcvision.rr`` entity paths) and each decision as text, on
the ``sim_time`` and ``decision`` timelines. World coordinates are drawn with north up (y flipped for the 2-D view)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from stcvision.controllers.stc.observers import Observer, Reading
from stcvision.controllers.stc.paths import JsonTrace, PathLog
from stcvision.rr import PipelineLogger, Recorder, RecordingFile, Recordings
from stcvision.rr import rerun_blueprint as rrb  # rerun, imported when a recording is made
from stcvision.rr import rerun_sdk as rr

__all__ = [
    "READINGS_BUDGET",
    "TRACE_ENTITY",
    "WORLD_BUDGET",
    "CoverRecorder",
    "blueprint",
    "readings_every",
    "run_cover_recorded",
]


def blueprint() -> rrb.Blueprint:
    """The layout a coverage run's recording opens with: the floor map with the true and
    believed paths, the camera's raw frame and ground view (cells, boxes, dots), the decision,
    the per-reading trace lines and the observation as text, the stage timings, on the
    ``sim_time`` timeline (``decision`` beside it)."""
    from stcvision.rr import layout

    return layout(
        rrb.Horizontal(
            rrb.Spatial2DView(origin="world", name="world (north up)"),
            rrb.Vertical(
                rrb.Spatial2DView(origin="raw", name="camera: raw frame"),
                rrb.Spatial2DView(origin="ground", name="ground view"),
            ),
            rrb.Vertical(
                rrb.TextDocumentView(origin="decision", name="decision"),
                rrb.TextLogView(origin="trace", name="trace (the --trace lines)"),
                rrb.TextDocumentView(origin="observation", name="observation"),
                rrb.TimeSeriesView(origin="timing", name="stage ms"),
            ),
            column_shares=[3, 2, 2],
        ),
        timeline="sim_time",
    )


#: a recording keeps the camera's stages of about this many readings: one reading in ``every``
#: (:class:`CoverRecorder`); a reading's five JPEG stages are ~90 kB (22x22 board, lowlight)
READINGS_BUDGET = 300
#: ... and the world's snapshot (every dot with its glow, the covered sub-cells) of about this
#: many: a snapshot grows with the marks laid (a 22x22 tour: ~7,000 dots, ~100 kB at its end)
WORLD_BUDGET = 50

#: where each reading's trace line (what ``cover --trace`` writes, :class:`JsonTrace`) goes, whole, as a text log
TRACE_ENTITY = "trace"


def readings_every(board, budget: int = READINGS_BUDGET) -> int:
    """One reading in how many a recording of ``board`` keeps in full: a tour reads about once
    per reachable sub-cell, so 1 up to ``budget`` sub-cells, then proportionally more."""
    n = int(board.reachable_cells().sum()) * 4
    return max(1, -(-n // budget))


class CoverRecorder(Observer, Recorder):
    """An observer of a coverage run (:func:`stcvision.controllers.stc.loop.run_cover`, ``observers=``).
    Streams ``path`` (.rrd) as it logs (:class:`stcvision.rr.RecordingFile`: renamed into
    place at the end, kept as it stood after Ctrl-C or SIGTERM).

    Bounded (rerun has no backpressure: what is logged stays in memory until written): every
    reading (decision, look) logs the robot's pose and the decision as text; one in ``every``
    (default :func:`readings_every`: ~:data:`READINGS_BUDGET` per run) also the camera's stages
    (JPEG-compressed, :class:`stcvision.rr.PipelineLogger`), and ~:data:`WORLD_BUDGET` per run
    the world's snapshot (every mark with its glow, the covered sub-cells), whose size grows with
    the marks laid. A reading the referee finds wrong is always logged in full, and the world as
    the run left it at the end.

    Every reading's trace line (the JSON object ``cover --trace`` writes, uncut) goes to
    :data:`TRACE_ENTITY` as a text log once it is final: a look's at once, a decision's when the
    next decision starts or the run ends (the referee judges a decision when the robot leaves
    its cell, after its looks). Only the decision awaiting its verdict is held."""

    def __init__(self, path: str | Path, board, *, every: int | None = None) -> None:
        self.path = Path(path)
        self.file = RecordingFile(self.path, app_id="stcvision-cover", default_blueprint=blueprint())
        self.rec = self.file.rec
        try:
            self.board = board
            self.paths = PathLog(board)  # the true and believed paths, drawn with the world's snapshots
            self.trace = JsonTrace(board)  # each reading's trace line, logged once final
            self.every = readings_every(board) if every is None else max(1, int(every))
            self.world_every = max(self.every, readings_every(board, WORLD_BUDGET))
            self.readings = self.full = 0  # readings seen, and logged in full
            self._last: Reading | None = None  # the last reading, when it was not logged in full
            self._pipe_logger = None
            self._static()
        except BaseException as exc:  # stopped before the caller holds it: ended here as the caller would
            self.end(exc)
            raise

    @staticmethod
    def _xy(p) -> np.ndarray:
        p = np.asarray(p, float).reshape(-1, 2)
        return np.column_stack([p[:, 0], -p[:, 1]])

    def _static(self) -> None:
        b = self.board
        w, h = b.size_m
        D = b.subcell_m
        lines = [[(x, 0), (x, -h)] for x in np.arange(0, w + 1e-9, 2 * D)]
        lines += [[(0, -y), (w, -y)] for y in np.arange(0, h + 1e-9, 2 * D)]
        self.rec.log("world/grid", rr.LineStrips2D(lines, colors=[150, 150, 150], radii=0.002), static=True)
        blocked = np.argwhere(~b.cell_free)
        if len(blocked):
            centres = self._xy([b.cell_center_m(i, j) for i, j in blocked])
            self.rec.log(
                "world/obstacles",
                rr.Boxes2D(centers=centres, sizes=[[2 * D, 2 * D]] * len(centres), colors=[200, 40, 40]),
                static=True,
            )
        self.rec.log(
            "world/red_lights", rr.Points2D(self._xy(b.red_lights_m()), colors=[255, 0, 0], radii=0.01), static=True
        )

    def attach(self, perception) -> None:
        """Read the run's perception (``run_cover``'s ``perception_hook``): its frames and
        whether the referee judges it, for the trace lines."""
        self.trace.attach(perception)

    def on_move(self, plant, belief) -> None:
        self.paths.on_move(plant, belief)

    def on_turn(self, plant, belief, measured_rad) -> None:
        self.trace.on_turn(plant, belief, measured_rad)

    def _log_trace(self, *, final: bool) -> None:
        """Log the trace lines that are final (all of them when ``final``) and forget them."""
        lines = self.trace.lines
        keep = 0 if final or not lines or lines[-1]["kind"] != "decision" else 1
        for line in lines[: len(lines) - keep]:
            self.rec.set_time("decision", sequence=line["decision"])
            self.rec.set_time("sim_time", duration=float(line["t_s"]))
            self.rec.log(TRACE_ENTITY, rr.TextLog(json.dumps(line, allow_nan=False), level="INFO"))
        del lines[: len(lines) - keep]

    def on_reading(self, ev: Reading) -> None:
        self.paths.on_reading(ev)
        self.trace.on_reading(ev)
        self._log_trace(final=False)
        if ev.kind == "look" and ev.frame is None:
            return
        self.readings += 1
        full = (self.readings - 1) % self.every == 0
        self._log_reading(ev, full=full, world=(self.readings - 1) % self.world_every == 0)
        self._last = None if full else ev

    def on_referee(self, kind: str, text: str) -> None:
        """A reading the referee finds wrong: its frames and the world, in full (once)."""
        self.trace.on_referee(kind, text)
        if self._last is not None:
            self._log_reading(self._last, full=True)
            self._last = None

    def on_end(self, plant, floor) -> None:
        self._world(plant.t, floor.phosphor, plant.visits)
        self._log_trace(final=True)

    def end(self, exc) -> None:
        """End the recording (:meth:`stcvision.rr.RecordingFile.end`); one stopped by a signal
        keeps the decision that was awaiting its verdict too."""
        if isinstance(exc, KeyboardInterrupt):
            self._log_trace(final=True)
        super().end(exc)

    def _log_reading(self, ev: Reading, *, full: bool, world: bool | None = None) -> None:
        p, sub = ev.plant, ev.belief.sub
        if ev.kind == "look":
            text = f"**look** from sub-cell {sub}: the cell ahead is {'marked' if ev.marked else 'unmarked'}"
        else:
            d, o = ev.decision, ev.obs
            text = (
                f"**decision {ev.k}** at sub-cell {sub}, t = {p.t:.0f} s\n\n"
                f"visited 1-3: {d.visited}, parent {d.parent}, child {d.child}, "
                f"target {d.target}{' (stop there)' if d.final else ''}\n\n"
                f"boxes {o.boxes}, start mark {o.start_mark}"
            )
        result, pipeline = ev.frame if (ev.frame is not None and full) else (None, None)
        self.full += full
        world = full if world is None else world
        self.decision(ev.k, p.t, p.pose, ev.floor.phosphor, p.visits, result, pipeline, text, world=world)

    def decision(
        self, k: int, t_s: float, pose, phosphor, visits, result, pipeline, text: str, *, world: bool = True
    ) -> None:
        """One reading: the robot, the text, with ``world`` the world's snapshot, with a
        ``result`` the camera's stages."""
        rec = self.rec
        rec.set_time("decision", sequence=k)
        rec.set_time("sim_time", duration=float(t_s))
        x, y, h = pose
        rec.log("world/robot", rr.Points2D(self._xy([(x, y)]), radii=0.07, colors=[60, 120, 255]))
        tip = (x + 0.1 * np.cos(h), y + 0.1 * np.sin(h))
        rec.log("world/robot_heading", rr.LineStrips2D([self._xy([(x, y), tip])], colors=[60, 120, 255], radii=0.006))
        if world:
            self._world(t_s, phosphor, visits)
        rec.log("decision", rr.TextDocument(text, media_type="text/markdown"))
        if result is not None and pipeline is not None:
            if self._pipe_logger is None or self._pipe_logger.pipeline is not pipeline:
                self._pipe_logger = PipelineLogger(rec, pipeline, jpeg_quality=70)
            self._pipe_logger.log(result, frame=k, sim_time_s=t_s)

    def _world(self, t_s: float, phosphor, visits) -> None:
        """Every mark with its glow at ``t_s``, the covered sub-cells, and the true (blue) and
        believed (orange) paths so far: the start and every forward move."""
        rec = self.rec
        for name, poses, colour in (("true", self.paths.true, [60, 120, 255]),
                                    ("believed", self.paths.believed, [255, 150, 30])):  # fmt: skip
            if len(poses) > 1:
                strip = self._xy([(x, y) for _, x, y, _ in poses])
                rec.log(f"world/path/{name}", rr.LineStrips2D([strip], colors=[colour], radii=0.003))
        if len(phosphor):
            lum = phosphor.luminance_at(t_s)
            g = np.clip(255 * np.sqrt(lum / max(phosphor.law.l_sat_cd_m2, 1e-9)), 30, 255).astype(np.uint8)
            colors = np.column_stack([np.zeros_like(g), g, np.zeros_like(g)])
            rec.log("world/marks", rr.Points2D(self._xy(phosphor.xy_m), radii=0.006, colors=colors))
        cov = np.argwhere(visits > 0)
        if len(cov):
            D = self.board.subcell_m
            centres = self._xy([self.board.subcell_center_m(i, j) for i, j in cov])
            rec.log(
                "world/covered",
                rr.Boxes2D(centers=centres, sizes=[[0.9 * D, 0.9 * D]] * len(cov), colors=[80, 200, 80, 60]),
            )


def run_cover_recorded(board, cfg, rrd=None, observers=(), perception_hook=None) -> dict:
    """:func:`stcvision.controllers.stc.loop.run_cover` with a rerun recording to ``rrd`` (when given),
    renamed into place when the run ends or a signal stops it; an error removes it."""
    from stcvision.controllers.stc.loop import run_cover

    with Recordings() as recs:
        recorder = recs.add(CoverRecorder(rrd, board)) if rrd else None

        def hook(perception):
            if recorder is not None:
                recorder.attach(perception)
            if perception_hook is not None:
                perception_hook(perception)

        return run_cover(board, cfg, observers=[recorder, *observers], perception_hook=hook)

"""Rerun logging of the pipeline: an observer of results, never inside the maths.

Entity paths mirror the stages::

    raw                  the camera frame
    dark_subtracted      after the dark frame (with the pipeline's pedestal)
    ground/image         the unwarped colour ground view (top-down, forward up)
    ground/cells         cell, sub-cell and neighbour outlines from the neighbours calibration
    ground/boxes         the five mark boxes (green = lit, grey = not)
    ground/dots          dots found (green = lit, grey = sub-threshold candidates)
    ground/red           red-light blobs
    ground/heading       the heading fit line
    channels/red         obstacle image
    channels/green       marks image
    observation          the cell observation as text
    timing/<stage>       per-stage milliseconds

Timelines: ``frame`` (sequence) and, when given, ``sim_time`` (seconds). Images are JPEG
compressed (``jpeg_quality``) so long runs stay small. With no recording enabled nothing is
built (``rr.Image`` alone costs ~0.1 ms).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

__all__ = [
    "ENTITY_PATHS",
    "PipelineLogger",
    "Recordings",
    "abort_recording",
    "blueprint",
    "check_recording_path",
    "finish_recording",
    "open_recording",
]

ENTITY_PATHS = (
    "raw",
    "dark_subtracted",
    "ground/image",
    "ground/cells",
    "ground/boxes",
    "ground/dots",
    "ground/red",
    "ground/heading",
    "channels/red",
    "channels/green",
    "observation",
)


def blueprint() -> rrb.Blueprint:
    """Layout: raw and dark-subtracted frames, the annotated ground view, both channel images,
    the observation text and the stage timings."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial2DView(origin="raw", name="raw frame"),
                rrb.Spatial2DView(origin="dark_subtracted", name="dark subtracted"),
            ),
            rrb.Spatial2DView(origin="ground", name="ground view"),
            rrb.Vertical(
                rrb.Spatial2DView(origin="channels/green", name="marks (green)"),
                rrb.Spatial2DView(origin="channels/red", name="obstacles (red)"),
            ),
            rrb.Vertical(
                rrb.TextDocumentView(origin="observation", name="observation"),
                rrb.TimeSeriesView(origin="timing", name="stage ms"),
            ),
            column_shares=[2, 3, 2, 2],
        ),
        collapse_panels=True,
    )


def check_recording_path(path: str | Path, *, overwrite: bool = False) -> Path:
    """Check, before any work, that ``path`` can be made as a rerun recording: a file name ending
    in .rrd (not a directory), its parent a folder, not an existing file unless ``overwrite``."""
    from stcvision.errors import OutputError
    from stcvision.fileio import check_output_file

    path = Path(path)
    if path.is_dir():
        raise OutputError(f"recording {path} is a directory; expected a file name ending in .rrd")
    if path.suffix.lower() != ".rrd":
        raise OutputError(f"recording {path} does not end in .rrd; expected OUT.rrd (rerun's file format)")
    return check_output_file(path, overwrite=overwrite, what="recording")


def check_display(environ=None, platform: str | None = None) -> None:
    """Refuse ``--spawn`` at once where no window can open: on Linux and the BSDs with neither
    ``DISPLAY`` nor ``WAYLAND_DISPLAY`` set, the rerun viewer starts, fails to open its window
    and leaves the command waiting on its gRPC port (seen: a traceback after about 20 s)."""
    import os
    import sys

    from stcvision.errors import StcVisionError

    env = os.environ if environ is None else environ
    plat = sys.platform if platform is None else platform
    if plat.startswith(("linux", "freebsd", "openbsd", "netbsd")) and not (
        env.get("DISPLAY") or env.get("WAYLAND_DISPLAY")
    ):
        raise StcVisionError(
            "--spawn opens the rerun viewer in a window, and there is no display here (DISPLAY and "
            "WAYLAND_DISPLAY are unset); write a file with --rrd OUT.rrd and open it with 'rerun OUT.rrd' "
            "where there is one"
        )


def open_recording(
    path: str | Path | None = None,
    *,
    spawn: bool = False,
    app_id: str = "stcvision",
    default_blueprint: rrb.Blueprint | None = None,
):
    """A recording stream writing to ``path`` (.rrd, atomically: into a hidden temporary sibling
    until :func:`finish_recording` renames it into place; :func:`abort_recording` removes it)
    and/or a spawned viewer; ``default_blueprint`` defaults to the pipeline's :func:`blueprint`.
    Returns ``(stream, temporary path or None)``."""
    from stcvision.errors import StcVisionError
    from stcvision.fileio import discard_temp, output_error, temp_sibling

    if spawn:
        check_display()
    rec = rr.RecordingStream(app_id)
    bp = default_blueprint or blueprint()
    tmp = None
    if path is not None:
        path = check_recording_path(path, overwrite=True)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = temp_sibling(path)
        except OSError as exc:
            raise output_error(path, exc) from None
        try:
            rec.save(tmp, default_blueprint=bp)
        except BaseException:  # a signal while the file sink starts: stop it, then remove its file
            abort_recording(rec, tmp)
            raise
    if spawn:
        try:
            rec.spawn(default_blueprint=bp)
        except (RuntimeError, OSError) as exc:
            abort_recording(rec, tmp)
            discard_temp(tmp)
            why = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise StcVisionError(
                f"cannot start the rerun viewer ({why}); install it (pip install rerun-sdk puts 'rerun' on "
                "PATH) or write a file with --rrd OUT.rrd instead of --spawn"
            ) from None
    return rec, tmp


def finish_recording(rec: rr.RecordingStream, tmp: Path | None, final: str | Path | None) -> None:
    """Flush ``rec`` and, if it writes to the temporary file ``tmp``, move it to ``final``
    atomically (the other half of :func:`open_recording`)."""
    from stcvision.fileio import commit_temp

    rec.flush()
    if tmp is not None:
        rec.disconnect()
        commit_temp(tmp, Path(final))


def abort_recording(rec: rr.RecordingStream, tmp: Path | None) -> None:
    """Stop ``rec`` and remove its temporary file: a run that failed or was interrupted leaves
    the old recording (or none) in place, never a partial one."""
    from stcvision.fileio import discard_temp

    try:
        rec.disconnect()
    finally:
        discard_temp(tmp)


class Recordings:
    """The recordings a block writes (anything with ``close()`` and ``abort()``: a
    :class:`PipelineLogger`, the STC robot's recorder): each is committed (renamed into place)
    when the block ends normally and removed when it raises (an error, Ctrl-C, SIGTERM), so no
    half-written recording is left behind::

        with Recordings() as recs:
            logger = recs.add(PipelineLogger.to_file(path, pipeline))
            ...
    """

    def __init__(self):
        self._open: list = []

    def add(self, recording):
        self._open.append(recording)
        return recording

    def __enter__(self) -> Recordings:
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        for r in self._open:
            if exc_type is None:
                r.close()
            else:
                r.abort()
        return False


class PipelineLogger:
    """Log :class:`stcvision.pipeline.PipelineResult` objects to a recording."""

    def __init__(
        self,
        recording: rr.RecordingStream,
        pipeline,
        *,
        jpeg_quality: int = 80,
        final_path: str | Path | None = None,
        tmp_path: Path | None = None,
    ) -> None:
        self.rec = recording
        self.pipeline = pipeline
        self.q = jpeg_quality
        self._final, self._tmp = final_path, tmp_path
        self._static_done = False

    @classmethod
    def to_file(cls, path: str | Path, pipeline, *, spawn: bool = False, **kw) -> PipelineLogger:
        rec, tmp = open_recording(path, spawn=spawn)
        return cls(rec, pipeline, final_path=path, tmp_path=tmp, **kw)

    @property
    def enabled(self) -> bool:
        return self.rec.is_enabled()

    def _img(self, path: str, img: np.ndarray, *, bgr: bool = True) -> None:
        if img.dtype != np.uint8:  # a 16-bit frame: JPEG holds 8 bits
            import cv2

            from stcvision.pipeline import display_scale

            img = cv2.convertScaleAbs(img, alpha=display_scale(img))
        if img.ndim == 3 and bgr:
            im = rr.Image(img, color_model="BGR")
        else:
            im = rr.Image(img)
        self.rec.log(path, im.compress(jpeg_quality=self.q))

    def log(self, result, *, frame: int, sim_time_s: float | None = None, text: str | None = None) -> None:
        if not self.rec.is_enabled():
            return
        rec = self.rec
        rec.set_time("frame", sequence=frame)
        if sim_time_s is not None:
            rec.set_time("sim_time", duration=float(sim_time_s))
        self._img("raw", result.frame)
        self._img("dark_subtracted", result.dark_subtracted)
        self._img("ground/image", self.pipeline.ground_view(result.dark_subtracted))
        self._img("channels/red", result.obstacle_u8(), bgr=False)
        self._img("channels/green", result.marks_u8(), bgr=False)
        d = result.dots
        if len(d):
            colors = np.where(d.lit[:, None], [[60, 255, 60]], [[140, 140, 140]])
            rec.log("ground/dots", rr.Points2D(d.xy_px, radii=2.5, colors=colors, labels=[f"{s:.1f}" for s in d.snr]))
        else:
            rec.log("ground/dots", rr.Clear(recursive=False))
        if len(result.red):
            rec.log("ground/red", rr.Points2D(result.red.xy_px, radii=6, colors=[255, 40, 40]))
        else:
            rec.log("ground/red", rr.Clear(recursive=False))
        h = result.heading
        if h.ok:
            pts = self.pipeline.profile.robot_to_ground(h.points_m)
            c = pts.mean(0)
            # direction (cos a, sin a) in the robot frame (x fwd, y left) is (-sin a, -cos a)
            # in ground pixels (x right, y down)
            u = np.array([-np.sin(h.line_angle_rad), -np.cos(h.line_angle_rad)])
            rec.log(
                "ground/heading",
                rr.LineStrips2D(
                    [[c - 40 * u, c + 40 * u]],
                    colors=[255, 200, 0],
                    labels=[f"{np.degrees(h.heading_error_rad):+.2f} deg"],
                ),
            )
        else:
            rec.log("ground/heading", rr.Clear(recursive=False))
        obs = result.observation
        polys = self.pipeline.geometry.outline_px(obs.heading_error_rad)
        cells = [np.vstack([p, p[:1]]) for k, p in polys.items() if not k.startswith("box")]
        rec.log("ground/cells", rr.LineStrips2D(cells, colors=[90, 120, 255], radii=0.6))
        boxes = [np.vstack([polys[f"box{b.box}"], polys[f"box{b.box}"][:1]]) for b in obs.boxes]
        bcol = [[60, 255, 60] if b.lit else [160, 160, 160] for b in obs.boxes]
        rec.log(
            "ground/boxes", rr.LineStrips2D(boxes, colors=bcol, radii=0.8, labels=[f"box {b.box}" for b in obs.boxes])
        )
        rec.log("observation", rr.TextDocument(text or observation_markdown(result), media_type="text/markdown"))
        for k, v in result.stage_ms.items():
            rec.log(f"timing/{k}", rr.Scalars(v))

    def close(self) -> None:
        """Flush, and move the recording into place atomically."""
        finish_recording(self.rec, self._tmp, self._final)
        self._tmp = None

    def abort(self) -> None:
        """Stop without keeping the recording (after an error or an interruption)."""
        abort_recording(self.rec, self._tmp)
        self._tmp = None


def observation_markdown(result) -> str:
    obs = result.observation
    lines = ["| box | lit | conf | dots |", "|---|---|---|---|"]
    lines += [f"| {b.box} | {'yes' if b.lit else 'no'} | {b.confidence:.2f} | {b.n_dots} |" for b in obs.boxes]
    lines += ["", "visited: " + ", ".join(f"sub-cell {k}: {'yes' if v else 'no'}" for k, v in obs.visited.items()), ""]
    lines += ["| neighbour | marks | red |", "|---|---|---|"]
    lines += [
        f"| {n.direction} | {'yes' if n.has_marks else 'no'} | {'yes' if n.has_red else 'no'} |"
        for n in obs.neighbours.values()
    ]
    h = result.heading
    lines += [
        "",
        f"heading: {np.degrees(h.heading_error_rad):+.2f} deg (residual {1000 * h.residual_m:.2f} mm)"
        if h.ok
        else f"heading: no fit ({h.reason})",
        f"total {result.total_ms:.2f} ms",
    ]
    return "\n".join(lines)

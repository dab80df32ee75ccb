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


class _Rerun:
    """rerun, imported when one of its names is first read: it costs a command ~0.35 s of import,
    which a run that records nothing (most runs) should not pay for importing a module that can
    record."""

    def __getattr__(self, attr: str):
        import rerun

        return getattr(rerun, attr)


class _RerunBlueprint:
    """``rerun.blueprint``, imported when one of its names is first read (as :data:`rerun_sdk`)."""

    def __getattr__(self, attr: str):
        import rerun.blueprint

        return getattr(rerun.blueprint, attr)


#: ``rerun`` and ``rerun.blueprint`` for the modules that record: imported on first use
rerun_sdk = _Rerun()
rerun_blueprint = _RerunBlueprint()
rr = rerun_sdk
rrb = rerun_blueprint

__all__ = [
    "ENTITY_PATHS",
    "INTERRUPTED_PROPERTY",
    "PipelineLogger",
    "Recorder",
    "RecordingFile",
    "Recordings",
    "blueprint",
    "check_recording_path",
    "layout",
    "rerun_blueprint",
    "rerun_sdk",
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


def layout(root: rrb.Container, *, timeline: str) -> rrb.Blueprint:
    """A recording's default blueprint: the views in ``root``, the time panel open on
    ``timeline`` (its other timelines one click away), the blueprint and selection panels
    folded away until wanted."""
    return rrb.Blueprint(
        root,
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="expanded", timeline=timeline),
    )


def blueprint() -> rrb.Blueprint:
    """The pipeline's layout: raw and dark-subtracted frames, the ground view with its cells,
    boxes, dots and heading, both channel images, the observation text and the stage timings,
    on the ``frame`` timeline."""
    return layout(
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
        timeline="frame",
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


class RecordingFile:
    """A rerun recording streamed to a .rrd file as it is logged: the one way the toolkit writes one.

    The stream goes to a hidden temporary sibling of ``path`` (rerun's file sink writes each
    batch as the batcher flushes it, every ``flush_tick``), so the file under the user's name
    is always a whole recording: the old one or the new one, never half of either. The end
    decides what happens to it (:meth:`end`):

    - the run ended: :meth:`close` writes rerun's footer and renames the file into place;
    - a termination signal (Ctrl-C, SIGTERM, SIGHUP): :meth:`interrupted` names the recording
      "interrupted by SIGINT" (in the viewer's recording list and in its properties), writes
      the footer all the same, and renames it into place: every entity logged before the
      signal is kept, the file verifies, and the line the run ends with says it was kept;
    - any other error: :meth:`abort` removes it.

    A SIGKILL or a power cut cannot be caught: its temporary is removed by the next run that
    writes into the folder, and the old recording stays.

    Parameters
    ----------
    path : str or pathlib.Path or None
        The .rrd file (checked by :func:`check_recording_path`; an existing one is replaced at
        the end, so check ``--force`` before). None: no file (a viewer only).
    spawn : bool
        Also stream to a spawned rerun viewer (refused at once where there is no display).
    app_id : str
        Rerun's application id: recordings of one kind share their layout in the viewer.
    default_blueprint : rerun.blueprint.Blueprint or None
        The layout the recording opens with (default: the pipeline's, :func:`blueprint`).

    Raises
    ------
    OutputError
        If ``path`` cannot be made.
    StcVisionError
        If ``spawn`` and the viewer cannot start.
    """

    def __init__(
        self,
        path: str | Path | None,
        *,
        spawn: bool = False,
        app_id: str = "stcvision",
        default_blueprint: rrb.Blueprint | None = None,
    ) -> None:
        from stcvision.errors import StcVisionError
        from stcvision.fileio import output_error, temp_sibling

        if spawn:
            check_display()
        self.rec = rr.RecordingStream(app_id)
        self.path = None if path is None else check_recording_path(path, overwrite=True)
        self._tmp: Path | None = None
        bp = default_blueprint or blueprint()
        if self.path is not None:
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                self._tmp = temp_sibling(self.path)
            except OSError as exc:
                raise output_error(self.path, exc) from None
            try:
                self.rec.save(self._tmp, default_blueprint=bp)
                self.rec.send_recording_name(self.path.name)
            except BaseException:  # a signal while the file sink starts: stop it, then remove its file
                self.abort()
                raise
        if spawn:
            try:
                self.rec.spawn(default_blueprint=bp)
            except (RuntimeError, OSError) as exc:
                self.abort()
                why = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
                raise StcVisionError(
                    f"cannot start the rerun viewer ({why}); install it (pip install rerun-sdk puts 'rerun' on "
                    "PATH) or write a file with --rrd OUT.rrd instead of --spawn"
                ) from None

    def close(self) -> None:
        """End the recording and rename it into place. After a termination signal whose
        exception a library swallowed, it is kept as :meth:`interrupted` and the signal's
        :class:`~stcvision.errors.Terminated` raised."""
        from stcvision.errors import Terminated
        from stcvision.fileio import commit_temp, raise_if_signalled

        try:
            raise_if_signalled()
        except Terminated as exc:
            self.interrupted(exc.signum)
            raise
        self.rec.flush()
        self.rec.disconnect()
        if self._tmp is not None:
            commit_temp(self._tmp, self.path)
            self._tmp = None

    def interrupted(self, signum: int) -> None:
        """End the recording after signal ``signum`` and keep it, named as interrupted."""
        import signal

        from stcvision.fileio import keep_partial

        if self._tmp is None:
            self.rec.disconnect()
            return
        try:
            why = signal.Signals(signum).name
        except ValueError:
            why = f"signal {signum}"
        self.rec.send_recording_name(f"{self.path.name} (interrupted by {why})")
        self.rec.send_property(INTERRUPTED_PROPERTY, rr.AnyValues(signal=why))
        self.rec.flush()
        self.rec.disconnect()  # the file sink writes rerun's footer: the file verifies
        keep_partial(self._tmp, self.path)
        self._tmp = None

    def abort(self) -> None:
        """Stop without keeping the recording (after an error): the old one, or none, stays."""
        from stcvision.fileio import discard_temp

        try:
            self.rec.disconnect()
        finally:
            discard_temp(self._tmp)
            self._tmp = None

    def end(self, exc: BaseException | None) -> None:
        """End as a block that raised ``exc`` (None: it did not) asks: :meth:`close`,
        :meth:`interrupted` after Ctrl-C or a termination signal (also one a library wrapped in
        another exception), :meth:`abort` after an error."""
        from stcvision.errors import signal_in_chain

        if exc is None:
            self.close()
        elif (signum := signal_in_chain(exc)) is not None:  # a signal, also one a library wrapped
            self.interrupted(signum)
        else:
            self.abort()


#: the recording property that marks a recording stopped by a signal (its value: the signal's name)
INTERRUPTED_PROPERTY = "interrupted"


class Recorder:
    """What writes a .rrd (a :class:`PipelineLogger`, the robots' recorders): ``file``, its
    :class:`RecordingFile`, and ``rec``, the stream to log to."""

    file: RecordingFile
    rec: rr.RecordingStream

    def close(self) -> None:
        """End the recording and rename it into place (:meth:`RecordingFile.close`)."""
        self.file.close()

    def abort(self) -> None:
        """Stop without keeping the recording (:meth:`RecordingFile.abort`)."""
        self.file.abort()

    def end(self, exc: BaseException | None) -> None:
        """End as :meth:`RecordingFile.end` says."""
        self.file.end(exc)


class Recordings:
    """The recordings a block writes (each a :class:`Recorder` or a :class:`RecordingFile`),
    each ended as the block ends (:meth:`RecordingFile.end`): renamed into place when it ends
    normally, kept as it stood after Ctrl-C or SIGTERM, removed after an error::

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
        try:
            for r in self._open:
                r.end(exc)
        finally:
            self._open.clear()
        return False


class PipelineLogger(Recorder):
    """Log :class:`stcvision.pipeline.PipelineResult` objects to a recording: its own file
    (:meth:`to_file`) or a stream another recorder writes (``recording``)."""

    def __init__(self, recording: rr.RecordingStream, pipeline, *, jpeg_quality: int = 80, file=None) -> None:
        self.rec = recording
        self.pipeline = pipeline
        self.q = jpeg_quality
        self.file = file

    @classmethod
    def to_file(cls, path: str | Path | None, pipeline, *, spawn: bool = False, **kw) -> PipelineLogger:
        """A logger writing the recording ``path`` (:class:`RecordingFile`; None: to a
        spawned viewer only)."""
        f = RecordingFile(path, spawn=spawn)
        return cls(f.rec, pipeline, file=f, **kw)

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

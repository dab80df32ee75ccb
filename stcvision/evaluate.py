"""Offline evaluation: run the pipeline on a dataset, score it, compare.

:func:`evaluate_dataset` runs :class:`stcvision.pipeline.Pipeline` on every frame of a dataset
(:func:`stcvision.datasets.open_dataset`), scores each against its label with
:func:`stcvision.scoring.score_frame`, and adds what ``scoring.summarize`` does not: the median
time per frame and per stage, recall by mark age (overall and per exposure setting), metrics per
exposure setting, per group, per camera (with the profile's floor error at the true dots) and per
neighbour red-light configuration, the box and obstacle
confusion matrices, and the worst frames. :func:`evaluate_images` runs the pipeline on a user's
own frames (no labels, so no accuracy); :func:`sweep_evaluation` runs a dataset's evaluation as
tasks of the sweep runner. :func:`compare` says per metric whether B is better, worse or the
same as A. The report (markdown, plots) of an evaluation is :mod:`stcvision.report`'s.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from stcvision.errors import BadInputError

__all__ = [
    "AGE_BINS_S",
    "METRICS",
    "Evaluation",
    "LabelledFrames",
    "compare",
    "evaluate_dataset",
    "evaluate_frames",
    "evaluate_image_folder",
    "evaluate_recording",
    "evaluate_images",
    "eval_chunk",
    "summarize_evaluation",
    "sweep_evaluation",
]

#: mark-age bin edges (s) of the recall breakdown: the webcam horizon is ~1 min, 0.25 s
#: exposures reach ~7 min, 1 s exposures ~15-18 min
AGE_BINS_S = (0, 10, 30, 60, 90, 120, 180, 300, 600, 900, 1200, math.inf)

#: (metric, which way is better, tolerance for "same", "abs" or "rel")
METRICS = (
    ("dot_recall", "higher", 0.002, "abs"),
    ("dot_precision", "higher", 0.002, "abs"),
    ("dot_loc_err_px_median", "lower", 0.05, "rel"),
    ("dot_loc_err_mm_median", "lower", 0.05, "rel"),
    ("dot_loc_err_mm_p95", "lower", 0.05, "rel"),
    ("heading_err_deg_rms", "lower", 0.05, "rel"),
    ("box_accuracy", "higher", 0.001, "abs"),
    ("obstacle_accuracy", "higher", 0.001, "abs"),
    ("ms_per_frame_median", "lower", 0.15, "rel"),
    ("frames_skipped", "lower", 0, "abs"),
)


def _median(v) -> float | None:
    return float(np.median(v)) if len(v) else None


def exposure_key(sensor: dict) -> str:
    """Return a readable key of a frame's exposure setting, e.g. ``"33.3 ms, gain 16"``."""
    return f"{1000 * sensor['exposure_s']:.4g} ms, gain {sensor['gain']:g}"


def recall_by_age(found: list, missed: list) -> list[dict]:
    f, m = np.asarray(found, float), np.asarray(missed, float)
    out = []
    for lo, hi in zip(AGE_BINS_S[:-1], AGE_BINS_S[1:], strict=True):
        nf = int(((f >= lo) & (f < hi)).sum())
        nm = int(((m >= lo) & (m < hi)).sum())
        if nf + nm:
            out.append(
                {
                    "age_s": [lo, None if math.isinf(hi) else hi],
                    "expected": nf + nm,
                    "found": nf,
                    "recall": nf / (nf + nm),
                }
            )
    return out


def visible_detection(result, truth: dict, *, match_m: float = 0.01) -> list[tuple[float, bool]]:
    """Return (age, found) of every visible truth dot, whatever its SNR.

    The matching of :func:`stcvision.scoring.score_frame`, to show where the visibility horizon
    cuts detection. ``result``: anything with ``dots.xy_m`` and ``dots.lit`` (the pipeline's or
    the baseline's).
    """
    from stcvision.scoring import match_dots

    d = result.dots
    m = match_dots(d.xy_m[np.flatnonzero(d.lit)], truth, None, match_m=match_m)
    return [(float(t["age_s"]), bool(f)) for t, f in zip(m.truth, m.matched, strict=True)]


def detection_by_age(pairs) -> list[dict]:
    """Fraction of *all* visible dots found, per age bin."""
    return recall_by_age([a for a, f in pairs if f], [a for a, f in pairs if not f])


def profile_floor_error_mm(profile, truth: dict, *, max_range_m: float = 0.9) -> list[float]:
    """Measure the floor error (mm) of the profile's image-to-floor map at the visible truth dots.

    Every visible truth dot within ``max_range_m`` of the robot counts: how well the profile
    fits this camera, independent of the dot search (the calibration's ground reprojection
    error, on real dot positions).
    """
    pts = [
        (d["uv_px"], d["xy_robot_m"])
        for d in truth["dots"]
        if d["visible"] and d["uv_px"] is not None and math.hypot(*d["xy_robot_m"]) <= max_range_m
    ]
    if not pts:
        return []
    uv = np.array([p[0] for p in pts], float)
    xy = np.array([p[1] for p in pts], float)
    err = 1000 * np.hypot(*(profile.image_to_robot(uv) - xy).T)
    return [float(e) for e in err[np.isfinite(err)]]


@dataclass
class FrameRecord:
    """What one frame gave, for the breakdowns and the report."""

    index: int
    frame: str
    group: str
    exposure: str
    score: Any  # stcvision.scoring.FrameScore
    total_ms: float
    stage_ms: dict
    boxes: list = field(default_factory=list)  # (truth lit, read lit)
    obstacles: list = field(default_factory=list)  # (truth red, read red)
    neighbour_config: str | None = None
    badness: float = 0.0
    visible: list = field(default_factory=list)  # (age, found) of every visible dot
    camera: str = "cam0"
    floor_err_mm: list = field(default_factory=list)  # profile image->floor error at the truth dots
    untrusted: str = ""  # why the pipeline did not trust its reading ("" when it did)

    def to_dict(self) -> dict:
        s = self.score
        return {
            "index": self.index,
            "frame": self.frame,
            "group": self.group,
            "exposure": self.exposure,
            "dots_expected": s.dots_expected,
            "dots_found": s.dots_found,
            "dots_true_positive": s.dots_true_positive,
            "heading_err_deg": s.heading_err_deg,
            "boxes_correct": s.boxes_correct,
            "boxes_total": s.boxes_total,
            "obstacles_correct": s.obstacles_correct,
            "obstacles_total": s.obstacles_total,
            "errors": s.errors,
            "total_ms": round(self.total_ms, 4),
            "badness": round(self.badness, 3),
        }

    def to_record(self) -> dict:
        """Everything, as plain JSON types (what a sweep task returns); see :meth:`from_record`."""
        import dataclasses

        return dataclasses.asdict(self)

    @classmethod
    def from_record(cls, d: dict) -> FrameRecord:
        from stcvision.scoring import FrameScore

        return cls(**{**d, "score": FrameScore(**d["score"])})


@dataclass
class Evaluation:
    """A dataset's evaluation: the summary and every frame's record.

    Attributes
    ----------
    summary : dict
        The metrics over all frames, and by age, exposure, group and camera; the frames skipped.
    records : list of FrameRecord
        One record per frame read, in label order.
    """

    summary: dict
    records: list[FrameRecord]


def _badness(s, truth_has_cell: bool) -> float:
    """How bad a frame went (for picking the worst frames to inspect)."""
    b = (s.dots_expected - len(s.dot_ages_found)) + (s.dots_found - s.dots_true_positive)
    b += 5 * (s.boxes_total - s.boxes_correct) + 5 * (s.obstacles_total - s.obstacles_correct)
    if truth_has_cell:
        b += 5 if s.heading_err_deg is None else abs(s.heading_err_deg) / 0.5
    return float(b)


def _summarize(recs: list[FrameRecord]) -> dict:
    from stcvision.scoring import summarize

    m = summarize([r.score for r in recs])
    m["ms_per_frame_median"] = _median([r.total_ms for r in recs])
    return m


def _confusion(pairs) -> list[list[int]]:
    c = [[0, 0], [0, 0]]
    for t, r in pairs:
        c[int(bool(t))][int(bool(r))] += 1
    return c


class _Progress:
    """A one-line text progress bar on stderr (only on a terminal)."""

    def __init__(self, total: int, label: str, stream=None) -> None:
        self.total, self.label = total, label
        self.stream = stream or sys.stderr
        self.on = bool(getattr(self.stream, "isatty", lambda: False)())
        self.done = 0

    def __call__(self, n: int = 1) -> None:
        self.done += n
        if self.on:
            w = 30
            k = int(w * self.done / max(self.total, 1))
            self.stream.write(f"\r{self.label} [{'#' * k}{'.' * (w - k)}] {self.done}/{self.total}")
            self.stream.flush()

    def close(self) -> None:
        if self.on:
            self.stream.write("\n")
            self.stream.flush()


def _progress(total: int, label: str):

    return _Progress(total, label)


def evaluate_dataset(ds, *, default_profile, profile=None, progress=None) -> Evaluation:
    """Run and score the pipeline on every frame of a dataset, in this process.

    :func:`evaluate_frames` on all of them, then :func:`summarize_evaluation`. A frame that
    cannot be decoded is skipped and counted; a frame of the wrong size is an error.

    Parameters
    ----------
    ds : Dataset
        The dataset (:func:`stcvision.datasets.open_dataset`).
    default_profile : Profile
        The profile of a camera the dataset holds none for.
    profile : Profile, optional
        Used for every frame if given; otherwise each camera's own profile from the dataset
        (``profiles/CAM.json``) if it has one, else ``default_profile``.
    progress : callable, optional
        ``progress(total, label)`` makes the progress bar, called with each frame done; default
        a one-line bar on a terminal's stderr.

    Returns
    -------
    Evaluation
        The summary and every frame's record.

    Raises
    ------
    BadInputError
        When a frame has the wrong size, or no frame could be read.
    """
    bar = (progress or _progress)(len(ds.labels), f"eval {ds.root.name}")
    records, skipped = evaluate_frames(
        ds, range(len(ds.labels)), default_profile=default_profile, profile=profile, on_frame=bar
    )
    close = getattr(bar, "close", None)
    if close:
        close()
    return summarize_evaluation(ds, records, skipped, profile=profile)


class LabelledFrames:
    """The frames of a dataset with what a detector needs for each, read once and cached.

    For each frame its image, its label, its camera's profile and its dark frame; the profiles
    and dark frames are read once and cached (a dataset has a few cameras and dark frames and
    many frames).

    ``profile`` (a Profile) is used for every frame if given; otherwise each camera's own profile
    from the dataset (``profiles/CAM.json``) if it has one, else ``default_profile``.
    :meth:`built` keeps one object per (camera, dark frame) built by a factory (a
    :class:`~stcvision.pipeline.Pipeline`, a :class:`~stcvision.baseline.Baseline`).
    """

    def __init__(self, ds, *, default_profile, profile=None) -> None:
        self.ds = ds
        self.default_profile = default_profile
        self.profile = profile
        self._profiles: dict[str, Any] = {}
        self._darks: dict[str, np.ndarray] = {}
        self._built: dict[tuple, Any] = {}

    def profile_for(self, cam: str):
        """Return a camera's profile: the one given, the dataset's own, or the default."""
        if self.profile is not None:
            return self.profile
        if cam not in self._profiles:
            from stcvision.profile import Profile

            p = self.ds.profile_path(cam)
            self._profiles[cam] = Profile.load(p) if p else self.default_profile
        return self._profiles[cam]

    def dark_for(self, dark_name: str | None) -> np.ndarray | None:
        """Return a dark frame of the dataset by name (None: no dark frame)."""
        if dark_name is None:
            return None
        if dark_name not in self._darks:
            from stcvision.fileio import read_image

            w, h = self.ds.image_size_px
            d = read_image(self.ds.root / dark_name, what="dark frame")
            if d.shape[:2] != (h, w):
                raise BadInputError(
                    f"dark frame {self.ds.root / dark_name} is {d.shape[1]}x{d.shape[0]}; expected {w}x{h}"
                )
            self._darks[dark_name] = d
        return self._darks[dark_name]

    def built(self, what: str, lab: dict, factory):
        """``factory(profile, dark)`` for this label's camera and dark frame, built once."""
        cam, dark_name = lab.get("camera", "cam0"), lab.get("dark")
        key = (what, cam if self.profile is None else "", dark_name)
        if key not in self._built:
            prof = self.profile_for(cam)
            prof.check_frame(tuple(reversed(self.ds.image_size_px)))
            self._built[key] = factory(prof, self.dark_for(dark_name))
        return self._built[key]

    def read(self, indices, skipped: list, on_frame=None):
        """Yield ``(index, label, image)`` of the frames ``indices``, skipping the undecodable ones.

        In label order. A frame that cannot be decoded is appended to ``skipped`` as ``{"frame",
        "reason"}``; a frame of the wrong size, or of another depth than its dark frame, is an
        error. ``on_frame(1)`` is called after each frame (progress).
        """
        from stcvision.fileio import check_same_depth, read_image

        w, h = self.ds.image_size_px
        bar = on_frame or (lambda n=1: None)
        for i in indices:
            lab = self.ds.labels[i]
            path = self.ds.root / lab["frame"]
            try:
                img = read_image(path, what="frame")
            except BadInputError as exc:
                skipped.append({"frame": lab["frame"], "reason": str(exc)})
                bar(1)
                continue
            if img.shape[:2] != (h, w):
                raise BadInputError(
                    f"frame {path} is {img.shape[1]}x{img.shape[0]}; expected {w}x{h} (the dataset's camera)"
                )
            if lab.get("dark") is not None:
                check_same_depth(img, self.dark_for(lab["dark"]), self.ds.root / lab["dark"], frame_path=path)
            yield i, lab, img
            bar(1)


def evaluate_frames(
    ds, indices, *, default_profile, profile=None, on_frame=None
) -> tuple[list[FrameRecord], list[dict]]:
    """Run and score the pipeline on the frames ``indices`` of ``ds`` (label order).

    Returns one :class:`FrameRecord` per readable frame, and ``{"frame", "reason"}`` per frame
    that could not be decoded (skipped). ``on_frame(1)`` is called after each frame (progress).
    A rendered frame is scored against the label its truth makes, a person's frame against its
    label (:func:`stcvision.scoring.score_label` for both).
    """
    from stcvision.labels import label_from_truth
    from stcvision.pipeline import Pipeline
    from stcvision.scoring import score_label

    frames = LabelledFrames(ds, default_profile=default_profile, profile=profile)
    records: list[FrameRecord] = []
    skipped: list[dict] = []
    for i, lab, img in frames.read(indices, skipped, on_frame):
        cam = lab.get("camera", "cam0")
        pipe = frames.built("pipeline", lab, lambda prof, dark: Pipeline(prof, dark=dark))
        res = pipe.process(img)
        rendered = "pose" in lab  # the simulator's truth, else a person's label
        label = label_from_truth(lab) if rendered else lab
        sc = score_label(res, label, pipe.profile)
        rec = FrameRecord(
            index=i,
            frame=lab["frame"],
            group=lab.get("group", ""),
            exposure=exposure_key(lab["sensor"]) if rendered else lab.get("exposure", "as labelled"),
            score=sc,
            total_ms=res.total_ms,
            stage_ms=dict(res.stage_ms),
            boxes=list(sc.box_pairs),
            obstacles=list(sc.red_pairs),
        )
        nb = label.get("neighbours")
        if nb:
            rec.neighbour_config = " ".join(
                f"{d}:{'R' if nb[d].get('red') else '-'}{'M' if nb[d].get('marks') else ''}"
                for d in ("right", "forward", "left")
                if d in nb
            )
        if rendered:
            rec.visible = visible_detection(res, lab)
            rec.floor_err_mm = profile_floor_error_mm(pipe.profile, lab)
        rec.camera = cam
        rec.untrusted = res.untrusted
        rec.badness = _badness(sc, "heading_error_deg" in label)
        records.append(rec)
    return records, skipped


def summarize_evaluation(ds, records: list[FrameRecord], skipped: list[dict], *, profile=None) -> Evaluation:
    """Summarise the frames' records as :func:`evaluate_dataset` does.

    The summary of :func:`evaluate_dataset` from the frames' records (in any grouping: the
    records of several :func:`evaluate_frames` calls, e.g. the tasks of a sweep).
    """
    from stcvision.pipeline import STAGES

    records = sorted(records, key=lambda r: r.index)
    if not records:
        raise BadInputError(f"no frame of {ds.root} could be read ({len(skipped)} skipped)")

    summary = {
        "dataset": str(ds.root),
        "recipe": ds.manifest.get("recipe_name"),
        "seed": ds.manifest.get("seed"),
        "profile": _profile_source(ds, profile),
    }
    summary.update(_summarize(records))
    summary["frames_skipped"] = len(skipped)
    # readings the pipeline itself marked untrusted (a lit frame, a dark frame of another camera):
    # scored like the rest, and counted, so that a set of real frames shows how many it refused
    summary["frames_untrusted"] = sum(1 for r in records if r.untrusted)
    summary["untrusted"] = [{"frame": r.frame, "reason": r.untrusted} for r in records if r.untrusted][:10]
    summary["skipped"] = skipped
    summary["stage_ms_median"] = {s: _median([r.stage_ms[s] for r in records]) for s in STAGES}
    found = [a for r in records for a in r.score.dot_ages_found]
    missed = [a for r in records for a in r.score.dot_ages_missed]
    summary["by_age"] = recall_by_age(found, missed)
    summary["visible_detected_by_age"] = detection_by_age([p for r in records for p in r.visible])
    by_exp: dict[str, list] = {}
    by_group: dict[str, list] = {}
    by_conf: dict[str, list] = {}
    for r in records:
        by_exp.setdefault(r.exposure, []).append(r)
        by_group.setdefault(r.group, []).append(r)
        if r.neighbour_config is not None:
            by_conf.setdefault(r.neighbour_config, []).append(r)
    summary["by_exposure"] = {}
    for k, recs in by_exp.items():
        m = _summarize(recs)
        m["by_age"] = recall_by_age(
            [a for r in recs for a in r.score.dot_ages_found], [a for r in recs for a in r.score.dot_ages_missed]
        )
        m["visible_detected_by_age"] = detection_by_age([p for r in recs for p in r.visible])
        summary["by_exposure"][k] = m
    summary["by_group"] = {k: _summarize(v) for k, v in by_group.items()}
    by_cam: dict[str, list] = {}
    for r in records:
        by_cam.setdefault(r.camera, []).append(r)
    summary["by_camera"] = {}
    for k, recs in by_cam.items():
        m = _summarize(recs)
        err = [e for r in recs for e in r.floor_err_mm]
        m["profile"] = "given" if profile is not None else ds.manifest["cameras"].get(k, {}).get("profile") or "default"
        m["profile_floor_err_mm_median"] = _median(err)
        m["profile_floor_err_mm_p95"] = float(np.percentile(err, 95)) if err else None
        m["profile_floor_err_points"] = len(err)
        summary["by_camera"][k] = m
    allerr = [e for r in records for e in r.floor_err_mm]
    summary["profile_floor_err_mm_median"] = _median(allerr)
    summary["by_neighbour_config"] = {
        k: {
            "frames": len(v),
            "obstacles_scored": sum(len(r.obstacles) for r in v),
            "obstacle_accuracy": _ratio(
                sum(t == x for r in v for t, x in r.obstacles), sum(len(r.obstacles) for r in v)
            ),
            "box_accuracy": _ratio(sum(t == x for r in v for t, x in r.boxes), sum(len(r.boxes) for r in v)),
        }
        for k, v in sorted(by_conf.items())
    }
    summary["box_confusion"] = _confusion(p for r in records for p in r.boxes)
    summary["obstacle_confusion"] = _confusion(p for r in records for p in r.obstacles)
    worst = sorted(records, key=lambda r: (-r.badness, r.index))
    summary["worst_frames"] = [r.to_dict() for r in worst[:10] if r.badness > 0]
    return Evaluation(summary, records)


def _profile_source(ds, profile) -> str:
    if profile is not None:
        return "given"
    return "per camera" if any(c.get("profile") for c in ds.manifest["cameras"].values()) else "default"


def _ratio(a, b):
    return a / b if b else None


def log_worst(ev: Evaluation, ds, rrd_path, *, default_profile, profile=None, n: int = 10) -> list[str]:
    """Re-run the pipeline on the ``n`` worst frames and log every stage to a rerun file."""
    from stcvision.fileio import read_image
    from stcvision.pipeline import Pipeline
    from stcvision.rr import PipelineLogger, Recordings, observation_markdown

    worst = [r for r in sorted(ev.records, key=lambda r: (-r.badness, r.index)) if r.badness > 0][:n]
    if not worst:
        worst = ev.records[:1]
    frames = LabelledFrames(ds, default_profile=default_profile, profile=profile)
    logger = None
    logged = []
    with Recordings() as recs:
        for j, r in enumerate(worst):
            lab = ds.labels[r.index]
            pipe = frames.built("pipeline", lab, lambda prof, dark: Pipeline(prof, dark=dark))
            res = pipe.process(read_image(ds.root / lab["frame"], what="frame"))
            if logger is None:
                logger = recs.add(PipelineLogger.to_file(rrd_path, pipe))
            else:
                logger.pipeline = pipe
            errs = "\n".join(f"- {e}" for e in r.score.errors) or "- none"
            text = (
                f"**{lab['frame']}** (group {r.group}, {r.exposure}), badness {r.badness:.1f}\n\n"
                f"dots expected {r.score.dots_expected}, found {r.score.dots_found}, "
                f"matched {r.score.dots_true_positive}; heading error {r.score.heading_err_deg}\n\n"
                f"errors:\n{errs}\n\n" + observation_markdown(res)
            )
            logger.log(res, frame=j, text=text)
            logged.append(lab["frame"])
    return logged


def evaluate_images(paths: list[Path], *, profile, dark, dark_path=None, progress=None):
    """Run the pipeline on the user's own frames, one result per frame.

    Yields (path, result or None, skip reason). A frame of another depth than ``dark`` (read
    from ``dark_path``) is refused.
    """
    from stcvision.fileio import check_same_depth, read_image
    from stcvision.pipeline import Pipeline

    pipe = Pipeline(profile, dark=dark)
    bar = (progress or _progress)(len(paths), "pipeline")
    try:
        for p in paths:
            try:
                img = read_image(p, what="frame")
            except BadInputError as exc:
                print(f"stcvision eval: skipped {p}: {exc}", file=sys.stderr)
                bar(1)
                yield p, None, str(exc), pipe
                continue
            profile.check_frame(img.shape)
            if dark is not None:
                check_same_depth(img, dark, dark_path, frame_path=p)
            res = pipe.process(img)
            bar(1)
            yield p, res, None, pipe
    finally:
        close = getattr(bar, "close", None)
        if close:
            close()


# ---------------------------------------------------------------------------------------- compare
#: frames per sweep task (a frame takes ~10-40 ms: a task is ~1 s, far above the sweep's cost)
FRAMES_PER_TASK = 50


def _sha256(path) -> str:
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def eval_chunk(params: dict, seed) -> dict:
    """Run and score a chunk of a dataset's frames: a sweep task.

    Sweep task: run and score frames ``first`` to ``stop - 1`` of the dataset; their records
    and the frames skipped as unreadable. ``seed`` is not used (the pipeline draws nothing).
    """
    from stcvision.datasets import open_dataset
    from stcvision.profile import Profile

    ds = open_dataset(params["dataset"], dark=params.get("dark"))
    if _sha256(ds.root / "labels.jsonl") != params["labels_sha256"]:
        raise BadInputError(f"dataset {ds.root} changed while it was being evaluated")
    profile = Profile.load(params["profile"]) if params["profile"] else None
    default = Profile.load(params["default_profile"]) if profile is None else None
    records, skipped = evaluate_frames(
        ds, range(params["first"], params["stop"]), default_profile=default, profile=profile
    )
    return {"records": [r.to_record() for r in records], "skipped": skipped}


def sweep_evaluation(ds, *, profile_path=None, default_profile_path=None, options=None, store=None, dark_path=None):
    """Every frame of dataset ``ds`` through :func:`eval_chunk` tasks of the sweep runner.

    ``profile_path`` is used for every frame; without it each camera's own profile from the
    dataset, else ``default_profile_path``. ``options`` is a
    :class:`stcvision.sweep.SweepOptions` (workers or a Dask scheduler); with ``store`` (a
    ``.jsonl`` path) an interrupted evaluation resumes. ``dark_path``: a labelled folder's dark
    frame for the frames whose label names none (:func:`stcvision.datasets.open_labelled_folder`).
    Returns ``(Evaluation, SweepReport)``; frames skipped as unreadable are named on stderr.
    """
    import tempfile

    from stcvision.profile import Profile
    from stcvision.sweep import SweepOptions, Task, run_sweep

    if profile_path is None and default_profile_path is None:
        raise BadInputError("sweep_evaluation needs profile_path or default_profile_path")
    base = {
        "dataset": str(ds.root.resolve()),
        "labels_sha256": _sha256(ds.root / "labels.jsonl"),
        "profile": str(Path(profile_path).resolve()) if profile_path else None,
        "profile_sha256": _sha256(profile_path) if profile_path else None,
        "default_profile": None if profile_path else str(default_profile_path),
        "dark": str(Path(dark_path).resolve()) if dark_path else None,
    }
    n = len(ds.labels)
    tasks = [
        Task(
            experiment=f"{__name__}:eval_chunk",
            params={**base, "first": a, "stop": min(a + FRAMES_PER_TASK, n)},
            seed=0,
        )
        for a in range(0, n, FRAMES_PER_TASK)
    ]
    options = options or SweepOptions()
    if store:
        report = run_sweep(tasks, store, options, desc=f"eval {ds.root.name}")
    else:
        with tempfile.TemporaryDirectory(prefix="stcvision-eval-") as tmp:
            report = run_sweep(tasks, Path(tmp) / "sweep.jsonl", options, desc=f"eval {ds.root.name}")
    report.raise_if_failed(f"chunks of {ds.root}")
    records, skipped = [], []
    for r in report.results.values():
        records += [FrameRecord.from_record(d) for d in r["records"]]
        skipped += r["skipped"]
    for sk in skipped:
        print(f"stcvision eval: skipped {ds.root / sk['frame']}: {sk['reason']}", file=sys.stderr)
    profile = Profile.load(profile_path) if profile_path else None
    return summarize_evaluation(ds, records, skipped, profile=profile), report


def evaluate_image_folder(paths, *, profile, dark, dark_path=None, out, rrd=None) -> dict:
    """Run the pipeline on a user's own frames and write one JSON line per frame.

    No labels: the lines go to ``out`` (atomically, when all are done); with ``rrd`` every frame
    goes to a rerun recording.

    Returns counts and medians (dots per frame, ms per frame, heading fits), the frames skipped
    as unreadable and those whose result is untrusted (a lights-on frame, say). Without ground
    truth there is no accuracy: ``accuracy`` is None.
    """
    items = (
        ({"frame": str(p)}, res, reason, pipe)
        for p, res, reason, pipe in evaluate_images(paths, profile=profile, dark=dark, dark_path=dark_path)
    )
    return _write_results(items, out=out, rrd=rrd, dark_path=dark_path)


def evaluate_recording(frames, *, name: str, profile, dark, dark_path=None, out, rrd=None, total=None) -> dict:
    """Run the pipeline on a recording's frames and write one JSON line per frame.

    As :func:`evaluate_image_folder`, for frames that come with their time (a ROS bag's or an
    MCAP file's, :func:`stcvision.bags.open_bag`): each line names the frame by its index in the
    recording and carries its time, ``t_s`` (and ``stamp_ns``, the exact header stamp).

    Parameters
    ----------
    frames : iterable of stcvision.video.Frame
        The frames, each with its index and time.
    name : str
        The recording's name in error messages.
    profile : stcvision.profile.Profile
        The camera's calibration.
    dark : numpy.ndarray or None
        The dark frame (read from ``dark_path``), of the frames' depth.
    dark_path : str, optional
        Where the dark frame was read from (for messages and the summary).
    out : str or os.PathLike
        The results file (JSON Lines), written atomically when all frames are done.
    rrd : str, optional
        A rerun recording of every frame.
    total : int, optional
        How many frames to expect (the progress bar's length).

    Returns
    -------
    dict
        As :func:`evaluate_image_folder`'s.
    """
    from stcvision.fileio import check_same_depth
    from stcvision.pipeline import Pipeline

    def items():
        pipe = Pipeline(profile, dark=dark)
        bar = _progress(total or 0, "pipeline")
        try:
            for f in frames:
                what = f"frame {f.index} of {name}"
                profile.check_frame(f.image.shape, what=what)
                if dark is not None:
                    check_same_depth(f.image, dark, dark_path, frame_path=what)
                res = pipe.process(f.image)
                bar(1)
                ident = {"frame": f.index, "t_s": f.t_s}
                if f.stamp_ns is not None:
                    ident["stamp_ns"] = f.stamp_ns
                yield ident, res, None, pipe
        finally:
            close = getattr(bar, "close", None)
            if close:
                close()

    return _write_results(items(), out=out, rrd=rrd, dark_path=dark_path)


def _write_results(items, *, out, rrd, dark_path) -> dict:
    """Write the results file of ``items`` and return the counts and medians.

    ``items`` yields a frame's identifying fields, its result or None, the reason it was
    skipped, and the pipeline; the counts and medians are :func:`evaluate_image_folder`'s.
    """
    import os

    from stcvision.fileio import check_output_file, commit_temp, discard_temp, dumps, output_error, temp_sibling
    from stcvision.rr import Recordings

    out = check_output_file(Path(out), overwrite=True, what="results file")
    logger = None
    ms, skipped, fits, ndots, untrusted = [], [], 0, [], []
    tmp = None
    # the lines stream into a temporary beside ``out``, renamed over it when all are done: a
    # recording's frames are too many to hold their results in memory
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = temp_sibling(out)
        with open(tmp, "w") as fh, Recordings() as recs:
            for i, (ident, res, reason, pipe) in enumerate(items):
                if res is None:
                    skipped.append({"frame": ident["frame"], "reason": reason})
                    fh.write(dumps({**ident, "skipped": reason}, indent=None) + "\n")
                    continue
                if rrd and logger is None:
                    from stcvision.rr import PipelineLogger

                    logger = recs.add(PipelineLogger.to_file(rrd, pipe))
                if logger is not None:
                    logger.log(res, frame=i)
                d = res.to_dict()
                if res.untrusted:  # e.g. a lit (lights-on) frame, or no dark frame on a sensor that needs one
                    untrusted.append({"frame": ident["frame"], "reason": res.untrusted})
                fh.write(dumps({**ident, **d}, indent=None) + "\n")
                ms.append(res.total_ms)
                fits += bool(res.heading.ok)
                ndots.append(len(d["dots"]))
            fh.flush()
            os.fsync(fh.fileno())
        commit_temp(tmp, out)
    except OSError as exc:
        discard_temp(tmp)
        if exc.filename is None or Path(exc.filename).resolve() not in (out.resolve(), tmp and tmp.resolve()):
            raise
        raise output_error(out, exc) from None
    except BaseException:
        discard_temp(tmp)
        raise
    return {
        "frames": len(ms),
        "frames_skipped": len(skipped),
        "skipped": skipped,
        "frames_untrusted": len(untrusted),
        "untrusted": untrusted,
        "results": str(out),
        "rrd": rrd,
        "dark": dark_path,
        "dots_per_frame_median": _median(ndots),
        "heading_fits": fits,
        "ms_per_frame_median": _median(ms),
        "accuracy": None,
        "note": "no labels: the pipeline ran, but without ground truth there is no accuracy to report",
    }


def compare(a: dict, b: dict, *, names=("A", "B")) -> dict:
    """Per metric: B better, worse or the same as A (within the metric's tolerance)."""
    for d, nm in zip((a, b), names, strict=True):
        if not isinstance(d, dict) or "dot_recall" not in d or "frames" not in d:
            raise BadInputError(f"{nm} is not the output of 'stcvision eval DIR --json' (no dot_recall)")
    rows = []
    for name, better, tol, kind in METRICS:
        va, vb = a.get(name), b.get(name)
        if va is None and vb is None:
            verdict, delta = "n/a", None
        elif va is None or vb is None:
            verdict, delta = "n/a", None
        else:
            delta = vb - va
            lim = tol * abs(va) if kind == "rel" else tol
            if abs(delta) <= lim:
                verdict = "same"
            else:
                verdict = "better" if (delta > 0) == (better == "higher") else "worse"
        rows.append({"metric": name, "a": va, "b": vb, "change": delta, "verdict": verdict, "better_is": better})
    same_set = (a.get("recipe"), a.get("seed"), a.get("frames")) == (b.get("recipe"), b.get("seed"), b.get("frames"))
    counts = {v: sum(r["verdict"] == v for r in rows) for v in ("better", "worse", "same")}
    return {"a": names[0], "b": names[1], "same_dataset": same_set, "rows": rows, **counts}

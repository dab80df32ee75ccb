"""The pipeline against the plain-OpenCV baseline (:mod:`stcvision.baseline`), side by side.

:func:`compare_detectors` runs every detector on the same labelled frames in one process, frame
by frame (so a busy machine slows them alike), and scores each with the project's matching
(:func:`stcvision.scoring.match_dots`): recall of the dots that should be found (expected SNR
>= 8, the scoring's rule) overall, by SNR and by mark age; precision; the median localisation
error in image pixels, over each detector's own matches and over the dots every detector
matched (the fair comparison: a detector that finds more faint dots localises them worse);
the fraction of *all* visible dots found by age (faint marks, past the SNR-8 line); and the
bright dots missed, for diagnosis. :func:`format_comparison` prints it as a table.
:func:`time_detectors` times them on the same frames without labels (``stcvision bench``).

Used by ``stcvision bench`` and by the comparison of the pipeline with the baseline in
docs/results/pipeline.md, "Beside a plain-OpenCV baseline".
"""

from __future__ import annotations

import math
import time

import numpy as np

__all__ = [
    "FAINT_AGE_S",
    "SNR_BINS",
    "compare_detectors",
    "default_detectors",
    "format_comparison",
    "time_detectors",
]

#: SNR bin edges of the recall breakdown (8: the scoring's "should be found" line)
SNR_BINS = (8.0, 12.0, 20.0, 50.0, math.inf)
#: mark ages (s) whose visible dots measure the faint-mark reach (past the webcam's ~67 s horizon)
FAINT_AGE_S = (90.0, 120.0)
SNR_VISIBLE = 8.0


def default_detectors(pipeline_params=None) -> dict:
    """name -> factory ``(profile, dark) -> detector`` (``.process(frame)`` giving dots with
    ``xy_m`` and ``lit``, or a result with ``.dots``): the pipeline and both baselines."""
    from stcvision.baseline import Baseline
    from stcvision.pipeline import Pipeline

    return {
        "pipeline": lambda prof, dark: Pipeline(prof, pipeline_params, dark=dark),
        "baseline": lambda prof, dark: Baseline(prof, dark, method="threshold"),
        "blob": lambda prof, dark: Baseline(prof, dark, method="blob"),
    }


def _dots(result):
    return getattr(result, "dots", result)


class _Tally:
    """One detector's outcomes over the frames."""

    def __init__(self) -> None:
        self.ms: list[float] = []
        self.n_found = 0
        self.n_tp = 0
        # per visible truth dot: (frame index, truth id) -> (snr, age, found, err_px)
        self.dots: dict[tuple[int, int], tuple[float, float, bool, float]] = {}

    def add(self, i: int, m, ms: float) -> None:
        self.ms.append(ms)
        self.n_found += m.n_found
        self.n_tp += m.n_true_positive
        for t, f, e in zip(m.truth, m.matched, m.err_px, strict=True):
            self.dots[(i, t["id"])] = (float(t["snr"]), float(t["age_s"]), bool(f), float(e))


def _recall_rows(rows: list[tuple[float, bool]], edges) -> list[dict]:
    out = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        sel = [f for v, f in rows if lo <= v < hi]
        if sel:
            out.append({"range": [lo, None if math.isinf(hi) else hi], "expected": len(sel), "found": int(sum(sel))})
            out[-1]["recall"] = out[-1]["found"] / len(sel)
    return out


def _summary(t: _Tally, common: set, labels) -> dict:
    from stcvision.evaluate import AGE_BINS_S

    bright = [(k, v) for k, v in t.dots.items() if v[0] >= SNR_VISIBLE]
    found = sum(v[2] for _, v in bright)
    lo, hi = FAINT_AGE_S
    faint = [v[2] for v in t.dots.values() if lo <= v[1] < hi]
    err = [v[3] for v in t.dots.values() if v[2] and not math.isnan(v[3])]
    err_c = [t.dots[k][3] for k in common if not math.isnan(t.dots[k][3])]
    missed = sorted((k for k, v in bright if not v[2]), key=lambda k: -t.dots[k][0])
    return {
        "ms_per_frame": float(np.median(t.ms)) if t.ms else None,
        "dots_expected": len(bright),
        "dots_found": int(found),
        "recall": found / len(bright) if bright else None,
        "recall_by_snr": _recall_rows([(v[0], v[2]) for _, v in bright], SNR_BINS),
        "recall_by_age": _recall_rows([(v[1], v[2]) for _, v in bright], AGE_BINS_S),
        "detections": t.n_found,
        "false_detections": t.n_found - t.n_tp,
        "precision": t.n_tp / t.n_found if t.n_found else None,
        "loc_err_px_median": float(np.median(err)) if err else None,
        "loc_err_px_median_common": float(np.median(err_c)) if err_c else None,
        "faint_visible": len(faint),
        "faint_found": int(sum(faint)),
        "faint_recall": sum(faint) / len(faint) if faint else None,
        "missed": [
            {
                "frame": labels[i]["frame"],
                "truth_id": j,
                "snr": round(t.dots[(i, j)][0], 2),
                "age_s": round(t.dots[(i, j)][1], 1),
            }
            for i, j in missed[:20]
        ],
    }


def compare_detectors(
    ds, *, default_profile, profile=None, indices=None, detectors: dict | None = None, on_frame=None
) -> dict:
    """Run ``detectors`` (name -> factory, default :func:`default_detectors`) on the frames
    ``indices`` (default all) of the dataset ``ds``, in turn on each frame, and score them.

    Returns ``{"frames", "skipped", "common_dots", "faint_age_s", "detectors": {name: summary}}``;
    a summary holds ``ms_per_frame`` (median), ``recall`` / ``dots_expected`` (expected SNR >= 8),
    ``recall_by_snr``, ``recall_by_age``, ``precision``, ``false_detections``,
    ``loc_err_px_median`` (own matches), ``loc_err_px_median_common`` (the ``common_dots``
    every detector matched), ``faint_recall`` (visible dots of :data:`FAINT_AGE_S`, any SNR) and
    ``missed`` (up to 20 SNR >= 8 dots not found, brightest first).
    """
    from stcvision.evaluate import LabelledFrames
    from stcvision.scoring import match_dots

    detectors = detectors or default_detectors()
    frames = LabelledFrames(ds, default_profile=default_profile, profile=profile)
    tallies = {name: _Tally() for name in detectors}
    skipped: list[dict] = []
    n = 0
    clock = time.perf_counter_ns
    for i, lab, img in frames.read(range(len(ds.labels)) if indices is None else indices, skipped, on_frame):
        n += 1
        for name, factory in detectors.items():
            det = frames.built(name, lab, factory)
            t0 = clock()
            d = _dots(det.process(img))
            ms = (clock() - t0) / 1e6
            tallies[name].add(i, match_dots(d.xy_m[np.flatnonzero(d.lit)], lab, det.profile), ms)
    common = set.intersection(*({k for k, v in t.dots.items() if v[2]} for t in tallies.values())) if n else set()
    return {
        "frames": n,
        "skipped": len(skipped),
        "common_dots": len(common),
        "faint_age_s": list(FAINT_AGE_S),
        "detectors": {name: _summary(t, common, ds.labels) for name, t in tallies.items()},
    }


def time_detectors(detectors: dict, frames: list, repeats: int) -> dict:
    """Median ms per frame of each built detector (name -> object with ``.process``) over
    ``repeats`` frames cycling through ``frames``, taking turns on each frame."""
    clock = time.perf_counter_ns
    ms: dict[str, list[float]] = {name: [] for name in detectors}
    for d in detectors.values():
        d.process(frames[0])  # warm up
    for k in range(repeats):
        img = frames[k % len(frames)]
        for name, d in detectors.items():
            t0 = clock()
            d.process(img)
            ms[name].append((clock() - t0) / 1e6)
    return {name: float(np.median(v)) for name, v in ms.items()}


def _pct(x) -> str:
    return "-" if x is None else f"{100 * x:.1f} %"


def format_comparison(c: dict) -> str:
    """The comparison as a small text table (one column per detector)."""
    names = list(c["detectors"])
    ds = c["detectors"]
    lo, hi = c["faint_age_s"]
    rows = [
        ("ms per frame", [f"{ds[n]['ms_per_frame']:.2f}" if ds[n]["ms_per_frame"] else "-" for n in names]),
        (
            "recall, SNR >= 8",
            [f"{_pct(ds[n]['recall'])} ({ds[n]['dots_found']}/{ds[n]['dots_expected']})" for n in names],
        ),
    ]
    for j, b in enumerate(ds[names[0]]["recall_by_snr"]):
        label = f"  SNR {b['range'][0]:g}-{b['range'][1]:g}" if b["range"][1] else f"  SNR >= {b['range'][0]:g}"
        rows.append((label, [_pct(ds[n]["recall_by_snr"][j]["recall"]) for n in names]))
    rows += [
        ("precision", [f"{_pct(ds[n]['precision'])} ({ds[n]['false_detections']} false)" for n in names]),
        ("loc. error, px median", [f"{ds[n]['loc_err_px_median']:.3f}" for n in names]),
        (f"  on the {c['common_dots']} common dots", [f"{ds[n]['loc_err_px_median_common']:.3f}" for n in names]),
        (
            f"visible {lo:g}-{hi:g} s dots found",
            [f"{_pct(ds[n]['faint_recall'])} of {ds[n]['faint_visible']}" for n in names],
        ),
    ]
    w0 = max(len(r[0]) for r in rows)
    w = [max(len(n), *(len(r[1][k]) for r in rows)) for k, n in enumerate(names)]
    out = [" " * w0 + "  " + "  ".join(n.rjust(w[k]) for k, n in enumerate(names))]
    out += [r[0].ljust(w0) + "  " + "  ".join(v.rjust(w[k]) for k, v in enumerate(r[1])) for r in rows]
    return f"{c['frames']} labelled frames\n" + "\n".join(out)

"""Does a rescaled profile read a resized frame as the original reads the original?

Each frame of a rendered dataset and its dark frame are resized (``cv2.INTER_AREA`` down,
``cv2.INTER_LINEAR`` up, as :func:`~stcvision.calibration.rescale.rescale_profile` assumes)
and read with its camera's profile rescaled to the new size; the reading is compared with the
original's on the original frame: the cell observation (the five boxes lit, each neighbour's
marks and red light), the heading, and every lit dot (the nearest within a tolerance)::

    python -m stcvision.calibration.rescale_check DATASET [--scales 0.5,0.75,1.5,2]
"""

from __future__ import annotations

import argparse
import json
import math

import cv2
import numpy as np

from stcvision.calibration.rescale import rescale_profile
from stcvision.errors import BadInputError

__all__ = ["DOT_MATCH_M", "compare_rescaled", "reading_key"]

#: a dot of the rescaled reading is the original's when within this distance on the floor: a
#: quarter of the 1.2 cm between the end dots of two marks meeting at a corner
DOT_MATCH_M = 0.003
#: the scales measured by default: half and three quarters, one and a half and twice the size
DEFAULT_SCALES = (0.5, 0.75, 1.5, 2.0)


def reading_key(obs) -> tuple:
    """The part of a cell observation a controller decides on: boxes lit, neighbours' marks and red."""
    return (
        tuple((b.box, b.lit) for b in obs.boxes),
        tuple((k, n.has_marks, n.has_red) for k, n in sorted(obs.neighbours.items())),
    )


def _resize(img: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    up = size[0] > img.shape[1]
    return cv2.resize(img, size, interpolation=cv2.INTER_LINEAR if up else cv2.INTER_AREA)


def compare_rescaled(root, scales=DEFAULT_SCALES, *, max_frames: int | None = None, on_frame=None) -> dict:
    """Read every frame of a dataset at each scale and compare with the original's reading.

    Parameters
    ----------
    root : str or Path
        A dataset made by ``stcvision dataset generate`` (frames with their dark frames).
    scales : sequence of float
        The resolutions, as multiples of the dataset's.
    max_frames : int, optional
        Read at most this many frames.
    on_frame : callable, optional
        Called with the frame's index after each frame (progress).

    Returns
    -------
    dict
        Per scale: frames, the share whose cell observation equals the original's, untrusted
        and misread counts, the share of the original's lit dots found within
        :data:`DOT_MATCH_M`, the rescaled reading's dots the original has not, and the heading's
        median and 90th-percentile difference (deg).
    """
    from stcvision.calibration.profiles import default_profile_path
    from stcvision.datasets.reading import open_dataset
    from stcvision.pipeline import Pipeline
    from stcvision.profile import Profile

    ds = open_dataset(root)
    w0, h0 = ds.image_size_px
    scales = [float(k) for k in scales]
    pipes: dict = {}
    acc = {k: {"frames": 0, "same": 0, "untrusted": 0, "dots": 0, "matched": 0, "extra": 0, "dh": []} for k in scales}
    labels = ds.labels[:max_frames] if max_frames else ds.labels
    for i, lab in enumerate(labels):
        cam = lab["camera"]
        frame = cv2.imread(str(ds.root / lab["frame"]), cv2.IMREAD_UNCHANGED)
        dark = cv2.imread(str(ds.root / lab["dark"]), cv2.IMREAD_UNCHANGED) if lab.get("dark") else None
        if frame is None:
            raise BadInputError(f"{ds.root / lab['frame']} cannot be read as an image")
        if (cam, 1.0) not in pipes:
            pipes[(cam, 1.0)] = Pipeline(Profile.load(ds.profile_path(cam) or default_profile_path()))
        a = pipes[(cam, 1.0)].process(frame, dark=dark)
        da = a.dots.xy_m[a.dots.lit]
        for k in scales:
            size = (round(w0 * k), round(h0 * k))
            if (cam, k) not in pipes:
                pipes[(cam, k)] = Pipeline(rescale_profile(pipes[(cam, 1.0)].profile, size))
            b = pipes[(cam, k)].process(_resize(frame, size), dark=None if dark is None else _resize(dark, size))
            s = acc[k]
            s["frames"] += 1
            if b.untrusted:
                s["untrusted"] += 1
            elif reading_key(b.observation) == reading_key(a.observation):
                s["same"] += 1
            db = b.dots.xy_m[b.dots.lit]
            s["dots"] += len(da)
            if len(da) and len(db):
                d = np.linalg.norm(da[:, None] - db[None], axis=2)
                s["matched"] += int((d.min(axis=1) < DOT_MATCH_M).sum())
                s["extra"] += int((d.min(axis=0) >= DOT_MATCH_M).sum())
            else:
                s["extra"] += len(db)
            s["dh"].append(abs(b.observation.heading_error_rad - a.observation.heading_error_rad))
        if on_frame is not None:
            on_frame(i)
    out = {}
    for k, s in acc.items():
        n, dh = s["frames"], np.degrees(s.pop("dh"))
        out[f"{k:g}"] = {
            **s,
            "size_px": [round(w0 * k), round(h0 * k)],
            "same_rate": s["same"] / n,
            "misread": n - s["same"] - s["untrusted"],
            "dots_matched_rate": s["matched"] / max(s["dots"], 1),
            "heading_diff_deg_median": float(np.median(dh)),
            "heading_diff_deg_p90": float(np.percentile(dh, 90)),
        }
    return out


def main(argv=None) -> int:
    """Print the comparison of :func:`compare_rescaled` as JSON."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset")
    ap.add_argument("--scales", default=",".join(f"{k:g}" for k in DEFAULT_SCALES))
    ap.add_argument("--max-frames", type=int, default=None)
    a = ap.parse_args(argv)
    scales = [float(x) for x in a.scales.split(",")]
    if not all(math.isfinite(k) and k > 0 for k in scales):
        ap.error("--scales: positive numbers")

    def progress(i):
        print(f"\rframe {i + 1}", end="", flush=True, file=__import__("sys").stderr)

    r = compare_rescaled(a.dataset, scales, max_frames=a.max_frames, on_frame=progress)
    print(json.dumps(r, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Labelling a folder of real frames: the pipeline proposes each frame's label, a person corrects
it on a review sheet, and the corrected labels come back as the folder's ``labels.jsonl``.

:func:`propose_label` writes what the pipeline read as a label (:mod:`stcvision.labels`: boxes,
neighbours' red lights and marks, the heading error, the dots found, in image pixels).
:func:`write_review_sheet` writes one self-contained HTML page (no server, no network: it opens
from the disk in any browser) showing, per frame, the frame with the proposed dots circled, the
ground view the pipeline read, and a form holding the proposal: a person sets each box and
neighbour to what the frame shows (or "not scored"), types the heading, keeps or drops the
proposed dots, and presses *Make labels.jsonl*, which fills the page's text box and offers the
file for download. :func:`accept_labels` checks the file a person made and writes it into the
folder, where ``stcvision eval FOLDER`` scores the pipeline against it.
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

import numpy as np

from stcvision.errors import BadInputError
from stcvision.stc_geometry import BOXES, NEIGHBOURS

__all__ = ["REVIEW_FILES", "accept_labels", "propose_label", "review_folder", "write_review_sheet"]

#: the files of a review sheet's folder besides its pictures
REVIEW_FILES = ("index.html", "proposed.jsonl")
#: a proposed dot's circle on the review sheet's frame (px), drawn in the frame's own pixels
DOT_RING_PX = 6


def propose_label(result, frame_name: str, profile) -> dict:
    """What the pipeline read of one frame, as a label to correct.

    Parameters
    ----------
    result : stcvision.pipeline.PipelineResult
        The pipeline's reading of the frame.
    frame_name : str
        The frame's file, relative to its folder.
    profile : stcvision.profile.Profile
        The frame's calibration: puts the found dots back in image pixels.

    Returns
    -------
    dict
        A label (:func:`stcvision.labels.parse_label`'s form). A reading the pipeline does not
        trust proposes nothing but a ``note`` saying why: a person labels that frame from
        scratch.
    """
    if result.untrusted:
        return {"frame": frame_name, "note": f"the pipeline does not trust this frame: {result.untrusted}"}
    obs = result.observation
    lab: dict = {
        "frame": frame_name,
        "boxes": {str(b.box): bool(b.lit) for b in obs.boxes},
        "neighbours": {
            name: {"red": bool(n.has_red), "marks": bool(n.has_marks)} for name, n in obs.neighbours.items()
        },
    }
    if result.heading.ok:
        lab["heading_error_deg"] = round(math.degrees(result.heading.heading_error_rad), 3)
    d = result.dots
    xy = d.xy_m[np.flatnonzero(d.lit)]
    uv = profile.robot_to_image(xy) if len(xy) else np.zeros((0, 2))
    lab["dots"] = [{"uv_px": [round(float(u), 2), round(float(v), 2)]} for u, v in uv if np.isfinite(u + v)]
    return lab


def _choice(name: str, value, options) -> str:
    opts = "".join(f'<option value="{v}"{" selected" if v == value else ""}>{text}</option>' for v, text in options)
    return f'<select name="{html.escape(name)}">{opts}</select>'


_LIT = (("true", "lit"), ("false", "unlit"), ("null", "not scored"))
_YES = (("true", "yes"), ("false", "no"), ("null", "not scored"))


def _json_value(v) -> str:
    return "null" if v is None else ("true" if v else "false")


def _frame_section(k: int, lab: dict, frame_png: str, ground_png: str | None) -> str:
    boxes = lab.get("boxes", {})
    nb = lab.get("neighbours", {})
    rows = "".join(
        f"<tr><td>box {b}</td><td>{_choice(f'box-{b}', _json_value(boxes.get(str(b))), _LIT)}</td></tr>" for b in BOXES
    )
    rows += "".join(
        f"<tr><td>{n}</td><td>red {_choice(f'red-{n}', _json_value(nb.get(n, {}).get('red')), _YES)} "
        f"marks {_choice(f'marks-{n}', _json_value(nb.get(n, {}).get('marks')), _YES)}</td></tr>"
        for n in NEIGHBOURS
    )
    heading = lab.get("heading_error_deg")
    ndots = len(lab.get("dots", []))
    ground = f'<img src="{ground_png}" alt="ground view of {html.escape(lab["frame"])}">' if ground_png else ""
    note = html.escape(lab.get("note", ""))
    return f"""
<section class="frame" data-index="{k}">
  <h2>{html.escape(lab["frame"])}</h2>
  <p class="note">{note}</p>
  <div class="pictures"><img src="{frame_png}" alt="{html.escape(lab["frame"])} with the proposed dots">{ground}</div>
  <table>{rows}
    <tr><td>heading error (deg, counter-clockwise +)</td>
        <td><input name="heading" type="number" step="0.1" value="{"" if heading is None else heading}"></td></tr>
    <tr><td>dots</td><td><select name="dots">
        <option value="keep" selected>keep the {ndots} proposed (circled)</option>
        <option value="drop">not scored</option></select></td></tr>
  </table>
</section>"""


_SCRIPT = """
const proposals = JSON.parse(document.getElementById("proposals").textContent);
function value(section, name) {
  const el = section.querySelector(`[name="${name}"]`);
  return el.value === "null" ? null : JSON.parse(el.value);
}
function makeLabels() {
  const lines = [];
  document.querySelectorAll("section.frame").forEach((s) => {
    const p = proposals[Number(s.dataset.index)];
    const lab = {frame: p.frame};
    const boxes = {};
    BOXES.forEach((b) => { boxes[String(b)] = value(s, `box-${b}`); });
    lab.boxes = boxes;
    const nb = {};
    NEIGHBOURS.forEach((n) => { nb[n] = {red: value(s, `red-${n}`), marks: value(s, `marks-${n}`)}; });
    lab.neighbours = nb;
    const h = s.querySelector('[name="heading"]').value;
    if (h !== "") lab.heading_error_deg = Number(h);
    if (s.querySelector('[name="dots"]').value === "keep" && p.dots) lab.dots = p.dots;
    lines.push(JSON.stringify(lab));
  });
  const text = lines.join("\\n") + "\\n";
  document.getElementById("labels").value = text;
  const link = document.getElementById("download");
  link.href = URL.createObjectURL(new Blob([text], {type: "application/jsonl"}));
  link.hidden = false;
  return text;
}
document.getElementById("make").addEventListener("click", makeLabels);
"""


def write_review_sheet(
    folder: str | Path, proposals: list[dict], pictures: list[tuple[bytes, bytes | None]], *, overwrite: bool = False
) -> list[str]:
    """Write the review sheet of a folder's frames.

    Parameters
    ----------
    folder : str or Path
        The sheet's folder: ``index.html``, ``proposed.jsonl`` and each frame's pictures
        (``NNNNNN-frame.png``, ``NNNNNN-ground.png``).
    proposals : list of dict
        Each frame's proposed label (:func:`propose_label`), in the sheet's order.
    pictures : list of (bytes, bytes or None)
        Each frame's PNG with the proposed dots circled, and its ground view's PNG (None when
        the pipeline did not read it).
    overwrite : bool
        Replace a sheet already there.

    Returns
    -------
    list of str
        The files written.
    """
    from stcvision.fileio import write_set

    if len(proposals) != len(pictures):
        raise BadInputError(f"{len(proposals)} proposals for {len(pictures)} pictures; expected one each")
    files: dict[str, bytes] = {}
    sections = []
    for k, (lab, (frame_png, ground_png)) in enumerate(zip(proposals, pictures, strict=True)):
        fname = f"{k:06d}-frame.png"
        gname = f"{k:06d}-ground.png" if ground_png is not None else None
        files[fname] = frame_png
        if gname:
            files[gname] = ground_png
        sections.append(_frame_section(k, lab, fname, gname))
    data = json.dumps(proposals).replace("</", "<\\/")  # a frame's name cannot end the script element
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>stcvision labels: review</title>
<style>
body {{ font-family: sans-serif; margin: 1em; }}
.pictures img {{ max-width: 48%; margin-right: 1%; image-rendering: pixelated; }}
section.frame {{ border-top: 1px solid #888; padding: 0.5em 0; }}
.note {{ color: #a00; }}
textarea {{ width: 100%; height: 12em; font-family: monospace; }}
</style></head><body>
<h1>Review the proposed labels</h1>
<p>Each frame shows what the pipeline read: set every box and neighbour to what the frame shows
(or "not scored" where you cannot tell), correct the heading (blank: not scored), keep or drop
the circled dots, then press <em>Make labels.jsonl</em>, save the file, and give it to
<code>stcvision label FOLDER --accept labels.jsonl</code>.</p>
<p><button id="make" type="button">Make labels.jsonl</button>
<a id="download" download="labels.jsonl" hidden>save labels.jsonl</a></p>
<textarea id="labels" readonly></textarea>
{"".join(sections)}
<script id="proposals" type="application/json">{data}</script>
<script>const BOXES = {json.dumps(list(BOXES))}; const NEIGHBOURS = {json.dumps(list(NEIGHBOURS))};
{_SCRIPT}</script>
</body></html>
"""
    files["proposed.jsonl"] = "".join(json.dumps(p) + "\n" for p in proposals).encode()
    files["index.html"] = page.encode()
    return [str(p) for p in write_set(folder, files, overwrite=overwrite)]


def accept_labels(folder: str | Path, labels_file: str | Path, *, overwrite: bool = False) -> dict:
    """Check the labels a person made on the review sheet and write them as the folder's
    ``labels.jsonl``.

    Parameters
    ----------
    folder : str or Path
        The folder of frames.
    labels_file : str or Path
        The ``labels.jsonl`` the review sheet made (or any file of hand labels).
    overwrite : bool
        Replace the folder's ``labels.jsonl`` if it has one.

    Returns
    -------
    dict
        ``labels`` (the file written), ``frames`` (labelled), ``boxes`` and ``neighbours``
        (fields set, not counting "not scored").

    Raises
    ------
    BadInputError
        A line that is not a label, or a label of a frame the folder does not hold.
    """
    from stcvision.fileio import write_bytes_atomic
    from stcvision.labels import read_labels

    folder = Path(folder)
    labels = read_labels(labels_file)
    for lab in labels:
        if not (folder / lab["frame"]).is_file():
            raise BadInputError(f"{labels_file} labels {lab['frame']}, which {folder} does not hold")
    text = Path(labels_file).read_bytes()
    out = write_bytes_atomic(folder / "labels.jsonl", text, overwrite=overwrite)
    return {
        "labels": str(out),
        "frames": len(labels),
        "boxes": sum(v is not None for lab in labels for v in lab.get("boxes", {}).values()),
        "neighbours": sum(
            v is not None for lab in labels for n in lab.get("neighbours", {}).values() for v in n.values()
        ),
    }


def _display(frame: np.ndarray) -> np.ndarray:
    """A dark-room frame made visible: stretched so that its 99.9th percentile is white."""
    import cv2

    top = float(np.percentile(frame, 99.9))
    return cv2.convertScaleAbs(frame, alpha=255.0 / max(top, 1.0))


def review_folder(paths, *, root, profile, dark, out, overwrite: bool = False, on_frame=None) -> dict:
    """Propose a label for every frame of a folder and write the review sheet.

    Parameters
    ----------
    paths : list of Path
        The frames, in the sheet's order.
    root : Path
        Their folder (labels name frames relative to it).
    profile : stcvision.profile.Profile
        The camera's calibration.
    dark : numpy.ndarray or None
        The dark frame at the frames' exposure (None: read without one; readings are then
        untrusted where the sensor's dark signal shows).
    out : str or Path
        The sheet's folder.
    overwrite : bool
        Replace a sheet already there.
    on_frame : callable, optional
        Called with 1 after each frame (progress).

    Returns
    -------
    dict
        ``sheet`` (its ``index.html``), ``frames``, ``untrusted`` (frames proposed with nothing
        but a note), ``files``.
    """
    import cv2

    from stcvision.fileio import check_same_depth, image_bytes, read_image
    from stcvision.pipeline import Pipeline

    pipe = Pipeline(profile, dark=dark)
    proposals, pictures = [], []
    bar = on_frame or (lambda n=1: None)
    for path in paths:
        frame = read_image(path, what="frame")
        profile.check_frame(frame.shape, what=str(path))
        if dark is not None:
            check_same_depth(frame, dark, "the dark frame", frame_path=path)
        res = pipe.process(frame)
        lab = propose_label(res, Path(path).relative_to(root).as_posix(), profile)
        shown = _display(frame)
        for d in lab.get("dots", []):
            u, v = (int(round(c)) for c in d["uv_px"])
            cv2.circle(shown, (u, v), DOT_RING_PX, (0, 255, 255), 1, cv2.LINE_AA)
        ground = None if res.untrusted else image_bytes(res.marks_u8())
        proposals.append(lab)
        pictures.append((image_bytes(shown), ground))
        bar(1)
    files = write_review_sheet(out, proposals, pictures, overwrite=overwrite)
    return {
        "sheet": str(Path(out) / "index.html"),
        "frames": len(proposals),
        "untrusted": [p["frame"] for p in proposals if "note" in p],
        "files": len(files),
    }

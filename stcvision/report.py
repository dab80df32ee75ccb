"""The evaluation's report, and the text table of a comparison.

The report is the markdown summary, the JSON files and the plots of an
:class:`stcvision.evaluate.Evaluation` (:func:`write_report`); the comparison's is a text table
(:func:`format_compare`). The numbers are :mod:`stcvision.evaluate`'s; this module only shows them
(matplotlib with the Agg backend, imported on first use).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stcvision.errors import BadInputError
from stcvision.evaluate import Evaluation

__all__ = ["REPORT_FILES", "format_compare", "write_report"]


#: the files :func:`write_report` writes into the report folder
def format_compare(r: dict) -> str:
    """:func:`stcvision.evaluate.compare`'s verdicts as a text table, one metric a line.

    Parameters
    ----------
    r : dict
        What :func:`~stcvision.evaluate.compare` returned.

    Returns
    -------
    str
    """

    def f(v):
        return "-" if v is None else f"{v:.4g}" if isinstance(v, float) else str(v)

    out = [f"A = {r['a']}", f"B = {r['b']}"]
    if not r["same_dataset"]:
        out.append("note: A and B were measured on different datasets (recipe, seed or frame count differ)")
    out.append(f"{'metric':<24} {'A':>10} {'B':>10} {'change':>10}  B vs A")
    for row in r["rows"]:
        out.append(f"{row['metric']:<24} {f(row['a']):>10} {f(row['b']):>10} {f(row['change']):>10}  {row['verdict']}")
    out.append(f"{r['better']} better, {r['worse']} worse, {r['same']} same")
    return "\n".join(out)


REPORT_FILES = (
    "summary.md",
    "eval.json",
    "frames.jsonl",
    "recall_vs_age.png",
    "heading_error_hist.png",
    "box_confusion.png",
    "obstacle_confusion.png",
    "stage_timing.png",
)


def _png(fig, path: Path, overwrite: bool) -> None:
    from stcvision.fileio import write_figure

    write_figure(path, fig, overwrite=overwrite, dpi=100, metadata={"Software": None})


def _pct(v) -> str:
    return "-" if v is None else f"{100 * v:.1f} %"


def _num(v, fmt=".2f", unit="") -> str:
    return "-" if v is None else f"{v:{fmt}}{unit}"


def write_report(ev: Evaluation, outdir: str | Path, *, overwrite: bool = False) -> list[str]:
    """Write the markdown summary, the JSON summary, per-frame JSONL and the PNG plots.

    Parameters
    ----------
    ev : Evaluation
        What :func:`stcvision.evaluate.evaluate_dataset` (or the sweep) returned.
    outdir : str or Path
        The report folder (made if missing).
    overwrite : bool
        Replace the report files a folder already holds (else refused).

    Returns
    -------
    list of str
        The paths of the files written (:data:`REPORT_FILES`).
    """
    import matplotlib

    matplotlib.use("Agg")
    from stcvision.fileio import dumps, write_bytes_atomic, write_json

    out = _report_folder(outdir, overwrite)
    s, recs = ev.summary, ev.records
    for name, fig in _report_figures(s, recs).items():
        _png(fig, out / name, overwrite)
    write_json(out / "eval.json", s, overwrite=overwrite)
    lines = "".join(dumps(r.to_dict(), indent=None) + "\n" for r in recs)
    write_bytes_atomic(out / "frames.jsonl", lines.encode(), overwrite=overwrite)
    md = _summary_lines(s) + _age_and_worst_lines(s)
    write_bytes_atomic(out / "summary.md", ("\n".join(md) + "\n").encode(), overwrite=overwrite)
    return [str(out / n) for n in REPORT_FILES]


def _report_folder(outdir: str | Path, overwrite: bool) -> Path:
    from stcvision.errors import FileExistsRefusedError

    out = Path(outdir)
    if out.exists() and not out.is_dir():
        raise BadInputError(f"report folder {out} is a file; expected a folder")
    if not overwrite:
        taken = [n for n in REPORT_FILES if (out / n).exists()]
        if taken:
            raise FileExistsRefusedError(f"{out} already holds {', '.join(taken)}; use --force to overwrite")
    return out


def _report_figures(s: dict, recs) -> dict:
    """Make the report's plots, by file name."""
    figs = {
        "recall_vs_age.png": _plot_recall_vs_age(s),
        "heading_error_hist.png": _plot_heading_errors(s, recs),
    }
    for key, fname, what in (
        ("box_confusion", "box_confusion.png", "box marked"),
        ("obstacle_confusion", "obstacle_confusion.png", "neighbour has a red light"),
    ):
        figs[fname] = _plot_confusion(np.array(s[key]), what)
    figs["stage_timing.png"] = _plot_stage_timing(s, recs)
    return figs


def _plot_recall_vs_age(s: dict):
    import matplotlib.pyplot as plt

    # recall vs mark age, per exposure: of the dots that should be found, and of all visible dots
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    for ax, key, title in (
        (axes[0], "by_age", "Recall (dots with expected SNR >= 8)"),
        (axes[1], "visible_detected_by_age", "Found / all visible dots (the visibility horizon)"),
    ):
        for k, m in s["by_exposure"].items():
            bins = m[key]
            if not bins:
                continue
            x = [b["age_s"][0] if b["age_s"][1] is None else 0.5 * (b["age_s"][0] + b["age_s"][1]) for b in bins]
            ax.plot(x, [100 * b["recall"] for b in bins], "o-", label=k)
        ax.set_xscale("symlog", linthresh=10)
        ax.set_xlabel("mark age (s)")
        ax.set_ylim(-3, 103)
        ax.set_title(title, fontsize=10)
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("dots found (%)")
    axes[0].legend(title="exposure", fontsize=8)
    fig.tight_layout()
    return fig


def _plot_heading_errors(s: dict, recs):
    import matplotlib.pyplot as plt

    # heading error histogram
    head = [r.score.heading_err_deg for r in recs if r.score.heading_err_deg is not None]
    fig, ax = plt.subplots(figsize=(6, 4))
    if head:
        lim = max(1.0, float(np.percentile(np.abs(head), 99)) * 1.1)
        ax.hist(np.clip(head, -lim, lim), bins=40, range=(-lim, lim), color="#3a7")
    ax.set_xlabel("heading error (deg), measured - true")
    ax.set_ylabel("frames")
    ax.set_title(f"Heading error: RMS {_num(s['heading_err_deg_rms'], '.3f')} deg over {len(head)} fits")
    fig.tight_layout()
    return fig


def _plot_confusion(c: np.ndarray, what: str):
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.2, 3.8))
    ax.imshow(c, cmap="Blues")
    for i in range(2):
        for j in range(2):
            dark_cell = c[i, j] > 0.5 * max(c.max(), 1)
            ax.text(j, i, str(c[i, j]), ha="center", va="center", color="white" if dark_cell else "black", fontsize=13)
    ax.set_xticks([0, 1], ["no", "yes"])
    ax.set_yticks([0, 1], ["no", "yes"])
    ax.set_xlabel("pipeline read")
    ax.set_ylabel("truth")
    ax.set_title(what)
    fig.tight_layout()
    return fig


def _plot_stage_timing(s: dict, recs):
    import matplotlib.pyplot as plt

    # per-stage timing
    stages = list(s["stage_ms_median"])
    data = [[r.stage_ms[k] for r in recs] for k in stages]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.boxplot(data, showfliers=False)
    ax.set_xticks(range(1, len(stages) + 1), stages)
    ax.set_ylabel("ms per frame")
    ax.set_title(f"Pipeline stages (median total {_num(s['ms_per_frame_median'])} ms per frame)")
    ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    return fig


def _summary_lines(s: dict) -> list[str]:
    """summary.md up to the per-camera table."""
    md = [
        f"# Evaluation of `{s['dataset']}`",
        "",
        f"Recipe `{s['recipe']}`, seed {s['seed']}, profile: {s['profile']}. "
        f"{s['frames']} frames scored, {s['frames_skipped']} skipped.",
        "",
        "| metric | value |",
        "|---|---|",
        f"| dot recall (expected SNR >= 8) | {_pct(s['dot_recall'])} |",
        f"| dot precision | {_pct(s['dot_precision'])} |",
        f"| dot location error, median | {_num(s['dot_loc_err_mm_median'], '.2f', ' mm')}, "
        f"{_num(s['dot_loc_err_px_median'], '.2f', ' px')} |",
        f"| dot location error, p95 | {_num(s['dot_loc_err_mm_p95'], '.2f', ' mm')} |",
        f"| heading error RMS | {_num(s['heading_err_deg_rms'], '.3f', ' deg')} ({s['heading_fits']} fits) |",
        f"| box accuracy | {_pct(s['box_accuracy'])} of {s['boxes_scored']} |",
        f"| obstacle accuracy | {_pct(s['obstacle_accuracy'])} of {s['obstacles_scored']} |",
        f"| time per frame, median | {_num(s['ms_per_frame_median'], '.2f', ' ms')} |",
        "",
        "## By exposure",
        "",
        "| exposure | frames | recall | precision | loc. median | heading RMS | boxes | obstacles | ms |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for k, m in s["by_exposure"].items():
        md.append(
            f"| {k} | {m['frames']} | {_pct(m['dot_recall'])} | {_pct(m['dot_precision'])} | "
            f"{_num(m['dot_loc_err_mm_median'], '.2f', ' mm')} | {_num(m['heading_err_deg_rms'], '.3f', ' deg')} | "
            f"{_pct(m['box_accuracy'])} | {_pct(m['obstacle_accuracy'])} | {_num(m['ms_per_frame_median'])} |"
        )
    md += [
        "",
        "## By group",
        "",
        "| group | frames | recall | precision | heading RMS | boxes | obstacles |",
        "|---|---|---|---|---|---|---|",
    ]
    for k, m in s["by_group"].items():
        md.append(
            f"| {k} | {m['frames']} | {_pct(m['dot_recall'])} | {_pct(m['dot_precision'])} | "
            f"{_num(m['heading_err_deg_rms'], '.3f', ' deg')} | {_pct(m['box_accuracy'])} | "
            f"{_pct(m['obstacle_accuracy'])} |"
        )
    md += [
        "",
        "## By camera (profile floor error: the profile's image->floor map at the true dots, <= 0.9 m)",
        "",
        "| camera | profile | frames | floor error median (p95) | recall | loc. median | heading RMS | boxes |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for k, m in s["by_camera"].items():
        md.append(
            f"| {k} | {m['profile']} | {m['frames']} | {_num(m['profile_floor_err_mm_median'], '.2f', ' mm')} "
            f"({_num(m['profile_floor_err_mm_p95'], '.2f', ' mm')}) | {_pct(m['dot_recall'])} | "
            f"{_num(m['dot_loc_err_mm_median'], '.2f', ' mm')} | {_num(m['heading_err_deg_rms'], '.3f', ' deg')} | "
            f"{_pct(m['box_accuracy'])} |"
        )
    return md


def _age_and_worst_lines(s: dict) -> list[str]:
    """summary.md from the recall by age on."""
    md: list[str] = []
    md += [
        "",
        "## Recall by mark age",
        "",
        "| age (s) | dots with SNR >= 8 | recall | visible dots | found |",
        "|---|---|---|---|---|",
    ]
    vis = {tuple(b["age_s"]): b for b in s["visible_detected_by_age"]}
    by_age = {tuple(x["age_s"]): x for x in s["by_age"]}
    for key in sorted(vis, key=lambda a: a[0]):
        b = by_age.get(key)
        hi = "inf" if key[1] is None else key[1]
        md.append(
            f"| {key[0]}-{hi} | {b['expected'] if b else 0} | {_pct(b['recall'] if b else None)} | "
            f"{vis[key]['expected']} | {_pct(vis[key]['recall'])} |"
        )
    if s["by_neighbour_config"]:
        md += [
            "",
            "## Obstacles by neighbour configuration (R = red light, M = marks)",
            "",
            "| right / forward / left | frames | obstacle accuracy | box accuracy |",
            "|---|---|---|---|",
        ]
        for k, m in s["by_neighbour_config"].items():
            md.append(f"| {k} | {m['frames']} | {_pct(m['obstacle_accuracy'])} | {_pct(m['box_accuracy'])} |")
    md += ["", "## Worst frames", ""]
    md += [
        f"- `{w['frame']}` ({w['group']}): badness {w['badness']}; {'; '.join(w['errors']) or 'missed or extra dots'}"
        for w in s["worst_frames"]
    ] or ["none"]
    if s["skipped"]:
        md += ["", "## Skipped frames", ""] + [f"- `{k['frame']}`: {k['reason']}" for k in s["skipped"]]
    md += ["", "## Plots", ""]
    md += [f"![{n}]({n})" for n in REPORT_FILES if n.endswith(".png")]
    return md

"""The toolkit's own synthetic camera through every lens format: its calibrated profile is exported
as an OCamCalib, OpenCV omnidir (Mei + radtan), Kalibr double-sphere and EUCM file, written, read
back with ``stcvision calibrate import`` (the flags ``export`` prints) and its floor error measured
against the renderer's truth (ray-traced spherical mirror), beside the toolkit's own calibration:

    python docs/measurements/lens_formats.py [--out-dir DIR]

Prints a markdown table (docs/explanation/calibration.md, "Profiles from other tools"). The
spherical mirror has no single viewpoint, so every central model is an approximation of it; what the
table shows is how much each format's equations cost on top of the toolkit's own calibration.
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import numpy as np

#: floor distances (m) the errors are binned by
BINS = ((0.1, 0.3), (0.3, 0.5), (0.5, 0.7), (0.7, 0.9))
FORMATS = ("ocamcalib", "omnidir", "ds", "eucm")


def floor_points(n_rings: int = 81, n_az: int = 180) -> np.ndarray:
    rho = np.linspace(0.1, 0.9, n_rings)
    az = np.linspace(-math.pi, math.pi, n_az, endpoint=False)
    rr, aa = np.meshgrid(rho, az)
    return np.column_stack([(rr * np.cos(aa)).ravel(), (rr * np.sin(aa)).ravel()])


def floor_error_mm(profile, camera, xy: np.ndarray) -> np.ndarray:
    """Distance (mm) between each floor point and where ``profile`` puts its true image point."""
    uv, ok = camera.projector.project(xy)
    err = np.full(len(xy), np.nan)
    err[ok] = 1000 * np.hypot(*(profile.image_to_robot(uv[ok]) - xy[ok]).T)
    return err


def through_format(profile, fmt: str, folder: Path, cli):
    """Export ``profile`` as ``fmt`` (any error accepted: this measures it), import it back."""
    from stcvision.calibration.lens_files import write_lens_file
    from stcvision.calibration.lens_import import model_from_profile
    from stcvision.profile import Profile

    model, fid, flags = model_from_profile(profile, fmt, max_err_deg=math.inf)
    kalibr = fmt in ("ds", "eucm")
    path = folder / f"cam.{fmt}.{'yaml' if kalibr or fmt == 'omnidir' else 'txt'}"
    write_lens_file(path, model, "kalibr" if kalibr else fmt, overwrite=True)
    out = folder / f"back.{fmt}.json"
    argv = ["calibrate", "import", str(path), "--viewpoint-height-m", str(flags["viewpoint_height_m"])]
    argv += [f"--forward-angle-deg={flags['forward_angle_deg']}", "--rim-px", str(flags["rim_px"])]
    argv += [f"--axis-tilt-deg={flags['axis_tilt_deg'][0]},{flags['axis_tilt_deg'][1]}", "--out", str(out), "--force"]
    argv += ["--mirrored"] if flags["mirrored"] else []
    code = cli(argv)
    if code != 0:
        raise RuntimeError(f"import of the {fmt} export failed ({code})")
    return Profile.load(out), fid


def table(formats=FORMATS, folder: Path | None = None) -> list[dict]:
    from stcvision.calibration.profiles import default_profile
    from stcvision.cli import main
    from stcvision.sim_camera.camera import SyntheticCamera

    cam = SyntheticCamera()
    own = default_profile()
    xy = floor_points()
    rho = np.hypot(xy[:, 0], xy[:, 1])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = folder or Path(tmp)
        cands = [("toolkit's own calibration", own, None)]
        for fmt in formats:
            prof, fid = through_format(own, fmt, folder, lambda a: main(a + ["--json"]))
            cands.append((fmt, prof, fid))
        for name, prof, fid in cands:
            err = floor_error_mm(prof, cam, xy)
            row = {"profile": name, "fit_err_deg_max": None if fid is None else fid.elevation_err_deg_max}
            for lo, hi in BINS:
                sel = (rho >= lo) & (rho <= hi) & np.isfinite(err)
                row[f"{lo}-{hi} m median/max mm"] = (float(np.median(err[sel])), float(err[sel].max()))
            rows.append(row)
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out-dir", type=Path, help="keep the exported files here")
    a = p.parse_args(argv)
    if a.out_dir:
        a.out_dir.mkdir(parents=True, exist_ok=True)
    rows = table(folder=a.out_dir)
    keys = [k for k in rows[0] if k.endswith("mm")]
    print("| profile | export's worst elevation error (deg) | " + " | ".join(keys) + " |")
    print("|---" * (len(keys) + 2) + "|")
    for r in rows:
        fit = "-" if r["fit_err_deg_max"] is None else f"{r['fit_err_deg_max']:.3f}"
        cells = " | ".join(f"{r[k][0]:.2f} / {r[k][1]:.2f}" for k in keys)
        print(f"| {r['profile']} | {fit} | {cells} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""A profile for the same camera run at another resolution.

A webcam's modes of one sensor area (binned or resized) see the same rays at scaled pixels:
with pixel centres at integers (OpenCV's convention), a point at ``u`` in one mode is at
``k (u + 0.5) - 0.5`` in a mode ``k`` times as wide. The profile's pixel quantities (the image
size, the centre, the rim's radius) scale so; its angles, its theta polynomial and decentering
(in units of the rim's radius) and its ground view (in metres) do not change.

The profile also carries the scale (``pixel_scale``, against the calibrated camera) and how the
frames are made (``resampling``), and the pipeline follows both: its settings in mirror-image
pixels scale (the dot window, the centroid's blur) and its noise model is the resized noise's
(area averaging lowers a pixel's noise and leaves pixels nearly independent; interpolating up
makes neighbours share their noise, so a window holds more of it than independent pixels would).
A camera's own mode at the new size (its pixels' noise independent) is ``native``.
"""

from __future__ import annotations

from stcvision.errors import BadInputError
from stcvision.limits import MAX_CAMERA_SIDE_PX
from stcvision.profile import PIXEL_SCALE_RANGE, Profile

__all__ = ["rescale_profile"]

#: how far the two sides' scales may differ: a mode that crops or stretches is another camera
MAX_ASPECT_CHANGE = 0.005


def rescale_profile(profile: Profile, size: tuple[int, int], *, native: bool = False) -> Profile:
    """Return ``profile`` for the camera at another resolution.

    Parameters
    ----------
    profile : Profile
        The profile (itself perhaps rescaled).
    size : tuple of int
        The new (W, H).
    native : bool
        The frames come from the camera's own mode at that size (independent pixel noise), not
        resized from the calibrated size (OpenCV's ``INTER_AREA`` down, ``INTER_LINEAR`` up).

    Returns
    -------
    Profile
        The rescaled profile, with its scale against the calibrated camera and its resampling.

    Raises
    ------
    BadInputError
        When the size is out of range, changes the aspect ratio, or takes the scale against the
        calibrated camera outside :data:`~stcvision.profile.PIXEL_SCALE_RANGE`.
    """
    w, h = (int(x) for x in size)
    if not (1 <= w <= MAX_CAMERA_SIDE_PX and 1 <= h <= MAX_CAMERA_SIDE_PX):
        raise BadInputError(f"--size {w}x{h}: expected 1..{MAX_CAMERA_SIDE_PX} px a side")
    w0, h0 = profile.image_size_px
    kx, ky = w / w0, h / h0
    if abs(kx / ky - 1) > MAX_ASPECT_CHANGE:
        raise BadInputError(
            f"--size {w}x{h} changes the aspect ratio of {w0}x{h0} (x{kx:.4g} wide, x{ky:.4g} high): a cropped or "
            "stretched mode sees other rays; calibrate that mode"
        )
    k = (kx + ky) / 2
    total = profile.pixel_scale * k
    lo, hi = PIXEL_SCALE_RANGE
    if not lo <= total <= hi:
        raise BadInputError(
            f"--size {w}x{h} is x{total:.4g} the calibrated camera's resolution; expected x{lo:g} to x{hi:g} "
            "(the dot window would be under a pixel, or wider than the dot search's scales)"
        )
    if native or abs(total - 1) < 1e-9:
        resampling = "none"
    else:
        resampling = "area" if total < 1 else "linear"
    cu, cv = profile.center_px
    return profile.replace(
        pixel_scale=1.0 if abs(total - 1) < 1e-9 else total,
        resampling=resampling,
        image_size_px=(w, h),
        center_px=(k * (cu + 0.5) - 0.5, k * (cv + 0.5) - 0.5),
        rim_radius_px=k * profile.rim_radius_px,
        provenance={**profile.provenance, "rescaled": k, "rescaled_from_px": [w0, h0]},
    )

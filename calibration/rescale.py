"""A profile for the same camera run at another resolution.

A webcam's modes of one sensor area (binned or resized) see the same rays at scaled pixels:
with pixel centres at integers (OpenCV's convention), a point at ``u`` in one mode is at
``k (u + 0.5) - 0.5`` in a mode ``k`` times as wide. The profile's pixel quantities (the image
size, the centre, the rim's radius) scale so; its angles, its theta polynomial and decentering
(in units of the rim's radius) and its ground view (in metres) do not change.
"""

from __future__ import annotations

from stcvision.errors import BadInputError
from stcvision.limits import MAX_CAMERA_SIDE_PX
from stcvision.profile import Profile

__all__ = ["rescale_profile"]

#: how far the two sides' scales may differ: a mode that crops or stretches is another camera
MAX_ASPECT_CHANGE = 0.005


def rescale_profile(profile: Profile, size: tuple[int, int]) -> Profile:
    """``profile`` for the camera at ``size`` (W, H); refused if the aspect ratio changes."""
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
    cu, cv = profile.center_px
    return profile.replace(
        image_size_px=(w, h),
        center_px=(k * (cu + 0.5) - 0.5, k * (cv + 0.5) - 0.5),
        rim_radius_px=k * profile.rim_radius_px,
        provenance={**profile.provenance, "rescaled": k, "rescaled_from_px": [w0, h0]},
    )

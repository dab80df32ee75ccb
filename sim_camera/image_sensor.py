"""Image sensor model: photons -> electrons -> noisy BGR frames at the ADC's bit depth.

What is modelled (per pixel, per colour channel; a full-resolution RGB sensor, i.e. no Bayer
mosaic and no demosaicing):

* signal electrons ``S`` (from the optics: luminance x etendue x QE x exposure), photo-response
  non-uniformity (PRNU);
* dark current ``D = dark_current_e_s * exposure_s * dsnu`` with a fixed per-camera pattern
  (log-normal dark-signal non-uniformity and hot pixels) that a dark frame captures;
* column offsets (fixed per camera, electrons) and a black-level pedestal;
* shot noise of ``S + D`` and read noise, drawn together as one Gaussian of variance
  ``S + D + read_noise_e**2``. (Exact Poisson statistics matter only for a few electrons, where
  the read noise of several electrons already hides the difference.)
* full-well saturation (blooming and glare of saturating sources are added by the renderer
  around each such source, see :mod:`stcvision.sim_camera.camera`);
* the ADC: ``adc_bits`` b, conversion gain ``dn_per_e = gain * (2**b - 1) / full_well_e`` DN per
  electron (at gain 1 the full well spans the ADC's range), a black-level pedestal, rounding and
  clipping to ``0 .. 2**b - 1``. Frames are sensor-true: b = 8 gives (H, W, 3) uint8, b > 8
  (H, W, 3) uint16 holding the ADC counts themselves (LSB-aligned: a 12-bit frame reads
  0..4095, not scaled to 65535), the form a machine-vision or astronomy camera delivers its raw
  frames in and the form a 16-bit PNG keeps.

Defaults describe the cheap wireless webcam in the dark of the ant-like STC paper (Srour &
Abboud: "The camera we used, was not intended to work with low-light conditions"): a VGA CMOS sensor
with 6 um pixels (the OmniVision OV7725 class), a 4.7 mm f/2.0 lens, 1/30 s exposure (30 frames/s)
and the analogue gain its auto-exposure reaches in the dark (16x). Noise figures are typical of
small-pixel consumer CMOS sensors (read noise ~6 e-, dark current ~40 e-/s at room temperature), not
taken from one datasheet.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

import cv2
import numba
import numpy as np

from stcvision.errors import BadInputError

__all__ = ["ROSE_SNR", "FixedPattern", "SensorParams", "detection_snr", "digitise", "expose", "gaussian_noise"]

#: Rose criterion: an object is detectable when its SNR is at least 5 (A. Rose, 1948).
ROSE_SNR = 5.0

#: photons per second in one lumen at 555 nm (1 lm = 1/683 W; E_photon = 3.58e-19 J)
PHOTONS_PER_LUMEN_S = 4.09e15


@dataclass(frozen=True, kw_only=True, slots=True)
class SensorParams:
    """Sensor and exposure settings. Exposure and gain are the camera's *settings* (a robot may
    change them); the rest is the sensor's physics (fixed for a given camera)."""

    exposure_s: float = 1.0 / 30.0
    gain: float = 16.0
    full_well_e: float = 20000.0
    read_noise_e: float = 6.0
    dark_current_e_s: float = 40.0
    dsnu_sigma: float = 0.3
    hot_pixel_fraction: float = 0.002
    hot_pixel_factor: float = 100.0
    column_offset_e_sigma: float = 4.0
    black_level_dn: float = 8.0
    prnu_sigma: float = 0.01
    pixel_pitch_m: float = 6.0e-6
    f_number: float = 2.0
    quantum_efficiency: float = 0.5
    mirror_reflectance: float = 0.9
    phosphor_bgr: tuple[float, float, float] = (0.20, 1.0, 0.08)
    red_led_bgr: tuple[float, float, float] = (0.02, 0.06, 1.0)
    floor_bgr: tuple[float, float, float] = (0.85, 1.0, 0.95)
    bloom_fraction: float = 0.3
    glare_fraction: float = 2.0e-3
    #: the ADC's depth (8..16 bits): a camera profile's ``adc_bits`` (sim_camera/hardware.py)
    adc_bits: int = 8

    def __post_init__(self) -> None:
        if isinstance(self.adc_bits, bool) or self.adc_bits not in range(8, 17):
            raise BadInputError(f"sensor parameter adc_bits must be an integer from 8 to 16, got {self.adc_bits!r}")
        for name in ("exposure_s", "gain", "full_well_e", "pixel_pitch_m", "f_number", "quantum_efficiency"):
            if not getattr(self, name) > 0:
                raise BadInputError(f"sensor parameter {name} must be > 0, got {getattr(self, name)}")
        for name in (
            "read_noise_e",
            "dark_current_e_s",
            "dsnu_sigma",
            "hot_pixel_fraction",
            "column_offset_e_sigma",
            "black_level_dn",
            "prnu_sigma",
            "bloom_fraction",
            "glare_fraction",
        ):
            if not getattr(self, name) >= 0:
                raise BadInputError(f"sensor parameter {name} must be >= 0, got {getattr(self, name)}")
        if self.exposure_s > 60:
            raise BadInputError(f"exposure_s {self.exposure_s} is longer than a minute; expected <= 60 s")

    @property
    def max_dn(self) -> int:
        """The ADC's largest count, ``2**adc_bits - 1`` (255 for 8 bits)."""
        return (1 << self.adc_bits) - 1

    @property
    def dtype(self) -> type:
        """The frames' dtype: uint8 for an 8-bit ADC, uint16 (ADC counts) for 9-16 bits."""
        return np.uint8 if self.adc_bits == 8 else np.uint16

    @property
    def dn_per_e(self) -> float:
        """Conversion gain: digital numbers (ADC counts) per electron; at gain 1 the full well
        spans the ADC's range."""
        return self.gain * self.max_dn / self.full_well_e

    @property
    def black_dn(self) -> float:
        """The black-level pedestal in ADC counts. ``black_level_dn`` is given on the 8-bit scale
        (8 DN of 255: the webcam's); a deeper ADC keeps the same fraction of its range, so the
        pedestal is the same in electrons at any depth (``black_level_dn * max_dn / 255``: 128.5
        counts at 12 bits, 2056 at 16), many times the read and column noise it must keep off
        zero."""
        return self.black_level_dn * self.max_dn / 255.0

    @property
    def e_per_cd_m2_s(self) -> float:
        """Electrons per second collected by one pixel looking (via the mirror) at an extended
        source of 1 cd/m^2, on the optical axis, for a channel response of 1: sensor-plane
        illuminance ``pi L T / (4 N^2)`` times pixel area, photons per lumen and QE."""
        lux = np.pi * self.mirror_reflectance / (4.0 * self.f_number**2)
        return lux * self.pixel_pitch_m**2 * PHOTONS_PER_LUMEN_S * self.quantum_efficiency

    def to_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: dict) -> SensorParams:
        names = set(cls.__dataclass_fields__)
        unknown = set(d) - names
        if unknown:
            raise BadInputError(f"unknown sensor parameter(s) {sorted(unknown)}; expected some of {sorted(names)}")
        kw = {}
        for k, v in d.items():
            default = getattr(cls(), k)
            if k == "adc_bits":
                if isinstance(v, bool) or not isinstance(v, int | float) or not float(v).is_integer():
                    raise BadInputError(f"sensor parameter adc_bits must be an integer from 8 to 16, got {v!r}")
                kw[k] = int(v)
                continue
            try:
                kw[k] = tuple(float(x) for x in v) if isinstance(default, tuple) else float(v)
            except (TypeError, ValueError):
                raise BadInputError(f"sensor parameter {k} must be a number, got {v!r}") from None
            if isinstance(default, tuple) and len(kw[k]) != 3:
                raise BadInputError(f"sensor parameter {k} must be 3 numbers (B, G, R), got {v!r}")
        return cls(**kw)

    def replace(self, **kw) -> SensorParams:
        return replace(self, **kw)


@dataclass(frozen=True, eq=False)
class FixedPattern:
    """Per-camera fixed pattern noise (drawn once from the camera's own seed).

    ``dark_gain`` (H, W, 3): multiplier of the mean dark current per pixel (log-normal DSNU,
    hot pixels); ``column_offset_e`` (W,): per-column offset in electrons; ``prnu`` (H, W, 3):
    photo-response non-uniformity.
    """

    dark_gain: np.ndarray
    column_offset_e: np.ndarray
    prnu: np.ndarray
    hot: np.ndarray
    cache: dict = field(default_factory=dict, repr=False)

    @classmethod
    def draw(cls, shape_hw: tuple[int, int], s: SensorParams, rng: np.random.Generator) -> FixedPattern:
        h, w = shape_hw
        dark = rng.lognormal(-0.5 * s.dsnu_sigma**2, s.dsnu_sigma, (h, w, 3)).astype(np.float32)
        hot = rng.random((h, w)) < s.hot_pixel_fraction
        dark[hot] *= np.float32(s.hot_pixel_factor)
        cols = (rng.standard_normal(w) * s.column_offset_e_sigma).astype(np.float32)
        prnu = (1.0 + rng.standard_normal((h, w, 3)) * s.prnu_sigma).astype(np.float32)
        return cls(dark, cols, prnu, hot)


def _normal_quantiles(n: int) -> np.ndarray:
    """The standard normal's quantiles at the centres of ``n`` equal bins of probability, float32.
    The standard library's ``NormalDist.inv_cdf`` (Wichura's AS241, ~1e-16) rather than
    ``scipy.special.ndtri``: the same 65,536 float32 values (checked), without importing
    scipy.special (0.17 s) into every command that renders a frame."""
    from statistics import NormalDist

    q = NormalDist().inv_cdf
    return np.array([q((i + 0.5) / n) for i in range(n)]).astype(np.float32)


_LUT = _normal_quantiles(65536)


def _raw_matches_integers() -> bool:
    """Whether this numpy's ``integers(0, 65536, dtype=uint16)`` on PCG64 is the uint16 view of
    its raw 64-bit outputs (it splits each 32-bit draw low half first, and PCG64 each 64-bit
    output low word first), checked once on a scratch generator."""
    a, b = np.random.Generator(np.random.PCG64(12345)), np.random.Generator(np.random.PCG64(12345))
    same = np.array_equal(
        a.integers(0, 65536, size=64, dtype=np.uint16), b.bit_generator.random_raw(16).view(np.uint16)
    )
    return same and a.bit_generator.state["state"] == b.bit_generator.state["state"]


_RAW_U16 = _raw_matches_integers()


def _noise_indices(rng: np.random.Generator, shape) -> np.ndarray:
    """``rng.integers(0, 65536, size=shape, dtype=np.uint16)``, the same numbers and the same
    generator state after; for numpy's default PCG64 (no 32-bit half pending) drawn as the
    uint16 view of raw 64-bit outputs, at half the cost (measured)."""
    n = int(np.prod(shape))
    bg = rng.bit_generator
    if _RAW_U16 and n % 4 == 0 and type(bg) is np.random.PCG64 and not bg.state["has_uint32"]:
        return bg.random_raw(n // 4).view(np.uint16).reshape(shape)
    return rng.integers(0, 65536, size=shape, dtype=np.uint16)


def gaussian_noise(rng: np.random.Generator, shape) -> np.ndarray:
    """Standard normal float32 noise via a 16-bit inverse-CDF table (tails cut at 4.3 sigma).

    About 2.5x faster than ``rng.standard_normal`` for a 640x480x3 frame and exactly Gaussian
    to 1/65536 in probability; every sample is an independent draw from ``rng``.
    """
    return np.take(_LUT, _noise_indices(rng, shape))


def _dark_terms(s: SensorParams, pattern: FixedPattern, n_avg: int):
    """Per-pixel dark mean (dark current + column offset, electrons), base variance (dark +
    read noise squared) and the noise sigma of a pixel without signal, ``sqrt(var0 / n_avg)``,
    for these settings; cached on the pattern (they depend only on exposure, dark current, read
    noise and the stack)."""
    key = (s.exposure_s, s.dark_current_e_s, s.read_noise_e)
    hit = pattern.cache.get(key)
    if hit is None:
        dark = pattern.dark_gain * np.float32(s.dark_current_e_s * s.exposure_s)
        var0 = dark + np.float32(s.read_noise_e**2)
        mean0 = dark + pattern.column_offset_e[None, :, None]
        hit = (var0, mean0)
        if len(pattern.cache) > 32:
            pattern.cache.clear()
        pattern.cache[key] = hit
    var0, mean0 = hit
    skey = (*key, "sigma", n_avg)
    sigma0 = pattern.cache.get(skey)
    if sigma0 is None:
        sigma0 = pattern.cache[skey] = np.sqrt(var0 * np.float32(1.0 / n_avg))
    return var0, mean0, sigma0


def expose(
    signal_e: np.ndarray,
    s: SensorParams,
    pattern: FixedPattern,
    rng: np.random.Generator,
    *,
    n_avg: int = 1,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Turn expected signal electrons into one noisy BGR frame at the ADC's depth.

    ``n_avg`` > 1: the average of that many frames of the same scene taken back to back (frame
    stacking, or a master dark frame): the fixed pattern is the same in each, the shot and read
    noise are independent, so the average is one frame whose temporal noise has ``1/n_avg`` of
    the variance. It is quantised once (the average of ``n_avg`` digitised frames, rounded back
    to the ADC's depth, differs from it by a fraction of a DN of rounding noise).

    Parameters
    ----------
    signal_e : (H, W, 3) float32
        Expected photo-electrons per pixel and channel during this exposure (modified in place:
        pass a scratch array). Blooming and glare of saturating sources are the renderer's job
        (they are local to each source); here the charge is clipped at the full well.
    out : (H, W, 3) float32, optional
        Where the exposed electrons go instead; ``signal_e`` is then left all zeros (the pass
        clears each pixel with signal as it reads it), so a renderer that splats a few sources
        into it needs not clear the whole image before the next frame.

    Returns
    -------
    (H, W, 3) BGR frame: uint8 for an 8-bit ADC, else uint16 ADC counts (:func:`digitise`).
    """
    e = signal_e
    if e.dtype != np.float32 or not e.flags.c_contiguous:
        raise BadInputError("expose: signal_e must be a C-contiguous float32 array")
    if n_avg != 1 and not (isinstance(n_avg, int | np.integer) and n_avg >= 1):
        raise BadInputError(f"expose: n_avg must be a whole number of frames >= 1, got {n_avg!r}")
    var0, mean0, sigma0 = _dark_terms(s, pattern, int(n_avg))
    idx = _noise_indices(rng, e.shape)  # the noise: indices into _LUT
    if out is not None and (out.shape != e.shape or out.dtype != np.float32 or not out.flags.c_contiguous):
        raise BadInputError("expose: out must be a C-contiguous float32 array of signal_e's shape")
    _expose_nb(
        e.reshape(-1),
        (e if out is None else out).reshape(-1),
        out is not None,
        pattern.prnu.reshape(-1),
        s.prnu_sigma > 0,
        var0.reshape(-1),
        mean0.reshape(-1),
        sigma0.reshape(-1),
        idx.reshape(-1),
        _LUT,
        np.float32(1.0 / n_avg),
        np.float32(s.full_well_e),
        np.float32(-s.black_dn / s.dn_per_e),
    )
    return digitise(e if out is None else out, s)


@numba.njit(cache=True, nogil=True)
def _expose_nb(e, out, clear, prnu, use_prnu, var0, mean0, sigma0, idx, lut, inv_n, full_well, floor):
    """One pass over the frame (flat float32 arrays; from ``e`` into ``out``, which may be ``e``;
    ``clear``: zero each pixel of ``e`` with signal once read, leaving ``e`` all zeros): PRNU, shot + read noise
    ``sqrt((e + var0) * inv_n) * lut[idx]``, dark current and column offsets ``mean0``, the full
    well, and the floor below which the black level cannot go. A pixel without signal (most of
    a dark-room frame) takes its noise sigma from ``sigma0`` (``sqrt(var0 * inv_n)``, the same
    value). The same float32 operations in the same order as the numpy passes it replaced, so
    the frames are bit for bit the same. (The ADC stays OpenCV's: a rounding to uint8 in this
    loop was measured slower than ``convertScaleAbs`` after it.)"""
    for i in range(e.size):
        x = e[i]
        if x == 0:
            x = mean0[i] + sigma0[i] * lut[idx[i]]
        else:
            if clear:
                e[i] = 0
            if use_prnu:
                x *= prnu[i]
            noise = np.sqrt((x + var0[i]) * inv_n) * lut[idx[i]]
            x = (x + mean0[i]) + noise
        if x > full_well:
            x = full_well
        if x < floor:
            x = floor
        out[i] = x


def digitise(e: np.ndarray, s: SensorParams) -> np.ndarray:
    """The ADC: ``DN = black + e * dn_per_e``, rounded and clipped to ``0 .. max_dn``; (H, W, 3)
    uint8 for 8 bits, uint16 ADC counts for more. ``e`` (float32 electrons, at or above
    ``-black_dn / dn_per_e``: :func:`expose` floors it) is scratch."""
    if s.adc_bits == 8:  # |x| (convertScaleAbs) is x there
        return cv2.convertScaleAbs(e, alpha=s.dn_per_e, beta=s.black_dn)
    # one pass: scale, offset, round to nearest and saturate to 0..65535 (OpenCV's saturate_cast)
    out = cv2.addWeighted(e, s.dn_per_e, e, 0.0, s.black_dn, dtype=cv2.CV_16U)
    if s.adc_bits < 16:
        np.minimum(out, np.uint16(s.max_dn), out=out)
    return out


def detection_snr(total_e: np.ndarray, cov_px: np.ndarray, s: SensorParams, *, window: int = 3) -> np.ndarray:
    """Expected SNR of a dot in a ``window`` x ``window`` square (the ant-like STC paper's square
    search window) after an ideal dark-frame subtraction.

    ``SNR = S / sigma_bg`` (Rose's definition: the signal against the noise of the background it
    must be told from), with ``S`` the dot's electrons inside the window (Gaussian
    approximation, window centred on the dot) and ``sigma_bg^2 = window^2 (dark + read^2 +
    q^2)``, ``q^2 = 1 / (12 dn_per_e^2)`` the quantisation noise. Detectable iff
    ``SNR >= ROSE_SNR``.
    """
    from scipy.special import erf

    total_e = np.asarray(total_e, float)
    half = window / 2
    sx = np.sqrt(np.maximum(cov_px[..., 0, 0], 1e-12))
    sy = np.sqrt(np.maximum(cov_px[..., 1, 1], 1e-12))
    frac = erf(half / (np.sqrt(2) * sx)) * erf(half / (np.sqrt(2) * sy))
    S = total_e * frac
    per_px = s.dark_current_e_s * s.exposure_s + s.read_noise_e**2 + 1.0 / (12 * s.dn_per_e**2)
    return S / np.sqrt(window * window * per_px)

"""The synthetic catadioptric camera: renders the phosphor floor and red lights into noisy
mirror images at the sensor's ADC depth (uint8 for 8 bits, uint16 ADC counts for more:
:mod:`stcvision.sim_camera.image_sensor`), with ground truth.

Build once, render many: :class:`SyntheticCamera` traces every pixel onto the floor once per
process for its optics (:func:`stcvision.sim_camera.optics.camera_geometry`, which keeps the
table for the next camera with the same optics) and draws its fixed-pattern noise once; per frame only
the robot pose moves the floor under that table.

Rendering
---------
* **Dots and lights** are small emitting discs. Each is projected with the forward solver
  (:func:`~stcvision.sim_camera.optics.project_floor_points`); its electrons are
  ``L * e_per_cd_m2_s * exposure * vignetting * (disc area / pixel footprint)`` -- the fraction
  of the pixel's floor footprint the disc fills -- spread by a Gaussian whose covariance is the
  lens blur plus the disc mapped through the local pixel->floor Jacobian (far dots are squashed
  radially, as a spherical mirror does).
* **Lights-on frames** (calibration) see the lit floor: uniform phosphor floor of
  ``room_floor_cd_m2`` with dark tape lines on every cell boundary, anti-aliased per pixel from
  its footprint; the robot body shows dark grey; outside the mirror is black.
* Sources that overflow the full well bloom (``bloom_fraction`` of the excess charge spreads
  over a few pixels) and carry veiling glare (``glare_fraction`` of their light over tens of
  pixels); both are added around each such source only.
* The sensor (:mod:`stcvision.sim_camera.image_sensor`) adds dark current, fixed pattern, noise, colour
  response and crosstalk, saturation, and quantises to its ADC's depth; every frame, dark
  frame and lights-on frame of a camera has the sensor's dtype.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np
from llvmlite import ir
from numba.extending import intrinsic

from stcvision.sim_camera.image_sensor import ROSE_SNR, FixedPattern, SensorParams, detection_snr, expose
from stcvision.sim_camera.optics import MirrorCameraParams, RayTable, camera_geometry

__all__ = [
    "Frame",
    "LightsOnParams",
    "Pose",
    "SyntheticCamera",
    "detection_snr",
    "visibility_horizon_s",
]

#: Lens blur (Gaussian sigma, px) of a cheap webcam lens looking at a spherical mirror.
PSF_SIGMA_PX = 0.6
#: Red obstacle light: a diffused red LED, 10 mm across, ~3000 cd/m^2 (typical diffused
#: indicator LED: tens to hundreds of mcd over a ~10 mm dome).
RED_LIGHT_DIAMETER_M = 0.010
RED_LIGHT_CD_M2 = 3000.0
_PATCH = 4  # splat patch half-size (px): 9x9
_GLARE_HALF = 24  # glare/bloom patch half-size (px): 49x49


def _gauss_kernel(sigma: float, half: int) -> np.ndarray:
    x = np.arange(-half, half + 1)
    g = np.exp(-0.5 * (x[:, None] ** 2 + x[None, :] ** 2) / sigma**2)
    return g / g.sum()


#: blooming spreads excess charge over a few pixels; veiling glare over tens (sigma 8 px)
_BLOOM_KERNEL = _gauss_kernel(2.0, _GLARE_HALF)
_GLARE_KERNEL = _gauss_kernel(8.0, _GLARE_HALF)


@numba.njit(cache=True, nogil=True)
def _splat_nb(out, iu, iv, uv, icov, total, bgr, core):
    """Add Gaussian spots to ``out`` (H, W, 3) float32: spot k centred at ``uv[k]`` with inverse
    covariance ``icov[k]``, evaluated on the (2P+1)^2 patch around pixel ``(iu[k], iv[k])``,
    normalised to 1 over the patch, times ``total[k]`` electrons and each channel's ``bgr``
    response; pixels outside the frame get none. ``core`` (n, 2P+1, 2P+1) receives each spot's
    electrons per patch pixel (zero outside the frame)."""
    h, w = out.shape[0], out.shape[1]
    m = core.shape[1]
    r = m // 2
    for k in range(iu.shape[0]):
        a, b, c = icov[k, 0, 0], icov[k, 0, 1], icov[k, 1, 1]
        s = 0.0
        for i in range(m):
            dv = (iv[k] + i - r) - uv[k, 1]
            for j in range(m):
                du = (iu[k] + j - r) - uv[k, 0]
                q = a * du * du + 2 * b * du * dv
                q += c * dv * dv
                g = np.exp(-0.5 * q)
                core[k, i, j] = g
                s += g
        for i in range(m):
            pv = iv[k] + i - r
            for j in range(m):
                pu = iu[k] + j - r
                if pv < 0 or pv >= h or pu < 0 or pu >= w:
                    core[k, i, j] = 0.0
                    continue
                e = core[k, i, j] / s * total[k]
                core[k, i, j] = e
                for ch in range(3):
                    if bgr[ch] > 0:
                        out[pv, pu, ch] += np.float32(e * bgr[ch])


@numba.njit(cache=True, nogil=True)
def _spill_nb(out, v_lo, v_hi, u_lo, u_hi, kv, ku, kb, kg, a, b):
    """``out[v_lo:v_hi, u_lo:u_hi, ch] += kb * a[ch] + kg * b[ch]`` (the kernels' window starting
    at row ``kv``, column ``ku``), in float32 as numpy's ``+= (...).astype(np.float32)``."""
    for v in range(v_lo, v_hi):
        for u in range(u_lo, u_hi):
            x, y = kb[kv + v - v_lo, ku + u - u_lo], kg[kv + v - v_lo, ku + u - u_lo]
            for ch in range(3):
                out[v, u, ch] += np.float32(x * a[ch] + y * b[ch])


@intrinsic
def _fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (LLVM's fma intrinsic: the hardware instruction where there is
    one, an exact emulation elsewhere)."""
    sig = numba.float64(numba.float64, numba.float64, numba.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        return builder.call(builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d])), args)

    return sig, codegen


@numba.njit(cache=True, nogil=True)
def _inv2_nb(a00, a01, a10, a11):
    """Inverse of [[a00, a01], [a10, a11]] as LAPACK's gesv with B = I computes it (what
    ``numpy.linalg.inv`` calls): LU with partial pivoting, multiplications by the reciprocal
    pivots, the back substitution's update fused. Bit for bit numpy's inverse (OpenBLAS) on
    300 000 random and 49 494 ray-table matrices; a compiled loop instead of one LAPACK call
    per 2x2 matrix."""
    swap = abs(a10) > abs(a00)
    if swap:
        a00, a01, a10, a11 = a10, a11, a00, a01
    r00 = 1.0 / a00
    low = a10 * r00
    r11 = 1.0 / (a11 - low * a01)
    # column 0 of the inverse solves A x = e0, column 1 A x = e1 (rows permuted by the pivot)
    x10 = (1.0 if swap else -low) * r11
    x00 = _fma(-a01, x10, 0.0 if swap else 1.0) * r00
    x11 = (-low if swap else 1.0) * r11
    x01 = _fma(-a01, x11, 1.0 if swap else 0.0) * r00
    return x00, x01, x10, x11


@numba.njit(cache=True, nogil=True)
def _geometry_nb(uv, vis, diameter, pixels, psf2, cand, iuv, fv, cov, icov):
    """:meth:`SyntheticCamera._geometry` for every visible source: its nearest pixel, that
    pixel's footprint and vignetting (``pixels``: :attr:`FloorProjector.pixels`), skipped where
    the footprint is not finite and positive, and its spot's covariance
    ``(d/2)^2/4 J^-1 J^-T + psf2 I`` and inverse (the products fused as numpy's matmul does
    them). Writes the first ``m`` rows of the outputs and returns ``m``."""
    h, w = pixels.shape[0], pixels.shape[1]
    m = 0
    for k in range(uv.shape[0]):
        if not vis[k]:
            continue
        iu = min(max(int(np.rint(uv[k, 0])), 0), w - 1)
        iv = min(max(int(np.rint(uv[k, 1])), 0), h - 1)
        rec = pixels[iv, iu]
        fp = rec[5]
        if not (np.isfinite(fp) and fp > 0):
            continue
        i00, i01, i10, i11 = _inv2_nb(rec[0], rec[1], rec[2], rec[3])
        c = (diameter[k] / 2) * (diameter[k] / 2) / 4.0
        m00, m01, m10, m11 = c * i00, c * i01, c * i10, c * i11
        c00 = _fma(m01, i01, m00 * i00) + psf2
        c01 = _fma(m01, i11, m00 * i10) + 0.0
        c10 = _fma(m11, i01, m10 * i00) + 0.0
        c11 = _fma(m11, i11, m10 * i10) + psf2
        cand[m], iuv[m, 0], iuv[m, 1], fv[m, 0], fv[m, 1] = k, iu, iv, fp, rec[6]
        cov[m, 0, 0], cov[m, 0, 1], cov[m, 1, 0], cov[m, 1, 1] = c00, c01, c10, c11
        icov[m, 0, 0], icov[m, 0, 1], icov[m, 1, 0], icov[m, 1, 1] = _inv2_nb(c00, c01, c10, c11)
        m += 1
    return m


@numba.njit(cache=True, nogil=True)
def _spill_all_nb(out, u0, v0, r, kb, kg, a, b):
    """For each source k, :func:`_spill_nb` of the (2r+1)^2 kernels centred on pixel
    ``(u0[k], v0[k])``, cut to the frame, with channel weights ``a[k]``, ``b[k]``."""
    h, w = out.shape[0], out.shape[1]
    for k in range(u0.shape[0]):
        v_lo, v_hi = max(v0[k] - r, 0), min(v0[k] + r + 1, h)
        u_lo, u_hi = max(u0[k] - r, 0), min(u0[k] + r + 1, w)
        if v_lo < v_hi and u_lo < u_hi:
            _spill_nb(out, v_lo, v_hi, u_lo, u_hi, v_lo - (v0[k] - r), u_lo - (u0[k] - r), kb, kg, a[k], b[k])


@dataclass(frozen=True, slots=True)
class Pose:
    """Robot pose in the world: position (m) and heading (rad, 0 = east, counter-clockwise)."""

    x_m: float
    y_m: float
    heading_rad: float

    def world_to_robot(self, xy_m) -> np.ndarray:
        xy = np.asarray(xy_m, float).reshape(-1, 2) - (self.x_m, self.y_m)
        c, s = np.cos(self.heading_rad), np.sin(self.heading_rad)
        return np.column_stack([c * xy[:, 0] + s * xy[:, 1], -s * xy[:, 0] + c * xy[:, 1]])

    def robot_to_world(self, xy_m) -> np.ndarray:
        xy = np.asarray(xy_m, float).reshape(-1, 2)
        c, s = np.cos(self.heading_rad), np.sin(self.heading_rad)
        return np.column_stack([c * xy[:, 0] - s * xy[:, 1] + self.x_m, s * xy[:, 0] + c * xy[:, 1] + self.y_m])

    def to_dict(self) -> dict:
        return {"x_m": self.x_m, "y_m": self.y_m, "heading_rad": self.heading_rad}


@dataclass(frozen=True, kw_only=True, slots=True)
class LightsOnParams:
    """The lit room used for calibration frames.

    ``room_floor_cd_m2``: a light floor (albedo ~0.3) under ~300 lx office light,
    ``L = E * albedo / pi ~ 30 cd/m^2``. Tape lines ``grid_line_m`` wide on every cell boundary
    reflect ``line_contrast`` of the floor; the robot's body ``body_contrast``. ``target_dn``:
    where auto-exposure puts the lit floor, on the 8-bit scale (140 of 255; a deeper ADC the
    same fraction of its range).
    """

    room_floor_cd_m2: float = 30.0
    grid_line_m: float = 0.012
    line_contrast: float = 0.12
    body_contrast: float = 0.25
    target_dn: float = 140.0


@dataclass(frozen=True, eq=False)
class Frame:
    """One rendered frame: ``image`` (H, W, 3) BGR at the sensor's depth (uint8 for an 8-bit ADC,
    uint16 ADC counts for more) and, if asked for, ``truth`` (a dict)."""

    image: np.ndarray
    truth: dict | None = None
    signal_e: np.ndarray | None = field(default=None, repr=False)


class SyntheticCamera:
    """A catadioptric camera on a robot.

    Parameters
    ----------
    optics : MirrorCameraParams
    sensor : SensorParams
        Default settings; :meth:`render` accepts per-frame overrides (exposure control).
    pattern_seed : int
        Seed of this camera's fixed-pattern noise (a physical camera has one pattern).
    """

    def __init__(
        self,
        optics: MirrorCameraParams | None = None,
        sensor: SensorParams | None = None,
        *,
        pattern_seed: int = 0,
    ) -> None:
        self.optics = optics or MirrorCameraParams()
        self.sensor = sensor or SensorParams()
        self.table: RayTable
        self.table, self.projector = camera_geometry(self.optics)
        shape = (self.optics.height_px, self.optics.width_px)
        self.pattern = FixedPattern.draw(shape, self.sensor, np.random.default_rng(pattern_seed))
        self._scratch = np.empty((*shape, 3), np.float32)
        # whether the scratch is all zeros: a rendered frame's exposure clears the few pixels its
        # sources lit (expose's ``out``), so the next frame needs not clear the whole image
        self._scratch_clear = False
        self._exposed = np.empty((*shape, 3), np.float32)  # the exposure's electrons, scratch
        self._last_projection = None  # (positions, diameters, result) of the last signal()

    @property
    def shape(self) -> tuple[int, int]:
        return (self.optics.height_px, self.optics.width_px)

    # ------------------------------------------------------------------ sources -> electrons
    def _geometry(self, uv, vis, diameter_m) -> dict:
        """What a set of sources' image positions fix, whatever their brightness: for each
        visible source with a usable floor footprint (``cand``) its nearest pixel, footprint,
        vignetting and the inverse covariance of its spot (PSF + disc mapped through the local
        pixel->floor Jacobian: far dots are squashed radially, as a spherical mirror does).
        ``diameter_m``: (N,) each source's disc diameter. One compiled pass
        (:func:`_geometry_nb`)."""
        n = len(uv)
        cand, iuv = np.empty(n, np.int64), np.empty((n, 2), np.int64)
        fv, cov, icov = np.empty((n, 2)), np.empty((n, 2, 2)), np.empty((n, 2, 2))
        m = _geometry_nb(uv, vis, diameter_m, self.projector.pixels, PSF_SIGMA_PX**2, cand, iuv, fv, cov, icov)
        return {
            "cand": cand[:m],
            "iu": iuv[:m, 0],
            "iv": iuv[:m, 1],
            "fp": fv[:m, 0],
            "vign": fv[:m, 1],
            "cov": cov[:m],
            "icov": icov[:m],
        }

    @staticmethod
    def _split_geometry(geo: dict, start: int, stop: int) -> dict:
        """The part of :meth:`_geometry`'s result for sources ``start:stop`` (indices from 0;
        ``cand`` is ascending, so the part is one slice)."""
        lo, hi = np.searchsorted(geo["cand"], (start, stop))
        part = {k: v[lo:hi] for k, v in geo.items()}
        part["cand"] = part["cand"] - start
        return part

    def _splat(self, out, uv, vis, geo, lum_cd_m2, diameter_m, bgr, s: SensorParams):
        """Add the electrons of emitting discs, projected to ``uv`` (visible where ``vis``; their
        :meth:`_geometry` ``geo``), to ``out`` (H, W, 3); return per-source info."""
        n = len(uv)
        info = {"uv": uv, "visible": vis, "total_e": np.zeros(n), "cov_px": np.zeros((n, 2, 2))}
        lum = np.broadcast_to(np.asarray(lum_cd_m2, float), (n,))
        lit = lum[geo["cand"]] > 0
        if not lit.any():
            return info
        idx, iu, iv = geo["cand"][lit], geo["iu"][lit], geo["iv"][lit]
        area = np.pi * (diameter_m / 2) ** 2
        total = lum[idx] * s.e_per_cd_m2_s * s.exposure_s * geo["vign"][lit] * (area / geo["fp"][lit])
        info["total_e"][idx] = total
        info["cov_px"][idx] = geo["cov"][lit]
        # evaluate each Gaussian on a 9x9 patch around its nearest pixel, normalised to 1, and add
        # it to the frame (one compiled pass: the patches are small and many)
        core = np.empty((len(idx), 2 * _PATCH + 1, 2 * _PATCH + 1))
        _splat_nb(out, iu, iv, uv[idx], geo["icov"][lit], total, np.asarray(bgr, float), core)
        # Very bright sources (a red LED in the dark) overflow the full well: a fraction of the
        # excess charge blooms into the neighbourhood, and the lens and mirror spread a faint
        # veiling glare around them. Only sources that saturate are worth the wider patches.
        peak = core.max(axis=(1, 2)) * max(bgr)
        sat = np.flatnonzero(peak > s.full_well_e)
        if len(sat):
            self._spill(out, iu[sat], iv[sat], core[sat], total[sat], bgr, s)
        return info

    def _project(self, sources) -> tuple[np.ndarray, np.ndarray, list]:
        """Image positions, visibility and :meth:`_geometry` of every source (``sources``: the
        (name, robot-frame positions, luminance, diameter, colour) of each kind), in one solver
        call (its cost is mostly per call, not per point). Rendering only what changes: the
        robot takes several frames where it stands (the short and the long frame, the looks), so
        the last positions' result is kept and reused when the same positions come again."""
        xy = np.concatenate([src[1] for src in sources])
        diameters = tuple(src[3] for src in sources)
        last = self._last_projection
        if last is not None and last[1] == diameters and np.array_equal(last[0], xy):
            return last[2]
        uv, vis = self.projector.project(xy)
        uv.setflags(write=False)  # handed out in every frame's info: nobody may change the kept copy
        vis.setflags(write=False)
        geo = self._geometry(uv, vis, np.repeat(np.array(diameters, float), [len(src[1]) for src in sources]))
        geos, start = [], 0
        for src in sources:
            geos.append(self._split_geometry(geo, start, start + len(src[1])))
            start += len(src[1])
        self._last_projection = (xy, diameters, (uv, vis, geos))
        return uv, vis, geos

    def _spill(self, out, u0, v0, core, total, bgr, s: SensorParams) -> None:
        """Bloom (the excess over the full well) and glare around saturating sources (their
        nearest pixels ``u0``, ``v0``, spot electrons ``core`` and totals), added to ``out``
        (H, W, 3) one source after the other on the window of the kernels inside the frame."""
        c = np.asarray(bgr, float)
        excess = np.maximum(core[:, None] * c[None, :, None, None] - s.full_well_e, 0.0).sum(axis=(2, 3))
        a = np.where(c > 0, s.bloom_fraction * excess, 0.0)
        b = s.glare_fraction * total[:, None] * c
        _spill_all_nb(out, u0, v0, _GLARE_HALF, _BLOOM_KERNEL, _GLARE_KERNEL, a, b)

    # ------------------------------------------------------------------ public API
    def signal(
        self,
        pose: Pose,
        *,
        t_s: float = 0.0,
        phosphor=None,
        red_lights_m=None,
        sensor: SensorParams | None = None,
        lamps=None,
    ):
        """Expected photo-electrons (H, W, 3) float32 of a dark-room frame, before noise, and
        per-source info (projected positions, electrons). ``lamps``: other emitting discs on the
        floor, ``(xy_m (N, 2) world, luminance_cd_m2, diameter_m, bgr response)`` (a stray light
        source: :mod:`stcvision.controllers.stc.faults`)."""
        s = sensor or self.sensor
        out = self._scratch
        if not self._scratch_clear:
            out.fill(0)
        self._scratch_clear = False  # the caller may change it (an exposure in place)
        info = {}
        sources = []  # (name, robot-frame positions, luminance, diameter, colour response)
        if phosphor is not None and len(phosphor):
            xy_r = pose.world_to_robot(phosphor.xy_m)
            sources.append(("dots", xy_r, phosphor.luminance_at(t_s), phosphor.dot_diameter_m, s.phosphor_bgr))
        if red_lights_m is not None and len(red_lights_m):
            xy_r = pose.world_to_robot(red_lights_m)
            sources.append(("lights", xy_r, RED_LIGHT_CD_M2, RED_LIGHT_DIAMETER_M, s.red_led_bgr))
        if lamps is not None and len(lamps[0]):
            xy_m, lum, diameter, bgr = lamps
            sources.append(("lamps", pose.world_to_robot(np.asarray(xy_m, float).reshape(-1, 2)), lum, diameter, bgr))
        if not sources:
            return out, info
        uv, vis, geos = self._project(sources)
        start = 0
        for (name, xy_r, lum, diameter, bgr), geo in zip(sources, geos, strict=True):
            part = slice(start, start + len(xy_r))
            start = part.stop
            info[name] = self._splat(out, uv[part], vis[part], geo, lum, diameter, bgr, s)
            info[name]["xy_robot"] = xy_r
            if name == "dots":
                info[name]["lum"] = lum
        return out, info

    def render(
        self,
        pose: Pose,
        *,
        rng: np.random.Generator,
        t_s: float = 0.0,
        phosphor=None,
        red_lights_m=None,
        sensor: SensorParams | None = None,
        board=None,
        truth: bool = False,
        n_avg: int = 1,
        lamps=None,
    ) -> Frame:
        """Render one dark-room frame (phosphor dots + red lights) at sim time ``t_s``.

        ``n_avg`` > 1 renders the average of that many frames taken back to back from ``t_s``
        (frame stacking; :func:`stcvision.sim_camera.image_sensor.expose`), the scene as it is at the middle of
        the stack: the marks a long stack must read are hundreds of seconds old or more and fade
        by a few per cent over it, and the fresh ones saturate in every frame anyway.

        Parameters
        ----------
        pose : Pose
            True robot pose (world).
        rng : numpy.random.Generator
            Temporal noise source.
        phosphor : stcvision.sim_camera.phosphor.PhosphorLayer, optional
        red_lights_m : (N, 2) world positions of red lights, optional
        sensor : SensorParams, optional
            Settings for this frame (exposure, gain); defaults to the camera's.
        board : stcvision.sim_camera.board.Board, optional
            Needed for the cell/box/neighbour regions in the ground truth.
        truth : bool
            Attach ground truth (slower: a few ms).
        lamps : other emitting discs, see :meth:`signal`.
        """
        s = sensor or self.sensor
        if n_avg > 1:
            t_s = t_s + 0.5 * (n_avg - 1) * s.exposure_s
        sig, info = self.signal(pose, t_s=t_s, phosphor=phosphor, red_lights_m=red_lights_m, sensor=s, lamps=lamps)
        image = expose(sig, s, self.pattern, rng, n_avg=n_avg, out=self._exposed)
        self._scratch_clear = True
        gt = None
        if truth:
            from stcvision.sim_camera.truth import build_truth

            gt = build_truth(self, pose, s, info, t_s=t_s, phosphor=phosphor, red_lights_m=red_lights_m, board=board)
        return Frame(image, gt)

    def dark_frame(self, *, rng: np.random.Generator, sensor: SensorParams | None = None, n_avg: int = 1) -> np.ndarray:
        """One frame with the lens capped (or the room dark and empty) at the given settings;
        with ``n_avg`` > 1 the average of that many (a master dark for stacked frames)."""
        s = sensor or self.sensor
        if not self._scratch_clear:
            self._scratch.fill(0)
            self._scratch_clear = True
        return expose(self._scratch, s, self.pattern, rng, n_avg=n_avg, out=self._exposed)

    def median_dark(self, n: int = 16, *, rng: np.random.Generator, sensor: SensorParams | None = None) -> np.ndarray:
        """The median of ``n`` dark frames at the given settings: what a user captures once
        (lens capped) to subtract from every frame; the median keeps its own noise small."""
        frames = np.stack([self.dark_frame(rng=rng, sensor=sensor) for _ in range(n)])
        return np.median(frames, axis=0).round().astype(frames.dtype)

    def lights_on(
        self,
        pose: Pose,
        *,
        board,
        rng: np.random.Generator,
        room: LightsOnParams | None = None,
        sensor: SensorParams | None = None,
        truth: bool = False,
    ) -> Frame:
        """A calibration frame: room lights on, floor and cell grid lines visible.

        The exposure is set automatically (gain 1) so the lit floor reads about
        ``room.target_dn``, as a webcam's auto-exposure does, unless ``sensor`` is given.
        """
        room = room or LightsOnParams()
        t = self.table
        lum = np.zeros(self.shape, np.float32)
        g = t.ground
        xy_w = pose.robot_to_world(t.floor_xy_m[g])
        # distance to the nearest cell boundary line (lines every 2D, board-aligned)
        cell = board.cell_m
        fx = np.abs(((xy_w[:, 0] + cell / 2) % cell) - cell / 2)
        fy = np.abs(((xy_w[:, 1] + cell / 2) % cell) - cell / 2)
        dist = np.minimum(fx, fy)
        pix = np.sqrt(t.footprint_m2[g])  # pixel size on the floor, for anti-aliasing
        cover = np.clip((room.grid_line_m / 2 - dist) / pix + 0.5, 0.0, 1.0)
        refl = 1.0 - cover * (1.0 - room.line_contrast)
        lum[g] = room.room_floor_cd_m2 * refl * t.vignetting[g]
        lum[t.body] = room.room_floor_cd_m2 * room.body_contrast * t.vignetting[t.body]
        s = sensor
        if s is None:
            base = self.sensor.replace(gain=1.0)
            e_per_s = room.room_floor_cd_m2 * base.e_per_cd_m2_s
            exposure = room.target_dn / 255.0 * base.max_dn / (base.dn_per_e * e_per_s)
            s = base.replace(exposure_s=float(exposure))
        sig = (lum * np.float32(s.e_per_cd_m2_s * s.exposure_s))[..., None] * np.asarray(s.floor_bgr, np.float32)
        image = expose(np.ascontiguousarray(sig, np.float32), s, self.pattern, rng)
        gt = None
        if truth:
            from stcvision.sim_camera.truth import build_truth

            gt = build_truth(self, pose, s, {}, t_s=0.0, board=board)
            gt["lights_on"] = True
        return Frame(image, gt)


def visibility_horizon_s(
    camera: SyntheticCamera,
    *,
    sensor: SensorParams | None = None,
    law=None,
    rho_m=0.25,
    charge_s: float = 3.0,
    n_stack: float = 1,
    max_age_s: float = 1.0e6,
):
    """Age (s) beyond which a dot charged for ``charge_s`` at ``rho_m`` from the robot is no
    longer detectable (expected SNR < :data:`ROSE_SNR` in a 3x3 window), for these settings.

    Averaging ``n_stack`` frames divides the noise variance by ``n_stack``. Returns 0 if the
    dot is never detectable and ``inf`` if it still is at ``max_age_s``. ``rho_m`` may be an
    array of distances (one rendering for them all): the result is then an array too.
    """
    from stcvision.sim_camera.phosphor import AfterglowLaw, PhosphorLayer

    s = sensor or camera.sensor
    law = law or AfterglowLaw()
    rho = np.atleast_1d(np.asarray(rho_m, float))
    layer = PhosphorLayer(law)
    # a direction away from the image axes, where no special symmetry helps; each dot's expected
    # electrons and blur are its own, so the dots may share the ray
    layer.charge(np.outer(rho, [np.cos(0.7), np.sin(0.7)]), t_start_s=-charge_s, duration_s=charge_s)
    _, info = camera.signal(Pose(0.0, 0.0, 0.0), t_s=0.0, phosphor=layer, sensor=s)
    d = info["dots"]
    ages = np.geomspace(0.1, max_age_s, 4000)
    rel = law.luminance_cd_m2(ages, charge_s) / law.luminance_cd_m2(0.0, charge_s)
    total = np.asarray(d["total_e"], float)[:, None] * rel[None, :]
    cov = np.broadcast_to(np.asarray(d["cov_px"], float)[:, None], (len(rho), len(ages), 2, 2))
    below = detection_snr(total, cov, s) * np.sqrt(n_stack) < ROSE_SNR
    out = np.where(below.any(axis=1), ages[np.argmax(below, axis=1)], np.inf)
    out = np.where(below[:, 0] | ~np.asarray(d["visible"], bool), 0.0, out)
    return float(out[0]) if np.ndim(rho_m) == 0 else out

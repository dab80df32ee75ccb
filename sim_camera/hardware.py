"""Hardware profiles: cameras and marking robots as named presets and as versioned JSON.

A **camera** profile sets the sensor's physics in :class:`stcvision.sim_camera.image_sensor.SensorParams`: the
quantum efficiency at the phosphor's ~520 nm, read noise, dark current at its operating
temperature, pixel pitch, full well and the lens f-number (the optics' geometry, the fixed
pattern's shape, the colour responses and the exposure/gain settings the robot chooses stay the
model's). A **robot** profile is a :class:`stcvision.sim_camera.robot.MarkingRobot`. Every figure of a
preset carries its source; "assumed" says where no datasheet or paper gives one.

JSON (``schema_version`` 1; unit-suffixed keys)::

    {"schema_version": 1, "kind": "camera", "name": "mycam", "adc_bits": 12,
     "sensor": {"quantum_efficiency": 0.8, "read_noise_e": 1.0, "dark_current_e_s": 0.5,
                "pixel_pitch_m": 2.9e-6, "full_well_e": 11200, "f_number": 1.4},
     "sources": {"read_noise_e": "datasheet ...", ...}}

    {"schema_version": 1, "kind": "robot", "name": "myrobot", "drive_speed_m_s": 0.08,
     "turn_90_s": 1.5, "rate_spread": 0.1, "fade_per_h": 0.2, "led_on_s": 3.0,
     "drive_sigma_m": 0.002, "initial_turn_error": 0.01, "settle_s": 0.3, "sources": {...}}

A camera file may set any other ``SensorParams`` field too; unknown keys and other schema
versions are refused with a one-line reason (:class:`stcvision.errors.BadInputError`).

``adc_bits`` is the sensor's (:attr:`SensorParams.adc_bits`): frames are sensor-true, uint8 for an
8-bit ADC and uint16 ADC counts for 12 or 16 bits (:mod:`stcvision.sim_camera.image_sensor`); the coverage loop
chooses each frame's gain from the sensor's own noise
(:func:`stcvision.controllers.stc.frames.sensor_gain`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

from stcvision.errors import BadInputError
from stcvision.sim_camera.image_sensor import SensorParams
from stcvision.sim_camera.robot import LEGO_STC_ROBOT, MarkingRobot

__all__ = [
    "CAMERAS",
    "COOLED",
    "LOWLIGHT",
    "WEBCAM",
    "CAMERA_FIGURES",
    "ROBOTS",
    "SCHEMA_VERSION",
    "CameraProfile",
    "camera_to_dict",
    "load_camera",
    "load_robot",
    "robot_to_dict",
]

SCHEMA_VERSION = 1
#: the figures a camera profile is about (the rest of SensorParams is the model's)
CAMERA_FIGURES = ("quantum_efficiency", "read_noise_e", "dark_current_e_s", "pixel_pitch_m", "full_well_e", "f_number")


@dataclass(frozen=True, kw_only=True, slots=True)
class CameraProfile:
    name: str
    description: str
    sensor: SensorParams = field(default_factory=SensorParams)
    sources: tuple[tuple[str, str], ...] = ()

    @property
    def adc_bits(self) -> int:
        """What the camera digitises (the sensor's ``adc_bits``: the frames' depth)."""
        return self.sensor.adc_bits


_WEBCAM_SRC = "sim_camera/image_sensor.py defaults: typical of small-pixel consumer CMOS, not one datasheet"
WEBCAM = CameraProfile(
    name="webcam",
    description="the STC paper's cheap wireless webcam in the dark (OmniVision OV7725 class VGA CMOS, 4.7 mm f/2.0)",
    sensor=SensorParams(),
    sources=(
        ("camera", "Srour & Abboud: 'The camera we used, was not intended to work with low-light conditions'"),
        ("quantum_efficiency", f"0.5 at 520 nm; {_WEBCAM_SRC}"),
        ("read_noise_e", f"6 e-; {_WEBCAM_SRC}"),
        ("dark_current_e_s", f"40 e-/s at room temperature; {_WEBCAM_SRC}"),
        ("pixel_pitch_m", "6.0 um: OmniVision OV7725 datasheet (pixel size 6.0 um x 6.0 um)"),
        ("full_well_e", f"20,000 e-; {_WEBCAM_SRC}"),
        ("f_number", "f/2.0: a 4.7 mm webcam lens (assumed, sim_camera/image_sensor.py)"),
        ("adc_bits", "8: what a consumer webcam delivers (8-bit YUV/JPEG; the OV7725's raw output is 10-bit)"),
    ),
)
LOWLIGHT = CameraProfile(
    name="lowlight",
    description=(
        "a low-light CMOS with controlled integration time: Sony STARVIS IMX462 (1/2.8'', 2.9 um, as in the "
        "ZWO ASI462MC), uncooled at ~25 C, on a fast f/1.4 M12 lens"
    ),
    sensor=SensorParams(
        quantum_efficiency=0.80,
        read_noise_e=1.0,
        dark_current_e_s=0.5,
        pixel_pitch_m=2.9e-6,
        full_well_e=11200.0,
        f_number=1.4,
        adc_bits=12,
    ),
    sources=(
        (
            "camera",
            "Srour & Abboud: 'try using a better camera, preferably camera with a fully controlled integration time'",
        ),
        ("quantum_efficiency", "~0.8 at 520 nm: ZWO ASI462MC relative QE curve (peak ~80 %), recalled, not re-checked"),
        ("read_noise_e", "1.0 e-: ZWO ASI462MC read-noise curve (2.5 e- at gain 0 to 0.47 e- at high gain), recalled"),
        (
            "dark_current_e_s",
            "0.5 e-/s at ~25 C: assumed, the order of uncooled STARVIS sensors; no datasheet figure at hand",
        ),
        ("pixel_pitch_m", "2.9 um: Sony IMX462 product information (unit cell 2.9 um x 2.9 um)"),
        ("full_well_e", "11,200 e-: ZWO ASI462MC specifications, recalled"),
        ("f_number", "f/1.4: assumed, a fast M12 low-light board-camera lens"),
        ("adc_bits", "12: ZWO ASI462MC specifications (12-bit ADC), recalled"),
    ),
)
COOLED = CameraProfile(
    name="cooled",
    description=(
        "a cooled back-illuminated CMOS (Sony IMX571 class, 3.76 um, as in the ZWO ASI2600MM Pro) at -10 C "
        "with an f/1.2 lens"
    ),
    sensor=SensorParams(
        quantum_efficiency=0.85,
        read_noise_e=1.2,
        dark_current_e_s=0.01,
        pixel_pitch_m=3.76e-6,
        full_well_e=50000.0,
        f_number=1.2,
        adc_bits=16,
    ),
    sources=(
        (
            "camera",
            "Srour & Abboud: 'try using a better camera'; a cooled astronomy camera (ZWO ASI2600MM Pro class)",
        ),
        ("quantum_efficiency", "0.85 at 520 nm: a cooled back-illuminated sensor (Sony IMX571 peak QE ~0.9)"),
        ("read_noise_e", "1.2 e-: ZWO ASI2600MM Pro (1.0-3.5 e- across gains), recalled"),
        ("dark_current_e_s", "0.01 e-/s: a cooled sensor at about -10 C (ZWO ASI2600MM Pro class), recalled"),
        ("pixel_pitch_m", "3.76 um: Sony IMX571 (ZWO ASI2600MM Pro specifications)"),
        ("full_well_e", "50,000 e-: ZWO ASI2600MM Pro specifications (50 ke-), recalled"),
        ("f_number", "f/1.2: a fast C-mount lens (f/0.95-1.4 are sold), chosen for the faint marks"),
        ("adc_bits", "16: ZWO ASI2600MM Pro specifications (16-bit ADC), recalled"),
    ),
)
CAMERAS = {c.name: c for c in (WEBCAM, LOWLIGHT, COOLED)}
ROBOTS = {LEGO_STC_ROBOT.name: LEGO_STC_ROBOT}

_ROBOT_FIGURES = tuple(f.name for f in dataclasses.fields(MarkingRobot) if f.name not in ("name", "sources"))


def camera_to_dict(c: CameraProfile) -> dict:
    """The JSON form (also what ``stcvision cover --list-cameras --json`` lists)."""
    return {
        "schema_version": SCHEMA_VERSION,
        "kind": "camera",
        "name": c.name,
        "description": c.description,
        "adc_bits": c.adc_bits,
        "sensor": {k: getattr(c.sensor, k) for k in CAMERA_FIGURES},
        "sources": dict(c.sources),
    }


def robot_to_dict(r: MarkingRobot) -> dict:
    return {
        "schema_version": SCHEMA_VERSION,
        "kind": "robot",
        "name": r.name,
        **{k: getattr(r, k) for k in _ROBOT_FIGURES},
        "sources": dict(r.sources),
    }


def _read(spec: str, kind: str, presets: dict) -> dict | object:
    if spec in presets:
        return presets[spec]
    p = Path(spec)
    if p.suffix.lower() != ".json":
        raise BadInputError(f"unknown {kind} {spec!r}; expected one of {', '.join(presets)} or a .json file")
    if not p.is_file():
        raise BadInputError(f"{kind} file {spec} does not exist")
    from stcvision.fileio import read_json

    d = read_json(p, what=f"{kind} file")
    if not isinstance(d, dict):
        raise BadInputError(f"{kind} file {spec} must hold one JSON object")
    if d.get("schema_version") != SCHEMA_VERSION:
        raise BadInputError(
            f"{kind} file {spec}: schema_version must be {SCHEMA_VERSION}, got {d.get('schema_version')!r}"
        )
    if d.get("kind", kind) != kind:
        raise BadInputError(f"{kind} file {spec} is a {d.get('kind')!r} profile")
    sources = d.get("sources", {})
    if not isinstance(sources, dict) or not all(isinstance(v, str) for v in sources.values()):
        raise BadInputError(f"{kind} file {spec}: 'sources' must map figure names to citations (strings)")
    return d


def load_camera(spec: str) -> CameraProfile:
    """A preset by name (:data:`CAMERAS`) or a camera JSON file."""
    d = _read(spec, "camera", CAMERAS)
    if isinstance(d, CameraProfile):
        return d
    unknown = set(d) - {"schema_version", "kind", "name", "description", "adc_bits", "sensor", "sources"}
    if unknown:
        raise BadInputError(f"camera file {spec}: unknown key(s) {sorted(unknown)}")
    fig = d.get("sensor")
    if not isinstance(fig, dict) or not set(CAMERA_FIGURES) <= set(fig):
        raise BadInputError(f"camera file {spec}: 'sensor' must give at least {', '.join(CAMERA_FIGURES)}")
    if "adc_bits" in d and "adc_bits" in fig and d["adc_bits"] != fig["adc_bits"]:
        raise BadInputError(
            f"camera file {spec}: adc_bits {d['adc_bits']!r} and sensor.adc_bits {fig['adc_bits']!r} differ"
        )
    try:
        sensor = SensorParams.from_dict({"adc_bits": d.get("adc_bits", 8), **fig})
    except BadInputError as e:
        raise BadInputError(f"camera file {spec}: {e}") from None
    return CameraProfile(
        name=str(d.get("name", Path(spec).stem)),
        description=str(d.get("description", "")),
        sensor=sensor,
        sources=tuple(d.get("sources", {}).items()),
    )


def load_robot(spec: str) -> MarkingRobot:
    """A preset by name (:data:`ROBOTS`) or a robot JSON file."""
    d = _read(spec, "robot", ROBOTS)
    if isinstance(d, MarkingRobot):
        return d
    unknown = set(d) - {"schema_version", "kind", "name", "sources", *_ROBOT_FIGURES}
    if unknown:
        raise BadInputError(f"robot file {spec}: unknown key(s) {sorted(unknown)}")
    missing = [k for k in _ROBOT_FIGURES if k not in d]
    if missing:
        raise BadInputError(f"robot file {spec}: missing {', '.join(missing)}")
    for k in _ROBOT_FIGURES:
        if isinstance(d[k], bool) or not isinstance(d[k], int | float):
            raise BadInputError(f"robot file {spec}: {k} must be a number, got {d[k]!r}")
    return MarkingRobot(
        name=str(d.get("name", Path(spec).stem)),
        sources=tuple(d.get("sources", {}).items()),
        **{k: float(d[k]) for k in _ROBOT_FIGURES},
    )

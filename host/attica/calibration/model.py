"""Sensor calibration, mounting and output convention: the values and their JSON file.

The models (the same equations as the firmware's input stage, docs/integration.md):

- inertial (gyro, rad/s; accel, m/s^2): ``v = M (s * (raw - o))`` with misalignment ``M`` (3x3),
  sensitivity ``s`` (3, per axis, unitless) and offset ``o`` (3, in the sensor's unit);
- magnetic (uT): ``m = S (raw - h)`` with soft-iron matrix ``S`` (3x3) and hard-iron offset ``h`` (3);
- mounting: the calibrated sensor-frame vectors are rotated into the body frame, ``v_body = R v``,
  with ``R`` given as a unit quaternion (w, x, y, z; body <- sensor) or as one of the 24 axis
  permutations by name (:data:`REMAPS`);
- convention: the earth frame of the outputs, ``"enu"`` (default), ``"ned"`` or ``"nwu"``.

A calibration file is JSON::

    {"format": "attica-calibration", "version": 1,
     "gyro": {"misalignment": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
              "sensitivity": [1, 1, 1], "offset": [0, 0, 0]},
     "accel": {...the same keys...},
     "mag": {"soft_iron": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "hard_iron": [0, 0, 0]},
     "mounting": {"quaternion": [1, 0, 0, 0]}            (or {"remap": "+x-z+y"}),
     "convention": "enu",
     "fit": {...}}                                      (optional: how it was made, free-form)

Every section is optional (missing = identity). Values are stored as decimal numbers that read back
to the same float32 (the firmware works in float32).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

FORMAT = "attica-calibration"
VERSION = 1
CONVENTIONS = ("enu", "ned", "nwu")
SECTIONS = ("gyro", "accel", "mag", "mounting", "convention", "fit")

Mat3 = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]
Vec3 = tuple[float, float, float]
IDENTITY: Mat3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
ZERO: Vec3 = (0.0, 0.0, 0.0)
ONES: Vec3 = (1.0, 1.0, 1.0)


def _remaps() -> dict[str, Mat3]:
    """The 24 proper axis permutations by name.

    ``"+x-z+y"`` means body x = +sensor x, body y = -sensor z, body z = +sensor y (the rows of R).
    """
    out: dict[str, Mat3] = {}
    axes = "xyz"
    for a in range(3):
        for b in range(3):
            for c in range(3):
                if len({a, b, c}) != 3:
                    continue
                for sa in (1.0, -1.0):
                    for sb in (1.0, -1.0):
                        for sc in (1.0, -1.0):
                            rows = []
                            for ax, sg in ((a, sa), (b, sb), (c, sc)):
                                r = [0.0, 0.0, 0.0]
                                r[ax] = sg
                                rows.append(tuple(r))
                            m = np.array(rows)
                            if round(float(np.linalg.det(m))) != 1:
                                continue
                            picks = ((a, sa), (b, sb), (c, sc))
                            name = "".join(("+" if s > 0 else "-") + axes[i] for i, s in picks)
                            out[name] = (rows[0], rows[1], rows[2])  # type: ignore[assignment]
    return out


REMAPS: dict[str, Mat3] = _remaps()
"""The 24 axis permutations (rotations) by name; ``"+x+y+z"`` is the identity."""


def _f32(x: Any, what: str) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: {x!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{what}: {v} is not finite")
    f = float(np.float32(v))
    if not math.isfinite(f):
        raise ValueError(f"{what}: {v} overflows float32")
    return f


def _vec3(x: Any, what: str) -> Vec3:
    if not isinstance(x, (list, tuple, np.ndarray)) or len(x) != 3:
        raise ValueError(f"{what}: expected 3 numbers, got {x!r}")
    return (_f32(x[0], f"{what}[0]"), _f32(x[1], f"{what}[1]"), _f32(x[2], f"{what}[2]"))


def _mat3(x: Any, what: str) -> Mat3:
    if not isinstance(x, (list, tuple, np.ndarray)) or len(x) != 3:
        raise ValueError(f"{what}: expected a 3x3 matrix (3 rows of 3), got {x!r}")
    rows = tuple(_vec3(r, f"{what}[{i}]") for i, r in enumerate(x))
    return (rows[0], rows[1], rows[2])


def _condition_ok(m: Mat3) -> bool:
    a = np.array(m, np.float64)
    s = np.linalg.svd(a, compute_uv=False)
    return bool(s[-1] > 0 and s[0] / s[-1] < 1e3)


@dataclass(frozen=True)
class InertialModel:
    """Gyro or accel model ``v = M (s * (raw - o))``.

    Attributes
    ----------
    misalignment
        M, 3x3 (rows), unitless; well conditioned (condition number below 1e3).
    sensitivity
        s, per-axis scale, unitless, each in (0, 1e3].
    offset
        o, in the sensor's unit (rad/s for the gyro, m/s^2 for the accel), sensor frame.

    """

    misalignment: Mat3 = IDENTITY
    sensitivity: Vec3 = ONES
    offset: Vec3 = ZERO

    def __post_init__(self) -> None:
        object.__setattr__(self, "misalignment", _mat3(self.misalignment, "misalignment"))
        object.__setattr__(self, "sensitivity", _vec3(self.sensitivity, "sensitivity"))
        object.__setattr__(self, "offset", _vec3(self.offset, "offset"))
        if not all(0.0 < s <= 1e3 for s in self.sensitivity):
            raise ValueError(f"sensitivity: each must be in (0, 1e3], got {self.sensitivity}")
        if not _condition_ok(self.misalignment):
            raise ValueError("misalignment: singular or badly conditioned (condition number >= 1e3)")

    @property
    def identity(self) -> bool:
        """True when the model changes nothing (the firmware then skips it)."""
        return self.misalignment == IDENTITY and self.sensitivity == ONES and self.offset == ZERO

    def apply(self, raw: NDArray[np.floating[Any]]) -> NDArray[np.float64]:
        """The model in float64 over (..., 3) samples (for fitting and plots; not the bit-exact path)."""
        r = np.asarray(raw, np.float64)
        out: NDArray[np.float64] = (
            (r - np.array(self.offset)) * np.array(self.sensitivity) @ np.array(self.misalignment).T
        )
        return out

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of this section."""
        return {
            "misalignment": [list(r) for r in self.misalignment],
            "sensitivity": list(self.sensitivity),
            "offset": list(self.offset),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any], what: str = "inertial") -> InertialModel:
        """From the JSON object of this section; ValueError names the bad field."""
        _only(d, {"misalignment", "sensitivity", "offset"}, what)
        try:
            return cls(
                misalignment=d.get("misalignment", IDENTITY),
                sensitivity=d.get("sensitivity", ONES),
                offset=d.get("offset", ZERO),
            )
        except ValueError as e:
            raise ValueError(f"{what}.{e}") from None


@dataclass(frozen=True)
class MagModel:
    """Magnetometer model ``m = S (raw - h)``.

    Attributes
    ----------
    soft_iron
        S, 3x3 (rows), unitless; well conditioned (condition number below 1e3).
    hard_iron
        h, uT, sensor frame.

    """

    soft_iron: Mat3 = IDENTITY
    hard_iron: Vec3 = ZERO

    def __post_init__(self) -> None:
        object.__setattr__(self, "soft_iron", _mat3(self.soft_iron, "soft_iron"))
        object.__setattr__(self, "hard_iron", _vec3(self.hard_iron, "hard_iron"))
        if not _condition_ok(self.soft_iron):
            raise ValueError("soft_iron: singular or badly conditioned (condition number >= 1e3)")

    @property
    def identity(self) -> bool:
        """True when the model changes nothing (the firmware then skips it)."""
        return self.soft_iron == IDENTITY and self.hard_iron == ZERO

    def apply(self, raw: NDArray[np.floating[Any]]) -> NDArray[np.float64]:
        """The model in float64 over (..., 3) samples (for fitting and plots; not the bit-exact path)."""
        r = np.asarray(raw, np.float64)
        out: NDArray[np.float64] = (r - np.array(self.hard_iron)) @ np.array(self.soft_iron).T
        return out

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of this section."""
        return {"soft_iron": [list(r) for r in self.soft_iron], "hard_iron": list(self.hard_iron)}

    @classmethod
    def from_dict(cls, d: dict[str, Any], what: str = "mag") -> MagModel:
        """From the JSON object of this section; ValueError names the bad field."""
        _only(d, {"soft_iron", "hard_iron"}, what)
        try:
            return cls(soft_iron=d.get("soft_iron", IDENTITY), hard_iron=d.get("hard_iron", ZERO))
        except ValueError as e:
            raise ValueError(f"{what}.{e}") from None


@dataclass(frozen=True)
class Mounting:
    """Rotation body <- sensor: a unit quaternion (w, x, y, z), or a remap name (:data:`REMAPS`).

    Exactly one of ``quaternion`` and ``remap`` is set (neither: identity). A quaternion must have
    |q| within 1e-3 of 1 (it is normalised); q and -q are the same mounting.
    """

    quaternion: tuple[float, float, float, float] | None = None
    remap: str | None = None

    def __post_init__(self) -> None:
        if self.quaternion is not None and self.remap is not None:
            raise ValueError("mounting: give a quaternion or a remap, not both")
        if self.remap is not None and self.remap not in REMAPS:
            names = ", ".join(REMAPS)
            raise ValueError(f"mounting.remap: {self.remap!r} is none of the 24 axis permutations ({names})")
        if self.quaternion is not None:
            q = self.quaternion
            if not isinstance(q, (list, tuple, np.ndarray)) or len(q) != 4:
                raise ValueError(f"mounting.quaternion: expected 4 numbers (w, x, y, z), got {q!r}")
            qq = tuple(_f32(v, f"mounting.quaternion[{i}]") for i, v in enumerate(q))
            n = math.sqrt(sum(v * v for v in qq))
            if abs(n - 1.0) > 1e-3:
                raise ValueError(f"mounting.quaternion: |q| = {n:.6g}, expected a unit quaternion")
            object.__setattr__(self, "quaternion", (qq[0], qq[1], qq[2], qq[3]))

    @property
    def identity(self) -> bool:
        """True for the identity rotation (the firmware then skips the stage)."""
        if self.remap is not None:
            return self.remap == "+x+y+z"
        return self.quaternion is None or self.quaternion == (1.0, 0.0, 0.0, 0.0)

    def matrix(self) -> NDArray[np.float64]:
        """R (3x3, body <- sensor) in float64."""
        if self.remap is not None:
            return np.array(REMAPS[self.remap], np.float64)
        if self.quaternion is None:
            return np.eye(3)
        w, x, y, z = np.array(self.quaternion, np.float64) / np.linalg.norm(self.quaternion)
        return np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of this section."""
        if self.remap is not None:
            return {"remap": self.remap}
        return {"quaternion": list(self.quaternion if self.quaternion is not None else (1.0, 0.0, 0.0, 0.0))}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Mounting:
        """From the JSON object of this section; ValueError names the bad field."""
        _only(d, {"quaternion", "remap"}, "mounting")
        q = d.get("quaternion")
        return cls(quaternion=tuple(q) if q is not None else None, remap=d.get("remap"))


@dataclass(frozen=True)
class Calibration:
    """Everything the input and output stages need; the default changes nothing.

    Attributes
    ----------
    gyro, accel
        Inertial models (rad/s, m/s^2).
    mag
        Magnetic model (uT).
    mounting
        Body <- sensor rotation, applied after the models.
    convention
        Earth frame of the outputs: ``"enu"``, ``"ned"`` or ``"nwu"``.
    fit
        Free-form record of how the calibration was made (kept in the file, not used by the filters).

    """

    gyro: InertialModel = field(default_factory=InertialModel)
    accel: InertialModel = field(default_factory=InertialModel)
    mag: MagModel = field(default_factory=MagModel)
    mounting: Mounting = field(default_factory=Mounting)
    convention: str = "enu"
    fit: dict[str, Any] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        if self.convention not in CONVENTIONS:
            raise ValueError(f"convention: {self.convention!r} is not one of {', '.join(CONVENTIONS)}")

    @property
    def identity(self) -> bool:
        """True when nothing is changed (every stage skipped)."""
        return (
            self.gyro.identity
            and self.accel.identity
            and self.mag.identity
            and self.mounting.identity
            and self.convention == "enu"
        )

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of this section."""
        d: dict[str, Any] = {"format": FORMAT, "version": VERSION}
        d["gyro"] = self.gyro.to_dict()
        d["accel"] = self.accel.to_dict()
        d["mag"] = self.mag.to_dict()
        d["mounting"] = self.mounting.to_dict()
        d["convention"] = self.convention
        if self.fit:
            d["fit"] = self.fit
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Calibration:
        """From a parsed calibration file; ValueError names the bad field."""
        if not isinstance(d, dict):
            raise ValueError("calibration: expected a JSON object")
        if d.get("format") != FORMAT:
            raise ValueError(f"calibration: format {d.get('format')!r}, expected {FORMAT!r}")
        if d.get("version") != VERSION:
            raise ValueError(f"calibration: version {d.get('version')!r}, this attica reads {VERSION}")
        _only(d, {"format", "version", *SECTIONS}, "calibration")
        return cls(
            gyro=InertialModel.from_dict(d.get("gyro", {}), "gyro"),
            accel=InertialModel.from_dict(d.get("accel", {}), "accel"),
            mag=MagModel.from_dict(d.get("mag", {})),
            mounting=Mounting.from_dict(d.get("mounting", {})),
            convention=d.get("convention", "enu"),
            fit=dict(d.get("fit", {})),
        )

    def save(self, path: str | Path) -> None:
        """Write the JSON file (numbers as the shortest decimals that read back to the same float32)."""
        Path(path).write_text(_dumps(_short(self.to_dict())) + "\n")

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read a calibration file; errors name the file and the field."""
        p = Path(path)
        try:
            d = json.loads(p.read_text())
        except json.JSONDecodeError as e:
            raise ValueError(f"{p}: not JSON ({e})") from None
        try:
            return cls.from_dict(d)
        except ValueError as e:
            raise ValueError(f"{p}: {e}") from None


def _only(d: Any, keys: set[str], what: str) -> None:
    if not isinstance(d, dict):
        raise ValueError(f"{what}: expected a JSON object, got {d!r}")
    extra = set(d) - keys
    if extra:
        known = ", ".join(sorted(keys))
        raise ValueError(f"{what}: unknown field(s) {', '.join(sorted(extra))} (known: {known})")


def _short(x: Any) -> Any:
    """Floats as the shortest repr of their float32 value (reads back to the same float32)."""
    if isinstance(x, float):
        return float(np.format_float_positional(np.float32(x), unique=True, trim="-")) if x == x else x
    if isinstance(x, dict):
        return {k: _short(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_short(v) for v in x]
    return x


def _dumps(x: Any, indent: str = "") -> str:
    """JSON with one line per vector or matrix row (readable calibration files)."""
    if isinstance(x, dict) and x:
        inner = indent + "  "
        items = [f"{inner}{json.dumps(k)}: {_dumps(v, inner)}" for k, v in x.items()]
        return "{\n" + ",\n".join(items) + "\n" + indent + "}"
    if isinstance(x, list) and x and all(isinstance(v, list) for v in x):
        inner = indent + "  "
        return "[\n" + ",\n".join(inner + json.dumps(v) for v in x) + "\n" + indent + "]"
    return json.dumps(x)

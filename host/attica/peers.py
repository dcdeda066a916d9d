"""Other people's orientation filters, run on the same recordings for a side-by-side comparison.

Optional: ``pip install .[peers]`` installs them (imufusion, vqf, ahrs). :func:`available_peers` lists
the ones importable here. Every peer is wrapped as a :class:`Peer` whose :meth:`Peer.run` returns
quaternions ``(w, x, y, z)`` sensor-to-ENU, the convention of attica and of BROAD's ground truth, so
the same metric applies unchanged.

Frame conventions (each checked on simulated data with known truth by ``tests/test_eval.py``, so a
convention mistake cannot hide behind a plausible number):

=================  =====================================================  ==========================
peer               what it returns                                        turned into ENU by
=================  =====================================================  ==========================
VQF, BasicVQF      ``quat6D``/``quat9D`` w,x,y,z sensor-to-earth, ENU     nothing
Fusion (imufusion) w,x,y,z sensor-to-earth in the chosen convention;      nothing (``CONVENTION_ENU``)
                   we select ``CONVENTION_ENU``
ahrs Madgwick      w,x,y,z sensor-to-earth, earth frame NWU               ``Qz(+90 deg) * q``
ahrs Mahony        w,x,y,z sensor-to-earth, earth frame ENU (9D)          nothing
ahrs EKF           w,x,y,z sensor-to-earth, ``frame='NED'`` (default)     ``Qz(+90 deg) * q`` (see below)
=================  =====================================================  ==========================

(ahrs' EKF in ``NED`` mode is fed our +g-up accelerometer like the other two, so its earth frame comes
out as NWU as well, and its reference field must then be given with the elevation ``-dip``; we pass the
dip measured from the first samples, as its default is a fixed location's field. The test pins both.)
For 6-axis variants the heading is arbitrary; only the inclination is compared, and the rotation about
the vertical does not change it.

Units: the peers take gyro in rad/s (Fusion: deg/s), accel in m/s^2 (Fusion: g), mag in any unit.
Initial state: as each library does by default (BROAD's example code also lets Madgwick/Mahony start
from the first sample; we use the libraries' own start-up).

Settings: each peer runs with its defaults (``default``) and with one tuned setting (``tuned``),
documented in :data:`TUNED` with the reason.

Rows without a magnetometer sample: :data:`MISSING_MAG` (no interpolation; 9-axis ahrs filters start at
the first sample; the notes of ``attica eval`` say what was done on each trial).
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.data import Recording
from attica.evaluate.estimate import Estimate

__all__ = [
    "MISSING_MAG",
    "Peer",
    "PEERS",
    "TUNED",
    "available_peers",
    "peer_by_name",
    "PeerMissingError",
]

F64 = NDArray[np.float64]

_S = float(np.sqrt(0.5))
_QZ90 = np.array([_S, 0.0, 0.0, _S])
"""Rotation by +90 deg about the vertical: NWU earth frame -> ENU."""


class PeerMissingError(RuntimeError):
    """The library a peer needs is not installed."""


def _qmul_left(a: F64, q: F64) -> F64:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=1,
    )


def _inputs(rec: Recording) -> tuple[F64, F64, F64, NDArray[np.bool_]]:
    """Gyro, accel, mag as float64 with the rows without a mag sample zeroed, and which rows have one.

    A row has a mag sample when its three values are finite and not all zero (attica's convention:
    NaN or zero rows are "no sample", as in phone logs whose magnetometer runs slower than the gyro).
    """
    g = np.ascontiguousarray(rec.gyr, dtype=np.float64)
    a = np.ascontiguousarray(rec.acc, dtype=np.float64)
    m = np.array(rec.mag, dtype=np.float64, order="C")
    present = np.isfinite(m).all(axis=1) & (m != 0.0).any(axis=1)
    m[~present] = 0.0
    return g, a, m, present


def _zero_note(library: str, present: NDArray[np.bool_]) -> tuple[str, ...]:
    """The note of a peer that takes a zero field as "no sample" (VQF, Fusion)."""
    missing = int(np.count_nonzero(~present))
    if missing == 0:
        return ()
    if missing == len(present):
        return (f"no mag sample in the recording: {library} ran without mag updates (heading not observed)",)
    return (f"{missing} of {len(present)} rows without a mag sample: given to {library} as zero (no sample)",)


def _run_vqf(rec: Recording, nine: bool, params: dict[str, Any], basic: bool) -> Estimate:
    import vqf

    g, a, m, present = _inputs(rec)
    cls = vqf.BasicVQF if basic else vqf.VQF
    ts = 1.0 / rec.rate
    rows = np.flatnonzero(present)
    # a slower magnetometer: its typical sample period (the median spacing of the rows with a sample, so
    # that a stretch without one does not count), so that tauMag and the rejection times stay seconds
    mag_ts = ts * float(np.median(np.diff(rows))) if nine and rows.size > 1 else -1.0
    est = cls(ts, -1.0, mag_ts, **params)
    out = est.updateBatch(g, a, m) if nine else est.updateBatch(g, a)
    q = np.asarray(out["quat9D" if nine else "quat6D"], dtype=np.float64)
    bias = None if basic else np.asarray(out["bias"], dtype=np.float64)
    notes = _zero_note("BasicVQF" if basic else "VQF", present) if nine else ()
    return Estimate(q, gyro_bias=bias, notes=notes)


def _run_fusion(rec: Recording, nine: bool, params: dict[str, Any]) -> Estimate:
    import imufusion

    g, a, m, present = _inputs(rec)
    settings = imufusion.AhrsSettings()
    settings.convention = imufusion.CONVENTION_ENU
    settings.sample_rate = float(rec.rate)
    for k, v in params.items():
        if k != "bias":
            setattr(settings, k, v)
    ahrs = imufusion.Ahrs()
    ahrs.set_settings(settings)
    bias = None
    if params.get("bias"):
        bias_settings = imufusion.BiasSettings()
        bias_settings.sample_rate = float(rec.rate)
        bias = imufusion.Bias()
        bias.set_settings(bias_settings)
    gd = np.degrees(g)
    ag = a / 9.80665
    out = np.empty((len(g), 4))
    for i in range(len(g)):
        w = gd[i]
        if bias is not None:
            w = bias.update(w)
        if nine:
            ahrs.update(w, ag[i], m[i])
        else:
            ahrs.update_no_magnetometer(w, ag[i])
        out[i] = ahrs.get_quaternion()
    return Estimate(out, notes=_zero_note("Fusion", present) if nine else ())


def _dip_deg(acc: F64, mag: F64) -> float:
    """Magnetic dip from the first (up to 50) samples (angle of the field below the horizontal), degrees."""
    k = min(len(acc), 50)
    a = acc[:k].mean(axis=0)
    m = mag[:k].mean(axis=0)
    c = float(np.dot(a, m) / (np.linalg.norm(a) * np.linalg.norm(m)))
    return float(np.degrees(np.arcsin(np.clip(-c, -1.0, 1.0))))


def _run_ahrs(rec: Recording, nine: bool, name: str, params: dict[str, Any]) -> Estimate:
    """An ahrs filter in batch mode; see :data:`MISSING_MAG` for the rows without a mag sample."""
    import ahrs.filters

    g, a, m, present = _inputs(rec)
    n = len(g)
    notes: list[str] = []
    start = 0
    if nine:
        rows = np.flatnonzero(present)
        if rows.size == 0:
            note = f"no mag sample in the recording: not run (ahrs {name} starts from the first row's field)"
            return Estimate(np.full((n, 4), np.nan), scored=np.zeros(n, np.bool_), notes=(note,))
        start = int(rows[0])
        if start:
            notes.append(
                f"rows 0-{start - 1} ({start / rec.rate:.2f} s) before the first mag sample: no estimate, "
                f"not scored (ahrs {name} starts from the first row's field)"
            )
        later = int(np.count_nonzero(~present[start:]))
        if later and name == "EKF":
            held = np.maximum.accumulate(np.where(present, np.arange(n), 0))
            m = m[held]
            notes.append(
                f"{later} later rows without a mag sample: the last sample held (ahrs EKF needs one)"
            )
        elif later:
            notes.append(
                f"{later} later rows without a mag sample: a 6-axis update there (ahrs {name}'s own)"
            )
    kw: dict[str, Any] = {"gyr": g[start:], "acc": a[start:], "frequency": float(rec.rate), **params}
    if nine:
        kw["mag"] = m[start:]
    if name == "EKF" and nine and "magnetic_ref" not in kw:
        # its default is a fixed location's field; in NED mode with our +g-up accelerometer its earth frame
        # comes out z-up (NWU), so the field's elevation is given as seen from there: -dip
        kw["magnetic_ref"] = -_dip_deg(a[present], m[present])
    q = np.full((n, 4), np.nan)
    q[start:] = np.asarray(getattr(ahrs.filters, name)(**kw).Q, dtype=np.float64)
    if name in ("Madgwick", "EKF") or not nine:
        q[start:] = _qmul_left(_QZ90, q[start:])
    scored = None
    if start:
        scored = np.arange(n) >= start
    return Estimate(q, scored=scored, notes=tuple(notes))


MISSING_MAG = """Rows without a magnetometer sample (NaN or zero, e.g. a phone's slower magnetometer):

- VQF, BasicVQF, Fusion (9-axis): the row is given as a zero field, which these libraries take as "no
  sample" (no mag update on that row); VQF is told the magnetometer's sample period (``magTs``, the
  median spacing of the rows with a sample),
  so that its mag time constants stay in seconds; Fusion has no such setting, so its rejection timeout
  counts mag updates: 5 s of them at a magnetometer k times slower are 5 k s;
- ahrs Madgwick, Mahony, EKF (9-axis): their batch mode starts from the first row's field, so they run
  from the first row with a sample on; the rows before have no estimate and are not scored (the table's
  notes say how many). Later rows without a sample: Madgwick and Mahony get a zero field, on which they
  make their 6-axis update; the EKF, which needs a field on every row, gets the last sample held;
- no sample at all: VQF and Fusion run without mag updates, the ahrs filters do not run (NaN scores).

Nothing is interpolated, and the last sample is held only for the ahrs EKF."""
"""What the peers are given for rows without a mag sample (``attica eval --peers`` prints the notes)."""


@dataclass(frozen=True)
class Peer:
    """One peer filter variant.

    Attributes
    ----------
    name : str
        Label used in tables (``vqf9``, ``fusion6@tuned`` ...).
    library : str
        Import name of the library (``vqf``, ``imufusion``, ``ahrs``).
    nine_axis : bool
        Uses the magnetometer (judged by total error) or not (inclination only).
    setting : str
        ``default`` or ``tuned``.
    runner : callable
        ``runner(recording)`` -> :class:`~attica.evaluate.estimate.Estimate` (quaternions sensor-to-ENU,
        rows scored, notes; VQF also its gyro bias).
    note : str
        What the setting is.

    Rows without a magnetometer sample are handled as :data:`MISSING_MAG` describes.

    """

    name: str
    library: str
    nine_axis: bool
    setting: str
    runner: Callable[[Recording], Estimate] = field(compare=False, repr=False)
    note: str = ""

    @property
    def installed(self) -> bool:
        """Whether the library imports here."""
        return importlib.util.find_spec(self.library) is not None

    def run(self, rec: Recording) -> F64:
        """Quaternions ``(N, 4)`` w,x,y,z sensor-to-ENU for a recording (NaN rows: no estimate)."""
        return self.estimate(rec).q

    def estimate(self, rec: Recording) -> Estimate:
        """The :class:`~attica.evaluate.estimate.Estimate` of a recording (the ``run`` of ``attica eval``)."""
        if not self.installed:
            raise PeerMissingError(
                f"{self.name} needs the Python package {self.library!r}: pip install '.[peers]'"
            )
        if not rec.lost:
            return self.runner(rec)
        return _over_gaps(self.runner, rec)


def _over_gaps(runner: Callable[[Recording], Estimate], rec: Recording) -> Estimate:
    """A peer over a recording with lost samples: each sample held over its periods, as attica steps it.

    The peers take one fixed period per call; a sample that stands for n periods is given n times
    (gyro held over the gap, mag only the first time), and its row scores the estimate after the last.
    """
    steps = rec.steps.astype(np.int64)
    idx = np.repeat(np.arange(rec.n), steps)
    first = np.ones(idx.size, np.bool_)
    first[1:] = idx[1:] != idx[:-1]
    mag = rec.mag[idx].copy()
    mag[~first] = np.nan  # one mag sample is one sample, not n
    held = Recording(rec.gyr[idx], rec.acc[idx], mag, rec.rate, name=rec.name, groups=rec.groups)
    est = runner(held)
    last = np.cumsum(steps) - 1
    note = (
        f"{rec.lost} lost sample(s): each sample held over its periods, as attica steps it "
        f"({rec.n} rows given as {idx.size}; a held row has no mag sample)"
    )
    # the runner's own notes count the rows it was given (the held ones included): said so
    notes = tuple(f"on the {idx.size} rows given, samples held: {n}" for n in est.notes)
    return Estimate(
        est.q[last],
        scored=est.scored[last] if est.scored is not None else None,
        flags=est.flags[last] if est.flags is not None else None,
        gyro_bias=est.gyro_bias[last] if est.gyro_bias is not None else None,
        notes=(*notes, note),
    )


TUNED: dict[str, tuple[dict[str, Any], str]] = {
    "vqf": ({"tauAcc": 2.0, "tauMag": 10.0}, "tauAcc 2 s, tauMag 10 s (defaults 3 s, 9 s)"),
    "basicvqf": ({"tauAcc": 2.0, "tauMag": 10.0}, "tauAcc 2 s, tauMag 10 s (defaults 3 s, 9 s)"),
    "fusion": (
        {"gain": 0.1, "bias": True},
        "gain 0.1 (default 0.5) and Fusion's gyro offset (Bias) correction",
    ),
    "madgwick": ({"gain": 0.1}, "beta 0.1 (ahrs' default 0.041 for 9D)"),
    "mahony": ({"k_P": 0.2, "k_I": 0.001}, "k_P 0.2, k_I 0.001 (defaults 1.0, 0.3)"),
    "ekf": (
        {"noises": [0.3**2, 1.0**2, 2.0**2]},
        "noise variances (gyro, acc, mag) 0.09, 1, 4 (defaults 0.09, 0.25, 0.64): trusts the gyro longer",
    ),
}
"""Tuned setting per peer family: (keyword arguments, description)."""

FUSION_DEFAULT = {
    "gain": 0.5,
    "gyroscope_range": 2000.0,
    "acceleration_rejection": 10.0,
    "magnetic_rejection": 10.0,
    "rejection_timeout": 5.0,
}
"""Fusion's settings as in its README example (the library's zero-initialised struct turns the
rejection features off, which is not how its authors run it). ``rejection_timeout`` is in seconds:
imufusion 1.3's ``AhrsSettings`` takes the ``sample_rate`` and counts the samples itself (the C
library's ``5 * SAMPLE_RATE`` samples of its README before 1.3), so 5 s at every rate. Until
2026-12-06 this held 1425, the samples of 5 s at BROAD's rate, read by Fusion as 1425 s: its
acceleration and magnetic recovery never ran (tests/test_peers_fusion.py)."""


def _make() -> list[Peer]:
    peers: list[Peer] = []
    for family, basic in (("vqf", False), ("basicvqf", True)):
        label = "BasicVQF" if basic else "VQF"
        for nine in (True, False):
            tag = f"{family}{9 if nine else 6}"
            peers.append(
                Peer(tag, "vqf", nine, "default", partial(_run_vqf, nine=nine, params={}, basic=basic), label)
            )
            params = TUNED[family][0]
            peers.append(
                Peer(
                    f"{tag}@tuned",
                    "vqf",
                    nine,
                    "tuned",
                    partial(_run_vqf, nine=nine, params=params, basic=basic),
                    f"{label}: {TUNED[family][1]}",
                )
            )
    for nine in (True, False):
        tag = f"fusion{9 if nine else 6}"
        peers.append(
            Peer(
                tag,
                "imufusion",
                nine,
                "default",
                partial(_run_fusion, nine=nine, params=FUSION_DEFAULT),
                "Fusion",
            )
        )
        tuned = {**FUSION_DEFAULT, **TUNED["fusion"][0]}
        peers.append(
            Peer(
                f"{tag}@tuned",
                "imufusion",
                nine,
                "tuned",
                partial(_run_fusion, nine=nine, params=tuned),
                f"Fusion: {TUNED['fusion'][1]}",
            )
        )
    for family, cls in (("madgwick", "Madgwick"), ("mahony", "Mahony"), ("ekf", "EKF")):
        tag = f"{family}9"
        peers.append(
            Peer(
                tag,
                "ahrs",
                True,
                "default",
                partial(_run_ahrs, nine=True, name=cls, params={}),
                f"ahrs {cls}",
            )
        )
        params = TUNED[family][0]
        peers.append(
            Peer(
                f"{tag}@tuned",
                "ahrs",
                True,
                "tuned",
                partial(_run_ahrs, nine=True, name=cls, params=params),
                f"ahrs {cls}: {TUNED[family][1]}",
            )
        )
    return peers


PEERS: list[Peer] = _make()
"""Every peer variant attica knows (installed or not)."""


def available_peers(names: list[str] | None = None) -> list[Peer]:
    """The installed peers, optionally only those whose name (or name before ``@``) is in ``names``."""
    out = [p for p in PEERS if p.installed]
    if names:
        out = [p for p in out if p.name in names or p.name.split("@")[0] in names]
    return out


def peer_by_name(name: str) -> Peer:
    """A peer by its exact name; KeyError listing the names otherwise."""
    for p in PEERS:
        if p.name == name:
            return p
    raise KeyError(f"unknown peer {name!r}; peers: {', '.join(p.name for p in PEERS)}")

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

__all__ = ["Peer", "PEERS", "TUNED", "available_peers", "peer_by_name", "PeerMissingError"]

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


def _inputs(rec: Recording) -> tuple[F64, F64, F64]:
    g = np.ascontiguousarray(rec.gyr, dtype=np.float64)
    a = np.ascontiguousarray(rec.acc, dtype=np.float64)
    m = np.ascontiguousarray(rec.mag, dtype=np.float64)
    # peers cannot take "no sample" rows: hold the last valid one (BROAD has none missing)
    bad = ~np.isfinite(m).all(axis=1)
    if bad.any():
        idx = np.where(~bad, np.arange(len(m)), 0)
        np.maximum.accumulate(idx, out=idx)
        m = m[idx]
        m[~np.isfinite(m)] = 0.0
    return g, a, m


def _run_vqf(rec: Recording, nine: bool, params: dict[str, Any], basic: bool) -> F64:
    import vqf

    g, a, m = _inputs(rec)
    cls = vqf.BasicVQF if basic else vqf.VQF
    est = cls(1.0 / rec.rate, **params)
    out = est.updateBatch(g, a, m) if nine else est.updateBatch(g, a)
    return np.asarray(out["quat9D" if nine else "quat6D"], dtype=np.float64)


def _run_fusion(rec: Recording, nine: bool, params: dict[str, Any]) -> F64:
    import imufusion

    g, a, m = _inputs(rec)
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
    return out


def _dip_deg(rec: Recording) -> float:
    """Magnetic dip from the first samples (angle of the field below the horizontal), degrees."""
    k = min(len(rec.acc), 50)
    a = rec.acc[:k].astype(np.float64).mean(axis=0)
    m = np.nanmean(rec.mag[:k].astype(np.float64), axis=0)
    c = float(np.dot(a, m) / (np.linalg.norm(a) * np.linalg.norm(m)))
    return float(np.degrees(np.arcsin(np.clip(-c, -1.0, 1.0))))


def _run_ahrs(rec: Recording, nine: bool, name: str, params: dict[str, Any]) -> F64:
    import ahrs.filters

    g, a, m = _inputs(rec)
    kw: dict[str, Any] = {"gyr": g, "acc": a, "frequency": float(rec.rate), **params}
    if nine:
        kw["mag"] = m
    if name == "EKF" and nine and "magnetic_ref" not in kw:
        # its default is a fixed location's field; in NED mode with our +g-up accelerometer its earth frame
        # comes out z-up (NWU), so the field's elevation is given as seen from there: -dip
        kw["magnetic_ref"] = -_dip_deg(rec)
    q = np.asarray(getattr(ahrs.filters, name)(**kw).Q, dtype=np.float64)
    if name in ("Madgwick", "EKF") or not nine:
        q = _qmul_left(_QZ90, q)
    return q


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
        ``runner(recording) -> (N, 4)`` quaternions sensor-to-ENU.
    note : str
        What the setting is.

    """

    name: str
    library: str
    nine_axis: bool
    setting: str
    runner: Callable[[Recording], F64] = field(compare=False, repr=False)
    note: str = ""

    @property
    def installed(self) -> bool:
        """Whether the library imports here."""
        return importlib.util.find_spec(self.library) is not None

    def run(self, rec: Recording) -> F64:
        """Quaternions ``(N, 4)`` w,x,y,z sensor-to-ENU for a recording."""
        if not self.installed:
            raise PeerMissingError(
                f"{self.name} needs the Python package {self.library!r}: pip install '.[peers]'"
            )
        return self.runner(rec)


TUNED: dict[str, tuple[dict[str, Any], str]] = {
    "vqf": ({"tauAcc": 2.0, "tauMag": 10.0}, "tauAcc 2 s, tauMag 10 s (defaults 3 s, 9 s)"),
    "basicvqf": ({"tauAcc": 2.0, "tauMag": 10.0}, "tauAcc 2 s, tauMag 10 s (defaults 3 s, 9 s)"),
    "fusion": (
        {"gain": 0.1, "bias": True},
        "gain 0.1 (default 0.5) and Fusion's gyro offset (Bias) correction",
    ),
    "madgwick": ({"gain": 0.1}, "beta 0.1 (ahrs' default 0.033 for 9D)"),
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
    "rejection_timeout": 5 * 285,
}
"""Fusion's settings as in its README example (the library's zero-initialised struct turns the
rejection features off, which is not how its authors run it). ``rejection_timeout`` is in samples."""


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

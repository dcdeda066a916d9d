"""Filter outputs that print with labels: :class:`Outputs`, a numpy record array of ``att_output_t``.

``Filter.run`` and ``Filter.step`` return :class:`Outputs`: a plain numpy structured array (fields
``q``, ``euler``, ``gyro_bias``, ``cov``, ``flags``, ``steps``: :data:`attica.outputs.OUTPUT_DTYPE`)
whose ``repr`` is a table with units and flag names instead of bare tuples::

    >>> attica.Filter("ars", 0.01).run(gyr, acc)
    Outputs: 1000 steps
    steps  q (w x y z)                          euler (deg: roll pitch yaw)  gyro_bias (rad/s) ...  flags
        1   0.75550 -0.56890  0.25956  0.19545    -73.96    37.92     0.00    0.00000 ...  INITIALISED
      ...

Field access gives ordinary arrays (``out["q"]`` is a float32 (N, 4) ndarray).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.settings import describe_flags

__all__ = ["Outputs", "as_outputs"]

_LABELS = {
    "q": "q (w x y z)",
    "euler": "euler (deg: roll pitch yaw)",
    "gyro_bias": "gyro_bias (rad/s)",
    "cov": "cov (diagonal)",
    "flags": "flags",
    "steps": "steps",
    "valid": "valid (written)",
}
_EDGE = 4
"""Rows shown at each end of a long output."""


class Outputs(np.ndarray):
    """A structured array of filter output records that prints as a labelled table.

    Anything that is not a whole record (a field, a comparison result) comes back as a plain ndarray.
    """

    def __getitem__(self, key: Any) -> Any:
        if isinstance(key, (int, np.integer)) and self.ndim == 1 and self.dtype.names is not None:
            i = int(key) + (self.shape[0] if key < 0 else 0)
            if not 0 <= i < self.shape[0]:
                raise IndexError(f"index {int(key)} is out of bounds for {self.shape[0]} outputs")
            return super().__getitem__(slice(i, i + 1)).reshape(())  # a 0-d view, printed with labels
        got = super().__getitem__(key)
        if isinstance(got, np.ndarray) and got.dtype.names is None:
            return got.view(np.ndarray)
        return got

    def __array_wrap__(self, obj: Any, context: Any = None, return_scalar: bool = False) -> Any:
        if isinstance(obj, np.ndarray) and obj.dtype.names is None:
            out = obj.view(np.ndarray)
            return out[()] if return_scalar else out
        return super().__array_wrap__(obj, context, return_scalar)

    def __repr__(self) -> str:
        if self.dtype.names is None or self.ndim > 1:
            return repr(self.view(np.ndarray))
        return _format(self)

    def __str__(self) -> str:
        return self.__repr__()


def as_outputs(records: NDArray[Any]) -> Outputs:
    """View output records (any shape) as :class:`Outputs` (no copy)."""
    return records.view(Outputs)


def _cell(name: str, value: Any) -> str:
    if name == "flags":
        return describe_flags(int(value))
    if name == "valid":
        return _valid_text(int(value))
    v = np.asarray(value)
    if v.dtype.kind == "f":
        if name == "euler":
            return " ".join(f"{x:8.2f}" for x in np.degrees(v.astype(np.float64)).reshape(-1))
        return " ".join(f"{x:8.5f}" for x in v.astype(np.float64).reshape(-1))
    if v.ndim == 0:
        return str(int(v)) if name == "steps" else f"0x{int(v):X}"
    return " ".join(str(int(x)) for x in v.reshape(-1))


_VALID_BITS = {"q": 0x1, "euler": 0x2, "gyro_bias": 0x4, "cov": 0x8}
"""``ATT_OUT_*``: which field a record's ``valid`` mask says was written."""
_VALID_ALL = 0xF


def _valid_text(value: int) -> str:
    v = int(value)
    return (
        "all" if v & _VALID_ALL == _VALID_ALL else "|".join(n for n, b in _VALID_BITS.items() if v & b) or "-"
    )


def _shown_fields(rec: NDArray[Any]) -> list[str]:
    names = list(rec.dtype.names or ())
    plain = rec.view(np.ndarray)
    if "valid" in names and rec.size:
        seen = int(np.bitwise_or.reduce(np.asarray(plain["valid"], np.uint32).reshape(-1)))
        names = [n for n in names if n not in _VALID_BITS or seen & _VALID_BITS[n]]  # fields never written
        if np.all(np.asarray(plain["valid"]) & _VALID_ALL == _VALID_ALL):
            names.remove("valid")  # everything written everywhere: nothing to say
    # cov is filled by the Kalman filters only: hide an all-zero cov
    if "cov" in names and rec.size and not np.any(np.asarray(plain["cov"])):
        names.remove("cov")
    if "steps" in names:  # the step number leads each row
        names.remove("steps")
        names.insert(0, "steps")
    return names


def _format(out: Outputs) -> str:
    plain = out.view(np.ndarray)
    names = _shown_fields(plain)
    if plain.ndim == 0:
        width = max(len(_LABELS.get(n, n)) for n in names)
        lines = ["Outputs: one step"]
        lines += [f"  {_LABELS.get(n, n):<{width}}  {_cell(n, plain[n])}" for n in names]
        return "\n".join(lines)
    n_rows = plain.shape[0]
    head = f"Outputs: {n_rows} step{'s' if n_rows != 1 else ''}"
    if n_rows == 0:
        return head
    idx = list(range(n_rows)) if n_rows <= 2 * _EDGE else [*range(_EDGE), -1, *range(n_rows - _EDGE, n_rows)]
    rows = [[_cell(n, plain[i][n]) for n in names] if i >= 0 else ["..."] * len(names) for i in idx]
    widths = [max(len(_LABELS.get(n, n)), *(len(r[j]) for r in rows)) for j, n in enumerate(names)]
    labels = [_LABELS.get(n, n) for n in names]
    lines = [
        head,
        "  ".join(x.rjust(w) if j == 0 else x.ljust(w) for j, (x, w) in enumerate(zip(labels, widths))),
    ]
    for r in rows:
        lines.append(
            "  ".join(
                c.rjust(w) if j == 0 else c.ljust(w) for j, (c, w) in enumerate(zip(r, widths))
            ).rstrip()
        )
    return "\n".join(lines)

"""The output digests (tools/attica_dev/digests.py): every output bit of every kind, the calibration
stages, the heading and retune hooks and the node's frames, against tests/digests.txt.

A change of behaviour fails here until the same commit regenerates the file
(``PYTHONPATH=tools python -m attica_dev.digests --update``) and says why.
"""

from __future__ import annotations

import pytest

from attica.kinds import labels
from attica_dev import digests


def test_digest_file_lists_every_case() -> None:
    committed = digests.read()
    names = [c.name for c in digests.cases()]
    assert len(names) == len(set(names))
    assert sorted(committed) == sorted(names), "regenerate tests/digests.txt: cases were added or removed"


def test_inputs_unchanged() -> None:
    """A change here is the simulator's (or numpy's), not the firmware's."""
    committed = digests.read()
    assert digests.compute("input.") == {k: v for k, v in committed.items() if k.startswith("input.")}


@pytest.mark.parametrize("kind", labels())
def test_outputs_unchanged(kind: str) -> None:
    committed = digests.read()
    now = digests.compute(kind + ".")
    assert now, f"no digest cases for {kind}"
    changed = sorted(k for k in now if committed.get(k) != now[k])
    assert not changed, f"{len(changed)} of {len(now)} digests of {kind} changed: {', '.join(changed)}"


def test_every_kind_has_a_retune_case() -> None:
    assert sorted(digests._RETUNE) == sorted(labels())


def test_a_one_bit_change_changes_the_digest() -> None:
    import numpy as np

    recs = digests.run_records(digests.implemented_kinds()[0], "default", "sim", True)
    flipped = recs.copy()
    flipped["q"].view(np.uint32)[-1, 3] ^= 1
    assert digests.sha(recs) != digests.sha(flipped)

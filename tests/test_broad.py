"""Every filter over every BROAD trial in ../shared: C and reference bit for bit."""

from __future__ import annotations

import pytest

from attica.crosscheck import Stream, crosscheck
from attica.data import load_recording
from attica.settings import FilterKind, implemented_kinds, make_settings

from helpers import broad_trials


@pytest.fixture(scope="module")
def streams() -> list[Stream]:
    out = []
    for path in broad_trials():
        rec = load_recording(path)
        out.append(Stream(rec.gyr, rec.acc, rec.mag, name=path.stem))
    return out


@pytest.mark.parametrize("kind", implemented_kinds(), ids=lambda k: k.label)
def test_broad_bit_exact(kind: FilterKind, streams: list[Stream]) -> None:
    settings = make_settings(kind, dt=1 / 285.714)
    r = crosscheck(kind, streams, settings, segment=1000)
    print(f"\n{kind.label}: {r.steps} steps over {len(streams)} BROAD trials compared")
    assert r.steps == sum(len(s.gyr) for s in streams)
    assert r.ok, r.first_mismatch

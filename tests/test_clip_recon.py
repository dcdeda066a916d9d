"""The clip reconstruction study of tools/attica_dev/clip_recon.py: the parabola fit on a known peak."""

from __future__ import annotations

import numpy as np
import pytest

from attica_dev.clip_recon import reconstruct


def _peak(n: int = 200, top: float = 12.0, clip: float = 8.0) -> tuple[np.ndarray, np.ndarray]:
    """A parabolic rate peak on axis 1 (negative, to check the sign), the true and the clipped gyro."""
    t = np.arange(n, dtype=np.float64)
    true = np.zeros((n, 3))
    true[:, 1] = -(top - 0.0008 * (t - 100.0) ** 2)
    true[:, 0] = 0.3  # an unclipped axis is left alone
    return true, np.clip(true, -clip, clip).astype(np.float32)


def test_replaced_restores_a_parabolic_peak_and_at_end_adds_its_lost_area() -> None:
    true, gyr = _peak()
    replaced, at_end = reconstruct(gyr, 8.0)
    clipped = np.abs(gyr[:, 1]) >= 8.0
    assert clipped.sum() > 50
    np.testing.assert_allclose(replaced[:, 1], true[:, 1], atol=1e-3)
    np.testing.assert_array_equal(replaced[:, 0], gyr[:, 0])
    lost = np.sum(true[clipped, 1] - gyr[clipped, 1])
    added = at_end[:, 1].astype(np.float64) - gyr[:, 1]
    assert np.count_nonzero(added) == 1
    last = int(np.flatnonzero(clipped)[-1])
    assert added[last + 4] == pytest.approx(lost, rel=1e-4)
    assert lost < -10.0  # the negative peak lost a negative rotation


def test_a_run_without_the_samples_around_it_is_left_alone() -> None:
    _, gyr = _peak()
    head = gyr[95:].copy()  # the run starts at the first sample: nothing before it to fit
    replaced, at_end = reconstruct(head, 8.0)
    np.testing.assert_array_equal(replaced, head)
    np.testing.assert_array_equal(at_end, head)

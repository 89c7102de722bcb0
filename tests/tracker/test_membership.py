import numpy as np

from tracker.membership import members


def test_members_is_numpys_isin_for_whole_numbers():
    """Against ``np.isin`` on random integers: duplicates, negatives, feature ids beyond 2^40, mixed widths, empty
    arrays on either side, none and all in."""
    rng = np.random.default_rng(8)
    for _ in range(300):
        low, high = sorted(rng.integers(-(1 << 41), 1 << 41, size=2))
        high = max(high, low + 1)
        values = rng.integers(low, high if rng.random() < 0.5 else low + 40, size=rng.integers(0, 60))
        among = rng.integers(low, high if rng.random() < 0.5 else low + 40, size=rng.integers(0, 60))
        if rng.random() < 0.3:
            values = values.astype(np.int32) if np.abs(values).max(initial=0) < 2**31 else values
        np.testing.assert_array_equal(members(values, among), np.isin(values, among))
    ids = np.arange(5, 25, dtype=np.int64)
    assert members(ids, ids[::-1]).all() and not members(ids, ids + 100).any()
    assert members(np.zeros(0, np.int64), ids).shape == (0,)

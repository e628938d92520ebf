"""``_EdgeStore.copy`` (the live re-solve's snapshot under the session lock) hands out pairs
stored in stamp order as they lie (read-only views): the same arrays as the stable sort's gather
it replaced, and never changed by the store afterwards."""

import numpy as np
import pytest

from rwhec_ros.sync.edge_store import _EdgeStore


def _reference(store):
    """The stable-sort gather ``copy`` used before (the reference)."""
    order = np.argsort(store.stamps[: store.n], kind="stable")
    return (store.stamps[: store.n][order], store.A[: store.n][order],
            store.B[: store.n][order], store.sigma[: store.n][order],
            store.kappa[: store.n][order])


@pytest.mark.parametrize("stamps", [
    [],  # empty
    [5],  # one pair
    [1, 2, 3, 7, 9],  # in time order: the shortcut
    [1, 2, 2, 2, 5],  # ties in order: the stable sort keeps them as they lie, so does the copy
    [3, 1, 2, 2, 0],  # out of order (e.g. a slot overwritten by a later keyframe): sorted
    [1, 2, 3, 5, 4],  # only the last pair out of order
])
def test_copy_equals_the_stable_sort(stamps):
    rng = np.random.default_rng(len(stamps))
    store = _EdgeStore("tag_0", "cam_0", 64)
    for i, s in enumerate(stamps):
        store.write(i, s, rng.standard_normal((4, 4)), rng.standard_normal((4, 4)),
                    float(rng.uniform(0.01, 0.1)), float(rng.uniform(10, 200)))
    store.n = len(stamps)
    got = store.copy()
    ref = _reference(store)
    for a, b in zip((got.stamps_ns, got.A, got.B, got.sigma, got.kappa), ref, strict=True):
        assert a.dtype == b.dtype and a.shape == b.shape
        assert np.array_equal(a, b)  # the same pairs in the same order, bit for bit
    assert np.all(np.diff(got.stamps_ns) >= 0)
    # read-only, and never changed by the store: a stored pair replaced, a pair appended
    if stamps:
        before = [a.copy() for a in (got.stamps_ns, got.A, got.B, got.sigma, got.kappa)]
        with pytest.raises(ValueError, match="read-only"):
            got.A[0] = 0.0
        store.write(0, 99, np.eye(4), np.eye(4), 1.0, 1.0)  # a replacement (slot < n)
        store.write(store.n, 100, np.eye(4), np.eye(4), 1.0, 1.0)  # an append (slot n)
        store.n += 1
        for a, b in zip((got.stamps_ns, got.A, got.B, got.sigma, got.kappa), before,
                        strict=True):
            assert np.array_equal(a, b)

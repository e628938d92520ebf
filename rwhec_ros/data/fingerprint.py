"""Which data set a result was solved from: the fingerprint of a data set, and the check.

A result YAML records ``dataset_fingerprint``: the number of pairs per edge (``"(x, y)"`` -> n,
readable) and the SHA-256 of the arrays (per edge in order: its frame names, stamps, ``A``,
``B``, ``sigma`` and ``kappa`` as little-endian ``int64``/``float64``), so that the same pairs
give the same fingerprint whether they are stored inline in the YAML or in the ``.npz`` file,
and the metadata (creation time, configuration) does not count. ``rwhec-calibrate report``
and ``dataset`` compare it with the data set they are given (:func:`fingerprint_mismatch`).
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["FINGERPRINT_KEY", "dataset_fingerprint", "fingerprint_mismatch"]

#: The key of the fingerprint in a result YAML.
FINGERPRINT_KEY = "dataset_fingerprint"


def dataset_fingerprint(dataset) -> dict[str, Any]:
    """``{"pairs": {"(x, y)": n, ...}, "total": N, "sha256": <hex>}`` of a
    :class:`~rwhec_ros.data.dataset.Dataset` (module docstring)."""
    h = hashlib.sha256()
    pairs = {}
    for e in dataset.edges:
        pairs[f"({e.x}, {e.y})"] = int(e.n)
        h.update(f"{e.x}\0{e.y}\0{int(e.n)}\0".encode())
        h.update(np.ascontiguousarray(e.stamps_ns, dtype="<i8").tobytes())
        for arr in (e.A, e.B, e.sigma, e.kappa):
            h.update(np.ascontiguousarray(arr, dtype="<f8").tobytes())
    h.update(b"unknown_scale" if dataset.unknown_scale else b"known_scale")
    return {"pairs": pairs, "total": int(sum(pairs.values())), "sha256": h.hexdigest()}


def fingerprint_mismatch(recorded: Mapping[str, Any], dataset) -> str:
    """How the data set differs from the ``recorded`` fingerprint, in words, or ``""`` when it
    is the data set the fingerprint was taken of."""
    now = dataset_fingerprint(dataset)
    if recorded.get("sha256") == now["sha256"]:
        return ""
    then = dict(recorded.get("pairs") or {})
    total = recorded.get("total", sum(int(v) for v in then.values()))
    words = f"the result was solved from {total} pairs on {len(then)} edges, the data set has " \
            f"{now['total']} pairs on {len(now['pairs'])} edges"
    if then == now["pairs"]:
        words += " (the same counts, other values)"
    else:
        diff = [k for k in sorted(set(then) | set(now["pairs"]))
                if then.get(k) != now["pairs"].get(k)]
        first = diff[0]
        words += (f" (e.g. edge {first}: {then.get(first, 0)} pairs in the result, "
                  f"{now['pairs'].get(first, 0)} in the data set)")
    return words

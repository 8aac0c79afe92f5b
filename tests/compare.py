"""Comparing floats that code computed: within a tolerance, never with == (two computations of one value,
on one machine or two, may differ by round-off: issue 35)."""

import numpy as np
import pytest


def close_tree(a, b, rel: float) -> bool:
    """Two TOML-like trees (dicts, lists, strings, numbers) equal but for floats within ``rel`` of each
    other (floats computed on two machines differ by round-off: never compared with ==)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(close_tree(a[k], b[k], rel) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(close_tree(x, y, rel) for x, y in zip(a, b))
    if isinstance(a, float) or isinstance(b, float):
        return a == pytest.approx(b, rel=rel, abs=0.0)
    return a == b


def assert_close(a, b, rel: float, what: str = "") -> None:
    """Arrays of one shape equal within ``rel`` of the larger's largest magnitude (NaN where both are
    NaN): a tolerance on the scale of the values, so that zeros and round-off-sized values compare too."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape, (what, a.shape, b.shape)
    both = np.isnan(a) & np.isnan(b)
    scale = max(np.abs(np.where(both, 0.0, a)).max(initial=0.0), np.abs(np.where(both, 0.0, b)).max(initial=0.0))
    difference = np.abs(np.where(both, 0.0, a - b)).max(initial=0.0)
    assert difference <= rel * scale, f"{what}: differ by {difference:.3g}, more than {rel:g} x {scale:.3g}"

"""Which steps a run saves: :func:`saved_steps` (issue #40: below :mod:`vpforms._solution` and
:mod:`vpforms.io`, which both need it, so that ``Solution.to_xarray`` can use ``vpforms.io``
without a cycle)."""

from __future__ import annotations

import numpy as np

__all__ = ["saved_steps"]


def saved_steps(n_steps: int, save_every: int | None) -> np.ndarray:
    """The step indices a run keeps: 0, k, 2k, …, n_steps (the last block may be partial), or only
    0 and n_steps when ``save_every`` is None."""
    if save_every is None:
        return np.array([0, n_steps]) if n_steps else np.array([0])
    k = int(save_every)
    if k < 1:
        raise ValueError(f"save_every must be ≥ 1, got {save_every}")
    return np.minimum(np.arange(-(-n_steps // k) + 1) * k, n_steps)

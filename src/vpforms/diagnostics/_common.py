"""Helpers shared by the trajectory diagnostics: point checks, chunks and padding."""

from __future__ import annotations

from typing import Any

import numpy as np


def _points(x0: Any) -> tuple[np.ndarray, bool]:
    x0 = np.asarray(x0, dtype=np.float64)
    if x0.ndim not in (1, 2) or x0.shape[-1] != 3:
        raise ValueError(f"x0 must have shape (3,) or (N, 3); got {x0.shape}")
    return x0.reshape(-1, 3), x0.ndim == 1


def _chunks(N: int, C: int):
    for lo in range(0, N, C):
        yield lo, min(lo + C, N)


def _pad(block: np.ndarray, C: int) -> np.ndarray:
    if block.shape[0] == C:
        return block
    return np.concatenate([block, np.repeat(block[-1:], C - block.shape[0], axis=0)])

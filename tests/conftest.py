"""Shared test helpers."""

from pathlib import Path

import vpforms  # noqa: F401  (float64 on)

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"

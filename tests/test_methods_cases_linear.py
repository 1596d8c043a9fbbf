"""All 36 cases on a random traceless linear field (issue #5): see test_methods_cases_abc.py."""

import pytest

from .test_methods_cases_abc import check_all_cases


@pytest.mark.slow  # ≈ 1–1.5 min: one compilation per case (runs in CI)
def test_all_36_cases_linear():
    check_all_cases("linear")

"""All 36 cases on the Lotka–Volterra field (issue #5): see test_methods_cases_abc.py."""

from .test_methods_cases_abc import check_all_cases


def test_all_36_cases_lotka_volterra():
    check_all_cases("lotka_volterra")

"""The expected calibration error: zero when the confidence is the accuracy, the gap otherwise."""

from __future__ import annotations

import pytest

from ipromp_pin.evaluation.cells import expected_calibration_error


def test_calibrated_confidences_have_no_calibration_error():
    # in the bin of 0.75: 3 of 4 right; in the bin of 1.0: all right
    rows = [(0.75, True), (0.75, True), (0.75, True), (0.75, False), (1.0, True), (1.0, True)]
    assert expected_calibration_error(rows) == pytest.approx(0.0)


def test_overconfidence_is_the_gap_weighted_by_the_bins():
    # posterior 1.000 and half of them wrong (the unknown task taken for a known one)
    rows = [(1.0, True), (1.0, False), (0.55, True), (0.55, True)]
    # bin of 1.0: |0.5 - 1.0| over 2 rows; bin of 0.55: |1.0 - 0.55| over 2 rows
    assert expected_calibration_error(rows) == pytest.approx((2 * 0.5 + 2 * 0.45) / 4)
    assert expected_calibration_error([]) is None
    assert expected_calibration_error([(float("nan"), True), (0.9, True)]) == pytest.approx(0.1)

"""``ipromp-pin calibrate`` (ipromp_pin.app.calibrate): reads the datasets, reports the fit,
stores it."""

from __future__ import annotations

import shutil
import sys

import numpy as np
import pytest

from ipromp_pin.app import main
from ipromp_pin.robot import ROBOTS_DIR, load_robot_settings


@pytest.mark.realdata
def test_calibrate_command_reports_and_writes_the_fit(chen2017_dir, tmp_path, capsys, monkeypatch):
    settings = tmp_path / "copy.toml"
    shutil.copy(ROBOTS_DIR / "baxter_left.toml", settings)
    before = load_robot_settings(settings)
    args = ["calibrate", str(chen2017_dir), "--robot", str(settings), "--write"]
    monkeypatch.setattr(sys, "argv", ["ipromp-pin", *args])  # the command line the file records
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "FK calibration (baxter_left, fit=mount)" in out and f"written to {settings}" in out
    assert "chen2017_handover: median residual" in out
    after = load_robot_settings(settings)
    info = after.calibration_info
    assert info["calibrated_by"].startswith("ipromp-pin ") and info["fit"] == "mount"
    assert info["residual_median_mm_after"] < 2.0 < info["residual_median_mm_before"]
    # the fitted mount offset is the stored one (within a few mm), the tool offset stays zero
    assert np.linalg.norm(after.mount_offset_m - before.mount_offset_m) < 0.003
    np.testing.assert_array_equal(after.tool_offset_m, np.zeros(3))
    assert after.arm_joints == before.arm_joints  # the rest of the file is kept


@pytest.mark.realdata
def test_calibrate_never_changes_the_shipped_settings(chen2017_dir, tmp_path, capsys, monkeypatch):
    shipped = ROBOTS_DIR / "baxter_left.toml"
    before = shipped.read_bytes()
    monkeypatch.chdir(tmp_path)
    assert main(["calibrate", str(chen2017_dir), "--robot", "baxter_left", "--write"]) == 0
    assert shipped.read_bytes() == before
    copy = tmp_path / "baxter_left_calibrated.toml"
    out = capsys.readouterr().out
    assert f"written to {copy}; use it with --robot {copy}" in out
    info = load_robot_settings(copy).calibration_info
    assert info["fit"] == "mount" and info["residual_median_mm_after"] < 2.0
    other = tmp_path / "mine.toml"  # an explicit file
    assert main(["calibrate", str(chen2017_dir), "--write", str(other)]) == 0
    assert load_robot_settings(other).calibration_info["fit"] == "mount" and shipped.read_bytes() == before

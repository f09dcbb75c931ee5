"""Tests of the matplotlib figures: files written, valid PNGs of the expected size, shape errors."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ipromp_pin.exceptions import DataError
from ipromp_pin.outputs import plots

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) in pixels from the IHDR chunk of a PNG file."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def assert_png(path: Path, size: tuple[int, int]) -> None:
    assert path.is_file() and path.stat().st_size > 5000
    assert png_size(path) == size
    from PIL import Image

    with Image.open(path) as image:
        image.verify()
    with Image.open(path) as image:
        pixels = np.asarray(image.convert("L"), dtype=float)
    assert pixels.std() > 5.0  # something was drawn


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(0)


def test_plot_distributions(tmp_path, rng):
    phase = np.linspace(0, 1, 50)
    mean = np.stack([np.sin(2 * np.pi * phase * (d + 1)) for d in range(5)], -1)
    demos = mean[None] + rng.normal(0, 0.1, (8, 50, 5))
    path = plots.plot_distributions(
        phase,
        mean,
        demos.std(0),
        tmp_path / "sub" / "dist.png",
        demos=demos,
        dim_names=[f"q{d}" for d in range(5)],
        title="task A",
        figsize=(9, 6),
        dpi=80,
    )
    assert path == tmp_path / "sub" / "dist.png"
    assert_png(path, (720, 480))


def test_plot_distributions_shape_errors(tmp_path):
    phase = np.linspace(0, 1, 10)
    with pytest.raises(DataError, match="field 'mean'"):
        plots.plot_distributions(phase, np.zeros((9, 2)), np.zeros((9, 2)), tmp_path / "x.png")
    with pytest.raises(DataError, match="field 'std'"):
        plots.plot_distributions(phase, np.zeros((10, 2)), np.zeros((10, 3)), tmp_path / "x.png")
    with pytest.raises(DataError, match="field 'demos'"):
        plots.plot_distributions(
            phase, np.zeros((10, 2)), np.ones((10, 2)), tmp_path / "x.png", demos=[np.zeros((10, 3))]
        )
    with pytest.raises(DataError, match="field 'dim_names'"):
        plots.plot_distributions(
            phase, np.zeros((10, 2)), np.ones((10, 2)), tmp_path / "x.png", dim_names=["a"]
        )
    assert not (tmp_path / "x.png").exists()


def test_plot_prediction(tmp_path, rng):
    t = np.linspace(0, 3, 60)
    q = np.stack([np.cos(t + j) for j in range(7)], -1)
    path = plots.plot_prediction(
        t,
        q,
        np.full_like(q, 0.05),
        tmp_path / "pred.png",
        truth_t_s=np.linspace(0, 3.2, 80),
        q_truth=rng.normal(0, 0.3, (80, 7)),
        observed_until_s=1.0,
        joint_names=[f"left_{j}" for j in range(7)],
    )
    assert_png(path, (1200, 800))


def test_plot_prediction_shape_errors(tmp_path):
    t = np.linspace(0, 3, 10)
    q = np.zeros((10, 7))
    with pytest.raises(DataError, match="field 'q_mean'"):
        plots.plot_prediction(t[:-1], q, q, tmp_path / "x.png")
    with pytest.raises(DataError, match="field 'q_truth'"):
        plots.plot_prediction(t, q, q, tmp_path / "x.png", truth_t_s=t, q_truth=np.zeros((10, 6)))
    with pytest.raises(DataError, match="field 'q_truth'"):
        plots.plot_prediction(t, q, q, tmp_path / "x.png", truth_t_s=t)


def test_plot_phase_posterior(tmp_path):
    alphas = np.linspace(0.6, 1.6, 21)
    log_post = {
        task: -((alphas - c) ** 2) / 0.02 for task, c in (("rod", 1.0), ("tape", 1.2), ("wrench", 0.8))
    }
    log_post["tape"][0] = -np.inf  # an impossible candidate is skipped, not an error
    path = plots.plot_phase_posterior(alphas, log_post, tmp_path / "phase.png", true_alpha=1.0, dpi=50)
    assert_png(path, (400, 250))
    table = np.stack(list(log_post.values()))
    path = plots.plot_phase_posterior(alphas, table, tmp_path / "phase2.png", tasks=list(log_post))
    assert_png(path, (800, 500))
    with pytest.raises(DataError, match="field 'tasks'"):
        plots.plot_phase_posterior(alphas, table, tmp_path / "x.png", tasks=["rod"])
    with pytest.raises(DataError, match="3 values for 21"):
        plots.plot_phase_posterior(alphas, {"rod": np.zeros(3)}, tmp_path / "x.png")
    with pytest.raises(DataError, match="no candidates"):
        plots.plot_phase_posterior({"rod": alphas}, {"tape": np.zeros(21)}, tmp_path / "x.png")


def test_plot_accuracy(tmp_path):
    records = [
        {
            "n_train": n,
            "obs_ratio": r,
            "observe": obs,
            "task": task,
            "accuracy": min(1.0, r + (0.2 if "emg" in obs else 0.0)),
        }
        for n in (5, 10)
        for r in (0.2, 0.4, 0.6)
        for obs in ("orientation", "orientation,emg")
        for task in ("rod", "tape")
    ]
    path = plots.plot_accuracy(records, tmp_path / "acc.png")
    assert_png(path, (1200, 450))
    # Records as the evaluation writes them: observe as a list of groups, several protocols.
    cells = [
        dict(r, observe=r["observe"].split(","), protocol=p) for r in records for p in ("paper", "splits")
    ]
    assert_png(plots.plot_accuracy(cells, tmp_path / "acc2.png", dpi=50), (600, 225))
    with pytest.raises(DataError, match="lacks"):
        plots.plot_accuracy([{"n_train": 5, "obs_ratio": 0.2}], tmp_path / "x.png")
    with pytest.raises(DataError, match="outside"):
        plots.plot_accuracy(
            [{"n_train": 5, "obs_ratio": 0.2, "observe": "emg", "accuracy": 1.5}], tmp_path / "x.png"
        )
    with pytest.raises(DataError, match="no records"):
        plots.plot_accuracy([], tmp_path / "x.png")


def captured(monkeypatch) -> list:
    """Figures that the plot functions save (kept open for inspection)."""
    figures = []

    def keep(fig, path, dpi):
        figures.append(fig)
        return Path(path)

    monkeypatch.setattr(plots, "_save", keep)
    return figures


def test_phase_posterior_draws_one_scale_for_every_task(tmp_path, monkeypatch):
    figures = captured(monkeypatch)
    alphas = np.linspace(0.6, 1.6, 21)
    shape = -((alphas - 1.0) ** 2) / 0.02
    joint = {"rod": shape - 36.0, "tape": shape - 21.0, "wrench": shape - 250.0}
    plots.plot_phase_posterior(alphas, joint, tmp_path / "phase.png")
    ax = figures[0].axes[0]
    assert ax.get_ylabel() == "log p(task, alpha | observation)"
    curves = {
        line.get_label().split()[0]: line.get_ydata() for line in ax.lines if "(peak" in line.get_label()
    }
    assert max(curves["rod"]) == pytest.approx(-36.0) and max(curves["tape"]) == pytest.approx(-21.0)
    # a task far below the best is drawn at the bottom of the shown range, its peak named
    assert min(curves["wrench"]) == pytest.approx(-21.0 - 60.0)
    assert any(line.get_label() == "wrench (peak -250.0)" for line in ax.lines)


def test_distributions_band_and_units(tmp_path, monkeypatch, rng):
    figures = captured(monkeypatch)
    phase = np.linspace(0, 1, 30)
    median = np.full((30, 2), 100.0)
    lower, upper = median * np.exp(-0.8), median * np.exp(0.8)  # asymmetric, as a log-scaled channel's
    plots.plot_distributions(
        phase,
        median,
        np.full((30, 2), 0.4),
        tmp_path / "d.png",
        band=(lower, upper),
        units=["Myo EMG units", "rad"],
    )
    axes = figures[0].axes
    assert [ax.get_ylabel() for ax in axes[:2]] == ["Myo EMG units", "rad"]
    band = axes[0].collections[0].get_paths()[0].vertices[:, 1]
    assert band.min() == pytest.approx(lower[0, 0]) and band.max() == pytest.approx(upper[0, 0])
    with pytest.raises(DataError, match="field 'band'"):
        plots.plot_distributions(phase, median, median * 0, tmp_path / "x.png", band=(upper, lower))
    with pytest.raises(DataError, match="field 'units'"):
        plots.plot_distributions(phase, median, median * 0, tmp_path / "x.png", units=["rad"])


def test_plots_leave_the_importers_backend_alone(tmp_path):
    """Importing and drawing neither switches matplotlib's backend nor loads pyplot."""
    png = tmp_path / "a.png"
    script = f"""
import sys
import matplotlib
matplotlib.use("svg")
from ipromp_pin.outputs import plots
assert matplotlib.get_backend() == "svg", matplotlib.get_backend()
record = dict(n_train=3, obs_ratio=0.5, observe="emg", accuracy=0.5)
plots.plot_accuracy([record], {str(png)!r})
assert matplotlib.get_backend() == "svg", matplotlib.get_backend()
assert "matplotlib.pyplot" not in sys.modules
print("ok")
"""
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"
    assert_png(png, (1200, 450))

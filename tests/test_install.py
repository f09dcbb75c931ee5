"""A built wheel carries the shipped settings: the main job runs from an installed copy, from any folder.

The wheel is built from a copy of the sources (so the build leaves nothing in the work tree) with
``pip wheel``, whose isolated build environment gets setuptools and wheel from pip's configured
index, as ``pip install -e .`` does. The installed copy's first run compiles the numba kernels
again (~20-30 s).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ("robots", "pipelines")


def _run(args: list[str], cwd: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    proc = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, f"{' '.join(args)} exited {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    return proc


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> dict[str, Path]:
    """A wheel of the project and its non-editable install into a plain folder (``--target``)."""
    tmp = tmp_path_factory.mktemp("install")
    src = tmp / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(PROJECT_ROOT / name, src / name)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in ("ipromp_pin", *SHIPPED):
        shutil.copytree(PROJECT_ROOT / name, src / name, ignore=ignore)
    dist = tmp / "dist"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(src)], cwd=tmp)
    (wheel,) = dist.glob("ipromp_pin-*.whl")
    site = tmp / "site"
    # --no-compile: the .pyc files found after the run below were written by that run's imports
    _run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "--no-compile", "-q", "--target", str(site)]
        + [str(wheel)],
        cwd=tmp,
    )
    return {"wheel": wheel, "site": site, "tmp": tmp}


def _env(site: Path) -> dict[str, str]:
    """Environment whose only PYTHONPATH entry is the installed copy (not the source tree)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONDONTWRITEBYTECODE")}
    env["PYTHONPATH"] = str(site)
    env["MPLBACKEND"] = "Agg"
    return env


def test_wheel_holds_every_module_and_the_shipped_settings(installed):
    names = set(zipfile.ZipFile(installed["wheel"]).namelist())
    modules = {p.relative_to(PROJECT_ROOT).as_posix() for p in (PROJECT_ROOT / "ipromp_pin").rglob("*.py")}
    assert modules and not modules - names, f"missing from the wheel: {sorted(modules - names)}"
    for folder in SHIPPED:
        files = {f"ipromp_pin/{folder}/{p.name}" for p in (PROJECT_ROOT / folder).glob("*.toml")}
        assert files and not files - names, f"missing from the wheel: {sorted(files - names)}"
    assert "ipromp_pin/robots/README.md" in names and "ipromp_pin/py.typed" in names
    schemas = {
        p.relative_to(PROJECT_ROOT).as_posix() for p in (PROJECT_ROOT / "ipromp_pin").rglob("*.schema.json")
    }
    assert schemas and not schemas - names, f"missing from the wheel: {sorted(schemas - names)}"


def test_installed_copy_runs_the_main_job_from_another_folder(installed):
    site, work = installed["site"], installed["tmp"] / "elsewhere"
    work.mkdir()
    env = _env(site)
    probe = (
        "import json, ipromp_pin, ipromp_pin.app.config as p\n"
        "from ipromp_pin.robot import ROBOTS_DIR, load_robot\n"
        "robot = load_robot('baxter_left')\n"
        "print(json.dumps({'package': ipromp_pin.__file__, 'robots': str(ROBOTS_DIR),\n"
        "    'settings': str(robot.settings.path), 'n_joints': robot.n_joints,\n"
        "    'pipeline': str(p.resolve_pipeline_path('baxter_handover'))}))\n"
    )
    found = json.loads(_run([sys.executable, "-c", probe], cwd=work, env=env).stdout)
    assert Path(found["package"]).is_relative_to(site), found
    assert Path(found["robots"]) == site / "ipromp_pin" / "robots"
    assert Path(found["settings"]) == site / "ipromp_pin" / "robots" / "baxter_left.toml"
    assert found["n_joints"] == 7
    assert Path(found["pipeline"]) == site / "ipromp_pin" / "pipelines" / "baxter_handover.toml"

    out = work / "out"
    run = _run(
        [sys.executable, "-m", "ipromp_pin.app", "run", "baxter_handover", "--out", "out", "--no-preview"],
        cwd=work,
        env={**env, "IPROMP_PIN_KERNELS": "numpy"},  # what a first run uses: nothing to compile
    )
    assert "Recognised task" in run.stdout
    assert (out / "trajectory.csv").stat().st_size > 0
    report = json.loads((out / "report.json").read_text())
    assert report["format"] == "ipromp_pin.report" and report["trajectory"]
    # the run imported the installed modules (installed without .pyc files, so these are the run's)
    assert list((site / "ipromp_pin" / "app" / "__pycache__").glob("run.*.pyc"))
    assert list((site / "ipromp_pin" / "app" / "__pycache__").glob("config.*.pyc"))
    assert list((site / "ipromp_pin" / "planning" / "__pycache__").glob("one_shot.*.pyc"))
    assert list((site / "ipromp_pin" / "app" / "__pycache__").glob("session.*.pyc"))
    assert list((site / "ipromp_pin" / "safety" / "__pycache__").glob("suite.*.pyc"))
    # and no inference or human-separation kernel was compiled (the self-collision certifier's small
    # kernel, about 1.5 s to compile, is the one the run's self_collision check compiles)
    compiled = {p.name.split(".")[0] for p in site.rglob("*.nbi")}
    assert compiled <= {"clearance_kernels"}, compiled

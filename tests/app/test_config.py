"""Pipeline configuration (``ipromp_pin.app.config``): one source for the schema, the defaults,
the field names of errors and the defaults the command line's help shows; ``outputs.dir`` relative to
the pipeline file."""

from __future__ import annotations

import argparse
import dataclasses
import re
from pathlib import Path

import pytest
from helpers_cli import PIPELINE

from ipromp_pin.app import config, main
from ipromp_pin.app.arguments import closed_loop_settings
from ipromp_pin.app.config import (
    PipelineConfig,
    PipelineSections,
    default_of,
    load_pipeline,
    schema,
)
from ipromp_pin.exceptions import PipelineError
from ipromp_pin.planning.closed_loop import ClosedLoopSettings
from ipromp_pin.shipped import DEFAULT_ROBOT

# A value other than the default for every key of the schema, and what the loaded field holds
# (``base`` is the pipeline file's folder: relative paths are relative to it).
OTHER_VALUES = {
    "data.dataset": ("recordings", lambda base: base / "recordings"),
    "data.format": ("bag", lambda base: "bag"),
    "data.rate_hz": (60, lambda base: 60.0),
    "data.frames": (["/left_hand_1"], lambda base: ["/left_hand_1"]),
    "data.synthetic_seed": (7, lambda base: 7),
    "model.observe": (["emg"], lambda base: ["emg"]),
    "model.load": ("m.npz", lambda base: base / "m.npz"),
    "model.save": ("/tmp/saved.npz", lambda base: Path("/tmp/saved.npz")),
    "model.cache": (False, lambda base: False),
    "observation.task": ("tape", lambda base: "tape"),
    "observation.demo": (3, lambda base: 3),
    "observation.ratio": (0.5, lambda base: 0.5),
    "observation.until_s": (0.6, lambda base: 0.6),
    "robot.settings": ("robots/arm.toml", lambda base: str(base / "robots" / "arm.toml")),
    "robot.objects": ("my_objects.toml", lambda base: base / "my_objects.toml"),
    "robot.retreat": (False, lambda base: False),
    "timing.control_rate_hz": (250.5, lambda base: 250.5),
    "outputs.dir": ("results", lambda base: base / "results"),
    "outputs.preview_html": (False, lambda base: False),
    "outputs.plots": (True, lambda base: True),
    "outputs.ros": (1, lambda base: 1),
    "outputs.rosbag": (False, lambda base: False),
    "outputs.ros1_bag": (True, lambda base: True),
}


def _toml(value) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, list):
        return "[" + ", ".join(f'"{v}"' for v in value) + "]"
    return repr(value)


def test_every_schema_key_round_trips(tmp_path):
    keys = [f"{section}.{key}" for section, table in schema().items() for key in table]
    assert sorted(keys) == sorted(OTHER_VALUES)  # a new field needs a row here
    flat = {field: name for name, field in PipelineConfig.flat_names().items()}  # field -> flat name
    assert sorted(flat) == sorted(keys)  # every field has its flat attribute, and only fields do
    for key in keys:
        section, name = key.split(".")
        written, expected = OTHER_VALUES[key]
        assert written != default_of(key) and expected(tmp_path) != default_of(key), key
        pipe = tmp_path / "p.toml"
        pipe.write_text(f"[{section}]\n{name} = {_toml(written)}\n")
        cfg = load_pipeline(pipe)
        assert getattr(getattr(cfg.sections, section), name) == expected(tmp_path), key
        assert getattr(cfg, flat[key]) == expected(tmp_path), key
        # every other field keeps its default
        defaults = PipelineSections()
        setattr(getattr(defaults, section), name, expected(tmp_path))
        assert cfg.sections == defaults, key


def test_the_shipped_pipeline_states_the_defaults():
    shipped = load_pipeline("baxter_handover").sections
    # the defaults, but for the demo it observes: a wrench demo (the first task's is refused as unknown)
    assert shipped.observation.task == "wrench"
    assert shipped == dataclasses.replace(
        PipelineSections(), observation=dataclasses.replace(PipelineSections().observation, task="wrench")
    )
    assert PipelineConfig().robot == DEFAULT_ROBOT == default_of("robot.settings")
    assert PipelineConfig(ratio=0.4).sections.observation.ratio == 0.4


def test_unknown_key_is_a_one_line_error_naming_section_and_key(tmp_path, capsys):
    pipe = tmp_path / "p.toml"
    pipe.write_text("[timing]\ncontrol_rate = 100.0\n")
    with pytest.raises(PipelineError) as err:
        load_pipeline(pipe)
    problem = "unknown key; did you mean 'control_rate_hz'? (known: control_rate_hz)"
    assert str(err.value) == f"{pipe}: field 'timing.control_rate': {problem}"
    assert main(["run", str(pipe), "--out", str(tmp_path / "out")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == [f"ipromp-pin run: error: {pipe}: field 'timing.control_rate': {problem}"]
    pipe.write_text("[timng]\ncontrol_rate_hz = 100.0\n")
    with pytest.raises(
        PipelineError, match=r"field 'timng': unknown section; did you mean 'timing'\? \(known: data"
    ):
        load_pipeline(pipe)
    pipe.write_text("[observation]\nratoi = 0.2\n")
    with pytest.raises(
        PipelineError, match=r"field 'observation.ratoi': unknown key; did you mean 'ratio'\?"
    ):
        load_pipeline(pipe)
    pipe.write_text('[timing]\ncontrol_rate_hz = "fast"\n')
    with pytest.raises(PipelineError, match=r"field 'timing.control_rate_hz': wrong type str$"):
        load_pipeline(pipe)
    with pytest.raises(PipelineError, match="unknown pipeline override 'speed'"):
        load_pipeline("baxter_handover", speed=2.0)


def test_validation_names_the_field_of_the_file(tmp_path):
    pipe = tmp_path / "p.toml"
    for text, field in (
        ("[observation]\nratio = 0.0\n", "observation.ratio"),
        ("[data]\nrate_hz = 0.5\n", "data.rate_hz"),
        ("[timing]\ncontrol_rate_hz = 5000\n", "timing.control_rate_hz"),
        ("[outputs]\nros = 3\n", "outputs.ros"),
        ("[model]\nobserve = []\n", "model.observe"),
        ("[data]\nsynthetic_seed = -1\n", "data.synthetic_seed"),
        ("[observation]\nuntil_s = 0\n", "observation.until_s"),
        ("[observation]\nuntil_s = 1e4\n", "observation.until_s"),
        ("[observation]\nratio = 0.2\nuntil_s = 0.6\n", "observation.until_s"),
    ):
        pipe.write_text(text)
        with pytest.raises(PipelineError, match=rf"^{re.escape(str(pipe))}: field '{field}': "):
            load_pipeline(pipe)


def test_the_window_is_a_ratio_or_seconds_and_the_command_line_replaces_the_files(tmp_path):
    pipe = tmp_path / "p.toml"
    pipe.write_text("[observation]\nuntil_s = 0.6\n")
    cfg = load_pipeline(pipe)
    assert (cfg.window.until_s, cfg.window.ratio) == (0.6, None)
    cfg = load_pipeline(pipe, ratio=0.3)  # --ratio: the file's seconds give way
    assert (cfg.until_s, cfg.window.ratio) == (None, 0.3)
    assert load_pipeline("baxter_handover", until_s=1.5).window.until_s == 1.5
    with pytest.raises(PipelineError, match="not both"):
        load_pipeline("baxter_handover", ratio=0.3, until_s=1.5)


def _help(capsys, *command: str) -> str:
    with pytest.raises(SystemExit):
        main([*command, "--help"])
    return " ".join(capsys.readouterr().out.split())


def _shown(text: str, option: str) -> str:
    """The "(default X" the help of ``option`` shows."""
    match = re.search(rf"{option} [A-Z_]+ [a-z].*?\(default ([^,);]+)", text)  # the help, not the usage
    assert match, option
    return match.group(1)


def test_help_defaults_are_those_of_the_settings(capsys, monkeypatch):
    run = _help(capsys, "run")
    assert float(_shown(run, "--ratio")) == default_of("observation.ratio")
    assert int(_shown(run, "--demo")) == default_of("observation.demo")
    assert float(_shown(run, "--rate")) == default_of("timing.control_rate_hz")
    replay = _help(capsys, "replay")
    settings = ClosedLoopSettings()
    assert (
        "--start-after S the robot starts S seconds after the human's motion starts (default: 20% of"
        in replay
    )
    for option, name in (
        ("--replan-rate", "replan_rate_hz"),
        ("--blend", "blend_s"),
        ("--freeze-phase", "freeze_phase"),
        ("--condition-noise", "condition_noise"),
    ):
        assert float(_shown(replay, option)) == getattr(settings, name), option
    assert _shown(_help(capsys, "train"), "--robot") == DEFAULT_ROBOT
    # derived, not copied: another default shows in the help
    monkeypatch.setattr(config, "default_of", lambda name: {"observation.ratio": 0.35}.get(name, 7))
    assert _shown(_help(capsys, "run"), "--ratio") == "0.35"


def _closed_loop_args(**given) -> argparse.Namespace:
    options = {"replan_rate": None, "blend": None, "freeze_phase": None, "condition_noise": None}
    options["start_confidence"] = None
    return argparse.Namespace(**{**options, **given})


def test_closed_loop_settings_take_only_the_options_given():
    assert closed_loop_settings(_closed_loop_args()) == ClosedLoopSettings()
    settings = closed_loop_settings(
        _closed_loop_args(blend=0.3, condition_noise="model"), control_rate_hz=50.0, start_ratio=None
    )
    assert settings == ClosedLoopSettings(blend_s=0.3, condition_noise=None, control_rate_hz=50.0)
    assert closed_loop_settings(_closed_loop_args(condition_noise="0.5")).condition_noise == 0.5
    with pytest.raises(PipelineError, match="^command line: field 'condition_noise': must be a positive"):
        closed_loop_settings(_closed_loop_args(condition_noise="lots"))
    with pytest.raises(PipelineError, match="^command line: field 'replan_rate_hz': 200 Hz is faster"):
        closed_loop_settings(_closed_loop_args(replan_rate=200.0))


def test_outputs_dir_is_relative_to_the_pipeline_file(tmp_path, tiny, monkeypatch):
    ds, model = tiny
    folder = tmp_path / "pipelines"
    folder.mkdir()
    pipe = folder / "p.toml"
    pipe.write_text(f'[data]\ndataset = "{ds}"\n[model]\nload = "{model}"\n[outputs]\ndir = "results"\n'
                    "preview_html = false\n")  # fmt: skip
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert load_pipeline(pipe).out_dir == folder / "results"
    assert main(["run", str(pipe)]) == 0
    assert (folder / "results" / "trajectory.csv").exists() and not (elsewhere / "results").exists()
    # --out on the command line is relative to the current folder
    assert main(["run", str(pipe), "--out", "here"]) == 0
    assert (elsewhere / "here" / "trajectory.csv").exists()
    # the shipped definition (empty outputs.dir) writes ./out, never into the package
    assert load_pipeline(PIPELINE).out_dir == Path("out")
    assert load_pipeline("baxter_handover").out_dir == Path("out")

"""The run's preview shows the report's figures: the separation and torque panels state the verdicts of
``human_clearance``, ``contact_speed`` and ``joint_torques`` (approach and retreat), their per-sample
tracks are the checks' own measures (the curve's minimum over a judged motion is the report's, at the
report's time, with the same link and body part), the body drawn is the human the checks judged, and
every check's time in the check list is the report's ``t_s``.

The demo has a tracked skeleton that leans toward the robot after the observation: the human the
checks judge (as observed, then held) is not the recorded one, the case where the preview used to
show another distance than the report."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from helpers_cli import PIPELINE
from helpers_human import leaning_skeleton

from ipromp_pin.app.config import load_pipeline
from ipromp_pin.app.session import prepare_session
from ipromp_pin.human import HumanMotion
from ipromp_pin.human.separation import HAND_REGION
from ipromp_pin.outputs.preview_content import preview_content
from ipromp_pin.outputs.report import report_dict
from ipromp_pin.plans import plan
from ipromp_pin.preview.scene import overlay_state

TIME = re.compile(r"t=(\d+\.\d+) s")


@pytest.fixture(scope="module")
def planned():
    cfg = load_pipeline(PIPELINE, task="rod", demo=3)
    s = prepare_session(cfg, log=lambda _m: None, warn=lambda _m: None)
    demo = leaning_skeleton(s.robot.settings.human, s.demo)
    observation = demo.head(cfg.ratio, groups=cfg.observe)
    p = plan(s.model, observation, s.robot, objects=s.context.objects, suite=s.suite)
    assert p.retreat is not None and p.context.human is not None and not p.context.human.assumed
    content = preview_content(
        p.approach, s.robot, demo, human=p.context.human, objects=p.context.objects, retreat=p.retreat
    )
    report = json.loads(json.dumps(report_dict(p.approach, demo, [], p.retreat), allow_nan=False))
    return p, demo, content, report


def segments(p) -> list[tuple[str, object, np.ndarray]]:
    """(row prefix, verdicts, (t0, t1) [s]) of the approach and the retreat."""
    a, r = p.approach, p.retreat
    return [
        ("", a.checks, a.trajectory.t_s[[0, -1]]),
        ("retreat ", r.checks, r.trajectory.t_s[[0, -1]]),
    ]


def within(t_s: np.ndarray, span: np.ndarray) -> np.ndarray:
    return (t_s >= span[0] - 1e-9) & (t_s <= span[1] + 1e-9)


def test_the_separation_curve_is_the_clearance_the_report_gives(planned):
    p, _, content, _ = planned
    sep = content.separation
    assert sep is not None
    for prefix, checks, span in segments(p):
        m = checks["human_clearance"].measures
        idx = np.flatnonzero(within(sep.t_s, span))
        assert idx.size >= 2, prefix
        i = idx[int(np.argmin(sep.distance_m[idx]))]
        # the curve's minimum over the judged motion: the report's, at its time, the same pair
        assert sep.distance_m[i] == pytest.approx(m.min_separation_m, rel=1e-9, abs=1e-12), prefix
        assert sep.t_s[i] == pytest.approx(m.t_s, abs=1e-9), prefix
        assert (sep.link[i], sep.body_part[i]) == (m.link, m.body_part), prefix
        assert m.body_part not in [n for n, r in zip(p.context.human.part_names, p.context.human.regions,
                                                      strict=True) if r == HAND_REGION]  # fmt: skip
        # the contact-speed ratio per sample: its largest is contact_speed's
        c = checks["contact_speed"].measures
        assert sep.speed_ratio[idx].max() == pytest.approx(c.max_speed_ratio, rel=1e-9, abs=1e-12), prefix
        assert sep.judged[idx].all(), prefix
    # samples after the motions (the robot at rest while the human moves) are marked not judged
    end = p.retreat.trajectory.t_s[-1]
    assert not sep.judged[sep.t_s > end + 1e-9].any() and sep.judged[sep.t_s <= end + 1e-9].all()


def test_the_separation_panel_states_the_verdicts(planned):
    p, _, content, _ = planned
    sep = content.separation
    stated = {f.check: f for f in sep.reported}
    for prefix, checks, _ in segments(p):
        for name, value in (("human_clearance", "min_separation_m"), ("contact_speed", "max_speed_ratio")):
            v = checks[name]
            f = stated[prefix + name]
            assert f.value == getattr(v.measures, value) and f.t_s == v.measures.t_s
            assert f.text == v.reason
    panel = overlay_state(content)["separation"]
    assert [r["text"] for r in panel["reported"]] == [f.text for f in sep.reported]
    assert "hand excluded" in panel["measure"]
    assert "min" not in panel  # no minimum of its own beside the report's


def test_the_body_drawn_is_the_human_the_checks_judged(planned):
    p, demo, content, _ = planned
    human = p.context.human
    body = content.body
    assert body is not None and not body.assumed
    np.testing.assert_array_equal(body.t_s, human.t_s)
    a, b, _ = human.capsules(human.t_s)
    np.testing.assert_allclose(body.a_m, a)
    np.testing.assert_allclose(body.radius_m, np.broadcast_to(human.radius_m, body.radius_m.shape))
    # after the observation the body is held where it was last seen, not the recorded (leaning) one
    recorded = HumanMotion.from_demo(demo, p.robot.settings.human)
    late = np.linspace(human.horizon_s + 0.5, float(demo.t[-1]), 20)
    held = body.at(late)[0]
    np.testing.assert_allclose(held, human.capsules(late)[0])
    assert np.abs(held - recorded.capsules(late)[0]).max() > 0.05
    assert "observed until" in content.separation.source


def test_the_torque_panel_states_the_reports_peak(planned):
    p, _, content, _ = planned
    tq = content.torques
    assert tq is not None
    stated = {f.check: f for f in tq.reported}
    n_approach = p.approach.checks["joint_torques"].measures.n_evaluated
    parts = {"": np.arange(n_approach), "retreat ": np.arange(n_approach, tq.t_s.size)}
    for prefix, checks, span in segments(p):
        v = checks["joint_torques"]
        m = v.measures
        idx = parts[prefix]  # the approach's evaluated samples, then the retreat's
        assert within(tq.t_s[idx], span).all(), prefix
        j = list(tq.joint_names).index(m.joint)
        peak = tq.ratio[idx].max()
        assert peak == pytest.approx(m.peak_torque_ratio, rel=1e-12), prefix
        i = idx[int(np.argmax(tq.ratio[idx, j]))]
        assert tq.ratio[i, j] == pytest.approx(peak, rel=1e-12) and tq.t_s[i] == pytest.approx(m.t_s)
        np.testing.assert_allclose(tq.ratio[idx].max(axis=0), m.ratios, atol=6e-5)
        assert idx.size == m.n_evaluated  # the samples the check evaluated
        f = stated[prefix + "joint_torques"]
        assert (f.value, f.t_s, f.text) == (m.peak_torque_ratio, m.t_s, v.reason)
    panel = overlay_state(content)["torques"]
    assert [r["text"] for r in panel["reported"]] == [f.text for f in tq.reported]


def test_every_checks_time_in_the_list_is_the_reports(planned):
    _, _, content, report = planned
    rows = {c.name: c.detail for c in content.feasibility}
    sections = [("", report["feasibility"]["checks"]), ("retreat ", report["retreat"]["checks"])]
    n = 0
    for prefix, checks in sections:
        for name, entry in checks.items():
            shown = TIME.findall(rows[prefix + name])
            if entry.get("t_s") is None:
                continue
            assert shown and set(shown) == {f"{entry['t_s']:.2f}"}, (prefix + name, rows[prefix + name])
            n += 1
    assert n >= 12  # every check with a time, the approach's and the retreat's

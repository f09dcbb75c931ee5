// The replay's time-scrubbing panel. One clock: every time is on the human's motion (t = 0 at its
// start); the page's time runs from 0 to data.duration_s (the animation's last frame) and is shown
// clamped to it.
(function () {
  const data = JSON.parse(document.getElementById("ipromp-timeline-data").textContent);
  const events = data.events;
  const panel = iprompEl("div", {id: "ipromp-timeline"});
  const head = iprompEl("div", {id: "ipromp-timeline-time"}, "");
  const slider = iprompEl("input", {id: "ipromp-timeline-slider", type: "range", min: "0",
    max: String(data.duration_s), step: "0.01", value: "0"});
  const status = iprompEl("div", {id: "ipromp-timeline-status"}, "");
  const summary = iprompEl("div", {id: "ipromp-timeline-summary"});
  for (const line of data.summary) summary.appendChild(iprompEl("div", {}, line));
  panel.appendChild(head);
  panel.appendChild(slider);
  panel.appendChild(status);
  panel.appendChild(summary);
  document.body.appendChild(panel);

  function eventAt(t) {
    let i = -1;
    while (i + 1 < events.length && events[i + 1].t_s <= t + 1e-9) i++;
    return i;
  }
  function fmt(x, unit) { return (x === null || x === undefined) ? "-" : x.toFixed(2) + " " + unit; }
  function clamp(t) { return Math.min(Math.max(t, 0), data.duration_s); }
  function observed(until) {
    const motion = data.motion_s;
    if (!motion) return {until_s: until};
    return {until_s: until, human_duration_s: motion, source: "recorded", fraction: Math.min(1, until / motion)};
  }
  function show(t) {
    t = clamp(t);
    const i = eventAt(t);
    const state = Object.assign({}, data.overlay);
    const motion = data.motion_s || data.duration_s;
    if (i >= 0) {
      const e = events[i];
      state.task = e.task;
      if (e.posterior.length) state.posterior = e.posterior;
      state.observed = observed(e.observed_until_s);
      status.replaceChildren(
        iprompEl("div", {}, "Re-plan " + (i + 1) + " of " + events.length + " at " + e.t_s.toFixed(2) +
          " s: predicted hand-over at " + fmt(e.predicted_handover_s, "s") + ", plan at rest at " +
          fmt(e.arrival_s, "s")),
        iprompEl("div", {"class": e.committed ? "committed" : "refused"},
          e.committed ? (e.action ? "committed: " + e.action : "committed")
            : "refused (the robot keeps the last safe plan): " + e.reason));
    } else {
      state.task = "";
      state.no_task_text = "(none yet: before the first re-plan at " + fmt(events.length ? events[0].t_s : null, "s") + ")";
      state.posterior = state.tasks.map(() => 1.0 / Math.max(state.tasks.length, 1));
      state.observed = observed(Math.min(t, motion));
      status.replaceChildren(iprompEl("div", {}, "Before the first re-plan: the robot waits at rest."));
    }
    iprompRender(state);
    head.textContent = "Time " + t.toFixed(2) + " s of " + data.duration_s.toFixed(2) +
      " s on the human's clock (t = 0 at the start of the human's motion)";
    window.iprompTimelineShown = t;
  }
  let last = null, below = null;
  function loop() {
    // the HTML panel (top left) ends above this one (bottom left) and scrolls (page.css)
    const h = panel.offsetHeight + 8;
    if (h !== below) { document.documentElement.style.setProperty("--ipromp-below", h + "px"); below = h; }
    const t = (viewer.animator && typeof viewer.animator.time === "number") ? viewer.animator.time : 0;
    if (t !== last) {
      last = t;
      slider.value = String(t);
      show(t);
    }
    requestAnimationFrame(loop);
  }
  slider.addEventListener("input", function () {
    const t = clamp(parseFloat(slider.value));
    const animator = viewer.animator;
    if (animator) {
      // the clip's actions must be active for a seek to pose the scene (they are once played)
      for (const action of animator.actions) { action.enabled = true; action.paused = false; action.play(); }
      animator.pause();
      animator.seek(t);
      animator.display_progress(t);
    }
    last = t;
    show(t);
  });
  show(0);
  window.iprompTimeline = events.length;
  requestAnimationFrame(loop);
})();

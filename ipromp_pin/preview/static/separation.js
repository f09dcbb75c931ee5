// The robot-body separation: the report's figures as the checks' verdicts give them, the checks'
// per-sample measure at the current time (its pair and state; samples no check judged are marked so),
// and the states along the time axis (a strip under the replay's time slider, or in its own panel),
// the reported figures' times marked on it. Reads the panel state's "separation"
// (window.iprompOverlayState, set by overlay.js); times are on the animation's time base, the human's.
(function () {
  const NAMES = {free: "free", within_sp: "within S_p", speed_limited: "speed-limited", violation: "violation"};
  let panel = null, strip = null, text = null, key = null, drawn = null, lastT = null, lastSpan = null;
  function build() {
    panel = iprompEl("div", {id: "ipromp-separation"});
    text = iprompEl("div", {id: "ipromp-separation-now"}, "");
    strip = iprompEl("canvas", {id: "ipromp-separation-strip", width: "496", height: "12"});
    key = iprompEl("div", {id: "ipromp-separation-key"});
    panel.appendChild(text);
    panel.appendChild(strip);
    panel.appendChild(key);
    document.body.appendChild(panel);
  }
  function place() {
    const slider = document.getElementById("ipromp-timeline-slider");
    if (slider && panel.parentNode !== slider.parentNode) {
      slider.parentNode.insertBefore(panel, slider.nextSibling);
      panel.classList.add("in-timeline");
    }
    return slider;
  }
  function now() {
    if (typeof window.iprompTimelineShown === "number") return window.iprompTimelineShown;
    const a = viewer.animator;
    return (a && typeof a.time === "number") ? a.time : 0;
  }
  function indexAt(sep, t) {
    let i = 0;
    while (i + 1 < sep.t_s.length && sep.t_s[i + 1] <= t + 1e-9) i++;
    return i;
  }
  function draw(sep, span, t) {
    const ctx = strip.getContext("2d");
    const w = strip.width, h = strip.height, n = sep.t_s.length;
    ctx.clearRect(0, 0, w, h);
    ctx.fillStyle = "#e0e0e0";
    ctx.fillRect(0, 0, w, h);
    for (let i = 0; i < n; i++) {
      const t1 = i + 1 < n ? sep.t_s[i + 1] : sep.t_s[i] + (n > 1 ? sep.t_s[i] - sep.t_s[i - 1] : 0.01);
      const x0 = Math.floor(w * sep.t_s[i] / span), x1 = Math.ceil(w * t1 / span);
      ctx.fillStyle = sep.colors[sep.state[i]];
      ctx.fillRect(x0, 0, Math.max(1, x1 - x0), h);
    }
    ctx.fillStyle = "#555";  // the reported figures' times
    for (const r of sep.reported) ctx.fillRect(Math.min(w - 1, Math.max(0, Math.round(w * r.t_s / span))), 0, 1, h);
    ctx.fillStyle = "#000";
    ctx.fillRect(Math.min(w - 2, Math.max(0, Math.round(w * t / span) - 1)), 0, 2, h);
  }
  function describe(sep, i) {
    const pair = sep.link[i] || sep.body_part[i] ? " (" + (sep.link[i] || "?") + " to " + (sep.body_part[i] || "?") + ")" : "";
    let s = "Separation " + sep.distance_m[i].toFixed(3) + " m" + pair + ": " + NAMES[sep.state[i]];
    if (sep.judged && !sep.judged[i]) s += " (the robot at rest after its motion: not judged by the checks)";
    const sp = sep.protective_distance_m ? sep.protective_distance_m[i] : null;
    const ratio = sep.speed_ratio ? sep.speed_ratio[i] : null;
    if (sp !== null) s += ", S_p " + sp.toFixed(3) + " m";
    if (ratio !== null && sep.state[i] !== "free") s += ", approach " + ratio.toFixed(2) + " of the contact-speed limit";
    return s;
  }
  function keyText(sep) {
    key.replaceChildren();
    if (sep.reported.length) {
      for (const r of sep.reported) key.appendChild(iprompEl("div", {"class": "ipromp-reported", "data-check": r.check}, r.check + ": " + r.text));
    } else {
      key.appendChild(iprompEl("div", {"class": "ipromp-reported"}, "No check in the report judged this separation."));
    }
    key.appendChild(iprompEl("div", {}, "Per sample: " + sep.measure + (sep.source ? "; the " + sep.source : "")));
    const row = iprompEl("div");
    for (const s of Object.keys(NAMES)) {
      const sw = iprompEl("span", {"class": "ipromp-swatch"});
      sw.style.background = sep.colors[s];
      row.appendChild(sw);
      row.appendChild(document.createTextNode(NAMES[s] + " " + (sep.counts[s] || 0) + "  "));
    }
    key.appendChild(row);
  }
  function loop() {
    const state = window.iprompOverlayState;
    const sep = state && state.separation;
    if (!sep) {
      if (panel) panel.style.display = "none";
    } else {
      if (!panel) build();
      panel.style.display = "";
      const slider = place();
      const last = sep.t_s[sep.t_s.length - 1];
      const span = slider ? parseFloat(slider.max) : Math.max(last, state.end_s || state.robot_duration_s || 0);
      const t = now();
      if (sep !== drawn || t !== lastT || span !== lastSpan) {
        const i = indexAt(sep, t);
        draw(sep, Math.max(span, 1e-6), t);
        text.textContent = "t = " + t.toFixed(2) + " s: " + describe(sep, i);
        if (sep !== drawn) keyText(sep);
        window.iprompSeparationShown = {t_s: t, index: i, state: sep.state[i]};
        drawn = sep; lastT = t; lastSpan = span;
      }
    }
    requestAnimationFrame(loop);
  }
  requestAnimationFrame(loop);
})();

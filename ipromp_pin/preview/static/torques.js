// The joints' torque usage at the current time, at the samples the joint-torque check evaluated: one
// bar per joint (|tau| / effort limit, coloured green below "warn", orange up to the allowed usage,
// red beyond), each joint's peak over them marked by a tick, what the gripper holds, and the report's
// figures as the check's verdicts give them. Reads the panel state's "torques"
// (window.iprompOverlayState, set by overlay.js); times are on the animation's time base, the human's.
(function () {
  const W = 300, ROW = 14, LABEL = 70, BAR = 170;
  let panel = null, canvas = null, text = null, key = null, drawn = null, lastT = null;
  function build(tq) {
    panel = iprompEl("div", {id: "ipromp-torques"});
    text = iprompEl("div", {id: "ipromp-torques-now"}, "");
    canvas = iprompEl("canvas", {id: "ipromp-torques-bars", width: String(W), height: String(ROW * tq.joints.length + 4)});
    key = iprompEl("div", {id: "ipromp-torques-key"});
    panel.appendChild(text);
    panel.appendChild(canvas);
    panel.appendChild(key);
    document.body.appendChild(panel);
  }
  function now() {
    if (typeof window.iprompTimelineShown === "number") return window.iprompTimelineShown;
    const a = viewer.animator;
    return (a && typeof a.time === "number") ? a.time : 0;
  }
  function indexAt(tq, t) {
    let i = 0;
    while (i + 1 < tq.t_s.length && tq.t_s[i + 1] <= t + 1e-9) i++;
    return i;
  }
  function color(tq, r) {
    if (r > tq.allowed + 1e-9) return tq.colors.over;
    return r < tq.warn ? tq.colors.ok : tq.colors.high;
  }
  function draw(tq, i) {
    canvas.height = ROW * tq.joints.length + 4;
    const ctx = canvas.getContext("2d");
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    ctx.font = "11px sans-serif";
    ctx.textBaseline = "middle";
    const scale = BAR / Math.max(1.0, Math.max.apply(null, tq.peak));
    tq.joints.forEach((name, j) => {
      const y = 2 + j * ROW, r = tq.ratio[i][j];
      ctx.fillStyle = "#222";
      ctx.fillText(name, 0, y + ROW / 2);
      ctx.fillStyle = "#e6e6e6";
      ctx.fillRect(LABEL, y + 2, BAR, ROW - 4);
      ctx.fillStyle = color(tq, r);
      ctx.fillRect(LABEL, y + 2, Math.max(1, r * scale), ROW - 4);
      ctx.fillStyle = "#000";  // the joint's peak over the motion
      ctx.fillRect(LABEL + Math.round(tq.peak[j] * scale) - 1, y, 2, ROW);
      ctx.fillStyle = "#222";
      ctx.fillText(Math.round(100 * r) + " %", LABEL + BAR + 6, y + ROW / 2);
    });
    ctx.fillStyle = tq.colors.over;  // the allowed usage (1 - effort margin)
    const xa = LABEL + Math.round(tq.allowed * scale);
    ctx.fillRect(xa, 0, 1, canvas.height);
  }
  function keyText(tq) {
    key.replaceChildren();
    for (const r of tq.reported) key.appendChild(iprompEl("div", {"class": "ipromp-reported", "data-check": r.check}, r.check + ": " + r.text));
    key.appendChild(iprompEl("div", {}, "Bars: " + (tq.samples || "every control sample") +
      "; tick: each joint's peak over them; allowed " + Math.round(100 * tq.allowed) + " % (red line)"));
    const row = iprompEl("div");
    for (const [name, label] of [["ok", "< " + Math.round(100 * tq.warn) + " %"], ["high", "< " + Math.round(100 * tq.allowed) + " %"], ["over", "beyond"]]) {
      const sw = iprompEl("span", {"class": "ipromp-swatch"});
      sw.style.background = tq.colors[name];
      row.appendChild(sw);
      row.appendChild(document.createTextNode(label + "  "));
    }
    key.appendChild(row);
  }
  function loop() {
    const state = window.iprompOverlayState;
    const tq = state && state.torques;
    if (!tq) {
      if (panel) panel.style.display = "none";
    } else {
      if (!panel) build(tq);
      panel.style.display = "";
      const sep = document.getElementById("ipromp-separation");  // stacked above it, bottom right
      const below = sep && sep.style.display !== "none" && !sep.classList.contains("in-timeline") ? sep.offsetHeight + 8 : 0;
      panel.style.bottom = (8 + below) + "px";
      const t = now();
      if (tq !== drawn || t !== lastT) {
        const i = indexAt(tq, t);
        draw(tq, i);
        const holding = tq.payload && tq.held[i] ? "holding " + tq.payload : "empty";
        text.textContent = "Joint torques at the sample t = " + tq.t_s[i].toFixed(2) + " s (of the effort limits); gripper " + holding;
        if (tq !== drawn) keyText(tq);
        window.iprompTorquesShown = {t_s: t, index: i, holding: holding, ratio: tq.ratio[i]};
        drawn = tq; lastT = t;
      }
    }
    requestAnimationFrame(loop);
  }
  requestAnimationFrame(loop);
})();

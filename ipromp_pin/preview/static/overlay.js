function iprompEl(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const k in (attrs || {})) e.setAttribute(k, attrs[k]);
  if (text !== undefined) e.textContent = text;
  return e;
}
function iprompRender(s) {
  window.iprompOverlayState = s;
  const root = document.getElementById("ipromp-overlay");
  root.replaceChildren();
  // the panel scrolls within the window (page.css); "Hide details" folds it to the title and task
  const fold = iprompEl("button", {id: "ipromp-collapse", type: "button"}, window.iprompCollapsed ? "Show details" : "Hide details");
  fold.addEventListener("click", function () { window.iprompCollapsed = !window.iprompCollapsed; iprompRender(window.iprompOverlayState); });
  root.classList.toggle("collapsed", !!window.iprompCollapsed);
  root.appendChild(fold);
  root.appendChild(iprompEl("h1", {id: "ipromp-title"}, s.title));
  const task = iprompEl("div", {id: "ipromp-task"}, "Recognised task: ");
  task.appendChild(iprompEl("b", {id: "ipromp-task-name"}, s.task || s.no_task_text || "(none)"));
  root.appendChild(task);
  if (s.tasks.length) {
    const table = iprompEl("table", {id: "ipromp-posterior"});
    s.tasks.forEach((name, i) => {
      const p = s.posterior.length ? s.posterior[i] : NaN;
      const row = iprompEl("tr", {"data-task": name, "class": name === s.task ? "winner" : ""});
      row.appendChild(iprompEl("td", {}, name));
      const bar = iprompEl("td");
      const fill = iprompEl("span", {"class": "ipromp-bar"});
      fill.style.width = (isNaN(p) ? 0 : Math.round(120 * p)) + "px";
      bar.appendChild(fill);
      row.appendChild(bar);
      row.appendChild(iprompEl("td", {"class": "ipromp-p"}, isNaN(p) ? "?" : p.toFixed(3)));
      table.appendChild(row);
    });
    root.appendChild(table);
  }
  if (s.observed) {
    // The observed fraction of the HUMAN's motion (its recorded or predicted duration).
    const o = s.observed;
    let text = "Observed: " + o.until_s.toFixed(2) + " s of the human's motion";
    if (o.human_duration_s) {
      text = "Observed: " + o.until_s.toFixed(2) + " s of the human's " + o.human_duration_s.toFixed(2) +
        " s motion (" + Math.round(100 * o.fraction) + " %" + (o.source ? ", " + o.source + " duration" : "") + ")";
    }
    root.appendChild(iprompEl("div", {id: "ipromp-observed"}, text));
  }
  root.appendChild(iprompEl("div", {id: "ipromp-timebase"}, s.timebase ||
    ("Times are on the human's motion (t = 0 at its start); the robot comes to rest at " +
     s.robot_duration_s.toFixed(2) + " s")));
  for (const note of (s.notes || [])) root.appendChild(iprompEl("div", {"class": "ipromp-note"}, note));
  if (s.feasibility.length) {
    const list = iprompEl("ul", {id: "ipromp-feasibility"});
    for (const c of s.feasibility) {
      const status = c.status || (c.passed ? "pass" : "fail");
      const tag = status === "skip" ? " (skipped)" : (!c.required && status !== "info" ? " (advisory)" : "");
      list.appendChild(iprompEl("li", {"class": status, "data-check": c.name},
        c.name + tag + (c.detail ? ": " + c.detail : "")));
    }
    root.appendChild(list);
  }
  if (s.collision_links.length) {
    root.appendChild(iprompEl("div", {}, "In collision (red): " + s.collision_links.join(", ")));
  }
  if (s.near_limit_joints.length) {
    root.appendChild(iprompEl("div", {}, "Near a joint limit (orange): " + s.near_limit_joints.join(", ")));
  }
  const legend = iprompEl("div", {id: "ipromp-legend"});
  for (const item of s.legend) {
    const row = iprompEl("div");
    const sw = iprompEl("span", {"class": "ipromp-swatch"});
    sw.style.background = item.color;
    row.appendChild(sw);
    row.appendChild(document.createTextNode(item.label));
    legend.appendChild(row);
  }
  root.appendChild(legend);
  root.appendChild(iprompEl("div", {id: "ipromp-hint"}, "Play / pause / scrub: Open Controls > Animations"));
}
(function () {
  const original = viewer.handle_command.bind(viewer);
  viewer.handle_command = function (cmd) {
    if (cmd && cmd.type === "ipromp_overlay") { iprompRender(cmd.state); viewer.set_dirty(); return; }
    if (cmd && cmd.type === "ipromp_synced") { window.iprompSynced = cmd.count; return; }
    original(cmd);
  };
})();

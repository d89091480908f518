// A job's page: live progress with a time estimate, cancel, delete, and the interactive 3-D view.
"use strict";
(() => {
  const root = document.getElementById("job");
  const jobId = root.dataset.jobId;
  const finished = ["succeeded", "failed", "cancelled"];

  function showProgress(job) {
    const statusNode = document.getElementById("job-status");
    statusNode.textContent = job.status;
    statusNode.className = `status ${job.status}`;
    const bar = document.getElementById("progress-bar");
    if (!bar) return;
    const fraction = job.progress.fraction;
    bar.style.width = `${(100 * fraction).toFixed(1)}%`;
    const p = job.progress;
    const training = p.training_decisions && p.decisions !== null && p.decisions < p.training_decisions;
    const done = training
      ? `${p.decisions.toLocaleString("en")} of ${p.training_decisions.toLocaleString("en")} decisions trained`
      : `episode ${p.episode} of ${p.episodes}`;
    document.getElementById("progress-text").textContent = `${Math.round(100 * fraction)}% · ${done}`;
    if (p.training_curve) drawCurve(p.training_curve, p.training_decisions);
    const eta = document.getElementById("eta");
    if (job.started_at && fraction > 0 && fraction < 1) {
      const elapsed = (Date.now() - Date.parse(job.started_at)) / 1000;
      eta.textContent = ` · about ${nanonav.duration(elapsed * (1 - fraction) / fraction)} left`;
    } else {
      eta.textContent = job.status === "queued" ? " · waiting for a worker" : "";
    }
  }

  // ------------------------------------------------------------ the training curve
  // A network's training: the share of its training episodes that reached a cell against the
  // decisions trained, redrawn each time the progress brings a longer curve.
  const SVG = "http://www.w3.org/2000/svg";
  const curveNode = document.getElementById("training-curve");
  let drawnRows = -1;

  function svg(name, attributes, text) {
    const node = document.createElementNS(SVG, name);
    for (const [key, value] of Object.entries(attributes)) node.setAttribute(key, String(value));
    if (text !== undefined) node.textContent = text;
    return node;
  }

  function drawCurve(rows, total) {
    if (!curveNode || rows.length === drawnRows) return;
    drawnRows = rows.length;
    curveNode.replaceChildren();
    const [left, right, top, bottom] = [62, 545, 12, 180];
    const x = (decisions) => left + (right - left) * decisions / Math.max(total, 1);
    const y = (share) => bottom - (bottom - top) * share;
    curveNode.appendChild(svg("rect", { x: left, y: top, width: right - left, height: bottom - top,
                                        class: "plot-area" }));
    for (const share of [0, 0.25, 0.5, 0.75, 1]) {
      curveNode.appendChild(svg("line", { x1: left, x2: right, y1: y(share), y2: y(share), class: "grid" }));
      curveNode.appendChild(svg("text", { x: left - 6, y: y(share) + 4, "text-anchor": "end" }, share.toFixed(2)));
    }
    for (const [part, anchor] of [[0, "start"], [0.5, "middle"], [1, "end"]]) {
      curveNode.appendChild(svg("text", { x: x(part * total), y: bottom + 16, "text-anchor": anchor },
                                Math.round(part * total).toLocaleString("en")));
    }
    curveNode.appendChild(svg("text", { x: (left + right) / 2, y: bottom + 34, "text-anchor": "middle" },
                              "decisions trained"));
    curveNode.appendChild(svg("text", { x: 14, y: (top + bottom) / 2, "text-anchor": "middle",
                                        transform: `rotate(-90 14 ${(top + bottom) / 2})` },
                              "success rate (training)"));
    const points = rows.filter((row) => row.success_rate !== null)
      .map((row) => [x(row.decisions), y(row.success_rate), row]);
    if (points.length > 1) {
      curveNode.appendChild(svg("polyline", { points: points.map(([px, py]) => `${px},${py}`).join(" "),
                                              class: "line" }));
    }
    for (const [px, py, row] of points) {
      const dot = svg("circle", { cx: px, cy: py, r: 3.5, class: "point" });
      dot.appendChild(svg("title", {}, `${row.decisions.toLocaleString("en")} decisions: ` +
                          `${(100 * row.success_rate).toFixed(1)}% of ${row.episodes} episodes reached a cell`));
      curveNode.appendChild(dot);
    }
    curveNode.dataset.rows = String(rows.length);
    curveNode.dataset.points = String(points.length);
  }

  if (curveNode) drawCurve(JSON.parse(curveNode.dataset.curve), Number(curveNode.dataset.decisions));

  // A page being left (a link followed) is not reloaded: the reload would cancel the navigation
  // under way and take the user back here.
  let leaving = false;
  window.addEventListener("beforeunload", () => { leaving = true; });
  window.addEventListener("pageshow", () => { leaving = false; });

  function whenFinished(job) {
    showProgress(job);
    // the results are rendered by the server: show them
    window.setTimeout(() => { if (!leaving) window.location.reload(); }, 300);
  }

  if (!finished.includes(root.dataset.status)) {
    let source = nanonav.follow(`/jobs/${jobId}/events`, showProgress, whenFinished);
    const poll = async () => {
      const answer = await nanonav.send("GET", `/jobs/${jobId}`);
      if (!answer.ok) return;
      if (finished.includes(answer.document.status)) whenFinished(answer.document);
      else { showProgress(answer.document); window.setTimeout(poll, 1000); }
    };
    if (source === null) poll();
    else source.onerror = () => { if (source.readyState === EventSource.CLOSED) { source = null; poll(); } };
    const cancel = document.getElementById("cancel");
    cancel.addEventListener("click", async () => {
      if (!window.confirm(`Cancel job #${jobId}? It stops without an evaluation; the training episodes it finished are kept.`)) return;
      cancel.disabled = true;
      const answer = await nanonav.send("POST", `/jobs/${jobId}/cancel`);
      if (answer.ok) showProgress(answer.document);
      else cancel.disabled = false;
    });
  }

  const remove = document.getElementById("delete");
  if (remove) nanonav.deleteButton(remove, `/jobs/${jobId}`, `job #${jobId}`, "/ui/jobs");

  // ------------------------------------------------------------ the 3-D view
  const open = document.getElementById("open-3d");
  if (!open) return;
  const MAX_ROBOTS = 30;
  const MAX_CELLS = 10;

  function sphere(cx, cy, cz, r, base, into) {
    const rings = 6;
    const segments = 10;
    for (let i = 0; i <= rings; i++) {
      const theta = (Math.PI * i) / rings;
      for (let j = 0; j < segments; j++) {
        const phi = (2 * Math.PI * j) / segments;
        into.x.push(cx + r * Math.sin(theta) * Math.cos(phi));
        into.y.push(cy + r * Math.sin(theta) * Math.sin(phi));
        into.z.push(cz + r * Math.cos(theta));
      }
    }
    for (let i = 0; i < rings; i++) {
      for (let j = 0; j < segments; j++) {
        const a = base + i * segments + j;
        const b = base + i * segments + ((j + 1) % segments);
        const c = a + segments;
        const d = b + segments;
        into.i.push(a, b); into.j.push(b, d); into.k.push(c, c);
      }
    }
    return base + (rings + 1) * segments;
  }

  function obstaclesMesh(centres, radius) {
    const mesh = { x: [], y: [], z: [], i: [], j: [], k: [] };
    let base = 0;
    for (const [x, y, z] of centres) base = sphere(x, y, z, radius, base, mesh);
    return { type: "mesh3d", ...mesh, color: "#555", opacity: 0.35, name: "obstacles",
             hoverinfo: "skip", showlegend: true };
  }

  function lines(points, color, name, showlegend) {
    return { type: "scatter3d", mode: "lines", x: points.map((p) => p[0]), y: points.map((p) => p[1]),
             z: points.map((p) => p[2]), line: { color, width: 3 }, name, showlegend, hoverinfo: "skip" };
  }

  async function draw() {
    open.disabled = true;
    open.textContent = "Loading the trajectory…";
    const answer = await nanonav.send("GET", `/jobs/${jobId}/trajectory?stride=${open.dataset.stride}`);
    if (!answer.ok) {
      open.textContent = answer.document && answer.document.detail
        ? `Cannot draw: ${answer.document.detail}` : "Cannot draw the trajectory";
      return;
    }
    const t = answer.document;
    const rows = t.step.length;
    const robots = Math.min(t.robots[0].length, MAX_ROBOTS);
    const cells = Math.min(t.cells[0].length, MAX_CELLS);
    const traces = [];
    for (let r = 0; r < robots; r++) {
      const own = t.step.map((step, row) => [step, row]).filter(([step]) => step <= t.robot_steps[r]);
      traces.push(lines(own.map(([, row]) => t.robots[row][r]), "#1f77b4", "robot paths", r === 0));
    }
    for (let c = 0; c < cells; c++) {
      traces.push(lines(t.cells.map((row) => row[c]), "#d62728", "cell paths", c === 0));
    }
    const moving = t.obstacles.length > 1;
    const obstacleTrace = traces.length;
    if (t.obstacles[0].length) traces.push(obstaclesMesh(t.obstacles[0], t.obstacle_radius));
    const now = traces.length;
    const at = (row) => ({
      robots: t.robots[row].slice(0, robots),
      cells: t.cells[row].slice(0, cells),
    });
    const first = at(0);
    traces.push({ type: "scatter3d", mode: "markers", x: first.robots.map((p) => p[0]),
                  y: first.robots.map((p) => p[1]), z: first.robots.map((p) => p[2]),
                  marker: { color: "#1f77b4", size: 4 }, name: "robots now" });
    traces.push({ type: "scatter3d", mode: "markers", x: first.cells.map((p) => p[0]),
                  y: first.cells.map((p) => p[1]), z: first.cells.map((p) => p[2]),
                  marker: { color: "#d62728", size: 6, symbol: "diamond" }, name: "cells now" });
    const view = document.getElementById("view3d");
    view.hidden = false;
    const layout = { margin: { l: 0, r: 0, t: 0, b: 0 }, legend: { orientation: "h" },
                     scene: { aspectmode: "cube", xaxis: { title: "x" }, yaxis: { title: "y" },
                              zaxis: { title: "z" } } };
    await Plotly.newPlot(view, traces, layout, { responsive: true, displaylogo: false });
    const slider = document.getElementById("step");
    const output = document.getElementById("step-value");
    slider.max = String(rows - 1);
    document.getElementById("step-label").hidden = false;
    open.hidden = true;
    slider.addEventListener("input", () => {
      const row = Number(slider.value);
      const p = at(row);
      output.textContent = String(t.step[row]);
      Plotly.restyle(view, {
        x: [p.robots.map((q) => q[0]), p.cells.map((q) => q[0])],
        y: [p.robots.map((q) => q[1]), p.cells.map((q) => q[1])],
        z: [p.robots.map((q) => q[2]), p.cells.map((q) => q[2])],
      }, [now, now + 1]);
      if (moving && t.obstacles[0].length) {
        const mesh = obstaclesMesh(t.obstacles[row], t.obstacle_radius);
        Plotly.restyle(view, { x: [mesh.x], y: [mesh.y], z: [mesh.z] }, [obstacleTrace]);
      }
    });
  }

  // The plotting library is large: it is fetched only when the view is opened.
  open.addEventListener("click", () => {
    if (window.Plotly) { draw(); return; }
    open.disabled = true;
    open.textContent = "Loading the 3-D view…";
    const script = document.createElement("script");
    script.src = "/static/vendor/plotly.min.js";
    script.onload = draw;
    script.onerror = () => { open.textContent = "Could not load the 3-D view"; };
    document.head.appendChild(script);
  });
})();

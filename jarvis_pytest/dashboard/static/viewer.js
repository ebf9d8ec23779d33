// jarvis-pytest dashboard: a single-page viewer over the dashboard's JSON API (see server.py for the endpoints).
// Views by URL hash: #/ runs · #/run/<run> live run · #/run/<run>/task/<task>[/<step>] trajectory ·
// #/compare/<a>/<b> two runs task by task. Vanilla JS, no build step, nothing loaded from outside this server.
"use strict";

const POLL_MS = 1500;
const app = document.getElementById("app");
const conn = document.getElementById("conn");
let generation = 0; // bumped on every navigation: stale polls and fetches see it and stop

// ---------------------------------------------------------------------------------------------------------------
// DOM and formatting helpers

function h(tag, attrs, ...kids) {
  const el = document.createElement(tag);
  setAttrs(el, attrs);
  for (const kid of kids.flat(Infinity)) {
    if (kid !== null && kid !== undefined && kid !== false) el.append(kid instanceof Node ? kid : String(kid));
  }
  return el;
}

function svg(tag, attrs, ...kids) {
  const el = document.createElementNS("http://www.w3.org/2000/svg", tag);
  setAttrs(el, attrs);
  for (const kid of kids.flat(Infinity)) {
    if (kid !== null && kid !== undefined && kid !== false) el.append(kid instanceof Node ? kid : String(kid));
  }
  return el;
}

function setAttrs(el, attrs) {
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === null || v === undefined || v === false) continue;
    if (k.startsWith("on")) el.addEventListener(k.slice(2), v);
    else el.setAttribute(k, v === true ? "" : String(v));
  }
}

const enc = encodeURIComponent;
const pct = (x) => (x === null || x === undefined ? "–" : `${(100 * x).toFixed(1)}%`);
const fmtTime = (iso) => (iso ? iso.replace("T", " ").replace(/\+00:00$/, " UTC") : "–");
const fmtSecs = (s) => (s === null || s === undefined ? "–" : s < 90 ? `${s.toFixed(1)} s` : `${(s / 60).toFixed(1)} min`);
const badge = (text) => h("span", { class: `badge ${String(text).replace(/\s+/g, "-")}` }, text);
const runHref = (run) => `#/run/${enc(run)}`;
const taskHref = (run, task, step) => `#/run/${enc(run)}/task/${enc(task)}` + (step === undefined ? "" : `/${step}`);
const fileUrl = (run, ...parts) => `/files/${[run, ...parts].map(enc).join("/")}`;
const shotUrl = (run, task, name) => fileUrl(run, "tasks", task, name);
const HUMAN = "human"; // the agent of runs a person made in the player (jarvis play)
// A run's time per task and per step (the rollup's timing): "12.3 s a task · 1.2 s a step".
const timeText = (t) => (t ? `${fmtSecs(t.task_median)} a task · ${fmtSecs(t.decision_per_step)} a step` : "–");
const whoseTime = (agent) => (agent === HUMAN ? "a person's time" : "time");

function setConn(ok, message) {
  conn.textContent = ok ? `updated ${new Date().toLocaleTimeString()}` : `connection problem: ${message} (retrying)`;
  conn.classList.toggle("down", !ok);
}

async function api(path) {
  const res = await fetch(path, { cache: "no-store" });
  let data;
  try {
    data = await res.json();
  } catch (e) {
    throw new Error(`${res.status} ${res.statusText}`);
  }
  if (!res.ok) throw new Error(data.error || `${res.status} ${res.statusText}`);
  return data;
}

// A region of the page re-rendered only when its data changed, so images do not flicker while polling.
function region(attrs) {
  const el = h("div", attrs);
  let last = null;
  el.show = (data, render) => {
    const key = JSON.stringify(data);
    if (key === last) return;
    last = key;
    el.replaceChildren(...[render(data)].flat().filter((x) => x !== null && x !== undefined));
  };
  return el;
}

// Fetch `path` now and then every `every` ms while `again(data)` is true and the page has not navigated away.
async function poll(path, update, again, every = POLL_MS) {
  const mine = generation;
  let first = true;
  for (;;) {
    let data = null;
    try {
      data = await api(path);
      if (mine !== generation) return;
      update(data);
      setConn(true);
    } catch (e) {
      if (mine !== generation) return;
      if (first) throw e;
      setConn(false, e.message);
    }
    first = false;
    if (data && !again(data)) return;
    await new Promise((r) => setTimeout(r, every));
    if (mine !== generation) return;
  }
}

function problemsBox(problems) {
  if (!problems || !problems.length) return null;
  return h("details", { class: "problems", "data-testid": "problems", open: problems.length <= 5 },
    h("summary", {}, `${problems.length} problem${problems.length > 1 ? "s" : ""} reading the results`),
    h("ul", {}, problems.map((p) => h("li", { "data-testid": "problem" }, h("code", {}, p.file), ": ", p.message))));
}

function progressBar(c) {
  const total = Math.max(c.total || 0, 1);
  const part = (n, cls) => (n ? h("span", { class: cls, style: `width:${(100 * n) / total}%` }) : null);
  return h("div", { class: "progress", title: `${c.done}/${c.total} done` },
    part(c.passed, "passed"), part(c.failed, "failed"), part(c.error, "error"), part(c.running, "running"),
    part((c.interrupted || 0) + (c.unknown || 0), "odd"));
}

function countsLine(c) {
  return `${c.done}/${c.total} done · ${c.running} running` + (c.pending ? ` · ${c.pending} pending` : "");
}

// ---------------------------------------------------------------------------------------------------------------
// Plot: success rate against the number of subtasks (the paper's figure), one line per run.

function curvePlot(series) {
  const pts = series.flatMap((s) => s.points);
  if (!pts.length) return h("p", { class: "muted" }, "No finished tasks to plot yet.");
  const W = 520, H = 280, L = 48, R = 16, T = 16, B = 40;
  const xs = pts.map((p) => p.subtasks);
  const x0 = Math.min(...xs), x1 = Math.max(...xs);
  const X = (n) => L + (x1 === x0 ? (W - L - R) / 2 : ((n - x0) / (x1 - x0)) * (W - L - R));
  const Y = (r) => T + (1 - r) * (H - T - B);
  const g = svg("svg", { class: "plot", width: W, height: H, viewBox: `0 0 ${W} ${H}`, "data-testid": "curve",
    role: "img", "aria-label": "success rate against the number of subtasks" });
  for (const r of [0, 0.25, 0.5, 0.75, 1]) {
    g.append(svg("line", { class: "grid", x1: L, x2: W - R, y1: Y(r), y2: Y(r) }),
      svg("text", { x: L - 6, y: Y(r) + 4, "text-anchor": "end" }, `${r * 100}%`));
  }
  for (let n = x0; n <= x1; n++) {
    g.append(svg("text", { x: X(n), y: H - B + 16, "text-anchor": "middle" }, n));
  }
  g.append(svg("line", { class: "axis", x1: L, x2: W - R, y1: Y(0), y2: Y(0) }),
    svg("line", { class: "axis", x1: L, x2: L, y1: T, y2: Y(0) }),
    svg("text", { x: (L + W - R) / 2, y: H - 6, "text-anchor": "middle" }, "number of subtasks"));
  series.forEach((s, i) => {
    const sorted = [...s.points].sort((a, b) => a.subtasks - b.subtasks);
    g.append(svg("polyline", { class: `series-${i}`, points: sorted.map((p) => `${X(p.subtasks)},${Y(p.rate)}`).join(" ") }));
    for (const p of sorted) {
      g.append(svg("circle", { class: `series-${i}`, cx: X(p.subtasks), cy: Y(p.rate), r: 4, "data-subtasks": p.subtasks, "data-rate": p.rate },
        svg("title", {}, `${s.label}: ${p.subtasks} subtask(s): ${p.passed}/${p.tasks} = ${pct(p.rate)}`)));
    }
    if (series.length > 1) {
      g.append(svg("circle", { class: `series-${i}`, cx: W - R - 200, cy: T + 8 + 16 * i, r: 4 }),
        svg("text", { x: W - R - 190, y: T + 12 + 16 * i }, s.label));
    }
  });
  return g;
}

function summaryTables(summary) {
  if (!summary) return null;
  if (!summary.available) return h("p", { class: "muted" }, summary.message || "No summary.");
  return (summary.tables || []).map((t) => h("div", { class: "card", "data-testid": "summary-table" },
    h("h3", {}, t.title),
    h("table", {},
      h("thead", {}, h("tr", {}, t.columns.map((c, i) => h("th", { class: i ? "num" : null }, c)))),
      h("tbody", {}, t.rows.map((row) => h("tr", {}, row.map((v, i) => h("td", { class: i ? "num" : null }, v))))))));
}

// ---------------------------------------------------------------------------------------------------------------
// Runs

async function runsView() {
  const list = region({ "data-testid": "runs" });
  const compare = region({});
  app.replaceChildren(h("h1", {}, "Runs"), list, h("h2", {}, "Compare two runs"), compare);
  await poll("/api/runs", (data) => {
    list.show(data, renderRuns);
    compare.show(data.runs.map((r) => r.id), renderComparePicker);
  }, () => true, 2 * POLL_MS);
}

function renderRuns(data) {
  if (!data.runs.length) return h("p", { class: "muted" }, `No runs in ${data.root} yet.`);
  return h("table", {},
    h("thead", {}, h("tr", {}, ["Run", "Agent", "Started", "State", "Progress", "", "TSR", "SSR", "Time", "Problems"].map((c) => h("th", {}, c)))),
    h("tbody", {}, data.runs.map((r) => {
      const c = r.counts || { done: 0, total: 0, running: 0, pending: 0 };
      return h("tr", { class: "row-link", "data-run": r.id },
        h("td", {}, h("a", { href: runHref(r.id) }, r.id)),
        h("td", { title: JSON.stringify(r.agent || {}, null, 1) }, r.agent_name || "–"),
        h("td", {}, fmtTime(r.started)),
        h("td", {}, badge(r.state)),
        h("td", {}, progressBar(c)),
        h("td", { class: "muted" }, countsLine(c)),
        h("td", { class: "num" }, pct(r.stats && r.stats.tsr)),
        h("td", { class: "num" }, pct(r.stats && r.stats.ssr)),
        h("td", { class: "num", "data-testid": "run-time", title: whoseTime(r.agent_name) }, timeText(r.stats && r.stats.timing)),
        h("td", { class: "num" }, (r.problems || []).length || ""));
    })));
}

function renderComparePicker(ids) {
  if (ids.length < 2) return h("p", { class: "muted" }, "Needs two runs.");
  const pick = (name, sel) => h("select", { name, "data-testid": `compare-${name}` }, ids.map((id, i) => h("option", { value: id, selected: i === sel }, id)));
  const a = pick("a", 1), b = pick("b", 0);
  return h("div", { class: "toolbar" }, "A", a, "B", b,
    h("button", { onclick: () => { location.hash = `#/compare/${enc(a.value)}/${enc(b.value)}`; } }, "Compare"));
}

// ---------------------------------------------------------------------------------------------------------------
// One run, live while it is in progress

async function runView(runId) {
  const head = region({}), problems = region({}), live = region({ "data-testid": "live" });
  const pending = region({}), tasks = region({ "data-testid": "tasks" }), summary = region({}), curve = region({});
  let filter = "";
  let lastData = null;
  const search = h("input", { type: "search", placeholder: "filter tasks (id, status, platform)", oninput: () => {
    filter = search.value.toLowerCase();
    if (lastData) tasks.show({ t: lastData.tasks, f: filter }, () => renderTasks(runId, lastData.tasks, filter));
  } });
  app.replaceChildren(head, problems, live, pending,
    h("h2", {}, "Tasks"), h("div", { class: "toolbar" }, search), tasks,
    h("h2", {}, "Summary"), summary,
    h("h2", {}, "Success rate against the number of subtasks"), curve);
  await poll(`/api/runs/${enc(runId)}`, (run) => {
    lastData = run;
    head.show({ ...run, tasks: null, summary: null, problems: null }, () => renderRunHead(run));
    problems.show(run.problems, problemsBox);
    live.show({ r: run.tasks.filter((t) => t.status === "running"), s: run.state }, (d) => renderLive(runId, d.r, d.s));
    pending.show({ p: run.pending, plan: run.has_plan, s: run.state }, () => renderPending(run));
    tasks.show({ t: run.tasks, f: filter }, () => renderTasks(runId, run.tasks, filter));
    summary.show(run.summary, summaryTables);
    curve.show(run.summary && run.summary.curve, (pts) => curvePlot([{ label: runId, points: pts || [] }]));
  }, (run) => run.state === "in progress");
}

function renderRunHead(run) {
  const c = run.counts;
  const num = (label, n, cls) => h("div", { class: "count", "data-testid": `count-${cls}` }, h("b", {}, n), label);
  return [
    h("h1", {}, run.id, " ", badge(run.state)),
    h("div", { class: "meta" },
      h("span", {}, "agent ", h("b", {}, run.agent_name || "–")),
      h("span", {}, "started ", h("b", {}, fmtTime(run.started))),
      run.finished ? h("span", {}, "finished ", h("b", {}, fmtTime(run.finished))) : null,
      h("span", {}, "last activity ", h("b", {}, fmtTime(run.updated))),
      h("span", {}, "TSR ", h("b", {}, pct(run.stats.tsr)), " · SSR ", h("b", {}, pct(run.stats.ssr))),
      h("span", {}, `${whoseTime(run.agent_name)} `, h("b", { "data-testid": "run-time" }, timeText(run.stats.timing))),
      run.files.map((f) => h("a", { href: fileUrl(run.id, f), target: "_blank" }, f))),
    h("div", { class: "counts" },
      num("done", `${c.done}/${c.total}`, "done"), num("passed", c.passed, "passed"), num("failed", c.failed, "failed"),
      num("errors", c.error, "error"), num("running", c.running, "running"),
      num("pending", run.has_plan ? c.pending : "?", "pending"),
      c.interrupted ? num("interrupted", c.interrupted, "interrupted") : null,
      c.unknown ? num("unreadable", c.unknown, "unknown") : null),
    progressBar(c),
  ];
}

function renderLive(runId, running, state) {
  if (!running.length && state !== "in progress") return null;
  const title = h("h2", {}, "Running now");
  if (!running.length) return [title, h("p", { class: "muted" }, "No task is running.")];
  return [title, h("div", { class: "live" }, running.map((t) => {
    const s = t.latest_step;
    return h("div", { class: "card", "data-testid": "live-task", "data-task": t.name },
      h("div", {}, h("a", { href: taskHref(runId, t.name) }, h("b", {}, t.task_id)), " ", badge(t.status)),
      h("div", { class: "meta" }, h("span", { "data-testid": "live-steps" }, `${t.steps} step${t.steps === 1 ? "" : "s"}`),
        h("span", {}, t.platforms.join(", ")), h("span", {}, `updated ${fmtTime(t.updated)}`)),
      s ? h("div", { "data-testid": "live-action" }, h("code", {}, `#${s.index} ${s.platform || "?"}: ${s.action_text}`)) : h("div", { class: "muted" }, "no step yet"),
      s && s.reasoning ? h("div", { class: "muted" }, s.reasoning.split("\n")[0].slice(0, 240)) : null,
      s && s.error ? h("div", { class: "errorbox" }, s.error) : null,
      h("div", { class: "thumbs" }, Object.entries(t.latest_screenshots).map(([platform, name]) =>
        h("figure", {}, h("img", { src: shotUrl(runId, t.name, name), alt: `${platform} latest screenshot`, loading: "lazy", "data-testid": "live-shot" }),
          h("figcaption", {}, `${platform} · ${name}`)))),
      problemsBox(t.problems));
  }))];
}

function renderPending(run) {
  if (!run.has_plan) {
    return run.state === "in progress" ? h("p", { class: "muted" }, "This run has no plan.json: pending tasks are not known.") : null;
  }
  if (!run.pending.length) return null;
  return h("div", { class: "card", "data-testid": "pending" }, h("h3", {}, `Pending (${run.pending.length})`),
    h("div", { class: "chips" }, run.pending.map((id) => h("span", { class: "chip" }, id))));
}

function renderTasks(runId, tasks, filter) {
  const shown = tasks.filter((t) => !filter || [t.task_id, t.status, t.category, t.platforms.join(" "), t.end_reason, t.failure_mode || ""].join(" ").toLowerCase().includes(filter));
  if (!tasks.length) return h("p", { class: "muted" }, "No task has started yet.");
  return h("table", {},
    h("thead", {}, h("tr", {}, ["Task", "Category", "Platforms", "Status", "Subtasks", "Steps", "End", "Duration", "Decision (a step)", "Problems"].map((c) => h("th", {}, c)))),
    h("tbody", {}, shown.map((t) => h("tr", { class: "row-link", "data-task": t.name, "data-status": t.status },
      h("td", {}, h("a", { href: taskHref(runId, t.name) }, t.task_id)),
      h("td", {}, t.category || "–"),
      h("td", {}, t.platforms.join(", ")),
      h("td", {}, badge(t.status)),
      h("td", { class: "num" }, t.subtasks_total ? `${t.subtasks_passed}/${t.subtasks_total}` : "–"),
      h("td", { class: "num" }, t.steps),
      h("td", {}, t.end_reason || "", t.failure_mode ? h("div", { class: "muted", "data-testid": "failure-mode" }, t.failure_mode) : null),
      h("td", { class: "num" }, fmtSecs(t.duration)),
      h("td", { class: "num", "data-testid": "task-time" }, t.agent_seconds === null || t.agent_seconds === undefined ? "–"
        : `${fmtSecs(t.agent_seconds)} (${fmtSecs(t.step_seconds)})`),
      h("td", { class: "num" }, t.problems.length ? h("span", { class: "badge error", title: t.problems.map((p) => p.message).join("\n") }, t.problems.length) : "")))));
}

// ---------------------------------------------------------------------------------------------------------------
// One task: step through its trajectory

// Points of an action to mark on its device's screenshot, in device pixels.
function actionMarks(action) {
  if (!action || typeof action.x !== "number" || typeof action.y !== "number") return { points: [], lines: [] };
  const end = { x: action.x, y: action.y };
  if (action.type === "DRAG_TO" && typeof action.start_x === "number" && typeof action.start_y === "number") {
    const start = { x: action.start_x, y: action.start_y, start: true };
    return { points: [start, end], lines: [[start, end]] };
  }
  if (action.type === "SWIPE") {
    const to = { x: action.x + (action.dx || 0), y: action.y + (action.dy || 0) };
    return { points: [{ ...end, start: true }, to], lines: [[end, to]] };
  }
  return { points: [end], lines: [] };
}

// Place the marks over the image as displayed: device pixels scaled by displayed size / natural size.
function placeMarks(box, img, marks) {
  box.querySelectorAll(".marker, .overlay").forEach((el) => el.remove());
  const W = img.naturalWidth, H = img.naturalHeight;
  if (!W || !H) return;
  const sx = img.clientWidth / W, sy = img.clientHeight / H;
  const ox = img.offsetLeft, oy = img.offsetTop;
  if (marks.lines.length) {
    const o = svg("svg", { class: "overlay", viewBox: `0 0 ${W} ${H}`, preserveAspectRatio: "none",
      style: `left:${ox}px;top:${oy}px;width:${img.clientWidth}px;height:${img.clientHeight}px` });
    for (const [a, b] of marks.lines) o.append(svg("line", { x1: a.x, y1: a.y, x2: b.x, y2: b.y }));
    box.append(o);
  }
  for (const p of marks.points) {
    box.append(h("div", { class: `marker${p.start ? " start" : ""}`, "data-testid": p.start ? "marker-start" : "marker",
      "data-x": p.x, "data-y": p.y, style: `left:${ox + p.x * sx}px;top:${oy + p.y * sy}px` }));
  }
}

function screenshotFigure(runId, task, platform, name, marks) {
  const img = h("img", { src: shotUrl(runId, task, name), alt: `${platform} screenshot`, "data-testid": "shot", "data-platform": platform });
  const box = h("div", { class: "shot" }, img);
  if (marks) {
    const place = () => placeMarks(box, img, marks);
    img.addEventListener("load", place);
    new ResizeObserver(place).observe(img);
  }
  return h("figure", {}, box, h("figcaption", {}, `${platform} · `, h("a", { href: img.src, target: "_blank" }, name)));
}

async function taskView(runId, taskName, stepParam) {
  const head = region({}), problems = region({}), verdicts = region({ "data-testid": "verdicts" });
  const timeline = region({}), stepPane = region({ "data-testid": "step" });
  const nav = h("div", { class: "stepnav card" });
  app.replaceChildren(head, problems,
    h("h2", {}, "Evaluation"), verdicts,
    h("h2", {}, "Trajectory"), nav,
    h("div", { class: "task-layout" }, timeline, stepPane));
  // `cur` is the shown frame; `follow` keeps showing the newest one while the task runs (until the user steps back)
  let frames = [], cur = null, follow = false, task = null;
  const wanted = stepParam === undefined ? null : Number(stepParam);

  const go = (i) => {
    if (!frames.length) return;
    cur = Math.max(0, Math.min(frames.length - 1, i));
    follow = cur === frames.length - 1;
    history.replaceState(null, "", taskHref(runId, taskName, frames[cur].index));
    draw();
  };
  const draw = () => {
    renderNav(nav, frames, cur, go);
    timeline.show({ frames: frames.map((f) => [f.index, f.label, !!f.error]), cur }, () => renderTimeline(frames, cur, go));
    stepPane.show({ frame: frames[cur] || null, status: task.status }, () => renderFrame(runId, taskName, frames[cur], task));
  };
  document.onkeydown = (e) => {
    if (e.target.closest && e.target.closest("input, select, textarea")) return;
    if (e.key === "ArrowLeft") go(cur - 1);
    if (e.key === "ArrowRight") go(cur + 1);
  };

  await poll(`/api/runs/${enc(runId)}/tasks/${enc(taskName)}`, (t) => {
    task = t;
    head.show({ ...t, steps_detail: null, extra_screenshots: null, latest_step: null, problems: null }, () => renderTaskHead(runId, t));
    problems.show(t.problems, problemsBox);
    verdicts.show({ s: t.subtasks, st: t.status, e: t.error, r: t.end_reason }, () => renderVerdicts(t));
    const shownIndex = cur !== null && frames[cur] ? frames[cur].index : wanted;
    frames = buildFrames(t);
    if (shownIndex === null) {
      follow = t.status === "running";
      cur = follow ? frames.length - 1 : 0;
    } else if (follow) {
      cur = frames.length - 1;
    } else {
      const i = frames.findIndex((f) => f.index === shownIndex);
      cur = i >= 0 ? i : Math.min(cur || 0, frames.length - 1);
    }
    cur = Math.max(0, cur);
    draw();
  }, (t) => t.status === "running");
}

// Every recorded step, plus the screenshots no step refers to (the final state, or a step being decided now).
function buildFrames(t) {
  const frames = t.steps_detail.map((s) => ({ ...s, kind: "step", label: `#${s.index} ${s.platform || "?"} ${s.action_text}` }));
  for (const e of t.extra_screenshots) {
    const final = t.status !== "running";
    frames.push({ index: e.index, screenshots: e.screenshots, kind: final ? "final" : "observing",
      label: final ? `final state (after step ${e.index - 1})` : `#${e.index} (agent deciding…)` });
  }
  return frames.sort((a, b) => a.index - b.index || (a.kind === "step" ? -1 : 1));
}

function renderTaskHead(runId, t) {
  return [
    h("div", { class: "muted" }, h("a", { href: runHref(runId) }, `← run ${runId}`)),
    h("h1", {}, t.task_id, " ", badge(t.status)),
    h("div", { class: "meta" },
      h("span", {}, "category ", h("b", {}, t.category || "–")),
      h("span", {}, "platforms ", h("b", {}, t.platforms.join(", ") || "–")),
      h("span", {}, "steps ", h("b", {}, t.steps)),
      h("span", {}, "end ", h("b", {}, t.end_reason || "–")),
      t.failure_mode ? h("span", {}, "failure mode ", h("b", { "data-testid": "task-failure-mode" }, t.failure_mode)) : null,
      Object.keys(t.backends || {}).length ? h("span", {}, "devices ", h("b", {}, Object.values(t.backends).join(", ")),
        (t.stand_ins || []).length ? h("span", { class: "muted" }, " (stand-in)") : null) : null,
      h("span", {}, "duration ", h("b", {}, fmtSecs(t.durations && t.durations.total))),
      h("span", {}, "agent ", h("b", {}, (t.agent && t.agent.name) || "–")),
      t.agent_seconds !== null && t.agent_seconds !== undefined ? h("span", {}, `${whoseTime(t.agent && t.agent.name)} `,
        h("b", { "data-testid": "task-time" }, `${fmtSecs(t.agent_seconds)} (${fmtSecs(t.step_seconds)} a step)`)) : null),
    playBox(t.task_id),
    t.instruction ? h("div", { class: "card" }, h("b", {}, "Instruction"), h("pre", { "data-testid": "instruction" }, t.instruction)) : null,
  ];
}

// "Play this task yourself": starts `jarvis play` for it (POST /api/play) and opens the player in a new tab.
function playBox(taskId) {
  const note = h("span", { class: "muted", "data-testid": "play-note" });
  const button = h("button", { "data-testid": "play", title: "boot this task's devices and play it in the browser as the agent human" }, "▶ Play this task yourself");
  button.addEventListener("click", async () => {
    const tab = window.open("about:blank", "_blank"); // opened now, while the click counts: a pop-up blocker allows it
    button.disabled = true;
    note.textContent = " starting its devices…";
    try {
      const res = await fetch("/api/play", { method: "POST", headers: { "Content-Type": "application/json", "X-Jarvis-Play": "1" },
        body: JSON.stringify({ task: taskId }) });
      const data = await res.json();
      if (!res.ok) throw new Error(data.error || res.statusText);
      note.replaceChildren(" playing in ", h("a", { href: data.url, target: "_blank", "data-testid": "play-link" }, "the player"),
        " as run ", h("a", { href: runHref(data.run) }, data.run));
      if (tab) tab.location.href = data.url;
    } catch (e) {
      if (tab) tab.close();
      note.textContent = ` cannot play: ${e.message}`;
    } finally {
      button.disabled = false;
    }
  });
  return h("div", { class: "toolbar" }, button, note);
}

function renderVerdicts(t) {
  const out = [];
  if (t.error) out.push(h("div", { class: "errorbox", "data-testid": "task-error" }, h("b", {}, "Error: "), t.error));
  if (!t.subtasks.length) {
    out.push(h("p", { class: "muted" }, t.status === "running" ? "Not evaluated yet (the task is running)." : "No evaluator verdicts."));
    return out;
  }
  for (const s of t.subtasks) {
    out.push(h("div", { class: `verdict ${s.passed ? "passed" : "failed"}`, "data-testid": "subtask" },
      h("div", {}, badge(s.passed ? "passed" : "failed"), " ", h("b", {}, `subtask ${s.index}`), ` ${s.template} · ${s.platform}`),
      h("ul", {}, s.evaluators.map((v) => h("li", { "data-testid": "evaluator" },
        badge(v.passed ? "passed" : "failed"), " ", h("code", {}, v.func), ": ", v.reason,
        Object.keys(v.args || {}).length ? h("details", {}, h("summary", { class: "muted" }, "arguments"), h("pre", {}, JSON.stringify(v.args, null, 2))) : null)))));
  }
  return out;
}

function renderNav(nav, frames, cur, go) {
  if (!frames.length) {
    nav.replaceChildren(h("span", { class: "muted" }, "No step recorded yet."));
    return;
  }
  const range = h("input", { type: "range", min: 0, max: frames.length - 1, value: cur, oninput: () => go(Number(range.value)) });
  nav.replaceChildren(
    h("button", { onclick: () => go(0), disabled: cur === 0, title: "first" }, "« first"),
    h("button", { onclick: () => go(cur - 1), disabled: cur === 0, title: "previous (←)", "data-testid": "prev" }, "◀"),
    h("span", { "data-testid": "step-position" }, `${cur + 1} / ${frames.length}`),
    h("button", { onclick: () => go(cur + 1), disabled: cur === frames.length - 1, title: "next (→)", "data-testid": "next" }, "▶"),
    h("button", { onclick: () => go(frames.length - 1), disabled: cur === frames.length - 1, title: "last" }, "last »"),
    range);
}

function renderTimeline(frames, cur, go) {
  return h("ol", { class: "timeline", "data-testid": "timeline" }, frames.map((f, i) =>
    h("li", { class: [i === cur ? "current" : "", f.error ? "has-error" : ""].join(" "), title: f.label, onclick: () => go(i) }, f.label)));
}

function renderFrame(runId, taskName, f, task) {
  if (!f) return h("p", { class: "muted" }, "Nothing to show yet.");
  const marks = f.kind === "step" ? actionMarks(f.action) : null;
  const shots = h("div", { class: "shots" }, Object.entries(f.screenshots || {}).sort().map(([platform, name]) =>
    screenshotFigure(runId, taskName, platform, name, platform === f.platform ? marks : null)));
  if (f.kind !== "step") {
    return [h("h3", {}, f.label), shots];
  }
  const person = (f.extra || {}).player;
  const timing = [["observe", f.observe_ms], [person ? "waited for the person" : "agent", f.agent_ms],
    ...(person ? [["think", person.think_ms]] : []), ["execute", f.exec_ms]]
    .map(([k, v]) => `${k} ${Math.round(v)} ms`).join(" · ");
  return [
    h("h3", {}, `Step ${f.index} on ${f.platform || "?"}`),
    f.error ? h("div", { class: "errorbox", "data-testid": "step-error" }, f.error) : null,
    h("div", { class: "card" }, h("b", {}, "Action "), h("code", { "data-testid": "action" }, f.action_text),
      f.action ? h("details", {}, h("summary", { class: "muted" }, "JSON"), h("pre", {}, JSON.stringify(f.action, null, 2))) : null),
    shots,
    ((f.extra || {}).commands || []).length ? h("div", { class: "card", "data-testid": "commands" }, h("b", {}, "Commands run on the device"),
      ...f.extra.commands.map((c) => h("details", { open: true },
        h("summary", {}, h("code", {}, `${c.platform}$ ${c.command.split("\n")[0].slice(0, 200)}`), ` → exit ${c.returncode} in ${c.seconds} s`),
        h("pre", {}, c.command + (c.output ? `\n--- output ---\n${c.output}` : ""))))) : null,
    h("div", { class: "card" }, h("b", {}, "Planner reasoning"),
      h("pre", { "data-testid": "reasoning" }, f.reasoning || "(none)"),
      f.raw_output && f.raw_output !== f.reasoning ? h("details", {}, h("summary", { class: "muted" }, "raw model output"), h("pre", {}, f.raw_output)) : null),
    h("div", { class: "muted" }, timing,
      Object.keys(f.usage || {}).length ? ` · tokens ${Object.entries(f.usage).map(([k, v]) => `${k} ${v}`).join(", ")}` : ""),
  ];
}

// ---------------------------------------------------------------------------------------------------------------
// Two runs task by task

async function compareView(a, b) {
  const data = await api(`/api/compare?a=${enc(a)}&b=${enc(b)}`);
  let onlyChanges = false;
  const table = region({ "data-testid": "compare" });
  const box = h("input", { type: "checkbox", onchange: () => { onlyChanges = box.checked; table.show({ onlyChanges }, () => renderCompare(data, onlyChanges)); } });
  const changes = {};
  for (const r of data.rows) changes[r.change] = (changes[r.change] || 0) + 1;
  const side = (label, r) => h("div", { class: "card" }, h("b", {}, `${label}: `), h("a", { href: runHref(r.id) }, r.id), " ", badge(r.state),
    h("div", { class: "meta" }, h("span", {}, "agent ", h("b", {}, r.agent_name || "–")), h("span", {}, "started ", h("b", {}, fmtTime(r.started))),
      h("span", {}, countsLine(r.counts)), h("span", {}, "TSR ", h("b", {}, pct(r.stats.tsr)), " · SSR ", h("b", {}, pct(r.stats.ssr))),
      h("span", {}, `${whoseTime(r.agent_name)} `, h("b", { "data-testid": `compare-time-${label}` }, timeText(r.stats.timing)))));
  app.replaceChildren(h("h1", {}, "Compare runs"), side("A", data.a), side("B", data.b),
    h("div", { class: "toolbar" }, Object.entries(changes).map(([k, n]) => h("span", {}, badge(k), ` ${n}`)),
      h("label", {}, box, " only tasks whose status changed")),
    table,
    h("h2", {}, "Success rate against the number of subtasks"),
    curvePlot([{ label: `A ${data.a.id}`, points: (data.a.summary && data.a.summary.curve) || [] },
      { label: `B ${data.b.id}`, points: (data.b.summary && data.b.summary.curve) || [] }]));
  table.show({ onlyChanges }, () => renderCompare(data, onlyChanges));
}

function renderCompare(data, onlyChanges) {
  const cell = (run, s) => (s ? [h("td", {}, h("a", { href: taskHref(run, s.name) }, badge(s.status))),
    h("td", { class: "num" }, s.subtasks_total ? `${s.subtasks_passed}/${s.subtasks_total}` : "–"),
    h("td", { class: "num" }, s.steps),
    h("td", { class: "num" }, fmtSecs(s.loop_seconds))] : [h("td", { class: "muted" }, "–"), h("td", {}), h("td", {}), h("td", {})]);
  const rows = data.rows.filter((r) => !onlyChanges || r.change !== "same");
  return h("table", {},
    h("thead", {}, h("tr", {}, ["Task", "A", "subtasks", "steps", "time", "B", "subtasks", "steps", "time", "Change"].map((c) => h("th", {}, c)))),
    h("tbody", {}, rows.map((r) => h("tr", { "data-task": r.task_id, "data-change": r.change },
      h("td", {}, r.task_id), cell(data.a.id, r.a), cell(data.b.id, r.b), h("td", {}, badge(r.change))))));
}

// ---------------------------------------------------------------------------------------------------------------
// Router

async function route() {
  generation += 1;
  document.onkeydown = null;
  const parts = location.hash.replace(/^#\/?/, "").split("/").filter((p) => p !== "").map(decodeURIComponent);
  app.replaceChildren(h("p", { class: "muted" }, "Loading…"));
  try {
    if (parts[0] === "run" && parts[2] === "task" && parts[3]) await taskView(parts[1], parts[3], parts[4]);
    else if (parts[0] === "run" && parts[1]) await runView(parts[1]);
    else if (parts[0] === "compare" && parts[2]) await compareView(parts[1], parts[2]);
    else await runsView();
  } catch (e) {
    app.replaceChildren(h("div", { class: "errorbox", "data-testid": "page-error" }, e.message),
      h("p", {}, h("a", { href: "#/" }, "back to the runs")));
  }
}

window.addEventListener("hashchange", route);
route();

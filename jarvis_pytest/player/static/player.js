// jarvis-pytest player: shows the task's device screens live and sends what the person does to the player's
// server (server.py), which makes each input an action of the unified action space (inputs.py). The page sends
// what the browser saw (displayed points and sizes, KeyboardEvent fields, typed text), one event at a time and in
// order; the server decides what action it is. Vanilla JS, nothing loaded from elsewhere.
"use strict";

const STATE_MS = 300;   // how often the page asks for the task's state
const FRAME_MS = 200;   // the pause between two frames of the screen
const DRAG_PX = 6;      // a press and release this far apart (displayed pixels) is a drag, nearer a click
const HOVER_MS = 1000;  // the mouse at rest this long at a new place is a hover (the server: MOVE_TO on desktops)
// Keys that type nothing: sent as key presses (the server's inputs.NAMED_KEYS)
const NAMED = new Set(["Enter", "Tab", "Backspace", "Delete", "Escape", "ArrowUp", "ArrowDown", "ArrowLeft",
  "ArrowRight", "Home", "End", "PageUp", "PageDown", "Insert", "ContextMenu",
  ...Array.from({ length: 24 }, (_, i) => `F${i + 1}`)]);
const SILENT = new Set(["Control", "Shift", "Alt", "Meta", "AltGraph", "OS", "Super", "Hyper", "Fn", "FnLock",
  "CapsLock", "NumLock", "ScrollLock", "Dead", "Process", "Unidentified", "Compose"]);
const BUTTONS = ["left", "middle", "right"];

const token = new URLSearchParams(location.hash.slice(1)).get("token") || "";
const $ = (id) => document.getElementById(id);
const shot = $("shot"), keys = $("keys"), screenBox = $("screen");
let state = null;
let platform = null;     // the device tab shown; inputs go to it
let tasksSeen = -1;
let seq = null;          // the number of the last event sent (from the server's, so a reload goes on from there)
let chain = Promise.resolve();
let press = null;        // the mouse button held: where, which and since when
let stopped = false;
let restTimer = null;    // the hover to send once the mouse rests
let lastPoint = null;    // the displayed point of the last pointer input sent (a click, a drag's end, a hover)

function headers(extra) {
  return { "X-Player-Token": token, ...(extra || {}) };
}

function showError(message) {
  const box = $("error");
  box.hidden = !message;
  box.textContent = message || "";
}

// One event after the other, in the order they happened.
function send(event) {
  if (!state || !state.task || !platform) return Promise.resolve();
  const body = { ...event, platform };
  chain = chain.then(async () => {
    seq += 1;
    body.seq = seq;
    try {
      const res = await fetch("/api/input", { method: "POST", headers: headers({ "Content-Type": "application/json" }),
        body: JSON.stringify(body) });
      const data = await res.json().catch(() => ({}));
      showError(res.ok ? "" : data.error || `${res.status} ${res.statusText}`);
    } catch (e) {
      showError(`cannot reach the player: ${e.message}`);
    }
  });
  return chain;
}

// -- the screen -------------------------------------------------------------------------------------------------

function displayed(e) {
  const r = shot.getBoundingClientRect();
  return { x: e.clientX - r.left, y: e.clientY - r.top, w: r.width, h: r.height };
}

function restless() {
  clearTimeout(restTimer);
  restTimer = null;
}
shot.addEventListener("mousedown", (e) => {
  e.preventDefault();
  restless();
  keys.focus({ preventScroll: true });
  press = { ...displayed(e), button: e.button, at: performance.now() };
});
shot.addEventListener("mouseup", (e) => {
  e.preventDefault();
  if (!press || press.button !== e.button) return;
  const at = displayed(e);
  const from = press;
  const held_ms = Math.round(performance.now() - from.at);
  press = null;
  if (e.button === 0 && Math.hypot(at.x - from.x, at.y - from.y) > DRAG_PX) {
    send({ kind: "drag", start_x: from.x, start_y: from.y, x: at.x, y: at.y, w: at.w, h: at.h, held_ms });
    lastPoint = at;
  } else {
    send({ kind: "click", button: BUTTONS[e.button] || "left", x: from.x, y: from.y, w: at.w, h: at.h, detail: e.detail,
      held_ms });
    lastPoint = from;
  }
});
// The mouse at rest at a new place, no button held: a hover (the server ignores it on a touch screen).
shot.addEventListener("mousemove", (e) => {
  restless();
  if (press || e.buttons) return;
  const at = displayed(e);
  restTimer = setTimeout(() => {
    restTimer = null;
    if (lastPoint && Math.hypot(at.x - lastPoint.x, at.y - lastPoint.y) <= DRAG_PX) return;
    lastPoint = at;
    send({ kind: "hover", x: at.x, y: at.y, w: at.w, h: at.h });
  }, HOVER_MS);
});
shot.addEventListener("mouseleave", restless);
shot.addEventListener("contextmenu", (e) => e.preventDefault());
shot.addEventListener("dragstart", (e) => e.preventDefault());
shot.addEventListener("wheel", (e) => {
  e.preventDefault();
  restless();
  const at = displayed(e);
  lastPoint = at;
  send({ kind: "scroll", x: at.x, y: at.y, w: at.w, h: at.h, dx: e.deltaX, dy: e.deltaY, mode: e.deltaMode });
}, { passive: false });

// Keys reach the hidden text box while the screen has the focus: key presses are sent as keys, text as text.
keys.addEventListener("keydown", (e) => {
  if (e.isComposing || SILENT.has(e.key)) return;
  const altgr = e.getModifierState && e.getModifierState("AltGraph");
  const chord = (e.ctrlKey || e.altKey || e.metaKey) && !altgr;
  if (!NAMED.has(e.key) && !chord) return; // a character: it arrives as text (input event)
  e.preventDefault();
  send({ kind: "key", key: e.key, code: e.code, ctrl: e.ctrlKey, alt: e.altKey, shift: e.shiftKey, meta: e.metaKey,
    altgraph: !!altgr });
});
function takeText() {
  const text = keys.value;
  keys.value = "";
  if (text) send({ kind: "text", text });
}
keys.addEventListener("input", (e) => { if (!e.isComposing) takeText(); });
keys.addEventListener("compositionend", takeText);
keys.addEventListener("focus", () => screenBox.classList.add("focused"));
keys.addEventListener("blur", () => screenBox.classList.remove("focused"));

for (const b of document.querySelectorAll("#system-buttons button")) {
  b.addEventListener("click", () => { send({ kind: "button", button: b.dataset.button }); keys.focus({ preventScroll: true }); });
}
$("done").addEventListener("click", () => send({ kind: "done" }));
$("fail").addEventListener("click", () => send({ kind: "fail" }));
$("combo-form").addEventListener("submit", (e) => {
  e.preventDefault();
  const combo = $("combo").value.trim();
  if (combo) send({ kind: "keys", combo });
  $("combo").value = "";
});
$("text-form").addEventListener("submit", (e) => {
  e.preventDefault();
  const text = $("text").value;
  if (text) send({ kind: "text", text });
  $("text").value = "";
});

// The shown tab's screen, frame after frame.
async function frames() {
  let shown = null;
  while (!stopped) {
    if (platform) {
      try {
        const res = await fetch(`/api/frame/${encodeURIComponent(platform)}`, { headers: headers(), cache: "no-store" });
        if (res.ok) {
          const url = URL.createObjectURL(await res.blob());
          await new Promise((resolve) => { shot.onload = shot.onerror = resolve; shot.src = url; });
          shot.dataset.platform = platform;
          if (shown) URL.revokeObjectURL(shown);
          shown = url;
        }
      } catch (e) { /* the state poll says when the player is gone */ }
    }
    await new Promise((r) => setTimeout(r, FRAME_MS));
  }
}

// -- the task's state -------------------------------------------------------------------------------------------

function renderTabs(platforms) {
  const tabs = $("tabs");
  tabs.replaceChildren(...platforms.map((p) => {
    const b = document.createElement("button");
    b.textContent = p;
    b.dataset.testid = `tab-${p}`;
    b.setAttribute("data-testid", `tab-${p}`);
    b.className = p === platform ? "current" : "";
    b.addEventListener("click", () => { platform = p; renderTabs(platforms); keys.focus({ preventScroll: true }); });
    return b;
  }));
  showSystemButtons();
}

// a touch screen's system buttons, under its screen only
function showSystemButtons() {
  $("system-buttons").hidden = !(state && state.touch && state.touch.includes(platform));
}

function render(s) {
  const status = $("status");
  const task = s.task;
  if (s.tasks !== tasksSeen) { // a new task: its devices, its first tab
    tasksSeen = s.tasks;
    platform = task ? task.platforms[0] : null;
    renderTabs(task ? task.platforms : []);
    keys.focus({ preventScroll: true });
  }
  $("task").textContent = task ? task.id : "";
  $("instruction").textContent = task ? task.instruction : "";
  $("step").textContent = task && s.step >= 0 ? `step ${s.step + 1}` : "";
  let cls = "busy", text;
  if (!task) text = "Waiting for the task to start (its devices are booting)…";
  else if (s.ending) { cls = "ended"; text = `You ended the task with ${s.ending.toUpperCase()}. The harness evaluates it now: the verdict is in the terminal and the dashboard.`; }
  else if (s.waiting && !s.queued) { cls = "turn"; text = `Your turn (step ${s.step + 1}).`; }
  else if (s.step < 0) text = "Setting up…";
  else text = s.queued ? `Carrying out your inputs (${s.queued} waiting)…` : "Carrying out…";
  status.className = `status ${cls}`;
  status.textContent = text;
  status.dataset.state = cls;
  $("done").disabled = $("fail").disabled = !task || !!s.ending;
  const t = s.typing;
  $("typing").textContent = t ? (t.type === "TYPING" ? `typing: ${t.text}` : `${t.type}…`) : "";
  const log = $("log");
  log.replaceChildren(...s.log.map((l) => {
    const li = document.createElement("li");
    li.textContent = `#${l.index} ${l.platform}: ${l.action}  (${l.think_s} s)` + (l.error ? `  — ${l.error}` : "");
    if (l.error) li.className = "error";
    return li;
  }));
  if (s.last_error && !$("error").textContent) showError(`the device refused the last action: ${s.last_error}`);
}

async function poll() {
  let misses = 0;
  while (!stopped) {
    try {
      const res = await fetch("/api/state", { headers: headers(), cache: "no-store" });
      const s = await res.json();
      if (!res.ok) throw new Error(s.error || res.statusText);
      if (seq === null) seq = s.last_seq;
      state = s;
      render(s);
      showSystemButtons();
      misses = 0;
    } catch (e) {
      misses += 1;
      if (misses >= 5) {
        $("status").textContent = "The player has stopped: the run ended (its results are in the terminal and the dashboard).";
        $("status").className = "status ended";
        $("status").dataset.state = "stopped";
        $("done").disabled = $("fail").disabled = true;
      }
    }
    await new Promise((r) => setTimeout(r, STATE_MS));
  }
}

if (!token) {
  $("status").textContent = "This address has no token: open the address the player printed (…/#token=…).";
} else {
  poll();
  frames();
}

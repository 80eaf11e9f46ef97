"""The replay player of a report: each scenario run drawn again from its bag, in the browser.

One ``<figure class="replay">`` per scenario with replay data (``scenarios/<id>/replay.js``,
:mod:`grader.report.replay`): the turtles on turtlesim's 11.09 m world with the pen trail as the
simulator drew it, the goals the grader handed over, and a timeline under it (the scenario's
steps, the commands sent, the grader's calls and events, log lines and the items decided on the
run, each a link to its item). Play, pause, speed 0.25x-8x, scrub, one tick back or on;
``report.html#replay=<scenario>&t=<seconds>`` opens that moment, and the link beside the player
always points at the moment shown, so a TA can send it. The page reads without JavaScript (the
player is then one line saying where the bag is); the script is inline and the data a local
``<script src>``, so a report opened from ``file://`` needs no network.

The figure carries the pose it draws (``data-t``, ``data-x``, ``data-y`` of the first turtle,
``data-turtles`` of all): what the Chromium test compares with the bag.
"""

from __future__ import annotations

import json
from html import escape
from typing import Any, Mapping, Sequence

from grader.report.replay import REPLAY_FILE
from grader.contracts.output_folder import SCENARIOS_DIR
from grader.rubric.result import ItemResult

#: where a report finds a scenario's folder, relative to the report
TICK_S = 0.016                       # turtlesim's update period: one "tick" of the step buttons
SPEEDS = (0.25, 0.5, 1, 2, 4, 8)

PLAYER_CSS = """
.replay{margin:0 0 1.5rem}.replay .stage{display:flex;flex-wrap:wrap;gap:1rem;align-items:flex-start}
.replay canvas.world{width:min(100%,440px);aspect-ratio:1;border:1px solid #888;background:#4556ff}
.replay .now{flex:1 1 16rem;font-size:.9rem;min-width:14rem}.replay .now dt{font-weight:600}
.replay .now dd{margin:0 0 .4rem;overflow-wrap:anywhere}
.replay canvas.timeline{width:100%;height:150px;border:1px solid #ccc;margin-top:.5rem;cursor:pointer}
.replay .controls{display:flex;flex-wrap:wrap;gap:.5rem;align-items:center;margin-top:.5rem}
.replay .controls input[type=range]{flex:1 1 12rem}.replay output{font-variant-numeric:tabular-nums;min-width:7rem}
.replay .legend{font-size:.8rem;color:#444}
@media print{.replay .controls,.replay canvas.timeline{display:none}}
"""

PLAYER_JS = r"""
(function () {
  "use strict";
  const DATA = window.graderReplays || {};
  const TICK = __TICK__;
  const STATUS_COLOUR = {pass: "#1a7f37", partial: "#9a6700", fail: "#cf222e", error: "#6e7781"};
  const players = {};
  window.graderPlayers = players;

  function last(ts, t) {              // the last index i with ts[i] <= t, or -1
    let lo = -1, hi = ts.length;
    while (hi - lo > 1) { const m = (lo + hi) >> 1; if (ts[m] <= t) lo = m; else hi = m; }
    return lo;
  }
  function lerp(ts, vs, t, wrap) {
    const i = last(ts, t);
    if (i < 0) return vs[0];
    if (i >= ts.length - 1) return vs[ts.length - 1];
    const f = (t - ts[i]) / ((ts[i + 1] - ts[i]) || 1);
    let d = vs[i + 1] - vs[i];
    if (wrap) d = Math.atan2(Math.sin(d), Math.cos(d));
    return vs[i] + d * f;
  }
  function pose(track, t) {
    return {x: lerp(track.t, track.x, t), y: lerp(track.t, track.y, t), th: lerp(track.t, track.th, t, true)};
  }
  function penAt(pens, t, dflt) {
    let pen = dflt;
    for (const p of pens || []) { if (p[0] <= t) pen = p.slice(1); else break; }
    return pen;
  }
  function fmt(t) { return t.toFixed(3).replace(/\.?0+$/, "") || "0"; }

  class Player {
    constructor(fig) {
      this.fig = fig; this.sc = fig.dataset.scenario; this.d = DATA[this.sc];
      this.items = JSON.parse(fig.dataset.items || "[]");
      this.t = 0; this.speed = 1; this.playing = false;
      const q = (s) => fig.querySelector(s);
      this.status = q(".replay-status");
      if (!this.d) { this.status.textContent = "The replay data of this scenario (" + fig.dataset.src + ") could not be loaded."; return; }
      this.status.textContent = "";
      fig.querySelector(".player").hidden = false;
      this.items.forEach((it) => { if (it.t === null) it.t = this.d.end; });
      this.world = q("canvas.world"); this.line = q("canvas.timeline");
      this.range = q("input[type=range]"); this.out = q("output"); this.link = q("a.moment-link");
      this.playBtn = q("button.play"); this.now = q("dl.now");
      this.range.max = String(this.d.end);
      this.range.addEventListener("input", () => { this.pause(); this.seek(parseFloat(this.range.value)); });
      this.playBtn.addEventListener("click", () => this.playing ? this.pause() : this.play());
      q("button.back").addEventListener("click", () => { this.pause(); this.seek(this.t - TICK); });
      q("button.on").addEventListener("click", () => { this.pause(); this.seek(this.t + TICK); });
      const sel = q("select.speed");
      sel.addEventListener("change", () => { this.speed = parseFloat(sel.value); });
      this.line.addEventListener("click", (ev) => this.clickTimeline(ev));
      this.draw();
    }
    seek(t) { this.t = Math.max(0, Math.min(this.d.end, t)); this.draw(); }
    play() {
      if (this.t >= this.d.end) this.t = 0;
      this.playing = true; this.playBtn.textContent = "Pause"; this.playBtn.setAttribute("aria-pressed", "true");
      let before = performance.now();
      const frame = (now) => {
        if (!this.playing) return;
        this.seek(this.t + (now - before) / 1000 * this.speed); before = now;
        if (this.t >= this.d.end) { this.pause(); return; }
        requestAnimationFrame(frame);
      };
      requestAnimationFrame(frame);
    }
    pause() {
      this.playing = false; this.playBtn.textContent = "Play"; this.playBtn.setAttribute("aria-pressed", "false");
    }
    draw() {
      this.drawWorld(); this.drawTimeline(); this.describe();
      this.range.value = String(this.t);
      this.out.textContent = "t = " + this.t.toFixed(2) + " s of " + this.d.end.toFixed(1) + " s";
      this.link.href = "#replay=" + encodeURIComponent(this.sc) + "&t=" + fmt(this.t);
      this.fig.dataset.t = this.t.toFixed(3);
    }
    drawWorld() {
      const c = this.world, size = c.width, g = c.getContext("2d"), d = this.d, k = size / d.world;
      const px = (x) => x * k, py = (y) => size - y * k;
      g.fillStyle = "rgb(69,86,255)"; g.fillRect(0, 0, size, size);
      const since = d.clears.filter((t) => t <= this.t).pop() ?? -Infinity;
      g.lineCap = "round";
      const shown = {};
      for (const [name, track] of Object.entries(d.turtles)) {
        const pens = d.pens[name], end = last(track.t, this.t);
        for (let i = 1; i <= end; i++) {
          if (track.t[i] < since) continue;
          const pen = penAt(pens, track.t[i], d.pen_default);
          if (pen[4]) continue;
          g.strokeStyle = "rgb(" + pen[0] + "," + pen[1] + "," + pen[2] + ")";
          g.lineWidth = Math.max(1, pen[3] * size / 500);
          g.beginPath(); g.moveTo(px(track.x[i - 1]), py(track.y[i - 1])); g.lineTo(px(track.x[i]), py(track.y[i])); g.stroke();
        }
        if (end < 0) continue;
        const p = pose(track, this.t);
        shown[name] = {x: +p.x.toFixed(3), y: +p.y.toFixed(3), theta: +p.th.toFixed(3)};
        g.save(); g.translate(px(p.x), py(p.y)); g.rotate(-p.th);
        g.fillStyle = "#f6d365"; g.strokeStyle = "#222"; g.lineWidth = 1.5;
        g.beginPath(); g.moveTo(14, 0); g.lineTo(-9, 8); g.lineTo(-5, 0); g.lineTo(-9, -8); g.closePath(); g.fill(); g.stroke();
        g.restore();
      }
      (d.placements || []).filter((r) => r[0] <= this.t).forEach((r) => {   // where the grader put it
        const x = px(r[1]), y = py(r[2]);
        g.strokeStyle = "rgba(255,255,255,.8)"; g.lineWidth = 1.5; g.setLineDash([3, 3]);
        g.strokeRect(x - 7, y - 7, 14, 14);
        g.beginPath(); g.moveTo(x, y); g.lineTo(x + 14 * Math.cos(r[3]), y - 14 * Math.sin(r[3])); g.stroke();
        g.setLineDash([]);
      });
      const goals = d.goals.filter((r) => r[0] <= this.t);
      goals.forEach((r, i) => {
        const latest = i === goals.length - 1, x = px(r[1]), y = py(r[2]);
        g.strokeStyle = latest ? "#fff" : "rgba(255,255,255,.5)"; g.lineWidth = latest ? 2.5 : 1.5;
        g.beginPath(); g.arc(x, y, latest ? 9 : 6, 0, 2 * Math.PI); g.moveTo(x - 12, y); g.lineTo(x + 12, y);
        g.moveTo(x, y - 12); g.lineTo(x, y + 12); g.stroke();
      });
      const first = Object.keys(shown)[0];
      this.fig.dataset.turtles = JSON.stringify(shown);
      if (first) { this.fig.dataset.x = String(shown[first].x); this.fig.dataset.y = String(shown[first].y); }
    }
    lanes() { return ["steps", "linear (m/s)", "angular (rad/s)", "grader", "logs", "items"]; }
    drawTimeline() {
      const c = this.line, ratio = window.devicePixelRatio || 1;
      const w = Math.max(200, c.clientWidth) * ratio, h = 150 * ratio;
      if (c.width !== w) { c.width = w; c.height = h; }
      const g = c.getContext("2d"), d = this.d, lanes = this.lanes(), lh = h / lanes.length;
      const X = (t) => t / (d.end || 1) * w;
      g.clearRect(0, 0, w, h); g.font = (10 * ratio) + "px sans-serif"; g.textBaseline = "middle";
      lanes.forEach((name, i) => {
        g.fillStyle = i % 2 ? "#f6f8fa" : "#fff"; g.fillRect(0, i * lh, w, lh);
        g.fillStyle = "#57606a"; g.fillText(name, 4, i * lh + lh / 2);
      });
      d.steps.forEach((s, i) => {
        g.fillStyle = i % 2 ? "#d0d7de" : "#afb8c1"; g.fillRect(X(s[0]), 1, Math.max(1, X(s[1]) - X(s[0])), lh - 2);
        g.fillStyle = "#24292f"; if (X(s[1]) - X(s[0]) > 40 * ratio) g.fillText(s[2], X(s[0]) + 3, lh / 2);
      });
      for (const cmd of Object.values(d.commands)) {
        [["v", 1, "#0969da"], ["w", 2, "#8250df"]].forEach(([key, lane, colour]) => {
          const vs = cmd[key], top = lane * lh, mid = top + lh / 2;
          const m = Math.max(1e-6, ...vs.map(Math.abs));
          g.strokeStyle = colour; g.lineWidth = ratio; g.beginPath();
          vs.forEach((v, i) => { const x = X(cmd.t[i]), y = mid - v / m * (lh / 2 - 2); i ? g.lineTo(x, y) : g.moveTo(x, y); });
          g.stroke();
        });
      }
      const ticks = (rows, lane, colour) => {
        g.strokeStyle = colour; g.lineWidth = ratio; g.beginPath();
        rows.forEach((r) => { g.moveTo(X(r[0]), lane * lh + 3); g.lineTo(X(r[0]), (lane + 1) * lh - 3); }); g.stroke();
      };
      ticks(d.events, 3, "#cf222e"); ticks(d.lines, 4, "#1a7f37");
      this.items.forEach((it) => {
        const x = X(it.t), y = 5 * lh + lh / 2, r = 5 * ratio;
        g.fillStyle = STATUS_COLOUR[it.status] || "#6e7781";
        g.beginPath(); g.moveTo(x, y - r); g.lineTo(x + r, y); g.lineTo(x, y + r); g.lineTo(x - r, y); g.closePath(); g.fill();
      });
      g.strokeStyle = "#000"; g.lineWidth = 2 * ratio; g.beginPath(); g.moveTo(X(this.t), 0); g.lineTo(X(this.t), h); g.stroke();
    }
    clickTimeline(ev) {
      const r = this.line.getBoundingClientRect(), f = (ev.clientX - r.left) / r.width;
      const lane = Math.floor((ev.clientY - r.top) / r.height * this.lanes().length);
      const t = f * this.d.end;
      if (lane === 5) {
        const near = this.items.find((it) => Math.abs(it.t - t) / this.d.end * r.width < 8);
        if (near) { location.hash = "#item-" + near.id; return; }
      }
      this.pause(); this.seek(t);
    }
    describe() {
      const d = this.d, t = this.t, rows = [];
      const step = d.steps.find((s) => s[0] <= t && t <= s[1]);
      rows.push(["Step", step ? step[2] : "—"]);
      for (const [name, cmd] of Object.entries(d.commands)) {
        const i = last(cmd.t, t);
        rows.push(["Commands to " + name, i < 0 ? "none yet" : "linear " + cmd.v[i] + " m/s, angular " + cmd.w[i] + " rad/s (t = " + cmd.t[i].toFixed(2) + " s)"]);
      }
      const ev = d.events[last(d.events.map((e) => e[0]), t)];
      rows.push(["Grader", ev ? ev[2] + " (t = " + ev[0].toFixed(2) + " s)" : "—"]);
      const line = d.lines[last(d.lines.map((e) => e[0]), t)];
      rows.push(["Log", line ? line[1] + ": " + line[2] + " (t = " + line[0].toFixed(2) + " s)" : "—"]);
      this.now.replaceChildren(...rows.flatMap(([k, v]) => {
        const dt = document.createElement("dt"), dd = document.createElement("dd");
        dt.textContent = k; dd.textContent = v; return [dt, dd];
      }));
    }
  }

  function fromHash() {
    // #replay-item=<item id> (the class view's link): the replay at the moment that decided it
    const item = location.hash.match(/^#replay-item=(.+)$/);
    if (item) {
      const a = document.querySelector('[id="item-' + decodeURIComponent(item[1]).replace(/"/g, "") + '"] .moment a');
      if (a) location.replace(a.getAttribute("href"));
      return;
    }
    const m = location.hash.match(/^#replay=([^&]+)(?:&t=([0-9.]+))?/);
    if (!m) return;
    const p = players[decodeURIComponent(m[1])];
    if (!p || !p.d) return;
    for (let e = p.fig.parentElement; e; e = e.parentElement) if (e.tagName === "DETAILS") e.open = true;
    p.pause(); p.seek(parseFloat(m[2] || "0")); p.fig.scrollIntoView();
  }
  document.querySelectorAll("figure.replay").forEach((fig) => { players[fig.dataset.scenario] = new Player(fig); });
  window.addEventListener("hashchange", fromHash);
  fromHash();
})();
""".replace("__TICK__", str(TICK_S))


def moment_s(item: ItemResult) -> float | None:
    """When the run decided ``item`` (its evidence's ``at_s``: seconds since the scenario
    started), or None when its whole run decided it."""
    at = (item.evidence or {}).get("at_s")
    return float(at) if isinstance(at, (int, float)) and not isinstance(at, bool) else None


def moment_link(item: ItemResult, scenarios: Sequence[str], replays: Sequence[str]) -> str:
    """A line under an item: the replay of its scenario at the moment that decided it."""
    shown = [sc for sc in scenarios if sc in replays]
    if not shown:
        return ""
    at = moment_s(item)
    links = ", ".join(f'<a href="#replay={escape(sc)}&amp;t={at if at is not None else 0:g}">{escape(sc)}'
                      + (f" at t = {at:.1f} s" if at is not None else "") + "</a>" for sc in shown)
    what = "the moment that decided it" if at is not None else "the run"
    return f'<p class="moment">Watch {what} in the replay: {links}.</p>'


def _markers(items: Sequence[ItemResult], item_scenarios: Mapping[str, Sequence[str]], sc: str) -> list[dict[str, Any]]:
    """The timeline's diamonds: each item judged on ``sc``, at its moment (None: the run's end)."""
    return [{"id": item.id, "status": item.status, "t": moment_s(item)} for item in items
            if sc in item_scenarios.get(item.id, ()) and item.kind != "manual"]


def player_html(replays: Sequence[str], items: Sequence[ItemResult],
                item_scenarios: Mapping[str, Sequence[str]]) -> str:
    """The report's replay section (empty without replay data): a player per scenario, the
    script that loads each one's data, the player's own script."""
    if not replays:
        return ""
    figures, scripts = [], []
    for sc in replays:
        src = f"{SCENARIOS_DIR}/{sc}/{REPLAY_FILE}"
        bag = f"{SCENARIOS_DIR}/{sc}/bag"
        marks = escape(json.dumps(_markers(items, item_scenarios, sc)), quote=True)
        speeds = "".join(f'<option value="{s:g}"{" selected" if s == 1 else ""}>{s:g}x</option>' for s in SPEEDS)
        figures.append(
            f'<figure class="replay" id="replay-{escape(sc)}" data-scenario="{escape(sc)}" data-src="{escape(src)}" '
            f'data-items="{marks}"><figcaption><b>{escape(sc)}</b> '
            f'<span class="replay-status">(the replay needs JavaScript; the recording is <a href="{escape(bag)}">'
            f'{escape(bag)}</a>)</span></figcaption>'
            f'<div class="player" hidden><div class="stage">'
            f'<canvas class="world" width="440" height="440" role="img" aria-label="The turtles of {escape(sc)} on '
            f'the turtlesim world, drawn from the recording"></canvas>'
            f'<dl class="now" aria-live="polite"></dl></div>'
            f'<canvas class="timeline" role="img" aria-label="Timeline of {escape(sc)}: steps, commands, the '
            f'grader\'s events, log lines and the items decided (click to go there)"></canvas>'
            f'<p class="legend">Lanes: the steps, linear and angular velocity commands, the grader\'s events '
            f'(goals, calls, placements), log lines, items decided (a diamond per item; click it).</p>'
            f'<div class="controls"><button type="button" class="play" aria-pressed="false">Play</button>'
            f'<button type="button" class="back" aria-label="One tick back">◀ tick</button>'
            f'<button type="button" class="on" aria-label="One tick on">tick ▶</button>'
            f'<label>speed <select class="speed">{speeds}</select></label>'
            f'<input type="range" min="0" step="{TICK_S}" value="0" aria-label="Time in {escape(sc)}">'
            f'<output>t = 0 s</output><a class="moment-link" href="#replay={escape(sc)}&amp;t=0">link to this '
            f'moment</a></div>'
            f'<p class="sub">Open the recording elsewhere: <a href="{escape(bag)}">{escape(bag)}</a> in Foxglove '
            f'(open the .mcap file), or <code>ros2 bag play {escape(bag)}</code>.</p></div></figure>')
        scripts.append(f'<script src="{escape(src)}"></script>')
    return (f'<section aria-labelledby="replay-h" id="replay"><h2 id="replay-h">Replay of each scenario</h2>'
            f'<p class="sub">What the turtle did and what the grader did, drawn from the recording. '
            f'<code>#replay=&lt;scenario&gt;&amp;t=&lt;seconds&gt;</code> after the page\'s address opens a moment.</p>'
            f'{"".join(figures)}</section>{"".join(scripts)}<script>{PLAYER_JS}</script>')

// scengen results browser: networks, test-case lineage, animations, evaluations, jobs and
// campaigns. Plain JavaScript, no build step, no request leaving the server. A report
// written by `scengen report` is this page with every answer it needs embedded
// (window.SCENGEN_REPORT), so it works from a file as well.
"use strict";

const REPORT = window.SCENGEN_REPORT || null;
const COLOURS = ["#2456a6", "#c62828", "#1a7f37", "#8e44ad", "#d97706", "#0e7490", "#be185d", "#4d7c0f"];
const CAR_COLOURS = ["#2456a6", "#8e44ad", "#d97706", "#0e7490", "#be185d", "#64748b", "#a16207", "#0f766e"];
// people on foot: the pictures' colours (service/pictures/pedestrians.py, held equal by a
// test), a disc each, their curves dotted
const PEDESTRIAN_COLOURS = ["#ff00ff", "#6200ea", "#000080", "#1b5e20"];
const CROSSWALK = { strip: "#8a8d93", stripe: "#ffffff", pavement: "#ebe6da" };
const CONTROLLER_COLOURS = {};

// ---------- data ----------

async function get(path) {
  if (REPORT) {
    if (path in REPORT.answers) return REPORT.answers[path];
    throw new Error(`this report does not hold ${path}`);
  }
  const answer = await fetch(path, { headers: { Accept: "application/json" } });
  if (!answer.ok) {
    let detail = answer.statusText;
    try { detail = (await answer.json()).detail || detail; } catch (e) { /* not JSON */ }
    throw new Error(`${answer.status}: ${detail}`);
  }
  return answer.json();
}

// ---------- elements ----------

function h(tag, attrs, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs || {})) {
    if (value === null || value === undefined || value === false) continue;
    if (key.startsWith("on")) node.addEventListener(key.slice(2), value);
    else if (key === "class") node.className = value;
    else node.setAttribute(key, value === true ? "" : value);
  }
  for (const child of children.flat(Infinity)) {
    if (child === null || child === undefined || child === false) continue;
    node.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return node;
}

function svg(tag, attrs, ...children) {
  const node = document.createElementNS("http://www.w3.org/2000/svg", tag);
  for (const [key, value] of Object.entries(attrs || {})) node.setAttribute(key, value);
  for (const child of children.flat(Infinity)) {
    if (child === null || child === undefined) continue;
    node.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return node;
}

function table(head, rows) {
  return h("table", {}, h("thead", {}, h("tr", {}, head.map((c) => h("th", {}, c)))),
    h("tbody", {}, rows.map((r) => (r instanceof Node ? r : h("tr", {}, r.map((c) => (c instanceof Node && c.tagName === "TD" ? c : h("td", {}, c))))))));
}

function link(text, hash) { return h("a", { href: hash }, text); }
function short(id) { return id ? id.slice(0, 8) : ""; }
function colourOf(controller, all) {
  if (!(controller in CONTROLLER_COLOURS)) {
    CONTROLLER_COLOURS[controller] = COLOURS[(all ? all.indexOf(controller) : Object.keys(CONTROLLER_COLOURS).length) % COLOURS.length];
  }
  return CONTROLLER_COLOURS[controller];
}
function download(text, name) {
  return h("a", { href: URL.createObjectURL(new Blob([text], { type: "application/json" })), download: name }, name);
}

// ---------- routing ----------

const main = document.getElementById("main");
// the page's content (null and false leave nothing)
function render(...nodes) { main.replaceChildren(...nodes.flat(Infinity).filter((n) => n !== null && n !== undefined && n !== false)); }
let stopPage = () => {};

const PAGES = [
  [/^#(?:\/(?:networks\/?)?)?$/, home],  // the start page lists the networks
  [/^#\/networks\/([^/]+)$/, networkPage],
  [/^#\/testcases(?:\?(.*))?$/, testcasesPage],
  [/^#\/testcases\/([0-9a-f]+)$/, testcasePage],
  [/^#\/evaluations(?:\?(.*))?$/, evaluationsPage],
  [/^#\/replay\/([0-9a-f]+)$/, replayPage],
  [/^#\/jobs\/?$/, jobsPage],
  [/^#\/jobs\/([0-9a-f]+)$/, jobPage],
];

function navigation() {
  const items = REPORT ? [["Campaign", REPORT.start]]
    : [["Networks", "#/"], ["Test-cases", "#/testcases"], ["Evaluations", "#/evaluations"], ["Jobs & campaigns", "#/jobs"]];
  const nav = document.getElementById("nav");
  nav.replaceChildren(...items.map(([text, hash]) => h("a", { href: hash, class: location.hash.startsWith(hash) && hash !== "#/" || location.hash === hash ? "active" : null }, text)));
}

async function route() {
  stopPage();
  stopPage = () => {};
  if (REPORT && (location.hash === "" || location.hash === "#/")) { location.hash = REPORT.start; return; }
  navigation();
  const hash = location.hash || "#/";
  for (const [pattern, page] of PAGES) {
    const found = hash.match(pattern);
    if (found) {
      render(h("p", { class: "muted" }, "Loading…"));
      try {
        await page(...found.slice(1));
      } catch (error) {
        render(h("h1", {}, "Something went wrong"), h("p", { class: "error" }, String(error.message || error)));
      }
      return;
    }
  }
  render(h("h1", {}, "No such page"), h("p", {}, link("Start page", "#/")));
}
window.addEventListener("hashchange", route);

// ---------- networks ----------
// A network's first visit makes the server read it and each junction's shapes, each in a
// fresh worker (a second or more apiece, longer on a busy machine; cached after): the page
// says what it waits for and for how long, and draws each junction from its shapes as
// they come (in the browser: no picture rendered on the server), a few at a time.

const TURN_COLOURS = { left: "#c62828", right: "#1a7f37", straight: "#2456a6" };

function waiting(text, why) { // a line that counts the seconds while it is on the page
  const started = performance.now();
  const clock = h("span", { class: "elapsed" });
  const reason = h("span", {});
  const line = h("p", { class: "muted waiting" }, text, " ", clock, reason);
  let shown = false;
  const tick = () => {
    shown = shown || line.isConnected;
    if (shown && !line.isConnected) return;
    const seconds = (performance.now() - started) / 1000;
    clock.textContent = seconds >= 1 ? `${seconds.toFixed(0)} s` : "";
    if (why && seconds >= 2) reason.textContent = ` (${why})`;
    setTimeout(tick, 500);
  };
  tick();
  return line;
}

function limiter(width) { // runs the jobs it is given, `width` at a time, in order
  let running = 0;
  const queue = [];
  const pump = () => {
    while (running < width && queue.length) {
      const [job, done] = queue.shift();
      running += 1;
      job().catch(() => {}).finally(() => { running -= 1; done(); pump(); });
    }
  };
  return (job) => new Promise((done) => { queue.push([job, done]); pump(); });
}
const drawInTurn = limiter(3); // junction drawings: the server's workers are few

async function home() {
  const networks = await get("/networks");
  render(h("h1", {}, "Networks and junctions"),
    h("p", { class: "muted" }, "Bundled and uploaded road networks; each junction with a supported control type can grow test-cases. Connecting lanes: ",
      h("span", { style: `color:${TURN_COLOURS.left}` }, "left"), ", ", h("span", { style: `color:${TURN_COLOURS.right}` }, "right"), ", ",
      h("span", { style: `color:${TURN_COLOURS.straight}` }, "straight"), "; stop lines red where there is a stop sign; dark bars past a stop line: signal heads (a test-case's page shows their colours); zebras: crosswalks, a bar at each curb where they have a walk signal (a network's page lists the walks over them)."));
  const list = h("div", {});
  main.append(list);
  for (const network of networks) {
    const card = h("div", { class: "card" }, h("h2", {}, link(network.id, `#/networks/${encodeURIComponent(network.id)}`),
      " ", h("span", { class: "badge" }, network.bundled ? "bundled" : "uploaded")));
    list.append(card);
    junctionCards(network, card, 4);
  }
}

async function junctionCards(network, card, most, walks = false) { // walks: list each junction's walks under it
  const heading = card.firstChild;
  card.append(waiting(`Reading the junctions of ${network.id}…`, "the first visit reads the network in a worker; later visits answer from the cache"));
  let junctions;
  try {
    junctions = (await get(`/networks/${encodeURIComponent(network.id)}/junctions`)).filter((j) => j.supported);
  } catch (error) {
    card.replaceChildren(heading, h("p", { class: "error" }, `junctions of ${network.id}: ${error.message || error}`));
    return;
  }
  const grid = h("div", { class: "grid" });
  const boxes = [];
  for (const junction of junctions.slice(0, most)) {
    const box = h("div", { class: "thumb", "data-junction": junction.id }, h("p", { class: "muted" }, `junction ${junction.id}: waiting its turn…`));
    grid.append(h("div", {}, box,
      h("div", {}, link(`junction ${junction.id}`, `#/testcases?network=${encodeURIComponent(network.id)}&junction=${encodeURIComponent(junction.id)}`),
        ` · ${junction.control} · ${junction.approaches} approaches · `, h("a", { href: junction.links.plot, target: "_blank" }, "picture"))));
    boxes.push([junction, box]);
  }
  const more = junctions.length > most ? h("p", {}, link(`all ${junctions.length} supported junctions`, `#/networks/${encodeURIComponent(network.id)}`)) : null;
  card.replaceChildren(heading, junctions.length ? grid : h("p", { class: "muted" }, "no junction with a supported control type"));
  if (more) card.append(more);
  await Promise.all(boxes.map(([junction, box]) => drawInTurn(() => drawJunction(network, junction, box, walks)))); // on the page: drawn
}

async function drawJunction(network, junction, box, walks) {
  if (!box.isConnected) return; // the page was left before its turn
  box.replaceChildren(waiting(`drawing junction ${junction.id}…`));
  let geometry;
  try {
    geometry = await get(`/networks/${encodeURIComponent(network.id)}/junctions/${encodeURIComponent(junction.id)}/geometry`);
    box.replaceChildren(junctionDrawing(geometry, junction.id));
  } catch (error) {
    box.replaceChildren(h("p", { class: "error" }, `junction ${junction.id}: ${error.message || error}`));
    return;
  }
  if (walks && (geometry.crossings || []).length && box.isConnected) box.parentNode.append(await walkList(network, junction));
}

// the walks over a junction's crosswalks (a walk: one crossing in one direction, what a
// pedestrian of a test-case does), as `scengen intersection` describes them
async function walkList(network, junction) {
  let description;
  try {
    description = await get(`/networks/${encodeURIComponent(network.id)}/junctions/${encodeURIComponent(junction.id)}`);
  } catch (error) {
    return h("p", { class: "error" }, `walks of junction ${junction.id}: ${error.message || error}`);
  }
  const walks = description.walks || [];
  if (!walks.length) return h("p", { class: "muted" }, "no walks");
  return h("details", { class: "walks", "data-junction": junction.id },
    h("summary", {}, `${walks.length} walks over ${new Set(walks.map((w) => w.crossing)).size} crosswalks`),
    h("ul", { class: "tree" }, walks.map((w) => h("li", { "data-walk": w.id, title: w.conflicts && w.conflicts.length ? `crosses the routes ${w.conflicts.join(", ")}` : null },
      h("strong", {}, w.id), ` · ${w.from} → ${w.to} · ${Number(w.length).toFixed(1)} m`,
      w.conflicts ? ` · ${w.conflicts.length} conflicting routes` : "", w.signal ? ` · signal link ${w.signal.link_index}` : ""))));
}

// ---------- traffic lights ----------
// A test-case's fixed-time program (its `signals` field) shows the colour of a link at time
// t as SignalProgram.colour does (service/core/network/signals.py): the phase at program
// position (t - offset) mod cycle, phases in order, the modulo Python's (never negative).
// The colours are those of the pictures (service/pictures/signals.py, held equal by a test).

const SIGNAL_COLOURS = { G: "#0a7d2c", g: "#7ddc72", y: "#f2a600", Y: "#f2a600", r: "#d42020", u: "#d42020", s: "#d42020", O: "#1fa6b8", o: "#9a6a1c" };
const SIGNAL_WORDS = { G: "protected green", g: "permissive green", y: "yellow", Y: "yellow with priority", r: "red", u: "red-yellow", s: "right on red after a stop", O: "off (priority)", o: "off, blinking (yield)" };
const SIGNAL_ORDER = "GgyYrusOo";
const SIGNAL_UNKNOWN = "#8c8c8c";

function signalColour(program, link, time) {
  const cycle = program.phases.reduce((sum, phase) => sum + phase.duration, 0);
  let position = (time - program.offset) % cycle;
  if (position < 0) position += cycle; // Python's float modulo: the sign of the divisor
  for (const phase of program.phases) {
    if (position < phase.duration) return phase.state[link];
    position -= phase.duration;
  }
  return program.phases[program.phases.length - 1].state[link];
}

function headId(head) { return `${head.fork}-${head.link_index}`; }
function walkHeadId(head) { return `walk-${head.walk}`; }

function junctionDrawing(geometry, id) { // the junction and its approaches, north up: roads, area, crosswalks, connecting lanes by turn, stop lines
  const [ax0, ay0, ax1, ay1] = boundsOf(geometry.area.flat());
  const side = Math.max(ax1 - ax0, ay1 - ay0) * 1.8 + 10; // the approaches in view
  const x0 = (ax0 + ax1 - side) / 2, y1 = (ay0 + ay1 + side) / 2;
  const at = (points) => points.map(([x, y]) => `${(x - x0).toFixed(2)},${(y1 - y).toFixed(2)}`).join(" ");
  const drawing = svg("svg", { viewBox: `0 0 ${side.toFixed(2)} ${side.toFixed(2)}`, class: "junction-drawing", "data-junction": id, role: "img", "aria-label": `junction ${id}` });
  for (const road of geometry.roads) for (const ring of road.polygon) drawing.append(svg("polygon", { points: at(ring), fill: road.sidewalk ? CROSSWALK.pavement : "#dcdee2" }));
  for (const ring of geometry.area) drawing.append(svg("polygon", { points: at(ring), fill: "#c6c9ce" }));
  for (const area of geometry.walking_areas || []) for (const ring of area.polygon) drawing.append(svg("polygon", { points: at(ring), fill: CROSSWALK.pavement, class: "walking-area" }));
  for (const crossing of geometry.crossings || []) { // a zebra: white bars on a dark strip
    const group = svg("g", { class: "crosswalk", "data-crossing": crossing.id }, svg("title", {}, `crosswalk ${crossing.id} over ${(crossing.edges || []).join(", ")}`));
    for (const ring of crossing.polygon) group.append(svg("polygon", { points: at(ring), fill: CROSSWALK.strip }));
    for (const bar of crossing.stripes || []) group.append(svg("polygon", { points: at(bar), fill: CROSSWALK.stripe, class: "stripe" }));
    drawing.append(group);
  }
  for (const path of geometry.paths) {
    drawing.append(svg("polyline", { points: at(path.line), fill: "none", stroke: TURN_COLOURS[path.turn] || "#6b7280", "stroke-width": 1.4, "vector-effect": "non-scaling-stroke", class: "route" },
      svg("title", {}, `${path.route} (${path.turn})`)));
  }
  for (const stop of geometry.stop_lines) {
    const signed = stop.stop_sign || stop.yield_sign;
    drawing.append(svg("polyline", { points: at(stop.line), stroke: stop.stop_sign ? "#b91c1c" : stop.yield_sign ? "#ea580c" : "#6b7280", "stroke-width": signed ? 3 : 1.5, ...(stop.yield_sign ? { "stroke-dasharray": "3 2" } : {}), "vector-effect": "non-scaling-stroke", class: "stop-line" }));
  }
  for (const head of geometry.signal_heads || []) { // where each signal stands; its colours are a test-case's
    drawing.append(svg("polygon", { points: at(head.polygon), fill: "#4b5563", class: "signal-head", "data-head": headId(head) },
      svg("title", {}, `signal of ${head.routes.join(", ")} (link ${head.link_index})`)));
  }
  for (const head of geometry.pedestrian_heads || []) { // a walk signal at each curb of a signalized crosswalk
    drawing.append(svg("polygon", { points: at(head.polygon), fill: "#4b5563", class: "pedestrian-head", "data-head": walkHeadId(head) },
      svg("title", {}, `walk signal of ${head.crossing} where ${head.walk} starts (link ${head.link_index})`)));
  }
  return drawing;
}

async function networkPage(network) {
  const record = await get(`/networks/${network}`);
  render(h("h1", {}, `Network ${record.id}`));
  const card = h("div", { class: "card" }, h("h2", {}, "Junctions"));
  main.append(card);
  await junctionCards(record, card, 1000, true);
}

// ---------- test-cases and their lineage ----------

async function listAll(path) { // every page of a listing, up to 2000 items
  const found = [];
  for (let offset = 0; offset < 2000; offset += 200) {
    const page = await get(`${path}?limit=200&offset=${offset}`);
    found.push(...page.items);
    if (!page.next) break;
  }
  return found;
}

// a test-case as lists, trees and matrices name it: its name (by default network, junction,
// ego route and level), else those parts; its level and duration beside it
function nameOf(t, ego) { return t.name || [t.network, t.junction, ego, `level ${t.level}`].filter(Boolean).join(" "); }
function seconds(duration) { return duration === undefined || duration === null ? "" : `${Number(duration).toFixed(duration % 1 ? 1 : 0)} s`; }

async function testcasesPage(query) {
  const filters = new URLSearchParams(query || "");
  const found = await listAll("/testcases");
  const byId = Object.fromEntries(found.map((t) => [t.id, t]));
  const children = {};
  for (const t of found) if (t.parent && byId[t.parent]) (children[t.parent] = children[t.parent] || []).push(t);
  const roots = found.filter((t) => !t.parent || !byId[t.parent]);
  const egos = {};
  await Promise.all(roots.map(async (root) => {
    const record = await get(`/testcases/${root.id}`);
    const route = record.testcase.ego.route;
    egos[root.id] = `${route.fork}:${route.exit}`;
  }));
  const visit = (t, root) => { egos[t.id] = egos[root.id]; (children[t.id] || []).forEach((c) => visit(c, root)); };
  roots.forEach((r) => visit(r, r));
  // siblings by name, numbers in it counted (variant 2 before variant 10), not newest first
  const byName = (a, b) => nameOf(a, egos[a.id]).localeCompare(nameOf(b, egos[b.id]), undefined, { numeric: true });
  Object.values(children).forEach((list) => list.sort(byName));

  const choices = (key, values) => h("label", {}, key, h("select", { name: key },
    h("option", { value: "" }, "any"), [...new Set(values)].sort().map((v) => h("option", { value: v, selected: filters.get(key) === String(v) ? true : null }, v))));
  const form = h("form", { class: "filters", onsubmit: (event) => {
    event.preventDefault();
    const chosen = new URLSearchParams([...new FormData(form)].filter(([, v]) => v));
    location.hash = `#/testcases?${chosen}`;
  } }, choices("network", found.map((t) => t.network)), choices("junction", found.map((t) => t.junction)),
  choices("ego", Object.values(egos)), choices("level", found.map((t) => String(t.level))), h("button", { type: "submit" }, "Filter"));
  const keep = (t) => (!filters.get("network") || t.network === filters.get("network"))
    && (!filters.get("junction") || t.junction === filters.get("junction"))
    && (!filters.get("ego") || egos[t.id] === filters.get("ego"));
  render(h("h1", {}, "Test-cases"), form);
  if (filters.get("level")) {
    const wanted = Number(filters.get("level"));
    const rows = found.filter((t) => keep(t) && t.level === wanted).sort(byName).map((t) => [link(nameOf(t, egos[t.id]), `#/testcases/${t.id}`),
      String(t.level), seconds(t.duration), t.network, t.junction, egos[t.id], String(t.nonegos), short(t.id)]);
    main.append(h("p", { class: "muted" }, `${rows.length} test-cases at level ${wanted}`),
      h("div", { id: "listing" }, table(["test-case", "level", "duration", "network", "junction", "ego route", "other cars", "id"], rows)));
    return;
  }
  const item = (t) => h("li", { "data-testcase": t.id }, link(nameOf(t, egos[t.id]), `#/testcases/${t.id}`), " ",
    h("span", { class: "badge" }, `level ${t.level}`), " ", h("span", { class: "muted" }, `${seconds(t.duration)} · ${t.nonegos} other cars · ${short(t.id)}`),
    children[t.id] ? h("ul", { class: "tree" }, children[t.id].map(item)) : null);
  const shown = roots.filter(keep);
  // roots on the same route are told apart by their duration and id in the heading
  const heading = (root) => h("strong", { class: "root" }, `${root.network} · junction ${root.junction} · ego ${egos[root.id]}`,
    h("span", { class: "muted" }, ` · ${seconds(root.duration)} · root ${short(root.id)}`));
  main.append(h("p", { class: "muted" }, `${shown.length} ${shown.length === 1 ? "root" : "roots"} (ego-only or uploaded test-cases); their extensions below them, siblings side by side.`),
    shown.length ? h("ul", { class: "tree", id: "lineage" }, shown.map((root) => h("li", {}, heading(root), h("ul", { class: "tree" }, item(root))))) : h("p", {}, "No test-case matches."));
}

// ---------- drawing: junction and cars ----------

class Player {
  // tracks: [{id, label, colour, length, width, samples: [[t, x, y, heading]], highlight, hidden}]
  // options.signals: the test-case's program (its colours drawn at each moment);
  // options.ego: the ego's route id (its signal named beside the clock)
  constructor(geometry, tracks, duration, options = {}) {
    this.geometry = geometry; this.tracks = tracks; this.duration = duration;
    this.signals = options.signals || null; this.heads = geometry.signal_heads || [];
    this.walkHeads = geometry.pedestrian_heads || [];
    const egoHead = this.heads.find((head) => head.routes.includes(options.ego));
    this.egoLink = egoHead ? egoHead.link_index : -1;
    this.time = 0; this.speed = 1; this.playing = false; this.frame = null;
    this.canvas = h("canvas", { width: options.width || 720, height: options.height || 560, id: "animation" });
    this.view();
    this.slider = h("input", { type: "range", min: 0, max: duration, step: 0.05, value: 0, id: "scrub", oninput: () => { this.seek(Number(this.slider.value)); } });
    this.clock = h("span", { id: "clock" }, "0.0 s");
    this.button = h("button", { id: "play", onclick: () => (this.playing ? this.pause() : this.play()) }, "Play");
    const speeds = h("select", { id: "speed", onchange: () => { this.speed = Number(speeds.value); } },
      [0.25, 0.5, 1, 2, 4].map((s) => h("option", { value: s, selected: s === 1 ? true : null }, `${s}×`)));
    this.controls = h("div", { class: "controls" }, this.button, this.slider, this.clock, h("label", {}, "speed ", speeds));
    this.element = h("div", {}, this.canvas, this.controls);
    this.draw();
  }

  view() {
    const [x0, y0, x1, y1] = boundsOf(this.geometry.area.flat());
    const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
    const half = Math.max(x1 - x0, y1 - y0) / 2 + 40;
    const scale = Math.min(this.canvas.width, this.canvas.height) / (2 * half);
    this.toScreen = (x, y) => [this.canvas.width / 2 + (x - cx) * scale, this.canvas.height / 2 - (y - cy) * scale];
    this.scale = scale;
  }

  play() {
    if (this.time >= this.duration) this.time = 0;
    this.playing = true; this.button.textContent = "Pause";
    let last = performance.now();
    const step = (now) => {
      if (!this.playing) return;
      this.seek(Math.min(this.duration, this.time + ((now - last) / 1000) * this.speed));
      last = now;
      if (this.time >= this.duration) { this.pause(); return; }
      this.frame = requestAnimationFrame(step);
    };
    this.frame = requestAnimationFrame(step);
  }

  pause() { this.playing = false; this.button.textContent = "Play"; if (this.frame) cancelAnimationFrame(this.frame); }

  seek(time) {
    this.time = time; this.slider.value = time; this.clock.textContent = `${time.toFixed(1)} s`;
    this.canvas.dataset.time = time.toFixed(2);
    this.draw();
  }

  draw() {
    const c = this.canvas.getContext("2d");
    c.fillStyle = "#fbfbf8"; c.fillRect(0, 0, this.canvas.width, this.canvas.height);
    const polygon = (ring, fill) => {
      c.beginPath();
      ring.forEach(([x, y], i) => { const [sx, sy] = this.toScreen(x, y); if (i) c.lineTo(sx, sy); else c.moveTo(sx, sy); });
      c.closePath(); c.fillStyle = fill; c.fill();
    };
    for (const road of this.geometry.roads) road.polygon.forEach((ring) => polygon(ring, road.sidewalk ? CROSSWALK.pavement : "#d4d6da"));
    this.geometry.area.forEach((ring) => polygon(ring, "#c8cace"));
    for (const area of this.geometry.walking_areas || []) area.polygon.forEach((ring) => polygon(ring, CROSSWALK.pavement));
    for (const crossing of this.geometry.crossings || []) { // a zebra: white bars on a dark strip
      crossing.polygon.forEach((ring) => polygon(ring, CROSSWALK.strip));
      (crossing.stripes || []).forEach((bar) => polygon(bar, CROSSWALK.stripe));
    }
    c.setLineDash([4, 4]); c.strokeStyle = "#ffffff"; c.lineWidth = 1;
    for (const path of this.geometry.paths) {
      c.beginPath();
      path.line.forEach(([x, y], i) => { const [sx, sy] = this.toScreen(x, y); if (i) c.lineTo(sx, sy); else c.moveTo(sx, sy); });
      c.stroke();
    }
    c.setLineDash([]);
    for (const stop of this.geometry.stop_lines) {
      c.beginPath(); c.strokeStyle = stop.stop_sign ? "#b91c1c" : stop.yield_sign ? "#ea580c" : "#6b7280"; c.lineWidth = stop.stop_sign || stop.yield_sign ? 3 : 1.5;
      c.setLineDash(stop.yield_sign ? [4, 3] : []);
      const [a, b] = stop.line.map(([x, y]) => this.toScreen(x, y));
      c.moveTo(...a); c.lineTo(...b); c.stroke();
      c.setLineDash([]);
    }
    this.walkersShown = [];
    for (const track of this.tracks) {
      if (track.hidden) continue;
      const pose = poseAt(track.samples, this.time);
      if (!pose) continue; // not yet, or no more: a pedestrian whose walk has ended is gone
      const [sx, sy] = this.toScreen(pose[0], pose[1]);
      if (track.walker) { this.drawWalker(c, track, sx, sy); continue; }
      const angle = (pose[2] * Math.PI) / 180; // clockwise from north
      c.save(); c.translate(sx, sy); c.rotate(angle);
      const l = track.length * this.scale, w = track.width * this.scale;
      c.globalAlpha = track.ghost ? 0.55 : 1;
      c.fillStyle = track.colour; c.fillRect(-w / 2, -l / 2, w, l);
      c.fillStyle = "#ffffff"; c.fillRect(-w / 2, -l / 2, w, Math.min(l * 0.18, 4));
      if (track.highlight) { c.strokeStyle = "#f59e0b"; c.lineWidth = 3; c.strokeRect(-w / 2 - 3, -l / 2 - 3, w + 6, l + 6); }
      c.restore();
      c.fillStyle = "#111827"; c.font = "12px system-ui, sans-serif";
      c.fillText(track.label, sx + 8, sy - 8 + (track.ghost ? 14 * (track.label.includes("complexity") ? 1 : 0) : 0));
    }
    this.canvas.dataset.walkers = JSON.stringify(this.walkersShown);
    this.drawHeads(c);
    c.fillStyle = "#111827"; c.font = "13px system-ui, sans-serif";
    const egoSignal = this.signals && this.egoLink >= 0 ? ` · ego's signal: ${SIGNAL_WORDS[signalColour(this.signals, this.egoLink, this.time)]}` : "";
    c.fillText(`t = ${this.time.toFixed(1)} s${egoSignal}`, 10, 18);
  }

  // a pedestrian: a disc in her colour (at least 4 px across her shoulders), ringed when
  // new, her id beside it; the canvas's data-walkers lists those drawn: [{id, x, y}]
  drawWalker(c, track, sx, sy) {
    const radius = Math.max(4, (Math.max(track.width, track.length) * this.scale) / 2);
    c.beginPath(); c.arc(sx, sy, radius, 0, 2 * Math.PI);
    c.fillStyle = track.colour; c.fill(); c.strokeStyle = "#ffffff"; c.lineWidth = 1.2; c.stroke();
    if (track.highlight) { c.beginPath(); c.arc(sx, sy, radius + 3, 0, 2 * Math.PI); c.strokeStyle = "#f59e0b"; c.lineWidth = 2; c.stroke(); }
    c.fillStyle = track.colour; c.font = "12px system-ui, sans-serif";
    c.fillText(track.label, sx + radius + 4, sy - radius - 2);
    this.walkersShown.push({ id: track.id, x: Number(sx.toFixed(1)), y: Number(sy.toFixed(1)) });
  }

  // each head in its colour at this moment, over the cars (s: red with a white dot), a
  // crosswalk's walk signal at each of its curbs too; the canvas's data-signals lists them:
  // [{head, colour, x, y}], x and y its centre on the canvas
  drawHeads(c) {
    const shown = [];
    const heads = [...this.heads.map((head) => [headId(head), head]), ...this.walkHeads.map((head) => [walkHeadId(head), head])];
    for (const [id, head] of heads) {
      const colour = this.signals ? signalColour(this.signals, head.link_index, this.time) : null;
      const corners = head.polygon.map(([x, y]) => this.toScreen(x, y));
      c.beginPath();
      corners.forEach(([sx, sy], i) => (i ? c.lineTo(sx, sy) : c.moveTo(sx, sy)));
      c.closePath(); c.fillStyle = SIGNAL_COLOURS[colour] || SIGNAL_UNKNOWN; c.fill();
      c.strokeStyle = "#3c3c3c"; c.lineWidth = 0.6; c.stroke();
      const x = corners.reduce((sum, p) => sum + p[0], 0) / corners.length;
      const y = corners.reduce((sum, p) => sum + p[1], 0) / corners.length;
      if (colour === "s") { c.beginPath(); c.arc(x, y, 2.5, 0, 2 * Math.PI); c.fillStyle = "#ffffff"; c.fill(); }
      shown.push({ head: id, colour, x: Number(x.toFixed(1)), y: Number(y.toFixed(1)) });
    }
    if (shown.length) this.canvas.dataset.signals = JSON.stringify(shown);
  }

  legend() { // the colours this test-case's heads show at some time
    const heads = [...this.heads, ...this.walkHeads];
    if (!this.signals || !heads.length) return null;
    const used = new Set(heads.flatMap((head) => this.signals.phases.map((phase) => phase.state[head.link_index])));
    return h("div", { class: "legend", id: "signal-legend" }, "signals: ", [...SIGNAL_ORDER].filter((c) => used.has(c)).map((c) =>
      h("span", {}, h("span", { class: `swatch${c === "s" ? " dotted" : ""}`, style: `background:${SIGNAL_COLOURS[c]}` }), `${c} ${SIGNAL_WORDS[c]}`)));
  }
}

function boundsOf(points) {
  const xs = points.map((p) => p[0]), ys = points.map((p) => p[1]);
  return [Math.min(...xs), Math.min(...ys), Math.max(...xs), Math.max(...ys)];
}

function poseAt(samples, time) {
  if (!samples.length || time < samples[0][0] - 1e-9 || time > samples[samples.length - 1][0] + 1e-9) return null;
  let lo = 0, hi = samples.length - 1;
  while (hi - lo > 1) { const mid = (lo + hi) >> 1; if (samples[mid][0] <= time) lo = mid; else hi = mid; }
  const a = samples[lo], b = samples[hi];
  const f = b[0] > a[0] ? Math.max(0, Math.min(1, (time - a[0]) / (b[0] - a[0]))) : 0;
  let turn = ((b[3] - a[3] + 540) % 360) - 180;
  return [a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f, a[3] + turn * f];
}

const rows = (samples) => samples.map((s) => [s.t, s.x, s.y, s.heading, s.speed, s.distance]);

// a test-case's level: the extension that added its last road users (0: ego-only)
function levelOf(testcase) {
  return Math.max(0, ...testcase.nonegos.map((car) => car.added_in), ...(testcase.pedestrians || []).map((p) => p.added_in));
}

function tracksOf(testcase) { // the cars, then the pedestrians (walker: drawn as discs, curves dotted)
  const level = levelOf(testcase);
  const tracks = testcase.nonegos.map((car, i) => ({
    id: car.id, label: car.added_in === level && level ? `${car.id} (new)` : car.id,
    colour: CAR_COLOURS[i % CAR_COLOURS.length], length: car.length, width: car.width,
    samples: rows(car.trajectory), highlight: car.added_in === level && level > 0, events: car.events,
  }));
  (testcase.pedestrians || []).forEach((person, i) => tracks.push({
    id: person.id, label: person.added_in === level ? `${person.id} (new)` : person.id, walker: true, walk: person.walk,
    colour: PEDESTRIAN_COLOURS[i % PEDESTRIAN_COLOURS.length], length: person.length, width: person.width,
    samples: rows(person.trajectory), highlight: person.added_in === level, events: person.events,
  }));
  return tracks;
}

function egoTrack(testcase, samples, label, colour, ghost) {
  return { id: label, label, colour, length: testcase.ego.length, width: testcase.ego.width, samples, ghost };
}

// The test ends with the goal (README, `scengen check`): an ego is drawn until its goal and
// is gone after it, as the replay's ego leaves the simulation there. An evaluation's verdict
// says when (`untilTime`); a certificate reaches it when its footprint has left the junction's
// area for good (`untilOut`): both keep the samples up to the first at or after it.
function untilTime(samples, time) {
  if (time === null || time === undefined) return samples;
  const last = samples.findIndex((s) => s[0] >= time - 1e-9);
  return last < 0 ? samples : samples.slice(0, last + 1);
}

function untilOut(samples, area, length, width) {
  let inside = -1;
  samples.forEach((s, k) => { if (area.some((ring) => overlaps(footprint(s, length, width), ring))) inside = k; });
  return inside >= 0 && inside + 1 < samples.length ? samples.slice(0, inside + 2) : samples;
}

function footprint(sample, length, width) { // a car's corners: centre, heading clockwise from north
  const a = (sample[3] * Math.PI) / 180, f = [Math.sin(a) * length / 2, Math.cos(a) * length / 2];
  const r = [Math.cos(a) * width / 2, -Math.sin(a) * width / 2];
  return [[1, 1], [1, -1], [-1, -1], [-1, 1]].map(([i, j]) => [sample[1] + i * f[0] + j * r[0], sample[2] + i * f[1] + j * r[1]]);
}

function overlaps(corners, ring) { // a convex quadrilateral and a simple polygon share area
  const inside = (point, polygon) => { // the crossing number
    let odd = false;
    for (let k = 0, j = polygon.length - 1; k < polygon.length; j = k++) {
      const [xk, yk] = polygon[k], [xj, yj] = polygon[j];
      if ((yk > point[1]) !== (yj > point[1]) && point[0] < ((xj - xk) * (point[1] - yk)) / (yj - yk) + xk) odd = !odd;
    }
    return odd;
  };
  const side = (a, b, c) => (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
  const crossing = (a, b, c, d) => side(a, b, c) * side(a, b, d) < 0 && side(c, d, a) * side(c, d, b) < 0;
  if (corners.some((corner) => inside(corner, ring)) || ring.some((point) => inside(point, corners))) return true;
  return corners.some((a, k) => ring.some((c, j) => crossing(a, corners[(k + 1) % 4], c, ring[(j + 1) % ring.length])));
}

// The time-distance panel: every shown track's distance over time, metres on the y axis,
// seconds on the x axis, each curve named in a gutter right of the plot (at its end's
// height, moved apart so that no two names overlap, a thin line back to its curve when
// moved), so that no name is cut off at the panel's edge.
const TD_FONT = 10, TD_CHAR = 6.2, TD_LINE = 13; // px: the names' font, a character's width (at most), a row

function niceStep(span, ticks) { // 1, 2, 2.5 or 5 times a power of ten: about `ticks` steps over span
  const raw = span / Math.max(1, ticks), power = 10 ** Math.floor(Math.log10(raw));
  return power * [1, 2, 2.5, 5, 10].find((f) => f * power >= raw - 1e-9);
}

function spreadLabels(wanted, top, bottom, gap) { // heights in order kept at least `gap` apart, within [top, bottom]
  const order = wanted.map((y, i) => [y, i]).sort((a, b) => a[0] - b[0] || a[1] - b[1]);
  const placed = order.map(([y]) => Math.min(Math.max(y, top), bottom));
  for (let k = 1; k < placed.length; k++) placed[k] = Math.max(placed[k], placed[k - 1] + gap);
  if (placed.length) placed[placed.length - 1] = Math.min(placed[placed.length - 1], bottom);
  for (let k = placed.length - 2; k >= 0; k--) placed[k] = Math.min(placed[k], placed[k + 1] - gap);
  const result = [];
  order.forEach(([, i], k) => { result[i] = placed[k]; });
  return result;
}

const curveName = (track) => (track.walker ? `${track.id} (pedestrian)` : track.id);

function timeDistance(tracks, duration) { // a pedestrian's curve dotted, named as hers
  const shown = tracks.filter((t) => !t.hidden && t.samples.length);
  const longest = Math.max(4, ...shown.map((t) => curveName(t).length));
  const width = 560, height = 300, left = 56, bottom = 34, top = 12;
  const right = Math.min(220, 14 + Math.ceil(longest * TD_CHAR)); // the names' gutter
  const most = Math.max(1, ...shown.flatMap((t) => t.samples.map((s) => s[5] || 0)));
  const step = niceStep(most, 6), high = Math.max(step, Math.ceil(most / step - 1e-9) * step);
  const plotRight = width - right, plotBottom = height - bottom;
  const x = (t) => left + (t / duration) * (plotRight - left);
  const y = (d) => plotBottom - (d / high) * (plotBottom - top);
  const plot = svg("svg", { width, height, id: "time-distance", viewBox: `0 0 ${width} ${height}` });
  for (let d = 0; d <= high + 1e-9; d += step) {
    plot.append(svg("line", { x1: left, y1: y(d), x2: plotRight, y2: y(d), stroke: "#eceef2" }),
      svg("text", { x: left - 6, y: y(d) + 3.5, "font-size": TD_FONT, "text-anchor": "end", class: "y-tick" }, String(Math.round(d * 100) / 100)));
  }
  const every = niceStep(duration, 9);
  for (let t = 0; t <= duration + 1e-9; t += every) {
    plot.append(svg("text", { x: x(t), y: plotBottom + 14, "font-size": TD_FONT, "text-anchor": "middle", class: "x-tick" }, String(Math.round(t * 100) / 100)));
  }
  plot.append(svg("line", { x1: left, y1: plotBottom, x2: plotRight, y2: plotBottom, stroke: "#6b7280" }),
    svg("line", { x1: left, y1: top, x2: left, y2: plotBottom, stroke: "#6b7280" }),
    svg("text", { x: (left + plotRight) / 2, y: height - 4, "font-size": 12, "text-anchor": "middle" }, "time (s)"),
    svg("text", { x: 14, y: (top + plotBottom) / 2, "font-size": 12, transform: `rotate(-90 14 ${(top + plotBottom) / 2})`, "text-anchor": "middle" }, shown.some((t) => t.walker) ? "distance driven or walked (m)" : "distance driven (m)"));
  const ends = shown.map((track) => track.samples[track.samples.length - 1]);
  const heights = spreadLabels(ends.map((end) => y(end[5] || 0) + 3.5), top + 8, plotBottom, TD_LINE);
  shown.forEach((track, i) => {
    const points = track.samples.map((s) => `${x(s[0]).toFixed(1)},${y(s[5] || 0).toFixed(1)}`).join(" ");
    const dashes = track.walker ? "0.1 4" : track.ghost ? "5 3" : "none";
    plot.append(svg("polyline", { points, fill: "none", stroke: track.colour, "stroke-width": track.highlight ? 3 : track.walker ? 2.4 : 1.6, "stroke-dasharray": dashes,
      "stroke-linecap": track.walker ? "round" : "butt", "data-track": track.id, class: track.walker ? "walker-curve" : "curve" }));
    const [endX, endY] = [x(ends[i][0]), y(ends[i][5] || 0)];
    plot.append(svg("line", { x1: endX + 2, y1: endY, x2: plotRight + 6, y2: heights[i] - 3.5, stroke: track.colour, "stroke-width": 0.6, "stroke-opacity": 0.7 }),
      svg("text", { x: plotRight + 8, y: heights[i], "font-size": TD_FONT, fill: track.colour, class: "curve-name" }, curveName(track)));
  });
  return plot;
}

function eventsTable(testcase) { // a pedestrian's lane: her crossing, or a lane she walks over
  const found = [];
  const people = testcase.pedestrians || [];
  for (const user of [...testcase.nonegos, ...people]) for (const e of user.events) found.push([e.t, user.id, e.kind, e.lane]);
  found.sort((a, b) => a[0] - b[0]);
  return table(["t (s)", people.length ? "road user" : "car", "event", "lane"], found.map(([t, car, kind, lane]) => [t.toFixed(2), car, kind, lane]));
}

// each pedestrian: her walk (a crosswalk in one direction), the level that added her, and
// when she was on the crosswalk (her events), in her colour
function pedestriansTable(testcase, tracks) {
  const people = testcase.pedestrians || [];
  if (!people.length) return null;
  const colours = Object.fromEntries(tracks.map((t) => [t.id, t.colour]));
  const when = (person, kind) => { const e = person.events.find((event) => event.kind === kind); return e ? `${e.t.toFixed(1)} s` : "—"; };
  return [h("h2", {}, "Pedestrians"), Object.assign(table(["pedestrian", "walk", "added at level", "at the curb", "onto the crosswalk", "off it", "walked"],
    people.map((p) => [h("span", {}, h("span", { class: "swatch round", style: `background:${colours[p.id]}` }), p.id), p.walk, String(p.added_in),
      when(p, "arrived"), when(p, "entered"), when(p, "exited"), `${p.trajectory[p.trajectory.length - 1].distance.toFixed(1)} m in ${p.trajectory[p.trajectory.length - 1].t.toFixed(1)} s`])),
  { id: "pedestrians" })];
}

function provenanceOf(testcase) {
  const p = testcase.provenance;
  if (!p) return h("p", { class: "muted" }, "An ego-only or uploaded test-case: no provenance.");
  const violates = (p.complexity_certificate_violates || []).map((v) => `${v.rule} against ${v.car}`);
  const rear = (p.complexity_certificate || {}).rear_end || [];
  return table(["", ""], [
    ["level", String(p.level)], ["new cars", (p.new_nonegos || []).join(", ")],
    ["the complexity certificate breaks", [...violates, ...rear.map((car) => `runs into ${car} (rear-end)`)].join("; ") || "—"],
    ["seed", String(p.seed)], ["answer sets tried", String(p.answer_sets_tried)],
    ["order of events", h("pre", {}, Array.isArray(p.order) ? p.order.join("\n") : JSON.stringify(p.order, null, 1))],
  ]);
}

async function geometryOf(testcase) { // the network the test-case runs on: with its guessed crosswalks if it has them
  const guessed = testcase.crossings_guessed ? "&guess_crossings=true" : "";
  return get(`/networks/${encodeURIComponent(testcase.network.ref)}/junctions/${encodeURIComponent(testcase.junction)}/geometry?control=${testcase.control}${guessed}`);
}

// ---------- a test-case ----------

async function testcasePage(id) {
  const record = await get(`/testcases/${id}`);
  const testcase = record.testcase;
  const geometry = await geometryOf(testcase);
  const tracks = tracksOf(testcase);
  const certificates = [];
  if (testcase.certificates) {
    const untilGoal = (kind) => untilOut(rows(testcase.certificates[kind]), geometry.area, testcase.ego.length, testcase.ego.width);
    certificates.push(egoTrack(testcase, untilGoal("solvability"), "ego (solvability)", "#111827", true));
    certificates.push(egoTrack(testcase, untilGoal("complexity"), "ego (complexity)", "#dc2626", true));
  }
  const player = new Player(geometry, [...tracks, ...certificates], testcase.duration, playerOptions(testcase));
  stopPage = () => player.pause();
  const toggle = h("label", {}, h("input", { type: "checkbox", id: "certificates", checked: certificates.length ? true : null, disabled: certificates.length ? null : true,
    onchange: (event) => { certificates.forEach((t) => { t.hidden = !event.target.checked; }); player.draw(); distance.replaceChildren(timeDistance(player.tracks, testcase.duration)); } }),
  " certificates (the ego's two proofs)");
  player.controls.append(toggle);
  const distance = h("div", {}, timeDistance(player.tracks, testcase.duration));
  const ego = testcase.ego.route;
  const evaluations = await get(`/evaluations?testcase=${id}&limit=200`).catch(() => ({ items: [] }));
  const downloads = REPORT
    ? [download(JSON.stringify(testcase, null, 1), `${(testcase.name || id).replace(/[:/\\]/g, "-")}.json`), h("span", { class: "muted" }, " (SUMO bundle and OpenSCENARIO: from the server, or `scengen export`)")]
    : [h("a", { href: record.links.document }, "test-case JSON"), " · ", h("a", { href: record.links.bundle }, "SUMO bundle (zip)"), " · ",
      h("a", { href: record.links.openscenario }, "OpenSCENARIO (zip)"), " · ", h("a", { href: `${record.links.openscenario}?flavour=carla` }, "OpenSCENARIO for CARLA")];
  render(
    h("h1", {}, titleOf(testcase, id)),
    h("p", { class: "muted" }, `${testcase.network.ref} · junction ${testcase.junction} (${testcase.control}) · ego ${ego.fork}:${ego.exit} · ${testcase.nonegos.length} other cars`
      + `${(testcase.pedestrians || []).length ? ` · ${testcase.pedestrians.length} pedestrian${testcase.pedestrians.length === 1 ? "" : "s"}` : ""} · id ${id}`,
      record.parent ? [" · parent ", link(short(record.parent), `#/testcases/${record.parent}`)] : null),
    h("div", { class: "row" }, h("div", { class: "card" }, player.element,
      h("div", { class: "legend" }, player.tracks.map((t) => h("span", {}, h("span", { class: t.walker ? "swatch round" : "swatch", style: `background:${t.colour}` }), t.walker ? `${t.id} (pedestrian${t.highlight ? ", new" : ""})` : t.label)),
        player.walkHeads.length ? h("span", { class: "muted" }, "walk signals: a bar at each curb of a crosswalk") : null),
      player.legend(),
    ), h("div", {},
      h("div", { class: "card" }, h("h2", {}, "Time and distance"), distance),
      h("div", { class: "card" }, h("h2", {}, "Downloads"), h("p", {}, downloads)))),
    pedestriansTable(testcase, player.tracks),
    h("h2", {}, "Provenance"), provenanceOf(testcase),
    h("h2", {}, "Evaluations"), evaluations.items.length
      ? table(["controller", "verdict", "replay"], evaluations.items.map((e) => [e.controller, verdictCell(e.verdict), link("replay", `#/replay/${e.id}`)]))
      : h("p", { class: "muted" }, "none yet"),
    h("details", {}, h("summary", {}, h("strong", {}, "Events"), ` (${[...testcase.nonegos, ...(testcase.pedestrians || [])].reduce((n, user) => n + user.events.length, 0)}: each ${(testcase.pedestrians || []).length ? "road user" : "car"}'s arrivals, stops and lane entries and exits)`), eventsTable(testcase)),
    REPORT ? null : h("p", {}, link("lineage: every test-case of this tree", `#/testcases?network=${encodeURIComponent(testcase.network.ref)}&junction=${encodeURIComponent(testcase.junction)}`)),
  );
  player.seek(0);
}

function playerOptions(testcase) {
  return { signals: testcase.signals || null, ego: `${testcase.ego.route.fork}:${testcase.ego.route.exit}` };
}

function titleOf(testcase, id) {
  if (testcase.name) return testcase.name;
  const level = levelOf(testcase);
  return `level ${level} · ego ${testcase.ego.route.fork}:${testcase.ego.route.exit} · ${short(id)}`;
}

function verdictCell(verdict) {
  if (verdict.passed) return h("span", { class: "pass", title: (verdict.information || []).join("\n") || null }, "pass");
  return h("span", { class: "fail", title: verdict.reasons.join("\n") }, `FAIL: ${failureText({ verdict })}`);
}

// a failed evaluation's cell: every reason its verdict gives, as its JUnit does (rules with
// their laws, collisions and goal misses with their times); older records without reasons:
// the rules, else the kind of failure
function failureText(e) {
  const reasons = e.reasons || (e.verdict && e.verdict.reasons) || [];
  if (reasons.length) return reasons.join("; ");
  if (e.rules && e.rules.length) return e.rules.join(", ");
  return e.verdict ? failureOf(e.verdict) : "failed";
}

function failureOf(verdict) {
  const rules = [...new Set(verdict.violations.map((v) => v.rule))];
  if (rules.length) return rules.join(", ");
  if (verdict.collisions.length) return "collision";
  if (verdict.errors && verdict.errors.length) return "error";
  if (!verdict.goal.reached) return "goal missed";
  return "failed";
}

// ---------- a controller's drive ----------

async function replayPage(id) {
  const evaluation = await get(`/evaluations/${id}`);
  const record = await get(`/testcases/${evaluation.testcase}`);
  const testcase = record.testcase;
  const [geometry, drive] = await Promise.all([geometryOf(testcase), get(`/evaluations/${id}/drive`)]);
  const verdict = evaluation.verdict;
  // until its goal: a drive stored before the replay ended there goes on after it
  const samples = untilTime(drive.trajectory.map((r) => [r[0], r[1], r[2], r[3], r[4], r[5]]), verdict.goal.reached ? verdict.goal.time : null);
  const tracks = [...tracksOf(testcase), egoTrack(testcase, samples, `ego (${evaluation.controller})`, "#111827", false)];
  const player = new Player(geometry, tracks, testcase.duration, playerOptions(testcase));
  stopPage = () => player.pause();
  const information = verdict.information || [];
  render(
    h("h1", {}, `${evaluation.controller} on ${titleOf(testcase, evaluation.testcase)}`),
    h("p", { id: "verdict" }, verdictCell(verdict), " · test-case ", link(testcase.name || short(evaluation.testcase), `#/testcases/${evaluation.testcase}`)),
    verdict.reasons.length ? h("ul", {}, verdict.reasons.map((r) => h("li", {}, r))) : h("p", { class: "muted" }, "The ego reached its exit without collision, obeying every rule."),
    information.length ? h("div", { id: "after-goal" }, h("p", { class: "muted" }, `The test ended with the ego's goal at ${verdict.goal.time.toFixed(2)} s; after it, not judged:`),
      h("ul", { class: "muted" }, information.map((line) => h("li", {}, line.replace(/^after its goal \(not judged\): /, ""))))) : null,
    samples.length ? null : h("p", { class: "muted" }, "This evaluation was stored before drives were kept: the ego is not shown."),
    h("div", { class: "row" }, h("div", { class: "card" }, player.element, player.legend()), h("div", { class: "card" }, h("h2", {}, "Time and distance"), timeDistance(tracks, testcase.duration))),
    criticalityTable(verdict.criticality),
    verdict.guard ? guardCard(verdict.guard) : null,
  );
  player.seek(0);
}

// a guarded controller's record (docs/controllers.md): how often the RSS guard cut the
// controller's acceleration, for which car, and each span of steps it did
function guardCard(guard) {
  const byCar = Object.entries(guard.by_car).map(([car, n]) => `${car} ${n}`).join(", ") || "none";
  const spans = (guard.spans || []).map((s) => [`${s.from.toFixed(2)}–${s.to.toFixed(2)} s`, s.car, s.scene, s.kind]);
  return h("div", { id: "guard", class: "card" }, h("h2", {}, "RSS guard"),
    h("p", {}, `Intervened at ${guard.interventions} of ${guard.steps} steps (${guard.braking} braking); by car: ${byCar}.`,
      guard.first ? ` First at ${guard.first.t.toFixed(2)} s: ${guard.first.why}.` : ""),
    guard.fallback ? h("p", { class: "fail" }, `ad-rss was not used: ${guard.fallback}; the time-gap rule guarded instead.`) : null,
    spans.length ? h("details", {}, h("summary", {}, `${spans.length} spans of steps`), table(["when", "car", "scene", "restriction"], spans)) : null);
}

// how close the ego came to a crash (README, Criticality): overall, then against each car
// and each pedestrian
function criticalityTable(criticality) {
  if (!criticality) return h("p", { id: "criticality", class: "muted" }, "This verdict has no criticality measures (stored before they were measured).");
  const at = (m, unit) => (m ? `${m.value.toFixed(2)} ${unit} at ${m.t.toFixed(2)} s` : "-");
  const measures = [["ttc", "s"], ["pet", "s"], ["drac", "m/s²"], ["distance", "m"]];
  const overall = ["overall", ...measures.map(([key, unit]) => {
    const found = criticality.overall[key];
    return found ? `${at(found, unit)}, ${found.car}${found.area ? ` (${found.area})` : ""}` : "-";
  })];
  const cars = Object.entries(criticality.others).map(([car, m]) => [car, at(m.ttc, "s"),
    m.pet.length ? m.pet.map((p) => `${at(p, "s")} (${p.area})`).join("; ") : "-", at(m.drac, "m/s²"), at(m.distance, "m")]);
  return h("div", { id: "criticality", class: "card" }, h("h2", {}, "Criticality"),
    h("p", { class: "muted" }, "Smallest time-to-collision, post-encroachment time at each conflict area, largest deceleration to avoid a crash, smallest distance."),
    table(["against", "TTC", "PET", "DRAC", "distance"], [overall, ...cars]));
}

// ---------- evaluations matrix ----------

async function evaluationsPage() {
  const found = await listAll("/evaluations");
  const controllers = [...new Set(found.map((e) => e.controller))].sort();
  const testcases = [...new Set(found.map((e) => e.testcase))];
  const cell = {};
  for (const e of found) { const key = `${e.testcase}|${e.controller}`; if (!(key in cell)) cell[key] = e; } // newest first
  const summaries = Object.fromEntries((await listAll("/testcases")).map((t) => [t.id, t]));
  await Promise.all(testcases.filter((t) => !summaries[t]).slice(0, 300).map(async (t) => {
    try { summaries[t] = await get(`/testcases/${t}`); } catch (e) { /* deleted since */ }
  }));
  const rows = testcases.map((t) => (summaries[t] ? { id: t, name: nameOf(summaries[t]), level: summaries[t].level, duration: summaries[t].duration } : { id: t, name: t }));
  render(h("h1", {}, "Evaluations"), h("p", { class: "muted" }, "Test-cases by controllers: pass, or the rule that failed; each cell opens that drive."),
    found.length ? h("div", { id: "evaluation-matrix" }, matrix(rows, controllers, (t, c) => cell[`${t.id}|${c}`])) : h("p", {}, "No evaluation yet."));
}

// rows: [{id, name, level, duration}], lookup(row, controller): its evaluation; a row per
// test-case, its name (the id beside it), level and duration first
function matrix(testcases, controllers, lookup) {
  return table(["test-case", "level", "duration", ...controllers], testcases.map((t) => h("tr", { "data-testcase": t.id },
    h("td", {}, link(t.name, `#/testcases/${t.id}`), h("span", { class: "muted" }, ` ${short(t.id)}`)),
    h("td", {}, t.level === undefined ? "" : String(t.level)), h("td", {}, seconds(t.duration)),
    controllers.map((c) => {
      const e = lookup(t, c);
      if (!e) return h("td", { class: "muted" }, "—");
      const passed = e.passed;
      const text = passed ? "pass" : failureText(e);
      return h("td", { class: `cell ${passed ? "pass" : "fail"}` }, h("a", { href: `#/replay/${e.evaluation || e.id}`, "data-evaluation": e.evaluation || e.id, "data-testcase": t.id, "data-controller": c }, text));
    }))));
}

// ---------- jobs and campaigns ----------

async function jobsPage() {
  const jobs = await get("/jobs?limit=100");
  render(h("h1", {}, "Jobs and campaigns"),
    jobs.items.length ? table(["job", "name", "items", "state", "done", "evaluations", "created"], jobs.items.map((j) => [
      link(short(j.id), `#/jobs/${j.id}`), j.name || "", j.items.map((i) => i.kind).join(", "), h("span", { class: `state-${j.state}` }, j.state),
      `${j.done}/${j.total}`, `${j.evaluations.passed} passed, ${j.evaluations.failed} failed`, new Date(j.created_at).toLocaleString()]))
      : h("p", {}, "No job yet: POST /jobs, `scengen submit`, or `scengen campaign`."));
}

async function jobPage(id) {
  let timer = null;
  stopPage = () => clearTimeout(timer);
  const show = async () => {
    const job = await get(`/jobs/${id}`);
    const hasCampaign = job.items.some((i) => i.kind === "campaign");
    const campaign = hasCampaign ? await get(`/jobs/${id}/campaign`).catch(() => null) : null;
    const content = [
      h("h1", {}, campaign ? `Campaign: ${campaign.plan.network} · junction ${campaign.plan.junction}` : `Job ${job.name || short(id)}`),
      h("p", { id: "job-state" }, "job ", h("span", { class: `state-${job.state}` }, job.state), ` · ${job.done}/${job.total} items ran`,
        campaign ? ` · the controllers' verdicts below (a job that ran succeeds whatever they are)` : null),
      table(["item", "kind", "state", "progress", "error"], job.items.map((i) => [String(i.position), i.kind, h("span", { class: `state-${i.state}` }, i.state), i.progress, i.error ? h("span", { class: "error" }, i.error) : ""])),
    ];
    if (!REPORT) content.push(h("p", {}, h("a", { href: `/jobs/${id}/junit` }, "JUnit"), " · ", h("a", { href: `/jobs/${id}/bundles` }, "SUMO bundles"),
      campaign ? [" · ", h("a", { href: `/jobs/${id}/campaign` }, "campaign JSON"), " · ", h("a", { href: `/jobs/${id}/campaign/junit` }, "campaign JUnit"), " · ", h("a", { href: `/jobs/${id}/campaign/report` }, "self-contained report")] : null));
    if (campaign) content.push(...campaignView(campaign));
    else if (hasCampaign) content.push(h("p", { class: "muted" }, "The campaign has not finished a level yet."));
    render(...content);
    if (!REPORT && (job.state === "queued" || job.state === "running")) timer = setTimeout(() => show().catch(() => {}), 2000);
  };
  await show();
}

function campaignView(outcome) {
  const plan = outcome.plan;
  const controllers = plan.controllers;
  controllers.forEach((c) => colourOf(c, controllers));
  const levelRows = outcome.levels.map((level) => [String(level.level), testcasesOf(level),
    ...controllers.map((c) => { const s = level.controllers[c]; const rules = Object.entries(s.rules).map(([r, n]) => `${r} ${n}`).join(", ");
      return h("td", { class: s.failed ? "fail" : "pass" }, shareText(s), rules ? h("div", { class: "muted" }, rules) : null,
        s.collisions ? h("div", { class: "muted" }, `${s.collisions} collision${s.collisions === 1 ? "" : "s"}`) : null, s.goal_misses ? h("div", { class: "muted" }, `${s.goal_misses} goal miss${s.goal_misses === 1 ? "" : "es"}`) : null); })]);
  const chainRows = outcome.chains.map((c) => [c.ego, String(c.chain + 1), String(c.reached), ...controllers.map((k) => (c.first_failure[k] === null ? "—" : `level ${c.first_failure[k]}`)),
    c.end ? h("span", { title: c.end }, c.end.length > 140 ? `${c.end.slice(0, 140)}…` : c.end) : `reached depth ${plan.depth}`]);
  const cases = [];
  for (const chain of outcome.chains) {
    const stem = chain.name || `${chain.ego} chain ${chain.chain + 1}`;
    for (const level of chain.levels) cases.push({ id: level.testcase, name: `${stem} level ${level.level}`, level: level.level, duration: level.duration, record: level });
  }
  return [
    h("p", { class: "muted" }, `ego routes ${plan.egos.join(", ")} · depth ${plan.depth} · ${plan.chains} chains each · seed ${plan.seed} · ${outcome.finished ? "finished" : "in progress"}`),
    h("h2", {}, "Share of test-cases each controller fails, by level"),
    h("p", { class: "muted" }, "Over the level's distinct test-cases (chains that repeat another's test-case count once), with the Wilson score 95% interval of each share (in brackets; bars in the plot)."),
    h("div", { class: "card" }, failurePlot(outcome)),
    Object.assign(table(["level", "test-cases", ...controllers], levelRows), { id: "failure-shares" }),
    h("h2", {}, "Diversity by level"),
    diversityView(outcome),
    h("h2", {}, "Criticality by level"),
    criticalityView(outcome),
    h("h2", {}, "Rule coverage"),
    h("p", { class: "muted" }, "A rule is covered when some level's complexity certificate breaks it: the suite then tests a controller on that rule."),
    table(["rule", "CVC", "covered by"], outcome.coverage.map((r) => [r.rule, r.law, r.covered ? h("span", {}, r.testcases.map((t, i) => [i ? ", " : "", link(short(t), `#/testcases/${t}`)])) : r.coverable !== false ? h("span", { class: "fail" }, "not covered") : h("span", { class: "muted" }, "the ego's own rule: no new car makes it harder")])),
    h("h2", {}, "Chains: the first level each controller fails"),
    table(["ego route", "chain", "levels", ...controllers, "ended"], chainRows),
    h("h2", {}, "Verdicts"),
    h("p", { class: "muted" }, "Every level of every chain by controller; a cell opens the replay of that drive with its verdict."),
    h("div", { id: "verdict-matrix" }, matrix(cases, controllers, (t, c) => t.record.verdicts[c])),
  ];
}

const LINE_DASHES = ["", "7 3", "2 3", "9 3 2 3"]; // the failure plot's lines, by controller

function failurePlot(outcome) {
  const controllers = outcome.plan.controllers;
  const width = 640, height = 320, left = 50, bottom = 36, right = 170;
  const levels = outcome.levels.map((l) => l.level);
  const most = Math.max(1, ...levels);
  const x = (l) => left + (l / most) * (width - left - right);
  const y = (s) => height - bottom - s * (height - bottom - 14);
  const plot = svg("svg", { width, height, viewBox: `0 0 ${width} ${height}`, id: "failure-plot" });
  for (const s of [0, 0.25, 0.5, 0.75, 1]) {
    plot.append(svg("line", { x1: left, y1: y(s), x2: width - right, y2: y(s), stroke: "#e5e7eb" }),
      svg("text", { x: left - 6, y: y(s) + 4, "font-size": 11, "text-anchor": "end" }, `${Math.round(s * 100)}%`));
  }
  for (const l of levels) plot.append(svg("text", { x: x(l), y: height - bottom + 16, "font-size": 11, "text-anchor": "middle" }, String(l)));
  plot.append(svg("text", { x: (left + width - right) / 2, y: height - 4, "font-size": 12, "text-anchor": "middle" }, "level (cars added)"),
    svg("text", { x: 12, y: (height - bottom) / 2, "font-size": 12, "text-anchor": "middle", transform: `rotate(-90 12 ${(height - bottom) / 2})` }, "test-cases failed"));
  controllers.forEach((c, i) => {
    const colour = colourOf(c, controllers);
    // each controller's line a few pixels beside the others' and dashed its own way, so
    // that lines of equal shares stay visible, each as the legend shows it
    const shift = (i - (controllers.length - 1) / 2) * 4;
    const dashes = LINE_DASHES[i % LINE_DASHES.length];
    const points = outcome.levels.map((l) => [x(l.level) + shift, y(l.controllers[c].share || 0)]);
    plot.append(svg("polyline", { points: points.map((p) => p.join(",")).join(" "), fill: "none", stroke: colour, "stroke-width": 2.2, class: "failure-line", "data-controller": c, ...(dashes ? { "stroke-dasharray": dashes } : {}) }));
    points.forEach(([px, py]) => plot.append(svg("circle", { cx: px, cy: py, r: 3.5, fill: colour })));
    outcome.levels.forEach((l) => { // the share's interval, a bar beside its point
      const interval = l.controllers[c].interval;
      if (!interval) return;
      const bx = x(l.level) + shift;
      plot.append(svg("line", { x1: bx, y1: y(interval.lower), x2: bx, y2: y(interval.upper), stroke: colour, "stroke-width": 1.2, opacity: 0.6, class: "interval", "data-controller": c, "data-level": l.level },
        svg("title", {}, `${c}, level ${l.level}: ${shareText(l.controllers[c])}`)));
    });
    plot.append(svg("line", { x1: width - right + 10, y1: 26 + i * 20, x2: width - right + 28, y2: 26 + i * 20, stroke: colour, "stroke-width": 2.2, ...(dashes ? { "stroke-dasharray": dashes } : {}) }),
      svg("text", { x: width - right + 32, y: 30 + i * 20, "font-size": 12 }, c));
  });
  return plot;
}

// a failure share with its Wilson interval, "1/9 11% (2–44%)" (a campaign stored before
// shares had one: "1/9")
function shareText(share) {
  const counted = `${share.failed}/${share.evaluated}`;
  if (!share.interval) return counted;
  const percent = (v) => Math.round(v * 100);
  return `${counted} ${percent(share.share)}% (${percent(share.interval.lower)}–${percent(share.interval.upper)}%)`;
}

// the level's distinct test-cases, and how many were grown when that is more
function testcasesOf(level) {
  return level.grown !== undefined && level.grown !== level.testcases ? `${level.testcases} (of ${level.grown} grown)` : String(level.testcases);
}

// per level: distinct test-cases, orders of events, routes, rules broken and the spread of
// the new cars' arrival and entry times
function diversityView(outcome) {
  if (outcome.levels.some((l) => !l.diversity)) return h("p", { class: "muted", id: "diversity-none" }, "This campaign was stored before levels kept their diversity.");
  const spread = (s) => (s ? `${round3(s.median)} (${round3(s.min)}–${round3(s.max)})` : "—");
  const rows = outcome.levels.map((l) => [String(l.level), testcasesOf(l), String(l.diversity.orders), String(l.diversity.routes),
    l.diversity.rules.length ? `${l.diversity.rules.length}: ${l.diversity.rules.join(", ")}` : "0", spread(l.diversity.arrival), spread(l.diversity.entry)]);
  return h("div", { id: "diversity" },
    h("p", { class: "muted" }, "How much of the space each level's distinct test-cases cover: the orders of events among their cars (and which new cars stop), the combinations of routes their new cars take, the rules their complexity certificates break, and when the new cars arrive at their stop line and enter the junction (median, min–max, seconds)."),
    table(["level", "test-cases", "orders of events", "routes", "rules broken", "arrival (s)", "entry (s)"], rows));
}

// ---------- criticality by level ----------

const MEASURES = [["ttc", "TTC", "s"], ["pet", "PET", "s"], ["drac", "DRAC", "m/s²"], ["distance", "distance", "m"]];
function criticalityOf(level, controller) { return (level.controllers[controller] || {}).criticality || null; }
function round3(value) { return String(Math.round(value * 1000) / 1000); }

// per controller: its failure rate by level, whether criticality grows, and a box and strip
// plot of each measure by level (box: quartiles, line: median, whiskers: min and max, dots:
// every test-case's value)
function criticalityView(outcome) {
  const controllers = outcome.plan.controllers;
  const measured = outcome.levels.some((l) => controllers.some((c) => (criticalityOf(l, c) || {}).measured));
  if (!measured) return h("p", { class: "muted", id: "criticality-none" }, "Criticality was not measured: this campaign's verdicts carry none.");
  const trends = outcome.criticality_trend || {};
  return h("div", { id: "criticality" },
    h("p", { class: "muted" }, "How close each run came, over the level's test-cases: the smallest time-to-collision (TTC), post-encroachment time (PET) and distance to any car or pedestrian, and the largest deceleration needed to avoid a crash (DRAC). Criticality grows when TTC, PET and distance fall and DRAC rises from level to level."),
    controllers.map((c) => h("div", { class: "card criticality-card", "data-controller": c },
      h("h3", {}, h("span", { class: "swatch", style: `background:${colourOf(c, controllers)}` }), c),
      h("p", { class: "failure-rate" }, "failed: ", outcome.levels.map((l, i) => [i ? " · " : "", `level ${l.level} `,
        h("span", { class: l.controllers[c].failed ? "fail" : "pass" }, shareText(l.controllers[c]))])),
      trends[c] ? h("p", { class: "trend" }, `criticality ${trends[c].summary}`) : null,
      h("div", { class: "row" }, MEASURES.map(([key, label, unit]) => criticalityPlot(outcome, c, key, `${label} (${unit})`))))));
}

function criticalityPlot(outcome, controller, measure, title) {
  const width = 230, height = 170, left = 40, right = 10, top = 22, bottom = 30;
  const levels = outcome.levels.map((l) => l.level);
  const spreads = outcome.levels.map((l) => (criticalityOf(l, controller) || {})[measure] || null);
  const values = spreads.flatMap((s) => (s ? s.values : []));
  const plot = svg("svg", { width, height, viewBox: `0 0 ${width} ${height}`, class: "criticality-plot", "data-controller": controller, "data-measure": measure });
  plot.append(svg("text", { x: left, y: 14, "font-size": 12, "font-weight": 600 }, title));
  const step = (width - left - right) / Math.max(1, levels.length);
  const x = (i) => left + step * (i + 0.5);
  levels.forEach((l, i) => plot.append(svg("text", { x: x(i), y: height - bottom + 14, "font-size": 10, "text-anchor": "middle", class: "level-tick" }, String(l))));
  plot.append(svg("text", { x: (left + width - right) / 2, y: height - 3, "font-size": 10, "text-anchor": "middle" }, "level"));
  if (!values.length) {
    plot.append(svg("text", { x: (left + width - right) / 2, y: (top + height - bottom) / 2, "font-size": 11, "text-anchor": "middle", fill: "#6b7280" }, "never arose"));
    return plot;
  }
  const low = Math.min(0, ...values), most = Math.max(...values);
  const tick = niceStep(most > low ? most - low : 1, 3);
  const high = Math.max(low + tick, Math.ceil(most / tick) * tick); // the axis ends on a tick
  const y = (v) => height - bottom - ((v - low) / (high - low)) * (height - bottom - top);
  for (let v = Math.ceil(low / tick) * tick; v <= high + 1e-9; v += tick) {
    plot.append(svg("line", { x1: left, y1: y(v), x2: width - right, y2: y(v), stroke: "#eceef2" }),
      svg("text", { x: left - 4, y: y(v) + 3.5, "font-size": 10, "text-anchor": "end" }, round3(v)));
  }
  plot.append(svg("line", { x1: left, y1: height - bottom, x2: width - right, y2: height - bottom, stroke: "#6b7280" }));
  const colour = colourOf(controller, outcome.plan.controllers);
  spreads.forEach((s, i) => {
    const group = svg("g", { class: "level", "data-level": levels[i] });
    plot.append(group);
    if (!s) return;
    const half = Math.min(14, step / 3);
    group.append(svg("line", { x1: x(i), y1: y(s.min), x2: x(i), y2: y(s.max), stroke: colour }),
      svg("rect", { x: x(i) - half, y: y(s.q3), width: 2 * half, height: Math.max(1, y(s.q1) - y(s.q3)), fill: colour, "fill-opacity": 0.18, stroke: colour }),
      svg("line", { x1: x(i) - half, y1: y(s.median), x2: x(i) + half, y2: y(s.median), stroke: colour, "stroke-width": 2.2, class: "median" },
        svg("title", {}, `level ${levels[i]}: median ${round3(s.median)}, quartiles ${round3(s.q1)}–${round3(s.q3)}, range ${round3(s.min)}–${round3(s.max)}, ${s.count} test-cases`)));
    s.values.forEach((v, k) => group.append(svg("circle", { cx: x(i) + (s.values.length > 1 ? (k / (s.values.length - 1) - 0.5) * half : 0), cy: y(v), r: 2.4, fill: colour, "data-value": v },
      svg("title", {}, `level ${levels[i]}: ${round3(v)}`))));
  });
  return plot;
}

route();

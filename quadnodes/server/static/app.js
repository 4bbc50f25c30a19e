// quadnodes serve — the page: the graph as nodes and wires, settings forms, 3-D views of mesh outputs.
// Talks only to the JSON API of quadnodes/server/app.py (token on every request) and its event WebSocket.
"use strict";

(function () {
  const TOKEN = window.QN_TOKEN || "";
  const FILE = document.title.replace(/ · quadnodes$/, "");
  const state = {
    graph: null,          // GET /api/graph
    run: null,            // GET /api/run
    palette: [],          // GET /api/palette
    views: [],            // [{id, port, mode, key}]
    drag: null,           // wire being dragged
    layout: {},           // node id -> [x, y]
    scale: 1,             // zoom of the graph canvas
    expanded: new Set(),  // nodes showing all their settings
  };
  const TURBO = ["#30123b", "#4145ab", "#4675ed", "#39a2fc", "#1bcfd4", "#24eca6", "#61fc6c", "#a4fc3b",
                 "#d1e834", "#f3c63a", "#fe9b2d", "#f36315", "#d93806", "#b11901", "#7a0402"]
    .map((c, i, a) => [i / (a.length - 1), c]);
  const PLANARITY = [[0, "#ffffff"], [0.33, "#f2dcc0"], [0.67, "#c9925a"], [1, "#6b4a2e"]];
  const $ = (sel, el) => (el || document).querySelector(sel);
  const el = (tag, attrs, ...kids) => {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (k === "class") e.className = v;
      else if (k === "text") e.textContent = v;
      else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
      else if (v !== undefined && v !== null && v !== false) e.setAttribute(k, v === true ? "" : v);
    }
    for (const k of kids) if (k !== null && k !== undefined) e.append(k);
    return e;
  };

  // ------------------------------------------------------------------ API
  async function api(method, path, body) {
    const opts = { method, headers: { Authorization: "Bearer " + TOKEN } };
    if (body !== undefined) {
      opts.headers["Content-Type"] = "application/json";
      opts.body = JSON.stringify(body);
    }
    const r = await fetch(path, opts);
    let data = null;
    try { data = await r.json(); } catch (e) { data = { ok: false, error: r.status + " " + r.statusText }; }
    return data;
  }

  async function loadGraph() {
    state.graph = await api("GET", "/api/graph");
    state.layout = Object.assign({}, state.graph.layout);
    renderGraph();
  }

  async function loadRun() {
    state.run = await api("GET", "/api/run");
    renderRunState();
    for (const [id, info] of Object.entries(state.run.nodes || {})) renderStatus(id, info);
  }

  // --------------------------------------------------------------- values
  function typeOf(op) { return state.graph.types[op]; }

  function shown(v) {
    if (Array.isArray(v)) return v.map(shown).join(", ");
    if (v === null || v === undefined) return "";
    return String(v);
  }

  function parseList(text, item) {
    const t = text.trim().replace(/^\[|\]$/g, "");
    if (t === "") return [];
    return t.split(",").map(s => parseItem(s.trim(), item));
  }

  function parseItem(s, item) {
    if (item === "int" || item === "float") {
      const n = Number(s);
      return s !== "" && Number.isFinite(n) ? n : s;   // a bad number goes to the server, which says why
    }
    if (item === "bool") return s === "true" ? true : s === "false" ? false : s;
    if (item === "str") return s.replace(/^["']|["']$/g, "");
    try { return JSON.parse(s); } catch (e) { return s; }
  }

  function parseField(f, input) {
    const text = input.value;
    if (f.kind === "bool") return input.checked;
    if (text.trim() === "" && (f.nullable || !f.required)) return null;   // back to the default
    switch (f.kind) {
      case "int": case "float": return parseItem(text.trim(), f.kind);
      case "choice": return f.options.find(o => String(o) === text) ?? text;
      case "list": return parseList(text, f.item);
      case "number_or_list": return /,|\[/.test(text) ? parseList(text, "float") : parseItem(text.trim(), "float");
      case "str": return text;
      default: try { return JSON.parse(text); } catch (e) { return text; }
    }
  }

  // ---------------------------------------------------------------- graph
  function renderGraph() {
    const g = state.graph;
    const box = $("#nodes");
    const focused = document.activeElement && document.activeElement.dataset
      ? [document.activeElement.closest && document.activeElement.closest(".node")?.dataset.node,
         document.activeElement.dataset.setting] : null;
    box.textContent = "";
    const fe = $("#file-error");
    fe.hidden = !g.file_error;
    fe.textContent = g.file_error ? "The file on disk has an error; showing the last valid graph.\n" + g.file_error : "";
    const connected = {};   // "node.port" (output) -> true
    for (const [id, body] of Object.entries(g.nodes))
      for (const ref of Object.values(body.inputs || {})) connected[ref] = true;
    for (const id of g.order) box.append(renderNode(id, g.nodes[id], connected));
    autoPlace(new Set(g.saved_layout || []));
    if (state.run) for (const [id, info] of Object.entries(state.run.nodes || {})) renderStatus(id, info);
    if (focused && focused[0] && focused[1]) {
      const inp = $(`.node[data-node="${focused[0]}"] [data-setting="${focused[1]}"]`);
      if (inp) inp.focus();
    }
    sizeCanvas();
    requestAnimationFrame(drawWires);
    syncViews();
  }

  function renderNode(id, body, connected) {
    const t = typeOf(body.op);
    const [x, y] = state.layout[id] || [20, 20];
    const err = state.graph.errors[id];
    const node = el("div", { class: "node" + (err ? " refused" : ""), "data-node": id });
    node.style.left = x + "px";
    node.style.top = y + "px";
    const head = el("div", { class: "node-head" },
      el("span", { class: "id", text: id }),
      el("span", { class: "op", text: body.op, title: t.summary }),
      el("span", { class: "gap" }),
      el("span", { class: "status", "data-status": "" }),
      el("button", { class: "del", title: "Delete node " + id, text: "×",
                     onclick: (e) => { e.stopPropagation(); edit("DELETE", "/api/nodes/" + encodeURIComponent(id)); } }));
    head.addEventListener("mousedown", (e) => startMove(e, id, node));
    node.append(head);

    const ins = el("div", { class: "col" });
    for (const p of t.inputs) {
      const ref = (body.inputs || {})[p.name];
      const port = el("div", { class: "port in" + (ref ? " connected" : "") + (p.required ? " required" : "")
                               + (/QuadMesh/.test(p.type) ? " mesh" : ""),
                               "data-port": p.name, title: p.name + ": " + p.type + (ref ? "  ← " + ref : "") },
        el("span", { class: "dot", "data-in": id + "." + p.name }),
        el("span", { class: "pname", text: p.name }));
      ins.append(port);
    }
    const outs = el("div", { class: "col" });
    for (const p of t.outputs) {
      const key = id + "." + p.name;
      const on = state.views.some(v => v.id === id && v.port === p.name);
      const port = el("div", { class: "port out" + (connected[key] ? " connected" : "") + (p.mesh ? " mesh" : ""),
                               "data-port": p.name, title: p.name + ": " + p.type },
        p.mesh ? el("span", { class: "eye" + (on ? " on" : ""), title: "Show " + key + " in 3-D", text: "◉",
                              "data-view": key, onclick: () => toggleView(id, p.name) }) : null,
        el("span", { class: "pname", text: p.name }),
        el("span", { class: "dot", "data-out": key }));
      outs.append(port);
    }
    node.append(el("div", { class: "ports" }, ins, outs));

    if (t.settings.length) {
      // the settings the file sets (and required ones) always; the others behind "more"
      const params = body.params || {};
      const open = state.expanded.has(id);
      const main = t.settings.filter(f => f.required || Object.prototype.hasOwnProperty.call(params, f.name));
      const rest = t.settings.filter(f => !main.includes(f));
      const form = el("div", { class: "settings" });
      for (const f of (open ? t.settings : main)) form.append(...renderField(id, body, f));
      if (main.length || open) node.append(form);
      if (rest.length) node.append(el("button", {
        class: "more", "data-more": id,
        text: open ? "fewer settings" : `${rest.length} more setting${rest.length > 1 ? "s" : ""}: ` + rest.map(f => f.name).join(", "),
        onclick: () => { open ? state.expanded.delete(id) : state.expanded.add(id); renderGraph(); } }));
    }
    const run = state.run && state.run.nodes && state.run.nodes[id];
    const msg = err || (run && run.status === "failed" ? run.error : null);
    node.append(el("div", { class: "node-error", "data-error": "", hidden: !msg, text: msg || "" }));
    if (run && run.status === "failed") node.classList.add("failed");
    return node;
  }

  function renderField(id, body, f) {
    const params = body.params || {};
    const has = Object.prototype.hasOwnProperty.call(params, f.name);
    const value = has ? params[f.name] : f.default;
    const label = el("label", { class: has ? "changed" : "", text: f.name,
                                title: `${f.name}: ${f.type}` + (f.required ? " (required)" : `, default ${JSON.stringify(f.default)}`)
                                       + (f.file ? ` — a file it ${f.file}s` : "") });
    const commit = (input) => {
      const v = parseField(f, input);
      edit("POST", `/api/nodes/${encodeURIComponent(id)}/settings`, { [f.name]: v });
    };
    let field;
    if (f.kind === "bool") {
      field = el("input", { type: "checkbox", "data-setting": f.name });
      field.checked = !!value;
      field.addEventListener("change", () => commit(field));
    } else if (f.kind === "choice") {
      field = el("select", { "data-setting": f.name });
      if (f.nullable) field.append(el("option", { value: "", text: "—" }));
      for (const o of f.options) field.append(el("option", { value: String(o), text: String(o) }));
      field.value = value === null || value === undefined ? "" : String(value);
      field.addEventListener("change", () => commit(field));
    } else {
      const numeric = f.kind === "int" || f.kind === "float";
      field = el("input", { type: "text", "data-setting": f.name, spellcheck: "false",
                            placeholder: f.required ? "required" : (f.default === null ? "none" : ""),
                            inputmode: numeric ? "decimal" : null });
      field.value = shown(value);
      field.addEventListener("change", () => commit(field));
      field.addEventListener("keydown", (e) => { if (e.key === "Enter") field.blur(); });
      if (f.range && (numeric || (f.kind === "number_or_list" && !Array.isArray(value)))) {
        const [lo, hi] = f.range;
        const step = f.kind === "int" ? 1 : (hi - lo) / 200;
        const slider = el("input", { type: "range", min: lo, max: hi, step, "data-slider": f.name });
        slider.value = value ?? lo;
        slider.addEventListener("input", () => { field.value = slider.value; });
        slider.addEventListener("change", () => { field.value = slider.value; commit(field); });
        return [label, el("div", { class: "slider" }, slider, field)];
      }
    }
    return [label, field];
  }

  function renderStatus(id, info) {
    const node = $(`.node[data-node="${id}"]`);
    if (!node) return;
    const badge = $("[data-status]", node);
    const s = info.status;
    badge.className = "status " + s;
    const secs = info.seconds === null || info.seconds === undefined ? ""
      : info.seconds < 0.01 ? " <10 ms" : info.seconds < 1 ? ` ${Math.round(info.seconds * 1000)} ms` : ` ${info.seconds.toFixed(2)} s`;
    badge.textContent = s === "cached" ? "cached" : s + (s === "ran" || s === "failed" ? secs : "");
    badge.title = s === "cached" ? "reused from the cache" + secs : s;
    badge.dataset.status = s;
    node.classList.toggle("failed", s === "failed");
    const box = $("[data-error]", node);
    const refused = state.graph && state.graph.errors[id];
    const msg = refused || (s === "failed" ? info.error : "");
    box.hidden = !msg;
    box.textContent = msg || "";
  }

  function renderRunState() {
    const r = state.run;
    const pill = $("#runstate");
    if (!r) return;
    pill.className = "pill " + r.state;
    const n = (k) => (r[k] || []).length;
    pill.textContent = r.state === "running" ? "running…"
      : r.state === "done" ? `${n("ran")} ran · ${n("cached")} cached · ${(r.seconds ?? 0).toFixed(2)} s`
      : r.state === "failed" ? `failed · ${n("ran")} ran` : "idle";
    pill.title = r.error || "";
  }

  // ------------------------------------------------------------ editing
  async function edit(method, path, body) {
    const res = await api(method, path, body);
    if (!res.ok) {
      // Refused: the graph stays as it was; the message goes on the node at fault (the file is unchanged).
      await loadGraph();
      if (res.node && !state.graph.errors[res.node]) state.graph.errors[res.node] = res.error;
      const box = res.node && $(`.node[data-node="${res.node}"] [data-error]`);
      if (box) { box.hidden = false; box.textContent = res.error; $(`.node[data-node="${res.node}"]`).classList.add("refused"); }
      else alert(res.error);
    }
    return res;
  }

  function startMove(e, id, node) {
    if (e.button !== 0 || e.target.closest("button")) return;
    e.preventDefault();
    const sx = e.clientX, sy = e.clientY;
    const [x0, y0] = state.layout[id];
    node.style.zIndex = 5;
    const move = (ev) => {
      const x = Math.max(0, Math.round(x0 + (ev.clientX - sx) / state.scale));
      const y = Math.max(0, Math.round(y0 + (ev.clientY - sy) / state.scale));
      state.layout[id] = [x, y];
      node.style.left = x + "px";
      node.style.top = y + "px";
      drawWires();
    };
    const up = () => {
      window.removeEventListener("mousemove", move);
      window.removeEventListener("mouseup", up);
      node.style.zIndex = "";
      const [x, y] = state.layout[id];
      if (x !== x0 || y !== y0) api("POST", "/api/layout", { positions: { [id]: [x, y] } });
      sizeCanvas();
    };
    window.addEventListener("mousemove", move);
    window.addEventListener("mouseup", up);
  }

  function dotCenter(dot) {
    const c = $("#canvas").getBoundingClientRect();
    const r = dot.getBoundingClientRect();
    return [(r.left + r.width / 2 - c.left) / state.scale, (r.top + r.height / 2 - c.top) / state.scale];
  }

  function curve([x1, y1], [x2, y2]) {
    const dx = Math.max(40, Math.abs(x2 - x1) * 0.5);
    return `M${x1},${y1} C${x1 + dx},${y1} ${x2 - dx},${y2} ${x2},${y2}`;
  }

  function drawWires() {
    const svg = $("#wires");
    svg.textContent = "";
    if (!state.graph) return;
    const NS = "http://www.w3.org/2000/svg";
    for (const [id, body] of Object.entries(state.graph.nodes)) {
      for (const [port, ref] of Object.entries(body.inputs || {})) {
        const a = $(`[data-out="${ref}"]`), b = $(`[data-in="${id}.${port}"]`);
        if (!a || !b) continue;
        const d = curve(dotCenter(a), dotCenter(b));
        const hit = document.createElementNS(NS, "path");
        hit.setAttribute("d", d);
        hit.setAttribute("class", "hit");
        const title = document.createElementNS(NS, "title");
        title.textContent = `${ref} → ${id}.${port} (click to disconnect)`;
        hit.append(title);
        hit.addEventListener("click", () => edit("POST", "/api/disconnect", { node: id, port }));
        const wire = document.createElementNS(NS, "path");
        wire.setAttribute("d", d);
        wire.setAttribute("class", "wire" + (b.closest(".port").classList.contains("mesh") ? " mesh" : ""));
        svg.append(hit, wire);
      }
    }
    if (state.drag) {
      const p = document.createElementNS(NS, "path");
      p.setAttribute("d", curve(state.drag.from, state.drag.to));
      p.setAttribute("class", "drag");
      svg.append(p);
    }
  }

  function sizeCanvas() {
    let w = 1200, h = 900;
    for (const n of document.querySelectorAll(".node")) {
      w = Math.max(w, n.offsetLeft + n.offsetWidth + 300);
      h = Math.max(h, n.offsetTop + n.offsetHeight + 200);
    }
    const c = $("#canvas");
    c.style.width = w + "px";
    c.style.height = h + "px";
    c.style.transform = `scale(${state.scale})`;
    const s = $("#sizer");
    s.style.width = w * state.scale + "px";
    s.style.height = h * state.scale + "px";
    $("#zoom-level").textContent = Math.round(state.scale * 100) + "%";
  }

  function setScale(s) {
    state.scale = Math.min(1.5, Math.max(0.3, s));
    localStorage.setItem("quadnodes.zoom." + FILE, String(state.scale));
    sizeCanvas();
    drawWires();
  }

  function fit() {
    let w = 0, h = 0;
    for (const n of document.querySelectorAll(".node")) {
      w = Math.max(w, n.offsetLeft + n.offsetWidth + 20);
      h = Math.max(h, n.offsetTop + n.offsetHeight + 20);
    }
    const wrap = $("#canvas-wrap");
    if (w && h) setScale(Math.max(0.6, Math.min(1, wrap.clientWidth / w, wrap.clientHeight / h)));
  }

  // Drag from an output dot to an input dot to connect; click a wire to disconnect.
  document.addEventListener("mousedown", (e) => {
    const out = e.target.closest && e.target.closest("[data-out]");
    if (!out || e.button !== 0) return;
    e.preventDefault();
    const c = $("#canvas").getBoundingClientRect();
    state.drag = { source: out.dataset.out, from: dotCenter(out),
                   to: [(e.clientX - c.left) / state.scale, (e.clientY - c.top) / state.scale] };
    const move = (ev) => {
      const r = $("#canvas").getBoundingClientRect();
      state.drag.to = [(ev.clientX - r.left) / state.scale, (ev.clientY - r.top) / state.scale];
      document.querySelectorAll(".dot.target").forEach(d => d.classList.remove("target"));
      const t = ev.target.closest && ev.target.closest("[data-in]");
      if (t) t.classList.add("target");
      drawWires();
    };
    const up = (ev) => {
      window.removeEventListener("mousemove", move);
      window.removeEventListener("mouseup", up);
      const t = ev.target.closest && ev.target.closest("[data-in]");
      const source = state.drag.source;
      state.drag = null;
      document.querySelectorAll(".dot.target").forEach(d => d.classList.remove("target"));
      drawWires();
      if (t) {
        const [node, port] = t.dataset.in.split(/\.(.*)/s);
        edit("POST", "/api/connect", { node, port, source });
      }
    };
    window.addEventListener("mousemove", move);
    window.addEventListener("mouseup", up);
  });

  // -------------------------------------------------------------- palette
  async function loadPalette() {
    state.palette = await api("GET", "/api/palette");
    const sel = $("#palette");
    for (const t of state.palette) sel.append(el("option", { value: t.op, text: `${t.name} — ${t.summary.slice(0, 70)}`, title: t.summary }));
    sel.addEventListener("change", async () => {
      const op = sel.value;
      sel.value = "";
      if (!op) return;
      const wrap = $("#canvas-wrap");
      const pos = [Math.round((wrap.scrollLeft + 40) / state.scale), Math.round((wrap.scrollTop + 40) / state.scale)];
      const t = state.palette.find(x => x.op === op);
      const need = t.inputs.filter(p => p.required), must = t.settings.filter(f => f.required);
      if (!need.length && !must.length) { await edit("POST", "/api/nodes", { op, pos }); return; }
      addDialog(t, need, must, pos);
    });
    $("#relayout").addEventListener("click", async () => {
      const pos = columns(new Set());
      await api("POST", "/api/layout", { positions: pos });
    });
  }

  // A node with required inputs or settings is valid only with them: ask for them before adding it.
  function addDialog(t, need, must, pos) {
    const outs = [];
    for (const id of state.graph.order)
      for (const o of typeOf(state.graph.nodes[id].op).outputs) outs.push({ ref: id + "." + o.name, type: o.type });
    const form = el("form", { class: "dialog-box" }, el("h3", { text: "Add " + t.name }),
                    el("p", { class: "muted", text: t.summary }));
    for (const p of need) {
      const s = el("select", { name: "in:" + p.name, required: true });
      const fits = outs.filter(o => o.type === p.type || p.type === "any" || o.type === "any" || p.type.includes(o.type));
      for (const o of (fits.length ? fits : outs)) s.append(el("option", { value: o.ref, text: o.ref }));
      if (fits.length) s.value = fits[fits.length - 1].ref;
      form.append(el("label", { text: `${p.name} (${p.type})` }), s);
    }
    for (const f of must) form.append(el("label", { text: `${f.name} (${f.type})` }),
                                      el("input", { name: "set:" + f.name, required: true, spellcheck: "false" }));
    const cancel = el("button", { type: "button", text: "Cancel" });
    form.append(el("div", { class: "buttons" }, cancel, el("button", { type: "submit", class: "primary", text: "Add" })));
    const back = el("div", { class: "dialog", "data-dialog": t.op }, form);
    cancel.addEventListener("click", () => back.remove());
    form.addEventListener("submit", async (e) => {
      e.preventDefault();
      const inputs = {}, params = {};
      for (const p of need) inputs[p.name] = form.elements["in:" + p.name].value;
      for (const f of must) params[f.name] = parseField(f, form.elements["set:" + f.name]);
      back.remove();
      await edit("POST", "/api/nodes", { op: t.op, inputs, params, pos });
    });
    document.body.append(back);
    const first = form.querySelector("select, input");
    if (first) first.focus();
  }

  // Columns by topological depth (as the server's auto_layout, with the real heights of the cards);
  // a tall column flows on into the next. Nodes in `keep` stay where they are.
  function columns(keep) {
    const order = state.graph.order, nodes = state.graph.nodes;
    const depth = {}, pos = {};
    for (const id of order) {
      const ups = Object.values(nodes[id].inputs || {}).map(r => r.split(".")[0]);
      depth[id] = 1 + Math.max(-1, ...ups.map(u => depth[u] ?? -1));
    }
    let x = 20;
    for (let col = 0; col <= Math.max(-1, ...Object.values(depth)); col++) {
      let y = 20, used = false;
      for (const id of order.filter(n => depth[n] === col && !keep.has(n))) {
        const n = $(`.node[data-node="${id}"]`);
        const h = n ? n.offsetHeight : 120;
        if (used && y + h > 1000) { x += 250; y = 20; }
        pos[id] = [x, y];
        y += h + 18;
        used = true;
      }
      if (used) x += 250;
    }
    return pos;
  }

  // Nodes without a saved position are placed on the page (not saved until moved or arranged).
  function autoPlace(saved) {
    if (state.graph.order.every(id => saved.has(id))) return;
    const pos = columns(saved);
    for (const [id, p] of Object.entries(pos)) {
      state.layout[id] = p;
      const n = $(`.node[data-node="${id}"]`);
      if (n) { n.style.left = p[0] + "px"; n.style.top = p[1] + "px"; }
    }
  }

  // ---------------------------------------------------------------- views
  const VIEWS_KEY = "quadnodes.views." + FILE;

  function saveViews() {
    localStorage.setItem(VIEWS_KEY, JSON.stringify(state.views.map(v => ({ id: v.id, port: v.port, mode: v.mode }))));
  }

  function toggleView(id, port) {
    const i = state.views.findIndex(v => v.id === id && v.port === port);
    if (i >= 0) state.views.splice(i, 1);
    else state.views.push({ id, port, mode: "deviation", key: null });
    saveViews();
    syncViews();
    document.querySelectorAll(`[data-view="${id}.${port}"]`).forEach(e => e.classList.toggle("on", i < 0));
  }

  function syncViews() {
    const box = $("#views");
    if (!state.graph) return;
    // drop views of nodes or ports that are gone
    state.views = state.views.filter(v => state.graph.nodes[v.id]
      && typeOf(state.graph.nodes[v.id].op).outputs.some(o => o.name === v.port));
    const want = new Set(state.views.map(v => v.id + "." + v.port));
    for (const card of [...box.querySelectorAll(".view")]) if (!want.has(card.dataset.view)) { Plotly.purge($(".view-plot", card)); card.remove(); }
    for (const v of state.views) {
      const name = v.id + "." + v.port;
      if (!box.querySelector(`.view[data-view="${name}"]`)) {
        const mode = el("select", { title: "Colour" },
          el("option", { value: "deviation", text: "zigzag" }),
          el("option", { value: "planarity", text: "planarity" }));
        mode.value = v.mode;
        mode.addEventListener("change", () => { v.mode = mode.value; saveViews(); v.key = null; refreshView(v); });
        const card = el("div", { class: "view", "data-view": name, "data-key": "" },
          el("div", { class: "view-head" },
            el("span", { class: "title", text: name }),
            el("span", { class: "info", "data-info": "" }),
            mode,
            el("button", { class: "del", title: "Close view", text: "×", onclick: () => toggleView(v.id, v.port) })),
          el("div", { class: "view-plot" }, el("div", { class: "msg", text: "waiting for the run…" })));
        box.append(card);
      }
      refreshView(v);
    }
    $("#views-empty").hidden = state.views.length > 0;
    box.classList.toggle("views-1", state.views.length === 1);
    box.classList.toggle("views-2", state.views.length === 2);
    for (const card of box.querySelectorAll(".view")) { const p = $(".view-plot", card); if (p && p.data) Plotly.Plots.resize(p); }
  }

  function b64(text, Type) {
    const bin = atob(text);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Type(bytes.buffer);
  }

  async function refreshView(v) {
    const info = state.run && state.run.nodes && state.run.nodes[v.id];
    const card = $(`.view[data-view="${v.id}.${v.port}"]`);
    if (!card) return;
    const plot = $(".view-plot", card);
    if (!info || !(info.status === "ran" || info.status === "cached")) {
      if (!plot.data) {
        const m = $(".msg", plot) || plot.appendChild(el("div", { class: "msg" }));
        m.textContent = info && info.status === "failed" ? "the node failed: " + info.error
          : info && info.status === "skipped" ? "not run: an upstream node failed" : "waiting for the run…";
      }
      return;
    }
    const aspect = plot.clientWidth / Math.max(1, plot.clientHeight);
    if (info.key && info.key === v.key && v.drawnMode === v.mode && Math.abs(aspect - (v.aspect || 0)) < 0.25) return;
    const want = info.key;
    v.key = want;
    const d = await api("GET", `/api/mesh/${encodeURIComponent(v.id)}/${encodeURIComponent(v.port)}`);
    if (d.error) { v.key = null; $("[data-info]", card).textContent = d.error; return; }
    if (v.key !== want) return;   // a newer run arrived meanwhile
    draw(v, plot, d);
    v.drawnMode = v.mode;
    v.aspect = aspect;
    card.dataset.key = d.key;
    const unit = d.unit || "";
    $("[data-info]", card).textContent = `${d.n_faces} panels · max zigzag ${d.max_deviation.toExponential(1)} · `
      + `max planarity ${d.max_planarity.toExponential(1)}`;
  }

  function draw(v, plot, d) {
    const P = b64(d.vertices, Float32Array), F = b64(d.faces, Int32Array);
    const E = b64(d.edges, Int32Array), dev = b64(d.edge_deviation, Float32Array), pl = b64(d.planarity, Float32Array);
    const n = d.n_vertices, m = d.n_faces;
    const x = new Float32Array(n), y = new Float32Array(n), z = new Float32Array(n);
    for (let k = 0; k < n; k++) { x[k] = P[3 * k]; y[k] = P[3 * k + 1]; z[k] = P[3 * k + 2]; }
    const I = new Int32Array(2 * m), J = new Int32Array(2 * m), K = new Int32Array(2 * m), cell = new Float32Array(2 * m);
    for (let f = 0; f < m; f++) {
      const a = F[4 * f], b = F[4 * f + 1], c = F[4 * f + 2], e = F[4 * f + 3];
      I[2 * f] = a; J[2 * f] = b; K[2 * f] = c;
      I[2 * f + 1] = a; J[2 * f + 1] = c; K[2 * f + 1] = e;
      cell[2 * f] = cell[2 * f + 1] = pl[f];
    }
    const planar = v.mode === "planarity";
    const unit = d.unit || "mm";
    const mesh = {
      type: "mesh3d", x, y, z, i: I, j: J, k: K, flatshading: true, hoverinfo: "skip", name: "panels",
      lighting: { ambient: 0.55, diffuse: 0.75, specular: 0.08, roughness: 0.7, fresnel: 0.1 },
      lightposition: { x: -1000, y: 2000, z: 4000 },
    };
    // baked shading as in the HTML view: a light upper left behind the viewer, panels from 55 % to full colour
    const L = lightDir();
    const shade = new Float32Array(2 * m);
    for (let f = 0; f < m; f++) {
      const a = F[4 * f], b = F[4 * f + 1], c = F[4 * f + 2], e = F[4 * f + 3];
      const u = [x[c] - x[a], y[c] - y[a], z[c] - z[a]], w = [x[e] - x[b], y[e] - y[b], z[e] - z[b]];
      const nx = u[1] * w[2] - u[2] * w[1], ny = u[2] * w[0] - u[0] * w[2], nz = u[0] * w[1] - u[1] * w[0];
      const len = Math.hypot(nx, ny, nz) || 1;
      shade[2 * f] = shade[2 * f + 1] = 0.55 + 0.45 * Math.abs((nx * L[0] + ny * L[1] + nz * L[2]) / len);
    }
    mesh.lighting = { ambient: 1, diffuse: 0, specular: 0, roughness: 1, fresnel: 0 };
    if (planar) Object.assign(mesh, {
      intensity: cell, intensitymode: "cell", colorscale: PLANARITY, cmin: 0, cmax: Math.max(1e-6, d.max_planarity),
      colorbar: { title: { text: "planarity<br>diag. dist /<br>mean diag.", side: "top" }, thickness: 12, len: 0.7, x: 1.0 },
    });
    else Object.assign(mesh, { intensity: shade, intensitymode: "cell", cmin: 0.55, cmax: 1, showscale: false,
                               colorscale: [[0, "rgb(118,121,127)"], [1, "rgb(214,220,230)"]] });
    const traces = [mesh];
    // structure lines, edge by edge, coloured by zigzag deviation on a log scale (1e-4 … 1)
    // lines float a little off the surface, one copy to each side (as the HTML view), so panels do not hide them
    const vn = new Float32Array(3 * n);
    let mean = 0;
    for (let f = 0; f < m; f++) {
      const a = F[4 * f], b = F[4 * f + 1], c = F[4 * f + 2], e = F[4 * f + 3];
      const u = [x[c] - x[a], y[c] - y[a], z[c] - z[a]], w = [x[e] - x[b], y[e] - y[b], z[e] - z[b]];
      const nn = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
      for (const q of [a, b, c, e]) { vn[3 * q] += nn[0]; vn[3 * q + 1] += nn[1]; vn[3 * q + 2] += nn[2]; }
    }
    const ne = d.n_edges;
    for (let k = 0; k < ne; k++) { const a = E[2 * k], b = E[2 * k + 1]; mean += Math.hypot(x[a] - x[b], y[a] - y[b], z[a] - z[b]); }
    const lift = 0.03 * mean / Math.max(1, ne);
    for (let q = 0; q < n; q++) {
      const len = Math.hypot(vn[3 * q], vn[3 * q + 1], vn[3 * q + 2]) || 1;
      vn[3 * q] *= lift / len; vn[3 * q + 1] *= lift / len; vn[3 * q + 2] *= lift / len;
    }
    const lx = new Float32Array(6 * ne), ly = new Float32Array(6 * ne), lz = new Float32Array(6 * ne), lc = new Float32Array(6 * ne);
    for (const [side, s] of [[0, 1], [1, -1]]) {
      for (let k = 0; k < ne; k++) {
        const a = E[2 * k], b = E[2 * k + 1], o = 3 * (side * ne + k);
        const c = Math.log10(Math.min(1, Math.max(1e-4, dev[k])));
        lx[o] = x[a] + s * vn[3 * a]; ly[o] = y[a] + s * vn[3 * a + 1]; lz[o] = z[a] + s * vn[3 * a + 2];
        lx[o + 1] = x[b] + s * vn[3 * b]; ly[o + 1] = y[b] + s * vn[3 * b + 1]; lz[o + 1] = z[b] + s * vn[3 * b + 2];
        lx[o + 2] = ly[o + 2] = lz[o + 2] = NaN;
        lc[o] = lc[o + 1] = lc[o + 2] = c;
      }
    }
    traces.push({
      type: "scatter3d", mode: "lines", x: lx, y: ly, z: lz, hoverinfo: "skip", name: "structure lines",
      line: planar ? { color: "#3b4250", width: 1.5 } : {
        color: lc, colorscale: TURBO, cmin: -4, cmax: 0, width: 3,
        colorbar: { title: { text: "zigzag<br>deviation", side: "top" }, thickness: 12, len: 0.7, x: 1.0,
                    tickvals: [-4, -3, -2, -1, 0], ticktext: ["1e-4", "1e-3", "0.01", "0.1", "1"] },
      },
    });
    const layout = {
      uirevision: v.id + "." + v.port, margin: { l: 0, r: 0, t: 0, b: 0 }, showlegend: false,
      paper_bgcolor: "#ffffff", scene: scene([x, y, z], unit, plot.clientWidth / Math.max(1, plot.clientHeight)),
    };
    const msg = $(".msg", plot);
    if (msg) msg.remove();
    Plotly.react(plot, traces, layout, { displaylogo: false, responsive: true,
                                         modeBarButtonsToRemove: ["toImage", "resetCameraLastSave3d"] });
  }

  function lightDir() {
    const el_ = 35 * Math.PI / 180, az = -65 * Math.PI / 180;
    const eye = [Math.cos(el_) * Math.cos(az), Math.cos(el_) * Math.sin(az), Math.sin(el_)];
    const right = [-Math.sin(az), Math.cos(az), 0];
    const up = [eye[1] * right[2] - eye[2] * right[1], eye[2] * right[0] - eye[0] * right[2], eye[0] * right[1] - eye[1] * right[0]];
    const d = [0, 1, 2].map(i => 0.75 * eye[i] + 0.45 * up[i] - 0.35 * right[i]);
    const len = Math.hypot(...d);
    return d.map(v => v / len);
  }

  // The camera of the PNG and HTML views (elevation 35°, azimuth -65°, orthographic), the box scaled so
  // that a long flat sheet fills the view as a compact one does (as quadnodes/html.py does).
  function scene(xyz, unit, aspect) {
    const lo = xyz.map(a => a.reduce((m, v) => Math.min(m, v), Infinity));
    const hi = xyz.map(a => a.reduce((m, v) => Math.max(m, v), -Infinity));
    const size = hi.map((h, i) => h - lo[i]);
    const longest = Math.max(...size) || 1;
    const box = size.map(s => Math.max(s, 0.15 * longest));
    const pad = 0.04 * longest;
    const ranges = box.map((b, i) => [(lo[i] + hi[i]) / 2 - b / 2 - pad, (lo[i] + hi[i]) / 2 + b / 2 + pad]);
    const big = Math.max(...box.map(b => b + 2 * pad));
    let ratio = box.map(b => (b + 2 * pad) / big);
    const el_ = 35 * Math.PI / 180, az = -65 * Math.PI / 180;
    const eye = [Math.cos(el_) * Math.cos(az), Math.cos(el_) * Math.sin(az), Math.sin(el_)];
    const right = [-Math.sin(az), Math.cos(az), 0];
    const up = [eye[1] * right[2] - eye[2] * right[1], eye[2] * right[0] - eye[0] * right[2], eye[0] * right[1] - eye[1] * right[0]];
    let ex = [Infinity, -Infinity], ey = [Infinity, -Infinity];
    for (const i of [0, 1]) for (const j of [0, 1]) for (const k of [0, 1]) {
      const c = [i * ratio[0], j * ratio[1], k * ratio[2]];
      const sx = c[0] * right[0] + c[1] * right[1] + c[2] * right[2], sy = c[0] * up[0] + c[1] * up[1] + c[2] * up[2];
      ex = [Math.min(ex[0], sx), Math.max(ex[1], sx)];
      ey = [Math.min(ey[0], sy), Math.max(ey[1], sy)];
    }
    const f = Math.min(Math.min(2.7, 1.9 * (aspect || 1.4) * 0.92) / (ex[1] - ex[0]), 1.9 / (ey[1] - ey[0]));
    ratio = ratio.map(r => r * f);
    const axis = (t, i) => ({ title: { text: `${t} (${unit})`, font: { size: 10, color: "#8a8f98" } }, range: ranges[i],
                              showbackground: false, gridcolor: "#e4e7ec", zerolinecolor: "#cfd4dc",
                              showspikes: false, tickfont: { size: 9, color: "#8a8f98" } });
    return {
      xaxis: axis("x", 0), yaxis: axis("y", 1), zaxis: axis("z", 2), aspectmode: "manual",
      aspectratio: { x: ratio[0], y: ratio[1], z: ratio[2] }, dragmode: "orbit",
      camera: { eye: { x: 2 * eye[0], y: 2 * eye[1], z: 2 * eye[2] }, up: { x: 0, y: 0, z: 1 },
                projection: { type: "orthographic" } },
    };
  }

  // --------------------------------------------------------------- events
  function connectEvents() {
    const proto = location.protocol === "https:" ? "wss:" : "ws:";
    const ws = new WebSocket(`${proto}//${location.host}/api/events?token=${encodeURIComponent(TOKEN)}`);
    let graphTimer = null;
    ws.onmessage = (msg) => {
      const ev = JSON.parse(msg.data);
      if (ev.type === "graph") {
        clearTimeout(graphTimer);
        graphTimer = setTimeout(loadGraph, 30);
      } else if (ev.type === "run") {
        loadRun().then(() => { for (const v of state.views) refreshView(v); });
      } else if (ev.type === "node") {
        if (!state.run || state.run.revision !== ev.revision) {
          state.run = { revision: ev.revision, state: "running", nodes: Object.assign({}, state.run ? state.run.nodes : {}) };
          renderRunState();
        }
        state.run.nodes[ev.id] = { status: ev.status, seconds: ev.seconds, error: ev.error, key: ev.key };
        if (ev.status === "running") {
          const done = Object.values(state.run.nodes).filter(n => n.status === "ran" || n.status === "cached").length;
          $("#runstate").textContent = `running ${ev.id} (${done + 1}/${state.graph ? state.graph.order.length : "?"})…`;
        }
        renderStatus(ev.id, ev);
        for (const v of state.views) if (v.id === ev.id) refreshView(v);
      } else if (ev.type === "refused") {
        if (state.graph && ev.node) {
          state.graph.errors = { [ev.node]: ev.error };
          const box = $(`.node[data-node="${ev.node}"] [data-error]`);
          if (box) { box.hidden = false; box.textContent = ev.error; }
        }
      }
    };
    ws.onclose = () => setTimeout(() => { $("#runstate").textContent = "reconnecting…"; connectEvents(); loadGraph(); loadRun(); }, 1000);
  }

  async function start() {
    try { state.views = JSON.parse(localStorage.getItem(VIEWS_KEY) || "[]").map(v => Object.assign({ key: null }, v)); }
    catch (e) { state.views = []; }
    await Promise.all([loadGraph(), loadPalette()]);
    await loadRun();
    if (!localStorage.getItem(VIEWS_KEY)) {
      // first visit: show the deepest mesh output that is not written to a file
      let best = null;
      const depth = {};
      for (const id of state.graph.order) {
        const body = state.graph.nodes[id];
        const ups = Object.values(body.inputs || {}).map(r => r.split(".")[0]);
        depth[id] = 1 + Math.max(-1, ...ups.map(u => depth[u] ?? -1));
        const out = typeOf(body.op).outputs.find(o => o.mesh);
        const writer = typeOf(body.op).settings.some(s => s.file === "write");
        if (out && !writer && (!best || depth[id] > best.depth)) best = { id, port: out.name, depth: depth[id] };
      }
      if (best) toggleView(best.id, best.port);
    }
    $("#zoom-in").addEventListener("click", () => setScale(state.scale * 1.15));
    $("#zoom-out").addEventListener("click", () => setScale(state.scale / 1.15));
    $("#zoom-fit").addEventListener("click", fit);
    const z = Number(localStorage.getItem("quadnodes.zoom." + FILE));
    if (z) setScale(z); else fit();
    syncViews();
    connectEvents();
    window.addEventListener("resize", () => { drawWires(); for (const p of document.querySelectorAll(".view-plot")) if (p.data) Plotly.Plots.resize(p); });
    document.body.dataset.ready = "1";
  }

  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", start);
  else start();
})();

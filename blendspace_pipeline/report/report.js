// blendspace-pipeline report: selection, details, filters and the error map readout.
// Events are delegated to a few containers so a 1,000-clip report wires a handful of listeners.
(() => {
  "use strict";
  const data = JSON.parse(document.getElementById("report-data").textContent);
  const space = document.getElementById("space");
  const details = document.getElementById("details");
  const tooltip = document.getElementById("tooltip");
  const diagnosticRows = document.querySelector("#diagnostics-table tbody");
  const [ax, ay] = data.axes;
  const sampleIndex = new Map(data.samples.map((s, i) => [s.name, i]));

  const esc = (text) => String(text).replace(/[&<>"']/g, (c) => ({
    "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;",
  })[c]);
  // Below 1e-9 a value is floating-point noise of an exact computation: show it as 0.
  const num = (v, digits = 4) => (v === null || v === undefined ? "–"
    : Math.abs(v) < 1e-9 ? "0" : String(+Number(v).toPrecision(digits)));
  const posText = (p) => (p ? `(${num(p[0])} ${ax.unit}, ${num(p[1])} ${ay.unit})` : "–");
  const pos = (p) => esc(posText(p));
  // Big sets draw merged paths (svg.DOM_LIMIT): there, the markers and areas of a selection are
  // drawn on demand into #selection-layer from the embedded positions, and removed with it.
  const lod = data.lod || null;
  const layer = document.getElementById("selection-layer");
  const SVG = space.namespaceURI; // the SVG namespace, without writing a URL into the page
  function overlay(tag, attributes) {
    const el = document.createElementNS(SVG, tag);
    for (const [k, v] of Object.entries(attributes)) el.setAttribute(k, v);
    el.classList.add("transient");
    layer.appendChild(el);
    return el;
  }
  function sampleMarker(name) {
    const found = space.querySelector(`[data-sample="${CSS.escape(name)}"]`);
    if (found || !lod || !sampleIndex.has(name)) return found;
    const i = sampleIndex.get(name);
    const [x, y] = lod.samples[i];
    return data.samples[i].generated
      ? overlay("rect", { class: "sample generated", "data-sample": name, x: x - 6, y: y - 6, width: 12, height: 12 })
      : overlay("circle", { class: "sample", "data-sample": name, cx: x, cy: y, r: 6 });
  }
  function placeholderMarker(i) {
    const found = space.querySelector(`[data-placeholder="${i}"]`);
    if (found || !lod) return found;
    const [x, y] = lod.placeholders[i];
    const p = data.placeholders[i];
    return overlay("path", { class: `placeholder ${p.priority}`, "data-placeholder": i, d: `M${x} ${y - 8}L${x + 8} ${y}L${x} ${y + 8}L${x - 8} ${y}Z` });
  }
  const circleD = (x, y, r) => `M${x - r} ${y}a${r} ${r} 0 1 0 ${2 * r} 0a${r} ${r} 0 1 0 ${-2 * r} 0Z`;
  function shapeMarkers(i) {
    const found = space.querySelectorAll(`[data-diagnostic-shape="${i}"]`);
    if (found.length || !lod || !lod.shapes[i]) return [...found];
    const [kind, points, radius] = lod.shapes[i];
    let d;
    if (kind === "circle") d = circleD(points[0][0], points[0][1], radius);
    else if (kind === "rings" || kind === "point") d = points.map(([x, y]) => circleD(x, y, kind === "point" ? 7 : radius)).join("");
    else d = "M" + points.map(([x, y]) => `${x} ${y}`).join("L") + (kind === "edge" ? "" : "Z");
    return [overlay("path", { class: "problem", "data-diagnostic-shape": i, d })];
  }

  function clearSelection() {
    for (const el of document.querySelectorAll(".highlight")) el.classList.remove("highlight");
    if (layer) layer.replaceChildren();
    space.classList.remove("has-selection");
  }

  function mark(elements) {
    let any = false;
    for (const el of elements) { if (el) { el.classList.add("highlight"); any = true; } }
    if (any) space.classList.add("has-selection");
  }

  function diagnosticLinks(indices) {
    if (!indices.length) return "<p class='empty'>No diagnostics involve it.</p>";
    return "<ul>" + indices.map((i) => {
      const d = data.diagnostics[i];
      return `<li><a data-goto-diagnostic="${i}"><span class="sev sev-${esc(d.severity)}">${esc(d.severity)}</span> `
        + `${esc(d.rule)}</a>: ${esc(d.message)}</li>`;
    }).join("") + "</ul>";
  }

  function selectSample(i) {
    const s = data.samples[i];
    clearSelection();
    if (pagers["clips-table"]) pagers["clips-table"].reveal(i);
    mark([sampleMarker(s.name), document.querySelector(`[data-clip-row="${i}"]`)]);
    const features = Object.entries(s.features || {}).map(([k, v]) => `<dt>${esc(k)}</dt><dd>${num(v)}</dd>`).join("");
    details.innerHTML = `<h3>${esc(s.name)}${s.generated ? ` <span class="tag generated">generated: ${esc(s.fix || "fix")}</span>` : ""}</h3>`
      + `<dl><dt>source</dt><dd><code>${esc(s.source)}</code></dd><dt>position</dt><dd>${pos(s.position)}</dd>`
      + `<dt>snapping error</dt><dd>${pos(s.snap)}</dd>`
      + (s.manual ? `<dt>placed by hand</dt><dd>${pos(s.manual)}</dd>` : "")
      + `${features}</dl><h3>Diagnostics</h3>${diagnosticLinks(s.diagnostics || [])}`;
  }

  function selectDiagnostic(i) {
    const d = data.diagnostics[i];
    clearSelection();
    if (pagers["diagnostics-table"]) pagers["diagnostics-table"].reveal(i);
    const row = diagnosticRows && diagnosticRows.querySelector(`[data-diagnostic="${i}"]`);
    mark([row, ...d.clips.map(sampleMarker), ...shapeMarkers(i)]);
    const clips = d.clips.map((c) => (sampleIndex.has(c) ? `<a data-goto-sample="${sampleIndex.get(c)}">${esc(c)}</a>` : esc(c)));
    details.innerHTML = `<h3><span class="sev sev-${esc(d.severity)}">${esc(d.severity)}</span> ${esc(d.rule)} <small>${esc(d.code)}</small></h3>`
      + `<p>${esc(d.message)}</p>` + (d.hint ? `<p><strong>hint:</strong> ${esc(d.hint)}</p>` : "")
      + `<dl><dt>clips</dt><dd>${clips.join(", ") || "–"}</dd><dt>where</dt><dd>${pos(d.position)}</dd>`
      + (d.fix ? `<dt>automatic fix</dt><dd>${esc(d.fix)}</dd>` : "") + "</dl>";
  }

  function selectPlaceholder(i) {
    const p = data.placeholders[i];
    clearSelection();
    if (pagers["placeholders-table"]) pagers["placeholders-table"].reveal(i);
    mark([placeholderMarker(i), document.querySelector(`[data-placeholder-row="${i}"]`)]);
    const features = Object.entries(p.features || {}).map(([k, v]) => `<dt>${esc(k)}</dt><dd>${num(v)}</dd>`).join("");
    details.innerHTML = `<h3><span class="prio ${esc(p.priority)}">${esc(p.priority)}</span> clip to add</h3>`
      + `<p>${esc(p.reason)}</p><dl><dt>position</dt><dd>${pos(p.position)}</dd><dt>rule</dt><dd>${esc(p.rule)}</dd>${features}</dl>`;
  }

  // What is under the pointer: the element's hooks, or in a big set the nearest marker within
  // reach (a bucket grid over the positions) and else the first finding whose shape holds it.
  const BUCKET = 16;
  const buckets = new Map();
  if (lod) {
    const add = (kind, list) => list.forEach(([x, y], i) => {
      const key = `${Math.floor(x / BUCKET)},${Math.floor(y / BUCKET)}`;
      if (!buckets.has(key)) buckets.set(key, []);
      buckets.get(key).push([kind, i, x, y]);
    });
    add("sample", lod.samples);
    add("placeholder", lod.placeholders);
  }
  function svgPoint(event) {
    return new DOMPoint(event.clientX, event.clientY).matrixTransform(space.getScreenCTM().inverse());
  }
  function insideShape(shape, x, y) {
    const [kind, points, radius] = shape;
    if (kind === "circle") return Math.hypot(x - points[0][0], y - points[0][1]) <= radius;
    if (kind === "rings" || kind === "point") {
      const r = kind === "point" ? 7 : radius;
      return points.some(([px, py]) => Math.abs(Math.hypot(x - px, y - py) - r) <= 3);
    }
    if (kind === "edge") {
      const [[ax, ay], [bx, by]] = points;
      const t = Math.max(0, Math.min(1, ((x - ax) * (bx - ax) + (y - ay) * (by - ay)) / ((bx - ax) ** 2 + (by - ay) ** 2 || 1)));
      return Math.hypot(x - ax - t * (bx - ax), y - ay - t * (by - ay)) <= 4;
    }
    if (kind === "region") return false; // the uncovered area is everything else: not a click target
    let inside = false; // even-odd rule over the polygon
    for (let i = 0, j = points.length - 1; i < points.length; j = i++) {
      const [xi, yi] = points[i], [xj, yj] = points[j];
      if ((yi > y) !== (yj > y) && x < ((xj - xi) * (y - yi)) / (yj - yi) + xi) inside = !inside;
    }
    return inside;
  }
  function hit(event) {
    const el = event.target.closest("[data-sample],[data-placeholder],[data-diagnostic-shape]");
    if (el && !el.classList.contains("transient")) {
      if (el.dataset.sample !== undefined) return ["sample", sampleIndex.get(el.dataset.sample)];
      if (el.dataset.placeholder !== undefined) return ["placeholder", +el.dataset.placeholder];
      return ["diagnostic", +el.dataset.diagnosticShape];
    }
    if (!lod) return null;
    const { x, y } = svgPoint(event);
    let best = null;
    let bestDistance = 8;
    const bx = Math.floor(x / BUCKET), by = Math.floor(y / BUCKET);
    for (let i = bx - 1; i <= bx + 1; i++) {
      for (let j = by - 1; j <= by + 1; j++) {
        for (const [kind, index, px, py] of buckets.get(`${i},${j}`) || []) {
          const distance = Math.hypot(px - x, py - y);
          if (distance <= bestDistance) { best = [kind, index]; bestDistance = distance; }
        }
      }
    }
    if (best || space.classList.contains("hide-problems")) return best;
    const index = lod.shapes.findIndex((shape) => shape && insideShape(shape, x, y));
    return index >= 0 ? ["diagnostic", index] : null;
  }
  function pick(event) {
    const found = hit(event);
    if (!found) return false;
    const [kind, i] = found;
    if (kind === "sample") selectSample(i);
    else if (kind === "placeholder") selectPlaceholder(i);
    else selectDiagnostic(i);
    return true;
  }

  space.addEventListener("click", (event) => { if (!pick(event)) { clearSelection(); } });
  space.addEventListener("mousemove", (event) => {
    const found = hit(event);
    if (!found) { tooltip.hidden = true; return; }
    const [kind, i] = found;
    let text;
    if (kind === "sample") {
      const s = data.samples[i];
      text = `${s.name} ${posText(s.position)}`;
    } else if (kind === "placeholder") {
      const p = data.placeholders[i];
      text = `${p.priority}: ${p.reason} ${posText(p.position)}`;
    } else {
      const d = data.diagnostics[i];
      text = `${d.severity} ${d.rule}: ${d.message}`;
    }
    tooltip.textContent = text;
    tooltip.style.left = `${event.clientX + 14}px`;
    tooltip.style.top = `${event.clientY + 12}px`;
    tooltip.hidden = false;
  });
  space.addEventListener("mouseleave", () => { tooltip.hidden = true; });

  details.addEventListener("click", (event) => {
    const link = event.target.closest("[data-goto-diagnostic],[data-goto-sample]");
    if (!link) return;
    if (link.dataset.gotoDiagnostic !== undefined) selectDiagnostic(+link.dataset.gotoDiagnostic);
    else selectSample(+link.dataset.gotoSample);
  });

  const rowHandler = (attribute, select) => (event) => {
    if (event.type === "keydown" && event.key !== "Enter") return;
    const row = event.target.closest(`[${attribute}]`);
    if (!row) return;
    select(+row.getAttribute(attribute));
    if (event.currentTarget !== space) space.scrollIntoView({ block: "nearest" });
  };
  for (const [selector, attribute, select] of [
    ["#diagnostics-table tbody", "data-diagnostic", selectDiagnostic],
    ["#clips-table tbody", "data-clip-row", selectSample],
    ["#placeholders-table tbody", "data-placeholder-row", selectPlaceholder],
  ]) {
    const body = document.querySelector(selector);
    if (body) { body.addEventListener("click", rowHandler(attribute, select)); body.addEventListener("keydown", rowHandler(attribute, select)); }
  }

  // Long tables: one page of rows in the DOM, rendered from the embedded rows; a filter box
  // (and for diagnostics the severity and rule filters) chooses which rows are paged through.
  const pagers = {};
  // Python's "%.<digits>g" (tables.num), so the rows the script renders read exactly like the
  // first page rendered by the build.
  function pyG(v, digits = 4) {
    if (v === null || v === undefined) return "–";
    if (v === 0) return Object.is(v, -0) ? "-0" : "0";
    if (!Number.isFinite(v)) return Number.isNaN(v) ? "nan" : v > 0 ? "inf" : "-inf";
    const [mantissa, exponentText] = v.toExponential(digits - 1).split("e");
    const exponent = +exponentText;
    if (exponent < -4 || exponent >= digits) {
      const m = mantissa.includes(".") ? mantissa.replace(/0+$/, "").replace(/\.$/, "") : mantissa;
      return `${m}e${exponent < 0 ? "-" : "+"}${String(Math.abs(exponent)).padStart(2, "0")}`;
    }
    const fixed = v.toFixed(Math.max(0, digits - 1 - exponent));
    return fixed.includes(".") ? fixed.replace(/0+$/, "").replace(/\.$/, "") : fixed;
  }
  const pair = (values, digits = 4) => (values ? `(${values.map((v) => pyG(v, digits)).join(", ")})` : "–");
  const clipList = (names) => names.map((n) => `<span class="clip-ref">${esc(n)}</span>`).join(" ") || "–";

  function diagnosticRow(i) {
    const d = data.diagnostics[i];
    return `<tr data-diagnostic="${i}" data-severity="${esc(d.severity)}" data-rule="${esc(d.rule)}" tabindex="0">`
      + `<td><span class="sev sev-${esc(d.severity)}">${esc(d.severity)}</span></td>`
      + `<td><code>${esc(d.rule)}</code><br><small>${esc(d.code)}</small></td><td>${clipList(d.clips)}</td>`
      + `<td>${esc(d.message)}${d.fix ? ` <span class="fix">fix: ${esc(d.fix)}</span>` : ""}</td><td>${esc(d.hint || "")}`
      + `${d.where ? `<br><small>${esc(d.where)}</small>` : ""}</td></tr>`;
  }
  const featuresText = (features) => Object.entries(features || {})
    .map(([k, v]) => `${esc(k)} ${pyG(v)} ${esc(data.units[k] || "")}`).join(", ") || "–";
  function placeholderRow(i) {
    const p = data.placeholders[i];
    return `<tr data-placeholder-row="${i}"><td><span class="prio ${p.priority}">${p.priority}</span></td>`
      + `<td>${pyG(p.position[0])} ${esc(ax.unit)}, ${pyG(p.position[1])} ${esc(ay.unit)}</td>`
      + `<td>${featuresText(p.features)}</td><td><code>${esc(p.rule)}</code></td><td>${esc(p.reason)}</td></tr>`;
  }
  const STRIP = "contacts-strip"; // named once: the page's markup is what counts its strips
  function contactsStrip(s) {
    const duration = (s.features || {}).duration || 0;
    if (!s.contacts || duration <= 0) return "–";
    const width = 120, row = 8;
    const bars = [];
    ["left", "right"].forEach((foot, lane) => {
      for (const [start, end] of s.contacts[foot] || []) {
        if (start === null || end === null) continue; // a NaN the JSON could only carry as null
        const x0 = (start / duration) * width, x1 = (end / duration) * width;
        bars.push(`<rect class="contact ${foot}" x="${x0.toFixed(1)}" y="${(lane * (row + 2)).toFixed(1)}" `
          + `width="${Math.max(x1 - x0, 0.5).toFixed(1)}" height="${row}"><title>${foot} foot down `
          + `${start.toFixed(2)}–${end.toFixed(2)} s</title></rect>`);
      }
    });
    const phases = s.clip && s.clip.phases;
    const label = phases ? `<br><small>plants at phase L ${phases.left.toFixed(2)}, R ${phases.right.toFixed(2)}</small>` : "";
    return `<svg class="${STRIP}" width="${width}" height="${2 * row + 2}" role="img" `
      + `aria-label="foot contacts of ${esc(s.name)}">${bars.join("")}</svg>${label}`;
  }
  function clipRow(i) {
    const s = data.samples[i];
    const kind = s.generated ? `<br><span class="tag generated">generated: ${esc(s.fix || "fix")}</span>` : "";
    const cells = data.feature_columns.map((f) => `<td>${pyG((s.features || {})[f])}</td>`).join("");
    const c = s.clip;
    let facts;
    if (!c) facts = `<td>–</td><td>–</td><td>–</td><td>–</td><td>${contactsStrip(s)}</td><td>–</td>`;
    else {
      let trim = c.range ? `<br>range ${pair(c.range)} s${c.auto ? " (auto)" : ""}` : "";
      trim += (c.guesses || []).map((g) => `<br><span class="tag guess">${esc(g)}</span>`).join("");
      facts = `<td>${pyG(c.fps)}</td><td>${c.frames}</td>`
        + `<td>${pyG(c.mpu)} m/unit<br><small>${esc(c.units)}</small></td>`
        + `<td>up ${esc(c.up)}<br>root ${esc(c.root)}<br>facing ${esc(c.facing)}${trim}</td>`
        + `<td>${contactsStrip(s)}</td><td>${(c.notes || []).map(esc).join("<br>") || "–"}</td>`;
    }
    return `<tr data-clip-row="${i}"><th scope="row">${esc(s.name)}${kind}<br><small>${esc(s.source)}</small></th>`
      + `<td>${pair(s.position)}</td><td>${pair(s.snap, 3)}</td><td>${pair(s.manual)}</td>${cells}${facts}</tr>`;
  }
  // Per table: how many rows, how to render row i, and the text its filter box matches.
  const tableRows = {
    "diagnostics-table": [data.diagnostics.length, diagnosticRow,
      (i) => { const d = data.diagnostics[i]; return [d.severity, d.rule, d.code, d.message, d.hint || "", ...d.clips].join(" "); }],
    "placeholders-table": [data.placeholders.length, placeholderRow,
      (i) => { const p = data.placeholders[i]; return [p.priority, p.rule, p.reason].join(" "); }],
    "clips-table": [data.samples.length, clipRow,
      (i) => { const s = data.samples[i]; return `${s.name} ${s.source} ${s.fix || ""}`; }],
  };

  function makePager(id, keep) {
    const table = document.getElementById(id);
    const box = document.querySelector(`.pager[data-for="${id}"]`);
    if (!table || !box || !tableRows[id]) return;
    const [count, renderRow, textOf] = tableRows[id];
    const rows = { length: count };
    const search = Array.from({ length: count }, (_, i) => textOf(i).toLowerCase());
    const body = table.tBodies[0];
    const input = box.querySelector("input");
    const info = box.querySelector(".page-info");
    const [previous, next] = box.querySelectorAll("button");
    const size = data.page_size;
    const state = { page: 0, shown: [] };
    const refilter = () => {
      const query = input.value.trim().toLowerCase();
      state.shown = [];
      for (let i = 0; i < rows.length; i++) {
        if ((!query || search[i].includes(query)) && (!keep || keep(i))) state.shown.push(i);
      }
    };
    const render = () => {
      const pages = Math.max(1, Math.ceil(state.shown.length / size));
      state.page = Math.min(Math.max(state.page, 0), pages - 1);
      const first = state.page * size;
      const page = state.shown.slice(first, first + size);
      body.innerHTML = page.map(renderRow).join("");
      info.textContent = (page.length ? `${first + 1}–${first + page.length} of ${state.shown.length}` : `0 of ${state.shown.length}`)
        + (state.shown.length < rows.length ? ` (${rows.length} in all)` : "") + ` · page ${state.page + 1} of ${pages}`;
      previous.disabled = state.page === 0;
      next.disabled = state.page >= pages - 1;
      box.dataset.page = String(state.page + 1);
    };
    const update = () => { refilter(); state.page = 0; render(); };
    input.addEventListener("input", update);
    box.addEventListener("click", (event) => {
      const button = event.target.closest("[data-step]");
      if (button) { state.page += +button.dataset.step; render(); }
    });
    // Show row i (clearing the text filter if it hides it); false when another filter hides it.
    const reveal = (i) => {
      let at = state.shown.indexOf(i);
      if (at < 0 && input.value) { input.value = ""; refilter(); at = state.shown.indexOf(i); }
      if (at < 0) return false;
      if (Math.floor(at / size) !== state.page) { state.page = Math.floor(at / size); render(); }
      return true;
    };
    pagers[id] = { update, reveal, shown: () => state.shown.length, total: rows.length };
    update();
  }

  // Diagnostics filters: severity checkboxes and a rule menu, applied through the pager.
  const filters = document.getElementById("diagnostic-filters");
  const keepDiagnostic = (i) => {
    if (!filters) return true;
    const d = data.diagnostics[i];
    const severities = new Set([...filters.querySelectorAll("input[name=severity]:checked")].map((b) => b.value));
    const rule = filters.querySelector("select[name=rule]").value;
    return severities.has(d.severity) && (!rule || d.rule === rule);
  };
  makePager("diagnostics-table", keepDiagnostic);
  makePager("placeholders-table");
  makePager("clips-table");
  function applyFilters() {
    const pager = pagers["diagnostics-table"];
    if (!filters || !pager) return;
    pager.update();
    document.getElementById("diagnostic-count").textContent = `${pager.shown()} of ${pager.total} shown`;
  }
  if (filters) { filters.addEventListener("change", applyFilters); applyFilters(); }

  // Diagram layers.
  document.getElementById("layer-toggles").addEventListener("change", (event) => {
    const layer = event.target.dataset.layer;
    if (layer) space.classList.toggle(`hide-${layer}`, !event.target.checked);
  });

  // Trajectory-error map: placement switch and readout under the pointer.
  const heat = document.getElementById("heat");
  const readout = document.getElementById("heat-point");
  let mode = "measured";
  const modeSwitch = document.getElementById("heat-mode");
  if (modeSwitch) {
    modeSwitch.addEventListener("change", (event) => {
      mode = event.target.value;
      // SVG elements have no `hidden` property: toggle the attribute the stylesheet hides.
      for (const view of heat.querySelectorAll(".heat-view")) view.toggleAttribute("hidden", view.dataset.mode !== mode);
    });
  }
  heat.addEventListener("mousemove", (event) => {
    const h = data.heat;
    const grid = h[mode];
    const point = new DOMPoint(event.clientX, event.clientY).matrixTransform(heat.getScreenCTM().inverse());
    const fx = (point.x - h.box[0]) / (h.box[2] - h.box[0]);
    const fy = (h.box[3] - point.y) / (h.box[3] - h.box[1]);
    if (!grid || fx < 0 || fx > 1 || fy < 0 || fy > 1) { readout.textContent = "Point at the map to read the error there."; return; }
    const col = Math.round(fx * (h.nx - 1));
    const row = Math.round(fy * (h.ny - 1));
    const x = ax.min + (col / (h.nx - 1)) * (ax.max - ax.min);
    const y = ay.min + (row / (h.ny - 1)) * (ay.max - ay.min);
    const ex = grid.ex[row * h.nx + col];
    const ey = grid.ey[row * h.nx + col];
    const at = `at ${ax.feature} ${num(x)} ${ax.unit}, ${ay.feature} ${num(y)} ${ay.unit}: `;
    if (ex === null) { readout.textContent = `${at}outside the hull (the engine clamps to its edge)`; return; }
    const distance = Math.hypot((ex / (ax.max - ax.min)) * 100, (ey / (ay.max - ay.min)) * 100);
    readout.textContent = `${at}off by ${num(ex, 3)} ${ax.unit} and ${num(ey, 3)} ${ay.unit} (${num(distance, 3)}% of an axis)`;
  });
})();

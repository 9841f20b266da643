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
  const sampleMarker = (name) => space.querySelector(`[data-sample="${CSS.escape(name)}"]`);

  function clearSelection() {
    for (const el of document.querySelectorAll(".highlight")) el.classList.remove("highlight");
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
    const row = diagnosticRows && diagnosticRows.querySelector(`[data-diagnostic="${i}"]`);
    mark([row, ...d.clips.map(sampleMarker), ...space.querySelectorAll(`[data-diagnostic-shape="${i}"]`)]);
    const clips = d.clips.map((c) => (sampleIndex.has(c) ? `<a data-goto-sample="${sampleIndex.get(c)}">${esc(c)}</a>` : esc(c)));
    details.innerHTML = `<h3><span class="sev sev-${esc(d.severity)}">${esc(d.severity)}</span> ${esc(d.rule)} <small>${esc(d.code)}</small></h3>`
      + `<p>${esc(d.message)}</p>` + (d.hint ? `<p><strong>hint:</strong> ${esc(d.hint)}</p>` : "")
      + `<dl><dt>clips</dt><dd>${clips.join(", ") || "–"}</dd><dt>where</dt><dd>${pos(d.position)}</dd>`
      + (d.fix ? `<dt>automatic fix</dt><dd>${esc(d.fix)}</dd>` : "") + "</dl>";
  }

  function selectPlaceholder(i) {
    const p = data.placeholders[i];
    clearSelection();
    mark([space.querySelector(`[data-placeholder="${i}"]`), document.querySelector(`[data-placeholder-row="${i}"]`)]);
    const features = Object.entries(p.features || {}).map(([k, v]) => `<dt>${esc(k)}</dt><dd>${num(v)}</dd>`).join("");
    details.innerHTML = `<h3><span class="prio ${esc(p.priority)}">${esc(p.priority)}</span> clip to add</h3>`
      + `<p>${esc(p.reason)}</p><dl><dt>position</dt><dd>${pos(p.position)}</dd><dt>rule</dt><dd>${esc(p.rule)}</dd>${features}</dl>`;
  }

  function pick(target) {
    const el = target.closest("[data-sample],[data-placeholder],[data-diagnostic-shape]");
    if (!el) return false;
    if (el.dataset.sample !== undefined) selectSample(sampleIndex.get(el.dataset.sample));
    else if (el.dataset.placeholder !== undefined) selectPlaceholder(+el.dataset.placeholder);
    else selectDiagnostic(+el.dataset.diagnosticShape);
    return true;
  }

  space.addEventListener("click", (event) => { if (!pick(event.target)) { clearSelection(); } });
  space.addEventListener("mousemove", (event) => {
    const el = event.target.closest("[data-sample],[data-placeholder],[data-diagnostic-shape]");
    if (!el) { tooltip.hidden = true; return; }
    let text;
    if (el.dataset.sample !== undefined) {
      const s = data.samples[sampleIndex.get(el.dataset.sample)];
      text = `${s.name} ${posText(s.position)}`;
    } else if (el.dataset.placeholder !== undefined) {
      const p = data.placeholders[+el.dataset.placeholder];
      text = `${p.priority}: ${p.reason} ${posText(p.position)}`;
    } else {
      const d = data.diagnostics[+el.dataset.diagnosticShape];
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

  // Diagnostics filters: severity checkboxes and a rule menu.
  const filters = document.getElementById("diagnostic-filters");
  function applyFilters() {
    if (!filters || !diagnosticRows) return;
    const severities = new Set([...filters.querySelectorAll("input[name=severity]:checked")].map((b) => b.value));
    const rule = filters.querySelector("select[name=rule]").value;
    let shown = 0;
    for (const row of diagnosticRows.rows) {
      const visible = severities.has(row.dataset.severity) && (!rule || row.dataset.rule === rule);
      row.hidden = !visible;
      shown += visible;
    }
    document.getElementById("diagnostic-count").textContent = `${shown} of ${diagnosticRows.rows.length} shown`;
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

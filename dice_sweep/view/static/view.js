// dice-sweep view: the page. Draws the sweep file's final-state diagram, zooms by asking
// /api/map for the visible range at screen resolution, rolls a clicked pixel with /api/roll
// and draws it as in Smith 2014's Fig. 5. No library: canvas 2D and fetch only.
"use strict";

(function () {
  // --- figure layout, CSS pixels --------------------------------------------------------
  const PLOT = { left: 84, top: 48, width: 512, height: 400 };
  const FIGURE = { width: PLOT.left + PLOT.width + 150, height: PLOT.top + PLOT.height + 58 };
  const DIE_SIZE = { width: 520, height: 330 };
  const OUTLINES = 12; // die outlines of the roll picture, at equal times (as plot_roll)
  const MAX_LAYERS = 12; // computed maps kept to draw under later ones
  const WHEEL_STEP = 0.0015; // zoom factor per wheel delta unit: exp(deltaY * WHEEL_STEP)
  const WHEEL_SETTLE_MS = 350; // a zoom by wheel is computed once the wheel rests this long
  const MIN_DRAG_PX = 5; // a drag shorter than this is a click

  const $ = (id) => document.getElementById(id);
  const mapCanvas = $("map");
  const overlay = $("overlay");
  const dieCanvas = $("die");

  const state = {
    file: null, // /api/file
    view: null, // {xmin, xmax, ymin, ymax}
    history: [],
    layers: [], // [file layer, computed layers...], drawn in order
    computing: null, // {controller, layer}
    requests: [], // every /api/map asked for: what tests read
    roll: null, // last /api/roll answer
    marker: null, // {x, y} of the rolled pixel
    status: "loading",
    drag: null,
    wheelTimer: null,
    animation: null,
  };

  // --- helpers ---------------------------------------------------------------------------
  function setupCanvas(canvas, width, height) {
    const ratio = window.devicePixelRatio || 1;
    canvas.width = Math.round(width * ratio);
    canvas.height = Math.round(height * ratio);
    canvas.style.width = width + "px";
    canvas.style.height = height + "px";
    const ctx = canvas.getContext("2d");
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    return ctx;
  }

  function hexToRgb(hex) {
    const v = parseInt(hex.slice(1), 16);
    return [(v >> 16) & 255, (v >> 8) & 255, v & 255];
  }

  function fmt(value, digits) {
    if (!isFinite(value)) return String(value);
    return Number(value.toPrecision(digits || 6)).toString();
  }

  function pct(share) {
    return (100 * share).toFixed(share > 0 && share < 0.001 ? 3 : 1) + " %";
  }

  function axisLabel(axis) {
    return axis.param + " (" + axis.unit + ")";
  }

  function sameView(a, b) {
    return a && b && a.xmin === b.xmin && a.xmax === b.xmax && a.ymin === b.ymin && a.ymax === b.ymax;
  }

  function fileView() {
    const f = state.file;
    return { xmin: f.x.min, xmax: f.x.max, ymin: f.y.min, ymax: f.y.max };
  }

  // --- colours ---------------------------------------------------------------------------
  let palette = null; // code -> [r, g, b]
  function colourOf(code) {
    if (code >= 0) return palette.sides[code] || [128, 128, 128];
    return code === -1 ? palette.undecided : palette.notComputed;
  }

  // --- layers: a map over a range, as an image one pixel per cell -------------------------
  function makeLayer(range, nx, ny, source) {
    const canvas = document.createElement("canvas");
    canvas.width = nx;
    canvas.height = ny;
    return {
      ...range, nx, ny, source,
      outcome: new Int16Array(nx * ny),
      pMax: null, entropy: null, // a probability map's: the most likely outcome's p, the entropy (nats)
      rowDone: new Uint8Array(ny),
      canvas, ctx: canvas.getContext("2d"),
      stats: null, complete: false,
    };
  }

  function fillRows(layer, first, rows, pMax, entropy) {
    // row 0 is the lowest y: it goes to the bottom line of the image; a probability map's
    // most likely outcome fades to white as its p falls to 1 / (n + 1), as plotting.shaded_sides
    const count = rows.length;
    const floor = 1 / (state.file.sides + 1);
    if (pMax && !layer.pMax) {
      layer.pMax = new Float32Array(layer.nx * layer.ny);
      layer.entropy = new Float32Array(layer.nx * layer.ny);
    }
    const image = layer.ctx.createImageData(layer.nx, count);
    for (let r = 0; r < count; r++) {
      const row = rows[r];
      const line = count - 1 - r;
      for (let i = 0; i < layer.nx; i++) {
        const code = row[i];
        layer.outcome[(first + r) * layer.nx + i] = code;
        let [red, green, blue] = colourOf(code);
        if (pMax) {
          const p = pMax[r][i];
          layer.pMax[(first + r) * layer.nx + i] = p;
          layer.entropy[(first + r) * layer.nx + i] = entropy[r][i];
          const strength = code === state.file.not_computed_code ? 1 : Math.min(1, Math.max(0, (p - floor) / (1 - floor)));
          [red, green, blue] = [red, green, blue].map((c) => Math.round(255 - strength * (255 - c)));
        }
        const k = 4 * (line * layer.nx + i);
        image.data[k] = red;
        image.data[k + 1] = green;
        image.data[k + 2] = blue;
        image.data[k + 3] = 255;
      }
      layer.rowDone[first + r] = 1;
    }
    layer.ctx.putImageData(image, 0, layer.ny - first - count);
  }

  function addLayer(layer) {
    state.layers.push(layer);
    const computed = state.layers.filter((l) => l.source !== "file");
    if (computed.length > MAX_LAYERS) state.layers.splice(state.layers.indexOf(computed[0]), 1);
  }

  function removeLayer(layer) {
    const i = state.layers.indexOf(layer);
    if (i > 0) state.layers.splice(i, 1);
  }

  // the layer drawn on top at (x, y) whose row there is computed, and its cell
  function cellAt(x, y) {
    for (let k = state.layers.length - 1; k >= 0; k--) {
      const l = state.layers[k];
      if (x < l.xmin || x > l.xmax || y < l.ymin || y > l.ymax) continue;
      const i = Math.min(l.nx - 1, Math.floor(((x - l.xmin) / (l.xmax - l.xmin)) * l.nx));
      const j = Math.min(l.ny - 1, Math.floor(((y - l.ymin) / (l.ymax - l.ymin)) * l.ny));
      if (!l.rowDone[j]) continue;
      // the cell's own centre, what was rolled; a sampled file layer names its cells
      const fi = l.xIndex ? l.xIndex[i] : i, fj = l.yIndex ? l.yIndex[j] : j;
      const cols = l.xIndex ? l.fileNum[0] : l.nx, rows = l.yIndex ? l.fileNum[1] : l.ny;
      return {
        layer: l, i: fi, j: fj,
        code: l.outcome[j * l.nx + i],
        p: l.pMax ? l.pMax[j * l.nx + i] : null,
        entropy: l.entropy ? l.entropy[j * l.nx + i] : null,
        x: l.xmin + ((fi + 0.5) * (l.xmax - l.xmin)) / cols,
        y: l.ymin + ((fj + 0.5) * (l.ymax - l.ymin)) / rows,
      };
    }
    return null;
  }

  // --- coordinates -----------------------------------------------------------------------
  const toScreenX = (x) => PLOT.left + ((x - state.view.xmin) / (state.view.xmax - state.view.xmin)) * PLOT.width;
  const toScreenY = (y) => PLOT.top + PLOT.height - ((y - state.view.ymin) / (state.view.ymax - state.view.ymin)) * PLOT.height;
  const toDataX = (px) => state.view.xmin + ((px - PLOT.left) / PLOT.width) * (state.view.xmax - state.view.xmin);
  const toDataY = (py) => state.view.ymin + ((PLOT.top + PLOT.height - py) / PLOT.height) * (state.view.ymax - state.view.ymin);
  const inPlot = (px, py) => px >= PLOT.left && px < PLOT.left + PLOT.width && py >= PLOT.top && py < PLOT.top + PLOT.height;

  // --- ticks -----------------------------------------------------------------------------
  function ticks(lo, hi, count) {
    const raw = (hi - lo) / count;
    const power = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 2.5, 5, 10].map((m) => m * power).find((s) => s >= raw) || 10 * power;
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
    const decimals = Math.max(0, -Math.floor(Math.log10(step) + 1e-9) + (step / power === 2.5 ? 1 : 0));
    return { values: out, label: (v) => (decimals > 12 ? v.toExponential(3) : v.toFixed(decimals)) };
  }

  // --- the figure ------------------------------------------------------------------------
  let mapCtx = null;
  let overlayCtx = null;

  function render() {
    const ctx = mapCtx;
    const f = state.file;
    ctx.save();
    ctx.fillStyle = "#ffffff";
    ctx.fillRect(0, 0, FIGURE.width, FIGURE.height);
    // title: the file's run, as plotting.outcome_title
    ctx.fillStyle = "#1d1d1f";
    ctx.font = "13px system-ui, sans-serif";
    ctx.textAlign = "center";
    f.title.split("\n").forEach((line, k, all) => ctx.fillText(line, PLOT.left + PLOT.width / 2, PLOT.top - 10 - 15 * (all.length - 1 - k)));
    // the map: every layer that overlaps the view, later ones on top
    ctx.save();
    ctx.beginPath();
    ctx.rect(PLOT.left, PLOT.top, PLOT.width, PLOT.height);
    ctx.clip();
    ctx.fillStyle = "#e9ebee"; // outside the file's range
    ctx.fillRect(PLOT.left, PLOT.top, PLOT.width, PLOT.height);
    ctx.imageSmoothingEnabled = false;
    const v = state.view;
    for (const l of state.layers) {
      const x0 = Math.max(v.xmin, l.xmin), x1 = Math.min(v.xmax, l.xmax);
      const y0 = Math.max(v.ymin, l.ymin), y1 = Math.min(v.ymax, l.ymax);
      if (!(x1 > x0 && y1 > y0)) continue;
      // source rectangle in cells (image y runs down), destination in screen pixels
      const sx = ((x0 - l.xmin) / (l.xmax - l.xmin)) * l.nx;
      const sw = ((x1 - x0) / (l.xmax - l.xmin)) * l.nx;
      const sy = ((l.ymax - y1) / (l.ymax - l.ymin)) * l.ny;
      const sh = ((y1 - y0) / (l.ymax - l.ymin)) * l.ny;
      const dx = toScreenX(x0), dy = toScreenY(y1);
      ctx.drawImage(l.canvas, sx, sy, sw, sh, dx, dy, toScreenX(x1) - dx, toScreenY(y0) - dy);
    }
    ctx.restore();
    // frame, ticks, labels
    ctx.strokeStyle = "#1d1d1f";
    ctx.lineWidth = 1;
    ctx.strokeRect(PLOT.left - 0.5, PLOT.top - 0.5, PLOT.width + 1, PLOT.height + 1);
    ctx.font = "12px system-ui, sans-serif";
    ctx.fillStyle = "#1d1d1f";
    const bottom = PLOT.top + PLOT.height;
    drawTicks(ctx, v.xmin, v.xmax, "center", "top", (value) => {
      const px = Math.round(toScreenX(value)) + 0.5;
      return [px, bottom, px, bottom + 5, px, bottom + 8];
    });
    ctx.font = "13px system-ui, sans-serif";
    ctx.fillText(axisLabel(f.x), PLOT.left + PLOT.width / 2, bottom + 30);
    ctx.font = "12px system-ui, sans-serif";
    drawTicks(ctx, v.ymin, v.ymax, "right", "middle", (value) => {
      const py = Math.round(toScreenY(value)) + 0.5;
      return [PLOT.left - 5, py, PLOT.left, py, PLOT.left - 8, py];
    });
    ctx.save();
    ctx.translate(16, PLOT.top + PLOT.height / 2);
    ctx.rotate(-Math.PI / 2);
    ctx.textAlign = "center";
    ctx.font = "13px system-ui, sans-serif";
    ctx.fillText(axisLabel(f.y), 0, 0);
    ctx.restore();
    drawLegend(ctx);
    ctx.restore();
    drawOverlay();
  }

  // ticks of one axis: at(value) gives the mark from (x0, y0) to (x1, y1) and the label's place
  function drawTicks(ctx, lo, hi, align, baseline, at) {
    const t = ticks(lo, hi, 6);
    ctx.textAlign = align;
    ctx.textBaseline = baseline;
    for (const value of t.values) {
      const [x0, y0, x1, y1, lx, ly] = at(value);
      ctx.beginPath(); ctx.moveTo(x0, y0); ctx.lineTo(x1, y1); ctx.stroke();
      ctx.fillText(t.label(value), lx, ly);
    }
  }

  function drawLegend(ctx) {
    // a colour bar as the paper's figures: not computed (if any), undecided, then side 0 up
    const entries = [];
    if (!state.file.complete) entries.push(["not computed", state.file.colors.not_computed]);
    entries.push(["undecided", state.file.colors.undecided]);
    state.file.colors.sides.forEach((c, k) => entries.push(["side " + k, c]));
    const left = PLOT.left + PLOT.width + 22;
    const h = PLOT.height / entries.length;
    const every = Math.ceil(entries.length / 24);
    ctx.font = (entries.length > 14 ? "11px" : "12px") + " system-ui, sans-serif";
    ctx.textAlign = "left";
    ctx.textBaseline = "middle";
    entries.forEach(([label, colour], k) => {
      const top = PLOT.top + PLOT.height - (k + 1) * h;
      ctx.fillStyle = colour;
      ctx.fillRect(left, top, 18, h);
      ctx.fillStyle = "#1d1d1f";
      if (k % every === 0 || k < 2) ctx.fillText(label, left + 26, top + h / 2);
    });
    ctx.strokeStyle = "#1d1d1f";
    ctx.strokeRect(left - 0.5, PLOT.top - 0.5, 19, PLOT.height + 1);
  }

  function drawOverlay() {
    const ctx = overlayCtx;
    ctx.clearRect(0, 0, FIGURE.width, FIGURE.height);
    if (state.drag && state.drag.moved) {
      const d = state.drag;
      ctx.strokeStyle = "#ffffff";
      ctx.lineWidth = 1.5;
      ctx.setLineDash([]);
      ctx.strokeRect(Math.min(d.x0, d.x1), Math.min(d.y0, d.y1), Math.abs(d.x1 - d.x0), Math.abs(d.y1 - d.y0));
      ctx.strokeStyle = "#000000";
      ctx.setLineDash([4, 4]);
      ctx.strokeRect(Math.min(d.x0, d.x1), Math.min(d.y0, d.y1), Math.abs(d.x1 - d.x0), Math.abs(d.y1 - d.y0));
      ctx.setLineDash([]);
    }
    if (state.marker) {
      const px = toScreenX(state.marker.x), py = toScreenY(state.marker.y);
      if (inPlot(px, py)) {
        for (const [colour, width] of [["#ffffff", 3], ["#000000", 1.2]]) {
          ctx.strokeStyle = colour;
          ctx.lineWidth = width;
          ctx.beginPath();
          ctx.arc(px, py, 6, 0, 2 * Math.PI);
          ctx.moveTo(px - 10, py); ctx.lineTo(px - 3, py);
          ctx.moveTo(px + 3, py); ctx.lineTo(px + 10, py);
          ctx.moveTo(px, py - 10); ctx.lineTo(px, py - 3);
          ctx.moveTo(px, py + 3); ctx.lineTo(px, py + 10);
          ctx.stroke();
        }
      }
    }
  }

  // --- the panel of the view's numbers -----------------------------------------------------
  function showStats(stats, source) {
    $("stats-source").textContent = source;
    const table = $("shares");
    table.replaceChildren();
    if (!stats) return;
    const rows = stats.shares.sides.map((share, k) => ["side " + k, state.file.colors.sides[k], share]);
    rows.push(["undecided", state.file.colors.undecided, stats.shares.undecided]);
    for (const [label, colour, share] of rows) {
      const tr = table.insertRow();
      const swatch = document.createElement("span");
      swatch.className = "swatch";
      swatch.style.background = colour;
      tr.insertCell().append(swatch);
      tr.insertCell().textContent = label;
      tr.insertCell().textContent = pct(share);
      const bar = document.createElement("span");
      bar.className = "bar";
      bar.style.width = Math.round(160 * share) + "px";
      tr.insertCell().append(bar);
    }
    const e = stats.basin_entropy;
    $("entropy").textContent = e
      ? `Basin entropy Sb = ${e.Sb.toFixed(4)}, boundary basin entropy Sbb = ${e.Sbb === null ? "n/a (no boundary)" : e.Sbb.toFixed(4)} ` +
        `(boxes of ${e.box_size} x ${e.box_size} cells; ${e.boundary_boxes} of ${e.boxes} on a boundary)` +
        (e.Sbb_above_log2 ? "; Sbb > ln 2: the boundary is fractal." : ".")
      : "Basin entropy: needs a whole map of at least 5 x 5 cells.";
    const m = stats.probability; // a probability map: the shares above are of the most likely sides
    if (m) {
      const [low, high] = m.predictable_share_range_from_draws;
      $("entropy").textContent += ` ${m.draws} draws per cell: one side at p >= ${m.predictable_probability} on ` +
        `${pct(m.predictable_share)} of the cells (${pct(low)} to ${pct(high)} within the draws), mean outcome entropy ` +
        `${m.basin_entropy_nats.toFixed(3)} nats (${m.basin_entropy_miller_madow_nats.toFixed(3)} Miller-Madow).`;
    }
  }

  function describeLayer(l) {
    if (l.source === "file") {
      const sampled = l.fileNum ? `, ${l.nx} x ${l.ny} of them sent` : "";
      return `the file's ${state.file.x.num} x ${state.file.y.num} cells (${state.file.name}${sampled})`;
    }
    return `the kernel, ${l.nx} x ${l.ny} cells` + (l.seconds !== undefined ? ` in ${l.seconds.toFixed(2)} s` : "");
  }

  function refreshStats() {
    const top = [...state.layers].reverse().find((l) => sameView(l, state.view) && l.complete);
    if (top) showStats(top.stats, "Shares of the view's cells, from " + describeLayer(top) + ".");
    else showStats(null, state.computing ? "Computing this view ..." : "Not computed at this range yet.");
  }

  // --- zoom ------------------------------------------------------------------------------
  function resolution() {
    const share = parseFloat($("resolution").value);
    const scale = Math.min(share, state.file.max_pixels / PLOT.width, state.file.max_pixels / PLOT.height);
    return { nx: Math.max(1, Math.round(PLOT.width * scale)), ny: Math.max(1, Math.round(PLOT.height * scale)) };
  }

  function clampView(v) {
    // the page stays inside the file's range: beyond it a start may put the die into the table
    const f = fileView();
    const clamp1 = (lo, hi, flo, fhi) => {
      if (hi - lo >= fhi - flo) return [flo, fhi];
      if (lo < flo) return [flo, flo + (hi - lo)];
      if (hi > fhi) return [fhi - (hi - lo), fhi];
      return [lo, hi];
    };
    const [xmin, xmax] = clamp1(v.xmin, v.xmax, f.xmin, f.xmax);
    const [ymin, ymax] = clamp1(v.ymin, v.ymax, f.ymin, f.ymax);
    return { xmin, xmax, ymin, ymax };
  }

  function setView(v, remember) {
    if (remember && state.view && !sameView(v, state.view)) state.history.push(state.view);
    state.view = v;
    $("back").disabled = state.history.length === 0;
    const exact = [...state.layers].reverse().find((l) => sameView(l, v) && l.complete);
    if (exact) { // seen before: draw it on top again rather than roll it again
      state.layers.splice(state.layers.indexOf(exact), 1);
      if (exact.source === "file") state.layers.unshift(exact); else state.layers.push(exact);
    }
    render();
    refreshStats();
  }

  function zoomTo(v) {
    setView(clampView(v), true);
    compute();
  }

  function cancelComputation() {
    if (!state.computing) return;
    state.computing.controller.abort();
    const layer = state.computing.layer;
    if (!layer.complete && !layer.rowDone.some((d) => d)) removeLayer(layer);
    state.computing = null;
    $("progress").hidden = true;
    state.status = "idle";
  }

  async function compute() {
    cancelComputation();
    const v = state.view;
    if (sameView(v, fileView())) { // the file's own pixels are the answer
      render();
      refreshStats();
      return;
    }
    const { nx, ny } = resolution();
    if (state.layers.some((l) => sameView(l, v) && l.complete && l.nx === nx && l.ny === ny)) return;
    const params = new URLSearchParams({ xmin: v.xmin, xmax: v.xmax, ymin: v.ymin, ymax: v.ymax, nx, ny });
    state.requests.push({ xmin: v.xmin, xmax: v.xmax, ymin: v.ymin, ymax: v.ymax, nx, ny });
    const controller = new AbortController();
    const layer = makeLayer(v, nx, ny, "kernel");
    state.computing = { controller, layer };
    state.status = "computing";
    addLayer(layer);
    showProgress(0, nx * ny);
    $("status").textContent = "";
    refreshStats();
    try {
      const response = await fetch("/api/map?" + params + "&stream=1", { signal: controller.signal });
      if (!response.ok) {
        const error = await response.json().catch(() => ({ error: response.statusText }));
        throw new Error(error.error);
      }
      const reader = response.body.getReader();
      const decoder = new TextDecoder();
      let buffer = "";
      let result = null;
      for (;;) {
        const { value, done } = await reader.read();
        if (done) break;
        buffer += decoder.decode(value, { stream: true });
        let cut;
        while ((cut = buffer.indexOf("\n")) >= 0) {
          const line = buffer.slice(0, cut);
          buffer = buffer.slice(cut + 1);
          if (!line) continue;
          const message = JSON.parse(line);
          if (message.event === "band") {
            fillRows(layer, message.rows[0], message.outcome, message.p_max, message.entropy);
            showProgress(message.done, message.total);
            if (state.computing && state.computing.layer === layer) render();
          } else if (message.event === "result") {
            result = message;
          }
        }
      }
      if (!result) throw new Error("the server closed the connection before the map was done");
      fillRows(layer, 0, result.outcome, result.p_max, result.entropy);
      layer.stats = result.stats;
      layer.seconds = result.seconds;
      layer.complete = true;
      if (state.computing && state.computing.layer === layer) {
        state.computing = null;
        state.status = "idle";
        $("progress").hidden = true;
      }
      render();
      refreshStats();
    } catch (error) {
      if (error.name === "AbortError") return;
      removeLayer(layer);
      if (state.computing && state.computing.layer === layer) {
        state.computing = null;
        state.status = "error";
        $("progress").hidden = true;
      }
      $("status").textContent = "Zoom not computed: " + error.message;
      render();
      refreshStats();
    }
  }

  function showProgress(done, total) {
    $("progress").hidden = false;
    $("progress-bar").style.width = ((100 * done) / total).toFixed(1) + "%";
    $("progress-text").textContent = `rolling ${total} starts: ${Math.floor((100 * done) / total)} %`;
  }

  // --- mouse -------------------------------------------------------------------------------
  function eventPoint(event) {
    const rect = overlay.getBoundingClientRect();
    return [event.clientX - rect.left, event.clientY - rect.top];
  }

  function showReadout(px, py) {
    if (!inPlot(px, py)) {
      $("readout").textContent = "Hover the map for a pixel's initial condition and side; drag a box or scroll to zoom; click a pixel to roll it.";
      return;
    }
    const f = state.file;
    const cell = cellAt(toDataX(px), toDataY(py));
    if (!cell) {
      $("readout").textContent = `${f.x.param} = ${fmt(toDataX(px))} ${f.x.unit}, ${f.y.param} = ${fmt(toDataY(py))} ${f.y.unit}: not computed`;
      return;
    }
    let side = cell.code >= 0 ? "side " + cell.code : cell.code === -1 ? "undecided" : "not computed";
    if (cell.p !== null && cell.code !== state.file.not_computed_code) {
      side = `most likely ${side}, p = ${cell.p.toFixed(3)} of ${f.draws} draws, entropy ${cell.entropy.toFixed(3)} nats`;
    }
    $("readout").textContent =
      `${f.x.param} = ${fmt(cell.x, 8)} ${f.x.unit}, ${f.y.param} = ${fmt(cell.y, 8)} ${f.y.unit}: ${side}` +
      ` (cell ${cell.i}, ${cell.j} of ${describeLayer(cell.layer)})`;
  }

  function onMouseDown(event) {
    if (event.button !== 0) return;
    const [px, py] = eventPoint(event);
    if (!inPlot(px, py)) return;
    state.drag = { x0: px, y0: py, x1: px, y1: py, moved: false };
    event.preventDefault();
  }

  function onMouseMove(event) {
    const [px, py] = eventPoint(event);
    if (state.drag) {
      state.drag.x1 = Math.min(Math.max(px, PLOT.left), PLOT.left + PLOT.width);
      state.drag.y1 = Math.min(Math.max(py, PLOT.top), PLOT.top + PLOT.height);
      state.drag.moved = Math.abs(state.drag.x1 - state.drag.x0) >= MIN_DRAG_PX || Math.abs(state.drag.y1 - state.drag.y0) >= MIN_DRAG_PX;
      drawOverlay();
    }
    showReadout(px, py);
  }

  function onMouseUp(event) {
    const d = state.drag;
    if (!d) return;
    state.drag = null;
    if (d.moved && Math.abs(d.x1 - d.x0) >= MIN_DRAG_PX && Math.abs(d.y1 - d.y0) >= MIN_DRAG_PX) {
      zoomTo({
        xmin: toDataX(Math.min(d.x0, d.x1)), xmax: toDataX(Math.max(d.x0, d.x1)),
        ymin: toDataY(Math.max(d.y0, d.y1)), ymax: toDataY(Math.min(d.y0, d.y1)),
      });
    } else if (!d.moved) {
      const cell = cellAt(toDataX(d.x0), toDataY(d.y0));
      if (cell) roll(cell.x, cell.y);
    }
    drawOverlay();
  }

  function onWheel(event) {
    const [px, py] = eventPoint(event);
    if (!inPlot(px, py)) return;
    event.preventDefault();
    const factor = Math.exp(event.deltaY * WHEEL_STEP);
    const x = toDataX(px), y = toDataY(py), v = state.view;
    const next = clampView({
      xmin: x - (x - v.xmin) * factor, xmax: x + (v.xmax - x) * factor,
      ymin: y - (y - v.ymin) * factor, ymax: y + (v.ymax - y) * factor,
    });
    if (!state.wheelTimer) state.history.push(state.view); // one history step per wheel gesture
    state.view = next;
    $("back").disabled = false;
    cancelComputation();
    render();
    refreshStats();
    clearTimeout(state.wheelTimer);
    state.wheelTimer = setTimeout(() => { state.wheelTimer = null; setView(state.view, false); compute(); }, WHEEL_SETTLE_MS);
  }

  // --- one roll ------------------------------------------------------------------------------
  async function roll(x, y) {
    state.marker = { x, y };
    drawOverlay();
    const f = state.file;
    $("roll-text").textContent = `Rolling from ${f.x.param} = ${fmt(x, 8)} ${f.x.unit}, ${f.y.param} = ${fmt(y, 8)} ${f.y.unit} ...`;
    const response = await fetch("/api/roll?" + new URLSearchParams({ x, y }));
    const data = await response.json();
    if (!response.ok) {
      $("roll-text").textContent = "No roll: " + data.error;
      return;
    }
    state.roll = data;
    showRoll(data);
  }

  function rollSentence(r) {
    const impacts = r.counts.impacts;
    if (r.outcome >= 0) return `side ${r.outcome} after ${impacts} impacts, decided at t = ${r.t_decided.toFixed(4)} s`;
    return `undecided (${r.status}) after ${impacts} impacts, stopped at t = ${r.t_end.toFixed(4)} s`;
  }

  function showRoll(r) {
    const f = state.file;
    $("roll-text").textContent = rollSentence(r);
    $("roll-start").textContent = "Start: " + Object.entries(r.start).map(([k, v]) => `${k} = ${fmt(v, 8)}`).join(", ") +
      ` (SI units); the cell centre of ${f.x.param}, ${f.y.param}.`;
    const table = $("impacts");
    table.replaceChildren();
    const head = table.createTHead().insertRow();
    for (const name of ["#", "t (s)", "surface", "corner", "x (m)", "y (m)", "phi (rad)", "E (J/kg)"]) {
      const th = document.createElement("th");
      th.textContent = name;
      head.append(th);
    }
    const body = table.createTBody();
    r.impacts.forEach((impact, k) => {
      const tr = body.insertRow();
      for (const value of [k + 1, impact.t.toFixed(5), impact.surface, impact.corner, impact.x.toFixed(5), impact.y.toFixed(5), impact.phi.toFixed(3), impact.energy.toExponential(3)]) {
        tr.insertCell().textContent = value;
      }
    });
    if (r.impacts_listed < r.counts.impacts) {
      const tr = body.insertRow();
      const td = tr.insertCell();
      td.colSpan = 8;
      td.textContent = `${r.counts.impacts} impacts counted by the kernel; ${r.impacts_listed} recorded here.`;
    }
    $("play").disabled = false;
    stopAnimation();
    drawRoll(r, null);
  }

  // the die in world coordinates -> canvas, equal aspect (as plotting._draw_roll_scene)
  function rollFrame(r) {
    const R = r.die.circumradius, margin = 1.5 * R;
    let xmin, xmax;
    if (r.die.walls === null) {
      xmin = Math.min(...r.path.x) - margin;
      xmax = Math.max(...r.path.x) + margin;
    } else {
      xmin = -r.die.walls / 2 - margin;
      xmax = r.die.walls / 2 + margin;
    }
    const ymin = -margin, ymax = Math.max(Math.max(...r.path.y), 0) + margin;
    const pad = { left: 50, right: 12, top: 12, bottom: 30 };
    const w = DIE_SIZE.width - pad.left - pad.right, h = DIE_SIZE.height - pad.top - pad.bottom;
    const scale = Math.min(w / (xmax - xmin), h / (ymax - ymin));
    const cx = (xmin + xmax) / 2, cy = (ymin + ymax) / 2;
    return {
      X: (x) => pad.left + w / 2 + (x - cx) * scale,
      Y: (y) => pad.top + h / 2 - (y - cy) * scale,
      pad, w, h, scale, cx, cy,
    };
  }

  function corners(r, x, y, phi) {
    const n = r.die.sides, R = r.die.circumradius, out = [];
    for (let k = 0; k < n; k++) { // corner k at phi + 2 pi k / n (dice_sweep.geometry)
      const a = phi + (2 * Math.PI * k) / n;
      out.push([x + R * Math.cos(a), y + R * Math.sin(a)]);
    }
    return out;
  }

  function drawDie(ctx, frame, r, x, y, phi, alpha) {
    const pts = corners(r, x, y, phi);
    ctx.globalAlpha = alpha;
    ctx.strokeStyle = "#000000";
    ctx.lineWidth = 1;
    ctx.beginPath();
    pts.forEach(([px, py], k) => (k ? ctx.lineTo(frame.X(px), frame.Y(py)) : ctx.moveTo(frame.X(px), frame.Y(py))));
    ctx.closePath();
    ctx.stroke();
    ctx.strokeStyle = r.colors.sides[0]; // side 0 joins corners 0 and 1, in its own colour
    ctx.lineWidth = 2.5;
    ctx.beginPath();
    ctx.moveTo(frame.X(pts[0][0]), frame.Y(pts[0][1]));
    ctx.lineTo(frame.X(pts[1][0]), frame.Y(pts[1][1]));
    ctx.stroke();
    ctx.globalAlpha = 1;
  }

  function drawRoll(r, time) {
    const ctx = dieCtx;
    const frame = rollFrame(r);
    ctx.clearRect(0, 0, DIE_SIZE.width, DIE_SIZE.height);
    ctx.save();
    ctx.beginPath();
    ctx.rect(frame.pad.left, frame.pad.top, frame.w, frame.h);
    ctx.clip();
    ctx.fillStyle = "#d9d9d9"; // the table
    ctx.fillRect(frame.pad.left, frame.Y(0), frame.w, frame.h);
    ctx.strokeStyle = "#4d4d4d";
    ctx.lineWidth = 1;
    ctx.beginPath(); ctx.moveTo(frame.pad.left, frame.Y(0)); ctx.lineTo(frame.pad.left + frame.w, frame.Y(0)); ctx.stroke();
    if (r.die.walls !== null) {
      ctx.lineWidth = 1.5;
      for (const wx of [-r.die.walls / 2, r.die.walls / 2]) {
        ctx.beginPath(); ctx.moveTo(frame.X(wx), frame.pad.top); ctx.lineTo(frame.X(wx), frame.pad.top + frame.h); ctx.stroke();
      }
    }
    ctx.strokeStyle = "rgba(31, 119, 180, 0.7)"; // the centre's path
    ctx.lineWidth = 1;
    ctx.beginPath();
    r.path.x.forEach((x, k) => (k ? ctx.lineTo(frame.X(x), frame.Y(r.path.y[k])) : ctx.moveTo(frame.X(x), frame.Y(r.path.y[k]))));
    ctx.stroke();
    ctx.fillStyle = "#ff7f0e"; // the centre at each impact
    for (const impact of r.impacts) {
      ctx.beginPath(); ctx.arc(frame.X(impact.x), frame.Y(impact.y), 2, 0, 2 * Math.PI); ctx.fill();
    }
    const n = r.path.t.length;
    if (time === null) { // Fig. 5: outlines at equal times, later ones darker
      for (let k = 0; k < OUTLINES; k++) {
        const index = Math.round((k * (n - 1)) / (OUTLINES - 1));
        drawDie(ctx, frame, r, r.path.x[index], r.path.y[index], r.path.phi[index], 0.25 + (0.75 * (k + 1)) / OUTLINES);
      }
    } else {
      const index = Math.min(n - 1, Math.round((time / Math.max(r.t_end, 1e-12)) * (n - 1)));
      drawDie(ctx, frame, r, r.path.x[index], r.path.y[index], r.path.phi[index], 1);
    }
    ctx.restore();
    // axes in metres
    ctx.strokeStyle = "#1d1d1f";
    ctx.strokeRect(frame.pad.left - 0.5, frame.pad.top - 0.5, frame.w + 1, frame.h + 1);
    ctx.fillStyle = "#1d1d1f";
    ctx.font = "11px system-ui, sans-serif";
    const xr = [frame.cx - frame.w / 2 / frame.scale, frame.cx + frame.w / 2 / frame.scale];
    const yr = [frame.cy - frame.h / 2 / frame.scale, frame.cy + frame.h / 2 / frame.scale];
    const tx = ticks(xr[0], xr[1], 5), ty = ticks(yr[0], yr[1], 4);
    ctx.textAlign = "center"; ctx.textBaseline = "top";
    tx.values.forEach((v) => ctx.fillText(tx.label(v), frame.X(v), frame.pad.top + frame.h + 4));
    ctx.fillText("x (m)", frame.pad.left + frame.w / 2, frame.pad.top + frame.h + 16);
    ctx.textAlign = "right"; ctx.textBaseline = "middle";
    ty.values.forEach((v) => ctx.fillText(ty.label(v), frame.pad.left - 4, frame.Y(v)));
    ctx.save(); ctx.translate(10, frame.pad.top + frame.h / 2); ctx.rotate(-Math.PI / 2);
    ctx.textAlign = "center"; ctx.fillText("y (m)", 0, 0); ctx.restore();
    ctx.textAlign = "left"; ctx.textBaseline = "top";
    ctx.fillText(time === null ? rollSentence(r) : `t = ${time.toFixed(3)} s`, frame.pad.left + 6, frame.pad.top + 4);
  }

  function stopAnimation() {
    if (state.animation) cancelAnimationFrame(state.animation.frame);
    state.animation = null;
    $("play").textContent = "Play";
  }

  function play() {
    const r = state.roll;
    if (!r) return;
    if (state.animation) { stopAnimation(); drawRoll(r, null); return; }
    const speed = parseFloat($("speed").value);
    const started = performance.now();
    $("play").textContent = "Stop";
    const step = (now) => {
      const t = ((now - started) / 1000) * speed;
      if (t >= r.t_end) { stopAnimation(); drawRoll(r, null); return; }
      drawRoll(r, t);
      state.animation.frame = requestAnimationFrame(step);
    };
    state.animation = { frame: requestAnimationFrame(step) };
  }

  // --- export ------------------------------------------------------------------------------
  function currentResolution() {
    const v = state.view;
    const top = [...state.layers].reverse().find((l) => sameView(l, v));
    if (top && top.source === "file") return { nx: state.file.x.num, ny: state.file.y.num };
    return top ? { nx: top.nx, ny: top.ny } : resolution();
  }

  function configUrl() {
    const v = state.view;
    const { nx, ny } = currentResolution();
    return "/api/config?" + new URLSearchParams({ xmin: v.xmin, xmax: v.xmax, ymin: v.ymin, ymax: v.ymax, nx, ny });
  }

  function download(href, name) {
    const a = document.createElement("a");
    a.href = href;
    a.download = name;
    document.body.append(a);
    a.click();
    a.remove();
  }

  function baseName() {
    return state.file.name.replace(/\.[^.]*$/, "") + "_view";
  }

  // --- start -------------------------------------------------------------------------------
  let dieCtx = null;

  async function start() {
    mapCtx = setupCanvas(mapCanvas, FIGURE.width, FIGURE.height);
    overlayCtx = setupCanvas(overlay, FIGURE.width, FIGURE.height);
    dieCtx = setupCanvas(dieCanvas, DIE_SIZE.width, DIE_SIZE.height);
    const response = await fetch("/api/file");
    const f = await response.json();
    if (!response.ok) { $("status").textContent = f.error; return; }
    state.file = f;
    palette = { sides: f.colors.sides.map(hexToRgb), undecided: hexToRgb(f.colors.undecided), notComputed: hexToRgb(f.colors.not_computed) };
    document.title = f.name + " - dice-sweep view";
    $("file-name").textContent = f.name;
    $("file-info").textContent = `${f.sides} sides, ${f.x.num} x ${f.y.num} cells` + (f.complete ? "" : ", not complete");
    const layer = makeLayer(fileView(), f.outcome[0].length, f.outcome.length, "file");
    if (f.x.index || f.y.index) { // a large file, sampled (docs/view.md)
      layer.xIndex = f.x.index || null;
      layer.yIndex = f.y.index || null;
      layer.fileNum = [f.x.num, f.y.num];
    }
    fillRows(layer, 0, f.outcome, f.p_max, f.entropy);
    layer.stats = f.stats;
    layer.complete = true;
    state.layers = [layer];
    setView(fileView(), false);
    overlay.addEventListener("mousedown", onMouseDown);
    window.addEventListener("mousemove", (e) => { if (state.drag || e.target === overlay) onMouseMove(e); });
    window.addEventListener("mouseup", onMouseUp);
    overlay.addEventListener("mouseleave", () => showReadout(-1, -1));
    overlay.addEventListener("wheel", onWheel, { passive: false });
    $("back").addEventListener("click", back);
    $("reset").addEventListener("click", () => { cancelComputation(); setView(fileView(), true); });
    $("cancel").addEventListener("click", () => { cancelComputation(); refreshStats(); });
    $("resolution").addEventListener("change", compute);
    $("play").addEventListener("click", play);
    $("export-png").addEventListener("click", () => download(mapCanvas.toDataURL("image/png"), baseName() + ".png"));
    $("export-toml").addEventListener("click", () => download(configUrl(), baseName() + ".toml"));
    window.addEventListener("keydown", (e) => {
      if (e.target.tagName === "SELECT") return;
      if (e.key === "Escape") { state.drag = null; cancelComputation(); refreshStats(); drawOverlay(); }
      if (e.key === "Backspace") { e.preventDefault(); back(); }
      if (e.key === "Home") { cancelComputation(); setView(fileView(), true); }
    });
    state.status = "idle";
  }

  function back() {
    const previous = state.history.pop();
    if (!previous) return;
    cancelComputation();
    setView(previous, false);
    if (![...state.layers].some((l) => sameView(l, previous) && l.complete)) compute();
  }

  // what tests and scripts read (docs/view.md): the page's state and its actions
  window.diceView = {
    state,
    plot: PLOT,
    zoomTo: (xmin, xmax, ymin, ymax) => zoomTo({ xmin, xmax, ymin, ymax }),
    roll,
    configUrl,
    cellAt,
  };

  start().catch((error) => { $("status").textContent = "The page could not start: " + error.message; });
})();

// rtusniff report charts: plain SVG drawn from the JSON in #report-data, no library, no network.
// Drag across any time chart to zoom every time chart to that span; double-click or "whole
// capture" to see all of it again. Click a legend entry to hide or show its series.
"use strict";
(function () {
  const data = JSON.parse(document.getElementById("report-data").textContent);
  const SVG = "http://www.w3.org/2000/svg";
  const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
    "#bcbd22", "#7f7f7f"];
  const HEIGHT = 190, LEFT = 64, RIGHT = 12, TOP = 10, BOTTOM = 26;
  const STEPS = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1e3, 2e3, 5e3, 1e4, 15e3, 3e4, 6e4, 12e4, 3e5, 6e5, 9e5,
    18e5, 36e5, 72e5, 108e5, 216e5, 432e5, 864e5];
  const OPEN_GROUPS = 3;
  const whole = [data.t0, data.t0 + data.n * data.width];
  let view = whole.slice();
  const charts = [];

  function el(name, attrs, parent) {
    const node = document.createElementNS(SVG, name);
    for (const key in attrs) node.setAttribute(key, attrs[key]);
    if (parent) parent.appendChild(node);
    return node;
  }

  function pad(n, width) { return String(n).padStart(width, "0"); }

  function timeText(ms, step) {
    const d = new Date(ms);
    const clock = pad(d.getUTCHours(), 2) + ":" + pad(d.getUTCMinutes(), 2) + ":" + pad(d.getUTCSeconds(), 2);
    return step < 1000 ? clock + "." + pad(d.getUTCMilliseconds(), 3) : clock;
  }

  function numberText(v) {
    if (v === 0) return "0";
    const a = Math.abs(v);
    if (a >= 1e9) return Number((v / 1e9).toPrecision(3)) + "G";
    if (a >= 1e6) return Number((v / 1e6).toPrecision(3)) + "M";
    if (a >= 1e5) return Number((v / 1e3).toPrecision(3)) + "k";
    if (a < 1e-3) return v.toExponential(1);
    return String(Number(v.toPrecision(4)));
  }

  function dateText(ms) {
    const d = new Date(ms);
    return d.getUTCFullYear() + "-" + pad(d.getUTCMonth() + 1, 2) + "-" + pad(d.getUTCDate(), 2);
  }

  function niceTicks(lo, hi, count) {
    const span = hi - lo || Math.abs(hi) || 1;
    const raw = span / count, power = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 5, 10].map(m => m * power).find(s => s >= raw);
    const ticks = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) ticks.push(v);
    return ticks;
  }

  function visibleRange(chart) {
    const first = Math.max(0, Math.floor((view[0] - data.t0) / data.width));
    const last = Math.min(data.n, Math.ceil((view[1] - data.t0) / data.width));
    return [first, last];
  }

  function yRange(chart, first, last) {
    let lo = Infinity, hi = -Infinity;
    if (chart.type === "bars") {
      for (let i = first; i < last; i++) {
        let total = 0;
        chart.series.forEach((s, k) => { if (!chart.hidden[k]) total += s.values[i] || 0; });
        hi = Math.max(hi, total);
      }
      lo = 0;
    } else {
      chart.series.forEach((s, k) => {
        if (chart.hidden[k]) return;
        const lists = s.band ? [s.values, s.band[0], s.band[1]] : [s.values];
        for (const list of lists) for (let i = first; i < last; i++) {
          const v = list[i];
          if (v !== null && v !== undefined) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
        }
      });
      if (lo > 0) lo = 0;
    }
    if (!isFinite(hi)) { lo = 0; hi = 1; }
    if (hi === lo) hi = lo + 1;
    return [lo, hi + (hi - lo) * 0.05];
  }

  function drawTimeAxis(svg, width, x) {
    const span = view[1] - view[0];
    const crosses = dateText(view[0]) !== dateText(view[1]);
    // With dates, labels are wider: fewer of them.
    const room = (width - LEFT - RIGHT) / (crosses ? 150 : 95);
    const step = STEPS.find(s => span / s <= room) || STEPS[STEPS.length - 1];
    let day = "";
    for (let t = Math.ceil(view[0] / step) * step; t <= view[1]; t += step) {
      el("line", {x1: x(t), x2: x(t), y1: TOP, y2: HEIGHT - BOTTOM, class: "grid"}, svg);
      const anchor = x(t) > width - RIGHT - 60 ? "end" : x(t) < LEFT + 60 ? "start" : "middle";
      // The date where the day changes (and at the first tick), when the view spans two days or more.
      const date = crosses && dateText(t) !== day ? dateText(t) + " " : "";
      day = dateText(t);
      el("text", {x: x(t), y: HEIGHT - 8, class: "tick", "text-anchor": anchor}, svg).textContent =
        date + timeText(t, step);
    }
  }

  function drawValueAxis(svg, width, y, lo, hi) {
    for (const v of niceTicks(lo, hi, 4)) {
      el("line", {x1: LEFT, x2: width - RIGHT, y1: y(v), y2: y(v), class: "grid"}, svg);
      el("text", {x: LEFT - 6, y: y(v) + 4, class: "tick", "text-anchor": "end"}, svg).textContent = numberText(v);
    }
  }

  // Steps: each bucket's value across its width, joined to the next where both have one, so
  // that a lone bucket shows too.
  function linePath(values, first, last, x, y, hold) {
    let d = "", pen = false;
    for (let i = first; i < last; i++) {
      const v = values[i];
      if (v === null || v === undefined) { pen = pen && hold; continue; }
      const left = x(data.t0 + i * data.width), right = x(data.t0 + (i + 1) * data.width), py = y(v).toFixed(1);
      d += (pen ? "H" + left.toFixed(1) + "V" + py : "M" + left.toFixed(1) + " " + py) + "H" +
        Math.max(right, left + 1).toFixed(1);
      pen = true;
    }
    return d;
  }

  function bandPath(band, first, last, x, y) {
    const [lows, highs] = band;
    let d = "";
    for (let i = first; i < last; i++) {
      if (lows[i] === null || highs[i] === null || lows[i] === highs[i]) continue;
      const px = x(data.t0 + (i + 0.5) * data.width);
      d += "M" + px.toFixed(1) + " " + y(highs[i]).toFixed(1) + "V" + y(lows[i]).toFixed(1);
    }
    return d;
  }

  function drawTimeChart(chart) {
    const svg = chart.svg, width = chart.box.clientWidth || 800;
    svg.setAttribute("viewBox", "0 0 " + width + " " + HEIGHT);
    svg.setAttribute("width", width);
    while (svg.firstChild) svg.removeChild(svg.firstChild);
    const [first, last] = visibleRange(chart);
    const [lo, hi] = yRange(chart, first, last);
    const x = t => LEFT + (t - view[0]) / (view[1] - view[0]) * (width - LEFT - RIGHT);
    const y = v => HEIGHT - BOTTOM - (v - lo) / (hi - lo) * (HEIGHT - BOTTOM - TOP);
    drawValueAxis(svg, width, y, lo, hi);
    drawTimeAxis(svg, width, x);
    // Series stay inside the plot: a bucket cut by the view's edge is cut there too.
    const clip = el("clipPath", {id: "clip-" + chart.id}, el("defs", {}, svg));
    el("rect", {x: LEFT, y: TOP - 2, width: width - LEFT - RIGHT, height: HEIGHT - TOP - BOTTOM + 4}, clip);
    const plot = el("g", {"clip-path": "url(#clip-" + chart.id + ")"}, svg);
    if (chart.type === "bars") {
      const base = new Array(data.n).fill(0);
      const barWidth = Math.max(1, x(view[0] + data.width) - x(view[0]) - 0.5);
      chart.series.forEach((s, k) => {
        if (chart.hidden[k]) return;
        let d = "";
        for (let i = first; i < last; i++) {
          const v = s.values[i];
          if (!v) continue;
          const left = x(data.t0 + i * data.width);
          d += "M" + left.toFixed(1) + " " + y(base[i]).toFixed(1) + "h" + barWidth.toFixed(1) + "V" +
            y(base[i] + v).toFixed(1) + "h" + (-barWidth).toFixed(1) + "Z";
          base[i] += v;
        }
        el("path", {d: d, fill: COLORS[k % COLORS.length], class: "bars"}, plot);
      });
    } else {
      chart.series.forEach((s, k) => {
        if (chart.hidden[k]) return;
        const color = COLORS[k % COLORS.length];
        if (s.band) el("path", {d: bandPath(s.band, first, last, x, y), stroke: color, class: "band"}, plot);
        el("path", {d: linePath(s.values, first, last, x, y, chart.hold), stroke: color, class: "line"}, plot);
      });
    }
    el("rect", {x: LEFT, y: TOP, width: width - LEFT - RIGHT, height: HEIGHT - TOP - BOTTOM, class: "frame"}, svg);
    chart.x = x;
    chart.selection = el("rect", {x: 0, y: TOP, width: 0, height: HEIGHT - TOP - BOTTOM, class: "selection"}, svg);
    chart.cursor = el("line", {x1: -10, x2: -10, y1: TOP, y2: HEIGHT - BOTTOM, class: "cursor"}, svg);
  }

  function timeAt(chart, px) {
    const width = chart.box.clientWidth || 800;
    const share = Math.min(Math.max((px - LEFT) / (width - LEFT - RIGHT), 0), 1);
    return view[0] + share * (view[1] - view[0]);
  }

  function pointer(chart, event) {
    const box = chart.svg.getBoundingClientRect();
    return event.clientX - box.left;
  }

  function readout(chart, px) {
    const t = timeAt(chart, px), i = Math.floor((t - data.t0) / data.width);
    if (i < 0 || i >= data.n) { chart.readout.textContent = ""; return; }
    const parts = chart.series.map((s, k) => chart.hidden[k] || s.values[i] === null ? null
      : s.name + " " + numberText(s.values[i])).filter(Boolean);
    chart.readout.textContent = timeText(data.t0 + i * data.width, 1) + " UTC, bucket of " +
      numberText(data.width / 1000) + " s: " + (parts.join(", ") || "nothing");
  }

  function zoom(from, to) {
    const minimum = data.width * 4;
    if (to - from < minimum) { const mid = (from + to) / 2; from = mid - minimum / 2; to = mid + minimum / 2; }
    view = [Math.max(from, whole[0]), Math.min(to, whole[1])];
    document.getElementById("zoom-state").textContent = view[0] === whole[0] && view[1] === whole[1]
      ? "whole capture" : timeText(view[0], 1) + " – " + timeText(view[1], 1) + " UTC";
    charts.forEach(drawTimeChart);
  }

  function legend(chart, parent, redraw) {
    const list = document.createElement("div");
    list.className = "legend";
    chart.series.forEach((s, k) => {
      const item = document.createElement("button");
      item.type = "button";
      item.className = "key";
      item.style.setProperty("--key", COLORS[k % COLORS.length]);
      item.textContent = s.name;
      if (s.title) item.title = s.title;
      item.addEventListener("click", () => {
        chart.hidden[k] = !chart.hidden[k];
        item.classList.toggle("off", chart.hidden[k]);
        redraw();
      });
      list.appendChild(item);
    });
    parent.appendChild(list);
  }

  function timeChart(spec, parent) {
    const figure = document.createElement("figure");
    figure.className = "chart";
    figure.id = "chart-" + spec.id;
    const caption = document.createElement("figcaption");
    caption.textContent = spec.title + (spec.unit ? " (" + spec.unit + ")" : "");
    figure.appendChild(caption);
    const chart = Object.assign({}, spec, {hidden: spec.series.map(() => false), box: figure});
    legend(chart, figure, () => drawTimeChart(chart));
    chart.svg = el("svg", {class: "plot", height: HEIGHT, role: "img", "aria-label": spec.title}, figure);
    chart.readout = document.createElement("div");
    chart.readout.className = "readout";
    figure.appendChild(chart.readout);
    parent.appendChild(figure);
    let dragFrom = null;
    chart.svg.addEventListener("mousedown", event => { dragFrom = pointer(chart, event); event.preventDefault(); });
    chart.svg.addEventListener("mousemove", event => {
      const px = pointer(chart, event);
      chart.cursor.setAttribute("x1", px);
      chart.cursor.setAttribute("x2", px);
      readout(chart, px);
      if (dragFrom !== null) {
        chart.selection.setAttribute("x", Math.min(dragFrom, px));
        chart.selection.setAttribute("width", Math.abs(px - dragFrom));
      }
    });
    chart.svg.addEventListener("mouseup", event => {
      const px = pointer(chart, event);
      if (dragFrom !== null && Math.abs(px - dragFrom) > 4) {
        const a = timeAt(chart, dragFrom), b = timeAt(chart, px);
        zoom(Math.min(a, b), Math.max(a, b));
      }
      dragFrom = null;
    });
    chart.svg.addEventListener("mouseleave", () => { dragFrom = null; chart.selection.setAttribute("width", 0); });
    chart.svg.addEventListener("dblclick", () => zoom(whole[0], whole[1]));
    charts.push(chart);
  }

  function distributionChart(series, parent) {
    const figure = document.createElement("figure");
    figure.className = "chart";
    figure.id = "chart-latency-distribution";
    const caption = document.createElement("figcaption");
    caption.textContent = "Latency distribution per slave (answers per bar; ms, logarithmic)";
    figure.appendChild(caption);
    const svg = el("svg", {class: "plot", height: HEIGHT, role: "img", "aria-label": caption.textContent});
    parent.appendChild(figure);
    const legendChart = {series: series, hidden: series.map(() => false)};
    const lg = ms => Math.log10(Math.max(ms, 1e-3));
    // The logarithmic axis of the series shown: its ends (log10 of ms) and the chart's width.
    const axis = () => {
      const shown = series.filter((s, k) => !legendChart.hidden[k]);
      const lo = lg(Math.min(...shown.map(s => s.from[0]), 1e9));
      const hi = Math.max(lg(Math.max(...shown.map(s => s.to[s.to.length - 1]), 1e-3)), lo + 0.1);
      return {shown: shown, lo: lo, hi: hi, width: figure.clientWidth || 800};
    };
    const draw = () => {
      const {shown, lo, hi, width} = axis();
      svg.setAttribute("viewBox", "0 0 " + width + " " + HEIGHT);
      svg.setAttribute("width", width);
      while (svg.firstChild) svg.removeChild(svg.firstChild);
      const top = Math.max(...shown.map(s => Math.max(...s.count)), 1);
      const x = ms => LEFT + (lg(ms) - lo) / (hi - lo) * (width - LEFT - RIGHT);
      const y = v => HEIGHT - BOTTOM - v / top * (HEIGHT - BOTTOM - TOP);
      drawValueAxis(svg, width, y, 0, top);
      for (let p = Math.ceil(lo * 3) / 3; p <= hi; p += 1 / 3) {
        const ms = Math.pow(10, p), label = Number(ms.toPrecision(1));
        el("line", {x1: x(label), x2: x(label), y1: TOP, y2: HEIGHT - BOTTOM, class: "grid"}, svg);
        el("text", {x: x(label), y: HEIGHT - 8, class: "tick", "text-anchor": "middle"}, svg).textContent = label + " ms";
      }
      series.forEach((s, k) => {
        if (legendChart.hidden[k]) return;
        let d = "M" + x(s.from[0]).toFixed(1) + " " + y(0).toFixed(1);
        s.count.forEach((c, i) => { d += "V" + y(c).toFixed(1) + "H" + x(s.to[i]).toFixed(1); });
        d += "V" + y(0).toFixed(1);
        el("path", {d: d, stroke: COLORS[k % COLORS.length], class: "line"}, svg);
      });
      el("rect", {x: LEFT, y: TOP, width: width - LEFT - RIGHT, height: HEIGHT - TOP - BOTTOM, class: "frame"}, svg);
    };
    legend(legendChart, figure, draw);
    figure.appendChild(svg);
    // Each bar said in words: its bounds and answers, under the pointer and in a table.
    const readoutBox = document.createElement("div");
    readoutBox.className = "readout";
    figure.appendChild(readoutBox);
    const bins = series[0].from.map((from, i) => ({from: from, to: series[0].to[i], counts: series.map(s => s.count[i])}));
    const binText = bin => numberText(bin.from) + "–" + numberText(bin.to) + " ms";
    svg.addEventListener("mousemove", event => {
      const {lo, hi, width} = axis(), px = event.clientX - svg.getBoundingClientRect().left;
      const ms = Math.pow(10, lo + (px - LEFT) / (width - LEFT - RIGHT) * (hi - lo));
      const bin = bins.find(b => b.from <= ms && ms < b.to);
      readoutBox.textContent = bin ? binText(bin) + ", answers: " + series.map((s, k) => legendChart.hidden[k] ? null
        : s.name + " " + numberText(bin.counts[k])).filter(Boolean).join("; ") : "";
    });
    svg.addEventListener("mouseleave", () => { readoutBox.textContent = ""; });
    const details = document.createElement("details");
    details.className = "bins";
    const summary = document.createElement("summary");
    summary.textContent = "The bars as numbers (answers per latency bin)";
    details.appendChild(summary);
    const table = document.createElement("table");
    table.className = "bins";
    const head = table.insertRow();
    ["latency", ...series.map(s => s.name)].forEach(name => {
      const cell = document.createElement("th");
      cell.textContent = name;
      head.appendChild(cell);
    });
    bins.filter(bin => bin.counts.some(c => c > 0)).forEach(bin => {
      const row = table.insertRow();
      row.insertCell().textContent = binText(bin);
      bin.counts.forEach(count => {
        const cell = row.insertCell();
        cell.className = "num";
        cell.textContent = count ? numberText(count) : "";
      });
    });
    details.appendChild(table);
    figure.appendChild(details);
    distributionChart.redraw = draw;
    draw();
  }

  // Value charts come in a folding section per slave: the first ones open, the rest on demand.
  const groups = {};
  function groupPlace(name, parent) {
    if (!groups[name]) {
      const details = document.createElement("details");
      details.className = "values";
      details.open = Object.keys(groups).length < OPEN_GROUPS;
      const summary = document.createElement("summary");
      summary.textContent = name;
      details.appendChild(summary);
      details.charts = [];
      details.addEventListener("toggle", () => { if (details.open) details.charts.forEach(drawTimeChart); });
      parent.appendChild(details);
      groups[name] = details;
    }
    return groups[name];
  }

  const place = document.getElementById("charts");
  if (place && data.n > 0) {
    const valuePlace = document.getElementById("value-charts");
    data.charts.forEach(spec => {
      if (!spec.group || !valuePlace) { timeChart(spec, place); return; }
      const details = groupPlace(spec.group, valuePlace);
      timeChart(spec, details);
      details.charts.push(charts[charts.length - 1]);
    });
    charts.forEach(drawTimeChart);
    if (data.distribution.length) distributionChart(data.distribution, place);
    document.getElementById("zoom-reset").addEventListener("click", () => zoom(whole[0], whole[1]));
    window.addEventListener("resize", () => {
      charts.forEach(drawTimeChart);
      if (distributionChart.redraw) distributionChart.redraw();
    });
  }
})();

/* dsim serve: live charts (uPlot) fed by server-sent events (htmx sse extension),
   the compare overlay, and table filters.  No build step, no downloads. */
(function () {
  "use strict";
  var COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf",
                "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22"];

  function plot(el, xLabel, labels, extraScale, units) {
    var series = [{label: xLabel}];
    labels.forEach(function (label, i) {
      // a column's unit beside its name in the legend ("right.x[2] (m)")
      var shown = units && units[i] ? label + " (" + units[i] + ")" : label;
      var s = {label: shown, stroke: COLORS[i % COLORS.length], width: 1.5, spanGaps: true};
      if (extraScale && extraScale.labels.indexOf(label) >= 0) { s.scale = extraScale.name; }
      series.push(s);
    });
    var axes = [{label: xLabel}, {}];
    if (extraScale) { axes.push({scale: extraScale.name, side: 1, grid: {show: false}}); }
    var opts = {width: Math.max(320, el.clientWidth || 600), height: 230,
                scales: {x: {time: false}}, series: series, axes: axes};
    var data = [[]].concat(labels.map(function () { return []; }));
    return {chart: new uPlot(opts, data, el), data: data, names: labels};
  }

  function redraw(p) { if (p) { p.chart.setData(p.data); } }

  function liveRun(live) {
    var start = parseFloat(live.dataset.start), stop = parseFloat(live.dataset.stop);
    var state = {last: -1, samples: 0, signals: null, health: null, fmu: null};
    var progress = document.getElementById("progress");
    var text = document.getElementById("progress-text");

    function handle(line) {
      if (line.type === "start") {
        if (state.signals) { return; }  // a reconnect sends the history again
        start = line.start; stop = line.stop;
        state.signals = plot(document.getElementById("chart-signals"), "time (s)", line.columns,
                             null, line.units);
        state.health = plot(document.getElementById("chart-health"), "time (s)",
                            ["iterations per step (mean)", "iterations in one step (most)",
                             "Lambda refreshes"],
                            {name: "refreshes", labels: ["Lambda refreshes"]});
        state.fmu = plot(document.getElementById("chart-fmu"), "wall (s)", line.components);
      } else if (line.type === "sample" && line.i > state.last && state.signals) {
        state.last = line.i;
        state.samples += 1;
        var s = state.signals.data, h = state.health.data, f = state.fmu.data;
        s[0].push(line.t);
        line.v.forEach(function (v, k) { s[k + 1].push(v); });
        h[0].push(line.t); h[1].push(line.it_mean); h[2].push(line.it_max); h[3].push(line.refreshes);
        f[0].push(line.wall);
        line.fmu.forEach(function (v, k) { if (f[k + 1]) { f[k + 1].push(v); } });
        var fraction = stop > start ? (line.t - start) / (stop - start) : 1;
        progress.value = Math.min(1, Math.max(0, fraction));
        text.textContent = "t = " + line.t.toPrecision(4) + " s of " + stop + " s (step " +
          line.i + ", " + (100 * progress.value).toFixed(0) + "%, " + line.refreshes +
          " Lambda refreshes)";
      }
    }

    // a long watch: past this many points a chart keeps every other one (and the last)
    var MOST = 8000;
    function halve(p) {
      if (!p || p.data[0].length <= MOST) { return; }
      p.data = p.data.map(function (values) {
        return values.filter(function (v, k) { return k % 2 === 0 || k === values.length - 1; });
      });
    }

    live.addEventListener("htmx:sseMessage", function (event) {
      if (event.detail.type !== "samples") { return; }
      JSON.parse(event.detail.data).forEach(handle);
      [state.signals, state.health, state.fmu].forEach(halve);
      [state.signals, state.health, state.fmu].forEach(redraw);
      live.dataset.samples = state.samples;
    });
    live.addEventListener("htmx:sseClose", function () {
      // the whole run from its CSV replaces the live samples
      fetch("/runs/" + live.dataset.run + "/signals.json").then(function (r) {
        return r.ok ? r.json() : null;
      }).then(function (full) {
        if (full && state.signals) {
          var labels = state.signals.names;
          state.signals.data = [full.time].concat(labels.map(function (l) {
            return full.columns[l] || full.time.map(function () { return null; });
          }));
          redraw(state.signals);
        }
        live.dataset.finished = "1";
      });
    });
  }

  function liveSweep(live) {
    var list = document.getElementById("points-live");
    live.addEventListener("htmx:sseMessage", function (event) {
      if (event.detail.type !== "samples") { return; }
      JSON.parse(event.detail.data).forEach(function (line) {
        if (line.type !== "point" || list.children.length >= line.done) { return; }
        var item = document.createElement("li");
        item.textContent = line.done + " of " + line.total + ": " + line.label + ": " +
          line.status + (line.error === null ? "" : ", error " + line.error.toExponential(2));
        list.appendChild(item);
      });
    });
    live.addEventListener("htmx:sseClose", function () {
      if (live.dataset.active === "1") { window.location.reload(); }
      live.dataset.finished = "1";
    });
  }

  function overlay(el) {
    fetch(el.dataset.url).then(function (r) { return r.json(); }).then(function (found) {
      if (!found.series.length) { el.textContent = "no run with this signal"; return; }
      var joined = uPlot.join(found.series.map(function (s) { return [s.time, s.values]; }));
      var p = plot(el, "time (s)", found.series.map(function (s) { return s.label; }));
      p.data = joined;
      redraw(p);
      el.dataset.curves = found.series.length;
    });
  }

  function filters() {
    document.querySelectorAll("input[data-filter]").forEach(function (input) {
      input.addEventListener("input", function () {
        var wanted = input.value.toLowerCase();
        document.querySelectorAll(input.dataset.filter).forEach(function (row) {
          row.style.display = row.textContent.toLowerCase().indexOf(wanted) >= 0 ? "" : "none";
        });
      });
    });
  }

  function init() {
    var live = document.getElementById("live");
    if (live) { (live.dataset.sweep ? liveSweep : liveRun)(live); }
    var chart = document.getElementById("chart-overlay");
    if (chart) { overlay(chart); }
    filters();
  }
  if (document.readyState === "loading") {
    document.addEventListener("DOMContentLoaded", init);
  } else { init(); }
})();

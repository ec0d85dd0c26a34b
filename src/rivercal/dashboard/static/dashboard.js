// rivercal dashboard: draws the page's plotly figures, keeps map labels apart, and follows the store without
// reloading the page.
(function () {
  "use strict";
  // where a label may sit around its marker, tried in this order until it overlaps nothing
  var POSITIONS = ["top center", "bottom center", "middle right", "middle left", "top right", "top left",
                   "bottom right", "bottom left"];

  function overlaps(a, b) {
    return a.left < b.right && b.left < a.right && a.top < b.bottom && b.top < a.bottom;
  }

  // Move the labels of the text trace of a drawn figure until no label overlaps another label or another
  // station's marker (at most a few rounds); on a crowded map the labels that still overlap one kept before
  // them or a marker, or reach beyond the figure, are then left out (their markers keep the name on hover).
  async function declutter(target, fig) {
    var trace = fig.data.findIndex(function (t) { return (t.mode || "").indexOf("text") >= 0; });
    if (trace < 0 || !Array.isArray(fig.data[trace].text)) { return; }
    var n = fig.data[trace].text.length;
    var chosen = new Array(n).fill(0);
    for (var round = 0; round < 2 * POSITIONS.length; round++) {
      var layer = target.querySelectorAll(".scatterlayer .trace")[trace];
      if (!layer) { return; }
      var labels = Array.from(layer.querySelectorAll(".textpoint text")).map(function (e) {
        return e.getBoundingClientRect();
      });
      var markers = Array.from(layer.querySelectorAll("path.point")).map(function (e) {
        return e.getBoundingClientRect();
      });
      if (labels.length !== n) { return; }
      var moved = false;
      for (var i = 0; i < n; i++) {
        var clash = false;
        for (var j = 0; j < n && !clash; j++) {
          if (j === i) { continue; }
          clash = (j < i && overlaps(labels[i], labels[j])) || (markers[j] && overlaps(labels[i], markers[j]));
        }
        if (clash && chosen[i] < POSITIONS.length - 1) {
          chosen[i] += 1;
          moved = true;
        }
      }
      if (!moved) { break; }
      await Plotly.restyle(target, {textposition: [chosen.map(function (k) { return POSITIONS[k]; })]}, [trace]);
    }
    await dropCrowded(target, fig, trace);
  }

  async function dropCrowded(target, fig, trace) {
    var layer = target.querySelectorAll(".scatterlayer .trace")[trace];
    if (!layer) { return; }
    var rect = function (e) { return e.getBoundingClientRect(); };
    var labels = Array.from(layer.querySelectorAll(".textpoint text")).map(rect);
    var markers = Array.from(layer.querySelectorAll("path.point")).map(rect);
    var texts = fig.data[trace].text;
    if (labels.length !== texts.length) { return; }
    var frame = target.getBoundingClientRect();
    var kept = [];
    var shown = texts.map(function (text, i) {
      var a = labels[i];
      var outside = a.left < frame.left || a.right > frame.right || a.top < frame.top || a.bottom > frame.bottom;
      var clash = outside || kept.some(function (k) { return overlaps(a, labels[k]); }) ||
        markers.some(function (m, j) { return j !== i && overlaps(a, m); });
      if (clash) { return ""; }
      kept.push(i);
      return text;
    });
    if (kept.length < texts.length) {
      await Plotly.restyle(target, {text: [shown]}, [trace]);
      target.dataset.labelsLeftOut = String(texts.length - kept.length);
    }
  }

  function draw(root) {
    if (typeof Plotly === "undefined") { return Promise.resolve(); }
    var done = [];
    root.querySelectorAll("script.figure").forEach(function (node) {
      var fig = JSON.parse(node.textContent);
      var target = document.getElementById(node.dataset.target);
      if (target) {
        done.push(Plotly.react(target, fig.data, fig.layout, {displaylogo: false, displayModeBar: false, responsive: true})
          .then(function () { return target.dataset.declutter ? declutter(target, fig) : null; })
          .then(function () { target.dataset.drawn = "1"; }));
      }
    });
    return Promise.all(done);
  }

  async function follow() {
    var main = document.getElementById("main");
    if (!main) { return; }
    try {
      var answer = await fetch("/api/version?run=" + encodeURIComponent(main.dataset.run), {cache: "no-store"});
      var now = await answer.json();
      if (!now.version || now.version === main.dataset.version) { return; }
      var page = await fetch(window.location.href, {cache: "no-store"});
      var doc = new DOMParser().parseFromString(await page.text(), "text/html");
      var fresh = doc.getElementById("main");
      if (fresh) {
        main.replaceWith(fresh);
        await draw(fresh);
        document.body.dataset.updates = String(Number(document.body.dataset.updates || 0) + 1);
      }
    } catch (err) {
      console.info("rivercal dashboard: store not reachable, trying again", err);
    }
  }

  document.addEventListener("DOMContentLoaded", function () {
    draw(document).catch(function (err) { console.error("rivercal dashboard: a figure failed", err); })
      .finally(function () {
        window.rivercalReady = performance.now();
        document.body.dataset.ready = "1";
      });
    window.setInterval(follow, Number(document.body.dataset.poll || 2000));
  });
})();

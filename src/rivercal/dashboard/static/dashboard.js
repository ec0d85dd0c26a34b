// rivercal dashboard: draws the page's plotly figures and follows the store without reloading the page.
(function () {
  "use strict";
  function draw(root) {
    if (typeof Plotly === "undefined") { return; }
    root.querySelectorAll("script.figure").forEach(function (node) {
      var fig = JSON.parse(node.textContent);
      var target = document.getElementById(node.dataset.target);
      if (target) {
        Plotly.react(target, fig.data, fig.layout, {displaylogo: false, responsive: true});
      }
    });
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
        draw(fresh);
        document.body.dataset.updates = String(Number(document.body.dataset.updates || 0) + 1);
      }
    } catch (err) {
      console.info("rivercal dashboard: store not reachable, trying again", err);
    }
  }
  document.addEventListener("DOMContentLoaded", function () {
    draw(document);
    window.rivercalReady = performance.now();
    document.body.dataset.ready = "1";
    window.setInterval(follow, Number(document.body.dataset.poll || 2000));
  });
})();

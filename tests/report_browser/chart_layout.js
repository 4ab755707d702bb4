// Injected at the end of a copy of a report by tests/report_browser.rs: measures every chart
// (svg.chart) as Chromium laid it out and writes the measures as JSON into a pre element
// (id chart-layout),
// which `chromium --dump-dom` prints. Boxes are [x, y, width, height] in the chart's viewBox units,
// from the rendered glyphs (getBoundingClientRect), not from the attributes the report wrote.
(() => {
  const charts = [...document.querySelectorAll("svg.chart")].map((svg) => {
    const vb = svg.viewBox.baseVal;
    const frame = svg.getBoundingClientRect();
    const k = vb.width / frame.width;
    const box = (el) => {
      const r = el.getBoundingClientRect();
      return [(r.left - frame.left) * k + vb.x, (r.top - frame.top) * k + vb.y, r.width * k, r.height * k];
    };
    const axis = (cls) => {
      const g = svg.querySelector("g." + cls);
      if (!g) return null;
      return {
        scale: g.dataset.scale || "",
        numbers: g.dataset.numbers || "",
        ticks: [...g.querySelectorAll("text.tick-label")].map((t) => ({ text: t.textContent.trim(), box: box(t) })),
      };
    };
    const legend = svg.querySelector("g.legend");
    const inLegend = (el) => legend !== null && legend.contains(el);
    return {
      title: (svg.querySelector("text.title") || { textContent: "" }).textContent.trim(),
      view_box: [vb.x, vb.y, vb.width, vb.height],
      texts: [...svg.querySelectorAll("text")].map((t) => ({ text: t.textContent.trim(), box: box(t) })),
      x: axis("x-axis"),
      y: axis("y-axis"),
      legend: legend ? { box: box(legend), texts: [...legend.querySelectorAll("text")].map((t) => t.textContent.trim()) } : null,
      curves: [...svg.querySelectorAll("polyline.series")].map((p) =>
        Array.from({ length: p.points.numberOfItems }, (_, i) => p.points.getItem(i)).map((q) => [q.x, q.y])),
      points: [...svg.querySelectorAll("circle.point")].filter((c) => !inLegend(c)).map((c) => [c.cx.baseVal.value, c.cy.baseVal.value]),
      targets: [...svg.querySelectorAll("line.target")].map((l) => ({ value: Number(l.dataset.value), y: l.y1.baseVal.value })),
    };
  });
  // JSON with every character that HTML would escape written as \uXXXX: the DOM dump keeps it verbatim
  const json = JSON.stringify({ charts }).replace(/[<>&\u0080-\uffff]/g, (c) => "\\u" + c.charCodeAt(0).toString(16).padStart(4, "0"));
  const pre = document.createElement("pre");
  pre.id = "chart-layout";
  pre.textContent = json;
  document.body.appendChild(pre);
})();

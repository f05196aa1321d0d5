// The list of runs: status, start, steps; each opens its page and its report.
"use strict";
async function load() {
  const conn = document.getElementById("conn");
  try {
    const r = await fetch("/runs.json", { cache: "no-store" });
    if (!r.ok) throw new Error(r.status + " " + (await r.text()));
    const runs = await r.json();
    const body = document.querySelector("#runs tbody");
    body.textContent = "";
    for (const run of runs) {
      const tr = document.createElement("tr");
      tr.className = "status-" + run.status;
      const cell = (text, href) => {
        const td = document.createElement("td");
        if (href) {
          const a = document.createElement("a");
          a.href = href;
          a.textContent = text;
          td.appendChild(a);
        } else td.textContent = text;
        tr.appendChild(td);
      };
      const base = "/run/" + encodeURIComponent(run.id) + "/";
      cell(run.id, base);
      cell(run.protocol);
      cell(run.status);
      cell(run.started);
      cell(run.steps);
      cell(run.has_report ? "report" : "make report", base + "report/");
      body.appendChild(tr);
    }
    document.getElementById("runs").dataset.count = runs.length;
    conn.textContent = runs.length + " runs";
    conn.className = "conn ok";
  } catch (e) {
    conn.textContent = "cannot list runs: " + e.message;
    conn.className = "conn lost";
  }
}
load();
setInterval(load, 5000);

// Board inspector: topic table, module health, live map and operator actions, fed by one
// server-sent event stream. Values are shown with textContent only.
"use strict";
(function () {
  const SVG = "http://www.w3.org/2000/svg";
  const el = (name) => document.getElementById(name);
  const robot = JSON.parse(el("robot-data").textContent);
  let mapFloor = null;        // the floor whose plan is on screen
  let pinnedFloor = null;     // a floor the user picked; otherwise follow the robot
  let overlay = null;         // the <g> the shapes are drawn into

  function cell(row, text, cls) {
    const td = row.insertCell();
    td.textContent = text;
    if (cls) td.className = cls;
    return td;
  }

  function fill(tableId, items, columns) {
    const body = el(tableId).tBodies[0];
    const rows = items.map((item) => {
      const tr = document.createElement("tr");
      columns(item).forEach(([text, cls]) => cell(tr, text, cls));
      return tr;
    });
    body.replaceChildren(...rows);
  }

  const fixed = (v, n) => (v === null || v === undefined ? "–" : v.toFixed(n));

  function showTopics(frame) {
    fill("topics-table", frame.board.topics, (t) => [
      [t.name], [t.model], [fixed(t.rate_hz, 1)],
      [t.subscribers.map((s) => s.name).join(", ")], [String(t.published)],
      [String(t.dropped + t.overflowed)], [fixed(t.age_s, 2)],
      [frame.values[t.name] ? frame.values[t.name].text : "", "value"],
    ]);
    for (const [i, t] of frame.board.topics.entries()) {
      el("topics-table").tBodies[0].rows[i].dataset.topic = t.name;
    }
  }

  function showHealth(frame) {
    fill("health-table", frame.health, (h) => [[h.module], [h.status], [String(h.restarts)], [h.detail]]);
    const e = frame.estop;
    el("estop-state").textContent = e && e.engaged ? `ENGAGED (${e.source})` : "released";
  }

  // --- live map -------------------------------------------------------------------------
  function node(name, attrs, parent) {
    const n = document.createElementNS(SVG, name);
    for (const [k, v] of Object.entries(attrs)) n.setAttribute(k, v);
    parent.appendChild(n);
    return n;
  }

  async function loadFloor(floor) {
    mapFloor = floor;
    const box = el("map");
    const response = await fetch(`/api/map/${floor}.svg`);
    let svg;
    if (response.ok) {
      const doc = new DOMParser().parseFromString(await response.text(), "image/svg+xml");
      svg = document.importNode(doc.documentElement, true);
      el("map-note").textContent = "";
    } else {
      svg = document.createElementNS(SVG, "svg");
      el("map-note").textContent = `no floor plan for floor ${floor}`;
    }
    box.replaceChildren(svg);
    // A floor plan may mark the group whose coordinates are floor-plan millimetres.
    const frame = svg.querySelector("#frame") || svg;
    overlay = node("g", { id: "overlay" }, frame);
  }

  const draw = {
    robot(s, g) {
      const r = node("g", {
        class: `robot ${s.label}`, "data-label": s.label,
        transform: `translate(${s.x_mm} ${s.y_mm}) rotate(${s.heading_deg})`,
      }, g);
      node("rect", { x: -robot.length_mm / 2, y: -robot.width_mm / 2, width: robot.length_mm, height: robot.width_mm, rx: 60 }, r);
      node("line", { x1: 0, y1: 0, x2: robot.length_mm / 2, y2: 0 }, r);
    },
    ray(s, g) {
      node("line", { class: `ray ${s.status}`, x1: s.x1_mm, y1: s.y1_mm, x2: s.x2_mm, y2: s.y2_mm }, g);
    },
    cloud(s, g) {
      const c = node("g", { class: "particles" }, g);
      for (const [x, y] of s.points) node("circle", { cx: x, cy: y, r: 35 }, c);
    },
    ellipse(s, g) {
      node("ellipse", {
        class: "uncertainty", rx: s.rx_mm, ry: s.ry_mm,
        transform: `translate(${s.x_mm} ${s.y_mm}) rotate(${s.angle_deg})`,
      }, g);
    },
  };

  async function showMap(map) {
    const floor = pinnedFloor ?? map.floor ?? robot.floors[0];
    if (floor === undefined) return;
    if (floor !== mapFloor) await loadFloor(floor);
    const svg = el("map").querySelector("svg");
    const placed = map.shapes.filter((s) => s.kind === "ray" || s.kind === "robot");
    if (!svg.getAttribute("viewBox") && placed.length) {
      const xs = placed.flatMap((s) => (s.kind === "ray" ? [s.x1_mm, s.x2_mm] : [s.x_mm]));
      const ys = placed.flatMap((s) => (s.kind === "ray" ? [s.y1_mm, s.y2_mm] : [s.y_mm]));
      const x0 = Math.min(...xs) - 2000, y0 = Math.min(...ys) - 2000;
      svg.setAttribute("viewBox", `${x0} ${y0} ${Math.max(...xs) + 2000 - x0} ${Math.max(...ys) + 2000 - y0}`);
    }
    const shapes = map.floor === floor ? map.shapes : [];
    const g = document.createElementNS(SVG, "g");
    for (const s of shapes) (draw[s.kind] || (() => {}))(s, g);
    overlay.replaceChildren(...g.childNodes);
  }

  const select = el("floor-select");
  for (const f of ["follow robot", ...robot.floors]) {
    const o = document.createElement("option");
    o.value = f === "follow robot" ? "" : String(f);
    o.textContent = f === "follow robot" ? f : `floor ${f}`;
    select.appendChild(o);
  }
  select.addEventListener("change", () => { pinnedFloor = select.value === "" ? null : Number(select.value); });

  // --- stream ---------------------------------------------------------------------------
  let busy = false;
  const stream = new EventSource("/api/board/stream");
  stream.onopen = () => { el("stream-state").textContent = "live"; };
  stream.onerror = () => { el("stream-state").textContent = "reconnecting…"; };
  stream.onmessage = async (event) => {
    if (busy) return;   // drawing is slower than the stream: skip, the next frame is newer
    busy = true;
    try {
      const frame = JSON.parse(event.data);
      showTopics(frame);
      showHealth(frame);
      await showMap(frame.map);
      document.body.dataset.frames = String(Number(document.body.dataset.frames || 0) + 1);
    } finally {
      busy = false;
    }
  };

  // --- operator -------------------------------------------------------------------------
  const token = el("token");
  token.value = sessionStorage.getItem("coffeebot-token") || "";
  token.addEventListener("change", () => sessionStorage.setItem("coffeebot-token", token.value));

  async function operator(method, path, body) {
    const response = await fetch(path, {
      method,
      headers: { Authorization: `Bearer ${token.value}`, "Content-Type": "application/json" },
      body: body === undefined ? undefined : JSON.stringify(body),
    });
    const data = await response.json();
    el("operator-message").textContent = response.ok ? "done" : data.error;
    return response.ok ? data : null;
  }

  async function showOrders() {
    const orders = await operator("GET", "/api/orders");
    if (!orders) return;
    fill("orders-table", orders, (o) => [[String(o.ahead)], [o.name], [o.room], [o.drink], [o.status], [""]]);
    orders.forEach((o, i) => {
      const td = el("orders-table").tBodies[0].rows[i].cells[5];
      if (o.status === "preparing") {
        td.appendChild(button("cup loaded", () => operator("POST", `/api/orders/${o.id}/cup-loaded`).then(showOrders)));
      }
      if (o.status === "waiting_for_elevator") {
        td.appendChild(button("elevator done", () => operator("POST", `/api/orders/${o.id}/elevator-confirm`).then(showOrders)));
      }
      td.appendChild(button("cancel", () => operator("DELETE", `/api/orders/${o.id}`).then(showOrders)));
    });
  }

  function button(text, onClick) {
    const b = document.createElement("button");
    b.textContent = text;
    b.className = "secondary";
    b.addEventListener("click", onClick);
    return b;
  }

  el("estop").addEventListener("click", () => operator("POST", "/api/estop", { engaged: true, reason: "operator pressed e-stop" }));
  el("resume").addEventListener("click", () => operator("POST", "/api/estop", { engaged: false }));
  el("refresh-orders").addEventListener("click", showOrders);
})();

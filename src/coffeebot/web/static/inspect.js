// Board inspector: alerts, topic table, module health, live map, orders and operator
// actions, fed by one server-sent event stream. Values are shown with textContent only.
"use strict";
(function () {
  const SVG = "http://www.w3.org/2000/svg";
  const FOLLOW_WIDTH_MM = 9000;     // what follow mode shows across: the robot and its cones
  const FOLLOW_ASPECT = 0.6;
  const el = (name) => document.getElementById(name);
  const robot = JSON.parse(el("robot-data").textContent);
  let mapFloor = null;        // the floor whose plan is on screen
  let pinnedFloor = null;     // a floor the user picked; otherwise follow the robot's floor
  let follow = true;          // zoomed to the robot, or the whole floor
  let overlay = null;         // the <g> the shapes are drawn into (floor-plan mm)
  let wholeView = null;       // the plan's own viewBox
  let ordersVersion = null;   // the orders table was filled at this version

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
    return rows;
  }

  const fixed = (v, n) => (v === null || v === undefined ? "–" : v.toFixed(n));

  function ago(seconds) {
    if (seconds === null || seconds === undefined) return "";
    if (seconds < 1) return `${seconds.toFixed(1)} s`;
    if (seconds < 120) return `${Math.round(seconds)} s`;
    return `${Math.round(seconds / 60)} min`;
  }

  // --- alerts, topics, health ------------------------------------------------------------
  function showAlerts(frame) {
    const list = el("alerts");
    const items = frame.alerts.map((a) => {
      const li = document.createElement("li");
      li.className = `alert ${a.severity}`;
      li.dataset.key = a.key;
      const badge = document.createElement("span");
      badge.className = "severity";
      badge.textContent = a.severity;
      const title = document.createElement("strong");
      title.textContent = a.title;
      const detail = document.createElement("span");
      detail.className = "detail";
      detail.textContent = a.detail;
      const age = document.createElement("span");
      age.className = "age muted";
      const fresh = a.fresh_s === null ? "" : ` · value ${ago(a.fresh_s)} old`;
      age.textContent = `for ${ago(a.since_s)}${fresh} · ${a.source}`;
      li.append(badge, " ", title, " ", detail, " ", age);
      return li;
    });
    if (!items.length) {
      const none = document.createElement("li");
      none.className = "none";
      none.textContent = "none";
      items.push(none);
    }
    list.replaceChildren(...items);
    el("alert-count").textContent = frame.alerts.length ? `(${frame.alerts.length})` : "";
  }

  function showTopics(frame) {
    const rows = fill("topics-table", frame.board.topics, (t) => [
      [t.name], [t.model], [fixed(t.rate_hz, 1)],
      [t.subscribers.map((s) => s.name).join(", ")], [String(t.published)],
      [String(t.dropped + t.overflowed)], [fixed(t.age_s, 2)],
      [frame.values[t.name] ? frame.values[t.name].text : "", "value"],
    ]);
    frame.board.topics.forEach((t, i) => {
      rows[i].dataset.topic = t.name;
      const limit = frame.stale_after_s[t.name];
      const stale = limit !== undefined && (t.age_s === null || t.age_s > limit);
      rows[i].cells[6].classList.toggle("stale", stale);
      rows[i].cells[6].title = limit === undefined ? "" : `expected at least every ${limit} s`;
    });
  }

  function showHealth(frame) {
    fill("health-table", frame.health, (h) => [[h.module], [h.status, h.status], [String(h.restarts)], [fixed(h.cpu_pct, 1)], [h.detail]]);
    el("cpu-note").textContent = frame.cpu
      ? `CPU, per cent of one core over the last 5 s: the board ${fixed(frame.cpu.board_pct, 1)}, the whole process ${fixed(frame.cpu.process_pct, 1)} (web server, recording and, simulated, the world included).`
      : "CPU per module shows after the first 5 s.";
    const e = frame.estop;
    el("estop-state").textContent = e && e.engaged ? `ENGAGED (${e.source})` : "released";
    el("operator-off").hidden = frame.operator_actions;
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
    svg.removeAttribute("width");
    svg.removeAttribute("height");
    box.replaceChildren(svg);
    box.dataset.floor = String(floor);
    wholeView = svg.getAttribute("viewBox");
    // The plan marks the group whose coordinates are floor-plan millimetres (y up).
    const frame = svg.querySelector(`#frame-${floor}`) || svg.querySelector("#frame") || svg;
    overlay = node("g", { id: "overlay" }, frame);
  }

  // A floor-plan point in the picture's own units (through whatever the frame does).
  function inPicture(svg, x, y) {
    const m = svg.getScreenCTM().inverse().multiply(overlay.getScreenCTM());
    const p = new DOMPoint(x, y).matrixTransform(m);
    return [p.x, p.y, Math.hypot(m.a, m.b)];
  }

  function fitView(svg, shapes) {
    const me = shapes.find((s) => s.kind === "robot");
    if (follow && me) {
      const [cx, cy, scale] = inPicture(svg, me.x_mm, me.y_mm);
      const w = FOLLOW_WIDTH_MM * scale, h = w * FOLLOW_ASPECT;
      svg.setAttribute("viewBox", `${cx - w / 2} ${cy - h / 2} ${w} ${h}`);
    } else if (wholeView) {
      svg.setAttribute("viewBox", wholeView);
    } else if (shapes.length) {
      // A drawing without a viewBox: frame what is drawn.
      const xs = shapes.flatMap((s) => (s.x_mm === undefined ? [] : [s.x_mm]));
      const ys = shapes.flatMap((s) => (s.y_mm === undefined ? [] : [s.y_mm]));
      const x0 = Math.min(...xs) - 4000, y0 = Math.min(...ys) - 4000;
      svg.setAttribute("viewBox", `${x0} ${y0} ${Math.max(...xs) + 4000 - x0} ${Math.max(...ys) + 4000 - y0}`);
    }
  }

  // Text inside the frame would be mirrored by its y flip: set it upright where it stands.
  function label(g, x, y, text, cls) {
    const t = node("text", { class: cls, transform: `translate(${x} ${y}) scale(1 -1)` }, g);
    t.textContent = text;
    return t;
  }

  const rad = (deg) => (deg * Math.PI) / 180;
  const pointList = (pts) => pts.map(([x, y]) => `${x.toFixed(0)},${y.toFixed(0)}`).join(" ");

  // A polygon with its words shown on hover: a sensor's cone, a camera's field, what it sees.
  function titled(g, cls, points, text, data) {
    const p = node("polygon", { class: cls, points: pointList(points), ...data }, g);
    node("title", {}, p).textContent = text;
  }

  const draw = {
    robot(s, g) {
      const silent = s.silent_s !== null && s.silent_s !== undefined;
      const r = node("g", {
        class: `robot ${s.label}${silent ? " silent" : ""}`, "data-label": s.label,
        transform: `translate(${s.x_mm} ${s.y_mm}) rotate(${s.heading_deg})`,
      }, g);
      node("rect", { x: -robot.length_mm / 2, y: -robot.width_mm / 2, width: robot.length_mm, height: robot.width_mm, rx: 60 }, r);
      node("line", { x1: 0, y1: 0, x2: robot.length_mm / 2, y2: 0 }, r);
      // A fleet's robots are named on the map; a silent one says since when.
      if (!["estimated", "true"].includes(s.label)) {
        const text = silent ? `${s.label}: silent for ${Math.round(s.silent_s)} s` : s.label;
        label(g, s.x_mm, s.y_mm + robot.width_mm, text, `robot-label${silent ? " silent" : ""}`);
      }
    },
    cone(s, g) {
      const steps = 6, pts = [[s.x_mm, s.y_mm]];
      for (let i = 0; i <= steps; i++) {
        const a = rad(s.heading_deg - s.half_fov_deg + (2 * s.half_fov_deg * i) / steps);
        pts.push([s.x_mm + s.range_mm * Math.cos(a), s.y_mm + s.range_mm * Math.sin(a)]);
      }
      titled(g, `cone ${s.reach} ${s.status}`, pts, s.text, { "data-sensor": s.sensor });
      if (s.reach === "hit") {
        const a = rad(s.heading_deg);
        node("circle", { class: "hit-point", cx: s.x_mm + s.range_mm * Math.cos(a), cy: s.y_mm + s.range_mm * Math.sin(a), r: 45 }, g);
      }
    },
    ellipse(s, g) {
      node("ellipse", {
        class: "uncertainty", rx: Math.max(s.rx_mm, 1), ry: Math.max(s.ry_mm, 1),
        transform: `translate(${s.x_mm} ${s.y_mm}) rotate(${s.angle_deg})`,
      }, g);
    },
    path(s, g) {
      node("polyline", { class: `path ${s.role}`, points: pointList(s.points) }, g);
    },
    goal(s, g) {
      node("circle", { class: "goal", cx: s.x_mm, cy: s.y_mm, r: 220 }, g);
      label(g, s.x_mm, s.y_mm + 350, s.label, "goal-label");
    },
    cloud(s, g) {
      const c = node("g", { class: "particles" }, g);
      for (const [x, y] of s.points) node("circle", { cx: x, cy: y, r: 35 }, c);
    },
    camera_field(s, g) {
      titled(g, `camera-field${s.working ? "" : " down"}`, s.corners, s.text, { "data-camera": s.camera_id });
    },
    camera_object(s, g) {
      titled(g, "camera-object", s.corners, s.text, { "data-object": s.id, "data-camera": s.camera_id });
    },
  };

  async function showMap(map) {
    const floor = pinnedFloor ?? map.floor ?? robot.floors[0];
    if (floor === undefined) return;
    if (floor !== mapFloor) await loadFloor(floor);
    const svg = el("map").querySelector("svg");
    // Layers belong to the followed robot's floor; every robot is drawn on its own floor.
    const shapes = map.shapes.filter((s) => (s.kind === "robot" ? s.floor === floor : map.floor === floor));
    const g = document.createElementNS(SVG, "g");
    for (const s of shapes) (draw[s.kind] || (() => {}))(s, g);
    overlay.replaceChildren(...g.childNodes);
    fitView(svg, shapes);
    el("map-caption").textContent = map.caption;
    el("camera-legend").hidden = !shapes.some((s) => s.kind.startsWith("camera_"));
    showReadings(shapes.filter((s) => s.kind === "cone"));
  }

  // Side by side on the map the numbers would overlap: they are listed under it instead.
  function showReadings(cones) {
    const chips = [...cones].sort((a, b) => a.sensor - b.sensor).map((c) => {
      const li = document.createElement("li");
      li.className = c.reach;
      li.dataset.sensor = c.sensor;
      li.textContent = c.text;
      return li;
    });
    el("readings").replaceChildren(...chips);
  }

  const select = el("floor-select");
  for (const f of ["robot's floor", ...robot.floors]) {
    const o = document.createElement("option");
    o.value = f === "robot's floor" ? "" : String(f);
    o.textContent = f === "robot's floor" ? f : `floor ${f}`;
    select.appendChild(o);
  }
  select.addEventListener("change", () => { pinnedFloor = select.value === "" ? null : Number(select.value); });
  const toggle = el("view-toggle");
  toggle.addEventListener("click", () => {
    follow = !follow;
    toggle.textContent = follow ? "Whole floor" : "Follow robot";
    toggle.setAttribute("aria-pressed", String(follow));
  });

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
      showAlerts(frame);
      showTopics(frame);
      showHealth(frame);
      await showMap(frame.map);
      if (frame.orders_version !== ordersVersion) await showOrders(frame.orders_version);
      document.body.dataset.frames = String(Number(document.body.dataset.frames || 0) + 1);
    } finally {
      busy = false;
    }
  };

  // --- operator -------------------------------------------------------------------------
  const token = el("token");
  token.value = sessionStorage.getItem("coffeebot-token") || "";
  token.addEventListener("change", () => {
    sessionStorage.setItem("coffeebot-token", token.value);
    ordersVersion = null;  // fetch the orders with the new token on the next frame
  });

  async function operator(method, path, body) {
    const response = await fetch(path, {
      method,
      headers: { Authorization: `Bearer ${token.value}`, "Content-Type": "application/json" },
      body: body === undefined ? undefined : JSON.stringify(body),
    });
    const data = await response.json();
    if (!response.ok) el("operator-message").textContent = data.error;
    return response.ok ? data : null;
  }

  async function act(method, path, done, body) {
    const answer = await operator(method, path, body);
    if (answer) el("operator-message").textContent = done;
    return answer;
  }

  const place = (o) => (o.status === "queued" ? `#${o.ahead}` : "out now");

  async function showOrders(version) {
    if (!token.value) {
      el("orders-note").hidden = false;
      el("orders-table").tBodies[0].replaceChildren();
      ordersVersion = version;
      return;
    }
    const response = await fetch("/api/orders", { headers: { Authorization: `Bearer ${token.value}` } });
    const orders = await response.json();
    ordersVersion = version;
    if (!response.ok) {
      el("orders-note").hidden = false;
      el("orders-note").textContent = orders.error;
      el("orders-table").tBodies[0].replaceChildren();
      return;
    }
    el("orders-note").hidden = orders.length > 0;
    el("orders-note").textContent = "No orders waiting or on the way.";
    const rows = fill("orders-table", orders, (o) => [
      [place(o)], [o.name], [o.room], [o.drink], [robot.status_text[o.status] || o.status, "status"], [""],
    ]);
    orders.forEach((o, i) => {
      rows[i].dataset.order = o.id;
      rows[i].dataset.status = o.status;
      const td = rows[i].cells[5];
      const who = `${o.name}'s ${o.drink} to ${o.room}`;
      if (o.status === "preparing") {
        td.appendChild(button("Cup loaded", () => act("POST", `/api/orders/${o.id}/cup-loaded`, `Cup loaded: ${who} is on its way.`)));
      }
      if (o.status === "waiting_for_elevator") {
        td.appendChild(button("Elevator done", () => act("POST", `/api/orders/${o.id}/elevator-confirm`, `Elevator step confirmed for ${who}.`)));
      }
      td.appendChild(button("Cancel", () => act("DELETE", `/api/orders/${o.id}`, `Cancelled ${who}.`)));
    });
  }

  function button(text, onClick) {
    const b = document.createElement("button");
    b.textContent = text;
    b.className = "secondary";
    b.addEventListener("click", onClick);
    return b;
  }

  el("estop").addEventListener("click", () => act("POST", "/api/estop", "Emergency stop engaged: the robot will not move.", { engaged: true, reason: "operator pressed e-stop" }));
  el("resume").addEventListener("click", () => act("POST", "/api/estop", "Emergency stop released.", { engaged: false }));
})();

// Live order status over server-sent events: the order itself (buttons) and its timeline
// (steps, plain words, arrival estimate, the countdown at the door). Text only ever goes in
// through textContent.
"use strict";
(function () {
  const box = document.getElementById("order");
  const id = box.dataset.orderId;
  // The order's key authorizes this page's requests; it came in the page's own address.
  const key = `key=${encodeURIComponent(box.dataset.orderKey)}`;
  const el = (name) => document.getElementById(name);

  let shownUpdatedAt = -Infinity;
  let pickupDeadline = null;   // local clock, ms: when the robot stops waiting at the door

  // The stream and a button's own response can arrive in either order: never step back to
  // an older state (the response to "I have my coffee" must not undo "delivered").
  function show(order) {
    if (order.updated_at < shownUpdatedAt) return false;
    shownUpdatedAt = order.updated_at;
    box.dataset.status = order.status;
    el("pickup").hidden = order.status !== "arrived";
    el("cancel").hidden = order.status !== "queued";
    return true;
  }

  function minutes(seconds) {
    if (seconds < 90) return "about a minute";
    return `about ${Math.round(seconds / 60)} min`;
  }

  function clock(ms) {
    return new Date(ms).toLocaleTimeString([], { hour: "2-digit", minute: "2-digit" });
  }

  function showTimeline(t) {
    if (t.status !== box.dataset.status) return;   // an older word than the order shown
    el("status-text").textContent = t.headline;
    el("detail").textContent = t.detail;
    const steps = t.steps.map((s) => {
      const li = document.createElement("li");
      li.className = s.state;
      li.dataset.step = s.key;
      li.textContent = s.label;
      return li;
    });
    el("steps").replaceChildren(...steps);
    const eta = el("eta");
    eta.hidden = t.arrival_in_s === null;
    if (t.arrival_in_s !== null) {
      const at = Date.now() + t.arrival_in_s * 1000;
      eta.textContent = `Arriving in ${minutes(t.arrival_in_s)} (around ${clock(at)})`;
    }
    pickupDeadline = t.pickup_left_s === null ? null : Date.now() + t.pickup_left_s * 1000;
    tick();
    el("keep-link").hidden = t.final;
  }

  function tick() {
    const countdown = el("countdown");
    countdown.hidden = pickupDeadline === null;
    if (pickupDeadline === null) return;
    const left = Math.max(0, Math.round((pickupDeadline - Date.now()) / 1000));
    const mm = Math.floor(left / 60), ss = String(left % 60).padStart(2, "0");
    countdown.textContent = `The robot waits ${mm}:${ss} more, then takes the cup back to the tea room.`;
  }
  setInterval(tick, 1000);

  const events = new EventSource(`/api/orders/${encodeURIComponent(id)}/events?${key}`);
  events.onopen = () => { el("live").textContent = "live"; };
  events.onerror = () => { el("live").textContent = "reconnecting…"; };
  events.onmessage = (event) => { show(JSON.parse(event.data)); };
  events.addEventListener("timeline", (event) => {
    const t = JSON.parse(event.data);
    showTimeline(t);
    if (t.final) {
      events.close();
      el("live").textContent = "";
    }
  });

  async function act(method, path) {
    const response = await fetch(path, { method });
    const body = await response.json();
    el("action-error").hidden = response.ok;
    if (!response.ok) el("action-error").textContent = body.error;
    else if (show(body)) {
      const timeline = await fetch(`/api/orders/${encodeURIComponent(id)}/timeline?${key}`);
      if (timeline.ok) showTimeline(await timeline.json());
    }
  }
  el("cancel").addEventListener("click", () => act("DELETE", `/api/orders/${encodeURIComponent(id)}?${key}`));
  el("pickup").addEventListener("click", () => act("POST", `/api/orders/${encodeURIComponent(id)}/pickup?${key}`));
})();

// Live order status over server-sent events. Text only ever goes in through textContent.
"use strict";
(function () {
  const box = document.getElementById("order");
  const id = box.dataset.orderId;
  // The order's key authorizes this page's requests; it came in the page's own address.
  const key = `key=${encodeURIComponent(box.dataset.orderKey)}`;
  const statusText = JSON.parse(document.getElementById("status-text-data").textContent);
  const el = (name) => document.getElementById(name);
  const finalStates = ["delivered", "cancelled", "failed"];

  let shownUpdatedAt = -Infinity;

  // The stream and a button's own response can arrive in either order: never step back to
  // an older state (the response to "I have my coffee" must not undo "delivered").
  function show(order) {
    if (order.updated_at < shownUpdatedAt) return;
    shownUpdatedAt = order.updated_at;
    box.dataset.status = order.status;
    el("status-text").textContent = statusText[order.status] || order.status;
    el("queue").textContent = order.status === "queued" ? `${order.ahead} order(s) ahead of yours` : "";
    el("detail").textContent = order.detail;
    el("pickup").hidden = order.status !== "arrived";
    el("cancel").hidden = order.status !== "queued";
  }

  const events = new EventSource(`/api/orders/${encodeURIComponent(id)}/events?${key}`);
  events.onopen = () => { el("live").textContent = "live"; };
  events.onerror = () => { el("live").textContent = "reconnecting…"; };
  events.onmessage = (event) => {
    const order = JSON.parse(event.data);
    show(order);
    if (finalStates.includes(order.status)) {
      events.close();
      el("live").textContent = "";
    }
  };

  async function act(method, path) {
    const response = await fetch(path, { method });
    const body = await response.json();
    el("action-error").hidden = response.ok;
    if (!response.ok) el("action-error").textContent = body.error;
    else show(body);
  }
  el("cancel").addEventListener("click", () => act("DELETE", `/api/orders/${encodeURIComponent(id)}?${key}`));
  el("pickup").addEventListener("click", () => act("POST", `/api/orders/${encodeURIComponent(id)}/pickup?${key}`));
})();

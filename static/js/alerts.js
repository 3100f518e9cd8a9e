// The open-alert count in every page's top bar, from /api/alerts/open every few seconds;
// when the server cannot be asked, the count says it is unknown rather than show an old one.

const POLL_MS = 5000;
const chip = document.getElementById("alert-count");

async function refresh() {
  try {
    const response = await fetch("/api/alerts/open", { headers: { Accept: "application/json" }, credentials: "same-origin" });
    if (!response.ok) throw new Error(`HTTP ${response.status}`);
    show((await response.json()).open);
  } catch {
    show(null);
  }
}

function show(count) {
  chip.hidden = false;
  chip.dataset.open = count === null ? "" : String(count);
  chip.className = `alert-chip ${count === null ? "unknown" : count === 0 ? "none" : ""}`;
  chip.textContent = count === null ? "alerts: ?" : count === 1 ? "1 open alert" : `${count} open alerts`;
  chip.title = count === null ? "The server cannot be reached: the count is unknown." : "Open alerts in your buildings";
}

if (chip) {
  refresh();
  setInterval(refresh, POLL_MS);
  window.addEventListener("cloudnav:alerts", refresh);
}

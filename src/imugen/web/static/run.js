// The run page: follow a running run's progress; a second click on Start sends nothing.
// (A file of its own: the page's Content-Security-Policy allows no inline script.)
document.addEventListener("DOMContentLoaded", () => {
  const run = document.getElementById("run");
  const startForm = document.getElementById("start-form");
  if (startForm) {
    startForm.addEventListener("submit", (event) => {
      const button = document.getElementById("start");
      if (button.disabled) {
        event.preventDefault();
        return;
      }
      button.disabled = true;
    });
  }
  if (!run || run.dataset.status !== "running") return;
  const poll = async () => {
    const p = await (await fetch(run.dataset.progress)).json();
    document.getElementById("status").textContent = p.status;
    document.getElementById("progress").textContent =
      `${p.done} of ${p.total} jobs, ${p.stage}, ${p.elapsed_s} s` +
      (p.left_s !== null ? `, about ${p.left_s} s left` : "");
    document.getElementById("log").textContent = p.log;
    if (p.status === "running") setTimeout(poll, 1500);
    else location.reload();
  };
  setTimeout(poll, 1500);
});

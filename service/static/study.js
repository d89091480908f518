// A study's page: follow its jobs live and refresh its table and pictures as they finish.
"use strict";
(() => {
  const root = document.getElementById("study");
  const studyId = root.dataset.studyId;
  const finished = ["succeeded", "failed", "cancelled"];
  let lastDone = -1;
  let refreshing = false;
  let wanted = false;

  // One table read at a time; one asked for meanwhile (a job ended while the last table was on
  // its way) follows it, so the page never stays on a table read before the study ended.
  async function refresh() {
    wanted = true;
    if (refreshing) return;
    refreshing = true;
    try {
      while (wanted) {
        wanted = false;
        await readTable();
      }
    } finally {
      refreshing = false;
    }
  }

  async function readTable() {
    const response = await fetch(`/ui/studies/${studyId}/results`);
    if (!response.ok) return;
    const holder = document.createElement("div");
    holder.innerHTML = await response.text();
    const fragment = holder.querySelector("#fragment");
    document.getElementById("study-counts").innerHTML = fragment.querySelector("#fragment-counts").innerHTML;
    document.getElementById("study-results").innerHTML = fragment.querySelector("#fragment-results").innerHTML;
    document.getElementById("progress-bar").style.width = `${(100 * Number(fragment.dataset.progress)).toFixed(1)}%`;
    const status = document.getElementById("study-status");
    status.textContent = fragment.dataset.status;
    status.className = `status ${fragment.dataset.status}`;
  }

  function onState(state) {
    const jobs = state.jobs || {};
    const done = (jobs.succeeded || 0) + (jobs.failed || 0) + (jobs.cancelled || 0);
    if (state.progress !== undefined) {
      document.getElementById("progress-bar").style.width = `${(100 * state.progress).toFixed(1)}%`;
    }
    if (done !== lastDone) { lastDone = done; refresh(); }
  }

  if (!finished.includes(root.dataset.status)) {
    let source = nanonav.follow(`/studies/${studyId}/events`, onState, () => { refresh(); hideCancel(); });
    const poll = async () => {
      const answer = await nanonav.send("GET", `/studies/${studyId}`);
      if (!answer.ok) return;
      onState(answer.document);
      if (!finished.includes(answer.document.status)) window.setTimeout(poll, 1500);
      else { refresh(); hideCancel(); }
    };
    if (source === null) poll();
    else source.onerror = () => { if (source.readyState === EventSource.CLOSED) { source = null; poll(); } };
    const cancel = document.getElementById("cancel");
    if (cancel) {
      cancel.addEventListener("click", async () => {
        if (!window.confirm(`Cancel study #${studyId}? Its queued jobs are cancelled and its running ones stopped; the jobs that finished are kept.`)) return;
        cancel.disabled = true;
        const answer = await nanonav.send("POST", `/studies/${studyId}/cancel`);
        if (answer.ok) refresh();
        else cancel.disabled = false;
      });
    }
  }

  function hideCancel() {
    const cancel = document.getElementById("cancel");
    if (cancel) cancel.hidden = true;
    document.getElementById("delete-row").hidden = false;
  }

  // A finished study's failed jobs, queued again in one request; the page then follows them.
  const retry = document.getElementById("retry");
  if (retry) {
    retry.addEventListener("click", async () => {
      retry.disabled = true;
      const answer = await nanonav.send("POST", `/studies/${studyId}/retry`);
      if (answer.ok) { window.location.reload(); return; }
      retry.disabled = false;
      const error = document.getElementById("retry-error");
      error.textContent = (answer.document && answer.document.detail) || `The server answered ${answer.status}.`;
      error.hidden = false;
    });
  }

  nanonav.deleteButton(
    document.getElementById("delete"), `/studies/${studyId}`, `study #${studyId}`, "/ui/studies"
  );
})();

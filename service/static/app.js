// Shared by every page: talk to the JSON API and show its problems next to the fields at fault.
"use strict";

const nanonav = {
  async send(method, url, body) {
    const response = await fetch(url, {
      method,
      headers: { "Content-Type": "application/json", Accept: "application/json" },
      body: body === undefined ? undefined : JSON.stringify(body),
    });
    let document = null;
    try { document = await response.json(); } catch (error) { document = null; }
    return { ok: response.ok, status: response.status, document };
  },

  // Delete `url` once the person confirms, then go to `then`; a refusal (409 while it still
  // runs, 404 once gone) is shown in #delete-error. The page sends the button disabled, so a
  // click before this script has run is not silently lost.
  deleteButton(button, url, what, then) {
    button.disabled = false;
    button.addEventListener("click", async () => {
      if (!window.confirm(`Delete ${what} for good? This cannot be undone.`)) return;
      button.disabled = true;
      const answer = await nanonav.send("DELETE", url);
      if (answer.ok) { window.location.assign(then); return; }
      button.disabled = false;
      const error = document.getElementById("delete-error");
      error.textContent = (answer.document && answer.document.detail) || `The server answered ${answer.status}.`;
      error.hidden = false;
    });
  },

  // Put each problem's field errors next to the input whose data-pointer matches; the rest,
  // and the problem's detail, go to the form's error list.
  showProblem(form, problem, pointerFor) {
    const list = form.querySelector("#form-errors");
    form.querySelectorAll(".field-error").forEach((node) => node.remove());
    form.querySelectorAll("[aria-invalid]").forEach((node) => node.removeAttribute("aria-invalid"));
    list.innerHTML = "";
    const errors = (problem && problem.errors) || [];
    const unplaced = [];
    for (const error of errors) {
      const pointer = error.pointer || (error.parameter ? `?${error.parameter}` : "");
      const input = pointerFor ? pointerFor(pointer) : form.querySelector(`[data-pointer="${pointer}"]`);
      if (input) {
        input.setAttribute("aria-invalid", "true");
        const note = document.createElement("span");
        note.className = "field-error";
        note.textContent = error.detail;
        input.insertAdjacentElement("afterend", note);
      } else {
        unplaced.push(`${pointer || "request"}: ${error.detail}`);
      }
    }
    if (!errors.length && problem) unplaced.push(problem.detail || problem.title || "the request failed");
    for (const text of unplaced) {
      const item = document.createElement("li");
      item.textContent = text;
      list.appendChild(item);
    }
    list.hidden = unplaced.length === 0;
  },

  // Follow an event stream; `onState` receives each state, `onEnd` when the stream ends.
  follow(url, onState, onEnd) {
    if (!window.EventSource) return null;
    const source = new EventSource(url);
    const handle = (event) => {
      const state = JSON.parse(event.data);
      onState(state);
      if (["succeeded", "failed", "cancelled"].includes(state.status)) {
        source.close();
        if (onEnd) onEnd(state);
      }
    };
    source.addEventListener("progress", handle);
    source.addEventListener("status", handle);
    source.addEventListener("message", handle);
    return source;
  },

  duration(seconds) {
    if (!isFinite(seconds) || seconds < 0) return "";
    if (seconds < 60) return `${Math.round(seconds)} s`;
    const minutes = Math.floor(seconds / 60);
    if (minutes < 60) return `${minutes} min ${Math.round(seconds % 60)} s`;
    return `${Math.floor(minutes / 60)} h ${minutes % 60} min`;
  },
};

// With API keys, the header has a button that ends the browser's session on the server; if the
// server could not end it, the person is told so rather than shown the login page.
document.getElementById("logout")?.addEventListener("click", async () => {
  const answer = await nanonav.send("POST", "/ui/logout");
  if (!answer.ok) {
    const reason = (answer.document && answer.document.detail) || `the server answered ${answer.status}`;
    window.alert(`Not logged out: ${reason}. Try again.`);
    return;
  }
  window.location.assign("/ui/login");
});

// A picture is drawn the first time it is asked for, which takes a moment: its box says
// "drawing…" until it has loaded. Listening on the document also covers the pictures a page
// puts in later (a study's results as its jobs finish).
(() => {
  const settle = (image) => {
    const box = image.closest("a.picture");
    if (box && image.complete && image.naturalWidth > 0) box.classList.add("loaded");
  };
  document.addEventListener("load", (event) => {
    if (event.target instanceof HTMLImageElement) settle(event.target);
  }, true);
  document.addEventListener("error", (event) => {
    const note = event.target instanceof HTMLImageElement
      && event.target.closest("a.picture")?.querySelector(".drawing");
    if (note) note.textContent = "could not draw this picture: reload the page to try again";
  }, true);
  document.querySelectorAll("a.picture img").forEach(settle);
})();

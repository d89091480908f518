// The new-job form: its fields fill the scenario's JSON, which is what is sent.
"use strict";
(() => {
  const form = document.getElementById("job-form");
  const editor = document.getElementById("scenario-json");
  const numeric = new Set(["seed", "robots.count", "obstacles.count", "learning.episodes",
    "learning.max_steps", "evaluation.worlds", "cells.capacity"]);

  function parsed() {
    try {
      const value = JSON.parse(editor.value || "{}");
      return value && typeof value === "object" && !Array.isArray(value) ? value : null;
    } catch (error) { return null; }
  }

  function setPath(target, path, value) {
    const parts = path.split(".");
    let node = target;
    for (const part of parts.slice(0, -1)) {
      if (typeof node[part] !== "object" || node[part] === null) node[part] = {};
      node = node[part];
    }
    const last = parts[parts.length - 1];
    if (value === undefined) {
      delete node[last];
      if (parts.length > 1 && Object.keys(node).length === 0) delete target[parts[0]];
    } else {
      node[last] = value;
    }
  }

  // A checkbox left alone sends nothing (the preset's, shown indeterminate); once clicked, what
  // it shows.
  function fieldValue(input) {
    if (input.type === "checkbox") return input.checked;
    if (input.value === "") return undefined;
    return numeric.has(input.name) ? Number(input.value) : input.value;
  }

  function getPath(source, path) {
    let node = source;
    for (const part of path.split(".")) {
      if (typeof node !== "object" || node === null || !(part in node)) return undefined;
      node = node[part];
    }
    return node;
  }

  function syncEditor(event) {
    const scenario = parsed() || {};
    const input = event.target;
    if (!input.name || input === editor) return;
    setPath(scenario, input.name, fieldValue(input));
    editor.value = JSON.stringify(scenario, null, 2);
  }

  // The fields show what the JSON says, whether typed or pasted there or filled in by the page;
  // a menu with no such choice shows none rather than a wrong one.
  function syncFields() {
    const scenario = parsed();
    if (scenario === null) return;
    for (const input of form.querySelectorAll("input[name], select[name]")) {
      const value = getPath(scenario, input.name);
      if (input.type === "checkbox") {
        input.checked = value === true;
        input.indeterminate = typeof value !== "boolean";
        continue;
      }
      const text = value === undefined || value === null || typeof value === "object" ? "" : String(value);
      input.value = text;
      if (input.tagName === "SELECT" && input.value !== text) input.selectedIndex = -1;
    }
  }

  form.addEventListener("input", syncEditor);
  form.addEventListener("change", syncEditor);
  editor.addEventListener("input", syncFields);
  syncFields();

  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const scenario = parsed();
    if (scenario === null) {
      nanonav.showProblem(form, { detail: "the scenario is not a JSON object", errors: [] });
      document.getElementById("json-details").open = true;
      return;
    }
    const button = form.querySelector("button[type=submit]");
    button.disabled = true;
    const answer = await nanonav.send("POST", "/jobs", scenario);
    button.disabled = false;
    if (answer.ok) {
      window.location.href = `/ui/jobs/${answer.document.id}`;
      return;
    }
    const placeFor = (pointer) => {
      const exact = form.querySelector(`[data-pointer="${pointer}"]`);
      if (exact) return exact;
      document.getElementById("json-details").open = true;
      return null;
    };
    nanonav.showProblem(form, answer.document, placeFor);
  });
})();

// The new-study form: base fields and JSON, one or two swept parameters, seeds, comparison.
"use strict";
(() => {
  const form = document.getElementById("study-form");

  function value(text) {
    const trimmed = text.trim();
    if (trimmed === "true" || trimmed === "false") return trimmed === "true";
    if (trimmed !== "" && !isNaN(Number(trimmed))) return Number(trimmed);
    return trimmed;
  }

  function body() {
    let base;
    try { base = JSON.parse(document.getElementById("base-json").value || "{}"); } catch (error) { base = null; }
    if (!base || typeof base !== "object" || Array.isArray(base)) return null;
    const preset = form.elements["base.preset"].value;
    if (preset) base.preset = preset;
    const episodes = form.elements["base.learning.episodes"].value;
    if (episodes !== "") base.learning = { ...(base.learning || {}), episodes: Number(episodes) };
    const grid = {};
    const keys = {};
    for (const i of [1, 2]) {
      const key = form.elements[`key${i}`].value;
      const values = form.elements[`values${i}`].value;
      if (!key) continue;
      keys[i] = key;
      grid[key] = values.split(",").filter((v) => v.trim() !== "").map(value);
    }
    const compare = keys[form.elements.compare.value] || null;
    const spec = { name: form.elements.name.value, base, grid, compare };
    const replicates = form.elements.replicates.value;
    spec.replicates = replicates === "" ? 1 : Number(replicates);
    return { spec, keys };
  }

  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const built = body();
    if (built === null) {
      nanonav.showProblem(form, { detail: "the base scenario is not a JSON object", errors: [] });
      return;
    }
    const button = form.querySelector("button[type=submit]");
    button.disabled = true;
    const answer = await nanonav.send("POST", "/studies", built.spec);
    button.disabled = false;
    if (answer.ok) {
      window.location.href = `/ui/studies/${answer.document.id}`;
      return;
    }
    // #/grid/<key>/<index> goes under that parameter's values
    const placeFor = (pointer) => {
      const match = /^#\/grid\/([^/]+)/.exec(pointer);
      if (match) {
        const key = match[1].replace(/~1/g, "/").replace(/~0/g, "~");
        for (const i of [1, 2]) {
          if (built.keys[i] === key) return form.querySelector(`[data-values="${i}"]`);
        }
      }
      return form.querySelector(`[data-pointer="${pointer}"]`);
    };
    nanonav.showProblem(form, answer.document, placeFor);
  });
})();

// The login page: check the key with the server, which keeps it in an HttpOnly cookie.
"use strict";

(() => {
  const form = document.getElementById("login-form");
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const key = form.querySelector("#key").value.trim();
    const answer = await nanonav.send("POST", "/ui/login", { key });
    if (answer.ok) {
      window.location.assign(form.dataset.next || "/");
    } else {
      nanonav.showProblem(form, answer.document);
    }
  });
})();

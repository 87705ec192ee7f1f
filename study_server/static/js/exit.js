// Before the exit survey completes the session, the last events must reach the server: flush the
// outbox, then tell the server the last seq it should hold. The server answers with a "saving" page
// (which comes back here) until they are acknowledged, and completes anyway after a few attempts.
import { Outbox } from "./outbox.js";

const form = document.getElementById("exit-form");
if (form) {
  const outbox = new Outbox({ api: form.dataset.api, token: form.dataset.token, pageId: "exit", study: form.dataset.study,
    batch: Number(form.dataset.batch) });
  const finish = async () => {
    await Promise.race([outbox.flush(), new Promise((r) => setTimeout(r, 4000))]);
    form.last_seq.value = String(outbox.lastSeq);
    form.submit();
  };
  form.addEventListener("submit", (event) => { event.preventDefault(); finish(); });
  if (form.dataset.auto) setTimeout(finish, 1500);
}

// The event outbox: every interaction gets a per-session sequence number, is kept in localStorage until
// the server acknowledges it, and is sent in batches, retried with backoff, and flushed when the page is
// hidden or closed. After a reload the page picks up whatever the server has not acknowledged.

const MAX_BATCH = 200;
const MAX_BACKOFF_MS = 30000;

export class Outbox {
  constructor({ api, token, pageId, study, onStatus = () => {} }) {
    this.api = api;
    this.token = token;
    this.pageId = pageId;
    this.key = `scenesuggest-outbox-${study}-${token.slice(-12)}`;
    this.onStatus = onStatus;
    this.backoff = 1000;
    this.sending = null;
    this.timer = null;
    const saved = this.read();
    this.nextSeq = saved.nextSeq;
    this.acked = saved.acked;
    addEventListener("pagehide", () => this.flush({ keepalive: true }));
    document.addEventListener("visibilitychange", () => {
      if (document.visibilityState === "hidden") this.flush({ keepalive: true });
    });
    addEventListener("online", () => this.flush());
  }

  read() {
    try {
      const saved = JSON.parse(localStorage.getItem(this.key) || "null");
      if (saved && Array.isArray(saved.pending)) return saved;
    } catch (e) { /* a corrupt entry starts afresh */ }
    return { nextSeq: 0, acked: -1, pending: [] };
  }

  write(state) {
    try {
      localStorage.setItem(this.key, JSON.stringify(state));
    } catch (e) { /* storage full or blocked: events stay in memory for this page */ }
  }

  /** Continue numbering after what the server already holds (a new browser, cleared storage). */
  resumeFrom(serverAcked) {
    const state = this.read();
    state.nextSeq = Math.max(state.nextSeq, serverAcked + 1);
    state.acked = Math.max(state.acked, serverAcked);
    state.pending = state.pending.filter((e) => e.seq > state.acked);
    this.nextSeq = state.nextSeq;
    this.write(state);
  }

  /** Stop logging and sending (another page of the session has taken over). */
  stop() {
    this.stopped = true;
    clearTimeout(this.timer);
  }

  log(type, payload = {}, trial = null) {
    if (this.stopped) return -1;
    const state = this.read();
    const event = { seq: state.nextSeq, t: performance.timeOrigin + performance.now(), type, trial, payload };
    state.nextSeq += 1;
    state.pending.push(event);
    this.nextSeq = state.nextSeq;
    this.write(state);
    this.schedule(1000);
    return event.seq;
  }

  get lastSeq() { return this.read().nextSeq - 1; }
  get pendingCount() { return this.read().pending.length; }

  schedule(ms) {
    if (this.timer) return;
    this.timer = setTimeout(() => { this.timer = null; this.flush(); }, ms);
  }

  /** Send everything pending; resolves true when the server has acknowledged all of it. */
  async flush({ keepalive = false } = {}) {
    if (this.stopped) return true;
    if (this.sending) return this.sending;
    this.sending = this.send(keepalive).finally(() => { this.sending = null; });
    return this.sending;
  }

  async send(keepalive) {
    for (;;) {
      const state = this.read();
      const batch = state.pending.slice(0, MAX_BATCH);
      if (!batch.length) { this.onStatus("saved"); return true; }
      let response;
      try {
        response = await fetch(`${this.api}/events`, {
          method: "POST", keepalive,
          headers: { "Content-Type": "application/json", Authorization: `Bearer ${this.token}` },
          body: JSON.stringify({ page_id: this.pageId, events: batch }),
        });
      } catch (e) {
        this.retryLater();
        return false;
      }
      if (response.status === 422) {  // a malformed event would block the queue forever: set it aside
        const problem = await response.json().catch(() => ({}));
        const bad = /^events\[(\d+)\]/.exec(problem.field || "");
        const index = bad ? Number(bad[1]) : 0;
        const now = this.read();
        const [dropped] = now.pending.splice(index, 1);
        now.pending.push({ seq: dropped.seq, t: dropped.t, type: "client_error", trial: dropped.trial,
          payload: { message: `rejected ${dropped.type}: ${problem.field} ${problem.error}`.slice(0, 1900) } });
        now.pending.sort((a, b) => a.seq - b.seq);
        this.write(now);
        continue;
      }
      if (!response.ok) { this.retryLater(); return false; }
      const { acked_seq: acked } = await response.json();
      const now = this.read();
      now.acked = Math.max(now.acked, acked);
      const sent = new Set(batch.map((e) => e.seq));
      now.pending = now.pending.filter((e) => e.seq > now.acked && !(sent.has(e.seq) && e.seq <= acked));
      this.write(now);
      this.backoff = 1000;
      this.onStatus(now.pending.length ? "saving" : "saved");
    }
  }

  retryLater() {
    this.onStatus("offline");
    const wait = this.backoff;
    this.backoff = Math.min(this.backoff * 2, MAX_BACKOFF_MS);
    this.schedule(wait);
  }
}

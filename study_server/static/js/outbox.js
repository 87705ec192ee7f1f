// The event outbox: every interaction gets a per-session sequence number, is kept in localStorage until
// the server acknowledges it, and is sent in batches, retried with backoff, and flushed when the page is
// hidden or closed. After a reload the page picks up whatever the server has not acknowledged.
//
// Nothing is dropped. The page also keeps its own events in memory until the server acknowledges them, so a
// second tab that overwrites the shared storage cannot erase them; when two pages number an event alike, the
// page renumbers its own at once, and when the server already holds a different event under a seq (409), the
// events are sent again under the seqs the server hands out. An ended session (410) stops the outbox.

// A batch's events in JSON at most this many characters (the server takes bodies up to 1 MiB; one event may be a
// whole library's fixed list, about 200 kB): a batch is cut short before it, always holding at least one event.
const MAX_BATCH_CHARS = 256 * 1024;
const MAX_BACKOFF_MS = 30000;
/** What tells two events apart when their seqs change: a random id kept with the event in this browser (never
 * sent); entries stored by an older page without one fall back to their client time and type. */
const identity = (e) => e.uid || `${e.t}|${e.type}`;
const newId = () => (crypto.randomUUID ? crypto.randomUUID() : `${Date.now()}-${Math.random()}`);
/** The event as the server takes it (the local id and the vocabulary version stay here). */
const wire = ({ uid, v, ...event }) => event;
/** The version of the event vocabulary an event was logged in (entries of pages before versions: 1). */
const versionOf = (e) => e.v ?? 1;

export class Outbox {
  constructor({ api, token, pageId, study, batch, vocabulary = 1, onStatus = () => {} }) {
    this.api = api;
    // events per request, as the server says (its boot data, the exit form's data-batch); a page whose script is
    // older than the server's (a cached one) sends one at a time: slower, and nothing is lost
    this.batch = Number.isInteger(batch) && batch > 0 ? batch : 1;
    this.vocabulary = vocabulary;  // the version of the event vocabulary this page logs in
    this.token = token;
    this.pageId = pageId;
    this.key = `scenesuggest-outbox-${study}-${token.slice(-12)}`;
    this.onStatus = onStatus;
    this.backoff = 1000;
    this.sending = null;
    this.timer = null;
    this.mine = new Map();  // identity → this page's event, until the server acknowledges it
    const saved = this.read();
    this.nextSeq = saved.nextSeq;
    this.acked = saved.acked;
    addEventListener("pagehide", () => this.flush({ keepalive: true }));
    document.addEventListener("visibilitychange", () => {
      if (document.visibilityState === "hidden") this.flush({ keepalive: true });
    });
    addEventListener("online", () => this.flush());
  }

  /** The shared state, with every event of this page that the storage lost or numbered twice put back. */
  read() {
    let state = null;
    try {
      const saved = JSON.parse(localStorage.getItem(this.key) || "null");
      if (saved && Array.isArray(saved.pending)) state = saved;
    } catch (e) { /* blocked or corrupt: this page's own copy below */ }
    if (!state && this.memory) state = JSON.parse(JSON.stringify(this.memory));  // storage blocked or cleared
    state = state || { nextSeq: 0, acked: -1, pending: [] };
    if (!this.mine.size) return state;
    const held = new Map(state.pending.map((e) => [identity(e), e]));
    const taken = new Set(state.pending.map((e) => e.seq));
    for (const [id, event] of this.mine) {
      if (held.has(id)) { this.mine.set(id, held.get(id)); continue; }
      if (taken.has(event.seq)) event.seq = state.nextSeq;  // another page used this seq for its own event
      state.nextSeq = Math.max(state.nextSeq, event.seq + 1);
      state.pending.push(event);
      taken.add(event.seq);
    }
    state.pending.sort((a, b) => a.seq - b.seq);
    return state;
  }

  write(state) {
    this.nextSeq = state.nextSeq;
    this.memory = state;
    try {
      localStorage.setItem(this.key, JSON.stringify(state));
    } catch (e) { /* storage full or blocked: events stay in memory for this page */ }
  }

  /** Forget the events of ``sent`` that the server acknowledged (``acked``: every seq up to it is stored).
   * Others stay, even under an acknowledged seq: sent again, the server acknowledges them if it holds them
   * and asks for new seqs if it holds something else there. */
  acknowledge(state, sent, acked) {
    state.acked = Math.max(state.acked, acked);
    const done = new Set(sent.filter((e) => e.seq <= acked).map(identity));
    state.pending = state.pending.filter((e) => !done.has(identity(e)));
    for (const id of done) this.mine.delete(id);
  }

  /** Continue numbering after what the server already holds (a new browser, cleared storage). */
  resumeFrom(serverAcked) {
    const state = this.read();
    state.nextSeq = Math.max(state.nextSeq, serverAcked + 1);
    state.acked = Math.max(state.acked, serverAcked);
    // events at or below the server's seq stay: if the server holds them they are acknowledged on sending,
    // if it holds others there, they are renumbered
    this.write(state);
  }

  /** Stop logging and sending (another page of the session has taken over). */
  stop() {
    this.write(this.read());  // this page's unacknowledged events stay in the shared storage for the next page
    this.stopped = true;
    clearTimeout(this.timer);
  }

  log(type, payload = {}, trial = null) {
    if (this.stopped) return -1;
    const state = this.read();
    const event = { seq: state.nextSeq, t: performance.timeOrigin + performance.now(), type, trial, payload,
      uid: newId(), v: this.vocabulary };
    state.nextSeq += 1;
    state.pending.push(event);
    this.mine.set(identity(event), event);
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

  /** Send batches until nothing is pending (true) or sending must wait or stop (false). */
  async send(keepalive) {
    for (;;) {
      const { version, batch } = this.nextBatch();
      if (!batch.length) { this.onStatus("saved"); return true; }
      const response = await this.post(version, batch, keepalive);
      if (!response) { this.retryLater(); return false; }
      if (response.status === 422) {  // a malformed event would block the queue forever: set it aside
        if (await this.setAside(response, batch)) continue;
        this.retryLater();  // not one event's content: nothing to set aside
        return false;
      }
      if (response.status === 409) {  // the server holds other events under some of these seqs: renumber ours
        if (await this.renumber(response, batch)) continue;
        this.retryLater();
        return false;
      }
      if (response.status === 410) {  // the session has ended: nothing more is taken
        this.stop();
        this.onStatus("ended");
        return false;
      }
      if (response.status === 429) {  // over a quota: wait as long as the server asks
        this.waitAsAsked(response);
        return false;
      }
      if (!response.ok) { this.retryLater(); return false; }
      await this.accept(response, batch);
    }
  }

  /** The first pending events, of one vocabulary version, within this.batch and MAX_BATCH_CHARS (at least one). */
  nextBatch() {
    const state = this.read();
    // one batch, one vocabulary: events an older page left behind are sent in the version they were logged in
    const version = state.pending.length ? versionOf(state.pending[0]) : this.vocabulary;
    const run = state.pending.findIndex((e) => versionOf(e) !== version);
    const batch = [];
    let chars = 0;
    for (const e of state.pending.slice(0, Math.min(this.batch, run < 0 ? this.batch : run))) {
      chars += JSON.stringify(wire(e)).length;
      if (batch.length && chars > MAX_BATCH_CHARS) break;
      batch.push(e);
    }
    return { version, batch };
  }

  /** POST one batch (``keepalive``: it may outlive the page); resolves the response, or null when it failed. */
  async post(version, batch, keepalive) {
    try {
      return await fetch(`${this.api}/events`, {
        method: "POST", keepalive,
        headers: { "Content-Type": "application/json", Authorization: `Bearer ${this.token}` },
        body: JSON.stringify({ page_id: this.pageId, vocabulary: version, events: batch.map(wire) }),
      });
    } catch (e) {
      return null;
    }
  }

  /** After a 422: a client_error note takes the seq of the event it names; false when it names no event. */
  async setAside(response, batch) {
    const problem = await response.json().catch(() => ({}));
    const bad = /^events\[(\d+)\]\.(payload|type)/.exec(problem.field || "");
    if (!bad) return false;
    const rejected = batch[Number(bad[1])];
    const now = this.read();
    const index = now.pending.findIndex((e) => identity(e) === identity(rejected));
    if (index < 0) return true;
    const [dropped] = now.pending.splice(index, 1);
    this.mine.delete(identity(dropped));
    const note = { seq: dropped.seq, t: dropped.t, type: "client_error", trial: dropped.trial, uid: newId(),
      v: versionOf(dropped),
      payload: { message: `rejected ${dropped.type}: ${problem.field} ${problem.error}`.slice(0, 1900) } };
    now.pending.push(note);
    this.mine.set(identity(note), note);
    now.pending.sort((a, b) => a.seq - b.seq);
    this.write(now);
    return true;
  }

  /** After a 409: the events of ``batch`` it names get new seqs from its next_seq on; false when it names none. */
  async renumber(response, batch) {
    const problem = await response.json().catch(() => ({}));
    if (!Array.isArray(problem.conflicts)) return false;
    const moved = new Set(problem.conflicts.map((i) => identity(batch[i])));
    const now = this.read();
    now.nextSeq = Math.max(now.nextSeq, problem.next_seq || 0);
    for (const e of now.pending) if (moved.has(identity(e))) { e.seq = now.nextSeq; now.nextSeq += 1; }
    now.pending.sort((a, b) => a.seq - b.seq);
    this.write(now);
    return true;
  }

  /** After a 429: send again once the answer's Retry-After (seconds; 60 without one) has passed. */
  waitAsAsked(response) {
    const wait = Number(response.headers.get("Retry-After")) || 60;
    this.onStatus("offline");
    this.timer = setTimeout(() => { this.timer = null; this.flush(); }, wait * 1000);
  }

  /** After a 2xx: forget what the server acknowledged of ``batch`` and reset the backoff. */
  async accept(response, batch) {
    const { acked_seq: acked } = await response.json();
    const now = this.read();
    this.acknowledge(now, batch, acked);
    this.write(now);
    this.backoff = 1000;
    this.onStatus(now.pending.length ? "saving" : "saved");
  }

  retryLater() {
    this.onStatus("offline");
    const wait = this.backoff;
    this.backoff = Math.min(this.backoff * 2, MAX_BACKOFF_MS);
    this.schedule(wait);
  }
}

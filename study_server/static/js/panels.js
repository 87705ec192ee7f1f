// The two ways of choosing a model: the fixed-order list with keyword search (condition "none"), and the
// floating panel of ranked suggestions beside a click, with a search box that overrides it ("basic", "full").

function el(tag, attrs = {}, children = []) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "text") node.textContent = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v);
  }
  for (const c of children) node.append(c);
  return node;
}

function tile(model, label, onPick, extra = {}) {
  const img = el("img", { src: model.thumbnail, alt: "", loading: "lazy", width: "72", height: "72" });
  return el("button", { type: "button", class: "tile", title: label, onclick: onPick, ...extra },
    [img, el("span", { text: label })]);
}

/** A category's name as words: "ChestOfDrawers" → "Chest of drawers", "4Shelves" → "4 shelves"; acronyms
 * ("TV", "PS3", "DSLR camera") and names already in words stay as they are. */
export function categoryLabel(category) {
  const words = category.replace(/([a-z])([A-Z])/g, "$1 $2").replace(/([0-9A-Z])([A-Z][a-z])/g, "$1 $2")
    .split(" ");
  return words.map((w, i) => (i > 0 && /^[A-Z][a-z]+$/.test(w) ? w.toLowerCase() : w)).join(" ");
}

/** Debounced keyword search against the study's library; ``show`` receives the hits. */
function searchBox(placeholder, api, onResults, log) {
  const input = el("input", { type: "search", placeholder, "aria-label": placeholder, autocomplete: "off" });
  let timer = null;
  let last = "";
  input.addEventListener("input", () => {
    clearTimeout(timer);
    timer = setTimeout(async () => {
      const text = input.value.trim();
      if (text === last) return;
      last = text;
      log("search", { text });
      if (!text) { onResults(null); return; }
      const r = await api(`/search?q=${encodeURIComponent(text)}`).then((x) => (x.ok ? x.json() : null))
        .catch(() => null);
      if (!r) { last = ""; return; }  // not answered (offline, or still too many lists): typing asks again
      if (input.value.trim() === text) onResults(r);
    }, 250);
  });
  return input;
}

export class ModelListPanel {
  constructor(container, { models, api, log, strings, onChoose }) {
    this.models = models;
    this.onChoose = onChoose;
    this.log = log;
    this.list = el("div", { class: "tiles", role: "list" });
    this.search = searchBox(strings.search, api, (r) => this.show(r), log);
    container.append(el("div", { class: "panel-head" }, [el("h2", { text: strings.models }), this.search]), this.list);
    this.show(null);
  }

  /** The fixed list (``results`` null) or search results, logged as shown. */
  show(results) {
    const started = performance.now();
    const source = results ? "search" : "fixed";
    const items = results ? results.hits : this.models;
    this.list.replaceChildren(...items.map((m, i) => tile(m, m.label || m.name || m.category, () => {
      for (const t of this.list.querySelectorAll(".tile")) t.classList.remove("chosen");
      this.list.children[i].classList.add("chosen");
      this.onChoose(m, { source, rank: i + 1, listId: results ? results.list_id : null });
    }, { "data-model": m.id, "data-rank": String(i + 1) })));
    this.log("list_shown", { source, items: items.map((m) => m.id), list_id: results ? results.list_id : null });
    // how long building the list took (ms), for the panel benchmark and the browser's performance tools
    performance.measure("model-list-build", { start: started, detail: { items: items.length } });
  }

  clearChoice() {
    for (const t of this.list.querySelectorAll(".tile")) t.classList.remove("chosen");
  }
}

export class SuggestionPanel {
  constructor(host, { api, log, strings, onPick }) {
    this.host = host;
    this.api = api;
    this.log = log;
    this.strings = strings;
    this.onPick = onPick;
    this.node = el("div", { class: "suggestions", role: "dialog", "aria-label": strings.suggestions, hidden: "" });
    host.append(this.node);
  }

  get open() { return !this.node.hidden; }

  close() { this.node.hidden = true; }

  /** Show the ranked categories of a suggestion response beside the pixel (x, y). */
  show(response, x, y) {
    this.response = response;
    const head = el("div", { class: "panel-head" }, [
      el("strong", { text: this.strings.suggestions }),
      el("button", { type: "button", class: "close", "aria-label": this.strings.close, text: "×", onclick: () => this.close() }),
    ]);
    this.search = searchBox(this.strings.search, this.api, (r) => this.showSearch(r), this.log);
    this.body = el("div", { class: "tiles", role: "list" });
    this.node.replaceChildren(head, this.search, this.body);
    this.showRanked();
    this.node.hidden = false;
    const host = this.host.getBoundingClientRect();
    const width = this.node.offsetWidth || 300;
    const height = this.node.offsetHeight || 360;
    const left = Math.min(Math.max(8, x - host.left + 24), host.width - width - 8);
    const top = Math.min(Math.max(8, y - host.top - 40), host.height - height - 8);
    this.node.style.left = `${left}px`;
    this.node.style.top = `${top}px`;
  }

  showRanked() {
    const items = this.response.suggestions;
    this.body.replaceChildren(...items.map((s, i) => {
      const group = el("div", { class: "category", role: "listitem" });
      const main = tile(s.models[0], s.label || categoryLabel(s.category), () => this.onPick(s, s.models[0], {
        source: "context", rank: i + 1, listId: this.response.list_id }),
      { "data-category": s.category, "data-rank": String(i + 1) });
      group.append(main);
      if (s.models.length > 1) {
        const more = el("button", { type: "button", class: "more", text: `+${s.models.length - 1}`, title: this.strings.more,
          onclick: () => {
            if (group.querySelector(".members")) { group.querySelector(".members").remove(); return; }
            group.append(el("div", { class: "members" }, s.models.map((m) => tile(m, m.label || m.name, () =>
              this.onPick(s, m, { source: "context", rank: i + 1, listId: this.response.list_id }), { "data-model": m.id }))));
          } });
        group.append(more);
      }
      return group;
    }));
  }

  showSearch(results) {
    if (!results) { this.showRanked(); return; }
    this.log("list_shown", { source: "search", items: results.hits.map((m) => m.id), list_id: results.list_id });
    this.body.replaceChildren(...results.hits.map((m, i) => tile(m, m.label || m.name || m.category, () =>
      this.onPick(null, m, { source: "search", rank: i + 1, listId: results.list_id }), { "data-model": m.id, "data-rank": String(i + 1) })));
  }
}

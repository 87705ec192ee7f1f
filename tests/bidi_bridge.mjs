// Firefox for the browser tests: puppeteer-core drives Debian's Firefox ESR over WebDriver BiDi, and this bridge
// lets the browser tests and the client benchmark drive it as they drive the other engines (browsers.py). It reads one
// JSON command per line on stdin ({id, op, ...}) and answers each with one line on stdout ({id, value} or
// {id, error}). Launched as: node bidi_bridge.mjs FIREFOX WIDTH HEIGHT HEADLESS(0|1)
import { createInterface } from "node:readline";
import puppeteer from "puppeteer-core";

const [,, executablePath, width, height, headless] = process.argv;
const browser = await puppeteer.launch({
  browser: "firefox", executablePath, headless: headless === "1",
  args: [`--width=${width}`, `--height=${height}`],
  extraPrefsFirefox: { "browser.shell.checkDefaultBrowser": false, "datareporting.policy.dataSubmissionEnabled": false },
});
const page = (await browser.pages())[0] ?? await browser.newPage();
try {
  await page.setViewport({ width: Number(width), height: Number(height) });
} catch (error) {
  // puppeteer sets the viewport and the screen orientation together; a Firefox ESR without BiDi's
  // emulation.setScreenOrientationOverride refuses the second after carrying out the first
  if (!String(error?.message).includes("setScreenOrientationOverride")) throw error;
}

const problems = [];
page.on("console", (m) => { if (m.type() === "error") problems.push(m.text()); });
page.on("pageerror", (e) => problems.push(String(e?.message ?? e)));

const ops = {
  goto: ({ url }) => page.goto(url, { waitUntil: "load" }).then(() => null),
  reload: () => page.reload({ waitUntil: "load" }).then(() => null),
  evaluate: ({ expression }) => page.evaluate(expression),
  click: ({ selector }) => page.click(selector),
  type: ({ selector, text }) => page.type(selector, text),
  mouse: async ({ action, x, y }) => {
    if (action === "move") await page.mouse.move(x, y);
    else if (action === "down") await page.mouse.down();
    else if (action === "up") await page.mouse.up();
  },
  key: async ({ action, key }) => {
    if (action === "down") await page.keyboard.down(key);
    else if (action === "up") await page.keyboard.up(key);
    else await page.keyboard.press(key);
  },
  screenshot: ({ path }) => page.screenshot({ path }).then(() => null),
  cookies: ({ url, cookies }) => page.setCookie(...cookies.map(
    (c) => ({ name: c.name, value: c.value, url, path: c.path, httpOnly: c.httpOnly }))).then(() => null),
  problems: () => problems.splice(0),
  close: async () => { await browser.close(); process.exit(0); },
};

const answer = (line) => process.stdout.write(JSON.stringify(line) + "\n");
answer({ id: 0, value: await browser.version() });
for await (const line of createInterface({ input: process.stdin })) {
  const command = JSON.parse(line);
  try {
    const value = await ops[command.op](command);
    answer({ id: command.id, value: value === undefined ? null : value });
  } catch (e) {
    answer({ id: command.id, error: String(e?.message ?? e) });
  }
}
await browser.close();

"""The three browser engines a crowd uses, driven the same way by the browser tests and the client benchmark:
Chromium (Playwright), Firefox ESR (puppeteer-core over WebDriver BiDi, through ``bidi_bridge.mjs``) and WebKitGTK,
Safari's engine (Selenium and WebKitWebDriver). Firefox and WebKit need a display for WebGL: they run headful on a
private Xvfb (Mesa's llvmpipe draws).

A :class:`Driver` is one page of one browser (a fresh profile), with what a participant does (clicks on selectors
and pixels, pointer drags, keys), the cookies a walk over HTTP leaves, and what a test reads (a JavaScript
expression's value, awaited when it is a promise). Drivers send whole CSS pixels, as people's pointers do. The
trial page's test hook is asked for through ``sessionStorage`` (``sceneSuggestTestHook``), which any engine's
driver can set on the study's origin before the trial page loads.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import time
from abc import ABC, abstractmethod
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ENGINES = ("chromium", "firefox", "webkit")
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
#: Headless Chromium with WebGL on SwiftShader (software), as on a machine without a GPU.
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--enable-unsafe-swiftshader", "--use-angle=swiftshader"]
FIREFOX = shutil.which("firefox-esr") or "/usr/bin/firefox-esr"
WEBKIT_DRIVER = shutil.which("WebKitWebDriver") or "/usr/bin/WebKitWebDriver"
XVFB = shutil.which("Xvfb") or "/usr/bin/Xvfb"
BRIDGE = Path(__file__).with_name("bidi_bridge.mjs")
#: The page's size in CSS pixels (width, height) unless a driver is given another.
VIEWPORT = (1280, 720)


def missing(engine: str) -> str | None:
    """Why ``engine`` cannot run on this machine (None: it can)."""
    needs = {"chromium": [(CHROMIUM, "chromium")],
             "firefox": [(FIREFOX, "firefox-esr"), (XVFB, "xvfb"),
                         (str(ROOT / "node_modules" / "puppeteer-core"), "npm ci (puppeteer-core)")],
             "webkit": [(WEBKIT_DRIVER, "webkit2gtk-driver"), (XVFB, "xvfb")]}[engine]
    absent = [what for path, what in needs if not Path(path).exists()]
    module = {"chromium": "playwright", "webkit": "selenium"}.get(engine)
    if module and importlib.util.find_spec(module) is None:
        absent.append(f"{module} (pip)")
    return ("not installed: " + ", ".join(absent)) if absent else None


class Display:
    """A private X display (Xvfb) for the headful engines; ``env`` is the environment their processes get."""

    def __init__(self):
        read, write = os.pipe()
        self.proc = subprocess.Popen([XVFB, "-displayfd", str(write), "-screen", "0", "1920x1200x24", "-nolisten",
                                      "tcp", "-noreset"], pass_fds=(write,), stderr=subprocess.DEVNULL)
        os.close(write)
        with os.fdopen(read) as f:
            number = f.readline().strip()
        self.env = {**os.environ, "DISPLAY": f":{number}"}

    def close(self):
        self.proc.terminate()
        self.proc.wait(10)


class Driver(ABC):
    """One page of one browser engine (see the module's docstring)."""

    name = ""
    version = ""

    # --- each engine's own (every driver below implements them) --------------------------------------------
    @abstractmethod
    def goto(self, url: str) -> None: ...
    @abstractmethod
    def reload(self) -> None: ...
    @abstractmethod
    def evaluate(self, expression: str): ...
    @abstractmethod
    def click(self, selector: str) -> None: ...
    @abstractmethod
    def fill(self, selector: str, text: str) -> None: ...
    @abstractmethod
    def mouse(self, action: str, x: float = 0, y: float = 0) -> None: ...
    @abstractmethod
    def key(self, action: str, key: str) -> None: ...
    @abstractmethod
    def screenshot(self, path: Path) -> None: ...
    @abstractmethod
    def add_cookies(self, base: str, cookies: list[dict]) -> None:
        """The cookies a walk over HTTP left (``HttpTransport.cookies()``: name, value, path, httpOnly), for
        the origin ``base``: the browser carries on as that participant. The page must be on that origin (WebDriver
        sets cookies on the page's own; Firefox keeps them apart per top-level site)."""
    @abstractmethod
    def close(self) -> None: ...

    def problems(self) -> list[str] | None:
        """Console errors since last asked (None: the engine's driver shows no console)."""
        return None

    # --- the same in every engine ---------------------------------------------------------------------------
    def until(self, expression: str, timeout: float = 30.0):
        """Poll a JavaScript expression until it is truthy; its value."""
        end = time.time() + timeout
        while time.time() < end:
            try:
                value = self.evaluate(expression)
            except Exception:  # noqa: BLE001 — the page is navigating
                value = None
            if value:
                return value
            time.sleep(0.05)
        raise AssertionError(f"{self.name}: timed out waiting for {expression}")

    def submit(self, selector: str, timeout: float = 30.0) -> None:
        """Click a control that loads another page, and wait for that page."""
        self.evaluate("(window.sceneSuggestLeaving = true)")
        self.click(selector)
        self.until("!window.sceneSuggestLeaving && document.readyState === 'complete' && document.body && "
                   "document.body.dataset.step", timeout)

    def press(self, keys: str) -> None:
        """A key or a chord (``"Control+z"``)."""
        *held, last = keys.split("+")
        for k in held:
            self.key("down", k)
        self.key("press", last)
        for k in reversed(held):
            self.key("up", k)

    def click_at(self, x: float, y: float, shift: bool = False) -> None:
        if shift:
            self.key("down", "Shift")
        self.mouse("move", round(x), round(y))
        self.mouse("down")
        self.mouse("up")
        if shift:
            self.key("up", "Shift")

    def drag(self, points) -> None:
        """Press at the first point, move through the others, release at the last (whole pixels)."""
        (x0, y0), *rest = points
        self.mouse("move", round(x0), round(y0))
        self.mouse("down")
        for x, y in rest:
            self.mouse("move", round(x), round(y))
        self.mouse("up")


class ChromiumDriver(Driver):
    name = "chromium"

    def __init__(self, display: Display | None = None, viewport: tuple[int, int] = VIEWPORT):
        from playwright.sync_api import sync_playwright

        self._pw = sync_playwright().start()
        self._browser = self._pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        self.version = self._browser.version
        self._context = self._browser.new_context(viewport={"width": viewport[0], "height": viewport[1]})
        self.page = self._context.new_page()
        self._problems: list[str] = []
        self.page.on("console", lambda m: m.type == "error" and self._problems.append(m.text))
        self.page.on("pageerror", lambda e: self._problems.append(str(e)))

    def goto(self, url): self.page.goto(url)
    def reload(self): self.page.reload()
    def evaluate(self, expression): return self.page.evaluate(f"async () => ({expression})")
    def click(self, selector): self.page.click(selector)
    def fill(self, selector, text): self.page.fill(selector, text)
    def screenshot(self, path): self.page.screenshot(path=str(path))

    def add_cookies(self, base, cookies):
        self._context.add_cookies(cookies)

    def mouse(self, action, x=0, y=0):
        getattr(self.page.mouse, action)(*((x, y) if action == "move" else ()))

    def key(self, action, key):
        getattr(self.page.keyboard, action)(key)

    def problems(self):
        seen, self._problems[:] = list(self._problems), []
        return seen

    def close(self):
        self._browser.close()
        self._pw.stop()


class FirefoxDriver(Driver):
    """Firefox ESR through ``bidi_bridge.mjs`` (puppeteer-core, WebDriver BiDi); headful on ``display``, or
    headless — where Firefox here has no WebGL at all, as a participant whose GL is broken."""

    name = "firefox"

    def __init__(self, display: Display | None = None, viewport: tuple[int, int] = VIEWPORT):
        args = ["node", str(BRIDGE), FIREFOX, str(viewport[0]), str(viewport[1]), "0" if display else "1"]
        env = {**(display.env if display else os.environ), "MOZ_CRASHREPORTER_DISABLE": "1"}
        self._proc = subprocess.Popen(args, cwd=ROOT, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                      stderr=subprocess.DEVNULL, text=True, bufsize=1)
        self._next = 0
        self.version = self._read(0)

    def _read(self, wanted: int):
        line = self._proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the Firefox bridge stopped (exit {self._proc.poll()})")
        answer = json.loads(line)
        assert answer["id"] == wanted, answer
        if "error" in answer:
            raise RuntimeError(f"firefox: {answer['error']}")
        return answer["value"]

    def _call(self, op: str, **args):
        self._next += 1
        self._proc.stdin.write(json.dumps({"id": self._next, "op": op, **args}) + "\n")
        return self._read(self._next)

    def goto(self, url): self._call("goto", url=url)
    def reload(self): self._call("reload")
    def evaluate(self, expression): return self._call("evaluate", expression=f"(async () => ({expression}))()")
    def click(self, selector): self._call("click", selector=selector)
    def fill(self, selector, text):
        self.evaluate(f"(document.querySelector({json.dumps(selector)}).value = '', true)")
        self._call("type", selector=selector, text=text)
    def mouse(self, action, x=0, y=0): self._call("mouse", action=action, x=x, y=y)
    def key(self, action, key): self._call("key", action=action, key=key)
    def screenshot(self, path): self._call("screenshot", path=str(path))
    def add_cookies(self, base, cookies): self._call("cookies", url=base, cookies=cookies)
    def problems(self): return self._call("problems")

    def close(self):
        try:
            self._proc.stdin.write(json.dumps({"id": -1, "op": "close"}) + "\n")
            self._proc.stdin.flush()
            self._proc.wait(20)
        except (OSError, subprocess.TimeoutExpired):
            self._proc.kill()


class WebKitDriver(Driver):
    """WebKitGTK through WebKitWebDriver (Selenium), headful on ``display``; each session is an ephemeral profile
    (WebKit's automation sessions keep no storage). It exposes no console."""

    name = "webkit"

    def __init__(self, display: Display | None = None, viewport: tuple[int, int] = VIEWPORT):
        from selenium import webdriver

        options = webdriver.WebKitGTKOptions()
        service = webdriver.WebKitGTKService(executable_path=WEBKIT_DRIVER, env=display.env if display else None)
        self._d = webdriver.WebKitGTK(options=options, service=service)
        self._d.set_script_timeout(600)  # an evaluated promise may take minutes (a benchmark's orbit)
        inner = self._fit_page(viewport)
        if inner != tuple(viewport):
            self._d.quit()
            raise RuntimeError(f"webkit: a page of {viewport[0]}×{viewport[1]} was asked for, the window gives "
                               f"{inner[0]}×{inner[1]} (is the display large enough?)")
        self.version = self._d.capabilities.get("browserVersion", "")

    def _inner(self) -> tuple[int, int]:
        return tuple(self._d.execute_script("return [window.innerWidth, window.innerHeight]"))

    def _fit_page(self, viewport: tuple[int, int], attempts: int = 4) -> tuple[int, int]:
        """Size the window so that its page is ``viewport`` (the window is as much larger as its frame takes). Under
        X the page follows a resize a moment later, so after each resize the page's size is read until it holds
        still before the frame is measured again. Returns the page's size at the end."""
        size = tuple(viewport)
        inner = self._inner()
        for _ in range(attempts):
            self._d.set_window_size(*size)
            inner = self._settled()
            if inner == tuple(viewport):
                break
            size = (size[0] + viewport[0] - inner[0], size[1] + viewport[1] - inner[1])
        return inner

    def _settled(self, still: int = 4, wait_s: float = 3.0) -> tuple[int, int]:
        """The page's size once ``still`` reads 50 ms apart agree (or after ``wait_s``)."""
        deadline = time.monotonic() + wait_s
        last, same = self._inner(), 1
        while same < still and time.monotonic() < deadline:
            time.sleep(0.05)
            now = self._inner()
            same = same + 1 if now == last else 1
            last = now
        return last

    def goto(self, url): self._d.get(url)
    def reload(self): self._d.refresh()

    def evaluate(self, expression):
        value = self._d.execute_async_script(
            "const done = arguments[arguments.length - 1];"
            f"Promise.resolve().then(async () => ({expression}))"
            ".then((v) => done({value: v === undefined ? null : v}), (e) => done({error: String(e)}));")
        if "error" in value:
            raise RuntimeError(f"webkit: {value['error']}")
        return value["value"]

    def click(self, selector):
        from selenium.webdriver.common.by import By

        self._d.find_element(By.CSS_SELECTOR, selector).click()

    def fill(self, selector, text):
        from selenium.webdriver.common.by import By

        element = self._d.find_element(By.CSS_SELECTOR, selector)
        element.clear()
        element.send_keys(text)

    def mouse(self, action, x=0, y=0):
        from selenium.webdriver.common.actions.action_builder import ActionBuilder

        actions = ActionBuilder(self._d)
        if action == "move":
            actions.pointer_action.move_to_location(int(x), int(y))
        elif action == "down":
            actions.pointer_action.pointer_down()
        else:
            actions.pointer_action.pointer_up()
        actions.perform()

    def key(self, action, key):
        from selenium.webdriver.common.action_chains import ActionChains
        from selenium.webdriver.common.keys import Keys

        name = {"Shift": Keys.SHIFT, "Control": Keys.CONTROL, "Delete": Keys.DELETE, "Alt": Keys.ALT,
                "Meta": Keys.META, "Escape": Keys.ESCAPE, "Enter": Keys.ENTER}.get(key, key)
        chain = ActionChains(self._d)
        if action == "down":
            chain.key_down(name)
        elif action == "up":
            chain.key_up(name)
        else:
            chain.key_down(name).key_up(name)
        chain.perform()

    def screenshot(self, path): self._d.save_screenshot(str(path))

    def add_cookies(self, base, cookies):
        for c in cookies:
            self._d.add_cookie({k: c[k] for k in ("name", "value", "path", "httpOnly")})

    def close(self):
        self._d.quit()


DRIVERS = {"chromium": ChromiumDriver, "firefox": FirefoxDriver, "webkit": WebKitDriver}

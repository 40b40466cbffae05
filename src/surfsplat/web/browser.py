"""A small driver of headless Chromium over the DevTools protocol, for the tests and benchmarks of the
browser viewer.

The browser is started with ``--remote-debugging-pipe``: it reads protocol messages (JSON, each ended
by a NUL byte) from file descriptor 3 and writes its answers and events to descriptor 4, so nothing
listens on a port. Headless WebGL2 runs on SwiftShader (``--use-angle=swiftshader``), Chromium's CPU
implementation; no GPU, display or network is needed. A :class:`Page` opens a URL at a fixed viewport
size (device scale 1) and collects the page's uncaught exceptions, ``console.error`` calls and failed
loads as :attr:`Page.errors`.
"""

from __future__ import annotations

import base64
import io
import json
import os
import queue
import shutil
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from PIL import Image

from ..errors import SurfsplatError

#: Where Debian's package installs Chromium, then the names searched on PATH.
CHROMIUM_CANDIDATES = ("/usr/bin/chromium", "chromium", "chromium-browser", "google-chrome", "chrome")

#: Flags of a headless, offline, throwaway browser with WebGL2 on SwiftShader.
HEADLESS_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
                  "--enable-unsafe-swiftshader", "--disable-background-networking", "--disable-component-update",
                  "--disable-sync", "--no-first-run", "--no-default-browser-check", "--mute-audio",
                  "--disable-extensions", "--allow-file-access-from-files")


class BrowserError(SurfsplatError):
    """The browser could not be started, did not answer, or a page failed."""


def find_chromium() -> str | None:
    """The path of a Chromium executable (:data:`CHROMIUM_CANDIDATES`), or None."""
    for name in CHROMIUM_CANDIDATES:
        path = name if os.path.isabs(name) else shutil.which(name)
        if path and os.path.isfile(path) and os.access(path, os.X_OK):
            return path
    return None


class Browser:
    """A headless Chromium driven through a DevTools pipe; use as a context manager.

    Args:
        executable: Chromium's path (default :func:`find_chromium`).
        timeout: seconds to wait for any one answer.
        flags: more command-line flags.
    """

    def __init__(self, executable: str | None = None, *, timeout: float = 60.0, flags: tuple[str, ...] = ()):
        path = executable or find_chromium()
        if path is None:
            raise BrowserError("no Chromium found (install Debian's chromium package)")
        if not (os.path.isfile(path) and os.access(path, os.X_OK)):
            raise BrowserError(f"{path}: no such executable")
        self.timeout = timeout
        self._profile = tempfile.mkdtemp(prefix="surfsplat-chromium-")
        to_browser, self._write = os.pipe()
        self._read, from_browser = os.pipe()

        def descriptors() -> None:   # in the child: its fds 3 (commands) and 4 (answers)
            os.dup2(to_browser, 3)
            os.dup2(from_browser, 4)

        command = [path, *HEADLESS_FLAGS, *flags, f"--user-data-dir={self._profile}", "--remote-debugging-pipe",
                   "about:blank"]
        self.process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                        stderr=subprocess.DEVNULL, preexec_fn=descriptors, pass_fds=(3, 4))
        os.close(to_browser)
        os.close(from_browser)
        self._next = 0
        self._answers: dict[int, queue.Queue] = {}
        self._events: dict[str, list] = {}
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read_loop, daemon=True)
        self._reader.start()
        self.version = self.call("Browser.getVersion")["product"]

    def _read_loop(self) -> None:
        buffer = b""
        while True:
            try:
                chunk = os.read(self._read, 1 << 20)
            except OSError:
                chunk = b""
            if not chunk:
                with self._lock:
                    for answers in self._answers.values():
                        answers.put({"error": {"message": "the browser closed its pipe"}})
                return
            buffer += chunk
            while b"\0" in buffer:
                raw, buffer = buffer.split(b"\0", 1)
                message = json.loads(raw)
                if "id" in message:
                    with self._lock:
                        waiting = self._answers.get(message["id"])
                    if waiting is not None:
                        waiting.put(message)
                else:
                    key = message.get("sessionId", "")
                    with self._lock:
                        self._events.setdefault(key, []).append(message)

    def call(self, method: str, params: dict | None = None, session: str | None = None,
             timeout: float | None = None) -> dict:
        """Send one protocol command and wait for its result (BrowserError on an error or no answer)."""
        with self._lock:
            self._next += 1
            ident = self._next
            answers: queue.Queue = queue.Queue()
            self._answers[ident] = answers
        message: dict = {"id": ident, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self._write, json.dumps(message).encode() + b"\0")
        try:
            answer = answers.get(timeout=timeout or self.timeout)
        except queue.Empty:
            raise BrowserError(f"the browser did not answer {method} within {timeout or self.timeout:g} s") from None
        finally:
            with self._lock:
                self._answers.pop(ident, None)
        if "error" in answer:
            raise BrowserError(f"{method}: {answer['error'].get('message')}")
        return answer.get("result", {})

    def events(self, session: str) -> list:
        """The events of ``session`` received so far (and forgets them)."""
        with self._lock:
            return self._events.pop(session, [])

    def page(self, url: str, width: int = 1024, height: int = 768) -> "Page":
        """A new tab showing ``url`` at ``width`` x ``height`` CSS pixels (device scale 1)."""
        return Page(self, url, width, height)

    def close(self) -> None:
        """Stop the browser and remove its profile."""
        try:
            if self.process.poll() is None:
                try:
                    self.call("Browser.close", timeout=5.0)
                except BrowserError:
                    pass
                try:
                    self.process.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self.process.kill()
                    self.process.wait()
        finally:
            for fd in (self._write, self._read):
                try:
                    os.close(fd)
                except OSError:
                    pass
            shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self) -> "Browser":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class Page:
    """A tab of a :class:`Browser`: navigation, evaluation, input events and the errors it reported."""

    def __init__(self, browser: Browser, url: str, width: int, height: int):
        self.browser = browser
        self.width, self.height = width, height
        self.target = browser.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = browser.call("Target.attachToTarget", {"targetId": self.target, "flatten": True})["sessionId"]
        self.errors: list[str] = []
        for domain in ("Runtime", "Page", "Log"):
            self.call(f"{domain}.enable")
        self.call("Emulation.setDeviceMetricsOverride", {"width": width, "height": height, "deviceScaleFactor": 1,
                                                        "mobile": False})
        self.call("Page.navigate", {"url": url})

    def call(self, method: str, params: dict | None = None, timeout: float | None = None) -> dict:
        """A protocol command in this tab's session."""
        return self.browser.call(method, params, self.session, timeout)

    def collect(self) -> list[str]:
        """:attr:`errors` after reading the tab's events: exceptions, console errors, failed loads."""
        for event in self.browser.events(self.session):
            method, params = event.get("method"), event.get("params", {})
            if method == "Runtime.exceptionThrown":
                details = params.get("exceptionDetails", {})
                text = details.get("exception", {}).get("description") or details.get("text", "exception")
                self.errors.append(f"exception: {text}")
            elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
                args = " ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", []))
                self.errors.append(f"console.error: {args}")
            elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
                entry = params["entry"]
                self.errors.append(f"{entry.get('source')}: {entry.get('text')} {entry.get('url', '')}".strip())
        return self.errors

    def evaluate(self, expression: str, timeout: float | None = None):
        """The value of a JavaScript expression (promises awaited); BrowserError where it throws."""
        result = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                                "awaitPromise": True}, timeout)
        if "exceptionDetails" in result:
            details = result["exceptionDetails"]
            raise BrowserError(f"{expression[:60]}: {details.get('exception', {}).get('description') or details}")
        return result.get("result", {}).get("value")

    def wait_for(self, expression: str, timeout: float = 60.0, poll: float = 0.05):
        """Poll until ``expression`` is truthy (its value), or until the page reports an error
        (BrowserError naming them) or ``timeout`` seconds pass."""
        end = time.monotonic() + timeout
        while True:
            try:
                value = self.evaluate(expression)
            except BrowserError as exc:   # e.g. the document not there yet during a navigation
                value, last = None, str(exc)
            else:
                last = ""
            if value:
                return value
            if self.collect():
                raise BrowserError("the page reported errors: " + "; ".join(self.errors))
            if time.monotonic() > end:
                raise BrowserError(f"{expression} not true after {timeout:g} s{'; ' + last if last else ''}")
            time.sleep(poll)

    def canvas(self, selector: str = "canvas") -> np.ndarray:
        """The pixels of a canvas (H, W, 3) uint8, from its ``toDataURL`` (the drawing buffer itself)."""
        url = self.evaluate(f"document.querySelector({json.dumps(selector)}).toDataURL('image/png')")
        data = base64.b64decode(url.split(",", 1)[1])
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))

    def screenshot(self) -> np.ndarray:
        """The page as shown (H, W, 3) uint8, overlays included."""
        data = base64.b64decode(self.call("Page.captureScreenshot", {"format": "png"})["data"])
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))

    def mouse(self, kind: str, x: float, y: float, buttons: int = 1, button: str = "left",
              modifiers: int = 0) -> None:
        """One mouse event (``kind``: mousePressed, mouseMoved, mouseReleased) at CSS pixel (x, y)."""
        self.call("Input.dispatchMouseEvent", {"type": kind, "x": x, "y": y, "button": button, "buttons": buttons,
                                               "clickCount": 1 if kind != "mouseMoved" else 0,
                                               "modifiers": modifiers})

    def drag(self, start: tuple[float, float], end: tuple[float, float], steps: int = 5) -> None:
        """A left-button drag from ``start`` to ``end`` in ``steps`` moves."""
        self.mouse("mousePressed", *start)
        for i in range(1, steps + 1):
            t = i / steps
            self.mouse("mouseMoved", start[0] + t * (end[0] - start[0]), start[1] + t * (end[1] - start[1]))
        self.mouse("mouseReleased", *end, buttons=0)

    def key(self, key: str, code: str | None = None, key_code: int = 0) -> None:
        """Press and release a key (``key`` as KeyboardEvent.key names it)."""
        for kind in ("keyDown", "keyUp"):
            self.call("Input.dispatchKeyEvent", {"type": kind, "key": key, "code": code or key,
                                                 "windowsVirtualKeyCode": key_code})

    def close(self) -> None:
        """Close the tab."""
        try:
            self.browser.call("Target.closeTarget", {"targetId": self.target}, timeout=10.0)
        except BrowserError:
            pass


def file_url(path: str | os.PathLike, query: str = "") -> str:
    """The ``file://`` URL of a local file, with an optional ``?query#hash`` suffix."""
    return Path(path).resolve().as_uri() + query

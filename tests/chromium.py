"""A small Chrome DevTools protocol client for page tests: headless Chromium, evaluate, screenshot.

Nothing is downloaded: it drives the system Chromium (``/usr/bin/chromium`` or ``$CHROMIUM``) over the
DevTools WebSocket with the ``websockets`` package.
"""

from __future__ import annotations

import base64
import itertools
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from websockets.sync.client import connect

CHROMIUM = os.environ.get("CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"


def available() -> bool:
    return Path(CHROMIUM).is_file() and os.access(CHROMIUM, os.X_OK)


class Browser:
    """Headless Chromium with one page; ``evaluate`` runs JavaScript in it and returns the value."""

    def __init__(self, *, width: int = 1600, height: int = 900) -> None:
        self.profile = tempfile.mkdtemp(prefix="qn-chromium-")
        # Chromium's log goes to a file, not a pipe: a pipe that nobody reads after start-up fills (64 KB of
        # warnings from a live WebGL page) and then blocks the browser's every write, so every DevTools call hangs
        self.log = Path(self.profile) / "stderr.log"
        self._stderr = open(self.log, "wb")
        self.proc = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--disable-dev-shm-usage", "--use-gl=swiftshader", "--enable-unsafe-swiftshader",
             f"--user-data-dir={self.profile}", "--remote-debugging-port=0", "--remote-debugging-address=127.0.0.1",
             f"--window-size={width},{height}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=self._stderr)
        url = None
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            m = re.search(r"DevTools listening on (ws://\S+)", self.log.read_text(errors="replace"))
            if m:
                url = m.group(1)
                break
            if self.proc.poll() is not None:
                break
            time.sleep(0.05)
        if url is None:
            self.close()
            raise RuntimeError("chromium did not start (no DevTools URL)")
        self._conn = connect(url, max_size=None, open_timeout=30)
        self.ws = self._conn.__enter__()
        self.ids = itertools.count(1)
        target = self.send("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.send("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        self.send("Page.enable", session=True)
        self.send("Runtime.enable", session=True)
        self.send("Emulation.setDeviceMetricsOverride", session=True, width=width, height=height,
                  deviceScaleFactor=1, mobile=False)
        self.console: list[str] = []

    def send(self, method: str, *, session: bool = False, timeout: float = 60, **params: Any) -> dict[str, Any]:
        mid = next(self.ids)
        msg: dict[str, Any] = {"id": mid, "method": method, "params": params}
        if session:
            msg["sessionId"] = self.session
        self.ws.send(json.dumps(msg))
        deadline = time.monotonic() + timeout
        while True:
            data = json.loads(self.ws.recv(timeout=max(0.1, deadline - time.monotonic())))
            if data.get("method") == "Runtime.exceptionThrown":
                self.console.append(json.dumps(data["params"]["exceptionDetails"])[:2000])
            if data.get("method") == "Page.javascriptDialogOpening":  # an alert would block the page: note, dismiss
                self.console.append("dialog: " + data["params"].get("message", ""))
                self.ws.send(json.dumps({"id": next(self.ids), "method": "Page.handleJavaScriptDialog",
                                         "params": {"accept": True}, "sessionId": self.session}))
            if data.get("method") == "Runtime.consoleAPICalled":
                self.console.append(" ".join(str(a.get("value", a.get("description", ""))) for a in data["params"]["args"]))
            if data.get("id") == mid:
                if "error" in data:
                    raise RuntimeError(f"{method}: {data['error']}")
                return data.get("result", {})

    def goto(self, url: str) -> None:
        self.send("Page.navigate", session=True, url=url)

    def evaluate(self, expression: str, *, timeout: float = 60) -> Any:
        res = self.send("Runtime.evaluate", session=True, expression=expression, awaitPromise=True,
                        returnByValue=True, timeout=timeout)
        if "exceptionDetails" in res:
            raise RuntimeError(f"{expression[:80]}: {res['exceptionDetails']}")
        return res.get("result", {}).get("value")

    def wait_for(self, expression: str, *, timeout: float = 60, interval: float = 0.1) -> Any:
        """Poll a JavaScript expression until it is truthy; return its value."""
        deadline = time.monotonic() + timeout
        last = None
        while time.monotonic() < deadline:
            try:
                last = self.evaluate(expression)
            except RuntimeError:
                last = None
            if last:
                return last
            time.sleep(interval)
        raise TimeoutError(f"timed out after {timeout} s waiting for {expression}; console: {self.console[-5:]}")

    def screenshot(self, path: str | os.PathLike[str]) -> Path:
        data = self.send("Page.captureScreenshot", session=True, format="png")["data"]
        p = Path(path)
        p.write_bytes(base64.b64decode(data))
        return p

    def close(self) -> None:
        try:
            if getattr(self, "ws", None) is not None:
                try:
                    self.send("Browser.close", timeout=5)
                except Exception:
                    pass
                self._conn.__exit__(None, None, None)
        finally:
            if self.proc.poll() is None:
                self.proc.terminate()
                try:
                    self.proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait()
            self._stderr.close()
            shutil.rmtree(self.profile, ignore_errors=True)

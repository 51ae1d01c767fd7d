"""The report of a fit, opened in a real headless browser (Debian's chromium).

Chromium is driven through the DevTools protocol over ``--remote-debugging-pipe`` (file
descriptors 3 and 4, NUL-separated JSON: no websocket, no extra package). The test
makes a fit with the CLI from the shipped example, writes its report, opens it at
1280 px and checks what a reader would meet: no console error or exception, no request
leaving the file (everything inline), no horizontal overflow of the page or of any
table, every figure loaded with a caption and alt text, and in print (A4) no table
wider than the printable width; it saves a screenshot and the PDF next to the report.

Chromium is found on PATH, or installed with apt-get when running as root; the test is
skipped, saying so, only when neither works.

The fits and reports the pages come from are made with the CLI's commands run in this
process (Click's runner, ``_cli``): the pages are what is checked here, and a process per
command paid the imports again (seven processes).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def _find_chromium() -> str | None:
    for name in NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


def _chromium() -> str:
    path = _find_chromium()
    if path is None and shutil.which("apt-get") and hasattr(os, "geteuid") and os.geteuid() == 0:
        env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
        subprocess.run(["apt-get", "update", "-qq"], env=env, capture_output=True, timeout=600)
        subprocess.run(["apt-get", "install", "-y", "-qq", "chromium"], env=env,
                       capture_output=True, timeout=900)  # fmt: skip
        path = _find_chromium()
    if path is None:
        pytest.skip("no chromium on PATH and it cannot be installed (not root or no apt-get)")
    return path


def _cli(*args: str, cwd: Path) -> str:
    """Run one ``loadbayes`` command in this process from ``cwd``; its standard output."""
    from cli_here import cli_here

    res = cli_here(*args, cwd=cwd)
    assert res.returncode == 0, res.stderr
    return res.stdout


class Browser:
    """A headless chromium on the DevTools pipe: send commands, collect events."""

    def __init__(self, exe: str, profile: Path) -> None:
        r_cmd, self._w_cmd = os.pipe()  # we write commands, chromium reads fd 3
        self._r_evt, w_evt = os.pipe()  # chromium writes fd 4, we read
        args = [exe, "--headless=new", "--remote-debugging-pipe", "--no-sandbox",
                "--disable-gpu", "--hide-scrollbars", "--no-first-run",
                "--no-default-browser-check", "--disable-extensions",
                "--disable-background-networking",
                f"--user-data-dir={profile}", "about:blank"]  # fmt: skip

        def fds():
            # Copies first, so that neither end is overwritten by the other's dup2.
            a, b = os.dup(r_cmd), os.dup(w_evt)
            os.dup2(a, 3)
            os.dup2(b, 4)

        # close_fds runs after preexec_fn in the child: keep 3 and 4 open.
        quiet = subprocess.DEVNULL
        self.proc = subprocess.Popen(args, preexec_fn=fds, pass_fds=(3, 4), close_fds=True,
                                     stdout=quiet, stderr=quiet)  # fmt: skip
        os.close(r_cmd)
        os.close(w_evt)
        self._buf = b""
        self._id = 0
        self.events: list[dict] = []
        self.session: str | None = None

    def _read(self, timeout: float) -> dict:
        import select

        while b"\0" not in self._buf:
            ready, _, _ = select.select([self._r_evt], [], [], timeout)
            if not ready:
                raise TimeoutError("chromium did not answer")
            chunk = os.read(self._r_evt, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed the pipe")
            self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        return json.loads(msg)

    def send(self, method: str, params: dict | None = None, *, timeout: float = 60) -> dict:
        """Send one command and return its result (events met meanwhile are kept)."""
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params or {}}
        if self.session and not method.startswith("Target."):
            msg["sessionId"] = self.session
        os.write(self._w_cmd, json.dumps(msg).encode() + b"\0")
        end = time.monotonic() + timeout
        while True:
            reply = self._read(max(end - time.monotonic(), 0.1))
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_for(self, method: str, timeout: float = 60) -> dict:
        """Wait for an event (or return one already received)."""
        for ev in self.events:
            if ev.get("method") == method:
                return ev
        end = time.monotonic() + timeout
        while True:
            ev = self._read(max(end - time.monotonic(), 0.1))
            self.events.append(ev)
            if ev.get("method") == method:
                return ev

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page."""
        res = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True})
        return res["result"].get("value")

    def close(self) -> None:
        try:
            self.send("Browser.close", timeout=10)
        except Exception:  # already gone: the wait below ends it either way
            pass
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        os.close(self._w_cmd)
        os.close(self._r_evt)


#: Per table: how much wider its content is than its box, and how far its right edge
#: passes the right edge of the body's content box (both <= 0 when it fits; 0.5 px of
#: sub-pixel rounding allowed).
OVERFLOW_JS = """
(() => {
  const body = document.body.getBoundingClientRect();
  const edge = body.right - parseFloat(getComputedStyle(document.body).paddingRight);
  return Array.from(document.querySelectorAll('table')).map((t, i) => ({
    i, over: t.scrollWidth - t.clientWidth,
    right: t.getBoundingClientRect().right - edge - 0.5}));
})()
"""

FIGURES_JS = """
(() => Array.from(document.querySelectorAll('figure')).map(f => {
  const img = f.querySelector('img');
  const cap = f.querySelector('figcaption');
  return {loaded: !!img && img.complete && img.naturalWidth > 0,
          alt: img ? img.alt.length : 0, caption: cap ? cap.textContent.length : 0};
}))()
"""


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> Path:
    """The README's example data, a one-level fit (all four figures, load curves among
    them: the quick start's drift fit has no single P0 to draw P(V) at), its report."""
    root = tmp_path_factory.mktemp("browser")
    (root / "bus.csv").write_text(_cli("example", "zip", cwd=root))
    _cli("fit", "zip", "bus.csv", "--v-base", "11", "--s-base", "5", "--p0", "1", "--q0", "0.4",
         "--draws", "3000", "--burn", "500", "--netcdf", "fit.nc", "--quiet", cwd=root)  # fmt: skip
    _cli("report", "fit.nc", "--out", "report.html", "--truth", "a1=0.3", "--truth", "a2=0.25",
         "--truth", "a3=0.45", "--quiet", cwd=root)  # fmt: skip
    return root / "report.html"


def test_report_in_a_headless_browser(report, tmp_path):
    exe = _chromium()
    b = Browser(exe, tmp_path / "profile")
    try:
        target = b.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        b.session = b.send("Target.attachToTarget", {"targetId": target, "flatten": True})[
            "sessionId"
        ]
        for domain in ("Page", "Runtime", "Log", "Network"):
            b.send(f"{domain}.enable")
        b.send("Emulation.setDeviceMetricsOverride",
               {"width": 1280, "height": 900, "deviceScaleFactor": 1, "mobile": False})  # fmt: skip
        b.events.clear()
        b.send("Page.navigate", {"url": report.resolve().as_uri()})
        b.wait_for("Page.loadEventFired")
        time.sleep(0.3)  # late console messages

        errors = [
            ev for ev in b.events
            if (ev.get("method") == "Runtime.consoleAPICalled"
                and ev["params"]["type"] in ("error", "assert"))
            or ev.get("method") == "Runtime.exceptionThrown"
            or (ev.get("method") == "Log.entryAdded"
                and ev["params"]["entry"]["level"] == "error")
        ]  # fmt: skip
        assert not errors, errors
        requests = [
            ev["params"]["request"]["url"]
            for ev in b.events
            if ev.get("method") == "Network.requestWillBeSent"
        ]
        outside = [u for u in requests if not u.startswith(("file:", "data:", "about:"))]
        assert not outside, outside

        assert b.evaluate("document.title").startswith("ZIP load model")
        page_over = b.evaluate("document.documentElement.scrollWidth - window.innerWidth")
        assert page_over <= 0, f"the page is {page_over} px wider than 1280 px"
        tables = b.evaluate(OVERFLOW_JS)
        assert len(tables) >= 3
        assert all(t["over"] <= 0 and t["right"] <= 0 for t in tables), tables
        figs = b.evaluate(FIGURES_JS)
        assert len(figs) >= 4  # curves, marginals, pairs, traces
        assert all(f["loaded"] and f["alt"] > 20 and f["caption"] > 40 for f in figs), figs
        # Summary first, then the contents, then the sections in the contents' order.
        order = b.evaluate(
            "Array.from(document.querySelectorAll('body > section, body > nav'))"
            ".map(e => e.id || e.className)"
        )
        assert order[:2] == ["summary", "contents"], order
        shot = b.send("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True})
        import base64

        png = base64.b64decode(shot["data"])
        (report.parent / "report.png").write_bytes(png)
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 50_000

        # Print: A4 with the page's 14 mm margins is 182 mm = 688 CSS px of content.
        b.send("Emulation.setEmulatedMedia", {"media": "print"})
        b.send("Emulation.setDeviceMetricsOverride",
               {"width": 688, "height": 1000, "deviceScaleFactor": 1, "mobile": False})  # fmt: skip
        printed = b.evaluate(OVERFLOW_JS)
        assert all(t["over"] <= 0 and t["right"] <= 0 for t in printed), printed
        assert b.evaluate("document.documentElement.scrollWidth") <= 688
        assert b.evaluate("document.documentElement.clientWidth") == 688
        b.send("Emulation.clearDeviceMetricsOverride")
        pdf = b.send("Page.printToPDF", {"paperWidth": 8.27, "paperHeight": 11.69,
                                          "preferCSSPageSize": True}, timeout=120)  # fmt: skip
        data = base64.b64decode(pdf["data"])
        (report.parent / "report.pdf").write_bytes(data)
        assert data[:5] == b"%PDF-" and data.count(b"/Type /Page") >= 3
    finally:
        b.close()


def test_composite_report_shows_the_recordings_units_and_what_is_determined(tmp_path):
    """A composite fit's report (issue 21): V, P, Q against the recording with the band and
    the zooms, units on every row, the identifiability text and the settings used."""
    import numpy as np
    import pandas as pd

    exe = _chromium()
    # A sag written here (not the package's simulator): a static load plus a first-order
    # lag that stands in for a motor's recovering current; the report checks the page.
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 2.0, 1 / 60)
    v = np.where((t >= 0.5) & (t < 0.7), 0.7, 1.0)
    lag = np.where(t >= 0.5, np.exp(-np.clip(t - 0.5, 0, None) / 0.15), 0.0) * (t < 0.7)
    p = 0.5 * v**2 + 0.5 * (1 - 0.6 * lag) + rng.normal(0, 0.005, t.size)
    q = 0.2 * v**2 + 0.1 + 0.3 * lag + rng.normal(0, 0.005, t.size)
    pd.DataFrame({"t_s": t, "v": v, "p": p, "q": q}).to_csv(tmp_path / "sag.csv", index=False)
    for args in (
        ["fit", "composite", "sag.csv", "--draws", "400", "--burn", "200", "--chains", "2",
         "--json", "c.json", "--netcdf", "c.nc", "--quiet"],
        ["report", "c.nc", "--out", "c.html", "--quiet"],
    ):  # fmt: skip
        _cli(*args, cwd=tmp_path)
    b = Browser(exe, tmp_path / "profile")
    try:
        _open(b, tmp_path / "c.html")
        assert b.evaluate("document.title").startswith("Composite load model")
        assert b.evaluate("document.documentElement.scrollWidth - window.innerWidth") <= 0
        tables = b.evaluate(OVERFLOW_JS)
        assert all(t["over"] <= 0 and t["right"] <= 0 for t in tables), tables
        figs = b.evaluate(FIGURES_JS)
        assert len(figs) >= 2 and all(f["loaded"] and f["caption"] > 40 for f in figs), figs
        heads = b.evaluate("Array.from(document.querySelectorAll('h2')).map(h => h.textContent)")
        assert any("Fit to the recordings" in h for h in heads), heads
        assert any("What the events determine" in h for h in heads), heads
        text = b.evaluate("document.body.innerText")
        assert "transient time constant T' [s]" in text  # the summary's meaning and unit
        assert "Static (ZIP) part" in text and "posterior-predictive" in text
        assert "sag.csv" in text and "seed" in text  # the settings used
    finally:
        b.close()


def _open(b: Browser, path: Path, width: int = 1280) -> None:
    target = b.send("Target.createTarget", {"url": "about:blank"})["targetId"]
    b.session = b.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
    for domain in ("Page", "Runtime", "Log", "Network"):
        b.send(f"{domain}.enable")
    b.send("Emulation.setDeviceMetricsOverride",
           {"width": width, "height": 900, "deviceScaleFactor": 1, "mobile": False})  # fmt: skip
    b.events.clear()
    b.send("Page.navigate", {"url": path.resolve().as_uri()})
    b.wait_for("Page.loadEventFired")


def test_paper_report_pieces_fit_the_screen_and_the_page(tmp_path):
    """The paper's report (studies/report.py) on the same page: its widest kind of table."""
    import numpy as np
    import pandas as pd

    from loadbayes.plots.fit import pyplot
    from loadbayes.studies.report import embedded_png, frame_html, png_bytes, write_report

    exe = _chromium()
    rng = np.random.default_rng(0)
    # 12 columns, long unbreakable labels: the IM study's Table I comparison at its widest.
    wide = pd.DataFrame({"motor": ["small_industrial", "large_industrial", "krause_3hp"] * 3})
    for c in ("coefficient_name", "gs", "ls", "gs_measured", "ls_measured", "kf_measured",
              "true", "paper_gs", "paper_ls", "paper_kf", "paper_true"):  # fmt: skip
        wide[c] = rng.normal(size=len(wide)) * 1e3 if c != "coefficient_name" else "b1"
    fig = pyplot().figure(figsize=(6, 3))
    fig.add_subplot().plot([0, 1], [0, 1])
    pngs = {"line": png_bytes(fig)}
    section = ("<section id='zip'><h2>A study</h2>" + frame_html(wide)
               + embedded_png(pngs, "line", "a straight line") + "</section>")  # fmt: skip
    path = write_report(tmp_path / "paper.html", [section], summary="<p>Headline.</p>")
    b = Browser(exe, tmp_path / "profile")
    try:
        _open(b, path)
        assert b.evaluate("document.documentElement.scrollWidth - window.innerWidth") <= 0
        tables = b.evaluate(OVERFLOW_JS)
        assert all(t["over"] <= 0 and t["right"] <= 0 for t in tables), tables
        figs = b.evaluate(FIGURES_JS)
        assert len(figs) == 1 and figs[0]["loaded"] and figs[0]["caption"] > 5
        assert b.evaluate("document.querySelector('nav.contents a').getAttribute('href')") == (
            "#zip"
        )
        b.send("Emulation.setEmulatedMedia", {"media": "print"})
        b.send("Emulation.setDeviceMetricsOverride",
               {"width": 688, "height": 1000, "deviceScaleFactor": 1, "mobile": False})  # fmt: skip
        printed = b.evaluate(OVERFLOW_JS)
        assert all(t["over"] <= 0 and t["right"] <= 0 for t in printed), printed
    finally:
        b.close()


@pytest.fixture(scope="module")
def fleet_report(tmp_path_factory) -> Path:
    """The README's fleet (``loadbayes example fleet``), pooled, with a map of its buses."""
    root = tmp_path_factory.mktemp("fleet_browser")

    def run(*args):
        _cli(*args, cwd=root)

    run("example", "fleet", "--out", "meters")
    run("fit", "zip", "meters/", "--by", "bus_id", "--class-col", "customer_class",
        "--out", "fleet.parquet", "--pool", "class", "--draws", "600", "--burn", "200",
        "--quiet")  # fmt: skip
    ids = [f"bus{i:02d}" for i in range(24)]
    (root / "coords.csv").write_text(
        "bus_id,lat,lon\n"
        + "".join(
            f"{b},{51 + 0.01 * (i // 6)},{-1 + 0.02 * (i % 6)}\n" for i, b in enumerate(ids)
        )  # fmt: skip
    )
    run("report", "fleet.parquet", "--out", "fleet.html", "--coords", "coords.csv", "--quiet")
    return root / "fleet.html"


def test_fleet_report_in_a_headless_browser(fleet_report, tmp_path):
    exe = _chromium()
    b = Browser(exe, tmp_path / "profile")
    try:
        _open(b, fleet_report)
        time.sleep(0.3)  # late console messages
        errors = [
            ev for ev in b.events
            if (ev.get("method") == "Runtime.consoleAPICalled"
                and ev["params"]["type"] in ("error", "assert"))
            or ev.get("method") == "Runtime.exceptionThrown"
            or (ev.get("method") == "Log.entryAdded"
                and ev["params"]["entry"]["level"] == "error")
        ]  # fmt: skip
        assert not errors, errors
        outside = [
            ev["params"]["request"]["url"]
            for ev in b.events
            if ev.get("method") == "Network.requestWillBeSent"
            and not ev["params"]["request"]["url"].startswith(("file:", "data:", "about:"))
        ]
        assert not outside, outside
        assert b.evaluate("document.title").startswith("Fleet of 24 buses")
        assert b.evaluate("document.documentElement.scrollWidth - window.innerWidth") <= 0
        tables = b.evaluate(OVERFLOW_JS)
        assert len(tables) >= 3  # the summary's mixes, the class table, the shrinkage
        assert all(t["over"] <= 0 and t["right"] <= 0 for t in tables), tables
        figs = b.evaluate(FIGURES_JS)
        assert len(figs) == 3  # class mixes, shrinkage, the map of dP/dV and dQ/dV
        assert all(f["loaded"] and f["alt"] > 20 and f["caption"] > 40 for f in figs), figs
        text = b.evaluate("document.body.innerText")
        assert "placed at the bus's coordinates (lon, lat)" in text
        order = b.evaluate(
            "Array.from(document.querySelectorAll('body > section, body > nav'))"
            ".map(e => e.id || e.className)"
        )
        assert order == ["summary", "contents", "class-mixes", "shrinkage", "buses-flagged",
                         "voltage-sensitivity", "settings"], order  # fmt: skip
        import base64

        shot = b.send("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True})
        png = base64.b64decode(shot["data"])
        (fleet_report.parent / "fleet.png").write_bytes(png)
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 50_000
        b.send("Emulation.setEmulatedMedia", {"media": "print"})
        b.send("Emulation.setDeviceMetricsOverride",
               {"width": 688, "height": 1000, "deviceScaleFactor": 1, "mobile": False})  # fmt: skip
        printed = b.evaluate(OVERFLOW_JS)
        assert all(t["over"] <= 0 and t["right"] <= 0 for t in printed), printed
    finally:
        b.close()

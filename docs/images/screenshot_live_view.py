"""How docs/images/live-view.png was made: docs/live-view.html in headless Chromium, driven over the DevTools
protocol, screenshotted after it has watched a run for a while.

    python3 docs/images/screenshot_live_view.py PORT OUT.png SECONDS &
    lineflow run launch/demo.toml --set capture.scale=0.15 --view-port PORT

Needs Debian's `chromium` and Python's `websockets`. Not part of the tests (they check the protocol with
tests/e2e/live_view_client.py); kept so that the picture can be made again.
"""
import base64, json, pathlib, subprocess, sys, tempfile, time, urllib.request
from websockets.sync.client import connect
page_url = f"file://{pathlib.Path(__file__).resolve().parents[1]}/live-view.html?ws=ws://127.0.0.1:{sys.argv[1]}"
out, wait = sys.argv[2], float(sys.argv[3])
port = 9333
chrome = subprocess.Popen(["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync", f"--user-data-dir={tempfile.mkdtemp()}",
    f"--remote-debugging-port={port}", "--window-size=1700,760", "about:blank"], stderr=subprocess.DEVNULL)
try:
    for _ in range(100):
        try:
            tabs = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json")); break
        except OSError: time.sleep(0.1)
    page = next(t for t in tabs if t["type"] == "page")
    with connect(page["webSocketDebuggerUrl"], max_size=None) as ws:
        n = 0
        def call(method, **params):
            global n; n += 1
            ws.send(json.dumps({"id": n, "method": method, "params": params}))
            while True:
                m = json.loads(ws.recv())
                if m.get("id") == n: return m.get("result", {})
        call("Emulation.setDeviceMetricsOverride", width=1700, height=760, deviceScaleFactor=1, mobile=False)
        call("Page.navigate", url=page_url)
        time.sleep(wait)
        png = call("Page.captureScreenshot", format="png")["data"]
        open(out, "wb").write(base64.b64decode(png))
finally:
    chrome.kill()

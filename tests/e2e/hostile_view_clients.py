"""Clients that misbehave towards the live view, for the live-view test.

    hostile_view_clients.py URL SECONDS

For SECONDS, from the moment the server listens: one client connects, subscribes to every channel and closes at
once, again and again (churn); another connects, subscribes to every channel and then never reads (a stalled
client, whose socket buffers fill). Prints one JSON line: how many churn connections were made and whether the
stalled client got connected. The test checks that the run beside them neither stalls nor loses anything.
"""

import json
import sys
import threading
import time

from websockets.exceptions import WebSocketException
from websockets.sync.client import connect

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


def subscribe_all(ws, deadline):
    """Reads until the first advertise and subscribes to all of it."""
    while time.monotonic() < deadline:
        m = ws.recv(timeout=max(0.01, deadline - time.monotonic()))
        if isinstance(m, str) and json.loads(m)["op"] == "advertise":
            subs = [{"id": c["id"], "channelId": c["id"]} for c in json.loads(m)["channels"]]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            return


def churn(url, until, counts):
    while time.monotonic() < until:
        try:
            with connect(url, subprotocols=SUBPROTOCOLS, open_timeout=1) as ws:
                subscribe_all(ws, time.monotonic() + 1)
                counts["churn"] += 1
        except (OSError, TimeoutError, WebSocketException):
            time.sleep(0.02)


def stall(url, until, counts):
    while time.monotonic() < until:
        try:
            ws = connect(url, subprotocols=SUBPROTOCOLS, open_timeout=1, max_size=None)
        except (OSError, TimeoutError, WebSocketException):
            time.sleep(0.02)
            continue
        subscribe_all(ws, time.monotonic() + 1)
        counts["stalled"] = True
        # Never reads again: the server's queue for this client and the socket's buffers fill.
        time.sleep(max(0.0, until - time.monotonic()))
        ws.close()
        return


def main():
    url, seconds = sys.argv[1], float(sys.argv[2])
    until = time.monotonic() + seconds
    counts = {"churn": 0, "stalled": False}
    threads = [threading.Thread(target=f, args=(url, until, counts)) for f in (churn, stall)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    print(json.dumps(counts, sort_keys=True))


if __name__ == "__main__":
    main()

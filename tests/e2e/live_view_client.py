"""A Foxglove WebSocket client (Python's `websockets`, independent of the server's SDK) for the live-view test.

    live_view_client.py URL TIMEOUT_S TOPIC...

Connects to a running `lineflow run --view` (retrying until the server listens), checks the server's protocol
messages, subscribes to every advertised channel and decodes what arrives by its schema: `RawImage` previews from
their CDR, annotations, scenes, calibrations and transforms from their JSON, each checked for the fields Foxglove
reads. Exits 0 once every TOPIC has given at least one well-formed message, printing one JSON line with the count
per channel; exits 1 naming what is missing or malformed.
"""

import json
import struct
import sys
import time

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

# The protocol's current name first; its earlier name, for servers that still use it (same messages).
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
MESSAGE_DATA = 0x01


def fail(msg):
    print(f"FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


class Cdr:
    """Reads little-endian CDR (the 4-byte encapsulation header first), aligned as ROS 2 writes it."""

    def __init__(self, data):
        if data[:2] != b"\x00\x01":
            fail(f"not little-endian CDR: {data[:4]!r}")
        self.data, self.pos = data, 4

    def u32(self):
        self.pos += (4 - (self.pos - 4) % 4) % 4
        (v,) = struct.unpack_from("<I", self.data, self.pos)
        self.pos += 4
        return v

    def string(self):
        n = self.u32()
        s = self.data[self.pos : self.pos + n - 1].decode()
        self.pos += n
        return s

    def octets(self):
        n = self.u32()
        b = self.data[self.pos : self.pos + n]
        self.pos += n
        return b


def raw_image(payload):
    c = Cdr(payload)
    sec, nsec = c.u32(), c.u32()
    frame_id = c.string()
    width, height = c.u32(), c.u32()
    encoding = c.string()
    step = c.u32()
    data = c.octets()
    channels = {"mono8": 1, "rgb8": 3}.get(encoding)
    if channels is None or step != width * channels or len(data) != step * height or not frame_id.startswith("camera/"):
        fail(f"preview {width}x{height} {encoding} step {step}, {len(data)} bytes, frame '{frame_id}'")
    return {"frame_id": frame_id, "width": width, "height": height, "stamp": sec * 10**9 + nsec}


def check(schema, payload):
    """Decodes one message by its schema name; returns a short description or fails."""
    if schema == "foxglove_msgs/msg/RawImage":
        return raw_image(payload)
    m = json.loads(payload)
    if schema == "foxglove.ImageAnnotations":
        pts = m["points"][0]
        if pts["type"] not in (1, 4) or any(set(p) != {"x", "y"} for p in pts["points"]):
            fail(f"annotations malformed: {str(m)[:200]}")
        return {"points": len(pts["points"])}
    if schema == "foxglove.SceneUpdate":
        for e in m["entities"]:
            if e["frame_id"] != "world" or any(len(l["points"]) % 2 for l in e["lines"]):
                fail(f"scene entity malformed: {str(e)[:200]}")
        return {"entities": [e["id"] for e in m["entities"]]}
    if schema == "foxglove.CameraCalibration":
        if len(m["K"]) != 9 or len(m["P"]) != 12 or len(m["D"]) != 5 or not m["frame_id"].startswith("camera/"):
            fail(f"calibration malformed: {m}")
        return {"frame_id": m["frame_id"], "width": m["width"]}
    if schema == "foxglove.FrameTransforms":
        for t in m["transforms"]:
            q = t["rotation"]
            if t["parent_frame_id"] != "world" or abs(sum(q[k] ** 2 for k in "xyzw") - 1) > 1e-9:
                fail(f"transform malformed: {t}")
        return {"transforms": len(m["transforms"])}
    fail(f"unexpected schema {schema}")


def main():
    url, timeout, wanted = sys.argv[1], float(sys.argv[2]), set(sys.argv[3:])
    deadline = time.monotonic() + timeout
    while True:
        try:
            ws = connect(url, subprotocols=SUBPROTOCOLS, open_timeout=2, max_size=None)
            break
        except OSError:
            if time.monotonic() > deadline:
                fail(f"no server at {url}")
            time.sleep(0.05)
    if ws.subprotocol not in SUBPROTOCOLS:
        fail(f"subprotocol {ws.subprotocol}")
    channels, subscribed, counts, seen_info = {}, {}, {}, False
    while not wanted <= {t for t, n in counts.items() if n > 0}:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            missing = sorted(wanted - set(counts))
            fail(f"nothing on {missing} within {timeout} s; received {counts}; advertised {sorted(c['topic'] for c in channels.values())}")
        try:
            msg = ws.recv(timeout=remaining)
        except TimeoutError:
            continue
        except ConnectionClosed as e:
            fail(f"the server closed the connection ({e}); received {counts}")
        if isinstance(msg, str):
            m = json.loads(msg)
            if m["op"] == "serverInfo":
                seen_info = True
            elif m["op"] == "advertise":
                new = [c for c in m["channels"] if c["id"] not in channels]
                for c in new:
                    channels[c["id"]] = c
                    subscribed[c["id"]] = c
                if new:
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": c["id"], "channelId": c["id"]} for c in new]}))
            continue
        if not seen_info:
            fail("message data before serverInfo")
        if msg[0] != MESSAGE_DATA:
            continue
        sub, _stamp = struct.unpack_from("<IQ", msg, 1)
        c = subscribed.get(sub)
        if c is None:
            fail(f"data on subscription {sub}, never made")
        check(c["schemaName"], msg[13:])
        counts[c["topic"]] = counts.get(c["topic"], 0) + 1
    ws.close()
    print(json.dumps({"channels": len(channels), "received": counts}, sort_keys=True))


if __name__ == "__main__":
    main()

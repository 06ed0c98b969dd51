#!/usr/bin/env python3
"""The `edges` stage, implementation `sobel`, written in Python with the stock `iceoryx2` and `numpy` packages.

It follows the node contract of docs/nodes.md like the Rust stages: the environment names the run, the graph and
the node; `--describe` prints the ports; the services are opened with the same names, type names, layouts and
settings as `runtime/src/transport.rs`; readiness goes to `lineflow/ready`, counters to `lineflow/status`; a message
with the end-of-stream flag ends the stream. The edge pixels equal those of the Rust `sobel` (3x3 Sobel with
replicated borders, L2 magnitude, OpenCV's non-maximum suppression rules) except at exact threshold ties.

Launch-file entry:
    [[node]]
    name = "edges"
    executable = "../nodes/python/sobel_node.py"
    params = { threshold = 100.0 }
"""
import ctypes
import json
import os
import sys
import time

import numpy as np
import iceoryx2 as iox2

END_OF_STREAM = 1
MAX_NODES = 64


class Stamp(ctypes.Structure):
    _fields_ = [
        ("frame", ctypes.c_uint64),
        ("capture_time_ns", ctypes.c_uint64),
        ("seq", ctypes.c_uint64),
        ("flags", ctypes.c_uint32),
        ("revision", ctypes.c_uint32),
    ]

    @staticmethod
    def type_name():
        return "lineflow/Stamp/v1"


class ImageHeader(ctypes.Structure):
    _fields_ = [
        ("stamp", Stamp),
        ("width", ctypes.c_uint32),
        ("height", ctypes.c_uint32),
        ("step", ctypes.c_uint32),
        ("encoding", ctypes.c_uint32),
        ("name", ctypes.c_uint8 * 64),
    ]

    @staticmethod
    def type_name():
        return "lineflow/Image/v1"


class EdgeMapHeader(ctypes.Structure):
    _fields_ = [
        ("stamp", Stamp),
        ("width", ctypes.c_uint32),
        ("height", ctypes.c_uint32),
        ("detector", ctypes.c_uint8 * 16),
        ("name", ctypes.c_uint8 * 64),
    ]

    @staticmethod
    def type_name():
        return "lineflow/EdgeMap/v2"


class EdgePixel(ctypes.Structure):
    _fields_ = [
        ("col", ctypes.c_uint16),
        ("row", ctypes.c_uint16),
        ("magnitude", ctypes.c_float),
        ("direction_rad", ctypes.c_float),
    ]

    @staticmethod
    def type_name():
        return "lineflow/EdgePixel/v1"


class NodeStatus(ctypes.Structure):
    _fields_ = [
        ("node_index", ctypes.c_uint32),
        ("pid", ctypes.c_uint32),
        ("msgs_in", ctypes.c_uint64),
        ("msgs_out", ctypes.c_uint64),
        ("drops", ctypes.c_uint64),
        ("duplicates", ctypes.c_uint64),
        ("missed", ctypes.c_uint64),
        ("missed_ranges", (ctypes.c_uint64 * 2) * 8),
        ("n_missed_ranges", ctypes.c_uint32),
        ("n_inputs", ctypes.c_uint32),
        ("last_frame_plus1", ctypes.c_uint64 * 8),
        ("flags", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
    ]

    @staticmethod
    def type_name():
        return "lineflow/NodeStatus/v1"


NODE_FINISHED = 2

# Encodings of ImageHeader.encoding.
MONO8, RGB8, MONO16, RGB16 = 0, 1, 2, 3


def gray_of(h, payload):
    """8-bit grey as lineflow-convert computes it (integer BT.601 luma)."""
    w, ht, step = h.width, h.height, h.step
    raw = np.frombuffer(payload, dtype=np.uint8, count=step * ht).reshape(ht, step)
    if h.encoding not in (MONO8, RGB8, MONO16, RGB16):
        raise ValueError(f"frame {h.stamp.frame}: encoding {h.encoding} is not supported by the Python sobel node")
    if h.encoding in (MONO16, RGB16):
        # 16-bit samples in native byte order; their high byte, as lineflow-convert takes it.
        raw = (raw.view(np.uint16) >> 8).astype(np.uint8)
    if h.encoding in (MONO8, MONO16):
        return raw[:, :w].copy()
    rgb = raw[:, : 3 * w].reshape(ht, w, 3).astype(np.uint32)
    return ((rgb[..., 0] * 77 + rgb[..., 1] * 150 + rgb[..., 2] * 29 + 128) >> 8).astype(np.uint8)


def sobel_edges(gray, threshold):
    """Edge pixels (rows, cols, gx, gy) of the Rust `sobel`: L2 magnitude above `threshold`, suppressed."""
    g = np.pad(gray.astype(np.int32), 1, mode="edge")
    gx = (g[:-2, 2:] + 2 * g[1:-1, 2:] + g[2:, 2:]) - (g[:-2, :-2] + 2 * g[1:-1, :-2] + g[2:, :-2])
    gy = (g[2:, :-2] + 2 * g[2:, 1:-1] + g[2:, 2:]) - (g[:-2, :-2] + 2 * g[:-2, 1:-1] + g[:-2, 2:])
    mag = gx * gx + gy * gy
    t2 = int(min(max(threshold, 0.0) ** 2, 2**31 - 1))
    m = np.pad(mag, 1, mode="constant")  # neighbours outside the image count as 0
    c = m[1:-1, 1:-1]
    left, right, up, down = m[1:-1, :-2], m[1:-1, 2:], m[:-2, 1:-1], m[2:, 1:-1]
    ax = np.abs(gx).astype(np.int64)
    ay = np.abs(gy).astype(np.int64) << 15
    tg22x = ax * 13573  # tan(22.5°) in 15-bit fixed point, as OpenCV
    horizontal = ay < tg22x
    vertical = ay > tg22x + (ax << 16)
    same_sign = (gx ^ gy) >= 0
    # Diagonal: s = +1 when the signs agree: compare up-left with down-right, else up-right with down-left.
    diag_pos = (c > m[:-2, :-2]) & (c > m[2:, 2:])
    diag_neg = (c > m[:-2, 2:]) & (c > m[2:, :-2])
    is_max = np.where(
        horizontal,
        (c > left) & (c >= right),
        np.where(vertical, (c > up) & (c >= down), np.where(same_sign, diag_pos, diag_neg)),
    )
    rows, cols = np.nonzero((c > t2) & is_max)
    return rows, cols, gx[rows, cols], gy[rows, cols]


def fail(msg):
    node = os.environ.get("LINEFLOW_NODE", "node")
    print(f"[{node}] error: {msg}", file=sys.stderr)
    sys.exit(1)


def main():
    describe = os.environ.get("LINEFLOW_DESCRIBE") == "1" or "--describe" in sys.argv
    if describe:
        print(json.dumps({
            "inputs": [{"port": "images", "message": "Image", "required": True}],
            "outputs": [{"port": "edges", "message": "EdgeMap", "required": True}],
        }))
        return
    try:
        env = {k: os.environ[k] for k in ("LINEFLOW_IOX2_PREFIX", "LINEFLOW_IOX2_ROOT", "LINEFLOW_GRAPH", "LINEFLOW_NODE")}
    except KeyError as e:
        fail(f"{e.args[0]} is not set: start nodes with `lineflow run` (docs/nodes.md)")
    graph = json.load(open(env["LINEFLOW_GRAPH"]))
    me = env["LINEFLOW_NODE"]
    spec = next((n for n in graph["nodes"] if n["name"] == me), None)
    if spec is None:
        fail(f"node '{me}' is not in the graph")
    params = {k: v for k, v in spec["params"].items() if k != "impl"}
    unknown = set(params) - {"threshold"}
    if unknown:
        fail(f"node '{me}': unknown parameters {sorted(unknown)} (the Python sobel takes: threshold)")
    threshold = float(params.get("threshold", 100.0))
    topic_in = spec["remap"].get("images", "images")
    topic_out = spec["remap"].get("edges", "edges")
    edge_in = next((e for e in graph["edges"] if e["topic"] == topic_in and me in e["to"]), None)
    edge_out = next((e for e in graph["edges"] if e["topic"] == topic_out and e["from"] == me), None)
    if edge_in is None or edge_out is None:
        fail(f"node '{me}': ports 'images' and 'edges' must be wired")

    iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
    cfg = iox2.config.default()
    cfg.global_cfg.prefix = iox2.FileName.new(env["LINEFLOW_IOX2_PREFIX"])
    root = env["LINEFLOW_IOX2_ROOT"].rstrip("/") + "/"
    cfg.global_cfg.root_path = iox2.Path.new(root)
    node = iox2.NodeBuilder.new().name(iox2.NodeName.new(me)).config(cfg).create(iox2.ServiceType.Ipc)

    def pubsub(edge, header, element):
        # The same settings as transport::open_pubsub, so that the Rust nodes open the same service.
        return (
            node.service_builder(iox2.ServiceName.new(edge["topic"]))
            .publish_subscribe(iox2.Slice[element])
            .user_header(header)
            .enable_safe_overflow(edge["policy"] == "latest")
            .subscriber_max_buffer_size(edge["depth"])
            .subscriber_max_borrowed_samples(2)
            .history_size(edge["history"])
            .max_publishers(2)
            .max_subscribers(len(edge["to"]) + 1)
            .max_nodes(len(edge["to"]) + 4)
            .open_or_create()
        )

    def event(name):
        return (
            node.service_builder(iox2.ServiceName.new(name))
            .event()
            .max_notifiers(MAX_NODES)
            .max_listeners(MAX_NODES)
            .max_nodes(MAX_NODES * 2)
            .event_id_max_value(MAX_NODES * 2)
            .open_or_create()
        )

    images = pubsub(edge_in, ImageHeader, ctypes.c_uint8)
    subscriber = images.subscriber_builder().buffer_size(edge_in["depth"]).create()
    listener = event(topic_in).listener_builder().create()
    edges = pubsub(edge_out, EdgeMapHeader, EdgePixel)
    element = ctypes.sizeof(EdgePixel)
    publisher = (
        edges.publisher_builder()
        .initial_max_slice_len(max(1, edge_out["max_payload_bytes"] // element))
        .allocation_strategy(iox2.AllocationStrategy.PowerOfTwo)
        .max_loaned_samples(2)
        .create()
    )
    notifier = event(topic_out).notifier_builder().create()
    status_service = (
        node.service_builder(iox2.ServiceName.new("lineflow/status"))
        .publish_subscribe(NodeStatus)
        .enable_safe_overflow(True)
        .subscriber_max_buffer_size(256)
        .history_size(0)
        .max_publishers(MAX_NODES * 2)
        .max_subscribers(4)
        .max_nodes(MAX_NODES * 2 + 4)
        .open_or_create()
    )
    status_pub = status_service.publisher_builder().max_loaned_samples(1).create()
    ready = event("lineflow/ready").notifier_builder().default_event_id(iox2.EventId.new(spec["index"])).create()

    # Connect: the publisher upstream and every subscriber downstream must be there (iceoryx2 pitfall P1).
    deadline = time.monotonic() + float(os.environ.get("LINEFLOW_CONNECT_TIMEOUT_S", "30"))
    while images.dynamic_config.number_of_publishers == 0 or edges.dynamic_config.number_of_subscribers < len(edge_out["to"]):
        if time.monotonic() > deadline:
            fail(f"node '{me}': peers did not connect to '{topic_in}' / '{topic_out}' in time")
        time.sleep(0.002)
    subscriber.has_samples()  # establishes the connection to the publisher
    publisher.update_connections()
    ready.notify()

    status = NodeStatus(node_index=spec["index"], pid=os.getpid(), n_inputs=1)

    def report(finished=False):
        if finished:
            status.flags |= NODE_FINISHED
        status_pub.send_copy(status)

    supervisor = os.getppid()
    seq = 0
    last = Stamp()

    def publish(header, pixels_list):
        nonlocal seq
        n = len(pixels_list)
        sample = publisher.loan_slice_uninit(n)
        header.stamp.seq = seq
        ctypes.memmove(sample.user_header_ptr, ctypes.byref(header), ctypes.sizeof(header))
        if n:
            ctypes.memmove(sample.payload_ptr, pixels_list.ctypes.data, n * element)
        delivered = sample.assume_init().send()
        notifier.notify()
        seq += 1
        status.msgs_out += 1
        status.drops += max(0, len(edge_out["to"]) - delivered)

    pixel_dtype = np.dtype([("col", "<u2"), ("row", "<u2"), ("magnitude", "<f4"), ("direction_rad", "<f4")])
    ended = False
    waitset = iox2.WaitSetBuilder.new().create(iox2.ServiceType.Ipc)
    guard = waitset.attach_notification(listener)
    tick = waitset.attach_interval(iox2.Duration.from_millis(100))
    while not ended:
        while True:
            sample = subscriber.receive()
            if sample is None:
                break
            h = ImageHeader.from_buffer_copy(ctypes.string_at(sample.user_header_ptr, ctypes.sizeof(ImageHeader)))
            if h.stamp.flags & END_OF_STREAM:
                ended = True
                continue
            payload = ctypes.string_at(sample.payload_ptr, h.step * h.height)
            del sample
            status.msgs_in += 1
            status.last_frame_plus1[0] = h.stamp.frame + 1
            gray = gray_of(h, payload)
            rows, cols, gx, gy = sobel_edges(gray, threshold)
            px = np.zeros(len(rows), dtype=pixel_dtype)
            px["col"], px["row"] = cols, rows
            px["magnitude"] = np.sqrt((gx * gx + gy * gy).astype(np.float32))
            px["direction_rad"] = np.arctan2(gy.astype(np.float32), gx.astype(np.float32))
            out = EdgeMapHeader(stamp=h.stamp, width=h.width, height=h.height, name=h.name)
            out.detector[:5] = list(b"sobel")
            publish(out, px)
            last = h.stamp
            report()
        if ended:
            break
        result = waitset.wait_and_process()
        listener.try_wait()
        if result in (iox2.WaitSetRunResult.Interrupt, iox2.WaitSetRunResult.TerminationRequest):
            break
        if os.getppid() != supervisor:
            # The supervisor is gone (docs/nodes.md, node contract 7): nobody would ever stop this node.
            sys.stderr.write(f"[{me}] error: the supervisor (pid {supervisor}) is gone: stopping\n")
            break
    eos = EdgeMapHeader()
    eos.stamp = Stamp(frame=last.frame + 1, capture_time_ns=last.capture_time_ns, flags=END_OF_STREAM)
    publish(eos, np.zeros(0, dtype=pixel_dtype))
    report(finished=True)


if __name__ == "__main__":
    try:
        main()
    except Exception as e:  # one clear line and a non-zero exit, as the Rust nodes do
        fail(f"{type(e).__name__}: {e}")

#!/usr/bin/env python3
"""Independent check of a lineflow recording with Python's `mcap` and `mcap-ros2-support` packages.

Usage: check_recording.py RECORDING RUN_OUT_DIR [PNG_DIR]

Every message of every channel is decoded from the schemas embedded in the file (ros2msg/CDR and JSON), without
lineflow's code, and checked against the run's outputs:
  * `lines2d` segments equal the rows of lines2d.csv;
  * `edges` messages match edges.csv (pixel counts and FNV-1a checksums over the decoded fields);
  * `gray` images match frames.csv (sizes, names and FNV-1a checksums of the pixels);
  * `images` equal the PNG files in PNG_DIR (written by `lineflow synth` for the same scene), if given;
  * image previews, annotations and scene entities parse and agree with the messages they render;
  * images recorded compressed (`lineflow_msgs/msg/CompressedImage`, `[record] images = "png"`) are read through
    PIL from the PNG file in their `data`, and must then pass the same checks.
Prints one line per channel and exits non-zero on the first mismatch.
"""
import csv
import json
import struct
import sys
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def fnv1a64(data, h=0xCBF29CE484222325):
    for b in data:
        h = ((h ^ b) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def pixels(schema_name, d):
    """The pixel bytes of an Image message, or of a CompressedImage one through PIL (PNG: lossless)."""
    if schema_name != "lineflow_msgs/msg/CompressedImage":
        return bytes(d.data)
    import io

    from PIL import Image

    img = Image.open(io.BytesIO(bytes(d.data)))
    if img.format != "PNG" or img.size != (d.width, d.height) or img.mode not in ("L", "RGB"):
        fail(f"compressed image {d.name}: {img.format} {img.size} {img.mode} for {d.width}x{d.height}")
    return img.tobytes()


def fail(msg):
    print(f"FAIL: {msg}")
    sys.exit(1)


def main():
    rec, out = Path(sys.argv[1]), Path(sys.argv[2])
    png_dir = Path(sys.argv[3]) if len(sys.argv) > 3 else None
    decoders = DecoderFactory()
    by_topic = {}
    with open(rec, "rb") as f:
        reader = make_reader(f, decoder_factories=[decoders])
        summary = reader.get_summary()
        if summary is None:
            fail("no summary section")
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if channel.message_encoding == "cdr":
                decoded = decoders.decoder_for("cdr", schema)(message.data)
            elif channel.message_encoding == "json":
                if schema.encoding != "jsonschema":
                    fail(f"{channel.topic}: json channel with schema encoding {schema.encoding}")
                json.loads(schema.data)
                decoded = json.loads(message.data)
            else:
                fail(f"{channel.topic}: undecodable message encoding {channel.message_encoding}")
            by_topic.setdefault(channel.topic, []).append((schema.name, message, decoded))

    if meta.get("lineflow.end", {}).get("complete") != "true":
        fail(f"recording not complete: {meta.get('lineflow.end')}")
    if "launch_text" not in meta.get("lineflow.run", {}):
        fail("no launch graph in the metadata")
    counts = summary.statistics.channel_message_counts
    for cid, channel in summary.channels.items():
        if counts.get(cid, 0) != len(by_topic.get(channel.topic, [])):
            fail(f"{channel.topic}: summary counts {counts.get(cid)} messages, read {len(by_topic.get(channel.topic, []))}")

    # Sequence numbers count per channel; publish_time is the capture time in the stamp.
    for topic, msgs in by_topic.items():
        seqs = [m.sequence for _, m, _ in msgs]
        if seqs != list(range(len(seqs))):
            fail(f"{topic}: sequence numbers {seqs[:5]}...")
        for _, m, d in msgs:
            if hasattr(d, "stamp") and d.stamp.capture_time_ns != m.publish_time:
                fail(f"{topic}: publish_time {m.publish_time} != stamp {d.stamp.capture_time_ns}")

    # lines2d against lines2d.csv
    rows = list(csv.DictReader(open(out / "lines2d.csv")))
    recorded = []
    for _, _, d in by_topic["lines2d"]:
        if len(d.segments) != d.n_segments or len(d.chain) != d.n_chain:
            fail("lines2d: counts disagree with the sequences")
        for s in d.segments:
            chain = d.chain[s.chain_start : s.chain_start + s.chain_len]
            if len(chain) != s.chain_len:
                fail("lines2d: chain slice out of range")
            recorded.append((d.name, str(s.id), s.start_px[0], s.start_px[1], s.end_px[0], s.end_px[1], s.chain_len))
    if len(recorded) != len(rows):
        fail(f"lines2d: {len(recorded)} segments recorded, {len(rows)} in lines2d.csv")
    for r, row in zip(sorted(recorded), sorted(rows, key=lambda r: (r["image"], r["id"]))):
        if r[0] != row["image"] or int(r[6]) != int(row["n_pixels"]):
            fail(f"lines2d: {r} vs {row}")
        for v, key in zip(r[2:6], ["col1", "row1", "col2", "row2"]):
            if abs(v - float(row[key])) > 1e-3:
                fail(f"lines2d: {key} {v} vs {row[key]}")
    print(f"lines2d          {len(by_topic['lines2d'])} messages, {len(recorded)} segments = lines2d.csv")

    # edges against edges.csv
    edge_rows = list(csv.DictReader(open(out / "edges.csv")))
    for (_, _, d), row in zip(by_topic["edges"], edge_rows):
        h = 0xCBF29CE484222325
        for p in d.pixels:
            h = fnv1a64(struct.pack("<HHff", p.col, p.row, p.magnitude, p.direction_rad), h)
        if int(row["frame"]) != d.stamp.frame or int(row["n_pixels"]) != len(d.pixels) or int(row["fnv1a64"], 16) != h:
            fail(f"edges frame {d.stamp.frame}: {len(d.pixels)} pixels, {h:016x} vs {row}")
    print(f"edges            {len(edge_rows)} edge maps = edges.csv (checksums over decoded fields)")

    # gray against frames.csv
    frame_rows = {int(r["frame"]): r for r in csv.DictReader(open(out / "frames.csv"))}
    for name, _, d in by_topic["gray"]:
        r = frame_rows[d.stamp.frame]
        if (d.name, d.width, d.height) != (r["image"], int(r["width"]), int(r["height"])) or fnv1a64(pixels(name, d)) != int(r["fnv1a64"], 16):
            fail(f"gray frame {d.stamp.frame} differs from frames.csv")
    print(f"gray             {len(by_topic['gray'])} images = frames.csv (checksums of the pixels)")

    # images against the PNG files of the same scene
    if png_dir is not None:
        from PIL import Image

        for name, _, d in by_topic["images"]:
            png = Image.open(png_dir / d.name).convert("RGB")
            if png.size != (d.width, d.height) or png.tobytes() != pixels(name, d):
                fail(f"images: {d.name} differs from {png_dir / d.name}")
        print(f"images           {len(by_topic['images'])} images = the PNG files")

    # keypoints: descriptors are count x descriptor_len float32 (descriptor_kind 0)
    for _, _, d in by_topic.get("keypoints", []):
        if len(d.keypoints) != d.count or len(bytes(d.descriptors)) != 4 * d.count * d.descriptor_len:
            fail(f"keypoints frame {d.stamp.frame}: counts disagree")
    # tie points: every track is observed in at least two frames, never twice in one
    tracks = {}
    for _, _, d in by_topic.get("tiepoints", []):
        for t in d.tie_points:
            tracks.setdefault(t.track, []).append(t.frame)
    if any(len(f) < 2 or len(set(f)) != len(f) for f in tracks.values()):
        fail("tiepoints: a track with one observation or two in one frame")
    if by_topic.get("tiepoints"):
        print(f"tiepoints        {len(tracks)} tracks, {sum(map(len, tracks.values()))} observations")

    # viewer channels
    for topic, msgs in by_topic.items():
        name = msgs[0][0]
        if name == "foxglove_msgs/msg/RawImage":
            source = by_topic[topic.rsplit("/", 1)[0]]
            for (_, _, p), (_, _, s) in zip(msgs, source):
                if len(p.data) != p.step * p.height or p.width > s.width or p.encoding not in ("mono8", "rgb8"):
                    fail(f"{topic}: preview {p.width}x{p.height} step {p.step} of {s.width}x{s.height}")
        elif name == "foxglove_msgs/msg/CompressedImage":
            import io

            from PIL import Image

            source = by_topic[topic.rsplit("/", 1)[0]]
            for (_, _, p), (_, _, s) in zip(msgs, source):
                img = Image.open(io.BytesIO(bytes(p.data)))
                if p.format != "jpeg" or img.format != "JPEG" or img.size[0] > s.width:
                    fail(f"{topic}: compressed preview {p.format} {img.format} {img.size} of {s.width}x{s.height}")
        elif name == "foxglove.ImageAnnotations":
            source = by_topic[topic.rsplit("/", 1)[0]]
            for (_, _, a), (_, _, s) in zip(msgs, source):
                expected = 2 * len(s.segments) if hasattr(s, "segments") else len(s.keypoints)
                if len(a["points"][0]["points"]) != expected:
                    fail(f"{topic}: annotation points disagree with the message they render")
        elif name == "foxglove.CameraCalibration":
            # Each calibration is in the frame of a preview of its image topic, in the preview's pixel grid (a
            # compressed preview's size is in its JPEG, not in the message).
            previews = {
                (p.frame_id, getattr(p, "width", None), getattr(p, "height", None))
                for _, _, p in by_topic.get(topic.rsplit("/", 1)[0] + "/preview", [])
            }
            for _, _, c in msgs:
                raw = (c["frame_id"], c["width"], c["height"])
                if len(c["K"]) != 9 or len(c["P"]) != 12 or (raw not in previews and (c["frame_id"], None, None) not in previews):
                    fail(f"{topic}: calibration {c['frame_id']} {c['width']}x{c['height']} matches no preview")
        elif name == "foxglove.FrameTransforms":
            for _, _, u in msgs:
                for t in u["transforms"]:
                    q = t["rotation"]
                    if t["parent_frame_id"] != "world" or not t["child_frame_id"].startswith("camera/") or abs(sum(q[k] ** 2 for k in "xyzw") - 1) > 1e-9:
                        fail(f"{topic}: transform malformed: {t}")
        elif name == "foxglove.SceneUpdate":
            # An empty result (no frame oriented yet) renders as an empty scene.
            for _, _, u in msgs:
                if any(e["frame_id"] != "world" for e in u["entities"]):
                    fail(f"{topic}: scene entities malformed")
    for topic in sorted(by_topic):
        print(f"decoded {topic:<24} {len(by_topic[topic]):>4} messages  {by_topic[topic][0][0]}")
    print("OK")


if __name__ == "__main__":
    main()

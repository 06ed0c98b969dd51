#!/usr/bin/env python3
"""Writes the small sample project folder the README's first command runs on (pure Python, deterministic).

Six 320x240 RGB views of a plaster facade with a 3x2 grid of recessed windows, the camera moving 0.6 m to the
right between views. Not photogrammetrically exact (the synthetic camera, `lineflow synth`, is); it exists so
that `lineflow process samples/facade` works on a fresh clone.
"""
import random
import struct
import zlib
from pathlib import Path

W, H = 320, 240


def png(path, rows):
    raw = b"".join(b"\x00" + bytes(r) for r in rows)

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    data = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", W, H, 8, 2, 0, 0, 0))
    data += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    path.write_bytes(data)


def view(k, rng):
    shift = int(k * 0.6 / 0.02)  # 2 cm per pixel at the facade
    rows = []
    for r in range(H):
        row = []
        for c in range(W):
            x = c + shift
            v = 200 + rng.randint(-6, 6)
            col = (v, v - 8, v - 20)
            wx, wy = x % 90, r % 110
            if 20 <= wx < 70 and 15 <= wy < 95:
                g = 60 + rng.randint(-3, 3)
                col = (g, g + 10, g + 25)  # glass
                if wx < 24 or wx >= 66 or wy < 19 or wy >= 91:
                    col = (235, 235, 230)  # frame
            if r >= 228:
                col = (120, 110, 100)  # plinth
            row.extend(col)
        rows.append(row)
    return rows


def main():
    here = Path(__file__).resolve().parent
    (here / "images").mkdir(exist_ok=True)
    rng = random.Random(7)
    for k in range(6):
        png(here / "images" / f"IMG_{k + 1}.png", view(k, rng))


if __name__ == "__main__":
    main()

# Writes star-section.png: a 64x64 8-bit grayscale PNG of a five-pointed star with rounded
# tips (white inside, black outside) over the square [-1, 1]^2, x right, y up, for a sweep's
# section_image. The tips are rounded (the star grown by 0.12) so that they stay wider than
# a cell of the example's lattice. Usage: python3 star-section.py star-section.png
import math
import struct
import sys
import zlib

W = H = 64
GROW = 0.12
pts = []
for k in range(10):
    r = 0.8 if k % 2 == 0 else 0.36
    a = math.pi / 2 + k * math.pi / 5
    pts.append((r * math.cos(a), r * math.sin(a)))


def in_polygon(x, y):
    c = False
    for i in range(len(pts)):
        (x1, y1), (x2, y2) = pts[i], pts[i - 1]
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            c = not c
    return c


def edge_distance(x, y):
    best = float("inf")
    for i in range(len(pts)):
        (x1, y1), (x2, y2) = pts[i], pts[i - 1]
        dx, dy = x2 - x1, y2 - y1
        t = max(0.0, min(1.0, ((x - x1) * dx + (y - y1) * dy) / (dx * dx + dy * dy)))
        best = min(best, math.hypot(x - x1 - t * dx, y - y1 - t * dy))
    return best


def inside(x, y):
    return in_polygon(x, y) or edge_distance(x, y) <= GROW


rows = b""
for r in range(H):
    y = 1 - (r + 0.5) * 2 / H
    rows += b"\0" + bytes(255 if inside(-1 + (c + 0.5) * 2 / W, y) else 0 for c in range(W))


def chunk(kind, data):
    crc = zlib.crc32(kind + data) & 0xFFFFFFFF
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)


png = b"\x89PNG\r\n\x1a\n"
png += chunk(b"IHDR", struct.pack(">IIBBBBB", W, H, 8, 0, 0, 0, 0))
png += chunk(b"IDAT", zlib.compress(rows, 9))
png += chunk(b"IEND", b"")
with open(sys.argv[1], "wb") as f:
    f.write(png)

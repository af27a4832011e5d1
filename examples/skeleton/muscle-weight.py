# Writes muscle-weight.png: a 64x16 8-bit grayscale PNG for a polygon's weight_image
# (DIS section 6.4): dark (0.45) at the two ends, rising smoothly to white (1.0) in the
# middle, with a darker band (0.7) across the centre, so a muscle polygon thins to tendons
# at its ends and shows a groove across its belly. Columns run along the polygon's first
# edge. Usage: python3 muscle-weight.py muscle-weight.png
import math
import struct
import sys
import zlib

W, H = 64, 16
rows = []
for j in range(H):
    row = bytearray([0])  # filter type 0
    for i in range(W):
        s = (i + 0.5) / W
        bell = math.sin(math.pi * s) ** 2
        w = 0.45 + 0.55 * bell
        if abs(s - 0.5) < 0.04:
            w = min(w, 0.7)
        row.append(round(255 * w))
    rows.append(bytes(row))


def chunk(kind, data):
    c = struct.pack(">I", len(data)) + kind + data
    return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


png = b"\x89PNG\r\n\x1a\n"
png += chunk(b"IHDR", struct.pack(">IIBBBBB", W, H, 8, 0, 0, 0, 0))
png += chunk(b"IDAT", zlib.compress(b"".join(rows), 9))
png += chunk(b"IEND", b"")
with open(sys.argv[1] if len(sys.argv) > 1 else "muscle-weight.png", "wb") as f:
    f.write(png)

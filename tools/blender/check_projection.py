#!/usr/bin/env python3
"""Check the ground truth of a Blender room folder by projecting its marker spheres.

tools/blender/render_room.py places small magenta emissive spheres at known world points
(markers.txt) and writes the camera pose (groundtruth.txt, T_world_cam in the OpenCV
camera convention) and intrinsics (camera.yaml). This script projects every marker through
those files, u = fx X/Z + cx, v = fy Y/Z + cy with (X, Y, Z) = R^T (p_world - t), and
measures where the marker really is in the rendered frame: the centroid of the magenta
pixels in a window around the prediction. A wrong axis flip, a half-pixel principal point
error, a focal length error or an off-by-one frame shows up as an offset of a pixel or more;
the projection itself is sub-pixel (a sphere's image centroid differs from its centre's
projection by far less than 0.1 px at these sizes).

    python3 tools/blender/check_projection.py DIR [--every N] [--max-median 0.3] [--max-error 1.0]

Exit status 0 when at least --min-hits markers were found, their median error is below
--max-median px and every error below --max-error px. Standard library only (it carries
a small PNG reader), so it runs without Blender, numpy or OpenCV.
"""

import argparse
import math
import os
import struct
import sys
import zlib

MARKER_RADIUS_M = 0.015  # render_room.py's marker spheres


def read_png(path):
    """8-bit grey/RGB/RGBA, non-interlaced PNG -> (width, height, channels, bytes)."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    pos, idat, hdr = 8, [], None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            hdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
    width, height, depth, ctype, _, _, interlace = hdr
    channels = {0: 1, 2: 3, 4: 2, 6: 4}.get(ctype)
    if depth != 8 or channels is None or interlace:
        raise ValueError(f"{path}: only 8-bit non-interlaced grey/RGB(A) PNGs are read")
    raw = zlib.decompress(b"".join(idat))
    stride = width * channels
    out = bytearray(height * stride)
    prev = bytearray(stride)
    for y in range(height):
        ftype = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        if ftype == 1:
            for i in range(channels, stride):
                line[i] = (line[i] + line[i - channels]) & 255
        elif ftype == 2:
            line = bytearray((a + b) & 255 for a, b in zip(line, prev))
        elif ftype == 3:
            for i in range(stride):
                left = line[i - channels] if i >= channels else 0
                line[i] = (line[i] + ((left + prev[i]) >> 1)) & 255
        elif ftype == 4:
            for i in range(stride):
                a = line[i - channels] if i >= channels else 0
                b = prev[i]
                c = prev[i - channels] if i >= channels else 0
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pred) & 255
        elif ftype != 0:
            raise ValueError(f"{path}: bad filter type {ftype} in row {y}")
        out[y * stride:(y + 1) * stride] = line
        prev = line
    return width, height, channels, out


def read_yaml_numbers(path):
    vals = {}
    with open(path) as f:
        for line in f:
            line = line.split("#", 1)[0].strip()
            if ":" in line:
                k, v = (s.strip() for s in line.split(":", 1))
                try:
                    vals[k] = float(v)
                except ValueError:
                    pass
    return vals


def read_rows(path):
    with open(path) as f:
        return [line.split() for line in f if line.strip() and not line.startswith("#")]


def quat_to_matrix(qx, qy, qz, qw):
    n = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    x, y, z, w = qx / n, qy / n, qz / n, qw / n
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]


def find_marker(img, u, v, radius_px):
    """Centroid of magenta pixels near (u, v), or None if too few are seen."""
    width, height, ch, px = img
    half = int(radius_px + 6)
    x0, x1 = max(0, int(u) - half), min(width - 1, int(u) + half + 1)
    y0, y1 = max(0, int(v) - half), min(height - 1, int(v) + half + 1)
    sw = sx = sy = 0.0
    count = 0
    for y in range(y0, y1 + 1):
        for x in range(x0, x1 + 1):
            i = (y * width + x) * ch
            r, g, b = px[i], px[i + 1], px[i + 2]
            weight = min(r, b) - 2 * g  # pinks and purples of the materials stay below 0
            if weight > 40 and abs(r - b) < 90:
                # partial coverage at the anti-aliased rim gives a partial weight
                w = min(weight, 255) / 255.0
                sw += w
                sx += w * x
                sy += w * y
                count += 1
    if count == 0 or sw < 0.7 * math.pi * radius_px * radius_px:  # partly hidden
        return None
    return sx / sw, sy / sw


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("dir")
    p.add_argument("--every", type=int, default=10, help="check every N-th frame")
    p.add_argument("--min-hits", type=int, default=5)
    p.add_argument("--max-median", type=float, default=0.3)
    p.add_argument("--max-error", type=float, default=1.0)
    a = p.parse_args()
    cam = read_yaml_numbers(os.path.join(a.dir, "camera.yaml"))
    fx, fy, cx, cy = cam["fx"], cam["fy"], cam["cx"], cam["cy"]
    gt = {row[0]: [float(v) for v in row[1:8]] for row in read_rows(os.path.join(a.dir, "groundtruth.txt"))}
    frames = read_rows(os.path.join(a.dir, "rgb.txt"))
    markers = [(row[0], [float(v) for v in row[1:4]])
               for row in read_rows(os.path.join(a.dir, "markers.txt"))]
    if not markers:
        sys.exit("check_projection: markers.txt lists no markers (rendered with --no-markers?)")
    errors = []
    for n, (stamp, name) in enumerate(frames):
        path = os.path.join(a.dir, name)
        if n % a.every or not os.path.isfile(path):
            continue
        tx, ty, tz, qx, qy, qz, qw = gt[stamp]
        R = quat_to_matrix(qx, qy, qz, qw)
        img = read_png(path)
        for mname, pw in markers:
            d = (pw[0] - tx, pw[1] - ty, pw[2] - tz)
            X, Y, Z = (sum(R[r][c] * d[r] for r in range(3)) for c in range(3))  # R^T d
            if Z < 0.2:
                continue
            u, v = fx * X / Z + cx, fy * Y / Z + cy
            radius = fx * MARKER_RADIUS_M / Z
            if not (radius + 3 <= u <= img[0] - radius - 4 and radius + 3 <= v <= img[1] - radius - 4):
                continue
            found = find_marker(img, u, v, radius)
            if found is None:
                print(f"{name} {mname}: predicted ({u:.2f}, {v:.2f}), not seen (occluded?)")
                continue
            e = math.hypot(found[0] - u, found[1] - v)
            errors.append(e)
            print(f"{name} {mname}: predicted ({u:.2f}, {v:.2f}) found ({found[0]:.2f}, "
                  f"{found[1]:.2f}) error {e:.3f} px (radius {radius:.1f} px)")
    if len(errors) < a.min_hits:
        print(f"FAIL: {len(errors)} markers found, need {a.min_hits}")
        return 1
    errors.sort()
    med, worst = errors[len(errors) // 2], errors[-1]
    ok = med <= a.max_median and worst <= a.max_error
    print(f"{'PASS' if ok else 'FAIL'}: {len(errors)} markers, median error {med:.3f} px, "
          f"max {worst:.3f} px (limits {a.max_median}, {a.max_error})")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

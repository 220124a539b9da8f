#!/usr/bin/env python3
"""Seed corpus of fuzz_map (tests/fuzz/fuzz_map.cpp) from a map saved by a short synthetic run.

    build/firmware_app/rdslam replay 'synth:static_halfsphere?frames=12' \\
        --set features.max_features=200 --save-map /tmp/seed.map
    tests/fuzz/make_map_seeds.py /tmp/seed.map tests/fuzz/corpus/fuzz_map

The keyframe images are replaced to keep the seeds small (tests/fuzz/run.sh gives this
target -max_len 128 KiB): the first keyframe's by a flat grey PNG of the camera's size (about 1 KB, so the image decoding is
fuzzed too), the others by none (PNG size 0, which the format allows); the CRC is recomputed. Writes, each with the target's
leading flags byte (docs/map_format.md has the layout; fuzz_map.cpp the flags):
  valid          the stripped map, flags 0 (the file as saved)
  valid_fixcrc   the same, flags 3 (the target rewrites size and CRC: mutations reach the decoder)
  truncated_*    cut in the preamble, in the header, in the first keyframe and in the points
                 (flags 0: refused as truncated; flags 3: the decoder runs out of bytes)
"""
import os
import struct
import sys
import zlib

PRE = 24


def flat_png(width: int, height: int) -> bytes:
    """An 8-bit grey PNG of one grey level."""
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    rows = b"".join(b"\0" + b"\x80" * width for _ in range(height))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows, 9)) + chunk(b"IEND", b""))


def strip_images(data: bytes) -> bytes:
    assert data[:8] == b"RDSLAMAP", "not a map file"
    p = bytearray(data[PRE:])
    o = 0

    def take(fmt):
        nonlocal o
        v = struct.unpack_from("<" + fmt, p, o)
        o += struct.calcsize("<" + fmt)
        return v

    (n,) = take("I"); o += n          # camera model
    (width, height) = take("ii"); take("10d")
    (n,) = take("I"); o += n          # feature mode
    (desc,) = take("i"); take("id"); take("q")
    (nk, _np) = take("qq"); take("qqq")
    out = bytearray(p[:o])
    for k in range(nk):
        start = o
        take("qq"); take("12d"); take("B")
        (nf,) = take("i"); take("ii"); take("f")
        o += nf * 40 + nf * desc
        out += p[start:o]
        (png,) = take("q")
        o += png
        image = flat_png(width, height) if k == 0 else b""
        out += struct.pack("<q", len(image)) + image
    out += p[o:]
    return bytes(out)


def with_preamble(payload: bytes) -> bytes:
    return b"RDSLAMAP" + struct.pack("<IQI", 1, len(payload), zlib.crc32(payload)) + payload


def main():
    src, out_dir = sys.argv[1], sys.argv[2]
    full = with_preamble(strip_images(open(src, "rb").read()))
    os.makedirs(out_dir, exist_ok=True)
    seeds = {"valid": b"\0" + full, "valid_fixcrc": b"\3" + full}
    header_end = PRE + 200
    for name, cut in [("preamble", 16), ("header", PRE + 40), ("keyframe", header_end),
                      ("points", len(full) - 300)]:
        seeds["truncated_" + name] = b"\0" + full[:cut]
        seeds["truncated_" + name + "_fixcrc"] = b"\3" + full[:cut]
    for name, b in seeds.items():
        with open(os.path.join(out_dir, name), "wb") as f:
            f.write(b)
    print(f"{len(seeds)} seeds, valid map {len(full)} bytes")


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""Forged live-point libraries for the livepoints fuzz target's seed corpus.

    forge_livepoints.py PAYLOAD OUTDIR

PAYLOAD is a valid library's payload (the zstd frame after its 32-byte
header, decompressed). Writes OUTDIR/forged-FIELD.payload, each the payload
with one field out of range (docs/livepoints.md, "File format"): the fuzz
target wraps a bare payload in a valid header and checksum, so these reach
the reader's range checks, and mutations of them the fields around.
"""
import os
import struct
import sys


def walk(p):
    """Offsets of the fields the forgeries edit, from the documented layout."""
    at = 0
    f = {}

    def u64(o):
        return struct.unpack_from("<Q", p, o)[0]

    def skip_str():
        nonlocal at
        at += 8 + u64(at)

    skip_str()  # trace path
    skip_str()  # scene name
    at += 4 + 4 + 4 + 8  # spp, width, height, seed
    f["repeat"] = at
    at += 4
    skip_str()  # description
    at += 1 + 8  # from-trace, digest
    width = struct.unpack_from("<I", p, at)[0]
    at += 4 + 4 + 4 + 3 + 12 + 4 + 128  # the trace header to its scene name
    skip_str()
    at += 1  # checksummed
    n_draws = u64(at)  # the draw table
    at += 8
    for _ in range(n_draws):
        at += 4 + 3 + 9 + 16  # id, flags, equations, factors, function, mask, encoding, blend colour
        skip_str()  # its name
    skip_str()  # method name
    at += 4 + 4 + 4 + 8  # numerics, seed
    f["slab_k"], f["slab_b"] = at, at + 4
    at += 8 + 3
    f["unit_fragments"], f["units"] = at, at + 24
    at += 5 * 8 + 8 + 1  # U, W, C, K, T, R, whole
    f["fragments"] = at
    at += 8
    counters = []
    n = u64(at)
    at += 8
    for _ in range(n):
        at += 8 + u64(at)
        counters.append(at)
        at += 8
    f["counters"] = counters
    at += 4 + 4 + 12  # the image's size and background
    f["rows"], f["first_row"], f["row_bytes"] = at, at + 8, 4 + width * 12
    return f


def main():
    src, out = sys.argv[1], sys.argv[2]
    p = bytearray(open(src, "rb").read())
    f = walk(p)
    os.makedirs(out, exist_ok=True)

    def forge(name, edit):
        b = bytearray(p)
        edit(b)
        open(os.path.join(out, "forged-%s.payload" % name), "wb").write(bytes(b))

    forge("n-2e60", lambda b: struct.pack_into("<Q", b, f["fragments"], 1 << 60))
    forge("u-0", lambda b: struct.pack_into("<Q", b, f["unit_fragments"], 0))
    forge("k-units-0", lambda b: struct.pack_into("<Q", b, f["units"], 0))
    forge("repeat-0", lambda b: struct.pack_into("<I", b, f["repeat"], 0))
    forge("repeat-5000", lambda b: struct.pack_into("<I", b, f["repeat"], 5000))
    forge("slab-k-0", lambda b: struct.pack_into("<I", b, f["slab_k"], 0))
    forge("slab-b-100", lambda b: struct.pack_into("<I", b, f["slab_b"], 100))
    for i in range(min(2, len(f["counters"]))):
        forge("counter-%d-max" % i, lambda b, i=i: struct.pack_into("<Q", b, f["counters"][i], (1 << 64) - 1))
    rows = struct.unpack_from("<Q", p, f["rows"])[0]
    if rows > 0:
        for name, v in (("nan", float("nan")), ("inf", float("inf")), ("minus-1", -1.0)):
            forge("pixel-" + name, lambda b, v=v: struct.pack_into("<f", b, f["first_row"] + 4, v))

        def twice(b):
            struct.pack_into("<Q", b, f["rows"], rows + 1)
            row = b[f["first_row"]:f["first_row"] + f["row_bytes"]]
            b[f["first_row"] + f["row_bytes"]:f["first_row"] + f["row_bytes"]] = row

        forge("row-twice", twice)


if __name__ == "__main__":
    main()

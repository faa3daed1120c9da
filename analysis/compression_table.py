#!/usr/bin/python3
"""The compression study's table (studies/compression.toml): for each input,
method and spp, DRAM bytes (read + written, every buffer, state bits included)
and cycles with configs/uncompressed.toml and with the default design, Hi-Z
rejections and the block-size shares of the depth and colour line writebacks.

  ropsim study run studies/compression.toml -j 2 --out comp
  /usr/bin/python3 analysis/compression_table.py comp > table.md
"""
import json
import os
import sys


def main(out):
    rows = {}
    for p in sorted(os.listdir(os.path.join(out, "points"))):
        d = os.path.join(out, "points", p)
        if not os.path.exists(os.path.join(d, "report.json")):
            continue
        par = json.load(open(os.path.join(d, "params.json")))
        rep = json.load(open(os.path.join(d, "report.json")))
        t = rep["timing"]
        on = "uncompressed" not in par["design"]
        key = (par["input"], par["method"], int(par["spp"]))
        r = rows.setdefault(key, {})
        r["on" if on else "off"] = t
    order = {"opaque": 0, "a2c": 1, "enderton": 2, "lk": 3}
    print("| input | method | spp | DRAM bytes, off | DRAM bytes, on | on / off | cycles off | cycles on "
          "| Hi-Z rejected | depth line writes in U, U/2, U/4 | colour line writes in U, U/2, U/4 |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|")
    for key in sorted(rows, key=lambda k: (k[0], k[2], order.get(k[1], 9))):
        r = rows[key]
        if "on" not in r or "off" not in r:
            continue
        a, b = r["off"], r["on"]
        ba = a["dram"]["bytes_read"] + a["dram"]["bytes_written"]
        bb = b["dram"]["bytes_read"] + b["dram"]["bytes_written"]
        comp = b["compression"]
        shares = {x["buffer"]: x["class_shares"] for x in comp["buffers"]}

        def sh(name):
            s = shares.get(name)
            return ", ".join("%.2f" % v for v in s) if s else "—"

        print("| %s | %s | %d | %d | %d | %.3f | %d | %d | %d | %s | %s |" % (
            key[0], key[1], key[2], ba, bb, bb / ba, a["total_cycles"], b["total_cycles"], comp["hiz_rejected"],
            sh("depth"), sh("color")))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: compression_table.py STUDY_OUT")
    main(sys.argv[1])

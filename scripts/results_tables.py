"""The tables of docs/results.md (scripts/results.py): for each NAME, the
function that runs ropsim through a Context and formats the Markdown table
that goes between the <!-- results:NAME --> markers, and TABLES, every
NAME with its speed (fast or slow) and function.
"""
import concurrent.futures
import json
import os
import subprocess
import sys

from results_context import ROOT

sys.path.insert(0, os.path.join(ROOT, "analysis"))


def q(name):
    """A results.db column name, quoted."""
    return '"%s"' % name


def f2(v):
    return "%.2f" % v


def f3(v):
    return "%.3f" % v


def thousands(v):
    return "{:,}".format(int(v))


def table(header, align, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "|".join(align) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out) + "\n"


# ---------------------------------------------------------------- quality

LK2011_CLOTH = {4: "0.88", 8: "0.79", 16: "0.67", 32: "0.57", 64: "0.49"}
LK2011_MOTOR = {4: "0.81", 8: "0.71", 16: "0.60", 32: "0.52", 64: "0.46"}


def lk_rmse_by_spp(db, inp):
    rows = db.execute(
        "select spp, avg(case when method='lk' then %s end), avg(case when method='enderton' then %s end) "
        "from results where input = ? group by spp order by spp" % (q("vs_reference.rmse_8bit"),
                                                                   q("vs_reference.rmse_8bit")), (inp,)).fetchall()
    return [(int(s), lk, en) for s, lk, en in rows]


def lk_table_db(ctx):
    return ctx.study("studies/lk-table.toml")[1]


def make_lk_table_cloth(ctx):
    db = lk_table_db(ctx)
    return table(["spp", "lk", "enderton", "ratio lk/enderton", "LK 2011 CLOTH ratio"], ["---:"] * 5,
                 [(s, f2(lk), f2(en), f2(lk / en), LK2011_CLOTH[s]) for s, lk, en in lk_rmse_by_spp(db, "cloth")])


def make_lk_table_scenes(ctx):
    db = lk_table_db(ctx)
    labels = {"enderton-1": "enderton-1 (2 layers, alpha 0.45)", "testcard": "testcard"}
    rows = []
    for inp, label in labels.items():
        rows.append([label] + [f2(lk / en) for _, lk, en in lk_rmse_by_spp(db, inp)])
    return table(["scene", "4", "8", "16", "32", "64 spp"], ["---"] + ["---:"] * 5, rows)


def lk_table_mesh(ctx, study, lk2011):
    out, db = ctx.study(study)
    rows = []
    for s, lk, en in lk_rmse_by_spp(db, db.execute("select input from results limit 1").fetchone()[0]):
        frags = db.execute("select max(%s) from results where spp = ?" % q("counters.fragments"), (s,)).fetchone()[0]
        rows.append((s, thousands(frags), f2(lk), f2(en), f2(lk / en), lk2011[s]))
    return table(["spp", "fragments", "lk", "enderton", "ratio lk/enderton", "LK 2011 %s ratio" %
                  ("MOTOR" if lk2011 is LK2011_MOTOR else "CLOTH")], ["---:"] * 6, rows)


def make_lk_table_motor(ctx):
    return lk_table_mesh(ctx, "studies/lk-table-motor.toml", LK2011_MOTOR)


def make_lk_table_cloth_mesh(ctx):
    return lk_table_mesh(ctx, "studies/lk-table-cloth-mesh.toml", LK2011_CLOTH)


def make_numerics(ctx):
    out, db = ctx.study("studies/numerics.toml")
    rmse, bias = q("vs_reference.rmse_8bit"), q("vs_reference.bias_8bit")
    cases = [("all 32 bits", 32, 32, 32)]
    cases += [("hash %d bits" % b, b, 32, 32) for b in (8, 12, 16)]
    cases += [("alpha %d bits" % b, 32, b, 32) for b in (4, 8)]
    cases += [("surface id %d bit%s" % (b, "" if b == 1 else "s"), 32, 32, b) for b in (1, 2, 4)]

    def sgn(v):
        v = round(v, 3)
        return "0.000" if v == 0 else "%+.3f" % v

    rows = []
    for label, h, a, s in cases:
        row = [label]
        for inp in ("cloth", "smoke"):
            r, b = db.execute("select avg(%s), avg(%s) from results where input = ? and spp = 16 and hash_bits = ? "
                              "and alpha_bits = ? and surface_id_bits = ?" % (rmse, bias), (inp, h, a, s)).fetchone()
            row += [f3(r), sgn(b)]
        rows.append(row)
    return table(["width", "cloth RMSE", "cloth bias", "smoke RMSE", "smoke bias"], ["---"] + ["---:"] * 4, rows)


def make_hash_width(ctx):
    out, db = ctx.study("studies/hash-width.toml")
    md = ctx.tmp("hash-width.md")
    subprocess.run([sys.executable, os.path.join(ROOT, "analysis", "study_cost.py"), out, "--param", "hash_bits",
                    "--spp", "16", "--markdown", md], check=True, stdout=subprocess.DEVNULL)
    with open(md) as f:
        return f.read()


# ---------------------------------------------------------------- cost

def dram_bytes(t):
    return t["dram"]["bytes_read"] + t["dram"]["bytes_written"]


NO_COMPRESSION = ["--hw-set", "compression.depth=false", "--hw-set", "compression.color=false",
                  "--hw-set", "hiz.enable=false"]


def make_cycle_designs(ctx):
    designs = [("uncompressed", []), ("narrow, no compression", NO_COMPRESSION),
               ("wide, no compression", NO_COMPRESSION)]
    files = ["uncompressed", "narrow", "wide"]
    reps = ctx.reports([["--fidelity", "cycle", "--scene", "cloth", "--spp", "16", "--method", "lk", "--hw",
                         os.path.join(ROOT, "configs", f + ".toml"), *extra] for f, (_, extra) in zip(files, designs)])
    rows = []
    for (label, _), rep in zip(designs, reps):
        t = rep["timing"]
        rows.append((label, t["total_cycles"], "%.1f" % t["frame_time_us"], f3(t["fragments_per_clock"]),
                     "%.1f" % (dram_bytes(t) / 1e6), "%.1f / %g" % (t["dram"]["achieved_gbps"], t["dram"]["peak_gbps"]),
                     t["bottleneck"]))
    return table(["config", "cycles", "frame time (µs)", "fragments/clock", "DRAM read+written (MB)",
                  "GB/s achieved / peak", "bottleneck"], ["---", "---:", "---:", "---:", "---:", "---:", "---"], rows)


def make_rop_count(ctx):
    out, db = ctx.study("studies/rop-count.toml", {"design": '"../configs/uncompressed.toml"'})
    rows = db.execute("select %s, %s, %s from results order by 1" % (
        q("distributor.rop_units"), q("timing.fragments_per_clock"), q("timing.bottleneck"))).fetchall()
    return table(["ROPs", "fragments/clock", "bottleneck"], ["---:", "---:", "---"],
                 [(int(r), f3(fpc), b) for r, fpc, b in rows])


def qvc_rows(db, where):
    return db.execute(
        "select method, spp, avg(%s), avg(%s), avg(%s + %s) from results where %s group by method, spp" % (
            q("vs_reference.rmse_8bit"), q("timing.total_cycles"), q("timing.dram.bytes_read"),
            q("timing.dram.bytes_written"), where)).fetchall()


def make_quality_vs_cost_cloth(ctx):
    out, db = ctx.study("studies/quality-vs-cost.toml")
    order = ["lk", "enderton", "naive", "a2c", "opaque"]
    keep = {"lk": (4, 8, 16, 32, 64), "enderton": (4, 8, 16, 32, 64), "naive": (16, 64), "a2c": (16, 64),
            "opaque": (16, 64)}
    rows = [r for r in qvc_rows(db, "input = 'cloth'") if r[0] in keep and int(r[1]) in keep[r[0]]]
    rows.sort(key=lambda r: (order.index(r[0]), r[1]))
    return table(["method", "spp", "RMSE", "cycles", "DRAM bytes"], ["---", "---:", "---:", "---:", "---:"],
                 [(m, int(s), f2(e), thousands(c), thousands(b)) for m, s, e, c, b in rows])


def make_table1(ctx):
    out, db = ctx.study("studies/table1.toml")
    rmse = q("vs_reference.rmse_8bit")
    res = db.execute("select input, %s, spp, avg(case when method='lk' then %s end), "
                     "avg(case when method='enderton' then %s end) from results group by input, %s, spp" % (
                         q("order"), rmse, rmse, q("order"))).fetchall()
    by = {}
    for inp, order, spp, lk, en in res:
        by.setdefault((inp, order), {})[int(spp)] = (lk, en)
    orders = ["authored", "shuffled", "far-to-near", "near-to-far"]
    rows = []
    for inp, order in sorted(by, key=lambda k: (k[0], orders.index(k[1]) if k[1] in orders else 9)):
        row = [inp, order]
        for spp in (4, 16, 64):
            lk, en = by[(inp, order)][spp]
            row += [f2(lk), f2(en), f2(en / lk)]
        rows.append(row)
    head = ["input", "order"]
    for spp in (4, 16, 64):
        head += ["lk %d" % spp, "end. %d" % spp, "ratio %d" % spp]
    return table(head, ["---", "---"] + ["---:"] * 9, rows)


def make_slab(ctx):
    out, db = ctx.study("studies/slab.toml", {"design": '"../configs/uncompressed.toml"'})
    res = db.execute("select input, %s, %s, avg(%s), avg(%s), avg(%s + %s) from results group by 1, 2, 3" % (
        q("slab.layers"), q("slab.bits"), q("vs_reference.rmse_8bit"), q("timing.total_cycles"),
        q("timing.dram.bytes_read"), q("timing.dram.bytes_written"))).fetchall()
    by = {}
    for inp, k, b, e, c, d in res:
        by.setdefault((inp, int(k)), {})[int(b)] = (e, c, d)
    rows = []
    for (inp, k) in sorted(by):
        v = by[(inp, k)]
        bs = sorted(v)
        rows.append((inp, k, " / ".join(f2(v[b][0]) for b in bs), " / ".join(thousands(v[b][1]) for b in bs),
                     " / ".join("%.1f M" % (v[b][2] / 1e6) for b in bs)))
    return table(["scene", "k", "RMSE at b = 8 / 32 / 64", "cycles at b = 8 / 32 / 64",
                  "DRAM bytes at b = 8 / 32 / 64"], ["---", "---:", "---", "---", "---"], rows)


UNCOMPRESSED = {"design": '"../configs/uncompressed.toml"'}


def qvc_by(db, inp=None):
    """{(method, spp): (rmse, cycles, dram bytes)}: means over the seeds."""
    where = "input = '%s'" % inp if inp else "1"
    return {(m, int(s)): (e, c, b) for m, s, e, c, b in qvc_rows(db, where)}


def make_quality_vs_cost_motor(ctx):
    out, db = ctx.study("studies/quality-vs-cost-motor.toml")
    v = qvc_by(db)
    keep = [("lk", s) for s in (4, 16, 32, 64)] + [("enderton", s) for s in (4, 16, 32, 64)]
    keep += [("naive", 64), ("a2c", 64), ("opaque", 64)]
    return table(["method", "spp", "RMSE", "cycles", "DRAM bytes"], ["---", "---:", "---:", "---:", "---:"],
                 [(m, s, f2(v[(m, s)][0]), thousands(v[(m, s)][1]), thousands(v[(m, s)][2])) for m, s in keep])


def make_hashed_foliage(ctx):
    out, db = ctx.study("studies/quality-vs-cost.toml", UNCOMPRESSED)
    rows = []
    for inp in ("cloth", "foliage"):
        v = qvc_by(db, inp)
        for m in ("lk", "enderton", "hashed-a2c", "hashed", "a2c"):
            r = [v[(m, s)] for s in (4, 16, 64)]
            rows.append((inp, m, "4 / 16 / 64", " / ".join(f2(x[0]) for x in r),
                         " / ".join(thousands(x[1]) for x in r), " / ".join("%.1f M" % (x[2] / 1e6) for x in r)))
    return table(["scene", "method", "spp", "RMSE", "cycles", "DRAM bytes"],
                 ["---", "---", "---:", "---:", "---:", "---:"], rows)


def make_slab_qvc(ctx):
    out, db = ctx.study("studies/quality-vs-cost.toml", UNCOMPRESSED)
    rows = []
    for inp in ("cloth", "foliage"):
        v = qvc_by(db, inp)
        r = [v[("slab", s)] for s in (4, 16, 64)]
        rows.append((inp, "4 / 16 / 64", " / ".join(f2(x[0]) for x in r), " / ".join(thousands(x[1]) for x in r),
                     " / ".join("%.1f M" % (x[2] / 1e6) for x in r)))
    return table(["scene", "spp", "RMSE", "cycles", "DRAM bytes"], ["---", "---:", "---:", "---:", "---:"], rows)


def multipass_table(v):
    rows = []
    for s in (4, 8, 16, 32, 64):
        row = [s]
        for suffix in ("", "+ac", "+depth", "+depth+ac"):
            lk, en = v[("lk" + suffix, s)][0], v[("enderton" + suffix, s)][0]
            row.append("%s / %s (%s)" % (f2(lk), f2(en), f2(lk / en)))
        rows.append(row)
    return table(["spp", "plain: lk / enderton (ratio)", "+ac", "+depth", "+depth+ac"], ["---:", "---", "---", "---",
                                                                                         "---"], rows)


def make_multipass_cloth(ctx):
    return multipass_table(qvc_by(ctx.study("studies/quality-vs-cost.toml", UNCOMPRESSED)[1], "cloth"))


def make_multipass_foliage(ctx):
    return multipass_table(qvc_by(ctx.study("studies/quality-vs-cost.toml", UNCOMPRESSED)[1], "foliage"))


def make_multipass_motor(ctx):
    return multipass_table(qvc_by(ctx.study("studies/quality-vs-cost-motor.toml")[1]))


def make_multipass_cost(ctx):
    v = qvc_by(ctx.study("studies/quality-vs-cost.toml", UNCOMPRESSED)[1], "cloth")
    keep = [(m, s) for m in ("wboit", "lk+ac", "lk+depth", "lk+depth+ac") for s in (4, 16, 64)]
    keep += [(m, 16) for m in ("enderton+ac", "enderton+depth", "enderton+depth+ac")]
    rows = []
    for m, s in keep:
        e, c, b = v[(m, s)]
        _, lc, lb = v[("lk", s)]
        rows.append((m, s, f2(e), thousands(c), f2(c / lc), thousands(b), f2(b / lb)))
    return table(["method", "spp", "RMSE", "cycles", "x lk cycles", "DRAM bytes", "x lk DRAM"],
                 ["---", "---:", "---:", "---:", "---:", "---:", "---:"], rows)


# ---------------------------------------------------------------- compression and Hi-Z

def compression_rows(ctx, scenes_only):
    import compression_table
    extra = {}
    if scenes_only:
        extra = {"meshes": None}
    else:
        extra = {"scenes": None}
    out, db = ctx.study("studies/compression.toml", extra)
    import contextlib
    import io
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        compression_table.main(out)
    return buf.getvalue().splitlines()


def make_compression_cloth(ctx):
    lines = compression_rows(ctx, True)
    return "\n".join(lines[:2] + [l for l in lines[2:] if l.startswith("| cloth |")]) + "\n"


def make_compression_motor(ctx):
    lines = compression_rows(ctx, False)
    return "\n".join(lines[:2] + [l for l in lines[2:] if l.startswith("| motor |")]) + "\n"


def depth_encoder_rows(ctx, inputs):
    """inputs: [(label, [input args])]: opaque and lk, plane and fit encoders."""
    jobs = []
    for label, args in inputs:
        for m in ("opaque", "lk"):
            for enc in ("plane", "fit"):
                jobs.append(["--fidelity", "functional", *args, "--method", m, "--compressibility", "--hw-set",
                             "compression.depth_encoder=" + enc])
    reps = ctx.reports(jobs)
    rows = []
    i = 0
    for label, _ in inputs:
        for m in ("opaque", "lk"):
            d = []
            for _ in ("plane", "fit"):
                b = [x for x in reps[i]["compressibility"]["buffers"] if x["buffer"] == "depth"][0]
                d.append((b["bytes_uncompressed"], b["bytes_compressed"]))
                i += 1
            u, p, f = d[0][0], d[0][1], d[1][1]
            rows.append((label, m, u, p, f, f3(p / u), f3(f / u), f3(p / f)))
    return rows


DEPTH_ENCODER_HEAD = (["input", "method", "depth bytes uncompressed", "plane", "fit", "plane / uncompressed",
                       "fit / uncompressed", "plane / fit"], ["---", "---"] + ["---:"] * 6)


def motor_trace(ctx):
    path = os.path.join(ctx.work, "motor.rtr")
    if not os.path.exists(path):
        ctx.call(["capture", os.path.join(ROOT, "traces/scenes/mesh/motor.toml"), "-o", path])
    return path


def make_depth_encoders(ctx):
    inputs = [("cloth, %d spp" % s, ["--scene", "cloth", "--spp", str(s)]) for s in (4, 16, 64)]
    inputs.append(("motor, 16 spp", ["--trace", motor_trace(ctx)]))
    return table(*DEPTH_ENCODER_HEAD, depth_encoder_rows(ctx, inputs))


def make_hiz_opaque(ctx):
    reps = ctx.reports([["--fidelity", f, "--scene", "opaque", "--spp", "16"] for f in ("cycle", "approximate")])
    c, a = (r["timing"]["compression"]["hiz_rejected"] for r in reps)
    return table(["fidelity", "Hi-Z rejected fragments"], ["---", "---:"],
                 [("cycle", thousands(c)), ("approximate", thousands(a)), ("approximate / cycle - 1",
                                                                           "%+.2f %%" % (100.0 * (a / c - 1)))])


# ---------------------------------------------------------------- host speed (deterministic columns only)

def make_trace_size(ctx):
    cases = [("cloth", d, c) for d in ("plane", "per-sample") for c in ("rgb-f32", "rgb-unorm8")]
    cases += [(s, "plane", "rgb-f32") for s in ("smoke", "testcard", "foliage")]

    def one(case):
        scene, depth, color = case
        path = ctx.tmp("%s-%s-%s.rtr" % case)
        ctx.call(["scene", scene, "--spp", "16", "--depth", depth, "--color", color, "-o", path])
        return json.loads(ctx.call(["trace", "info", path, "--json"]))

    with concurrent.futures.ThreadPoolExecutor(ctx.jobs) as ex:
        infos = list(ex.map(one, cases))
    rows = []
    for (scene, depth, color), info in zip(cases, infos):
        b = info["bytes"]
        rows.append((scene, depth, color, thousands(info["fragments"]), f2(b["per_fragment_uncompressed"]),
                     f2(b["per_fragment_on_disk"]), thousands(b["file"])))
    return table(["scene (16 spp)", "`--depth`", "`--color`", "fragments", "uncompressed bytes / fragment",
                  "zstd on disk bytes / fragment", "file bytes"], ["---", "---", "---"] + ["---:"] * 4, rows)


# name: (speed, function)
TABLES = {
    "lk-table-cloth": ("fast", make_lk_table_cloth),
    "lk-table-scenes": ("fast", make_lk_table_scenes),
    "lk-table-motor": ("slow", make_lk_table_motor),
    "lk-table-cloth-mesh": ("slow", make_lk_table_cloth_mesh),
    "numerics": ("slow", make_numerics),
    "hash-width": ("slow", make_hash_width),
    "quality-vs-cost-cloth": ("slow", make_quality_vs_cost_cloth),
    "quality-vs-cost-motor": ("slow", make_quality_vs_cost_motor),
    "hashed-foliage": ("slow", make_hashed_foliage),
    "slab-qvc": ("slow", make_slab_qvc),
    "multipass-cloth": ("slow", make_multipass_cloth),
    "multipass-foliage": ("slow", make_multipass_foliage),
    "multipass-motor": ("slow", make_multipass_motor),
    "multipass-cost": ("slow", make_multipass_cost),
    "table1": ("slow", make_table1),
    "slab": ("slow", make_slab),
    "cycle-designs": ("fast", make_cycle_designs),
    "rop-count": ("fast", make_rop_count),
    "compression-cloth": ("fast", make_compression_cloth),
    "compression-motor": ("slow", make_compression_motor),
    "depth-encoders": ("slow", make_depth_encoders),
    "hiz-opaque": ("fast", make_hiz_opaque),
    "trace-size": ("fast", make_trace_size),
}

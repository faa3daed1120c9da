#!/usr/bin/env python3
"""Exact per-channel RMS errors of Enderton et al.'s Examples 1 and 2 (S = 4
samples, every fragment covering the whole pixel, drawn back to front) for
ropsim's sampling: naive (an independent alpha-coin per sample), stratified
(enderton: R = floor(alpha S + xi) samples chosen uniformly), and the same with
alpha correction (+ac), depth-based accumulation (+depth) and both
(+depth+ac), as docs/methods.md defines their composites. Enumerates every
outcome with its probability; prints the table of docs/results.md."""
import itertools
from math import sqrt

S = 4


def counts(alpha):
    """R = floor(alpha S + xi): {R: probability}."""
    f = int(alpha * S)
    p = alpha * S - f
    return {f: 1 - p, f + 1: p} if p > 0 else {f: 1.0}


def subsets(r):
    return [frozenset(c) for c in itertools.combinations(range(S), r)]


def outcomes(layers, mode):
    """Yields (probability, per-layer sets of chosen samples); layers far to near."""
    if mode == "naive":
        for bits in itertools.product([0, 1], repeat=S * len(layers)):
            p = 1.0
            sets = []
            for i, (a, _) in enumerate(layers):
                chosen = frozenset(s for s in range(S) if bits[i * S + s])
                p *= a ** len(chosen) * (1 - a) ** (S - len(chosen))
                sets.append(chosen)
            yield p, sets
        return
    per_layer = []
    for a, _ in layers:
        opts = []
        for r, pr in counts(a).items():
            subs = subsets(r)
            opts += [(pr / len(subs), c) for c in subs]
        per_layer.append(opts)
    for combo in itertools.product(*per_layer):
        p = 1.0
        for q, _ in combo:
            p *= q
        yield p, [c for _, c in combo]


def pixel(layers, bg, sets, variant):
    """The composite of one outcome. layers: [(alpha, rgb)] far to near (draw order)."""
    n = len(layers)
    # Stochastic z-buffer: each sample holds the nearest layer that chose it.
    top = [None] * S
    for i in range(n):  # far to near: a later (nearer) layer overwrites
        for s in sets[i]:
            top[s] = i
    T = 1.0
    for a, _ in layers:
        T *= 1 - a
    A = 1 - T
    written = [s for s in range(S) if top[s] is not None]
    R = len(written)
    if variant in ("plain", "ac"):
        col = [sum(layers[top[s]][1][c] for s in written) for c in range(3)]
        if variant == "plain":
            return [(col[c] + (S - R) * bg[c]) / S for c in range(3)]
        return [(A * col[c] / R if R else 0.0) + T * bg[c] for c in range(3)]
    # depth-based: layer i adds alpha c at samples whose stored layer is not nearer
    acc = [0.0, 0.0, 0.0, 0.0]
    for s in range(S):
        for i, (a, rgb) in enumerate(layers):
            if top[s] is None or top[s] <= i:  # i is at or in front of the stored surface
                for c in range(3):
                    acc[c] += a * rgb[c]
                acc[3] += a
    if variant == "depth":
        return [acc[c] / S + (S - R) * bg[c] / S for c in range(3)]
    return [A * acc[c] / acc[3] + T * bg[c] for c in range(3)]


def exact(layers, bg):
    c = list(bg)
    for a, rgb in layers:  # far to near: over
        c = [a * rgb[k] + (1 - a) * c[k] for k in range(3)]
    return c


def rms(layers, bg, mode, variant):
    e = exact(layers, bg)
    acc = [0.0, 0.0, 0.0]
    for p, sets in outcomes(layers, mode):
        v = pixel(layers, bg, sets, variant)
        for c in range(3):
            acc[c] += p * (v[c] - e[c]) ** 2
    return [sqrt(x) for x in acc]


EX1 = ([(0.45, (0, 1, 0)), (0.45, (1, 0, 0))], (0, 0, 1))  # green far, red near, over blue
EX2 = ([(0.25, (1, 1, 1))] * 4, (0.25, 0.25, 0.25))
ROWS = [("naive", "naive", "plain"), ("enderton", "stratified", "plain"), ("enderton+ac", "stratified", "ac"),
        ("enderton+depth", "stratified", "depth"), ("enderton+depth+ac", "stratified", "depthac")]

if __name__ == "__main__":
    print("| method | Example 1 (R, G, B) | Example 2 |")
    print("|---|---|---|")
    for name, mode, variant in ROWS:
        e1 = rms(*EX1, mode, variant)
        e2 = rms(*EX2, mode, variant)
        print(f"| `{name}` | ({e1[0]:.4f}, {e1[1]:.4f}, {e1[2]:.4f}) | {e2[0]:.4f} |")

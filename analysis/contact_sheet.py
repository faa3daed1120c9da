#!/usr/bin/python3
"""Puts images side by side with their file names as captions.

usage: contact_sheet.py OUT.png IMAGE.png [IMAGE.png ...]
Runs on /usr/bin/python3 with Debian's python3-matplotlib.
"""
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402


def main(argv):
    if len(argv) < 3:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    out, paths = argv[1], argv[2:]
    fig, axes = plt.subplots(1, len(paths), figsize=(3.2 * len(paths), 3.6), dpi=110)
    if len(paths) == 1:
        axes = [axes]
    for ax, p in zip(axes, paths):
        ax.imshow(mpimg.imread(p), interpolation="nearest")
        ax.set_title(os.path.splitext(os.path.basename(p))[0], fontsize=9)
        ax.axis("off")
    fig.tight_layout()
    tmp = out + ".tmp.png"
    fig.savefig(tmp)
    os.replace(tmp, out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

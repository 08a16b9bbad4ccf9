"""Measure a screenshot (PNG) of the HTML report: how much of it is not white, how many
colours it has, and how many pixels carry each of the plots' line colours (cli/src/plot.rs
PALETTE). Prints one JSON object."""
import json
import sys

import numpy as np
from PIL import Image

PALETTE = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189)]

img = np.asarray(Image.open(sys.argv[1]).convert("RGB")).astype(int)
h, w, _ = img.shape
px = img.reshape(-1, 3)
nonwhite = int((px.min(axis=1) < 235).sum())
colours = len(np.unique(px[:, 0] * 65536 + px[:, 1] * 256 + px[:, 2]))
hits = [int((np.abs(px - np.array(c)).max(axis=1) <= 12).sum()) for c in PALETTE]
print(json.dumps(dict(width=w, height=h, nonwhite_fraction=nonwhite / (w * h),
                      colours=colours, palette_pixels=hits)))

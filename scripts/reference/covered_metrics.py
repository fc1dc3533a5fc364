"""One table row from two RGBA renders of a view and `meshtracer compare --json` on them.

    covered_metrics.py REFERENCE.png OURS.png COMPARE.json NAME

Covered FLIP is compare's mean FLIP over the pixels either image covers (alpha > 0): pixels
neither covers are black in both and add no error, so it is flip x pixels / covered pixels. The
luminance ratio is ours / reference of the mean linear Rec. 709 luminance over those pixels.
"""
import json
import sys

import numpy
from PIL import Image


def linear(srgb):
    c = srgb / 255.0
    return numpy.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def main(reference, ours, compare, name):
    a = numpy.asarray(Image.open(reference).convert("RGBA"), dtype=numpy.float64)
    b = numpy.asarray(Image.open(ours).convert("RGBA"), dtype=numpy.float64)
    with open(compare) as f:
        metrics = json.load(f)
    covered = (a[..., 3] > 0) | (b[..., 3] > 0)
    n = int(covered.sum())
    if n == 0:
        print(f"| {name} | nothing covered | | |")
        return
    flip = metrics["flip"] * covered.size / n
    weights = numpy.array([0.2126, 0.7152, 0.0722])
    # Premultiplied by alpha, as compare composites over black.
    lum_a = (linear(a[..., :3]) @ weights * a[..., 3] / 255.0)[covered].mean()
    lum_b = (linear(b[..., :3]) @ weights * b[..., 3] / 255.0)[covered].mean()
    ratio = lum_b / lum_a if lum_a > 0 else float("inf")
    print(f"| {name} | {flip:.4f} | {metrics['coverage_iou']:.4f} | {ratio:.3f} |")


if __name__ == "__main__":
    main(*sys.argv[1:5])

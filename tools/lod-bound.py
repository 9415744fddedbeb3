#!/usr/bin/env python3
"""How true can a LOD image at p pixels of error be? Bounds from the true picture itself.

Renders the view at full detail at 4x the resolution (16 rays per pixel on a 4x4 grid: the
true picture), then measures, like `oocfmt curve` (RMSE over sRGB channels on the model's
pixels), what perfect pre-filtering would give:

- the truth blurred by a p-pixel box centred on each pixel (a filter that follows the pixel);
- the truth averaged over grid-aligned p-pixel blocks, each block shown flat (what records of
  p pixels that are exact footprint means give, sampled once per pixel);

and renders the real images (full detail at 1 ray per pixel; each --poe with translucent LOD
entries, the default, and with --opaque-lod) to set them beside the bounds, split into the
pixels the model covers fully (interior) and those it covers partly (silhouettes), with the
share of the squared error each holds. --crops X,Y,W,H writes error maps of that region (red too bright, blue too dark, 4x gain).

    cargo build --release -p oocfmt-cli
    python3 -m venv target/lod-venv && target/lod-venv/bin/pip install numpy pillow
    target/lod-venv/bin/python tools/lod-bound.py MODEL.oocf --poe 1,2,4
"""

import argparse
import os
import sys

try:
    import numpy as np
    from PIL import Image
except ImportError:
    sys.exit("needs numpy and Pillow: see the usage in this script's docstring")

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import benchlib  # noqa: E402

S = 4  # supersampling per axis of the true picture
LUMA = np.array([0.2126, 0.7152, 0.0722])


def linear(c):
    c = c / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def srgb(lin):
    lin = np.clip(lin, 0.0, 1.0)
    return 255.0 * np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)


def render(model, work, name, size, args):
    path = os.path.join(work, name + ".png")
    benchlib.run(["render", model, "--size", size, "-o", path, "--cache", "blocking"] + args)
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)


def centred_box(img, width, h, w):
    """Mean of `img` (S times the resolution) over a `width`-pixel box centred on each pixel."""
    k = int(round(width * S))
    pad = k
    spec = ((pad, pad), (pad, pad)) + ((0, 0),) * (img.ndim - 2)
    c = np.cumsum(np.cumsum(np.pad(img, spec, mode="edge"), axis=0), axis=1)
    c = np.pad(c, ((1, 0), (1, 0)) + ((0, 0),) * (img.ndim - 2))
    ys = (np.arange(h) * S + S / 2 - k / 2 + pad).astype(int)
    xs = (np.arange(w) * S + S / 2 - k / 2 + pad).astype(int)
    y0, x0 = np.meshgrid(ys, xs, indexing="ij")
    return (c[y0 + k, x0 + k] - c[y0, x0 + k] - c[y0 + k, x0] + c[y0, x0]) / (k * k)


def aligned_blocks(img, b, h, w):
    """`img` averaged over grid-aligned b-pixel blocks, each block's mean repeated over it."""
    hb, wb = h // b * b, w // b * b
    lo = img[: hb * S, : wb * S].reshape(hb // b, b * S, wb // b, b * S, -1).mean(axis=(1, 3))
    up = np.repeat(np.repeat(lo, b, axis=0), b, axis=1)
    out = img.reshape(h, S, w, S, -1).mean(axis=(1, 3))
    out[:hb, :wb] = up
    return out


class Truth:
    def __init__(self, hi, h, w):
        self.h, self.w = h, w
        self.hi = linear(hi)
        hit = np.any(np.abs(self.hi - self.hi[0, 0]) > 1e-6, axis=2).astype(np.float64)
        self.hit = hit
        self.coverage = hit.reshape(h, S, w, S).mean(axis=(1, 3))
        self.ref = srgb(self.hi.reshape(h, S, w, S, 3).mean(axis=(1, 3)))

    def figures(self, img, region):
        """RMSE, bias and the interior/silhouette split of `img` on `region`."""
        se = ((img - self.ref) ** 2).mean(axis=2)
        interior = region & (self.coverage == 1.0)
        edge = region & ~interior
        total = max(se[region].sum(), 1e-12)
        return {
            "rmse": float(np.sqrt(se[region].mean())),
            "bias": float(((img - self.ref) @ LUMA)[region].mean()),
            "interior_rmse": float(np.sqrt(se[interior].mean())) if interior.any() else 0.0,
            "interior_share": float(se[interior].sum() / total),
            "edge_rmse": float(np.sqrt(se[edge].mean())) if edge.any() else 0.0,
            "interior_px": float(interior.sum() / max(region.sum(), 1)),
        }


def error_map(img, ref, box, path):
    x, y, w, h = box
    diff = (img - ref).mean(axis=2)[y : y + h, x : x + w]
    tile = np.zeros((h, w, 3))
    tile[..., 0] = np.clip(4 * diff, 0, 255)
    tile[..., 2] = np.clip(-4 * diff, 0, 255)
    Image.fromarray(tile.astype(np.uint8)).resize((3 * w, 3 * h), Image.NEAREST).save(path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--size", default="1024x768")
    ap.add_argument("--poe", default="1,2,4")
    ap.add_argument("--widths", default="1.5,2,3,4", help="pixel widths of the ideal filters")
    ap.add_argument("--view", default="", help="extra render arguments, e.g. '--eye X,Y,Z'")
    ap.add_argument("--work", default=os.path.join(benchlib.ROOT, "target", "lod-bound"))
    ap.add_argument("--crops", default="", help="X,Y,W,H: write error maps of this region")
    a = ap.parse_args()
    benchlib.require_binary()
    os.makedirs(a.work, exist_ok=True)
    w, h = (int(v) for v in a.size.split("x"))
    view = a.view.split()
    truth = Truth(render(a.model, a.work, "truth", f"{w * S}x{h * S}", view + ["--poe", "0"]), h, w)
    model_px = truth.coverage > 0
    print(f"# {a.model} at {a.size}; {benchlib.machine()}")
    print("| image | RMSE | bias | interior px | interior RMSE | share of SE | silhouette RMSE |")
    print("|---|--:|--:|--:|--:|--:|--:|")

    def row(name, img, region):
        f = truth.figures(img, region)
        print(
            f"| {name} | {f['rmse']:.2f} | {f['bias']:+.2f} | {100 * f['interior_px']:.1f} % | "
            f"{f['interior_rmse']:.2f} | {100 * f['interior_share']:.1f} % | {f['edge_rmse']:.2f} |"
        )

    for width in (float(v) for v in a.widths.split(",")):
        img = srgb(centred_box(truth.hi, width, h, w))
        row(f"truth, {width:g}-px box per pixel", img, model_px | (centred_box(truth.hit, width, h, w) > 0))
    for width in (int(float(v)) for v in a.widths.split(",") if float(v).is_integer()):
        img = srgb(aligned_blocks(truth.hi, width, h, w))
        hit_b = aligned_blocks(truth.hit[..., None], width, h, w)[..., 0] > 0
        row(f"truth, flat {width}-px blocks", img, model_px | hit_b)
    series = [("full detail, 1 ray/pixel (the floor)", ["--poe", "0"])]
    for p in a.poe.split(","):
        series += [(f"PoE {p}", ["--poe", p]), (f"PoE {p} --opaque-lod", ["--poe", p, "--opaque-lod"])]
    for name, args in series:
        stem = name.split(",")[0].replace(" ", "-").replace("--", "")
        img = render(a.model, a.work, stem, a.size, view + args)
        region = model_px | np.any(np.abs(img - img[0, 0]) > 0.5, axis=2)
        row(name, img, region)
        if a.crops:
            box = [int(v) for v in a.crops.split(",")]
            error_map(img, truth.ref, box, os.path.join(a.work, f"error-{stem}.png"))


if __name__ == "__main__":
    main()

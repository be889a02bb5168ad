"""How far `vplace.ssim_noise_free` reads from the SSIM against the noise-free truth, measured
where that truth is known: a clean image, two synthetic "renders" of it carrying a real truth's
noise, and images scored both ways.

The noise is the real thing: the difference of a view's two truth renders (seeds 7919 and 7927,
the report's), divided by sqrt 2, is one render's noise with its per-pixel spread and its heavy
tails. Each synthetic render is the clean image plus that noise with a random sign per pixel
(independent between the two renders), scaled by 0.5, 1 and 2 (the noise of 4x, 1x and 1/4 the
samples). The clean image is the mean of the two renders blurred by a Gaussian of 1.2 px, a
stand-in with the view's flat surfaces and edges (the estimator's error depends on how much of
the view is flat, not on the exact image).

Run from the repository root (it renders the two truths once, cached in OUT/cache):

    .venv/bin/python docs/noise_free/simulate.py --scene skyroom --samples 512 --out /tmp/nf

It prints, per view and noise scale, the two synthetic renders' SSIM against each other and, for
each image, its exact SSIM against the clean image and what the estimator reads (its error).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import bpy

from addon.capture import passes as capture
from addon.job import OTHER_REFERENCE_SEED
from addon.native import vplace
from addon.report.config import PRESETS, TRUTH_SEED
from addon.scenes import registry


def blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """A separable Gaussian blur of an (H, W, 3) image, edges extended."""
    r = int(3.5 * sigma + 0.5)
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    out = np.pad(img.astype(np.float64), ((r, r), (r, r), (0, 0)), mode="edge")
    out = sum(k[i] * out[i : i + img.shape[0]] for i in range(2 * r + 1))
    out = sum(k[i] * out[:, i : i + img.shape[1]] for i in range(2 * r + 1))
    return out.astype(np.float32)


def images(clean: np.ndarray) -> dict[str, np.ndarray]:
    """The clean image and three kinds of error an estimate can make."""
    h, w = clean.shape[:2]
    _, xx = np.mgrid[0:h, 0:w]
    gain = 1.0 + 0.1 * np.sin(2 * np.pi * xx / w * 3)[..., None]
    return {
        "clean": clean,
        "blurred (sigma 2 px)": blur(clean, 2.0),
        "low-frequency gain (10 %)": (clean * gain).astype(np.float32),
        "dimmed 5 %": (clean * 0.95).astype(np.float32),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="skyroom")
    ap.add_argument("--samples", type=int, default=512)
    ap.add_argument("--resolution", type=int, nargs=2, default=(192, 108))
    ap.add_argument("--draws", type=int, default=3)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    preset = PRESETS[args.scene]
    registry.open_blend(registry.builtin_scene(args.scene))
    scene = bpy.context.scene
    rng = np.random.default_rng(0)
    for name in (*preset.fit_views, *preset.held_out_views):
        cam = bpy.data.objects[name]
        a, b = (
            capture.capture(
                scene,
                camera=cam,
                resolution=tuple(args.resolution),
                samples=args.samples,
                seed=seed,
                cache_dir=args.out / "cache",
            ).gi
            for seed in (TRUTH_SEED, OTHER_REFERENCE_SEED)
        )
        clean = blur((a + b) / 2, 1.2)
        noise = (a - b) / np.sqrt(2)
        print(f"{name}: the two renders agree at SSIM {vplace.ssim(a, b):.3f}")
        for scale in (0.5, 1.0, 2.0):
            agree, rows = [], {k: [] for k in images(clean)}
            for _ in range(args.draws):
                s1, s2 = (rng.choice([-1.0, 1.0], size=noise.shape[:2])[..., None] for _ in "ab")
                ra = (clean + scale * s1 * noise).astype(np.float32)
                rb = (clean + scale * s2 * noise).astype(np.float32)
                agree.append(vplace.ssim(ra, rb))
                for k, x in images(clean).items():
                    rows[k].append((vplace.ssim(x, clean), vplace.ssim_noise_free(x, ra, rb)))
            print(f"  noise x{scale}: synthetic renders agree at {np.mean(agree):.3f}")
            for k, r in rows.items():
                r = np.array(r)
                exact, est = r[:, 0].mean(), r[:, 1].mean()
                print(
                    f"    {k:28s} exact {exact:.4f}  estimated {est:.4f}  error {est - exact:+.4f}"
                )


if __name__ == "__main__":
    main()

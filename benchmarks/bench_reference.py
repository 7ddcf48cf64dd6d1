"""daskrad against an independent path-traced reference of the Cornell box.

The reference (:func:`daskrad.reference.path_trace`, 2,048 paths per pixel at 128×128) is cached
in ``benchmarks/results/cornell_reference_128.exr``; its own noise is printed so the errors
below can be read against it. Each daskrad configuration is timed end to end (in-process) and
compared pixel by pixel: relative RMS error (RMS of the difference over the RMS of the
reference), and the relative error of the mean radiance per channel (a unit or energy error
shows up there first).
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import time
from pathlib import Path

import numpy as np

from daskrad.io import read_exr, write_exr, write_png
from daskrad.reference import path_trace
from daskrad.run import run
from daskrad.scene import load_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
SCENE = Path(__file__).parent.parent / "scenes" / "cornell_box.obj"
SIZE = 128
SPP = 2048


def cached_path_trace(scene_path: Path, stem: str, spp: int = SPP, size: int = SIZE
                      ) -> tuple[np.ndarray, float]:
    """The path-traced image of ``scene_path`` through its camera at ``size``², ``spp`` paths
    per pixel, cached as ``results/<stem>_<size>.exr`` with its first half
    (``..._half.exr``), and its relative RMS noise estimated from the two halves."""
    path = RESULTS / f"{stem}_{size}.exr"
    half_path = RESULTS / f"{stem}_{size}_half.exr"
    if not path.exists() or not half_path.exists():
        scene = load_scene(scene_path)
        cam = dataclasses.replace(scene.camera, width=size, height=size)
        a = path_trace(scene, cam, spp=spp // 2, seed=1)
        b = path_trace(scene, cam, spp=spp // 2, seed=100_003)
        RESULTS.mkdir(exist_ok=True)
        write_exr(path, 0.5 * (a + b))
        write_exr(half_path, a)
        write_png(path.with_suffix(".png"), 0.5 * (a + b))
    ref = read_exr(path).astype(np.float64)
    half = read_exr(half_path).astype(np.float64)
    # var(half) = 2 var(full); the halves differ from the full image by ± its noise
    noise = np.sqrt(np.mean((half - ref) ** 2)) / np.sqrt(np.mean(ref**2))
    return ref, float(noise)


def reference() -> tuple[np.ndarray, float]:
    """The cached reference image and its estimated relative RMS noise (from two halves)."""
    return cached_path_trace(SCENE, "cornell_reference")


def errors(img: np.ndarray, ref: np.ndarray) -> dict:
    """Relative RMS over all pixels and over the pixels off the light (both images below 1.5
    in every channel: the light's radiance is 17, the walls' below 1), whose outline pixels
    differ by the two renderers' pixel sampling alone (a fixed grid against random jitter)
    and swamp the rest; and the relative error of the mean radiance per channel."""
    def rel_rms(mask):
        d, r = (img - ref)[mask], ref[mask]
        return float(np.sqrt(np.mean(d**2)) / np.sqrt(np.mean(r**2)))

    off_light = (img.max(axis=2) < 1.5) & (ref.max(axis=2) < 1.5)
    mean_err = (img.reshape(-1, 3).mean(0) / ref.reshape(-1, 3).mean(0) - 1.0).tolist()
    return {"relative_rms": rel_rms(np.ones(img.shape[:2], bool)),
            "relative_rms_off_light": rel_rms(off_light),
            "mean_relative_error_rgb": mean_err}


CONFIGS = {
    "default": {},
    "coarse elements (60)": {"element_size": 60.0},
    "fine elements (15)": {"element_size": 15.0},
    "finer elements (10)": {"element_size": 10.0, "patch_size": 60.0},
}


def main() -> dict:
    ref, noise = reference()
    rows = []
    out = RESULTS / "bench_reference_tmp.exr"
    for name, opts in CONFIGS.items():
        settings = Settings(width=SIZE, height=SIZE, **opts)
        t = time.perf_counter()
        report = run(SCENE, out, settings, progress=False)
        seconds = time.perf_counter() - t
        img = read_exr(out).astype(np.float64)
        rows.append({"config": name, "elements": report["counts"]["elements"],
                     "shots": report["iterations"], "seconds": seconds, **errors(img, ref)})
    for suffix in (".exr", ".png", ".json"):
        out.with_suffix(suffix).unlink(missing_ok=True)
    shutil.rmtree(out.with_suffix(".zarr"), ignore_errors=True)
    print(f"reference: {SPP} paths/pixel at {SIZE}x{SIZE}, relative RMS noise {noise:.4f}")
    print(f"{'config':<22}{'elements':>9}{'shots':>7}{'seconds':>9}{'rel RMS':>9}"
          f"{'off light':>10}{'mean err R/G/B':>24}")
    for r in rows:
        m = r["mean_relative_error_rgb"]
        print(f"{r['config']:<22}{r['elements']:>9}{r['shots']:>7}{r['seconds']:>9.2f}"
              f"{r['relative_rms']:>9.4f}{r['relative_rms_off_light']:>10.4f}"
              f"   {m[0]:+.3f} {m[1]:+.3f} {m[2]:+.3f}")
    result = {"reference": {"spp": SPP, "size": SIZE, "relative_rms_noise": noise},
              "configs": rows}
    (RESULTS / "reference.json").write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()

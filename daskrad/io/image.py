"""OpenEXR and PNG output.

Writes go to a temporary file in the same directory and are renamed into place, so an
interrupted run never leaves a half-written image that looks like a result.
"""

from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path

import numpy as np

#: What daskrad writes into an image's metadata (the EXR header's ``software`` attribute, the
#: PNG's ``Software`` text): an existing file is replaced only when it carries it.
SOFTWARE = "daskrad"


def written_by_daskrad(path: str | Path) -> bool:
    """Whether the file at ``path`` (.exr, .png or a run report .json) says daskrad wrote it."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".exr":
            import OpenEXR

            with OpenEXR.File(str(path), header_only=True) as f:
                return str(f.header().get("software", "")).startswith(SOFTWARE)
        if suffix == ".png":
            from PIL import Image

            with Image.open(path) as im:
                return str(im.info.get("Software", "")).startswith(SOFTWARE)
        if suffix == ".json":
            import json

            report = json.loads(path.read_text())
            return isinstance(report, dict) and SOFTWARE in report.get("versions", {})
    except Exception:          # unreadable, truncated, not the format at all: not ours
        return False
    return False


def _atomic_target(path: Path) -> Path:
    return path.with_name(f".{path.name}.partial{path.suffix}")


@contextlib.contextmanager
def _removed_on_failure(tmp: Path):
    """Remove the temporary file if the write fails (disk full): nothing half-written stays."""
    try:
        yield
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_exr(path: str | Path, rgb: np.ndarray) -> None:
    """Write linear radiance ``rgb : (H, W, 3)`` as a float32 scanline OpenEXR with ZIP compression.

    docs/stack.md: OpenEXR writes a non-C-contiguous array as garbage, silently, and refuses
    float64; hence the explicit contiguous float32 copy.
    """
    import OpenEXR

    path = Path(path)
    pixels = np.ascontiguousarray(rgb, dtype=np.float32)
    if pixels.ndim != 3 or pixels.shape[2] != 3:
        raise ValueError(f"rgb must be (H, W, 3), got {pixels.shape}")
    tmp = _atomic_target(path)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
              "software": SOFTWARE}
    with _removed_on_failure(tmp):
        try:
            OpenEXR.File(header, {"RGB": pixels}).write(str(tmp))
        except RuntimeError as err:       # OpenEXR reports a failed write (disk full) so
            raise OSError(errno.EIO, f"cannot write the image: {err}", str(path)) from err
        os.replace(tmp, path)


def read_exr(path: str | Path) -> np.ndarray:
    """``(H, W, 3) float32`` linear RGB from an OpenEXR file written by :func:`write_exr`."""
    import OpenEXR

    with OpenEXR.File(str(path)) as f:
        return np.array(f.channels()["RGB"].pixels, dtype=np.float32)


def display(rgb: np.ndarray, exposure: float | None = None, stops: float = 0.0) -> np.ndarray:
    """Linear radiance ``(..., 3)`` → linear display values in ``[0, 1]``, same shape.

    Exposure (a factor) is chosen, unless given, so the 99th percentile of luminance maps to
    0.9 (emitters, which are far brighter than anything they light, then saturate instead of
    darkening the image), times ``2 ** stops``; then a Reinhard-style shoulder.
    """
    rgb = np.nan_to_num(np.asarray(rgb, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    rgb = np.maximum(rgb, 0.0)
    if exposure is None:
        lum = rgb.reshape(-1, 3) @ np.array([0.2126, 0.7152, 0.0722])
        ref = np.percentile(lum, 99.0) if lum.size else 0.0
        exposure = 0.9 / ref if ref > 0 else 1.0
    x = rgb * (exposure * 2.0 ** float(stops))
    x = x / (1.0 + x / 4.0) * 1.25  # soft shoulder; 1 → 1.0, keeps mid-tones linear-ish
    return np.clip(x, 0.0, 1.0)


def srgb8(x: np.ndarray) -> np.ndarray:
    """Linear display values in ``[0, 1]`` → 8-bit sRGB (the sRGB transfer curve)."""
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(srgb * 255.0).astype(np.uint8)


def tonemap(rgb: np.ndarray, exposure: float | None = None, stops: float = 0.0) -> np.ndarray:
    """Linear radiance → 8-bit sRGB for the preview (:func:`display`, then :func:`srgb8`).
    Returns ``(H, W, 3) uint8``."""
    return srgb8(display(rgb, exposure, stops))


def write_png(path: str | Path, rgb: np.ndarray, exposure: float | None = None,
              stops: float = 0.0) -> None:
    """Tone-mapped sRGB preview of linear ``rgb : (H, W, 3)``; ``stops`` brightens (> 0) or
    darkens the automatic (or given) exposure by powers of two (``--exposure``)."""
    from PIL import Image, PngImagePlugin

    path = Path(path)
    tmp = _atomic_target(path)
    info = PngImagePlugin.PngInfo()
    info.add_text("Software", SOFTWARE)
    with _removed_on_failure(tmp):
        Image.fromarray(tonemap(rgb, exposure, stops), mode="RGB").save(tmp, format="PNG",
                                                                        pnginfo=info)
        os.replace(tmp, path)

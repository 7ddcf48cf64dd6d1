"""Run settings: every option of ``daskrad run`` with its default (DESIGN §7).

``None`` means "derived from the scene" (sizes follow the scene's scale).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace


@dataclass(frozen=True)
class Settings:
    method: str = "hemisphere"          # form-factor method, a key of formfactor.METHODS
    resolution: int = 256               # item-buffer side R (hemisphere) / face side (hemicube)
    edge_angle: float = 1.0             # degrees a projected edge piece may subtend (eq. 4)
    patch_size: float | None = None     # max patch edge length, scene units
    element_size: float | None = None   # max element edge length, scene units
    tolerance: float = 1e-3             # stop when RMS unshot / initial RMS unshot < tolerance
    max_iterations: int = 5000
    batch: int = 8                      # K shooters per form-factor task
    spp: int = 4                        # stratified samples per pixel
    workers: int = 0                    # 0: in-process, no cluster
    scheduler: str | None = None        # tcp://host:port of an existing cluster
    width: int | None = None            # image size; None: the camera's
    height: int | None = None
    seed: int = 0

    def replace(self, **changes) -> Settings:
        return replace(self, **changes)

    def as_dict(self) -> dict:
        return asdict(self)

"""Run settings: every option of ``daskrad run`` with its default (DESIGN §7).

``None`` means "derived from the scene" (sizes follow the scene's scale).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace


@dataclass(frozen=True)
class Settings:
    method: str = "hemisphere"          # form-factor method, a key of formfactor.METHODS
    # item-buffer side R (hemisphere) / face side (hemicube). 200: the smallest R at which the
    # default method is within 0.2 % on every configuration of bench_methods (issue 6 item 2)
    # and 0.15 % on the Cornell rows; R = 100 saves ~27 % of a shot for 0.7 % / 0.4 %.
    resolution: int = 200
    edge_angle: float | None = None     # degrees per projected edge piece (eq. 4); None: auto
                                        # (quarter-pixel sagitta, formfactor.auto_edge_angle)
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
    checkpoint_every: int = 8           # batches between checkpoints into OUT.zarr
    dashboard: str = "127.0.0.1:8787"   # --workers N: dashboard bind address (loopback only)
    connect_timeout: float = 30.0       # --scheduler: seconds to reach it and see a worker
    # two-pass lighting (issue 5): direct light at vertices, adaptive subdivision, per pixel
    two_pass: bool = True               # area lights gathered at vertices, not shot
    area_samples: int = 4               # shadow rays per area light: area_samples²
    area_method: str = "hemisphere"     # area lights: a key of direct.AREA_METHODS
    #                                     (bench_arealight: 1/16 of the rays' error, same time)
    subdivide: float = 0.5              # relative spread of ρH splitting an element; 0: off
    min_element_size: float | None = None  # None: element size / 4 (two levels)
    per_pixel: bool = True              # the per-pixel pass (eq. 9) on elements over rdiff
    rdiff: float = 0.1                  # eq. 9 threshold, in units of the scene's white level
    #                                     (bench_twopass: 0.1 is within 1 % of the best error)
    mirror_depth: int = 4               # mirror bounces per pixel ray

    def replace(self, **changes) -> Settings:
        return replace(self, **changes)

    def as_dict(self) -> dict:
        return asdict(self)

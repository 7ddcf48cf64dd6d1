"""Run settings: every option of ``daskrad run`` with its default, stated once (docs/design.md §7).

``None`` means "derived from the scene" (sizes follow the scene's scale). :meth:`Settings.
validate` checks every value against its range and the method registries before a run loads
or writes anything.
"""

from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass, replace

#: Largest item-buffer side: an R × R buffer of int32 ids and float64 depths per shooter
#: point is 12 R² bytes (4096: 200 MB), and a shot's time grows as R².
MAX_RESOLUTION = 4096
#: Largest image side (the sample seeds assume fewer than 2¹⁶ columns and rows) and area:
#: the float64 image is 24 bytes per pixel (2²⁶ pixels: 1.5 GiB).
MAX_IMAGE_SIDE = 1 << 16
MAX_IMAGE_PIXELS = 1 << 26
#: Samples per pixel at most (the seeds leave 2¹⁰ per pixel, :data:`daskrad.render.SEED_STRIDE`).
MAX_SPP = 1024
#: ``max_iterations`` None: shots per patch of the scene, and at least :data:`MIN_SHOTS`. A
#: converging solve shoots each patch about once or twice in a furnished room (measured to the
#: default tolerance: RenderPark's office3 1.09 shots a patch, the classroom 1.76, graz 1.95)
#: and up to five times in a small room (the Cornell box: 1,560 shots, 309 patches), six in
#: the round room of ``scenes/quadrics.toml`` (9,885 shots, 1,688 patches: at 4 a patch it
#: stopped at 6,752 shots, 5.7e-3, and its solve took 4.9 s against 5.3 s converged, re-shots
#: coming from the row cache); a fixed cap left every interior of more than a few thousand
#: patches unconverged. 8 leaves room above them all.
SHOTS_PER_PATCH = 8
MIN_SHOTS = 5000
_ADDRESS = re.compile(r"^(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]*):(\d{1,5})$")


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
    max_iterations: int | None = None   # shots at most; None: SHOTS_PER_PATCH a patch, at
    #                                     least MIN_SHOTS (with_patches)
    batch: int = 8                      # K shooters per form-factor task
    sample_share: float = 0.03          # a shooter with less than this share of the
    #                                     brightest patch's power shoots from one point, not
    #                                     its penumbra samples (0: never; solve.SAMPLE_SHARE)
    relaxation: float = 1.3             # overshooting factor ω of a shot (1: plain
    #                                     progressive refinement; solve.RELAXATION)
    spp: int = 4                        # stratified samples per pixel
    edge_spp: int = 64                  # samples of a pixel whose spp samples differ (an
    #                                     edge, render.EDGE_STEP); <= spp: never
    workers: int = 0                    # 0: in-process, no cluster
    processes: bool = False             # --workers N: worker processes, not threads of this one
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
    exposure: float = 0.0               # PNG brightness, stops over the automatic exposure

    def replace(self, **changes) -> Settings:
        return replace(self, **changes)

    def with_patches(self, n_patches: int) -> Settings:
        """These settings with ``max_iterations`` resolved for a scene of ``n_patches``
        patches (None: ``max(MIN_SHOTS, SHOTS_PER_PATCH × n_patches)``)."""
        if self.max_iterations is not None:
            return self
        return replace(self, max_iterations=max(MIN_SHOTS, SHOTS_PER_PATCH * int(n_patches)))

    def as_dict(self) -> dict:
        return asdict(self)

    def validate(self) -> Settings:
        """``self`` if every value is in range and every name is registered, else
        :class:`~daskrad.errors.OptionError` naming the option (one line)."""
        from daskrad.direct import check_area_method
        from daskrad.errors import OptionError
        from daskrad.formfactor import get_method

        def bad(name: str, why: str):
            raise OptionError(f"--{name.replace('_', '-')} {why}, got {getattr(self, name)!r}")

        def integer(name: str, low: int, high: float = math.inf) -> None:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= high:
                bad(name, f"must be an integer in [{low}, {high:g}]")

        def positive(name: str, optional: bool = False, zero: bool = False) -> None:
            v = getattr(self, name)
            if v is None and optional:
                return
            if (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                    or not (v >= 0 if zero else v > 0)):
                bad(name, "must be a finite number " + (">= 0" if zero else "> 0"))

        get_method(self.method)                 # the registries say what they hold
        check_area_method(self.area_method)
        integer("resolution", 2, MAX_RESOLUTION)
        if self.edge_angle is not None:
            positive("edge_angle")
            if self.edge_angle > 90:
                bad("edge_angle", "must be in (0, 90] degrees")
        for name in ("patch_size", "element_size", "min_element_size"):
            positive(name, optional=True)
        positive("tolerance", zero=True)       # 0: shoot max_iterations times
        if self.tolerance >= 1.0:               # the relative unshot RMS starts at 1
            bad("tolerance", "must be in [0, 1) (the relative unshot RMS starts at 1: a run "
                "would stop before its first shot)")
        if self.max_iterations is not None:      # None: from the patch count
            integer("max_iterations", 0)
        integer("batch", 1, 1 << 16)
        positive("sample_share", zero=True)
        positive("relaxation")
        if not 1.0 <= self.relaxation < 2.0:
            bad("relaxation", "must be in [1, 2)")
        integer("spp", 1, MAX_SPP)
        integer("edge_spp", 0, MAX_SPP)
        if self.workers is not None:      # None: chosen from the scene's size
            integer("workers", 0, 1 << 12)
        for name in ("width", "height"):
            if getattr(self, name) is not None:
                integer(name, 1, MAX_IMAGE_SIDE)
        if self.width and self.height and self.width * self.height > MAX_IMAGE_PIXELS:
            raise OptionError(f"--width {self.width} --height {self.height}: the image would "
                              f"have more than {MAX_IMAGE_PIXELS} pixels")
        integer("seed", 0)
        integer("checkpoint_every", 1)
        address = _ADDRESS.match(str(self.dashboard))
        if not address or not 0 <= int(address.group(1)) <= 65535:
            bad("dashboard", "must be HOST:PORT (port 0-65535)")
        if self.scheduler is not None and not re.match(r"^[a-z]+://\S+:\d{1,5}$",
                                                       str(self.scheduler)):
            bad("scheduler", "must be an address like tcp://HOST:PORT")
        positive("connect_timeout")
        if not isinstance(self.processes, bool):
            bad("processes", "must be true or false")
        if self.processes and self.scheduler is not None:
            raise OptionError("--processes is for --workers N (a LocalCluster daskrad starts); "
                              "with --scheduler the cluster's own workers run the tasks")
        if self.processes and not self.workers:
            raise OptionError("--processes is for a LocalCluster: give --workers N (N > 0)")
        integer("area_samples", 1, 64)
        positive("subdivide", zero=True)
        positive("rdiff", zero=True)
        integer("mirror_depth", 0, 64)
        if (isinstance(self.exposure, bool) or not isinstance(self.exposure, (int, float))
                or not math.isfinite(self.exposure)):
            bad("exposure", "must be a finite number of stops")
        return self

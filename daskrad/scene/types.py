"""The scene as plain arrays (docs/design.md §3, §6).

A :class:`Scene` is what step 1 reads from disk, before any meshing: input polygons (triangles
and planar convex quads), one material per polygon, the TOML's lights and camera. Units are the
file's own; radiometric quantities are per the file's unit of area (W/m² when the file is in
metres).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Materials:
    """The material table, one row per material.

    Attributes
    ----------
    names : tuple of str, length M
    diffuse : (M, 3) float64
        ``Kd``, diffuse reflectance per RGB channel, each in ``[0, 1)``.
    emission : (M, 3) float64
        ``Ke``, emitted **radiance** (W·m⁻²·sr⁻¹) of a one-sided Lambertian emitter along the
        face normal; exitance is ``π · Ke``.
    specular : (M, 3) float64
        ``Ks`` as written in the MTL; 0 when the file has none or ``illum`` is 0 or 1.
    shininess : (M,) float64
        ``Ns``, the Phong exponent.
    mirror : (M,) bool
        ``illum 3``: a mirror that reflects rays in the per-pixel pass.
    """

    names: tuple[str, ...]
    diffuse: np.ndarray
    emission: np.ndarray
    specular: np.ndarray
    shininess: np.ndarray
    mirror: np.ndarray

    def __len__(self) -> int:
        return len(self.names)


@dataclass(frozen=True)
class PointLights:
    """Isotropic point lights.

    ``position : (L, 3) float64``; ``intensity : (L, 3) float64``, W/sr per RGB channel.
    """

    position: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    intensity: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __len__(self) -> int:
        return len(self.position)


@dataclass(frozen=True)
class DirectionalLights:
    """Parallel lights.

    ``direction : (L, 3) float64``, unit vectors along which the light *travels* (a sun overhead
    has direction ``(0, -1, 0)`` in a y-up scene); ``irradiance : (L, 3) float64``, W/m² on a
    surface facing the light.
    """

    direction: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    irradiance: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __len__(self) -> int:
        return len(self.direction)


@dataclass(frozen=True)
class Camera:
    """A pinhole camera. ``fov`` is the horizontal field of view in degrees.

    Convention (docs/design.md §6): ``forward = normalize(look_at - eye)``, ``right = forward × up``
    (normalized), ``true_up = right × forward``; image x grows along ``right``, image row 0 is at
    the top. Seen from the front of the Cornell box the red wall (x ≈ 550) is on the left.
    """

    eye: np.ndarray
    look_at: np.ndarray
    up: np.ndarray
    fov: float
    width: int
    height: int


@dataclass(frozen=True)
class Scene:
    """One scene, as loaded and validated.

    Attributes
    ----------
    path : str
        The file it came from (for messages and the report).
    vertices : (V, 3) float64
        Finite coordinates.
    polygons : (Q, 4) int32
        Corner indices of each input polygon after triangulation of n-gons: planar convex quads
        keep four corners, triangles have ``-1`` in column 3. Corners wind counter-clockwise
        seen from the lit side (the normal ``(v1 - v0) × (v2 - v0)`` points to it).
    polygon_material : (Q,) int32
        Row of :attr:`materials` for each polygon.
    materials : Materials
    point_lights : PointLights
    directional_lights : DirectionalLights
    camera : Camera or None
        ``None`` when the TOML gives none; the renderer then frames the bounding box.
    dropped_degenerate : int
        Zero-area faces dropped while loading (reported in a warning).
    origin : (3,) float64
        Where the file's coordinates had the scene's centre: ``vertices``, point lights and the
        camera are relative to it (:func:`daskrad.scene.validate.centre_of`); 0 for a scene
        near the world's origin.
    back_material : (Q,) int32 or None
        The material of each polygon's back, ``-1`` for a one-sided polygon (light leaves and
        arrives on its normal's side only, the default). ``None``: every polygon one-sided.
    warnings : tuple of str
        One line per change made to the input while loading (zero-area and duplicated faces
        dropped, coplanar overlaps resolved), each naming the file; also issued as
        :class:`daskrad.errors.DaskradWarning`.
    """

    path: str
    vertices: np.ndarray
    polygons: np.ndarray
    polygon_material: np.ndarray
    materials: Materials
    point_lights: PointLights = field(default_factory=PointLights)
    directional_lights: DirectionalLights = field(default_factory=DirectionalLights)
    camera: Camera | None = None
    dropped_degenerate: int = 0
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    back_material: np.ndarray | None = None
    warnings: tuple[str, ...] = ()

    @property
    def two_sided(self) -> np.ndarray:
        """``(Q,) bool``: polygons that are lit and light on both sides."""
        if self.back_material is None:
            return np.zeros(len(self.polygons), bool)
        return self.back_material >= 0

    @property
    def bounds(self) -> np.ndarray:
        """``(2, 3) float64``: min and max corner of the bounding box of the used vertices."""
        used = self.polygons[self.polygons >= 0]
        v = self.vertices[np.unique(used)]
        return np.stack([v.min(axis=0), v.max(axis=0)])

    @property
    def diagonal(self) -> float:
        """Length of the bounding-box diagonal: the scene's scale for every relative tolerance."""
        b = self.bounds
        return float(np.linalg.norm(b[1] - b[0]))

    @property
    def emitting(self) -> np.ndarray:
        """``(Q,) bool``: polygons whose material emits."""
        return (self.materials.emission[self.polygon_material] > 0).any(axis=1)

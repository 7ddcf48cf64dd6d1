"""Step 1 of the pipeline, input: scene files and their TOML sidecar → :class:`Scene`."""

from daskrad.scene.builders import BOX_FACES, box_scene
from daskrad.scene.config import read_config
from daskrad.scene.load import SUFFIXES, load_scene
from daskrad.scene.types import Camera, DirectionalLights, Materials, PointLights, Scene
from daskrad.scene.validate import scene_from_arrays

__all__ = [
    "BOX_FACES",
    "SUFFIXES",
    "Camera",
    "DirectionalLights",
    "Materials",
    "PointLights",
    "Scene",
    "box_scene",
    "load_scene",
    "read_config",
    "scene_from_arrays",
]

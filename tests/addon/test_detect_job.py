"""The photos the detection jobs read (``detect_job.photo_images``): one view's or every
photo's, with one clear line for a missing view or no photo at all."""

import bpy
import numpy as np
import pytest
from PIL import Image

from tests.addon.support import empty_scene


def test_photo_images_names_what_is_missing(tmp_path):
    from headrecon_addon.detect_job import photo_images

    empty_scene()
    scene = bpy.context.scene
    with pytest.raises(ValueError, match="Load the photos first"):
        list(photo_images(scene, "", "detect the face on"))
    path = tmp_path / "front.png"
    Image.fromarray(np.full((64, 48, 3), 128, np.uint8)).save(path)
    assert bpy.ops.headrecon.load_photo(filepath=str(path), view="front",
                                        camera_view="orthographic-front") == {"FINISHED"}
    with pytest.raises(ValueError, match="No photo for view 'side'"):
        list(photo_images(scene, "side", "detect the face on"))
    for view in ("", "front"):
        (plane, name, img), = photo_images(scene, view, "detect the face on")
        assert name == "front" and plane.headrecon.view == "front"
        assert tuple(img.size) == (48, 64)

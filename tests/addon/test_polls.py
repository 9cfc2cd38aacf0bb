"""Operators that cannot run say why (bpy module, background)."""

import bpy
import pytest


def test_poll_messages(scene):
    # Operators that cannot run say why (poll_message_set); background ops raise with it.
    with pytest.raises(RuntimeError, match="Load a front and a profile photo"):
        bpy.ops.headrecon.fit()
    with pytest.raises(RuntimeError, match="no photos with landmarks"):
        bpy.ops.headrecon.export_landmarks(filepath="/tmp/never.json")

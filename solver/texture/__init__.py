"""The texture: per-vertex UVs into a photo, the model's UV tiles and the bake from all photos."""

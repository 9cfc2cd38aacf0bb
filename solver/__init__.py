"""HeadRecon's solver: pure numpy/scipy, never imports bpy.

Everything here takes and returns plain arrays (metres, Blender axes: Z up, the face
looks toward -Y, the subject's left is +X) so the Blender add-on, the command line and
the tests share one code path. Modules use relative imports only, so the package works
both as the top-level ``solver`` of a checkout and as ``<extension>.solver`` inside
Blender.
"""

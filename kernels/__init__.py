"""Pure NumPy kernels: arrays in, arrays out. Nothing here imports bpy, mathutils, bmesh,
`addon` or `operators` (tests/kernels/test_purity.py checks it with bpy made unimportable)."""

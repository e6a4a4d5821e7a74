"""Procedural images of the sample scenes, made with seeded NumPy (packed into the files)."""

from __future__ import annotations

import numpy as np


def checkerboard_image(width: int, height: int, square: int, light_rgb, dark_rgb) -> np.ndarray:
    """(H, W, 3) sRGB-encoded floor tiles: square size in pixels, the top-left square light."""
    rows, cols = np.indices((height, width)) // square
    light_tile = ((rows + cols) % 2 == 0)[..., None]
    return np.where(light_tile, np.asarray(light_rgb, float), np.asarray(dark_rgb, float))


def orange_peel_height(width: int = 256, height: int = 128, dimples: int = 500,
                       seed: int = 7) -> np.ndarray:
    """(H, W, 3) heights in [0, 1]: shallow round dimples (a Worley F1 pattern) that tile in u.

    The lat-long UV of a sphere stretches u by 2 (2pi around vs pi pole to pole), so distances
    are measured with u scaled by width/height to keep the dimples round on the sphere.
    """
    rng = np.random.default_rng(seed)
    centres = rng.random((dimples, 2)) * [width, height]  # pixels
    py, px = np.mgrid[0:height, 0:width] + 0.5
    nearest = np.full((height, width), np.inf)
    for cx, cy in centres:
        dx = np.abs(px - cx)
        dx = np.minimum(dx, width - dx)  # wrap around the seam in u
        nearest = np.minimum(nearest, dx * dx + (py - cy) ** 2)
    dist = np.sqrt(nearest)
    heights = np.sqrt(dist / dist.max())  # 0 at dimple centres, flat rims between them
    return np.repeat(heights[..., None], 3, axis=2)


def brick_images(size: int = 256, rows: int = 16, cols: int = 8, mortar: int = 1,
                 bevel: int = 3, seed: int = 11) -> tuple[np.ndarray, np.ndarray]:
    """A running-bond brick wall that tiles: (H, W, 3) heights in [0, 1] (mortar 0, brick
    faces 1, `bevel` px ramps at brick edges) and (H, W, 3) sRGB-encoded colours, one slightly
    varied colour per brick."""
    rng = np.random.default_rng(seed)
    brick_h, brick_w = size // rows, size // cols
    y, x = np.mgrid[0:size, 0:size]
    row = y // brick_h
    xs = (x + (row % 2) * (brick_w // 2)) % size  # odd rows offset by half a brick
    col = xs // brick_w
    # distance (px) from each pixel to the nearest mortar line, inside its brick
    edge = np.minimum.reduce([y % brick_h, brick_h - 1 - y % brick_h,
                              xs % brick_w, brick_w - 1 - xs % brick_w]).astype(float)
    heights = np.clip((edge - mortar + 1.0) / bevel, 0.0, 1.0)
    shade = rng.random((rows, cols))  # per-brick colour variation
    brick_rgb = np.array([0.62, 0.27, 0.18]) + (shade[row, col, None] - 0.5) * [0.16, 0.08, 0.06]
    mortar_rgb = np.array([0.72, 0.70, 0.66])
    colours = np.where((heights > 0.0)[..., None], brick_rgb, mortar_rgb)
    return np.repeat(heights[..., None], 3, axis=2), colours

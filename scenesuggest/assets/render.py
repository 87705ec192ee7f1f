"""Thumbnails rendered from the real geometry: flat-shaded triangles in a small z-buffer rasteriser
(numpy, 2× supersampled), so that building a library needs no GPU, no OpenGL and no browser.

The camera looks at the model's front from above and to its right (azimuth and elevation below), with an
orthographic projection fitted to the model's bounding box; light comes from over the viewer's shoulder.
Texture colours are sampled at each triangle's centroid, which is plenty at thumbnail size.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

#: The view: degrees round +Y from the model's front (+Z) towards +X, and above the horizon.
AZIMUTH_DEG = 35.0
ELEVATION_DEG = 25.0
SUPERSAMPLE = 2
#: Triangles up to these many pixels across are rasterised together in batches; larger ones one by one.
TIERS_PX = (4, 16, 48)
SAMPLES_PER_BATCH = 2_000_000
MARGIN = 1.08
AMBIENT = 0.35


def _image_colors(image, uv: np.ndarray) -> np.ndarray:
    rgb = np.asarray(image.convert("RGB"), dtype=float) / 255.0
    h, w = rgb.shape[:2]
    u = np.mod(uv[:, 0], 1.0)
    v = np.mod(uv[:, 1], 1.0)
    x = np.clip((u * w).astype(int), 0, w - 1)
    y = np.clip(((1.0 - v) * h).astype(int), 0, h - 1)
    return rgb[y, x]


def face_colors(mesh: trimesh.Trimesh) -> np.ndarray:
    """(F, 3) RGB in 0..1 for each face: texture at the centroid, else material or face colour."""
    n = len(mesh.faces)
    visual = mesh.visual
    if isinstance(visual, trimesh.visual.TextureVisuals):
        material = visual.material
        image = getattr(material, "image", None) or getattr(material, "baseColorTexture", None)
        if image is not None and visual.uv is not None and len(visual.uv) == len(mesh.vertices):
            base = _image_colors(image, visual.uv[mesh.faces].mean(axis=1))
            factor = getattr(material, "baseColorFactor", None)
            if factor is not None:
                base = base * np.asarray(factor[:3], dtype=float) / 255.0
            return base
        color = getattr(material, "baseColorFactor", None)
        if color is None:
            color = getattr(material, "diffuse", None)
        if color is None:
            color = (200, 200, 200, 255)
        return np.tile(np.asarray(color[:3], dtype=float) / 255.0, (n, 1))
    return np.asarray(visual.face_colors[:, :3], dtype=float) / 255.0


def _triangles(meshes: list[trimesh.Trimesh]) -> tuple[np.ndarray, np.ndarray]:
    """(T, 3, 3) world triangles and (T, 3) colours of all meshes."""
    if not meshes:
        return np.zeros((0, 3, 3)), np.zeros((0, 3))
    return (np.concatenate([m.vertices[m.faces] for m in meshes]),
            np.concatenate([face_colors(m) for m in meshes]))


def _camera() -> tuple[np.ndarray, np.ndarray]:
    """(3×3 world→view rotation, unit vector from the model towards the camera) for the thumbnail view."""
    az, el = math.radians(AZIMUTH_DEG), math.radians(ELEVATION_DEG)
    eye = np.array([math.sin(az) * math.cos(el), math.sin(el), math.cos(az) * math.cos(el)])
    right = np.cross([0.0, 1.0, 0.0], eye)
    right /= np.linalg.norm(right)
    up = np.cross(eye, right)
    return np.stack([right, up, eye]), eye


def _rasterise_small(xyz: np.ndarray, rgb: np.ndarray, image: np.ndarray, depth: np.ndarray, k: int) -> None:
    """Z-buffer triangles whose pixel bbox fits in k×k, all at once: test the k×k pixel centres of each
    triangle's bbox, then keep the nearest sample per pixel."""
    n = depth.shape[0]
    x0 = np.floor(xyz[:, :, 0].min(axis=1)).astype(int)
    y0 = np.floor(xyz[:, :, 1].min(axis=1)).astype(int)
    offsets = np.arange(k)
    px = (x0[:, None, None] + offsets[None, None, :]).astype(float) + 0.5  # (T, 1, k)
    py = (y0[:, None, None] + offsets[None, :, None]).astype(float) + 0.5  # (T, k, 1)
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = (xyz[:, i, :].T[:, :, None, None] for i in range(3))
    area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    area = np.where(np.abs(area) < 1e-12, np.nan, area)
    w0 = ((bx - px) * (cy - py) - (cx - px) * (by - py)) / area
    w1 = ((cx - px) * (ay - py) - (ax - px) * (cy - py)) / area
    w2 = 1.0 - w0 - w1
    inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0) & (px < n) & (py < n) & (px >= 0) & (py >= 0)
    t_idx, j, i = np.nonzero(inside)
    if not len(t_idx):
        return
    z = (w0 * az + w1 * bz + w2 * cz)[t_idx, j, i]
    flat = (y0[t_idx] + j) * n + (x0[t_idx] + i)
    order = np.lexsort((z, flat))
    flat, z, t_idx = flat[order], z[order], t_idx[order]
    last = np.r_[flat[1:] != flat[:-1], True]  # the nearest sample of each pixel
    flat, z, t_idx = flat[last], z[last], t_idx[last]
    d, im = depth.reshape(-1), image.reshape(-1, 3)
    nearer = z > d[flat]
    d[flat[nearer]] = z[nearer]
    im[flat[nearer]] = rgb[t_idx[nearer]]


def _rasterise(xyz: np.ndarray, rgb: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Z-buffer ``xyz`` (T, 3, 3) triangles in pixel coordinates (x right, y down, z towards the viewer) into
    an n×n image; returns (colour image, coverage mask)."""
    image = np.zeros((n, n, 3))
    depth = np.full((n, n), -np.inf)
    span = (np.ceil(xyz[:, :, :2].max(axis=1)) - np.floor(xyz[:, :, :2].min(axis=1))).max(axis=1)
    done = np.zeros(len(xyz), dtype=bool)
    for k in TIERS_PX:
        tier = np.flatnonzero(~done & (span <= k))
        batch = max(1, SAMPLES_PER_BATCH // (k + 1) ** 2)  # bounds the memory of the sample grids
        for lo in range(0, len(tier), batch):
            idx = tier[lo:lo + batch]
            _rasterise_small(xyz[idx], rgb[idx], image, depth, k + 1)
        done[tier] = True
    for tri, colour in zip(xyz[~done], rgb[~done], strict=True):
        (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = tri
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-12:
            continue
        xa, xb = max(int(np.floor(min(x0, x1, x2))), 0), min(int(np.ceil(max(x0, x1, x2))), n - 1)
        ya, yb = max(int(np.floor(min(y0, y1, y2))), 0), min(int(np.ceil(max(y0, y1, y2))), n - 1)
        if xa > xb or ya > yb:
            continue
        px = np.arange(xa, xb + 1)[None, :] + 0.5
        py = np.arange(ya, yb + 1)[:, None] + 0.5
        w0 = ((x1 - px) * (y2 - py) - (x2 - px) * (y1 - py)) / area
        w1 = ((x2 - px) * (y0 - py) - (x0 - px) * (y2 - py)) / area
        w2 = 1.0 - w0 - w1
        z = w0 * z0 + w1 * z1 + w2 * z2
        window = depth[ya:yb + 1, xa:xb + 1]
        nearer = (w0 >= 0) & (w1 >= 0) & (w2 >= 0) & (z > window)
        window[nearer] = z[nearer]
        image[ya:yb + 1, xa:xb + 1][nearer] = colour
    return image, np.isfinite(depth)


def render_thumbnail(scene: trimesh.Scene | trimesh.Trimesh, size_px: int = 256) -> bytes:
    """A PNG (transparent background) of ``scene`` given in the canonical frame (+Y up, front +Z)."""
    meshes = scene.dump() if isinstance(scene, trimesh.Scene) else [scene]
    tris, colors = _triangles([m for m in meshes if isinstance(m, trimesh.Trimesh) and len(m.faces)])
    view, eye = _camera()
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    lengths = np.linalg.norm(normals, axis=1)
    ok = lengths > 0
    tris, colors, normals = tris[ok], colors[ok], normals[ok] / lengths[ok, None]
    light = eye + np.array([0.3, 0.6, 0.0])
    light /= np.linalg.norm(light)
    shade = AMBIENT + (1 - AMBIENT) * np.abs(normals @ light)  # two-sided: SketchUp faces point either way
    shaded = np.clip(colors * shade[:, None], 0, 1)

    n = size_px * SUPERSAMPLE
    projected = tris @ view.T
    if len(projected):
        lo = projected.reshape(-1, 3).min(axis=0)
        hi = projected.reshape(-1, 3).max(axis=0)
        centre, half = (lo[:2] + hi[:2]) / 2, max(hi[:2] - lo[:2]) / 2 * MARGIN or 1.0
        pixels = np.empty_like(projected)
        pixels[..., 0] = (projected[..., 0] - centre[0] + half) / (2 * half) * n
        pixels[..., 1] = (centre[1] + half - projected[..., 1]) / (2 * half) * n
        pixels[..., 2] = projected[..., 2]
    else:
        pixels = projected
    image, mask = _rasterise(pixels, shaded, n)
    rgba = np.dstack([image, mask.astype(float)])
    rgba[..., :3] *= rgba[..., 3:]  # premultiply so that the edges downsample cleanly
    small = Image.fromarray((rgba * 255).round().astype(np.uint8), "RGBA").resize((size_px, size_px),
                                                                                   Image.Resampling.BOX)
    out = np.asarray(small, dtype=float)
    alpha = out[..., 3:] / 255.0
    out[..., :3] = np.where(alpha > 0, out[..., :3] / np.maximum(alpha, 1e-6), 0)
    buf = io.BytesIO()
    Image.fromarray(out.clip(0, 255).round().astype(np.uint8), "RGBA").save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def save_thumbnail(scene, path: str | Path, size_px: int = 256) -> Path:
    path = Path(path)
    path.write_bytes(render_thumbnail(scene, size_px))
    return path

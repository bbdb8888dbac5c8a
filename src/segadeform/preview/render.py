"""A small software renderer for previews: shaded triangle meshes, orthographic, no Blender, no GPU.

:func:`render` draws meshes (painter's algorithm: triangles sorted back to
front, Lambert shading with a head light) with matplotlib's 2-D polygon
collections into an RGB array, and :func:`save_image` / :func:`save_animation`
write PNG, GIF or MP4 (MP4 needs ffmpeg on PATH).  Needs the ``plot`` extra
(matplotlib) and nothing else.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["MeshLayer", "render", "save_image", "save_animation", "view_rotation"]


class MeshLayer:
    """One mesh to draw: vertices (V, 3), faces (F, 3), an RGB colour in 0..1, optional alpha, and a
    depth bias (metres towards the camera, for sorting only: cloth a few mm over skin wins the tie)."""

    def __init__(self, vertices, faces, color=(0.8, 0.8, 0.8), alpha: float = 1.0, depth_bias: float = 0.0):
        v = np.asarray(vertices, np.float64)
        f = np.asarray(faces, np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
            raise InputError("a layer needs vertices (V, 3) and triangles (F, 3)", got=(v.shape, f.shape))
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise InputError("face indices out of range", expected=f"0..{len(v) - 1}", got=(f.min(), f.max()))
        if not np.isfinite(v).all():
            raise InputError("vertices contain NaN or inf")
        self.vertices, self.faces = v, f
        self.color = np.asarray(color, np.float64)
        self.alpha = float(alpha)
        self.depth_bias = float(depth_bias)


def view_rotation(azimuth_deg: float, elevation_deg: float = 10.0) -> np.ndarray:
    """(3, 3) rotation turning world (+Y up, facing +Z) into camera space (x right, y up, -z away)."""
    a, e = np.deg2rad(azimuth_deg), np.deg2rad(elevation_deg)
    ry = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    rx = np.array([[1, 0, 0], [0, np.cos(e), -np.sin(e)], [0, np.sin(e), np.cos(e)]])
    return rx @ ry


def render(
    layers: Sequence[MeshLayer],
    *,
    azimuth: float = 0.0,
    elevation: float = 10.0,
    size=(480, 640),
    bounds=None,
    background=(1.0, 1.0, 1.0),
    title: str | None = None,
) -> np.ndarray:
    """Render ``layers`` seen from ``azimuth`` degrees about +Y (0: from the front, +Z).

    Args:
        size: (width, height) in pixels.
        bounds: ((xmin, xmax), (ymin, ymax)) in camera space; default: fit every layer.
    Returns:
        (height, width, 3) uint8 image.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    R = view_rotation(azimuth, elevation)
    light = np.array([0.3, 0.4, 1.0])
    light /= np.linalg.norm(light)
    polys, colors, depth = [], [], []
    for layer in layers:
        v = layer.vertices @ R.T
        tri = v[layer.faces]  # (F, 3, 3)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-20)
        shade = 0.35 + 0.65 * np.abs(n @ light)  # two-sided: garments are open surfaces
        rgb = np.clip(layer.color[None] * shade[:, None], 0, 1)
        polys.append(tri[:, :, :2])
        colors.append(np.concatenate([rgb, np.full((len(rgb), 1), layer.alpha)], axis=1))
        depth.append(tri[:, :, 2].mean(axis=1) + layer.depth_bias)
    if not polys:
        raise InputError("nothing to render")
    P = np.concatenate(polys)
    C = np.concatenate(colors)
    order = np.argsort(np.concatenate(depth))  # far (small z) first
    w, h = size
    fig = plt.figure(figsize=(w / 100, h / 100), dpi=100)
    ax = fig.add_axes([0, 0, 1, 1])
    ax.set_facecolor(background)
    fig.patch.set_facecolor(background)
    ax.add_collection(PolyCollection(P[order], facecolors=C[order], edgecolors="none", antialiased=False))
    if bounds is None:
        lo, hi = P.reshape(-1, 2).min(0), P.reshape(-1, 2).max(0)
        c, r = (lo + hi) / 2, (hi - lo).max() / 2 * 1.08
        aspect = w / h
        bounds = (
            (c[0] - r * max(aspect, 1), c[0] + r * max(aspect, 1)),
            (c[1] - r / min(aspect, 1), c[1] + r / min(aspect, 1)),
        )
    (x0, x1), (y0, y1) = bounds
    # equal scale on both axes
    sx, sy = (x1 - x0) / w, (y1 - y0) / h
    s = max(sx, sy)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    ax.set_xlim(cx - s * w / 2, cx + s * w / 2)
    ax.set_ylim(cy - s * h / 2, cy + s * h / 2)
    ax.axis("off")
    if title:
        ax.text(0.02, 0.98, title, transform=ax.transAxes, va="top", ha="left", fontsize=9, color="0.2")
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return img


def fit_bounds(
    points: np.ndarray, *, azimuth: float = 0.0, elevation: float = 10.0, size=(480, 640), margin: float = 1.08
):
    """Camera-space bounds that hold ``points (..., 3)`` from this view (one framing for a whole animation)."""
    v = np.asarray(points, np.float64).reshape(-1, 3) @ view_rotation(azimuth, elevation).T
    lo, hi = v[:, :2].min(0), v[:, :2].max(0)
    c, r = (lo + hi) / 2, (hi - lo) / 2 * margin
    w, h = size
    s = max(r[0] / (w / 2), r[1] / (h / 2))
    return ((c[0] - s * w / 2, c[0] + s * w / 2), (c[1] - s * h / 2, c[1] + s * h / 2))


def save_image(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write an RGB uint8 image as PNG, atomically."""
    from matplotlib.image import imsave

    from ..io.atomic import atomic_path

    p = Path(path)
    with atomic_path(p) as tmp:
        imsave(tmp, image, format="png")
    return p


def save_animation(path: str | os.PathLike, frames: Sequence[np.ndarray], fps: float) -> Path:
    """Write frames as an animated GIF (pillow, through matplotlib's dependency) or MP4 (ffmpeg), atomically."""
    from ..io.atomic import atomic_path

    p = Path(path)
    ext = p.suffix.lower()
    if not frames:
        raise InputError("no frames to write")
    with atomic_path(p) as tmp:
        if ext == ".gif":
            from PIL import Image

            ims = [Image.fromarray(f) for f in frames]
            ims[0].save(
                tmp, format="GIF", save_all=True, append_images=ims[1:], duration=int(round(1000 / fps)), loop=0
            )
        elif ext == ".mp4":
            import shutil
            import subprocess

            if shutil.which("ffmpeg") is None:
                raise InputError("writing .mp4 needs ffmpeg on PATH", expected=".gif or .png, or install ffmpeg")
            h, w = frames[0].shape[:2]
            cmd = [
                "ffmpeg",
                "-loglevel",
                "error",
                "-y",
                "-f",
                "rawvideo",
                "-pix_fmt",
                "rgb24",
                "-s",
                f"{w}x{h}",
                "-r",
                f"{fps}",
                "-i",
                "-",
                "-pix_fmt",
                "yuv420p",
                "-vf",
                "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                "-f",
                "mp4",
                str(tmp),
            ]
            proc = subprocess.run(
                cmd, input=b"".join(np.ascontiguousarray(f).tobytes() for f in frames), capture_output=True
            )
            if proc.returncode != 0:
                raise InputError(f"ffmpeg failed: {proc.stderr.decode(errors='replace')[-300:]}")
        else:
            raise InputError("unknown animation format", path=p, expected=".gif or .mp4", got=ext)
    return p

"""A small software renderer for previews: shaded triangle meshes, orthographic, no Blender, no GPU.

:func:`render` draws meshes (a depth buffer in numpy: each pixel shows the
nearest triangle at its centre; flat Lambert shading with a head light) into
an RGB array, and :func:`save_image` / :func:`save_animation`
write PNG, GIF or MP4 (MP4 needs ffmpeg on PATH).  Needs the ``plot`` extra
(matplotlib) and nothing else.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["MeshLayer", "rasterize", "render", "save_image", "save_animation", "check_encoder", "view_rotation"]


class MeshLayer:
    """One mesh to draw: vertices (V, 3), faces (F, 3), an RGB colour in 0..1, optional alpha (blended with the
    background, not with what is behind), and a depth bias (metres towards the camera, for the depth test only:
    cloth a few mm over skin wins the tie)."""

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

    Each pixel shows the nearest triangle at its centre (a depth buffer, :func:`rasterize`): cloth a few
    millimetres over the skin covers it wherever it is outside the body, and the body shows through only where the
    garment really is behind it.  (A painter's algorithm, sorting whole triangles by their mean depth, draws
    skin over cloth that is outside it wherever a large body triangle's centre is nearer than a small cloth
    triangle's: speckles that are not in the geometry.)

    Args:
        size: (width, height) in pixels.
        bounds: ((xmin, xmax), (ymin, ymax)) in camera space; default: fit every layer.
    Returns:
        (height, width, 3) uint8 image.
    """
    R = view_rotation(azimuth, elevation)
    light = np.array([0.3, 0.4, 1.0])
    light /= np.linalg.norm(light)
    bg = np.asarray(background, np.float64)
    tris, colors, bias = [], [], []
    for layer in layers:
        tri = (layer.vertices @ R.T)[layer.faces]  # (F, 3, 3)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-20)
        shade = 0.35 + 0.65 * np.abs(n @ light)  # two-sided: garments are open surfaces
        rgb = np.clip(layer.color[None] * shade[:, None], 0, 1)
        tris.append(tri)
        colors.append(layer.alpha * rgb + (1.0 - layer.alpha) * bg[None])
        bias.append(np.full(len(tri), layer.depth_bias))
    if not tris:
        raise InputError("nothing to render")
    T = np.concatenate(tris)
    w, h = size
    if bounds is None:
        lo, hi = T[:, :, :2].reshape(-1, 2).min(0), T[:, :, :2].reshape(-1, 2).max(0)
        c, r = (lo + hi) / 2, (hi - lo).max() / 2 * 1.08
        aspect = w / h
        bounds = (
            (c[0] - r * max(aspect, 1), c[0] + r * max(aspect, 1)),
            (c[1] - r / min(aspect, 1), c[1] + r / min(aspect, 1)),
        )
    (x0, x1), (y0, y1) = bounds
    # equal scale on both axes; a subject of no extent (every point in one place: a cache of zeros) is not a
    # division by zero (NaN warnings, nothing drawn): a micrometre a pixel
    s = max((x1 - x0) / w, (y1 - y0) / h, 1e-6)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    pix = np.empty_like(T)  # pixel coordinates: x right, y down, depth (larger: nearer)
    pix[..., 0] = (T[..., 0] - (cx - s * w / 2)) / s
    pix[..., 1] = ((cy + s * h / 2) - T[..., 1]) / s
    pix[..., 2] = T[..., 2] + np.concatenate(bias)[:, None]
    face = rasterize(pix, w, h)
    img = np.empty((h * w, 3), np.float64)
    img[:] = bg
    hit = face >= 0
    img[hit] = np.concatenate(colors)[face[hit]]
    img = np.round(255 * img.reshape(h, w, 3)).astype(np.uint8)
    return _titled(img, title) if title else img


def rasterize(pix: np.ndarray, width: int, height: int, *, chunk: int = 2_000_000) -> np.ndarray:
    """The nearest triangle at every pixel centre: a depth buffer, vectorised over (triangle, pixel) pairs.

    ``pix (F, 3, 3)``: each triangle's corners in pixel coordinates (x right, y down; pixel (i, j) covers
    [i, i + 1) x [j, j + 1) and is sampled at its centre) and a depth, larger = nearer.  A centre on an edge
    belongs to both triangles; the nearer wins, ties to the lower index.  Returns ``(height * width,)`` int64:
    the winning triangle per pixel (row-major), -1 where none covers it.  Degenerate triangles (zero area in the
    image plane) and non-finite corners cover nothing.
    """
    pix = np.asarray(pix, np.float64)
    best = np.full(height * width, -1, np.int64)
    depth = np.full(height * width, -np.inf)
    if not len(pix):
        return best
    x, y, z = pix[..., 0], pix[..., 1], pix[..., 2]
    ok = np.isfinite(pix).all(axis=(1, 2))
    area = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
    ok &= area != 0
    with np.errstate(invalid="ignore"):
        i0 = np.clip(np.ceil(np.nanmin(x, 1) - 0.5), 0, width).astype(np.int64)
        i1 = np.clip(np.floor(np.nanmax(x, 1) - 0.5), -1, width - 1).astype(np.int64)
        j0 = np.clip(np.ceil(np.nanmin(y, 1) - 0.5), 0, height).astype(np.int64)
        j1 = np.clip(np.floor(np.nanmax(y, 1) - 0.5), -1, height - 1).astype(np.int64)
    nx, ny = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    count = np.where(ok, nx * ny, 0)
    faces = np.flatnonzero(count)
    # chunks of whole triangles whose pairs fit in `chunk`
    ends = np.cumsum(count[faces])
    lo = 0
    while lo < len(faces):
        hi = max(int(np.searchsorted(ends, (ends[lo - 1] if lo else 0) + chunk, side="right")), lo + 1)
        f = faces[lo:hi]
        t = np.repeat(f, count[f])
        k = np.arange(len(t)) - np.repeat(np.cumsum(count[f]) - count[f], count[f])
        px = i0[t] + k % nx[t] + 0.5
        py = j0[t] + k // nx[t] + 0.5
        # barycentric coordinates from the edge functions, normalised by the signed area
        a = area[t]
        w0 = ((x[t, 1] - px) * (y[t, 2] - py) - (x[t, 2] - px) * (y[t, 1] - py)) / a
        w1 = ((x[t, 2] - px) * (y[t, 0] - py) - (x[t, 0] - px) * (y[t, 2] - py)) / a
        w2 = 1.0 - w0 - w1
        inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0)
        t, w0, w1, w2 = t[inside], w0[inside], w1[inside], w2[inside]
        d = w0 * z[t, 0] + w1 * z[t, 1] + w2 * z[t, 2]
        p = ((j0[t] + k[inside] // nx[t]) * width + i0[t] + k[inside] % nx[t]).astype(np.int64)
        # per pixel: the nearest candidate of this chunk (ties: the lower triangle index), then against the buffer
        order = np.lexsort((t, -d, p))
        p, d, t = p[order], d[order], t[order]
        first = np.ones(len(p), bool)
        first[1:] = p[1:] != p[:-1]
        p, d, t = p[first], d[first], t[first]
        win = (d > depth[p]) | ((d == depth[p]) & (t < best[p]))
        depth[p[win]], best[p[win]] = d[win], t[win]
        lo = hi
    return best


def _titled(img: np.ndarray, title: str) -> np.ndarray:
    """``img`` with ``title`` written in its top left corner (matplotlib's text, as before)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    h, w = img.shape[:2]
    fig = Figure(figsize=(w / 100, h / 100), dpi=100)  # no pyplot: no global figure state
    canvas = FigureCanvasAgg(fig)
    fig.figimage(img, 0, 0, origin="upper")
    fig.text(0.02, 0.98, title, va="top", ha="left", fontsize=9, color="0.2")
    canvas.draw()
    out = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    return out


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


def check_encoder(path: str | os.PathLike) -> None:
    """Refuse an animation whose encoder is missing (MP4 needs ffmpeg on PATH): a caller checks before rendering."""
    import shutil

    p = Path(path)
    if p.suffix.lower() == ".mp4" and shutil.which("ffmpeg") is None:
        raise InputError(
            "writing .mp4 needs ffmpeg on PATH", path=p, expected="ffmpeg installed, or a .gif or .png", got="no ffmpeg"
        )


def save_animation(path: str | os.PathLike, frames: Sequence[np.ndarray], fps: float) -> Path:
    """Write frames as an animated GIF (pillow, through matplotlib's dependency) or MP4 (ffmpeg), atomically."""
    from ..io.atomic import atomic_path

    p = Path(path)
    ext = p.suffix.lower()
    if not frames:
        raise InputError("no frames to write")
    check_encoder(p)
    with atomic_path(p) as tmp:
        if ext == ".gif":
            from PIL import Image

            ims = [Image.fromarray(f) for f in frames]
            ims[0].save(
                tmp, format="GIF", save_all=True, append_images=ims[1:], duration=int(round(1000 / fps)), loop=0
            )
        elif ext == ".mp4":
            import subprocess

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

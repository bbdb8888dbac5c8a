"""The cloth stage's hard cases beyond the generic runner (catalogue.CLOTH_CASES): each gives a finite, bounded
result or a clear error."""

from __future__ import annotations

import ctypes
import gc
import logging
import tracemalloc

import numpy as np
import pytest

from segadeform.body import default_body_path, load_body
from segadeform.body.cloth import ClothSettings, ClothStage, garment_setup
from segadeform.errors import InputError
from segadeform.geometry.primitives import frustum
from segadeform.motion import make_motion
from tests.hard_cases.catalogue import CLOTH_CASES


@pytest.fixture(scope="module")
def body():
    return load_body(default_body_path())


def _skirt(n_around=16, n_rings=6):
    return frustum(n_around, n_rings, 0.17, 0.33, 1.02, 0.55)


def _targets(v, trans):
    """The garment carried by the root's translation (what a deformer roughly gives around the hips)."""
    return np.stack([v + t for t in trans])


def test_the_cases_are_named_with_reasons():
    assert all(r and len(r) < 120 for r in CLOTH_CASES.values())
    tested = {n[len("test_") :] for n in globals() if n.startswith("test_cloth_")}
    assert tested == set(CLOTH_CASES)


def test_cloth_200k_vertices(body):
    v, f = frustum(632, 317, 0.17, 0.33, 1.02, 0.55)
    assert len(v) > 200_000
    m = make_motion("walk", seconds=2 / 30.0)
    setup = garment_setup(v, f, body.shaped_vertices()[0], body.faces)
    assert len(setup.edges) > 3 * len(v) - 2000
    out = ClothStage(setup, body.v_template, body.faces).step(
        _targets(v, m.trans[:2]), body.forward(m.poses[:2], None, m.trans[:2]).vertices
    )
    assert out.shape == (2, len(v), 3) and np.isfinite(out).all()
    assert np.linalg.norm(out - _targets(v, m.trans[:2]), axis=-1).max() < 0.5


class _MallInfo2(ctypes.Structure):
    _fields_ = [
        (n, ctypes.c_size_t)
        for n in (
            "arena",
            "ordblks",
            "smblks",
            "hblks",
            "hblkhd",
            "usmblks",
            "fsmblks",
            "uordblks",
            "fordblks",
            "keepcost",
        )
    ]


def _c_heap_bytes() -> int | None:
    """The bytes malloc has handed out and not had back (glibc's mallinfo2: in use in the heap + in mmapped chunks),
    which sees the compiled kernel's buffers that tracemalloc does not; None where the C library has no mallinfo2."""
    try:
        fn = ctypes.CDLL(None).mallinfo2
    except (AttributeError, OSError):
        return None
    fn.restype = _MallInfo2
    m = fn()
    return int(m.uordblks + m.hblkhd)


def test_cloth_stream_10000_frames(body):
    """10,000 frames through one stage, 100 at a time, beside a second stage given each hundred in two calls of
    37 and 63: the same frames every time (state across calls), and memory flat from the tenth hundred to the last,
    Python's (tracemalloc) and malloc's (the kernel's buffers; a kernel that kept one buffer per call failed it by
    200 MB), measured after a garbage collection so that garbage the collector frees at times of its own choosing
    does not count.  The stream is a 100-frame dance played forward and back in turn: continuous, so the stage
    never resets, without posing the body 10,000 times (which took most of this test's minutes)."""
    v, f = _skirt(12, 4)
    m = make_motion("dance", seconds=100 / 30.0, seed=2)
    assert m.n_frames == 100
    posed_once = body.forward(m.poses, None, m.trans).vertices
    y_once = _targets(v, m.trans)
    setup = garment_setup(v, f, body.shaped_vertices()[0], body.faces)
    a = ClothStage(setup, body.v_template, body.faces)
    b = ClothStage(setup, body.v_template, body.faces)
    held = {}
    tracemalloc.start()
    try:
        for k in range(100):
            step = 1 if k % 2 == 0 else -1
            posed, y = posed_once[::step], y_once[::step]
            out = a.step(y, posed)
            np.testing.assert_array_equal(np.concatenate([b.step(y[:37], posed[:37]), b.step(y[37:], posed[37:])]), out)
            assert np.isfinite(out).all()
            del posed, y, out
            if k in (9, 99):
                gc.collect()
                held[k] = (tracemalloc.get_traced_memory()[0], _c_heap_bytes())
    finally:
        tracemalloc.stop()
    assert a.frames == b.frames == 10000 and a.contacts > 0 and a.resets == 0
    # nothing accumulates: what is held after the last hundred is what was held after the tenth, by Python's
    # allocators (tracemalloc) and by malloc (the kernel's buffers; glibc only)
    assert held[99][0] - held[9][0] < 64 * 1024, held
    if held[9][1] is not None:
        assert held[99][1] - held[9][1] < 256 * 1024, held


def test_cloth_nan_from_upstream(body):
    v, f = _skirt()
    m = make_motion("walk", seconds=0.2)
    posed = body.forward(m.poses, None, m.trans).vertices
    y = _targets(v, m.trans)
    setup = garment_setup(v, f, body.shaped_vertices()[0], body.faces)
    stage = ClothStage(setup, body.v_template, body.faces, first_frame=40)
    first = stage.step(y[:2], posed[:2])
    bad = y[2:].copy()
    bad[1, 3] = np.nan
    with pytest.raises(InputError, match="NaN or inf in the garment frames at frame 43") as ei:
        stage.step(bad, posed[2:])
    assert "Traceback" not in str(ei.value)
    assert stage.frames == 2  # the bad call took nothing: the stage goes on as if it had not been made
    rest = stage.step(y[2:], posed[2:])
    np.testing.assert_array_equal(
        np.concatenate([first, rest]), ClothStage(setup, body.v_template, body.faces).step(y, posed)
    )


def test_cloth_teleport_resets_once(body, caplog):
    v, f = _skirt()
    m = make_motion("walk", seconds=0.5)
    trans = m.trans.copy()
    trans[6:] += [3.0, 0.0, 2.0]
    trans[11:] -= [3.0, 0.0, 2.0]
    posed = body.forward(m.poses, None, trans).vertices
    y = _targets(v, trans)
    setup = garment_setup(v, f, body.shaped_vertices()[0], body.faces)
    stage = ClothStage(setup, body.v_template, body.faces)
    with caplog.at_level(logging.WARNING, logger="segadeform.body.cloth"):
        out = np.concatenate([stage.step(y[lo : lo + 4], posed[lo : lo + 4]) for lo in range(0, len(y), 4)])
    said = [r.getMessage() for r in caplog.records if "started again" in r.getMessage()]
    assert stage.resets == 2 and len(said) == 1 and "frame 6" in said[0]
    assert np.isfinite(out).all() and np.linalg.norm(out - y, axis=-1).max() < 0.3  # no explosion
    # without the reset the stage would carry a 3.6 m velocity: with reset far from the jump, it does not reset
    calm = ClothStage(setup, body.v_template, body.faces, ClothSettings(reset=10.0)).step(y, posed)
    assert np.linalg.norm(calm - y, axis=-1).max() > np.linalg.norm(out - y, axis=-1).max()


def test_cloth_zero_length_edges(body):
    """Two coincident vertices (a seam) joined by a face that would make an edge of rest length 0, the target pulling
    them 2 cm apart: since cloth ABI 15 vertices at one rest position are one point of cloth (``ClothSetup.weld``), so
    the setup holds no zero-length edge and the two move as one (the seam stays shut), never NaN."""
    v, f = _skirt()
    n = len(v)
    k = n - 1  # a hem vertex: loose, far from the body
    v2 = np.vstack([v, v[k:]])  # vertex n coincides with vertex k
    f2 = np.vstack([f, [[k, n, k - 1]]])  # a zero-area face: edge (k, n) would have rest length 0
    m = make_motion("walk", seconds=0.3)
    posed = body.forward(m.poses, None, m.trans).vertices
    y = _targets(v2, m.trans)
    y[:, n] += [0.0, -0.02, 0.0]  # the target opens the seam by 2 cm
    setup = garment_setup(v2, f2, body.shaped_vertices()[0], body.faces, ClothSettings(attachment=0.0))
    assert setup.weld[n] == k and (setup.rest_len > 0).all() and setup.radius[k] > 0 and setup.radius[n] > 0
    assert not ((setup.edges == [k, n]).all(axis=1)).any()
    out = ClothStage(setup, body.v_template, body.faces, ClothSettings(attachment=0.0)).step(y, posed)
    assert np.isfinite(out).all()
    gap = np.linalg.norm(out[:, n] - out[:, k], axis=-1)
    assert (gap == 0).all() and np.linalg.norm(out - y, axis=-1).max() < 0.3

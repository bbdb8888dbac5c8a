"""Reading official SMPL ``.pkl`` files without chumpy and without running arbitrary code.

SMPL's pickles (Python 2, protocol 2) hold ``chumpy.ch.Ch`` objects (their
state carries the numpy array under ``x``), a ``scipy.sparse`` CSC matrix
(``J_regressor``) and plain numpy arrays.  :class:`RestrictedUnpickler` maps
the few globals those need to inert stand-ins and refuses every other global
(``os.system``, ``builtins.eval``, ``subprocess.Popen`` ...) with an
``UnpicklingError``, so a crafted file cannot execute code.  Stand-ins are
converted to plain numpy arrays after loading; nothing from chumpy or scipy
is imported or called during unpickling.
"""

from __future__ import annotations

import io
import pickle

import numpy as np

__all__ = ["RestrictedUnpickler", "load_smpl_pickle"]


class _StandIn:
    """Holds the state of an object we do not construct (chumpy, scipy.sparse)."""

    kind = "object"

    def __init__(self, *args):
        self.args = args
        self.state = None

    def __setstate__(self, state):
        self.state = state


class _Chumpy(_StandIn):
    kind = "chumpy"


class _Sparse(_StandIn):
    kind = "sparse"
    fmt: str  # "coo", "csc" or "csr": set by the subclass _find_class makes


def _reconstructor(cls, base, state):
    """Replacement for ``copyreg._reconstructor`` that only builds our stand-ins."""
    if not (isinstance(cls, type) and issubclass(cls, _StandIn)):
        raise pickle.UnpicklingError(f"refusing to reconstruct {cls!r}")
    return cls()


def _ndarray_reconstruct(subtype, shape, dtype):
    if subtype is not np.ndarray:
        raise pickle.UnpicklingError(f"refusing array subtype {subtype!r}")
    return np.ndarray.__new__(np.ndarray, shape, dtype)


def _dtype(*args):
    return np.dtype(*args)


def _scalar(dtype, data=None):
    if not isinstance(dtype, np.dtype) or dtype.hasobject:
        raise pickle.UnpicklingError("refusing object scalar")
    return np.frombuffer(data, dtype=dtype, count=1)[0]


def _codecs_encode(text, encoding="utf-8"):
    """Protocol-2 pickles written by Python 3 carry bytes as ``_codecs.encode(str, 'latin1')``."""
    if not isinstance(text, str) or encoding.lower().replace("-", "") not in ("latin1", "iso88591"):
        raise pickle.UnpicklingError("refusing _codecs.encode with an unexpected argument")
    return text.encode("latin-1")


_NUMPY_MODULES = ("numpy.core.multiarray", "numpy._core.multiarray", "numpy")
_ALLOWED = {
    ("copy_reg", "_reconstructor"): _reconstructor,
    ("copyreg", "_reconstructor"): _reconstructor,
    ("__builtin__", "object"): object,
    ("builtins", "object"): object,
    ("_codecs", "encode"): _codecs_encode,
}
for _m in _NUMPY_MODULES:
    _ALLOWED[(_m, "_reconstruct")] = _ndarray_reconstruct
    _ALLOWED[(_m, "ndarray")] = np.ndarray
    _ALLOWED[(_m, "dtype")] = _dtype
    _ALLOWED[(_m, "scalar")] = _scalar


class RestrictedUnpickler(pickle.Unpickler):
    """An unpickler that knows only numpy arrays, chumpy objects and scipy sparse matrices."""

    def find_class(self, module: str, name: str):
        if (module, name) in _ALLOWED:
            return _ALLOWED[(module, name)]
        if module.split(".")[0] == "chumpy":
            return _Chumpy
        if module.startswith("scipy.sparse") and name in ("csc_matrix", "csr_matrix", "coo_matrix"):
            return type(name, (_Sparse,), {"fmt": name[:3]})
        raise pickle.UnpicklingError(f"forbidden global in pickle: {module}.{name}")


def _to_numpy(obj):
    if isinstance(obj, np.ndarray):
        if obj.dtype.hasobject:
            raise pickle.UnpicklingError("object arrays are not allowed")
        return obj
    if isinstance(obj, _Chumpy):
        st = obj.state if isinstance(obj.state, dict) else {}
        if "x" not in st:
            raise pickle.UnpicklingError("chumpy object without an 'x' array")
        return _to_numpy(st["x"])
    if isinstance(obj, _Sparse):
        st = obj.state if isinstance(obj.state, dict) else {}
        shape = st.get("_shape")
        if shape is None or st.get("data") is None:
            raise pickle.UnpicklingError("sparse matrix state is incomplete")
        import scipy.sparse as sp

        if obj.fmt == "coo":
            m = sp.coo_matrix((_to_numpy(st["data"]), (_to_numpy(st["row"]), _to_numpy(st["col"]))), shape=shape)
        else:
            ctor = sp.csc_matrix if obj.fmt == "csc" else sp.csr_matrix
            m = ctor((_to_numpy(st["data"]), _to_numpy(st["indices"]), _to_numpy(st["indptr"])), shape=tuple(shape))
        return np.asarray(m.toarray())
    if isinstance(obj, (int, float, str, bytes, bool)) or obj is None:
        return obj
    if isinstance(obj, (list, tuple)):
        return type(obj)(_to_numpy(x) for x in obj)
    if isinstance(obj, dict):
        return {k: _to_numpy(v) for k, v in obj.items()}
    raise pickle.UnpicklingError(f"unexpected object of type {type(obj).__name__}")


def load_smpl_pickle(data: bytes) -> dict:
    """Unpickle SMPL model bytes into a dict of numpy arrays (and plain values)."""
    obj = RestrictedUnpickler(io.BytesIO(data), encoding="latin1").load()
    if not isinstance(obj, dict):
        raise pickle.UnpicklingError(f"expected a dict at the top level, got {type(obj).__name__}")
    return {str(k): _to_numpy(v) for k, v in obj.items()}
